"""Running work on a Dask cluster: a local one of N worker processes, or an existing one.

The renderer is never sent over the wire: a task receives a plain-Python job
(scene name or :class:`~sparselt.rendering.scenes.SceneSpec`, configuration,
chunk), builds the Mitsuba scene inside its worker (cached per worker
process) and sizes Dr.Jit's thread pool to its share of the machine's cores,
so that N workers on one machine do not oversubscribe it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import socket
from urllib.parse import urlparse

from .checks import check_integer


class WorkerDied(RuntimeError):
    """A task's worker died every time the task was tried (Dask's ``KilledWorker``: a segmentation fault in the
    renderer, or the system killing the worker for its memory). What had landed is kept; the message says so."""


@contextlib.contextmanager
def worker_deaths_reported(what):
    """Turn Dask's ``KilledWorker`` raised inside the block into :class:`WorkerDied`, naming ``what`` was running
    (e.g. "a reference pass") and that a rerun resumes from what landed: a clear error (exit 2) at the command line
    instead of Dask's traceback."""
    from distributed import KilledWorker

    try:
        yield
    except KilledWorker as error:
        raise WorkerDied(f"the Dask worker running {what} died every time it was tried (a crash in native code, or "
                         f"killed for its memory: see the worker's log); what finished is kept, and a rerun of the "
                         f"same command resumes from it ({error})") from error


#: Environment variable that fixes Dr.Jit's threads per task on the workers (overrides the per-host share).
WORKER_THREADS_VARIABLE = "SPARSELT_WORKER_THREADS"


def check_worker_count(workers):
    """``workers`` as an int in ``[1, os.cpu_count()]``: a local cluster runs one process per worker.

    More worker processes than the machine has cores only compete for them
    (and past a few hundred the cluster never finishes starting), so they
    are refused before anything starts.

    Raises
    ------
    TypeError
        Not an integer.
    ValueError
        Below 1 or above the machine's cores; the message names both.
    """
    cores = os.cpu_count() or 1
    workers = check_integer("workers", workers, 1)
    if workers > cores:
        raise ValueError(f"workers must be at most {cores}, the CPU cores of this machine (a local Dask cluster runs "
                         f"one single-threaded process per worker), got {workers}; for more, start a cluster across "
                         "machines and pass its --scheduler")
    return workers


def _host_of(address):
    return urlparse(address).hostname or address


@contextlib.contextmanager
def dask_client(*, workers=None, scheduler=None, say=print):
    """A ``dask.distributed`` client: a new local cluster of ``workers`` processes, or ``scheduler``'s.

    Parameters
    ----------
    workers : int, optional
        Start a ``LocalCluster`` of this many single-threaded worker processes,
        at most ``os.cpu_count()`` (:func:`check_worker_count`).
    scheduler : str, optional
        Address of an existing scheduler (``tcp://host:8786``).
    say : callable
        Where the dashboard address is printed.

    Yields
    ------
    distributed.Client
    """
    if (workers is None) == (scheduler is None):
        raise ValueError("give exactly one of workers (a local cluster) and scheduler (an existing cluster)")
    from dask.distributed import Client, LocalCluster

    cluster = None
    if scheduler is None:
        check_worker_count(workers)
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR)
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as error:
            raise RuntimeError(f"cannot reach the Dask scheduler at {scheduler!r} ({error})") from None
    try:
        link = client.dashboard_link
        say(f"Dask: {len(client.scheduler_info().get('workers', {}))} workers, dashboard at {link}")
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def tasks_per_host(client):
    """How many tasks run at once on each worker host (its workers' threads added up)."""
    counts = {}
    for address, worker in client.scheduler_info().get("workers", {}).items():
        host = _host_of(address)
        counts[host] = counts.get(host, 0) + int(worker.get("nthreads", 1))
    return counts


def worker_thread_share(concurrency):
    """Dr.Jit threads for a task running in this worker: the host's cores over the tasks it runs at once.

    ``concurrency`` is :func:`tasks_per_host`'s record; outside a Dask worker
    the answer is ``None`` (keep the default pool).
    """
    if not concurrency:
        return None
    if os.environ.get(WORKER_THREADS_VARIABLE):
        return check_integer(WORKER_THREADS_VARIABLE, int(os.environ[WORKER_THREADS_VARIABLE]), 1)
    try:
        from distributed import get_worker

        host = _host_of(get_worker().address)
    except (ImportError, ValueError):
        return None
    tasks = concurrency.get(host) or concurrency.get(socket.gethostname()) or 1
    return max(1, (os.cpu_count() or 1) // tasks)
