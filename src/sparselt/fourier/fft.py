"""The FFT backend: every FFT in sparselt goes through this module.

ducc0 is the backend: it was the fastest multi-threaded n-D FFT measured on
our 2-core machines (a 16M-point real 4-D float32 transform in about 90 ms on
2 threads, scipy about 120 ms; see ``benchmarks/``). Single precision stays
single precision (float32 -> complex64), double stays double.

Normalisation follows numpy's names: ``'backward'`` (forward unnormalised,
inverse divided by N: the ``numpy.fft`` convention that
:class:`~sparselt.fourier.sparse.SparseFourier` uses), ``'ortho'`` (both
divided by sqrt(N): unitary) and ``'forward'``.
"""

from __future__ import annotations

import os

import ducc0
import numpy as np

NORMS = ("backward", "ortho", "forward")


def default_threads():
    """Threads for FFTs: ``SPARSELT_THREADS`` or every core."""
    value = os.environ.get("SPARSELT_THREADS")
    return int(value) if value else (os.cpu_count() or 1)


def _inorm(norm, forward):
    if norm not in NORMS:
        raise ValueError(f"norm must be one of {NORMS}, got {norm!r}")
    if norm == "ortho":
        return 1
    if norm == "backward":
        return 0 if forward else 2
    return 2 if forward else 0


def _axes(array, axes):
    if axes is None:
        return tuple(range(array.ndim))
    axes = tuple(int(axis) for axis in np.atleast_1d(axes))
    normalised = tuple(axis % array.ndim if -array.ndim <= axis < array.ndim else None for axis in axes)
    if None in normalised or len(set(normalised)) != len(normalised):
        raise ValueError(f"axes {axes} are not distinct axes of an array with {array.ndim} dimensions")
    return normalised


def _complex(array):
    array = np.asarray(array)
    if array.dtype in (np.complex64, np.complex128):
        return array
    if array.dtype == np.float32:
        return array.astype(np.complex64)
    return array.astype(np.complex128)


def _real(array):
    array = np.asarray(array)
    if array.dtype in (np.float32, np.float64):
        return array
    if np.iscomplexobj(array):
        raise ValueError("a real FFT needs real input; use fftn for complex data")
    return array.astype(np.float64)


def fftn(array, axes=None, *, norm="backward", out=None, threads=None):
    """Forward complex FFT over ``axes`` (all by default), like ``numpy.fft.fftn``."""
    array = _complex(array)
    return ducc0.fft.c2c(array, axes=_axes(array, axes), forward=True, inorm=_inorm(norm, True), out=out,
                         nthreads=threads or default_threads())


def ifftn(array, axes=None, *, norm="backward", out=None, threads=None):
    """Inverse complex FFT over ``axes``, like ``numpy.fft.ifftn``."""
    array = _complex(array)
    return ducc0.fft.c2c(array, axes=_axes(array, axes), forward=False, inorm=_inorm(norm, False), out=out,
                         nthreads=threads or default_threads())


def rfftn(array, axes=None, *, norm="backward", out=None, threads=None):
    """Real-to-complex FFT, like ``numpy.fft.rfftn``: the last axis keeps ``n // 2 + 1`` frequencies."""
    array = _real(array)
    return ducc0.fft.r2c(array, axes=_axes(array, axes), forward=True, inorm=_inorm(norm, True), out=out,
                         nthreads=threads or default_threads())


def irfftn(array, last_size, axes=None, *, norm="backward", out=None, threads=None, overwrite_input=False):
    """Inverse of :func:`rfftn`; ``last_size`` is the length of the last transformed axis.

    ``overwrite_input=True`` lets the transform destroy ``array`` (about 30%
    faster: no internal copy).
    """
    array = _complex(array)
    return ducc0.fft.c2r(array, axes=_axes(array, axes), lastsize=int(last_size), forward=False,
                         inorm=_inorm(norm, False), out=out, nthreads=threads or default_threads(),
                         allow_overwriting_input=bool(overwrite_input))
