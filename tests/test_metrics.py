"""Image metrics (thesis 5.2): SSIM, PSNR, RMSE, relMSE and the HDR SSIM convention.

Golden values come from scikit-image, an independent implementation
(``structural_similarity(a, b, data_range=..., gaussian_weights=True,
sigma=1.5, use_sample_covariance=False[, channel_axis=-1])``), and from the
SSIM formula worked by hand where it has a closed form (constant images).
"""

import math

import numpy as np
import pytest

from sparselt.analysis.metrics import (
    display_image,
    image_ssim,
    peak_signal_to_noise_ratio,
    reference_exposure,
    relative_mean_squared_error,
    root_mean_squared_error,
    structural_similarity,
)


def scikit_image_ssim(image, reference, data_range, channel_axis=None, full=False):
    metrics = pytest.importorskip("skimage.metrics")
    return metrics.structural_similarity(
        image, reference, data_range=data_range, gaussian_weights=True, sigma=1.5,
        use_sample_covariance=False, channel_axis=channel_axis, full=full,
    )


def hdr_image(seed, shape=(32, 40, 3)):
    """A smooth linear HDR RGB image with a few bright highlights."""
    rng = np.random.default_rng(seed)
    rows, columns = np.meshgrid(np.linspace(0, 1, shape[0]), np.linspace(0, 1, shape[1]), indexing="ij")
    base = 0.2 + 0.5 * np.sin(3 * rows) * np.cos(2 * columns) ** 2
    image = np.stack([base, 0.8 * base + 0.1 * rows, 0.6 * base + 0.2 * columns], axis=-1)
    image = image * np.exp(0.3 * rng.standard_normal(shape))
    image[rng.integers(0, shape[0], 5), rng.integers(0, shape[1], 5)] = 20.0
    return image


# --------------------------------------------------------------------------- SSIM


@pytest.mark.parametrize(
    "shape, channel_axis, data_range, seed",
    [
        ((11, 11), None, 1.0, 0),
        ((24, 31), None, 1.0, 1),
        ((40, 17), None, 255.0, 2),
        ((20, 20, 3), -1, 1.0, 3),
        ((18, 25, 3), 2, 4.0, 4),
        ((3, 16, 21), 0, 2.0, 5),
    ],
)
def test_ssim_equals_scikit_image(shape, channel_axis, data_range, seed):
    rng = np.random.default_rng(seed)
    reference = data_range * rng.random(shape)
    image = reference + 0.1 * data_range * rng.standard_normal(shape)
    ours, our_map = structural_similarity(image, reference, data_range=data_range, channel_axis=channel_axis, full=True)
    theirs, their_map = scikit_image_ssim(image, reference, data_range, channel_axis, full=True)
    assert abs(ours - theirs) <= 1e-10
    assert our_map.shape == shape
    np.testing.assert_allclose(our_map, their_map, rtol=0, atol=1e-10)
    assert structural_similarity(image, reference, data_range=data_range, channel_axis=channel_axis) == ours


@pytest.mark.parametrize("first, second, data_range", [(0.2, 0.7, 1.0), (10.0, 200.0, 255.0), (0.5, 0.5, 1.0)])
def test_ssim_of_two_constant_images_is_the_luminance_term(first, second, data_range):
    """Golden values from the formula by hand: constant images have zero variance and covariance, so
    SSIM = (2 a b + C1) / (a^2 + b^2 + C1) with C1 = (0.01 L)^2 (the contrast-structure term is C2 / C2)."""
    c1 = (0.01 * data_range) ** 2
    expected = (2 * first * second + c1) / (first ** 2 + second ** 2 + c1)
    image, reference = np.full((16, 16), first), np.full((16, 16), second)
    assert structural_similarity(image, reference, data_range=data_range) == pytest.approx(expected, rel=1e-12)
    colour = np.stack([image, reference, image], axis=-1)
    flipped = np.stack([reference, image, image], axis=-1)  # channels 0 and 1 swapped, channel 2 equal
    assert structural_similarity(colour, flipped, data_range=data_range, channel_axis=-1) == pytest.approx(
        (2 * expected + 1) / 3, rel=1e-12)


def test_ssim_accepts_integer_and_float32_input_as_float64():
    rng = np.random.default_rng(6)
    reference = rng.integers(0, 256, (16, 16)).astype(np.uint8)
    image = rng.integers(0, 256, (16, 16)).astype(np.uint8)
    expected = structural_similarity(image.astype(np.float64), reference.astype(np.float64), data_range=255)
    assert structural_similarity(image, reference, data_range=255) == expected
    assert structural_similarity(image.astype(np.float32), reference.astype(np.float32), data_range=255) == expected


@pytest.mark.parametrize("shape, channel_axis", [((15, 19), None), ((13, 12, 3), -1)])
def test_ssim_of_identical_images_is_one(shape, channel_axis):
    image = 7.0 * np.random.default_rng(7).random(shape)
    value, ssim_map = structural_similarity(image, image.copy(), data_range=7.0, channel_axis=channel_axis, full=True)
    assert abs(value - 1.0) <= 1e-12
    np.testing.assert_allclose(ssim_map, 1.0, rtol=0, atol=1e-12)


def test_ssim_decreases_as_noise_grows():
    rng = np.random.default_rng(8)
    reference = rng.random((32, 32))
    noise = rng.standard_normal((32, 32))
    values = [structural_similarity(reference + level * noise, reference, data_range=1.0)
              for level in (0.0, 0.01, 0.05, 0.1, 0.3, 1.0)]
    assert values[0] == pytest.approx(1.0, abs=1e-12)
    assert all(later < earlier for earlier, later in zip(values, values[1:])), values


# --------------------------------------------------------------------------- PSNR, RMSE, relMSE


@pytest.mark.parametrize("shape, data_range, seed", [((10,), 1.0, 0), ((16, 16), 1.0, 1), ((8, 9, 3), 255.0, 2)])
def test_psnr_and_rmse_equal_scikit_image(shape, data_range, seed):
    metrics = pytest.importorskip("skimage.metrics")
    rng = np.random.default_rng(seed)
    reference = data_range * rng.random(shape)
    image = reference + 0.05 * data_range * rng.standard_normal(shape)
    assert peak_signal_to_noise_ratio(image, reference, data_range=data_range) == pytest.approx(
        metrics.peak_signal_noise_ratio(reference, image, data_range=data_range), rel=0, abs=1e-10
    )
    assert root_mean_squared_error(image, reference) == pytest.approx(
        math.sqrt(metrics.mean_squared_error(reference, image)), rel=1e-12
    )


def test_psnr_and_rmse_hand_computed():
    image = np.array([0.0, 0.5, 1.0, 1.0])
    reference = np.array([0.0, 0.5, 0.5, 1.0])  # squared errors 0, 0, 0.25, 0 -> MSE 1/16
    assert root_mean_squared_error(image, reference) == pytest.approx(0.25, rel=1e-15)
    assert peak_signal_to_noise_ratio(image, reference, data_range=1.0) == pytest.approx(10 * math.log10(16), rel=1e-15)
    assert peak_signal_to_noise_ratio(reference, reference, data_range=1.0) == math.inf
    assert root_mean_squared_error(reference, reference) == 0.0


def test_relative_mse_hand_computed_grayscale():
    image = np.array([[1.0, 2.0], [0.5, 0.0]])
    reference = np.array([[1.0, 1.0], [0.0, 1.0]])
    # (0/(1+e) + 1/(1+e) + 0.25/(0+e) + 1/(1+e)) / 4 with e = 0.01
    expected = (0.0 + 1 / 1.01 + 0.25 / 0.01 + 1 / 1.01) / 4
    assert relative_mean_squared_error(image, reference) == pytest.approx(expected, rel=1e-14)
    assert relative_mean_squared_error(image, reference, epsilon=1.0) == pytest.approx((0 + 0.5 + 0.25 + 0.5) / 4, rel=1e-14)


def test_relative_mse_rgb_shares_the_mean_channel_denominator():
    reference = np.array([[[1.0, 2.0, 2.0]]])  # mean of squares = (1 + 4 + 4) / 3 = 3
    image = np.array([[[2.0, 2.0, 0.0]]])  # squared errors 1, 0, 4
    expected = (1 / 3.01 + 0 + 4 / 3.01) / 3
    assert relative_mean_squared_error(image, reference) == pytest.approx(expected, rel=1e-14)


# --------------------------------------------------------------------------- validation: one row per branch


GOOD = np.random.default_rng(9).random((16, 16))
COLOUR = np.zeros((16, 16, 3))


def call(*args, **kwargs):
    """One row's arguments: positional and keyword."""
    return args, kwargs


def _with(array, index, value):
    """A copy of array with one entry replaced."""
    array = array.copy()
    array[index] = value
    return array


@pytest.mark.parametrize("arguments, error, message", [
    (call(GOOD, GOOD), ValueError, "data_range is required"),
    (call(GOOD, GOOD, data_range=None), ValueError, "data_range is required"),
    (call(GOOD, GOOD, 1.0), TypeError, None),  # data_range is keyword-only
    (call(GOOD, GOOD, data_range=0.0), ValueError, "greater than 0"),
    (call(GOOD, GOOD, data_range=-1.0), ValueError, "greater than 0"),
    (call(GOOD, GOOD, data_range=math.inf), ValueError, "finite"),
    (call(GOOD, GOOD, data_range=math.nan), ValueError, "finite"),
    (call(GOOD, GOOD, data_range="1.0"), TypeError, "data_range"),
    (call(GOOD, GOOD[:, :15], data_range=1.0), ValueError, "same shape"),
    (call(np.zeros((6, 6)), np.zeros((6, 6)), data_range=1.0), ValueError, "at least 11x11"),
    (call(np.zeros((10, 30)), np.zeros((10, 30)), data_range=1.0), ValueError, "at least 11x11"),
    (call(np.zeros((30, 10)), np.zeros((30, 10)), data_range=1.0), ValueError, "at least 11x11"),
    (call(np.zeros((10, 16, 3)), np.zeros((10, 16, 3)), data_range=1.0, channel_axis=-1),
     ValueError, "at least 11x11"),
    (call(np.zeros((0, 16)), np.zeros((0, 16)), data_range=1.0), ValueError, "empty"),
    (call(_with(GOOD, (3, 4), np.nan), GOOD, data_range=1.0), ValueError, "NaN or infinite"),
    (call(GOOD, _with(GOOD, (0, 0), np.inf), data_range=1.0), ValueError, "reference contains 1 NaN or infinite"),
    (call(GOOD + 0j, GOOD, data_range=1.0), ValueError, "real-valued"),
    (call(np.full((16, 16), "a"), GOOD, data_range=1.0), TypeError, "numeric"),
    (call(COLOUR, COLOUR, data_range=1.0), ValueError, "pass channel_axis"),
    (call(GOOD, GOOD, data_range=1.0, channel_axis=-1), ValueError, "must be 3-D"),
    (call(COLOUR, COLOUR, data_range=1.0, channel_axis=3), ValueError, r"channel_axis must be None or in \[-3, 2\]"),
    (call(COLOUR, COLOUR, data_range=1.0, channel_axis=1.5), TypeError, "channel_axis"),
    (call(GOOD, GOOD, data_range=1.0, full="yes"), TypeError, "full"),
], ids=["missing-data-range", "none-data-range", "positional-data-range", "zero-data-range",
        "negative-data-range", "infinite-data-range", "nan-data-range", "non-numeric-data-range",
        "mismatched-shapes", "smaller-than-window-6x6", "smaller-than-window-10x30", "smaller-than-window-30x10",
        "small-colour-image", "empty-image", "nan-in-image", "inf-in-reference", "complex-input",
        "non-numeric-input", "colour-without-channel-axis", "channel-axis-on-grayscale",
        "out-of-range-channel-axis", "non-integer-channel-axis", "non-boolean-full"])
def test_structural_similarity_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        structural_similarity(*args, **kwargs)


@pytest.mark.parametrize("arguments, error, message", [
    (call(GOOD, GOOD), ValueError, "data_range is required"),
    (call(GOOD, GOOD, data_range=-2.0), ValueError, "greater than 0"),
    (call(GOOD, GOOD.T[:3], data_range=1.0), ValueError, "same shape"),
], ids=["missing-data-range", "negative-data-range", "mismatched-shapes"])
def test_peak_signal_to_noise_ratio_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        peak_signal_to_noise_ratio(*args, **kwargs)


@pytest.mark.parametrize("arguments, error, message", [
    (call(np.array([1.0, np.nan]), np.array([1.0, 2.0])), ValueError, "NaN or infinite"),
    (call(np.zeros(3), np.zeros(4)), ValueError, "same shape"),
], ids=["nan", "mismatched-shapes"])
def test_root_mean_squared_error_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        root_mean_squared_error(*args, **kwargs)


@pytest.mark.parametrize("arguments, error, message", [
    (call(GOOD, GOOD, epsilon=0.0), ValueError, "epsilon"),
    (call(GOOD, GOOD, epsilon=-1e-2), ValueError, "epsilon"),
    (call(GOOD, GOOD, epsilon=math.inf), ValueError, "epsilon"),
    (call(np.zeros(4), np.zeros(4)), ValueError, r"\(height, width\) or \(height, width, channels\)"),
], ids=["zero-epsilon", "negative-epsilon", "infinite-epsilon", "wrong-dimensions"])
def test_relative_mean_squared_error_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        relative_mean_squared_error(*args, **kwargs)


@pytest.mark.parametrize("arguments, error, message", [
    (call(GOOD, GOOD), ValueError, r"\(height, width, 3\)"),
], ids=["non-rgb"])
def test_display_image_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        display_image(*args, **kwargs)


@pytest.mark.parametrize("arguments, error, message", [
    (call(_with(hdr_image(10), (1, 1, 1), np.nan), hdr_image(10)), ValueError, "NaN or infinite"),
], ids=["nan"])
def test_image_ssim_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        image_ssim(*args, **kwargs)


# --------------------------------------------------------------------------- HDR convention


def test_reference_exposure_maps_99th_percentile_of_luminance_to_point_nine():
    reference = hdr_image(11)
    luminance = reference.mean(axis=-1)
    assert np.percentile(luminance * reference_exposure(reference), 99) == pytest.approx(0.9, rel=1e-12)
    assert reference_exposure(np.zeros((4, 4, 3))) == 1.0
    assert reference_exposure(np.zeros((0, 3))) == 1.0


def test_show_writes_its_picture_at_the_shared_exposure():
    """``sparselt show`` exposes a signal's image as compare exposes its reference: its 99th percentile of
    luminance (the channels' mean) at 0.9, not by a convention of its own."""
    from types import SimpleNamespace

    from sparselt import visualize

    image = hdr_image(13)
    written = {}

    class Folder:
        def write_png(self, name, picture, *, exposure):
            written[name] = (picture, exposure)
            return name

    signal = SimpleNamespace(image=lambda client=None: image, axes=("x", "y"), shape=(40, 32))
    assert visualize._write_pictures(signal, Folder(), 4, None) == ["image.png"]
    picture, exposure = written["image.png"]
    np.testing.assert_array_equal(picture, image)
    assert np.percentile(image.mean(axis=-1) * exposure, 99) == pytest.approx(0.9, rel=1e-12)


def test_display_image_is_the_srgb_curve_at_reference_exposure():
    reference = hdr_image(12)
    shown = display_image(reference, reference)
    assert shown.min() >= 0.0 and shown.max() <= 1.0
    linear = np.clip(reference * reference_exposure(reference), 0, 1)
    expected = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)
    np.testing.assert_allclose(shown, expected, rtol=0, atol=1e-15)


def test_image_ssim_of_identical_hdr_images_is_one():
    reference = hdr_image(13)
    assert abs(image_ssim(reference.copy(), reference) - 1.0) <= 1e-12


@pytest.mark.parametrize("scale", [1e-3, 0.37, 250.0])
def test_image_ssim_is_invariant_to_a_common_scale(scale):
    reference = hdr_image(14)
    image = reference * np.exp(0.2 * np.random.default_rng(15).standard_normal(reference.shape))
    unscaled = image_ssim(image, reference)
    assert unscaled < 0.99
    assert image_ssim(scale * image, scale * reference) == pytest.approx(unscaled, abs=1e-12)


def test_image_ssim_equals_ssim_of_display_images():
    reference = hdr_image(16)
    image = 1.3 * reference
    expected = structural_similarity(display_image(image, reference), display_image(reference, reference),
                                     data_range=1.0, channel_axis=-1)
    assert image_ssim(image, reference) == expected
    # Exposure comes from the reference only: a uniformly brighter image is penalised.
    assert expected < 0.999


def test_image_ssim_is_lower_for_a_noisier_image():
    reference = hdr_image(17)
    noise = np.random.default_rng(18).standard_normal(reference.shape)
    values = [image_ssim(np.abs(reference * (1 + level * noise)), reference) for level in (0.05, 0.2, 0.5)]
    assert values[0] < 1.0
    assert values[0] > values[1] > values[2], values


def test_flip_is_zero_for_the_reference_and_grows_with_the_error():
    from sparselt.analysis.metrics import flip_error

    reference = hdr_image(7)
    rng = np.random.default_rng(8)
    errors = [flip_error(reference * np.exp(level * rng.standard_normal(reference.shape)), reference)
              for level in (0.05, 0.2, 0.8)]
    assert flip_error(reference, reference) == 0.0
    assert 0 < errors[0] < errors[1] < errors[2] <= 1
    with pytest.raises(ValueError, match="FLIP needs two"):
        flip_error(reference[..., 0], reference[..., 0])


def test_flip_refuses_a_black_reference_instead_of_aborting_the_process():
    """flip-evaluator aborts the interpreter (a C++ abort) when the reference has no light: refused first."""
    from sparselt.analysis.metrics import flip_error

    black = np.zeros((16, 16, 3), dtype=np.float32)
    with pytest.raises(ValueError, match="every pixel of the reference is 0"):
        flip_error(np.ones_like(black), black)
