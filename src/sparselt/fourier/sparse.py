"""Sparse Fourier representations: the common output of every recovery algorithm.

A :class:`SparseFourier` holds ``K`` coefficients of an n-D discrete Fourier
transform in the ``numpy.fft.fftn`` convention (unnormalised forward DFT),
addressed by flat C-order indices into the spectrum of shape ``shape``:

.. math:: f(n) = \\frac{1}{N} \\sum_{j=0}^{K-1} c_j \\, e^{2 \\pi i \\langle k_j, n / s \\rangle}

so that :meth:`SparseFourier.to_signal` equals ``numpy.fft.ifftn`` of the
scattered coefficients (thesis eq. 4.2). Values may carry trailing channel
axes (``(K, 3)`` for RGB sharing one support).

Real signals have Hermitian spectra, ``c(-k) = conj(c(k))``. A representation
built with ``real=True`` must be closed under that symmetry (every index has
its partner with the conjugate value), :meth:`SparseFourier.largest` keeps
partners together, and :meth:`SparseFourier.to_signal` returns a real array.
"""

from __future__ import annotations

import numpy as np

from ..checks import check_integer
from . import fft
from .hermitian import largest_closed, partner_indices  # noqa: F401  (partner_indices re-exported)


def check_shape(shape):
    """A shape as a tuple of positive ints, or a ValueError saying what is allowed."""
    try:
        shape = tuple(int(size) for size in shape)
    except TypeError:
        raise ValueError(f"shape must be a sequence of positive integers, got {shape!r}") from None
    if not shape or any(size <= 0 for size in shape):
        raise ValueError(f"shape must be a non-empty sequence of positive integers, got {shape!r}")
    return shape


class SparseFourier:
    """``K`` Fourier coefficients of a signal of shape ``shape``.

    Parameters
    ----------
    shape : sequence of int
        Shape of the signal (and of its full spectrum).
    indices : array_like of int, shape (K,)
        Distinct flat C-order indices into the spectrum. Stored sorted.
    values : array_like, shape (K,) or (K, channels...)
        Complex coefficients, ``numpy.fft.fftn`` convention.
    real : bool, optional
        The represented signal is real: the support must be closed under
        ``k -> -k`` with conjugate values (checked to a relative tolerance).

    Raises
    ------
    ValueError
        Indices out of range or repeated, values of the wrong length, or a
        ``real`` representation that is not Hermitian.
    """

    def __init__(self, shape, indices, values, *, real=False, tolerance=1e-4):
        self.shape = check_shape(shape)
        self.size = int(np.prod(self.shape, dtype=np.int64))
        indices = np.asarray(indices)
        if indices.ndim != 1 or (indices.size and not np.issubdtype(indices.dtype, np.integer)):
            raise ValueError(f"indices must be a 1-D array of integers, got dtype {indices.dtype} and shape {indices.shape}")
        indices = indices.astype(np.int64)
        values = np.asarray(values)
        if values.ndim == 0 or values.shape[0] != indices.size:
            raise ValueError(f"values must have one row per index: {indices.size} indices, values of shape {values.shape}")
        if indices.size and (indices.min() < 0 or indices.max() >= self.size):
            bad = indices[(indices < 0) | (indices >= self.size)][0]
            raise ValueError(f"index {bad} is out of range for shape {self.shape} (0 <= index < {self.size})")
        order = np.argsort(indices, kind="stable")
        indices = indices[order]
        if indices.size > 1 and np.any(indices[1:] == indices[:-1]):
            raise ValueError(f"indices must be distinct; {indices[1:][indices[1:] == indices[:-1]][0]} is repeated")
        if not np.iscomplexobj(values):
            values = values.astype(np.complex128 if values.dtype != np.float32 else np.complex64)
        self.indices = indices
        self.values = values[order]
        self.real = bool(real)
        if self.real:
            self._check_hermitian(tolerance)

    # -- construction ------------------------------------------------------

    @classmethod
    def from_spectrum(cls, spectrum, indices=None, *, real=False, channel_axes=0):
        """Take coefficients of a dense spectrum (all of them, or those at ``indices``).

        ``channel_axes`` trailing axes of ``spectrum`` are channels.
        """
        spectrum = np.asarray(spectrum)
        shape = spectrum.shape[:spectrum.ndim - channel_axes] if channel_axes else spectrum.shape
        flat = spectrum.reshape((-1,) + spectrum.shape[len(shape):])
        if indices is None:
            indices = np.arange(flat.shape[0], dtype=np.int64)
        indices = np.asarray(indices, dtype=np.int64)
        return cls(shape, indices, flat[indices], real=real)

    @classmethod
    def from_signal(cls, signal, *, channel_axes=0):
        """The full (dense) representation of a signal: its FFT.

        Parameters
        ----------
        signal : array_like of numbers
            At least one grid axis, then ``channel_axes`` trailing channel axes.
        channel_axes : int, optional
            Trailing axes that are channels (not transformed).

        Raises
        ------
        TypeError
            ``signal`` is not an array of numbers.
        ValueError
            ``signal`` has no grid axis (a scalar) or an empty one.
        """
        channel_axes = check_integer("channel_axes", channel_axes, 0)
        signal = np.asarray(signal)
        if signal.dtype.kind not in "biufc":
            raise TypeError(f"signal must be an array of numbers, got dtype {signal.dtype}")
        if signal.ndim - channel_axes < 1:
            raise ValueError(f"signal must have at least one grid axis besides its {channel_axes} channel axes, got an "
                             f"array of shape {signal.shape}" + (" (a scalar)" if signal.ndim == 0 else ""))
        if signal.size == 0:
            raise ValueError(f"signal must not be empty, got an array of shape {signal.shape}")
        axes = tuple(range(signal.ndim - channel_axes))
        return cls.from_spectrum(fft.fftn(signal, axes=axes), real=not np.iscomplexobj(signal), channel_axes=channel_axes)

    # -- properties ----------------------------------------------------------

    @property
    def sparsity(self):
        """Number of coefficients ``K``."""
        return int(self.indices.size)

    @property
    def channel_shape(self):
        return tuple(self.values.shape[1:])

    def coordinates(self):
        """Frequency coordinates of each coefficient, shape (K, D), in ``[0, shape)``."""
        return np.stack(np.unravel_index(self.indices, self.shape), axis=1)

    def partners(self):
        """Flat indices of the Hermitian partners of the coefficients."""
        return partner_indices(self.shape, self.indices)

    def _check_hermitian(self, tolerance):
        partners = self.partners()
        position = np.searchsorted(self.indices, partners)
        position = np.minimum(position, max(self.sparsity - 1, 0))
        present = self.indices[position] == partners if self.sparsity else np.zeros(0, bool)
        if not np.all(present):
            missing = self.indices[~present][0]
            raise ValueError(
                f"a real representation needs the Hermitian partner of every coefficient; index {missing} has "
                f"none (partner {partners[~present][0]}); use .hermitian_closure() or real=False"
            )
        scale = max(float(np.abs(self.values).max(initial=0.0)), 1e-30)
        mismatch = np.abs(self.values - np.conj(self.values[position])).max(initial=0.0)
        if mismatch > tolerance * scale:
            raise ValueError(f"coefficients are not conjugate-symmetric (largest mismatch {mismatch:.3g}); not a real signal")

    def hermitian_closure(self):
        """The representation of the real part of the signal, closed under ``k -> -k``.

        Every coefficient becomes the Hermitian part ``(c(k) + conj(c(-k))) / 2``
        (a missing coefficient counts as zero), so the closure's signal is the
        real part of the original signal.
        """
        partners = self.partners()
        union = np.union1d(self.indices, partners)
        values = np.zeros((union.size,) + self.channel_shape, dtype=self.values.dtype)
        values[np.searchsorted(union, self.indices)] += self.values
        values[np.searchsorted(union, partners)] += np.conj(self.values)
        values /= 2
        return SparseFourier(self.shape, union, values, real=True)

    # -- operations ----------------------------------------------------------

    def to_spectrum(self, dtype=None):
        """The full dense spectrum (zeros off the support), shape ``shape + channels``."""
        dtype = dtype or self.values.dtype
        dense = np.zeros((self.size,) + self.channel_shape, dtype=dtype)
        dense[self.indices] = self.values
        return dense.reshape(self.shape + self.channel_shape)

    def to_signal(self, dtype=None, *, work=None, out=None):
        """The signal: ``numpy.fft.ifftn`` of the spectrum over the signal axes (real part if ``real``).

        Parameters
        ----------
        dtype : {numpy.float32, numpy.float64}, optional
            Precision of a ``real`` signal without channels (default: that of
            the values). Such a signal is synthesised from its half spectrum by
            one real inverse FFT, in half the memory and time of a complex one.
        work, out : ndarray, optional
            For that real synthesis: an all-zero half spectrum (shape
            ``shape[:-1] + (shape[-1] // 2 + 1,)``, the complex type of
            ``dtype``) that the transform may destroy, and the array of
            ``shape`` and ``dtype`` to write the signal into (the operator's
            buffers, :meth:`PartialFourier.release_buffers`: no fresh
            signal-size pages to fault in). The result is the same.
        """
        axes = tuple(range(len(self.shape)))
        if self.real and not self.channel_shape:
            real_dtype = np.dtype(dtype) if dtype is not None else np.dtype(self.values.real.dtype)
            last = self.shape[-1]
            half_shape = self.shape[:-1] + (last // 2 + 1,)
            complex_dtype = np.dtype(np.complex64 if real_dtype == np.float32 else np.complex128)
            coordinates = np.unravel_index(self.indices, self.shape)
            kept = coordinates[-1] <= last // 2  # the mirror of an interior entry is implicit in c2r
            if work is None:
                half = np.zeros(half_shape, dtype=complex_dtype)
            elif work.shape != half_shape or work.dtype != complex_dtype:
                raise ValueError(f"work must be a zeroed {complex_dtype} array of shape {half_shape}, "
                                 f"got {work.dtype} {work.shape}")
            else:
                half = work
            if out is not None and (out.shape != self.shape or out.dtype != real_dtype):
                raise ValueError(f"out must be a {real_dtype} array of shape {self.shape}, got {out.dtype} {out.shape}")
            half[tuple(c[kept] for c in coordinates)] = self.values[kept]
            return fft.irfftn(half, last, axes=axes, out=out, overwrite_input=True)
        signal = fft.ifftn(self.to_spectrum(), axes=axes)
        return np.ascontiguousarray(signal.real) if self.real else signal

    def energy(self):
        """Energy of each coefficient, summed over channels: ``|c|^2``."""
        energy = np.abs(self.values) ** 2
        return energy.reshape(self.sparsity, -1).sum(axis=1)

    def largest(self, count):
        """The ``count`` coefficients of largest energy, by the top-K rule of :mod:`sparselt.fourier.hermitian`.

        For a ``real`` representation Hermitian pairs are kept together: the
        result has ``count`` or ``count - 1`` coefficients. Ties go to the
        smaller flat index.
        """
        count = int(count)
        if count < 0:
            raise ValueError(f"count must be non-negative, got {count}")
        if count >= self.sparsity:
            return self
        energy = self.energy()
        if not self.real:
            keep = np.sort(np.lexsort((self.indices, -energy))[:count])
            return SparseFourier(self.shape, self.indices[keep], self.values[keep])
        kept = largest_closed(energy, count, self.shape, indices=self.indices)
        keep = np.searchsorted(self.indices, kept)
        return SparseFourier(self.shape, self.indices[keep], self.values[keep], real=True)

    def __repr__(self):
        return (f"SparseFourier(shape={self.shape}, K={self.sparsity}, channels={self.channel_shape}, "
                f"real={self.real})")


def sample_support(size, count, rng):
    """``count`` distinct indices of ``[0, size)``, uniformly at random, in O(count) memory.

    Draws integers with replacement and keeps first occurrences, in draw order,
    until ``count`` are distinct: a uniformly random subset in random order,
    without the O(size) memory of ``rng.choice(size, count, replace=False)``.

    Raises
    ------
    ValueError
        ``count`` negative or larger than ``size``.
    """
    size, count = int(size), int(count)
    if not 0 <= count <= size:
        raise ValueError(f"count must be between 0 and size={size}, got {count}")
    chosen = np.empty(0, dtype=np.int64)
    while chosen.size < count:
        needed = count - chosen.size
        draw = rng.integers(0, size, size=needed + needed // 8 + 16, dtype=np.int64)
        combined = np.concatenate([chosen, draw])
        _, first = np.unique(combined, return_index=True)
        chosen = combined[np.sort(first)]
    return chosen[:count]


def random_sparse_fourier(shape, count, rng, *, real=False, values="normal", decay=None, channels=()):
    """A random K-sparse :class:`SparseFourier`: the one generator of tests, benchmarks and experiments.

    Parameters
    ----------
    shape : tuple of int
    count : int
        Coefficients drawn. With ``real`` they are closed under the Hermitian
        partner map (``count // 2`` drawn, each with its conjugate partner), so
        the signal is real and has about ``count`` coefficients.
    rng : numpy.random.Generator
    values : {'normal', 'uniform', 'unit'}
        Complex standard normal values, real values uniform in ``[0, 1)``
        (thesis 4.3's random signal), or unit-modulus values of uniform phase
        (the SFT's test signals).
    decay : float, optional
        Multiply the values by ``rank ** -decay`` in a random order: a
        compressible spectrum with power-law magnitudes.
    channels : tuple of int, optional
        Trailing value axes (e.g. ``(3,)`` for RGB).
    """
    shape = check_shape(shape)
    size = int(np.prod(shape, dtype=np.int64))
    drawn = min(int(count) // 2 if real else int(count), size)
    support = sample_support(size, drawn, rng)
    value_shape = (support.size,) + tuple(channels)
    if values == "uniform":
        coefficients = rng.random(value_shape).astype(np.complex128)
    elif values == "normal":
        coefficients = rng.standard_normal(value_shape) + 1j * rng.standard_normal(value_shape)
    elif values == "unit":
        coefficients = np.exp(2j * np.pi * rng.random(value_shape))
    else:
        raise ValueError(f"values must be 'normal', 'uniform' or 'unit', got {values!r}")
    if decay is not None:
        scale = (np.arange(1, support.size + 1) ** -float(decay))[rng.permutation(support.size)]
        coefficients = coefficients * scale.reshape((-1,) + (1,) * len(channels))
    representation = SparseFourier(shape, support, coefficients)
    return representation.hermitian_closure() if real else representation
