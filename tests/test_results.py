"""A comparison's results as an xarray Dataset (`sparselt.load_comparison`): results.csv and summary.csv are its views.

The folder is a real `compare` run at test_compare's tiny size (Cornell box, 16x16x4x4, through Mitsuba).
"""

import csv
import json
import math
import os

import numpy as np
import pytest
from test_compare import tiny

import sparselt
from sparselt.experiments.compare import compare
from sparselt.report.comparison import COLUMN_ORDER, results_csv, summary_csv
from sparselt.report.results import RESULT_ROW_ORDER, dataset_csv, records_dataset, results_dataset
from sparselt.storage.folder import ExperimentFolder


@pytest.fixture(scope="module")
def comparison(tmp_path_factory):
    out = tmp_path_factory.mktemp("results") / "run"
    config = tiny(methods=("pt", "samples-mean"), spps=(4,), seeds=(1, 2), timing_repeats=1)
    compare(config, out, progress=False, cache_directory=str(tmp_path_factory.mktemp("references")))
    return out, config


def _csv(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _snapshot(folder):
    """Every file under ``folder``: its bytes and modification time."""
    files = {}
    for root, _, names in os.walk(folder):
        for name in names:
            path = os.path.join(root, name)
            with open(path, "rb") as handle:
                files[os.path.relpath(path, folder)] = (handle.read(), os.stat(path).st_mtime_ns)
    return files


def test_dimensions_and_coordinates(comparison):
    out, config = comparison
    results = sparselt.load_comparison(out)
    ladder = json.loads((out / "compare.json").read_text())["pt_ladder"]["spps"]
    assert results.relmse.dims == ("method", "spp", "seed")
    assert list(results["method"].values) == ["pt", "samples-mean"]  # the baseline first, then as configured
    assert list(results["spp"].values) == sorted(set(config.spps) | set(ladder))
    assert list(results["seed"].values) == [1, 2]
    assert results.attrs["scene"] == "cornell-box" and results.attrs["kind"] == "dof"
    assert results.attrs["relmse_epsilon"] == 0.01 and results.attrs["reference_spp"] == 256
    assert results.attrs["baseline"] == "pt" and results.attrs["status"] == "complete"
    assert json.loads(results.attrs["config"])["methods"] == ["pt", "samples-mean"]
    assert json.loads(results.attrs["provenance"])[0]["command"]
    for name in ("ssim", "relmse", "flip", "luminance_ratio", "contrast_ratio", "seconds_sampling",
                 "seconds_reconstruction", "seconds_integration", "seconds_other", "seconds_total",
                 "seconds_total_min", "seconds_total_max", "path_samples", "relmse_pt_equal_time", "verdict"):
        assert name in results.data_vars, name


def test_values_are_those_of_results_csv_and_nan_where_not_run(comparison):
    out, _ = comparison
    results = sparselt.load_comparison(out)
    rows = _csv(out / "results.csv")
    for row in rows:
        cell = results.sel({"method": row["method"], "spp": int(row["spp"]), "seed": int(row["seed"])})
        for name, text in row.items():
            if name in ("method", "spp", "seed"):
                continue
            value = cell[name].item()
            if text == "":
                assert isinstance(value, float) and math.isnan(value), (name, value)
            elif results[name].attrs["value_type"] in ("real", "integer"):
                assert value == pytest.approx(float(text), rel=1e-5), (row["method"], name)
            else:
                assert str(value) == text, (row["method"], name)
    # samples-mean ran at 4 spp only; PT's ladder rungs are other cells: every variable NaN there.
    run = {(row["method"], int(row["spp"]), int(row["seed"])) for row in rows}
    ladder_only = [int(spp) for spp in results["spp"].values if ("samples-mean", int(spp), 1) not in run]
    assert ladder_only
    for spp in ladder_only:
        cell = results.sel({"method": "samples-mean", "spp": spp})
        assert all(np.all(cell[name].isnull()) for name in results.data_vars)
    assert not np.isnan(results.relmse.sel({"method": "pt", "spp": 4, "seed": 2}).item())
    # The file is the Dataset's view, byte for byte.
    assert dataset_csv(results, COLUMN_ORDER, row_order=RESULT_ROW_ORDER) == (out / "results.csv").read_text()


def test_summary_loads_over_method_and_spp(comparison):
    out, _ = comparison
    summary = sparselt.load_summary(out)
    assert summary.relmse.dims == ("method", "spp")
    records = _csv(out / "summary.csv")
    assert len(records) == int(summary.seeds.notnull().sum())
    for record in records:
        cell = summary.sel({"method": record["method"], "spp": int(record["spp"])})
        assert cell.seeds.item() == int(record["seeds"]) == 2
        assert cell.relmse.item() == pytest.approx(float(record["relmse"]), rel=1e-5)
        assert str(cell.verdict.item()) == record["verdict"]
    assert dataset_csv(summary) == (out / "summary.csv").read_text()
    mean = sparselt.load_comparison(out).relmse.sel({"method": "samples-mean", "spp": 4}).mean("seed").item()
    assert summary.relmse.sel({"method": "samples-mean", "spp": 4}).item() == pytest.approx(mean, rel=1e-12)
    # The bias test (Welch per pixel, Benjamini-Hochberg at 1%) of each (method, spp) over its two seeds, and the
    # luminance ratio's mean over seeds inside its interval.
    bias = json.loads((out / "compare.json").read_text())["bias"]
    assert (bias["level"], bias["correction"], bias["reference_degrees_of_freedom"]) == (0.01, "benjamini-hochberg", 3)
    assert {(cell["method"], cell["spp"]) for cell in bias["cells"]} == {
        (record["method"], int(record["spp"])) for record in records}
    for record in records:
        assert 0.0 <= float(record["bias_fraction"]) <= 1.0
        assert float(record["luminance_ratio_ci_low"]) < float(record["luminance_ratio"]) < float(
            record["luminance_ratio_ci_high"])
    ratio = sparselt.load_comparison(out).luminance_ratio.sel({"method": "pt", "spp": 4}).mean("seed").item()
    assert summary.luminance_ratio.sel({"method": "pt", "spp": 4}).item() == pytest.approx(ratio, rel=1e-12)


def test_loading_writes_nothing_and_takes_no_lock(comparison):
    out, _ = comparison
    before = _snapshot(out)
    sparselt.load_comparison(out)
    sparselt.load_summary(out)
    assert _snapshot(out) == before


def test_a_folder_that_is_not_a_comparison_is_refused(tmp_path):
    with pytest.raises(ValueError, match=f"{str(tmp_path / 'missing')!r} is not a sparselt compare folder: no such"):
        sparselt.load_comparison(tmp_path / "missing")
    (tmp_path / "plain").mkdir()
    with pytest.raises(ValueError, match=f"{str(tmp_path / 'plain')!r} is not a sparselt compare folder: it holds "
                                         "no sparselt-folder.json"):
        sparselt.load_comparison(tmp_path / "plain")
    other = ExperimentFolder(tmp_path / "render", kind="render", identity={"spp": 4})
    with other.open():
        other.write_text("image.txt", "x")
        other.complete()
    with pytest.raises(ValueError, match=f"{str(tmp_path / 'render')!r} holds a 'render' run, not a 'compare' one"):
        sparselt.load_summary(tmp_path / "render")


def test_an_unlisted_cell_is_refused(comparison, tmp_path):
    import shutil

    out, _ = comparison
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / "cells" / "samples-mean_spp4_seed9.json").write_text((copy / "cells" / "samples-mean_spp4_seed1.json")
                                                                  .read_text())
    with pytest.raises(ValueError, match="holds cells/samples-mean_spp4_seed9.json, which its manifest does not list"):
        sparselt.load_comparison(copy)


# ---------------------------------------------------------------------------------------- the views, without rendering
def _rows():
    rows = []
    for method in ("pt", "cosamp:gamma=0.5"):
        for seed in (2, 1):
            for spp in ((8, 4) if method == "pt" else (4,)):
                rows.append({"method": method, "spp": spp, "seed": seed, "seconds_total": 0.5 * spp,
                             "path_samples": 1048576 * spp, "relmse": 1.0 / spp, "timing_noisy": seed == 2,
                             "verdict": "baseline" if method == "pt" else "wins",
                             "relmse_pt_equal_time": "" if method == "pt" else float("nan"),
                             "note": 'a, "b"'})
    return rows


def test_records_keep_their_types_and_missing_cells_are_nan():
    dataset = results_dataset(_rows())
    assert list(dataset["method"].values) == ["pt", "cosamp:gamma=0.5"]
    assert list(dataset["spp"].values) == [4, 8] and list(dataset["seed"].values) == [1, 2]
    assert dataset.path_samples.attrs["value_type"] == "integer" and dataset.path_samples.dtype == np.float64
    assert dataset.timing_noisy.attrs["value_type"] == "boolean" and dataset.verdict.attrs["value_type"] == "text"
    assert np.isnan(dataset.relmse.sel({"method": "cosamp:gamma=0.5", "spp": 8, "seed": 1}).item())
    assert dataset.timing_noisy.sel({"method": "pt", "spp": 8, "seed": 2}).item() is True
    assert results_dataset([dict(row, spp=4) for row in _rows() if row["method"] == "pt" and row["spp"] == 4]) \
        .path_samples.dtype == np.int64  # no missing cell: integers stay integers


def test_the_csv_view_orders_rows_by_coordinate_and_writes_values_as_the_rows_had_them():
    lines = results_csv(_rows(), ("method", "spp", "seed", "path_samples")).splitlines()
    assert lines[0] == "method,spp,seed,path_samples,note,relmse,relmse_pt_equal_time,seconds_total,timing_noisy,verdict"
    assert [line.split(",")[:3] for line in lines[1:]] == [
        ["pt", "4", "1"], ["pt", "8", "1"], ["pt", "4", "2"], ["pt", "8", "2"], ["cosamp:gamma=0.5", "4", "1"],
        ["cosamp:gamma=0.5", "4", "2"]]  # methods as first seen, then seed, then spp
    assert lines[1] == 'pt,4,1,4194304,"a, ""b""",0.25,,2,False,baseline'  # integers in full, '' and NaN empty
    assert summary_csv([]) == "method,spp\n"


def test_two_records_of_one_cell_are_refused():
    with pytest.raises(ValueError, match=r"two records label the same cell \(method='pt', spp=4, seed=1\)"):
        records_dataset([{"method": "pt", "spp": 4, "seed": 1}] * 2, ("method", "spp", "seed"))
    with pytest.raises(ValueError, match="lacks the dimension 'seed'"):
        records_dataset([{"method": "pt", "spp": 4}], ("method", "spp", "seed"))
