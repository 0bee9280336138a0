"""Acquire primary-sample-space signals: chunked, resumable, reproducible.

:func:`acquire_signal` evaluates every cell of a grid over the axes of a
signal kind as the mean of ``spp`` jittered samples of ``f(S(u))`` (thesis
3.2.2 and 5.3: "each point in these signals was estimated as the average of 64
randomly jittered samples"), in chunks that fit in memory, with a progress bar,
writing the signal store described in :mod:`sparselt.storage.zarr_store`.

Every chunk is one task, :func:`sample_chunk`: it builds (or reuses) the scene
in the process that runs it, samples the chunk's cells, writes them into the
store and returns a small record (checksum, NaN count). The in-process run
and a Dask run (``workers=`` / ``scheduler=``) execute the same task, so the
stored bytes are the same, and so is the signal for any chunking: a sample's
random numbers depend only on (seed, cell, sample index).

Integrity (issue 9): one writer per store (:class:`~sparselt.storage.StoreLock`);
a chunk is recorded in the journal only after it is durably written, and
re-checked against its CRC-32 on resume; the scene's identity (content of the
XML file and everything it references, or the description and generator code
of a built-in scene) is in the metadata and a resume with another identity is
refused; every limit is checked and the scene loaded before anything is
written or removed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import math
import os
import shutil
import time
from dataclasses import dataclass

import numpy as np

from ..checks import check_integer
from ..distributed import worker_deaths_reported
from ..measurement import available_memory, progress_bar
from ..provenance import environment_record, format_bytes
from ..signal import Signal, load_signal
from ..storage import zarr_store
from ..storage.errors import is_link_loop, os_error_hint, output_path_problem
from ..storage.folder import identity_differences, missing_folders, remove_empty_folders
from ..storage.lock import LOCK_FILE, StoreLock, check_unlocked
from ..storage.zarr_store import FORMAT, FORMAT_VERSION, ChunkGrid, ChunkJournal
from .identity import describe_scene_change
from .scenes import SCENES, SceneSpec
from .setup import DEFAULT_MAX_DEPTH, SceneSetup

DEFAULT_SPP = 64
LANES_PER_CHUNK = 1 << 22
MAXIMUM_SPP = 1 << 16
LANES_PER_LAUNCH = 1 << 32  # Dr.Jit's 32-bit lane indices: cells x spp of one launch stay below
# Default chunking of a cluster run: at least this many chunks per task slot. Chunks stay at most 4M samples, so
# only a signal of fewer than 4M samples per slot (a run of about a second) gets bigger chunks than 4M-sample ones
# would give; there each further chunk costs a task's round trip and a launch (4 per slot: +13-17% over the
# in-process run on a 4.2M-sample signal, 2: +9-11%, 1: +5-8%; issue 24).
CHUNKS_PER_WORKER = 1
MAXIMUM_AXES = 63  # NumPy arrays have at most 64 axes, one of them RGB
NONFINITE_POLICIES = ("error", "zero")

THESIS_PRESETS = {
    # thesis 5.3: 100x100 image plane, 4 in each of the 8 directional dimensions (6.6e8 cells)
    "path": (100, 100) + (4,) * 8,
    "path-indirect": (100, 100) + (4,) * 8,
    # thesis 7.1.2 and 7.2.1: 250x250 image plane, 16x16 lens or secondary direction
    "dof": (250, 250, 16, 16),
    "indirect": (250, 250, 16, 16),
}


class NonFiniteSampleError(RuntimeError):
    """The renderer returned NaN or infinite path contributions."""


@dataclass(frozen=True)
class AcquisitionConfig:
    """Everything that determines a signal; recorded in its store's metadata.

    Attributes
    ----------
    scene : str
        Built-in scene name or path of a Mitsuba 3 XML file.
    kind : str
        One of 'path', 'path-indirect', 'dof', 'indirect'.
    shape : tuple of int
        Resolution of each axis of the kind (image plane first).
    spp : int
        Jittered samples averaged per cell (thesis: 64).
    seed : int
        Seed in ``[0, 2**32)``; same seed, same signal.
    max_depth : int
        Longest path, Mitsuba's convention (thesis: 3).
    aperture, focus_distance : float or None
        Thin-lens override of the scene's camera.
    variant : str
        Mitsuba variant.
    nonfinite : {'error', 'zero'}
        What to do when a sample is NaN or infinite: stop with an error
        (default), or count it, record the count and use 0 in its place.
    scene_parameters : tuple of (str, str)
        Values of a scene file's ``$name`` parameters (``-D name=value``),
        sorted; part of the scene's identity.
    """

    scene: str
    kind: str
    shape: tuple
    spp: int = DEFAULT_SPP
    seed: int = 0
    max_depth: int = DEFAULT_MAX_DEPTH
    aperture: float | None = None
    focus_distance: float | None = None
    variant: str = "llvm_ad_rgb"
    nonfinite: str = "error"
    scene_parameters: tuple = ()

    def setup(self, scene_spec=None):
        """The :class:`~sparselt.rendering.setup.SceneSetup` of the signal (``scene_spec``: a programmatic scene)."""
        return SceneSetup(scene=self.scene, kind=self.kind, shape=self.shape, max_depth=self.max_depth,
                          parameters=self.scene_parameters, aperture=self.aperture,
                          focus_distance=self.focus_distance, variant=self.variant, scene_spec=scene_spec)

    def record(self):
        record = dataclasses.asdict(self)
        record["shape"] = list(self.shape)
        record["scene_parameters"] = [list(pair) for pair in self.scene_parameters]
        return record


def validate_config(config, chunk_cells=None):
    """Check a configuration (and a requested chunk size) without loading the renderer.

    Raises
    ------
    ValueError
        The first problem found, naming the bad value and what is allowed.
    """
    config.setup().check_values()  # kind, depth, variant, shape: the scene setup's one check
    check_integer("spp", config.spp, 1, MAXIMUM_SPP - 1)
    check_integer("seed", config.seed, 0, 2**32 - 1)
    if config.nonfinite not in NONFINITE_POLICIES:
        raise ValueError(f"nonfinite must be one of {NONFINITE_POLICIES}, got {config.nonfinite!r}")
    if len(config.shape) > MAXIMUM_AXES:
        raise ValueError(f"shape has {len(config.shape)} axes; at most {MAXIMUM_AXES} are supported "
                         f"(a path signal of max depth {config.max_depth} needs more: use max depth <= 16)")
    if chunk_cells is not None:
        check_integer("chunk_cells", chunk_cells, 1)
        if chunk_cells * config.spp >= LANES_PER_LAUNCH:
            raise ValueError(f"chunk_cells x spp = {chunk_cells} x {config.spp} = {chunk_cells * config.spp} samples in "
                             f"one launch; at most 2**32 - 1 are supported: use --chunk-cells <= "
                             f"{(LANES_PER_LAUNCH - 1) // config.spp}")


def _check_shape_matches(config, layout):
    if len(layout.axes) > MAXIMUM_AXES:
        raise ValueError(f"kind {config.kind!r} at max depth {config.max_depth} has {len(layout.axes)} axes; at most "
                         f"{MAXIMUM_AXES} are supported (use max depth <= 16)")


def signal_bytes(shape):
    """Bytes of a float32 RGB signal of this grid shape."""
    return math.prod(shape) * 3 * 4


@dataclass(frozen=True)
class ChunkJob:
    """One chunk to sample: everything a worker needs, as plain Python (picklable).

    ``scene`` is a built-in scene name (the worker builds it from its own
    registry, meshes included) or a :class:`SceneSpec`; ``store`` is the
    signal store, or ``None`` to return the values instead of writing them.
    """

    config: AcquisitionConfig
    scene: object
    grid: ChunkGrid
    index: int
    store: str | None = None
    concurrency: dict | None = None


_WORKER_SCENES = {}


def _scene_key(job):
    return (repr(job.scene), tuple(job.config.scene_parameters), job.config.aperture, job.config.focus_distance,
            tuple(job.config.shape[:2]), job.config.variant, job.config.kind, job.config.max_depth)


def _worker_scene(job):
    """The scene and layout of a job, built once per process."""
    key = _scene_key(job)
    if key not in _WORKER_SCENES:
        loaded = job.config.setup(None if isinstance(job.scene, str) else job.scene).load()
        _WORKER_SCENES.clear()  # one scene per worker process at a time
        _WORKER_SCENES[key] = (loaded.scene, loaded.layout)
    return _WORKER_SCENES[key]


def sample_chunk(job):
    """Sample one chunk (the task of every acquisition, in-process or on a Dask worker).

    Returns
    -------
    dict
        ``{"chunk", "crc32", "nonfinite"}``, plus ``"values"`` (shape
        ``(cells, 3)``) when ``job.store`` is ``None``.

    Raises
    ------
    NonFiniteSampleError
        NaN/infinite samples, or cell means overflowing float32, with
        ``nonfinite='error'``.
    DiskFullError
        The store's device is full.
    """
    from ..distributed import worker_thread_share
    from .mitsuba import set_thread_count

    threads = worker_thread_share(job.concurrency)
    if threads is not None:
        set_thread_count(threads)
    config = job.config
    scene, layout = _worker_scene(job)
    first, count, _ = job.grid.chunk(job.index)
    means, nonfinite = scene.sample_cells(layout, config.shape, first, count, config.spp, config.seed)
    overflow = ~np.all(np.isfinite(means), axis=1)  # finite samples whose float32 sum overflowed
    if overflow.any():
        cell = first + int(np.flatnonzero(overflow)[0])
        if config.nonfinite == "error":
            raise NonFiniteSampleError(
                f"{int(overflow.sum())} cell means overflow float32 in cells {first}..{first + count - 1} "
                f"(first at cell {cell}): the scene's radiance is too large to store (float32 holds up to "
                f"3.4e38); scale the emitters down, or rerun with --nonfinite zero to store 0 in those cells. "
                "Finished chunks are kept."
            )
        means[overflow] = 0.0
        nonfinite = nonfinite + overflow * config.spp
    bad = int(nonfinite.sum())
    if bad and config.nonfinite == "error":
        cell = first + int(np.flatnonzero(nonfinite)[0])
        raise NonFiniteSampleError(
            f"the renderer returned {bad} NaN or infinite samples in cells {first}..{first + count - 1} "
            f"(first at cell {cell}, grid index {tuple(int(i) for i in np.unravel_index(cell, config.shape))}); "
            "finished chunks are kept. Rerun with --nonfinite zero to count them and use 0 in their place."
        )
    record = {"chunk": job.index, "nonfinite": bad}
    if job.store is None:
        record.update(crc32=zarr_store.checksum(means), values=means)
    else:
        record["crc32"] = zarr_store.write_chunk(job.store, job.grid, job.index, means)
    return record


def acquire_signal(config, path=None, *, overwrite=False, progress=True, chunk_cells=None, scene_spec=None,
                   workers=None, scheduler=None, verify=False):
    """Sample a signal, in memory or into a resumable signal store.

    Parameters
    ----------
    config : AcquisitionConfig
        What to sample.
    path : str, optional
        Signal store (a folder). Without it the signal is kept in memory, which
        is refused when it would take more than half of the available RAM.
    overwrite : bool, optional
        Replace an existing complete signal, or an incomplete one of a
        different configuration or scene. The new signal is written beside
        the old one and takes its place only once complete, so the old one
        survives a failed run. An incomplete signal of the same configuration
        and scene is always resumed, and so is a complete one of the same
        configuration and scene with damaged chunks (they are sampled again).
        A complete one of the same configuration and scene, undamaged, is
        returned as it is (:func:`complete_signal`: only chunks whose files
        changed since they were written are read to tell). A folder holding
        files a signal store does not is refused, even with ``overwrite``.
    progress : bool, optional
        Show a progress bar (samples, rate, ETA) on standard error.
    chunk_cells : int, optional
        At most this many cells per chunk (default: about 4M samples per
        chunk, and at least one chunk per worker thread on a cluster). The
        data do not depend on it; a resumed run keeps the chunking
        it started with.
    scene_spec : SceneSpec, optional
        Use this scene description instead of resolving ``config.scene``.
    workers : int, optional
        Sample on a local Dask cluster of this many worker processes, at most
        ``os.cpu_count()``.
    scheduler : str, optional
        Sample on the existing Dask cluster of this scheduler; its workers
        must reach ``path`` (a shared file system).
    verify : bool, optional
        Check every chunk of a complete store against its CRC-32 (not only
        those whose files changed) and sample the damaged ones again.

    Returns
    -------
    Signal

    Raises
    ------
    ValueError
        Invalid configuration, shape not matching the kind, output folder
        in the way, scene changed since the signal was started, or not
        enough memory or disk.
    StoreLockedError
        Another run is writing this store (the message names it).
    NonFiniteSampleError
        NaN or infinite samples with ``nonfinite='error'``; finished chunks
        are kept and the run can be resumed.
    DiskFullError
        The disk filled during the run; finished chunks are kept and the run
        resumes once space is freed.
    """

    validate_config(config, chunk_cells)
    distributed = workers is not None or scheduler is not None
    if workers is not None and scheduler is not None:
        raise ValueError("give either workers (a local Dask cluster) or scheduler (an existing one), not both")
    if workers is not None:
        from ..distributed import check_worker_count

        check_worker_count(workers)  # before any cluster starts: more processes than cores would only hang
    if distributed and path is None:
        raise ValueError("a distributed acquisition writes into a store: give an output path")
    if scene_spec is not None and not isinstance(scene_spec, SceneSpec):
        raise TypeError(f"scene_spec must be a SceneSpec, got {type(scene_spec).__name__}")
    setup = config.setup(scene_spec)
    source = config.scene if scene_spec is None and config.scene in SCENES else setup.spec
    # Cheap checks first; the layout of a scene file needs its camera, hence the renderer (checked below).
    _check_shape_matches(config, setup.validate().layout(thin_lens=True))
    spec = setup.spec
    grid = _chunking(config, chunk_cells, parallelism=None)
    nbytes = signal_bytes(config.shape)
    if path is None:
        available = available_memory()
        if nbytes > available // 2:
            raise ValueError(
                f"a signal of shape {tuple(config.shape)} takes {format_bytes(nbytes)}, more than half of the "
                f"{format_bytes(available)} of available memory; give an output path to store it on disk"
            )
        identity = None
    else:
        if "://" in os.fspath(path):
            raise ValueError(f"output {os.fspath(path)!r}: only file-system paths are supported (a shared one for a "
                             "cluster); fsspec URLs are not, because the store's lock and journal need a file system")
        path = os.path.abspath(os.fspath(path))
        identity = setup.scene_identity
        check_unlocked(path)
        plan = _inspect_store(path, config, identity, overwrite=overwrite, verify=verify)
        if plan == "complete":
            signal = _settle_complete_store(path, config, identity, verify)
            if signal is not None:
                return signal
            plan = _inspect_store(path, config, identity, overwrite=overwrite, verify=verify)
        _check_disk_space(path, grid if plan not in ("resume", "repair") else None)  # again with the cluster's chunking

    # Loading the scene checks the file (syntax, sensor, references) before anything is written or removed.
    loaded = setup.load()
    scene, layout = loaded.scene, loaded.layout
    job = ChunkJob(config=config, scene=source, grid=grid, index=0)
    _WORKER_SCENES.clear()
    _WORKER_SCENES[_scene_key(job)] = (scene, layout)

    try:
        if path is None:
            return _acquire_in_memory(config, spec, scene, layout, job, progress)
        with contextlib.ExitStack() as stack:
            client = None
            if distributed:
                from ..distributed import dask_client, tasks_per_host

                client = stack.enter_context(dask_client(workers=workers, scheduler=scheduler))
                job = dataclasses.replace(job, concurrency=tasks_per_host(client))
                grid = _chunking(config, chunk_cells, parallelism=sum(job.concurrency.values()))
                job = dataclasses.replace(job, grid=grid)
                _check_disk_space(path, grid if plan not in ("resume", "repair") else None)
            return _acquire_into_store(path, config, spec, scene, layout, job, identity, overwrite, progress, client,
                                       verify)
    finally:
        _WORKER_SCENES.clear()  # the scene is not kept alive after the run


def _chunking(config, chunk_cells, *, parallelism):
    """The chunk grid: ``chunk_cells`` if given, else about 4M samples per chunk and, on a cluster of
    ``parallelism`` task slots, at least :data:`CHUNKS_PER_WORKER` chunks per slot."""
    target = chunk_cells or max(1, LANES_PER_CHUNK // config.spp)
    if chunk_cells is None and parallelism:
        target = min(target, max(1, -(-math.prod(config.shape) // (CHUNKS_PER_WORKER * parallelism))))
    return ChunkGrid.for_cells(config.shape, target)


def _acquire_into_store(path, config, spec, scene, layout, job, identity, overwrite, progress, client, verify=False):
    """Write (or resume, repair or replace) the store at ``path`` under its lock; return the loaded signal.

    A replacement ('replace') is written beside the old store, in the hidden
    sibling :func:`~sparselt.storage.zarr_store.sibling_path` ``(path, 'new')``,
    and exchanged with it only once complete, so the old signal survives a
    failed run; a run killed before the exchange leaves that sibling, which
    the next replacement of the same configuration resumes (any other run
    removes it). A damaged complete store ('repair') has just its damaged
    chunks sampled again, like a resume.
    """
    grid = job.grid
    recovered = zarr_store.recover_replacement(path)
    if recovered and progress:
        print(f"note: {recovered} ({path!r})")
    created = missing_folders(path)
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as error:
        raise ValueError(f"cannot create the output folder {path!r}: {os_error_hint(error, path)}; "
                         "choose another --out") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise PermissionError(f"output folder {path!r} is not writable")
    lock = StoreLock(path)
    try:
        lock.acquire()
    except BaseException:
        remove_empty_folders(created)  # the folders this run created, while empty (a failed lock leaves no file)
        raise
    staging = zarr_store.sibling_path(path, "new")
    staging_lock = None
    try:
        if lock.previous_holder:
            holder = lock.previous_holder
            print(f"note: took over the lock of a run that is gone (PID {holder.get('pid')} on {holder.get('host')})")
        plan = _inspect_store(path, config, identity, overwrite=overwrite, verify=verify)  # again, now it is ours
        if plan == "complete":  # another run finished it meanwhile
            return load_signal(path)
        target = path
        if plan == "replace":
            target = staging
            os.makedirs(staging, exist_ok=True)
            zarr_store.check_not_foreign(staging)
            staging_lock = StoreLock(staging)
            staging_lock.acquire()
            resumable = (zarr_store.store_status(staging) == "incomplete"
                         and _inspect_store(staging, config, identity, overwrite=True) == "resume")
            plan = "resume" if resumable else "new"
        elif os.path.isdir(staging) and not zarr_store.foreign_entries(staging):
            shutil.rmtree(staging)  # left by an interrupted replacement; this run does not need it
        journal = ChunkJournal(target)
        if plan == "repair":
            meta = zarr_store.read_attributes(target)
            grid = ChunkGrid(tuple(meta["shape"]), tuple(meta["chunk_shape"]))
            finished = _damaged_to_journal(target, grid, meta, journal, progress, verify)
        elif plan == "resume":
            meta = zarr_store.read_attributes(target)
            grid = ChunkGrid(tuple(meta["shape"]), tuple(meta["chunk_shape"]))
            finished = _verified_chunks(target, grid, journal, progress)
        else:
            zarr_store.remove_store(target)
            zarr_store.forget_open_arrays(target)
            meta = _meta(config, spec, scene, layout, identity, grid, status="incomplete")
            zarr_store.create_store(target, grid, layout.axes, meta)
            finished = {}
        job = dataclasses.replace(job, grid=grid, store=target)
        pending = [index for index in range(grid.count) if index not in finished]
        _run_chunks(job, pending, finished, journal, progress, client)
        _finish(target, grid, journal)
        if target != path:
            zarr_store.forget_open_arrays(target)
            zarr_store.replace_store(target, path)
        return load_signal(path)
    finally:
        zarr_store.forget_open_arrays(path)
        zarr_store.forget_open_arrays(staging)
        lock.release()
        if staging_lock is not None:
            staging_lock.release()


def _damaged_to_journal(path, grid, meta, journal, progress, verify=False):
    """Turn a complete store with damaged chunks back into an unfinished one whose journal lists the intact chunks.

    The store is marked incomplete first, so a run killed while repairing it
    resumes; the intact chunks keep their recorded checksums and NaN counts
    (``chunk_nonfinite``; a store written before it was recorded counts 0 for them).
    """
    try:
        checksums = zarr_store.recorded_checksums(path, meta, grid.count)
        # As the inspection found them: the chunks it read and found intact are not read again.
        damaged = set(_damaged_chunks_of_complete_store(path, meta, verify=verify))
    except zarr_store.CorruptSignalError:
        checksums, damaged = (), set(range(grid.count))  # nothing can be verified: every chunk is sampled again
    counts = meta.get("chunk_nonfinite")
    if not isinstance(counts, list) or len(counts) != grid.count:
        counts = [0] * grid.count
    records = {index: {"crc32": checksums[index], "nonfinite": int(counts[index]), "seconds": 0.0}
               for index in range(grid.count) if index not in damaged}
    if progress:
        print(f"note: {len(damaged)} of the {grid.count} chunks of the complete signal {path!r} are missing or damaged"
              f"{f' (first: chunk {min(damaged)})' if damaged else ''}; sampling them again")
    journal.rewrite(records)
    meta = {key: value for key, value in meta.items() if key not in ("chunk_crc32", "chunk_nonfinite", "chunk_files")}
    meta["status"] = "incomplete"
    zarr_store.write_attributes(path, meta)
    return records


def _acquire_in_memory(config, spec, scene, layout, job, progress):
    cells = math.prod(config.shape)
    data = np.empty((cells, 3), dtype=np.float32)
    bar = progress_bar(progress, total=cells * config.spp, description=f"{config.kind} {config.scene}", unit="sample")
    start = time.perf_counter()
    nonfinite = 0
    try:
        for index in range(job.grid.count):
            record = sample_chunk(dataclasses.replace(job, index=index))
            first, count, _ = job.grid.chunk(index)
            data[first:first + count] = record["values"]
            nonfinite += record["nonfinite"]
            if bar is not None:
                bar.update(count * config.spp)
    finally:
        if bar is not None:
            bar.close()
    if nonfinite:
        print(f"warning: {nonfinite} NaN or infinite samples counted and replaced by 0")
    meta = _meta(config, spec, scene, layout, None, job.grid, status="complete")
    meta.update(nonfinite_samples=nonfinite, sampling_seconds=time.perf_counter() - start)
    return Signal(data=data.reshape(tuple(config.shape) + (3,)), kind=config.kind, axes=layout.axes, meta=meta)


def _run_chunks(job, pending, finished, journal, progress, client):
    """Sample the pending chunks, recording each in the journal as it lands; return the seconds spent.

    Each journal record carries the seconds since the previous one landed (or
    the start), so the sampling time of a run that is killed is kept.
    """
    config, grid = job.config, job.grid
    cells = math.prod(config.shape)
    done_cells = sum(grid.chunk(index)[1] for index in finished)
    bar = progress_bar(progress, total=cells * config.spp, description=f"{config.kind} {config.scene}", unit="sample",
                       initial=done_cells * config.spp)
    start = time.perf_counter()
    last = [start]

    def land(record):
        now = time.perf_counter()
        record = dict(record, seconds=now - last[0])
        last[0] = now
        journal.append([record])
        finished[record["chunk"]] = record
        if bar is not None:
            bar.update(grid.chunk(record["chunk"])[1] * config.spp)

    try:
        if client is None:
            for index in pending:
                land(sample_chunk(dataclasses.replace(job, index=index)))
        else:
            _run_on_dask(client, job, pending, land)
    finally:
        if bar is not None:
            bar.close()
    return time.perf_counter() - start


def _run_on_dask(client, job, pending, land):
    from dask.distributed import as_completed

    # The renderer stays out of the task graph: the in-process scene is not sent, only the job.
    futures = [client.submit(sample_chunk, dataclasses.replace(job, index=index), pure=False,
                             key=f"sparselt-chunk-{index}-{os.getpid()}-{time.monotonic_ns()}") for index in pending]
    try:
        for future in as_completed(futures):
            with worker_deaths_reported("a chunk of samples"):
                result = future.result()
            land(result)
    except BaseException:
        client.cancel(futures)
        raise


def _finish(path, grid, journal):
    """Mark a store complete once every chunk is in: checksums and NaN counts into the metadata, journal removed.

    ``sampling_seconds`` becomes the total over every run that sampled chunks
    of this store (the journal's seconds added to those already recorded).
    """
    records = journal.read()
    zarr_store.remove_temporary_files(path)
    missing = [index for index in range(grid.count) if index not in records] or zarr_store.missing_chunks(path, grid)
    if missing:
        raise RuntimeError(f"internal error: chunks {missing[:5]} of {path!r} are not written; rerun to resume")
    nonfinite_total = int(sum(record["nonfinite"] for record in records.values()))
    if nonfinite_total:
        print(f"warning: {nonfinite_total} NaN or infinite samples counted and replaced by 0")
    meta = zarr_store.read_attributes(path)
    meta.update(status="complete", nonfinite_samples=nonfinite_total,
                chunk_crc32=[records[index]["crc32"] for index in range(grid.count)],
                chunk_nonfinite=[records[index]["nonfinite"] for index in range(grid.count)],
                chunk_files=zarr_store.chunk_signatures(path, grid))  # a rerun tells changed chunks by these
    meta["sampling_seconds"] = meta.get("sampling_seconds", 0.0) + sum(record["seconds"] for record in records.values())
    zarr_store.write_attributes(path, meta)
    journal.remove()


def _verified_chunks(path, grid, journal, progress):
    """Journal records whose chunk still matches its checksum; damaged ones are dropped (sampled again).

    The sampling seconds of dropped records stay counted in the metadata's ``sampling_seconds``.
    """
    records = journal.read()
    damaged = []
    for index, record in list(records.items()):
        if index >= grid.count:
            damaged.append(index)
            continue
        values = zarr_store.read_chunk(path, grid, index)
        if values is None or zarr_store.checksum(values) != record["crc32"]:
            damaged.append(index)
    lost_seconds = sum(records.pop(index)["seconds"] for index in damaged if index in records)
    if damaged:
        if progress:
            print(f"note: {len(damaged)} recorded chunks of {path!r} are missing or damaged "
                  f"(first: chunk {min(damaged)}); sampling them again")
        if lost_seconds:
            meta = zarr_store.read_attributes(path)
            meta["sampling_seconds"] = meta.get("sampling_seconds", 0.0) + lost_seconds
            zarr_store.write_attributes(path, meta)
        journal.rewrite(records)
    return records


def _check_disk_space(path, grid):
    """Refuse a new store larger than the free space: every chunk file rounded up to whole blocks."""
    if grid is None:
        return
    probe = path
    while not os.path.exists(probe):
        probe = os.path.dirname(probe)
    free = shutil.disk_usage(probe).free
    block = max(512, os.statvfs(probe).f_bsize)
    chunk_bytes = grid.cells_per_chunk * 3 * 4
    nbytes = grid.count * -(-chunk_bytes // block) * block + 4 * block  # uncompressed: an upper bound
    if nbytes > free:
        raise ValueError(f"the signal takes up to {format_bytes(nbytes)} but only {format_bytes(free)} of disk is free "
                         f"at {path!r}: free some space there, or choose another --out on a disk with room")


def _meta(config, spec, scene, layout, identity, grid, *, status):
    camera = scene.camera
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "status": status,
        "config": config.record(),
        "scene": spec.name,
        "scene_description": spec.description,
        "scene_identity": identity,
        "hide_emitters": spec.hide_emitters,
        "camera": {
            "fov": camera.fov,
            "fov_axis": camera.fov_axis,
            "aperture_radius": camera.aperture_radius,
            "focus_distance": camera.focus_distance,
            "to_world": [list(operation) for operation in camera.to_world.operations],
        },
        "kind": config.kind,
        "axes": list(layout.axes),
        "dimensions": list(layout.dimensions),
        "shape": list(config.shape),
        "chunk_shape": list(grid.chunk_shape),
        "chunk_count": grid.count,
        "chunk_cells": grid.cells_per_chunk,
        "spp": config.spp,
        "seed": config.seed,
        "max_depth": config.max_depth,
        "variant": config.variant,
        "dtype": "float32",
        "storage": {"format": "zarr", "zarr_format": 3, "compressor": f"zstd level {zarr_store.COMPRESSION_LEVEL}",
                    "checksum": "crc32 of each chunk's float32 C-order bytes"},
        "provenance": environment_record(),
    }


def _inspect_store(path, config, identity, *, overwrite, verify=False):
    """What to do with ``path``: 'new', 'resume', 'repair', 'replace' or 'complete' (the store's data are not
    changed here).

    'replace' (``overwrite``) writes the new store beside the old one and
    swaps them once it is complete; 'repair' samples again the damaged chunks
    of a complete store of this configuration and scene (missing, not
    decodable, or not matching their recorded CRC-32); 'complete' is such a
    store with none: nothing to do. Only the chunks whose files changed since
    the store recorded them are read to tell (every chunk with ``verify``).
    A folder holding anything a signal store does not is refused,
    ``overwrite`` or not. Refusals raise ValueError.
    """
    problem = output_path_problem(path)  # a link loop, a broken link, a file, a file in the way
    if problem:
        raise ValueError(f"output path {path!r} {problem}")
    if os.path.isdir(path):
        zarr_store.check_not_foreign(path)
    status = zarr_store.store_status(path)
    if status is None:
        entries = [name for name in os.listdir(path) if name != LOCK_FILE] if os.path.isdir(path) else []
        if zarr_store.GROUP_FILE in entries:
            raise ValueError(f"output folder {path!r} holds a Zarr group that is not a sparselt signal ('zarr.json'); "
                             "sparselt removes or replaces nothing there, --overwrite or not: choose another output "
                             "folder")
        if entries and not overwrite:
            raise ValueError(f"output folder {path!r} exists, is not empty and is not a signal; "
                             "pass --overwrite or choose another path")
        return "replace" if entries else "new"
    if status == "complete":
        if overwrite:
            return "replace"
        meta = zarr_store.read_attributes(path)
        _check_same_complete_signal(path, meta, config, identity)
        damaged = _damaged_chunks_of_complete_store(path, meta, verify=verify)
        if damaged is None:  # metadata this version cannot repair (reading the signal says what is wrong)
            raise ValueError(f"signal {path!r} already exists; pass --overwrite to replace it")
        if damaged:
            _record_nonfinite_policy(path, meta, config)
            return "repair"
        return "complete"
    if status == "legacy":
        if not overwrite:
            raise ValueError(f"{path!r} holds a signal in the old .npy folder format; pass --overwrite to replace it")
        return "replace"
    try:
        meta = zarr_store.read_attributes(path)
    except ValueError:
        if not overwrite:
            raise
        return "replace"
    if not _same_signal(meta.get("config") or {}, config.record()):
        if overwrite:
            return "replace"
        raise ValueError(f"{path!r} holds an unfinished signal of a different configuration; "
                         "pass --overwrite to replace it, or rerun its own command to resume it")
    recorded = (meta.get("scene_identity") or {}).get("digest")
    if recorded != identity["digest"]:
        if overwrite:
            return "replace"
        changed = describe_scene_change(meta.get("scene_identity") or {}, identity)
        raise ValueError(f"the scene of the unfinished signal {path!r} has changed since it was started"
                         f"{' (' + changed + ')' if changed else ''}; resuming would mix two scenes. "
                         "Restore the scene, or pass --overwrite to start again")
    _record_nonfinite_policy(path, meta, config)
    return "resume"


def _record_nonfinite_policy(path, meta, config):
    if meta["config"].get("nonfinite") != config.nonfinite:  # the NaN policy may change on resume
        meta["config"]["nonfinite"] = config.nonfinite
        zarr_store.write_attributes(path, meta)


def _check_same_complete_signal(path, meta, config, identity):
    """Refuse a complete store of another configuration or scene (``--overwrite`` replaces it), naming what
    differs."""
    recorded = {key: value for key, value in (meta.get("config") or {}).items() if key != "nonfinite"}
    requested = {key: value for key, value in config.record().items() if key != "nonfinite"}
    if recorded != requested:
        difference = identity_differences(recorded, requested)
        raise ValueError(f"signal {path!r} already exists with another configuration ({difference}); pass "
                         "--overwrite to replace it, or choose another --out")
    if (meta.get("scene_identity") or {}).get("digest") != identity["digest"]:
        changed = describe_scene_change(meta.get("scene_identity") or {}, identity)
        raise ValueError(f"signal {path!r} already exists, sampled from another version of the scene"
                         f"{' (' + changed + ')' if changed else ''}; pass --overwrite to replace it, or choose "
                         "another --out")


def _complete_grid(meta):
    """The chunk grid a complete store's metadata describe, or ``None`` when this version cannot use them."""
    shape, chunk_shape = meta.get("shape"), meta.get("chunk_shape")
    if meta.get("format_version") != FORMAT_VERSION or not all(
            isinstance(sizes, list) and sizes and all(type(size) is int and size > 0 for size in sizes)
            for sizes in (shape, chunk_shape)) or len(shape) != len(chunk_shape):
        return None
    return ChunkGrid(tuple(shape), tuple(chunk_shape))


def _damaged_chunks_of_complete_store(path, meta, *, verify=False):
    """Damaged chunks of a complete store (all of them when its checksums are unusable); ``None`` when its
    metadata do not describe a chunking this version can repair.

    Only the chunks whose files changed since the store recorded them
    (:func:`~sparselt.storage.zarr_store.changed_chunks`: size or
    modification time, or missing) are read and checked against their CRC-32,
    every chunk with ``verify`` or when the store recorded no signatures.
    """
    grid = _complete_grid(meta)
    if grid is None:
        return None
    try:
        checksums = zarr_store.recorded_checksums(path, meta, grid.count)
    except zarr_store.CorruptSignalError:
        return list(range(grid.count))
    signatures = zarr_store.chunk_signatures(path, grid)
    candidates = None if verify else zarr_store.changed_chunks(meta.get("chunk_files"), signatures)
    return zarr_store.damaged_chunks(path, grid, checksums, candidates)


def _settle_complete_store(path, config, identity, verify):
    """The loaded signal of a complete store of this configuration and scene with no damaged chunk (as
    :func:`_inspect_store` found it); ``None`` when it is not complete after all (it changed meanwhile: the caller
    samples as usual).

    Where chunk files changed but still match their CRC-32 (a store completed
    before signatures were recorded, or copied), their signatures are
    recorded anew under the store's lock, so the next rerun reads nothing; a
    store that cannot take the lock (read-only, a full disk) is used as it is.
    """
    meta = zarr_store.read_attributes(path)
    if meta.get("chunk_files") == zarr_store.chunk_signatures(path, _complete_grid(meta)):
        return load_signal(path)  # nothing to record: no lock, nothing written
    lock = StoreLock(path)
    try:
        lock.acquire()
    except (OSError, zarr_store.DiskFullError) as error:
        if isinstance(error, OSError) and error.errno not in (errno.EROFS, errno.EACCES, errno.EPERM):
            raise
        return load_signal(path)  # verified, but its signatures cannot be recorded here
    try:
        if _inspect_store(path, config, identity, overwrite=False, verify=verify) != "complete":
            return None
        meta = zarr_store.read_attributes(path)
        meta["chunk_files"] = zarr_store.chunk_signatures(path, _complete_grid(meta))
        zarr_store.write_attributes(path, meta)
    finally:
        lock.release()
    return load_signal(path)


def complete_signal(config, path, *, verify=False):
    """The signal at ``path`` if it is complete for ``config``: nothing to sample; else ``None``.

    Complete means: the store is marked complete, was sampled with this
    configuration (the NaN policy aside) from this scene, and none of its
    chunks is missing or damaged. Only the chunks whose files changed since
    they were written are read to tell (every chunk with ``verify``), so a
    rerun of a finished ``sparselt sample`` is immediate.

    Parameters
    ----------
    config : AcquisitionConfig
    path : str
        The signal store.
    verify : bool, optional
        Read every chunk and check it against its CRC-32 (damage the files'
        size and time do not show: a failing disk).

    Returns
    -------
    Signal or None
        ``None`` when there is something to do (no store, an unfinished or
        damaged one): :func:`acquire_signal` does it.

    Raises
    ------
    ValueError
        A complete store of another configuration or scene, or a folder
        that is not a signal store (as :func:`acquire_signal`).
    StoreLockedError
        Another run is writing the store.
    """
    validate_config(config)
    path = os.path.abspath(os.fspath(path))
    if zarr_store.store_status(path) != "complete" or is_link_loop(path):
        return None
    identity = config.setup().scene_identity
    check_unlocked(path)
    if _inspect_store(path, config, identity, overwrite=False, verify=verify) != "complete":
        return None
    return _settle_complete_store(path, config, identity, verify)


def _same_signal(recorded, requested):
    """Whether a recorded configuration is the requested one, the NaN policy aside (it may change on resume)."""
    ignore = ("nonfinite",)
    return ({k: v for k, v in recorded.items() if k not in ignore}
            == {k: v for k, v in requested.items() if k not in ignore})
