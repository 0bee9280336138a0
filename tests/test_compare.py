"""The equal-time harness (`sparselt compare`) and the CoSaMP 4-D pipeline (thesis 8.1).

Rendering tests use the real Cornell box at 16x16x4x4 through Mitsuba.
"""

import csv
import dataclasses
import gc
import json
import math
import os
import re
import weakref

import numpy as np
import pytest

from sparselt.cli import main
from sparselt.experiments.compare import RESULT_COLUMNS, ComparisonConfig, compare
from sparselt.methods import TIME_PHASES, method_class, method_names
from sparselt.methods.base import WARM_UP_SEED
from sparselt.methods.cosamp_reconstruction import image_from_samples, reconstruct_luminance, thesis_image_from_samples
from sparselt.methods.pixel_samples import PixelSamples

# Focused far behind the box (an aperture alone now focuses where the central ray hits): the statistics below
# were calibrated on this smoothly blurred image.
TINY = dict(scene="cornell-box", kind="dof", shape=(16, 16, 4, 4), aperture=0.1, focus_distance=1000.0,
            reference_spp=256)
#: The CoSaMP methods' options in these tests (K = 8 of N = 4096 fits the tiny budgets).
COSAMP_OPTIONS = {"gamma": 0.5, "sparsity": 8}


def tiny(**changes):
    """The tiny comparison; the CoSaMP methods among its methods get :data:`COSAMP_OPTIONS` unless told otherwise."""
    config = dataclasses.replace(ComparisonConfig(**TINY), **changes)
    if "options" not in changes:
        options = {name: dict(COSAMP_OPTIONS) for name in config.methods if name in ("cosamp", "cosamp-thesis")}
        config = dataclasses.replace(config, options=options)
    return config


def read_rows(folder):
    with open(folder / "results.csv", newline="") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        return header, [dict(zip(header, row)) for row in reader]


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return str(tmp_path_factory.mktemp("references"))


@pytest.fixture(scope="module")
def finished(tmp_path_factory, cache):
    out = tmp_path_factory.mktemp("compare") / "run"
    config = tiny(methods=("pt", "samples-mean", "cosamp", "cosamp-thesis"), spps=(4, 16), seeds=(1, 2))
    result = compare(config, out, progress=False, cache_directory=cache)
    return out, config, result


def test_results_csv_columns_rows_and_seconds(finished):
    out, config, _ = finished
    header, rows = read_rows(out)
    assert tuple(header[:len(RESULT_COLUMNS)]) == RESULT_COLUMNS
    ladder = json.loads((out / "compare.json").read_text())["pt_ladder"]
    pt_spps = set(config.spps) | set(ladder["spps"])
    assert len(rows) == (len(config.methods) - 1) * len(config.spps) * len(config.seeds) + len(pt_spps) * len(
        config.seeds)
    assert {(r["method"], int(r["spp"]), int(r["seed"])) for r in rows} == {
        (m, s, seed) for m in config.methods[1:] for s in config.spps for seed in config.seeds} | {
        ("pt", s, seed) for s in pt_spps for seed in config.seeds}
    for row in rows:
        phases = sum(float(row[f"seconds_{phase}"]) for phase in TIME_PHASES)
        assert float(row["seconds_total"]) == pytest.approx(phases, rel=1e-5, abs=1e-6)
        assert int(row["path_samples"]) == 16 * 16 * int(row["spp"])
        assert int(row["timing_repeats"]) == 3
        assert float(row["seconds_total_min"]) <= float(row["seconds_total"]) <= float(row["seconds_total_max"])
        assert 0 < float(row["luminance_ratio"]) < 3 and -1 <= float(row["ssim"]) <= 1


def test_outputs_and_provenance(finished):
    out, config, _ = finished
    for name in ("quality_vs_time.png", "image_grid.png", "crop_grid.png", "table_8.md", "compare.json"):
        assert (out / name).stat().st_size > 0
    for method in config.methods:
        for suffix in (".exr", ".png"):
            assert (out / "images" / f"{method}_spp16_seed2{suffix}").exists()
    assert (out / "images" / "reference.exr").exists()
    record = json.loads((out / "compare.json").read_text())
    assert record["status"] == "complete" and record["relmse_epsilon"] == 0.01
    assert record["config"]["methods"] == list(config.methods) and record["config"]["seeds"] == [1, 2]
    assert record["provenance"]["versions"]["mitsuba"] and "git" in record["provenance"]
    assert set(record["warm_up_seconds"]) == set(config.methods)
    table = (out / "table_8.md").read_text()
    assert "| SPP | Total | Sampling | Reconstruction | Integration |" in table


def test_samples_mean_is_the_mean_of_the_cosamp_samples(finished):
    """Same budget and seed: samples-mean and the control-variate correction agree on average."""
    out, _, _ = finished
    plain = np.load(out / "images" / "samples-mean_spp16_seed1.npy")
    corrected = np.load(out / "images" / "cosamp_spp16_seed1.npy")
    # The correction term has zero mean over pixels up to its own noise: image means within 5%.
    assert abs(corrected.mean() / plain.mean() - 1) < 0.05


def test_thesis_procedure_darkens_and_the_default_does_not(finished):
    _, _, result = finished
    by = {(r["method"], r["spp"], r["seed"]): r for r in result.rows}
    thesis = np.mean([by["cosamp-thesis", 16, s]["luminance_ratio"] for s in (1, 2)])
    default = np.mean([by["cosamp", 16, s]["luminance_ratio"] for s in (1, 2)])
    assert thesis < 0.9  # reproduced: "considerably darker" (8.1.2)
    assert abs(default - 1) < abs(thesis - 1)


def test_reference_is_cached_and_reused(tmp_path, finished, cache):
    out, _, first = finished
    # The module's first comparison renders the reference into the fresh cache; this one finds it.
    assert first.reference["cached"] is False
    cached_image = first.reference["path"]
    modified = os.stat(cached_image).st_mtime_ns
    result = compare(tiny(methods=("pt",), spps=(4,)), tmp_path / "again", progress=False, cache_directory=cache)
    assert result.reference["cached"] is True and result.reference["path"] == cached_image
    assert os.stat(cached_image).st_mtime_ns == modified
    record = json.loads((tmp_path / "again" / "compare.json").read_text())
    assert record["reference"]["cached"] is True


def test_pt_relmse_falls_with_spp(tmp_path, cache):
    """relMSE ~ 1/spp: at 64 spp it is below 4 spp by many standard errors (8 fixed seeds)."""
    seeds = tuple(range(1, 9))
    result = compare(tiny(methods=("pt",), spps=(4, 64), seeds=seeds, reference_spp=1024), tmp_path / "pt",
                     progress=False, cache_directory=cache)
    errors = {spp: np.array([r["relmse"] for r in result.rows if r["spp"] == spp]) for spp in (4, 64)}
    difference = errors[4].mean() - errors[64].mean()
    standard_error = math.sqrt(errors[4].var(ddof=1) / len(seeds) + errors[64].var(ddof=1) / len(seeds))
    assert difference > 5 * standard_error
    assert errors[64].mean() < errors[4].mean() / 4  # 16x the samples; reference noise keeps a floor


def test_resumed_comparison_equals_an_uninterrupted_one(tmp_path, finished, cache):
    out, config, _ = finished
    resumed = tmp_path / "resumed"
    compare(dataclasses.replace(config, spps=(4,), methods=("pt", "cosamp")), resumed, progress=False,
            cache_directory=cache)
    (resumed / "cells" / "cosamp_spp4_seed2.json").unlink()  # as if killed before that cell was recorded
    compare(config, resumed, progress=False, cache_directory=cache)
    _, full_rows = read_rows(out)
    _, resumed_rows = read_rows(resumed)
    key = lambda r: (r["method"], r["spp"], r["seed"])  # noqa: E731
    # PT's ladder follows measured times, so its length may differ between runs; the configured cells may not.
    configured = {(m, str(s), str(seed)) for m in config.methods for s in config.spps for seed in config.seeds}
    full_rows = [row for row in full_rows if key(row) in configured]
    resumed_rows = [row for row in resumed_rows if key(row) in configured]
    assert sorted(map(key, full_rows)) == sorted(map(key, resumed_rows)) == sorted(configured)
    for method in config.methods:
        for spp in config.spps:
            for seed in config.seeds:
                name = f"{method}_spp{spp}_seed{seed}.npy"
                np.testing.assert_array_equal(np.load(out / "images" / name), np.load(resumed / "images" / name))
    quality = {key(r): (r["ssim"], r["relmse"], r["luminance_ratio"]) for r in full_rows}
    assert all(quality[key(r)] == (r["ssim"], r["relmse"], r["luminance_ratio"]) for r in resumed_rows)


def sparse_positive_signal(shape, terms, seed):
    """A real, non-negative 4-D signal with exactly ``terms`` conjugate pairs plus the mean."""
    rng = np.random.default_rng(seed)
    size = math.prod(shape)
    spectrum = np.zeros(size, dtype=np.complex128)
    chosen = rng.choice(np.arange(1, size), size=terms, replace=False)
    spectrum[chosen] = rng.standard_normal(terms) + 1j * rng.standard_normal(terms)
    signal = np.fft.ifftn(spectrum.reshape(shape)).real
    signal = signal - signal.min() + 0.1 * np.abs(signal).max()
    return signal / signal.max()


def test_cosamp_pipeline_recovers_an_exactly_sparse_signal():
    """Synthetic K-sparse luminance fed through the method's pipeline (gamma 1) is recovered exactly."""
    shape = (16, 16, 8, 8)
    truth = sparse_positive_signal(shape, terms=12, seed=3)
    spectrum = np.abs(np.fft.fftn(truth))
    sparsity = int(np.count_nonzero(spectrum > 1e-9 * spectrum.max()))
    assert 13 <= sparsity <= 25  # 12 conjugate pairs (or self-conjugate entries) and the mean
    rng = np.random.default_rng(4)
    spp = 16
    pixels = 16 * 16
    # Samples as the renderer draws them: pixel-major, each at a random cell of its pixel.
    x, y = np.meshgrid(np.arange(16), np.arange(16))  # row-major pixels: y rows
    pixel_cell = (x.reshape(-1) * 16 + y.reshape(-1)) * 64
    cells = np.repeat(pixel_cell, spp) + rng.integers(0, 64, size=pixels * spp)
    values = np.repeat(truth.reshape(-1)[cells][:, None], 3, axis=1).astype(np.float32)
    samples = PixelSamples(values=values, cells=cells, spp=spp, resolution=(16, 16), nonfinite=0)
    measured, counts = np.unique(cells, return_counts=True)
    reconstruction, result = reconstruct_luminance(measured, truth.reshape(-1)[measured] / 1.0, shape, gamma=1.0,
                                                   sparsity=sparsity, dtype=np.float64)
    assert result.stop_reason == "converged"
    np.testing.assert_allclose(reconstruction, truth, atol=1e-6)
    exact = truth.reshape(16, 16, -1).mean(axis=2).T
    image, details = thesis_image_from_samples(samples, shape, gamma=1.0, sparsity=sparsity)
    assert details["cosamp_stop_reason"] == "converged"
    np.testing.assert_allclose(image[..., 1], exact, rtol=1e-4)
    # Cross-fitted control variate: each fold alone recovers the signal, which then explains every sample.
    image, details = image_from_samples(samples, shape, gamma=1.0, sparsity=sparsity)
    assert [fold["cosamp_stop_reason"] for fold in details["folds"]] == ["converged", "converged"]
    assert details["control_variate_coefficient"] == pytest.approx(1.0, abs=1e-4)
    np.testing.assert_allclose(image[..., 1], exact, rtol=1e-4)


def test_the_registry_lists_exactly_the_methods_the_readme_documents():
    """Every built-in method (registered from ``sparselt.methods``) is in the README's method table, and every name
    the table gives is registered: adding, renaming or removing a method without its documentation fails here."""
    from sparselt.methods.registry import method_source

    with open(os.path.join(os.path.dirname(__file__), os.pardir, "README.md"), encoding="utf-8") as handle:
        readme = handle.read()
    table = readme.split("| method | what it is |\n|---|---|\n", 1)[1].split("\n\n", 1)[0]
    documented = {name for line in table.splitlines() for name in re.findall(r"`([a-z0-9-]+)`", line.split(" | ")[0])}
    built_in = {name for name in method_names() if method_source(name).startswith("sparselt.methods.")}
    assert documented == built_in


def test_an_unknown_method_is_refused_with_every_registered_name():
    with pytest.raises(ValueError, match="unknown method 'magic'") as raised:
        compare(tiny(methods=("pt", "magic")), "unused", progress=False)
    listed = str(raised.value).split("registered methods: ")[1].split(" (")[0].split(", ")
    assert listed == sorted(method_names())


BAD = [
    (dict(kind="path", shape=(16, 16, 4, 4, 4, 4, 4, 4, 4, 4), methods=("cosamp",)), "does not support kind 'path'"),
    (dict(spps=(0,)), "spp must be"),
    (dict(spps=(-3,)), "spp must be"),
    (dict(shape=(16, 16, 4)), "has 3 axes but kind 'dof'"),
    (dict(methods=("cosamp",), resolution=(24, 24)), "multiple of the shape's image axes"),
    (dict(kind="fog"), "compare supports kinds"),
    (dict(methods=("pt", "pt")), "repeat"),
]


@pytest.mark.parametrize("changes, message", BAD)
def test_bad_configuration_is_refused_before_anything_is_written(tmp_path, changes, message):
    out = tmp_path / "out"
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        compare(tiny(**changes), out, progress=False)
    assert not out.exists()


def test_folder_of_another_comparison_is_refused_and_kept(finished, cache):
    out, _, _ = finished
    before = sorted(p.name for p in (out / "cells").iterdir())
    with pytest.raises(ValueError, match="holds another compare run.*method_options.cosamp: .*gamma.*0.5.*recorded"):
        compare(tiny(options={"cosamp": {"gamma": 0.25, "sparsity": 8}}), out, progress=False, cache_directory=cache)
    assert sorted(p.name for p in (out / "cells").iterdir()) == before


def test_cli_reports_errors_with_exit_code(tmp_path, capsys):
    code = main(["compare", "--scene", "cornell-box", "--kind", "dof", "--aperture", "0.1", "--shape", "16,16,4,4",
                 "--methods", "pt,nope", "--spp", "4", "--out", str(tmp_path / "x"), "--no-progress"])
    assert code == 2
    assert "registered methods" in capsys.readouterr().err


def test_cosamp_control_variate_is_unbiased(tmp_path, cache):
    """Per seed, cosamp minus samples-mean (same samples) has zero mean: |mean| < 4 standard errors."""
    seeds = tuple(range(1, 11))
    # PT's ladder is not what this tests: capped low, it costs a fraction of the ten seeds' time.
    result = compare(tiny(methods=("samples-mean", "cosamp"), spps=(8,), seeds=seeds, timing_repeats=1,
                          options={"cosamp": {"sparsity": 100}}, pt_ladder_max_spp=16), tmp_path / "unbiased",
                     progress=False, cache_directory=cache)
    ratio = {(r["method"], r["seed"]): r["luminance_ratio"] for r in result.rows}
    differences = np.array([ratio["cosamp", s] - ratio["samples-mean", s] for s in seeds])
    standard_error = differences.std(ddof=1) / math.sqrt(len(seeds))
    assert standard_error > 0
    assert abs(differences.mean()) < 4 * standard_error, differences


def test_noise_sigma_is_the_median_standard_error_of_the_pixel_means():
    from sparselt.methods.filtered import noise_sigma

    rng = np.random.default_rng(12)
    values = (rng.random((6 * 5 * 7, 3)) ** 3).astype(np.float32)
    samples = PixelSamples(values=values, cells=np.zeros(len(values), dtype=np.int64), spp=7, resolution=(6, 5),
                           nonfinite=0)
    per_pixel = values.reshape(5, 6, 7, 3).astype(np.float64)
    expected = np.median(np.sqrt(per_pixel.var(axis=2, ddof=1).sum(axis=-1) / 7))
    assert noise_sigma(samples) == pytest.approx(expected, rel=1e-9)


def test_each_budget_is_run_once_untimed_before_its_first_timed_run(tmp_path, cache, monkeypatch):
    """A budget's first run in a process takes fresh memory (measured: up to 2x the later runs' time), so every
    (row, spp) runs once at the warm-up seed before its first timed run, once per command, PT's rungs included;
    its seconds go to the row's warm-up time, never to a cell."""
    calls = []
    for name in ("pt", "samples-mean"):
        method = method_class(name)

        def logged(self, context, budget, timer, run=method.run, name=name):
            calls.append((name, budget.spp, budget.seed))
            return run(self, context, budget, timer)

        monkeypatch.setattr(method, "run", logged)
    config = tiny(methods=("pt", "samples-mean"), spps=(4, 8), seeds=(1, 2), timing_repeats=2)
    out = tmp_path / "budgets"
    compare(config, out, progress=False, cache_directory=cache)
    timed = [call for call in calls if call[2] != WARM_UP_SEED]
    budgets = {(name, spp) for name, spp, _ in timed}
    assert {spp for name, spp in budgets if name == "pt"} - set(config.spps)  # PT's rungs beyond the budgets too
    for name, spp in budgets:
        first_timed = next(index for index, call in enumerate(calls) if call[:2] == (name, spp)
                           and call[2] != WARM_UP_SEED)
        warmed = [index for index, call in enumerate(calls) if call == (name, spp, WARM_UP_SEED)]
        # Before the first timed run, never after it (the method's own warm-up may have run this spp too).
        assert warmed and max(warmed) < first_timed, (name, spp, calls)
    record = json.loads((out / "compare.json").read_text())
    assert set(record["warm_up_seconds"]) == {"pt", "samples-mean"}
    # A rerun in a new process finds every cell done: nothing runs, nothing is warmed.
    calls.clear()
    compare(config, out, progress=False, cache_directory=cache)
    assert calls == []


def test_a_timed_run_starts_after_the_last_runs_garbage_is_freed_by_a_young_collection(tmp_path, cache,
                                                                                        monkeypatch):
    """Before each timed run the harness frees what earlier runs left in reference cycles (so a run does not pay
    for them), and does so with a collection of the young generations: a full one scans every live object of
    the process (0.13 s per cell on a comparison's heap, measured)."""
    class Cycle:
        def __init__(self):
            self.itself = self

    left = []  # weak references to each run's cyclic garbage
    observed = []  # per run: (every earlier run's garbage freed, the generation of the last collection before it)
    collections = []
    method = method_class("samples-mean")

    def leaving_a_cycle(self, context, budget, timer, run=method.run):
        observed.append((all(reference() is None for reference in left), collections[-1] if collections else None))
        left.append(weakref.ref(Cycle()))
        return run(self, context, budget, timer)

    def record(phase, info):
        if phase == "start":
            collections.append(info["generation"])

    monkeypatch.setattr(method, "run", leaving_a_cycle)
    gc.callbacks.append(record)
    try:
        compare(tiny(methods=("samples-mean",), spps=(4,), seeds=(1, 2), timing_repeats=2, pt_ladder_max_spp=8),
                tmp_path / "garbage", progress=False, cache_directory=cache)
    finally:
        gc.callbacks.remove(record)
    assert len(observed) >= 4  # the warm-ups and four timed repeats
    assert all(freed for freed, _ in observed), observed
    timed = observed[-4:]  # the warm-up runs come first
    assert all(generation is not None and generation < 2 for _, generation in timed), timed


def test_timing_repeats_run_in_rounds_and_an_interrupted_run_resumes_between_them(tmp_path, cache, monkeypatch):
    """Each cell's repeats are spread over the run (PT's rungs between them), each repeat is kept as it
    finishes, and a run stopped mid-round resumes without running a finished repeat again."""
    calls = []
    stop_at = {"call": 4}
    for name in ("pt", "samples-mean"):
        method = method_class(name)

        def logged(self, context, budget, timer, run=method.run, name=name):
            calls.append((name, budget.spp, budget.seed))
            if len(calls) == stop_at["call"]:
                raise RuntimeError("stopped")
            return run(self, context, budget, timer)

        monkeypatch.setattr(method, "run", logged)
    config = tiny(methods=("pt", "samples-mean"), spps=(4,), seeds=(1,), timing_repeats=3)
    out = tmp_path / "rounds"
    with pytest.raises(RuntimeError, match="stopped"):
        compare(config, out, progress=False, cache_directory=cache)
    interrupted = list(calls)
    stop_at["call"] = -1
    compare(config, out, progress=False, cache_directory=cache)
    resumed = calls[len(interrupted):]
    # The interrupted call never finished; every other run happened exactly once over the two commands.
    warm_up_seed = WARM_UP_SEED  # each command warms each method up once (not a cell's run)
    finished = [call for call in interrupted[:-1] + resumed if call[2] != warm_up_seed]
    cells = {call: finished.count(call) for call in finished}
    assert set(cells.values()) == {3}, cells
    positions = [index for index, call in enumerate(finished) if call[0] == "samples-mean"]
    assert positions[-1] - positions[0] > len(positions)  # not back to back: PT's rungs ran between them
    # Between samples-mean's first two repeats: round 1's PT cells (its budget, then the ladder in search order),
    # then round 2's, which runs the plan backwards: the plan is PT's budgets, then the ladder's rungs sorted by spp
    # (a downward extension to 1 spp is searched last but planned first).
    between = finished[positions[0] + 1:positions[1]]
    assert between and all(call[0] == "pt" for call in between) and len(between) % 2 == 0, between
    first_round, second_round = between[:len(between) // 2], between[len(between) // 2:]
    assert sorted(first_round) == sorted(second_round)
    budgets = [call for call in first_round if call[1] in config.spps]
    rungs = sorted((call for call in first_round if call[1] not in config.spps), key=lambda call: call[1])
    assert second_round == (budgets + rungs)[::-1]  # round 2 runs round 1's plan backwards
    for name in cells:
        record = json.loads((out / "cells" / f"{name[0]}_spp{name[1]}_seed{name[2]}.json").read_text())
        assert len(record["repeat_totals"]) == 3 and record["row"]["timing_repeats"] == 3
        assert record["row"]["seconds_total"] == pytest.approx(float(np.median(record["repeat_totals"])))
