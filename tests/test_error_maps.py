"""Per-pixel error maps at matched time (``error_maps.png``): relMSE's terms, one shared log colour scale.

The maps are :func:`sparselt.analysis.metrics.pixel_relative_squared_error`
of the image grid's rows (:func:`sparselt.report.comparison_rows.matched_rows`);
their means are the rows' relMSE. One tiny real comparison checks the figure
is written, listed in the manifest and shown on ``index.html``.
"""

import csv
import dataclasses
import json

import numpy as np
import pytest

from sparselt.analysis.metrics import (
    pixel_relative_squared_error,
    relative_mean_squared_error,
)
from sparselt.experiments.quality import RELMSE_EPSILON
from sparselt.report.comparison_figures import (
    ERROR_SCALE_PERCENTILES,
    error_map_figure,
    error_maps,
    matched_pictures,
    shared_error_scale,
)
from sparselt.report.comparison_rows import matched_rows
from sparselt.storage.folder import MANIFEST_FILE


def _rows():
    """Two methods, two budgets, two seeds; 'slow' has no run as fast as 'fast''s shortest."""
    rows = []
    for method, factor in (("fast", 1.0), ("slow", 3.0)):
        for spp in (4, 16):
            for seed in (2, 1):
                rows.append({"method": method, "spp": spp, "seed": seed, "seconds_total": factor * spp / 4,
                             "relmse": 0.1, "ssim": 0.5, "luminance_ratio": 1.0})
    return rows


def _images(rows, shape=(12, 10, 3), seed=0):
    rng = np.random.default_rng(seed)
    reference = rng.random(shape)
    images = {(row["method"], row["spp"], row["seed"]): reference + rng.normal(0, 0.05 * row["spp"], shape)
              for row in rows}
    return reference, (lambda row: images[row["method"], row["spp"], row["seed"]])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_maps_mean_is_relmse_for_a_random_pair(seed):
    rng = np.random.default_rng(seed)
    reference = rng.lognormal(size=(17, 13, 3))
    image = reference + rng.normal(size=reference.shape)
    error = pixel_relative_squared_error(image, reference, epsilon=RELMSE_EPSILON)
    assert error.shape == (17, 13)
    assert float(np.mean(error)) == pytest.approx(
        relative_mean_squared_error(image, reference, epsilon=RELMSE_EPSILON), rel=1e-12)


def test_the_map_against_a_loop_over_pixels():
    """Golden values from plain loops: per pixel, the mean over channels of (x - y)^2 over mean_c y^2 + 0.01."""
    rng = np.random.default_rng(3)
    reference, image = rng.random((3, 2, 3)), rng.random((3, 2, 3))
    error = pixel_relative_squared_error(image, reference, epsilon=0.01)
    for row in range(3):
        for column in range(2):
            denominator = sum(reference[row, column, channel] ** 2 for channel in range(3)) / 3 + 0.01
            expected = sum((image[row, column, channel] - reference[row, column, channel]) ** 2
                           for channel in range(3)) / 3 / denominator
            assert error[row, column] == pytest.approx(expected, rel=1e-12)


def test_error_maps_are_the_image_grids_cells():
    rows = _rows()
    reference, image_of = _images(rows)
    matched, target, pictures = matched_pictures(rows, reference, image_of)
    assert (matched, target) == matched_rows(rows)
    maps = error_maps(matched, reference, image_of, epsilon=RELMSE_EPSILON)
    assert len(maps) == len(matched) == len(pictures) - 1
    for row, error in zip(matched, maps):
        assert row["seed"] == 1  # the image grid's seed: the smallest
        assert float(np.mean(error)) == pytest.approx(
            relative_mean_squared_error(image_of(row), reference, epsilon=RELMSE_EPSILON), rel=1e-12)


def test_the_scale_is_shared_over_all_maps():
    rng = np.random.default_rng(4)
    small, large = rng.uniform(1e-4, 1e-3, (20, 20)), rng.uniform(1.0, 10.0, (20, 20))
    small[0, 0] = 0.0  # zeros cannot be shown on a log scale: left out of the percentiles
    low, high = shared_error_scale([small, large])
    together = np.concatenate([small.ravel()[1:], large.ravel()])
    assert (low, high) == pytest.approx(tuple(np.percentile(together, ERROR_SCALE_PERCENTILES)))
    assert low < 1e-3 and high > 1.0  # spans both maps, unlike either map's own scale
    assert shared_error_scale([large, small]) == (low, high)  # independent of the panels' order
    assert shared_error_scale([small]) != (low, high)


def test_every_panel_uses_the_one_scale_and_the_bar_names_epsilon():
    rows = _rows()
    reference, image_of = _images(rows)
    matched, target, _ = matched_pictures(rows, reference, image_of)
    maps = error_maps(matched, reference, image_of, epsilon=RELMSE_EPSILON)
    figure = error_map_figure(matched, target, maps, epsilon=RELMSE_EPSILON)
    low, high = shared_error_scale(maps)
    images = [axis.images[0] for axis in figure.axes if axis.images]
    assert len(images) == len(matched)
    for image in images:
        assert (image.norm.vmin, image.norm.vmax) == pytest.approx((low, high))
        assert type(image.norm).__name__ == "LogNorm"
    labels = [axis.get_ylabel().replace("\n", " ") for axis in figure.axes]
    assert "relative squared error (ε = 0.01)" in labels
    titles = [axis.get_title() for axis in figure.axes if axis.images]
    for row, error, title in zip(matched, maps, titles):
        assert title.splitlines()[0] == row["method"] and f"{row['spp']} spp" in title
        assert f"relMSE {float(np.mean(error)):.3g}" in title and " s" in title


def test_the_scale_of_a_constant_or_zero_error():
    low, high = shared_error_scale([np.full((4, 4), 0.5)])
    assert low < 0.5 < high and high / low == pytest.approx(10.0)
    assert shared_error_scale([np.zeros((4, 4))]) == (1e-6, 1e-5)


def test_the_scale_rejects_no_maps():
    with pytest.raises(ValueError, match="at least one error map"):
        shared_error_scale([])


@pytest.mark.parametrize("percentiles", [(50.0, 50.0), (-1.0, 99.0), (1.0, 101.0)])
def test_the_scale_rejects_bad_percentiles(percentiles):
    with pytest.raises(ValueError, match="0 <= lower < upper <= 100"):
        shared_error_scale([np.ones((2, 2))], percentiles=percentiles)


def test_the_figure_rejects_no_rows():
    with pytest.raises(ValueError, match="at least one matched row"):
        error_map_figure([], 1.0, [], epsilon=0.01)


def test_the_figure_rejects_a_map_count_that_is_not_the_rows():
    rows = _rows()
    matched, target = matched_rows(rows)
    with pytest.raises(ValueError, match="one map per matched row"):
        error_map_figure(matched, target, [np.ones((2, 2))], epsilon=0.01)


def test_a_small_comparison_writes_the_error_maps_and_its_page_shows_them(tmp_path):
    from sparselt.experiments.compare import ComparisonConfig, compare

    config = dataclasses.replace(ComparisonConfig(
        scene="cornell-box", kind="dof", shape=(16, 16, 4, 4), aperture=0.1, focus_distance=1000.0,
        reference_spp=256), methods=("pt", "samples-mean"), spps=(4,), seeds=(1,))
    out = tmp_path / "run"
    compare(config, out, progress=False, cache_directory=str(tmp_path / "references"))
    assert (out / "error_maps.png").stat().st_size > 0
    assert "error_maps.png" in json.loads((out / MANIFEST_FILE).read_text())["files"]
    page = (out / "index.html").read_text()
    assert 'src="error_maps.png"' in page and "one logarithmic colour scale shared by all panels" in page
    assert page.index('src="image_grid.png"') < page.index('src="error_maps.png"') < page.index('src="crop_grid.png"')
    # The panels' relMSE are the rows' (the maps are relMSE's terms of the image grid's cells).
    with open(out / "results.csv", newline="") as handle:
        rows = [dict(row, spp=int(row["spp"]), seed=int(row["seed"]), seconds_total=float(row["seconds_total"]))
                for row in csv.DictReader(handle)]
    matched, _ = matched_rows(rows)
    reference = np.load(out / "images" / "reference.npy")
    for row in matched:
        image = np.load(out / "images" / f"{row['method']}_spp{row['spp']}_seed{row['seed']}.npy")
        error = pixel_relative_squared_error(image, reference, epsilon=RELMSE_EPSILON)
        assert float(np.mean(error)) == pytest.approx(float(row["relmse"]), rel=1e-4)
