"""The gradient-domain solvers of :mod:`sparselt.recovery.poisson` (issue 23, first part)."""

import numpy as np
import pytest
import scipy.sparse as sparse
import scipy.sparse.linalg as sparse_linalg

from sparselt.recovery.poisson import (PLAIN_ADMM, difference_adjoint, forward_differences, l1_objective,
                                       screened_poisson, screened_poisson_l1)


def _image(seed, shape=(23, 31, 3)):
    rng = np.random.default_rng(seed)
    return rng.random(shape)


def test_difference_adjoint_is_the_adjoint():
    rng = np.random.default_rng(1)
    image = rng.standard_normal((9, 12))
    gx, gy = rng.standard_normal((9, 11)), rng.standard_normal((8, 12))
    dx, dy = forward_differences(image)
    assert np.isclose(np.sum(dx * gx) + np.sum(dy * gy), np.sum(image * difference_adjoint(gx, gy)), rtol=1e-12)


@pytest.mark.parametrize("solver, options, bound", [
    (screened_poisson, {}, 1e-9),
    (screened_poisson_l1, {"precision": "double"}, 1e-9),
    (screened_poisson_l1, {}, 2e-6),  # the default float32 I step: float32 rounding of an image in [0, 1)
])
def test_exact_gradients_and_primal_recover_the_image_to_rounding(solver, options, bound):
    image = _image(2)
    result = solver(image, *forward_differences(image), **options)
    assert np.max(np.abs(result.estimate - image)) < bound


def test_the_dct_solve_equals_a_sparse_direct_solve():
    rng = np.random.default_rng(3)
    height, width, alpha = 7, 10, 0.2
    primal = rng.standard_normal((height, width))
    gx, gy = rng.standard_normal((height, width - 1)), rng.standard_normal((height - 1, width))

    def difference(n):
        return sparse.diags([-np.ones(n - 1), np.ones(n - 1)], [0, 1], shape=(n - 1, n))

    dx = sparse.kron(sparse.identity(height), difference(width))
    dy = sparse.kron(difference(height), sparse.identity(width))
    matrix = alpha ** 2 * sparse.identity(height * width) + dx.T @ dx + dy.T @ dy
    right = alpha ** 2 * primal.ravel() + dx.T @ gx.ravel() + dy.T @ gy.ravel()
    direct = sparse_linalg.spsolve(matrix.tocsc(), right).reshape(height, width)
    assert np.max(np.abs(screened_poisson(primal, gx, gy, alpha=alpha).estimate - direct)) < 1e-10


def test_the_l2_solution_is_linear_in_its_inputs():
    a, b = _image(4), _image(5)
    ga, gb = forward_differences(_image(6)), forward_differences(_image(7))
    combined = screened_poisson(2 * a - 3 * b, 2 * ga[0] - 3 * gb[0], 2 * ga[1] - 3 * gb[1]).estimate
    separate = 2 * screened_poisson(a, *ga).estimate - 3 * screened_poisson(b, *gb).estimate
    assert np.max(np.abs(combined - separate)) < 1e-10


def test_the_l2_solution_is_unbiased_when_its_inputs_are():
    """Unbiased primal and gradients (independent zero-mean noise): the mean reconstruction over seeds is the image,
    within 3 standard errors in every pixel but a Sidak-expected few (fixed seeds)."""
    image = _image(8, (12, 14))
    gradients = forward_differences(image)
    runs = []
    for seed in range(200):
        rng = np.random.default_rng(100 + seed)
        noisy = image + rng.standard_normal(image.shape)
        noisy_gradients = [g + rng.standard_normal(g.shape) for g in gradients]
        runs.append(screened_poisson(noisy, *noisy_gradients).estimate)
    runs = np.array(runs)
    error = runs.std(axis=0, ddof=1) / np.sqrt(len(runs))
    z = np.abs(runs.mean(axis=0) - image) / error
    assert np.mean(z > 3) < 0.02  # 0.27% expected outside 3 standard errors
    assert abs(float((runs.mean(axis=0) - image).mean())) < 3 * float(runs.mean(axis=(1, 2)).std(ddof=1)) / np.sqrt(200)


def test_l1_ignores_a_few_outlying_gradients_that_l2_spreads():
    image = _image(9, (20, 20))
    gx, gy = forward_differences(image)
    gx = gx.copy()
    gx[10, 10] += 50.0  # one firefly-like gradient
    l2 = screened_poisson(image, gx, gy).estimate
    l1 = screened_poisson_l1(image, gx, gy, max_iterations=500)
    assert np.max(np.abs(l1.estimate - image)) < 0.05 * np.max(np.abs(l2 - image))
    assert l1.stop_reason in ("converged", "max_iterations") and l1.iterations >= 1


@pytest.mark.parametrize("arguments, message", [
    (dict(primal=np.zeros(5)), "primal must be"),
    (dict(gradient_x=np.zeros((6, 6))), r"gradient_x must have shape \(6, 7\)"),
    (dict(gradient_y=np.zeros((6, 8))), r"gradient_y must have shape \(5, 8\)"),
    (dict(alpha=0.0), "alpha must be a positive"),
    (dict(primal=np.full((6, 8), np.nan)), "primal holds NaN"),
])
def test_bad_input_is_refused(arguments, message):
    given = dict(primal=np.zeros((6, 8)), gradient_x=np.zeros((6, 7)), gradient_y=np.zeros((5, 8)), alpha=0.2)
    given.update(arguments)
    with pytest.raises(ValueError, match=message):
        screened_poisson(given.pop("primal"), given.pop("gradient_x"), given.pop("gradient_y"), **given)


def test_l2_at_512_squared_recovers_the_image():
    """The issue's size (its 0.1 s target is measured by hand, never asserted here): exact inputs, exact output."""
    image = _image(10, (512, 512, 3))
    result = screened_poisson(image, *forward_differences(image))
    assert np.max(np.abs(result.estimate - image)) < 1e-9


def test_l1_iterations_do_not_depend_on_the_image_scale():
    """The penalty is in units of the data: scaling every input by s scales the result by s, same iterations."""
    rng = np.random.default_rng(11)
    image = _image(12, (16, 18))
    noisy = image + 0.1 * rng.standard_normal(image.shape)
    gradients = [g + 0.1 * rng.standard_normal(g.shape) for g in forward_differences(image)]
    # Exactly so in double precision; the default float32 I step rounds 1000 x differently (to its rounding).
    one = screened_poisson_l1(noisy, *gradients, precision="double")
    scaled = screened_poisson_l1(1000.0 * noisy, *[1000.0 * g for g in gradients], precision="double")
    assert one.iterations == scaled.iterations
    np.testing.assert_allclose(scaled.estimate, 1000.0 * one.estimate, rtol=1e-8, atol=1e-8)
    one, scaled = screened_poisson_l1(noisy, *gradients), screened_poisson_l1(1000.0 * noisy, *[1000.0 * g for g in gradients])
    assert np.linalg.norm(scaled.estimate - 1000.0 * one.estimate) < 1e-2 * np.linalg.norm(1000.0 * one.estimate)
    with pytest.raises(ValueError, match="start must be 'primal', 'l2' or an image"):
        screened_poisson_l1(noisy, *gradients, start="zero")


def _admm_in_numpy(primal, gradient_x, gradient_y, alpha, penalty, tolerance, max_iterations):
    """The L1 solve's ADMM as plain NumPy expressions, one array per part: what the fused kernels must compute."""
    from scipy.fft import dctn, idctn

    height, width = primal.shape[:2]
    ky = 4.0 * np.sin(np.pi * np.arange(height) / (2.0 * height)) ** 2
    kx = 4.0 * np.sin(np.pi * np.arange(width) / (2.0 * width)) ** 2
    eigenvalues = (ky[:, None] + kx[None, :])[..., None]
    targets = (alpha * primal, gradient_x, gradient_y)
    size = sum(part.size for part in targets)
    rho = penalty * size / sum(float(np.sum(np.abs(part))) for part in targets)

    def soft(value):
        return np.sign(value) * np.maximum(np.abs(value) - 1.0 / rho, 0.0)

    def apply(image):
        return (alpha * image,) + forward_differences(image)

    image = primal.copy()
    residual = [h - b for h, b in zip(apply(image), targets)]
    z = [soft(r) for r in residual]
    u = [r - zz for r, zz in zip(residual, z)]
    history = []
    for _ in range(max_iterations):
        shifted = [b + zz - uu for b, zz, uu in zip(targets, z, u)]
        right = alpha * shifted[0] + difference_adjoint(shifted[1], shifted[2])
        previous = image
        spectrum = dctn(right, type=2, norm="ortho", axes=(0, 1))
        spectrum /= alpha * alpha + eigenvalues
        image = idctn(spectrum, type=2, norm="ortho", axes=(0, 1))
        fitted = apply(image)
        z = [soft(h - b + uu) for h, b, uu in zip(fitted, targets, u)]
        u = [uu + h - b - zz for uu, h, b, zz in zip(u, fitted, targets, z)]
        history.append(np.linalg.norm(image - previous) / np.linalg.norm(image))
        if history[-1] < tolerance:
            break
    return image, history


@pytest.mark.parametrize("shape", [(23, 31, 3), (300, 260, 3)])
def test_the_fused_admm_computes_the_numpy_iterations(shape):
    """The L1 solve's fused kernels (kernels.admm_*) against the NumPy expressions: the same image, bit for bit.

    The larger shape runs the kernels in parallel; the stop rule's norms agree to rounding.
    """
    image = _image(5, shape)
    rng = np.random.default_rng(6)
    gradient_x, gradient_y = forward_differences(image)
    gradient_x = gradient_x + rng.standard_normal(gradient_x.shape) * 0.05
    gradient_y = gradient_y + rng.standard_normal(gradient_y.shape) * 0.05
    gradient_x[3, 4] += 5.0  # an outlier the soft threshold must keep out
    primal = image + rng.standard_normal(image.shape) * 0.1
    expected, history = _admm_in_numpy(primal, gradient_x, gradient_y, 0.2, 1.0, 1e-3, 12)
    result = screened_poisson_l1(primal, gradient_x, gradient_y, alpha=0.2, tolerance=1e-3, max_iterations=12,
                                 **PLAIN_ADMM)
    assert result.iterations == len(history)
    np.testing.assert_array_equal(result.estimate, expected)
    np.testing.assert_allclose(result.residual_history, history, rtol=1e-12)


def _noisy_problem(seed, shape=(40, 48, 3)):
    """A random noisy gradient-domain problem: an image, Gaussian noise on primal and gradients, a few outliers."""
    rng = np.random.default_rng(seed)
    image = _image(seed, shape)
    gradient_x, gradient_y = (g + 0.05 * rng.standard_normal(g.shape) for g in forward_differences(image))
    gradient_x[rng.integers(0, shape[0], 10), rng.integers(0, shape[1] - 1, 10)] += 3.0  # firefly-like outliers
    return image + 0.1 * rng.standard_normal(image.shape), gradient_x, gradient_y


@pytest.fixture(scope="module")
def long_plain_run():
    """Plain ADMM (the first version: primal start, no relaxation, float64), 2000 iterations: the minimiser's
    objective to about 1e-6 (relative) on these problems."""
    runs = {}
    for seed in (21, 22):
        problem = _noisy_problem(seed)
        result = screened_poisson_l1(*problem, max_iterations=2000, tolerance=1e-15, **PLAIN_ADMM)
        assert result.iterations == 2000 and result.stop_reason == "max_iterations"
        runs[seed] = problem, l1_objective(result.estimate, *problem)
    return runs


@pytest.mark.parametrize("seed", [21, 22])
def test_the_default_solve_reaches_the_long_plain_runs_objective(long_plain_run, seed):
    """Relaxation, the L2 start and the float32 I step change the path, not the minimiser: run long, the defaults
    reach the objective of 2000 plain iterations to 1e-4 (relative; float32 I steps leave about 1e-6)."""
    problem, reference = long_plain_run[seed]
    result = screened_poisson_l1(*problem, max_iterations=2000, tolerance=1e-9)
    assert abs(l1_objective(result.estimate, *problem) / reference - 1) < 1e-4
    plain = screened_poisson_l1(*problem, max_iterations=2000, tolerance=1e-9, **PLAIN_ADMM)
    # The L1 minimiser is weakly determined along flat directions: images within 1% (measured 0.2-0.25%).
    assert np.linalg.norm(result.estimate - plain.estimate) < 1e-2 * np.linalg.norm(plain.estimate)


@pytest.mark.parametrize("seed", [21, 22])
def test_the_defaults_beat_plain_admm_at_the_methods_budget(long_plain_run, seed):
    """At gradient-l1's budget (50 iterations at most, tolerance 1e-3) the defaults end at least as close to the
    minimiser as plain ADMM did, in at most as many iterations."""
    problem, reference = long_plain_run[seed]
    new = screened_poisson_l1(*problem, max_iterations=50, tolerance=1e-3)
    old = screened_poisson_l1(*problem, max_iterations=50, tolerance=1e-3, **PLAIN_ADMM)
    assert new.iterations <= old.iterations
    assert l1_objective(new.estimate, *problem) - reference <= l1_objective(old.estimate, *problem) - reference


@pytest.mark.parametrize("precision", ["single", "double"])
def test_warm_started_and_plain_starts_agree(precision):
    """From the L2 solution or from the primal image, run long, the iterates meet at the same minimiser."""
    problem = _noisy_problem(23)
    warm = screened_poisson_l1(*problem, start="l2", max_iterations=1500, tolerance=1e-12, precision=precision)
    cold = screened_poisson_l1(*problem, start="primal", max_iterations=1500, tolerance=1e-12, precision=precision)
    warm_objective, cold_objective = l1_objective(warm.estimate, *problem), l1_objective(cold.estimate, *problem)
    assert abs(warm_objective / cold_objective - 1) < 1e-4
    assert np.linalg.norm(warm.estimate - cold.estimate) < 1e-2 * np.linalg.norm(cold.estimate)


@pytest.mark.parametrize("options", [{}, {"precision": "double"}, {"relaxation": 1.8, "start": "primal"}])
def test_the_l1_solve_is_deterministic(options):
    """The same inputs give the same bytes (parallel kernels and threaded DCTs included); shape (300, 260, 3) runs
    the kernels in parallel."""
    problem = _noisy_problem(24, (300, 260, 3))
    first = screened_poisson_l1(*problem, max_iterations=15, **options)
    second = screened_poisson_l1(*problem, max_iterations=15, **options)
    assert first.estimate.dtype == np.float64 and first.estimate.shape == problem[0].shape
    assert first.estimate.tobytes() == second.estimate.tobytes()
    assert first.residual_history == second.residual_history and first.iterations == second.iterations


def test_the_stop_reason_and_iterations_are_truthful():
    problem = _noisy_problem(25)
    capped = screened_poisson_l1(*problem, max_iterations=3, tolerance=1e-12)
    assert capped.iterations == 3 == len(capped.residual_history) and capped.stop_reason == "max_iterations"
    loose = screened_poisson_l1(*problem, max_iterations=500, tolerance=0.05)
    assert loose.stop_reason == "converged" and loose.iterations == len(loose.residual_history) < 500
    assert loose.residual_history[-1] < 0.05 <= min(loose.residual_history[:-1], default=1.0)


@pytest.mark.parametrize("arguments, message", [
    (dict(relaxation=2.0), r"relaxation must be in \(0, 2\)"),
    (dict(relaxation=0.0), r"relaxation must be in \(0, 2\)"),
    (dict(precision="half"), "precision must be 'single' or 'double'"),
])
def test_bad_l1_options_are_refused(arguments, message):
    with pytest.raises(ValueError, match=message):
        screened_poisson_l1(np.zeros((6, 8)), np.zeros((6, 7)), np.zeros((5, 8)), **arguments)


def test_l1_from_a_given_start_image_is_the_l1_from_the_same_image_computed_inside():
    """start=<the L2 solution> takes the same steps as start='l2'; a start of another shape is refused."""
    primal, gradient_x, gradient_y = _noisy_problem(4, shape=(24, 20, 3))
    l2 = screened_poisson(primal, gradient_x, gradient_y, alpha=0.3).estimate
    inside = screened_poisson_l1(primal, gradient_x, gradient_y, alpha=0.3, max_iterations=7)
    given = screened_poisson_l1(primal, gradient_x, gradient_y, alpha=0.3, max_iterations=7, start=l2)
    np.testing.assert_array_equal(given.estimate, inside.estimate)
    with pytest.raises(ValueError, match="a start image must have the primal's shape"):
        screened_poisson_l1(primal, gradient_x, gradient_y, start=l2[:-1])
