"""Guided rendering (thesis 6.2, 8.3, 8.4): the in-kernel warp follows the map, the estimator is unbiased."""

import json
import math

import numpy as np
import pytest

from chi_square import chi_square_p_value, sidak_threshold
from sparselt.guiding import ImportanceMap
from sparselt.methods import Budget, ComparisonContext
from sparselt.methods.guided import render_with_map
from sparselt.rendering.mitsuba import MitsubaScene, initialize, warp_points
from sparselt.rendering.mitsuba.guided import GUIDED_STREAM, film_pixel, global_order, warp_axes
from sparselt.rendering.mitsuba.lanes import item_lanes
from sparselt.rendering.layout import path_layout
from sparselt.rendering.scenes import get_scene

MAP_SHAPES = [(9,), (6, 5), (4, 4, 3), (4, 3, 3, 4)]


def peaky(shape, seed):
    rng = np.random.default_rng(seed)
    values = rng.random(shape) ** 6
    values[rng.random(shape) < 0.3] = 0.0
    return values


@pytest.mark.parametrize("shape", MAP_SHAPES)
def test_in_kernel_warp_draws_cells_with_the_map_probabilities(shape):
    """Chi-square (Sidak-corrected over the shapes) on the cells the Dr.Jit warp picks."""
    importance = ImportanceMap(peaky(shape, len(shape)), defensive=0.02)
    count = 200_000
    uniforms = np.random.default_rng(7).random((count, len(shape)))
    points, cells = warp_points(shape, importance.level_tables(), uniforms)
    assert np.all((points >= 0) & (points < 1))
    np.testing.assert_array_equal(cells, importance.cells_of(points))
    observed = np.bincount(cells, minlength=importance.size)
    assert chi_square_p_value(observed, count * importance.pdf.ravel()) > sidak_threshold(len(MAP_SHAPES) + 1)


def test_in_kernel_conditional_warp_given_image_cells():
    shape = (3, 2, 4, 4)
    importance = ImportanceMap(peaky(shape, 11), defensive=0.05)
    count = 100_000
    image_cell = 4
    uniforms = np.random.default_rng(8).random((count, 2))
    points, cells = warp_points(shape, importance.level_tables(), uniforms,
                                                image_cells=np.full(count, image_cell))
    assert np.all(cells // 16 == image_cell)
    expected = importance.pdf.reshape(6, 16)[image_cell]
    observed = np.bincount(cells % 16, minlength=16)
    assert chi_square_p_value(observed, count * expected / expected.sum()) > sidak_threshold(len(MAP_SHAPES) + 1)


@pytest.fixture(scope="module", params=["cornell-box", "cornell-caustics"])
def path_context(request):
    scene = MitsubaScene(get_scene(request.param), (24, 24))
    grid = (12, 12) + (2,) * 8
    return ComparisonContext(scene=scene, layout=path_layout("path", 3), kind="path", grid_shape=grid,
                             resolution=(24, 24), max_depth=3)


@pytest.mark.parametrize("mode", ["per-pixel", "global"])
@pytest.mark.parametrize("defensive", [0.0, 0.3])
def test_guided_mean_equals_the_unguided_mean(path_context, mode, defensive):
    """Image mean of guided renders (random peaky map) within 4 standard errors of plain path tracing."""
    from sparselt.methods.pixel_samples import draw_pixel_samples

    values = peaky(path_context.grid_shape, 3) + (0.05 if defensive == 0.0 else 0.0)  # no zero cells without mixture
    importance = ImportanceMap(values, defensive=defensive)
    seeds = range(1, 9)
    guided = np.array([render_with_map(path_context, importance, Budget(32, seed), mode)[0].mean() for seed in seeds])
    plain = np.array([draw_pixel_samples(path_context, Budget(32, 100 + seed)).pixel_means().mean() for seed in seeds])
    standard_error = math.sqrt(guided.var(ddof=1) / len(seeds) + plain.var(ddof=1) / len(seeds))
    assert abs(guided.mean() - plain.mean()) < 4 * standard_error, (guided.mean(), plain.mean(), standard_error)


def test_uniform_map_reproduces_path_tracing_exactly_in_distribution():
    """defensive = 1: the density is 1 everywhere and the per-pixel estimator is plain path tracing."""
    scene = MitsubaScene(get_scene("cornell-box").with_lens(0.1, None), (16, 16))
    context = ComparisonContext(scene=scene, layout=path_layout("dof", 3, thin_lens=True), kind="dof",
                                grid_shape=(16, 16, 4, 4), resolution=(16, 16), max_depth=3)
    importance = ImportanceMap(np.random.default_rng(0).random((16, 16, 4, 4)), defensive=1.0)
    image, nonfinite = render_with_map(context, importance, Budget(1024, 1), "per-pixel")
    assert nonfinite == 0 and image.shape == (16, 16, 3) and np.all(np.isfinite(image))
    reference, _ = scene.render_path(1024, 3, 3)
    assert abs(image.mean() / reference.mean() - 1) < 0.05


def test_guided_methods_in_a_comparison(tmp_path):
    """Every guided method runs in compare at 2x the map's image axes, counts the pilot, stays unbiased on average.

    guided-pilot's pilot is part of the budget (pilot_fraction 0.25); the thesis procedures draw map_spp per map
    cell on top of it (pilot_fraction 0).
    """
    from sparselt.experiments.compare import ComparisonConfig, compare

    config = ComparisonConfig(scene="cornell-box", kind="dof", shape=(16, 16, 4, 4), aperture=0.1, resolution=(32, 32),
                              methods=("pt", "guided-pilot", "guided-cosamp", "guided-bilateral"), spps=(8,),
                              seeds=(1, 2), reference_spp=256, timing_repeats=1,
                              options={"*": {"gamma": 0.5, "sparsity": 20, "map_spp": 8}})
    result = compare(config, tmp_path / "guided", progress=False)
    rows = {(row["method"], row["seed"]): row for row in result.rows}
    for method in config.methods[1:]:
        pilot = 0 if method == "guided-pilot" else 16 * 16 * 8  # in the budget, or map_spp per map cell on top
        assert rows[method, 1]["path_samples"] == 32 * 32 * 8 + pilot
        assert abs(np.mean([rows[method, s]["luminance_ratio"] for s in (1, 2)]) - 1) < 0.15
    record = json.loads(next((tmp_path / "guided" / "cells").glob("guided-cosamp_*.json")).read_text())
    assert 0.1 <= record["details"]["mean_defensive"] <= 1.0
    assert (tmp_path / "guided" / "table_6.md").exists()


def test_guided_methods_need_a_resolution_multiple_of_the_map(tmp_path):
    from sparselt.experiments.compare import ComparisonConfig, compare

    config = ComparisonConfig(scene="cornell-box", kind="dof", shape=(16, 16, 4, 4), aperture=0.1, resolution=(40, 36),
                              methods=("guided-pilot",), spps=(8,))
    with pytest.raises(ValueError, match="multiple of the shape's image axes"):
        compare(config, tmp_path / "x", progress=False)


def test_mixed_conditionals_interpolate_between_map_and_uniform():
    from sparselt.methods.guided import mixed_conditionals

    values = np.zeros((2, 1, 4))
    values[0, 0, 0] = 3.0
    values[1, 0] = [1, 1, 2, 0]
    mixed = mixed_conditionals(values, np.array([0.5, 1.0]))
    np.testing.assert_allclose(mixed[0, 0], [0.5 / 4 + 0.5, 0.5 / 4, 0.5 / 4, 0.5 / 4])
    np.testing.assert_allclose(mixed[1, 0], [0.25, 0.25, 0.25, 0.25])


def test_global_mode_runs_every_sample_once_grouped_by_film_pixel(path_context):
    """The global render's lane order is a permutation of the samples, sorted by the film pixel each lands in."""
    scene, layout = path_context.scene, path_context.layout
    importance = ImportanceMap(peaky(path_context.grid_shape, 5), defensive=0.1)
    spp, seed = 4, 3
    tables = importance.level_tables()
    order = np.asarray(global_order(scene, layout, importance.shape, tables, spp, seed))
    lane_count = scene.width * scene.height * spp
    assert np.array_equal(np.sort(order), np.arange(lane_count))
    mi = initialize()
    _, generator, _ = item_lanes(scene.width * scene.height, spp, seed, stream=GUIDED_STREAM)
    uniforms = {name: generator.next_float32() for name in layout.dimensions}
    warp_axes(importance.shape, tables, uniforms, layout.axes, mi.UInt32(0), 0)  # every level
    landing = np.asarray(film_pixel(scene, uniforms))
    assert np.all(np.diff(landing[order].astype(np.int64)) >= 0)
    assert np.unique(landing).size > scene.width * scene.height // 2  # the samples spread over the film


def test_global_mode_gives_the_same_bytes_for_the_same_seed(path_context):
    """The global splat adds in lane order on the host: no dependence on how threads interleaved (issue 24)."""
    importance = ImportanceMap(peaky(path_context.grid_shape, 9), defensive=0.2)
    first = render_with_map(path_context, importance, Budget(16, 4), "global")[0]
    again = render_with_map(path_context, importance, Budget(16, 4), "global")[0]
    assert first.tobytes() == again.tobytes()
    other = render_with_map(path_context, importance, Budget(16, 5), "global")[0]
    assert first.tobytes() != other.tobytes()
