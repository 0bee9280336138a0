"""Gridded primary-sample-space signals and loading them from their store.

A signal is the path contribution ``f(S(u))`` averaged over the cells of a
regular grid in primary sample space (thesis 3.2.2): an array of shape
``shape + (3,)`` (RGB, float32) with named axes.

On disk a signal is a Zarr v3 store (:mod:`sparselt.storage.zarr_store`):
:func:`load_signal` returns a :class:`Signal` whose ``data`` reads the store
lazily, chunk by chunk (a :class:`~sparselt.storage.zarr_store.VerifiedArray`),
so a signal larger than RAM (the thesis path signal is 7.9 GB) is read in
pieces and slices cost only the chunks they touch; ``np.asarray(signal.data)``
reads it whole. Every chunk read is checked against the CRC-32 recorded when
it was sampled: a damaged one raises
:class:`~sparselt.storage.zarr_store.CorruptSignalError` naming the store, the
chunk and the remedy (rerunning the ``sparselt sample`` command that wrote it
samples the damaged chunks again). Only a store whose every chunk is written
and recorded says ``"status": "complete"``; :func:`load_signal` refuses
metadata it does not know (format version, kind, data type) or that lacks an
attribute.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from .checks import check_integer
from .rendering.layout import KINDS
from .storage.zarr_store import (
    FORMAT_VERSION,
    REPAIR_REMEDY,
    SIBLING_ROLES,
    ChunkGrid,
    ChunkJournal,
    CorruptSignalError,
    VerifiedArray,
    missing_chunks,
    open_data,
    read_attributes,
    recorded_checksums,
    sibling_path,
    store_status,
)

#: Attributes every signal store records in its zarr.json (``chunk_crc32`` too once complete), and their types.
REQUIRED_ATTRIBUTES = {"format": str, "format_version": int, "status": str, "kind": str, "axes": list, "shape": list,
                       "chunk_shape": list}


class IncompleteSignalError(ValueError):
    """The signal folder holds an acquisition that has not finished."""


@dataclass
class Signal:
    """A gridded primary-sample-space signal.

    Attributes
    ----------
    data : ndarray or VerifiedArray, shape ``shape + (3,)``
        Cell means, RGB. A stored signal's data are read lazily, every chunk
        checked against its CRC-32 (:func:`load_signal`).
    kind : str
        Signal kind ('path', 'path-indirect', 'dof', 'indirect').
    axes : tuple of str
        Name of each grid axis; the first two are the image plane ``x, y``.
    meta : dict
        Everything recorded about the acquisition (scene, spp, seed, ...).
    store : str or None
        The store the data come from (``load_signal``), else ``None``.
    """

    data: np.ndarray
    kind: str
    axes: tuple
    meta: dict = field(default_factory=dict)
    store: str | None = None

    def __post_init__(self):
        self.axes = tuple(self.axes)
        if len(self.axes) < 2:
            raise ValueError(f"a signal needs at least the two image-plane axes (x, y), got axes {self.axes}")
        if self.data.ndim != len(self.axes) + 1 or self.data.shape[-1] != 3:
            raise ValueError(
                f"signal data of shape {self.data.shape} does not match axes {self.axes}: "
                "expected one array axis per signal axis plus a trailing RGB axis of size 3"
            )

    @property
    def shape(self):
        """Grid resolution, one entry per axis (without the RGB axis)."""
        return tuple(self.data.shape[:-1])

    def image(self, *, rows_per_block=None, client=None):
        """Integrate over every non-image axis: the pixel values.

        Parameters
        ----------
        rows_per_block : int, optional
            ``x`` columns read at a time, at least 1 (default: about 16M values).
        client : distributed.Client, optional
            Compute on this Dask cluster with ``dask.array`` over the store's
            chunks (a stored signal only): 1.26x faster than in-process on a
            201 MB signal with 2 local workers (``benchmarks/distributed_sampling.py``).
            The workers read through the same verified reader
            (``dask.array.from_array`` over ``self.data``), so every chunk is
            checked against its CRC-32 on the cluster too.

        Returns
        -------
        ndarray, shape (height, width, 3), float32
            Mean over all axes but ``x`` and ``y``, transposed so that rows are
            ``y``. Accumulated in float64 in blocks of ``x`` columns, so the
            memory used is bounded even for a signal larger than RAM.

        Raises
        ------
        CorruptSignalError
            A chunk read does not match its recorded CRC-32 or cannot be decoded.
        """
        width, height = self.shape[0], self.shape[1]
        if rows_per_block is not None:
            rows_per_block = check_integer("rows_per_block", rows_per_block, 1)
        if client is not None:
            if self.store is None or not isinstance(self.data, VerifiedArray):
                raise ValueError("computing the image on a cluster needs a stored signal (load_signal)")
            import dask.array

            lazy = dask.array.from_array(self.data, chunks=self.data.chunks, asarray=True, fancy=False)
            mean = lazy.mean(axis=tuple(range(2, lazy.ndim - 1)), dtype=np.float64)
            return np.ascontiguousarray(client.compute(mean).result().transpose(1, 0, 2)).astype(np.float32)
        rest = int(np.prod(self.shape[2:], dtype=np.int64))
        if rows_per_block is None:
            rows_per_block = max(1, int(2**24 // max(1, height * rest)))
        image = np.empty((width, height, 3), dtype=np.float64)
        for start in range(0, width, rows_per_block):
            block = np.asarray(self.data[start:start + rows_per_block], dtype=np.float64)
            image[start:start + rows_per_block] = block.reshape(block.shape[0], height, rest, 3).mean(axis=2)
        return np.ascontiguousarray(image.transpose(1, 0, 2)).astype(np.float32)


def signal_status(path):
    """'complete', 'incomplete', 'legacy' (the old ``.npy`` folder format) or ``None`` (not a signal)."""
    return store_status(path)


def load_signal(path, *, mmap=True):
    """Load a signal store written by ``sparselt sample``.

    Parameters
    ----------
    path : str
        The signal folder (a Zarr v3 store).
    mmap : bool, optional
        Keep the data on disk, read lazily chunk by chunk (default); ``False``
        reads it into RAM (every chunk verified).

    Returns
    -------
    Signal
        Its ``data`` is a :class:`~sparselt.storage.zarr_store.VerifiedArray`
        (or, with ``mmap=False``, an ndarray read through one).

    Raises
    ------
    FileNotFoundError
        ``path`` is not a signal folder.
    IncompleteSignalError
        The acquisition has not finished; rerun the same ``sparselt sample``
        command to resume it.
    CorruptSignalError
        A chunk file is missing, or the recorded chunk checksums are missing,
        of the wrong length or wiped (and, on reading, a chunk does not match
        its checksum or cannot be decoded); rerun the same ``sparselt sample``
        command with ``--verify`` to repair it.
    ValueError
        The folder is in the old ``.npy`` format, or its metadata are not a
        signal's this version reads: unknown format version or kind, an
        attribute missing or of the wrong type, data not float32 or not of the
        recorded shape or chunking.
    """
    path = os.fspath(path)
    status = store_status(path)
    if status is None:
        leftovers = [sibling_path(path, role) for role in SIBLING_ROLES if os.path.isdir(sibling_path(path, role))]
        hint = (f"; {leftovers[0]!r} is left by a replacement that was interrupted: rerun the `sparselt sample` "
                "command to finish it") if leftovers and not os.path.exists(path) else ""
        raise FileNotFoundError(f"{path!r} is not a sparselt signal folder (no Zarr group 'zarr.json' of a signal)"
                                f"{hint}")
    if status == "legacy":
        raise ValueError(f"{path!r} holds a signal in the old .npy folder format, which this version no longer reads; "
                         "resample it with 'sparselt sample ... --overwrite'")
    meta = read_attributes(path)
    if status != "complete":  # first: what to do about an unfinished run matters more than its metadata
        finished = len(ChunkJournal(path).read())
        total = meta.get("chunk_count", "?")
        raise IncompleteSignalError(
            f"signal {path!r} is incomplete ({finished}/{total} chunks finished); "
            "rerun the same 'sparselt sample' command to resume it"
        )
    _check_attributes(path, meta)
    expected = tuple(meta["shape"]) + (3,)
    try:
        array = open_data(path)
    except Exception as error:  # noqa: BLE001  (zarr raises several types for a damaged array)
        raise ValueError(f"the data of signal {path!r} cannot be opened ({error}); "
                         "resample the signal with 'sparselt sample --overwrite'") from None
    if np.dtype(array.dtype) != np.float32:
        raise ValueError(f"signal {path!r} stores data type {np.dtype(array.dtype)}, expected float32 (data/zarr.json "
                         "'data_type'); resample it with 'sparselt sample --overwrite'")
    if tuple(array.shape) != expected:
        raise ValueError(f"signal data in {path!r} has shape {tuple(array.shape)}, metadata says {expected}")
    if tuple(array.chunks) != tuple(meta["chunk_shape"]) + (3,):
        raise ValueError(f"signal data in {path!r} are stored in chunks of shape {tuple(array.chunks)}, its metadata "
                         f"says {tuple(meta['chunk_shape']) + (3,)}; resample it with 'sparselt sample --overwrite'")
    grid = ChunkGrid(tuple(meta["shape"]), tuple(meta["chunk_shape"]))
    missing = missing_chunks(path, grid)
    if missing:
        raise CorruptSignalError(f"signal {path!r} is damaged: {len(missing)} of {grid.count} chunk files are missing "
                                 f"(first: chunk {missing[0]}); {REPAIR_REMEDY}")
    data = VerifiedArray(path, grid, recorded_checksums(path, meta, grid.count))
    if not mmap:
        data = np.asarray(data)
    return Signal(data=data, kind=meta["kind"], axes=tuple(meta["axes"]), meta=meta, store=os.path.abspath(path))


def _check_attributes(path, meta):
    """Refuse metadata this version does not read, naming the attribute and what is allowed."""
    where = f"signal {path!r}"
    version = meta.get("format_version")
    if version != FORMAT_VERSION:
        found = "has no attribute 'format_version'" if version is None else f"has format_version {version!r}"
        raise ValueError(f"{where} {found} in its zarr.json; this version of sparselt reads format_version "
                         f"{FORMAT_VERSION} only: read it with the sparselt that wrote it, or resample it")
    for name, kind in REQUIRED_ATTRIBUTES.items():
        if name not in meta:
            raise ValueError(f"{where} lacks the attribute {name!r} in its zarr.json; a signal records "
                             f"{', '.join(REQUIRED_ATTRIBUTES)} (and chunk_crc32 once complete): resample it with "
                             "'sparselt sample --overwrite'")
        value = meta[name]
        if isinstance(value, bool) or not isinstance(value, kind):
            raise ValueError(f"{where}: attribute {name!r} must be a {'JSON ' + kind.__name__}, got {value!r:.60}")
    if meta["kind"] not in KINDS:
        raise ValueError(f"{where} has kind {meta['kind']!r} in its zarr.json; the kinds are {', '.join(KINDS)}")
    shape, chunk_shape, axes = meta["shape"], meta["chunk_shape"], meta["axes"]
    for name, sizes in (("shape", shape), ("chunk_shape", chunk_shape)):
        if len(sizes) < 2 or any(isinstance(size, bool) or not isinstance(size, int) or size < 1 for size in sizes):
            raise ValueError(f"{where}: attribute {name!r} must list at least two positive integers (one per axis, "
                             f"image plane first), got {sizes!r:.60}")
    if len(chunk_shape) != len(shape) or any(chunk > size for chunk, size in zip(chunk_shape, shape)):
        raise ValueError(f"{where}: attribute 'chunk_shape' {chunk_shape} does not fit 'shape' {shape} (one entry per "
                         "axis, each at most the axis's size)")
    if len(axes) != len(shape) or not all(isinstance(name, str) for name in axes):
        raise ValueError(f"{where}: attribute 'axes' must name each of the {len(shape)} axes of 'shape', got "
                         f"{axes!r:.60}")
