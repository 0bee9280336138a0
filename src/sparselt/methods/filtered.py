r"""Filtered path tracing: ``gaussian``, ``bilateral``, ``cosamp-bilateral`` (thesis 8.2), ``aov-bilateral``, ``oidn``.

Every method here draws exactly the samples of the CoSaMP methods (same budget,
same seed: :func:`~sparselt.methods.pixel_samples.draw_pixel_samples`), takes
their per-pixel mean (the path-traced image) and filters it; every second is
counted: sampling, the AOV pass, CoSaMP, the filter.

Parameters are fixed defaults or derived from the noisy data, never from the
reference (recorded in each result's details and in ``compare.json``):

- window radius 3 (7x7 pixels), spatial sigma 2 pixels; the ``gaussian``
  method uses sigma 1 pixel on the same window;
- the range sigma of the path-traced image (and of the CoSaMP image) is
  ``2 s``, ``s`` the median over pixels of the standard error of the pixel
  mean, ``sqrt(sum_c var_c / spp)`` from the samples themselves: differences
  within two noise levels are smoothed, larger ones are treated as edges;
- feature buffers (``aov`` integrator at 4 spp): albedo sigma 0.1, normal
  sigma 0.3, depth sigma 0.1 times the median depth.

References
----------
Thesis 8.2 (eq. 8.1-8.3, flowchart 8.5). Joint bilateral with feature buffers:
Dammertz et al. (2010), Rousselle et al. (2013). OIDN: Áfra (2019-).
"""

from __future__ import annotations

import numpy as np

from ..filters import bilateral, cross_bilateral, gaussian, oidn_denoise
from .base import WARM_UP_SEED, Budget, Method, MethodResult, PhaseTimer
from .cosamp_reconstruction import image_from_samples, reconstruction_options
from .pixel_samples import draw_pixel_samples, sample_mean_image
from .registry import register

RADIUS = 3
SIGMA_SPATIAL = 2.0
GAUSSIAN_SIGMA = 1.0
RANGE_NOISE_MULTIPLE = 2.0
AOV_SPP = 4
ALBEDO_SIGMA = 0.1
NORMAL_SIGMA = 0.3
RELATIVE_DEPTH_SIGMA = 0.1


def noise_sigma(samples):
    """Median over pixels of the standard error of the pixel mean (RGB Euclidean), from the samples.

    Per-pixel sums and sums of squares accumulated in float64 without a
    float64 copy of the samples.
    """
    width, height = samples.resolution
    if samples.spp < 2:
        return 1e-6
    values = samples.values.reshape(height * width, samples.spp, 3)
    total = values.sum(axis=1, dtype=np.float64)
    squares = np.einsum("psc,psc->pc", values, values, dtype=np.float64)
    variance = np.maximum(squares - total * total / samples.spp, 0.0) / (samples.spp - 1)
    error = np.sqrt(variance.sum(axis=-1) / samples.spp)
    sigma = float(np.median(error))
    if sigma <= 0:
        sigma = float(error.mean())
    return sigma if sigma > 0 else 1e-6


class _FilteredMethod(Method):
    kinds = ("dof", "indirect", "path")
    warm_up_spp = 2  # the noise estimate needs two samples per pixel

    def run(self, context, budget):
        timer = PhaseTimer()
        samples, image = sample_mean_image(context, budget, timer)
        filtered, details = self.filter(context, budget, samples, image, timer)
        details.update(nonfinite_samples=samples.nonfinite)
        return MethodResult(image=np.asarray(filtered, dtype=np.float32), seconds=timer.seconds,
                            path_samples=samples.values.shape[0], details=details)

    def filter(self, context, budget, samples, image, timer):  # pragma: no cover - interface
        raise NotImplementedError


def _aov_guides(context, budget, timer):
    with timer("sampling"):
        buffers, _ = context.scene.render_aovs(AOV_SPP, budget.seed)
    depth = buffers["depth"]
    depth_sigma = RELATIVE_DEPTH_SIGMA * float(np.median(depth[depth > 0])) if np.any(depth > 0) else 1.0
    return buffers, depth_sigma


@register
class GaussianFilter(_FilteredMethod):
    name = "gaussian"
    description = f"path-traced samples, Gaussian filter sigma {GAUSSIAN_SIGMA} px, radius {RADIUS}"

    def filter(self, context, budget, samples, image, timer):
        with timer("reconstruction"):
            result = gaussian(image, GAUSSIAN_SIGMA, radius=RADIUS, channel_axis=-1)
        return result, {"sigma": GAUSSIAN_SIGMA, "radius": RADIUS}


@register
class BilateralFilter(_FilteredMethod):
    name = "bilateral"
    description = ("path-traced samples, bilateral filter (eq. 8.1-8.2): radius 3, sigma_s 2 px, "
                   "sigma_r 2x the median standard error of the pixel means")

    def filter(self, context, budget, samples, image, timer):
        with timer("reconstruction"):
            sigma_range = RANGE_NOISE_MULTIPLE * noise_sigma(samples)
            result = bilateral(image, RADIUS, SIGMA_SPATIAL, sigma_range, channel_axis=-1)
        return result, {"radius": RADIUS, "sigma_spatial": SIGMA_SPATIAL, "sigma_range": sigma_range}


@register
class CosampBilateral(_FilteredMethod):
    name = "cosamp-bilateral"
    kinds = ("dof", "indirect")
    needs_resolution_multiple = True
    description = ("thesis 8.2 (eq. 8.3): the path-traced image of the CoSaMP samples, cross-bilateral filtered with "
                   "itself and the CoSaMP reconstruction (thesis procedure) as range guides")

    def filter(self, context, budget, samples, image, timer):
        gamma, sparsity = reconstruction_options(context)
        reconstruction, details = image_from_samples(samples, context.grid_shape, gamma=gamma, sparsity=sparsity,
                                                     thesis_faithful=True, timer=timer)
        with timer("reconstruction"):
            sigma_range = RANGE_NOISE_MULTIPLE * noise_sigma(samples)
            result = cross_bilateral(image, [image, reconstruction], RADIUS, SIGMA_SPATIAL, sigma_range,
                                     channel_axis=-1)
        details.update(radius=RADIUS, sigma_spatial=SIGMA_SPATIAL, sigma_range=sigma_range)
        return result, details

    def warm_up(self, context):
        # Compile the sampler's and the filter's kernels without paying for a CoSaMP run.
        draw_pixel_samples(context, Budget(spp=self.warm_up_spp, seed=WARM_UP_SEED))
        cross_bilateral(np.zeros((4, 4, 3)), [np.zeros((4, 4))], 1, 1.0, 1.0, channel_axis=-1)


@register
class AovBilateral(_FilteredMethod):
    name = "aov-bilateral"
    description = ("path-traced samples, joint bilateral guided by the image and the aov integrator's albedo, "
                   "normal and depth (4 spp, timed): radius 3, sigma_s 2 px, sigma_r as 'bilateral', "
                   "albedo 0.1, normal 0.3, depth 0.1x median depth")

    def filter(self, context, budget, samples, image, timer):
        buffers, depth_sigma = _aov_guides(context, budget, timer)
        with timer("reconstruction"):
            sigma_range = RANGE_NOISE_MULTIPLE * noise_sigma(samples)
            result = cross_bilateral(image, [image, buffers["albedo"], buffers["normal"], buffers["depth"]], RADIUS,
                                     SIGMA_SPATIAL, [sigma_range, ALBEDO_SIGMA, NORMAL_SIGMA, depth_sigma],
                                     channel_axis=-1)
        return result, {"radius": RADIUS, "sigma_spatial": SIGMA_SPATIAL, "sigma_range": sigma_range,
                        "aov_spp": AOV_SPP, "albedo_sigma": ALBEDO_SIGMA, "normal_sigma": NORMAL_SIGMA,
                        "depth_sigma": depth_sigma}


@register
class OidnDenoiser(_FilteredMethod):
    name = "oidn"
    description = "path-traced samples denoised by Intel Open Image Denoise (RT, hdr, albedo + normal from a 4 spp aov pass)"

    def filter(self, context, budget, samples, image, timer):
        buffers, _ = _aov_guides(context, budget, timer)
        with timer("reconstruction"):
            result = oidn_denoise(image, buffers["albedo"], buffers["normal"])
        return result, {"aov_spp": AOV_SPP, "denoiser": "pyoidn RT hdr, albedo + normal"}
