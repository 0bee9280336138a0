"""Gridded primary-sample-space signals and their on-disk format.

A signal is the path contribution ``f(S(u))`` averaged over the cells of a
regular grid in primary sample space (thesis 3.2.2): an array of shape
``shape + (3,)`` (RGB, float32) with named axes.

On disk a signal is a folder::

    meta.json          configuration, layout, provenance; "status" says whether
                       the data is complete
    data.npy           the data, present only once every chunk is written
    data.partial.npy   the data while it is being acquired (never loads)
    progress.json      chunks finished so far (only while incomplete)

The data file is a plain ``.npy`` array that :func:`load_signal` memory-maps,
so a signal larger than RAM (the thesis path signal is 7.9 GB) is read lazily
and random subsets of cells cost only what they touch. Chunks are committed
atomically: a chunk's cells are flushed to ``data.partial.npy`` before the
chunk is recorded in ``progress.json`` (itself replaced atomically), and only a
finished acquisition renames the data to ``data.npy``. A killed run therefore
never leaves a file that loads as complete, and resuming recomputes only the
chunks that were not recorded.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from .provenance import read_json

META_FILE = "meta.json"
DATA_FILE = "data.npy"
PARTIAL_DATA_FILE = "data.partial.npy"
PROGRESS_FILE = "progress.json"
FORMAT_VERSION = 1


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
    """

    data: np.ndarray
    kind: str
    axes: tuple
    meta: dict = field(default_factory=dict)

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

    def image(self, *, rows_per_block=None):
        """Integrate over every non-image axis: the pixel values.

        Returns
        -------
        ndarray, shape (height, width, 3), float32
            Mean over all axes but ``x`` and ``y``, transposed so that rows are
            ``y``. Accumulated in float64 in blocks of ``x`` columns, so the
            memory used is bounded even for a memory-mapped signal.
        """
        width, height = self.shape[0], self.shape[1]
        rest = int(np.prod(self.shape[2:], dtype=np.int64))
        if rows_per_block is None:
            rows_per_block = max(1, int(2**24 // max(1, height * rest)))
        image = np.empty((width, height, 3), dtype=np.float64)
        for start in range(0, width, rows_per_block):
            block = np.asarray(self.data[start:start + rows_per_block], dtype=np.float64)
            image[start:start + rows_per_block] = block.reshape(block.shape[0], height, rest, 3).mean(axis=2)
        return np.ascontiguousarray(image.transpose(1, 0, 2)).astype(np.float32)


def signal_status(path):
    """'complete', 'incomplete' or ``None`` (not a signal folder)."""
    meta_path = os.path.join(path, META_FILE)
    if not os.path.isfile(meta_path):
        return None
    if os.path.isfile(os.path.join(path, DATA_FILE)) and read_json(meta_path).get("status") == "complete":
        return "complete"
    return "incomplete"


def load_signal(path, *, mmap=True):
    """Load a signal folder written by ``sparselt sample``.

    Parameters
    ----------
    path : str
        The signal folder.
    mmap : bool, optional
        Memory-map the data read-only (default); ``False`` reads it into RAM.

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
    """
    path = os.fspath(path)
    meta_path = os.path.join(path, META_FILE)
    if not os.path.isfile(meta_path):
        raise FileNotFoundError(f"{path!r} is not a sparselt signal folder (no {META_FILE})")
    meta = read_json(meta_path)
    data_path = os.path.join(path, DATA_FILE)
    if meta.get("status") != "complete" or not os.path.isfile(data_path):
        done = "unknown"
        progress_path = os.path.join(path, PROGRESS_FILE)
        if os.path.isfile(progress_path):
            progress = read_json(progress_path)
            done = f"{len(progress.get('finished_chunks', []))}/{progress.get('chunk_count')} chunks"
        raise IncompleteSignalError(
            f"signal {path!r} is incomplete ({done} finished); rerun the same 'sparselt sample' command to resume it"
        )
    try:
        data = np.load(data_path, mmap_mode="r" if mmap else None, allow_pickle=False)
    except (ValueError, EOFError, OSError) as error:
        raise ValueError(f"the data file {data_path!r} is empty or corrupt ({error}); "
                         "resample the signal with 'sparselt sample --overwrite'") from None
    expected = tuple(meta["shape"]) + (3,)
    if data.shape != expected:
        raise ValueError(f"signal data in {path!r} has shape {data.shape}, metadata says {expected}")
    return Signal(data=data, kind=meta["kind"], axes=tuple(meta["axes"]), meta=meta)
