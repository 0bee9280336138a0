"""Partial-Fourier operator (adjoint, isometry) and CoSaMP / OMP recovery."""

import math

import numpy as np
import pytest

from sparselt.fourier.sparse import SparseFourier, random_sparse_fourier
from sparselt.operators import LinearOperator, PartialFourier, dottest
from sparselt.recovery.cosamp import cosamp, omp

SHAPES = [(64,), (63,), (12, 10), (8, 6, 5), (6, 5, 4, 4)]


def _coordinate_vector(operator, rng):
    """A random vector of the operator's coordinate space (non-canonical entries zero, self-conjugate real)."""
    vector = (rng.standard_normal(operator.input_size) + 1j * rng.standard_normal(operator.input_size)).astype(operator.dtype)
    if operator.real:
        vector[operator._noncanonical] = 0
        vector[operator._selfconjugate] = vector[operator._selfconjugate].real
    return vector


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("real", [True, False])
@pytest.mark.parametrize("dtype, tolerance", [(np.float32, 1e-5), (np.float64, 1e-12)])
def test_adjoint(shape, real, dtype, tolerance):
    rng = np.random.default_rng(len(shape))
    size = math.prod(shape)
    operator = PartialFourier(shape, rng.choice(size, size // 3, replace=False), real=real, dtype=dtype)
    for seed in range(3):
        assert dottest(operator, seed=seed, rtol=tolerance, input_vector=_coordinate_vector(operator, rng))
        assert dottest(operator, seed=seed, rtol=tolerance)  # any complex vector: the real inner product holds


@pytest.mark.parametrize("real", [True, False])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_operator_in_pylops_terms(real, dtype):
    shape = (6, 5, 4)
    operator = PartialFourier(shape, np.arange(0, 120, 3), real=real, dtype=dtype)
    assert operator.shape == (40, math.prod(operator.dims)) and operator.dimsd == (40,)
    assert operator.clinear is (not real)
    y = np.random.default_rng(1).standard_normal(40).astype(operator.data_dtype)
    np.testing.assert_array_equal(operator.H.matvec(y), operator.rmatvec(y))
    x = operator.rmatvec(y)
    np.testing.assert_array_equal(operator @ x, operator.matvec(x))
    assert operator.H.H is operator
    assert dottest(operator.H)


class _WrongAdjoint(LinearOperator):
    """A 3x4 matrix whose 'adjoint' forgets the conjugate transpose."""

    def __init__(self):
        self.matrix = np.arange(12.0).reshape(3, 4) + 1j
        self.dims, self.dimsd, self.dtype, self.clinear = (4,), (3,), np.dtype(np.complex128), True

    def _matvec(self, vector):
        return self.matrix @ vector

    def _rmatvec(self, vector):
        return self.matrix.T @ vector  # should be .conj().T


def test_dottest_raises_on_a_wrong_adjoint():
    with pytest.raises(AssertionError, match="dot test failed"):
        dottest(_WrongAdjoint())
    assert dottest(_WrongAdjoint(), raise_error=False) is False


def test_matvec_checks_the_vector_size():
    operator = PartialFourier((4, 4), np.arange(8))
    with pytest.raises(ValueError, match="matvec takes 12 values"):
        operator.matvec(np.zeros(5))


def test_cosamp_callback_sees_every_iteration_and_can_stop():
    rng = np.random.default_rng(3)
    shape = (16, 16)
    signal = np.real(np.fft.ifft2(np.where(rng.random(shape) < 0.02, rng.standard_normal(shape), 0))).astype(np.float32)
    operator = PartialFourier(shape, rng.choice(256, 120, replace=False), dtype=np.float32)
    seen = []
    result = cosamp(operator, signal.reshape(-1)[operator.indices], 12,
                    callback=lambda iteration, residual, support, values: seen.append((iteration, residual)) or iteration == 2)
    assert result.stop_reason == "callback" and [i for i, _ in seen] == [1, 2]
    assert seen[-1][1] == pytest.approx(result.residual_history[1])
    with pytest.raises(TypeError, match="callback must be callable"):
        cosamp(operator, signal.reshape(-1)[operator.indices], 12, callback=3)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("real", [True, False])
def test_fully_sampled_operator_is_an_isometry_onto_the_signal(shape, real):
    """Every cell sampled: ||A u|| = ||u||, and A u equals the SparseFourier signal of u."""
    rng = np.random.default_rng(7)
    operator = PartialFourier(shape, np.arange(math.prod(shape)), real=real, dtype=np.float64)
    vector = _coordinate_vector(operator, rng)
    samples = operator.matvec(vector)
    assert np.linalg.norm(samples) == pytest.approx(np.linalg.norm(vector), rel=1e-12)
    support = np.flatnonzero(vector)
    estimate = operator.to_sparse_fourier(support, vector[support])
    assert estimate.real == real
    assert np.allclose(estimate.to_signal().reshape(-1), samples)


def _sparse_signal(shape, count, rng, real=True):
    representation = random_sparse_fourier(shape, count, rng, real=real)
    return representation.to_signal(), representation.sparsity


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("shape", [(512,), (40, 30), (16, 12, 10), (12, 10, 8, 6)])
@pytest.mark.parametrize("real", [True, False])
def test_cosamp_recovers_exactly_sparse_signals(seed, shape, real):
    rng = np.random.default_rng(seed)
    size = math.prod(shape)
    signal, count = _sparse_signal(shape, max(4, size // 100), rng, real)
    indices = rng.choice(size, size // 4, replace=False)
    operator = PartialFourier(shape, indices, real=real, dtype=np.float64)
    result = cosamp(operator, signal.reshape(-1)[indices], count, tolerance=1e-9)
    assert result.relative_error(signal) <= 1e-5
    assert result.stop_reason == "converged"
    assert result.samples == indices.size and result.iterations <= 30
    assert set(result.seconds) == {"proxy", "select", "least_squares", "prune", "residual"}
    assert result.estimate.sparsity <= count + 1


def test_cosamp_in_single_precision():
    rng = np.random.default_rng(4)
    shape = (32, 24, 8, 8)
    signal, count = _sparse_signal(shape, 800, rng)
    indices = np.sort(rng.choice(signal.size, signal.size // 10, replace=False))
    operator = PartialFourier(shape, indices, dtype=np.float32)
    result = cosamp(operator, signal.reshape(-1)[indices].astype(np.float32), count)
    assert result.relative_error(signal) <= 1e-5


@pytest.mark.parametrize("noise", [0.01, 0.05])
def test_cosamp_error_stays_within_a_small_multiple_of_the_noise(noise):
    rng = np.random.default_rng(11)
    shape = (40, 30, 8)
    signal, count = _sparse_signal(shape, 96, rng)
    indices = rng.choice(signal.size, signal.size // 5, replace=False)
    clean = signal.reshape(-1)[indices]
    perturbation = rng.standard_normal(clean.size)
    perturbation *= noise * np.linalg.norm(clean) / np.linalg.norm(perturbation)
    operator = PartialFourier(shape, indices, dtype=np.float64)
    result = cosamp(operator, clean + perturbation, count)
    assert result.relative_error(signal) <= 4 * noise
    assert result.stop_reason in ("stagnated", "max_iterations", "converged")


def test_cosamp_on_a_compressible_signal_is_close_to_the_best_k_term_approximation():
    rng = np.random.default_rng(5)
    shape = (48, 40, 6)
    size = math.prod(shape)
    indices = rng.choice(size, 600, replace=False)
    values = (rng.standard_normal(600) + 1j * rng.standard_normal(600)) * np.arange(1, 601) ** -1.2
    representation = SparseFourier(shape, indices, values).hermitian_closure()
    signal = representation.to_signal()
    count = 200
    best = representation.largest(count).to_signal()
    best_error = np.linalg.norm(best - signal) / np.linalg.norm(signal)
    sampled = rng.choice(size, size // 4, replace=False)
    result = cosamp(PartialFourier(shape, sampled, dtype=np.float64), signal.reshape(-1)[sampled], count)
    assert result.relative_error(signal) <= 3 * best_error + 1e-6
    assert result.iterations <= 30


@pytest.mark.parametrize("real", [True, False])
def test_omp_recovers_small_problems_exactly(real):
    rng = np.random.default_rng(3)
    shape = (24, 20)
    signal, count = _sparse_signal(shape, 12, rng, real)
    indices = rng.choice(signal.size, 160, replace=False)
    result = omp(PartialFourier(shape, indices, real=real, dtype=np.float64), signal.reshape(-1)[indices], count)
    assert result.relative_error(signal) <= 1e-8
    assert result.estimate.sparsity == count


def test_cosamp_residual_history_is_recorded():
    rng = np.random.default_rng(8)
    signal, count = _sparse_signal((30, 20, 8), 60, rng)
    indices = rng.choice(signal.size, signal.size // 4, replace=False)
    result = cosamp(PartialFourier((30, 20, 8), indices, dtype=np.float64), signal.reshape(-1)[indices], count)
    assert len(result.residual_history) == result.iterations
    assert result.residual_history[-1] < result.residual_history[0]
    assert result.transforms >= 2 * result.iterations


@pytest.fixture
def small_problem():
    rng = np.random.default_rng(0)
    indices = rng.choice(200, 50, replace=False)
    return PartialFourier((20, 10), indices, dtype=np.float64), rng.standard_normal(50)


def _unchanged(samples):
    return samples


def _drop_last(samples):
    return samples[:-1]


def _with_nan(samples):
    bad = samples.copy()
    bad[3] = np.nan
    return bad


def _complex(samples):
    return samples + 1j


# Rows: (how the 50 good samples of small_problem are spoiled, sparsity K).
@pytest.mark.parametrize("arguments, error, message", [
    ((_unchanged, 0), ValueError, "0 < K"),
    ((_unchanged, -3), ValueError, "0 < K"),
    ((_unchanged, 50), ValueError, "0 < K"),
    ((_unchanged, 2.5), TypeError, "integer"),
    ((_drop_last, 5), ValueError, "50 samples"),
    ((_complex, 5), ValueError, "complex"),
], ids=["sparsity-zero", "negative-sparsity", "sparsity-equal-to-samples", "non-integer-sparsity",
        "wrong-length", "complex-samples"])
def test_cosamp_invalid_input(small_problem, arguments, error, message):
    operator, samples = small_problem
    spoil, count = arguments
    with pytest.raises(error, match=message):
        cosamp(operator, spoil(samples), count)


@pytest.mark.parametrize("arguments, error, message", [
    ((_with_nan, 5), ValueError, "NaN"),
], ids=["nan-sample"])
def test_omp_invalid_input(small_problem, arguments, error, message):
    operator, samples = small_problem
    spoil, count = arguments
    with pytest.raises(error, match=message):
        omp(operator, spoil(samples), count)


def call(*args, **kwargs):
    """One row's arguments: positional and keyword."""
    return args, kwargs


@pytest.mark.parametrize("arguments, error, message", [
    (call((20, 10), np.array([])), ValueError, "non-empty"),
    (call((20, 10), np.array([0, 200])), ValueError, "out of range"),
    (call((20, 10), np.array([-1, 3])), ValueError, "out of range"),
    (call((20, 10), np.array([4, 7, 4])), ValueError, "repeated"),
    (call((20, 10), np.array([0.5, 2.0])), ValueError, "integers"),
    (call((20, 0), [1]), ValueError, "positive"),
    (call((20, 10), [1], dtype=np.int32), ValueError, "float32 or float64"),
], ids=["no-indices", "index-past-the-end", "negative-index", "repeated-index", "fractional-indices",
        "zero-size-axis", "integer-dtype"])
def test_partial_fourier_invalid_input(arguments, error, message):
    args, kwargs = arguments
    with pytest.raises(error, match=message):
        PartialFourier(*args, **kwargs)


def test_repeated_samples_become_cell_means_and_recover():
    from sparselt.operators import mean_per_cell

    rng = np.random.default_rng(12)
    shape = (30, 20, 6)
    signal, count = _sparse_signal(shape, 40, rng)
    cells = rng.integers(0, signal.size, size=signal.size // 2)  # with repeats
    noise = 0.01 * signal.std() * rng.standard_normal(cells.size)
    unique, means, counts = mean_per_cell(cells, signal.reshape(-1)[cells] + noise)
    assert counts.sum() == cells.size and np.all(np.diff(unique) > 0)
    first = unique[np.argmax(counts)]
    assert means[np.argmax(counts)] == pytest.approx(np.mean(signal.reshape(-1)[first] + noise[cells == first]))
    result = cosamp(PartialFourier(shape, unique, dtype=np.float64), means, count)
    assert result.relative_error(signal) < 0.05
