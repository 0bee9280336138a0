"""The comparison reference's passes: one verified file per 64-spp pass, rendered in-process or on Dask workers.

A reference (:func:`sparselt.rendering.baseline.cached_reference`) is the
mean of independent passes of Mitsuba's ``path`` integrator, each with its
own seed; its per-pixel variance comes from their spread (Jung et al. 2020;
thesis 8.1.1). This module keeps each pass as the truth of the cache: pass
``i`` of a reference folder is ``passes/{i:05d}.npy`` (its float64 mean
image, the subtracted depth already taken away) and ``passes/{i:05d}.json``
(its SHA-256, seed, render seconds and machine), the record written after
the image, both atomically. A pass is used only when its record is there and
the image's bytes match it; so a longer reference continues a shorter one,
and a killed run, in-process or on a cluster, loses at most the passes that
were in flight.

The Dask task (:func:`render_pass_task`) receives a plain-Python
:class:`PassJob` (the picklable :class:`~sparselt.rendering.setup.SceneSetup`,
never the Mitsuba scene), loads the scene once per worker process and sizes
Dr.Jit's thread pool to its share of the host, as the acquisition's chunk
tasks do (:mod:`sparselt.rendering.acquire`). Mitsuba's ``path`` integrator
was measured bit-deterministic for a fixed seed across processes and Dr.Jit
thread counts (1, 2, 3, 8 and 16 threads; three scenes, 24 to 128 pixels
wide): the film adds a pixel's 64 consecutive samples in one thread, in lane
order, whatever the pool's size. Hosts whose CPUs differ in SIMD width might
add them in another order (not measured); each pass records its machine.
"""

from __future__ import annotations

import datetime
import io
import os
import socket
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..digest import bytes_digest
from ..distributed import worker_deaths_reported
from ..provenance import atomic_write_bytes, read_json, write_json

#: The folder of a reference's cache entry that holds its passes.
PASS_FOLDER = "passes"


def pass_paths(folder, index):
    """``(image, record)`` paths of pass ``index`` in the reference folder ``folder``."""
    stem = os.path.join(folder, PASS_FOLDER, f"{index:05d}")
    return stem + ".npy", stem + ".json"


def render_pass(scene, pass_spp, depth, subtracted_depth, pass_seed):
    """One pass of the reference on a loaded scene: ``path`` at ``depth``, less ``subtracted_depth`` if given.

    Parameters
    ----------
    scene : MitsubaScene
        Anything with ``render_path(spp, max_depth, seed) -> (image, seconds)``.
    pass_spp, depth : int
    subtracted_depth : int or None
        Depth whose image is subtracted with the same seed (the indirect kinds).
    pass_seed : int
        Mitsuba's seed of the pass.

    Returns
    -------
    image : ndarray, shape (height, width, 3), float64
    seconds : float
        The renders' wall time.
    """
    image, seconds = scene.render_path(pass_spp, depth, pass_seed)
    pass_image = image.astype(np.float64)
    if subtracted_depth is not None:
        image, elapsed = scene.render_path(pass_spp, subtracted_depth, pass_seed)
        pass_image -= image.astype(np.float64)
        seconds += elapsed
    return pass_image, float(seconds)


def read_pass(folder, index, *, shape, seed, spp):
    """Pass ``index`` of a reference folder if it is complete and intact: ``(image, record)``, else None.

    A pass whose image has no record yet (a run killed between the two) is
    missing. One whose record is unreadable, or whose image does not match
    the record's SHA-256, shape, seed or spp, is not trusted: a note goes to
    standard error and None is returned, so that the pass is rendered again.
    """
    image_path, record_path = pass_paths(folder, index)
    if not os.path.isfile(record_path):
        return None
    try:
        record = read_json(record_path)
        if not isinstance(record, dict):
            raise ValueError(f"{record_path!r} does not hold a record")  # noqa: TRY004  (a garbled file)
        with open(image_path, "rb") as handle:
            data = handle.read()
        if bytes_digest(data) != record.get("sha256"):
            raise ValueError(f"{image_path!r} does not match the SHA-256 its record holds")
        if record.get("seed") != seed or record.get("spp") != spp:
            raise ValueError(f"{record_path!r} is of seed {record.get('seed')!r} at {record.get('spp')!r} spp, "
                             f"not seed {seed} at {spp} spp")
        image = np.load(io.BytesIO(data), allow_pickle=False)
        if image.dtype != np.float64 or image.shape != tuple(shape):
            raise ValueError(f"{image_path!r} holds a {image.dtype} array of shape {image.shape}, "
                             f"not float64 of shape {tuple(shape)}")
    except (OSError, ValueError, EOFError) as error:
        print(f"sparselt: note: reference pass {index} in {folder!r} is unreadable ({error}); rendering it again",
              file=sys.stderr)
        return None
    return image, record


def write_pass(folder, index, image, *, seed, spp, seconds, machine):
    """Store pass ``index``: its image, then its record (SHA-256, seed, spp, seconds, machine), each atomically.

    An older record of the pass is removed first, so that the pass is
    missing, not wrong, until the new record lands. Returns the record.
    """
    image_path, record_path = pass_paths(folder, index)
    os.makedirs(os.path.dirname(image_path), exist_ok=True)
    if os.path.lexists(record_path):
        os.remove(record_path)
    buffer = io.BytesIO()
    np.save(buffer, np.asarray(image, dtype=np.float64))
    data = buffer.getvalue()
    atomic_write_bytes(image_path, data)
    record = {"index": int(index), "seed": int(seed), "spp": int(spp), "sha256": bytes_digest(data),
              "seconds": float(seconds), "machine": str(machine),
              "finished": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
    write_json(record_path, record)
    return record


@dataclass(frozen=True)
class PassJob:
    """One pass to render on a Dask worker: everything it needs, as plain Python (picklable).

    ``scene_key`` identifies the loaded scene in the worker's cache (the
    setup's digest and the resolution, computed once by the caller);
    ``concurrency`` is :func:`sparselt.distributed.tasks_per_host`'s record.
    """

    setup: object
    resolution: tuple
    scene_key: str
    index: int
    pass_seed: int
    pass_spp: int
    depth: int
    subtracted_depth: int | None
    concurrency: dict | None = None


_WORKER_SCENES = {}


def _worker_scene(job):
    """The job's scene, loaded once per worker process (one scene at a time)."""
    if job.scene_key not in _WORKER_SCENES:
        scene = job.setup.load(tuple(job.resolution)).scene
        _WORKER_SCENES.clear()
        _WORKER_SCENES[job.scene_key] = scene
    return _WORKER_SCENES[job.scene_key]


def render_pass_task(job):
    """Render one pass on a worker (the Dask task): ``(index, image float64, seconds, hostname)``."""
    from ..distributed import worker_thread_share
    from .mitsuba import set_thread_count

    threads = worker_thread_share(job.concurrency)
    if threads is not None:
        set_thread_count(threads)
    image, seconds = render_pass(_worker_scene(job), job.pass_spp, job.depth, job.subtracted_depth, job.pass_seed)
    return job.index, image, seconds, socket.gethostname()


def render_passes(indices, *, scene, make_job, land, should_stop, client=None):
    """Render the passes ``indices`` (in order of submission), handing each to ``land`` as it completes.

    Parameters
    ----------
    indices : list of int
        The missing passes, in index order.
    scene : MitsubaScene
        The in-process scene (used when ``client`` is None).
    make_job : callable
        ``index -> PassJob``; in-process, only its seed, spp and depths are used.
    land : callable
        ``(index, image, seconds, machine) -> None``; writes the pass.
    should_stop : callable
        ``() -> bool``, asked before each new pass is started (the deadline).
    client : distributed.Client, optional
        Render on its workers, at most twice its threads' passes in flight at
        once; what is still in flight when ``should_stop`` says so, or when an
        error is raised, is cancelled.
    """
    if client is None:
        for index in indices:
            if should_stop():
                return
            job = make_job(index)
            image, seconds = render_pass(scene, job.pass_spp, job.depth, job.subtracted_depth, job.pass_seed)
            land(index, image, seconds, socket.gethostname())
        return
    from dask.distributed import as_completed

    if not indices or should_stop():
        return
    threads = sum(int(worker.get("nthreads", 1)) for worker in client.scheduler_info().get("workers", {}).values())
    waiting = list(indices)
    running = []

    def submit():
        index = waiting.pop(0)
        # The renderer stays out of the task graph: only the job travels. The key is unique per run, so a
        # cancelled pass of an earlier run is never mistaken for this one.
        future = client.submit(render_pass_task, make_job(index), pure=False,
                               key=f"sparselt-reference-pass-{index}-{os.getpid()}-{time.monotonic_ns()}")
        running.append(future)
        return future

    queue = as_completed([submit() for _ in range(min(len(waiting), 2 * max(threads, 1)))])
    try:
        for future in queue:
            running.remove(future)
            with worker_deaths_reported("a reference pass"):
                result = future.result()
            land(*result)
            if waiting and not should_stop():
                queue.add(submit())
            elif should_stop() and running:
                client.cancel(running)
                return
    except BaseException:
        client.cancel(running)
        raise
