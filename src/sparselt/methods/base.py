"""The one interface every equal-time comparison method implements (thesis 8.1.1).

A method gets a budget (samples per pixel and a seed) and the comparison's
:class:`ComparisonContext` (scene loaded in the renderer, signal grid, output
resolution, options) and returns a :class:`MethodResult`: the image and where
its time went. :func:`sparselt.experiments.compare.compare` runs methods from
the registry in :mod:`sparselt.methods`; new methods (filters, guiding, the
SFT) plug in by subclassing :class:`Method` and registering, without touching
the harness.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .. import measurement
from .options import MethodOptions, resolve_options

TIME_PHASES = ("sampling", "reconstruction", "integration", "other")
WARM_UP_SEED = 0xFFFF_FFFF  # never a comparison seed (those are < 2**32 - 1)


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
    seconds : dict
        Wall seconds per phase, keys :data:`TIME_PHASES`; their sum is the
        method's total time.
    path_samples : int
        Path samples drawn (every one counted, pilot samples included).
    details : dict
        Anything else worth recording (iterations, stop reason, ...), JSON-able.
    """

    image: np.ndarray
    seconds: dict
    path_samples: int
    details: dict = field(default_factory=dict)

    @property
    def total_seconds(self):
        return float(sum(self.seconds.values()))


@dataclass
class ComparisonContext:
    """Everything a method needs besides its budget.

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
    options : MethodOptions
        The running method's options, typed and resolved
        (:class:`~sparselt.methods.options.MethodOptions`): the harness gives
        each method a context carrying its own (:meth:`with_options`).
    """

    scene: object
    layout: object
    kind: str
    grid_shape: tuple
    resolution: tuple
    max_depth: int
    options: MethodOptions = field(default_factory=MethodOptions)

    def with_options(self, options):
        """This context carrying ``options`` (a method's resolved :class:`MethodOptions`)."""
        return dataclasses.replace(self, options=options)

    @property
    def upscale(self):
        """Output pixels per grid cell along ``(x, y)``."""
        return (self.resolution[0] // self.grid_shape[0], self.resolution[1] // self.grid_shape[1])


class PhaseTimer(measurement.PhaseTimer):
    """:class:`sparselt.measurement.PhaseTimer` over the comparison's phases, :data:`TIME_PHASES`."""

    def __init__(self, phases=TIME_PHASES):
        super().__init__(phases)


class Method:
    """Base class of comparison methods.

    Subclasses set :attr:`name`, :attr:`kinds` (signal kinds they support; the
    harness refuses others before anything runs), :attr:`description`, and
    implement :meth:`run`. Optional attributes:

    ``Options``
        A frozen :class:`~sparselt.methods.options.MethodOptions` dataclass
        declaring the method's options (default: none). The harness
        validates them before anything runs and passes the resolved object
        as ``context.options``.
    ``needs_resolution_multiple``
        The output resolution must be a multiple of the grid's image axes.
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
    """

    name = ""
    kinds = ()
    description = ""
    Options = MethodOptions
    needs_resolution_multiple = False
    baseline = False
    family = "other"
    thesis_procedure = False

    warm_up_spp = 1

    @classmethod
    def roles(cls):
        """What the reports need to know of the method: ``{baseline, family, thesis_procedure}``."""
        return {"baseline": bool(cls.baseline), "family": str(cls.family),
                "thesis_procedure": bool(cls.thesis_procedure)}

    def options_of(self, context):
        """This method's options from ``context``: the resolved object the harness put there.

        A context built by hand may carry a plain dict (or nothing): it is
        resolved here, through the one validation of
        :func:`~sparselt.methods.options.resolve_options`.

        Raises
        ------
        TypeError
            The context carries another method's options object.
        """
        options = context.options
        if isinstance(options, self.Options):
            return options
        if isinstance(options, dict) or type(options) is MethodOptions:
            given = options if isinstance(options, dict) else {}
            return resolve_options(self.Options, given, grid_shape=context.grid_shape, owner=self.name)
        raise TypeError(f"method {self.name!r} got options of type {type(options).__name__}, expected "
                        f"{self.Options.__name__}")

    def warm_up(self, context):
        """Compile the renderer's kernels: one run at :attr:`warm_up_spp`, result discarded."""
        self.run(context, Budget(spp=self.warm_up_spp, seed=WARM_UP_SEED))

    def run(self, context, budget):  # pragma: no cover - interface
        raise NotImplementedError
