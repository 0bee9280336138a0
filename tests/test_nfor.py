"""NFOR (Bitterli et al. 2016): the numba kernels against plain NumPy loops, exactness on affine images, the
error reduction on a noisy synthetic image, and the ``nfor`` method through the renderer under the contract."""

import math

import numpy as np
import pytest

from sparselt.filters import nfor
from sparselt.methods import Budget, ComparisonContext, get_method
from sparselt.methods.contract import check_method


@pytest.fixture(scope="module", autouse=True)
def compiled():
    nfor.warm_up()


# --- a slow reference of the same algorithm: loops over pixels, np.linalg.solve per window ----------------------


def reference_weights(guide, variance, radius, patch_radius, bandwidth):
    _, height, width = guide.shape
    size = 2 * radius + 1
    weights = np.zeros((size * size, height, width))
    for y in range(height):
        for x in range(width):
            for index in range(size * size):
                dy, dx = index // size - radius, index % size - radius
                qy, qx = y + dy, x + dx
                if not (0 <= qy < height and 0 <= qx < width):
                    continue
                terms = []
                for sy in range(-patch_radius, patch_radius + 1):
                    for sx in range(-patch_radius, patch_radius + 1):
                        p = (y + sy, x + sx)
                        q = (qy + sy, qx + sx)
                        if not (0 <= p[0] < height and 0 <= p[1] < width and 0 <= q[0] < height and 0 <= q[1] < width):
                            continue
                        here, there = variance[:, p[0], p[1]], variance[:, q[0], q[1]]
                        difference = guide[:, p[0], p[1]] - guide[:, q[0], q[1]]
                        terms.append(np.mean((difference ** 2 - (here + np.minimum(here, there)))
                                             / (nfor.DISTANCE_EPSILON + bandwidth ** 2 * (here + there))))
                weights[index, y, x] = math.exp(-max(0.0, float(np.mean(terms))))
    return weights.astype(np.float32)


def window(height, width, y, x, radius):
    size = 2 * radius + 1
    for index in range(size * size):
        qy, qx = y + index // size - radius, x + index % size - radius
        if 0 <= qy < height and 0 <= qx < width:
            yield index, qy, qx


def reference_coefficients_at(target, features, weights, radius, ridge, y, x, *, solver="solve"):
    """beta at (y, x): ridge least squares, by the normal equations or by lstsq on the weighted design matrix."""
    _, height, width = target.shape
    rows, values, row_weights = [], [], []
    for index, qy, qx in window(height, width, y, x, radius):
        rows.append(np.concatenate([[1.0], features[:, qy, qx] - features[:, y, x]]))
        values.append(target[:, qy, qx])
        row_weights.append(float(weights[index, y, x]))
    design, values, row_weights = np.array(rows), np.array(values), np.array(row_weights)
    gram = design.T @ (row_weights[:, None] * design)
    penalty = np.zeros(design.shape[1])
    penalty[1:] = ridge * np.diag(gram)[1:] + nfor.RIDGE_FLOOR * gram[0, 0]
    if solver == "solve":
        return np.linalg.solve(gram + np.diag(penalty), design.T @ (row_weights[:, None] * values))
    root = np.sqrt(row_weights)[:, None]
    augmented = np.vstack([root * design, np.diag(np.sqrt(penalty))])
    right = np.vstack([root * values, np.zeros((design.shape[1], values.shape[1]))])
    return np.linalg.lstsq(augmented, right, rcond=None)[0]


def reference_regression(target, features, weights, radius, ridge):
    _, height, width = target.shape
    accumulated = np.zeros_like(target)
    total = np.zeros((height, width))
    for y in range(height):
        for x in range(width):
            beta = reference_coefficients_at(target, features, weights, radius, ridge, y, x)
            for index, qy, qx in window(height, width, y, x, radius):
                weight = float(weights[index, y, x])
                reconstruction = np.concatenate([[1.0], features[:, qy, qx] - features[:, y, x]]) @ beta
                accumulated[:, qy, qx] += weight * reconstruction
                total[qy, qx] += weight
    return accumulated / total


def reference_box(image, radius):
    height, width = image.shape[-2:]
    out = np.empty_like(image)
    for y in range(height):
        for x in range(width):
            out[..., y, x] = image[..., max(0, y - radius):y + radius + 1, max(0, x - radius):x + radius + 1].mean(
                axis=(-2, -1))
    return out


def reference_nl_means(values, weights, radius):
    _, height, width = values.shape
    out = np.zeros_like(values)
    for y in range(height):
        for x in range(width):
            pairs = list(window(height, width, y, x, radius))
            weight = np.array([float(weights[index, y, x]) for index, _, _ in pairs])
            neighbours = np.array([values[:, qy, qx] for _, qy, qx in pairs])
            out[:, y, x] = weight @ neighbours / weight.sum()
    return out


def reference_nfor(colour_halves, colour_variances, feature_halves, *, radius, patch_radius, bandwidths,
                   feature_radius, feature_patch_radius, feature_bandwidth, selection_patch_radius, second_pass, ridge):
    colour = np.moveaxis(colour_halves, -1, 1)
    variances = np.moveaxis(colour_variances, -1, 1)
    prefiltered = []  # per buffer: (2, channels, height, width)
    for halves in feature_halves:
        halves = np.moveaxis(halves if halves.ndim == 4 else halves[..., None], -1, 1)
        variance = 0.5 * (halves[0] - halves[1]) ** 2
        prefiltered.append(np.stack([
            reference_nl_means(halves[half], reference_weights(halves[1 - half], variance, feature_radius,
                                                               feature_patch_radius, feature_bandwidth),
                               feature_radius)
            for half in range(2)]))
    features = np.concatenate([0.5 * (buffer[0] + buffer[1]) for buffer in prefiltered])
    outputs, errors = [], []
    for bandwidth in bandwidths:
        filtered = np.stack([
            reference_regression(colour[half], features,
                                 reference_weights(colour[1 - half], variances[1 - half], radius, patch_radius,
                                                   bandwidth), radius, ridge)
            for half in range(2)])
        errors.append((0.5 * ((filtered[0] - colour[1]) ** 2 - variances[1] + (filtered[1] - colour[0]) ** 2
                              - variances[0]) - 0.25 * (filtered[0] - filtered[1]) ** 2).mean(axis=0))
        outputs.append(filtered)
    selection_weights = reference_weights(0.5 * (colour[0] + colour[1]), 0.25 * (variances[0] + variances[1]),
                                          radius, selection_patch_radius, 1.0)
    errors = reference_nl_means(np.array(errors), selection_weights, radius)
    choice = np.argmin(errors, axis=0)
    selection = reference_nl_means(np.array([(choice == index).astype(float) for index in range(len(bandwidths))]),
                                   selection_weights, radius)
    halves = sum(selection[index] * outputs[index] for index in range(len(bandwidths)))
    image = 0.5 * (halves[0] + halves[1])
    if second_pass:
        final = []
        for buffer in prefiltered:
            combined = 0.5 * (buffer[0] + buffer[1])
            variance = 0.25 * (buffer[0] - buffer[1]) ** 2
            final.append(reference_nl_means(combined, reference_weights(combined, variance, 2, feature_patch_radius,
                                                                        feature_bandwidth), 2))
        image = reference_regression(image, np.concatenate(final),
                                     reference_weights(image, 0.25 * (halves[0] - halves[1]) ** 2, radius,
                                                       patch_radius, 1.0), radius, ridge)
    return np.moveaxis(image, 0, -1)


# --- tests -----------------------------------------------------------------------------------------------------


def test_one_window_regression_equals_lstsq_on_the_weighted_design_matrix():
    generator = np.random.default_rng(5)
    height = width = 12
    radius, ridge = 4, 1e-3
    target = generator.normal(size=(3, height, width))
    features = generator.normal(size=(3, height, width))
    weights = generator.random(((2 * radius + 1) ** 2, height, width)).astype(np.float32)
    coefficients = nfor.regression_coefficients(target, features, weights, radius=radius, ridge=ridge)
    for y, x in [(0, 0), (5, 6), (11, 3), (7, 11)]:
        expected = reference_coefficients_at(target, features, weights, radius, ridge, y, x, solver="lstsq")
        np.testing.assert_allclose(coefficients[:, :, y, x], expected, rtol=1e-8, atol=1e-12)


def test_nl_means_weights_equal_the_loop_reference():
    generator = np.random.default_rng(2)
    guide = generator.random((3, 9, 11))
    variance = 0.01 * generator.random((3, 9, 11))
    weights = nfor.nl_means_weights(guide, variance, radius=3, patch_radius=2, bandwidth=0.5)
    expected = reference_weights(guide, variance, 3, 2, 0.5)
    np.testing.assert_allclose(weights, expected, rtol=2e-7, atol=1e-12)
    assert np.all(weights[(7 * 7) // 2] == 1.0)  # the centre with itself


def test_the_whole_filter_equals_the_loop_reference():
    generator = np.random.default_rng(11)
    height = width = 10
    truth = generator.random((height, width, 3))
    colour = truth + 0.1 * generator.normal(size=(2, height, width, 3))
    variances = 0.01 + 0.002 * generator.random((2, height, width, 3))
    albedo = generator.random((height, width, 3)) + 0.05 * generator.normal(size=(2, height, width, 3))
    depth = generator.random((height, width)) + 0.05 * generator.normal(size=(2, height, width))
    for second_pass in (False, True):
        settings = {"radius": 3, "patch_radius": 1, "bandwidths": (0.5, 1.0), "feature_radius": 2,
                    "feature_patch_radius": 1, "feature_bandwidth": 0.5, "selection_patch_radius": 1,
                    "second_pass": second_pass, "ridge": 1e-4}
        result = nfor.nfor_filter(colour, variances, [albedo, depth], **settings)
        expected = reference_nfor(colour, variances, [albedo, depth], **settings)
        np.testing.assert_allclose(result.image, expected, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(result.selection.sum(axis=0), 1.0, rtol=1e-12)
        assert 0.02 < result.selection[0].mean() < 0.98  # both bandwidths selected somewhere


def test_an_affine_function_of_the_features_comes_out_unchanged():
    generator = np.random.default_rng(3)
    height, width = 24, 20
    features = [np.repeat(generator.random((1, height, width, 3)), 2, axis=0),
                np.repeat(generator.random((1, height, width)), 2, axis=0)]  # noise-free: both halves equal
    stacked = np.concatenate([features[0][0], features[1][0][..., None]], axis=-1)
    slopes = generator.normal(size=(4, 3))
    image = 0.5 + stacked @ slopes
    colour = np.stack([image, image])
    result = nfor.nfor_filter(colour, np.full_like(colour, 0.05), features)
    np.testing.assert_allclose(result.image, image, rtol=0, atol=1e-6)


def test_noisy_textured_image_error_drops():
    generator = np.random.default_rng(7)
    height = width = 64
    y, x = np.mgrid[0:height, 0:width] / height
    texture = np.where((np.floor(x * 6) + np.floor(y * 5)) % 2 == 0, 0.8, 0.25)[..., None] * np.array([1.0, 0.7, 0.4])
    shading = (0.6 + 0.4 * np.sin(3.0 * x + 2.0 * y))[..., None]
    truth = texture * shading
    sigma = 0.08
    colour = truth + sigma * generator.normal(size=(2, height, width, 3))
    variances = np.full_like(colour, sigma ** 2)
    albedo = texture + 0.02 * generator.normal(size=(2, height, width, 3))
    normal = np.zeros((2, height, width, 3))
    normal[..., 2] = 1.0
    depth = np.ones((2, height, width))
    result = nfor.nfor_filter(colour, variances, [albedo, normal, depth])

    def relmse(image):
        return float(np.mean((image - truth) ** 2 / (truth ** 2 + 1e-2)))

    noisy = relmse(colour.mean(axis=0))
    filtered = relmse(result.image)
    # measured: noisy 0.0896, filtered 0.00540 (a factor of 16.6); the bound leaves a factor of 2
    assert filtered < noisy / 8, (noisy, filtered)


@pytest.mark.parametrize("arguments, message", [
    ({"radius": 0}, "radius must be an integer >= 1"),
    ({"bandwidths": ()}, "bandwidths must be a non-empty sequence"),
    ({"bandwidths": (0.5, -1.0)}, r"bandwidths\[...\] must be a finite number > 0"),
    ({"ridge": -1.0}, "ridge must be a finite number >= 0"),
    ({"colour_variances": -np.ones((2, 4, 4, 3))}, "colour_variances has negative values"),
    ({"colour_halves": np.ones((3, 4, 4, 3))}, "colour_halves must have shape"),
    ({"feature_halves": [np.ones((2, 5, 4))]}, r"feature_halves\[0\] has image shape"),
    ({"feature_halves": []}, "feature_halves must be a non-empty sequence"),
])
def test_bad_arguments_are_refused(arguments, message):
    given = {"colour_halves": np.ones((2, 4, 4, 3)), "colour_variances": np.ones((2, 4, 4, 3)),
                 "feature_halves": [np.ones((2, 4, 4))]}
    given.update(arguments)
    with pytest.raises(ValueError, match=message):
        nfor.nfor_filter(given.pop("colour_halves"), given.pop("colour_variances"), given.pop("feature_halves"),
                         **given)


def test_the_method_keeps_the_contract_through_the_renderer():
    from sparselt.rendering.layout import path_layout
    from sparselt.rendering.mitsuba import MitsubaScene
    from sparselt.rendering.scenes import get_scene

    shape = (16, 16, 4, 4)
    spec = get_scene("cornell-box").with_lens(0.1, 1000.0)
    context = ComparisonContext(scene=MitsubaScene(spec, shape[:2]), layout=path_layout("dof", 3, thin_lens=True),
                                kind="dof", grid_shape=shape, resolution=shape[:2], max_depth=3)
    method = get_method("nfor:radius=5", grid_shape=shape)
    report = check_method(method, context, Budget(spp=4, seed=3))  # twice: the same image for the same seed
    result = report["result"]
    assert result.image.shape == (16, 16, 3) and result.path_samples == 16 * 16 * 4 == report["drawn"]
    assert report["seconds"]["reconstruction"] > 0 and report["seconds"]["sampling"] > 0
    assert result.details["aov_seeds"] == [6, 7] and result.details["radius"] == 5
    noisy = np.asarray(result.image)
    assert np.all(np.isfinite(noisy)) and noisy.mean() > 0
    with pytest.raises(ValueError, match="needs spp >= 2"):
        check_method(method, context, Budget(spp=1, seed=3))


def test_half_statistics_are_the_even_and_odd_samples_means_and_variances_of_their_means():
    from sparselt.methods.nfor import half_statistics
    from sparselt.methods.pixel_samples import PixelSamples

    generator = np.random.default_rng(4)
    width, height, spp = 5, 4, 6
    values = generator.random((height * width * spp, 3)).astype(np.float32)
    samples = PixelSamples(values=values, cells=np.zeros(len(values), dtype=np.int64), spp=spp,
                           resolution=(width, height), nonfinite=0)
    means, variances = half_statistics(samples)
    per_pixel = values.astype(np.float64).reshape(height, width, spp, 3)
    for half in range(2):
        np.testing.assert_allclose(means[half], per_pixel[:, :, half::2].mean(axis=2), rtol=1e-12)
        np.testing.assert_allclose(variances[half], per_pixel[:, :, half::2].var(axis=2, ddof=1) / 3, rtol=1e-12)
    np.testing.assert_allclose(means.mean(axis=0), samples.pixel_means(), rtol=1e-6)
    _, smoothed = half_statistics(samples, variance_radius=1)
    np.testing.assert_allclose(smoothed[0, 1, 1], variances[0, 0:3, 0:3].mean(axis=(0, 1)), rtol=1e-12)
    np.testing.assert_allclose(smoothed[1, 0, 0], variances[1, 0:2, 0:2].mean(axis=(0, 1)), rtol=1e-12)
    two = PixelSamples(values=values[: height * width * 2], cells=np.zeros(height * width * 2, dtype=np.int64), spp=2,
                       resolution=(width, height), nonfinite=0)
    means, variances = half_statistics(two)
    np.testing.assert_allclose(variances[0], 0.5 * (means[0] - means[1]) ** 2, rtol=1e-12)
