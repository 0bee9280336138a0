"""The thesis's scenes and the built-in scenes that stand for them: the one correspondence every report reads.

The thesis rendered three scenes we cannot ship: the Cornell box (its own
variant), the Dragons (depth of field) and San Miguel. Our stand-ins are
Mitsuba's Cornell box, ``dof-sculptures`` and ``courtyard``
(:mod:`sparselt.rendering.procedural`), with the thin lens San Miguel's
depth-of-field tables need (:data:`SAN_MIGUEL`). Each table of the thesis
that reports a scene is listed in :data:`TABLE_SCENES` with the scene we run
for it and the signal kind; Tables 5.1/5.2 report one signal per row
(:data:`PATH_SPACE_ROWS`).

Every place that needs "which of our scenes is the thesis's X" or "which
thesis table belongs beside our scene Y" reads it here: the comparison
report (Tables 6.2/6.3 and 8.1/8.2 beside ``compare``'s rows), and every
chapter of ``sparselt reproduce``.

References
----------
Thesis chapters 5-8: Tables 5.1/5.2 (path space of the Cornell box and San
Miguel), 6.1-6.3 (the SFT and its importance maps), 7.1-7.3 (gamma mapping on
the Dragons and San Miguel), 8.1/8.2 (the equal-time comparisons).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ThesisScene:
    """One scene of the thesis and the built-in scene that stands for it.

    Attributes
    ----------
    name : str
        The thesis's name, as its table captions print it ("San Miguel").
    scene : str
        Our built-in scene.
    row_label : str or None
        The scene's label in the rows of Tables 5.1/5.2 ("Cornell"); None
        for a scene those tables do not report.
    aperture, focus_distance : float or None
        Our thin lens for the thesis's depth-of-field signals of this scene
        (``None``: the scene's own camera).
    gamma : float or None
        The gamma of eq. 7.1 the thesis's CoSaMP reconstruction used on this
        scene (8.1.1); ``None`` where the thesis ran no reconstruction.
    """

    name: str
    scene: str
    row_label: str | None = None
    aperture: float | None = None
    focus_distance: float | None = None
    gamma: float | None = None

    def lens(self):
        """The thin lens as keyword arguments of a configuration (``aperture``, ``focus_distance``); {} for none."""
        values = {"aperture": self.aperture, "focus_distance": self.focus_distance}
        return {key: value for key, value in values.items() if value is not None}


CORNELL_BOX = ThesisScene(name="Cornell Box", scene="cornell-box", row_label="Cornell")
DRAGONS = ThesisScene(name="Dragons", scene="dof-sculptures", gamma=0.25)
SAN_MIGUEL = ThesisScene(name="San Miguel", scene="courtyard", row_label="San Miguel", aperture=0.1,
                         focus_distance=8.0, gamma=0.5)
#: thesis name -> :class:`ThesisScene`
THESIS_SCENES = {scene.name: scene for scene in (CORNELL_BOX, SAN_MIGUEL, DRAGONS)}


@dataclass(frozen=True)
class TableScene:
    """The scene of one thesis table: the thesis's, and what we run for it.

    Attributes
    ----------
    table : str
        The thesis table ("8.2").
    thesis_scene : ThesisScene
    scene : str
        Our scene run for the table (the thesis scene's stand-in, or a variant
        of it: ``cornell-caustics`` for Table 6.2's importance maps).
    kind : str
        The signal kind (:mod:`sparselt.rendering.layout`).
    also : tuple of str
        Other scenes of ours whose reports show the table beside them.
    """

    table: str
    thesis_scene: ThesisScene
    scene: str
    kind: str
    also: tuple = ()

    def lens(self):
        """The thin lens of the table's signal: the thesis scene's for kind ``dof``, else {}."""
        return self.thesis_scene.lens() if self.kind == "dof" else {}

    @property
    def scenes(self):
        """Every scene of ours the table stands beside: :attr:`scene`, then :attr:`also`."""
        return (self.scene,) + tuple(self.also)


#: thesis table -> :class:`TableScene`, for every table that reports one scene
TABLE_SCENES = {record.table: record for record in (
    TableScene("6.1", CORNELL_BOX, "cornell-box", "path"),
    TableScene("6.2", CORNELL_BOX, "cornell-caustics", "path", also=("cornell-box",)),
    TableScene("6.3", SAN_MIGUEL, "courtyard", "path"),
    TableScene("7.1", DRAGONS, "dof-sculptures", "dof"),
    TableScene("7.2", SAN_MIGUEL, "courtyard", "dof"),
    TableScene("7.3", SAN_MIGUEL, "courtyard", "indirect"),
    TableScene("8.1", DRAGONS, "dof-sculptures", "dof"),
    TableScene("8.2", SAN_MIGUEL, "courtyard", "dof"),
)}

#: Tables 5.1/5.2, one signal per row: the thesis's row label -> (thesis scene, our signal kind)
PATH_SPACE_ROWS = {f"{scene.row_label}{suffix}": (scene, kind) for scene in (CORNELL_BOX, SAN_MIGUEL)
                   for suffix, kind in (("", "path"), (" Indirect Only", "path-indirect"))}

#: The equal-time comparisons' tables (8.1.1: CoSaMP execution times, depth of field) and the importance
#: maps' tables (6.2: SFT importance sampling).
EQUAL_TIME_TABLES = ("8.1", "8.2")
GUIDING_TABLES = ("6.2", "6.3")


def table_scene(table):
    """The :class:`TableScene` of thesis table ``table``.

    Raises
    ------
    ValueError
        A table that reports no single scene (the list names those that do).
    """
    if table not in TABLE_SCENES:
        raise ValueError(f"thesis table {table!r} reports no single scene; tables with one: {', '.join(TABLE_SCENES)}")
    return TABLE_SCENES[table]


def table_for_scene(scene, tables):
    """The first of ``tables`` (thesis table numbers) that stands beside our scene ``scene``; None if none does.

    Examples
    --------
    >>> table_for_scene("courtyard", EQUAL_TIME_TABLES)
    '8.2'
    >>> table_for_scene("cornell-box", GUIDING_TABLES)
    '6.2'
    >>> table_for_scene("my-scene.xml", EQUAL_TIME_TABLES) is None
    True
    """
    return next((table for table in tables if scene in table_scene(table).scenes), None)


def correspondence_text():
    """The correspondence as one sentence for a page: "Dragons = dof-sculptures, ... (cornell-caustics for the caustics)"."""
    variants = {record.thesis_scene.name: record.scene for record in TABLE_SCENES.values()
                if record.scene != record.thesis_scene.scene}
    parts = []
    for scene in (DRAGONS, SAN_MIGUEL, CORNELL_BOX):
        text = f"{scene.name} = {scene.scene}"
        if scene.name in variants:
            text += f" ({variants[scene.name]} for the caustics)"
        parts.append(text)
    return ", ".join(parts)


__all__ = ["CORNELL_BOX", "DRAGONS", "EQUAL_TIME_TABLES", "GUIDING_TABLES", "PATH_SPACE_ROWS", "SAN_MIGUEL",
           "TABLE_SCENES", "THESIS_SCENES", "TableScene", "ThesisScene", "correspondence_text", "table_for_scene",
           "table_scene"]
