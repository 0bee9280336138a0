"""CoSaMP and OMP on a partial-Fourier operator (thesis 2.2.1, Algorithms 1 and 2).

Both recover the Fourier coefficients of a grid signal from point samples
``y = A u`` with :class:`~sparselt.operators.PartialFourier`. Everything of
signal size is an FFT; every other step works on vectors of support size or
sample size.

CoSaMP iteration (Needell & Tropp 2009):

1. proxy ``A^* r`` by one FFT of the residual;
2. select the ``2K`` largest proxy entries and merge them with the current
   support;
3. least squares on the merged support by a few conjugate-gradient steps,
   warm-started from the current estimate (its first gradient *is* the
   proxy on the support, so it costs nothing); each step is two FFTs
   (four steps by default: measured fastest overall on 250x250x16x16);
4. prune to the ``K`` largest;
5. residual ``y - A u`` by one inverse FFT.

It stops when the relative residual falls below ``tolerance``, when it has not
improved for ``patience`` iterations (compressible or noisy signals: the best
estimate is kept), or after ``max_iterations``.

Model-based CoSaMP (Baraniuk et al. 2010): with ``allowed``, a set of
frequencies known to hold the signal's support, step 2 selects among those
only, so the support never leaves them.
"""

from __future__ import annotations

import math

import numpy as np

from ..checks import check_integer
from ..fourier.hermitian import keep_within, partner_indices
from ..measurement import PhaseTimer
from ..operators.base import SupportRestricted
from .result import RecoveryResult


def _validate(operator, samples, sparsity):
    if not isinstance(operator, SupportRestricted):
        raise TypeError(f"operator must provide the support-restricted operations of "
                        f"sparselt.operators.SupportRestricted (as PartialFourier does), got {type(operator).__name__}")
    samples = np.asarray(samples)
    if samples.ndim != 1 or samples.size != operator.output_size:
        raise ValueError(f"y must be a vector of {operator.output_size} samples (one per sampled cell), got shape {samples.shape}")
    if operator.real and np.iscomplexobj(samples):
        raise ValueError("the operator is real (real=True) but y is complex")
    if not np.all(np.isfinite(samples)):
        bad = int(np.count_nonzero(~np.isfinite(samples)))
        raise ValueError(f"y has {bad} NaN or infinite samples; drop or repair them before recovery")
    sparsity = check_integer("sparsity K", sparsity, -2**62)
    if not 0 < sparsity < operator.output_size:
        raise ValueError(f"sparsity K must satisfy 0 < K < number of samples ({operator.output_size}), got {sparsity}")
    samples = samples.astype(operator.sample_dtype, copy=False)
    norm = float(np.linalg.norm(samples.astype(np.result_type(samples.dtype, np.float64))))
    largest = (float(np.finfo(operator.sample_dtype).max) / max(1, samples.size)) ** 0.5  # keeps ||y||^2 finite
    if not np.isfinite(norm) or float(np.abs(samples).max(initial=0.0)) > largest:
        raise ValueError(f"y holds values up to {float(np.abs(samples).max()):.3g}, too large for "
                         f"{np.dtype(operator.sample_dtype).name} arithmetic (at most {largest:.3g} here); "
                         "divide y by a scale and multiply the estimate back")
    return samples


def _check_tolerance(tolerance):
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float, np.floating)):
        raise TypeError(f"tolerance must be a number, got {tolerance!r}")
    if not (np.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"tolerance must be finite and >= 0, got {tolerance!r}")
    return float(tolerance)


def _largest(energy, budget, operator, labels=None):
    """Coefficient entries of largest energy whose counts add up to at most ``budget``.

    The top-K rule of :mod:`sparselt.fourier.hermitian` on half-spectrum
    entries, each of which stands for a whole Hermitian group (1 or 2 counts).

    ``energy[i]`` belongs to flat coefficient index ``labels[i]`` (default ``i``).
    """
    guess = min(energy.size, (budget // 2 + 64) if operator.real else budget)
    if guess < energy.size:
        top = _top_entries(energy, guess)
    else:
        top = np.arange(energy.size)
    top = top[np.argsort(-energy[top], kind="stable")]
    chosen = top if labels is None else labels[top]
    return np.sort(chosen[keep_within(operator.coefficient_counts(chosen), budget)])


def _top_entries(energy, count):
    """Indices of the ``count`` largest entries (any order), in about one pass over ``energy``.

    A strided subsample estimates a threshold a little below the ``count``-th
    largest value; only the entries above it are partitioned exactly. Falls
    back to a full partition when the estimate leaves too few candidates.
    """
    size = energy.size
    if size > 1 << 20 and count < size // 8:
        stride = 31
        subsample = energy[::stride]
        keep_fraction = min(1.0, 1.5 * count / size + 20.0 / subsample.size)
        rank = int((1.0 - keep_fraction) * (subsample.size - 1))
        threshold = np.partition(subsample, rank)[rank]
        candidates = np.flatnonzero(energy >= threshold)
        if count <= candidates.size <= 4 * count + 1024:
            values = energy[candidates]
            return candidates[np.argpartition(values, values.size - count)[values.size - count:]]
    return np.argpartition(energy, size - count)[size - count:]


def _sorted_union(first, second):
    """Sorted distinct entries of two index arrays (a sort, not numpy's hash-based unique: faster here)."""
    merged = np.concatenate([first, second])
    merged.sort()
    return merged[np.concatenate([[True], merged[1:] != merged[:-1]])] if merged.size else merged


def _conjugate_gradient(operator, support, values, samples, residual, gradient, steps):
    """Minimise ``||samples - A_T u||`` from ``values``; ``residual`` and ``gradient`` belong to ``values``.

    Real inner product throughout (the real-signal operator is only real-linear).
    Returns the new values and the residual in sample space. ``2 steps - 1`` FFTs.
    """
    direction = gradient.copy()
    gradient_norm = np.vdot(gradient, gradient).real
    for step in range(steps):
        if gradient_norm == 0.0:
            break
        image = operator.forward_on(support, direction)
        curvature = np.vdot(image, image).real
        if curvature <= 0.0:
            break
        step_length = gradient_norm / curvature
        values = values + step_length * direction
        residual = residual - step_length * image
        if step == steps - 1:
            break
        gradient = operator.adjoint_on(support, residual)
        new_norm = np.vdot(gradient, gradient).real
        direction = gradient + (new_norm / gradient_norm) * direction
        gradient_norm = new_norm
    return values, residual


def _warm_least_squares(operator, merged, support, values, spectrum, samples, residual, steps):
    """Least squares on ``merged``, warm-started from ``values`` on ``support``.

    The first gradient is the proxy ``spectrum`` restricted to ``merged``, so it costs no transform.
    """
    warm = np.zeros(merged.size, dtype=operator.coefficient_dtype)
    warm[np.searchsorted(merged, support)] = values
    gradient = operator.adjoint_on(merged, None, spectrum)
    return _conjugate_gradient(operator, merged, warm, samples, residual, gradient, steps)


def _allowed_entries(operator, allowed):
    """The coefficient entries (flat, sorted) that a full-spectrum mask ``allowed`` admits, or None for all.

    ``allowed`` is a boolean array of the signal's grid shape over the full
    spectrum (``numpy.fft.fftn`` order). For a real operator it must be
    Hermitian-symmetric, so that it keeps or drops each conjugate pair whole;
    its half-spectrum entries are kept, less the non-canonical ones (their
    canonical partner stands for the pair).
    """
    if allowed is None:
        return None
    grid_shape = getattr(operator, "grid_shape", None)
    coefficient_shape = getattr(operator, "coefficient_shape", None)
    if grid_shape is None or coefficient_shape is None:
        raise TypeError(f"allowed needs an operator with grid_shape and coefficient_shape (as PartialFourier has), "
                        f"got {type(operator).__name__}")
    mask = np.asarray(allowed)
    if mask.dtype != np.bool_:
        raise TypeError(f"allowed must be a boolean mask over the spectrum, got dtype {mask.dtype}")
    if mask.shape != tuple(grid_shape):
        raise ValueError(f"allowed must have the signal's grid shape {tuple(grid_shape)} (the full spectrum), "
                         f"got {mask.shape}")
    if not operator.real:
        entries = np.flatnonzero(mask)
    else:
        partner = np.roll(np.flip(mask), 1, axis=tuple(range(mask.ndim)))  # mask at -k mod shape
        if not np.array_equal(mask, partner):
            bad = np.unravel_index(int(np.flatnonzero(mask != partner)[0]), mask.shape)
            raise ValueError(f"allowed must be Hermitian-symmetric for a real signal (frequency k allowed exactly "
                             f"when -k is), but differs from its mirror at {tuple(int(v) for v in bad)}; "
                             "build it symmetric (mask | mask at -k)")
        entries = np.flatnonzero(mask[..., :coefficient_shape[-1]])
        last = grid_shape[-1]
        plane = entries % coefficient_shape[-1]
        in_plane = (plane == 0) | ((last % 2 == 0) & (2 * plane == last))
        if in_plane.any():  # both members of a pair are half-spectrum entries: keep the canonical one
            full = np.ravel_multi_index(np.unravel_index(entries[in_plane], coefficient_shape), grid_shape)
            keep = np.ones(entries.size, dtype=bool)
            keep[in_plane] = partner_indices(grid_shape, full) >= full
            entries = entries[keep]
    if entries.size == 0:
        raise ValueError("allowed admits no coefficient: give at least one allowed frequency")
    return entries.astype(np.int64)


def _check_callback(callback):
    if callback is not None and not callable(callback):
        raise TypeError(f"callback must be callable or None, got {callback!r}")
    return callback


def _start(operator, y, sparsity, tolerance, callback, phases):
    """The checked inputs and the empty state every greedy solver starts from (CoSaMP, OMP)."""
    samples = _validate(operator, y, sparsity)
    clock = PhaseTimer(phases)
    support = np.zeros(0, dtype=np.int64)
    values = np.zeros(0, dtype=operator.coefficient_dtype)
    return (samples, _check_tolerance(tolerance), _check_callback(callback), clock, operator.transforms,
            float(np.linalg.norm(samples)) or 1.0, support, values, samples.copy(), [])


def _stop(relative, tolerance, callback, iteration, support, values):
    """``'converged'`` at the tolerance, ``'callback'`` when the callback says stop, else ``None``."""
    if relative <= tolerance:
        return "converged"
    if callback is not None and callback(iteration, relative, support, values):
        return "callback"
    return None


def cosamp(operator, y, sparsity, *, max_iterations=30, tolerance=1e-6, conjugate_gradient_steps=4,
           patience=2, stagnation=1e-3, callback=None, allowed=None):
    """Compressive Sampling Matching Pursuit (Needell & Tropp 2009; thesis Algorithm 2).

    Parameters
    ----------
    operator : PartialFourier
        Sampled cells and the Fourier representation.
    y : ndarray, shape (number of samples,)
        Sample values (real for a real operator).
    sparsity : int
        ``K``: full-spectrum coefficients to keep (a conjugate pair of a real
        signal counts as two), ``0 < K < number of samples``.
    max_iterations : int, optional
        Upper bound on iterations.
    tolerance : float, optional
        Stop when ``||y - A u|| / ||y||`` is below this.
    conjugate_gradient_steps : int, optional
        Warm-started CG steps for the least squares on the merged support.
    patience, stagnation : int, float, optional
        Stop when the residual has not fallen by a relative ``stagnation``
        for ``patience`` iterations; the best estimate is returned.
    callback : callable, optional
        Called after every iteration as ``callback(iteration, relative_residual,
        support, values)`` (PyLops' and sigpy's hook); returning True stops
        the run (stop reason ``'callback'``).
    allowed : ndarray of bool, optional
        Model-based recovery: a mask of the signal's grid shape over the full
        spectrum (``numpy.fft.fftn`` order), True where a frequency may enter
        the support; the ``2K`` selection looks at those only. For a real
        signal it must be Hermitian-symmetric (``k`` allowed exactly when
        ``-k`` is), so that conjugate pairs stay whole. Default: every
        frequency (plain CoSaMP).

    Returns
    -------
    RecoveryResult
        Time per phase: proxy, select, least_squares, prune, residual.

    Raises
    ------
    ValueError
        K out of range, y of the wrong length, NaN in y; ``allowed`` of the
        wrong shape, not Hermitian-symmetric (real signals) or empty.
    TypeError
        ``allowed`` not boolean.

    Notes
    -----
    With ``allowed`` the merged support, and so the estimate, lies inside the
    mask: CoSaMP over the union-of-subspaces model of the mask's
    frequencies (Baraniuk et al. 2010, whose model-based CoSaMP replaces the
    two top-K steps by the model's best approximation; for a fixed set of
    frequencies that is top-K within the set).

    References
    ----------
    D. Needell and J. A. Tropp, "CoSaMP: Iterative signal recovery from
    incomplete and inaccurate samples", ACHA 26(3), 2009. Thesis 2.2.1.
    R. G. Baraniuk, V. Cevher, M. F. Duarte and C. Hegde, "Model-based
    compressive sensing", IEEE Trans. Inf. Theory 56(4), 2010.
    """
    samples, tolerance, callback, clock, transforms_before, norm, support, values, residual, history = _start(
        operator, y, sparsity, tolerance, callback, ("proxy", "select", "least_squares", "prune", "residual"))
    candidates = _allowed_entries(operator, allowed)
    best = (math.inf, support, values)
    stop_reason = "max_iterations"
    quiet = 0
    iteration = 0
    for iteration in range(1, max_iterations + 1):
        with clock("proxy"):
            spectrum = operator.transform_samples(residual)
            energy = operator.proxy_energy(spectrum)
        with clock("select"):
            if candidates is None:
                selected = _largest(energy, 2 * sparsity, operator)
            else:
                selected = _largest(energy[candidates], 2 * sparsity, operator, labels=candidates)
            merged = _sorted_union(selected, support)
        with clock("least_squares"):
            merged_values, _ = _warm_least_squares(operator, merged, support, values, spectrum, samples, residual,
                                                   conjugate_gradient_steps)
        with clock("prune"):
            magnitude = (merged_values.real.astype(np.float64) ** 2 + merged_values.imag.astype(np.float64) ** 2)
            keep = np.searchsorted(merged, _largest(magnitude, sparsity, operator, labels=merged))
            support, values = merged[keep], merged_values[keep]
        with clock("residual"):
            residual = samples - operator.forward_on(support, values)
            relative = float(np.linalg.norm(residual)) / norm
            history.append(relative)
        if relative < best[0] * (1.0 - stagnation):
            quiet = 0
        else:
            quiet += 1
        if relative < best[0]:
            best = (relative, support, values)
        reason = _stop(relative, tolerance, callback, iteration, support, values)
        if reason is not None:
            stop_reason = reason
            break
        if quiet >= patience:
            stop_reason = "stagnated"
            break
    _, support, values = best
    return _result(operator, support, values, history, iteration, clock, stop_reason, transforms_before)


def omp(operator, y, sparsity, *, tolerance=1e-6, conjugate_gradient_steps=50, callback=None):
    """Orthogonal Matching Pursuit (thesis Algorithm 1): the small-problem baseline.

    One coefficient entry (a conjugate pair for real signals) joins the
    support per iteration; least squares on the support by conjugate
    gradients run to convergence. Cost grows with K: use it for small problems.

    Parameters and result as :func:`cosamp`; stops when the support holds
    ``sparsity`` coefficients (``'sparsity_reached'``) or the relative residual
    is below ``tolerance`` (``'converged'``).
    """
    samples, tolerance, callback, clock, transforms_before, norm, support, values, residual, history = _start(
        operator, y, sparsity, tolerance, callback, ("proxy", "select", "least_squares", "residual"))
    stop_reason = "sparsity_reached"
    iteration = 0
    while True:
        iteration += 1
        with clock("proxy"):
            spectrum = operator.transform_samples(residual)
            energy = operator.proxy_energy(spectrum)
            energy[support] = 0.0
        with clock("select"):
            chosen = int(np.argmax(energy))
            merged = _sorted_union(support, np.array([chosen]))
        with clock("least_squares"):
            values, residual = _warm_least_squares(operator, merged, support, values, spectrum, samples, residual,
                                                   conjugate_gradient_steps)
            support = merged
        with clock("residual"):
            residual = samples - operator.forward_on(support, values)
            relative = float(np.linalg.norm(residual)) / norm
            history.append(relative)
        reason = _stop(relative, tolerance, callback, iteration, support, values)
        if reason is not None:
            stop_reason = reason
            break
        if int(operator.coefficient_counts(support).sum()) >= sparsity or support.size >= operator.input_size:
            break
    return _result(operator, support, values, history, iteration, clock, stop_reason, transforms_before)


def _result(operator, support, values, history, iterations, clock, stop_reason, transforms_before):
    return RecoveryResult(
        estimate=operator.to_sparse_fourier(support, values),
        residual_history=tuple(history),
        iterations=iterations,
        samples=operator.output_size,
        seconds=dict(clock.seconds),
        stop_reason=stop_reason,
        transforms=operator.transforms - transforms_before,
    )
