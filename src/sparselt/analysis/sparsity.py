"""Sparsity of a signal: the per-channel Gini index (eq. 5.1) in its canonical or Fourier basis (thesis 5.1, 5.4.1).

One idea: :func:`signal_gini` -- the per-channel Gini index of a
:class:`~sparselt.signal.Signal`, in its canonical (primary-sample-space) basis
or its Fourier basis, exact when the data fit a memory limit and streamed
(with an out-of-core FFT for the Fourier basis) otherwise; the result is a
:class:`SignalGini`.

The Gini index of a vector lives in :mod:`sparselt.analysis.gini`
(:func:`gini_index`, :func:`gini_index_streaming`, :class:`GiniHistogram`,
:class:`GiniEstimate`, re-exported here), the out-of-core reading and FFT in
:mod:`sparselt.analysis.out_of_core`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from ..fourier import fft
from .gini import (
    _DEFAULT_PIECE,
    _EXACT_BLOCK,
    _PIECE_BYTES_PER_VALUE,
    DEFAULT_BUCKETS,
    GiniEstimate,
    GiniHistogram,
    _check_flag,
    _check_sorted,
    _gini_from_sorted,
    _validate_buckets,
    gini_index,
    gini_index_streaming,
)
from .out_of_core import (
    _SignalReader,
    _half_spectrum_axes,
    _plan_split,
    _read_channel,
    _scratch_directory,
    _stream_canonical,
    _stream_fourier,
)

__all__ = [
    "DOMAINS",
    "GiniEstimate",
    "GiniHistogram",
    "SignalGini",
    "gini_index",
    "gini_index_streaming",
    "signal_gini",
]

DOMAINS = ("canonical", "fourier")
DEFAULT_MEMORY_LIMIT_BYTES = 4 * 2**30


@dataclass(frozen=True)
class SignalGini:
    """Per-colour-channel Gini indices of a signal.

    Attributes
    ----------
    values : ndarray, shape (3,), float64
        Gini index of each channel (R, G, B).
    error_bounds : ndarray, shape (3,), float64
        ``|exact - value|`` bound per channel: zero on the exact path, the
        streaming bound (see :func:`gini_index_streaming`) otherwise.
    exact : bool
        Whether the exact (in-memory sort) path was taken.
    domain : str
        'canonical' or 'fourier'.
    energy : bool
        Whether the index is of the energies.
    """

    values: np.ndarray
    error_bounds: np.ndarray
    exact: bool
    domain: str
    energy: bool


def _exact_bytes(shape, itemsize, domain):
    """Estimated peak bytes of :func:`_exact_channel_gini` on one channel of grid ``shape``.

    'canonical': the channel's copy; 'fourier': the channel, its half spectrum
    and the full-spectrum magnitudes rebuilt from it, at their largest
    overlap. Both add the float64 temporaries of one accumulation block of
    the exact sum.
    """
    size = math.prod(shape)
    accumulation = 24 * min(size, _EXACT_BLOCK)
    if domain == "canonical":
        return itemsize * size + accumulation
    halved = max(range(len(shape)), key=lambda axis: shape[axis])
    kept = size // shape[halved] * (shape[halved] // 2 + 1)
    peak = max(size + 2 * kept, 3 * kept, kept + size)
    return itemsize * peak + accumulation


def _exact_channel_gini(reader, channel, shape, dtype, domain, energy):
    """Exact Gini index of one channel: copy it, take magnitudes (of its full spectrum for 'fourier'), sort, eq. 5.1.

    The full spectrum's magnitudes are rebuilt from a real FFT halved along
    the largest axis by Hermitian symmetry, ``|X[-k]| = |X[k]|``: each plane
    that stands for a conjugate pair appears twice.
    """
    values = _read_channel(reader, channel, shape, dtype, _DEFAULT_PIECE)
    if domain == "canonical":
        np.abs(values, out=values)
        flat = values.reshape(-1)
    else:
        axes, halved = _half_spectrum_axes(shape, range(len(shape)))
        spectrum = fft.rfftn(values, axes=axes)
        del values
        magnitudes = np.abs(spectrum)
        del spectrum
        size = shape[halved]

        def plane(selection):
            index = [slice(None)] * len(shape)
            index[halved] = selection
            return magnitudes[tuple(index)].reshape(-1)

        mirrored = plane(slice(1, (size + 1) // 2))
        self_conjugate = [plane(slice(0, 1))]
        if size % 2 == 0 and size > 1:
            self_conjugate.append(plane(slice(size // 2, size // 2 + 1)))
        flat = np.concatenate(self_conjugate + [mirrored, mirrored])  # the full spectrum's magnitudes
        del magnitudes, mirrored, self_conjugate
    flat.sort()
    _check_sorted(flat, "signal values" if domain == "canonical" else "Fourier magnitudes")
    return _gini_from_sorted(flat, energy=energy)


def signal_gini(signal, *, domain, energy=False, memory_limit_bytes=DEFAULT_MEMORY_LIMIT_BYTES,
                buckets=DEFAULT_BUCKETS, temporary_directory=None, progress=False):
    """Gini index (eq. 5.1) of each colour channel of a signal, in the canonical or the Fourier basis.

    Parameters
    ----------
    signal : sparselt.signal.Signal
        Data of shape ``grid_shape + (3,)``, float32 or float64, possibly a
        read-only memory map larger than RAM.
    domain : {'canonical', 'fourier'}
        'canonical': the magnitudes ``|x|`` of the primary-sample-space values
        themselves (the thesis's "Time" / primary-sample-space columns).
        'fourier': the magnitudes of the n-D DFT over all grid axes, per
        channel (the full spectrum; computed in the data's precision, float32
        -> complex64, with :mod:`sparselt.fourier.fft`).
    energy : bool, optional
        The index of the energies ``|x|**2`` instead of the magnitudes.
    memory_limit_bytes : int, optional
        Memory the computation may allocate (default 4 GiB; the interpreter and
        the caller's arrays are not counted). The exact path is taken when its
        estimated peak fits, the streaming path otherwise.
    buckets : int, optional
        Histogram size of the streaming path (see :func:`gini_index_streaming`).
    temporary_directory : str or path, optional
        Folder for the scratch spectrum of the out-of-core FFT; by default the
        signal's own folder (for a memory map) or :func:`tempfile.gettempdir`,
        whichever is writable with enough free space.
    progress : bool, optional
        Show tqdm progress bars on the streaming path.

    Returns
    -------
    SignalGini
        ``values`` and ``error_bounds`` per channel (bounds zero when exact).

    Raises
    ------
    TypeError
        ``signal`` is not a Signal, or its data are not real numbers.
    ValueError
        An unknown ``domain``; a non-positive ``memory_limit_bytes``, or one
        too small for the streaming histogram and one slab of the grid; an
        empty grid; negative, NaN or inf values (the latter two in either
        domain); a bad ``buckets``.
    OSError
        No folder has room for the out-of-core spectrum.

    Notes
    -----
    *Exact path* (estimated peak: one channel's copy for 'canonical'; about
    two for 'fourier'): per channel, copy the channel, take magnitudes (a real
    FFT over all grid axes whose halved axis is the largest one, then the
    magnitudes of the full spectrum rebuilt by Hermitian symmetry, ``|X[-k]| =
    |X[k]|``), sort and apply eq. 5.1 as :func:`gini_index` does.

    *Streaming path*: one :class:`GiniHistogram` per channel
    (:func:`gini_index_streaming` has the estimator and the error bound).
    'canonical' reads the data in pieces (all three channels in one pass when
    three histograms fit). 'fourier' is an out-of-core FFT per channel: the
    grid axes are split into leading axes ``shape[:s]`` and trailing axes
    ``shape[s:]``; stage 1 reads slabs of leading indices, applies a real FFT
    over the trailing axes (halved along the largest of them) and appends it
    to a scratch file (complex64 for float32 data, deleted afterwards;
    ``N * (n_h//2 + 1)/n_h`` values, about half the spectrum); stage 2 maps
    the scratch file, applies the FFT over the leading axes to blocks of
    trailing frequencies and feeds their magnitudes to the histogram with
    multiplicity 2 for the frequencies that stand for a conjugate pair, so the
    result is the index of the full spectrum. ``s`` is chosen for the
    smallest scratch file among the splits that fit the memory limit (for
    the thesis's 100 x 100 x 4**8 path signal, ``s = 1``, halving along ``y``:
    a 2.7 GB scratch file per channel). Pages of memory-mapped input and
    scratch are released after each piece, so resident memory stays bounded.

    References
    ----------
    .. [1] Thesis, section 5.1 "Sparsity Metrics" (eq. 5.1) and section 5.4.1
       (tables 5.1 and 5.2: per-channel Gini of magnitude and energy in the
       Fourier and primary-sample-space bases).
    .. [2] N. Hurley and S. Rickard, "Comparing measures of sparsity", IEEE
       Transactions on Information Theory 55(10), 4723-4741, 2009.
    """
    data = getattr(signal, "data", None)
    # An ndarray, a memory map or a lazily chunked store array (``load_signal``'s Zarr data): sliced piece by piece.
    if not all(hasattr(data, name) for name in ("shape", "dtype", "ndim", "__getitem__")) or data.ndim < 2 \
            or data.shape[-1] != 3:
        raise TypeError(f"signal must be a sparselt Signal with data of shape grid_shape + (3,), got {signal!r:.80}")
    if domain not in DOMAINS:
        raise ValueError(f"domain must be one of {DOMAINS}, got {domain!r}")
    energy = _check_flag(energy, "energy")
    progress = _check_flag(progress, "progress")
    if isinstance(memory_limit_bytes, (bool, np.bool_)) or not isinstance(memory_limit_bytes, (int, np.integer)) \
            or memory_limit_bytes <= 0:
        raise ValueError(f"memory_limit_bytes must be a positive integer, got {memory_limit_bytes!r}")
    memory_limit_bytes = int(memory_limit_bytes)
    buckets = _validate_buckets(buckets)
    if temporary_directory is not None and not os.path.isdir(os.fspath(temporary_directory)):
        raise ValueError(f"temporary_directory {temporary_directory!r} is not an existing folder")
    if np.iscomplexobj(data):
        raise ValueError(f"signal data must be real, got dtype {data.dtype}; the signal holds radiance values")
    if data.dtype.kind not in "biuf":
        raise TypeError(f"signal data must be real numbers, got dtype {data.dtype}")
    dtype = np.dtype(np.float32) if data.dtype == np.float32 else np.dtype(np.float64)
    shape = tuple(int(size) for size in data.shape[:-1])
    if math.prod(shape) == 0:
        raise ValueError(f"signal grid {shape} has no cells")

    reader = _SignalReader(data)
    try:
        if _exact_bytes(shape, dtype.itemsize, domain) <= memory_limit_bytes:
            values = [_exact_channel_gini(reader, channel, shape, dtype, domain, energy) for channel in range(3)]
            return _signal_result(values, [0.0] * 3, exact=True, domain=domain, energy=energy)

        histogram_bytes = GiniHistogram.memory_bytes(buckets)
        if domain == "canonical" and 4 * histogram_bytes <= memory_limit_bytes:
            groups = [(0, 1, 2)]  # one pass over the data for all three channels
        else:
            groups = [(0,), (1,), (2,)]
        spare = memory_limit_bytes - len(groups[0]) * histogram_bytes
        piece = min(_DEFAULT_PIECE, spare // (4 * _PIECE_BYTES_PER_VALUE))
        budget = spare - piece * _PIECE_BYTES_PER_VALUE
        plan = None
        if domain == "fourier" and piece >= 1:
            plan = _plan_split(shape, dtype.itemsize, budget)
        if piece < 1 or budget < 4 * dtype.itemsize or (domain == "fourier" and plan is None):
            one_dimensional = "; a one-dimensional spectrum is never streamed" if len(shape) == 1 else ""
            raise ValueError(
                f"memory_limit_bytes={memory_limit_bytes} is too small for the streaming Gini index of a "
                f"{domain} signal of grid {shape} with buckets={buckets} (the histogram alone takes "
                f"{histogram_bytes} bytes{one_dimensional}); raise the limit or use fewer buckets"
            )
        if plan is not None:
            split, _, _, kept = plan
            scratch_bytes = math.prod(shape[:split]) * kept * 2 * dtype.itemsize
            scratch = _scratch_directory(data, temporary_directory, scratch_bytes)
        estimates = {}
        for group in groups:
            histograms = {channel: GiniHistogram(buckets=buckets, piece_size=int(piece)) for channel in group}
            if domain == "canonical":
                _stream_canonical(reader, shape, dtype, histograms, group, budget, int(piece), progress)
            else:
                _stream_fourier(reader, shape, dtype, histograms[group[0]], group[0], budget, scratch, progress)
            for channel in group:
                estimates[channel] = histograms[channel].estimate(energy=energy)
            del histograms
        return _signal_result([estimates[channel].value for channel in range(3)],
                              [estimates[channel].error_bound for channel in range(3)],
                              exact=False, domain=domain, energy=energy)
    finally:
        reader.close()


def _signal_result(values, bounds, *, exact, domain, energy):
    values = np.asarray(values, dtype=np.float64)
    bounds = np.asarray(bounds, dtype=np.float64)
    values.setflags(write=False)
    bounds.setflags(write=False)
    return SignalGini(values=values, error_bounds=bounds, exact=exact, domain=domain, energy=energy)
