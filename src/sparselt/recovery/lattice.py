"""Rank-1 lattice reduction of multidimensional sparse Fourier transforms (thesis 6.1.1, eq. 6.1-6.2).

A function on ``[0, 1)^D`` whose frequencies lie in a box of shape ``s`` is
sampled at the lattice points ``x_j = (j g mod N) / N`` with
``g = (1, s_0, s_0 s_1, ...)``: the box spectrum maps bijectively onto a 1-D
spectrum of length ``N = prod(s)``, which :func:`sparselt.recovery.sft.sft`
recovers from a few samples, never forming the grid.
"""

from __future__ import annotations

import numpy as np

from ..fourier.sparse import SparseFourier, check_shape
from .sft import SparseFourierTransformResult, sft

# ---------------------------------------------------------------------------
# rank-1 lattice reduction (thesis 6.1.1, eq. 6.1-6.2)


def _lowest(shape, lowest):
    if lowest is None:
        return tuple(-(size // 2) for size in shape)
    lowest = tuple(int(value) for value in np.atleast_1d(lowest))
    if len(lowest) != len(shape):
        raise ValueError(f"lowest must give one frequency per axis ({len(shape)}), got {lowest}")
    return lowest


def lattice_generator(shape):
    """Generating vector ``g = (1, s0, s0 s1, ...)`` of the rank-1 lattice (thesis eq. 6.1)."""
    shape = check_shape(shape)
    return np.concatenate(([1], np.cumprod(shape[:-1], dtype=np.int64))).astype(np.int64)


def lattice_points(shape, indices):
    """Lattice points ``x_j = (j g mod N) / N`` in ``[0, 1)^D`` for the given ``j`` (eq. 6.1), shape ``(m, D)``."""
    shape = check_shape(shape)
    size = int(np.prod(shape, dtype=np.int64))
    indices = np.asarray(indices, dtype=np.int64)
    return ((indices[:, None] * lattice_generator(shape)[None, :]) % size) / size


def lattice_to_grid(shape, indices, lowest=None):
    """Grid spectrum index of each lattice frequency: the bijection of eq. 6.2.

    A frequency ``k`` of the box ``lowest <= k < lowest + shape`` appears on
    the lattice at ``l = sum_d k_d g_d mod N``; ``l - sum_d lowest_d g_d``
    has the mixed-radix digits ``k_d - lowest_d`` (eq. 6.2). This returns,
    for 1-D indices ``l``, the flat C-order index of ``k mod shape`` in the
    ``numpy.fft.fftn`` grid of ``shape``.

    Parameters
    ----------
    shape : sequence of int
        The grid (and frequency box) shape ``(s_0, ..., s_{D-1})``.
    indices : array_like of int
        Lattice (1-D) frequencies in ``[0, N)``.
    lowest : sequence of int, optional
        Lowest frequency of the box on each axis; default ``-(s_d // 2)``,
        the box of ``numpy.fft.fftfreq(s_d) * s_d``.
    """
    shape = check_shape(shape)
    lowest = _lowest(shape, lowest)
    size = int(np.prod(shape, dtype=np.int64))
    generator = lattice_generator(shape)
    base = int(np.dot(np.asarray(lowest, dtype=np.int64), generator)) % size
    digits = (np.asarray(indices, dtype=np.int64) - base) % size
    coordinates = []
    for axis, extent in enumerate(shape):
        coordinates.append((digits // generator[axis] % extent + lowest[axis]) % extent)
    return np.ravel_multi_index(tuple(coordinates), shape).astype(np.int64)


def grid_to_lattice(shape, indices, lowest=None):
    """Inverse of :func:`lattice_to_grid`: lattice frequency of each flat grid spectrum index."""
    shape = check_shape(shape)
    lowest = _lowest(shape, lowest)
    size = int(np.prod(shape, dtype=np.int64))
    generator = lattice_generator(shape)
    coordinates = np.unravel_index(np.asarray(indices, dtype=np.int64), shape)
    total = np.zeros(np.shape(indices), dtype=np.int64)
    for axis, extent in enumerate(shape):
        frequency = (coordinates[axis] - lowest[axis]) % extent + lowest[axis]  # k in the box
        total = total + frequency * generator[axis]
    return total % size


def sft_lattice(function, shape, sparsity, *, lowest=None, **options):
    """Sparse Fourier Transform of a function on ``[0, 1)^D`` by rank-1 lattice reduction (thesis 6.1.1).

    Parameters
    ----------
    function : callable
        ``function(points) -> values`` for an ``(m, D)`` array of points in
        ``[0, 1)^D``; one finite real or complex value per point.
    shape : sequence of int
        The frequency box (and grid) ``(s_0, ..., s_{D-1})``; ``N = prod(shape)``
        must be below ``2**31``.
    sparsity : int
        ``K``, coefficients to recover, ``0 < K <= N / 2``.
    lowest : sequence of int, optional
        Lowest frequency of the box per axis, default ``-(s_d // 2)`` (the
        frequencies of ``numpy.fft.fftn`` on the grid); use zeros for
        ``0 <= k < shape``.
    **options
        Passed to :func:`sft` (``alpha``, ``snr``, ``seed``, ...).

    Returns
    -------
    SparseFourierTransformResult
        As :func:`sft`, with ``.estimate`` a SparseFourier of shape ``shape``:
        ``estimate.to_signal()`` is the function on the grid ``m / shape``.

    Raises
    ------
    ValueError
        A shape with a zero or negative size, and every error of :func:`sft`.

    Notes
    -----
    The samples ``y[j] = f(x_j)``, ``x_j = (j g mod N) / N``,
    ``g = (1, s_0, s_0 s_1, ...)`` (eq. 6.1), make each term
    ``c_k exp(2 pi i k.x)`` of a trigonometric polynomial the 1-D frequency
    ``l = k.g mod N``: distinct for distinct ``k`` in the box (mixed radix,
    eq. 6.2). The length-``N`` DFT of ``y`` has ``N c_k`` at ``l``, which is
    also the ``numpy.fft.fftn`` coefficient of ``f`` on the grid at
    ``k mod shape``. Only the lattice points the 1-D transform asks for are
    evaluated.

    References
    ----------
    Thesis 6.1.1, eq. 6.1-6.2; L. Kämmerer, D. Potts, T. Volkmer,
    "High-dimensional sparse FFT based on sampling along multiple rank-1
    lattices", Appl. Comput. Harmon. Anal. 2021.
    """
    shape = check_shape(shape)
    lowest = _lowest(shape, lowest)
    size = int(np.prod(shape, dtype=np.int64))
    if not callable(function):
        raise ValueError(f"function must be callable as function(points) -> values, got {type(function).__name__}")

    def oracle(indices):
        values = np.asarray(function(lattice_points(shape, indices)))
        if values.shape not in ((indices.size,), (indices.size, 1)):
            raise ValueError(f"the function must return one value per point: {indices.size} points, "
                             f"got an array of shape {values.shape}")
        return values.reshape(indices.size)

    result = sft(oracle, size, sparsity, **options)
    line = result.estimate
    grid = SparseFourier(shape, lattice_to_grid(shape, line.indices, lowest), line.values)
    parameters = dict(result.parameters, shape=shape, lowest=lowest)
    return SparseFourierTransformResult(
        estimate=grid, residual_history=result.residual_history, iterations=result.iterations,
        samples=result.samples, seconds=result.seconds, stop_reason=result.stop_reason, transforms=result.transforms,
        support_samples=result.support_samples, magnitude_samples=result.magnitude_samples, bins=result.bins,
        parameters=parameters)
