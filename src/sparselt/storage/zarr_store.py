"""The on-disk signal: a Zarr v3 store whose chunks are the acquisition chunks.

Layout of a signal folder ``S``::

    S/zarr.json        the group; its attributes are the signal's metadata
                       ("status" is "complete" only once every chunk is in)
    S/data/            the array, shape ``grid + (3,)``, float32, zstd, dimension
                       names = the signal's axes + "channel"
    S/chunks.jsonl     the journal: one line per finished chunk, with the CRC-32
                       of its data, appended and fsynced after the chunk file is
                       durably on disk (only while incomplete)
    S/.sparselt.lock   the writer's lock (only while a run holds it)

A chunk is the cells of a C-order contiguous run: chunks span whole trailing
axes, have size 1 on the leading ones and cut one axis in between (see
:class:`ChunkGrid`), so the acquisition kernel samples ``first .. first +
count - 1`` and the result is one Zarr chunk, written whole (no
read-modify-write, so workers never share a chunk file). ``xarray.open_zarr(S)``
and ``dask.array.from_zarr(S, component="data")`` read a signal directly.

This is the only module that imports ``zarr``.
"""

from __future__ import annotations

import errno
import json
import math
import os
import shutil
import zlib
from dataclasses import dataclass

import numpy as np

from ..provenance import read_json

FORMAT = "sparselt-signal"
FORMAT_VERSION = 2
ARRAY_NAME = "data"
GROUP_FILE = "zarr.json"
JOURNAL_FILE = "chunks.jsonl"
LEGACY_FILES = ("meta.json", "data.npy", "data.partial.npy", "progress.json")
COMPRESSION_LEVEL = 3
NO_SPACE_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


class DiskFullError(RuntimeError):
    """The device holding the store ran out of space; the run resumes once space is freed."""


@dataclass(frozen=True)
class ChunkGrid:
    """How a grid of cells is cut into acquisition chunks (= Zarr chunks).

    Attributes
    ----------
    shape : tuple of int
        The signal grid (without the RGB axis).
    chunk_shape : tuple of int
        ``(1, ..., 1, c, shape[k+1], ..., shape[-1])``: every chunk is a
        C-order contiguous run of cells.
    """

    shape: tuple
    chunk_shape: tuple

    @classmethod
    def for_cells(cls, shape, cells):
        """The chunking whose chunks hold as many cells as possible, but at most ``cells``."""
        shape = tuple(int(size) for size in shape)
        cells = max(1, int(cells))
        for axis in range(len(shape)):
            tail = math.prod(shape[axis + 1:])
            if tail <= cells:
                cut = min(shape[axis], cells // tail)
                return cls(shape, (1,) * axis + (cut,) + shape[axis + 1:])
        raise AssertionError("unreachable: the last axis has tail 1")

    @property
    def counts(self):
        """Chunks along each axis."""
        return tuple(-(-size // chunk) for size, chunk in zip(self.shape, self.chunk_shape))

    @property
    def count(self):
        return math.prod(self.counts)

    @property
    def cells_per_chunk(self):
        return math.prod(self.chunk_shape)

    def chunk(self, index):
        """``(first_cell, cell_count, region)`` of chunk ``index`` (C order over the chunk grid)."""
        if not 0 <= index < self.count:
            raise IndexError(f"chunk {index} is outside 0..{self.count - 1}")
        coordinates = np.unravel_index(int(index), self.counts)
        starts = [int(c) * size for c, size in zip(coordinates, self.chunk_shape)]
        stops = [min(start + size, limit) for start, size, limit in zip(starts, self.chunk_shape, self.shape)]
        first = int(np.ravel_multi_index(starts, self.shape)) if self.shape else 0
        count = math.prod(stop - start for start, stop in zip(starts, stops))
        region = tuple(slice(start, stop) for start, stop in zip(starts, stops))
        return first, count, region

    def chunk_key(self, index):
        """Path of the chunk's file inside the array folder (Zarr's default key encoding, '/' separated)."""
        coordinates = [int(c) for c in np.unravel_index(int(index), self.counts)] + [0]
        return os.path.join("c", *map(str, coordinates))


def checksum(values):
    """CRC-32 of a chunk's float32 data in C order."""
    return zlib.crc32(np.ascontiguousarray(values, dtype=np.float32).tobytes()) & 0xFFFFFFFF


def store_status(path):
    """``'complete'``, ``'incomplete'``, ``'legacy'`` (the old ``.npy`` folder) or ``None`` (not a signal)."""
    path = os.fspath(path)
    group = os.path.join(path, GROUP_FILE)
    if os.path.isfile(group):
        try:
            attributes = read_attributes(path)
        except ValueError:
            return "incomplete"
        if attributes.get("format") != FORMAT:
            return None
        return "complete" if attributes.get("status") == "complete" else "incomplete"
    if os.path.isfile(os.path.join(path, "meta.json")):
        return "legacy"
    return None


def read_attributes(path):
    """The signal's metadata (the group's attributes)."""
    record = read_json(os.path.join(os.fspath(path), GROUP_FILE))
    if not isinstance(record, dict) or not isinstance(record.get("attributes"), dict):
        raise ValueError(f"{os.path.join(path, GROUP_FILE)!r} is not a Zarr group's metadata")
    return record["attributes"]


def write_attributes(path, attributes):
    """Replace the signal's metadata (atomically, then fsynced)."""
    import zarr

    with no_space_is_clear(path, "writing the metadata"):
        group = zarr.open_group(os.fspath(path), mode="r+", zarr_format=3)
        group.attrs.put(attributes)
        _fsync_file(os.path.join(path, GROUP_FILE))


def create_store(path, grid, axes, attributes):
    """A new, empty store (the folder must not hold another store; other files, the lock included, stay)."""
    import zarr

    with no_space_is_clear(path, "creating the store"):
        group = zarr.open_group(os.fspath(path), mode="a", zarr_format=3, attributes=attributes)
        group.create_array(
            ARRAY_NAME, shape=tuple(grid.shape) + (3,), chunks=tuple(grid.chunk_shape) + (3,), dtype="float32",
            fill_value=0.0, dimension_names=list(axes) + ["channel"],
            compressors=zarr.codecs.ZstdCodec(level=COMPRESSION_LEVEL),
            chunk_key_encoding={"name": "default", "separator": "/"},
        )
        for name in (GROUP_FILE, os.path.join(ARRAY_NAME, GROUP_FILE)):
            _fsync_file(os.path.join(path, name))
        _fsync_directory(path)


def remove_store(path):
    """Delete a store's (or a legacy folder's) files, leaving the folder and its lock."""
    path = os.fspath(path)
    for name in (GROUP_FILE, JOURNAL_FILE) + LEGACY_FILES:
        target = os.path.join(path, name)
        if os.path.isfile(target):
            os.remove(target)
    array_folder = os.path.join(path, ARRAY_NAME)
    if os.path.isdir(array_folder):
        shutil.rmtree(array_folder)


_OPEN_ARRAYS = {}


def _array(path, mode):
    import zarr

    key = (os.path.abspath(path), mode)
    array = _OPEN_ARRAYS.get(key)
    if array is None:
        # Every chunk gets a file, zeros included: a missing file then always means a missing chunk.
        array = zarr.open_array(os.path.join(os.fspath(path), ARRAY_NAME), mode=mode, zarr_format=3)
        array = array.with_config({"write_empty_chunks": True})
        _OPEN_ARRAYS[key] = array
    return array


def forget_open_arrays(path):
    """Drop this process's cached handles on a store (after it was removed or recreated)."""
    folder = os.path.abspath(path)
    for key in [key for key in _OPEN_ARRAYS if key[0] == folder]:
        del _OPEN_ARRAYS[key]


def open_data(path):
    """The signal's data as a read-only, lazily chunked Zarr array."""
    import zarr

    return zarr.open_array(os.path.join(os.fspath(path), ARRAY_NAME), mode="r", zarr_format=3)


def write_chunk(path, grid, index, values):
    """Write chunk ``index`` (``values``: shape ``(cell_count, 3)``), make it durable, return its CRC-32."""
    first, count, region = grid.chunk(index)
    values = np.ascontiguousarray(values, dtype=np.float32)
    if values.shape != (count, 3):
        raise ValueError(f"chunk {index} takes {count} cells, got values of shape {values.shape}")
    shape = tuple(s.stop - s.start for s in region) + (3,)
    with no_space_is_clear(path, f"writing chunk {index}"):
        _array(path, "r+")[region] = values.reshape(shape)
        chunk_file = os.path.join(os.fspath(path), ARRAY_NAME, grid.chunk_key(index))
        _fsync_file(chunk_file)
        _fsync_directory(os.path.dirname(chunk_file))
    return checksum(values)


def read_chunk(path, grid, index):
    """Chunk ``index`` as stored, shape ``(cell_count, 3)``; ``None`` when it is missing or cannot be decoded."""
    first, count, region = grid.chunk(index)
    chunk_file = os.path.join(os.fspath(path), ARRAY_NAME, grid.chunk_key(index))
    if not os.path.isfile(chunk_file):
        return None
    try:
        return np.asarray(_array(path, "r")[region], dtype=np.float32).reshape(count, 3)
    except Exception:  # noqa: BLE001  (any decoding failure means: damaged, sample it again)
        return None


def missing_chunks(path, grid):
    """Indices of chunks whose file is absent (a complete store has none)."""
    folder = os.path.join(os.fspath(path), ARRAY_NAME)
    return [index for index in range(grid.count) if not os.path.isfile(os.path.join(folder, grid.chunk_key(index)))]


def remove_temporary_files(path):
    """Remove Zarr's temporary ``*.partial`` files left by writers that were killed mid-write."""
    for folder, _, files in os.walk(os.path.join(os.fspath(path), ARRAY_NAME)):
        for name in files:
            if name.endswith(".partial"):
                os.remove(os.path.join(folder, name))


class ChunkJournal:
    """Append-only record of finished chunks: ``{"chunk": i, "crc32": c, "nonfinite": n}`` per line.

    Each line is appended and fsynced after its chunk is durable. A line cut
    short by a kill is ignored when read, so its chunk is sampled again.
    """

    def __init__(self, path):
        self.path = os.path.join(os.fspath(path), JOURNAL_FILE)

    def read(self):
        """Finished chunks: ``{index: record}`` (later lines win)."""
        records = {}
        if not os.path.isfile(self.path):
            return records
        with open(self.path, encoding="utf-8", errors="replace") as handle:
            for line in handle:
                try:
                    record = json.loads(line)
                    records[int(record["chunk"])] = {"crc32": int(record["crc32"]), "nonfinite": int(record.get("nonfinite", 0))}
                except (ValueError, KeyError, TypeError):
                    continue
        return records

    def append(self, records):
        """Append records and fsync."""
        if not records:
            return
        text = "".join(json.dumps({"chunk": int(r["chunk"]), "crc32": int(r["crc32"]), "nonfinite": int(r["nonfinite"])})
                       + "\n" for r in records)
        with no_space_is_clear(os.path.dirname(self.path), "recording finished chunks"):
            with open(self.path, "a", encoding="utf-8") as handle:
                handle.write(text)
                handle.flush()
                os.fsync(handle.fileno())

    def rewrite(self, records):
        """Replace the journal by ``records`` (``{index: record}``), e.g. after dropping damaged chunks."""
        from ..provenance import atomic_write_bytes

        text = "".join(json.dumps({"chunk": index, **record}) + "\n" for index, record in sorted(records.items()))
        with no_space_is_clear(os.path.dirname(self.path), "recording finished chunks"):
            atomic_write_bytes(self.path, text.encode())

    def remove(self):
        if os.path.isfile(self.path):
            os.remove(self.path)


class no_space_is_clear:
    """Context manager: a full disk (ENOSPC, EDQUOT, EFBIG) becomes a :class:`DiskFullError` naming the store."""

    def __init__(self, path, action, remedy="finished chunks are kept: free some space and rerun the same command to resume"):
        self.path, self.action, self.remedy = os.fspath(path), action, remedy

    def __enter__(self):
        return self

    def __exit__(self, kind, error, traceback):
        if error is None:
            return False
        cause = error
        while cause is not None and not (isinstance(cause, OSError) and cause.errno in NO_SPACE_ERRORS):
            cause = cause.__cause__ or cause.__context__
        if cause is None:
            return False
        try:
            free = shutil.disk_usage(self.path if os.path.exists(self.path) else os.path.dirname(self.path)).free
            free_text = f"{free} bytes free"
        except OSError:
            free_text = "free space unknown"
        raise DiskFullError(
            f"no space left on the device holding {self.path!r} while {self.action} ({os.strerror(cause.errno)}, "
            f"{free_text}); {self.remedy}"
        ) from None


def _fsync_file(path):
    descriptor = os.open(path, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def _fsync_directory(path):
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        os.fsync(descriptor)
    except OSError:
        pass
    finally:
        os.close(descriptor)
