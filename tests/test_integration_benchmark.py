"""The Table 4.1 benchmark machinery on tiny sizes: files, one CSV row per measurement, agreement.

Timings themselves belong in ``benchmarks/``; this only checks that the
experiment runs end to end and records what it claims.
"""

import csv
import json

import numpy as np
import pytest

from sparselt.experiments.integration_benchmark import (
    MINIMUM_REACHING,
    IntegrationBenchmarkResult,
    contributing_coefficients,
    estimate_peak_bytes,
    run_integration_benchmark,
    sample_support,
    thesis_signal,
)
from sparselt.experiments.integration_child import measure_in_this_process
from sparselt.fourier.integration import METHODS

SIZES = (8, 12)
#: The sizes of ``sparselt reproduce``'s quick scale for chapter 4 (Table 4.1's fit range there).
QUICK_SIZES = (32, 48, 64)


@pytest.fixture(scope="module")
def benchmark(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench-integrate")
    result = run_integration_benchmark(out, sizes=SIZES, repeats=2, density=0.01, progress=False)
    return out, result


def test_writes_every_file(benchmark):
    out, result = benchmark
    assert isinstance(result, IntegrationBenchmarkResult)
    for name in ("integration.csv", "integration.md", "figure_4_1_time.png", "figure_4_2_memory.png", "config.json"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
        assert result.files[name] == str(out / name)
    assert (out / "figure_4_1_time.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [path.name for path in out.iterdir() if path.name.startswith(".tmp-")]


def test_csv_has_one_measured_row_per_method_and_size(benchmark):
    out, result = benchmark
    with open(out / "integration.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert sorted((row["method"], int(row["s"])) for row in rows) == sorted((m, s) for m in METHODS for s in SIZES)
    for row in rows:
        assert row["status"] == "measured", row
        size = int(row["s"])
        assert int(row["N"]) == size ** 4 and int(row["P"]) == size ** 2
        assert int(row["K"]) == int(size ** 4 * 0.01)
        runs = row["run_seconds"].split(";")
        assert 1 <= len(runs) <= 2
        assert row["seconds"] == min(runs, key=float)  # the best of the timed runs, as written
        assert int(row["baseline_bytes"]) > 0
        assert int(row["contributing_coefficients"]) >= MINIMUM_REACHING and float(row["image_max"]) > 0, row
        assert 0 <= int(row["uniform_contributing_coefficients"]) <= int(row["contributing_coefficients"])
    assert len(result.measurements) == len(METHODS) * len(SIZES)
    assert result.empty_image_sizes == ()


#: The child below: every integration allocates (and touches) BALLAST_BYTES and sleeps SLEEP_SECONDS first.
CHILD_WITH_BALLAST = """
import json, sys, time
import numpy as np
from sparselt.experiments import integration_child

real = integration_child.integrate

def integrate(*arguments):
    ballast = np.ones({ballast} // 8)
    time.sleep({sleep})
    result = real(*arguments)
    del ballast
    return result

integration_child.integrate = integrate
task = dict(size=8, method="sum", seed=0, density=0.01, minimum_reaching=1, repeats=2, check=False)
print(json.dumps(integration_child.measure_in_this_process(task)))
"""
BALLAST_BYTES = 64 * 2**20
SLEEP_SECONDS = 0.1


def test_the_child_measures_a_known_allocation_and_a_known_time():
    """The child's peak is VmHWM over the baseline around the call: an array of known size allocated inside the
    call is in it, and the warm-up's identical array (freed before the reset) is not; each timed call's seconds
    include a known sleep."""
    import subprocess
    import sys

    from sparselt.experiments.isolation import child_environment

    script = CHILD_WITH_BALLAST.format(ballast=BALLAST_BYTES, sleep=SLEEP_SECONDS)
    completed = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                               env=child_environment(), check=True)
    record = json.loads(completed.stdout.strip().splitlines()[-1])
    # Up to a MiB of the array may land on pages already resident at the baseline (freed heap).
    assert BALLAST_BYTES - 2**20 <= record["peak_bytes"] < 1.5 * BALLAST_BYTES, record
    assert len(record["seconds"]) == 2
    assert all(SLEEP_SECONDS <= seconds < SLEEP_SECONDS + 5 for seconds in record["seconds"])


def test_every_method_agrees_with_convolution(benchmark):
    _, result = benchmark
    assert result.agreement_passed is True
    assert all(item.check_error is not None and item.check_error < 1e-9 for item in result.measurements)


def test_summary_and_config_are_recorded(benchmark):
    out, result = benchmark
    record = json.loads((out / "config.json").read_text())
    assert record["config"]["sizes"] == list(SIZES) and record["config"]["seed"] == 0
    assert "versions" in record["environment"]
    assert record["results"]["agreement_passed"] is True
    assert result.ratio_size == max(SIZES) and result.speed_ratio > 0
    assert set(result.time_exponents) == set(METHODS)
    assert record["config"]["minimum_reaching"] == MINIMUM_REACHING and record["results"]["empty_image_sizes"] == []
    text = (out / "integration.md").read_text()
    assert "Table 4.1" in text and all(f"`{method}`" in text for method in METHODS)
    assert "Coefficients reaching the image" in text and "Deviation from the thesis's uniform draw" in text
    assert f"time fitted over s = {', '.join(map(str, SIZES))}" in text and "Warning" not in text


def test_sample_support_is_distinct_and_in_range():
    rng = np.random.default_rng(1)
    support = sample_support(1000, 900, rng)
    assert support.size == 900 and np.unique(support).size == 900
    assert support.min() >= 0 and support.max() < 1000
    with pytest.raises(ValueError, match="count"):
        sample_support(10, 11, rng)


def test_sample_support_is_uniform():
    """Chi-square: each of 20 indices is drawn into a 5-subset with probability 1/4."""
    rng = np.random.default_rng(2)
    trials = 4000
    counts = np.bincount(np.concatenate([sample_support(20, 5, rng) for _ in range(trials)]), minlength=20)
    expected = trials * 5 / 20
    statistic = float(np.sum((counts - expected) ** 2 / expected))
    assert statistic < 43.8  # chi-square, 19 degrees of freedom, p = 0.001


def test_thesis_signal_follows_the_pseudo_code():
    representation = thesis_signal(12, seed=3)
    assert representation.shape == (12,) * 4 and representation.sparsity == int(12 ** 4 * 1e-4)
    values = thesis_signal(12, density=0.01, seed=3).values
    assert np.all(values.imag == 0) and values.real.min() >= 0 and values.real.max() < 1
    assert np.array_equal(thesis_signal(12, seed=3).indices, representation.indices)


def _on_plane(representation):
    coordinates = representation.coordinates()
    return np.all(coordinates[:, 2:] == 0, axis=1)


@pytest.mark.parametrize("size, density, minimum, expected", [
    (16, 1e-4, 4, 4),    # K = 6, the uniform draw has none on the plane: four are moved there
    (8, 1e-4, 4, 1),     # K = 1: the single coefficient
    (4, 0.5, 100, 16),   # K = 128, more than the P = 16 frequencies of the plane: all of them
    (16, 1e-4, 0, 0),    # the uniform draw as it is
])
def test_thesis_signal_puts_a_minimum_on_the_integration_plane(size, density, minimum, expected):
    uniform = thesis_signal(size, density=density, seed=0, minimum_reaching=0)
    raised = thesis_signal(size, density=density, seed=0, minimum_reaching=minimum)
    assert raised.sparsity == uniform.sparsity == max(1, int(size ** 4 * density))  # K is the thesis's
    reaching = max(expected, contributing_coefficients(uniform))
    assert contributing_coefficients(raised) == int(_on_plane(raised).sum()) == reaching
    assert np.unique(raised.indices).size == raised.sparsity
    assert np.array_equal(np.sort(raised.values), np.sort(uniform.values))  # values kept, only moved
    off_plane = uniform.indices[~_on_plane(uniform)]
    assert np.isin(raised.indices[~_on_plane(raised)], off_plane).all()  # no new off-plane coefficient
    assert np.isin(uniform.indices[_on_plane(uniform)], raised.indices).all()  # the drawn on-plane ones stay


def test_thesis_signal_leaves_a_draw_with_enough_on_the_plane_unchanged():
    size, density = 8, 0.05  # K = 204, P / N = 1 / 64: about 3 on the plane
    for seed in range(20):
        uniform = thesis_signal(size, density=density, seed=seed, minimum_reaching=0)
        if contributing_coefficients(uniform) >= 2:
            raised = thesis_signal(size, density=density, seed=seed, minimum_reaching=2)
            assert np.array_equal(raised.indices, uniform.indices) and np.array_equal(raised.values, uniform.values)


def test_moved_coefficients_land_uniformly_on_the_plane():
    """Chi-square: over many seeds, the 64 plane frequencies of s = 8 are filled equally often."""
    counts = np.zeros(64)
    for seed in range(400):
        representation = thesis_signal(8, density=0.01, seed=seed, minimum_reaching=4)  # K = 40, ~0.6 drawn there
        coordinates = representation.coordinates()[_on_plane(representation)]
        np.add.at(counts, coordinates[:, 0] * 8 + coordinates[:, 1], 1)
    expected = counts.sum() / 64
    statistic = float(np.sum((counts - expected) ** 2 / expected))
    assert counts.sum() >= 1600 and statistic < 103.4  # chi-square, 63 degrees of freedom, p = 0.001


def _timed_convolution(size, minimum_reaching=MINIMUM_REACHING):
    """The child's record of the timed convolution at ``s = size`` with the benchmark's defaults."""
    return measure_in_this_process({"size": size, "method": "convolution", "seed": 0, "density": 1e-4,
                                    "minimum_reaching": minimum_reaching, "repeats": 1, "check": False})


@pytest.mark.parametrize("size", QUICK_SIZES)
def test_the_timed_convolution_integrates_a_non_empty_image_at_quick_scale(size):
    """At every size of ``sparselt reproduce 4 --scale quick``, coefficients reach the timed image."""
    record = _timed_convolution(size)
    assert record["contributing_coefficients"] >= 1 and record["image_max"] > 0, record
    if size in (32, 48):  # seed 0's uniform draw has none there: the check sees what the floor prevents
        empty = _timed_convolution(size, minimum_reaching=0)
        assert empty["contributing_coefficients"] == 0 and empty["image_max"] == 0


def test_the_timed_convolution_integrates_a_non_empty_image_at_every_reproduce_scale():
    """The sizes ``sparselt reproduce`` really runs chapter 4 at, every scale (skipped where it has no scales)."""
    scales = pytest.importorskip("sparselt.experiments.reproduce.scales")
    sizes = sorted({size for scale in scales.SCALES.values() for size in scale.integration_sizes})
    records = {size: _timed_convolution(size) for size in sizes}
    assert [size for size, record in records.items() if record["image_max"] == 0] == [], records


def test_warns_when_no_coefficient_reaches_the_image(tmp_path):
    with pytest.warns(RuntimeWarning, match=r"at s = 8 no coefficient reaches the image"):
        result = run_integration_benchmark(tmp_path / "out", sizes=(8,), methods=("convolution",), repeats=1,
                                           minimum_reaching=0, progress=False)
    assert result.empty_image_sizes == (8,)
    item = result.measurement("convolution", 8)
    assert item.contributing_coefficients == 0 and item.image_max == 0
    text = (tmp_path / "out" / "integration.md").read_text()
    assert "**Warning:** at s = 8 no coefficient reaches the image" in text


@pytest.mark.parametrize("method", METHODS)
def test_estimated_peak_memory_bounds_the_measured_one(method):
    """The guard's estimate against the peak tracemalloc measures while ``integrate`` runs (NumPy reports
    its allocations to tracemalloc): never far below it, and O(N) only for the dense methods."""
    import tracemalloc

    from sparselt.fourier.integration import integrate

    size = 32
    representation = thesis_signal(size, density=1e-4, seed=5)  # the thesis's density: K = N / 10^4
    coefficients = representation.indices.shape[0]
    integrate(representation, method=method)  # first call: imports and caches outside the measurement
    tracemalloc.start()
    try:
        integrate(representation, method=method)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    estimate = estimate_peak_bytes(method, size, coefficients)
    assert estimate >= 0.5 * peak, (estimate, peak)
    dense = 2 * size ** 4 * np.dtype(np.complex128).itemsize
    if method in ("sum", "time-fft"):
        assert peak >= 0.4 * dense and estimate <= 2 * peak, (estimate, peak)
    else:
        assert peak < 0.25 * dense and estimate < 0.25 * dense, (estimate, peak)


@pytest.mark.parametrize("arguments, message", [
    ({"sizes": ()}, "sizes"),
    ({"sizes": (1,)}, "sizes"),
    ({"sizes": (8, 8)}, "repeat"),
    ({"methods": ("fast",)}, "unknown"),
    ({"methods": ("sum", "sum")}, "repeat"),
    ({"seed": -1}, "seed"),
    ({"repeats": 0}, "repeats"),
    ({"density": 0.0}, "density"),
    ({"sizes": (8.5,)}, "integers"),
    ({"check_max_size": -1}, "check_max_size"),
    ({"minimum_reaching": -1}, "minimum_reaching"),
])
def test_rejects_bad_arguments(tmp_path, arguments, message):
    with pytest.raises(ValueError, match=message):
        run_integration_benchmark(tmp_path / "out", progress=False, **arguments)


@pytest.mark.parametrize("overwrite", [False, True])
def test_refuses_a_folder_with_a_foreign_file_even_with_overwrite(tmp_path, overwrite):
    (tmp_path / "keep.txt").write_text("x")
    with pytest.raises(ValueError, match="did not write.*keep.txt"):
        run_integration_benchmark(tmp_path, sizes=(8,), methods=("convolution",), overwrite=overwrite, progress=False)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["keep.txt"] and (tmp_path / "keep.txt").read_text() == "x"


def test_a_rerun_with_the_same_identity_resumes_and_another_is_refused(tmp_path, monkeypatch):
    from sparselt.experiments import integration_benchmark

    out = tmp_path / "bench"
    arguments = dict(sizes=(8,), methods=("convolution", "time"), repeats=1, density=0.01, progress=False)
    first = run_integration_benchmark(out, **arguments)
    cells = sorted(path.name for path in (out / "cells").iterdir())
    assert cells == ["convolution-s8.json", "time-s8.json"]
    stamps = {name: (out / "cells" / name).stat().st_mtime_ns for name in cells}

    def no_child(*_, **__):
        raise AssertionError("a finished cell was measured again")

    monkeypatch.setattr(integration_benchmark, "run_child", no_child)
    again = run_integration_benchmark(out, **arguments)  # same identity: resumes, nothing measured
    assert again.measurement("time", 8).seconds == first.measurement("time", 8).seconds
    assert {name: (out / "cells" / name).stat().st_mtime_ns for name in cells} == stamps
    assert json.loads((out / "sparselt-folder.json").read_text())["status"] == "complete"

    with pytest.raises(ValueError, match="another bench-integrate run.*repeats: 1 recorded, 2 now"):
        run_integration_benchmark(out, **dict(arguments, repeats=2))
    assert {name: (out / "cells" / name).stat().st_mtime_ns for name in cells} == stamps
    monkeypatch.undo()
    replaced = run_integration_benchmark(out, overwrite=True, **dict(arguments, methods=("convolution",)))
    assert sorted(path.name for path in (out / "cells").iterdir()) == ["convolution-s8.json"]
    assert [item.method for item in replaced.measurements] == ["convolution"]


@pytest.mark.parametrize("sizes, message", [
    ((100000,), r"s = 100000 .* needs at least .* the largest s that fits is \d+"),
    ((60000,), r"s = 60000 gives N = s\^4 = 1.3e\+19 values, beyond the int64 .* the largest s allowed is 55108"),
], ids=["beyond-memory", "beyond-int64"])
def test_a_size_that_cannot_run_is_refused_up_front(tmp_path, monkeypatch, sizes, message):
    from sparselt.experiments import integration_benchmark

    if sizes == (60000,):  # the int64 bound speaks where the machine's memory is unknown
        monkeypatch.setattr(integration_benchmark, "_total_bytes", lambda: None)
    with pytest.raises(ValueError, match=message):
        run_integration_benchmark(tmp_path / "out", sizes=sizes, progress=False)
    assert not (tmp_path / "out").exists()


def test_the_size_bound_follows_the_machine_memory(tmp_path, monkeypatch):
    from sparselt.experiments import integration_benchmark

    monkeypatch.setattr(integration_benchmark, "_total_bytes", lambda: 2**30)
    largest = integration_benchmark.largest_size(("convolution",), 1e-4, 2**30)
    assert integration_benchmark.minimum_bytes(largest, ("convolution",), 1e-4)[0] <= 2**30
    assert integration_benchmark.minimum_bytes(largest + 1, ("convolution",), 1e-4)[0] > 2**30
    with pytest.raises(ValueError, match=f"the largest s that fits is {largest}$"):
        run_integration_benchmark(tmp_path / "out", sizes=(32, largest + 1), methods=("convolution",), progress=False)


def test_cli_bench_integrate_refuses_a_size_with_exit_code_2(tmp_path, capsys):
    from sparselt.cli import main

    assert main(["bench", "integrate", "--sizes", "100000", "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert "s = 100000" in error and "largest s that fits" in error and "Traceback" not in error


def test_skips_what_does_not_fit_and_records_failures(tmp_path, monkeypatch):
    from sparselt.experiments import integration_benchmark

    monkeypatch.setattr(integration_benchmark, "_available_bytes", lambda: 300 * 2**20)
    result = run_integration_benchmark(tmp_path / "skip", sizes=(8, 40), methods=("convolution", "sum"), repeats=1,
                                       density=0.01, progress=False)
    skipped = result.measurement("sum", 40)  # 2 N complex128 = 105 MB + interpreter > 0.9 x 300 MiB
    assert skipped.status == "skipped" and "available" in skipped.reason and skipped.seconds is None
    assert result.measurement("sum", 8).measured and result.ratio_size == 8
    with open(tmp_path / "skip" / "integration.csv", newline="") as handle:
        assert {row["status"] for row in csv.DictReader(handle)} == {"measured", "skipped"}

    monkeypatch.setattr(integration_benchmark, "_CHILD_MODULE", "sparselt.no_such_module")
    failed = run_integration_benchmark(tmp_path / "fail", sizes=(8,), methods=("convolution",), progress=False)
    item = failed.measurement("convolution", 8)
    assert item.status == "failed" and "No module named" in item.reason
    assert failed.agreement_passed is None and failed.ratio_size is None
