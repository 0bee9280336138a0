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
noisy as two independent paths, or worse. Film edges have no outward offset.

**The reconnection shift** (option ``shift='reconnection'``,
:mod:`sparselt.rendering.mitsuba.reconnection`): the offset replays the base
up to its first hit and then reconnects to the base's second vertex where
both samples are rough (Kettunen et al. 2015, 5.1), so the pair shares all
the light beyond ``x2``; the pairs are weighted from both sides (multiple
importance sampling), which keeps the estimates unbiased where the
reconnection fails. Its price: the offsets no longer bring new light paths,
so the primal image has one independent tail per base sample instead of
five, and its kernel is larger. Measured in ``docs/experiments/ablation-shift``
(2x on cornell-box and courtyard) and over the whole standard suite in
``docs/experiments/suite-gradient-reconnection`` (0.32x on mirror-room, where
mirrors make the two sides choose different shifts and the pairs fall back to
uncorrelated differences, and a loss on thin-geometry): the default stays
``'replay'``.

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
the paper gives (``shift='reconnection'``, above).

**Reconstruction** (:mod:`sparselt.recovery.poisson`). ``gradient-l2``: the
screened Poisson solution ``min alpha^2 |I - P|^2 + |D_x I - G_x|^2 + |D_y I
- G_y|^2`` by one DCT-II (Neumann); with a fixed alpha (``alpha_choice=
'fixed'``, the paper's 0.2) linear in its inputs, so unbiased.
``gradient-l1``: the same objective with the L1 norm by ADMM over the same
DCT solve (biased, robust to the gradients' outliers, as in the paper's "L1"
reconstructions).

**The choice of alpha** (option ``alpha_choice``, default ``'held-out'``).
How much the gradients should be trusted depends on the scene: where the
shift correlates the pair (diffuse surfaces) a small alpha wins; where it
does not (fireflies, caustics, depth of field through glossy objects) the
gradients are noisier than the pixels and any fixed alpha loses to path
tracing (issue 37 measured 0.17-0.58x). The samples are drawn as two
independent halves (base samples below ``spp // 2`` and the rest, reduced
apart in the same launch); each half's L2
reconstruction, for each alpha of a factor-2 ladder around 0.2 and for the
primal image alone, is scored against the *other* half's primal image
(:func:`~sparselt.recovery.poisson.held_out_alpha`: an unbiased estimate of
its squared error up to a constant, weighted like relMSE), and the best
alpha reconstructs all the samples. No reference is used; the cost is two
launches and a few inverse DCTs. Where the gradients are judged useless the
image is the primal image: path tracing with the offset paths as its
samples. The choice depends on the samples, so the image is consistent
(its bias vanishes with spp) rather than unbiased. One sample per pixel
cannot be halved and keeps ``alpha``.

**The choice of shift** (option ``shift='auto'``). Neither shift wins
everywhere: reconnection doubled the speed-up on diffuse interiors and lost
on mirrors and thin geometry (above). With ``'auto'`` a pilot of a quarter of
the base samples (:func:`pilot_spp`, at least 2) is drawn with each shift,
each in two halves and with its own random numbers (:func:`shift_seed`);
:func:`~sparselt.recovery.poisson.held_out_choice` scores every (shift,
alpha) pair by how well one half's L2 reconstruction predicts the mean of
*both* shifts' other-half primal images (a judge shared by every candidate,
so the score compares reconstruction errors, not the primal images' own
noise), and the rest of the base samples is drawn with the winner, its
pilot's samples kept. ``replay`` is the default: reconnection replaces it
only where its score is lower by more than 2 standard errors (a near-tie
on a pilot is decided by noise, and reconnection costs more per sample).
The losing pilot is spent: a quarter more base samples than ``spp``, all
counted. No reference is used. Measured over the suite
(``docs/experiments/suite-shift-auto`` and
``suite-shift-auto-significance``): worse than plain replay on most scenes
(the pilot's extra quarter, and wrong choices on depth of field at 16 spp),
so ``'replay'`` stays the default.

**L1 only where it pays** (``gradient-l1``, option ``l1_check``, default
``'held-out'``). The L1 solve costs tens of DCT solves (about 0.1 s at
256x256) and is not always better than the L2 one: on outdoor-texture its
image was 5-7% worse and 4% darker (L1's median bias under sunlight), at 64
spp on dof-sculptures and cornell-box 0-4% worse
(``docs/experiments/study-l1-iterations``). With the held-out halves at
hand, each half is reconstructed both ways at the chosen alpha (the L1 one
with a few ADMM iterations) and judged by the other half's primal image
(:func:`~sparselt.recovery.poisson.held_out_l1_check`, a paired difference:
the judge's own noise cancels). The L1 solve of all the samples runs only
where the L1 images are better by more than 2 standard errors; elsewhere the
L2 image (one DCT) is the result. ``'always'`` is the paper's L1 solve.

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

from ..kernels import replay_estimates
from ..recovery.poisson import (DEFAULT_ALPHA, HELD_OUT_ALPHAS, L1_CHECK_ITERATIONS, held_out_alpha, held_out_choice,
                                held_out_l1_check, screened_poisson, screened_poisson_l1)
from ..recovery.result import RecoveryResult
from ..rendering.mitsuba.gradients import GRADIENT_SHIFTS, SHIFT_MAPS, gradient_paths
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
    alpha_choice: str = option("held-out", choices=("held-out", "fixed"),
                               help="'held-out': alpha from a ladder around 0.2 (or the primal image alone) by how "
                                    "well one half of the samples' L2 reconstruction predicts the other half's primal "
                                    "image (no reference used); 'fixed': the option alpha, as in the paper")
    shift: str = option("replay", choices=SHIFT_MAPS + ("auto",),
                        help="the shift map: replay every random number at the neighbour ('replay'), or replay up "
                             "to the first hit and reconnect to the base's second vertex where both samples are "
                             "rough ('reconnection', Kettunen et al. 2015, 5.1; needs offsets=4: 2x on diffuse "
                             "interiors, 0.3x on mirror-room, docs/experiments/suite-gradient-reconnection), or "
                             "chosen per image ('auto': a pilot of a quarter of the base samples with each shift, "
                             "judged on held-out halves; the rest with the winner)")

    def __post_init__(self):
        if self.shift in ("reconnection", "auto") and self.offsets != 4:
            raise ValueError(f"shift={self.shift!r} needs offsets=4 (the reconnection's pairs are weighted from both "
                             f"sides), got offsets={self.offsets}: give shift=replay with offsets=2")
        if self.shift == "auto" and self.demodulation != "none":
            raise ValueError(f"shift='auto' needs demodulation='none' (the pilots are judged before the albedo of "
                             f"all the samples is known), got demodulation={self.demodulation!r}")


@dataclass(frozen=True)
class GradientL2Options(GradientOptions):
    """``gradient-l2``: the shared options only."""


@dataclass(frozen=True)
class GradientL1Options(GradientOptions):
    max_iterations: int = option(50, minimum=1, help="ADMM iterations at most")
    tolerance: float = option(1e-3, minimum=0.0, minimum_inclusive=False,
                              help="stop when an iteration moves the image by less than this times its norm")
    l1_check: str = option("held-out", choices=("held-out", "always"),
                           help="'held-out': the L1 solve only where each half's L1 image (check_iterations) "
                                "predicts the other half's primal image better than its L2 image by more than 2 "
                                "standard errors, else the L2 image (one DCT); it needs the held-out halves "
                                "(alpha_choice='held-out', shift other than 'auto'), without them the L1 solve runs; "
                                "'always': the L1 solve, as in the paper")
    check_iterations: int = option(L1_CHECK_ITERATIONS, minimum=1, help="ADMM iterations of each half's L1 solve in "
                                   "the held-out check")


def gradient_estimates(sums, spp, pairs=None, replayed=None, emission=None):
    """The primal image and the two gradient images from the per-pixel sums of base and offset paths.

    Parameters
    ----------
    sums : ndarray, shape (height, width, 1 + offsets, 3)
        :func:`~sparselt.rendering.mitsuba.gradients.sample_gradients`'
        sums: base paths at index 0, the offsets of
        :data:`~sparselt.rendering.mitsuba.GRADIENT_SHIFTS` after.
    spp : int
        Base samples per pixel.
    pairs, replayed : ndarray, optional
        The reconnection shift's weighted tails and replayed parts
        (:class:`~sparselt.rendering.mitsuba.gradients.GradientSamples`).
        With them the replayed parts are estimated from ``replayed`` as
        below, and the tails as each pixel's mean over its neighbours of the
        pair's two-sided estimate and each gradient as the sum of the two
        sides' weighted differences (:mod:`sparselt.rendering.mitsuba.reconnection`);
        ``sums`` is then not used. Without them
        :func:`sparselt.kernels.replay_estimates` forms the estimates on every core.
    emission : ndarray, optional
        Without ``pairs``: subtracted from ``sums`` where they are read (the
        emission seen directly, estimated apart), no difference array formed.

    Returns
    -------
    primal : ndarray, shape (height, width, 3)
        The mean of every path that lands in the pixel (its base paths and its
        neighbours' offsets); with ``pairs``, the mean of its pairs' estimates.
    gradient_x : ndarray, shape (height, width - 1, 3)
        Estimates of ``I(y, x + 1) - I(y, x)``: the mean over every base/offset
        pair that spans the two pixels (one or two per sample).
    gradient_y : ndarray, shape (height - 1, width, 3)
        The same along ``y``.
    """
    sums = np.asarray(sums)
    shifts = GRADIENT_SHIFTS[sums.shape[2] - 1]
    if pairs is not None:
        replayed_estimates = gradient_estimates(replayed, spp)
        tail_estimates = _pair_estimates(np.asarray(pairs, dtype=np.float64), spp, shifts)
        return tuple(first + second for first, second in zip(replayed_estimates, tail_estimates))
    return replay_estimates(sums, shifts, spp, emission)


def _pair_estimates(pairs, spp, shifts):
    """:func:`gradient_estimates` from two-sided weighted pair sums: each pair ``(p, p + s)`` estimates ``I(p)`` by
    ``W_base(p, s) + W_offset(p + s, -s)`` and ``I(p + s) - I(p)`` by the sum of both sides' weighted differences."""
    height, width = pairs.shape[:2]
    primal = np.zeros((height, width, 3))
    partners = np.zeros((height, width))
    gradients = {"x": np.zeros((height, width - 1, 3)), "y": np.zeros((height - 1, width, 3))}
    for k, (dx, dy) in enumerate(shifts):
        base, offset = pairs[:, :, k, 0], pairs[:, :, k, 1]
        source, target = _landing(height, width, dx, dy)
        primal[source] += base[source]
        primal[target] += offset[source]
        partners[source] += 1.0
        axis = "x" if dx else "y"
        gradients[axis] += (offset - base)[source] if dx + dy > 0 else (base - offset)[source]
    return primal / (spp * partners[..., None]), gradients["x"] / spp, gradients["y"] / spp


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


def pilot_spp(spp):
    """``shift='auto'``'s pilot: base samples per pixel drawn with each shift, a quarter of ``spp``, at least 2
    (two halves) and at most ``spp``."""
    return min(spp, max(2, spp // 4))


def shift_seed(seed, index):
    """The seed of ``shift='auto'``'s draw ``index`` (0, 1: the pilots of :data:`SHIFT_MAPS`' shifts; 2: the rest):
    ``seed`` itself for the first, hashed beyond 32 bits for the others (independent random numbers;
    :func:`~sparselt.rendering.mitsuba.launch.fold_seed`)."""
    return seed + index * (1 << 32)


def _score_key(key):
    """A held-out score's key as text: the alpha, or the shift and alpha of ``shift='auto'``."""
    return str(key) if not isinstance(key, tuple) else f"{key[0]}:{key[1]}"


#: :class:`~sparselt.rendering.mitsuba.gradients.GradientSamples`' per-path sums (the estimates' inputs).
PATH_SUMS = ("sums", "replayed", "pairs")


def _merged(parts, *, paths=True, unused=()):
    """One :class:`~sparselt.rendering.mitsuba.gradients.GradientSamples` of several draws: their sums added
    (without ``paths``, :data:`PATH_SUMS` are left None: the caller estimates from the parts; the fields named in
    ``unused`` are left None too: at 1024x576 each sum is a 70 MB pass)."""
    if len(parts) == 1:
        return parts[0]

    def total(name):
        values = [getattr(part, name) for part in parts]
        if values[0] is None or (not paths and name in PATH_SUMS) or name in unused:
            return None
        return sum(values[1:], values[0])

    return parts[0]._replace(**{name: total(name) for name in parts[0]._fields})


def _estimates(samples, spp, separate, divisors):
    """The primal and gradient estimates of ``samples``: without the emission seen directly if ``separate``,
    demodulated by ``divisors`` (:func:`demodulation_divisors`' per-path divisors) if given."""
    sums, replayed, pairs = samples.sums, samples.replayed, samples.pairs
    if separate and pairs is None and divisors is None:  # subtracted where the estimates read the sums
        return gradient_estimates(sums, spp, emission=samples.camera_emission)
    if separate:
        sums = sums - samples.camera_emission
        replayed = None if replayed is None else replayed - samples.camera_emission
    if divisors is not None:
        sums = sums / divisors
        if pairs is not None:
            replayed = replayed / divisors
            pairs = pairs / np.stack([divisors[:, :, :1].repeat(divisors.shape[2] - 1, axis=2), divisors[:, :, 1:]],
                                     axis=3)
    return gradient_estimates(sums, spp, pairs, replayed)


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
        separate = options.direct_emission == "primal" and context.layout.count_camera_emission
        if options.shift == "auto" and budget.spp >= 2:
            drawn, shift, alpha, scores, pilot = self._choose_shift(context, budget, separate, timer)
            part_spps = None
        else:
            shift, pilot = ("replay" if options.shift == "auto" else options.shift), 0
            held_out = options.alpha_choice == "held-out" and budget.spp >= 2
            # Held out: two independent halves of the samples (base samples below spp // 2 and the rest, reduced
            # apart in the same launch), so that each half's primal image can judge the other's reconstruction.
            with timer("sampling"):
                drawn = self._sample(context, budget.spp, budget.seed, shift, halves=held_out)
                drawn = list(drawn) if held_out else [drawn]
            part_spps = (budget.spp // 2, budget.spp - budget.spp // 2) if held_out else None
            alpha, scores = options.alpha, None
        with timer("integration"):
            # With halves, the estimates of all the samples are the halves' weighted by their spp (the estimates
            # are linear in the sums), so the path sums are not added up.
            demodulate = options.demodulation == "albedo"
            samples = _merged(drawn, paths=not part_spps, unused=tuple(
                name for name, needed in (("albedo", demodulate), ("camera_emission", separate)) if not needed))
            albedo, divisors = (demodulation_divisors(samples.albedo, budget.spp, options.albedo_floor)
                                if demodulate else (None, None))
            if part_spps:
                halves = [_estimates(part, spp, separate, divisors) for part, spp in zip(drawn, part_spps)]
                primal, gradient_x, gradient_y = (
                    (part_spps[0] * first + part_spps[1] * second) / budget.spp
                    for first, second in zip(*halves))
            else:
                halves = None
                primal, gradient_x, gradient_y = _estimates(samples, budget.spp, separate, divisors)
        with timer("reconstruction"):
            l2_images = None
            if halves:
                alpha, scores, half_images = held_out_alpha(halves, return_images=True)
                if np.isfinite(alpha):
                    # The L2 solution is linear in the estimates, and the estimates of all the samples are the
                    # halves' weighted by their spp: so is the L2 image of all the samples (no third solve).
                    first, second = half_images[alpha]
                    l2_images = ((part_spps[0] * first.astype(np.float64) + part_spps[1] * second) / budget.spp,
                                 (first, second))
            solver_details = {}
            if np.isfinite(alpha):
                result, solver_details = self.reconstruct(options, alpha, primal, gradient_x, gradient_y, halves,
                                                          l2_images)
                estimate, iterations, stop_reason = result.estimate, result.iterations, result.stop_reason
            else:  # the gradients judged useless: the primal image (every path of the pixel, PT's estimator)
                estimate, iterations, stop_reason = primal, 0, "primal"
            image = estimate * albedo if demodulate else estimate
            if separate:
                image = image + gradient_estimates(samples.camera_emission, budget.spp)[0]
        # The pilot with the shift that lost is spent too.
        paths = (budget.spp + pilot) * gradient_paths(width, height, options.offsets)
        details = {"offsets": options.offsets, "shift": options.shift, "shift_used": shift, "pilot_spp": pilot,
                   "alpha": float(alpha),
                   "alpha_choice": options.alpha_choice,
                   "alpha_scores": {_score_key(key): value for key, value in scores.items()} if scores else None,
                   "direct_emission": options.direct_emission,
                   "demodulation": options.demodulation, "albedo_floor": options.albedo_floor,
                   "demodulated_fraction": float(np.mean(albedo != 1.0)) if demodulate else 0.0,
                   "iterations": iterations, "stop_reason": stop_reason, "nonfinite_samples": samples.nonfinite,
                   "paths_per_base_sample": paths / (budget.spp * width * height), **solver_details}
        return MethodResult(image=np.asarray(image, dtype=np.float32), path_samples=int(paths), details=details)

    def _choose_shift(self, context, budget, separate, timer):
        """``shift='auto'``: a pilot of :func:`pilot_spp` base samples per pixel with each shift, in independent
        halves, judged by :func:`~sparselt.recovery.poisson.held_out_choice` (with alpha); the rest of the base
        samples with the winner, its pilot's samples kept. Returns ``(drawn, shift, alpha, scores, pilot_spp)``."""
        options = self.options
        pilot = pilot_spp(budget.spp)
        alphas = HELD_OUT_ALPHAS if options.alpha_choice == "held-out" else (options.alpha,)
        with timer("sampling"):
            pilots = {shift: list(self._sample(context, pilot, shift_seed(budget.seed, index), shift, halves=True))
                      for index, shift in enumerate(SHIFT_MAPS)}
        with timer("integration"):
            halves = {shift: [_estimates(part, spp, separate, None)
                              for part, spp in zip(parts, (pilot // 2, pilot - pilot // 2))]
                      for shift, parts in pilots.items()}
        with timer("reconstruction"):
            (shift, alpha), scores = held_out_choice(halves, alphas=alphas)
        drawn = pilots[shift]
        rest = budget.spp - pilot
        if rest:
            with timer("sampling"):
                drawn.append(self._sample(context, rest, shift_seed(budget.seed, len(SHIFT_MAPS)), shift))
        return drawn, shift, alpha, scores, pilot

    def _sample(self, context, spp, seed, shift, *, halves=False):
        """The scene's gradient samples with the method's offsets, the first-hit albedo reduced only to demodulate."""
        return context.scene.sample_gradients(context.layout, context.grid_shape, spp, seed,
                                              offsets=self.options.offsets, shift=shift, halves=halves,
                                              albedo=self.options.demodulation == "albedo")

    def reconstruct(self, options, alpha, primal, gradient_x, gradient_y, halves,
                    l2_images):  # pragma: no cover - interface
        """The image from the estimates of all the samples at ``alpha`` (finite); ``halves`` the estimates of the
        two held-out halves, or None; ``l2_images`` the L2 images at ``alpha`` of all the samples and of each half,
        ``(image, (image_a, image_b))``, where the held-out choice computed them (float32 solves), or None.
        Returns ``(RecoveryResult, details)``, ``details`` added to the run's."""
        raise NotImplementedError


def _l2_result(l2_images, primal, gradient_x, gradient_y, alpha):
    """The L2 reconstruction of all the samples: the held-out choice's if given, else one solve."""
    if l2_images is None:
        return screened_poisson(primal, gradient_x, gradient_y, alpha=alpha)
    return RecoveryResult(estimate=l2_images[0], iterations=0, stop_reason="exact", seconds={"solve": 0.0})


@register
class GradientL2(_GradientDomain):
    """Gradient-domain path tracing, screened Poisson L2 reconstruction (Kettunen et al. 2015, 4)."""

    name = "gradient-l2"
    Options = GradientL2Options
    description = ("gradient-domain path tracing: base paths and their one-pixel shifts in primary sample space, "
                   "screened Poisson L2 solve by one DCT (unbiased)")

    def reconstruct(self, options, alpha, primal, gradient_x, gradient_y, halves, l2_images):
        return _l2_result(l2_images, primal, gradient_x, gradient_y, alpha), {}


@register
class GradientL1(_GradientDomain):
    """Gradient-domain path tracing, L1 reconstruction by ADMM over the DCT solve (Kettunen et al. 2015, 4)."""

    name = "gradient-l1"
    Options = GradientL1Options
    description = ("gradient-domain path tracing with the L1 reconstruction (ADMM over the DCT solve; biased, "
                   "robust to outlying gradients)")

    def warm_up(self, context):
        """The shared warm-up, then the L1 solve and its held-out check on a small image of noise: their numba
        kernels load on first use (1.5-2 s in a fresh process, measured), and the 2-spp warm-up reaches them only
        where its held-out choice keeps the gradients (alpha finite); otherwise the first timed run paid for it."""
        super().warm_up(context)
        generator = np.random.default_rng(WARM_UP_SEED)
        height, width = 8, 12

        def estimates():
            return (generator.random((height, width, 3)), generator.normal(size=(height, width - 1, 3)),
                    generator.normal(size=(height - 1, width, 3)))

        halves = [estimates(), estimates()]
        held_out_l1_check(halves, DEFAULT_ALPHA, iterations=2, tolerance=self.options.tolerance)
        screened_poisson_l1(*halves[0], alpha=DEFAULT_ALPHA, tolerance=self.options.tolerance, max_iterations=2)

    def reconstruct(self, options, alpha, primal, gradient_x, gradient_y, halves, l2_images):
        """The L1 solve (from the L2 image), or with ``l1_check='held-out'`` (and halves) the L2 one unless the L1
        image of each half predicts the other half's primal image better beyond noise (:func:`held_out_l1_check`)."""
        if options.l1_check == "held-out" and halves:
            use_l1, check = held_out_l1_check(halves, alpha, iterations=options.check_iterations,
                                              tolerance=options.tolerance,
                                              l2_images=None if l2_images is None else l2_images[1])
            details = {"l1_check": check, "solver_used": "l1" if use_l1 else "l2"}
        else:
            use_l1, details = True, {"l1_check": None, "solver_used": "l1"}
        if not use_l1:
            return _l2_result(l2_images, primal, gradient_x, gradient_y, alpha), details
        return screened_poisson_l1(primal, gradient_x, gradient_y, alpha=alpha, tolerance=options.tolerance,
                                   max_iterations=options.max_iterations,
                                   start="l2" if l2_images is None else l2_images[0]), details
