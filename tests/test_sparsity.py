"""Gini index (thesis eq. 5.1): Hurley & Rickard's properties, golden values, the streaming bound, signals."""

import os

import numpy as np
import pytest

from sparselt.analysis.sparsity import (
    DOMAINS,
    GiniEstimate,
    GiniHistogram,
    gini_index,
    gini_index_streaming,
    signal_gini,
)
from sparselt.signal import Signal

SEEDS = (0, 1, 2)
# Streaming on small signals: a small histogram and a limit below the exact path's estimate.
FORCE_STREAMING = dict(memory_limit_bytes=400_000, buckets=2**12)


def _mean_difference_gini(values):
    """Independent definition: G = sum_ij |c_i - c_j| / (2 N ||c||_1), equal to eq. 5.1."""
    values = np.asarray(values, dtype=np.float64)
    return np.abs(values[:, None] - values[None, :]).sum() / (2 * values.size * values.sum())


def _random_magnitudes(seed, size=200):
    return np.random.default_rng(seed).lognormal(0.0, 1.5, size)


# ---------------------------------------------------------------- Hurley & Rickard's six properties


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("energy", [False, True])
def test_robin_hood_moving_wealth_to_the_poorer_decreases_gini(seed, energy):
    values = _random_magnitudes(seed)
    rich, poor = int(np.argmax(values)), int(np.argmin(values))
    before = gini_index(values, energy=energy)
    for fraction in (0.05, 0.25, 0.45):
        moved = values.copy()
        amount = fraction * (values[rich] - values[poor])  # < half the gap: the order of the two is kept
        moved[rich] -= amount
        moved[poor] += amount
        after = gini_index(moved, energy=energy)
        assert after < before - 1e-9


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("energy", [False, True])
def test_scaling_leaves_gini_unchanged(seed, energy):
    values = _random_magnitudes(seed)
    reference = gini_index(values, energy=energy)
    for factor in (1e-6, 0.3, 7.5, 1e12):
        assert gini_index(values * factor, energy=energy) == pytest.approx(reference, abs=1e-13)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("energy", [False, True])
def test_rising_tide_decreases_gini(seed, energy):
    values = _random_magnitudes(seed)
    previous = gini_index(values, energy=energy)
    for tide in (0.01, 0.1, 1.0, 10.0):
        current = gini_index(values + tide, energy=energy)
        assert current < previous
        previous = current


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("energy", [False, True])
def test_cloning_leaves_gini_unchanged(seed, energy):
    values = _random_magnitudes(seed)
    reference = gini_index(values, energy=energy)
    assert gini_index(np.concatenate([values, values]), energy=energy) == pytest.approx(reference, abs=1e-13)
    assert gini_index(np.tile(values, 5), energy=energy) == pytest.approx(reference, abs=1e-13)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("energy", [False, True])
def test_bill_gates_growing_the_largest_entry_increases_gini_towards_one(seed, energy):
    values = _random_magnitudes(seed)
    largest = int(np.argmax(values))
    previous = gini_index(values, energy=energy)
    for growth in (1.0, 10.0, 1e3, 1e6, 1e9):
        grown = values.copy()
        grown[largest] += growth
        current = gini_index(grown, energy=energy)
        assert current > previous
        previous = current
    assert previous == pytest.approx(1 - 1 / values.size, abs=1e-6)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("energy", [False, True])
def test_babies_appending_zeros_increases_gini(seed, energy):
    values = _random_magnitudes(seed)
    previous = gini_index(values, energy=energy)
    for zeros in (1, 10, 100):
        current = gini_index(np.concatenate([values, np.zeros(zeros)]), energy=energy)
        assert current > previous
        previous = current


# ---------------------------------------------------------------- golden values


def test_hand_computed_value():
    # [1, 2, 3]: 1 - 2 * (1 * 2.5 + 2 * 1.5 + 3 * 0.5) / (6 * 3) = 2/9
    assert gini_index([3, 1, 2]) == pytest.approx(2 / 9, abs=1e-15)
    # energies [1, 4, 9]: 1 - 2 * (2.5 + 6 + 4.5) / (14 * 3) = 8/21
    assert gini_index([3, 1, 2], energy=True) == pytest.approx(8 / 21, abs=1e-15)


@pytest.mark.parametrize("seed", SEEDS)
def test_matches_the_mean_absolute_difference_definition(seed):
    values = np.random.default_rng(seed).pareto(1.5, 700)
    assert gini_index(values) == pytest.approx(_mean_difference_gini(values), abs=1e-12)
    assert gini_index(values, energy=True) == pytest.approx(_mean_difference_gini(values**2), abs=1e-12)
    assert gini_index(values.astype(np.float32)) == pytest.approx(
        _mean_difference_gini(values.astype(np.float32)), abs=1e-12)


@pytest.mark.parametrize("size", [1, 2, 7, 1000])
def test_constant_uniform_and_zero_vectors_have_gini_zero(size):
    for values in (np.full(size, 3.5), np.ones(size, dtype=np.float32), np.zeros(size), np.zeros(size, dtype=int)):
        assert gini_index(values) == 0.0
        assert gini_index(values, energy=True) == 0.0


@pytest.mark.parametrize("size", [2, 3, 10, 12345])
def test_one_hot_has_gini_one_minus_one_over_n(size):
    values = np.zeros(size)
    values[size // 3] = 4.2
    assert gini_index(values) == pytest.approx(1 - 1 / size, abs=1e-14)
    assert gini_index(values, energy=True) == pytest.approx(1 - 1 / size, abs=1e-14)


def test_uniform_random_values_approach_one_third_and_energy_is_sparser():
    # For U(0, 1): mean absolute difference 1/3 over twice the mean 1/2 gives 1/3; for U**2, 1/2.
    values = np.random.default_rng(5).random(10**6)
    assert gini_index(values) == pytest.approx(1 / 3, abs=2e-3)
    assert gini_index(values, energy=True) == pytest.approx(1 / 2, abs=2e-3)


def test_shape_dtype_and_negative_zero_do_not_matter():
    values = np.random.default_rng(3).random((4, 5, 6))
    reference = gini_index(values.ravel())
    assert gini_index(values) == reference
    assert gini_index(np.asfortranarray(values)) == reference
    assert gini_index(values.tolist()) == reference
    assert gini_index([0.0, -0.0, 1.0]) == pytest.approx(2 / 3)
    assert gini_index([True, False, False]) == pytest.approx(2 / 3)


def test_energy_variant_is_the_index_of_squares():
    values = _random_magnitudes(9, 5000)
    assert gini_index(values, energy=True) == pytest.approx(gini_index(values**2), abs=1e-13)


# ---------------------------------------------------------------- validation


@pytest.mark.parametrize("arguments, error, message", [
    (dict(magnitudes=[]), ValueError, "empty"),
    (dict(magnitudes=np.array([1 + 1j, 2])), ValueError, r"np\.abs"),
    (dict(magnitudes=[1.0, -0.5, 2.0]), ValueError, r"negative.*np\.abs"),
    (dict(magnitudes=[1.0, np.nan, 2.0]), ValueError, r"NaN.*np\.abs"),
    (dict(magnitudes=[1.0, np.inf]), ValueError, r"inf.*np\.abs"),
    (dict(magnitudes=[1.0, -np.inf]), ValueError, "negative"),
    (dict(magnitudes=np.array(["a", "b"])), TypeError, "numeric"),
    (dict(magnitudes=[1.0, 2.0], energy="yes"), TypeError, "energy"),
], ids=["empty", "complex", "negative", "nan", "inf", "negative-inf", "non-numeric", "non-bool-energy"])
def test_gini_index_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        gini_index(**arguments)


@pytest.mark.parametrize("arguments, error, message", [
    # Squares below 1e-308 vanish in the float64 sums of the histogram (the exact path rescales first).
    (dict(chunks=np.array([1e-200, 2e-200, 0.0]), energy=True, buckets=2**8), ValueError, "rescale"),
    (dict(chunks=[np.zeros(0), []], buckets=16), ValueError, "no values"),
    (dict(chunks=[np.ones(10), np.array([1.0, -1e-50])], buckets=16), ValueError, r"negative.*np\.abs"),
    (dict(chunks=[np.array([1.0, np.nan], dtype=np.float32)], buckets=16), ValueError, "NaN"),
    (dict(chunks=[np.array([1.0, np.inf])], buckets=16), ValueError, "inf"),
    (dict(chunks=[np.array([1.0, 1e300])], buckets=16), ValueError, "rescale"),
    (dict(chunks=[np.array([1.0 + 2.0j])], buckets=16), ValueError, r"np\.abs"),
], ids=["energy-underflow", "no-values", "negative", "nan", "inf", "beyond-float32", "complex"])
def test_gini_index_streaming_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        gini_index_streaming(**arguments)


@pytest.mark.parametrize("arguments, error, message", [
    (dict(buckets=3), ValueError, "power of two"),
    (dict(buckets=1), ValueError, "power of two"),
    (dict(buckets=2**32), ValueError, "power of two"),
    (dict(buckets=1024.0), TypeError, "buckets"),
    (dict(buckets=16, piece_size=0), ValueError, "piece_size"),
    (dict(buckets=16, piece_size=2.5), TypeError, "piece_size"),
], ids=["buckets-3", "buckets-1", "buckets-2**32", "non-integer-buckets", "piece-size-zero", "fractional-piece-size"])
def test_gini_histogram_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        GiniHistogram(**arguments)


@pytest.mark.parametrize("arguments, error, message", [
    (dict(values=np.ones(4), weights=np.ones(3, dtype=int)), ValueError, "shape"),
    (dict(values=np.ones(3), weights=np.array([1, -1, 2])), ValueError, "non-negative"),
    (dict(values=np.ones(3), weights=np.full(3, 0.5)), TypeError, "integers"),
], ids=["weights-of-another-shape", "negative-weights", "fractional-weights"])
def test_gini_histogram_add_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        GiniHistogram(buckets=16).add(**arguments)


# ---------------------------------------------------------------- streaming bound


def _heavy_tailed(rng, size):
    return rng.pareto(0.8, size)


def _mostly_zero(rng, size):
    values = rng.exponential(1.0, size)
    values[rng.random(size) < 0.7] = 0.0
    return values


def _ties(rng, size):
    return rng.integers(0, 50, size).astype(np.float64)


def _uniform(rng, size):
    return rng.random(size).astype(np.float32)


def _log_normal(rng, size):
    return rng.lognormal(0.0, 3.0, size)


DISTRIBUTIONS = [_uniform, _log_normal, _heavy_tailed, _mostly_zero, _ties]


def _chunks(values, rng):
    """Uneven chunks, some of them 2-D, float64 or float32 as given."""
    cuts = np.sort(rng.integers(0, values.size, 6))
    pieces = np.split(values, cuts)
    return [piece.reshape(-1, 2) if piece.size % 2 == 0 else piece for piece in pieces]


@pytest.mark.parametrize("distribution", DISTRIBUTIONS, ids=lambda function: function.__name__.strip("_"))
@pytest.mark.parametrize("energy", [False, True])
def test_streaming_brackets_the_exact_value_on_a_million_values(distribution, energy):
    rng = np.random.default_rng(11)
    values = distribution(rng, 10**6)
    exact = gini_index(values, energy=energy)
    estimate = gini_index_streaming(_chunks(values, rng), energy=energy)
    assert isinstance(estimate, GiniEstimate) and estimate.count == values.size
    assert abs(estimate.value - exact) <= estimate.error_bound + 1e-12
    assert estimate.error_bound < 1e-5  # the derivation promises < 2**-15 / 8 for default buckets


@pytest.mark.parametrize("distribution", DISTRIBUTIONS, ids=lambda function: function.__name__.strip("_"))
@pytest.mark.parametrize("buckets", [2**4, 2**9, 2**12])
@pytest.mark.parametrize("energy", [False, True])
def test_the_bound_holds_for_coarse_histograms(distribution, buckets, energy):
    # Wide buckets make the ranking error large: the exact value must still lie inside.
    rng = np.random.default_rng(buckets)
    values = distribution(rng, 20_000)
    exact = gini_index(values, energy=energy)
    estimate = gini_index_streaming(_chunks(values, rng), energy=energy, buckets=buckets)
    assert abs(estimate.value - exact) <= estimate.error_bound + 1e-12
    assert estimate.lower <= exact + 1e-12 and exact - 1e-12 <= estimate.upper


def test_the_bound_holds_for_values_at_the_bucket_edges():
    # The worst case of the derivation: each bucket holds only its extremes, low values first.
    edges = np.array([1.0, np.nextafter(np.float32(2.0), np.float32(0.0)), 2.0, 3.999], dtype=np.float32)
    values = np.repeat(edges, [700, 300, 10, 990])
    for energy in (False, True):
        exact = gini_index(values, energy=energy)
        estimate = gini_index_streaming(values, energy=energy, buckets=2**8)  # buckets are octaves: [1, 2), [2, 4)
        assert abs(estimate.value - exact) <= estimate.error_bound + 1e-12
        assert estimate.error_bound > 1e-3  # and the bound is not vacuously zero there


def test_bound_is_zero_when_every_bucket_holds_one_value():
    values = np.array([0.0, 0.0, 1.0, 2.0, 2.0, 8.0, 1e-3])
    estimate = gini_index_streaming(values)
    assert estimate.value == pytest.approx(gini_index(values), abs=1e-14)
    assert estimate.error_bound < 1e-12  # only the floating-point allowance


def test_streaming_constant_zero_and_one_hot():
    assert gini_index_streaming([np.zeros(5), np.zeros(7)], buckets=64) == GiniEstimate(0.0, 0.0, 12)
    assert gini_index_streaming([np.full(9, 2.5)], buckets=64) == GiniEstimate(0.0, 0.0, 9)
    one_hot = gini_index_streaming([np.zeros(99), np.array([3.0])], buckets=64)
    assert one_hot.value == pytest.approx(1 - 1 / 100, abs=1e-14) and one_hot.error_bound < 1e-12


def test_weights_count_as_repeated_values():
    rng = np.random.default_rng(4)
    values = rng.lognormal(0.0, 1.0, 3000)
    weights = rng.integers(0, 4, 3000)
    weighted, repeated = GiniHistogram(buckets=2**10), GiniHistogram(buckets=2**10)
    weighted.add(values, weights=weights)
    repeated.add(np.repeat(values, weights))
    for energy in (False, True):
        a, b = weighted.estimate(energy=energy), repeated.estimate(energy=energy)
        assert a.count == b.count == weights.sum()
        assert a.value == pytest.approx(b.value, abs=1e-12)
        exact = gini_index(np.repeat(values, weights), energy=energy)
        assert abs(a.value - exact) <= a.error_bound + 1e-12


def test_small_pieces_give_the_same_histogram():
    values = np.random.default_rng(8).lognormal(0.0, 2.0, (37, 29))
    whole, pieces = GiniHistogram(buckets=2**10), GiniHistogram(buckets=2**10, piece_size=10)
    whole.add(values)
    pieces.add(values.T)  # non-contiguous, cut into pieces of at most 10
    assert np.array_equal(whole.counts, pieces.counts)
    assert np.array_equal(whole.minimum, pieces.minimum) and np.array_equal(whole.maximum, pieces.maximum)
    assert pieces.estimate().value == pytest.approx(whole.estimate().value, abs=1e-13)


# ---------------------------------------------------------------- signals


def _random_signal(shape, dtype=np.float32, seed=0):
    rng = np.random.default_rng(seed)
    data = (rng.lognormal(0.0, 1.0, shape + (3,)) * rng.random(shape + (3,)) ** 4).astype(dtype)
    axes = ("x", "y", "lens_u", "lens_v")[:len(shape)]
    return Signal(data=data, kind="dof", axes=axes)


@pytest.mark.parametrize("dtype, tolerance", [(np.float64, 1e-12), (np.float32, 1e-6)])
@pytest.mark.parametrize("energy", [False, True])
def test_exact_fourier_path_equals_gini_of_the_full_numpy_spectrum(dtype, tolerance, energy):
    for shape in [(6, 5, 4, 3), (7, 4), (4, 9, 1, 6)]:  # odd, even and unit axes: Hermitian planes differ
        signal = _random_signal(shape, dtype)
        result = signal_gini(signal, domain="fourier", energy=energy)
        assert result.exact and np.array_equal(result.error_bounds, np.zeros(3))
        for channel in range(3):
            spectrum = np.fft.fftn(signal.data[..., channel].astype(np.float64))
            assert result.values[channel] == pytest.approx(gini_index(np.abs(spectrum), energy=energy), abs=tolerance)


@pytest.mark.parametrize("energy", [False, True])
def test_exact_canonical_path_equals_gini_of_the_channel_magnitudes(energy):
    signal = _random_signal((6, 5, 4, 3))
    signal.data[0, 0, 0, 0] = -2.0  # canonical uses magnitudes |x|
    result = signal_gini(signal, domain="canonical", energy=energy)
    assert result.exact and result.domain == "canonical" and result.energy == energy
    expected = [gini_index(np.abs(signal.data[..., channel]), energy=energy) for channel in range(3)]
    assert np.array_equal(result.values, expected)


@pytest.mark.parametrize("domain", DOMAINS)
@pytest.mark.parametrize("energy", [False, True])
@pytest.mark.parametrize("shape, dtype", [((16, 12, 8, 10), np.float64), ((16, 12, 8, 10), np.float32),
                                          ((130, 97), np.float64)])
def test_forced_streaming_agrees_with_the_exact_path_within_its_bounds(domain, energy, shape, dtype):
    signal = _random_signal(shape, dtype, seed=3)
    exact = signal_gini(signal, domain=domain, energy=energy)
    streamed = signal_gini(signal, domain=domain, energy=energy, **FORCE_STREAMING)
    assert exact.exact and not streamed.exact
    assert np.all(streamed.error_bounds > 0) and np.all(streamed.error_bounds < 1e-3)
    # float32 spectra: the two FFT orders round differently (about 1e-7), outside the ranking bound.
    rounding = 1e-12 if dtype == np.float64 or domain == "canonical" else 1e-6
    assert np.all(np.abs(streamed.values - exact.values) <= streamed.error_bounds + rounding)


def test_streaming_a_memory_mapped_signal_leaves_no_scratch_file(tmp_path):
    signal = _random_signal((16, 12, 8, 10), np.float32, seed=6)
    np.save(tmp_path / "data.npy", signal.data)
    mapped = Signal(data=np.load(tmp_path / "data.npy", mmap_mode="r"), kind="dof", axes=signal.axes)
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    for domain in DOMAINS:
        exact = signal_gini(signal, domain=domain)
        streamed = signal_gini(mapped, domain=domain, temporary_directory=scratch, **FORCE_STREAMING)
        assert not streamed.exact
        assert np.all(np.abs(streamed.values - exact.values) <= streamed.error_bounds + 1e-6)
        assert signal_gini(mapped, domain=domain).values.tolist() == exact.values.tolist()
        with_progress = signal_gini(mapped, domain=domain, progress=True, **FORCE_STREAMING)
        assert with_progress.values.tolist() == streamed.values.tolist()
    assert os.listdir(scratch) == []


def _with_nan(signal):
    signal.data[3, 2, 1, 0, 2] = np.nan
    return signal


def _small_with_nan():
    signal = _random_signal((6, 5, 4, 3))
    signal.data[1, 2, 3, 0, 1] = np.nan
    return signal


_SMALL_SIGNAL = _random_signal((4, 3))


@pytest.mark.parametrize("arguments, error, message", [
    (dict(signal=_SMALL_SIGNAL, domain="wavelet"), ValueError, "domain"),
    (dict(signal=_SMALL_SIGNAL, domain="canonical", memory_limit_bytes=0), ValueError, "memory_limit_bytes"),
    (dict(signal=_random_signal((16, 12, 8, 10)), domain="fourier", memory_limit_bytes=1000, buckets=2**12),
     ValueError, "too small"),
    (dict(signal=_SMALL_SIGNAL, domain="fourier", temporary_directory="/nonexistent/folder"),
     ValueError, "temporary_directory"),
    (dict(signal=np.ones((4, 3, 3)), domain="canonical"), TypeError, "Signal"),
    (dict(signal=_SMALL_SIGNAL, domain="canonical", progress=1), TypeError, "progress"),
    (dict(signal=Signal(data=np.ones((4, 3, 3), dtype=np.complex64), kind="dof", axes=("x", "y")),
          domain="canonical"), ValueError, "real"),
    (dict(signal=Signal(data=np.ones((0, 3, 3), dtype=np.float32), kind="dof", axes=("x", "y")),
          domain="canonical"), ValueError, "no cells"),
    (dict(signal=_small_with_nan(), domain="canonical"), ValueError, "NaN"),
    (dict(signal=_small_with_nan(), domain="fourier"), ValueError, "NaN"),
    (dict(signal=_with_nan(_random_signal((16, 12, 8, 10))), domain="canonical", **FORCE_STREAMING),
     ValueError, "NaN"),
    (dict(signal=_with_nan(_random_signal((16, 12, 8, 10))), domain="fourier", **FORCE_STREAMING),
     ValueError, "NaN"),
], ids=["unknown-domain", "zero-memory-limit", "memory-limit-too-small", "missing-temporary-directory",
        "not-a-signal", "non-bool-progress", "complex-data", "empty-grid", "nan-canonical", "nan-fourier",
        "nan-canonical-streamed", "nan-fourier-streamed"])
def test_signal_gini_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        signal_gini(**arguments)
