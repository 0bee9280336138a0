"""ImportanceMap (thesis 6.2.1 eq. 6.3-6.5, with the defensive mixture of 9.3): sampling follows the pdf."""

import math

import numpy as np
import pytest

from sparselt.guiding import ImportanceMap
from chi_square import chi_square_p_value, sidak_threshold

SHAPES = [(7,), (5, 3), (4, 3, 5), (3, 4, 2, 3)]
TESTS = len(SHAPES) * 2  # sample + conditional


def random_map(shape, seed):
    rng = np.random.default_rng(seed)
    values = rng.random(shape) ** 4  # peaky, like a light transport signal
    values[rng.random(shape) < 0.2] = 0.0  # and some empty cells
    return values


@pytest.mark.parametrize("shape", SHAPES)
def test_sampled_cells_follow_the_pdf(shape):
    importance = ImportanceMap(random_map(shape, sum(shape)), defensive=0.05)
    rng = np.random.default_rng(1)
    count = 200_000
    points, density = importance.sample(rng.random((count, len(shape))))
    assert np.all((points >= 0) & (points < 1))
    observed = np.bincount(importance.cells_of(points), minlength=importance.size)
    p_value = chi_square_p_value(observed, count * importance.pdf.ravel())
    assert p_value > sidak_threshold(TESTS), p_value
    np.testing.assert_allclose(density, importance.density(points), rtol=1e-12)


@pytest.mark.parametrize("shape", SHAPES[1:])
def test_conditional_sampling_follows_the_conditional_pdf(shape):
    importance = ImportanceMap(random_map(shape, 3 + sum(shape)), defensive=0.1)
    conditional = importance.conditional(1)
    rng = np.random.default_rng(2)
    count = 100_000
    image_cell = 1
    points, density = conditional.sample(np.full(count, image_cell), rng.random((count, len(shape) - 1)))
    rest_shape = shape[1:]
    cells = np.ravel_multi_index([np.minimum((points[:, k] * n).astype(int), n - 1) for k, n in enumerate(rest_shape)],
                                 rest_shape)
    expected = importance.pdf[image_cell].ravel() / importance.pdf[image_cell].sum()
    observed = np.bincount(cells, minlength=expected.size)
    assert chi_square_p_value(observed, count * expected) > sidak_threshold(TESTS)
    np.testing.assert_allclose(density, conditional.density(np.full(count, image_cell), points), rtol=1e-12)


def test_density_is_pdf_over_cell_volume_and_integrates_to_one():
    importance = ImportanceMap(random_map((6, 5, 4), 9), defensive=0.2)
    rng = np.random.default_rng(3)
    points = rng.random((50_000, 3))
    cells = importance.cells_of(points)
    np.testing.assert_allclose(importance.density(points), importance.pdf.ravel()[cells] * importance.size)
    # Monte Carlo integral of the density over the unit cube: 1 within 5 standard errors.
    values = importance.density(points)
    assert abs(values.mean() - 1) < 5 * values.std() / math.sqrt(values.size)
    assert importance.pdf.sum() == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("defensive", [0.05, 0.3, 1.0])
def test_defensive_mixture_bounds_the_density(defensive):
    values = np.zeros((8, 8))
    values[0, 0] = 1.0  # a map that ignores almost everything
    importance = ImportanceMap(values, defensive=defensive)
    grid = (np.stack(np.meshgrid(np.arange(8), np.arange(8), indexing="ij"), -1).reshape(-1, 2) + 0.5) / 8
    assert importance.density(grid).min() >= defensive - 1e-12
    if defensive == 1.0:
        np.testing.assert_allclose(importance.density(grid), 1.0)


def test_negative_reconstruction_values_clamp_when_asked():
    values = np.array([[1.0, -0.5], [2.0, 0.0]])
    with pytest.raises(ValueError, match="1 negative values"):
        ImportanceMap(values)
    importance = ImportanceMap(values, defensive=0.0, clamp_negative=True)
    np.testing.assert_allclose(importance.pdf, [[1 / 3, 0.0], [2 / 3, 0.0]])


@pytest.mark.parametrize("arguments, error, message", [
    (dict(values=np.array([1.0, np.nan])), ValueError, "1 NaN or infinite"),
    (dict(values=np.zeros(4), defensive=0.0), ValueError, "all zero and defensive = 0"),
    (dict(values=np.ones(4), defensive=1.5), ValueError, r"defensive must be in \[0, 1\]"),
    (dict(values=np.ones(4), defensive=-0.1), ValueError, r"defensive must be in \[0, 1\]"),
    (dict(values=np.ones(4), defensive="a"), TypeError, "defensive must be a number"),
    (dict(values=np.ones(())), ValueError, "at least one axis"),
], ids=["nan-value", "all-zero-without-defensive", "defensive-above-one", "negative-defensive",
        "non-numeric-defensive", "zero-dimensional"])
def test_importance_map_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        ImportanceMap(**arguments)


def test_all_zero_map_with_defensive_is_uniform():
    importance = ImportanceMap(np.zeros((3, 3)), defensive=0.5)
    np.testing.assert_allclose(importance.pdf, 1 / 9)


@pytest.mark.parametrize("arguments, error, message", [
    (dict(u=np.array([[0.5, 1.0]])), ValueError, r"u must lie in \[0, 1\)\^2"),
    (dict(u=np.zeros((3, 3))), ValueError, r"u must have shape \(n, 2\)"),
], ids=["point-outside-the-unit-cube", "wrong-point-dimension"])
def test_importance_map_sample_invalid_input(arguments, error, message):
    importance = ImportanceMap(np.ones((2, 2)))
    with pytest.raises(error, match=message):
        importance.sample(**arguments)
