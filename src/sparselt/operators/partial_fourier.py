"""Point samples of a signal that is sparse in the n-D DFT (thesis 2.2, 3.1).

``PartialFourier`` is ``A = S F^{-1}``: synthesise a grid signal from Fourier
coefficients, then read it at a set of grid cells (the point basis that
rendering measures in). It is matrix-free through the FFT backend, in float32
or float64, with a persistent set of buffers so that CoSaMP's inner loops
allocate nothing of signal size.

Coefficients are orthonormal coordinates ``u``: the map from ``u`` to the
full grid signal is an isometry, so proxies ``A^* r`` of different
frequencies compare fairly.

Complex signals (``real=False``)
    ``u`` is the full spectrum with the unitary normalisation:
    ``x = ifftn(u, norm='ortho')``.
Real signals (``real=True``)
    ``u`` lives on the half spectrum of ``numpy.fft.rfftn`` (last axis
    ``n // 2 + 1``). Each *canonical* entry stands for a conjugate pair
    ``(c(k), c(-k) = conj(c(k)))`` of the full spectrum and counts as two
    coefficients; entries whose partner is themselves (self-conjugate) count
    as one and are real; in the planes ``j = 0`` and ``j = n/2`` of the last
    axis, where both members of a pair lie in the half spectrum, only the
    canonical member (the smaller flat index) is a coordinate and the other is
    held at zero. The operator is real-linear, and :meth:`adjoint` is the
    adjoint in the real inner product ``Re <a, b>``.

A cell sampled several times is given once, with the mean of its samples
(that is how rendering measures it); unsampled cells are unknown.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..fourier import fft
from ..fourier.hermitian import partner_indices
from ..fourier.sparse import SparseFourier, check_shape
from .. import kernels
from ..cell_statistics import cell_means
from .base import LinearOperator

DTYPES = {np.dtype(np.float32): np.dtype(np.complex64), np.dtype(np.float64): np.dtype(np.complex128)}


def mean_per_cell(cells, values):
    """Collapse repeated measurements: each distinct cell once, with the mean of its samples.

    :func:`sparselt.cell_statistics.cell_means` over the distinct cells,
    checked at this public boundary and returned in the values' dtype.

    Parameters
    ----------
    cells : array_like of int, shape (M,)
        Flat cell index of each sample (repeats allowed).
    values : array_like, shape (M,)
        Sample values.

    Returns
    -------
    unique_cells : ndarray of int64, sorted
    means : ndarray
        Mean of the values of each cell (the operator's ``y``).
    counts : ndarray of int64
        Samples per cell.

    Raises
    ------
    TypeError
        ``cells`` are not integers.
    ValueError
        ``cells`` and ``values`` differ in length, or a cell is negative.
    """
    cells = np.asarray(cells)
    if cells.size and cells.dtype.kind not in "iu":
        raise TypeError(f"cells must be integer cell indices, got dtype {cells.dtype}")
    cells = cells.astype(np.int64)
    values = np.asarray(values)
    if cells.shape != values.shape[:1] or cells.ndim != 1:
        raise ValueError(f"cells and values must have one entry per sample, got shapes {cells.shape} and {values.shape}")
    if cells.size and cells.min() < 0:
        raise ValueError(f"cells must be flat cell indices >= 0, got {int(cells.min())}")
    unique_cells, means, counts = cell_means(cells, values)
    return unique_cells, means.astype(values.dtype if np.issubdtype(values.dtype, np.inexact) else np.float64), counts


@functools.lru_cache(maxsize=8)
def _plane_fixes(grid_shape):
    """Flat half-spectrum indices of the non-canonical and the self-conjugate entries, and the planes of the last axis.

    A function of the grid shape alone, kept for the last few shapes (both
    folds of a cross-fitted reconstruction, and every repeat, share one);
    the arrays are read-only.
    """
    last = grid_shape[-1]
    half = last // 2 + 1
    planes = [0] + ([last // 2] if last % 2 == 0 and last > 1 else [])
    other = grid_shape[:-1]
    count = math.prod(other)
    flat_other = np.arange(count, dtype=np.int64)
    partner_other = partner_indices(other, flat_other) if other else flat_other
    noncanonical, selfconjugate = [], []
    for plane in planes:
        flat = flat_other * half + plane
        noncanonical.append(flat[partner_other < flat_other])
        selfconjugate.append(flat[partner_other == flat_other])
    plane_of_last = np.zeros(half, dtype=bool)
    plane_of_last[planes] = True
    arrays = (np.concatenate(noncanonical), np.concatenate(selfconjugate), plane_of_last)
    for array in arrays:
        array.flags.writeable = False
    return arrays


class PartialFourier(LinearOperator):
    """Samples at grid cells ``indices`` of the signal with Fourier coordinates ``u``.

    Parameters
    ----------
    shape : sequence of int
        Grid shape of the signal.
    indices : array_like of int
        Distinct flat C-order indices of the sampled cells.
    real : bool, optional
        Real signal, half-spectrum coordinates (default True).
    dtype : {numpy.float32, numpy.float64}, optional
        Precision of the samples (coefficients are the matching complex type).
    threads : int, optional
        FFT threads (default: every core).

    Raises
    ------
    ValueError
        Empty, out-of-range or repeated indices; bad shape or dtype.
    """

    def __init__(self, shape, indices, *, real=True, dtype=np.float32, threads=None):
        self.grid_shape = check_shape(shape)
        dtype = np.dtype(dtype)
        if dtype not in DTYPES:
            raise ValueError(f"dtype must be float32 or float64, got {dtype}")
        self.real = bool(real)
        self.sample_dtype = dtype if self.real else DTYPES[dtype]
        self.coefficient_dtype = DTYPES[dtype]
        self.size = math.prod(self.grid_shape)
        indices = np.asarray(indices)
        if indices.ndim != 1 or indices.size == 0:
            raise ValueError("indices must be a non-empty 1-D array of sampled cells")
        if not np.issubdtype(indices.dtype, np.integer):
            raise ValueError(f"indices must be integers, got dtype {indices.dtype}")
        indices = indices.astype(np.int64)
        if indices.min() < 0 or indices.max() >= self.size:
            bad = indices[(indices < 0) | (indices >= self.size)][0]
            raise ValueError(f"sample index {bad} is out of range for shape {self.grid_shape} (0 <= index < {self.size})")
        ordered = indices if np.all(indices[1:] > indices[:-1]) else np.sort(indices)
        if np.any(ordered[1:] == ordered[:-1]):
            repeated = int(ordered[1:][ordered[1:] == ordered[:-1]][0])
            raise ValueError(f"sample indices must be distinct (cell {repeated} is repeated): give each cell once, "
                             "with the mean of its samples")
        self.indices = indices
        self.threads = threads
        if self.real:
            last = self.grid_shape[-1]
            self.coefficient_shape = self.grid_shape[:-1] + (last // 2 + 1,)
        else:
            self.coefficient_shape = self.grid_shape
        self.input_size = math.prod(self.coefficient_shape)
        self.output_size = int(indices.size)
        self.dims = self.coefficient_shape
        self.dimsd = (self.output_size,)
        self.dtype = self.coefficient_dtype
        self.data_dtype = self.sample_dtype
        self.clinear = not self.real  # half-spectrum coordinates of a real signal: real-linear only
        self._axes = tuple(range(len(self.grid_shape)))
        self.transforms = 0  # full FFTs performed, for cost accounting
        self._weights_support = None
        self._weights_cache = (None, None)
        self._grid = np.zeros(self.grid_shape, dtype=self.sample_dtype)  # zero except at sampled cells
        self._spectrum = np.zeros(self.coefficient_shape, dtype=self.coefficient_dtype)  # zero except on a support
        self._grid_out = np.empty(self.grid_shape, dtype=self.sample_dtype)  # synthesis output
        self._spectrum_out = np.empty(self.coefficient_shape, dtype=self.coefficient_dtype)  # analysis output
        self._energy = None  # proxy energy, allocated on first use
        if self.real:
            self._noncanonical, self._selfconjugate, self._plane_of_last = _plane_fixes(self.grid_shape)

    # -- real half-spectrum bookkeeping ------------------------------------

    def _weights(self, support):
        """(analysis scale a, synthesis scale b) of coefficient entries ``support``.

        Cached for the last support array seen: CoSaMP's conjugate-gradient
        steps reuse one support many times.
        """
        if not self.real:
            return None, None
        if support is self._weights_support:
            return self._weights_cache
        size = self.size
        in_plane, selfconjugate = self._classify(support)
        analysis = np.where(selfconjugate, 1.0 / math.sqrt(size), math.sqrt(2.0 / size)).astype(self.sample_dtype)
        # c2r counts an interior entry twice (its mirror is implicit) and a plane entry once.
        synthesis = np.where(selfconjugate, math.sqrt(size), np.where(in_plane, math.sqrt(2.0 * size), math.sqrt(size / 2.0)))
        self._weights_support = support
        self._weights_cache = (analysis, synthesis.astype(self.sample_dtype))
        return self._weights_cache

    def coefficient_counts(self, support):
        """How many full-spectrum coefficients each entry of ``support`` stands for (1 or 2)."""
        if not self.real:
            return np.ones(np.size(support), dtype=np.int64)
        _, selfconjugate = self._classify(np.asarray(support))
        return np.where(selfconjugate, 1, 2)

    def _classify(self, support):
        """Masks of the entries of ``support`` in the planes j = 0, n/2 and of the self-conjugate ones."""
        in_plane = self._plane_of_last[support % self.coefficient_shape[-1]]
        selfconjugate = np.zeros(support.size, dtype=bool)
        if in_plane.any():
            selfconjugate[in_plane] = np.isin(support[in_plane], self._selfconjugate)
        return in_plane, selfconjugate

    # -- the operator on a support --------------------------------------------

    def forward_on(self, support, values):
        """``A`` applied to coefficients that are zero off ``support`` (flat coefficient indices)."""
        spectrum = self._spectrum.reshape(-1)
        _, synthesis = self._weights(support)
        spectrum[support] = values if synthesis is None else values * synthesis
        self.transforms += 1
        if self.real:
            # The transform may destroy its input; zeroing the whole buffer is cheaper than the copy it saves.
            grid = fft.irfftn(self._spectrum, self.grid_shape[-1], axes=self._axes, out=self._grid_out,
                              threads=self.threads, overwrite_input=True)
            kernels.zero(self._spectrum)
        else:
            grid = fft.ifftn(self._spectrum, axes=self._axes, norm="ortho", out=self._grid_out, threads=self.threads)
            spectrum[support] = 0
        return kernels.gather(grid.reshape(-1), self.indices, np.empty(self.output_size, dtype=self.sample_dtype))

    def transform_samples(self, samples):
        """The unscaled spectrum of the sampled cells holding ``samples``.

        Returns a buffer that the next call overwrites: copy it to keep it.
        """
        samples = np.asarray(samples)
        if samples.shape != (self.output_size,):
            raise ValueError(f"expected {self.output_size} samples, got shape {samples.shape}")
        kernels.scatter(self._grid.reshape(-1), self.indices, samples.astype(self.sample_dtype, copy=False))
        self.transforms += 1
        if self.real:
            return fft.rfftn(self._grid, axes=self._axes, out=self._spectrum_out, threads=self.threads)
        return fft.fftn(self._grid, axes=self._axes, norm="ortho", out=self._spectrum_out, threads=self.threads)

    def adjoint_on(self, support, samples, spectrum=None):
        """``A^*`` restricted to ``support``; pass ``spectrum`` from :meth:`transform_samples` to reuse it."""
        if spectrum is None:
            spectrum = self.transform_samples(samples)
        values = spectrum.reshape(-1)[support]
        analysis, _ = self._weights(support)
        return values if analysis is None else values * analysis

    def proxy_energy(self, spectrum):
        """``|A^* r|^2`` on every coefficient entry, up to one common factor, from :meth:`transform_samples`.

        Returns a buffer that the next call overwrites: copy it to keep it.
        """
        spectrum = np.asarray(spectrum)
        if spectrum.dtype == self.coefficient_dtype and spectrum.size == self.input_size:
            if self._energy is None:
                self._energy = np.empty(self.input_size, dtype=np.finfo(self.coefficient_dtype).dtype)
            energy = kernels.squared_magnitude(np.ascontiguousarray(spectrum), self._energy)
        else:
            energy = np.square(spectrum.real)
            energy += np.square(spectrum.imag)
        if self.real:
            flat = energy.reshape(-1)
            flat[self._noncanonical] = 0.0
            flat[self._selfconjugate] *= 0.5
        return energy.reshape(-1)

    # -- LinearOperator interface -----------------------------------------------

    def _matvec(self, vector):
        """``A u`` for a full coefficient vector (length ``input_size``)."""
        support = np.flatnonzero(vector)
        if self.real:
            support = np.setdiff1d(support, self._noncanonical)
        return self.forward_on(support, vector[support])

    def _rmatvec(self, samples):
        """``A^* y`` as a full coefficient vector (zero on non-canonical entries)."""
        spectrum = self.transform_samples(samples).reshape(-1)
        if not self.real:
            return spectrum.copy()
        every = np.arange(self.input_size, dtype=np.int64)
        result = self.adjoint_on(every, None, spectrum)
        result[self._noncanonical] = 0
        return result

    def release_buffers(self):
        """Hand over the operator's signal-size work arrays; the operator cannot be used afterwards.

        Returns ``(spectrum, grid)``: an all-zero half spectrum (complex) and a
        grid of the sample precision, already in memory, for
        :meth:`SparseFourier.to_signal`'s ``work`` and ``out`` (the synthesis
        of the estimate, the last step of a reconstruction).
        """
        if self._spectrum is None:
            raise RuntimeError("this PartialFourier's buffers were released; build a new operator")
        if not self.real:
            raise ValueError("release_buffers serves the real synthesis; a complex operator has no half spectrum")
        spectrum, grid = self._spectrum, self._grid_out
        self._spectrum = self._grid_out = self._grid = self._spectrum_out = self._energy = None
        return spectrum, grid

    # -- results -------------------------------------------------------------------

    def to_sparse_fourier(self, support, values):
        """The estimate in the SparseFourier convention (full spectrum, ``numpy.fft.fftn``).

        Orthonormal coordinates ``u = a c`` (see :meth:`_weights`) give
        ``c = u / a``; each canonical half-spectrum entry becomes the pair
        ``c(k), c(-k) = conj(c(k))``, a self-conjugate entry one real ``c(k)``.
        """
        support = np.asarray(support, dtype=np.int64)
        values = np.asarray(values, dtype=np.complex128)
        if not self.real:
            return SparseFourier(self.grid_shape, support, values * math.sqrt(self.size))
        analysis, _ = self._weights(support)
        coefficients = values / analysis
        coordinates = np.unravel_index(support, self.coefficient_shape)
        full = np.ravel_multi_index(coordinates, self.grid_shape)
        mirrored = partner_indices(self.grid_shape, full)
        pairs = mirrored != full
        coefficients = np.where(pairs, coefficients, coefficients.real)
        indices = np.concatenate([full, mirrored[pairs]])
        return SparseFourier(self.grid_shape, indices, np.concatenate([coefficients, np.conj(coefficients[pairs])]),
                             real=True, tolerance=1e-3)
