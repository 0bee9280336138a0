"""How images are shown: luminance, exposure and tone mapping (files are written by :mod:`sparselt.image_io`).

Display conventions, in one place: luminance (Rec. 709); the exposure of a
picture (:func:`reference_exposure`: the reference's 99th luminance
percentile maps to 0.9); tone mapping (linear radiance times the exposure,
clipped to ``[0, 1]``, then the sRGB transfer curve).
"""

from __future__ import annotations

import numpy as np

LUMINANCE_WEIGHTS = (0.2126, 0.7152, 0.0722)


def luminance(rgb):
    """Rec. 709 luminance of linear RGB (last axis of size 3); float32 for float32 input, else float64.

    The luminance channel of thesis 8.1.1 (CoSaMP reconstructs it; chroma
    comes from the samples) and of the comparison's luminance ratio.
    """
    rgb = np.asarray(rgb)
    if rgb.shape[-1:] != (3,):
        raise ValueError(f"luminance needs RGB values on the last axis (size 3), got shape {rgb.shape}")
    dtype = np.float32 if rgb.dtype == np.float32 else np.float64
    return rgb.astype(dtype, copy=False) @ np.asarray(LUMINANCE_WEIGHTS, dtype=dtype)


def srgb_tonemap(image, exposure=1.0):
    """Map linear HDR radiance to display values in ``[0, 1]`` (sRGB curve).

    Parameters
    ----------
    image : ndarray
        Linear radiance, any shape; NaN and negative values map to 0.
    exposure : float, optional
        Multiplier applied before clipping.
    """
    linear = np.clip(np.nan_to_num(np.asarray(image, dtype=np.float64) * exposure, nan=0.0, posinf=1.0), 0.0, 1.0)
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)


def reference_exposure(reference):
    """Exposure that maps the 99th percentile of luminance of ``reference`` to 0.9.

    Parameters
    ----------
    reference : array_like
        Linear HDR image, channels last (e.g. ``(height, width, 3)``).
        Luminance is the mean over the last axis.

    Returns
    -------
    float
        ``0.9 / p99`` where ``p99`` is the 99th percentile of luminance; 1.0
        when the image is empty or ``p99`` is not positive (a black image).

    Notes
    -----
    Used for every tone-mapped picture sparselt writes and, through
    :func:`sparselt.analysis.metrics.display_image`, for every SSIM on HDR
    images, so that what the metric compares is what the pictures show.

    References
    ----------
    Thesis, section 5.2 "Image Quality Metric".
    """
    brightness = np.asarray(reference, dtype=np.float64).mean(axis=-1)  # channel mean, as the thesis's figures
    level = np.percentile(brightness, 99) if brightness.size else 0.0
    return 0.9 / level if level > 0 else 1.0
