"""Gridded primary-sample-space signals and loading them from their store.

A signal is the path contribution ``f(S(u))`` averaged over the cells of a
regular grid in primary sample space (thesis 3.2.2): an array of shape
``shape + (3,)`` (RGB, float32) with named axes.

On disk a signal is a Zarr v3 store (:mod:`sparselt.storage.zarr_store`):
:func:`load_signal` returns a :class:`Signal` whose ``data`` is the lazily
chunked Zarr array, so a signal larger than RAM (the thesis path signal is
7.9 GB) is read chunk by chunk and slices cost only the chunks they touch;
``np.asarray(signal.data)`` reads it whole. Only a store whose every chunk is
written and recorded says ``"status": "complete"``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np


from .storage.zarr_store import ChunkGrid, ChunkJournal, missing_chunks, open_data, read_attributes, store_status


class IncompleteSignalError(ValueError):
    """The signal folder holds an acquisition that has not finished."""


@dataclass
class Signal:
    """A gridded primary-sample-space signal.

    Attributes
    ----------
    data : ndarray, shape ``shape + (3,)``
        Cell means, RGB. May be a read-only memory map.
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
            ``x`` columns read at a time (default: about 16M values).
        client : distributed.Client, optional
            Compute on this Dask cluster with ``dask.array`` over the store's
            chunks (a stored signal only): 1.26x faster than in-process on a
            201 MB signal with 2 local workers (``benchmarks/distributed_sampling.py``).

        Returns
        -------
        ndarray, shape (height, width, 3), float32
            Mean over all axes but ``x`` and ``y``, transposed so that rows are
            ``y``. Accumulated in float64 in blocks of ``x`` columns, so the
            memory used is bounded even for a signal larger than RAM.
        """
        width, height = self.shape[0], self.shape[1]
        if client is not None:
            if self.store is None:
                raise ValueError("computing the image on a cluster needs a stored signal (load_signal)")
            import dask.array

            lazy = dask.array.from_zarr(self.store, component="data")
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
        reads it into RAM.

    Returns
    -------
    Signal

    Raises
    ------
    FileNotFoundError
        ``path`` is not a signal folder.
    IncompleteSignalError
        The acquisition has not finished; rerun the same ``sparselt sample``
        command to resume it.
    ValueError
        The folder is in the old ``.npy`` format, or its data are damaged
        (a chunk file missing or not matching the metadata).
    """
    path = os.fspath(path)
    status = store_status(path)
    if status is None:
        raise FileNotFoundError(f"{path!r} is not a sparselt signal folder (no Zarr group 'zarr.json' of a signal)")
    if status == "legacy":
        raise ValueError(f"{path!r} holds a signal in the old .npy folder format, which this version no longer reads; "
                         "resample it with 'sparselt sample ... --overwrite'")
    meta = read_attributes(path)
    if status != "complete":
        finished = len(ChunkJournal(path).read())
        total = meta.get("chunk_count", "?")
        raise IncompleteSignalError(
            f"signal {path!r} is incomplete ({finished}/{total} chunks finished); "
            "rerun the same 'sparselt sample' command to resume it"
        )
    expected = tuple(meta["shape"]) + (3,)
    try:
        data = open_data(path)
    except Exception as error:  # noqa: BLE001  (zarr raises several types for a damaged array)
        raise ValueError(f"the data of signal {path!r} cannot be opened ({error}); "
                         "resample the signal with 'sparselt sample --overwrite'") from None
    if tuple(data.shape) != expected:
        raise ValueError(f"signal data in {path!r} has shape {tuple(data.shape)}, metadata says {expected}")
    grid = ChunkGrid(tuple(meta["shape"]), tuple(meta["chunk_shape"]))
    missing = missing_chunks(path, grid)
    if missing:
        raise ValueError(f"signal {path!r} is damaged: {len(missing)} of {grid.count} chunk files are missing "
                         f"(first: chunk {missing[0]}); resample it with 'sparselt sample --overwrite'")
    if not mmap:
        data = np.asarray(data[...], dtype=np.float32)
    return Signal(data=data, kind=meta["kind"], axes=tuple(meta["axes"]), meta=meta, store=os.path.abspath(path))
