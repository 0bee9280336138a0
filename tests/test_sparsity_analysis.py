"""`sparselt analyze` writes an experiment folder (issue 18): identity, resume, foreign files, tables.

The signals are small synthetic ones in memory: the folder's promises need no renderer.
"""

import csv
import json

import numpy as np
import pytest

from sparselt.cli import main
from sparselt.experiments import sparsity_analysis
from sparselt.experiments.sparsity_analysis import analysis_identity, analyze_signal
from sparselt.signal import Signal
from sparselt.storage.folder import MANIFEST_FILE

ARGUMENTS = dict(gammas=(1.0, 0.5), fractions=(0.01, 0.1, 1.0), progress=False)


def _signal(seed=5, shape=(24, 20, 4, 4), meta=None):
    data = np.random.default_rng(seed).random(shape + (3,)).astype(np.float32) ** 4
    return Signal(data=data, kind="dof", axes=("x", "y", "lens_u", "lens_v"), meta=dict(meta or {"scene": "synthetic"}))


def _cells(out):
    return {path.name: path.stat().st_mtime_ns for path in (out / "cells").iterdir()}


def test_writes_tables_through_the_folder_and_lists_them(tmp_path):
    out = tmp_path / "analysis"
    result = analyze_signal(_signal(), out, **ARGUMENTS)
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert manifest["kind"] == "analyze" and manifest["status"] == "complete"
    for name in ("gini.csv", "ssim.csv", "table_5_1_fourier.md", "table_5_1_fourier.csv", "table_5_2_canonical.md",
                 "table_7_gamma.md", "table_7_gamma.csv", "ssim_vs_fraction.png", "thresholded.png", "analysis.json",
                 "cells/gamma-1.json", "cells/gamma-0.5.json"):
        assert name in manifest["files"] and (out / name).is_file(), name
    with open(out / "gini.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2 * 4 * 3 and set(rows[0]) == {"gamma", "domain", "energy", "channel", "gini", "error_bound"}
    assert "| gamma | Time | Time Energy | Frequency | Frequency Energy |" in result["gamma_table"]
    assert result["gamma_table"] == (out / "table_7_gamma.md").read_text()


@pytest.mark.parametrize("overwrite", [False, True])
def test_a_folder_with_a_foreign_file_is_refused_even_with_overwrite(tmp_path, overwrite):
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="did not write.*notes.txt"):
        analyze_signal(_signal(), tmp_path, overwrite=overwrite, **ARGUMENTS)
    assert [path.name for path in tmp_path.iterdir()] == ["notes.txt"]


def test_a_rerun_with_the_same_identity_resumes_without_recomputing(tmp_path, monkeypatch):
    out = tmp_path / "analysis"
    first = analyze_signal(_signal(), out, **ARGUMENTS)
    stamps = _cells(out)

    def no_gini(*_, **__):
        raise AssertionError("a finished gamma was analysed again")

    monkeypatch.setattr(sparsity_analysis, "gini_table", no_gini)
    again = analyze_signal(_signal(), out, **ARGUMENTS)
    assert again["gini"] == first["gini"] and again["ssim"] == first["ssim"]
    assert _cells(out) == stamps
    history = json.loads((out / MANIFEST_FILE).read_text())["history"]
    assert [entry["plan"] for entry in history] == ["new", "resume"]


@pytest.mark.parametrize("changes, difference", [
    (dict(gammas=(1.0, 0.25)), "gammas"),
    (dict(fractions=(0.01, 1.0)), "fractions"),
    (dict(signal=_signal(seed=6)), "signal"),
], ids=["other-gammas", "other-fractions", "other-signal"])
def test_another_identity_is_refused_and_overwrite_replaces_it(tmp_path, changes, difference):
    out = tmp_path / "analysis"
    analyze_signal(_signal(), out, **ARGUMENTS)
    stamps = _cells(out)
    arguments = dict(ARGUMENTS, **{key: value for key, value in changes.items() if key != "signal"})
    signal = changes.get("signal", _signal())
    with pytest.raises(ValueError, match=f"another analyze run.*{difference}"):
        analyze_signal(signal, out, **arguments)
    assert _cells(out) == stamps
    analyze_signal(signal, out, overwrite=True, **arguments)
    gammas = arguments["gammas"]
    assert sorted(_cells(out)) == sorted(f"gamma-{gamma:g}.json" for gamma in gammas)


def test_identity_is_the_signal_content_not_its_path():
    meta = {"scene": "s", "config": {"spp": 4}, "scene_identity": {"digest": "abc"}, "chunk_crc32": [1, 2, 3]}
    here = Signal(data=np.zeros((2, 2, 3), np.float32), kind="path", axes=("x", "y"), meta=meta, store="/one")
    there = Signal(data=np.zeros((2, 2, 3), np.float32), kind="path", axes=("x", "y"), meta=meta, store="/two")
    changed = Signal(data=np.zeros((2, 2, 3), np.float32), kind="path", axes=("x", "y"),
                     meta=dict(meta, chunk_crc32=[1, 2, 4]), store="/one")
    identity = analysis_identity(here, (1.0,), (0.5,), (0.5,), 2**30)
    assert identity == analysis_identity(there, (1.0,), (0.5,), (0.5,), 2**30)
    assert identity != analysis_identity(changed, (1.0,), (0.5,), (0.5,), 2**30)
    assert "/one" not in json.dumps(identity)


@pytest.mark.parametrize("arguments, message", [
    (dict(gammas=(0.5, 0.5)), "repeat"),
    (dict(fractions=(0.1, 0.1)), "repeat"),
    (dict(grid_fractions=(0.3,)), r"grid fractions \[0.3\] are not among"),
    (dict(memory_limit_bytes=0), "memory_limit_bytes"),
], ids=["repeated-gamma", "repeated-fraction", "grid-fraction-not-analysed", "memory-limit-zero"])
def test_bad_arguments_are_refused_before_the_folder_is_made(tmp_path, arguments, message):
    with pytest.raises(ValueError, match=message):
        analyze_signal(_signal(), tmp_path / "never", **dict(ARGUMENTS, **arguments))
    assert not (tmp_path / "never").exists()


def test_cli_analyze_refuses_a_foreign_folder_with_exit_code_2(tmp_path, monkeypatch, capsys):
    import sparselt.signal

    monkeypatch.setattr(sparselt.signal, "load_signal", lambda path: _signal())
    out = tmp_path / "analysis"
    out.mkdir()
    (out / "paper.tex").write_text("x")
    assert main(["analyze", "signal", "--gamma", "1", "--fractions", "0.1,1", "--out", str(out), "--overwrite"]) == 2
    assert "did not write" in capsys.readouterr().err and (out / "paper.tex").read_text() == "x"
