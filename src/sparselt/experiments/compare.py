"""Equal-time comparison of rendering methods (``sparselt compare``; thesis chapters 6 and 8).

The research question of the thesis's applications: *is there a gain in image
quality for the same computation time?* (8.1.1). :func:`compare` runs every
requested method of the registry (:mod:`sparselt.methods`) at every budget and
seed on one scene, in one process, kernels warmed first, and measures each
image against a path-traced reference.

Output folder (an :class:`~sparselt.storage.folder.ExperimentFolder`)::

    sparselt-folder.json    the folder's manifest: identity (configuration with defaults
                            explicit, scene content digest), files written, status, and
                            every command that contributed (versions, git revision)
    compare.json            resolved configuration (the union of methods, budgets and
                            seeds over reruns), every method's record (description, roles,
                            source, resolved options), warm-up (compile) times, harness overhead
    results.csv             one row per (method, spp, seed): RESULT_COLUMNS first
    cells/                  one JSON record per finished (method, spp, seed), with the
                            method's resolved options: what a rerun resumes from
    repeats/                each cell's timing repeats so far (the rounds of _CellRunner):
                            a run interrupted between rounds resumes from them
    images/                 EXR + PNG + npy per method, spp and seed, and the reference
    quality_vs_time.png     SSIM and relMSE against seconds (Figures 8.1/8.3)
    image_grid.png          every method at matched time (Figures 8.2/8.4, 8.7/8.9)
    crop_grid.png           detail crops where the methods differ most, at matched time
    table_8.md, .csv        time per phase (Tables 8.1/8.2), thesis numbers beside
    equal_time.md, .csv     relMSE and SSIM of each method over PT's at the same time
    table_6.md              guided methods: Tables 6.2/6.3 layout (image size, spp, guided and PT time)
    methods.md, .csv        every method's family, role, source and resolved options
    index.html              the report page

Every file is written atomically and listed in the manifest; a rerun with the
same comparison skips the finished cells, and may add methods, budgets or
seeds. A folder holding another comparison (other settings, or the scene's
files changed) is refused, naming what differs, unless ``overwrite``; a folder
holding files sparselt did not write is always refused.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ..analysis.metrics import (
    contrast_ratio,
    flip_error,
    image_ssim,
    luminance_ratio,
    reference_exposure,
    relative_mean_squared_error,
)
from ..checks import check_integer
from ..images import luminance
from ..methods import TIME_PHASES, Budget, ComparisonContext, baseline_name, get_method, resolve_options
from ..methods.contract import check_result
from ..provenance import environment_record
from ..rendering import mitsuba_backend
from ..rendering.baseline import METHOD_SEED_LIMIT, REFERENCE_SEED_LIMIT, check_wavefront, reference_relmse_floor
from ..rendering.identity import scene_identity
from ..rendering.layout import path_layout
from ..rendering.scenes import SceneSpec, get_scene
from ..report.comparison import results_table, write_comparison_outputs
from ..report.comparison_rows import EXTRA_COLUMNS, RESULT_COLUMNS
from ..storage.folder import ExperimentFolder
from .equal_time import NOISY_TIMING_RATIO, add_equal_time_columns, summarize

KINDS = ("dof", "indirect", "path", "path-indirect")
RELMSE_EPSILON = 0.01
CONFIG_FILE = "compare.json"
IMAGES = "images"
# What makes two comparisons the same: everything but the lists a rerun may extend.
EXTENSIBLE = ("methods", "spps", "seeds")
#: Bounds checked before any work: a reference beyond them would run for days (2-core machine, ~5 M samples/s).
MAXIMUM_REFERENCE_SPP = 2**24
MAXIMUM_REFERENCE_SAMPLES = 2**40
REFERENCE_SAMPLES_PER_SECOND = 5e6


@dataclass(frozen=True)
class ComparisonConfig:
    """What :func:`compare` runs.

    Attributes
    ----------
    scene : str
        Built-in scene name or Mitsuba XML file.
    kind : {'dof', 'indirect', 'path', 'path-indirect'}
        Signal kind whose integral the methods render.
    shape : tuple of int
        Signal grid of the kind (image axes first), as in ``sparselt sample``.
    methods : tuple of str
        Registered method names (built-in or plug-in).
    spps : tuple of int
        Budgets: path samples per output pixel.
    seeds : tuple of int
        Seeds; every (method, spp) runs once per seed.
    resolution : tuple of int or None
        Output ``(width, height)``; default the shape's image axes.
    reference_spp : int
        Samples per pixel of the reference (Mitsuba ``path``).
    reference_seed : int
        Seed of the reference (independent of the methods' seeds).
    max_depth : int
        Longest path (Mitsuba's convention).
    aperture, focus_distance : float or None
        Thin-lens override of the scene's camera.
    options : dict
        The methods' options: ``{method name: {option name: value}}``; the
        key ``'*'`` sets an option for every method of the run that
        declares it (a method's own entry wins). Values may be text (from a
        command line). Each method declares its options, defaults and
        ranges (``sparselt methods NAME``); :meth:`resolved_options` checks
        them all before anything runs.
    timing_repeats : int
        Runs of every cell; its time is their median (see :class:`_CellRunner`).
    pt_ladder_max_spp : int
        The largest spp of PT's automatic ladder (a row whose time it does
        not reach has no equal-time value, and says so).
    caustic_mask : bool
        Also report ``relmse_caustic``: relMSE inside :func:`caustic_mask`.
    variant : str
        Mitsuba variant.
    scene_parameters : tuple of (str, str)
        Values of a scene file's ``$name`` parameters (``-D name=value``), sorted.
    """

    scene: str
    kind: str
    shape: tuple
    methods: tuple = ("pt", "cosamp")
    spps: tuple = (40, 81, 163)
    seeds: tuple = (1, 2, 3)
    resolution: tuple | None = None
    reference_spp: int = 4096
    reference_seed: int = 0
    max_depth: int = 3
    aperture: float | None = None
    focus_distance: float | None = None
    options: dict = field(default_factory=dict)
    timing_repeats: int = 3
    pt_ladder_max_spp: int = 4096
    caustic_mask: bool = False
    variant: str = "llvm_ad_rgb"
    scene_parameters: tuple = ()

    @property
    def output_resolution(self):
        return tuple(self.resolution) if self.resolution is not None else tuple(self.shape[:2])

    def resolved_options(self):
        """``{method: MethodOptions}`` of every method of the run: the one validation of their options.

        Raises
        ------
        ValueError
            Options for a method name that is not registered, a ``'*'``
            option no registered method declares, or an option a method does
            not declare or whose value it refuses (the message names
            ``method.option`` and what is allowed).
        TypeError
            ``options`` is not a mapping of mappings, or a value has the wrong type.
        """
        return resolve_run_options(self.methods, self.options, self.shape)

    def record(self):
        record = asdict(self)
        for name in ("shape", "methods", "spps", "seeds"):
            record[name] = list(record[name])
        record["scene_parameters"] = [list(pair) for pair in self.scene_parameters]
        record["resolution"] = list(self.output_resolution)
        record["options"] = {method: dict(values) for method, values in sorted(self.options.items())}
        return record

    def identity(self):
        """What makes two comparisons the same: the record without the lists a rerun may extend, and
        every method's options resolved (``method_options``).

        Stating a default (``--option cosamp.gamma=0.25``) is the same
        comparison as leaving it out. ``method_options`` may grow (a rerun
        may add methods); a method already in the folder must come back with
        the same options (:class:`~sparselt.storage.folder.ExperimentFolder`'s
        ``growable`` identity keys).
        """
        record = {key: value for key, value in self.record().items() if key not in EXTENSIBLE + ("options",)}
        record["method_options"] = {name: options.record() for name, options in self.resolved_options().items()}
        return record


def resolve_run_options(methods, options, grid_shape):
    """``{method: MethodOptions}`` for ``methods`` from ``{method or '*': {name: value}}`` (see
    :meth:`ComparisonConfig.resolved_options`).

    Options for a registered method that is not in this run, and ``'*'``
    options that no method of this run declares, are not used (a rerun with
    fewer methods keeps the same options); a method name that is not
    registered, or a ``'*'`` option no registered method declares, is a
    typo and refused.
    """
    from ..methods import method_names

    if not isinstance(options, dict) or not all(isinstance(values, dict) for values in options.values()):
        raise TypeError(f"options must map a method name (or '*') to {{option: value}}, got {options!r}")
    for name in options:
        if name != "*":
            get_method(name)  # an unknown name is refused, listing the registered ones
    everywhere = {key.replace("-", "_"): value for key, value in options.get("*", {}).items()}
    declared_anywhere = {item.name for name in method_names() for item in get_method(name).Options.declared()}
    unknown = sorted(set(everywhere) - declared_anywhere)
    if unknown:
        raise ValueError(f"option '*.{unknown[0]}' is declared by no registered method ('sparselt methods NAME' lists "
                         "a method's options)")
    resolved = {}
    for name in methods:
        method = get_method(name)
        declared = {item.name for item in method.Options.declared()}
        given = {key: value for key, value in everywhere.items() if key in declared}
        given.update(options.get(name, {}))
        resolved[name] = resolve_options(method.Options, given, grid_shape=tuple(grid_shape), owner=name)
    return resolved


@dataclass
class ComparisonResult:
    """Rows of ``results.csv`` (dicts), the paths written, and every method's record (roles, options)."""

    rows: list
    out: str
    reference: dict = field(default_factory=dict)
    overhead_fraction: float = 0.0
    methods: dict = field(default_factory=dict)
    summary: list = field(default_factory=list)

    def table(self):
        return results_table(self.rows)


def validate_config(config):
    """Check everything that needs no renderer; raise ValueError naming the bad value."""
    if config.kind not in KINDS:
        raise ValueError(f"compare supports kinds {', '.join(KINDS)}; got {config.kind!r}")
    if not config.methods:
        raise ValueError("give at least one method")
    if len(set(config.methods)) != len(config.methods):
        raise ValueError(f"methods {list(config.methods)} repeat a name")
    methods = [get_method(name) for name in config.methods]
    for method in methods:
        if config.kind not in method.kinds:
            raise ValueError(f"method {method.name!r} does not support kind {config.kind!r}; it supports "
                             f"{', '.join(method.kinds)}")
    if not config.spps:
        raise ValueError("give at least one spp")
    for spp in config.spps:
        check_integer("spp", spp, 1, 2**16 - 1)
    if not config.seeds:
        raise ValueError("give at least one seed")
    for seed in config.seeds:
        check_integer("seed", seed, 0, METHOD_SEED_LIMIT - 1)  # above it: the reference's passes
    check_integer("timing repeats", config.timing_repeats, 1, 100)
    check_integer("PT ladder max spp", config.pt_ladder_max_spp, 2, 2**16 - 1)
    check_integer("reference seed", config.reference_seed, 0, REFERENCE_SEED_LIMIT - 1)
    check_integer("max_depth", config.max_depth, 1)
    if len(config.shape) < 2:
        raise ValueError(f"shape {tuple(config.shape)} needs at least the two image axes")
    for size in config.shape:
        check_integer("every shape entry", size, 1)
    if math.prod(config.shape) >= 2**32:
        raise ValueError(f"shape {tuple(config.shape)} has more than 2**32 - 1 cells")
    resolution = config.output_resolution
    if len(resolution) != 2:
        raise ValueError(f"resolution takes width,height; got {resolution}")
    for size in resolution:
        check_integer("resolution", size, 1)
    for method in methods:
        if method.needs_resolution_multiple and any(r % s for r, s in zip(resolution, config.shape[:2])):
            raise ValueError(f"method {method.name!r} needs --resolution to be a multiple of the shape's image axes "
                             f"{tuple(config.shape[:2])}; got {resolution}")
    config.resolved_options()  # every method's options, checked before anything runs
    check_wavefront(resolution, max(max(config.spps), config.pt_ladder_max_spp))
    check_reference_spp(resolution, config.reference_spp)
    if min(resolution) < 11:
        raise ValueError(f"resolution {resolution} is too small for SSIM (at least 11x11 pixels)")
    spec = get_scene(config.scene).with_parameters(config.scene_parameters).with_lens(config.aperture, config.focus_distance)
    if spec.camera is not None:
        _check_layout(config, spec.resolved_camera().thin_lens, spec.hide_emitters)
    return spec


def check_reference_spp(resolution, spp):
    """Refuse a reference that would run for days: an estimate and a bound, before any work."""
    check_integer("reference spp", spp, 1, MAXIMUM_REFERENCE_SPP)
    samples = resolution[0] * resolution[1] * spp
    if samples > MAXIMUM_REFERENCE_SAMPLES:
        raise ValueError(f"a reference of {resolution[0]}x{resolution[1]} pixels at {spp} spp is {samples:.3g} path "
                         f"samples, about {samples / REFERENCE_SAMPLES_PER_SECOND / 3600:.3g} hours at "
                         f"~{REFERENCE_SAMPLES_PER_SECOND / 1e6:.0f} M samples/s; at most "
                         f"{MAXIMUM_REFERENCE_SAMPLES:.3g} samples (reference spp <= "
                         f"{MAXIMUM_REFERENCE_SAMPLES // (resolution[0] * resolution[1])} at this resolution)")


def _check_layout(config, thin_lens, hide_emitters=False):
    layout = path_layout(config.kind, config.max_depth, thin_lens=thin_lens, hide_emitters=hide_emitters)
    if len(config.shape) != len(layout.axes):
        raise ValueError(f"shape {tuple(config.shape)} has {len(config.shape)} axes but kind {config.kind!r} at max "
                         f"depth {config.max_depth} has {len(layout.axes)}: {', '.join(layout.axes)}")
    return layout


def cell_name(method, spp, seed):
    return f"{method}_spp{spp}_seed{seed}"


SPECULAR_BSDFS = ("conductor", "roughconductor", "dielectric", "roughdielectric", "thindielectric", "plastic",
                  "roughplastic")


def _without_specular(value):
    """A scene dictionary whose specular and glossy BSDFs are replaced by a grey diffuse one."""
    if isinstance(value, dict):
        if value.get("type") in SPECULAR_BSDFS:
            return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}
        return {key: _without_specular(item) for key, item in value.items()}
    return value


def caustic_mask(loaded, reference, *, spp, max_depth, seed=0, fraction=0.3):
    """Pixels lit by caustics: where removing every specular BSDF darkens a surface that stays the same.

    The scene is rendered again with its conductors and dielectrics made
    diffuse (no caustic can form) at ``spp``; a pixel is in the mask when the
    surface it sees is unchanged (same albedo in both scenes, so not one of
    the replaced objects) and the caustic-free render is darker than the
    reference by more than ``fraction`` of the reference. Only the reference
    and the two scenes enter it; no method's image does. Built-in scenes
    only (a scene file's BSDFs are not rewritten).
    """
    spec = loaded.spec
    if spec.objects is None:
        raise ValueError("the caustic mask needs a built-in scene (a scene file's materials are not rewritten)")
    plain = SceneSpec(name=spec.name + "-diffuse", description="specular BSDFs made diffuse",
                      objects=_without_specular(spec.objects), camera=spec.camera, lens_overrides=spec.lens_overrides,
                      hide_emitters=spec.hide_emitters)
    other = mitsuba_backend.MitsubaScene(plain, (loaded.width, loaded.height))
    without, _ = other.render_path(spp, max_depth, seed)
    albedo, _ = loaded.render_aovs(16, seed)
    albedo_plain, _ = other.render_aovs(16, seed)
    same_surface = np.abs(luminance(albedo["albedo"]) - luminance(albedo_plain["albedo"])) < 0.02
    level, level_without = luminance(reference), luminance(without)
    return same_surface & (level - level_without > fraction * level) & (level > 0)


def quality(image, reference, mask=None):
    """SSIM (the project's HDR convention), relMSE (epsilon 0.01), HDR-FLIP, luminance and contrast ratios.

    With a boolean ``mask`` (height, width), also ``relmse_caustic``: the
    relMSE over the masked pixels only.
    """
    record = {
        "ssim": image_ssim(image, reference),
        "flip": flip_error(image, reference),
        "relmse": relative_mean_squared_error(image, reference, epsilon=RELMSE_EPSILON),
        "luminance_ratio": luminance_ratio(image, reference),
        "contrast_ratio": contrast_ratio(image, reference),
    }
    if mask is not None:
        record["relmse_caustic"] = (relative_mean_squared_error(image[mask][None], reference[mask][None],
                                                                epsilon=RELMSE_EPSILON) if mask.any() else "")
    return record


def compare(config, out, *, overwrite=False, progress=True, cache_directory=None):
    """Run an equal-time comparison and write its folder (see the module docstring).

    Parameters
    ----------
    config : ComparisonConfig
    out : str
        Output folder. A folder holding the same comparison is resumed
        (finished cells are kept); one holding another comparison is refused
        unless ``overwrite``.
    overwrite : bool, optional
        Replace a folder that holds another comparison: only its listed files
        are removed, and only after the configuration is validated and the
        scene has loaded. A folder with files sparselt did not write is
        refused even so.
    progress : bool, optional
        Progress bars and one line per finished cell on standard error.
    cache_directory : str, optional
        Where reference images are cached (default ``$SPARSELT_CACHE/references``).

    Returns
    -------
    ComparisonResult

    Raises
    ------
    ValueError
        Unknown method (the message lists the registered ones), a method that
        does not support the kind, spp <= 0, a shape that does not match the
        kind, a resolution that is not a multiple of the shape's image axes
        where a method needs it, a reference beyond :data:`MAXIMUM_REFERENCE_SAMPLES`,
        an output folder holding another comparison or foreign files.
        Nothing already computed is touched before these checks pass.
    StoreLockedError
        Another run is writing the folder (the message names it).
    """
    from ..rendering.baseline import cached_reference

    started = time.perf_counter()
    spec = validate_config(config)
    folder = comparison_folder(config, spec, out, overwrite=overwrite)
    folder.inspect()  # refusals before the scene loads; nothing is removed yet

    load_start = time.perf_counter()
    loaded = mitsuba_backend.MitsubaScene(spec, config.output_resolution, variant=config.variant)
    load_seconds = time.perf_counter() - load_start
    layout = _check_layout(config, loaded.camera.thin_lens, spec.hide_emitters)
    context = ComparisonContext(scene=loaded, layout=layout, kind=config.kind, grid_shape=tuple(config.shape),
                                resolution=config.output_resolution, max_depth=config.max_depth)
    baseline = baseline_name()
    names = tuple(config.methods) + ((baseline,) if baseline not in config.methods else ())  # PT's ladder
    methods = [get_method(name) for name in names]  # their kinds were checked by validate_config
    options = resolve_run_options(names, config.options, config.shape)

    with folder.open():
        record = folder.read_json(CONFIG_FILE) if folder.exists(CONFIG_FILE) else {}
        resolved = dict(config.record(), identity=config.identity())
        for name in EXTENSIBLE:  # a rerun may add methods, budgets or seeds: record the union
            earlier = record.get("config", {}).get(name, [])
            resolved[name] = list(dict.fromkeys(list(earlier) + resolved[name]))
        record["config"] = resolved
        record["provenance"] = environment_record()  # this command's; the manifest keeps every command's
        record["methods"] = dict(record.get("methods", {}), **{
            method.name: method_record(method, options[method.name]) for method in methods})
        record.setdefault("warm_up_seconds", {})
        record["relmse_epsilon"] = RELMSE_EPSILON
        record["hide_emitters"] = spec.hide_emitters
        record["status"] = "running"
        folder.write_json(CONFIG_FILE, record)

        reference_start = time.perf_counter()
        reference, reference_record = cached_reference(loaded, config.kind, spp=config.reference_spp,
                                                       max_depth=config.max_depth, seed=config.reference_seed,
                                                       progress=progress, cache_directory=cache_directory)
        reference_seconds = time.perf_counter() - reference_start
        exposure = reference_exposure(reference)
        folder.write_image(f"{IMAGES}/reference", reference, exposure=exposure)
        mask = None
        if config.caustic_mask:
            mask = caustic_mask(loaded, reference, spp=min(config.reference_spp, 1024), max_depth=config.max_depth,
                                seed=config.reference_seed)
            folder.write_png(f"{IMAGES}/caustic_mask.png", np.repeat(mask[..., None], 3, axis=2).astype(np.float32))
            record["caustic_mask_pixels"] = int(mask.sum())
        record["reference"] = {key: reference_record[key] for key in ("key", "seconds", "cached", "path")}
        floor = reference_relmse_floor(reference, reference_record["variance"], epsilon=RELMSE_EPSILON)
        record["reference_relmse_floor"] = floor if math.isfinite(floor) else None

        runner = _CellRunner(folder, context, options, config, reference, mask, exposure, record, progress,
                             floor=record["reference_relmse_floor"])
        ladder = runner.run_all(methods, get_method(baseline))
        if ladder is not None:
            record["pt_ladder"] = ladder
        method_seconds = runner.seconds

        rows = _load_rows(folder, [baseline] + record["config"]["methods"])
        fit = add_equal_time_columns(rows, baseline=baseline)
        summary = summarize(rows, fit, baseline=baseline)
        record["pt_fit"] = None if fit is None else {
            "intercept_seconds": fit.intercept, "seconds_per_spp": fit.slope, "time_relative_residual": fit.time_residual,
            "relmse_per_seed": {str(seed): {"c": c, "floor": floor} for seed, (c, floor) in fit.relmse.items()},
            "spp_range": list(fit.spp_range)}
        report_start = time.perf_counter()
        write_comparison_outputs(folder, rows, reference, config, spec.name, methods=record["methods"],
                                 summary=summary, fit=record["pt_fit"], epsilon=RELMSE_EPSILON,
                                 image_of=lambda row: np.load(folder.path_of(
                                     f"{IMAGES}/{cell_name(row['method'], row['spp'], row['seed'])}.npy")),
                                 provenance=environment_record(), columns=RESULT_COLUMNS + EXTRA_COLUMNS)
        report_seconds = time.perf_counter() - report_start
        total = time.perf_counter() - started
        harness = max(0.0, total - method_seconds - reference_seconds)
        record["status"] = "complete"
        record["seconds"] = {"total": total, "methods": method_seconds, "reference": reference_seconds,
                             "harness": harness, "of_which_scene_load": load_seconds,
                             "of_which_reports": report_seconds, "of_which_metrics": runner.metric_seconds}
        record["harness_overhead_fraction"] = harness / total if total > 0 else 0.0
        folder.write_json(CONFIG_FILE, record)
        folder.complete(seconds=record["seconds"])
    return ComparisonResult(rows=rows, out=folder.path, reference=record["reference"],
                            overhead_fraction=record["harness_overhead_fraction"], methods=record["methods"],
                            summary=summary)


class _CellRunner:
    """Runs a comparison's cells: each (method, spp, seed) ``timing_repeats`` times, in rounds, and PT's ladder.

    A repeat re-runs the whole method with the same budget (a method gives
    the same image for the same seed, which is checked): re-timing the same
    computation would leave out exactly what varies between runs (the
    renderer's launches, allocation, caches). The time of a cell is the
    median of its repeats' totals, its phases those of the median run, and
    min and max are recorded.

    The repeats run in **rounds**, not back to back: round 1 runs every
    method's cells once and then PT's ladder (whose extent follows the
    methods' round-1 times); rounds 2, 3, ... run every cell again, PT's
    rungs included, in reverse order on even rounds. A shared machine's speed
    drifts over minutes (two demo runs measured the methods 16-45% slower
    and PT 10-18% slower in the second: PT, timed last, saw another
    machine); in rounds every cell samples the whole run's conditions, and
    the alternating order cancels a linear drift. Each repeat is recorded
    as it finishes (``repeats/NAME.json``), so an interrupted run resumes
    within a round; a cell enters ``cells/`` only with all its repeats.
    """

    def __init__(self, folder, context, options, config, reference, mask, exposure, record, progress, *, floor):
        self.folder, self.context, self.options, self.config = folder, context, options, config
        self.reference, self.mask, self.exposure, self.record, self.progress = reference, mask, exposure, record, progress
        self.floor = floor  # the reference's relMSE floor, or None when unknown (a one-pass reference)
        self.seconds = 0.0
        self.warm = set()
        self.metric_seconds = 0.0
        self.contexts = {}

    # ----------------------------------------------------------------- the plan
    def run_all(self, methods, baseline):
        """Every cell of ``methods`` (the baseline's at the run's budgets and on its ladder); return the ladder's
        record (or None when there is no other method)."""
        config = self.config
        budgets = [(spp, seed) for seed in config.seeds for spp in config.spps]
        plan = [(method, spp, seed) for method in methods if method.name != baseline.name
                and method.name in config.methods for spp, seed in budgets]
        if baseline.name in config.methods:
            plan += [(baseline, spp, seed) for spp, seed in budgets]
        for method, spp, seed in plan:  # round 1
            self._repeat(method, spp, seed, 1)
        ladder = None
        if any(method.name != baseline.name for method in methods):
            ladder = self._ladder(baseline, lambda spp: [self._repeat(baseline, spp, seed, 1) for seed in config.seeds],
                                  self._other_times(baseline, plan))
            plan += [(baseline, spp, seed) for spp in ladder["spps"] for seed in config.seeds
                     if spp not in config.spps or baseline.name not in config.methods]
        for round_number in range(2, config.timing_repeats + 1):
            if self.progress:
                print(f"compare: timing round {round_number} of {config.timing_repeats} ({len(plan)} cells)",
                      file=sys.stderr)
            for method, spp, seed in (reversed(plan) if round_number % 2 == 0 else plan):
                self._repeat(method, spp, seed, round_number)
        for method, spp, seed in plan:
            self._finish(method, spp, seed)
        if ladder is not None:
            # The medians may have moved from round 1's times: extend the ladder (each new rung with all its
            # repeats) until it covers them again.
            ladder = self._ladder(baseline, lambda spp: [self._finished(baseline, spp, seed) for seed in config.seeds],
                                  self._other_times(baseline, plan), start=ladder["spps"])
        return ladder

    def _ladder(self, baseline, run_rung, others, start=None):
        """PT at spp = s0, 2 s0, 4 s0, ... (s0 below the smallest budget) for every seed, until its time passes
        every other method's time or the cap :attr:`ComparisonConfig.pt_ladder_max_spp`; then s0 / 2, s0 / 4,
        ... down to 1 spp while PT's smallest rung is slower than the fastest method. ``run_rung(spp)`` runs a
        rung and returns its times (one per seed); ``others`` are the other methods' times; ``start`` is a
        ladder already run."""
        config = self.config
        target = max(others, default=0.0)
        fastest = min(others, default=math.inf)
        steps = list(start or [])
        spp = steps[-1] if steps else max(1, min(config.spps) // 2)
        capped = False
        while True:
            reached = float(np.median(run_rung(spp)))
            if spp not in steps:
                steps.append(spp)
            if reached > target and len(steps) >= 2:
                break
            if 2 * spp > config.pt_ladder_max_spp:
                capped = True
                break
            spp *= 2
        # Downwards too, while a method is faster than PT's smallest rung: nothing is extrapolated at either end.
        steps.sort()
        spp = steps[0]
        lowest = float(np.median(run_rung(spp)))
        while spp > 1 and lowest > fastest:
            spp //= 2
            steps.insert(0, spp)
            lowest = float(np.median(run_rung(spp)))  # every rung listed is run (1 spp was once listed unrun)
        return {"spps": steps, "target_seconds": target, "reached_seconds": reached, "capped": capped,
                "max_spp": config.pt_ladder_max_spp, "fastest_seconds": fastest}

    def _other_times(self, baseline, plan):
        """The times of every other method's cell: this run's plan and those an earlier run of the folder
        finished (its union of budgets), which the ladder must cover too."""
        times = {cell_name(method.name, spp, seed): self._time(method.name, spp, seed)
                 for method, spp, seed in plan if method.name != baseline.name}
        for name, done in self.folder.cells().items():
            if done["row"]["method"] != baseline.name and done["row"]["method"] in self.record["config"]["methods"]:
                times.setdefault(name, done["row"]["seconds_total"])
        return list(times.values())

    # ----------------------------------------------------------------- one cell
    def _context(self, method):
        if method.name not in self.contexts:
            self.contexts[method.name] = self.context.with_options(self.options[method.name])
        return self.contexts[method.name]

    def _repeats(self, name):
        path = f"repeats/{name}.json"
        return self.folder.read_json(path) if self.folder.exists(path) else None

    def _time(self, method_name, spp, seed):
        """The cell's time so far: the median of its repeats (the finished cell's time when it is done)."""
        name = cell_name(method_name, spp, seed)
        done = self.folder.cell(name)
        if done is not None:
            return done["row"]["seconds_total"]
        return float(np.median(self._repeats(name)["totals"]))

    def _repeat(self, method, spp, seed, round_number):
        """Run repeat ``round_number`` of a cell unless it is done; return the cell's time so far."""
        name = cell_name(method.name, spp, seed)
        done = self.folder.cell(name) is not None
        partial = None if done else self._repeats(name)
        if done or (partial is not None and len(partial["totals"]) >= round_number):
            return self._time(method.name, spp, seed)
        context = self._context(method)
        if method.name not in self.warm:
            warm_start = time.perf_counter()
            method.warm_up(context)
            self.record["warm_up_seconds"][method.name] = time.perf_counter() - warm_start
            self.seconds += self.record["warm_up_seconds"][method.name]
            self.warm.add(method.name)
        budget = Budget(spp=spp, seed=seed)
        run_start = time.perf_counter()
        result = method.run(context, budget)
        wall = time.perf_counter() - run_start
        self.seconds += wall
        seconds = check_result(method, result, context, budget, wall_seconds=wall)
        if partial is None:
            metrics_start = time.perf_counter()
            row = _row(method.name, spp, seed, result, seconds, self.reference, self.mask)
            self.metric_seconds += time.perf_counter() - metrics_start  # harness time, never a method's
            self.folder.write_image(f"{IMAGES}/{name}", result.image, exposure=self.exposure)
            partial = {"row": row, "details": result.details, "phases": [], "totals": [], "wall_seconds": [],
                       "repeat_image_difference": 0.0}
            if self.progress:
                print(f"compare: {method.name:18s} spp {spp:5d} seed {seed}: {row['seconds_total']:7.3f} s "
                      f"(repeat 1 of {self.config.timing_repeats}), SSIM {row['ssim']:.3f}, relMSE "
                      f"{row['relmse']:.4g}, luminance x{row['luminance_ratio']:.3f}", file=sys.stderr)
        else:
            first = np.load(self.folder.path_of(f"{IMAGES}/{name}.npy"))
            scale = float(np.abs(first).max()) or 1.0
            difference = float(np.abs(result.image.astype(np.float64) - first).max()) / scale
            # Atomic accumulation (the global guided mode splats samples into pixels from many threads) sums in
            # another order each run: equal to float32 rounding, not bitwise. Anything larger is a breach.
            if difference > 1e-4:
                raise ValueError(f"method {method.name!r} gave another image when run again with the same seed "
                                 f"({seed}) at spp {spp} (largest difference {difference:.2g} of the image's "
                                 "maximum): a method must be a function of its budget")
            partial["repeat_image_difference"] = max(partial["repeat_image_difference"], difference)
        partial["phases"].append(seconds)
        partial["totals"].append(sum(seconds.values()))
        partial["wall_seconds"].append(wall)
        self.folder.write_json(f"repeats/{name}.json", partial)
        return float(np.median(partial["totals"]))

    def _finished(self, method, spp, seed):
        """Run a cell's remaining repeats back to back (a rung added after the rounds), finish it; its time."""
        for round_number in range(1, self.config.timing_repeats + 1):
            self._repeat(method, spp, seed, round_number)
        return self._finish(method, spp, seed)

    def _finish(self, method, spp, seed):
        """Record a cell whose repeats are all in: median time, min, max, the median run's phases."""
        name = cell_name(method.name, spp, seed)
        done = self.folder.cell(name)
        if done is not None:
            return done["row"]["seconds_total"]
        partial = self._repeats(name)
        totals = partial["totals"]
        median = sorted(range(len(totals)), key=totals.__getitem__)[len(totals) // 2]
        seconds = partial["phases"][median]
        row = dict(partial["row"], **{f"seconds_{phase}": seconds[phase] for phase in TIME_PHASES})
        if self.floor is not None:
            row.update(reference_relmse_floor=self.floor, relmse_debiased=row["relmse"] - self.floor,
                       reference_limited=bool(row["relmse"] < 2 * self.floor))
        row.update(seconds_total=float(np.median(totals)), seconds_total_min=min(totals),
                   seconds_total_max=max(totals), timing_repeats=len(totals),
                   timing_noisy=bool(max(totals) > NOISY_TIMING_RATIO * min(totals)))
        self.folder.record_cell(name, {"row": row, "details": partial["details"], "seconds": seconds,
                                       "repeat_totals": totals,
                                       "repeat_image_difference": partial["repeat_image_difference"],
                                       "options": self.options[method.name].record(),
                                       "wall_seconds": partial["wall_seconds"]})
        return row["seconds_total"]


def method_record(method, options):
    """What ``compare.json`` and the reports know of a method: description, roles, source, resolved options."""
    from ..methods.registry import method_source

    return dict(description=method.description, source=method_source(method.name), options=options.record(),
                **method.roles())


def comparison_folder(config, spec, out, *, overwrite=False):
    """The :class:`~sparselt.storage.folder.ExperimentFolder` of a comparison: its identity is the configuration
    (defaults explicit, without the lists a rerun may extend) and the scene's content identity."""
    return ExperimentFolder(out, kind="compare", identity=config.identity(), scene=scene_identity(spec),
                            overwrite=overwrite, growable=("method_options",))


def _row(name, spp, seed, result, seconds, reference, mask=None):
    row = {"method": name, "spp": spp, "seed": seed, "seconds_total": sum(seconds.values())}
    row.update({f"seconds_{phase}": seconds[phase] for phase in TIME_PHASES})
    row["path_samples"] = int(result.path_samples)
    row.update(quality(result.image, reference, mask))
    return row


def _load_rows(folder, methods):
    """Every finished cell in the folder: this run's and those of earlier runs of the same comparison."""
    rows = [record["row"] for record in folder.cells().values()]
    order = {name: index for index, name in enumerate(methods)}
    rows.sort(key=lambda row: (order.get(row["method"], len(order)), row["method"], row["seed"], row["spp"]))
    return rows
