r"""Methods ``gradient-l2`` and ``gradient-l1``: gradient-domain path tracing in primary sample space.

Kettunen et al. (2015) trace, for each base path of a pixel, an *offset* path
at each neighbouring pixel, obtained from the base path by a shift map, and
estimate the image's finite differences from the pairs; the image is rebuilt
from the noisy primal image and the noisy gradients by a screened Poisson
solve. A shift that keeps the pair's paths close makes the difference's
variance far lower than that of two independent estimates.

**The shift** (:func:`~sparselt.rendering.mitsuba.gradients.sample_gradients`).
Our sampler evaluates a path at an explicit point of primary sample space, so
the simplest shift is a translation there: the offset path replays the base
path's random numbers (lens, light, BSDF and lobe samples) with the film
position moved by exactly one pixel. A translation of the unit cube's film
coordinates has Jacobian 1, and it maps pixel ``p``'s box onto its
neighbour's, so the offset path is a uniformly distributed sample of the
neighbour: ``f(T u) - f(u)`` is an unbiased estimate of ``I(p + 1) - I(p)``
(Manzi et al. 2015 and Kettunen et al. 2015 call the general version the
"random replay" of primary samples). With the 4 neighbours of the paper, the
difference between ``p`` and ``p + 1`` is estimated twice per sample (the
``+x`` offset of ``p``'s base and the ``-x`` offset of ``p + 1``'s); the two
are averaged, the balance heuristic of the two techniques, which have the
same density 1 in primary sample space. The primal image is the mean of every
path that lands in the pixel: its base paths and its neighbours' offsets, all
uniform samples of its box (correlated with the neighbours', unbiased). Every
path counts in the budget: ``--spp`` is base samples per pixel, and a base
sample costs ``1 + offsets`` paths.

**Where the shift fails** (is unbiased but does not correlate). The offset
keeps the base path's *local* directions, so it tracks the base path only
while both see the same surface with similar normals: across a silhouette or
a depth discontinuity the shifted camera ray lands on different geometry and
the whole path differs; after a rough bounce small differences in the hit
point grow with distance; an emitter seen directly, or a caustic seen through
glass, is an on/off difference at its edge. There the gradient sample is as
noisy as two independent paths, or worse (the paper's reconnection shift
does better on diffuse vertices; it is not built). Film edges have no
outward offset.

**Emitters seen directly** (option ``direct_emission``). The part of a path's
contribution that is emission seen by the camera ray itself
(``camera_emission``, returned by the same launch) is a step at the emitter's
silhouette: a pair straddling it differs by the emitter's radiance, a gradient
sample as noisy as the pixels themselves, and the Poisson solve spreads that
noise over the neighbourhood. Measured on cornell-box (path, depth 3, 250x250,
3 seeds), with everything reconstructed as in the paper: 86-93% of
``gradient-l2``'s relMSE lies within 5 pixels of the light (1.5% of the
pixels), and elsewhere its relMSE is 13x below PT's at the same spp. By
default (``'primal'``) that part is therefore left out of the gradients and
added back from the primal image after the solve: the two parts are estimated
from the same paths, both unbiased, so ``gradient-l2`` stays unbiased.
``'gradient'`` is the paper's way (everything through the gradients).

**Texture** (option ``demodulation``). Where the albedo changes from pixel
to pixel, a base path and its offset see different reflectances: even when
their incident light is perfectly correlated, their difference
``a(p+1) L' - a(p) L`` carries the full noise of ``L`` times the albedo
step, and on a textured scene the gradients are hardly better than two
independent pixels. With ``'albedo'`` every path's contribution is
divided by the mean first-hit diffuse albedo ``A(q)`` of the pixel ``q`` it
lands in (reduced in the sampling launch from the same paths), per channel,
before the primal and the gradients are formed; the solve rebuilds the
demodulated image ``E = I / A``, whose gradients are those of the lighting
alone, and the image is ``A E``. Dividing a pixel's sums by one number is
linear, so the gradients of ``E`` are estimated as before; ``A`` comes from
the same paths, so the image is consistent (its bias, that of a ratio
estimator at the few pixels whose albedo varies within the pixel, vanishes
with spp) rather than unbiased. A channel whose albedo is at most
``albedo_floor`` (mirrors, glass, emitters, the sky) is not demodulated
(divided by 1), so regions whose light is not ``albedo x irradiance`` keep
the image's own scale. This is the albedo demodulation of denoisers
(Zimmer et al. 2015; Bako et al. 2017) applied to the gradient-domain
estimates; ``'none'``, the paper's estimator, is the default: on the
standard suite's scenes at 256x256 (``docs/experiments/ablation-demodulation``)
demodulation lowered the error by a few percent on textured scenes and raised
it by as much elsewhere (``gradient-l2`` on the courtyard: 14%). The final
image multiplies the smooth solution by the pixel's albedo *estimate*, whose
own noise at pixels that straddle texture edges (sub-pixel texture) is no
longer cancelled by the division, and that noise is of the order of what the
gradients gained. Kettunen et al.'s reconnection shift, which keeps the
offset path's light path and changes only its first vertex, is the remedy
the paper gives; it is not built.

**Reconstruction** (:mod:`sparselt.recovery.poisson`). ``gradient-l2``: the
screened Poisson solution ``min alpha^2 |I - P|^2 + |D_x I - G_x|^2 + |D_y I
- G_y|^2`` by one DCT-II (Neumann), ``alpha = 0.2``; linear in its inputs, so
unbiased. ``gradient-l1``: the same objective with the L1 norm by ADMM over
the same DCT solve (biased, robust to the gradients' outliers, as in the
paper's "L1" reconstructions).

References
----------
Kettunen, M., Manzi, M., Aittala, M., Lehtinen, J., Durand, F., Zwicker, M.
(2015). Gradient-domain path tracing. ACM TOG 34(4), 123. Zimmer, H.,
Rousselle, F., Jakob, W., Wang, O., Adler, D., Jarosz, W., Sorkine-Hornung,
O., Sorkine-Hornung, A. (2015). Path-space motion estimation and
decomposition for robust animation filtering. CGF 34(4). Bako, S. et al.
(2017). Kernel-predicting convolutional networks for denoising Monte Carlo
renderings. ACM TOG 36(4). Manzi, M.,
Kettunen, M., Aittala, M., Lehtinen, J., Durand, F., Zwicker, M. (2015).
Gradient-domain bidirectional path tracing. EGSR.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..recovery.poisson import DEFAULT_ALPHA, screened_poisson, screened_poisson_l1
from ..rendering.mitsuba.gradients import GRADIENT_SHIFTS, gradient_paths
from .base import WARM_UP_SEED, Budget, Method, MethodResult, PhaseTimer
from .options import MethodOptions, option
from .preconditions import FilmResolution
from .registry import register


@dataclass(frozen=True)
class GradientOptions(MethodOptions):
    """Options both gradient-domain methods share."""

    alpha: float = option(DEFAULT_ALPHA, minimum=0.0, minimum_inclusive=False,
                          help="weight of the primal image against the gradients (Kettunen et al. 2015: 0.2)")
    offsets: int = option(4, choices=(4, 2), help="offset paths per base sample: the 4 neighbours (as in the "
                          "paper) or +x and +y only")
    direct_emission: str = option("primal", choices=("primal", "gradient"),
                                  help="emitters seen directly by the camera ray: from the primal image, added "
                                       "after the solve ('primal'), or through the gradients like the rest "
                                       "('gradient', as in the paper)")
    demodulation: str = option("none", choices=("albedo", "none"),
                               help="divide every path by its pixel's mean first-hit diffuse albedo before "
                                    "differencing and multiply it back after the solve ('albedo'), or not "
                                    "('none', as in the paper; the ablation of issue 37 found no consistent gain)")
    albedo_floor: float = option(0.02, minimum=0.0, maximum=1.0,
                                 help="a channel whose pixel albedo is at most this is not demodulated")


@dataclass(frozen=True)
class GradientL2Options(GradientOptions):
    """``gradient-l2``: the shared options only."""


@dataclass(frozen=True)
class GradientL1Options(GradientOptions):
    max_iterations: int = option(50, minimum=1, help="ADMM iterations at most")
    tolerance: float = option(1e-3, minimum=0.0, minimum_inclusive=False,
                              help="stop when an iteration moves the image by less than this times its norm")


def gradient_estimates(sums, spp):
    """The primal image and the two gradient images from the per-pixel sums of base and offset paths.

    Parameters
    ----------
    sums : ndarray, shape (height, width, 1 + offsets, 3)
        :func:`~sparselt.rendering.mitsuba.gradients.sample_gradients`'
        sums: base paths at index 0, the offsets of
        :data:`~sparselt.rendering.mitsuba.GRADIENT_SHIFTS` after.
    spp : int
        Base samples per pixel.

    Returns
    -------
    primal : ndarray, shape (height, width, 3)
        The mean of every path landing in the pixel (its base paths and its
        neighbours' offsets).
    gradient_x : ndarray, shape (height, width - 1, 3)
        Estimates of ``I(y, x + 1) - I(y, x)``: the mean over every base/offset
        pair that spans the two pixels (one or two per sample).
    gradient_y : ndarray, shape (height - 1, width, 3)
        The same along ``y``.
    """
    sums = np.asarray(sums, dtype=np.float64)
    height, width, paths, _ = sums.shape
    shifts = GRADIENT_SHIFTS[paths - 1]
    base = sums[:, :, 0]
    primal = base.copy()
    landed = np.ones((height, width))
    gradients = {"x": [np.zeros((height, width - 1, 3)), 0], "y": [np.zeros((height - 1, width, 3)), 0]}
    for k, (dx, dy) in enumerate(shifts, start=1):
        offset = sums[:, :, k]
        source, target = _landing(height, width, dx, dy)
        primal[target] += offset[source]
        landed[target] += 1.0
        axis = "x" if dx else "y"
        # A +1 shift estimates I(base + 1) - I(base) at the base; a -1 shift, I(base) - I(base - 1) at base - 1.
        difference = (offset - base)[source] if dx + dy > 0 else (base - offset)[source]
        gradients[axis][0] += difference
        gradients[axis][1] += 1
    primal /= spp * landed[..., None]
    gradient_x = gradients["x"][0] / (spp * gradients["x"][1])
    gradient_y = gradients["y"][0] / (spp * gradients["y"][1])
    return primal, gradient_x, gradient_y


def _landing(height, width, dx, dy):
    """The base pixels whose offset by ``(dx, dy)`` lands inside the film, and the pixels it lands in (slices)."""
    source = (slice(max(0, -dy), height - max(0, dy)), slice(max(0, -dx), width - max(0, dx)))
    target = (slice(max(0, dy), height - max(0, -dy)), slice(max(0, dx), width - max(0, -dx)))
    return source, target


def demodulation_divisors(albedo_sums, spp, floor):
    """Each pixel's demodulation divisor, and the divisor of every (base pixel, shift) path: its landing pixel's.

    Parameters
    ----------
    albedo_sums : ndarray, shape (height, width, 1 + offsets, 3)
        :class:`~sparselt.rendering.mitsuba.gradients.GradientSamples`'
        ``albedo``: sums of the first hits' diffuse albedo per base pixel and shift.
    spp : int
        Base samples per pixel.
    floor : float
        A channel whose pixel albedo is at most this is divided by 1.

    Returns
    -------
    pixel : ndarray, shape (height, width, 3)
        ``A(q)``, the mean first-hit albedo of every path landing in ``q``
        (the primal estimate of the albedo), or 1 where it is at most ``floor``.
    paths : ndarray, shape (height, width, 1 + offsets, 3)
        The divisor of the sums of each base pixel and shift: ``pixel`` at the
        pixel the path lands in (1 for offsets outside the film).
    """
    albedo = gradient_estimates(albedo_sums, spp)[0]
    pixel = np.where(albedo > floor, albedo, 1.0)
    height, width, paths_per_base, _ = albedo_sums.shape
    paths = np.ones(albedo_sums.shape)
    paths[:, :, 0] = pixel
    for k, (dx, dy) in enumerate(GRADIENT_SHIFTS[paths_per_base - 1], start=1):
        source, target = _landing(height, width, dx, dy)
        paths[source[0], source[1], k] = pixel[target]
    return pixel, paths


class _GradientDomain(Method):
    """Sampling (base and offset paths in one kernel), the estimates, a reconstruction: both methods' pipeline."""

    kinds = ("dof", "indirect", "path", "path-indirect")
    family = "gradient"
    requires = (FilmResolution(),)

    def warm_up(self, context):
        self.run(context, Budget(spp=2, seed=WARM_UP_SEED), PhaseTimer())

    def run(self, context, budget, timer):
        options = self.options
        width, height = context.resolution
        if (width, height) != (context.scene.width, context.scene.height):
            raise ValueError(f"{self.name} renders at the scene's film resolution {context.scene.width}x"
                             f"{context.scene.height}, got an output resolution {width}x{height}")
        with timer("sampling"):
            samples = context.scene.sample_gradients(context.layout, context.grid_shape, budget.spp, budget.seed,
                                                     offsets=options.offsets)
        with timer("integration"):
            sums = samples.sums
            separate = options.direct_emission == "primal" and context.layout.count_camera_emission
            if separate:
                sums = sums - samples.camera_emission
            demodulate = options.demodulation == "albedo"
            if demodulate:
                albedo, divisors = demodulation_divisors(samples.albedo, budget.spp, options.albedo_floor)
                sums = sums / divisors
            primal, gradient_x, gradient_y = gradient_estimates(sums, budget.spp)
        with timer("reconstruction"):
            result = self.reconstruct(options, primal, gradient_x, gradient_y)
            image = result.estimate * albedo if demodulate else result.estimate
            if separate:
                image = image + gradient_estimates(samples.camera_emission, budget.spp)[0]
        paths = budget.spp * gradient_paths(width, height, options.offsets)
        details = {"offsets": options.offsets, "alpha": options.alpha, "direct_emission": options.direct_emission,
                   "demodulation": options.demodulation, "albedo_floor": options.albedo_floor,
                   "demodulated_fraction": float(np.mean(albedo != 1.0)) if demodulate else 0.0,
                   "iterations": result.iterations,
                   "stop_reason": result.stop_reason, "nonfinite_samples": samples.nonfinite,
                   "paths_per_base_sample": paths / (budget.spp * width * height)}
        return MethodResult(image=np.asarray(image, dtype=np.float32), path_samples=int(paths), details=details)

    def reconstruct(self, options, primal, gradient_x, gradient_y):  # pragma: no cover - interface
        raise NotImplementedError


@register
class GradientL2(_GradientDomain):
    """Gradient-domain path tracing, screened Poisson L2 reconstruction (Kettunen et al. 2015, 4)."""

    name = "gradient-l2"
    Options = GradientL2Options
    description = ("gradient-domain path tracing: base paths and their one-pixel shifts in primary sample space, "
                   "screened Poisson L2 solve by one DCT (unbiased)")

    def reconstruct(self, options, primal, gradient_x, gradient_y):
        return screened_poisson(primal, gradient_x, gradient_y, alpha=options.alpha)


@register
class GradientL1(_GradientDomain):
    """Gradient-domain path tracing, L1 reconstruction by ADMM over the DCT solve (Kettunen et al. 2015, 4)."""

    name = "gradient-l1"
    Options = GradientL1Options
    description = ("gradient-domain path tracing with the L1 reconstruction (ADMM over the DCT solve; biased, "
                   "robust to outlying gradients)")

    def reconstruct(self, options, primal, gradient_x, gradient_y):
        return screened_poisson_l1(primal, gradient_x, gradient_y, alpha=options.alpha,
                                   tolerance=options.tolerance, max_iterations=options.max_iterations)
