"""Evaluated Dr.Jit arrays read back as NumPy arrays, in the dtypes the estimators return, and NumPy arrays
uploaded into kernels (:func:`to_device`)."""

from __future__ import annotations

import numpy as np

from .runtime import modules

#: Bytes of alignment of every NumPy buffer a kernel reads (:func:`to_device`).
UPLOAD_ALIGNMENT = 64


def to_device(array_type, values, dtype):
    """A Dr.Jit array of ``array_type`` (``mi.UInt32``, ``mi.Float``, ...) holding ``values`` as ``dtype``, from a
    copy aligned to :data:`UPLOAD_ALIGNMENT` bytes.

    Dr.Jit reads a NumPy buffer in place and writes the buffer's alignment
    into the kernel's code (``align 64`` when its address is a multiple of 64
    bytes, ``align 1`` otherwise): the same kernel then has two versions,
    and which one a run needs depends on where the allocator happened to put
    the buffer. Measured on a scene file with ``aaf-indirect``: the allocated
    pass recompiled (0.7 s, inside a timed run) on one seed in two. Every
    upload through here has the one alignment.
    """
    values = np.ascontiguousarray(values, dtype=dtype).reshape(-1)
    raw = np.empty(values.nbytes + UPLOAD_ALIGNMENT, dtype=np.uint8)
    offset = -raw.ctypes.data % UPLOAD_ALIGNMENT
    aligned = raw[offset:offset + values.nbytes].view(values.dtype)
    aligned[...] = values
    return array_type(aligned)


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
