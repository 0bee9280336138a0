"""What a suite runs: a TOML suite file, or the built-in ``standard`` suite at a scale (issue 36).

A suite is an experiment whose cells are equal-time comparisons
(:mod:`sparselt.experiments.compare`), one per scene; this module reads and
checks its description. The file::

    [suite]
    name = "my-suite"
    methods = ["pt", "oidn", "aaf-dof", "aaf-dof:width_scale=0.5"]   # variants as in compare
    spp = [16, 64]
    seeds = [1, 2, 3]
    timing_repeats = 3
    reference_spp = "auto"          # or a number
    resolution = [256, 256]          # default for every scene

    [[scene]]
    name = "checker-dof"
    scene = "scenes/checker.xml"     # a built-in name, or a path relative to this file
    kind = "dof"
    shape = [256, 256, 8, 8]
    aperture = 0.15

Every key is checked before anything renders: an unknown key, a missing
scene file, a kind a method cannot run are refused with the file, the line
and the key (:class:`SuiteError`).
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import tomllib
from dataclasses import dataclass, field

from ..rendering.layout import KINDS, default_shape
from .compare import ComparisonConfig, validate_config

#: The keys of ``[suite]`` and what each holds (types checked by :func:`read_suite`).
SUITE_KEYS = {
    "name": "the suite's name (letters, digits, '-', '_', '.')",
    "methods": "list of method names or variants METHOD:NAME=VALUE",
    "spp": "list of budgets in samples per pixel",
    "seeds": "list of seeds (default [1, 2, 3])",
    "timing_repeats": "runs of every cell; its time is the median (default 3)",
    "reference_spp": "reference samples per pixel, or \"auto\" (default \"auto\")",
    "reference_minutes": "the reference's rendering time limit per scene, in minutes (default 10 with auto)",
    "resolution": "[width, height] of every scene (default: each scene file's film)",
    "max_depth": "longest path of every scene (default 3)",
    "pt_ladder_max_spp": "the largest spp of PT's ladder (default 4096)",
    "options": "methods' options: {method or \"*\" = {option = value}}",
    "description": "free text",
}
#: The keys of each ``[[scene]]``.
SCENE_KEYS = {
    "name": "the scene's name in the suite (letters, digits, '-', '_', '.'; unique)",
    "scene": "a built-in scene name, or a Mitsuba XML file relative to the suite file",
    "kind": f"signal kind: one of {', '.join(KINDS)}",
    "shape": "signal grid of the kind (default: the resolution, then the kind's default cells)",
    "aperture": "thin-lens aperture radius (overrides the camera's)",
    "focus_distance": "thin-lens focus distance",
    "max_depth": "longest path (overrides the suite's)",
    "resolution": "[width, height] (overrides the suite's)",
    "parameters": "the XML file's $name parameters: {name = value} (-D name=value)",
    "methods": "this scene's methods (overrides the suite's)",
    "reason": "why the scene is in the suite (free text)",
}
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.\-]*")
#: ``reference_spp`` when the reference grows until its floor is small against the judged errors.
AUTO = "auto"


class SuiteError(ValueError):
    """A suite file or configuration sparselt refuses; the message names the file, line and key."""


@dataclass(frozen=True)
class SuiteScene:
    """One scene of a suite: everything its comparison needs beyond the suite's settings.

    Attributes
    ----------
    name : str
        The scene's name in the suite (its folder ``scenes/NAME``).
    scene : str
        Built-in scene name, or the absolute path of a Mitsuba XML file.
    kind : str
    shape, resolution : tuple of int or None
    aperture, focus_distance : float or None
    max_depth : int or None
    parameters : tuple of (str, str)
    methods : tuple of str or None
        This scene's methods; None: the suite's.
    reason : str
    """

    name: str
    scene: str
    kind: str
    shape: tuple | None = None
    aperture: float | None = None
    focus_distance: float | None = None
    max_depth: int | None = None
    resolution: tuple | None = None
    parameters: tuple = ()
    methods: tuple | None = None
    reason: str = ""


@dataclass(frozen=True)
class SuiteConfig:
    """A suite: its settings and its scenes (see the module docstring for the file's keys).

    Attributes
    ----------
    name : str
    methods, spps, seeds : tuple
    scenes : tuple of SuiteScene
    timing_repeats : int
    reference_spp : int or 'auto'
    reference_minutes : float or None
    resolution : tuple of int or None
    max_depth : int
    pt_ladder_max_spp : int
    options : dict
    source : str
        Where it came from: the suite file's path, or ``standard:SCALE``.
    """

    name: str
    methods: tuple
    spps: tuple
    scenes: tuple
    seeds: tuple = (1, 2, 3)
    timing_repeats: int = 3
    reference_spp: int | str = AUTO
    reference_minutes: float | None = None
    resolution: tuple | None = None
    max_depth: int = 3
    pt_ladder_max_spp: int = 4096
    options: dict = field(default_factory=dict)
    description: str = ""
    source: str = ""

    def comparison(self, scene):
        """The :class:`~sparselt.experiments.compare.ComparisonConfig` of ``scene`` (a :class:`SuiteScene`)."""
        resolution = scene.resolution or self.resolution
        max_depth = scene.max_depth if scene.max_depth is not None else self.max_depth
        shape = scene.shape
        if shape is None and resolution is not None:
            shape = suite_shape(scene.kind, max_depth, tuple(resolution))
        return ComparisonConfig(
            scene=scene.scene, kind=scene.kind, shape=None if shape is None else tuple(shape),
            methods=tuple(scene.methods or self.methods), spps=tuple(self.spps), seeds=tuple(self.seeds),
            resolution=None if resolution is None else tuple(resolution), reference_spp=self.reference_spp,
            reference_minutes=self.reference_minutes, max_depth=max_depth, aperture=scene.aperture,
            focus_distance=scene.focus_distance, options=self.options, timing_repeats=self.timing_repeats,
            pt_ladder_max_spp=self.pt_ladder_max_spp, scene_parameters=tuple(sorted(scene.parameters)))

    def record(self):
        """JSON-able description (the suite's identity and ``suite.json``)."""
        record = dataclasses.asdict(self)
        record["scenes"] = [dataclasses.asdict(scene) for scene in self.scenes]
        return record


#: The most cells a suite's default grid has (a float32 signal of 1 GiB); a scene's own ``shape`` may have more.
MAXIMUM_DEFAULT_CELLS = 2**28


def suite_shape(kind, max_depth, resolution):
    """A scene's grid when the suite gives none: the resolution, then the kind's default cells per axis
    (:func:`~sparselt.rendering.layout.default_shape`), halved until the grid has at most
    :data:`MAXIMUM_DEFAULT_CELLS` cells (down to one cell per axis).

    A path kind at depth 3 has eight path-vertex axes: 256x256 pixels at the default 4 cells per axis would be
    4.3e9 cells, more than a grid may hold; 2 per axis gives 1.7e7.

    Examples
    --------
    >>> suite_shape("dof", 3, (256, 256))
    (256, 256, 16, 16)
    >>> suite_shape("path", 3, (256, 256))
    (256, 256, 2, 2, 2, 2, 2, 2, 2, 2)
    """
    shape = default_shape(kind, max_depth, resolution)
    image, cells = shape[:2], shape[2:]
    size = cells[0] if cells else 1
    while size > 1 and math.prod(image) * size ** len(cells) > MAXIMUM_DEFAULT_CELLS:
        size //= 2
    return tuple(image) + (size,) * len(cells)


# --------------------------------------------------------------------------------------------- reading a file
class _Lines:
    """Where each table and key of a TOML file is, for error messages (``tomllib`` keeps no positions)."""

    HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
    KEY = re.compile(r"^\s*([A-Za-z0-9_\-\"'.]+)\s*=")

    def __init__(self, path, text):
        self.path = path
        self.tables = []  # (header name, array index or None, first line number, {key: line})
        current = ("", None, 1, {})
        self.tables.append(current)
        counts = {}
        for number, line in enumerate(text.splitlines(), start=1):
            header = self.HEADER.match(line)
            if header:
                name = header.group(2).strip().strip('"')
                index = None
                if header.group(1) == "[[":
                    index = counts.get(name, 0)
                    counts[name] = index + 1
                current = (name, index, number, {})
                self.tables.append(current)
                continue
            key = self.KEY.match(line)
            if key:
                current[3].setdefault(key.group(1).strip("\"'").split(".")[0], number)

    def line(self, table, index=None, key=None):
        """The line of ``key`` in table ``table`` (its ``index``-th for an array of tables), else the table's."""
        for name, position, first, keys in self.tables:
            if name == table and position == index:
                return keys.get(key, first) if key is not None else first
        return 1

    def error(self, message, table, index=None, key=None):
        where = f"{self.path}:{self.line(table, index, key)}"
        if key is not None:
            place = f"[suite] {key!r}" if table == "suite" else f"[[scene]] #{index + 1} {key!r}"
            return SuiteError(f"{where}: {place}: {message}")
        return SuiteError(f"{where}: {message}")


def _check_type(lines, value, expected, table, index, key, what):
    if isinstance(value, bool) or not isinstance(value, expected):
        raise lines.error(f"expected {what}, got {value!r}", table, index, key)
    return value


def _integer_list(lines, value, table, index, key, what, length=None):
    _check_type(lines, value, list, table, index, key, f"a list of {what}")
    if not value or any(isinstance(item, bool) or not isinstance(item, int) for item in value):
        raise lines.error(f"expected a non-empty list of whole numbers ({what}), got {value!r}", table, index, key)
    if length is not None and len(value) != length:
        raise lines.error(f"expected {length} numbers ({what}), got {value!r}", table, index, key)
    return tuple(value)


def _string_list(lines, value, table, index, key, what):
    if not isinstance(value, list) or not value or not all(isinstance(item, str) for item in value):
        raise lines.error(f"expected a non-empty list of {what}, got {value!r}", table, index, key)
    return tuple(value)


def _number(lines, value, table, index, key, what):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise lines.error(f"expected a positive number ({what}), got {value!r}", table, index, key)
    return float(value)


def _name(lines, value, table, index, key):
    _check_type(lines, value, str, table, index, key, "text")
    if not NAME_PATTERN.fullmatch(value):
        raise lines.error(f"{value!r} is not a name (letters, digits, '-', '_', '.'; starting with a letter or "
                          "digit): it names a folder", table, index, key)
    return value


def _unknown_keys(lines, table, allowed, index, section):
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        listing = "; ".join(f"{key} ({what})" for key, what in allowed.items())
        raise lines.error(f"unknown key {unknown[0]!r}; {section} takes: {listing}", section.strip("[]"), index,
                          unknown[0])


def read_suite(path):
    """Read and check a suite file (see the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        A TOML file; scene files are resolved relative to its folder.

    Returns
    -------
    SuiteConfig

    Raises
    ------
    SuiteError
        A file that is not TOML, an unknown or missing key, a value of the
        wrong type, a scene file that does not exist, two scenes of one name,
        or a scene whose comparison ``compare`` would refuse (a method that
        cannot run its kind, a bad shape): the message names the file, the
        line and the key.
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as handle:
            content = handle.read()
    except FileNotFoundError:
        raise SuiteError(f"suite file {path!r} does not exist") from None
    except IsADirectoryError:
        raise SuiteError(f"suite file {path!r} is a folder, not a TOML file") from None
    text = content.decode("utf-8", errors="replace")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SuiteError(f"{path}: not a valid TOML file ({error})") from None
    lines = _Lines(path, text)
    unknown = sorted(set(data) - {"suite", "scene"})
    if unknown:
        raise lines.error(f"unknown table {unknown[0]!r}; a suite file has [suite] and [[scene]] tables",
                          unknown[0] if isinstance(data[unknown[0]], dict) else "")
    suite = data.get("suite")
    if not isinstance(suite, dict):
        raise SuiteError(f"{path}: no [suite] table (it names the suite, its methods and budgets)")
    _unknown_keys(lines, suite, SUITE_KEYS, None, "[suite]")
    for key in ("name", "methods", "spp"):
        if key not in suite:
            raise lines.error(f"[suite] needs {key!r} ({SUITE_KEYS[key]})", "suite")
    settings = {"name": _name(lines, suite["name"], "suite", None, "name"),
                "methods": _string_list(lines, suite["methods"], "suite", None, "methods", "method names"),
                "spps": _integer_list(lines, suite["spp"], "suite", None, "spp", "samples per pixel")}
    if "seeds" in suite:
        settings["seeds"] = _integer_list(lines, suite["seeds"], "suite", None, "seeds", "seeds")
    if "timing_repeats" in suite:
        settings["timing_repeats"] = _check_type(lines, suite["timing_repeats"], int, "suite", None,
                                                 "timing_repeats", "a whole number")
    if "reference_spp" in suite:
        value = suite["reference_spp"]
        if value != AUTO and (isinstance(value, bool) or not isinstance(value, int)):
            raise lines.error(f"expected a whole number of samples per pixel or \"auto\", got {value!r}", "suite",
                              None, "reference_spp")
        settings["reference_spp"] = value
    if "reference_minutes" in suite:
        settings["reference_minutes"] = _number(lines, suite["reference_minutes"], "suite", None,
                                                "reference_minutes", "minutes")
    if "resolution" in suite:
        settings["resolution"] = _integer_list(lines, suite["resolution"], "suite", None, "resolution",
                                               "width, height", length=2)
    for key in ("max_depth", "pt_ladder_max_spp"):
        if key in suite:
            settings[key] = _check_type(lines, suite[key], int, "suite", None, key, "a whole number")
    if "options" in suite:
        options = suite["options"]
        if not isinstance(options, dict) or not all(isinstance(values, dict) for values in options.values()):
            raise lines.error("expected a table of tables: options.METHOD.NAME = VALUE (or options.\"*\".NAME)",
                              "suite", None, "options")
        settings["options"] = {method: dict(values) for method, values in options.items()}
    if "description" in suite:
        settings["description"] = _check_type(lines, suite["description"], str, "suite", None, "description",
                                              "text")
    entries = data.get("scene")
    if not isinstance(entries, list) or not entries:
        raise SuiteError(f"{path}: no [[scene]] tables (each names a scene and its kind)")
    folder = os.path.dirname(os.path.abspath(path))
    scenes = []
    for index, entry in enumerate(entries):
        scenes.append(_read_scene(lines, entry, index, folder))
    config = SuiteConfig(scenes=tuple(scenes), source=os.path.abspath(path), **settings)
    validate_suite(config, lines=lines)
    return config


def _read_scene(lines, entry, index, folder):
    from ..rendering.scenes import scene_names

    _unknown_keys(lines, entry, SCENE_KEYS, index, "[[scene]]")
    for key in ("name", "scene", "kind"):
        if key not in entry:
            raise lines.error(f"[[scene]] needs {key!r} ({SCENE_KEYS[key]})", "scene", index)
    values = {"name": _name(lines, entry["name"], "scene", index, "name")}
    scene = _check_type(lines, entry["scene"], str, "scene", index, "scene", "a built-in scene name or a file")
    if scene not in scene_names():
        resolved = scene if os.path.isabs(scene) else os.path.join(folder, scene)
        if not os.path.isfile(resolved):
            raise lines.error(f"{scene!r} is neither a built-in scene ({', '.join(scene_names())}) nor a file "
                              f"({resolved!r} does not exist)", "scene", index, "scene")
        scene = os.path.normpath(resolved)
    values["scene"] = scene
    kind = _check_type(lines, entry["kind"], str, "scene", index, "kind", "a kind")
    if kind not in KINDS:
        raise lines.error(f"kind {kind!r} is not one of {', '.join(KINDS)}", "scene", index, "kind")
    values["kind"] = kind
    if "shape" in entry:
        values["shape"] = _integer_list(lines, entry["shape"], "scene", index, "shape", "cells per axis")
    if "resolution" in entry:
        values["resolution"] = _integer_list(lines, entry["resolution"], "scene", index, "resolution",
                                             "width, height", length=2)
    for key in ("aperture", "focus_distance"):
        if key in entry:
            values[key] = _number(lines, entry[key], "scene", index, key, SCENE_KEYS[key])
    if "max_depth" in entry:
        values["max_depth"] = _check_type(lines, entry["max_depth"], int, "scene", index, "max_depth",
                                          "a whole number")
    if "parameters" in entry:
        parameters = entry["parameters"]
        if not isinstance(parameters, dict) or not all(
                isinstance(value, (str, int, float)) and not isinstance(value, bool) for value in parameters.values()):
            raise lines.error(f"expected a table of name = value (text or numbers), got {parameters!r}", "scene",
                              index, "parameters")
        values["parameters"] = tuple(sorted((str(name), str(value)) for name, value in parameters.items()))
    if "methods" in entry:
        values["methods"] = _string_list(lines, entry["methods"], "scene", index, "methods", "method names")
    if "reason" in entry:
        values["reason"] = _check_type(lines, entry["reason"], str, "scene", index, "reason", "text")
    return SuiteScene(**values)


def validate_suite(config, *, lines=None):
    """Check every scene's comparison as ``compare`` would, before anything renders.

    Parameters
    ----------
    config : SuiteConfig
    lines : _Lines, optional
        The suite file's positions (errors then name its line and key).

    Returns
    -------
    dict
        ``{scene name: SceneSetup}``: every scene's resolved setup.

    Raises
    ------
    SuiteError
        Two scenes of one name, or a comparison ``compare`` refuses; the
        message names the scene (and the file's line and key).
    """

    def error(message, index, key):
        if lines is not None:
            return lines.error(message, "scene", index, key)
        scene = config.scenes[index].name
        return SuiteError(f"suite {config.name!r}, scene {scene!r}, {key!r}: {message}")

    if not config.scenes:
        raise SuiteError(f"suite {config.name!r} has no scenes")
    seen = {}
    for index, scene in enumerate(config.scenes):
        if scene.name in seen:
            raise error(f"scene name {scene.name!r} is used twice (scenes #{seen[scene.name] + 1} and "
                        f"#{index + 1}); each scene's folder is scenes/NAME", index, "name")
        seen[scene.name] = index
    setups = {}
    for index, scene in enumerate(config.scenes):
        comparison = config.comparison(scene)
        try:
            setups[scene.name], _ = validate_config(comparison, with_methods=True)
        except (ValueError, TypeError) as problem:
            message = str(problem)
            rows = comparison.methods
            key = "methods" if any(row in message for row in rows) else "scene"
            if key == "methods" and scene.methods is None and lines is not None:
                raise lines.error(f"scene {scene.name!r} (kind {scene.kind}): {message}", "suite", None,
                                  "methods") from None
            candidates = ("shape", "resolution", "aperture", "focus_distance", "max_depth", "kind", "parameters")
            for candidate in () if key == "methods" else candidates:
                if candidate.replace("_", " ") in message.lower() and (
                        getattr(scene, candidate, None) not in (None, ())):
                    key = candidate
                    break
            raise error(message, index, key) from None
    return setups
