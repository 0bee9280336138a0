"""Evaluated Dr.Jit arrays read back as NumPy arrays, in the dtypes the estimators return."""

from __future__ import annotations

import numpy as np

from .runtime import modules


def count_false(mask):
    """Number of ``False`` lanes of an evaluated ``mi.Bool``."""
    array = np.asarray(mask)
    return int(array.size - np.count_nonzero(array))


def to_numpy(value):
    """An evaluated Dr.Jit scalar or 3-vector per lane as numpy: float32 ``(n,)`` / ``(n, 3)``, bool ``(n,)``."""
    mi, dr = modules()
    if isinstance(value, mi.Bool):
        return np.asarray(value, dtype=bool)
    if dr.size_v(value) == 3:
        return rgb_array((value.x, value.y, value.z))
    return np.asarray(value, dtype=np.float32)


def rgb_array(channels):
    """Three evaluated Dr.Jit channels as a float32 ``(n, 3)`` array."""
    return np.stack([np.asarray(channel, dtype=np.float32) for channel in channels], axis=1)


def stacked(channels):
    """Evaluated Dr.Jit channels as float64 ``(n,)`` (one) or ``(n, 3)`` (three)."""
    arrays = [np.asarray(channel, dtype=np.float64) for channel in channels]
    return arrays[0] if len(arrays) == 1 else np.stack(arrays, axis=1)
