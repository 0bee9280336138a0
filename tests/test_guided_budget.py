"""The guided methods' pilot inside the budget (issue 37): samples counted, the thesis's procedure kept, unbiased.

``pilot_fraction > 0`` draws the pilot per output pixel as part of the budget and reuses it in the image;
``pilot_fraction = 0`` is the thesis's extra pilot of ``map_spp`` per map cell (6.2.1, 8.3), bit for bit.
"""

import math

import numpy as np
import pytest

from sparselt.guiding import ImportanceMap
from sparselt.images import luminance
from sparselt.methods import (
    Budget,
    ComparisonContext,
    MethodResult,
    PhaseTimer,
    get_method,
    run_timed,
)
from sparselt.methods.guided import PILOT_SEED_MASK, mixed_conditionals, render_with_map
from sparselt.methods.pixel_samples import cell_means, draw_pixel_samples
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import MitsubaScene
from sparselt.rendering.scenes import get_scene

SIZE = 16
DEPTH = 3


@pytest.fixture(scope="module")
def scene():
    return MitsubaScene(get_scene("cornell-box"), (SIZE, SIZE))


def _context(scene, kind, grid_shape):
    return ComparisonContext(scene=scene, layout=path_layout(kind, DEPTH), kind=kind, grid_shape=grid_shape,
                             resolution=(SIZE, SIZE), max_depth=DEPTH)


@pytest.fixture(scope="module")
def path_context(scene):
    """The output resolution on the map's image axes (the suite's setting), path kind."""
    return _context(scene, "path", (SIZE, SIZE) + (2,) * 8)


@pytest.fixture(scope="module")
def indirect_context(scene):
    return _context(scene, "indirect", (SIZE, SIZE, 4, 4))


@pytest.fixture(scope="module")
def coarse_context(scene):
    """A map grid four times coarser than the output along each image axis."""
    return _context(scene, "indirect", (SIZE // 4, SIZE // 4, 8, 8))


@pytest.fixture(scope="module")
def reference(scene, indirect_context):
    """The indirect kind's estimator in 8 passes of 2048 spp, shape (8, SIZE, SIZE, 3)."""
    return np.array([scene.render_estimator(indirect_context.layout, 2048, 1000 + index)[0] for index in range(8)],
                    dtype=np.float64)


def thesis_run(method, context, budget):
    """The guided methods' ``run`` before the pilot joined the budget, copied verbatim (less the details)."""
    options = method.options
    timer = PhaseTimer()
    pilot = draw_pixel_samples(context, Budget(spp=options.map_spp, seed=budget.seed ^ 0x5A5A5A5A),
                               resolution=tuple(context.grid_shape[:2]))
    cells, means, _ = cell_means(pilot, math.prod(context.grid_shape), context.grid_shape)
    values, _ = method.map_values(context, options, cells, means, timer)
    if options.mode == "per-pixel" and options.map_spp >= 2:
        weights = method.select_defensive(context, options, pilot, timer)
        importance = ImportanceMap(mixed_conditionals(values, weights), defensive=0.0)
    else:
        importance = ImportanceMap(values, defensive=options.defensive, clamp_negative=True)
    image, _ = render_with_map(context, importance, budget, options.mode)
    width, height = context.resolution
    return MethodResult(image=image, path_samples=int(pilot.values.shape[0]) + width * height * budget.spp)


@pytest.mark.parametrize("name, options", [("guided-pilot", {}), ("guided-cosamp", {"pilot_fraction": 0.25}),
                                           ("guided-bilateral", {"pilot_fraction": 0.5})])
def test_the_pilot_in_the_budget_spends_exactly_the_budget(scene, path_context, indirect_context, name, options):
    context = indirect_context if name == "guided-bilateral" else path_context
    method = get_method(name, options={"sparsity": 20, **options} if name != "guided-pilot" else options,
                        grid_shape=context.grid_shape)
    result = run_timed(method, context, Budget(spp=8, seed=3))
    pilot_spp = max(1, round(method.options.pilot_fraction * 8))
    assert result.path_samples == 8 * SIZE * SIZE
    assert result.details["pilot_spp"] == pilot_spp and result.details["guided_spp"] == 8 - pilot_spp
    assert result.details["pilot_samples"] == pilot_spp * SIZE * SIZE
    assert result.image.shape == (SIZE, SIZE, 3) and np.all(np.isfinite(result.image))


def test_the_image_combines_pilot_and_guided_means_by_their_sample_counts(path_context):
    """Every cell at weight 1 (the map helps nowhere): the rest is plain PT and the image (2 pilot + 6 rest) / 8."""
    method = get_method("guided-pilot", grid_shape=path_context.grid_shape)
    result = run_timed(method, path_context, Budget(spp=8, seed=5))
    assert result.details["uniform_cells"] == 1.0 and "weight 1" in result.details["guided_render"]
    pilot = draw_pixel_samples(path_context, Budget(spp=2, seed=5 ^ PILOT_SEED_MASK)).pixel_means()
    rest, _ = path_context.scene.render_estimator(path_context.layout, 6, 5)
    expected = ((2 * pilot.astype(np.float64) + 6 * rest.astype(np.float64)) / 8).astype(np.float32)
    assert result.image.tobytes() == expected.tobytes()
    # The uniform map's guided render is the same estimator, up to the warp's rounding.
    uniform = ImportanceMap(np.ones(path_context.grid_shape), defensive=1.0)
    np.testing.assert_allclose(render_with_map(path_context, uniform, Budget(spp=6, seed=5), "per-pixel")[0], rest,
                               rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("name, grid", [("guided-pilot", "path"), ("guided-cosamp", "path"),
                                        ("guided-bilateral", "indirect")])
def test_pilot_fraction_zero_is_the_thesis_procedure_bit_for_bit(path_context, indirect_context, name, grid):
    context = path_context if grid == "path" else indirect_context
    given = {"map_spp": 8, "pilot_fraction": 0.0} | ({"sparsity": 20} if name != "guided-pilot" else {})
    method = get_method(name, options=given, grid_shape=context.grid_shape)
    result = run_timed(method, context, Budget(spp=8, seed=3))
    expected = thesis_run(method, context, Budget(spp=8, seed=3))
    assert result.image.tobytes() == expected.image.tobytes()
    assert result.path_samples == expected.path_samples == 8 * SIZE * SIZE + 8 * math.prod(context.grid_shape[:2])
    assert result.details["pilot"].startswith("thesis")


def test_the_thesis_procedures_keep_the_thesis_pilot_by_default():
    """sparselt reproduce (chapter 8) runs guided-cosamp and guided-bilateral with their defaults."""
    from sparselt.experiments.reproduce.equal_time import CHAPTER_8_METHODS
    from sparselt.methods import method_class

    for name in ("guided-cosamp", "guided-bilateral"):
        assert name in CHAPTER_8_METHODS and method_class(name).Options().pilot_fraction == 0.0
    assert method_class("guided-pilot").Options().pilot_fraction == 0.25


@pytest.mark.parametrize("spp, mode, grid, reason", [
    (1, "global", "path", "leave no guided sample"),
    (4, "per-pixel", "path", "cannot cross-validate"),
    (8, "per-pixel", "one cell", "nothing to guide"),
])
def test_where_guiding_cannot_run_the_method_is_path_tracing(scene, path_context, spp, mode, grid, reason):
    """A budget too small for pilot and guided samples, or a grid with nothing to guide: the kind's PT."""
    context = path_context if grid == "path" else _context(scene, "path", (SIZE, SIZE) + (1,) * 8)
    method = get_method("guided-pilot", options={"mode": mode}, grid_shape=context.grid_shape)
    result = run_timed(method, context, Budget(spp=spp, seed=2))
    assert reason in result.details["fallback"] and result.path_samples == spp * SIZE * SIZE
    expected, _ = context.scene.render_estimator(context.layout, spp, 2)
    assert result.image.tobytes() == expected.tobytes()


def test_pilot_fraction_is_validated():
    with pytest.raises(ValueError, match=r"guided-pilot.pilot_fraction must be a finite number in \[0, 1\)"):
        get_method("guided-pilot", options={"pilot_fraction": 1.0}, grid_shape=(16, 16, 4, 4))
    with pytest.raises(ValueError, match=r"guided-cosamp.pilot_fraction must be a finite number in \[0, 1\)"):
        get_method("guided-cosamp", options={"pilot_fraction": -0.1}, grid_shape=(16, 16, 4, 4))


def _forced_weights(method, weight):
    """``method`` with every image cell's defensive weight ``weight``: the map is used everywhere."""
    method.select_defensive = lambda context, options, pilot, timer: np.full(math.prod(context.grid_shape[:2]),
                                                                             weight)
    return method


def _block_luminance(images, block=4):
    """Mean luminance over ``block x block`` pixel blocks: (n, SIZE, SIZE, 3) -> (n, SIZE / block, SIZE / block)."""
    level = luminance(images)
    count = SIZE // block
    return level.reshape(level.shape[0], count, block, count, block).mean(axis=(2, 4))


@pytest.mark.parametrize("case", ["per-pixel forced map", "global", "coarse grid"])
def test_the_combined_estimator_is_unbiased(indirect_context, coarse_context, reference, case):
    """32 seeds' mean: image luminance and every 4x4 block's within a few standard errors of the reference.

    The map is built from the very pilot the image reuses and is used everywhere (weight 0.25 forced per image
    cell, or global mode with defensive 0.25): a dependence between map and reused pilot would show as bias.
    Blocks, not pixels: at 16 spp a guided pixel's estimate is skewed, and a per-pixel z test over 32 seeds
    flags a few percent of the pixels of the thesis's own (unbiased, pilot not reused) estimator too.
    """
    context = coarse_context if case == "coarse grid" else indirect_context
    method = get_method("guided-pilot", options={"mode": "global" if case == "global" else "per-pixel",
                                                 "defensive": 0.25}, grid_shape=context.grid_shape)
    if case != "global":
        method = _forced_weights(method, 0.25)
    results = [run_timed(method, context, Budget(spp=16, seed=seed)) for seed in range(32)]
    assert all(result.path_samples == 16 * SIZE * SIZE for result in results)  # 4 pilot + 12 guided per pixel
    if case != "global":
        assert results[0].details["mean_defensive"] == 0.25 and "guided_render" not in results[0].details
    runs = np.array([result.image for result in results], dtype=np.float64)
    total = luminance(runs).mean(axis=(1, 2))
    expected = luminance(reference).mean(axis=(1, 2))
    error = math.sqrt(total.var(ddof=1) / len(total) + expected.var(ddof=1) / len(expected))
    assert abs(total.mean() - expected.mean()) < 3 * error, (total.mean(), expected.mean(), error)
    blocks, reference_blocks = _block_luminance(runs), _block_luminance(reference)
    z = np.abs(blocks.mean(axis=0) - reference_blocks.mean(axis=0)) / np.sqrt(
        blocks.var(axis=0, ddof=1) / len(blocks) + reference_blocks.var(axis=0, ddof=1) / len(reference_blocks))
    assert np.max(z) < 3.8, z  # 16 blocks: about a 0.2% chance for an unbiased estimator with normal means


def test_where_guiding_cannot_help_the_error_is_path_tracing(scene, indirect_context, reference):
    """The Cornell box's smooth indirect light: (nearly) every cell keeps weight 1 and the error is PT's at the spp."""
    method = get_method("guided-pilot", grid_shape=indirect_context.grid_shape)
    guided, plain = [], []
    mean = reference.mean(axis=0)
    for seed in range(24):
        result = run_timed(method, indirect_context, Budget(spp=8, seed=seed))
        assert result.details["uniform_cells"] >= 0.95
        guided.append(np.mean((luminance(result.image.astype(np.float64)) - luminance(mean)) ** 2))
        image, _ = scene.render_estimator(indirect_context.layout, 8, 500 + seed)
        plain.append(np.mean((luminance(image.astype(np.float64)) - luminance(mean)) ** 2))
    guided, plain = np.array(guided), np.array(plain)
    standard_error = math.sqrt(guided.var(ddof=1) / len(guided) + plain.var(ddof=1) / len(plain))
    assert abs(guided.mean() - plain.mean()) < 3 * standard_error, (guided.mean(), plain.mean(), standard_error)
