"""The experiment protocol (issue 34): one runner owns the folder life cycle of every experiment.

A small pure-Python experiment (no rendering) drives :func:`run_experiment`: cells run once and resume, an
interrupted run keeps its finished cells, refusals come before any work, overwrite removes only what the manifest
lists, and the manifest ends complete with the experiment's summary.
"""

import json

import pytest

from sparselt.experiments.protocol import Experiment, Unfinished, run_experiment
from sparselt.storage.folder import MANIFEST_FILE, FolderError
from sparselt.storage.lock import LOCK_FILE


class Interrupted(Exception):
    """Stands for a kill in the middle of a cell."""


class Counting(Experiment):
    """Cells named by ``names``; each writes ``<name>.txt`` and records its value; the report writes
    ``report.json`` from the records. ``log`` is every call the runner made, in order."""

    kind = "counting"

    def __init__(self, names=("a", "b", "c"), *, value=1, fail_at=None, unfinished=(), fail_prepare=False):
        self.names, self.value, self.fail_at = tuple(names), value, fail_at
        self.unfinished, self.fail_prepare = tuple(unfinished), fail_prepare
        self.log, self.reported = [], None

    def validate(self):
        self.log.append("validate")
        if self.value < 0:
            raise ValueError(f"value must be at least 0, got {self.value}")

    def identity(self):
        return {"names": list(self.names), "value": self.value}

    def prepare(self):
        self.log.append("prepare")
        if self.fail_prepare:
            raise RuntimeError("the scene did not load")
        return {"offset": 10}

    def begin(self, folder, state):
        self.log.append("begin")
        folder.write_json("config.json", {"value": self.value})

    def plan(self):
        return self.names

    def run_cell(self, name, state, folder):
        self.log.append(f"run {name}")
        if name == self.fail_at:
            raise Interrupted(name)
        folder.write_text(f"{name}.txt", f"{name} {self.value}\n")
        record = {"name": name, "value": self.value + state["offset"], "pair": (1, 2)}
        return Unfinished(record) if name in self.unfinished else record

    def cell_finished(self, name, record, *, resumed):
        self.log.append(f"finished {name}" + (" (resumed)" if resumed else ""))

    def report(self, folder, state, records):
        self.log.append("report")
        self.reported = records
        folder.write_json("report.json", records)
        return sorted(records)

    def summary(self, result):
        return {"cells": len(result)}


def _manifest(out):
    return json.loads((out / MANIFEST_FILE).read_text())


def _stamps(out):
    return {path.relative_to(out).as_posix(): path.stat().st_mtime_ns for path in out.rglob("*") if path.is_file()
            and path.name != MANIFEST_FILE}


def test_cells_run_once_and_a_second_run_runs_none(tmp_path):
    out = tmp_path / "run"
    first = Counting()
    assert run_experiment(first, out, progress=False) == ["a", "b", "c"]
    assert first.log == ["validate", "prepare", "begin", "run a", "finished a", "run b", "finished b", "run c",
                         "finished c", "report"]
    cells = {name: (out / "cells" / f"{name}.json").stat().st_mtime_ns for name in "abc"}

    again = Counting()
    run_experiment(again, out, progress=False)
    assert [entry for entry in again.log if entry.startswith("run ")] == []
    assert [entry for entry in again.log if entry.startswith("finished ")] == [
        "finished a (resumed)", "finished b (resumed)", "finished c (resumed)"]
    assert "begin" in again.log  # the run's description is written by every run
    assert {name: (out / "cells" / f"{name}.json").stat().st_mtime_ns for name in "abc"} == cells
    assert [entry["plan"] for entry in _manifest(out)["history"]] == ["new", "resume"]


def test_an_interrupted_run_keeps_its_finished_cells_and_a_rerun_completes(tmp_path):
    out = tmp_path / "run"
    with pytest.raises(Interrupted):
        run_experiment(Counting(fail_at="b"), out, progress=False)
    assert sorted(path.name for path in (out / "cells").iterdir()) == ["a.json"]
    assert _manifest(out)["status"] == "running" and not (out / "report.json").exists()
    stamp = (out / "cells" / "a.json").stat().st_mtime_ns

    rerun = Counting()  # the lock was released: the rerun takes the folder
    run_experiment(rerun, out, progress=False)
    assert [entry for entry in rerun.log if entry.startswith("run ")] == ["run b", "run c"]
    assert (out / "cells" / "a.json").stat().st_mtime_ns == stamp
    assert _manifest(out)["status"] == "complete"


def test_the_report_gets_every_record_as_stored_whether_resumed_or_run_now(tmp_path):
    out = tmp_path / "run"
    with pytest.raises(Interrupted):
        run_experiment(Counting(fail_at="c"), out, progress=False)
    rerun = Counting()
    run_experiment(rerun, out, progress=False)
    assert list(rerun.reported) == ["a", "b", "c"]  # plan order
    assert rerun.reported == {name: {"name": name, "value": 11, "pair": [1, 2]} for name in "abc"}  # JSON, as stored
    assert json.loads((out / "report.json").read_text()) == rerun.reported


def test_another_identity_is_refused_before_any_work_and_nothing_changes(tmp_path):
    out = tmp_path / "run"
    run_experiment(Counting(), out, progress=False)
    stamps, manifest = _stamps(out), _manifest(out)
    other = Counting(value=2)
    with pytest.raises(FolderError, match="another counting run.*value: 1 recorded, 2 now.*--overwrite"):
        run_experiment(other, out, progress=False)
    assert other.log == ["validate"]  # refused before prepare: no expensive work
    assert _stamps(out) == stamps and _manifest(out) == manifest


def test_overwrite_replaces_only_the_listed_files_and_only_once_prepare_succeeded(tmp_path):
    out = tmp_path / "run"
    run_experiment(Counting(), out, progress=False)
    stamps = _stamps(out)
    with pytest.raises(RuntimeError, match="did not load"):
        run_experiment(Counting(value=2, fail_prepare=True), out, overwrite=True, progress=False)
    assert _stamps(out) == stamps and _manifest(out)["identity"]["value"] == 1  # the old run is intact

    run_experiment(Counting(names=("a",), value=2), out, overwrite=True, progress=False)
    manifest = _manifest(out)
    assert manifest["identity"] == {"names": ["a"], "value": 2} and manifest["status"] == "complete"
    assert sorted(manifest["files"]) == ["a.txt", "cells/a.json", "config.json", "report.json"]
    on_disk = {path.relative_to(out).as_posix() for path in out.rglob("*") if path.is_file()}
    assert on_disk - {MANIFEST_FILE, LOCK_FILE} == set(manifest["files"])  # b's and c's files are gone
    assert (out / "a.txt").read_text() == "a 2\n"
    assert [entry["plan"] for entry in manifest["history"]] == ["replace"]


@pytest.mark.parametrize("overwrite", [False, True])
def test_foreign_files_are_refused_even_with_overwrite(tmp_path, overwrite):
    out = tmp_path / "run"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    experiment = Counting()
    with pytest.raises(FolderError, match="did not write.*notes.txt"):
        run_experiment(experiment, out, overwrite=overwrite, progress=False)
    assert [path.name for path in out.iterdir()] == ["notes.txt"] and experiment.log == ["validate"]


@pytest.mark.parametrize("overwrite", [False, True])
def test_a_foreign_file_beside_a_finished_run_is_refused_even_with_overwrite(tmp_path, overwrite):
    out = tmp_path / "run"
    run_experiment(Counting(), out, progress=False)
    (out / "cells" / "mine.json").write_text("{}")
    stamps = _stamps(out)
    with pytest.raises(FolderError, match="manifest does not list.*cells/mine.json"):
        run_experiment(Counting(value=2), out, overwrite=overwrite, progress=False)
    assert _stamps(out) == stamps


def test_validate_errors_before_anything_is_written(tmp_path):
    experiment = Counting(value=-1)
    with pytest.raises(ValueError, match="value must be at least 0, got -1"):
        run_experiment(experiment, tmp_path / "never", progress=False)
    assert not (tmp_path / "never").exists() and experiment.log == ["validate"]


def test_the_manifest_ends_complete_listing_every_file_and_recording_the_summary(tmp_path):
    out = tmp_path / "run"
    run_experiment(Counting(), out, progress=False)
    manifest = _manifest(out)
    assert manifest["kind"] == "counting" and manifest["status"] == "complete"
    assert manifest["identity"] == {"names": ["a", "b", "c"], "value": 1}
    assert sorted(manifest["files"]) == ["a.txt", "b.txt", "c.txt", "cells/a.json", "cells/b.json", "cells/c.json",
                                         "config.json", "report.json"]
    entry = manifest["history"][-1]
    assert entry["cells"] == 3 and "finished" in entry and isinstance(entry["seconds"], float)


def test_an_unfinished_cell_reaches_the_report_but_runs_again_on_a_rerun(tmp_path):
    out = tmp_path / "run"
    first = Counting(unfinished=("b",))
    run_experiment(first, out, progress=False)
    assert sorted(path.name for path in (out / "cells").iterdir()) == ["a.json", "c.json"]
    assert first.reported["b"] == {"name": "b", "value": 11, "pair": (1, 2)}  # as returned: never stored
    assert _manifest(out)["status"] == "complete"

    rerun = Counting()
    run_experiment(rerun, out, progress=False)
    assert [entry for entry in rerun.log if entry.startswith("run ")] == ["run b"]
    assert sorted(path.name for path in (out / "cells").iterdir()) == ["a.json", "b.json", "c.json"]


def test_a_cell_planned_twice_is_an_error_before_any_cell_runs(tmp_path):
    experiment = Counting(names=("a", "b", "a"))
    with pytest.raises(ValueError, match="plans a cell twice"):
        run_experiment(experiment, tmp_path / "run", progress=False)
    assert not any(entry.startswith("run ") for entry in experiment.log)
