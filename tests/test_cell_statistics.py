"""The per-cell statistics every estimator shares (issue 34): cell means, the sample variance, the tap rule.

Each against an independent computation: a Python loop over the samples for
the cell means, ``numpy.var`` for the variance, the window's definition for
the Gaussian taps.
"""

import math

import numpy as np
import pytest

from sparselt.cell_statistics import VARIANCE_FORMS, cell_means, variance_from_sums
from sparselt.filters.axis_aligned import gaussian_taps


def _loop_means(cells, weights):
    """Per cell, the float64 sum of its weights in sample order over its count (a plain Python loop)."""
    sums, counts = {}, {}
    for cell, weight in zip(cells.tolist(), weights.tolist()):
        sums[cell] = sums.get(cell, 0.0) + weight
        counts[cell] = counts.get(cell, 0) + 1
    order = sorted(sums)
    return np.array(order), np.array([sums[cell] / counts[cell] for cell in order]), np.array([counts[c] for c in order])


@pytest.mark.parametrize("size", [None, 500])
def test_cell_means_equal_a_loop_over_the_samples(size):
    rng = np.random.default_rng(4)
    cells = rng.integers(0, 40, 3000)
    strays = rng.random(3000) < 0.02
    cells[strays] = rng.integers(40, 500, int(strays.sum()))  # strays far from the others
    weights = (rng.random(3000) * 10.0 ** rng.uniform(-4, 4, 3000)).astype(np.float32)
    measured, means, counts = cell_means(cells, weights, size)
    expected_cells, expected_means, expected_counts = _loop_means(cells, weights.astype(np.float64))
    np.testing.assert_array_equal(measured, expected_cells)
    np.testing.assert_array_equal(counts, expected_counts)
    np.testing.assert_array_equal(means, expected_means)  # the same additions in the same order: the same bits
    assert means.dtype == np.float64 and counts.sum() == cells.size


def test_cell_means_of_complex_values_average_both_parts():
    rng = np.random.default_rng(5)
    cells = rng.integers(0, 9, 200)
    values = rng.standard_normal(200) + 1j * rng.standard_normal(200)
    measured, means, counts = cell_means(cells, values)
    sums = {}
    for cell, value in zip(cells.tolist(), values.tolist()):  # each part summed in sample order
        sums[cell] = sums.get(cell, 0j) + value
    assert means.dtype == np.complex128 and measured.tolist() == sorted(sums)
    np.testing.assert_array_equal(means, np.array([sums[cell] for cell in sorted(sums)]) / counts)


def test_the_pixel_and_tile_cell_means_are_the_one_cell_means():
    from sparselt.methods.pixel_samples import PixelSamples
    from sparselt.methods.pixel_samples import cell_means as pixel_cell_means
    from sparselt.methods.wedge_cosamp import tile_cell_means
    from sparselt.images import luminance

    rng = np.random.default_rng(6)
    grid, tile, spp = (8, 8, 2, 2), 4, 3
    pixels = 64
    pixel = np.repeat(np.arange(pixels), spp)
    row, column = np.divmod(pixel, 8)
    cells = (column * 8 + row) * 4 + rng.integers(0, 4, pixels * spp)
    cells[5] = 255  # a stray sample outside its pixel
    values = rng.random((pixels * spp, 3)).astype(np.float32)
    samples = PixelSamples(values=values, cells=cells, spp=spp, resolution=(8, 8), nonfinite=0)
    expected = _loop_means(cells, luminance(values).astype(np.float64))
    for got in (pixel_cell_means(samples, 256, grid), pixel_cell_means(samples, 256)):
        for part, want in zip(got, expected):
            np.testing.assert_array_equal(part, want)
    local, means, bounds = tile_cell_means(samples, grid, tile)
    by_cell = dict(zip(expected[0].tolist(), expected[1].tolist()))
    for index in range(4):  # tile index = tile_x * tiles_y + tile_y
        tile_x, tile_y = divmod(index, 2)
        run = slice(bounds[index], bounds[index + 1])
        x, rest = np.divmod(local[run], tile * 4)
        y, lens = np.divmod(rest, 4)
        flat = ((tile_x * tile + x) * 8 + tile_y * tile + y) * 4 + lens
        assert np.all(np.diff(local[run]) > 0)
        assert means[run].tolist() == [by_cell[cell] for cell in flat.tolist()]
    assert bounds[-1] == len(by_cell)


@pytest.mark.parametrize("form", VARIANCE_FORMS)
def test_variance_from_sums_is_numpys_sample_variance(form):
    rng = np.random.default_rng(7)
    samples = rng.standard_normal((50, 17)) * 3.0 + 10.0
    total, squares = samples.sum(axis=1), (samples * samples).sum(axis=1)
    for ddof in (0, 1):
        got = variance_from_sums(total, squares, 17.0, form=form, ddof=ddof)
        np.testing.assert_allclose(got, samples.var(axis=1, ddof=ddof), rtol=1e-10)


def test_each_form_is_the_expression_its_callers_computed():
    rng = np.random.default_rng(8)
    count = rng.integers(2, 9, 30).astype(np.float64)
    total, squares = rng.random(30) * count, rng.random(30) * count * 2
    mean = total / count
    assert np.array_equal(variance_from_sums(total, squares, count),
                          np.maximum(squares - count * mean * mean, 0.0) / (count - 1))
    assert np.array_equal(variance_from_sums(total, squares, count, form="total"),
                          np.maximum(squares - total * total / count, 0.0) / (count - 1))
    assert np.array_equal(variance_from_sums(total, squares, count, form="moment"),
                          np.maximum(squares / count - mean * mean, 0.0) * count / (count - 1))


def test_variance_of_weighted_passes_divides_by_passes_less_one():
    """The reference's passes: pass means x_i of n_i samples; sum n_i (x_i - m)^2 / (passes - 1)."""
    means, sizes = np.array([1.0, 2.0, 4.0]), np.array([2.0, 3.0, 5.0])
    got = variance_from_sums((sizes * means).sum(), (sizes * means * means).sum(), sizes.sum(), denominator=2)
    centre = (sizes * means).sum() / sizes.sum()
    assert got == pytest.approx((sizes * (means - centre) ** 2).sum() / 2, rel=1e-12)
    assert variance_from_sums(2.0, 2.0, 2.0) == 0.0  # equal samples: exactly zero, never negative


def test_variance_from_sums_refuses_an_unknown_form():
    with pytest.raises(ValueError, match="form must be one of mean, total, moment, got 'median'"):
        variance_from_sums(1.0, 1.0, 2.0, form="median")
    with pytest.raises(ValueError, match="denominator applies to the forms 'mean' and 'total'"):
        variance_from_sums(1.0, 1.0, 2.0, form="moment", denominator=1.0)


@pytest.mark.parametrize("maximum_radius", [1, 2, 5, 20, 24, 25, 64])
def test_the_tap_rule_stays_in_the_window(maximum_radius):
    for sigma in np.concatenate([np.linspace(0.0, 30.0, 3001), [maximum_radius / 3.0, np.nextafter(
            maximum_radius / 3.0, np.inf), 1.9999999, 2.0, 3.9999999, 4.0]]):
        width, radius = gaussian_taps(float(sigma), maximum_radius)
        assert width == min(sigma, maximum_radius / 3.0)
        assert radius == min(maximum_radius, math.ceil(3.0 * width)) and 0 <= radius <= maximum_radius
        assert (radius == 0) == (width == 0)


def test_the_tap_rule_at_its_boundaries():
    assert gaussian_taps(0.0, 24) == (0.0, 0)
    assert gaussian_taps(1.0, 24) == (1.0, 3)  # ceil(3 sigma)
    assert gaussian_taps(0.01, 24) == (0.01, 1)  # any positive width reaches its neighbours
    assert gaussian_taps(5.0, 24) == (5.0, 15)  # every pixel within the radius: no stride
    assert gaussian_taps(100.0, 24) == (8.0, 24)  # the width clipped to a third of the window
    assert gaussian_taps(100.0, 20) == (20 / 3, 20)  # a window that is no multiple of 3
