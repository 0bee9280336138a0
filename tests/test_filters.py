"""Filters of thesis 8.2/8.4 (eq. 8.1-8.3) against a direct loop over the window, in 2-D and 4-D."""

import itertools
import math

import numpy as np
import pytest

from sparselt.filters import bilateral, cross_bilateral, gaussian


def direct_cross_bilateral(image, guides, radius, sigma_spatial, sigmas):
    """Eq. 8.3 written as loops: every point, every offset of the clipped window."""
    grid = image.shape[:-1]
    out = np.empty_like(image, dtype=np.float64)
    for point in itertools.product(*(range(n) for n in grid)):
        total, accumulated = 0.0, np.zeros(image.shape[-1])
        for offset in itertools.product(range(-radius, radius + 1), repeat=len(grid)):
            neighbour = tuple(p + o for p, o in zip(point, offset))
            if any(not 0 <= q < n for q, n in zip(neighbour, grid)):
                continue
            weight = math.exp(-sum(o * o for o in offset) / (2 * sigma_spatial**2))
            for guide, sigma in zip(guides, sigmas):
                distance = np.sum((np.atleast_1d(guide[point]) - np.atleast_1d(guide[neighbour])) ** 2)
                weight *= math.exp(-distance / (2 * sigma**2))
            total += weight
            accumulated += weight * image[neighbour]
        out[point] = accumulated / total
    return out


@pytest.mark.parametrize("seed", [0, 1])
def test_cross_bilateral_equals_the_direct_sum_in_2d(seed):
    rng = np.random.default_rng(seed)
    image = rng.random((9, 7, 3))
    second = rng.random((9, 7, 2))
    result = cross_bilateral(image, [image, second], 2, 1.5, [0.3, 0.5], channel_axis=-1)
    expected = direct_cross_bilateral(image, [image, second], 2, 1.5, [0.3, 0.5])
    np.testing.assert_allclose(result, expected, rtol=1e-12)


def test_cross_bilateral_equals_the_direct_sum_in_4d():
    rng = np.random.default_rng(2)
    signal = rng.random((5, 4, 3, 3))
    guide = rng.random((5, 4, 3, 3))
    result = cross_bilateral(signal, [guide], 1, 1.0, 0.4)
    expected = direct_cross_bilateral(signal[..., None], [guide], 1, 1.0, [0.4])[..., 0]
    np.testing.assert_allclose(result, expected, rtol=1e-12)


def test_per_axis_radius_in_4d():
    rng = np.random.default_rng(6)
    signal = rng.random((5, 4, 3, 3))
    result = cross_bilateral(signal, [signal], (2, 1, 1, 0), 1.3, 0.5)
    # Radius 0 along the last axis: the direct sum over a (5, 3, 3, 1) window.
    direct = np.empty_like(signal)
    for point in itertools.product(*(range(n) for n in signal.shape)):
        total = accumulated = 0.0
        for offset in itertools.product(range(-2, 3), range(-1, 2), range(-1, 2), [0]):
            q = tuple(p + o for p, o in zip(point, offset))
            if all(0 <= c < n for c, n in zip(q, signal.shape)):
                w = math.exp(-sum(o * o for o in offset) / (2 * 1.3**2) - (signal[point] - signal[q]) ** 2 / (2 * 0.25))
                total += w
                accumulated += w * signal[q]
        direct[point] = accumulated / total
    np.testing.assert_allclose(result, direct, rtol=1e-12)


def test_bilateral_is_cross_bilateral_guided_by_the_image():
    rng = np.random.default_rng(3)
    image = rng.random((8, 8, 3)).astype(np.float32)
    result = bilateral(image, 2, 1.0, 0.2, channel_axis=-1)
    assert result.dtype == np.float32
    expected = direct_cross_bilateral(image.astype(np.float64), [image.astype(np.float64)], 2, 1.0, [0.2])
    np.testing.assert_allclose(result, expected, rtol=1e-5)


def test_constant_image_is_unchanged():
    image = np.full((10, 12, 3), 0.7)
    np.testing.assert_allclose(bilateral(image, 3, 2.0, 0.1, channel_axis=-1), image, rtol=1e-14)
    np.testing.assert_allclose(gaussian(image, 1.3, channel_axis=-1), image, rtol=1e-14)


def test_constant_guide_reduces_to_the_spatial_gaussian():
    rng = np.random.default_rng(4)
    image = rng.random((11, 9, 3))
    flat = np.ones((11, 9))
    np.testing.assert_allclose(cross_bilateral(image, [flat], 3, 1.2, 0.01, channel_axis=-1),
                               gaussian(image, 1.2, radius=3, channel_axis=-1), rtol=1e-13)


def test_gaussian_matches_a_normalised_window_away_from_borders():
    image = np.zeros((21, 21))
    image[10, 10] = 1.0
    result = gaussian(image, 2.0, radius=6)
    axis = np.arange(-6, 7)
    kernel = np.exp(-(axis[:, None] ** 2 + axis[None, :] ** 2) / 8.0)
    # Pixels whose whole window lies inside the image: the normalised kernel around the impulse.
    np.testing.assert_allclose(result[6:15, 6:15], (kernel / kernel.sum())[2:11, 2:11], rtol=1e-12)
    # Near the border the window is clipped and renormalised: weights still sum to one.
    np.testing.assert_allclose(gaussian(np.ones((21, 21)), 2.0, radius=6), 1.0, rtol=1e-14)


def test_radius_zero_is_the_identity():
    image = np.random.default_rng(5).random((6, 6, 3))
    np.testing.assert_array_equal(bilateral(image, 0, 1.0, 0.1, channel_axis=-1), image)


IMAGE = np.ones((6, 6, 3))
BAD = [
    (dict(radius=-1), ValueError, "radius must be >= 0"),
    (dict(radius=1.5), TypeError, "radius must be an integer"),
    (dict(radius=(1, 1, 1)), ValueError, "radius has 3 entries for a 2-D grid"),
    (dict(sigma_spatial=0.0), ValueError, "sigma_spatial must be finite and greater than 0"),
    (dict(sigma_spatial=float("nan")), ValueError, "sigma_spatial must be finite"),
    (dict(sigma_range=-2.0), ValueError, r"sigma_range\[0\] must be finite and greater than 0"),
    (dict(sigma_range=[0.1, 0.2, 0.3]), ValueError, "3 values for 1 guides"),
    (dict(guides=[np.ones((5, 6))]), ValueError, r"guide 0 has shape \(5, 6\)"),
    (dict(guides=np.ones((6, 6))), TypeError, "guides must be a list"),
    (dict(image=np.where(np.eye(6)[..., None] > 0, np.nan, 1.0) * IMAGE), ValueError, "image has 18 NaN"),
]


@pytest.mark.parametrize("changes, error, message", BAD, ids=[
    "negative-radius", "fractional-radius", "radius-with-too-many-entries", "sigma-spatial-zero", "nan-sigma-spatial",
    "negative-sigma-range", "more-sigma-ranges-than-guides", "guide-of-another-shape", "guides-not-a-list",
    "nan-in-image"])
def test_cross_bilateral_invalid_input(changes, error, message):
    """Each row changes one argument of an otherwise valid call."""
    arguments = dict(image=IMAGE, guides=[np.ones((6, 6))], radius=1, sigma_spatial=1.0, sigma_range=0.1)
    arguments.update(changes)
    with pytest.raises(error, match=message):
        cross_bilateral(arguments.pop("image"), arguments.pop("guides"), channel_axis=-1, **arguments)


def test_oidn_lowers_the_error_of_a_4_spp_cornell_box(tmp_path):
    """OIDN (colour + albedo + normal) on a 4 spp render: relMSE against 1024 spp falls several-fold."""
    from sparselt.analysis.metrics import relative_mean_squared_error
    from sparselt.filters import oidn_denoise
    from sparselt.rendering.mitsuba import MitsubaScene
    from sparselt.rendering.scenes import get_scene

    scene = MitsubaScene(get_scene("cornell-box"), (128, 128))
    reference, _ = scene.render_path(1024, 3, seed=7)
    noisy, _ = scene.render_path(4, 3, seed=1)
    buffers, seconds = scene.render_aovs(4, seed=1)
    assert seconds > 0 and buffers["albedo"].shape == (128, 128, 3) and buffers["depth"].shape == (128, 128)
    denoised = oidn_denoise(noisy, buffers["albedo"], buffers["normal"])
    before = relative_mean_squared_error(noisy, reference, epsilon=0.01)
    after = relative_mean_squared_error(denoised, reference, epsilon=0.01)
    assert after < before / 4


def test_oidn_missing_says_how_to_install(monkeypatch):
    import sys

    from sparselt.filters import oidn_denoise

    monkeypatch.setitem(sys.modules, "pyoidn", None)  # as if it were not installed
    with pytest.raises(RuntimeError, match="pip install pyoidn"):
        oidn_denoise(np.ones((4, 4, 3)))


@pytest.mark.parametrize("changes, error, message", [
    (dict(albedo=np.ones((4, 5, 3))), ValueError, "albedo has shape"),
    (dict(color=np.full((4, 4, 3), np.inf)), ValueError, "color has NaN or infinite"),
    (dict(albedo=None, normal=np.ones((4, 4, 3))), ValueError, "normals only together with albedo"),
], ids=["albedo-of-another-shape", "infinite-color", "normals-without-albedo"])
def test_oidn_denoise_invalid_input(changes, error, message):
    """Each row changes one argument of an otherwise valid call."""
    from sparselt.filters import oidn_denoise

    arguments = dict(color=np.ones((4, 4, 3)), albedo=np.ones((4, 4, 3)), normal=np.zeros((4, 4, 3)))
    arguments.update(changes)
    with pytest.raises(error, match=message):
        oidn_denoise(arguments.pop("color"), **arguments)
