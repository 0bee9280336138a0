"""The one interface every equal-time comparison method implements (thesis 8.1.1).

A method is an estimator with its options: an instance of a :class:`Method`
subclass carries its resolved options (:attr:`Method.options`), so two
variants of one method (``cosamp`` at gamma 0.25 and 0.5) are two instances
side by side in one comparison. It gets the comparison's
:class:`ComparisonContext` (scene loaded in the renderer, signal grid, output
resolution), a budget (samples per pixel and a seed) and the harness's
:class:`PhaseTimer`, and returns a :class:`MethodResult`: the image, the path
samples drawn and its details; its seconds are the timer's
(:func:`run_timed`). What a method needs of the comparison (a thin lens, a
tile that divides the grid, ...) it declares (:attr:`Method.requires`,
:mod:`sparselt.methods.preconditions`), and the harness checks it before
anything renders. :func:`sparselt.experiments.compare.compare` runs methods
from the registry in :mod:`sparselt.methods`; new methods (filters, guiding,
the SFT) plug in by subclassing :class:`Method` and registering, without
touching the harness.
"""

from __future__ import annotations

import dataclasses
import gc
from dataclasses import dataclass, field

import numpy as np

from .. import measurement
from ..rendering.baseline import METHOD_SEED_LIMIT
from .options import MethodOptions, declared_options, resolve_options

TIME_PHASES = ("sampling", "reconstruction", "integration", "other")
#: The seed of every warm-up run: the first seed a comparison refuses for its runs (they are below
#: :data:`~sparselt.rendering.baseline.METHOD_SEED_LIMIT`), so a warm-up never replays a cell's samples. It is
#: small enough that a method's seed arithmetic on it (``seed + 7919``, ``seed ^ 0x5A5A5A5A``) stays below
#: ``2**32``; the renderer folds any larger non-negative seed to 32 bits anyway.
WARM_UP_SEED = METHOD_SEED_LIMIT


@dataclass(frozen=True)
class Budget:
    """What a method may spend: ``spp`` path samples per output pixel, with ``seed``."""

    spp: int
    seed: int


@dataclass(frozen=True)
class MethodResult:
    """What one method produced at one budget.

    Attributes
    ----------
    image : ndarray, shape (height, width, 3), float32
        Linear RGB at the comparison's output resolution.
    path_samples : int
        Path samples drawn (every one counted, pilot samples included).
    details : dict
        Anything else worth recording (iterations, stop reason, ...), JSON-able.
    seconds : dict or None
        Wall seconds per phase, keys :data:`TIME_PHASES`; their sum is the
        method's total time. A method leaves it out: :func:`run_timed` fills
        it from the :class:`PhaseTimer` the method timed its phases in.
    """

    image: np.ndarray
    path_samples: int
    details: dict = field(default_factory=dict)
    seconds: dict | None = None

    @property
    def total_seconds(self):
        return float(sum(self.seconds.values()))


@dataclass
class ComparisonContext:
    """Everything a method needs besides its budget (its options are its own: :attr:`Method.options`).

    Attributes
    ----------
    scene : MitsubaScene
        The scene loaded at the output resolution (renderer adapter object).
    layout : PathLayout
        PSS layout of the signal kind.
    kind : str
        Signal kind ('dof', 'indirect', 'path').
    grid_shape : tuple of int
        Signal grid, image axes ``(width, height)`` first.
    resolution : tuple of int
        Output image ``(width, height)``.
    max_depth : int
        Longest path (Mitsuba's convention).
    """

    scene: object
    layout: object
    kind: str
    grid_shape: tuple
    resolution: tuple
    max_depth: int

    @property
    def upscale(self):
        """Output pixels per grid cell along ``(x, y)``."""
        return (self.resolution[0] // self.grid_shape[0], self.resolution[1] // self.grid_shape[1])


class PhaseTimer(measurement.PhaseTimer):
    """:class:`sparselt.measurement.PhaseTimer` over the comparison's phases, :data:`TIME_PHASES`."""

    def __init__(self, phases=TIME_PHASES):
        super().__init__(phases)


class Method:
    """Base class of comparison methods: an estimator and its resolved options.

    Subclasses set :attr:`name`, :attr:`kinds` (signal kinds they support; the
    harness refuses others before anything runs), :attr:`description`, and
    implement :meth:`run`. Optional attributes:

    ``Options``
        A frozen :class:`~sparselt.methods.options.MethodOptions` dataclass
        declaring the method's options (default: none). An instance carries
        its resolved options as :attr:`options`.
    ``requires``
        What the method needs of the comparison, beyond its kinds: a tuple of
        :class:`~sparselt.methods.preconditions.Requirement` (a thin lens, a
        tile option that divides the grid, the scene's film resolution, a
        least spp). The harness checks every requirement before anything
        renders (:meth:`check_preconditions`).
    ``needs_resolution_multiple``
        The output resolution must be a multiple of the grid's image axes
        (a requirement too).
    ``baseline``
        The method every other is compared with at equal time (``pt``; one
        registered method at most).
    ``family``
        What kind of method it is, for the reports: ``'path tracing'``,
        ``'cosamp'`` (the CoSaMP image methods of thesis 8.1, beside Tables
        8.1/8.2), ``'ablation'``, ``'filter'``, ``'denoiser'``, ``'guided'``
        (importance sampling from a map, beside Tables 6.2/6.3), ``'sft'``,
        or any other word for a plug-in.
    ``thesis_procedure``
        The method is a procedure of the thesis, as the thesis describes it
        (rather than a baseline or our own variant).

    Parameters
    ----------
    options : MethodOptions or mapping, optional
        Resolved options (an instance of :attr:`Options`), or ``{name:
        value}`` resolved here through the one validation,
        :func:`~sparselt.methods.options.resolve_options` (default: every
        option at its default).
    grid_shape : tuple of int, optional
        The comparison's grid: needed to resolve a mapping when an option's
        default or bound depends on the grid (``K = N / 200``).
    label : str, optional
        The row this instance is in a comparison (a variant's text as
        written, ``'cosamp:gamma=0.5'``); default :attr:`name`.

    Raises
    ------
    ValueError, TypeError
        Options the method refuses (the message names ``method.option`` and
        what is allowed), or a grid-dependent option without ``grid_shape``.
    """

    name = ""
    kinds = ()
    description = ""
    Options = MethodOptions
    requires = ()
    needs_resolution_multiple = False
    baseline = False
    family = "other"
    thesis_procedure = False

    warm_up_spp = 1

    def __init__(self, options=None, *, grid_shape=None, label=None):
        if not isinstance(options, self.Options):
            given = {} if options is None else options
            if not isinstance(given, dict):
                raise TypeError(f"method {self.name!r} takes options as {self.Options.__name__} or a mapping of "
                                f"option name to value, got {type(options).__name__}")
            if grid_shape is None:
                grid_bound = [item.name for item in declared_options(self.Options)
                              if item.derive is not None or callable(item.maximum)]
                if grid_bound:
                    raise TypeError(f"method {self.name!r}: option {grid_bound[0]!r} depends on the grid; give "
                                    "grid_shape to resolve its options")
                grid_shape = ()
            options = resolve_options(self.Options, given, grid_shape=tuple(grid_shape), owner=self.name)
        self.options = options
        self.label = self.name if label is None else str(label)

    def __repr__(self):
        return f"{type(self).__name__}({self.options!r}, label={self.label!r})"

    @classmethod
    def roles(cls):
        """What the reports need to know of the method: ``{baseline, family, thesis_procedure}``."""
        return {"baseline": bool(cls.baseline), "family": str(cls.family),
                "thesis_procedure": bool(cls.thesis_procedure)}

    @classmethod
    def requirements(cls):
        """Every declared precondition: the kinds, the resolution multiple when needed, then :attr:`requires`."""
        from .preconditions import ResolutionMultiple, SupportedKind

        return ((SupportedKind(),) + ((ResolutionMultiple(),) if cls.needs_resolution_multiple else ())
                + tuple(cls.requires))

    def check_preconditions(self, setup):
        """Refuse a comparison this method cannot run in, before anything renders.

        Parameters
        ----------
        setup : MethodSetup
            What is known of the comparison
            (:class:`~sparselt.methods.preconditions.MethodSetup`): before the
            scene loads, its camera may be unknown (checked again after).

        Raises
        ------
        ValueError
            The first requirement not met; the message names the method (its
            row), what it needs and how to give it.
        """
        for requirement in self.requirements():
            requirement.check(self, setup)

    def warm_up(self, context):
        """Compile the renderer's kernels: one run at :attr:`warm_up_spp`, result discarded."""
        self.run(context, Budget(spp=self.warm_up_spp, seed=WARM_UP_SEED), PhaseTimer())

    def run(self, context, budget, timer):  # pragma: no cover - interface
        """Render ``context`` at ``budget``, timing every phase in ``timer``; return a :class:`MethodResult`."""
        raise NotImplementedError


def warm_up(method, context):
    """Compile ``method``'s kernels for ``context`` (:meth:`Method.warm_up`) after freeing what is garbage.

    Dr.Jit writes the live instances of a Mitsuba plugin class (every BSDF,
    every emitter) into the code of a kernel that calls them, so freeing a
    scene changes the kernels of every other scene. Measured: a comparison
    on a scene file, then ``aaf-indirect`` on cornell-box in the same
    process, compiled two kernels inside its first timed run because the
    first scene was collected between the warm-up and the run. Collecting
    first makes the warm-up's kernels the ones the runs use; the harness
    collects the young generations before each run's clock starts
    (:func:`collect_recent_garbage`), and :func:`run_timed` keeps the
    collector off inside the run.
    """
    gc.collect()
    method.warm_up(context)


def collect_recent_garbage():
    """Free the garbage of the runs before a timed run, before its clock starts: the collector's young generations.

    :func:`run_timed` keeps the collector off, so what a run allocated is
    young until the harness collects; the old generation holds the
    process's long-lived objects (modules, the renderer's plugins, figures'
    caches). A full collection scans them all: measured 0.13 s per call on
    a comparison's heap (350k objects; ``reproduce --chapter 8 --scale
    tiny`` spent 22 of its 42 s in 162 full collections), about a run's own
    time at small budgets. The full collection :func:`warm_up` makes once
    per method frees a scene dropped before it (the case that changes
    kernels). Checked on two comparisons (9 methods, the path and indirect
    kinds) and ``reproduce``'s chapter 8: a full collection right after the
    young one found only numba's compiler garbage (llvmlite's IR, after a
    kernel compiled), never an array.
    """
    gc.collect(1)


def run_timed(method, context, budget):
    """Run ``method`` at ``budget`` with a fresh :class:`PhaseTimer`: the result carries the timer's seconds.

    What the harness (and the contract) call; a method's result leaves
    :attr:`MethodResult.seconds` out.

    Raises
    ------
    ValueError
        The method returned a result with its own seconds (it must time its
        phases in the timer it was given).
    """
    timer = PhaseTimer()
    collecting = gc.isenabled()
    gc.disable()  # as timeit: no collection pause inside a timed run
    try:
        result = method.run(context, budget, timer)
    finally:
        if collecting:
            gc.enable()
    if not isinstance(result, MethodResult):
        return result  # check_result names it
    if result.seconds is not None:
        raise ValueError(f"method {method.label!r} returned MethodResult(seconds=...); a method times its phases in "
                         "the timer run(context, budget, timer) receives, and the harness takes them from it")
    return dataclasses.replace(result, seconds=dict(timer.seconds))
