r"""``nfor``: path-traced samples denoised by NFOR (Bitterli et al. 2016), a comparison denoiser.

The method draws exactly the path samples of ``oidn`` and of the CoSaMP
methods for the same budget
(:func:`~sparselt.methods.pixel_samples.sample_mean_image`), so equal spp
means equal path samples, and splits each pixel's samples in two halves by
their index (even: ``A``, odd: ``B``). Per pixel it forms the two half means
and the variance of each half's mean (sample variance over the half's
samples divided by their count; with one sample per half, the half
difference, ``(y_A - y_B)^2 / 2``), box filtered over 3x3 pixels by default
(``variance_radius``: with two samples per half the estimate has one degree
of freedom, is often exactly 0, and a zero variance makes every NL-means
weight but the centre's vanish; smoothing measured on the Cornell box at
64x64: relMSE 0.0074 -> 0.0025 at 4 spp, 0.0014 -> 0.0015 at 16 spp). The feature buffers (albedo, shading
normal, depth) come from Mitsuba's ``aov`` integrator in two independent
passes of ``aov_spp / 2`` samples per pixel at seeds ``2 seed`` and
``2 seed + 1`` (distinct for distinct budget seeds), so each feature has two
halves too. Every second is counted: both passes in ``'sampling'``, the
halves in ``'integration'``, the filter in ``'reconstruction'``. The filter is
:func:`sparselt.filters.nfor.nfor_filter`; its module notes give the
algorithm and its simplifications against the paper.

References
----------
Bitterli, B. et al. (2016). Nonlinearly weighted first-order regression for
denoising Monte Carlo renderings. Computer Graphics Forum 35(4), 107-117.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..filters import nfor as nfor_filters
from .base import Method, MethodResult
from .options import MethodOptions, option
from .pixel_samples import sample_mean_image
from .preconditions import MinimumSpp
from .registry import register


@dataclass(frozen=True)
class NforOptions(MethodOptions):
    """NFOR's options: the feature passes, the regression window, the NL-means bandwidths, the prefilter.

    The paper's section of each is in its help text (Bitterli et al. 2016).
    """

    variance_radius: int = option(1, minimum=0, maximum=8,
                                  help="box radius smoothing each half's per-pixel variance estimate before the "
                                       "NL-means weights use it (0: none; few samples per half make it noisy)")
    aov_spp: int = option(4, minimum=2, maximum=1024,
                          help="samples per pixel of the albedo/normal/depth passes, in two independent halves of "
                               "aov_spp // 2 and aov_spp - aov_spp // 2")
    radius: int = option(9, minimum=1, maximum=32,
                         help="(paper 4) regression window radius in pixels (the window is 2 radius + 1 wide)")
    patch_radius: int = option(3, minimum=0, maximum=8,
                               help="(paper 4) NL-means patch radius of the colour weights")
    bandwidth_small: float = option(0.5, minimum=0.0, minimum_inclusive=False,
                                    help="(paper 5.3) NL-means k of the sharper candidate filter")
    bandwidth_large: float = option(1.0, minimum=0.0, minimum_inclusive=False,
                                    help="(paper 5.3) NL-means k of the smoother candidate filter")
    feature_radius: int = option(5, minimum=1, maximum=16,
                                 help="(paper 5.1) window radius of the feature prefilter (NL-means, cross halves)")
    feature_patch_radius: int = option(3, minimum=0, maximum=8,
                                       help="(paper 5.1) patch radius of the feature prefilter")
    feature_bandwidth: float = option(0.5, minimum=0.0, minimum_inclusive=False,
                                      help="(paper 5.1) NL-means k of the feature prefilter")
    selection_patch_radius: int = option(1, minimum=0, maximum=8,
                                         help="(paper 5.3) NL-means patch radius of the error and selection map "
                                              "filter")
    second_pass: bool = option(True, help="(paper 5.4) regress the selected image once more, guided by itself")
    ridge: float = option(1e-7, minimum=0.0, maximum=1.0,
                          help="(paper 4) ridge on the regression slopes, relative to each slope's Gram diagonal")


def half_statistics(samples, variance_radius=0):
    """The two halves of each pixel's samples (even and odd sample index): means and variances of the means.

    Parameters
    ----------
    samples : PixelSamples
        At least 2 samples per pixel.
    variance_radius : int, optional
        Box radius (clipped at the border) smoothing each half's variance
        estimate (default 0: none).

    Returns
    -------
    means, variances : ndarray, shape (2, height, width, 3), float64
        ``variances[h]`` estimates the variance of ``means[h]``: the unbiased
        sample variance over the half's samples over their count, or, where
        a half has one sample, ``(means[0] - means[1])^2 / 2``; then box
        filtered over ``(2 variance_radius + 1)^2`` pixels.
    """
    per_pixel = samples.per_pixel(samples.values)
    means = []
    variances = []
    for half in range(2):
        values = per_pixel[:, :, half::2].astype(np.float64)
        count = values.shape[2]
        mean = values.mean(axis=2)
        means.append(mean)
        variances.append(values.var(axis=2, ddof=1) / count if count >= 2 else None)
    difference = 0.5 * (means[0] - means[1]) ** 2
    variances = [difference if variance is None else variance for variance in variances]
    variances = np.stack(variances)
    if variance_radius:
        variances = np.moveaxis(nfor_filters.box_filter(np.moveaxis(variances, -1, 1), variance_radius), 1, -1)
    return np.stack(means), variances


def feature_halves(context, options, seed, timer):
    """Albedo, normal and depth from two independent ``aov`` passes (``'sampling'``): (2, height, width[, 3]) each."""
    first_spp = options.aov_spp // 2
    with timer("sampling"):
        first, _ = context.scene.render_aovs(first_spp, 2 * seed)
        second, _ = context.scene.render_aovs(options.aov_spp - first_spp, 2 * seed + 1)
    return [np.stack([first[name], second[name]]).astype(np.float64) for name in ("albedo", "normal", "depth")]


@register
class NforDenoiser(Method):
    name = "nfor"
    kinds = ("dof", "indirect", "path")
    family = "denoiser"
    Options = NforOptions
    requires = (MinimumSpp(2, reason="it splits each pixel's samples in two halves"),)
    warm_up_spp = 2
    description = ("path-traced samples denoised by NFOR (Bitterli et al. 2016): cross-half NL-means weighted "
                   "first-order regression on prefiltered albedo/normal/depth (two 2-spp aov passes, timed), "
                   "collaborative, k in {0.5, 1} selected per pixel from the halves, second pass")

    def run(self, context, budget, timer):
        options = self.options
        samples, _ = sample_mean_image(context, budget, timer)
        with timer("integration"):
            means, variances = half_statistics(samples, options.variance_radius)
        features = feature_halves(context, options, budget.seed, timer)
        with timer("reconstruction"):
            result = nfor_filters.nfor_filter(
                means, variances, features, radius=options.radius, patch_radius=options.patch_radius,
                bandwidths=(options.bandwidth_small, options.bandwidth_large), feature_radius=options.feature_radius,
                feature_patch_radius=options.feature_patch_radius, feature_bandwidth=options.feature_bandwidth,
                selection_patch_radius=options.selection_patch_radius, second_pass=options.second_pass,
                ridge=options.ridge)
            image = np.asarray(result.image, dtype=np.float32)
        details = dict(options.record())
        details.update(nonfinite_samples=samples.nonfinite, aov_seeds=[2 * budget.seed, 2 * budget.seed + 1],
                       selected_small_fraction=float(result.selection[0].mean()))
        return MethodResult(image=image, path_samples=samples.values.shape[0], details=details)

    def warm_up(self, context):
        """Compile the filter's kernels on a tiny image, then one run at 2 spp (the renderer's kernels)."""
        nfor_filters.warm_up()
        super().warm_up(context)


__all__ = ["NforDenoiser", "NforOptions", "feature_halves", "half_statistics"]
