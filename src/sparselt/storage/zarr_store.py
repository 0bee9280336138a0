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

Nothing else belongs in a store: a folder holding any other entry is not
sparselt's (:func:`foreign_entries`) and no command removes or replaces it.
A complete store records the CRC-32 of every chunk (``chunk_crc32``), and
every read through :class:`VerifiedArray` (what
:func:`sparselt.signal.load_signal` returns as ``Signal.data``) checks the
chunks it touches against them: damage raises :class:`CorruptSignalError`,
and rerunning the ``sparselt sample`` command that wrote the store samples
just the damaged chunks again. A complete store also records the size and
modification time of every chunk file (``chunk_files``,
:func:`chunk_signatures`), so a rerun reads only the chunks whose files
changed to decide whether the store is complete and intact (with
``--verify``, every chunk).

A store is replaced (``sample --overwrite``) by writing the new one beside it,
in the hidden sibling ``.S.sparselt-new`` (:func:`sibling_path`), and
exchanging the two folders once the new one is complete
(:func:`replace_store`): at every instant ``S`` holds either the old complete
signal or the new complete one.

A chunk is the cells of a C-order contiguous run: chunks span whole trailing
axes, have size 1 on the leading ones and cut one axis in between (see
:class:`ChunkGrid`), so the acquisition kernel samples ``first .. first +
count - 1`` and the result is one Zarr chunk, written whole (no
read-modify-write, so workers never share a chunk file). ``xarray.open_zarr(S)``
and ``dask.array.from_zarr(S, component="data")`` read a signal directly.

This is the only module that imports ``zarr``.
"""

from __future__ import annotations

import ctypes
import errno
import itertools
import json
import math
import numbers
import os
import shutil
import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..provenance import read_json
from .errors import NO_SPACE_ERRORS, DiskFullError, no_space_is_clear  # noqa: F401  (also imported from here)
from .lock import LOCK_FILE

FORMAT = "sparselt-signal"
FORMAT_VERSION = 2
ARRAY_NAME = "data"
GROUP_FILE = "zarr.json"
JOURNAL_FILE = "chunks.jsonl"
LEGACY_FILES = ("meta.json", "data.npy", "data.partial.npy", "progress.json")
COMPRESSION_LEVEL = 3


#: What to do about a damaged store: the ``sample`` command that wrote it samples just the damaged chunks again
#: (``--verify`` reads every chunk: damage that changed neither a file's size nor its time is found too).
REPAIR_REMEDY = "rerun the same `sparselt sample` command with --verify to repair it"
#: Roles of a store's hidden siblings: the replacement being written, and the old store during a fallback swap.
SIBLING_ROLES = ("new", "old")


class CorruptSignalError(ValueError):
    """A stored signal's chunk does not match its recorded CRC-32, cannot be decoded, or cannot be verified.

    The message names the store, the chunk and the remedy (:data:`REPAIR_REMEDY`).
    """


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
    """CRC-32 of a chunk's float32 data in C order (its bytes in memory, read without a copy)."""
    return zlib.crc32(memoryview(np.ascontiguousarray(values, dtype=np.float32)).cast("B")) & 0xFFFFFFFF


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
    """The store's data array, opened once per process and store.

    The handle is kept with the identity of the array's metadata file: a store
    removed and created again at the same path (by another process, as a
    cluster's workers see it) is opened again, never written through a
    handle that holds the old store's shape and chunking.
    """
    import zarr

    key = (os.path.abspath(path), mode)
    folder = os.path.join(os.fspath(path), ARRAY_NAME)
    try:
        status = os.stat(os.path.join(folder, "zarr.json"))
        stamp = (status.st_ino, status.st_mtime_ns, status.st_size)
    except OSError:
        stamp = None
    cached = _OPEN_ARRAYS.get(key)
    if cached is not None and cached[0] == stamp:
        return cached[1]
    # Every chunk gets a file, zeros included: a missing file then always means a missing chunk.
    array = zarr.open_array(folder, mode=mode, zarr_format=3)
    array = array.with_config({"write_empty_chunks": True})
    _OPEN_ARRAYS[key] = (stamp, array)
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


def recorded_checksums(path, attributes, count):
    """The CRC-32 of every chunk recorded in a complete store's metadata (``chunk_crc32``), checked.

    Parameters
    ----------
    path : str
        The store (for messages).
    attributes : dict
        Its metadata (:func:`read_attributes`).
    count : int
        Its number of chunks.

    Returns
    -------
    tuple of int

    Raises
    ------
    CorruptSignalError
        The list is missing, not a list of CRC-32 values, of another length
        than the chunk count, or all zero (wiped): the chunks cannot be verified.
    """
    values = attributes.get("chunk_crc32")
    where = f"signal {os.fspath(path)!r}"
    remedy = f"its chunks cannot be verified: {REPAIR_REMEDY} (every chunk is sampled again)"
    if values is None:
        raise CorruptSignalError(f"{where} records no chunk checksums (attribute 'chunk_crc32' is missing from its "
                                 f"zarr.json); {remedy}")
    if not isinstance(values, list) or any(isinstance(value, bool) or not isinstance(value, int)
                                           or not 0 <= value < 2**32 for value in values):
        raise CorruptSignalError(f"{where}: attribute 'chunk_crc32' must be a list of CRC-32 values (integers in "
                                 f"[0, 2**32)), got {str(values)[:60]}; {remedy}")
    if len(values) != count:
        raise CorruptSignalError(f"{where} records {len(values)} chunk checksums ('chunk_crc32') for its {count} chunks; "
                                 f"{remedy}")
    if not any(values):
        raise CorruptSignalError(f"{where}: its {count} chunk checksums ('chunk_crc32') are all zero (wiped); {remedy}")
    return tuple(values)


#: Chunks whose CRC-32 this process has checked: ``(store, index) -> (crc32, file signature)``.
_VERIFIED_CHUNKS = {}


def _file_signature(path):
    status = os.stat(path)
    return status.st_ino, status.st_size, status.st_mtime_ns


class VerifiedArray:
    """A complete signal's data, read-only: every chunk read is checked against its recorded CRC-32.

    The array-like that :func:`sparselt.signal.load_signal` puts in
    ``Signal.data``: ``shape``, ``dtype``, ``ndim``, basic indexing (integers,
    slices, ``...``) and ``numpy.asarray``. A read decodes each chunk it
    touches whole (as Zarr does), checks the chunk's CRC-32 the first time
    this process reads it (a chunk file that changed since is checked again)
    and copies the selected part. Reads touching several chunks decode them
    on a few threads. It pickles as the store's path and checksums, so Dask
    workers (``dask.array.from_array``) verify the chunks they read too.

    Parameters
    ----------
    path : str
        The store.
    grid : ChunkGrid
        Its chunking.
    checksums : sequence of int
        The recorded CRC-32 of each chunk (:func:`recorded_checksums`).

    Raises
    ------
    CorruptSignalError
        On a read, when a chunk touched is missing, cannot be decoded or does
        not match its checksum; the message names the store, the chunk and
        the remedy.
    """

    def __init__(self, path, grid, checksums):
        self.store = os.path.abspath(os.fspath(path))
        self.grid = grid
        self.checksums = tuple(int(value) for value in checksums)
        if len(self.checksums) != grid.count:
            raise ValueError(f"{len(self.checksums)} checksums for the {grid.count} chunks of {self.store!r}")
        self.shape = tuple(grid.shape) + (3,)
        self.chunks = tuple(grid.chunk_shape) + (3,)
        self.dtype = np.dtype(np.float32)
        self.ndim = len(self.shape)
        self._zarr = None

    @property
    def size(self):
        return math.prod(self.shape)

    @property
    def nbytes(self):
        return self.size * self.dtype.itemsize

    def __len__(self):
        return self.shape[0]

    def __repr__(self):
        return f"VerifiedArray({self.store!r}, shape={self.shape}, dtype=float32)"

    def __getstate__(self):
        return {"store": self.store, "grid": self.grid, "checksums": self.checksums}

    def __setstate__(self, state):
        self.__init__(state["store"], state["grid"], state["checksums"])

    def __dask_tokenize__(self):
        return ("sparselt-verified-array", self.store, self.checksums)

    def __array__(self, dtype=None, copy=None):
        values = self[...]
        return values if dtype is None else values.astype(dtype, copy=False)

    def __getitem__(self, key):
        selection = self._selection(key)
        ranges = [range(start, stop, step) for start, stop, step, _, _ in selection]
        out = np.empty([len(r) for r in ranges], dtype=np.float32)
        if out.size:
            pieces = self._pieces(ranges)
            if len(pieces) == 1:
                self._copy(out, *pieces[0])
            else:
                with ThreadPoolExecutor(max_workers=min(len(pieces), os.cpu_count() or 1, 8)) as pool:
                    for _ in pool.map(lambda piece: self._copy(out, *piece), pieces):
                        pass
        index = tuple(0 if drop else slice(None, None, -1 if flip else 1) for _, _, _, drop, flip in selection)
        return out[index]

    def _selection(self, key):
        """Per axis ``(start, stop, step, dropped, flipped)`` with ``step > 0`` (a negative step is read forwards, then flipped)."""
        key = key if isinstance(key, tuple) else (key,)
        ellipses = [position for position, item in enumerate(key) if item is Ellipsis]
        if len(ellipses) > 1:
            raise IndexError("an index can only have a single ellipsis ('...')")
        if ellipses:
            at = ellipses[0]
            key = key[:at] + (slice(None),) * (self.ndim - len(key) + 1) + key[at + 1:]
        if len(key) > self.ndim:
            raise IndexError(f"too many indices for signal data of {self.ndim} dimensions: {len(key)} given")
        key = key + (slice(None),) * (self.ndim - len(key))
        selection = []
        for axis, (item, size) in enumerate(zip(key, self.shape)):
            if isinstance(item, (numbers.Integral, np.integer)) and not isinstance(item, (bool, np.bool_)):
                index = int(item)
                if not -size <= index < size:
                    raise IndexError(f"index {index} is out of bounds for axis {axis} with size {size}")
                index %= size
                selection.append((index, index + 1, 1, True, False))
            elif isinstance(item, slice):
                indices = range(*item.indices(size))
                flipped = indices.step < 0
                if flipped:
                    indices = indices[::-1]
                selection.append((indices.start, indices.stop, indices.step, False, flipped))
            else:
                raise TypeError(f"signal data take integers, slices and '...' as indices (basic indexing), got "
                                f"{type(item).__name__} for axis {axis}: read a slice, then index the array it gives")
        return selection

    def _pieces(self, ranges):
        """``(chunk index, part of the chunk, part of the output)`` for every chunk the selection touches."""
        touched = [np.unique(np.arange(r.start, r.stop, r.step) // size) for r, size in zip(ranges, self.chunks)]
        pieces = []
        for coordinates in itertools.product(*touched[:-1]):  # the RGB axis is one chunk
            source, target = [], []
            for r, coordinate, size, limit in zip(ranges, tuple(coordinates) + (0,), self.chunks, self.shape):
                begin, end = int(coordinate) * size, min(int(coordinate) * size + size, limit)
                first = r.start if r.start >= begin else r.start + -(-(begin - r.start) // r.step) * r.step
                last = min(r.stop, end)
                offset = (first - r.start) // r.step
                source.append(slice(first - begin, last - begin, r.step))
                target.append(slice(offset, offset + len(range(first, last, r.step))))
            index = int(np.ravel_multi_index(tuple(int(c) for c in coordinates), self.grid.counts)) if coordinates else 0
            pieces.append((index, tuple(source), tuple(target)))
        return pieces

    def _copy(self, out, index, source, target):
        _, _, region = self.grid.chunk(index)
        whole = all(part == slice(0, bounds.stop - bounds.start, 1) for part, bounds in zip(source, region))
        if whole and source[-1] == slice(0, 3, 1):
            self._read(index, into=out[target])  # decoded straight into the output: no copy
        else:
            out[target] = self._read(index)[source]

    def verify(self, index):
        """Check chunk ``index`` against its CRC-32 (reading it only if this process has not verified it yet)."""
        chunk_file = os.path.join(self.store, ARRAY_NAME, self.grid.chunk_key(index))
        try:
            if _VERIFIED_CHUNKS.get((self.store, index)) == (self.checksums[index], _file_signature(chunk_file)):
                return
        except FileNotFoundError:
            pass
        self._read(index)

    def chunk(self, index):
        """Chunk ``index`` as stored (shape: its region of the grid + (3,)), checked against its CRC-32."""
        return self._read(index)

    def _read(self, index, into=None):
        """Decode chunk ``index`` (into the array view ``into`` when given) and check it; return its values."""
        _, _, region = self.grid.chunk(index)
        chunk_file = os.path.join(self.store, ARRAY_NAME, self.grid.chunk_key(index))
        where = f"chunk {index} of signal {self.store!r}"
        try:
            signature = _file_signature(chunk_file)
        except FileNotFoundError:
            raise CorruptSignalError(f"{where} is missing (no file {self.grid.chunk_key(index)!r}); "
                                     f"{REPAIR_REMEDY}") from None
        try:
            if self._zarr is None:
                self._zarr = open_data(self.store)
            selection = region + (slice(None),)
            if into is None:
                values = np.asarray(self._zarr[selection], dtype=np.float32)
            else:
                from zarr.core.buffer import cpu

                self._zarr.get_basic_selection(selection, out=cpu.NDBuffer.from_numpy_array(into))
                values = into
        except Exception as error:  # noqa: BLE001  (Zarr and its codecs raise several types for damaged bytes)
            raise CorruptSignalError(f"{where} cannot be decoded ({type(error).__name__}: {error}); "
                                     f"{REPAIR_REMEDY}") from None
        expected = self.checksums[index]
        if _VERIFIED_CHUNKS.get((self.store, index)) != (expected, signature):
            found = checksum(values)
            if found != expected:
                raise CorruptSignalError(f"{where} is damaged: its CRC-32 is {found:#010x}, the store recorded "
                                         f"{expected:#010x}; {REPAIR_REMEDY}")
            _VERIFIED_CHUNKS[(self.store, index)] = (expected, signature)
        return values


def damaged_chunks(path, grid, checksums, indices=None):
    """Indices of the chunks of a store that are missing, cannot be decoded or do not match ``checksums``.

    Only ``indices`` are checked (default: every chunk). Chunks this process
    already verified (and whose files did not change since) are not read again.
    """
    reader = VerifiedArray(path, grid, checksums)
    damaged = []
    for index in (range(grid.count) if indices is None else indices):
        try:
            reader.verify(index)
        except CorruptSignalError:
            damaged.append(index)
    return damaged


def foreign_entries(path):
    """Entries of a folder that a signal store does not hold, as paths relative to it (sorted, at most 10).

    A store holds ``zarr.json``, ``data/`` (``zarr.json`` and chunk files
    ``c/<i>/.../<k>``), ``chunks.jsonl``, the lock, the old format's files and
    the temporary files of Zarr's (``*.partial``) and sparselt's atomic
    writers (``.tmp-*``). Anything else was put there by someone else.
    """
    path = os.fspath(path)
    own = {GROUP_FILE, JOURNAL_FILE, LOCK_FILE} | set(LEGACY_FILES)
    foreign = []

    def temporary(name):
        return name.endswith(".partial") or name.startswith(".tmp-")

    for name in sorted(os.listdir(path)):
        full = os.path.join(path, name)
        if name == ARRAY_NAME and os.path.isdir(full) and not os.path.islink(full):
            for inner in sorted(os.listdir(full)):
                inner_path = os.path.join(full, inner)
                if inner == "c" and os.path.isdir(inner_path) and not os.path.islink(inner_path):
                    for folder, folders, files in os.walk(inner_path):
                        relative = os.path.relpath(folder, path)
                        foreign += [os.path.join(relative, entry) for entry in sorted(folders) if not entry.isdigit()]
                        foreign += [os.path.join(relative, entry) for entry in sorted(files)
                                    if not (entry.isdigit() or temporary(entry))]
                        folders[:] = [entry for entry in folders if entry.isdigit()]
                elif not (inner == GROUP_FILE and os.path.isfile(inner_path)) and not temporary(inner):
                    foreign.append(os.path.join(ARRAY_NAME, inner))
        elif not ((name in own and os.path.isfile(full)) or temporary(name)):
            foreign.append(name)
        if len(foreign) >= 10:
            break
    return sorted(foreign)[:10]


def check_not_foreign(path):
    """Refuse a folder holding anything a signal store does not (nothing there is removed or replaced)."""
    foreign = foreign_entries(path) if os.path.isdir(path) else []
    if foreign:
        shown = ", ".join(repr(name) for name in foreign[:2]) + (" ..." if len(foreign) > 2 else "")
        raise ValueError(f"output folder {os.fspath(path)!r} is not a signal: it holds files that sparselt did not "
                         f"write ({shown}); "
                         "sparselt removes or replaces nothing there, --overwrite or not: choose another output folder "
                         "or move those files away")


def sibling_path(path, role):
    """The hidden sibling ``.<name>.sparselt-<role>`` of store ``path``, in the same folder (``role``: 'new' or 'old')."""
    if role not in SIBLING_ROLES:
        raise ValueError(f"role must be one of {SIBLING_ROLES}, got {role!r}")
    parent, name = os.path.split(os.path.abspath(os.fspath(path)))
    return os.path.join(parent, f".{name}.sparselt-{role}")


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(first, second):
    """Swap two folders in one atomic step (Linux ``renameat2(RENAME_EXCHANGE)``); ``False`` where unsupported."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if renameat2(_AT_FDCWD, os.fsencode(first), _AT_FDCWD, os.fsencode(second), _RENAME_EXCHANGE) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(code, f"cannot exchange {first!r} and {second!r}: {os.strerror(code)}", second)


def replace_store(new, path):
    """Put the complete store ``new`` (a sibling of ``path``) in the place of store ``path``, then delete the old one.

    Where the file system can exchange two folders atomically (Linux), ``path``
    holds the old store or the new one at every instant. Elsewhere the old
    store is renamed to its 'old' sibling first; a run killed between the two
    renames leaves no store under ``path`` until :func:`recover_replacement`
    (the next ``sample`` run) finishes the swap.
    """
    path = os.path.abspath(os.fspath(path))
    parent = os.path.dirname(path)
    if _exchange(new, path):
        _fsync_directory(parent)
        shutil.rmtree(new)  # now the old store
        return
    old = sibling_path(path, "old")
    if os.path.exists(old):
        shutil.rmtree(old)
    os.rename(path, old)
    os.rename(new, path)
    _fsync_directory(parent)
    shutil.rmtree(old)


def recover_replacement(path):
    """Finish a replacement that a run killed between the fallback's two renames left undone.

    With no store under ``path``: the complete new sibling goes into place, or
    else the old store goes back. A stale 'old' sibling beside a store is
    removed. Returns what was done (``None``: nothing to do).
    """
    path = os.path.abspath(os.fspath(path))
    old, new = sibling_path(path, "old"), sibling_path(path, "new")
    if not os.path.isdir(old):
        return None
    if os.path.exists(path):
        if foreign_entries(old):
            return None
        shutil.rmtree(old)
        return "removed the old store left by an interrupted replacement"
    if store_status(new) == "complete":
        os.rename(new, path)
        shutil.rmtree(old)
        return "finished an interrupted replacement: the new store is in place"
    os.rename(old, path)
    return "undid an interrupted replacement: the old store is back in place"


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


def chunk_signatures(path, grid):
    """``[size, mtime_ns]`` of every chunk file (``None`` for a missing one), in chunk order.

    A complete store records them (``chunk_files``) when its last chunk is
    in, so a rerun of the command that wrote it can tell, from the files'
    metadata alone, which chunks were written since (and only those are read
    and checked against their CRC-32: :func:`changed_chunks`).
    """
    folder = os.path.join(os.fspath(path), ARRAY_NAME)
    signatures = []
    for index in range(grid.count):
        try:
            status = os.stat(os.path.join(folder, grid.chunk_key(index)))
        except FileNotFoundError:
            signatures.append(None)
            continue
        signatures.append([status.st_size, status.st_mtime_ns])
    return signatures


def changed_chunks(recorded, signatures):
    """Indices whose current signature (:func:`chunk_signatures`) differs from the ``recorded`` one; every index
    when nothing usable was recorded (a store completed before signatures were recorded)."""
    if not isinstance(recorded, list) or len(recorded) != len(signatures):
        return list(range(len(signatures)))
    return [index for index, (before, now) in enumerate(zip(recorded, signatures)) if now is None or before != now]


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
    """Append-only record of finished chunks: ``{"chunk": i, "crc32": c, "nonfinite": n, "seconds": s}`` per line.

    Each line is appended and fsynced after its chunk is durable. A line cut
    short by a kill is ignored when read, so its chunk is sampled again.
    ``seconds`` is the sampling time the run spent up to this chunk since its
    previous line (or its start), so the time of a killed run is kept.
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
                    records[int(record["chunk"])] = {"crc32": int(record["crc32"]),
                                                     "nonfinite": int(record.get("nonfinite", 0)),
                                                     "seconds": float(record.get("seconds", 0.0))}
                except (ValueError, KeyError, TypeError):
                    continue
        return records

    def append(self, records):
        """Append records and fsync."""
        if not records:
            return
        text = "".join(json.dumps({"chunk": int(r["chunk"]), "crc32": int(r["crc32"]), "nonfinite": int(r["nonfinite"]),
                                   "seconds": float(r.get("seconds", 0.0))}) + "\n" for r in records)
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
