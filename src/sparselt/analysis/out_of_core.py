"""Out-of-core machinery for signals larger than memory (thesis 5.4.1).

One idea: read a signal's data, possibly a memory map or a lazily chunked
store array larger than RAM, in bounded pieces, and compute its Fourier
transform out of core, so that :func:`sparselt.analysis.sparsity.signal_gini`
can give the per-channel Gini index (thesis 5.1, eq. 5.1) of signals like the
thesis's 100 x 100 x 4**8 path signal (section 5.4.1, tables 5.1 and 5.2).

* :func:`_piece_indices` -- C-ordered pieces of an array of bounded size.
* :class:`_SignalReader` -- read-only access that drops memory-mapped pages
  after each piece; :func:`_read_channel` copies one colour channel with it.
* :func:`_stream_canonical` -- feeds the magnitudes of the data, piece by
  piece, to streaming histograms.
* :func:`_plan_split`, :func:`_scratch_directory`, :func:`_stream_fourier` --
  the two-stage out-of-core FFT through a scratch file on disk, feeding the
  magnitudes of the full spectrum (conjugate pairs counted twice) to a
  streaming histogram.

These helpers are internal to :mod:`sparselt.analysis`; a histogram here is
anything with ``add(values, *, weights=None)``
(:class:`~sparselt.analysis.gini.GiniHistogram`).
"""

from __future__ import annotations

import math
import mmap
import os
import shutil
import tempfile

import numpy as np

from ..fourier import fft
from ..fourier.hermitian import real_fft_multiplicity
from ..measurement import progress_bar

_SCRATCH_MARGIN_BYTES = 64 * 2**20
_LARGEST_FFT_BLOCK = 2**24  # values per out-of-core FFT slab or block: larger ones only cost memory


def _piece_indices(shape, max_size):
    """Index tuples cutting an array of ``shape`` into C-ordered pieces of at most ``max_size`` elements.

    Each piece is a contiguous range of the C-order flattening; a piece is never
    smaller than one innermost row unless a row alone exceeds ``max_size``.
    """
    shape = tuple(int(size) for size in shape)
    if not shape:
        yield ()
        return
    inner = math.prod(shape[1:])
    if inner <= max_size or len(shape) == 1:
        step = max(1, max_size // max(inner, 1))
        if len(shape) == 1:
            step = max(1, max_size)
        for start in range(0, shape[0], step):
            yield (slice(start, min(start + step, shape[0])),)
        return
    for index in range(shape[0]):
        for rest in _piece_indices(shape[1:], max_size):
            yield (index,) + rest


class _SignalReader:
    """Read-only access to signal data whose memory-mapped pages can be dropped after each piece.

    A top-level ``np.memmap`` (what :func:`~sparselt.signal.load_signal`
    returns) is mapped again here so that :meth:`release` can tell the kernel
    (``MADV_DONTNEED``) that the pages read so far are no longer needed: they
    then stop counting towards the process's resident memory. Other arrays are
    used as they are.
    """

    def __init__(self, data):
        self._file = self._mapping = None
        self.array = data
        if isinstance(data, np.memmap) and isinstance(data.base, mmap.mmap) and data.filename \
                and data.flags.c_contiguous and data.nbytes > 0:
            start = int(data.offset) - int(data.offset) % mmap.ALLOCATIONGRANULARITY
            try:
                self._file = open(data.filename, "rb")
                self._mapping = mmap.mmap(self._file.fileno(), int(data.offset) - start + data.nbytes,
                                          access=mmap.ACCESS_READ, offset=start)
            except (OSError, ValueError):
                self.close()
                return
            self.array = np.frombuffer(self._mapping, dtype=data.dtype, count=data.size,
                                       offset=int(data.offset) - start).reshape(data.shape)

    def release(self):
        """Tell the kernel the pages of a re-mapped memory map read so far are no longer needed."""
        if self._mapping is not None and hasattr(mmap, "MADV_DONTNEED"):
            try:
                self._mapping.madvise(mmap.MADV_DONTNEED)
            except OSError:
                pass

    def close(self):
        """Unmap and close what :meth:`__init__` opened; the reader is unusable afterwards."""
        self.array = None
        if self._mapping is not None:
            try:
                self._mapping.close()
            except BufferError:  # a view is still alive (an exception is unwinding): leave it to the collector
                pass
            self._mapping = None
        if self._file is not None:
            self._file.close()
            self._file = None


def _progress(iterable, *, total, description, enabled):
    """``iterable`` behind the package's one progress bar when ``enabled``, else as it is."""
    bar = progress_bar(enabled, total=total, description=description, unit="piece", iterable=iterable)
    return iterable if bar is None else bar


def _half_spectrum_axes(shape, axes):
    """Axes order for a real FFT over ``axes`` whose halved (last) axis is the largest one."""
    axes = list(axes)
    halved = max(axes, key=lambda axis: shape[axis])
    axes.remove(halved)
    return tuple(axes) + (halved,), halved


def _read_channel(reader, channel, shape, dtype, piece_values):
    """A new ``dtype`` array of grid ``shape`` holding colour ``channel``, read in pieces of ``piece_values`` cells."""
    out = np.empty(shape, dtype=dtype)
    for index in _piece_indices(shape, piece_values):
        out[index] = reader.array[index][..., channel]
        reader.release()
    return out


def _scratch_directory(data, temporary_directory, needed):
    """First folder with ``needed`` bytes (plus a margin) free for the out-of-core FFT's scratch file.

    Only ``temporary_directory`` when given; otherwise the folder of a
    memory-mapped ``data``, then :func:`tempfile.gettempdir`. Raises
    :class:`OSError` when none is writable with that much room.
    """
    if temporary_directory is not None:
        candidates = [os.fspath(temporary_directory)]
    else:
        candidates = []
        filename = getattr(data, "filename", None)
        if filename:
            candidates.append(os.path.dirname(os.path.abspath(filename)))
        candidates.append(tempfile.gettempdir())
    for directory in candidates:
        if os.path.isdir(directory) and os.access(directory, os.W_OK) \
                and shutil.disk_usage(directory).free >= needed + _SCRATCH_MARGIN_BYTES:
            return directory
    raise OSError(
        f"the out-of-core Fourier transform needs {needed} bytes of scratch space, but none of {candidates} "
        "is a writable folder with that much free space; pass temporary_directory="
    )


def _plan_split(shape, itemsize, budget):
    """Choose the axes of the two out-of-core FFT stages.

    Stage 1 transforms the trailing axes ``shape[split:]`` (a real FFT, halved
    along their largest axis) for each index of the leading axes; stage 2
    transforms the leading axes for each block of trailing frequencies. Among
    the splits whose smallest slab and block fit ``budget``, take the smallest
    scratch file, then the fewest leading cells (longest contiguous reads).
    """
    best = None
    for split in range(1, len(shape)):
        leading, trailing = math.prod(shape[:split]), math.prod(shape[split:])
        axes, halved = _half_spectrum_axes(shape, range(split, len(shape)))
        kept = trailing // shape[halved] * (shape[halved] // 2 + 1)
        if trailing * 8 * itemsize > budget or leading * 4 * itemsize > budget:
            continue
        key = (leading * kept, leading)
        if best is None or key < best[0]:
            best = (key, split, axes, halved, kept)
    return None if best is None else best[1:]


def _stream_canonical(reader, shape, dtype, histograms, channels, budget, piece, progress):
    """Feed ``|x|`` of each of ``channels`` to ``histograms[channel]``, reading the data once in pieces.

    A piece holds at most ``piece`` cells and fits ``budget`` bytes.
    """
    cells = max(1, budget // (4 * np.dtype(dtype).itemsize))
    cells = min(cells, piece)
    indices = list(_piece_indices(shape, cells))
    for index in _progress(indices, total=len(indices), description=f"Gini, canonical, channels {channels}",
                           enabled=progress):
        block = reader.array[index]
        for channel in channels:
            magnitudes = np.abs(np.asarray(block[..., channel], dtype=dtype))
            histograms[channel].add(magnitudes)
        del block
        reader.release()


def _stream_fourier(reader, shape, dtype, histogram, channel, budget, scratch, progress):
    """Feed the full n-D spectrum's magnitudes of one ``channel`` to ``histogram``: the out-of-core FFT.

    With the axes of :func:`_plan_split`, stage 1 writes a real FFT over the
    trailing axes of each slab of leading indices to an unlinked scratch file
    in the folder ``scratch``; stage 2 maps it, transforms blocks of trailing
    frequencies over the leading axes and adds their magnitudes with
    multiplicity 2 for the frequencies that stand for a conjugate pair
    (:func:`~sparselt.fourier.hermitian.real_fft_multiplicity`), 1 otherwise.
    Peak memory stays within ``budget`` bytes.
    """
    itemsize = np.dtype(dtype).itemsize
    complex_dtype = np.complex64 if dtype == np.float32 else np.complex128
    split, axes, halved, kept = _plan_split(shape, itemsize, budget)
    leading_shape, trailing_shape = shape[:split], shape[split:]
    leading, trailing = math.prod(leading_shape), math.prod(trailing_shape)
    spectrum_axes = tuple(axis - split + 1 for axis in axes)
    kept_shape = list(trailing_shape)
    kept_shape[halved - split] = shape[halved] // 2 + 1
    descriptor, path = tempfile.mkstemp(prefix="sparselt-spectrum-", suffix=".tmp", dir=scratch)
    try:
        try:
            os.unlink(path)  # POSIX: the file lives until closed, even if we are killed
            path = None
        except OSError:
            pass
        with os.fdopen(descriptor, "w+b") as handle:
            descriptor = None
            rows = max(1, min(budget // (trailing * 8 * itemsize), _LARGEST_FFT_BLOCK // trailing))
            indices = list(_piece_indices(leading_shape, rows))
            for index in _progress(indices, total=len(indices), description=f"FFT stage 1, channel {channel}",
                                   enabled=progress):
                slab = np.array(reader.array[index][..., channel], dtype=dtype).reshape((-1,) + trailing_shape)
                reader.release()
                spectrum = fft.rfftn(slab, axes=spectrum_axes)
                del slab
                np.ascontiguousarray(spectrum, dtype=complex_dtype).tofile(handle)
                del spectrum
            handle.flush()
            columns = math.prod(kept_shape)
            stride = math.prod(kept_shape[halved - split + 1:])
            pair_weights = real_fft_multiplicity(shape[halved], kept_shape[halved - split])
            mapping = mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ)
            spectrum = None
            try:
                spectrum = np.frombuffer(mapping, dtype=complex_dtype).reshape(leading, columns)
                width = int(max(1, min(columns, budget // (leading * 4 * itemsize), _LARGEST_FFT_BLOCK // leading)))
                starts = range(0, columns, width)
                for start in _progress(starts, total=len(starts), description=f"FFT stage 2, channel {channel}",
                                       enabled=progress):
                    stop = min(start + width, columns)
                    block = np.array(spectrum[:, start:stop]).reshape(leading_shape + (stop - start,))
                    if hasattr(mmap, "MADV_DONTNEED"):
                        mapping.madvise(mmap.MADV_DONTNEED)
                    fft.fftn(block, axes=tuple(range(split)), out=block)
                    magnitudes = np.abs(block)
                    del block
                    weights = pair_weights[(np.arange(start, stop) // stride) % kept_shape[halved - split]]
                    histogram.add(magnitudes, weights=np.broadcast_to(weights, magnitudes.shape))
                    del magnitudes
            finally:
                spectrum = None
                try:
                    mapping.close()
                except BufferError:  # a view is still alive (an exception is unwinding)
                    pass
    finally:
        if descriptor is not None:
            os.close(descriptor)
        if path is not None and os.path.exists(path):
            os.unlink(path)

