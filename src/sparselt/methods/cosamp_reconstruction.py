"""Methods ``cosamp`` and ``cosamp-thesis``: 4-D CoSaMP reconstruction of the image (thesis 8.1).

Both draw ``spp`` samples per pixel at uniformly random cells of the pixel's
non-image axes (:func:`~sparselt.methods.pixel_samples.draw_pixel_samples`),
measure each sampled cell by the mean luminance of its samples, gamma-map the
measurements (eq. 7.1), recover ``K`` Fourier coefficients of the mapped 4-D
signal with CoSaMP, reconstruct the whole grid, undo the gamma mapping and
average over the non-image axes. Chroma comes per pixel from the samples.

``cosamp-thesis`` stops there, as the thesis does. Its images are darker and
flatter than the reference (8.1.2). Two causes, both measurable:

1. *Jensen's inequality on noisy cell means.* The gamma curve ``t ** gamma``
   is concave: a cell measured by one or two noisy path samples is mapped to
   ``E[(X / m) ** gamma] < (E[X] / m) ** gamma``. Most cells hold a single
   sample, so the mapped measurements are biased low, the more so the noisier
   the scene (fireflies).
2. *Smoothing before a convex inverse.* CoSaMP keeps ``K = N / 200`` terms: a
   smooth fit of the mapped signal. The inverse ``t ** (1 / gamma)`` is
   convex, so the mean of the inverse of a smoothed signal is below the mean
   of the inverse of the signal (again Jensen): dark regions are lifted and
   bright ones flattened, and the mean falls. The maximum ``m`` is a single
   cell's mean (often a firefly), which pushes nearly every value into the
   steep part of the curve and amplifies both effects.

``cosamp`` (the default) removes the bias without touching the reference: the
reconstruction ``R`` becomes a control variate. For output pixel ``p`` with
samples ``u_i`` falling in cells ``c_i``,

.. math:: I_p = \\bar f_p + \\hat\\chi_p \\Big(\\frac{1}{|P|}\\sum_{c \\in P} R(c)
          - \\frac{1}{n}\\sum_i R(c_i)\\Big)

where ``\\bar f_p`` is the per-pixel sample mean (RGB), ``\\hat\\chi_p`` its
chroma (RGB divided by luminance) and ``P`` the grid cells under the pixel.
Since ``c_i`` is uniform over ``P``, the bracket has expectation zero for a
fixed ``R``: the estimator keeps the mean of path tracing whatever ``R`` is,
and its variance is that of ``f - R``, smaller than path tracing's where
``R`` follows the variation over the lens (or secondary direction). ``R`` is
fitted to the same samples; with ``K`` much smaller than the number of
measured cells the fit leaves the correction nearly unbiased (measured: the
luminance ratio of the comparison).
"""

from __future__ import annotations

import math

import numpy as np

from ..analysis.threshold import check_gamma
from ..images import luminance
from ..operators.partial_fourier import PartialFourier
from ..recovery.cosamp import cosamp
from .base import Budget, Method, MethodResult, PhaseTimer
from .pixel_samples import cell_means, draw_pixel_samples
from .registry import register

DEFAULT_GAMMA = 0.25
SPARSITY_RATE = 1 / 200  # thesis 8.1.1: "an expected sparsity rate of 1/200"
# Rendered measurements are noisy: the residual cannot fall below the noise. Stop at the first
# iteration that improves it by less than 1% (measured on dof-sculptures 250x250x16x16 at 40 spp:
# 3 iterations instead of 5, 1.97 s instead of 3.35 s, final residual 0.2168 in both), with 3
# conjugate-gradient steps per least squares (1.55 s, residual 0.2169).
STAGNATION = 1e-2
PATIENCE = 1
CONJUGATE_GRADIENT_STEPS = 3


def default_sparsity(grid_shape):
    """``K = N / 200`` (thesis 8.1.1), at least 1."""
    return max(1, math.prod(grid_shape) // 200)


def reconstruct_luminance(cells, means, grid_shape, *, gamma, sparsity, dtype=np.float32):
    """CoSaMP reconstruction of the luminance signal on the whole grid (thesis 8.1.1).

    Parameters
    ----------
    cells : ndarray of int64
        Distinct flat cells that were measured.
    means : ndarray
        Their measured (mean) luminance, non-negative.
    grid_shape : tuple of int
        Signal grid.
    gamma : float
        Gamma of eq. 7.1 applied before recovery and inverted after.
    sparsity : int
        ``K``, full-spectrum coefficients kept (``0 < K < len(cells)``).

    Returns
    -------
    reconstruction : ndarray, shape ``grid_shape``, ``dtype``
        Linear luminance ``m * max(T, 0) ** (1 / gamma)``, ``T`` the recovered
        mapped signal and ``m`` the largest measurement.
    result : RecoveryResult
        CoSaMP's record.

    Raises
    ------
    ValueError
        ``sparsity`` not below the number of measured cells (more spp, or a
        smaller ``--sparsity``).
    """
    gamma = check_gamma(gamma)
    if not 0 < sparsity < cells.size:
        raise ValueError(f"sparsity K={sparsity} must be below the number of measured cells ({cells.size}); "
                         "raise --spp or lower --sparsity")
    maximum = float(means.max(initial=0.0))
    scale = 1.0 / maximum if maximum > 0 else 0.0
    mapped = np.power(means * scale, gamma).astype(dtype)
    operator = PartialFourier(grid_shape, cells, real=True, dtype=dtype)
    result = cosamp(operator, mapped, int(sparsity), stagnation=STAGNATION, patience=PATIENCE,
                    conjugate_gradient_steps=CONJUGATE_GRADIENT_STEPS)
    signal = result.estimate.to_signal(dtype=dtype)
    np.maximum(signal, 0, out=signal)  # t ** (1 / gamma) is undefined below 0
    np.power(signal, np.dtype(dtype).type(1.0 / gamma), out=signal)
    signal *= np.dtype(dtype).type(maximum)
    return signal, result


def pixel_integral(reconstruction, upscale):
    """Mean of a grid signal over its non-image axes, as an output image (height, width).

    Each grid pixel covers ``upscale`` output pixels along ``(x, y)``.
    """
    width, height = reconstruction.shape[:2]
    grid_image = reconstruction.reshape(width, height, -1).mean(axis=2, dtype=np.float64).T
    return np.repeat(np.repeat(grid_image, upscale[1], axis=0), upscale[0], axis=1)


def chroma(pixel_rgb):
    """RGB divided by luminance per pixel; grey (1, 1, 1) where the luminance is zero."""
    level = luminance(pixel_rgb)[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(level > 0, pixel_rgb / np.where(level > 0, level, 1.0), 1.0)
    return ratio


class _CosampMethod(Method):
    kinds = ("dof", "indirect")
    needs_resolution_multiple = True
    thesis_faithful = False

    def warm_up(self, context):
        # The renderer is the only part with kernels to compile; CoSaMP is numpy and FFTs.
        draw_pixel_samples(context, _warm_budget())

    def options(self, context):
        gamma = context.options.get("gamma")
        if gamma is None:
            gamma = DEFAULT_GAMMA
        sparsity = context.options.get("sparsity") or default_sparsity(context.grid_shape)
        faithful = self.thesis_faithful or bool(context.options.get("thesis_faithful", False))
        return check_gamma(gamma), int(sparsity), faithful

    def run(self, context, budget):
        gamma, sparsity, faithful = self.options(context)
        timer = PhaseTimer()
        with timer("sampling"):
            samples = draw_pixel_samples(context, budget)
        image, details = image_from_samples(samples, context.grid_shape, gamma=gamma, sparsity=sparsity,
                                            thesis_faithful=faithful, timer=timer)
        return MethodResult(image=image, seconds=timer.seconds, path_samples=samples.values.shape[0],
                            details=details)


def image_from_samples(samples, grid_shape, *, gamma, sparsity, thesis_faithful=False, timer=None):
    """The CoSaMP image of a set of pixel samples: everything after sampling (thesis 8.1.1).

    Parameters
    ----------
    samples : PixelSamples
        ``spp`` samples per output pixel with the grid cell of each.
    grid_shape : tuple of int
        Signal grid; its image axes divide the output resolution.
    gamma, sparsity : float, int
        As :func:`reconstruct_luminance`.
    thesis_faithful : bool, optional
        ``True``: the integrated reconstruction times the samples' chroma
        (thesis). ``False``: the reconstruction as a control variate (see the
        module docstring).
    timer : PhaseTimer, optional
        Receives the 'other', 'reconstruction' and 'integration' times.

    Returns
    -------
    image : ndarray, shape (height, width, 3), float32
    details : dict
    """
    timer = timer or PhaseTimer()
    width, height = samples.resolution
    upscale = (width // grid_shape[0], height // grid_shape[1])
    with timer("other"):
        cells, means, _ = cell_means(samples, math.prod(grid_shape))
        pixel_rgb = samples.pixel_means().astype(np.float64)
    with timer("reconstruction"):
        reconstruction, result = reconstruct_luminance(cells, means, grid_shape, gamma=gamma, sparsity=sparsity)
    with timer("integration"):
        integral = pixel_integral(reconstruction, upscale)
        pixel_chroma = chroma(pixel_rgb)
        if thesis_faithful:
            image = integral[..., None] * pixel_chroma
        else:
            at_samples = samples.pixel_means_of(reconstruction.reshape(-1)[samples.cells])
            image = pixel_rgb + pixel_chroma * (integral - at_samples)[..., None]
    details = {
        "gamma": gamma,
        "sparsity": sparsity,
        "thesis_faithful": bool(thesis_faithful),
        "measured_cells": int(cells.size),
        "cosamp_iterations": result.iterations,
        "cosamp_stop_reason": result.stop_reason,
        "cosamp_relative_residual": result.relative_residual,
        "nonfinite_samples": samples.nonfinite,
    }
    return image.astype(np.float32), details


def _warm_budget():
    return Budget(spp=1, seed=0xFFFF_FFFF)


@register
class Cosamp(_CosampMethod):
    """CoSaMP reconstruction used as a control variate: the mean of path tracing, less variance where it fits."""

    name = "cosamp"
    description = "CoSaMP 4-D reconstruction (thesis 8.1) as a control variate for the pixel's samples (unbiased)"


@register
class CosampThesis(_CosampMethod):
    """Exactly the thesis's procedure (8.1.1): the integrated reconstruction times the samples' chroma."""

    name = "cosamp-thesis"
    description = "CoSaMP 4-D reconstruction exactly as thesis 8.1.1 (darker, lower contrast)"
    thesis_faithful = True
