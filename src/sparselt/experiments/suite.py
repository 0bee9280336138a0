"""``sparselt suite``: every method over a suite of scenes, one equal-time comparison per scene (issue 36).

A suite is an experiment of the protocol (:mod:`sparselt.experiments.protocol`)
whose cells are comparisons: scene ``NAME``'s is a complete ``sparselt
compare`` folder, ``scenes/NAME``, run with the suite's methods, budgets,
seeds and reference settings (:class:`~sparselt.experiments.suite_config.SuiteConfig`).
The report aggregates them (:mod:`sparselt.experiments.suite_aggregate`).

Output folder::

    sparselt-folder.json   the manifest (identity: the suite's configuration and every scene's content digest)
    suite.json             configuration, per scene its machine, seconds and reference, the bootstrap's settings
    suite.csv              compare's summary columns of every scene, with ``scene``, ``kind`` and ``machine``
    aggregate.csv, .md     per (method, spp): geometric means over scenes with 95% bootstrap intervals, verdict
                           counts, the worst scene
    speedups.png           every (scene, method, spp)'s equal-quality speed-up, one colour scale
    index.html             the tables, per scene an interactive viewer (reference and every method at matched
                           time, slider, zoom, exposure, error view) and a link to the scene's own report
    viewer/NAME/           the viewer's images: matched-time images and per-pixel error maps (PNG)
    scenes/NAME/           each scene's comparison folder (resumable on its own)
    references/            the references' 64-spp passes (cached, resumable; on the suite's file system, so
                           that every worker of a cluster sees them)

Each scene's comparison runs in a child process
(:func:`~sparselt.experiments.isolation.run_in_child`): a crash in native code
there (a segmentation fault in the renderer) ends that scene's comparison
only; the scene is reported as not compared, with how its process ended, and
is not recorded, so a rerun of the same command tries it again (its
comparison folder resumes). A scene whose comparison raises ``ValueError``
(media, a black reference, an image without noise) is recorded as not
compared, and a rerun says the same.

On a Dask cluster (``scheduler``), the references render first, their passes
spread over every worker; then each scene's comparison runs as one task on a
worker that holds a whole machine (the worker resource ``machine``, so no
other task shares it while it is timed), in a child process of that worker,
and the machine is recorded per scene.
"""

from __future__ import annotations

import hashlib
import os
import socket
import sys
import time

from ..distributed import WorkerDied, worker_deaths_reported
from ..provenance import environment_record
from .compare import compare
from .isolation import ChildCrashed, describe_exit, exit_cause, load_importable_plugins, run_in_child
from .protocol import Experiment, Unfinished, run_experiment
from .suite_config import validate_suite

SUITE_KIND = "suite"
SUITE_FILE = "suite.json"
SCENES = "scenes"
REFERENCES = "references"
#: The Dask worker resource a scene's comparison holds: one per machine (``dask worker --resources machine=1``).
MACHINE_RESOURCE = "machine"


def machine_record(threads=None):
    """Where a scene's timings come from: host name, processor count and the threads the renderer used."""
    return {"host": socket.gethostname(), "cpus": os.cpu_count(), "threads": threads}


def run_scene(comparison, out, cache_directory, *, progress=False, threads=None):
    """Run one scene's comparison into ``out``; return its suite record (machine, seconds, reference).

    Runs in-process, or on a Dask worker (:func:`scene_task`).
    """
    started = time.perf_counter()
    result = compare(comparison, out, progress=progress, cache_directory=cache_directory)
    if threads is None:
        from ..rendering.mitsuba import thread_count

        threads = thread_count()
    return {"machine": machine_record(threads), "seconds": time.perf_counter() - started,
            "compare_seconds": result.seconds, "reference": {key: result.reference.get(key) for key in (
                "spp", "floor", "floor_trimmed", "passes", "met") if key in result.reference}}


def scene_task(comparison, out, cache_directory, plugins=()):
    """A scene's comparison as a Dask task: in a child process of the worker (a crash there is a
    :class:`~sparselt.experiments.isolation.ChildCrashed` for this scene, the worker lives on), with the
    renderer's and numba's threads set to the worker's own and the client's plug-in modules imported (they must be
    importable on the worker)."""
    from dask.distributed import get_worker

    load_importable_plugins(plugins)
    threads = int(get_worker().state.nthreads)
    return run_in_child(run_scene, comparison, out, cache_directory, threads=threads, child_threads=threads)


class SuiteExperiment(Experiment):
    """The suite as an experiment: one cell per scene (its comparison), the aggregate as report.

    Parameters
    ----------
    config : SuiteConfig
    scheduler : str, optional
        A Dask scheduler's address (see the module docstring).
    """

    kind = SUITE_KIND
    cell_unit = "scene"

    def __init__(self, config, *, scheduler=None):
        self.config = config
        self.scheduler = scheduler
        self.comparisons = {scene.name: config.comparison(scene) for scene in config.scenes}
        self.setups = {}
        self.progress = True
        self.started = time.perf_counter()

    def identity(self):
        record = self.config.record()
        record.pop("source")  # the same suite read from another path is the same suite
        return record

    def scene_identity(self):
        """Every scene's content identity, and one digest of them all: a scene file changed since is another
        suite (the message names its files)."""
        identities = {name: setup.scene_identity for name, setup in self.setups.items()}
        files = {f"{name}: {file}": digest for name, identity in identities.items()
                 for file, digest in (identity.get("files") or {}).items()}
        text = "\n".join(f"{name} {identity['digest']}" for name, identity in identities.items())
        return {"digest": hashlib.sha256(text.encode()).hexdigest(), "files": files, "scenes": identities}

    def validate(self):
        self.setups = validate_suite(self.config)

    def plan(self):
        return [scene.name for scene in self.config.scenes]

    def begin(self, folder, state):
        folder.claim_folder(SCENES)
        folder.claim_folder(REFERENCES)
        folder.write_json(SUITE_FILE, {"config": self.config.record(), "status": "running",
                                       "provenance": environment_record()})

    def run_cell(self, name, state, folder):
        if self.progress:
            print(f"suite: scene {name} ({self.comparisons[name].kind})", file=sys.stderr)
        try:  # in a child process: a crash in native code ends that scene's comparison, not the suite
            record = run_in_child(run_scene, self.comparisons[name], folder.path_of(f"{SCENES}/{name}"),
                                  folder.path_of(REFERENCES), progress=self.progress)
        except ValueError as error:  # recorded: the suite goes on, and says so at the end
            print(f"suite: scene {name} cannot be compared: {error}", file=sys.stderr)
            return _not_compared(name, error)
        except ChildCrashed as crash:  # not recorded: a rerun tries again
            record = _crashed(name, crash)
            print(f"suite: scene {name} cannot be compared: {record[NOT_COMPARED]}", file=sys.stderr)
            return Unfinished(record)
        return dict(record, scene=name)

    def run_cells(self, folder, state, *, progress):
        self.progress = progress
        if self.scheduler is None:
            return super().run_cells(folder, state, progress=progress)
        return self._run_on_cluster(folder, progress)

    def _run_on_cluster(self, folder, progress):
        """References across the cluster, then each scene's comparison on one whole machine."""
        from dask.distributed import as_completed
        from ..distributed import dask_client
        from ..methods import plugin_modules
        from .comparison_reference import ComparisonReference

        names = self.plan()
        records = {name: folder.cell(name) for name in names}
        missing = [name for name in names if records[name] is None]
        say = (lambda text: print(text, file=sys.stderr)) if progress else (lambda text: None)
        with dask_client(scheduler=self.scheduler, say=say) as client:
            workers = client.scheduler_info().get("workers", {})
            machines = [address for address, worker in workers.items()
                        if (worker.get("resources") or {}).get(MACHINE_RESOURCE, 0) >= 1]
            if not machines:
                raise RuntimeError(f"no worker of the Dask cluster at {self.scheduler!r} holds the resource "
                                   f"{MACHINE_RESOURCE!r}: start one worker per machine with 'dask worker "
                                   f"{self.scheduler} --resources {MACHINE_RESOURCE}=1 --nthreads N' (N its cores)")
            for name in list(missing):  # every worker renders the references' passes (same bytes as in-process)
                comparison = self.comparisons[name]
                say(f"suite: reference of {name} on the cluster")
                try:
                    loaded = self.setups[name].load(comparison.output_resolution).scene
                    ComparisonReference(comparison, self.setups[name], cache_directory=folder.path_of(REFERENCES),
                                        scheduler=self.scheduler).start(loaded, progress)
                except ValueError as error:  # e.g. a black reference: the scene's, as in its comparison
                    records[name] = _not_compared(name, error)
                    folder.record_cell(name, records[name])
                except WorkerDied as crash:  # a pass's worker died every time it was tried: the rest go on
                    records[name] = _crashed(name, crash)
                    folder.attempted += 1  # not recorded: a rerun tries again, from the passes that landed
                else:
                    continue
                missing.remove(name)
                say(f"suite: scene {name} cannot be compared: {records[name][NOT_COMPARED]}")
            futures = {}
            for name in missing:
                future = client.submit(scene_task, self.comparisons[name], folder.path_of(f"{SCENES}/{name}"),
                                       folder.path_of(REFERENCES), plugin_modules(), resources={MACHINE_RESOURCE: 1},
                                       pure=False, key=f"sparselt-suite-{name}-{os.getpid()}-{time.monotonic_ns()}")
                futures[future] = name
            for future in as_completed(list(futures)):
                name = futures[future]
                try:
                    with worker_deaths_reported("its comparison"):
                        record = dict(future.result(), scene=name)
                except ValueError as error:
                    record = _not_compared(name, error)
                except (ChildCrashed, WorkerDied) as crash:
                    record = _crashed(name, crash)
                if CRASHED in record:
                    records[name] = record  # not recorded: a rerun tries again
                    folder.attempted += 1
                else:
                    folder.record_cell(name, record)
                    records[name] = folder.cell(name)
                if NOT_COMPARED in record:
                    say(f"suite: scene {name} cannot be compared: {record[NOT_COMPARED]}")
                else:
                    say(f"suite: scene {name} done on {record['machine']['host']} in {record['seconds']:.0f} s")
        for name in names:
            self.cell_finished(name, records[name], resumed=name not in missing)
        return records

    def report(self, folder, state, records):
        from .suite_report import write_suite_outputs

        unfinished = [name for name, record in records.items() if record is None or isinstance(record, Unfinished)]
        if unfinished:
            raise RuntimeError(f"internal error: scenes {unfinished} did not finish")
        not_compared = {name: record[NOT_COMPARED] for name, record in records.items() if NOT_COMPARED in record}
        if len(not_compared) == len(records):
            raise ValueError("no scene of the suite could be compared: " + "; ".join(
                f"scene {name!r}: {message}" for name, message in not_compared.items()))
        return write_suite_outputs(folder, self.config, records, seconds=time.perf_counter() - self.started,
                                   not_compared=not_compared,
                                   crashed=[name for name, record in records.items() if CRASHED in record])


#: A scene's cell record key holding why its comparison could not be made (its message).
NOT_COMPARED = "not_compared"


#: A crashed scene's record key: how its process ended (such a record is not kept: a rerun tries the scene again).
CRASHED = "crashed"


def _crashed(name, crash):
    """The record of scene ``name`` whose comparison's process died (``crash``: a
    :class:`~sparselt.experiments.isolation.ChildCrashed`, or a :class:`~sparselt.distributed.WorkerDied` for a
    Dask worker that died every time it ran the scene's comparison or a pass of its reference)."""
    if isinstance(crash, ChildCrashed):
        how = describe_exit(crash.returncode)
        cause = exit_cause(crash.returncode)
        text = f"its comparison's process ended with {how}" + (f": {cause}" if cause else " and no result")
    else:
        how = "worker died"
        text = str(crash)
    return {"scene": name, NOT_COMPARED: f"{text}; not recorded: a rerun of the same command tries this scene "
            "again, resuming its comparison from what it finished", CRASHED: how}


def _not_compared(name, error):
    """The cell record of scene ``name`` whose comparison raised ``error`` (a ``ValueError``: its scene, kind or
    settings make it impossible, e.g. participating media, a black reference, an image without noise)."""
    return {"scene": name, NOT_COMPARED: str(error)}


def run_suite(config, out, *, overwrite=False, progress=True, scheduler=None):
    """Run suite ``config`` into folder ``out`` (see the module docstring); a rerun resumes.

    Parameters
    ----------
    config : SuiteConfig
    out : str or os.PathLike
    overwrite : bool
        Replace a folder holding another run (only files its manifest lists).
    progress : bool
        Progress on standard error.
    scheduler : str, optional
        A Dask scheduler's address.

    Returns
    -------
    SuiteResult
        (:func:`sparselt.experiments.suite_report.write_suite_outputs`).

    Raises
    ------
    ValueError
        A comparison a scene's settings make impossible (nothing has run), an
        output folder holding another run or foreign files.
    """
    return run_experiment(SuiteExperiment(config, scheduler=scheduler), out, overwrite=overwrite, progress=progress)
