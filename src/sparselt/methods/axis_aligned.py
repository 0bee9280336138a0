r"""Methods ``aaf-dof`` and ``aaf-indirect``: axis-aligned filtering from a per-sample frequency analysis.

Both draw the samples of ``pt``'s budget in the sampler's own kernel together
with what the analysis needs (the camera ray's hit depth; for indirect light
the secondary ray's length, whether it was sampled from a diffuse lobe, the
first hit's normal and diffuse reflectance: :data:`AUXILIARY_QUANTITIES`),
derive each pixel's bandlimit and filter width
(:mod:`sparselt.filters.axis_aligned`) and filter the pixel means with
:func:`~sparselt.filters.axis_aligned.axis_aligned_filter`. Every second is
counted: sampling with its auxiliary outputs, the analysis and the filter.

**The filter** is separable (Mehta et al. 2012, 5): a guided 1-D Gaussian
pass along the rows, then one along the columns, each with a tap at every
pixel within ``min(maximum_radius, ceil(3 sigma))`` of the output pixel and
normalised by its own weights, each with the output pixel's width, guide and
tolerance (at most ``2 (2 maximum_radius + 1)`` taps per pixel). A firefly
becomes a smooth spot, not a lattice of dots (the strided 2-D window it
replaced); :func:`filter_variance_factor` is its variance reduction.

``aaf-dof`` (Mehta et al. 2014, 3.1; Soler et al. 2009). The width is
``0.307 min |c|`` pixels over the circles of confusion ``c`` of the pixel's
samples (0 where they straddle the focal plane). Neighbours must lie at a
similar defocus: the guide is the signed circles of confusion of the pixel's
nearest and farthest sample (a pixel that mixes two surfaces matches neither
pure neighbour), its tolerance the pixel's own width (at least one pixel): a neighbour whose defocus differs by less than the filter's scale is
indistinguishable after filtering, one that differs by more is a surface
across a depth discontinuity. The depths decide, not the sample positions.

``aaf-dof:factoring=direct`` (Mehta et al. 2012 for the analysis, factored as
in Mehta et al. 2014). In-focus pixels (defocus width below
:data:`IN_FOCUS_WIDTH`) are not filtered by the defocus analysis; where some
of their samples' shadow rays were blocked, the soft-shadow analysis
(:func:`~sparselt.filters.axis_aligned.shadow_filter_width`: ``beta =
sigma_l s_2 / 3`` from the light's size and the least slope ``d1 / d2 - 1``
of the pixel's blocked light samples, capped at the pixel rate) gives their
first vertex's direct lighting a width. That part, demodulated by the pixel's
mean first-hit albedo (every sample's, as the direct light), is filtered with
it (guides: camera depth with the width on the receiver as tolerance, and the
shading normal), modulated back, and the rest of the pixel's light is added
unfiltered. Pixels without a blocked sample, with a width below
half a pixel or without a diffuse albedo are left as ``factoring=none``
leaves them; the allocation is the same (no extra samples). The
per-sample inputs (the direct light, ``d1``, ``d2``, the light's size) are
reduced in the sampling kernel as the other statistics are.

``aaf-indirect`` (Mehta et al. 2013). Factored by the lobe the first vertex
sampled: samples whose secondary ray came from a diffuse lobe carry the
diffuse indirect light, which the analysis bandlimits (``Omega_h / z_min``);
they are demodulated by the pixel's mean diffuse reflectance, filtered and
modulated back. Samples from glossy or specular lobes (the courtyard's glossy
floor and plastic coatings) are not bandlimited by the diffuse transfer and
are added unfiltered. Guides: the pixel's camera depth, with the width on the
receiver in scene units as tolerance (neighbours farther than the filter's own
scale in depth are another surface), and the mean shading normal (tolerance
``normal_tolerance``).

**Adaptive sampling** (Mehta et al. 2012, 4.3; 2013, 5). A pilot pass draws
``pilot_fraction`` of the budget uniformly (at least 2 spp); the analysis of
the pilot gives each pixel's filter width and so the factor ``r_p`` by which
the filter will divide its variance (:func:`filter_variance_factor`); the rest
of the budget goes where it lowers the filtered image's expected relMSE most,
``n_p`` proportional to ``sqrt(v_p r_p)`` (:func:`allocate_samples`, ``v_p``
the pilot's per-sample variance over ``(mean luminance)^2 + 0.01``, the
relMSE's own weighting, smoothed over 5x5 pixels), each pixel at most
``maximum_allocation`` times ``spp`` (a capped pixel's excess is not handed
on). ``aaf-indirect`` filters only the diffuse-lobe part of a pixel, so its
``v_p r_p`` is the diffuse part's variance times ``r_p`` plus the rest's
(:meth:`AafIndirect.filtered_variance`): a pixel whose noise is in its glossy
samples gains nothing from the filter. Every sample is counted. The papers
derive the counts from the bandlimits alone; ours add the measured variance,
because in-focus pixels (no filtering at all) carry most of the error. The
final widths come from all of a pixel's samples.

**Samples cost what their paths cost** (``sample_cost='vertices'``, the
default). Equal time, not equal samples, is the comparison, and the pixels an
allocation favours often have long paths: on dof-sculptures the allocated
lanes cost 1.47 times as many uniform ones, on courtyard 1.31 times. The pilot
reduces each sample's path vertices in its kernel (``path_vertices``); a
pixel's cost per sample is ``c_p = 0.5 +`` their mean
(:data:`FIXED_SAMPLE_COST`, :meth:`PixelStatistics.sample_cost`), and the
allocation minimises the predicted relMSE at the cost of the uniform rest,
``n_p`` proportional to ``sqrt(v_p r_p / c_p)``: fewer samples, no dearer in
total, where paths are long. ``sample_cost='uniform'`` is the papers' rule.

**When not to allocate** (issue 37: "where the analysis predicts no gain, no
extra cost"). Measured over the suite's scenes (eighth session), the papers'
allocation helped where a few pixels hold most of the error (dof-sculptures'
in-focus gold, sunlit-room's fireflies) and hurt elsewhere (courtyard,
glossy-interior, outdoor-texture, user-dof): a pixel whose few pilot samples
all took the glossy lobe gets no width and draws many samples, and allocated
samples fall on long, costly paths. With the cost and the glossy part in the
model (ninth session) the allocation beats one uniform launch on six of the
eight scenes measured (``docs/experiments/README.md``); it still loses on
outdoor-texture, whose error is the filter's, not the variance the model
sees, and on user-dof (160x96), where a second launch's fixed cost decides.
So the pilot is drawn in two halves in its one launch, and the allocation is
kept only where the one from each half lowers the other half's predicted
error times cost at least ``allocation_gain`` times (1.2: the check, the
second launch and the allocation's own passes cost 5-15% at 256x256), read
on every other pixel of every other row (:meth:`_AxisAligned.held_out_gain`,
:data:`CHECK_STEP`); otherwise the rest is uniform. A budget
below ``single_launch_below`` samples is drawn in one uniform launch: a
launch's fixed cost (tracing, code generation: 10-14 ms on 2 cores) is
then a large share of the time. The bound is crude: below it the allocation
is given up where it would have won (dof-sculptures at 128x128 and 16 spp:
1.52x over PT in one launch, 1.79x with the pilot and the allocation); at
2^18 instead, user-dof at 160x96 and 64 spp lost (0.965x, the two launches of
a declined allocation) where one launch wins (1.08x). Deciding from the
launch's measured cost would make the image depend on the machine's timing.

Both are biased (a filter), consistent only as the widths shrink; the bias is
measured in ``tests/test_axis_aligned.py`` and in the experiments.

References
----------
Mehta, Wang, Ramamoorthi (2012); Mehta, Wang, Ramamoorthi, Durand (2013);
Mehta, Yao, Ramamoorthi, Durand (2014). See :mod:`sparselt.filters.axis_aligned`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..cell_statistics import variance_from_sums
from ..filters.axis_aligned import (DIFFUSE_BANDLIMIT, axis_aligned_filter, circle_of_confusion, dof_filter_width,
                                    gaussian_taps, indirect_filter_width, shadow_filter_width)
from .base import WARM_UP_SEED, Budget, Method, MethodResult, PhaseTimer
from .preconditions import ThinLens
from .options import MethodOptions, option
from ..rendering.mitsuba.pixel_statistics import ALLOCATION_BLOCK, PIXEL_STATISTICS, REDUCTIONS
from .registry import register



#: A sample's cost beyond its path vertices, in path vertices (the lane's set-up and camera ray), for
#: :meth:`PixelStatistics.sample_cost`. Measured: the allocated lanes of five of the suite's scenes cost 0.53-1.47
#: times the same number of uniform lanes; cost ``0.5 + vertices`` predicts 0.47-1.37 (docs/experiments/README.md,
#: issue 37's ninth session).
FIXED_SAMPLE_COST = 0.5
#: The held-out check (:meth:`_AxisAligned.held_out_gain`) reads every ``CHECK_STEP``-th pixel of every
#: ``CHECK_STEP``-th row: its score is a ratio of sums over the image, which a quarter of the pixels estimate, at a
#: quarter of the cost (about 45 ms at 256x256 for ``aaf-indirect`` on every pixel).
CHECK_STEP = 2


def _maximum_radius():
    return option(24, minimum=1, maximum=64, help="the filter window's half width never exceeds this (pixels)")


@dataclass(frozen=True)
class AxisAlignedOptions(MethodOptions):
    """Options both axis-aligned filters share: the window and the adaptive sampling."""

    width_scale: float = option(1.0, minimum=0.0, help="multiplies the analysis's filter width (1: the widest "
                                "Gaussian whose response is 1/2 at the pixel's bandlimit; 0: no filtering)")
    maximum_radius: int = _maximum_radius()
    pilot_fraction: float = option(0.25, minimum=0.0, maximum=1.0,
                                   help="share of the budget drawn uniformly first (at least 2 spp); the rest is "
                                        "allocated per pixel from the analysis (Mehta et al. 2012, 4.3); 1: every "
                                        "pixel gets spp samples")
    maximum_allocation: float = option(8.0, minimum=1.0, help="no pixel gets more than this many times the "
                                       "budget's spp")
    allocation_gain: float = option(1.2, minimum=0.0,
                                    help="allocate only where the allocation from one half of the pilot lowers the "
                                         "other half's predicted relMSE x cost at least this many times (both ways, "
                                         "geometric mean; 1.2 pays for the check and the second launch); otherwise "
                                         "the rest is uniform. 0: always allocate (the papers' rule)")
    sample_cost: str = option("vertices", choices=("vertices", "uniform"),
                              help="vertices: the allocation weighs each pixel's expected cost per sample (0.5 plus "
                                   "the mean number of path vertices its pilot samples reached), n_p ~ "
                                   "sqrt(v_p r_p / c_p), and spends what the uniform samples would cost; uniform: "
                                   "every sample costs the same (the papers' rule)")
    single_launch_below: int = option(1 << 20, minimum=0,
                                      help="a budget of fewer samples (pixels x spp; default 2^20, a 256x256 image "
                                           "at 16 spp) is drawn uniformly in one launch, no pilot: a second "
                                           "launch's fixed cost (tracing and code generation, 10-14 ms) is then over "
                                           "about 5% of the budget at the standard suite's median cost per sample; "
                                           "0: never")


@dataclass(frozen=True)
class AafDofOptions(AxisAlignedOptions):
    """``aaf-dof``: the shared options and the factoring of in-focus pixels."""

    factoring: str = option("none", choices=("direct", "none"),
                            help="direct: pixels in focus (defocus width below one pixel) whose samples' shadow rays "
                                 "were blocked filter their albedo-demodulated direct lighting with the soft-shadow "
                                 "width (Mehta et al. 2012; factored as in Mehta et al. 2014); none: they are not "
                                 "filtered")
    normal_tolerance: float = option(0.3, minimum=0.0, minimum_inclusive=False,
                                     help="tolerance of the shading-normal guide of the factored direct-light filter "
                                          "(unit normals)")


@dataclass(frozen=True)
class AafIndirectOptions(AxisAlignedOptions):
    bandlimit: float = option(DIFFUSE_BANDLIMIT, minimum=0.0, minimum_inclusive=False,
                              help="Omega_h, the diffuse transfer's bandlimit (Mehta et al. 2013, 4.1: 2.8)")
    normal_tolerance: float = option(0.3, minimum=0.0, minimum_inclusive=False,
                                     help="tolerance of the shading-normal guide (unit normals)")


class PixelStatistics:
    """Per-pixel reductions of per-sample quantities, merged over a uniform pilot and allocated passes.

    Each statistic (:data:`~sparselt.rendering.mitsuba.PIXEL_STATISTICS`)
    keeps its own per-pixel sample count: guides may come from the pilot alone.

    Parameters
    ----------
    shape : tuple of int
        ``(height, width)``.
    """

    def __init__(self, shape):
        self.shape = tuple(shape)
        self.counts = np.zeros(int(np.prod(shape)), dtype=np.int64)
        self._values, self._counts = {}, {}

    def add(self, statistics, counts):
        """Merge one pass: ``statistics`` name -> per-pixel reduction, ``counts`` its samples per pixel."""
        counts = np.broadcast_to(np.asarray(counts, dtype=np.int64), self.counts.shape)
        for name, value in statistics.items():
            if name not in self._values:
                self._values[name] = np.array(value, dtype=np.float64)
                self._counts[name] = counts.copy()
                continue
            merge, _ = REDUCTIONS[PIXEL_STATISTICS[name]]
            merge(self._values[name], value, out=self._values[name])
            self._counts[name] += counts
        self.counts += counts

    @classmethod
    def subsampled(cls, statistics, counts, shape, step):
        """One pass's statistics (as :meth:`add` takes them) of every ``step``-th pixel of every ``step``-th row
        of an image of ``shape``: a smaller image, as if only those pixels had been drawn."""
        height, width = shape
        rows, columns = np.arange(0, height, step), np.arange(0, width, step)
        pixels = (rows[:, None] * width + columns[None, :]).reshape(-1)  # gathered, not a full-size reshaped copy
        result = cls((rows.size, columns.size))
        result.add({name: np.asarray(value)[pixels] for name, value in statistics.items()}, counts)
        return result

    def total(self, name):
        """The reduction of ``name`` per pixel, shape ``(height, width, ...)``."""
        value = self._values[name]
        return value.reshape(self.shape + value.shape[1:])

    def mean(self, name):
        """The per-pixel sum of ``name`` over that statistic's own sample count."""
        counts = np.maximum(self._counts[name], 1).reshape(self.shape).astype(np.float64)
        total = self.total(name)
        return total / counts.reshape(counts.shape + (1,) * (total.ndim - 2))

    def relative_variance(self, total=None, squares=None):
        """Per-pixel variance of one sample (RGB mean) over (mean luminance^2 + 0.01), smoothed over 5x5 pixels.

        From ``rgb`` and ``rgb_squared`` (the pilot's); or of a part of each
        sample, from that part's per-pixel ``total`` and sum of ``squares``
        over the same samples (relative to the whole pixel's luminance).
        """
        from ..images import luminance

        count = np.maximum(self._counts["rgb_squared"], 2).reshape(self.shape)[..., None].astype(np.float64)
        mean = self.total("rgb") / count
        variance = variance_from_sums(self.total("rgb") if total is None else total,
                                      self.total("rgb_squared") if squares is None else squares, count, form="moment")
        level = luminance(mean)
        return _box_mean(variance.mean(axis=-1) / (level * level + 0.01))

    def sample_cost(self):
        """Each pixel's expected cost per sample in path vertices, ``FIXED_SAMPLE_COST`` plus the mean number of
        vertices its samples reached (``path_vertices``, the pilot's), smoothed over 5x5 pixels."""
        return _box_mean(FIXED_SAMPLE_COST + self.mean("path_vertices"))


def _box_mean(image):
    """The mean over each pixel's 5x5 neighbourhood (edges repeated), computed separably."""
    padded = np.pad(image, 2, mode="edge")
    height, width = image.shape
    rows = sum(padded[:, offset:offset + width] for offset in range(5))
    return sum(rows[offset:offset + height] for offset in range(5)) / 25.0


def filter_variance_factor(sigma, maximum_radius):
    """Variance of :func:`axis_aligned_filter`'s output over its input's, per pixel, for independent pixels.

    Parameters
    ----------
    sigma : ndarray
        Each pixel's filter width in pixels (0: not filtered).
    maximum_radius : int
        The filter's ``maximum_radius``.

    Returns
    -------
    ndarray, same shape
        ``r_p``; 1 where ``sigma`` is 0.

    Notes
    -----
    The filter is two normalised 1-D passes with the taps of
    :func:`~sparselt.filters.axis_aligned.gaussian_taps` (the filter's own
    rule): one at every pixel within the radius. Without the guides, away
    from the image border and where the width is locally constant, the 2-D
    weights are the outer product of the 1-D ones, so the factor is the square
    of the 1-D one, ``r_p = (sum_d w_d^2 / (sum_d w_d)^2)^2`` over the offsets
    ``d = -radius, ..., radius``, ``w_d = exp(-d^2 / (2 sigma^2))``: about
    ``1 / (4 pi sigma^2)`` for widths of a few pixels. Widths are rounded to
    0.01 pixel to share the sums.
    """
    sigma = np.minimum(np.asarray(sigma, dtype=np.float64), maximum_radius / 3.0)
    hundredths = np.rint(np.maximum(sigma, 0.0) * 100.0).astype(np.int64)  # the width rounded to 0.01 pixel
    return _variance_factor_table(int(maximum_radius))[hundredths]


@functools.lru_cache(maxsize=8)
def _variance_factor_table(maximum_radius):
    """:func:`filter_variance_factor` of every width ``0, 0.01, ..., maximum_radius / 3`` (read only)."""
    table = np.ones(int(math.floor(maximum_radius / 3.0 * 100.0 + 0.5)) + 1)
    for index in range(1, table.size):
        width, radius = gaussian_taps(index / 100.0, maximum_radius)
        offsets = np.arange(-radius, radius + 1)
        weights = np.exp(-0.5 * (offsets / width) ** 2)
        table[index] = (np.sum(weights ** 2) / np.sum(weights) ** 2) ** 2
    table.flags.writeable = False
    return table


def allocate_samples(weight, extra_total, cap, cost=None):
    """Extra samples per pixel minimising the filtered image's expected relMSE at a given sampling cost.

    Minimises ``sum(w_p / n_p)`` subject to ``sum(c_p n_p) = B`` (Lagrange):
    ``n_p = lambda sqrt(w_p / c_p)``, ``B`` what ``extra_total`` uniform
    samples cost (``extra_total`` times the mean cost), then at most ``cap``.
    A capped pixel's excess is not handed on: it would go to pixels whose
    weight is low, at their full cost (sunlit-room, whose fireflies reach the
    cap: spending it took 1.8x the time for no less error), so the budget is
    not always spent, and every sample drawn is counted. With every ``c_p``
    equal this is Mehta et al.'s ``n_p`` proportional to ``sqrt(w_p)``. The
    counts are rounded systematically (each pixel's share of the running sum
    of the ideal counts, in pixel order): each within one of its ideal, their
    sum the ideal sum rounded down, no sort.

    Parameters
    ----------
    weight : ndarray
        ``w_p``, each pixel's predicted relative variance of one sample after filtering
        (:meth:`_AxisAligned.allocation_weight`).
    extra_total : int
        Samples whose uniform cost is the budget.
    cap : int
        No pixel gets more.
    cost : ndarray, optional
        ``c_p``, a pixel's expected cost per sample (:meth:`PixelStatistics.sample_cost`); default: every
        sample costs the same.

    Returns
    -------
    ndarray of int64, same shape as ``weight``; ``sum(c_p n_p)`` at most the budget (to rounding).
    """
    shape = np.shape(weight)
    weight = np.maximum(np.asarray(weight, dtype=np.float64), 0.0).reshape(-1)
    cost = np.ones(weight.size) if cost is None else np.asarray(cost, dtype=np.float64).reshape(-1)
    if extra_total <= 0 or cap <= 0 or not np.any(weight > 0):
        share = np.full(weight.size, max(0, min(cap, extra_total // max(1, weight.size))), dtype=np.int64)
        return share.reshape(shape)
    budget = float(extra_total) * float(cost.mean())
    rate = np.sqrt(weight / cost)
    ideal = np.minimum(budget / float(np.sum(cost * rate)) * rate, cap)
    running = np.floor(np.cumsum(ideal) + 1e-4)  # 1e-4: the running sum's rounding, far below one sample
    counts = np.diff(running, prepend=0.0).astype(np.int64)
    return np.minimum(counts, cap).reshape(shape)


def _summary(sigma):
    filtered = sigma > 0
    return {"filtered_pixel_fraction": float(filtered.mean()),
            "median_sigma_pixels": float(np.median(sigma[filtered])) if filtered.any() else 0.0,
            "max_sigma_pixels": float(sigma.max(initial=0.0))}


class _AxisAligned(Method):
    """Pilot, allocation, allocated samples, analysis, filter: the pipeline both methods share.

    Subclasses give :attr:`statistics` (the per-pixel reductions every pass
    gathers, :data:`~sparselt.rendering.mitsuba.PIXEL_STATISTICS`),
    :attr:`pilot_statistics` (those the pilot alone gives: guides),
    :meth:`widths` (the analysis) and :meth:`finish` (the filtered image).
    Every reduction happens in the sampling kernel, for the uniform pilot
    and for the allocated counts alike (whole blocks reduced in the kernel, the rest
    merged per pixel on the host:
    :func:`~sparselt.rendering.mitsuba.pixel_statistics.sample_pixel_statistics`).
    """

    family = "filter"
    statistics = ()
    pilot_statistics = ()

    def warm_up(self, context):
        # A pilot of 2 spp in halves, then the allocated pass, then the uniform rest: every kernel and the filter
        # compiled (a one-launch run uses the pilot's), results discarded.
        for rest in ("allocated", "uniform"):
            self._run(context, Budget(spp=4, seed=WARM_UP_SEED), PhaseTimer(), warming=rest)
        # An allocation with both blocks and single lanes: the 4-spp warm-up's allocation may hold no whole block.
        counts = np.zeros(context.resolution[0] * context.resolution[1], dtype=np.int64)
        counts[:2] = 2 * ALLOCATION_BLOCK - 1
        context.scene.sample_pixel_statistics(context.layout, context.grid_shape, WARM_UP_SEED, self.statistics,
                                              counts=counts, first_sample=2)

    def check(self, context):
        """Refuse a context the analysis cannot describe, before any sampling (default: nothing)."""

    def run(self, context, budget, timer):
        return self._run(context, budget, timer)

    def _run(self, context, budget, timer, *, warming=None):
        """The pipeline; ``warming`` (``'allocated'`` or ``'uniform'``) draws the pilot in halves and then the
        rest that way, whatever the budget and the held-out gain."""
        options = self.options
        self.check(context)
        width, height = context.resolution
        pilot_spp, plan = self._pilot_plan(options, budget.spp, width * height, warming)
        statistics = PixelStatistics((height, width))
        # A one-launch run reduces the pilot's statistics too, unused: the path kernel is then the warmed pilot's.
        names = ("rgb_squared",) + (("path_vertices",) if options.sample_cost == "vertices" else ()) + \
            self.pilot_statistics + self.statistics
        with timer("sampling"):
            pilot, nonfinite = context.scene.sample_pixel_statistics(
                context.layout, context.grid_shape, budget.seed, names, spp=pilot_spp, halves=plan == "held-out")
        with timer("integration"):
            parts = pilot if plan == "held-out" else (pilot,)
            halves = []
            for part in parts:
                statistics.add(part, pilot_spp // len(parts))
                if plan == "held-out":  # every other pixel of every other row: the check's ratios of sums
                    halves.append(PixelStatistics.subsampled(part, pilot_spp // 2, (height, width), CHECK_STEP))
        details = {}
        if pilot_spp < budget.spp:
            with timer("other"):
                extra_total = (budget.spp - pilot_spp) * width * height
                cap = max(0, int(options.maximum_allocation * budget.spp) - pilot_spp)
                gain = self.held_out_gain(context, options, halves, budget.spp, pilot_spp, cap) if halves else None
                allocate = warming == "allocated" or (warming is None and (gain is None or
                                                                           gain >= options.allocation_gain))
                if allocate:
                    weight, cost = self.allocation_weight(context, options, statistics)
                    extra = allocate_samples(weight, extra_total, cap, cost)
                details.update(allocation="allocated" if allocate else "uniform (held-out gain below allocation_gain)",
                               allocation_held_out_gain=gain if gain is not None else "")
            if allocate:
                nonfinite += self._draw_allocated(context, budget, pilot_spp, extra.reshape(-1), statistics, timer)
            else:  # the rest in one uniform launch, sample indices after the pilot's
                with timer("sampling"):
                    rest, bad = context.scene.sample_pixel_statistics(
                        context.layout, context.grid_shape, budget.seed, self.statistics, spp=budget.spp - pilot_spp,
                        first_sample=pilot_spp)
                nonfinite += bad
                with timer("integration"):
                    statistics.add(rest, budget.spp - pilot_spp)
        else:
            details.update(allocation=plan, allocation_held_out_gain="")
        with timer("reconstruction"):
            image, sigma, finished = self.finish(context, options, statistics)
        details.update(finished)
        details.update(pilot_spp=pilot_spp, largest_pixel_spp=int(statistics.counts.max()),
                       smallest_pixel_spp=int(statistics.counts.min()), nonfinite_samples=nonfinite,
                       width_scale=options.width_scale, maximum_radius=options.maximum_radius,
                       pilot_fraction=options.pilot_fraction, maximum_allocation=options.maximum_allocation,
                       allocation_gain=options.allocation_gain, single_launch_below=options.single_launch_below,
                       sample_cost=options.sample_cost)
        details.update(_summary(sigma))
        return MethodResult(image=np.asarray(image, dtype=np.float32), path_samples=int(statistics.counts.sum()),
                            details=details)

    @staticmethod
    def _pilot_plan(options, spp, pixels, warming):
        """The pilot's spp and how the rest is decided: ``'one launch ...'``, ``'held-out'`` or ``'allocated'``.

        One launch where the budget has fewer than ``single_launch_below``
        samples or ``pilot_fraction`` covers it. With ``allocation_gain > 0``
        the pilot is drawn in two halves (its spp rounded up to even) for
        :meth:`held_out_gain`.
        """
        if not warming and 0 < pixels * spp < options.single_launch_below:
            return spp, "one launch (budget below single_launch_below)"
        pilot_spp = min(spp, max(2, int(round(options.pilot_fraction * spp))))
        if pilot_spp >= spp:
            return spp, "one launch (pilot_fraction covers the budget)"
        if options.allocation_gain > 0 or warming:
            pilot_spp += pilot_spp % 2
            return (pilot_spp, "held-out") if pilot_spp < spp else (spp, "one launch (pilot_fraction covers the budget)")
        return pilot_spp, "allocated"

    def allocation_weight(self, context, options, statistics):
        """``(w_p, c_p)``: each pixel's predicted relative variance of one sample after filtering, ``v_p r_p``
        (:meth:`filtered_variance`), and its cost per sample (None where ``sample_cost`` is uniform): what
        :func:`allocate_samples` weighs."""
        sigma, _ = self.widths(context, options, statistics)
        cost = statistics.sample_cost() if options.sample_cost == "vertices" else None
        return self.filtered_variance(statistics, filter_variance_factor(sigma, options.maximum_radius)), cost

    def filtered_variance(self, statistics, factor):
        """Each pixel's relative variance of one sample after the filter divides it by ``1 / factor``: the whole
        pixel's, ``v_p r_p``."""
        return statistics.relative_variance() * factor

    def held_out_gain(self, context, options, halves, spp, pilot_spp, cap):
        """How many times the allocation from one pilot half lowers the other half's predicted relMSE x cost.

        The allocation :func:`allocate_samples` derives from half ``A``
        (``n_p``, with the pilot's own ``pilot_spp``) is scored on half ``B``'s
        per-pixel variances, filter factors and costs, ``w_p = v_p r_p`` and
        ``c_p``: the uniform budget's predicted error times its cost,
        ``sum(w_p) / spp * spp sum(c_p)``, over the allocation's,
        ``sum(w_p / n_p) * sum(c_p n_p)``; then ``B`` on ``A``; their
        geometric mean (with ``sample_cost`` uniform, every ``c_p`` is 1 and
        the costs cancel: ``sum(w_p) / spp`` over ``sum(w_p / n_p)``). An
        allocation that chases one half's noise (a firefly, a pixel whose
        few pilot samples missed the diffuse lobe and so got no width), or
        that buys its error with costlier paths, scores near or below 1 on
        the other half. 1 where the pilot shows no variance.
        """
        extra_total = (spp - pilot_spp) * int(halves[0].counts.size)
        analysed = [self.allocation_weight(context, options, statistics) for statistics in halves]
        scores = []
        for (weight, cost), (held_weight, held_cost) in (analysed, analysed[::-1]):
            allocated = allocate_samples(weight, extra_total, cap, cost) + pilot_spp
            predicted = float(np.sum(held_weight / allocated))
            if held_cost is not None:
                predicted *= float(np.sum(held_cost * allocated)) / (spp * float(np.sum(held_cost)))
            scores.append(float(np.sum(held_weight)) / spp / predicted if predicted > 0 else 1.0)
        return float(math.sqrt(scores[0] * scores[1]))

    def _draw_allocated(self, context, budget, first_index, extra, statistics, timer):
        """Draw ``extra[p]`` more samples of pixel ``p`` (sample indices from ``first_index``) into ``statistics``."""
        with timer("sampling"):
            reduced, nonfinite = context.scene.sample_pixel_statistics(
                context.layout, context.grid_shape, budget.seed, self.statistics, counts=extra,
                first_sample=first_index)
        with timer("integration"):
            statistics.add(reduced, extra)
        return nonfinite

    def widths(self, context, options, statistics):  # pragma: no cover - interface
        raise NotImplementedError

    def finish(self, context, options, statistics):  # pragma: no cover - interface
        raise NotImplementedError


def _lens_arguments(context):
    lens = context.scene.lens_geometry()
    return lens["aperture_radius"], lens["focus_distance"], lens["pixels_per_tangent"]


#: Statistics ``aaf-dof`` gathers in every pass, and in the pilot alone, with ``factoring="direct"``.
#: The albedo comes from every sample, as the direct light does (a pilot-only albedo demodulated a pixel's direct
#: light by a few of its samples' reflectance: at texture edges that ratio was off, and the filter carried it over).
FACTORED_STATISTICS = ("direct_rgb", "albedo", "least_penumbra")
FACTORED_PILOT_STATISTICS = ("normal", "depth", "hits")
#: Pixels whose defocus width is below this (pixels) are in focus: the factored filter may take them.
IN_FOCUS_WIDTH = 1.0


def _pixel_depth(statistics):
    hits = statistics.total("hits")
    return np.where(hits > 0, statistics.total("depth") / np.maximum(hits, 1), np.inf)  # pilot sums both


def _demodulable(statistics):
    # Demodulation needs a diffuse reflectance in every channel: other pixels (metals, the environment) are
    # neither filtered nor taken as neighbours (their guide is out of reach).
    return np.all(statistics.mean("albedo") > 1e-3, axis=-1)


@register
class AafDof(_AxisAligned):
    name = "aaf-dof"
    kinds = ("dof",)
    Options = AafDofOptions
    requires = (ThinLens(),)
    description = ("axis-aligned filter for depth of field (Mehta et al. 2014): per-pixel Gaussian 0.307 x the "
                   "least circle of confusion of the pixel's samples, guided by the defocus of its nearest and "
                   "farthest sample; a quarter of the budget as pilot, the rest allocated per pixel; factoring=direct "
                   "filters in-focus pixels' albedo-demodulated direct light with the soft-shadow width (Mehta et al. "
                   "2012)")

    @property
    def statistics(self):
        factored = FACTORED_STATISTICS if self.options.factoring == "direct" else ()
        return ("rgb", "nearest", "farthest") + factored

    @property
    def pilot_statistics(self):
        return FACTORED_PILOT_STATISTICS if self.options.factoring == "direct" else ()

    def check(self, context):
        circle_of_confusion(1.0, *_lens_arguments(context))  # a pinhole camera fails here

    def widths(self, context, options, statistics):
        sigma = dof_filter_width(statistics.total("nearest"), statistics.total("farthest"), *_lens_arguments(context))
        return options.width_scale * sigma, None

    def shadow_widths(self, context, options, statistics, sigma):
        """The factored pixels' soft-shadow widths (pixels and scene units; 0 elsewhere) and their mask.

        A pixel is factored where its defocus width ``sigma`` is below
        :data:`IN_FOCUS_WIDTH`, its first hit has an albedo to demodulate by,
        and :func:`~sparselt.filters.axis_aligned.shadow_filter_width` gives
        it a width (some sample's shadow ray was blocked, the width at least
        :data:`~sparselt.filters.axis_aligned.MINIMUM_SIGMA`).
        """
        shadow, shadow_world = shadow_filter_width(statistics.total("least_penumbra"), _pixel_depth(statistics),
                                                   context.scene.lens_geometry()["pixels_per_tangent"])
        factored = (sigma < IN_FOCUS_WIDTH) & _demodulable(statistics) & (options.width_scale * shadow > 0)
        return (np.where(factored, options.width_scale * shadow, 0.0),
                np.where(factored, options.width_scale * shadow_world, 0.0), factored)

    def finish(self, context, options, statistics):
        lens_arguments = _lens_arguments(context)
        sigma, _ = self.widths(context, options, statistics)
        # Both ends of the pixel's defocus range: a pixel that mixes two surfaces matches neither pure neighbour.
        guide = np.stack([circle_of_confusion(statistics.total(end), *lens_arguments) for end in ("nearest", "farthest")],
                         axis=-1)
        means = statistics.mean("rgb")
        image = axis_aligned_filter(means, sigma, guide=guide, tolerance=np.maximum(sigma, 1.0),
                                    maximum_radius=options.maximum_radius)
        details = {"aperture_radius": lens_arguments[0], "focus_distance": lens_arguments[1],
                   "guide": "signed circles of confusion of the nearest and farthest sample (depths)",
                   "factoring": options.factoring}
        if options.factoring == "none":
            return image, sigma, details
        shadow, shadow_world, factored = self.shadow_widths(context, options, statistics, sigma)
        details.update(factored_pixel_fraction=float(factored.mean()),
                       median_shadow_sigma_pixels=float(np.median(shadow[factored])) if factored.any() else 0.0,
                       normal_tolerance=options.normal_tolerance)
        if not factored.any():  # the analysis predicts no gain anywhere: nothing more to do
            return image, sigma, details
        image = np.array(image, dtype=np.float64)
        direct, albedo = statistics.mean("direct_rgb"), statistics.mean("albedo")
        demodulable = _demodulable(statistics)
        safe = demodulable[..., None]
        irradiance = np.where(safe, direct / np.where(safe, albedo, 1.0), 0.0)
        pixel_depth = _pixel_depth(statistics)
        depth_guide = np.where(np.isfinite(pixel_depth) & demodulable, pixel_depth, 1e30)
        filtered = axis_aligned_filter(irradiance, shadow, guide=depth_guide,
                                       tolerance=np.where(factored, shadow_world, 1.0),
                                       fixed_guide=statistics.mean("normal"), fixed_tolerance=options.normal_tolerance,
                                       maximum_radius=options.maximum_radius)
        image[factored] = filtered[factored] * albedo[factored] + (means[factored] - direct[factored])
        return image, sigma, details


@register
class AafIndirect(_AxisAligned):
    name = "aaf-indirect"
    kinds = ("indirect",)
    Options = AafIndirectOptions
    # The albedo from every sample, as the diffuse light it demodulates (a pilot-only albedo divided a textured
    # pixel's light by a few of its samples' reflectance: 1.5x the relMSE of one uniform pass on outdoor-texture).
    statistics = ("rgb", "diffuse_rgb", "shortest", "albedo")
    pilot_statistics = ("normal", "depth", "hits", "diffuse_rgb_squared")
    description = ("axis-aligned filter for diffuse indirect light (Mehta et al. 2013): width from the shortest "
                   "diffuse secondary ray per pixel, albedo-demodulated, glossy-lobe samples unfiltered; "
                   "a quarter of the budget as pilot, the rest allocated per pixel")

    def widths(self, context, options, statistics):
        sigma, sigma_world = indirect_filter_width(statistics.total("shortest"), _pixel_depth(statistics),
                                                   context.scene.lens_geometry()["pixels_per_tangent"],
                                                   bandlimit=options.bandlimit)
        safe = _demodulable(statistics)
        return options.width_scale * np.where(safe, sigma, 0.0), options.width_scale * sigma_world

    def filtered_variance(self, statistics, factor):
        """Only the diffuse part is filtered: ``v_diffuse r_p + v_rest`` (relative variances of one sample's
        diffuse-lobe part and of the rest, from the pilot's sums and sums of squares of each; a sample is one or
        the other, so the rest's are the differences). A pixel whose noise is in its glossy samples gains nothing
        from the filter, and the allocation sees that."""
        diffuse, diffuse_squares = statistics.total("diffuse_rgb"), statistics.total("diffuse_rgb_squared")
        rest = statistics.relative_variance(statistics.total("rgb") - diffuse,
                                            statistics.total("rgb_squared") - diffuse_squares)
        return statistics.relative_variance(diffuse, diffuse_squares) * factor + rest

    def finish(self, context, options, statistics):
        sigma, sigma_world = self.widths(context, options, statistics)
        safe = _demodulable(statistics)[..., None]
        means = statistics.mean("rgb")
        diffuse_part = statistics.mean("diffuse_rgb")
        albedo = statistics.mean("albedo")
        irradiance = np.where(safe, diffuse_part / np.where(safe, albedo, 1.0), 0.0)
        pixel_depth = _pixel_depth(statistics)
        depth_guide = np.where(np.isfinite(pixel_depth) & safe[..., 0], pixel_depth, 1e30)
        filtered = axis_aligned_filter(irradiance, sigma, guide=depth_guide, tolerance=np.maximum(sigma_world, 1e-6),
                                       fixed_guide=statistics.mean("normal"), fixed_tolerance=options.normal_tolerance,
                                       maximum_radius=options.maximum_radius)
        image = np.where(safe, filtered * albedo, diffuse_part) + (means - diffuse_part)
        return image, sigma, {"bandlimit": options.bandlimit, "normal_tolerance": options.normal_tolerance,
                              "guide": "camera depth (tolerance: the width on the receiver) and shading normal"}
