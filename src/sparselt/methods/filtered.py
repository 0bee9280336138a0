r"""Filtered path tracing: ``gaussian``, ``bilateral``, ``cosamp-bilateral`` (thesis 8.2), ``aov-bilateral``, ``oidn``.

Every method here draws exactly the samples of the CoSaMP methods (same budget,
same seed: :func:`~sparselt.methods.pixel_samples.draw_pixel_samples`), takes
their per-pixel mean (the path-traced image) and filters it; every second is
counted: sampling, the AOV pass, CoSaMP, the filter.

Parameters are declared options with fixed defaults (``sparselt methods
NAME`` lists them) or derived from the noisy data, never from the reference
(recorded in each result's details and in ``compare.json``):

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

from dataclasses import dataclass

import numpy as np

from ..cell_statistics import variance_from_sums
from ..filters import bilateral, cross_bilateral, gaussian, oidn_denoise
from .base import WARM_UP_SEED, Budget, Method, MethodResult
from .cosamp_reconstruction import COSAMP_BYTES_PER_CELL, CosampOptions, thesis_image_from_samples
from .options import MethodOptions, option
from .pixel_samples import draw_pixel_samples, sample_mean_image
from .preconditions import GridMemory
from .registry import register

MAXIMUM_RADIUS = 32


def _radius(default=3):
    return option(default, minimum=1, maximum=MAXIMUM_RADIUS, section="8.2",
                  help="filter window radius in pixels (the window is 2 radius + 1 wide)")


@dataclass(frozen=True)
class GaussianOptions(MethodOptions):
    sigma: float = option(1.0, minimum=0.0, minimum_inclusive=False, help="Gaussian sigma in pixels")
    radius: int = _radius()


@dataclass(frozen=True)
class BilateralOptions(MethodOptions):
    """The bilateral filter's options (eq. 8.1-8.2), shared by every bilateral method."""

    radius: int = _radius()
    sigma_spatial: float = option(2.0, minimum=0.0, minimum_inclusive=False, section="8.2 (eq. 8.1)",
                                  help="spatial sigma in pixels")
    range_noise_multiple: float = option(2.0, minimum=0.0, minimum_inclusive=False, section="8.2 (eq. 8.2)",
                                         help="range sigma in units of the median standard error of the pixel "
                                              "means (measured on the samples, never on the reference)")


@dataclass(frozen=True)
class AovOptions(MethodOptions):
    """The feature-buffer pass (Mitsuba's aov integrator), shared by the methods it guides; its time is counted."""

    aov_spp: int = option(4, minimum=1, maximum=1024, help="samples per pixel of the albedo/normal/depth pass")


@dataclass(frozen=True)
class AovBilateralOptions(BilateralOptions, AovOptions):
    albedo_sigma: float = option(0.1, minimum=0.0, minimum_inclusive=False, help="range sigma of the albedo guide")
    normal_sigma: float = option(0.3, minimum=0.0, minimum_inclusive=False, help="range sigma of the normal guide")
    relative_depth_sigma: float = option(0.1, minimum=0.0, minimum_inclusive=False,
                                         help="range sigma of the depth guide, times the median depth")


@dataclass(frozen=True)
class CosampBilateralOptions(BilateralOptions, CosampOptions):
    """The bilateral filter's and the CoSaMP reconstruction's options (thesis 8.2)."""


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
    variance = variance_from_sums(total, squares, samples.spp, form="total")
    error = np.sqrt(variance.sum(axis=-1) / samples.spp)
    sigma = float(np.median(error))
    if sigma <= 0:
        sigma = float(error.mean())
    return sigma if sigma > 0 else 1e-6


class _FilteredMethod(Method):
    kinds = ("dof", "indirect", "path")
    family = "filter"
    warm_up_spp = 2  # the noise estimate needs two samples per pixel
    sample_cells = False  # whether the filter reads the samples' grid cells (draw_pixel_samples)

    def run(self, context, budget, timer):
        options = self.options
        samples, image = sample_mean_image(context, budget, timer, cells=self.sample_cells)
        filtered, details = self.filter(context, options, budget, samples, image, timer)
        details.update(nonfinite_samples=samples.nonfinite)
        return MethodResult(image=np.asarray(filtered, dtype=np.float32), path_samples=samples.values.shape[0],
                            details=details)

    def filter(self, context, options, budget, samples, image, timer):  # pragma: no cover - interface
        raise NotImplementedError


def _aov_guides(context, options, budget, timer):
    with timer("sampling"):
        buffers, _ = context.scene.render_aovs(options.aov_spp, budget.seed)
    depth = buffers["depth"]
    relative = getattr(options, "relative_depth_sigma", 0.1)
    depth_sigma = relative * float(np.median(depth[depth > 0])) if np.any(depth > 0) else 1.0
    return buffers, depth_sigma


@register
class GaussianFilter(_FilteredMethod):
    name = "gaussian"
    Options = GaussianOptions
    description = "path-traced samples, Gaussian filter (sigma 1 px, radius 3 by default)"

    def filter(self, context, options, budget, samples, image, timer):
        with timer("reconstruction"):
            result = gaussian(image, options.sigma, radius=options.radius, channel_axis=-1)
        return result, {"sigma": options.sigma, "radius": options.radius}


@register
class BilateralFilter(_FilteredMethod):
    name = "bilateral"
    Options = BilateralOptions
    description = ("path-traced samples, bilateral filter (eq. 8.1-8.2): radius 3, sigma_s 2 px, "
                   "sigma_r 2x the median standard error of the pixel means (defaults)")

    def filter(self, context, options, budget, samples, image, timer):
        with timer("reconstruction"):
            sigma_range = options.range_noise_multiple * noise_sigma(samples)
            result = bilateral(image, options.radius, options.sigma_spatial, sigma_range, channel_axis=-1)
        return result, {"radius": options.radius, "sigma_spatial": options.sigma_spatial, "sigma_range": sigma_range}


@register
class CosampBilateral(_FilteredMethod):
    name = "cosamp-bilateral"
    kinds = ("dof", "indirect")
    Options = CosampBilateralOptions
    needs_resolution_multiple = True
    thesis_procedure = True
    sample_cells = True  # the CoSaMP reconstruction bins the samples into the grid
    requires = (GridMemory(COSAMP_BYTES_PER_CELL),)  # the CoSaMP reconstruction's dense grid
    description = ("thesis 8.2 (eq. 8.3): the path-traced image of the CoSaMP samples, cross-bilateral filtered with "
                   "itself and the CoSaMP reconstruction (thesis procedure) as range guides")

    def filter(self, context, options, budget, samples, image, timer):
        reconstruction, details = thesis_image_from_samples(samples, context.grid_shape, gamma=options.gamma,
                                                            sparsity=options.sparsity, timer=timer)
        with timer("reconstruction"):
            sigma_range = options.range_noise_multiple * noise_sigma(samples)
            result = cross_bilateral(image, [image, reconstruction], options.radius, options.sigma_spatial,
                                     sigma_range, channel_axis=-1)
        details.update(radius=options.radius, sigma_spatial=options.sigma_spatial, sigma_range=sigma_range)
        return result, details

    def warm_up(self, context):
        # Compile the sampler's and the filter's kernels without paying for a CoSaMP run.
        draw_pixel_samples(context, Budget(spp=self.warm_up_spp, seed=WARM_UP_SEED), cells=self.sample_cells)
        cross_bilateral(np.zeros((4, 4, 3)), [np.zeros((4, 4))], 1, 1.0, 1.0, channel_axis=-1)


@register
class AovBilateral(_FilteredMethod):
    name = "aov-bilateral"
    Options = AovBilateralOptions
    description = ("path-traced samples, joint bilateral guided by the image and the aov integrator's albedo, "
                   "normal and depth (4 spp, timed): radius 3, sigma_s 2 px, sigma_r as 'bilateral', "
                   "albedo 0.1, normal 0.3, depth 0.1x median depth (defaults)")

    def filter(self, context, options, budget, samples, image, timer):
        buffers, depth_sigma = _aov_guides(context, options, budget, timer)
        with timer("reconstruction"):
            sigma_range = options.range_noise_multiple * noise_sigma(samples)
            result = cross_bilateral(image, [image, buffers["albedo"], buffers["normal"], buffers["depth"]],
                                     options.radius, options.sigma_spatial,
                                     [sigma_range, options.albedo_sigma, options.normal_sigma, depth_sigma],
                                     channel_axis=-1)
        return result, {"radius": options.radius, "sigma_spatial": options.sigma_spatial, "sigma_range": sigma_range,
                        "aov_spp": options.aov_spp, "albedo_sigma": options.albedo_sigma,
                        "normal_sigma": options.normal_sigma, "depth_sigma": depth_sigma}


@register
class OidnDenoiser(_FilteredMethod):
    name = "oidn"
    family = "denoiser"
    Options = AovOptions
    description = "path-traced samples denoised by Intel Open Image Denoise (RT, hdr, albedo + normal from a 4 spp aov pass)"

    def filter(self, context, options, budget, samples, image, timer):
        buffers, _ = _aov_guides(context, options, budget, timer)
        with timer("reconstruction"):
            result = oidn_denoise(image, buffers["albedo"], buffers["normal"])
        return result, {"aov_spp": options.aov_spp, "denoiser": "pyoidn RT hdr, albedo + normal"}
