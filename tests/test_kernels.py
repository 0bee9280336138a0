"""The numba loops equal the NumPy expressions they replace, bit for bit (issue 24: no result may change)."""

import numpy as np
import pytest

from sparselt import kernels
from sparselt.fourier.sparse import random_sparse_fourier
from sparselt.operators import PartialFourier
from sparselt.recovery.cosamp import cosamp

SIZES = (1000, kernels.PARALLEL_MINIMUM * 3 + 17)  # the NumPy path and the parallel one


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.complex64])
def test_gather_and_scatter_equal_fancy_indexing(size, dtype):
    rng = np.random.default_rng(size)
    source = rng.standard_normal(4 * size).astype(dtype)
    indices = np.sort(rng.choice(source.size, size, replace=False))
    out = np.empty(size, dtype=dtype)
    assert kernels.gather(source, indices, out) is out
    assert np.array_equal(out, source[indices])
    target = np.zeros(4 * size, dtype=dtype)
    expected = target.copy()
    expected[indices] = out
    kernels.scatter(target, indices, out)
    assert np.array_equal(target, expected)


@pytest.mark.parametrize("size", SIZES)
def test_zero_clears_a_complex_array(size):
    array = (np.arange(size) + 1j).astype(np.complex64).reshape(-1, 1)
    kernels.zero(array)
    assert not np.any(array)


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_squared_magnitude_rounds_as_numpy(size, dtype):
    rng = np.random.default_rng(1)
    spectrum = (rng.standard_normal(size) + 1j * rng.standard_normal(size)).astype(dtype) * 1e3
    expected = np.square(spectrum.real)
    expected += np.square(spectrum.imag)
    out = np.empty(size, dtype=expected.dtype)
    assert np.array_equal(kernels.squared_magnitude(spectrum, out), expected)


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("exponent", [4.0, 2.0, 1 / 0.3])
def test_clamped_power_equals_maximum_then_power(size, exponent):
    rng = np.random.default_rng(2)
    values = rng.standard_normal(size).astype(np.float32)
    values[::7] = 0.0
    values[::11] = -0.0
    values[5] = np.nan
    values[6] = 1e-30  # a power that underflows to a subnormal
    expected = np.power(np.maximum(values, 0), np.float32(exponent))
    result = kernels.clamped_power(values.copy(), exponent)
    assert np.array_equal(result, expected, equal_nan=True)
    assert np.array_equal(np.signbit(result), np.signbit(expected))


def test_clamped_power_rejects_a_non_positive_exponent():
    with pytest.raises(ValueError, match="exponent must be positive"):
        kernels.clamped_power(np.ones(4, dtype=np.float32), 0.0)


def test_released_buffers_synthesise_the_estimate_exactly_and_retire_the_operator():
    shape = (24, 20, 8, 6)
    rng = np.random.default_rng(3)
    signal = random_sparse_fourier(shape, 40, rng, real=True).to_signal().astype(np.float32)
    cells = np.sort(rng.choice(signal.size, signal.size // 3, replace=False))
    operator = PartialFourier(shape, cells, dtype=np.float32)
    result = cosamp(operator, signal.reshape(-1)[cells], 40)
    expected = result.estimate.to_signal(dtype=np.float32)
    work, grid = operator.release_buffers()
    assert not np.any(work)
    synthesised = result.estimate.to_signal(dtype=np.float32, work=work, out=grid)
    assert synthesised is grid
    assert np.array_equal(synthesised, expected)
    with pytest.raises(RuntimeError, match="released"):
        operator.release_buffers()
    with pytest.raises(ValueError, match="work must be a zeroed"):
        result.estimate.to_signal(dtype=np.float32, work=np.zeros(3, dtype=np.complex64))


def test_counting_order_is_the_stable_argsort():
    keys = np.random.default_rng(4).integers(0, 300, 100_000).astype(np.uint32)
    order = kernels.counting_order(keys, 300)
    assert order.dtype == np.uint32
    assert np.array_equal(order, np.argsort(keys, kind="stable"))
    with pytest.raises(ValueError, match="below bins=300"):
        kernels.counting_order(np.array([300], dtype=np.uint32), 300)


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("row", [(3,), ()])
def test_slot_table_kernels_equal_their_numpy_expressions(size, row):
    rng = np.random.default_rng(5)
    slots = np.zeros(8 * size, dtype=np.int32)
    read = np.sort(rng.choice(slots.size, size, replace=False))
    kernels.number_slots(slots, read, 7)
    expected = np.zeros_like(slots)
    expected[read] = np.arange(8, 8 + size)
    assert np.array_equal(slots, expected)
    asked = rng.choice(slots.size, size)
    assert np.array_equal(kernels.unnumbered(slots, asked), asked[slots[asked] == 0])
    values = rng.standard_normal((size + 7,) + row).astype(np.float32)
    known = rng.choice(read, size)
    assert np.array_equal(kernels.gather_slotted(values, slots, known), values[slots[known] - 1])


@pytest.mark.parametrize("upscale", [(1, 1), (2, 3)])
def test_blocked_cell_means_equal_bincount(upscale):
    """Pixel samples summed per image-cell block give bincount's cells, means and counts exactly."""
    from sparselt.methods.pixel_samples import PixelSamples, cell_means

    grid_shape, spp = (6, 5, 4, 3), 7
    width, height = grid_shape[0] * upscale[0], grid_shape[1] * upscale[1]
    rng = np.random.default_rng(6)
    pixel_y, pixel_x = np.divmod(np.repeat(np.arange(width * height), spp), width)
    block = (pixel_x // upscale[0]) * grid_shape[1] + pixel_y // upscale[1]
    cells = block * 12 + rng.integers(0, 12, block.size)
    values = rng.random((cells.size, 3)).astype(np.float32)
    samples = PixelSamples(values=values, cells=cells, spp=spp, resolution=(width, height), nonfinite=0)
    size = int(np.prod(grid_shape))
    expected = cell_means(samples, size)
    blocked = cell_means(samples, size, grid_shape)
    for got, want in zip(blocked, expected):
        assert np.array_equal(got, want)
    strays = cells.copy()
    strays[::13] = (strays[::13] + 12) % size  # jitter rounded into a neighbouring cell, some past the grid's end
    stray = PixelSamples(values=values, cells=strays, spp=spp, resolution=(width, height), nonfinite=0)
    for got, want in zip(cell_means(stray, size, grid_shape), cell_means(stray, size)):
        assert np.array_equal(got, want)


def test_ordered_sums_add_in_lane_order():
    rng = np.random.default_rng(7)
    targets = rng.integers(0, 50, 10_000).astype(np.uint32)
    channels = [rng.standard_normal(10_000).astype(np.float32) for _ in range(3)]
    expected = np.zeros((50, 3), dtype=np.float32)
    for lane in range(0, 10_000):
        for channel in range(3):
            expected[targets[lane], channel] += channels[channel][lane]
    assert np.array_equal(kernels.ordered_sums(targets, channels, 50), expected)


def _replay_estimates_by_definition(sums, shifts, spp, emission):
    """Kettunen et al. 2015, 3, pixel by pixel: a pixel's primal is the mean of every path that lands in it (its
    base paths and each neighbour's offset towards it); the difference to the next pixel along an axis is the mean
    of the pairs that span the two (offset minus base for a +1 shift from the left pixel, base minus offset for a -1
    shift from the right one)."""
    sums = sums.astype(np.float64) - emission
    height, width, _, channels = sums.shape
    primal = np.zeros((height, width, channels))
    gradient_x = np.zeros((height, width - 1, channels))
    gradient_y = np.zeros((height - 1, width, channels))
    for y in range(height):
        for x in range(width):
            landing = [sums[y, x, 0]] + [sums[y - dy, x - dx, k] for k, (dx, dy) in enumerate(shifts, start=1)
                                         if 0 <= y - dy < height and 0 <= x - dx < width]
            primal[y, x] = np.sum(landing, axis=0) / (spp * len(landing))
            for gradient, (step_x, step_y) in ((gradient_x, (1, 0)), (gradient_y, (0, 1))):
                if x + step_x >= width or y + step_y >= height:
                    continue
                pairs = []
                for k, (dx, dy) in enumerate(shifts, start=1):
                    if (dx, dy) == (step_x, step_y):
                        pairs.append(sums[y, x, k] - sums[y, x, 0])
                    elif (dx, dy) == (-step_x, -step_y):
                        pairs.append(sums[y + step_y, x + step_x, 0] - sums[y + step_y, x + step_x, k])
                gradient[y, x] = np.sum(pairs, axis=0) / (spp * len(pairs))
    return primal, gradient_x, gradient_y


@pytest.mark.parametrize("offsets", [4, 2])
@pytest.mark.parametrize("shape", [(6, 5), (1, 4), (3, 1)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_replay_estimates_equal_their_definition(offsets, shape, dtype):
    """The replay shift's primal and gradient images on every core equal the pixel-by-pixel definition (films of
    one row or column included), with and without the emission subtracted."""
    from sparselt.rendering.mitsuba.gradients import GRADIENT_SHIFTS

    rng = np.random.default_rng(offsets + shape[0])
    sums = rng.standard_normal(shape + (offsets + 1, 3)).astype(dtype)
    emission = rng.standard_normal(sums.shape)
    for subtracted in (None, emission):
        expected = _replay_estimates_by_definition(sums, GRADIENT_SHIFTS[offsets], 7,
                                                   0.0 if subtracted is None else subtracted)
        for got, want in zip(kernels.replay_estimates(sums, GRADIENT_SHIFTS[offsets], 7, subtracted), expected):
            assert got.shape == want.shape and got.dtype == np.float64
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("shape", [(5, 7, 3), (64, 48, 1)])
def test_screened_spectrum_equals_numpy_in_place_arithmetic(shape):
    """The screened Poisson spectrum kernel rounds as NumPy's multiply, add and divide on float32 arrays."""
    generator = np.random.default_rng(4)
    primal, gradient = (generator.standard_normal(shape).astype(np.float32) for _ in range(2))
    eigenvalues = generator.uniform(0, 8, shape[:2] + (1,)).astype(np.float32)
    for alpha in (0.05, 0.2, 3.2):
        weight = np.float32(alpha * alpha)
        expected = np.multiply(primal, weight)
        expected += gradient
        expected /= weight + eigenvalues
        out = kernels.screened_spectrum(primal, gradient, eigenvalues, alpha * alpha, np.empty_like(primal))
        np.testing.assert_array_equal(out, expected)


@pytest.mark.parametrize("runs", [7, 9000])  # the NumPy path and the parallel one
def test_run_ramps_equal_repeat_and_arange(runs):
    """Runs of repeated pixels and of numbered samples or slots, as the NumPy expressions they replace."""
    generator = np.random.default_rng(8)
    counts = generator.integers(0, 30, runs)
    bases = np.sort(generator.choice(10 * runs, runs, replace=False))
    starts = np.cumsum(counts) - counts
    for step in (0, 1):
        expected = (np.repeat(bases, counts) + step * (np.arange(counts.sum()) - np.repeat(starts, counts)))
        for dtype in (np.uint32, np.int64):
            out = kernels.run_ramps(counts, bases, step, dtype)
            assert out.dtype == dtype
            np.testing.assert_array_equal(out, expected.astype(dtype))
    with pytest.raises(ValueError, match="must not be negative"):
        kernels.run_ramps(np.array([2, -1]), np.array([0, 1]), 1, np.uint32)


@pytest.mark.parametrize("reduction", ["sum", "min", "max"])
def test_merge_runs_equals_a_loop_over_the_blocks_in_order(reduction):
    """Runs of blocks merged into their rows on every core: the same bytes as a sequential float64 loop in block
    order (the order a row's values are summed in is fixed); rows without runs keep their value."""
    generator = np.random.default_rng(4)
    lengths = generator.integers(1, 40, size=3000)
    rows = np.sort(generator.choice(10000, size=lengths.size, replace=False))
    starts = np.concatenate(([0], np.cumsum(lengths)))
    partial = [generator.standard_normal(starts[-1]).astype(np.float32) * 1e3 for _ in range(3)]
    start = generator.standard_normal((10000, 3))
    merged = start.copy()
    kernels.merge_runs(merged, partial, rows, starts, reduction)
    expected = start.copy()
    operation = {"sum": lambda a, b: a + b, "min": min, "max": max}[reduction]
    for run, row in enumerate(rows):
        for position in range(starts[run], starts[run + 1]):
            for column in range(3):
                expected[row, column] = operation(expected[row, column], float(partial[column][position]))
    assert merged.tobytes() == expected.tobytes()
    single = start[:, 0].copy()  # a one-dimensional result is one column
    kernels.merge_runs(single, partial[:1], rows, starts, reduction)
    assert single.tobytes() == merged[:, 0].copy().tobytes()
    with pytest.raises(ValueError, match="one entry more than rows"):
        kernels.merge_runs(merged, partial, rows, starts[:-1], reduction)
    with pytest.raises(ValueError, match=r"contiguous \(rows, 2\) float64"):
        kernels.merge_runs(merged, partial[:2], rows, starts, reduction)
