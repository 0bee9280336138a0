"""The experiment folder (issue 18): identity, lock, manifest, foreign files, atomic artefacts, resumable cells.

No renderer here: these are the folder's own promises. The commands' cases
(compare, table61, render, show, reproduce) are in test_run_folders.py.
"""

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from sparselt.storage import StoreLockedError
from sparselt.storage.folder import MANIFEST_FILE, ExperimentFolder, FolderError


def _folder(path, identity=None, **options):
    return ExperimentFolder(path, kind="test", identity=identity or {"size": 1, "name": "a"}, **options)


def _run(path, identity=None, files=("result.txt",), cells=(), **options):
    folder = _folder(path, identity, **options)
    folder.inspect()
    with folder.open():
        for name in files:
            folder.write_text(name, f"{name} of {identity}")
        for name in cells:
            folder.record_cell(name, {"value": name})
        folder.complete()
    return folder


def _tree(path):
    return sorted(os.path.relpath(os.path.join(root, name), path)
                  for root, _, names in os.walk(path) for name in names)


def test_new_folder_lists_every_file_and_records_the_command(tmp_path):
    out = tmp_path / "run"
    _run(out, files=("a.txt", "sub/b.json"), cells=("one",))
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert manifest["status"] == "complete"
    assert manifest["files"] == sorted(["a.txt", "sub/b.json", "cells/one.json"])
    assert manifest["identity"] == {"size": 1, "name": "a"}
    entry = manifest["history"][0]
    assert entry["plan"] == "new" and "versions" in entry and "git" in entry and "finished" in entry
    assert not (out / ".sparselt.lock").exists()


def test_resume_keeps_cells_and_appends_to_the_history(tmp_path):
    out = tmp_path / "run"
    _run(out, cells=("one",))
    folder = _folder(out)
    assert folder.inspect() == "resume"
    with folder.open():
        assert folder.cell("one") == {"value": "one"}
        assert folder.cell("two") is None
        folder.record_cell("two", {"value": "two"})
        assert set(folder.cells()) == {"one", "two"}
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert [entry["plan"] for entry in manifest["history"]] == ["new", "resume"]
    assert manifest["status"] == "running"  # this run did not call complete()


@pytest.mark.parametrize("overwrite", [False, True])
def test_a_folder_with_foreign_files_is_refused_and_nothing_is_deleted(tmp_path, overwrite):
    out = tmp_path / "paper"
    (out / "data").mkdir(parents=True)
    (out / "paper.tex").write_text("\\documentclass{article}")
    (out / "data" / "measurements.csv").write_text("1,2,3")
    before = _tree(out)
    with pytest.raises(FolderError, match="did not write.*paper.tex"):
        _run(out, overwrite=overwrite)
    assert _tree(out) == before


@pytest.mark.parametrize("overwrite", [False, True])
def test_a_foreign_file_added_to_a_sparselt_folder_is_refused(tmp_path, overwrite):
    out = tmp_path / "run"
    _run(out, files=("a.txt", "images/b.png"))
    (out / "images" / "notes.txt").write_text("mine")
    with pytest.raises(FolderError, match="does not list.*notes.txt"):
        _run(out, identity={"size": 2}, overwrite=overwrite)
    assert (out / "images" / "notes.txt").read_text() == "mine"
    assert (out / "a.txt").exists()


def test_another_identity_is_refused_naming_what_differs(tmp_path):
    out = tmp_path / "run"
    _run(out, identity={"size": 1, "name": "a"})
    with pytest.raises(FolderError, match=r"size: 1 recorded, 2 now"):
        _run(out, identity={"size": 2, "name": "a"})
    assert (out / "result.txt").read_text().endswith("{'size': 1, 'name': 'a'}")


def test_a_growable_identity_key_may_gain_entries_but_not_change_them(tmp_path):
    """A comparison's per-method options: a rerun may add a method; a method already there keeps its options."""
    out = tmp_path / "run"
    growable = {"growable": ("methods",)}
    _run(out, identity={"size": 1, "methods": {"a": {"k": 1}}}, **growable)
    _run(out, identity={"size": 1, "methods": {"b": {"k": 5}}}, files=("more.txt",), **growable)
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert manifest["identity"]["methods"] == {"a": {"k": 1}, "b": {"k": 5}}  # the union is recorded
    assert [entry["plan"] for entry in manifest["history"]] == ["new", "resume"]
    with pytest.raises(FolderError, match=r"methods.a: \{\"k\": 1\} recorded, \{\"k\": 2\} now"):
        _run(out, identity={"size": 1, "methods": {"a": {"k": 2}}}, **growable)
    with pytest.raises(FolderError, match=r"size: 1 recorded, 3 now"):
        _run(out, identity={"size": 3, "methods": {"a": {"k": 1}}}, **growable)
    with pytest.raises(FolderError, match=r"methods: "):  # without growable the whole dict must match
        _run(out, identity={"size": 1, "methods": {"a": {"k": 1}}})


def test_overwrite_removes_only_what_the_manifest_lists(tmp_path):
    out = tmp_path / "run"
    _run(out, identity={"size": 1}, files=("old.txt", "images/old.png"), cells=("cell",))
    _run(out, identity={"size": 2}, files=("new.txt",), overwrite=True)
    assert _tree(out) == sorted([MANIFEST_FILE, "new.txt"])
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert manifest["identity"] == {"size": 2} and manifest["files"] == ["new.txt"]


def test_overwrite_removes_nothing_before_open(tmp_path):
    """Replacing happens in open(), which callers enter after validating and loading the scene."""
    out = tmp_path / "run"
    _run(out, identity={"size": 1}, files=("old.txt",))
    folder = _folder(out, {"size": 2}, overwrite=True)
    assert folder.inspect() == "replace"
    assert (out / "old.txt").exists()


def test_a_second_writer_is_refused_with_the_holder(tmp_path):
    out = tmp_path / "run"
    first = _folder(out)
    first.inspect()
    with first.open():
        with pytest.raises(StoreLockedError, match=f"test folder .* PID {os.getpid()}"):
            _folder(out).inspect()
        with pytest.raises(StoreLockedError, match=f"PID {os.getpid()}"):
            with _folder(out, {"size": 9}, overwrite=True).open():
                pass
        first.write_text("still.txt", "ours")
    assert (out / "still.txt").exists()


def test_a_lock_left_by_a_killed_run_is_taken_over(tmp_path):
    out = tmp_path / "run"
    script = textwrap.dedent(f"""
        import os
        from sparselt.storage.folder import ExperimentFolder
        folder = ExperimentFolder({str(out)!r}, kind="test", identity={{"size": 1, "name": "a"}})
        folder.inspect()
        with folder.open():
            folder.record_cell("one", {{"value": "one"}})
            os.kill(os.getpid(), 9)
    """)
    subprocess.run([sys.executable, "-c", script], check=False)
    assert (out / ".sparselt.lock").exists()
    folder = _folder(out)
    assert folder.inspect() == "resume"
    with folder.open():
        assert folder.cell("one") == {"value": "one"}


@pytest.mark.parametrize("make, message", [
    (lambda path: path.write_text("x"), "existing file, not a folder"),
    (lambda path: os.symlink(path, path), "symbolic link loop"),
    (lambda path: os.symlink(path.parent / "nowhere", path), "broken symbolic link"),
])
def test_unusable_output_paths(tmp_path, make, message):
    out = tmp_path / "out"
    make(out)
    with pytest.raises(FolderError, match=message):
        _folder(out).inspect()


def test_a_url_is_refused(tmp_path):
    with pytest.raises(FolderError, match="only file-system paths"):
        _folder("s3://bucket/run")


def test_a_damaged_manifest_is_refused_not_replaced(tmp_path):
    out = tmp_path / "run"
    _run(out)
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    manifest["format_version"] = 99
    (out / MANIFEST_FILE).write_text(json.dumps(manifest))
    with pytest.raises(FolderError, match="format version 99"):
        _run(out, overwrite=True)
    assert (out / "result.txt").exists()


def test_writes_outside_open_are_refused(tmp_path):
    folder = _folder(tmp_path / "run")
    folder.inspect()
    with pytest.raises(RuntimeError, match="outside"):
        folder.write_text("a.txt", "x")


def test_artefacts_round_trip(tmp_path):
    out = tmp_path / "run"
    folder = _folder(out)
    folder.inspect()
    image = np.random.default_rng(1).random((12, 10, 3)).astype(np.float32)
    with folder.open():
        folder.write_npy("image.npy", image)
        folder.write_png("image.png", image)
        folder.write_json("record.json", {"a": np.float32(1.5), "b": [1, 2]})
    np.testing.assert_array_equal(np.load(out / "image.npy"), image)
    assert (out / "image.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((out / "record.json").read_text()) == {"a": 1.5, "b": [1, 2]}
    assert not [name for name in os.listdir(out) if name.startswith(".tmp-")]


def test_a_full_disk_names_the_file_and_the_run_resumes(tmp_path):
    """A write that fails for lack of space (EFBIG under a file-size limit) leaves no half file and no
    unlisted file; the same run, with room again, resumes."""
    out = tmp_path / "run"
    script = textwrap.dedent(f"""
        import resource, signal, sys
        from sparselt.storage.folder import ExperimentFolder
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        folder = ExperimentFolder({str(out)!r}, kind="test", identity={{"size": 1, "name": "a"}})
        folder.inspect()
        with folder.open():
            folder.record_cell("one", {{"value": "one"}})
            resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))
            try:
                folder.write_bytes("big.bin", bytes(100000))
            except Exception as error:
                print(type(error).__name__, error)
                sys.exit(3)
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert result.returncode == 3, result.stderr
    assert "DiskFullError" in result.stdout and "big.bin" in result.stdout and "rerun" in result.stdout
    assert not (out / "big.bin").exists()
    assert not [name for name in os.listdir(out) if name.startswith(".tmp-")]
    folder = _folder(out)
    assert folder.inspect() == "resume"
    with folder.open():
        assert folder.cell("one") == {"value": "one"}
        folder.write_bytes("big.bin", bytes(100000))
        folder.complete()
    assert (out / "big.bin").stat().st_size == 100000


def test_owned_sub_folders_are_not_foreign_and_are_emptied_on_replace(tmp_path):
    out = tmp_path / "run"
    folder = _folder(out, {"scale": "quick"})
    folder.inspect()
    with folder.open():
        child_path = folder.claim_folder("chapter1")
        _run(os.path.join(child_path, "inner"), files=("x.txt",))
        folder.complete()
    assert _folder(out, {"scale": "quick"}).inspect() == "resume"
    with pytest.raises(FolderError, match="scale: 'quick' recorded, 'thesis' now"):
        _folder(out, {"scale": "thesis"}).inspect()
    _run(out, identity={"scale": "thesis"}, files=("index.html",), overwrite=True)
    assert _tree(out) == sorted([MANIFEST_FILE, "index.html"])



@pytest.mark.parametrize("how", ["failure", "interrupt", "wrapped interrupt"])
def test_a_failed_new_run_leaves_nothing_and_an_interrupted_one_is_kept(tmp_path, how):
    """A new folder whose run fails before recording any cell is removed; a Ctrl-C keeps it (status running, a
    rerun resumes), also when it arrives as the RuntimeError drjit.custom wraps around a KeyboardInterrupt raised
    in a Mitsuba render's Python part (that path removed the folder while the command said its work was kept)."""
    out = tmp_path / "run"
    folder = _folder(out)
    folder.inspect()
    with pytest.raises(RuntimeError if how != "interrupt" else KeyboardInterrupt):
        with folder.open():
            folder.write_text("result.txt", "partial")
            if how == "failure":
                raise RuntimeError("a bug")
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt as interrupt:
                if how == "interrupt":
                    raise
                raise RuntimeError("drjit.custom: the callback raised") from interrupt
    if how == "failure":
        assert not out.exists()
        return
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert manifest["status"] == "running" and manifest["files"] == ["result.txt"]
