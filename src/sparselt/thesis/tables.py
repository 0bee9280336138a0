"""Thesis Tables 6.1, 6.2/6.3 and 8.1/8.2 beside ours: the thesis's side read once, each table built once.

A single run's report (``sparselt table61``, ``sparselt compare``) and the
chapters of ``sparselt reproduce`` call the same functions with plain rows:

* :func:`table_6_1`: Table 6.1 (the SFT's sample counts, 6.1.2) beside our
  SFT runs, one row per run (several scenes: one row per run and scene);
* :func:`guiding_table`: Table 6.2 or 6.3 (SFT importance sampling, 6.2)
  beside our guided method, the thesis's i-th image size beside our i-th
  budget;
* :func:`equal_time_thesis`: Table 8.1 or 8.2's times per spp, which
  :func:`sparselt.report.comparison.table_8` sets beside the CoSaMP methods.

Which table belongs beside which of our scenes is
:mod:`sparselt.thesis.scenes`; the numbers are :mod:`sparselt.thesis.numbers`.

References
----------
Thesis 6.1.2 (Table 6.1), 6.2.2 (Tables 6.2 and 6.3), 8.1.1 (Tables 8.1 and 8.2).
"""

from __future__ import annotations

import math

from ..report.table import Table
from .numbers import thesis_rows, thesis_table
from .scenes import EQUAL_TIME_TABLES, GUIDING_TABLES, table_for_scene, table_scene

#: Thesis Tables 8.1/8.2: the phases timed, as printed.
THESIS_TIMES = ("Total", "Sampling", "CoSaMP", "Integration")
#: Thesis Tables 6.2/6.3: (spp, SFT importance sampling time, path tracing time), as each prints its columns.
GUIDING_COLUMNS = {
    "6.2": ("Samples per Pixel", "SFT Importance Sampling Time (s)", "Path Tracing Time (s)"),
    "6.3": ("Samples per Pixel", "SFT Importance Sampling Time (s)", "Path Tracing Time"),
}
#: Thesis Table 6.1's path space (6.1.2): a 100x100 image and eight 4-cell axes.
THESIS_SHAPE = (100, 100) + (4,) * 8


def _by_size(table, columns):
    """``{first number of the label: values}`` of a thesis table (``'1000x1000'`` -> 1000, ``'40'`` -> 40)."""
    return {int(label.split("x")[0]): values for label, values in thesis_rows(table, columns)}


def thesis_times(table):
    """Table 8.1 or 8.2: ``{spp: (total, sampling, CoSaMP, integration)}`` in seconds, as printed."""
    if table not in EQUAL_TIME_TABLES:
        raise ValueError(f"the equal-time tables are {', '.join(EQUAL_TIME_TABLES)}; got {table!r}")
    return _by_size(table, THESIS_TIMES)


def thesis_guiding_times(table):
    """Table 6.2 or 6.3: ``{image side: (spp, SFT importance sampling s, path tracing s)}``, as printed."""
    if table not in GUIDING_TABLES:
        raise ValueError(f"the importance-sampling tables are {', '.join(GUIDING_TABLES)}; got {table!r}")
    return _by_size(table, GUIDING_COLUMNS[table])


def thesis_table_6_1():
    """Thesis Table 6.1 (6.1.2: K = N / 10^4 of the 100x100x4^8 path space): alpha -> sample counts.

    Returns
    -------
    dict
        ``{alpha: {'support', 'magnitude', 'total', 'spp'}}`` for every row of the table.
    """
    keys = ("support", "magnitude", "total", "spp")
    columns = ("Support Detection", "Magnitude Estimation", "Total Samples", "Samples per Pixel")
    return {int(label): dict(zip(keys, values)) for label, values in thesis_rows("6.1", columns)}


def equal_time_thesis(scene, kind):
    """``(table, thesis scene, {spp: times})`` of Table 8.1/8.2 beside our ``scene`` at ``kind``; None if none.

    Tables 8.1/8.2 are depth of field: other kinds get None.
    """
    table = table_for_scene(scene, EQUAL_TIME_TABLES) if kind == "dof" else None
    return None if table is None else (table, table_scene(table).thesis_scene.name, thesis_times(table))


def guiding_thesis(scene):
    """``(table, thesis scene, {image side: (spp, SFT s, PT s)})`` of Table 6.2/6.3 beside ``scene``; None if none."""
    table = table_for_scene(scene, GUIDING_TABLES)
    return None if table is None else (table, table_scene(table).thesis_scene.name, thesis_guiding_times(table))


def table_6_1(rows, *, caption_suffix, epsilon, notes=()):
    """Thesis Table 6.1 beside our SFT runs (one :class:`~sparselt.report.Table`).

    Parameters
    ----------
    rows : list of dict
        Runs as ``sparselt table61`` records them (``alpha``,
        ``samples_per_point``, ``support_samples``, ``magnitude_samples``,
        ``total_samples``, ``samples_per_pixel``, ``fraction_of_signal``,
        ``sft`` / ``pt_equal_samples`` / ``pt_equal_time`` qualities,
        ``seconds``), each with an optional ``scene``: rows of several scenes
        are labelled ``"alpha, scene"``, and the thesis's counts stand beside
        the rows of Table 6.1's scene only (:mod:`sparselt.thesis.scenes`);
        rows without a scene are one run's, the thesis beside every alpha it has.
    caption_suffix : str
        Appended to "Table 6.1: <the thesis's caption>" (what ours is).
    epsilon : float
        The relMSE's epsilon the runs used (stated in the notes).
    notes : sequence of str
        Added after the thesis's grid note.

    Returns
    -------
    Table
    """
    thesis_rows_by_alpha = thesis_table_6_1()
    thesis_scene = table_scene("6.1").scene
    cells = math.prod(THESIS_SHAPE)
    table_rows = []
    for row in rows:
        scene = row.get("scene")
        beside = float(row["alpha"]).is_integer() and scene in (None, thesis_scene)
        thesis = thesis_rows_by_alpha.get(int(row["alpha"])) if beside else None
        thesis_cells = ([str(thesis[key]) for key in ("support", "magnitude", "total", "spp")] if thesis
                        else ["-"] * 4)
        label = str(row["alpha"]) if scene is None else f"{row['alpha']:g}, {scene}"
        table_rows.append((label, [
            str(row["samples_per_point"]), str(row["support_samples"]), str(row["magnitude_samples"]),
            str(row["total_samples"]), f"{row['samples_per_pixel']:.1f}", f"{row['fraction_of_signal']:.3f}",
            *thesis_cells, f"{row['sft']['ssim']:.3f}", f"{row['sft']['relmse']:.3g}",
            f"{row['pt_equal_samples']['ssim']:.3f}", f"{row['pt_equal_samples']['relmse']:.3g}",
            f"{row['pt_equal_time']['relmse']:.3g}", f"{row['seconds']:.1f}"]))
    return Table(
        caption=f"Table 6.1: {thesis_table('6.1')['caption']}{caption_suffix}",
        label_header="alpha",
        columns=["samples per point", "support detection", "magnitude estimation", "total samples",
                 "samples per pixel", "lattice points / N", "thesis support detection",
                 "thesis magnitude estimation", "thesis total samples", "thesis samples per pixel", "SFT SSIM",
                 "SFT relMSE", "PT same samples SSIM", "PT same samples relMSE", "PT same time relMSE", "seconds"],
        kinds=[""] + ["ours"] * 5 + ["thesis"] * 4 + ["ours"] * 6, rows=table_rows,
        notes=[f"Thesis: grid {'x'.join(map(str, THESIS_SHAPE))} = {cells:,} cells, K = N / 10^4 = "
               f"{round(cells * 1e-4):,}, one path sample per lattice point; relMSE epsilon {epsilon}. "
               "PT same samples / same time: path tracing given the SFT's path samples / seconds."] + list(notes))


def guiding_table(table, budgets, *, resolution, subject):
    """Thesis Table 6.2 or 6.3 beside our guided method (one :class:`~sparselt.report.Table`).

    Parameters
    ----------
    table : str
        '6.2' or '6.3'.
    budgets : list of dict
        Our budgets in increasing spp, each ``{'spp', 'seconds', 'relmse',
        'pt_seconds', 'pt_relmse'}``: the guided method's and path tracing's
        means over seeds at the same spp.
    resolution : tuple of int
        Our image ``(width, height)``.
    subject : str
        What ours is, for the caption (scene, map grid, seeds).

    Returns
    -------
    Table
        Row ``i`` pairs the thesis's ``i``-th image size with our ``i``-th
        budget: spp, the guided time, PT's time and their ratio of each, and
        our relMSE ratio at the same spp.
    """
    thesis = thesis_guiding_times(table)
    width, height = resolution
    rows = []
    for index in range(max(len(thesis), len(budgets))):
        size, values = list(thesis.items())[index] if index < len(thesis) else (None, None)
        mine = budgets[index] if index < len(budgets) else None
        rows.append((f"{f'{size}x{size}' if size else '-'} / {f'{width}x{height}' if mine else '-'}", [
            f"{values[0]}" if values else "-", f"{mine['spp']}" if mine else "-",
            f"{values[1]}" if values else "-", f"{mine['seconds']:.3f}" if mine else "-",
            f"{values[2]}" if values else "-", f"{mine['pt_seconds']:.3f}" if mine else "-",
            f"{values[1] / values[2]:.2f}" if values else "-",
            f"{mine['seconds'] / mine['pt_seconds']:.2f}" if mine else "-",
            f"{mine['relmse']:.4g} / {mine['pt_relmse']:.4g}" if mine else "-"]))
    return Table(
        caption=f"Table {table}: {thesis_table(table)['caption']} (ours: {subject}; row i pairs the thesis's i-th "
                "image size with our i-th budget)",
        columns=["thesis spp", "ours", "thesis SFT importance sampling s", "ours", "thesis PT s", "ours",
                 "thesis SFT / PT time", "ours", "ours: relMSE guided / PT (same spp)"],
        kinds=["thesis", "ours"] * 4 + ["ours"], rows=rows, label_header="image size (thesis / ours)")


#: Tables 8.1/8.2 by our scene: ``{scene: (table, thesis scene, {spp: times})}`` (:func:`equal_time_thesis`).
THESIS_TABLES = {scene: equal_time_thesis(scene, "dof") for table in EQUAL_TIME_TABLES
                 for scene in table_scene(table).scenes}
#: Tables 6.2/6.3 by our scene: ``{scene: (table, thesis scene, {image side: (spp, SFT s, PT s)})}``.
THESIS_GUIDING_TABLES = {scene: guiding_thesis(scene) for table in GUIDING_TABLES for scene in table_scene(table).scenes}


__all__ = ["GUIDING_COLUMNS", "THESIS_GUIDING_TABLES", "THESIS_SHAPE", "THESIS_TABLES",
           "THESIS_TIMES", "equal_time_thesis", "guiding_table", "guiding_thesis", "table_6_1", "thesis_guiding_times",
           "thesis_table_6_1", "thesis_times"]
