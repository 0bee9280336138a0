r"""Guided rendering from importance maps: ``guided-pilot``, ``guided-cosamp``, ``guided-bilateral`` (thesis 6.2, 8.3, 8.4).

Each method draws a pilot pass of uniform path-tracing samples, turns it into
a map over the signal grid of the comparison, and renders the output with
guided samples (:meth:`MitsubaScene.render_guided`). The map's cost (pilot
samples, CoSaMP, the 4-D filter, building the CDFs) is counted in the
method's time and its samples in ``path_samples``. The option
``pilot_fraction`` says where the pilot's samples come from:

``pilot_fraction > 0``: the pilot is part of the budget (default of ``guided-pilot``)
    The pilot draws ``s_p = max(1, round(pilot_fraction * spp))`` uniform
    samples per output pixel and the guided render the rest,
    ``s_g = spp - s_p``: ``spp`` path samples per pixel in all. The pilot's
    samples are path tracing's own, so the image reuses them; per pixel it is
    ``(s_p * pilot mean + s_g * guided mean) / spp``. Both means are unbiased
    (the guided one given any map, so given a map built from the pilot) and
    the weights are constants, so the combination is unbiased. A pixel whose
    image cell keeps the defensive weight 1 (the map not shown to help) is
    plain path tracing at ``spp`` samples: path tracing's variance, the map
    costing only time; where every image cell keeps weight 1, the rest is
    rendered by the kind's path-tracing kernel (the same estimator, without
    the warp's cost). The pilot is drawn per output pixel whatever the grid;
    where the grid's image axes are coarser than the output, a map cell
    averages the pixels it covers (:func:`.pixel_samples.cell_means`) and
    the image still reuses every pilot sample in its own pixel. When
    ``s_g < 1``, or when per-pixel mode would cross-validate the weights on
    fewer than 2 pilot samples per pixel, the method renders plain path
    tracing at the budget and its details say so; so it does when the grid
    has one cell on every non-image axis (per-pixel mode has nothing to
    guide there: the suite's grid of a deep path kind). A pilot inside the
    budget is the thesis's future work (9.3).
``pilot_fraction = 0``: the thesis's procedure (6.2.1, 8.3; default of ``guided-cosamp`` and ``guided-bilateral``)
    The pilot draws ``map_spp`` samples per cell of the map's image plane on
    top of the budget, for the map only; the guided render draws ``spp`` per
    pixel. ``sparselt reproduce`` (chapter 8) runs these two methods with
    their defaults, so it keeps the thesis's procedure.

Map sources:

``guided-pilot``
    The raw pilot cell means (luminance): the ablation any reconstruction
    must beat.
``guided-cosamp``
    The CoSaMP reconstruction of the pilot (thesis 8.3): cell means, gamma,
    CoSaMP, inverse gamma (the thesis procedure of 8.1.1), negative values
    clamped to 0.
``guided-bilateral``
    The pilot cell means filtered in 4-D by a normalised cross-bilateral
    filter whose range guide is the CoSaMP reconstruction (thesis 8.4):
    window 5x5x3x3, spatial sigma 1 cell, range sigma 2x the median absolute
    reconstruction value; unsampled cells have weight 0.

Every map is mixed with the uniform density, so the guided estimator's
variance is at most ``1 / weight`` times path tracing's; the one-sample
balance heuristic between map and uniform is the same estimator (see
:mod:`sparselt.guiding.importance_map`). Mode ``per-pixel`` (default) keeps
every pixel's spp and guides the non-image axes by the map's conditional,
with a mixture weight chosen per image cell from ``(0.1, 0.25, 0.5, 1)`` by
the cross-validated second moment of the guided estimator on the pilot's own
samples, a weight below 1 only where it helps by two standard errors (1 =
plain path tracing where the map is not shown to help); ``global``
draws cells over the image plane too, with the fixed ``defensive`` weight.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .. import kernels
from ..cell_statistics import variance_from_sums
from ..filters import cross_bilateral
from ..guiding import ImportanceMap
from ..images import luminance
from .base import WARM_UP_SEED, Budget, Method, MethodResult
from .cosamp_reconstruction import CosampOptions, reconstruct_luminance
from .options import MethodOptions, option
from .pixel_samples import cell_means, draw_pixel_samples
from .preconditions import GridMemory
from .registry import register
from .sft_reconstruction import SftOptions, reconstruct

DEFAULT_MAP_SPP = 16
DEFAULT_DEFENSIVE = 0.1
#: ``guided-pilot``'s share of the budget drawn as the (reused) pilot; 0 is the thesis's extra pilot.
DEFAULT_PILOT_FRACTION = 0.25
THESIS_PILOT_FRACTION = 0.0
PILOT_SEED_MASK = 0x5A5A5A5A  # the pilot's seed is the budget's seed XOR this (its own sample streams)
# Per-pixel mode: candidate defensive weights per image cell, chosen by cross-validation on the pilot.
DEFENSIVE_CANDIDATES = (0.1, 0.25, 0.5, 1.0)
SIGNIFICANCE_Z = 2.0  # one-sided: a weight below 1 must lower the second moment by 2 standard errors
MODES = ("per-pixel", "global")
BILATERAL_RADIUS = (2, 2, 1, 1)


@dataclass(frozen=True)
class GuidingOptions(MethodOptions):
    """The pilot pass and the mixture, shared by every guided method (thesis 6.2.1, 8.3)."""

    map_spp: int = option(DEFAULT_MAP_SPP, minimum=1, maximum=2**16 - 1, section="6.2.1, 8.3",
                          help="pilot path samples per map cell of the image plane, on top of the budget (counted "
                               "in path_samples); used by guided-sft and, with pilot_fraction = 0, by the others")
    mode: str = option("per-pixel", choices=MODES, section="6.2.1",
                       help="per-pixel: every pixel keeps its spp, the map guides the other axes; global: cells "
                            "drawn over the image plane too")
    defensive: float = option(DEFAULT_DEFENSIVE, minimum=0.0, maximum=1.0, section="6.2.1",
                              help="weight of the uniform density in the mixture (in per-pixel mode the pilot, "
                                   "CoSaMP and bilateral maps choose it per image cell by cross-validation on the "
                                   "pilot instead)")


def pilot_fraction_option(default):
    """The declaration of ``pilot_fraction`` (one help and range; the default is the method's)."""
    return option(default, minimum=0.0, maximum=1.0, maximum_inclusive=False, section="6.2.1, 9.3",
                  help="share of the budget drawn as a uniform path-traced pilot, max(1, round(fraction * spp)) per "
                       "pixel, reused in the image (combined with the guided mean by sample counts: unbiased; "
                       "the pilot in the budget is the thesis's future work 9.3); the guided render draws the rest; "
                       "0: the thesis's pilot of map_spp per map cell on top of the budget, for the map only (6.2.1)")


@dataclass(frozen=True)
class GuidedPilotOptions(GuidingOptions):
    """``guided-pilot``: the pilot in the budget by default (our variant, not a thesis procedure)."""

    pilot_fraction: float = pilot_fraction_option(DEFAULT_PILOT_FRACTION)


@dataclass(frozen=True)
class GuidedCosampOptions(GuidingOptions, CosampOptions):
    """A guided method whose map is a CoSaMP reconstruction (8.3, 8.4): the thesis's extra pilot by default."""

    pilot_fraction: float = pilot_fraction_option(THESIS_PILOT_FRACTION)


@dataclass(frozen=True)
class GuidedSftOptions(GuidingOptions, SftOptions):
    """A guided method whose map is the SFT reconstruction (6.2)."""


def render_with_map(context, importance, budget, mode):
    """The guided render of ``context`` with ``importance`` (an ImportanceMap over the grid)."""
    densities = importance.cell_densities(0 if mode == "global" else 2)
    return context.scene.render_guided(context.layout, importance.shape, importance.level_tables(), densities,
                                       budget.spp, budget.seed, mode=mode)


#: A guided method's peak memory beyond PT's per grid cell (the importance map, its conditionals and tables, the
#: pilot's cell means), measured with ``guided-pilot`` on cornell-box's path grid at 16x16, 32x32 and 64x64 image
#: cells of 4^8 (49, 45, 46 bytes: a 64x64 film at that grid peaked at 12.3 GB) and on dof-sculptures' 64x64x32x32
#: (55 bytes); with about 15% to spare. ``guided-cosamp`` measured 64 there, ``guided-bilateral`` 114.
GUIDED_BYTES_PER_CELL = 64.0


class _GuidedMethod(Method):
    kinds = ("dof", "indirect", "path")
    family = "guided"
    needs_resolution_multiple = True
    requires = (GridMemory(GUIDED_BYTES_PER_CELL),)
    Options = GuidedPilotOptions

    def warm_up(self, context):
        in_budget = self.options.get("pilot_fraction", THESIS_PILOT_FRACTION) > 0  # guided-sft: no such option
        pilot_resolution = tuple(context.resolution) if in_budget else tuple(context.grid_shape[:2])
        draw_pixel_samples(context, Budget(spp=1, seed=WARM_UP_SEED), resolution=pilot_resolution)
        if in_budget:  # the fallback to plain path tracing
            context.scene.render_estimator(context.layout, 1, WARM_UP_SEED)
        kernels.warm_up()  # the numba loops of the map's CoSaMP reconstruction
        uniform = ImportanceMap(np.ones(context.grid_shape), defensive=1.0)
        render_with_map(context, uniform, Budget(spp=1, seed=WARM_UP_SEED), self.options.mode)

    def run(self, context, budget, timer):
        if self.options.pilot_fraction > 0:
            return self._run_pilot_in_budget(context, budget, timer)
        return self._run_thesis_pilot(context, budget, timer)

    def pilot_split(self, spp):
        """``(pilot, guided)`` samples per pixel of a budget of ``spp`` with the pilot in the budget."""
        pilot = max(1, round(self.options.pilot_fraction * spp))
        return pilot, spp - pilot

    def _run_thesis_pilot(self, context, budget, timer):
        """The thesis's procedure: ``map_spp`` pilot samples per map cell on top of the budget, for the map only."""
        options = self.options
        map_spp, mode = options.map_spp, options.mode
        with timer("sampling"):
            pilot = draw_pixel_samples(context, Budget(spp=map_spp, seed=budget.seed ^ PILOT_SEED_MASK),
                                       resolution=tuple(context.grid_shape[:2]))
        importance, details = self._importance(context, pilot, timer)
        with timer("sampling"):
            image, nonfinite = render_with_map(context, importance, budget, mode)
        width, height = context.resolution
        details.update(map_spp=map_spp, mode=mode, nonfinite_samples=nonfinite + pilot.nonfinite,
                       pilot_samples=int(pilot.values.shape[0]), pilot="thesis: map_spp per map cell, extra")
        return MethodResult(image=image, path_samples=int(pilot.values.shape[0]) + width * height * budget.spp,
                            details=details)

    def _run_pilot_in_budget(self, context, budget, timer):
        """The pilot inside the budget, per output pixel, reused in the image (module docstring)."""
        options = self.options
        mode = options.mode
        pilot_spp, guided_spp = self.pilot_split(budget.spp)
        width, height = context.resolution
        pilot_budget = Budget(spp=pilot_spp, seed=budget.seed ^ PILOT_SEED_MASK)
        details = {"pilot": "in the budget, reused", "pilot_fraction": options.pilot_fraction, "mode": mode,
                   "pilot_spp": pilot_spp, "guided_spp": guided_spp}
        fallback = None
        if guided_spp < 1:
            fallback = f"the pilot's {pilot_spp} spp leave no guided sample in a budget of {budget.spp} spp"
        elif mode == "per-pixel" and math.prod(context.grid_shape[2:]) == 1:
            fallback = ("the map's grid has one cell on every non-image axis, so in per-pixel mode it has nothing "
                        "to guide")
        elif mode == "per-pixel" and pilot_spp < 2:
            fallback = (f"{pilot_spp} pilot sample per pixel cannot cross-validate the per-cell weights "
                        "(2 needed)")
        if fallback is not None:
            with timer("sampling"):
                image, nonfinite = context.scene.render_estimator(context.layout, budget.spp, budget.seed)
            details.update(fallback=f"plain path tracing at {budget.spp} spp: {fallback}", pilot_spp=0,
                           guided_spp=0, nonfinite_samples=nonfinite)
            return MethodResult(image=image, path_samples=width * height * budget.spp, details=details)
        with timer("sampling"):
            pilot = draw_pixel_samples(context, pilot_budget)
        # Per-pixel mode chooses the weights first: where the map helps nowhere, it is not built at all.
        weights = self.select_defensive(context, options, pilot, timer) if mode == "per-pixel" else None
        if weights is not None and np.all(weights == 1.0):  # the same estimator as the map's, without the warp
            details.update(defensive_weights="per image cell, cross-validated", mean_defensive=1.0, uniform_cells=1.0,
                           map="not built: every image cell at weight 1",
                           guided_render="plain path tracing: every image cell at weight 1")
            with timer("sampling"):
                guided, nonfinite = context.scene.render_estimator(context.layout, guided_spp, budget.seed)
        else:
            importance, map_details = self._importance(context, pilot, timer, weights=weights)
            details.update(map_details)
            with timer("sampling"):
                guided, nonfinite = render_with_map(context, importance, Budget(spp=guided_spp, seed=budget.seed),
                                                    mode)
        with timer("integration"):
            combined = pilot_spp * pilot.pixel_means().astype(np.float64) + guided_spp * guided.astype(np.float64)
            image = (combined / budget.spp).astype(np.float32)
        samples = int(pilot.values.shape[0]) + width * height * guided_spp
        details.update(nonfinite_samples=nonfinite + pilot.nonfinite, pilot_samples=int(pilot.values.shape[0]))
        return MethodResult(image=image, path_samples=samples, details=details)

    def _importance(self, context, pilot, timer, weights=None):
        """The importance map built from ``pilot`` and its details.

        ``weights``: the per-cell weights when already chosen (per-pixel mode); otherwise per-pixel mode with 2
        pilot samples per pixel or more chooses them here, after building the map (the thesis procedure's order).
        """
        options = self.options
        defensive, mode = options.defensive, options.mode
        with timer("other"):
            cells, means, _ = cell_means(pilot, math.prod(context.grid_shape), context.grid_shape)
        values, details = self.map_values(context, options, cells, means, timer)
        if mode == "per-pixel" and (weights is not None or pilot.spp >= 2):
            if weights is None:
                weights = self.select_defensive(context, options, pilot, timer)
            with timer("other"):
                importance = ImportanceMap(mixed_conditionals(values, weights), defensive=0.0)
            details.update(defensive_weights="per image cell, cross-validated", mean_defensive=float(weights.mean()),
                           uniform_cells=float(np.mean(weights == 1.0)))
        else:
            with timer("other"):
                importance = ImportanceMap(values, defensive=defensive, clamp_negative=True)
            details.update(defensive=defensive)
        return importance, details

    def select_defensive(self, context, options, pilot, timer):
        """The defensive weight of each image cell, chosen on the pilot's own samples (no reference).

        The pilot's samples split in two folds; the map built from one fold is
        scored on the other fold's samples. They were drawn uniformly, so for
        a candidate weight ``a`` the per-sample difference
        ``d = f^2 / q_a - f^2`` has mean (second moment of the guided
        estimator ``f / q_a``) minus (that of path tracing). A cell takes the
        candidate of :data:`DEFENSIVE_CANDIDATES` with the most negative mean
        difference among those whose mean plus :data:`SIGNIFICANCE_Z` standard
        errors is still below zero: guiding must be shown to help in that
        cell, not merely look best among noisy estimates (the winner's curse
        of picking the smallest of several noisy numbers). Otherwise the cell
        keeps weight 1, plain path tracing.
        """
        image_cells = math.prod(context.grid_shape[:2])
        rest = math.prod(context.grid_shape[2:])
        candidates = [weight for weight in DEFENSIVE_CANDIDATES if weight < 1.0]
        sums = np.zeros((image_cells, len(candidates)))
        squares = np.zeros((image_cells, len(candidates)))
        counts = np.zeros(image_cells)
        for fold in (0, 1):
            with timer("other"):
                train, test = pilot.fold(fold), pilot.fold(1 - fold)
                cells, means, _ = cell_means(train, math.prod(context.grid_shape), context.grid_shape)
            values, _ = self.map_values(context, options, cells, means, timer)
            with timer("other"):
                conditional = _conditionals(values, image_cells, rest)
                level = luminance(test.values).astype(np.float64)
                squared = level * level
                image_cell, offset = test.cells // rest, test.cells % rest
                guided = rest * conditional[image_cell, offset]
                counts += np.bincount(image_cell, minlength=image_cells)
                for index, weight in enumerate(candidates):
                    difference = squared / (weight + (1.0 - weight) * guided) - squared
                    sums[:, index] += np.bincount(image_cell, weights=difference, minlength=image_cells)
                    squares[:, index] += np.bincount(image_cell, weights=difference * difference,
                                                     minlength=image_cells)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = sums / counts[:, None]
            variance = variance_from_sums(sums, squares, counts[:, None])
            upper = mean + SIGNIFICANCE_Z * np.sqrt(variance / counts[:, None])
        helps = (counts[:, None] >= 2) & (upper < 0)
        score = np.where(helps, mean, np.inf)
        best = np.argmin(score, axis=1)
        choice = np.where(np.isfinite(score[np.arange(image_cells), best]), np.asarray(candidates)[best], 1.0)
        return choice

    def map_values(self, context, options, cells, means, timer):  # pragma: no cover - interface
        raise NotImplementedError


def _conditionals(values, image_cells, rest):
    """Per image cell, the map's distribution over the other axes (rows sum to 1; empty rows uniform)."""
    flat = np.maximum(np.asarray(values, dtype=np.float64).reshape(image_cells, rest), 0.0)
    totals = flat.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(totals > 0, flat / np.where(totals > 0, totals, 1.0), 1.0 / rest)


def mixed_conditionals(values, weights):
    """Map values whose conditional at image cell ``p`` is ``weights[p] * uniform + (1 - weights[p]) * map``.

    Each image cell gets the same total, so the result serves the per-pixel
    mode (which uses only the conditionals).
    """
    values = np.asarray(values)
    image_cells = weights.size
    rest = values.size // image_cells
    conditional = _conditionals(values, image_cells, rest)
    mixed = weights[:, None] / rest + (1.0 - weights[:, None]) * conditional
    return mixed.reshape(values.shape)


def _scatter(cells, means, grid_shape):
    values = np.zeros(math.prod(grid_shape))
    values[cells] = means
    return values.reshape(grid_shape)


@register
class GuidedPilot(_GuidedMethod):
    name = "guided-pilot"
    description = "guided by the raw pilot cell means (the ablation), defensive mixture"

    def map_values(self, context, options, cells, means, timer):
        with timer("other"):
            return _scatter(cells, means, context.grid_shape), {"map": "pilot"}


@register
class GuidedCosamp(_GuidedMethod):
    name = "guided-cosamp"
    requires = (GridMemory(80.0),)
    kinds = ("dof", "indirect", "path")
    Options = GuidedCosampOptions
    thesis_procedure = True
    description = "guided by the CoSaMP reconstruction of the pilot (thesis 8.3), defensive mixture"

    def map_values(self, context, options, cells, means, timer):
        gamma, sparsity = options.gamma, options.sparsity
        with timer("reconstruction"):
            reconstruction, result = reconstruct_luminance(cells, means, context.grid_shape, gamma=gamma,
                                                           sparsity=sparsity)
        return reconstruction, {"map": "cosamp", "gamma": gamma, "sparsity": sparsity,
                                "cosamp_iterations": result.iterations}


@register
class GuidedBilateral(_GuidedMethod):
    name = "guided-bilateral"
    requires = (GridMemory(128.0),)
    kinds = ("dof", "indirect")
    Options = GuidedCosampOptions
    thesis_procedure = True
    description = ("guided by the pilot filtered in 4-D with the CoSaMP reconstruction as range guide (thesis 8.4), "
                   "defensive mixture")

    def map_values(self, context, options, cells, means, timer):
        gamma, sparsity = options.gamma, options.sparsity
        with timer("reconstruction"):
            reconstruction, result = reconstruct_luminance(cells, means, context.grid_shape, gamma=gamma,
                                                           sparsity=sparsity)
            sampled = np.zeros(math.prod(context.grid_shape))
            sampled[cells] = 1.0
            stacked = np.stack([_scatter(cells, means, context.grid_shape), sampled.reshape(context.grid_shape)], -1)
            scale = float(np.median(np.abs(reconstruction[reconstruction > 0]))) if np.any(reconstruction > 0) else 1.0
            sigma_range = 2.0 * scale
            filtered = cross_bilateral(stacked, [reconstruction], BILATERAL_RADIUS, 1.0, sigma_range, channel_axis=-1)
            with np.errstate(invalid="ignore", divide="ignore"):
                values = np.where(filtered[..., 1] > 0, filtered[..., 0] / filtered[..., 1], 0.0)
        return values, {"map": "bilateral", "gamma": gamma, "sparsity": sparsity, "sigma_range": sigma_range,
                        "radius": list(BILATERAL_RADIUS), "cosamp_iterations": result.iterations}


@register
class GuidedSft(_GuidedMethod):
    """Guided by the SFT reconstruction of the rendered signal over the map grid (thesis 6.2.1)."""

    name = "guided-sft"
    kinds = ("dof", "indirect", "path")
    Options = GuidedSftOptions
    #: The map's and the SFT's arrays grow faster than the grid: on cornell-box's path grid, 16x16 image cells of
    #: 4^8 (16.8M cells) peaked at 2.1 GB beyond PT's (about 120 bytes per cell); 32x32 (67M cells) was killed by
    #: the system at 24 GB after 12 minutes (over 360 bytes per cell). 400 refuses that measured failure; a bound,
    #: not a model.
    requires = (GridMemory(400.0),)
    thesis_procedure = True
    description = ("guided by the Sparse Fourier Transform reconstruction over the map grid (thesis 6.2; "
                   "map_spp path samples per lattice point, K = N/10^4 by default), defensive mixture; "
                   "the SFT's samples and time are counted")

    def warm_up(self, context):
        super().warm_up(context)
        small = dataclasses.replace(self.options, sparsity=1)
        reconstruct(context, 1, WARM_UP_SEED, small)

    def run(self, context, budget, timer):
        options = self.options
        result = reconstruct(context, options.map_spp, budget.seed ^ PILOT_SEED_MASK, options)
        timer.seconds["sampling"] += result.seconds["sampling"]
        timer.seconds["reconstruction"] += result.seconds["reconstruction"]
        with timer("reconstruction"):
            values = luminance(result.signal()).astype(np.float64)  # eq. 6.3: pdf proportional to R, negatives clamped
        with timer("other"):
            importance = ImportanceMap(values, defensive=options.defensive, clamp_negative=True)
        with timer("sampling"):
            image, nonfinite = render_with_map(context, importance, budget, options.mode)
        width, height = context.resolution
        details = {"map": "sft", "map_spp": options.map_spp, "mode": options.mode, "defensive": options.defensive,
                   "sparsity": options.sparsity, "alpha": options.alpha, "snr_db": options.snr,
                   "map_samples": result.path_samples, "support_samples": result.support_samples,
                   "magnitude_samples": result.magnitude_samples, "nonfinite_samples": nonfinite + result.nonfinite}
        return MethodResult(image=image, path_samples=result.path_samples + width * height * budget.spp,
                            details=details)
