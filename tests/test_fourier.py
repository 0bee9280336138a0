"""FFT backend (Parseval, agreement with numpy), SparseFourier, and the four integration methods."""

import numpy as np
import pytest

from sparselt.fourier import fft
from sparselt.fourier.integration import METHODS, integrate
from sparselt.fourier.sparse import SparseFourier, partner_indices, random_sparse_fourier

TOLERANCE = {np.float32: 2e-5, np.float64: 1e-12}


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape", [(64,), (16, 12), (8, 6, 5, 4)])
def test_unitary_fft_preserves_energy_and_inverts(dtype, shape):
    rng = np.random.default_rng(len(shape))
    signal = (rng.normal(size=shape) + 1j * rng.normal(size=shape)).astype(np.complex64 if dtype == np.float32 else np.complex128)
    spectrum = fft.fftn(signal, norm="ortho")
    assert spectrum.dtype == signal.dtype
    energy = np.sum(np.abs(signal.astype(np.complex128)) ** 2)
    assert abs(np.sum(np.abs(spectrum.astype(np.complex128)) ** 2) / energy - 1) < TOLERANCE[dtype]
    back = fft.ifftn(spectrum, norm="ortho")
    assert np.max(np.abs(back - signal)) < 10 * TOLERANCE[dtype] * np.max(np.abs(signal))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_real_fft_matches_numpy_and_round_trips(dtype):
    rng = np.random.default_rng(3)
    signal = rng.random((10, 9, 8)).astype(dtype)
    spectrum = fft.rfftn(signal)
    assert spectrum.dtype == (np.complex64 if dtype == np.float32 else np.complex128)
    reference = np.fft.rfftn(signal.astype(np.float64))
    assert np.max(np.abs(spectrum - reference)) < 50 * TOLERANCE[dtype] * np.max(np.abs(reference))
    assert np.max(np.abs(fft.irfftn(spectrum, 8) - signal)) < 10 * TOLERANCE[dtype]
    assert np.allclose(fft.fftn(signal.astype(np.float64)), np.fft.fftn(signal.astype(np.float64)))


def call(*args, **kwargs):
    """One row's arguments: positional and keyword."""
    return args, kwargs


@pytest.mark.parametrize("arguments, error, message", [
    (call(np.zeros(4), norm="unitary"), ValueError, "norm"),
    (call(np.zeros((4, 4)), axes=(0, 2)), ValueError, "axes"),
], ids=["unknown-norm", "axis-out-of-range"])
def test_fftn_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        fft.fftn(*args, **kwargs)


@pytest.mark.parametrize("arguments, error, message", [
    (call(np.zeros(4, complex)), ValueError, "real"),
], ids=["complex-input"])
def test_rfftn_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        fft.rfftn(*args, **kwargs)


def _random_sparse(shape, count, seed, real=False, channels=()):
    return random_sparse_fourier(shape, 2 * count if real else count, np.random.default_rng(seed), real=real,
                                 channels=channels)


@pytest.mark.parametrize("shape", [(32,), (9, 7), (6, 5, 4), (8, 6, 4, 3), (4, 3, 2, 3, 2)])
def test_to_signal_is_numpy_ifftn_of_the_scattered_coefficients(shape):
    representation = _random_sparse(shape, 20, seed=len(shape))
    dense = np.zeros(int(np.prod(shape)), complex)
    dense[representation.indices] = representation.values
    assert np.allclose(representation.to_signal(), np.fft.ifftn(dense.reshape(shape)))


def test_from_signal_round_trip_and_realness():
    rng = np.random.default_rng(0)
    signal = rng.random((6, 5, 4, 3))
    representation = SparseFourier.from_signal(signal, channel_axes=1)
    assert representation.real and representation.channel_shape == (3,)
    assert np.allclose(representation.to_signal(), signal)
    assert representation.to_signal().dtype == np.float64


def test_hermitian_closure_gives_the_real_part():
    representation = _random_sparse((6, 5, 4), 15, seed=5)
    closed = representation.hermitian_closure()
    assert np.allclose(closed.to_signal(), representation.to_signal().real)
    assert set(partner_indices(closed.shape, closed.indices)) == set(closed.indices)


def test_largest_keeps_hermitian_pairs_together():
    rng = np.random.default_rng(2)
    representation = SparseFourier.from_signal(rng.random((8, 6, 5)))
    for count in (1, 2, 7, 10, 51):
        kept = representation.largest(count)
        assert kept.sparsity in (count, count - 1)
        assert set(kept.partners()) == set(kept.indices)
        threshold = kept.energy().min()
        dropped = np.setdiff1d(representation.indices, kept.indices)
        dropped_energy = representation.energy()[np.searchsorted(representation.indices, dropped)]
        assert dropped_energy.max() <= threshold * (1 + 1e-9)


@pytest.mark.parametrize("arguments, error, message", [
    (dict(shape=(4, 4), indices=[0, 16], values=[1, 2]), ValueError, "out of range"),
    (dict(shape=(4, 4), indices=[3, 3], values=[1, 2]), ValueError, "distinct"),
    (dict(shape=(4, 4), indices=[1, 2], values=[1]), ValueError, "one row per index"),
    (dict(shape=(4, 0), indices=[], values=[]), ValueError, "positive"),
    (dict(shape=(4, 4), indices=[1], values=[1.0], real=True), ValueError, "partner"),
    (dict(shape=(4, 4), indices=[1, 3], values=[1.0, 5.0], real=True), ValueError, "conjugate"),
], ids=["index-out-of-range", "repeated-index", "too-few-values", "zero-size-axis", "real-without-partner",
        "real-partners-not-conjugate"])
def test_sparse_fourier_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        SparseFourier(**arguments)


CASES = [((16, 12, 4, 4), (0, 1)), ((8, 8, 6), (0, 1)), ((6, 5, 4, 3, 2), (0, 1)), ((10, 6, 4, 4), (2, 0)),
         ((6, 5, 4, 3), (3, 1, 0)), ((12,), ()), ((7, 6), (1,))]


@pytest.mark.parametrize("shape, keep", CASES)
@pytest.mark.parametrize("real", [False, True])
def test_every_integration_method_equals_the_direct_sum(shape, keep, real):
    representation = _random_sparse(shape, max(3, int(np.prod(shape)) // 20), seed=sum(shape), real=real)
    signal = representation.to_signal()
    integrated = tuple(axis for axis in range(len(shape)) if axis not in keep)
    direct = signal.sum(axis=integrated) / np.prod([shape[axis] for axis in integrated]) if integrated else signal
    ranks = list(np.argsort(np.argsort(keep)))
    direct = np.transpose(direct, ranks) if keep else direct
    for method in METHODS:
        result = integrate(representation, keep, method)
        assert result.shape == tuple(shape[axis] for axis in keep)
        assert np.allclose(result, direct, atol=1e-12), method
        assert np.isrealobj(result) == real


def test_integration_with_rgb_channels():
    representation = _random_sparse((8, 6, 4, 4), 40, seed=9, real=True, channels=(3,))
    expected = representation.to_signal().mean(axis=(2, 3))
    for method in METHODS:
        assert np.allclose(integrate(representation, (0, 1), method), expected)


@pytest.mark.parametrize("arguments, error, message", [
    (call(_random_sparse((4, 4, 2, 2), 5, 0), (0, 4)), ValueError, "out of range"),
    (call(_random_sparse((4, 4, 2, 2), 5, 0), (1, 1)), ValueError, "repeats"),
    (call(_random_sparse((4, 4, 2, 2), 5, 0), "xy"), ValueError, "axis"),
    (call(_random_sparse((4, 4), 3, 0), (0,), method="trapezoid"), ValueError, "convolution"),
], ids=["axis-out-of-range", "repeated-axis", "axis-names-not-numbers", "unknown-method"])
def test_integrate_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        integrate(*args, **kwargs)


def test_random_sparse_fourier_is_real_closed_and_reproducible():
    first = random_sparse_fourier((8, 6, 4), 30, np.random.default_rng(3), real=True)
    again = random_sparse_fourier((8, 6, 4), 30, np.random.default_rng(3), real=True)
    np.testing.assert_array_equal(first.indices, again.indices)
    assert first.real and set(first.partners()) == set(first.indices) and first.sparsity <= 30
    assert not np.iscomplexobj(first.to_signal())
    uniform = random_sparse_fourier((16,), 5, np.random.default_rng(0), values="uniform")
    assert uniform.sparsity == 5 and np.all((uniform.values.real >= 0) & (uniform.values.real < 1))
    decayed = random_sparse_fourier((64,), 10, np.random.default_rng(1), decay=2.0)
    assert np.sort(np.abs(decayed.values))[0] < np.sort(np.abs(decayed.values))[-1] / 10
    with pytest.raises(ValueError, match="'normal', 'uniform' or 'unit'"):
        random_sparse_fourier((8,), 2, np.random.default_rng(0), values="cauchy")
