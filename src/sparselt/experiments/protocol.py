"""One experiment protocol: an experiment declares what it does, one runner does the rest (issue 34).

An :class:`Experiment` declares

- its configuration (:meth:`Experiment.identity`, every default explicit, and
  the scene's content identity, :meth:`Experiment.scene_identity`), checked by
  :meth:`Experiment.validate` before any work;
- what it needs loaded once (:meth:`Experiment.prepare`: the scene in the
  renderer, a signal, a reference image), done after the folder was inspected
  and before anything in it changes;
- what it writes once the folder is open and before any cell
  (:meth:`Experiment.begin`: a configuration file that describes the run
  while it runs);
- its plan, the names of its resumable cells (:meth:`Experiment.plan`), and
  the work of one cell (:meth:`Experiment.run_cell`), which returns the
  cell's JSON record, or an :class:`Unfinished` one for an attempt a rerun
  should make again; :meth:`Experiment.cell_finished` hears of every cell in
  plan order (progress printed line by line);
- its report (:meth:`Experiment.report`), written from the cells' records.

:func:`run_experiment` owns the rest, the same way for every command: the
:class:`~sparselt.storage.folder.ExperimentFolder` life cycle (identity,
refusals, lock, manifest, atomic artefacts), resuming finished cells, the
record of timing repeats (:meth:`~sparselt.storage.folder.ExperimentFolder.record_repeat`;
an experiment that times its cells in rounds, ``compare``, schedules the
rounds in its own :meth:`Experiment.run_cells`), provenance (the folder's
history records every command) and progress.

Adding an experiment is one module with an :class:`Experiment` subclass and
its report; the CLI calls :func:`run_experiment`.
"""

from __future__ import annotations

import time

from ..measurement import progress_bar
from ..storage.folder import ExperimentFolder


class Unfinished:
    """What :meth:`Experiment.run_cell` returns for an attempt that is not kept: its record reaches
    :meth:`Experiment.report`, but the cell is not recorded, so a rerun runs it again.

    For outcomes that depend on this machine's state rather than on the
    experiment's identity: a measurement skipped because the memory it needs
    was not available, or one whose child process died.

    Parameters
    ----------
    record : dict
        The attempt's record, as :meth:`Experiment.report` receives it.
    """

    __slots__ = ("record",)

    def __init__(self, record):
        self.record = record

    def __repr__(self):
        return f"Unfinished({self.record!r})"


class Experiment:
    """Base class of experiments run by :func:`run_experiment`.

    Subclasses set :attr:`kind` (the folder's kind: the command's name) and
    implement :meth:`identity` and :meth:`report`; experiments with resumable
    work implement :meth:`plan` and :meth:`run_cell`.

    Attributes
    ----------
    kind : str
        The command writing the folder ('show', 'render', 'analyze', ...).
    growable : tuple of str
        Identity keys a rerun may extend (see :class:`~sparselt.storage.folder.ExperimentFolder`).
    cell_unit : str
        What one cell is, for the progress bar.
    """

    kind = ""
    growable = ()
    cell_unit = "cell"

    def identity(self):  # pragma: no cover - interface
        """Everything that determines the results, defaults explicit, JSON-able."""
        raise NotImplementedError

    def scene_identity(self):
        """The scene's content identity (a :class:`~sparselt.rendering.setup.SceneSetup`'s), or None."""
        return None

    def validate(self):
        """Every check that needs no renderer and no folder; raise ValueError/TypeError naming the bad value."""

    def prepare(self):
        """Load what every cell needs (the scene, a signal); runs after the folder is inspected, before it opens."""
        return None

    def begin(self, folder, state):
        """Write what describes the run while it runs (a configuration file), once the folder is open and before
        any cell; every run, resumed or not, writes it again (default: nothing)."""

    def plan(self):
        """The names of the resumable cells, in the order they run (default: none)."""
        return ()

    def run_cell(self, name, state, folder):  # pragma: no cover - interface
        """Do the work of cell ``name``; write its artefacts through ``folder``; return its JSON record."""
        raise NotImplementedError

    def run_cells(self, folder, state, *, progress):
        """Run every planned cell that is not done yet, in plan order, recording each as it finishes; return the
        records of every planned cell by name.

        The default schedule runs :meth:`plan`'s cells once each and hands the
        records to :meth:`report` as stored (read back from ``cells/``, so a
        fresh run and a resumed one report the same values); an
        :class:`Unfinished` outcome is handed on as returned and not recorded
        (the folder's ``attempted`` counts it).
        :meth:`cell_finished` hears of every planned cell, done earlier or
        now, in plan order. An experiment whose cells are timed several times
        overrides it to run them in rounds over every cell
        (:meth:`~sparselt.storage.folder.ExperimentFolder.record_repeat` keeps
        each repeat as it finishes); a cell enters ``cells/`` only when it is
        complete.
        """
        names = list(self.plan())
        if len(set(names)) != len(names):
            raise ValueError(f"internal error: experiment {self.kind!r} plans a cell twice: {names}")
        records = {name: folder.cell(name) for name in names}
        missing = [name for name in names if records[name] is None]
        bar = progress_bar(progress and len(missing) > 1, total=len(names), initial=len(names) - len(missing),
                           description=self.kind, unit=self.cell_unit)
        for name in names:
            resumed = records[name] is not None
            if not resumed:
                if bar is not None:
                    bar.set_postfix_str(name)
                outcome = self.run_cell(name, state, folder)
                if isinstance(outcome, Unfinished):
                    records[name] = outcome.record
                    folder.attempted += 1
                else:
                    folder.record_cell(name, outcome)
                    records[name] = folder.cell(name)
                if bar is not None:
                    bar.update(1)
            self.cell_finished(name, records[name], resumed=resumed)
        if bar is not None:
            bar.close()
        return records

    def cell_finished(self, name, record, *, resumed):
        """Hear that cell ``name`` is finished with ``record`` (``resumed``: an earlier run recorded it), for
        every planned cell in plan order; an experiment printing its progress line by line prints here (default:
        nothing)."""

    def report(self, folder, state, records):  # pragma: no cover - interface
        """Write the report from the cells' ``records`` (by name); return what the command returns."""
        raise NotImplementedError

    def summary(self, result):
        """What the folder's history records of this command when it completes (JSON-able; default: its
        ``seconds``, which an experiment may replace by its own breakdown)."""
        return {}


def experiment_folder(experiment, out, *, overwrite=False):
    """The :class:`~sparselt.storage.folder.ExperimentFolder` of ``experiment`` at ``out``."""
    return ExperimentFolder(out, kind=experiment.kind, identity=experiment.identity(),
                            scene=experiment.scene_identity(), overwrite=overwrite, growable=experiment.growable)


def run_experiment(experiment, out, *, overwrite=False, progress=True):
    """Run ``experiment`` into folder ``out``: validate, inspect, prepare, open, begin, run the cells not yet
    done, report.

    Parameters
    ----------
    experiment : Experiment
    out : str or os.PathLike
        Output folder. A folder holding the same experiment resumes (its
        finished cells are kept); one holding another is refused unless
        ``overwrite``; one holding files sparselt did not write is refused.
    overwrite : bool, optional
        Replace a folder of another identity: only the files its manifest
        lists, and only after the configuration is validated and
        :meth:`Experiment.prepare` succeeded.
    progress : bool, optional
        A progress bar over the cells on standard error.

    Returns
    -------
    object
        What :meth:`Experiment.report` returns.

    A rerun of a complete folder with nothing new to run says so on
    standard output (and exits 0 from the CLI, like every rerun).

    Raises
    ------
    ValueError
        A configuration the experiment refuses, or a folder that cannot take
        this run (:class:`~sparselt.storage.folder.FolderError`); nothing is
        changed on disk.
    StoreLockedError
        Another run is writing the folder.
    """
    started = time.perf_counter()
    experiment.validate()
    folder = experiment_folder(experiment, out, overwrite=overwrite)
    plan = folder.inspect()  # refusals before any expensive work; nothing is changed yet
    was_complete = plan == "resume" and folder.status == "complete"
    state = experiment.prepare()
    with folder.open():
        experiment.begin(folder, state)
        records = experiment.run_cells(folder, state, progress=progress)
        result = experiment.report(folder, state, records)
        folder.complete(**dict({"seconds": time.perf_counter() - started}, **experiment.summary(result)))
    if was_complete and not folder.recorded and not folder.attempted:
        print(f"{experiment.kind}: {folder.path} is complete: an earlier run of the same command did every cell, "
              "none was run again (the report was written again)")
    return result


__all__ = ["Experiment", "Unfinished", "experiment_folder", "run_experiment"]
