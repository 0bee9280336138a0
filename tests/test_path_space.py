"""Issue 13: the Sparse Fourier Transform with the renderer as its oracle (thesis 6.1, 6.2)."""

import math

import numpy as np
import pytest

from sparselt.experiments.compare import ComparisonConfig, compare
from sparselt.experiments.sft_path_space import Table61Config, validate
from sparselt.fourier.sparse import SparseFourier
from sparselt.recovery.lattice import lattice_points
from sparselt.recovery.path_space import CellOracle, lattice_image, largest_energy_fraction, sft_path_space
from sparselt.rendering.acquire import AcquisitionConfig, acquire_signal
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import MitsubaScene

SHAPE = (16, 16) + (2,) * 8


@pytest.fixture(scope="module")
def rendered(cornell):
    scene = MitsubaScene(cornell, SHAPE[:2])
    return scene, path_layout("path", 3, thin_lens=scene.camera.thin_lens)


def test_lattice_point_j_lies_in_cell_j():
    """The rank-1 lattice (eq. 6.1) visits the grid cells in C order: point j is in cell j."""
    shape = (5, 3, 4, 2)
    size = math.prod(shape)
    points = lattice_points(shape, np.arange(size))
    cells = np.floor(points * np.asarray(shape)).astype(int)
    assert np.array_equal(np.ravel_multi_index(cells.T, shape), np.arange(size))


def test_oracle_reads_the_sample_signal_of_the_same_cell(rendered, cornell):
    """Same seed and spp: the oracle's value is the `sample` signal's cell, bit for bit (same random numbers)."""
    scene, layout = rendered
    signal = acquire_signal(AcquisitionConfig(scene="cornell-box", kind="path", shape=SHAPE, spp=8, seed=3),
                            progress=False, scene_spec=cornell)
    flat = np.asarray(signal.data).reshape(-1, 3)
    cells = np.random.default_rng(0).choice(flat.shape[0], 2000, replace=False)
    oracle = CellOracle(lambda c: scene.sample_cells(layout, SHAPE, 0, 0, 8, 3, cells=c), SHAPE, 8)
    assert np.array_equal(oracle.read(cells).astype(np.float32), flat[cells])


def test_oracle_with_another_seed_agrees_within_standard_errors(rendered, cornell):
    """Independent samples of the same cells: the mean difference is zero within 3 standard errors."""
    scene, layout = rendered
    cells = np.arange(0, math.prod(SHAPE), 7)
    first = CellOracle(lambda c: scene.sample_cells(layout, SHAPE, 0, 0, 16, 11, cells=c), SHAPE, 16).read(cells)
    second = CellOracle(lambda c: scene.sample_cells(layout, SHAPE, 0, 0, 16, 12, cells=c), SHAPE, 16).read(cells)
    difference = (first - second).mean(axis=1)
    standard_error = difference.std(ddof=1) / math.sqrt(difference.size)
    assert standard_error > 0 and abs(difference.mean()) < 3 * standard_error


def test_every_path_sample_is_counted_exactly_once(rendered):
    scene, layout = rendered
    evaluated = []

    def evaluate(cells):
        evaluated.append(np.asarray(cells).copy())
        return scene.sample_cells(layout, SHAPE, 0, 0, 2, 5, cells=cells)

    result = sft_path_space(evaluate, SHAPE, 40, 2, alpha=4, snr=10, seed=2, batch_cells=5000)
    drawn = np.concatenate(evaluated)
    assert np.unique(drawn).size == drawn.size  # no cell rendered twice, across the three channels' SFTs
    assert result.cells == drawn.size and result.path_samples == 2 * drawn.size
    assert result.support_samples + result.magnitude_samples == result.path_samples
    assert max(len(batch) for batch in evaluated) <= 5000


def _trigonometric_scene(shape, terms, seed=1):
    """A synthetic 'scene': cell values whose C-order flattening is a real trigonometric polynomial."""
    size = math.prod(shape)
    rng = np.random.default_rng(seed)
    frequencies = rng.choice(np.arange(1, size // 2), terms, replace=False)
    spectrum = np.zeros(size, complex)
    spectrum[frequencies] = rng.normal(size=terms) + 1j * rng.normal(size=terms)
    spectrum[(-frequencies) % size] = np.conj(spectrum[frequencies])
    spectrum[0] = 3.0 * size
    line = np.fft.ifft(spectrum).real
    return np.stack([line, 0.5 * line, 2.0 * line], axis=-1).reshape(tuple(shape) + (3,))


def test_sft_through_the_oracle_recovers_a_trigonometric_scene_exactly():
    shape = (32, 32, 4, 4, 4, 4)
    cells = _trigonometric_scene(shape, 20)
    flat = cells.reshape(-1, 3)
    result = sft_path_space(lambda c: (flat[c], np.zeros(len(c), int)), shape, 41, 3, snr=np.inf, seed=4)
    assert result.cells < 0.25 * flat.shape[0]  # sparse: a fraction of the lattice is read
    assert np.allclose(result.signal(), cells, atol=1e-9 * np.abs(cells).max())
    expected = cells.reshape(32, 32, -1, 3).mean(axis=2).transpose(1, 0, 2)
    assert np.allclose(result.image(), expected, rtol=1e-5, atol=1e-6)


def test_lattice_image_is_the_mean_over_the_non_image_axes_for_any_signal():
    shape = (6, 5, 3, 4)
    values = np.random.default_rng(2).normal(size=shape)
    spectrum = np.fft.fft(values.reshape(-1))
    keep = np.flatnonzero(spectrum)
    image = lattice_image(SparseFourier((values.size,), keep, spectrum[keep]), shape)
    assert np.allclose(image, values.reshape(6, 5, -1).mean(axis=2).T)


def test_compressibility_is_one_for_a_sparse_signal_and_small_for_noise():
    sparse = _trigonometric_scene((16, 16, 4, 4), 10)[..., 0]
    assert largest_energy_fraction(sparse, 20) == pytest.approx(1.0)
    noise = np.random.default_rng(3).normal(size=(16, 16, 4, 4))
    share = 41 / noise.size  # white noise: exponential energies, the top share q holds q (1 + ln 1/q) of them
    assert largest_energy_fraction(noise, 41) < 2 * share * (1 + math.log(1 / share))


@pytest.mark.parametrize("changes, error, message", [
    (dict(kind="volumes"), ValueError, "unknown signal kind .volumes.; choose one of path"),
    (dict(shape=(8,)), ValueError, "image-plane"),
    (dict(shape=(8, 8, 2, 2)), ValueError, "at least 11x11"),
    (dict(shape=(2**16, 2**16)), ValueError, "2\\*\\*31"),
    (dict(spp=0), ValueError, "samples per lattice point"),
    (dict(alphas=(0.5,)), ValueError, "alpha must be at least 1"),
    (dict(alphas=()), ValueError, "at least one alpha"),
    (dict(sparsity=10**6), ValueError, "sparsity"),
    (dict(spp=1.5), TypeError, "samples per lattice point"),
])
def test_bad_table61_input_is_refused_before_sampling(changes, error, message):
    config = Table61Config(**dict(dict(scene="cornell-box", shape=SHAPE), **changes))
    with pytest.raises(error, match=message):
        validate(config)


def test_sft_path_space_refuses_bad_input_before_sampling():
    def never(cells):
        raise AssertionError("sampled")

    for arguments, message in (((SHAPE, 40, 0), "samples per lattice point"), ((SHAPE, 10**6, 1), "sparsity"),
                               (((8,), 1, 1), "image-plane")):
        with pytest.raises(ValueError, match=message):
            sft_path_space(never, *arguments)
    with pytest.raises(ValueError, match="alpha"):
        sft_path_space(never, SHAPE, 40, 1, alpha=0.5)


def test_compare_method_sft_records_its_samples(tmp_path):
    config = ComparisonConfig(scene="cornell-box", kind="path", shape=SHAPE, methods=("pt", "sft"), spps=(1,),
                              seeds=(1,), timing_repeats=1, pt_ladder_max_spp=16, reference_spp=64,
                              options={"sft": {"sparsity": 30}})
    result = compare(config, tmp_path / "c", progress=False)
    row = next(row for row in result.rows if row["method"] == "sft")
    assert 0 < row["path_samples"] <= math.prod(SHAPE)
    assert row["seconds_sampling"] > 0 and row["seconds_reconstruction"] > 0
    assert np.isfinite(row["relmse"])


def test_guided_sft_counts_its_map_samples(tmp_path):
    config = ComparisonConfig(scene="cornell-caustics", kind="path", shape=SHAPE, methods=("guided-sft",), spps=(2,),
                              resolution=(32, 32), reference_spp=64, seeds=(1,), timing_repeats=1,
                              options={"guided-sft": {"sparsity": 30, "map_spp": 1, "mode": "global"}})
    result = compare(config, tmp_path / "g", progress=False)
    row = next(row for row in result.rows if row["method"] == "guided-sft")
    assert row["path_samples"] > 32 * 32 * 2  # the SFT's lattice samples come on top of the render's
    assert np.isfinite(row["relmse"])


def test_table61_command_writes_the_table_beside_the_thesis(tmp_path):
    from sparselt.cli import main

    out = tmp_path / "t"
    arguments = ["table61", "--scene", "cornell-box", "--shape", "12,12,2,2,2,2,2,2,2,2", "--alpha", "4",
                 "--noise-spp", "2", "--sparsity", "8", "--reference-spp", "32", "--compressibility-shape",
                 "4,4,2,2,2,2,2,2,2,2", "--out", str(out), "--no-progress"]
    assert main(arguments) == 0
    table = (out / "table_6_1.md").read_text()
    assert "| 717225300 |" in table  # thesis Table 6.1, alpha 4: total samples, beside ours
    rows = (out / "table_6_1.csv").read_text().strip().splitlines()
    assert len(rows) == 3 and rows[1].startswith("4.0,1,")  # alpha 4 at 1 and 2 samples per point
    assert (out / "figure_6_1.png").exists() and (out / "compressibility.md").exists()
    stamp = (out / "cells" / "alpha4_spp1.json").stat().st_mtime_ns
    assert main(arguments) == 0  # resumes: nothing recomputed
    assert (out / "cells" / "alpha4_spp1.json").stat().st_mtime_ns == stamp


@pytest.mark.parametrize("dense", [True, False], ids=["dense-slot-table", "sorted-indices"])
def test_indexed_values_reads_each_index_once_in_both_modes(monkeypatch, dense):
    from sparselt.recovery import sample_cache

    monkeypatch.setattr(sample_cache, "DENSE_LIMIT", 10**6 if dense else 10)
    store = sample_cache.IndexedValues(1000, (3,), np.float64)
    assert store.dense is dense
    rng = np.random.default_rng(0)
    truth = rng.normal(size=(1000, 3))
    for _ in range(5):
        asked = rng.integers(0, 1000, 300)  # repeats and indices read before
        missing = store.missing(asked)
        assert np.all(np.diff(missing) > 0) and not np.isin(missing, store.indices).any()
        store.add(missing, truth[missing])
        assert np.array_equal(store.get(asked), truth[asked])
    assert np.unique(store.indices).size == store.count
