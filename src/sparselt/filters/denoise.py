"""Intel Open Image Denoise (OIDN), the denoiser rendering researchers use, through ``pyoidn``.

``pyoidn`` was chosen over ``mitsuba-oidn`` by measurement (see ``benchmarks/filters.py``):
both run OIDN's CPU device; ``pyoidn`` takes numpy arrays directly.
"""

from __future__ import annotations

import numpy as np

INSTALL_HINT = "install it with '.venv/bin/pip install pyoidn' (scripts/bootstrap.sh does this)"


def oidn_available():
    try:
        import pyoidn  # noqa: F401
    except ImportError:
        return False
    return True


def _image(array, name, shape=None):
    array = np.asarray(array)
    if array.ndim != 3 or array.shape[-1] != 3:
        raise ValueError(f"{name} must be (height, width, 3), got shape {array.shape}")
    if shape is not None and array.shape != shape:
        raise ValueError(f"{name} has shape {array.shape}, the colour image {shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} has NaN or infinite values")
    return np.ascontiguousarray(array, dtype=np.float32)


def oidn_denoise(color, albedo=None, normal=None, *, quality="high"):
    """Denoise a linear HDR render with OIDN's ``RT`` filter (colour, optionally albedo and normal).

    Parameters
    ----------
    color : ndarray, shape (height, width, 3)
        Linear HDR radiance, non-negative (negative values are set to 0).
    albedo, normal : ndarray, optional
        Feature buffers of the same shape (albedo in [0, 1], normals in [-1, 1]),
        noisy like the colour (OIDN prefilters them).
    quality : {'high', 'balanced', 'fast'}
        OIDN's quality setting.

    Returns
    -------
    ndarray, float32, same shape

    Raises
    ------
    RuntimeError
        ``pyoidn`` is not installed (the message says how to install it).
    ValueError
        Shapes differ, NaN or infinite values, normals without albedo.

    References
    ----------
    Áfra, A. T. (2019-). Intel Open Image Denoise. https://www.openimagedenoise.org
    """
    try:
        import pyoidn
    except ImportError as error:
        raise RuntimeError(f"OIDN is unavailable: the package pyoidn is missing; {INSTALL_HINT}") from error
    color = np.maximum(_image(color, "color"), 0.0)
    if normal is not None and albedo is None:
        raise ValueError("OIDN takes normals only together with albedo")
    albedo = None if albedo is None else np.clip(_image(albedo, "albedo", color.shape), 0.0, 1.0)
    normal = None if normal is None else np.clip(_image(normal, "normal", color.shape), -1.0, 1.0)
    return np.asarray(pyoidn.denoise(color, albedo, normal, hdr=True, quality=quality), dtype=np.float32)
