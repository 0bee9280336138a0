"""Sparse Fourier Transform (thesis 2.3) and rank-1 lattice reduction (thesis 6.1.1)."""

import dataclasses
import time

import numpy as np
import pytest

from sparselt.fourier import fft
from sparselt.fourier.sparse import random_sparse_fourier
from sparselt.recovery.lattice import (
    grid_to_lattice,
    lattice_generator,
    lattice_points,
    lattice_to_grid,
    sft_lattice,
)
from sparselt.recovery.sft import SparseFourierTransformResult, sft
from sparselt.recovery.sft_filters import make_filter


def sparse_signal(n, sparsity, seed, *, real=False, unit=False):
    """A K-sparse spectrum (numpy.fft convention) and its signal, from the one generator."""
    representation = random_sparse_fourier((n,), sparsity, np.random.default_rng(seed), real=real,
                                           values="unit" if unit else "normal")
    spectrum = np.zeros(n, dtype=np.complex128)
    spectrum[representation.indices] = representation.values
    signal = fft.ifftn(spectrum)
    return spectrum, signal.real if real else signal


class CountingOracle:
    """Records every index it is asked for."""

    def __init__(self, signal):
        self.signal = signal
        self.requests = []

    def __call__(self, indices):
        self.requests.append(np.array(indices, copy=True))
        return self.signal[indices]

    @property
    def asked(self):
        return np.concatenate(self.requests) if self.requests else np.zeros(0, dtype=np.int64)


def relative_error(estimate, spectrum):
    return np.linalg.norm(estimate.to_spectrum() - spectrum) / np.linalg.norm(spectrum)


# -- exact recovery ---------------------------------------------------------


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("n, sparsity", [(2 ** 12, 3), (2 ** 13, 10), (2 ** 14, 20), (2 ** 15, 50), (2 ** 16, 5),
                                         (2 ** 16, 50)])
def test_exact_recovery_of_sparse_signals(n, sparsity, seed):
    spectrum, signal = sparse_signal(n, sparsity, seed)
    result = sft(lambda indices: signal[indices], n, sparsity, seed=seed)
    assert result.stop_reason == "converged"
    assert result.samples < n / 2  # the sparse path, not the dense fallback
    assert result.estimate.shape == (n,)
    np.testing.assert_array_equal(result.estimate.indices, np.sort(np.flatnonzero(spectrum)))
    assert relative_error(result.estimate, spectrum) < 1e-6
    np.testing.assert_allclose(result.estimate.to_signal(), signal, atol=1e-6 * np.abs(signal).max())


@pytest.mark.parametrize("n", [3 ** 9, 2 ** 10 * 3 ** 4, 10 ** 5, 2 * 3 * 5 * 7 * 11 * 13])
def test_exact_recovery_for_smooth_sizes(n):
    spectrum, signal = sparse_signal(n, 20, seed=n)
    result = sft(lambda indices: signal[indices], n, 20, seed=1)
    assert result.stop_reason != "dense"
    assert relative_error(result.estimate, spectrum) < 1e-6


@pytest.mark.parametrize("seed", range(2))
def test_exact_recovery_of_real_signals(seed):
    n, sparsity = 2 ** 15, 30
    spectrum, signal = sparse_signal(n, sparsity, seed, real=True)
    assert not np.iscomplexobj(signal)
    result = sft(lambda indices: signal[indices], n, sparsity, seed=seed)
    assert relative_error(result.estimate, spectrum) < 1e-6


@pytest.mark.parametrize("window, width", [("chebyshev", 3.0), ("gaussian", 4.0), ("bspline", 8.0)])
def test_every_window_recovers_exactly(window, width):
    spectrum, signal = sparse_signal(2 ** 14, 10, seed=5)
    result = sft(lambda indices: signal[indices], 2 ** 14, 10, window=window, width=width, seed=5)
    assert result.parameters["window"] == window
    assert relative_error(result.estimate, spectrum) < 1e-6


def test_extra_magnitude_hashes_are_counted_and_exact():
    spectrum, signal = sparse_signal(2 ** 16, 20, seed=3)
    result = sft(lambda indices: signal[indices], 2 ** 16, 20, magnitude_hashes=3, seed=3)
    assert result.magnitude_samples > 0
    assert relative_error(result.estimate, spectrum) < 1e-6


def test_fewer_coefficients_than_sparsity_and_zero_signal():
    spectrum, signal = sparse_signal(2 ** 14, 4, seed=2)
    result = sft(lambda indices: signal[indices], 2 ** 14, 10, seed=2)
    assert result.estimate.sparsity == 4
    assert relative_error(result.estimate, spectrum) < 1e-6
    zero = sft(lambda indices: np.zeros(indices.size), 2 ** 14, 10, seed=2)
    assert zero.estimate.sparsity == 0


@pytest.mark.parametrize("n, sparsity", [(97, 1), (1009, 5)])
def test_dense_fallback_without_a_divisor_is_exact(n, sparsity):
    """Prime sizes: no number of bins divides them, so it reads everything and takes one FFT."""
    spectrum, signal = sparse_signal(n, sparsity, seed=0)
    oracle = CountingOracle(signal)
    result = sft(oracle, n, sparsity, seed=0)
    assert result.stop_reason == "dense" and result.transforms == 1
    assert result.samples == n == np.unique(oracle.asked).size
    assert relative_error(result.estimate, spectrum) < 1e-10


# -- noise --------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(2))
@pytest.mark.parametrize("snr", [10.0, 20.0, 30.0])
@pytest.mark.parametrize("n, sparsity", [(2 ** 14, 5), (2 ** 16, 20)])
def test_noisy_recovery_is_within_the_noise_bound(n, sparsity, snr, seed):
    """Nothing missed; error within 4x of least squares on the true support from as many samples.

    With unit coefficients and noise of total energy ``signal / snr``, least
    squares on the known support from ``m`` random samples has relative error
    ``sqrt(K / (snr m))``.
    """
    spectrum, signal = sparse_signal(n, sparsity, seed, unit=True)
    rng = np.random.default_rng(100 + seed)
    noise = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    noise *= np.linalg.norm(signal) / np.linalg.norm(noise) / 10 ** (snr / 20)
    noisy = signal + noise
    result = sft(lambda indices: noisy[indices], n, sparsity, snr=snr, seed=seed)
    np.testing.assert_array_equal(result.estimate.indices, np.sort(np.flatnonzero(spectrum)))
    bound = np.sqrt(sparsity / (10 ** (snr / 10) * result.samples))
    assert relative_error(result.estimate, spectrum) < 4 * bound


# -- sample accounting ----------------------------------------------------------


@pytest.mark.parametrize("options", [{}, {"magnitude_hashes": 2}, {"snr": 20.0}])
@pytest.mark.parametrize("n, sparsity", [(2 ** 12, 10), (2 ** 16, 30)])
def test_sample_count_is_exact_and_never_exceeds_n(n, sparsity, options):
    _, signal = sparse_signal(n, sparsity, seed=4)
    oracle = CountingOracle(signal)
    result = sft(oracle, n, sparsity, seed=4, **options)
    asked = oracle.asked
    assert np.unique(asked).size == asked.size  # no index is read twice
    assert asked.size == result.samples == result.support_samples + result.magnitude_samples
    assert result.samples <= n
    assert asked.min() >= 0 and asked.max() < n
    for request in oracle.requests:
        assert request.dtype == np.int64 and np.all(np.diff(request) > 0)


def test_dense_fraction_bounds_the_samples():
    n = 2 ** 12
    spectrum, signal = sparse_signal(n, 50, seed=1)
    oracle = CountingOracle(signal)
    result = sft(oracle, n, 50, seed=1, dense_fraction=0.05)
    assert result.stop_reason == "dense"
    assert result.samples == n == oracle.asked.size
    assert relative_error(result.estimate, spectrum) < 1e-10


def test_result_record():
    _, signal = sparse_signal(2 ** 14, 10, seed=0)
    result = sft(lambda indices: signal[indices], 2 ** 14, 10, seed=0)
    assert isinstance(result, SparseFourierTransformResult)
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.samples = 0
    assert set(result.seconds) == {"setup", "support", "magnitude", "oracle"}
    assert result.iterations == len(result.residual_history) >= 1
    assert len(result.bins) >= result.iterations
    assert result.samples_per_coefficient == result.samples / 10
    assert result.parameters["alpha"] == 4.0 and result.parameters["seed"] == 0


class SleepingOracle(CountingOracle):
    """Sleeps a known time per call: oracle time the solver must book as ``oracle``, never in its own phases."""

    SECONDS = 0.05

    def __call__(self, indices):
        time.sleep(self.SECONDS)
        return super().__call__(indices)


def test_phase_times_add_up_to_the_measured_time_and_the_oracle_is_booked_apart():
    """The docstring's promise: setup, support, magnitude and oracle add up to the total; the oracle's own time
    (here a known sleep per call) is in ``oracle`` and nowhere else."""
    _, signal = sparse_signal(2 ** 14, 10, seed=0)
    oracle = SleepingOracle(signal)
    start = time.perf_counter()
    result = sft(oracle, 2 ** 14, 10, seed=0)
    wall = time.perf_counter() - start
    slept = len(oracle.requests) * SleepingOracle.SECONDS
    assert len(oracle.requests) >= 2
    assert slept <= result.seconds["oracle"] <= wall
    computation = result.seconds["setup"] + result.seconds["support"] + result.seconds["magnitude"]
    # Had the oracle's sleeps been counted in a computing phase too, the phases would add up to more than the wall.
    assert computation <= wall - slept
    assert sum(result.seconds.values()) == pytest.approx(wall, rel=0.2)


def test_same_seed_same_result():
    _, signal = sparse_signal(2 ** 14, 10, seed=0)
    first = sft(lambda indices: signal[indices], 2 ** 14, 10, seed=7)
    second = sft(lambda indices: signal[indices], 2 ** 14, 10, seed=7)
    assert first.samples == second.samples
    np.testing.assert_array_equal(first.estimate.values, second.estimate.values)


# -- the filter -------------------------------------------------------------------


@pytest.mark.parametrize("n, bins", [(2 ** 16, 16), (2 ** 12, 256), (3 ** 9, 27)])
@pytest.mark.parametrize("window", ["chebyshev", "gaussian"])
def test_filter_response_matches_the_direct_dft(n, bins, window):
    """Both evaluators (chirp-z table, Taylor expansion) equal the direct sum over the taps."""
    filt = make_filter(n, bins, 3.0, window, 1e-10)
    taps = np.arange(-filt.half_width, filt.half_width + 1)
    offsets = np.unique(np.linspace(-filt.reach, filt.reach, 301).astype(np.int64))
    direct = (filt.taps[None, :] * np.exp(-2j * np.pi * np.outer(offsets, taps) / n)).sum(axis=1) / n
    np.testing.assert_allclose(filt.response(offsets), direct.real, atol=1e-12)
    assert filt.response(np.array([0]))[0] == pytest.approx(1.0, abs=1e-14)
    assert filt.response(np.array([filt.reach + 1]))[0] == 0.0


# -- rank-1 lattice ---------------------------------------------------------------


@pytest.mark.parametrize("lowest", [None, "zero"])
@pytest.mark.parametrize("shape", [(7,), (4, 6), (3, 4, 5), (2, 3, 2, 4)])
def test_lattice_map_is_a_bijection(shape, lowest):
    lowest = (0,) * len(shape) if lowest == "zero" else None
    size = int(np.prod(shape))
    line = np.arange(size)
    grid = lattice_to_grid(shape, line, lowest)
    np.testing.assert_array_equal(np.sort(grid), line)  # onto and one-to-one
    np.testing.assert_array_equal(grid_to_lattice(shape, grid, lowest), line)
    # eq. 6.1: on the lattice, frequency k of the box is the 1-D frequency l = k.g mod N
    coordinates = np.stack(np.unravel_index(grid, shape), axis=1)
    low = np.array([-(s // 2) for s in shape]) if lowest is None else np.zeros(len(shape), dtype=int)
    box = (coordinates - low) % np.array(shape) + low
    points = lattice_points(shape, line)
    assert points.shape == (size, len(shape)) and points.min() >= 0 and points.max() < 1
    on_lattice = np.exp(2j * np.pi * points @ box.T)
    one_d = np.exp(2j * np.pi * np.outer(line, line) / size)
    np.testing.assert_allclose(on_lattice, one_d, atol=1e-9)


def test_lattice_generator():
    np.testing.assert_array_equal(lattice_generator((100, 100, 4, 4)), [1, 100, 10000, 40000])


def trigonometric_polynomial(shape, count, seed, lowest=None):
    rng = np.random.default_rng(seed)
    low = [-(s // 2) for s in shape] if lowest is None else list(lowest)
    frequencies = np.unique(np.stack([rng.integers(lo, lo + s, count) for lo, s in zip(low, shape)], axis=1), axis=0)
    coefficients = rng.standard_normal(len(frequencies)) + 1j * rng.standard_normal(len(frequencies))

    def function(points):
        return np.exp(2j * np.pi * points @ frequencies.T) @ coefficients

    grids = np.meshgrid(*[np.arange(s) / s for s in shape], indexing="ij")
    on_grid = function(np.stack([g.ravel() for g in grids], axis=1)).reshape(shape)
    return function, frequencies, on_grid


@pytest.mark.parametrize("seed", range(2))
@pytest.mark.parametrize("shape", [(64, 64), (16, 16, 16), (8, 8, 8, 8), (32, 24, 10), (20, 20, 20, 20)])
def test_lattice_recovers_trigonometric_polynomials(shape, seed):
    function, frequencies, on_grid = trigonometric_polynomial(shape, 15, seed)
    calls = []

    def counted(points):
        calls.append(len(points))
        assert points.ndim == 2 and points.shape[1] == len(shape)
        return function(points)

    result = sft_lattice(counted, shape, len(frequencies), seed=seed)
    assert result.estimate.shape == shape
    assert sum(calls) == result.samples <= np.prod(shape)
    expected = np.sort(np.ravel_multi_index(tuple((frequencies % np.array(shape)).T), shape))
    np.testing.assert_array_equal(result.estimate.indices, expected)
    error = np.linalg.norm(result.estimate.to_signal() - on_grid) / np.linalg.norm(on_grid)
    assert error < 1e-6


def test_lattice_box_from_zero():
    shape = (16, 12, 10)
    function, _, on_grid = trigonometric_polynomial(shape, 10, seed=3, lowest=(0, 0, 0))
    result = sft_lattice(function, shape, 10, lowest=(0, 0, 0), seed=3)
    assert np.linalg.norm(result.estimate.to_signal() - on_grid) / np.linalg.norm(on_grid) < 1e-6


def test_lattice_reads_a_small_fraction_of_a_large_grid():
    shape = (100, 100, 4, 4)  # the thesis's image and two 4-level axes: 160,000 cells
    function, frequencies, _ = trigonometric_polynomial(shape, 20, seed=1)
    result = sft_lattice(function, shape, len(frequencies), seed=1)
    assert result.samples < 0.05 * np.prod(shape)
    expected = np.sort(np.ravel_multi_index(tuple((frequencies % np.array(shape)).T), shape))
    np.testing.assert_array_equal(result.estimate.indices, expected)


# -- bad input: one row per branch -----------------------------------------------------


def identity_oracle(indices):
    return indices.astype(float)


def zeros_on_lattice(points):
    return np.zeros(len(points))


def call(*args, **kwargs):
    """One row's arguments: positional and keyword."""
    return args, kwargs


@pytest.mark.parametrize("arguments, error, message", [
    (call(identity_oracle, 1024, 0), ValueError, r"sparsity K must satisfy 0 < K <= n/2 = 512.*got 0"),
    (call(identity_oracle, 1024, 513), ValueError, r"0 < K <= n/2 = 512.*got 513"),
    (call(identity_oracle, 1024, 2.5), TypeError, "sparsity K must be an integer"),
    (call(identity_oracle, 0, 1), ValueError, "signal size n must be >= 1, got 0"),
    (call(identity_oracle, -8, 1), ValueError, "signal size n must be >= 1, got -8"),
    (call(identity_oracle, 1024.0, 1), TypeError, "signal size n must be an integer"),
    (call(identity_oracle, 2 ** 31, 1), ValueError, "below 2\\*\\*31"),
    (call(identity_oracle, 1024, 4, alpha=0.5), ValueError, r"alpha must be at least 1.*got 0.5"),
    (call(lambda indices: np.zeros(indices.size + 1), 2 ** 14, 4), ValueError, "one value per index"),
    (call(lambda indices: np.full(indices.size, np.nan), 2 ** 14, 4), ValueError, "NaN or infinite"),
    (call(lambda indices: np.array(["a"] * indices.size), 2 ** 14, 4), ValueError, "real or complex numbers"),
    (call(np.zeros(1024), 1024, 4), ValueError, "oracle must be callable"),
    (call(identity_oracle, 1024, 4, window="hann"), ValueError, "window must be one of"),
    (call(identity_oracle, 1024, 4, width=0.5), ValueError, "width must be at least 1"),
    (call(identity_oracle, 1024, 4, snr=float("nan")), ValueError, "snr must be a number of decibels"),
    (call(identity_oracle, 1024, 4, leakage=0.5), ValueError, r"leakage must be in \(0, 0.1\)"),
    (call(identity_oracle, 1024, 4, dense_fraction=1.5), ValueError, r"dense_fraction must be in \(0, 1\]"),
    (call(identity_oracle, 1024, 4, magnitude_hashes=-1), ValueError,
     "magnitude_hashes must be >= 0, got -1"),
    (call(identity_oracle, 1024, 4, shift_ratio=1), ValueError, "shift_ratio must be >= 2, got 1"),
    (call(identity_oracle, 1024, 4, max_iterations=0), ValueError, "max_iterations must be >= 1, got 0"),
    (call(identity_oracle, 1024, 4, max_iterations=2.0), TypeError, "max_iterations must be an integer"),
    (call(identity_oracle, 1024, 4, alpha="4"), TypeError, "alpha must be a finite number"),
], ids=["sparsity-zero", "sparsity-above-half-n", "non-integer-sparsity", "size-zero", "negative-size",
        "non-integer-size", "size-beyond-index-arithmetic", "alpha-below-one", "oracle-returns-extra-values",
        "oracle-returns-nan", "oracle-returns-strings", "oracle-not-callable", "unknown-window",
        "width-below-one", "nan-snr", "large-leakage", "dense-fraction-above-one", "negative-magnitude-hashes",
        "shift-ratio-one", "max-iterations-zero", "max-iterations-float", "alpha-string"])
def test_sft_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        sft(*args, **kwargs)


@pytest.mark.parametrize("arguments, error, message", [
    (call(zeros_on_lattice, (16, 0), 4), ValueError, "shape must be a non-empty sequence of positive integers"),
    (call(zeros_on_lattice, (16, -4), 4), ValueError, "positive integers, got \\(16, -4\\)"),
    (call(lambda points: np.zeros((len(points), 2)), (64, 64), 4), ValueError, "one value per point"),
    (call(zeros_on_lattice, (64, 64), 4, lowest=(0,)), ValueError, "one frequency per axis"),
], ids=["zero-size-axis", "negative-size-axis", "function-returns-two-values-per-point",
        "lowest-with-too-few-frequencies"])
def test_sft_lattice_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        sft_lattice(*args, **kwargs)
