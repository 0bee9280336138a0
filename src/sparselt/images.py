"""Writing images: tone-mapped PNGs for people, float EXRs for programs.

Tone mapping convention (used by every PNG sparselt writes): linear radiance
times ``exposure``, clipped to ``[0, 1]``, then the sRGB transfer curve.
"""

from __future__ import annotations

import io

import numpy as np

from .provenance import atomic_write_bytes


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


def write_png(path, image, *, exposure=1.0):
    """Tone-map a linear ``(height, width, 3)`` image and write it as PNG, atomically."""
    from matplotlib import image as matplotlib_image

    buffer = io.BytesIO()
    matplotlib_image.imsave(buffer, srgb_tonemap(image, exposure), format="png")
    atomic_write_bytes(path, buffer.getvalue())


def save_figure(figure, path, **options):
    """Save a matplotlib figure atomically and close it."""
    import matplotlib.pyplot as pyplot

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", **options)
    pyplot.close(figure)
    atomic_write_bytes(path, buffer.getvalue())
