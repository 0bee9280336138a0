"""The test signal of the integration benchmark: thesis section 4.3's random sparse 4-D Fourier signal.

Thesis section 4.3: a random sparse signal of size ``N = s^4`` with
``K = N / 10^4`` Fourier coefficients (``support = randperm(N, K)``,
``values = rand``), integrated over its last two dimensions. The signal is
drawn by the package's one generator,
:func:`~sparselt.fourier.sparse.random_sparse_fourier`, whose
:func:`~sparselt.fourier.sparse.sample_support` draws the support without
ever allocating an ``N``-sized array. This module also gives the signal the
agreement check integrates: the measured signal plus coefficients on the kept
plane, so that the check sees a non-trivial image.

References
----------
Thesis chapter 4, section 4.3 (methodology).
"""

from __future__ import annotations

import math

import numpy as np

from ..fourier.sparse import SparseFourier, random_sparse_fourier

DIMENSIONS = 4
KEEP_AXES = (0, 1)
THESIS_DENSITY = 1e-4


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


def thesis_signal(size, *, density=THESIS_DENSITY, seed=0, dimensions=DIMENSIONS):
    """The random sparse signal of thesis section 4.3.

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

    Returns
    -------
    SparseFourier
        ``K = coefficient_count(N, density)`` coefficients, support uniformly
        random without repetition, values uniform in ``[0, 1)`` (stored as
        complex128). The random stream depends on ``(seed, size)`` only, so
        every method at one size sees the same signal.
    """
    shape = (int(size),) * int(dimensions)
    total = math.prod(shape)
    rng = np.random.default_rng([int(seed), int(size)])
    return random_sparse_fourier(shape, coefficient_count(total, density), rng, values="uniform")


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
    coordinates = np.unravel_index(representation.indices, representation.shape)
    on_plane = np.ones(representation.sparsity, dtype=bool)
    for axis in range(len(representation.shape)):
        if axis not in KEEP_AXES:
            on_plane &= coordinates[axis] == 0
    return int(on_plane.sum())


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
