"""``wedge-cosamp``: the depth-of-field wedge, model-based CoSaMP inside it, the unbiased image, its refusals.

The wedge and the solver are tested on synthetic signals (no rendering); the
method on the real Cornell box at 16x16x4x4 through Mitsuba, as ``cosamp``'s
tests do.
"""

import dataclasses
import math

import numpy as np
import pytest

from sparselt.experiments.compare import ComparisonConfig, compare, validate_config
from sparselt.fourier.hermitian import partner_indices
from sparselt.methods import Budget, ComparisonContext, MethodSetup, get_method, run_timed
from sparselt.methods.wedge_cosamp import check_tiling, default_tile, wedge_mask
from sparselt.operators import PartialFourier
from sparselt.recovery.cosamp import cosamp

TINY = dict(scene="cornell-box", kind="dof", shape=(16, 16, 4, 4), aperture=0.1, focus_distance=1000.0,
            reference_spp=256)


def concentric_disc(a, b):
    """Shirley and Chiu's concentric map of the square [-1, 1]^2 onto the unit disc (Mitsuba's aperture map)."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
    wide = np.abs(a) > np.abs(b)
    radius = np.where(wide, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        angle = np.where(wide, (math.pi / 4) * b / a, math.pi / 2 - (math.pi / 4) * a / b)
    angle = np.where((a == 0) & (b == 0), 0.0, angle)
    return radius * np.cos(angle), radius * np.sin(angle)


def sheared_light_field(shape, coc, seed, *, waves=12, cycles=0.25):
    """``L(x, y, u, v) = T(x + c d_x(u, v), y + c d_y(u, v))``: a random texture seen through a thin lens.

    ``d`` is the concentric map of ``(2u - 1, 2v - 1)`` at the lens cells' centres, ``T`` a sum of ``waves``
    plane waves of random direction and frequency up to ``cycles`` per pixel (not periodic over the tile).
    """
    rng = np.random.default_rng(seed)
    x, y = np.arange(shape[0]) + 0.5, np.arange(shape[1]) + 0.5
    u, v = (np.arange(shape[2]) + 0.5) / shape[2], (np.arange(shape[3]) + 0.5) / shape[3]
    x, y, u, v = np.meshgrid(x, y, u, v, indexing="ij")
    along_x, along_y = concentric_disc(2 * u - 1, 2 * v - 1)
    x, y = x + coc * along_x, y + coc * along_y
    field = np.zeros(shape)
    for _ in range(waves):
        frequency = rng.uniform(-cycles, cycles, size=2)
        field += rng.standard_normal() * np.cos(2 * math.pi * (frequency[0] * x + frequency[1] * y)
                                                + rng.uniform(0, 2 * math.pi))
    return field


def energy_inside(signal, mask):
    """Fraction of the signal's spectral energy, the zero frequency left out, that ``mask`` holds."""
    energy = np.abs(np.fft.fftn(signal)) ** 2
    energy.reshape(-1)[0] = 0.0
    return float(energy[mask].sum() / energy.sum())


# -- the wedge ------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("coc", [0.0, 1.5, -3.0, 6.0])
def test_wedge_holds_the_spectrum_of_a_sheared_light_field(coc):
    """Most of the energy of T(x + c d(u)) lies in the wedge of [c - 1/4, c + 1/4]; the mirrored wedge (the
    other sign of the shear) holds much less of it wherever the shear is not zero; the mask is Hermitian."""
    shape = (16, 16, 8, 8)
    mask = wedge_mask(shape, (coc - 0.25, coc + 0.25))
    mirrored = wedge_mask(shape, (-coc - 0.25, -coc + 0.25))
    assert mask.dtype == bool and mask.shape == shape
    assert np.array_equal(mask, np.roll(np.flip(mask), 1, axis=(0, 1, 2, 3)))  # k allowed exactly when -k is
    assert mask.reshape(-1)[0] and mask.mean() < 0.35
    for seed in range(3):
        field = sheared_light_field(shape, coc, seed)
        inside = energy_inside(field, mask)
        assert inside > 0.75, (seed, inside)
        if coc != 0:
            assert energy_inside(field, mirrored) < inside - 0.2


def test_wedge_widens_with_the_depth_range_and_the_margin_and_wraps_around_the_lens_axis():
    shape = (10, 10, 8, 8)
    narrow, wide = wedge_mask(shape, (0.5, 0.5)), wedge_mask(shape, (-2.0, 3.0))
    assert np.all(wide[narrow]) and wide.mean() > narrow.mean()
    assert np.all(wedge_mask(shape, (0.5, 0.5), margin=2.0)[narrow])
    tight = wedge_mask(shape, (0.0, 0.0), margin=0.0)  # in focus, no margin: the lens's zero frequency only
    assert np.array_equal(np.flatnonzero(tight.any(axis=(0, 1))), [0])
    # c = 20: k_u = 2 c s k_x / T = 8 s at k_x = 2, s in [1/sqrt(2), 1]: bins 6, 7, 8 = 0 (wrapped around 8 bins).
    assert np.flatnonzero(wedge_mask(shape, (20.0, 20.0), margin=0.0)[2, 0, :, 0]).tolist() == [0, 6, 7]
    assert wedge_mask(shape, (-20.0, 20.0), margin=0.0)[2, 0, :, 0].all()  # a range wider than the lens axis
    per_axis = wedge_mask(shape, ((0.0, 0.0), (3.0, 3.0)), margin=0.0)
    assert np.flatnonzero(per_axis.any(axis=(0, 1, 3))).tolist() == [0]  # x in focus
    assert per_axis.any(axis=(0, 1, 2)).sum() > 1  # y sheared


@pytest.mark.parametrize("arguments, message", [
    (dict(tile_shape=(8, 8, 4), circle_of_confusion_range=(0, 1)), r"\(T_x, T_y, U, V\)"),
    (dict(tile_shape=(8, 8, 4, 4), circle_of_confusion_range=(2, 1)), "low <= high"),
    (dict(tile_shape=(8, 8, 4, 4), circle_of_confusion_range=(0, np.inf)), "finite"),
    (dict(tile_shape=(8, 8, 4, 4), circle_of_confusion_range=(0, 1), margin=-1.0), "margin"),
])
def test_wedge_mask_refuses_bad_arguments(arguments, message):
    with pytest.raises(ValueError, match=message):
        wedge_mask(**arguments)


# -- model-based CoSaMP -----------------------------------------------------------------------------------------------


def wedge_sparse_signal(shape, mask, pairs, rng):
    """A real signal of ``pairs`` random conjugate pairs of frequencies inside ``mask``; its support (flat, full)."""
    spectrum = np.zeros(shape, dtype=complex).reshape(-1)
    chosen = rng.choice(np.flatnonzero(mask), pairs, replace=False)
    partners = partner_indices(shape, chosen)
    values = rng.standard_normal(pairs) + 1j * rng.standard_normal(pairs)
    spectrum[chosen] = values
    spectrum[partners] = np.conj(values)
    alone = chosen == partners
    spectrum[chosen[alone]] = values[alone].real
    return np.fft.ifftn(spectrum.reshape(shape)).real, np.flatnonzero(spectrum)


SHAPE = (10, 10, 8, 8)


@pytest.mark.parametrize("seed", range(4))
def test_restricted_cosamp_recovers_a_wedge_sparse_signal_exactly(seed):
    rng = np.random.default_rng(seed)
    mask = wedge_mask(SHAPE, (1.0, 2.5))
    signal, support = wedge_sparse_signal(SHAPE, mask, 20, rng)
    cells = np.sort(rng.choice(signal.size, signal.size // 20, replace=False))
    result = cosamp(PartialFourier(SHAPE, cells, dtype=np.float64), signal.reshape(-1)[cells], support.size,
                    tolerance=1e-9, allowed=mask)
    assert result.stop_reason == "converged" and result.relative_error(signal) <= 1e-6
    assert np.array_equal(np.sort(result.support), support)
    assert mask.reshape(-1)[result.support].all()
    assert result.samples == cells.size


def test_the_wedge_rescues_recovery_from_fewer_samples_than_plain_cosamp_needs():
    """At 2.5% of the cells (about 4 samples per coefficient) CoSaMP inside the wedge finds every support;
    plain CoSaMP, the same samples, misses some (3 of these 6 seeds)."""
    mask = wedge_mask(SHAPE, (1.0, 2.5))
    plain_errors, model_errors = [], []
    for seed in range(6):
        rng = np.random.default_rng(seed)
        signal, support = wedge_sparse_signal(SHAPE, mask, 20, rng)
        cells = np.sort(rng.choice(signal.size, signal.size // 40, replace=False))
        samples = signal.reshape(-1)[cells]
        plain = cosamp(PartialFourier(SHAPE, cells, dtype=np.float64), samples, support.size, tolerance=1e-9)
        model = cosamp(PartialFourier(SHAPE, cells, dtype=np.float64), samples, support.size, tolerance=1e-9,
                       allowed=mask)
        assert np.array_equal(np.sort(model.support), support)
        plain_errors.append(plain.relative_error(signal))
        model_errors.append(model.relative_error(signal))
    assert max(model_errors) < 1e-4
    assert sum(error > 1e-2 for error in plain_errors) >= 2, plain_errors


def test_default_cosamp_is_unchanged_and_an_all_allowing_mask_changes_nothing():
    rng = np.random.default_rng(9)
    signal, support = wedge_sparse_signal(SHAPE, np.ones(SHAPE, dtype=bool), 30, rng)
    cells = np.sort(rng.choice(signal.size, signal.size // 8, replace=False))
    samples = signal.reshape(-1)[cells].astype(np.float32)
    runs = [cosamp(PartialFourier(SHAPE, cells), samples, support.size, **arguments)
            for arguments in ({}, {"allowed": None}, {"allowed": np.ones(SHAPE, dtype=bool)})]
    for other in runs[1:]:
        np.testing.assert_array_equal(other.estimate.indices, runs[0].estimate.indices)
        np.testing.assert_array_equal(other.estimate.values, runs[0].estimate.values)
        assert other.residual_history == runs[0].residual_history


@pytest.mark.parametrize("allowed, error, message", [
    (np.ones((10, 10, 8), dtype=bool), ValueError, "grid shape"),
    (np.ones(SHAPE, dtype=np.uint8), TypeError, "boolean"),
    (np.zeros(SHAPE, dtype=bool), ValueError, "admits no coefficient"),
    (np.eye(1, math.prod(SHAPE), 1, dtype=bool).reshape(SHAPE), ValueError, "Hermitian-symmetric"),
])
def test_cosamp_refuses_a_bad_mask(allowed, error, message):
    cells = np.arange(0, math.prod(SHAPE), 7)
    with pytest.raises(error, match=message):
        cosamp(PartialFourier(SHAPE, cells), np.ones(cells.size, dtype=np.float32), 4, allowed=allowed)


# -- the method -------------------------------------------------------------------------------------------------------


def test_wedge_cosamp_is_unbiased_over_seeds(tmp_path):
    """Per seed, wedge-cosamp minus samples-mean (the same samples) has zero mean: |mean| < 4 standard errors
    (as cosamp's test); four 8x8 tiles, so the tiling and the per-tile depth ranges are exercised."""
    seeds = tuple(range(1, 11))
    config = ComparisonConfig(**TINY, methods=("samples-mean", "wedge-cosamp"), spps=(8,), seeds=seeds,
                              timing_repeats=1, options={"wedge-cosamp": {"tile": 8, "sparsity": 25}},
                              pt_ladder_max_spp=16)  # PT's ladder is not what this tests
    result = compare(config, tmp_path / "unbiased", progress=False, cache_directory=str(tmp_path / "references"))
    ratio = {(row["method"], row["seed"]): row["luminance_ratio"] for row in result.rows}
    differences = np.array([ratio["wedge-cosamp", seed] - ratio["samples-mean", seed] for seed in seeds])
    standard_error = differences.std(ddof=1) / math.sqrt(len(seeds))
    assert standard_error > 0
    assert abs(differences.mean()) < 4 * standard_error, differences


@pytest.fixture(scope="module")
def scenes():
    from sparselt.rendering.mitsuba import MitsubaScene
    from sparselt.rendering.scenes import get_scene

    thin_lens = MitsubaScene(get_scene("cornell-box").with_lens(0.1, 1000.0), (16, 16))
    pinhole = MitsubaScene(get_scene("cornell-box"), (16, 16))
    return thin_lens, pinhole


def _context(scene, options=None, shape=(16, 16, 4, 4)):
    from sparselt.rendering.layout import path_layout

    method = get_method("wedge-cosamp", grid_shape=shape, options=options)
    context = ComparisonContext(scene=scene, layout=path_layout("dof", 3, thin_lens=True), kind="dof",
                                grid_shape=shape, resolution=shape[:2], max_depth=3)
    return method, context


def test_wedge_cosamp_runs_per_tile_and_records_its_details(scenes):
    method, context = _context(scenes[0], {"tile": 8})
    result = run_timed(method, context, Budget(spp=6, seed=4))
    details = result.details
    assert details["tiles"] == 4 and details["sparsity_per_tile"] == 8 * 8 * 4 * 4 // 200
    assert 0 < details["wedge_fraction"] <= 1 and details["cosamp_iterations"] > 0
    assert [fold["tiles_solved"] for fold in details["folds"]] == [4, 4]
    assert math.isfinite(details["control_variate_coefficient"])
    assert result.image.shape == (16, 16, 3) and result.path_samples == 16 * 16 * 6
    assert set(result.seconds) <= {"sampling", "reconstruction", "integration", "other"}


def test_default_tile_divides_the_image_axes():
    assert default_tile((250, 250, 16, 16)) == 25 and default_tile((16, 16, 4, 4)) == 16
    assert default_tile((128, 96, 8, 8)) == 32 and default_tile((97, 97, 4, 4)) == 1
    assert check_tiling((250, 250, 16, 16), 25) == (10, 10)


def test_a_tile_that_does_not_divide_the_grid_is_refused(scenes):
    method, context = _context(scenes[0], {"tile": 5})
    with pytest.raises(ValueError, match=r"tile=5 must divide both image axes of the grid 16x16; choose one of 1, 2, "
                                         r"4, 8, 16"):
        run_timed(method, context, Budget(spp=4, seed=1))
    with pytest.raises(ValueError, match=r"option wedge-cosamp.tile=5 must divide both image axes of the grid 16x16"):
        method.check_preconditions(MethodSetup.of_context(context))  # declared: refused before anything renders
    with pytest.raises(ValueError, match="option wedge-cosamp.tile must be"):
        _context(scenes[0], {"tile": 32})


def test_kinds_other_than_dof_are_refused_before_anything_runs():
    config = ComparisonConfig(scene="cornell-box", kind="indirect", shape=(16, 16, 4, 4), methods=("wedge-cosamp",),
                              spps=(4,))
    with pytest.raises(ValueError, match="method 'wedge-cosamp' does not support kind 'indirect'; it supports dof"):
        validate_config(config)
    validate_config(dataclasses.replace(config, kind="dof", aperture=0.1))


def test_a_pinhole_camera_is_refused(scenes):
    method, context = _context(scenes[1])
    with pytest.raises(ValueError, match="needs a thin-lens camera; this one is a pinhole"):
        run_timed(method, context, Budget(spp=4, seed=1))
    with pytest.raises(ValueError, match="method 'wedge-cosamp' needs a thin-lens camera with an aperture"):
        method.check_preconditions(MethodSetup.of_context(context))


def test_too_few_samples_are_refused(scenes):
    method, context = _context(scenes[0], {"sparsity": 600})
    with pytest.raises(ValueError, match="sparsity K=600 per tile must be below the measured cells"):
        run_timed(method, context, Budget(spp=4, seed=1))
    with pytest.raises(ValueError, match="needs spp >= 2"):
        run_timed(method, _context(scenes[0])[1], Budget(spp=1, seed=1))
