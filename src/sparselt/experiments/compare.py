"""Equal-time comparison of rendering methods (``sparselt compare``; thesis chapters 6 and 8).

The research question of the thesis's applications: *is there a gain in image
quality for the same computation time?* (8.1.1). :func:`compare` runs every
requested method of the registry (:mod:`sparselt.methods`) at every budget and
seed on one scene, in one process, kernels warmed first and each budget run
once untimed before it is timed (:class:`~sparselt.experiments.comparison_cells.CellRunner`),
and measures each image against a path-traced reference.

Output folder (an :class:`~sparselt.storage.folder.ExperimentFolder`)::

    sparselt-folder.json    the folder's manifest: identity (configuration with defaults
                            explicit, scene content digest), files written, status, and
                            every command that contributed (versions, git revision)
    compare.json            resolved configuration (the union of methods, budgets and
                            seeds over reruns), every method's record (description, roles,
                            source, resolved options), warm-up times (compiles and untimed budget runs), harness overhead
    results.csv             one row per (method, spp, seed): RESULT_COLUMNS first
    cells/                  one JSON record per finished (method, spp, seed), with the
                            method's resolved options: what a rerun resumes from
    repeats/                each cell's timing repeats so far (the rounds of CellRunner):
                            a run interrupted between rounds resumes from them
    images/                 EXR + PNG + npy per method, spp and seed, and the reference
    quality_vs_time.png     SSIM and relMSE against seconds (Figures 8.1/8.3)
    image_grid.png          every method at matched time (Figures 8.2/8.4, 8.7/8.9)
    error_maps.png          their per-pixel relative squared error, one false-colour scale for all
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

import dataclasses
import time
from dataclasses import asdict, dataclass, field
from functools import cached_property

import numpy as np

from ..analysis.metrics import (
    reference_exposure,
)
from ..checks import check_integer, check_positive_finite
from ..methods import ComparisonContext, MethodSetup, baseline_name, get_method
from ..methods.variants import parse_method_variant
from ..provenance import environment_record
from ..rendering.baseline import (
    METHOD_SEED_LIMIT,
    REFERENCE_SEED_LIMIT,
    check_wavefront,
    reference_cache_directory,
)
from ..rendering.layout import KINDS
from ..rendering.setup import DEFAULT_MAX_DEPTH, DEFAULT_VARIANT, SceneSetup
from ..storage.cache import usable_cache_directory
from ..report.comparison import results_table, write_comparison_outputs
from ..report.comparison_rows import EXTRA_COLUMNS, RESULT_COLUMNS, in_comparison_order
from ..results import COMPARISON_KIND  # the folder load_comparison reads
from ..results import CONFIGURATION_FILE as CONFIG_FILE
from .comparison_cells import IMAGES, CellRunner, cell_name
from .comparison_reference import AUTO, ComparisonReference, remeasure_cells
from .equal_time import (
    bias_record,
    fit_record,
    judge,
)
from .protocol import Experiment, run_experiment
from .quality import RELMSE_EPSILON, caustic_mask

# What makes two comparisons the same: everything but the lists a rerun may extend and the reference's budget
# (a rerun with a longer reference measures every cell again against it).
EXTENSIBLE = ("methods", "spps", "seeds")
REFERENCE_BUDGET = ("reference_spp", "reference_minutes")
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
    reference_spp : int or 'auto'
        Samples per pixel of the reference (Mitsuba ``path``, in 64-spp
        passes, cached and resumable). ``'auto'`` starts from
        :data:`AUTO_INITIAL_SPP` and adds passes until the reference's floor
        is at most :data:`AUTO_FLOOR_SHARE` of the smallest debiased headline
        relMSE among the cells it judges (every method's at the run's budgets,
        PT's too), or ``reference_minutes`` run out.
    reference_minutes : float or None
        The reference's rendering time limit in minutes (passes already
        cached cost nothing); default :data:`AUTO_DEFAULT_MINUTES` with
        ``'auto'``, none with a number.
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
        Runs of every cell; its time is their median (see :class:`CellRunner`).
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
    shape: tuple | None = None
    methods: tuple = ("pt", "cosamp")
    spps: tuple = (40, 81, 163)
    seeds: tuple = (1, 2, 3)
    resolution: tuple | None = None
    reference_spp: int | str = 4096
    reference_seed: int = 0
    reference_minutes: float | None = None
    max_depth: int = DEFAULT_MAX_DEPTH
    aperture: float | None = None
    focus_distance: float | None = None
    options: dict = field(default_factory=dict)
    timing_repeats: int = 3
    pt_ladder_max_spp: int = 4096
    caustic_mask: bool = False
    variant: str = DEFAULT_VARIANT
    scene_parameters: tuple = ()

    def __post_init__(self):
        if self.shape is None:  # the film's resolution and the kind's default on the other axes, recorded as such
            object.__setattr__(self, "shape", self.setup.grid_shape)

    @cached_property  # resolved once per configuration: its scene, identity and loading share it
    def setup(self):
        """The comparison's :class:`~sparselt.rendering.setup.SceneSetup`: scene, parameters, lens, kind, grid."""
        return SceneSetup(scene=self.scene, kind=self.kind, shape=self.shape, max_depth=self.max_depth,
                          parameters=self.scene_parameters, aperture=self.aperture,
                          focus_distance=self.focus_distance, variant=self.variant)

    @property
    def output_resolution(self):
        return tuple(self.resolution) if self.resolution is not None else tuple(self.shape[:2])

    def resolved_options(self):
        """``{row: MethodOptions}`` of every method of the run (a row is a method name or a variant as written).

        Raises
        ------
        ValueError
            Options for a method name that is not registered, a ``'*'``
            option no registered method declares, a malformed variant, or an
            option a method does not declare or whose value it refuses (the
            message names ``method.option`` and what is allowed).
        TypeError
            ``options`` is not a mapping of mappings, or a value has the wrong type.
        """
        return {row: method.options for row, method in self.comparison_methods().items()}

    def comparison_methods(self, rows=None):
        """``{row: Method}``: the estimator of every row of ``rows`` (default :attr:`methods`), its options
        resolved (:func:`comparison_methods`)."""
        return comparison_methods(self.methods if rows is None else rows, self.options, self.shape)

    def record(self):
        record = asdict(self)
        for name in ("shape", "methods", "spps", "seeds"):
            record[name] = list(record[name])
        record["scene_parameters"] = [list(pair) for pair in self.scene_parameters]
        record["resolution"] = list(self.output_resolution)
        record["options"] = {method: dict(values) for method, values in sorted(self.options.items())}
        return record

    def identity(self, methods=None):
        """What makes two comparisons the same: the record without the lists a rerun may extend, and
        every row's options resolved (``method_options``, by row: a method name or a variant as written).

        Stating a default (``--option cosamp.gamma=0.25``) is the same
        comparison as leaving it out. ``method_options`` may grow (a rerun
        may add methods); a method already in the folder must come back with
        the same options (:class:`~sparselt.storage.folder.ExperimentFolder`'s
        ``growable`` identity keys). ``methods`` (``{row: Method}``, from
        :meth:`comparison_methods`) saves resolving the options again.
        """
        methods = self.comparison_methods() if methods is None else methods
        record = {key: value for key, value in self.record().items()
                  if key not in EXTENSIBLE + REFERENCE_BUDGET + ("options",)}
        record["method_options"] = {row: methods[row].options.record() for row in self.methods}
        return record


def comparison_methods(rows, options, grid_shape):
    """``{row: Method}`` for the rows of a comparison: the one resolution of their options.

    Parameters
    ----------
    rows : sequence of str
        Method names or variants ``METHOD:NAME=VALUE[:NAME=VALUE...]``
        (:func:`~sparselt.methods.variants.parse_method_variant`).
    options : dict
        ``{method or '*': {name: value}}``. A row's options, lowest
        precedence first: the defaults, ``'*'`` (for every row whose method
        declares the option), its method's entry (every row of that method),
        the variant's own values.
    grid_shape : tuple of int
        The signal grid (derived defaults and bounds).

    Options for a registered method that is not in this run, and ``'*'``
    options that no method of this run declares, are not used (a rerun with
    fewer methods keeps the same options); a method name that is not
    registered, or a ``'*'`` option no registered method declares, is a
    typo and refused.

    Raises
    ------
    ValueError, TypeError
        As :meth:`ComparisonConfig.resolved_options`.
    """
    from ..methods import method_class, method_names

    if not isinstance(options, dict) or not all(isinstance(values, dict) for values in options.values()):
        raise TypeError(f"options must map a method name (or '*') to {{option: value}}, got {options!r}")
    for name in options:
        if name != "*":
            method_class(name)  # an unknown name is refused, listing the registered ones
    everywhere = {key.replace("-", "_"): value for key, value in options.get("*", {}).items()}
    declared_anywhere = {item.name for name in method_names() for item in method_class(name).Options.declared()}
    unknown = sorted(set(everywhere) - declared_anywhere)
    if unknown:
        raise ValueError(f"option '*.{unknown[0]}' is declared by no registered method ('sparselt methods NAME' lists "
                         "a method's options)")
    methods = {}
    for row in rows:
        name, _ = parse_method_variant(row)
        declared = {item.name for item in method_class(name).Options.declared()}
        given = {key: value for key, value in everywhere.items() if key in declared}
        given.update(options.get(name, {}))
        methods[row] = get_method(row, grid_shape=tuple(grid_shape), options=given)
    return methods


def resolve_run_options(methods, options, grid_shape):
    """``{row: MethodOptions}`` for the rows ``methods`` (see :func:`comparison_methods`)."""
    return {row: method.options for row, method in comparison_methods(methods, options, grid_shape).items()}


@dataclass
class ComparisonResult:
    """Rows of ``results.csv`` (dicts), the paths written, and every method's record (roles, options)."""

    rows: list
    out: str
    reference: dict = field(default_factory=dict)
    overhead_fraction: float = 0.0
    methods: dict = field(default_factory=dict)
    summary: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)

    def table(self):
        return results_table(self.rows)


def validate_config(config, *, with_methods=False):
    """Check everything that needs no renderer; raise ValueError naming the bad value.

    Every row's options are resolved here, once (:func:`comparison_methods`),
    and every method's declared preconditions checked
    (:meth:`~sparselt.methods.base.Method.check_preconditions`; those on the
    camera of a scene file wait for it to load, :func:`check_preconditions`).

    Returns
    -------
    setup : SceneSetup
    methods : dict
        With ``with_methods``: ``{row: Method}`` of every row and of the
        baseline (PT's ladder), in that order.
    """
    if config.kind not in KINDS:
        raise ValueError(f"compare supports kinds {', '.join(KINDS)}; got {config.kind!r}")
    if not config.methods:
        raise ValueError("give at least one method")
    if len(set(config.methods)) != len(config.methods):
        raise ValueError(f"methods {list(config.methods)} repeat a name")
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
    setup = config.setup.validate()  # kind, depth, shape, scene, parameters, lens: before anything else
    resolution = config.output_resolution
    if len(resolution) != 2:
        raise ValueError(f"resolution takes width,height; got {resolution}")
    for size in resolution:
        check_integer("resolution", size, 1)
    baseline = baseline_name()
    methods = config.comparison_methods(tuple(config.methods) + ((baseline,) if baseline not in config.methods
                                                                  else ()))  # every option, checked once
    _check_distinct(methods)
    spec = setup.spec  # a built-in scene's camera is known before it loads; a scene file's after (compare())
    camera = spec.resolved_camera() if spec.camera is not None else None
    check_preconditions(methods, MethodSetup(kind=config.kind, grid_shape=tuple(config.shape),
                                             resolution=resolution, spps=tuple(config.spps),
                                             thin_lens=None if camera is None else bool(camera.thin_lens)))
    check_wavefront(resolution, max(max(config.spps), config.pt_ladder_max_spp))
    if config.reference_spp != AUTO:
        check_reference_spp(resolution, config.reference_spp)
    if config.reference_minutes is not None:
        check_positive_finite(config.reference_minutes, "reference minutes",
                              hint="the reference's rendering time limit, e.g. 10")
    if min(resolution) < 11:
        raise ValueError(f"resolution {resolution} is too small for SSIM (at least 11x11 pixels)")
    return (setup, methods) if with_methods else setup


def check_preconditions(methods, setup):
    """Every method's declared preconditions against ``setup`` (a :class:`~sparselt.methods.MethodSetup`).

    Raises
    ------
    ValueError
        The first one not met, naming the method's row and the fix.
    """
    for method in methods.values():
        method.check_preconditions(setup)


def _check_distinct(methods):
    """Refuse two rows that are one estimator (one method, the same resolved options: ``cosamp`` and
    ``cosamp:gamma=0.25``)."""
    seen = {}
    for row, method in methods.items():
        key = (method.name, tuple(sorted(method.options.record().items())))
        if key in seen:
            raise ValueError(f"methods {seen[key]!r} and {row!r} are the same estimator (method {method.name!r} with "
                             f"the same options {method.options.record()}); give each once")
        seen[key] = row


def check_reference_spp(resolution, spp):
    """Refuse a reference that would run for days: an estimate and a bound, before any work."""
    if isinstance(spp, str):
        raise ValueError(f"reference spp must be a number of samples per pixel or {AUTO!r}, got {spp!r}")
    check_integer("reference spp", spp, 1, MAXIMUM_REFERENCE_SPP)
    samples = resolution[0] * resolution[1] * spp
    if samples > MAXIMUM_REFERENCE_SAMPLES:
        raise ValueError(f"a reference of {resolution[0]}x{resolution[1]} pixels at {spp} spp is {samples:.3g} path "
                         f"samples, about {samples / REFERENCE_SAMPLES_PER_SECOND / 3600:.3g} hours at "
                         f"~{REFERENCE_SAMPLES_PER_SECOND / 1e6:.0f} M samples/s; at most "
                         f"{MAXIMUM_REFERENCE_SAMPLES:.3g} samples (reference spp <= "
                         f"{MAXIMUM_REFERENCE_SAMPLES // (resolution[0] * resolution[1])} at this resolution)")





def compare(config, out, *, overwrite=False, progress=True, cache_directory=None, scheduler=None):
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
    scheduler : str, optional
        A Dask scheduler's address: the reference's missing passes render on
        its workers, with the same bytes as in-process (each pass is a
        function of its seed; the passes are averaged in their order).

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
    return run_experiment(ComparisonExperiment(config, cache_directory=cache_directory, scheduler=scheduler), out,
                          overwrite=overwrite, progress=progress)


@dataclass(frozen=True)
class _LoadedComparison:
    """What :meth:`ComparisonExperiment.prepare` loads once: the method context and the scene's load time."""

    context: ComparisonContext
    load_seconds: float


class ComparisonExperiment(Experiment):
    """``sparselt compare`` as an experiment of the protocol (:mod:`sparselt.experiments.protocol`).

    Its cells are the (row, spp, seed) cells of :class:`CellRunner`, timed
    ``timing_repeats`` times in rounds over every cell (so it overrides
    :meth:`run_cells`), after the reference; its report is every output of
    :func:`~sparselt.report.comparison.write_comparison_outputs` and ``compare.json``.
    """

    kind = COMPARISON_KIND
    growable = ("method_options",)

    def __init__(self, config, *, cache_directory=None, scheduler=None):
        self.config = config
        self.cache_directory = cache_directory
        self.scheduler = scheduler
        self.started = time.perf_counter()
        self.setup = self.methods = self._identity = None
        self.seconds = {}

    def validate(self):
        self.setup, self.methods = validate_config(self.config, with_methods=True)  # {row: Method}, PT's included
        self._identity = self.config.identity(self.methods)

    def identity(self):
        return self._identity

    def scene_identity(self):
        return self.setup.scene_identity

    def prepare(self):
        """Check the reference's cache (one that cannot be used stops the run before anything is written), load the
        scene once and check every method's preconditions again, now that a scene file's camera is known: before
        the reference renders."""
        config = self.config
        usable_cache_directory(self.cache_directory or reference_cache_directory())
        load_start = time.perf_counter()
        scene = self.setup.load(config.output_resolution)
        load_seconds = time.perf_counter() - load_start
        context = ComparisonContext(scene=scene.scene, layout=scene.layout, kind=config.kind,
                                    grid_shape=tuple(config.shape), resolution=config.output_resolution,
                                    max_depth=config.max_depth)
        check_preconditions(self.methods, MethodSetup.of_context(context, spps=tuple(config.spps)))
        return _LoadedComparison(context=context, load_seconds=load_seconds)

    def run_cells(self, folder, state, *, progress):
        """The reference (cached), then every cell in rounds and PT's ladder; returns ``compare.json``'s record."""

        config, methods, loaded = self.config, self.methods, state.context.scene
        record = folder.read_json(CONFIG_FILE) if folder.exists(CONFIG_FILE) else {}
        resolved = dict(config.record(), identity=self._identity)
        for name in EXTENSIBLE:  # a rerun may add methods, budgets or seeds: record the union
            earlier = record.get("config", {}).get(name, [])
            resolved[name] = list(dict.fromkeys(list(earlier) + resolved[name]))
        record["config"] = resolved
        record["provenance"] = environment_record()  # this command's; the manifest keeps every command's
        record["methods"] = dict(record.get("methods", {}), **{
            row: method_record(method) for row, method in methods.items()})
        record.setdefault("warm_up_seconds", {})
        record["relmse_epsilon"] = RELMSE_EPSILON
        record["hide_emitters"] = self.setup.spec.hide_emitters
        record["status"] = "running"
        folder.write_json(CONFIG_FILE, record)

        reference_start = time.perf_counter()
        reference = ComparisonReference(config, self.setup, cache_directory=self.cache_directory,
                                        scheduler=self.scheduler)
        measure = reference.start(loaded, progress)
        self.seconds["reference"] = time.perf_counter() - reference_start
        exposure = reference_exposure(measure.image)
        folder.write_image(f"{IMAGES}/reference", measure.image, exposure=exposure)
        if config.caustic_mask:
            mask = caustic_mask(loaded, measure.image, spp=min(measure.spp, 1024), max_depth=config.max_depth,
                                seed=config.reference_seed)
            folder.write_png(f"{IMAGES}/caustic_mask.png", np.repeat(mask[..., None], 3, axis=2).astype(np.float32))
            record["caustic_mask_pixels"] = int(mask.sum())
            reference.measure = measure = dataclasses.replace(measure, mask=mask)

        runner = CellRunner(folder, state.context, config, lambda image: reference.measure(image), exposure, progress,
                            rows_so_far=tuple(record["config"]["methods"]))
        outcome = runner.run_all(list(methods.values()), methods[baseline_name()])
        remeasured = remeasure_cells(folder, reference.measure)
        if config.reference_spp == AUTO:
            reference_start = time.perf_counter()
            record["reference_target"] = reference.converge(folder, loaded, record["config"], progress)
            self.seconds["reference"] += time.perf_counter() - reference_start
            folder.write_image(f"{IMAGES}/reference", reference.measure.image, exposure=exposure)  # the longer one
        self.measure = reference.measure
        record["reference"] = self.measure.summary()
        record["reference"]["cells_measured_again"] = remeasured + record.get("reference_target", {}).get(
            "cells_measured_again", 0)
        record["reference_relmse_floor"] = self.measure.floor
        record["warm_up_seconds"].update(outcome.warm_up_seconds)
        if outcome.ladder is not None:
            record["pt_ladder"] = outcome.ladder
        self.seconds["methods"] = outcome.method_seconds
        self.seconds["metrics"] = outcome.metric_seconds
        return record

    def report(self, folder, state, record):
        """Equal-time columns and summary, every table and figure, and ``compare.json`` completed."""
        config, baseline = self.config, baseline_name()
        rows = _load_rows(folder, [baseline] + record["config"]["methods"])

        def image_of(row):
            return np.load(folder.path_of(f"{IMAGES}/{cell_name(row['method'], row['spp'], row['seed'])}.npy"))

        variance, degrees = self.measure.bias_test_variance()
        record["bias"] = bias_record(rows, image_of, self.measure.image, variance, degrees)
        fit, summary = judge(rows, baseline=baseline, reference_spp=self.measure.spp, bias=record["bias"])
        record["pt_fit"] = fit_record(fit)
        report_start = time.perf_counter()
        write_comparison_outputs(folder, rows, self.measure.image, config, self.setup.spec.name, methods=record["methods"],
                                 summary=summary, fit=fit, epsilon=RELMSE_EPSILON,
                                 image_of=image_of, provenance=environment_record(), columns=RESULT_COLUMNS + EXTRA_COLUMNS)
        report_seconds = time.perf_counter() - report_start
        total = time.perf_counter() - self.started
        harness = max(0.0, total - self.seconds["methods"] - self.seconds["reference"])
        record["status"] = "complete"
        record["seconds"] = {"total": total, "methods": self.seconds["methods"], "reference": self.seconds["reference"],
                             "harness": harness, "of_which_scene_load": state.load_seconds,
                             "of_which_reports": report_seconds, "of_which_metrics": self.seconds["metrics"]}
        record["harness_overhead_fraction"] = harness / total if total > 0 else 0.0
        folder.write_json(CONFIG_FILE, record)
        return ComparisonResult(rows=rows, out=folder.path, reference=record["reference"],
                                overhead_fraction=record["harness_overhead_fraction"], methods=record["methods"],
                                summary=summary, seconds=record["seconds"])

    def summary(self, result):
        return {"seconds": result.seconds}


def method_record(method):
    """What ``compare.json`` and the reports know of a row's method: description, roles, source, resolved options
    (and, for a variant, the method it is a variant of: ``method``)."""
    from ..methods.registry import method_source

    record = dict(description=method.description, source=method_source(method.name),
                  options=method.options.record(), **method.roles())
    if method.label != method.name:
        record["method"] = method.name
    return record


def _load_rows(folder, methods):
    """Every finished cell in the folder: this run's and those of earlier runs of the same comparison."""
    return in_comparison_order([record["row"] for record in folder.cells().values()], methods)
