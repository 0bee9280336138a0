r"""Methods ``cosamp`` and ``cosamp-thesis``: 4-D CoSaMP reconstruction of the image (thesis 8.1).

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
reconstruction becomes a control variate, cross-fitted so that it cannot
bias the image. The samples of each pixel are split in two folds (even and
odd sample index); ``R_k``, reconstructed from fold ``k`` alone, corrects the
samples of the other fold. For output pixel ``p`` with cells ``P`` under it,

.. math:: I_p = \bar f_p + \beta\,\hat\chi_p\,\frac{1}{2}\sum_{k=0}^{1}
          \Big(\frac{1}{|P|}\sum_{c \in P} R_k(c) - \frac{1}{n_{1-k}}
          \sum_{i \in \text{fold } 1-k} R_k(c_i)\Big)

with ``\bar f_p`` the per-pixel sample mean (RGB) and ``\hat\chi_p`` its
chroma (RGB over luminance). A sample's cell is uniform over ``P`` and
independent of the other fold, so every bracket has expectation zero: the
estimator keeps the mean of path tracing whatever ``R`` is. ``\beta`` is the
variance-optimal control-variate coefficient ``cov(f, R) / var(R)``,
estimated from the pixel-centred samples of both folds (no reference is
involved); it says how much of the within-pixel variation of the samples the
reconstruction explains, and a useless reconstruction (``beta`` near 0) falls
back to the samples' mean instead of adding its own noise. Measured on
dof-sculptures 128x128x16x16: ``beta`` 0.02 at 16 spp, 0.11 at 40, 0.29 at
81; the uncorrected in-sample version was 6% dark at 16 spp (overfitting).
The control variate is :func:`cross_fitted_image`, which takes any
reconstruction of a fold's samples: ``wedge-cosamp``
(:mod:`sparselt.methods.wedge_cosamp`) uses it with its per-tile one.

References
----------
Thesis 8.1. Glynn, P. W. and Szechtman, R. (2002). Some new perspectives on
the method of control variates. Chernozhukov et al. (2018), double/debiased
machine learning (cross-fitting).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import kernels
from ..analysis.threshold import check_gamma
from ..images import luminance
from ..operators.partial_fourier import PartialFourier
from ..recovery.cosamp import cosamp
from .base import WARM_UP_SEED, Budget, Method, MethodResult, PhaseTimer
from .options import MethodOptions, option
from .pixel_samples import cell_means, draw_pixel_samples
from .preconditions import GridMemory, MinimumSpp
from .registry import register

DEFAULT_GAMMA = 0.25
#: The CoSaMP methods' peak memory beyond PT's per grid cell (their dense grid arrays, :class:`GridMemory`): 37 and
#: 36 bytes measured for ``cosamp`` and ``cosamp-thesis`` on dof-sculptures' 64x64x32x32, 30 for
#: ``cosamp-bilateral``; with about 30% to spare.
COSAMP_BYTES_PER_CELL = 48.0
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


def _half_the_grid(grid_shape):
    return max(1, math.prod(grid_shape) // 2)


@dataclass(frozen=True)
class CosampOptions(MethodOptions):
    """The CoSaMP reconstruction's options, shared by every method that runs it (8.1-8.4)."""

    gamma: float = option(DEFAULT_GAMMA, minimum=0.0, minimum_inclusive=False, section="7.1, 8.1.1",
                          help="gamma of eq. 7.1 applied to the measurements before recovery and inverted after "
                               "(thesis: 0.25 depth of field, 0.5 architecture)")
    sparsity: int | None = option(None, derive=default_sparsity, default_text="N/200", minimum=1,
                                  maximum=_half_the_grid, maximum_text="N/2", section="8.1.1",
                                  help="K, the Fourier coefficients CoSaMP keeps (the thesis's expected sparsity "
                                       "rate 1/200)")


def reconstruct_luminance(cells, means, grid_shape, *, gamma, sparsity, dtype=np.float32, allowed=None,
                          threads=None):
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
    allowed : ndarray of bool, optional
        The frequencies the support may use (model-based CoSaMP; see
        :func:`~sparselt.recovery.cosamp.cosamp`); default all.
    threads : int, optional
        FFT threads (default every core).

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
    operator = PartialFourier(grid_shape, cells, real=True, dtype=dtype, threads=threads)
    result = cosamp(operator, mapped, int(sparsity), stagnation=STAGNATION, patience=PATIENCE,
                    conjugate_gradient_steps=CONJUGATE_GRADIENT_STEPS, allowed=allowed)
    work, grid = operator.release_buffers()  # in memory already: no fresh pages to fault in
    signal = result.estimate.to_signal(dtype=dtype, work=work, out=grid.reshape(grid_shape))
    kernels.clamped_power(signal, 1.0 / gamma)  # t ** (1 / gamma) is undefined below 0: clamp first
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
    """What both CoSaMP procedures share: the samples of :func:`draw_pixel_samples`, then :meth:`image`."""

    kinds = ("dof", "indirect")
    family = "cosamp"
    needs_resolution_multiple = True
    Options = CosampOptions
    requires = (GridMemory(COSAMP_BYTES_PER_CELL),)

    def warm_up(self, context):
        # The renderer's kernels and the numba loops around CoSaMP's FFTs compile here, not in a timed run.
        draw_pixel_samples(context, Budget(spp=1, seed=WARM_UP_SEED))
        kernels.warm_up()

    def run(self, context, budget, timer):
        with timer("sampling"):
            samples = draw_pixel_samples(context, budget)
        image, details = self.image(samples, context.grid_shape, timer)
        return MethodResult(image=image, path_samples=samples.values.shape[0], details=details)

    def image(self, samples, grid_shape, timer):  # pragma: no cover - interface
        """The procedure's image of the samples and its details (everything after sampling)."""
        raise NotImplementedError


def _procedure_details(samples, *, gamma, sparsity, thesis_faithful):
    return {"gamma": gamma, "sparsity": sparsity, "thesis_faithful": bool(thesis_faithful),
            "nonfinite_samples": samples.nonfinite}


def thesis_image_from_samples(samples, grid_shape, *, gamma, sparsity, timer=None):
    """The thesis's CoSaMP image of a set of pixel samples (8.1.1): the integrated reconstruction of all
    samples times the samples' chroma.

    Parameters
    ----------
    samples : PixelSamples
        ``spp`` samples per output pixel with the grid cell of each.
    grid_shape : tuple of int
        Signal grid; its image axes divide the output resolution.
    gamma, sparsity : float, int
        As :func:`reconstruct_luminance`.
    timer : PhaseTimer, optional
        Receives the 'other', 'reconstruction' and 'integration' times.

    Returns
    -------
    image : ndarray, shape (height, width, 3), float32
    details : dict
        Gamma, K, CoSaMP iterations, stop reason and residual, measured cells.

    Raises
    ------
    ValueError
        K not below the measured cells.
    """
    timer = timer or PhaseTimer()
    width, height = samples.resolution
    upscale = (width // grid_shape[0], height // grid_shape[1])
    details = _procedure_details(samples, gamma=gamma, sparsity=sparsity, thesis_faithful=True)
    with timer("other"):
        pixel_chroma = chroma(samples.pixel_means().astype(np.float64))
        cells, means, _ = cell_means(samples, math.prod(grid_shape), grid_shape)
    with timer("reconstruction"):
        reconstruction, result = reconstruct_luminance(cells, means, grid_shape, gamma=gamma, sparsity=sparsity)
    with timer("integration"):
        image = pixel_integral(reconstruction, upscale)[..., None] * pixel_chroma
    details.update(measured_cells=int(cells.size), cosamp_iterations=result.iterations,
                   cosamp_stop_reason=result.stop_reason, cosamp_relative_residual=result.relative_residual)
    return image.astype(np.float32), details


def image_from_samples(samples, grid_shape, *, gamma, sparsity, timer=None):
    """The ``cosamp`` image of a set of pixel samples: the cross-fitted control variate of the module docstring.

    Parameters
    ----------
    samples : PixelSamples
        ``spp >= 2`` samples per output pixel with the grid cell of each.
    grid_shape : tuple of int
        Signal grid; its image axes divide the output resolution.
    gamma, sparsity : float, int
        As :func:`reconstruct_luminance`.
    timer : PhaseTimer, optional
        Receives the 'other', 'reconstruction' and 'integration' times.

    Returns
    -------
    image : ndarray, shape (height, width, 3), float32
    details : dict
        Gamma, K, CoSaMP iterations, ``control_variate_coefficient`` (beta)
        and each fold's record.

    Raises
    ------
    ValueError
        ``spp < 2``; K not below the measured cells.
    """
    timer = timer or PhaseTimer()
    if samples.spp < 2:
        raise ValueError(f"cosamp splits each pixel's samples in two folds and needs spp >= 2, got {samples.spp}")
    width, height = samples.resolution
    upscale = (width // grid_shape[0], height // grid_shape[1])
    size = math.prod(grid_shape)
    details = _procedure_details(samples, gamma=gamma, sparsity=sparsity, thesis_faithful=False)

    def reconstruct(train):
        with timer("other"):
            cells, means, _ = cell_means(train, size, grid_shape)
        with timer("reconstruction"):
            reconstruction, result = reconstruct_luminance(cells, means, grid_shape, gamma=gamma, sparsity=sparsity)
        return reconstruction, {"measured_cells": int(cells.size), "cosamp_iterations": result.iterations,
                                "cosamp_stop_reason": result.stop_reason,
                                "cosamp_relative_residual": result.relative_residual}

    image, beta, folds = cross_fitted_image(samples, reconstruct, upscale, timer=timer)
    details.update(control_variate_coefficient=beta, folds=folds,
                   cosamp_iterations=sum(fold["cosamp_iterations"] for fold in folds))
    return image, details


def cross_fitted_image(samples, reconstruct, upscale, *, timer=None):
    """The cross-fitted control variate of the module docstring, for any reconstruction of the samples.

    Parameters
    ----------
    samples : PixelSamples
        ``spp >= 2`` samples per output pixel with the grid cell of each.
    reconstruct : callable
        ``reconstruct(train) -> (reconstruction, record)``: a grid signal of
        linear luminance (the signal's grid shape) made from the
        :class:`PixelSamples` ``train`` alone (one fold), and a JSON-able
        dict describing it. It times its own phases.
    upscale : tuple of int
        Output pixels per grid cell along ``(x, y)``.
    timer : PhaseTimer, optional
        Receives the 'other' and 'integration' times of the control variate.

    Returns
    -------
    image : ndarray, shape (height, width, 3), float32
        Each pixel's sample mean (RGB) plus ``beta`` times its chroma times
        the mean of the two folds' corrections (module docstring).
    beta : float
        The control-variate coefficient ``cov(f, R) / var(R)`` from the
        pixel-centred samples of both folds (0 when the reconstructions are
        constant within every pixel).
    folds : list of dict
        ``reconstruct``'s record of each fold (trained on fold 0, then on fold 1).

    Raises
    ------
    ValueError
        ``spp < 2``.

    Notes
    -----
    Unbiased whatever ``reconstruct`` does, as long as it sees only its
    training fold: each correction compares the reconstruction's pixel
    integral with its mean at the other fold's samples, whose cells are
    uniform over the pixel and independent of the reconstruction.
    """
    timer = timer or PhaseTimer()
    if samples.spp < 2:
        raise ValueError(f"the cross-fitted control variate splits each pixel's samples in two folds and needs "
                         f"spp >= 2, got {samples.spp}")
    width, height = samples.resolution
    with timer("other"):
        pixel_rgb = samples.pixel_means().astype(np.float64)
        pixel_chroma = chroma(pixel_rgb)
    correction = np.zeros((height, width))
    covariance = variance = 0.0
    folds = []
    for train_fold in (0, 1):
        with timer("other"):
            train, test = samples.fold(train_fold), samples.fold(1 - train_fold)
        reconstruction, record = reconstruct(train)
        with timer("integration"):
            at_samples = reconstruction.reshape(-1)[test.cells].astype(np.float64).reshape(-1, test.spp)
            level = luminance(test.values).astype(np.float64).reshape(-1, test.spp)
            centred = at_samples - at_samples.mean(axis=1, keepdims=True)
            covariance += float(np.sum(centred * (level - level.mean(axis=1, keepdims=True))))
            variance += float(np.sum(centred * centred))
            correction += 0.5 * (pixel_integral(reconstruction, upscale)
                                 - at_samples.mean(axis=1).reshape(height, width))
        folds.append(record)
    with timer("integration"):
        beta = covariance / variance if variance > 0 else 0.0
        image = pixel_rgb + beta * pixel_chroma * correction[..., None]
    return image.astype(np.float32), beta, folds


@register
class Cosamp(_CosampMethod):
    """CoSaMP reconstructions as a cross-fitted control variate: the mean of path tracing, less variance where they fit."""

    name = "cosamp"
    description = "CoSaMP 4-D reconstruction (thesis 8.1) as a cross-fitted control variate of the pixel's samples (unbiased)"
    requires = (MinimumSpp(2),) + _CosampMethod.requires

    def image(self, samples, grid_shape, timer):
        options = self.options
        return image_from_samples(samples, grid_shape, gamma=options.gamma, sparsity=options.sparsity, timer=timer)


@register
class CosampThesis(_CosampMethod):
    """Exactly the thesis's procedure (8.1.1): the integrated reconstruction times the samples' chroma."""

    name = "cosamp-thesis"
    description = "CoSaMP 4-D reconstruction exactly as thesis 8.1.1 (darker, lower contrast)"
    thesis_procedure = True

    def image(self, samples, grid_shape, timer):
        options = self.options
        return thesis_image_from_samples(samples, grid_shape, gamma=options.gamma, sparsity=options.sparsity,
                                         timer=timer)
