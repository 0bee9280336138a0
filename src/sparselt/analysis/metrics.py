"""Image quality metrics: SSIM, PSNR, RMSE and relMSE (thesis section 5.2).

All metrics compare an ``image`` against a ``reference`` of the same shape and
compute in float64.

HDR convention
--------------
Rendered images are linear HDR radiance, but SSIM needs values on a known,
bounded range. Every SSIM that sparselt reports on HDR images uses one
convention, implemented by :func:`image_ssim`:

1. Both images are multiplied by the exposure of the *reference*,
   :func:`reference_exposure` (the exposure that maps the 99th percentile of
   the reference's luminance to 0.9; the same exposure ``sparselt show`` uses
   for its pictures).
2. Both are mapped to ``[0, 1]`` with the sRGB transfer curve,
   :func:`sparselt.images.srgb_tonemap` (which clips to ``[0, 1]``), giving
   :func:`display_image`.
3. :func:`structural_similarity` is computed on the two display images with
   ``data_range=1.0``, per colour channel, and averaged over the channels.

Because the exposure comes from the reference only, the score does not change
when both images are scaled by the same positive factor, and an image that is
uniformly too bright or too dark is penalised.

References
----------
Thesis, section 5.2 "Image Quality Metric".

Wang, Z., Bovik, A. C., Sheikh, H. R. and Simoncelli, E. P. (2004). Image
quality assessment: from error visibility to structural similarity. IEEE
Transactions on Image Processing, 13(4), 600-612. doi:10.1109/TIP.2003.819861
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from scipy import ndimage

from ..checks import check_positive_finite, finite_float_array
from ..images import luminance, reference_exposure, srgb_tonemap  # noqa: F401  (reference_exposure re-exported)

__all__ = [
    "TRIMMED_FRACTION",
    "pixel_relative_squared_error",
    "relative_error_denominator",
    "trimmed_pixel_count",
    "trimmed_relative_mean_squared_error",
    "display_image",
    "flip_error",
    "image_ssim",
    "peak_signal_to_noise_ratio",
    "reference_exposure",
    "relative_mean_squared_error",
    "root_mean_squared_error",
    "structural_similarity",
]

#: Standard deviation of the Gaussian SSIM window, in pixels (Wang et al. 2004).
GAUSSIAN_SIGMA = 1.5
#: The Gaussian is cut at this many standard deviations: radius 5, an 11x11 window.
GAUSSIAN_TRUNCATE = 3.5
#: Side of the square SSIM window, in pixels.
WINDOW_SIZE = 2 * int(GAUSSIAN_TRUNCATE * GAUSSIAN_SIGMA + 0.5) + 1
#: Stabilising constants: ``c1 = (K1 * L)**2`` and ``c2 = (K2 * L)**2`` (eq. 5.2).
K1 = 0.01
K2 = 0.03


def _image_pair(image, reference):
    """Both arrays as float64, checked to be finite, non-empty and of the same shape."""
    image = finite_float_array(image, "image")
    reference = finite_float_array(reference, "reference")
    if image.shape != reference.shape:
        raise ValueError(
            f"image and reference must have the same shape; got image.shape={image.shape} "
            f"and reference.shape={reference.shape}"
        )
    if image.size == 0:
        raise ValueError(f"image and reference must not be empty; got shape {image.shape}")
    return image, reference


def _positive_finite(value, name, *, hint):
    """``value`` as a positive finite float; ValueError (or TypeError) otherwise; None means it was not given."""
    if value is None:
        raise ValueError(f"{name} is required: pass {name}=<{hint}> as a keyword argument")
    return check_positive_finite(value, name, hint=hint)


# --------------------------------------------------------------------------- SSIM


def _gaussian_window(array):
    return ndimage.gaussian_filter(array, sigma=GAUSSIAN_SIGMA, truncate=GAUSSIAN_TRUNCATE, mode="reflect")


def _ssim_map(image, reference, data_range):
    """Per-pixel SSIM (eq. 5.2) of two 2-D float64 arrays, before cropping."""
    mean_image = _gaussian_window(image)
    mean_reference = _gaussian_window(reference)
    # Population (weighted) moments: E[xy] - E[x] E[y], no N / (N - 1) correction.
    variance_image = _gaussian_window(image * image) - mean_image * mean_image
    variance_reference = _gaussian_window(reference * reference) - mean_reference * mean_reference
    covariance = _gaussian_window(image * reference) - mean_image * mean_reference
    c1 = (K1 * data_range) ** 2
    c2 = (K2 * data_range) ** 2
    luminance_numerator = 2 * mean_image * mean_reference + c1
    structure_numerator = 2 * covariance + c2
    luminance_denominator = mean_image**2 + mean_reference**2 + c1
    structure_denominator = variance_image + variance_reference + c2
    return (luminance_numerator * structure_numerator) / (luminance_denominator * structure_denominator)


def _cropped_mean(ssim_map):
    border = (WINDOW_SIZE - 1) // 2
    return float(ssim_map[border:-border, border:-border].mean(dtype=np.float64))


def structural_similarity(image, reference, *, data_range=None, channel_axis=None, full=False):
    """Mean structural similarity (SSIM) of ``image`` against ``reference``.

    Parameters
    ----------
    image, reference : array_like
        Two images of the same shape: ``(height, width)`` when
        ``channel_axis`` is None, otherwise ``(height, width)`` plus one
        channel axis. Computed in float64; values must be finite.
    data_range : float
        Required, keyword only. The dynamic range ``L`` of the images
        (maximum possible value minus minimum possible value), for example
        ``1.0`` for display images in ``[0, 1]``. Must be finite and > 0.
        There is no default: guessing it from the data makes SSIM values
        incomparable between images.
    channel_axis : int or None, optional
        The axis that holds colour channels, or None (default) for a
        grayscale image. With channels, SSIM is computed for each channel
        separately and the result is the mean over channels.
    full : bool, optional
        If True, also return the per-pixel SSIM map (same shape as the
        input, not cropped).

    Returns
    -------
    float
        The mean SSIM, in ``[-1, 1]``; exactly 1 for identical images.
    ndarray
        Only when ``full`` is True: the per-pixel SSIM map.

    Raises
    ------
    ValueError
        If ``data_range`` is missing, None, not finite or not positive; if the
        shapes differ; if the images are not 2-D (plus the channel axis); if a
        side is shorter than the 11-pixel window; if a value is NaN or
        infinite; if ``channel_axis`` is out of range.
    TypeError
        If ``data_range`` or ``channel_axis`` has the wrong type, or an image
        is not numeric.

    Notes
    -----
    For each pixel, with Gaussian-weighted local statistics over the window
    around it (eq. 5.2),

    .. math::

        \\mathrm{SSIM}(x, y) = \\frac{(2\\mu_x\\mu_y + c_1)(2\\sigma_{xy} + c_2)}
                                 {(\\mu_x^2 + \\mu_y^2 + c_1)(\\sigma_x^2 + \\sigma_y^2 + c_2)},
        \\qquad c_1 = (k_1 L)^2, \\quad c_2 = (k_2 L)^2,

    where :math:`\\mu` are weighted means, :math:`\\sigma_x^2, \\sigma_y^2`
    weighted (population, not sample) variances, :math:`\\sigma_{xy}` the
    weighted covariance, :math:`L` = ``data_range``, :math:`k_1 = 0.01` and
    :math:`k_2 = 0.03`. The weights are a Gaussian of standard deviation 1.5
    pixels truncated at 3.5 standard deviations, an 11x11 window, applied with
    :func:`scipy.ndimage.gaussian_filter` in ``'reflect'`` mode. The result is
    the mean of the map after removing a border of 5 pixels (half the window)
    on every side, where the window reaches past the image.

    This is numerically the same as scikit-image's
    ``structural_similarity(image, reference, data_range=L,
    gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
    channel_axis=channel_axis)``, which the tests check.

    References
    ----------
    Thesis, section 5.2 "Image Quality Metric", eq. 5.2.

    Wang, Z., Bovik, A. C., Sheikh, H. R. and Simoncelli, E. P. (2004). Image
    quality assessment: from error visibility to structural similarity. IEEE
    Transactions on Image Processing, 13(4), 600-612.
    """
    data_range = _positive_finite(data_range, "data_range", hint="max possible value minus min possible value, e.g. 1.0")
    if not isinstance(full, (bool, np.bool_)):
        raise TypeError(f"full must be True or False; got {full!r}")
    image, reference = _image_pair(image, reference)

    if channel_axis is None:
        if image.ndim != 2:
            raise ValueError(
                f"with channel_axis=None the images must be 2-D (height, width); got shape {image.shape}. "
                "For colour images pass channel_axis (e.g. channel_axis=-1)."
            )
        spatial_shape = image.shape
    else:
        if isinstance(channel_axis, bool) or not isinstance(channel_axis, numbers.Integral):
            raise TypeError(f"channel_axis must be an int or None; got {channel_axis!r}")
        if image.ndim != 3:
            raise ValueError(
                f"with channel_axis={channel_axis} the images must be 3-D (two image axes and one channel axis); "
                f"got shape {image.shape}"
            )
        if not -image.ndim <= channel_axis < image.ndim:
            raise ValueError(
                f"channel_axis must be None or in [{-image.ndim}, {image.ndim - 1}] for {image.ndim}-D images; "
                f"got {channel_axis}"
            )
        channel_axis = int(channel_axis) % image.ndim
        image = np.moveaxis(image, channel_axis, -1)
        reference = np.moveaxis(reference, channel_axis, -1)
        spatial_shape = image.shape[:2]
    if min(spatial_shape) < WINDOW_SIZE:
        raise ValueError(
            f"images must be at least {WINDOW_SIZE}x{WINDOW_SIZE} pixels (the Gaussian SSIM window); "
            f"got image sides {tuple(spatial_shape)}"
        )

    # SSIM is invariant to scaling both images and L together: work in units of L, so that squares of
    # huge values (data ranges near 1e300) cannot overflow.
    image, reference, data_range = image / data_range, reference / data_range, 1.0
    if channel_axis is None:
        ssim_map = _ssim_map(image, reference, data_range)
        mean = _cropped_mean(ssim_map)
    else:
        maps = [_ssim_map(image[..., channel], reference[..., channel], data_range) for channel in range(image.shape[-1])]
        mean = float(np.mean([_cropped_mean(channel_map) for channel_map in maps]))
        ssim_map = np.moveaxis(np.stack(maps, axis=-1), -1, channel_axis)
    if full:
        return mean, ssim_map
    return mean


# --------------------------------------------------------------------------- pixel-wise errors


def root_mean_squared_error(image, reference):
    """Root mean squared error (RMSE) between ``image`` and ``reference``.

    Parameters
    ----------
    image, reference : array_like
        Arrays of the same (any) shape with finite values; computed in float64.

    Returns
    -------
    float
        ``sqrt(mean((image - reference)**2))``, in the units of the images.

    Raises
    ------
    ValueError
        If the shapes differ, the arrays are empty, or a value is NaN or infinite.

    Notes
    -----
    .. math:: \\mathrm{RMSE} = \\sqrt{\\frac{1}{N}\\sum_i (x_i - y_i)^2}

    References
    ----------
    Thesis, section 5.2 "Image Quality Metric".
    """
    image, reference = _image_pair(image, reference)
    return float(np.sqrt(np.mean((image - reference) ** 2)))


def peak_signal_to_noise_ratio(image, reference, *, data_range=None):
    """Peak signal-to-noise ratio (PSNR), in decibels.

    Parameters
    ----------
    image, reference : array_like
        Arrays of the same (any) shape with finite values; computed in float64.
    data_range : float
        Required, keyword only. The peak value ``L`` (maximum possible value
        minus minimum possible value), e.g. ``1.0`` for display images. Must
        be finite and > 0.

    Returns
    -------
    float
        ``10 log10(L**2 / MSE)``; ``inf`` for identical arrays.

    Raises
    ------
    ValueError
        If ``data_range`` is missing, None, not finite or not positive; if the
        shapes differ, the arrays are empty, or a value is NaN or infinite.
    TypeError
        If ``data_range`` is not a real number.

    Notes
    -----
    .. math:: \\mathrm{PSNR} = 10 \\log_{10} \\frac{L^2}{\\frac{1}{N}\\sum_i (x_i - y_i)^2}

    References
    ----------
    Thesis, section 5.2 "Image Quality Metric".
    """
    data_range = _positive_finite(data_range, "data_range", hint="max possible value minus min possible value, e.g. 1.0")
    image, reference = _image_pair(image, reference)
    mean_squared_error = float(np.mean((image - reference) ** 2))
    if mean_squared_error == 0.0:
        return math.inf
    return float(10.0 * np.log10(data_range**2 / mean_squared_error))


def relative_mean_squared_error(image, reference, *, epsilon=1e-2):
    """Relative mean squared error (relMSE), as used in rendering.

    Parameters
    ----------
    image, reference : array_like
        Same shape: ``(height, width)`` for grayscale or ``(height, width,
        channels)`` with channels last; finite values, computed in float64.
    epsilon : float, optional
        Added to the denominator so that black reference pixels do not divide
        by zero (default ``1e-2``). Must be finite and > 0.

    Returns
    -------
    float
        The mean over pixels (and channels) of the squared error divided by
        the reference's squared value plus ``epsilon``.

    Raises
    ------
    ValueError
        If ``epsilon`` is not finite or not positive; if the shapes differ,
        the arrays are not 2-D or 3-D, are empty, or hold NaN or infinite values.
    TypeError
        If ``epsilon`` is not a real number.

    Notes
    -----
    For a grayscale image,

    .. math:: \\mathrm{relMSE} = \\frac{1}{N}\\sum_p \\frac{(x_p - y_p)^2}{y_p^2 + \\epsilon}.

    For a colour image ``(height, width, C)`` the denominator is shared by the
    channels of a pixel: the per-pixel mean over channels of the squared
    reference, so a pixel that is dark in one channel only does not dominate,

    .. math:: \\mathrm{relMSE} = \\frac{1}{N C}\\sum_p \\sum_c
              \\frac{(x_{p,c} - y_{p,c})^2}{\\frac{1}{C}\\sum_{c'} y_{p,c'}^2 + \\epsilon}.

    References
    ----------
    Thesis, section 5.2 "Image Quality Metric" (for the metric family);
    Rousselle, F., Knaus, C. and Zwicker, M. (2011). Adaptive sampling and
    reconstruction using greedy error minimization. ACM Transactions on
    Graphics, 30(6) (relMSE as used in rendering).
    """
    return float(np.mean(pixel_relative_squared_error(image, reference, epsilon=epsilon)))


def relative_error_denominator(reference, *, epsilon):
    """relMSE's per-pixel denominator: the mean over channels of the squared reference, plus ``epsilon``.

    ``(height, width)`` for a grayscale or colour reference (float64); the one
    place :func:`relative_mean_squared_error`, its per-pixel map and the
    reference's floor map divide by.
    """
    reference = np.asarray(reference, dtype=np.float64)
    if reference.ndim == 2:
        return reference**2 + epsilon
    if reference.ndim == 3:
        return np.mean(reference**2, axis=-1) + epsilon
    raise ValueError(f"images must be (height, width) or (height, width, channels); got shape {reference.shape}")


def pixel_relative_squared_error(image, reference, *, epsilon=1e-2):
    """relMSE's per-pixel terms, ``(height, width)``: the mean over channels of ``(x - y)^2 / (mean_c y^2 + eps)``.

    Its mean over pixels is :func:`relative_mean_squared_error`; the error
    maps, :func:`trimmed_relative_mean_squared_error` and the outlier share
    read it. Validation as :func:`relative_mean_squared_error`.
    """
    epsilon = _positive_finite(epsilon, "epsilon", hint="a small positive number, e.g. 1e-2")
    image, reference = _image_pair(image, reference)
    denominator = relative_error_denominator(reference, epsilon=epsilon)
    squared = (image - reference) ** 2
    if squared.ndim == 3:
        squared = np.mean(squared, axis=-1)
    return squared / denominator


#: The share of per-pixel errors the field's trimmed relMSE discards: the top 0.1% (SimpleImageIO's
#: ``RelMSE_OutlierRejection``; Figueiredo et al. 2025).
TRIMMED_FRACTION = 0.001


def trimmed_pixel_count(pixels, fraction=TRIMMED_FRACTION):
    """How many of ``pixels`` per-pixel errors the trimmed relMSE discards: ``floor(fraction * pixels)``, at
    least one (and none of a single pixel)."""
    if pixels <= 1:
        return 0
    return min(max(1, int(math.floor(fraction * pixels))), pixels - 1)


def trimmed_relative_mean_squared_error(image, reference, *, epsilon=1e-2, fraction=TRIMMED_FRACTION):
    """relMSE with the largest ``fraction`` of per-pixel errors discarded, and the share of relMSE they held.

    Parameters
    ----------
    image, reference : array_like
        As :func:`relative_mean_squared_error`.
    epsilon : float, optional
        relMSE's epsilon (default ``1e-2``).
    fraction : float, optional
        The share of pixels discarded, largest errors first:
        :func:`trimmed_pixel_count` (``floor(fraction * pixels)``, at least
        one pixel). Default 0.1%, the field's convention.

    Returns
    -------
    trimmed : float
        The mean of the remaining per-pixel errors (:func:`pixel_relative_squared_error`).
    outlier_share : float
        The discarded pixels' share of the untrimmed relMSE's sum (0 when the
        images are equal): above 0.5, a few pixels decide the metric.
    kept : ndarray of bool, shape (height, width)
        The pixels kept (ties at the threshold broken by position, so exactly
        ``pixels - trimmed_pixel_count(pixels)`` are kept).

    Notes
    -----
    Fireflies (rare high-energy samples) put most of a path tracer's relMSE
    into a handful of pixels at low spp; the trimmed metric keeps a verdict
    from being decided by them (Figueiredo et al. 2025, which average 10
    runs of it; SimpleImageIO, ``Metrics.RelMSE_OutlierRejection``).
    """
    errors = pixel_relative_squared_error(image, reference, epsilon=epsilon)
    flat = errors.ravel()
    discarded = trimmed_pixel_count(flat.size, fraction)
    kept = np.ones(flat.size, dtype=bool)
    if discarded:
        kept[np.argpartition(flat, flat.size - discarded)[flat.size - discarded:]] = False
    total = float(flat.sum())
    trimmed = float(flat[kept].mean())
    share = float(flat[~kept].sum()) / total if total > 0 else 0.0
    return trimmed, share, kept.reshape(errors.shape)


# --------------------------------------------------------------------------- HDR convention


def display_image(image, reference):
    """Map linear HDR ``image`` to display values in ``[0, 1]``, exposed for ``reference``.

    Parameters
    ----------
    image : array_like
        Linear HDR image ``(height, width, 3)`` to map.
    reference : array_like
        The reference image of the same shape; only its exposure
        (:func:`reference_exposure`) is used. Pass the reference itself as
        ``image`` to get the reference's display image.

    Returns
    -------
    ndarray
        float64 array of the same shape with values in ``[0, 1]``:
        ``srgb_tonemap(image, reference_exposure(reference))``. Values that
        the exposure pushes above 1 are clipped to 1 and negative values to 0,
        as in the PNGs sparselt writes.

    Raises
    ------
    ValueError
        If the shapes differ, the images are not ``(height, width, 3)``, or a
        value is NaN or infinite.

    Notes
    -----
    This is the one HDR-to-display convention for SSIM in sparselt; see the
    module docstring.

    References
    ----------
    Thesis, section 5.2 "Image Quality Metric".
    """
    image, reference = _image_pair(image, reference)
    if image.ndim != 3 or image.shape[-1] != 3:
        raise ValueError(f"images must be (height, width, 3) linear RGB; got shape {image.shape}")
    return srgb_tonemap(image, reference_exposure(reference))


def flip_error(image, reference):
    """Mean HDR-FLIP error of a linear RGB image against a linear RGB reference (0 = indistinguishable).

    FLIP (Andersson et al. 2020, 2021) models what a viewer notices flipping
    between the two images; its HDR mode tone-maps both at the exposures
    spanning the reference's range and keeps the worst error per pixel. Both
    images must be ``(height, width, 3)`` and are clipped at 0 (FLIP takes
    non-negative radiance); computed by NVIDIA's ``flip-evaluator`` package
    at its default 67 pixels per degree.

    References
    ----------
    Andersson, P., Nilsson, J., Shirley, P. and Akenine-Möller, T. (2021).
    Visualizing errors in rendered high dynamic range images. Eurographics.
    """
    import flip_evaluator

    image, reference = np.asarray(image), np.asarray(reference)
    if image.shape != reference.shape or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"FLIP needs two (height, width, 3) images of one shape, got {image.shape} and "
                         f"{reference.shape}")
    test = np.ascontiguousarray(np.maximum(image, 0), dtype=np.float32)
    target = np.ascontiguousarray(np.maximum(reference, 0), dtype=np.float32)
    if not np.any(target > 0):  # FLIP's HDR exposure range comes from the reference: it aborts the process on none
        raise ValueError("HDR-FLIP needs a reference with some light in it: every pixel of the reference is 0 (or "
                         "negative)")
    _, mean, _ = flip_evaluator.evaluate(target, test, "HDR", applyMagma=False, computeMeanError=True)
    return float(mean)


def image_ssim(image, reference):
    """SSIM of a linear HDR RGB ``image`` against ``reference``, by the sparselt convention.

    Parameters
    ----------
    image, reference : array_like
        Linear HDR images ``(height, width, 3)`` of the same shape, at least
        11x11 pixels, with finite values.

    Returns
    -------
    float
        ``structural_similarity(display_image(image, reference),
        display_image(reference, reference), data_range=1.0,
        channel_axis=-1)``: the mean over R, G, B of the SSIM of the display
        images. 1 for identical images; unchanged when both images are
        multiplied by the same positive factor.

    Raises
    ------
    ValueError
        As :func:`display_image` and :func:`structural_similarity`.

    Notes
    -----
    Both images are exposed with :func:`reference_exposure` of the reference,
    mapped with the sRGB curve to ``[0, 1]`` (:func:`display_image`), and
    compared with eq. 5.2 with :math:`L = 1`.

    References
    ----------
    Thesis section 5.2, eq. 5.2, and Wang et al. (2004), as :func:`structural_similarity`.
    """
    return structural_similarity(
        display_image(image, reference),
        display_image(reference, reference),
        data_range=1.0,
        channel_axis=-1,
    )


# --------------------------------------------------------------------------- brightness and contrast


def luminance_ratio(image, reference):
    """Mean Rec. 709 luminance of ``image`` over that of ``reference`` (1 = same brightness).

    The comparison's darkening measure (thesis 8.1.2: CoSaMP images
    "considerably darker").
    """
    image, reference = _image_pair(image, reference)
    level = float(luminance(reference).mean())
    if level <= 0:
        raise ValueError("the reference is black (mean luminance <= 0): a luminance ratio is undefined")
    return float(luminance(image).mean()) / level


def contrast_ratio(image, reference):
    """RMS contrast (standard deviation over mean of luminance) of ``image`` over that of ``reference``.

    Below 1: flatter than the reference ("lower contrast", thesis 8.1.2).
    """
    image, reference = _image_pair(image, reference)

    def contrast(values):
        level = luminance(values)
        mean = float(level.mean())
        return float(level.std()) / mean if mean > 0 else 0.0

    base = contrast(reference)
    if base <= 0:
        raise ValueError("the reference has no contrast (uniform or black): a contrast ratio is undefined")
    return contrast(image) / base
