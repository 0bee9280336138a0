"""The test signal of the integration benchmark: thesis section 4.3's random sparse 4-D Fourier signal.

Thesis section 4.3: a random sparse signal of size ``N = s^4`` with
``K = N / 10^4`` Fourier coefficients (``support = randperm(N, K)``,
``values = rand``), integrated over its last two dimensions. The signal is
drawn by the package's one generator,
:func:`~sparselt.fourier.sparse.random_sparse_fourier`, whose
:func:`~sparselt.fourier.sparse.sample_support` draws the support without
ever allocating an ``N``-sized array.

Deviation from the thesis's uniform draw
----------------------------------------
Only a coefficient whose integrated coordinates are all zero reaches the
image (thesis eq. 4.12; :func:`contributing_coefficients`). The integration
plane holds ``P = s^2`` of the ``N = s^4`` frequencies, so a uniform draw puts
``K P / N = 10^-4 s^2`` coefficients there on average: 0.1 at ``s = 32``,
1.6 at ``s = 128``. Drawn uniformly, nearly every signal of the thesis's
range integrates to an all-zero image, and the methods are timed computing
zeros. :func:`thesis_signal` therefore raises the number on the plane to
``min(minimum_reaching, K, P)`` (``MINIMUM_REACHING`` by default) when the
uniform draw has fewer: it moves that many off-plane coefficients, chosen
uniformly, to plane frequencies not yet in the support, chosen uniformly,
keeping their values. ``N``, ``K`` and ``P``, which set every method's cost
(Table 4.1), are unchanged, and so is the signal whenever the uniform draw
already has enough on the plane; ``minimum_reaching=0`` gives the uniform
draw itself.

This module also gives the signal the agreement check integrates: the
measured signal plus coefficients on the kept plane with complex values.

References
----------
Thesis chapter 4, sections 4.2 (eq. 4.12) and 4.3 (methodology).
"""

from __future__ import annotations

import math

import numpy as np

from ..checks import check_integer
from ..fourier.sparse import SparseFourier, random_sparse_fourier

DIMENSIONS = 4
KEEP_AXES = (0, 1)
THESIS_DENSITY = 1e-4
#: Coefficients moved onto the integration plane where the uniform draw has fewer (at most K and P); see the notes.
MINIMUM_REACHING = 4


def coefficient_count(signal_size, density=THESIS_DENSITY):
    """The number of coefficients ``K`` of a signal of ``N`` values.

    Parameters
    ----------
    signal_size : int
        ``N``, the number of values of the signal.
    density : float, optional
        ``K / N``; the thesis's ``10^-4`` by default.

    Returns
    -------
    int
        ``floor(N * density)``, at least 1 (the thesis: ``K = N / 10^4``).
    """
    return max(1, int(signal_size * density))


def thesis_signal(size, *, density=THESIS_DENSITY, seed=0, dimensions=DIMENSIONS, minimum_reaching=MINIMUM_REACHING):
    """The random sparse signal of thesis section 4.3, with at least a few coefficients reaching the image.

    Parameters
    ----------
    size : int
        ``s``, the length of every axis.
    density : float, optional
        ``K / N``; the thesis's ``10^-4`` by default.
    seed : int, optional
        Seed of the random stream.
    dimensions : int, optional
        Number of axes; ``N = size^dimensions``.
    minimum_reaching : int, optional
        At least ``min(minimum_reaching, K, P)`` coefficients lie on the
        integration plane of ``P = s^2`` frequencies (integrated coordinates
        zero), so that they reach the image; 0 keeps the thesis's uniform
        draw as it is.

    Returns
    -------
    SparseFourier
        ``K = coefficient_count(N, density)`` coefficients, support uniformly
        random without repetition, then raised onto the plane as the module
        notes describe; values uniform in ``[0, 1)`` (stored as complex128).
        The random stream depends on ``(seed, size)`` only, so every method
        at one size sees the same signal.

    Raises
    ------
    TypeError
        ``minimum_reaching`` not an integer.
    ValueError
        ``minimum_reaching`` negative.

    Notes
    -----
    The uniform draw is made first and is the same for every
    ``minimum_reaching``; the extra draws (which coefficients move, and
    where) follow it in the same stream. The result is uniform given its
    number of on-plane coefficients: its on-plane coefficients are a uniform
    subset of the plane, its others a uniform subset of the rest.
    """
    minimum_reaching = check_integer("minimum_reaching", minimum_reaching, 0)
    shape = (int(size),) * int(dimensions)
    total = math.prod(shape)
    rng = np.random.default_rng([int(seed), int(size)])
    representation = random_sparse_fourier(shape, coefficient_count(total, density), rng, values="uniform")
    plane = math.prod(shape[axis] for axis in KEEP_AXES)
    return _raise_reaching(representation, min(minimum_reaching, representation.sparsity, plane), rng)


def _integrated_axes(shape):
    return tuple(axis for axis in range(len(shape)) if axis not in KEEP_AXES)


def _on_plane(representation):
    """Whether each coefficient has all its integrated coordinates zero."""
    coordinates = np.unravel_index(representation.indices, representation.shape)
    on_plane = np.ones(representation.sparsity, dtype=bool)
    for axis in _integrated_axes(representation.shape):
        on_plane &= coordinates[axis] == 0
    return on_plane, coordinates


def _raise_reaching(representation, target, rng):
    """Move uniformly chosen off-plane coefficients to free plane frequencies until ``target`` lie on the plane."""
    on_plane, coordinates = _on_plane(representation)
    missing = target - int(on_plane.sum())
    if missing <= 0:
        return representation
    shape = representation.shape
    plane_shape = tuple(shape[axis] for axis in KEEP_AXES)
    occupied = np.ravel_multi_index(tuple(coordinates[axis][on_plane] for axis in KEEP_AXES), plane_shape)
    free = np.setdiff1d(np.arange(math.prod(plane_shape), dtype=np.int64), occupied)
    targets = np.unravel_index(rng.choice(free, size=missing, replace=False), plane_shape)
    moved = rng.choice(np.flatnonzero(~on_plane), size=missing, replace=False)
    new_coordinates = [np.zeros(missing, dtype=np.int64) for _ in shape]
    for axis, target_coordinate in zip(KEEP_AXES, targets):
        new_coordinates[axis] = target_coordinate
    indices = representation.indices.copy()
    indices[moved] = np.ravel_multi_index(tuple(new_coordinates), shape)
    return SparseFourier(shape, indices, representation.values)


def contributing_coefficients(representation):
    """The number of coefficients that reach the integrated image.

    Parameters
    ----------
    representation : SparseFourier
        A signal integrated over every axis not in ``KEEP_AXES``.

    Returns
    -------
    int
        Coefficients whose integrated coordinates are all zero (the only ones
        that reach the image).
    """
    return int(_on_plane(representation)[0].sum())


def agreement_signal(representation, seed):
    """The measured signal plus coefficients on the kept plane, with complex values.

    At ``K = N / 10^4`` almost no coefficient of the thesis signal has zero
    integrated coordinates, so every method returns (nearly) zeros; adding
    on-plane coefficients makes the agreement check see a non-trivial image.

    Parameters
    ----------
    representation : SparseFourier
        The measured signal.
    seed : int
        Seed of the benchmark; the random stream depends on ``(seed, s)``.

    Returns
    -------
    SparseFourier
        The union of both supports, with new values ``u + 1j v``, ``u`` and
        ``v`` uniform in ``[0, 1)``.
    """
    shape = representation.shape
    rng = np.random.default_rng([int(seed), shape[0], 1])
    plane = shape[KEEP_AXES[0]] * shape[KEEP_AXES[1]]
    count = min(plane, max(8, representation.sparsity))
    kept = np.unravel_index(rng.choice(plane, size=count, replace=False), (shape[KEEP_AXES[0]], shape[KEEP_AXES[1]]))
    coordinates = [np.zeros(count, dtype=np.int64) for _ in shape]
    coordinates[KEEP_AXES[0]], coordinates[KEEP_AXES[1]] = kept
    support = np.union1d(representation.indices, np.ravel_multi_index(tuple(coordinates), shape))
    values = rng.random(support.size) + 1j * rng.random(support.size)
    return SparseFourier(shape, support, values)
