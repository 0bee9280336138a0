"""Integrating sparse Fourier representations into images (thesis chapter 4).

:func:`integrate` returns the mean of a signal over its integrated axes (the
pixel values when the kept axes are the image plane) straight from a
:class:`~sparselt.fourier.sparse.SparseFourier`, by one of four methods that
all give the same numbers and differ in cost (Table 4.1; ``N`` signal size,
``K`` coefficients, ``P`` output points):

=================  =========================================  ============  ==========
method             what it does                               time          memory
=================  =========================================  ============  ==========
``sum``            reconstruct the signal, average             O(N log N)    O(N)
``time``           Fourier time integration per coefficient    O(K P)        O(K + P)
                   and output point, no FFT (4.1, eq. 4.3-4.7)
``time-fft``       time integration applied to the spectrum,   O(N log N)    O(N)
                   then a full inverse FFT (eq. 4.8)
``convolution``    keep the coefficients whose integrated      O(K + P       O(K + P)
                   coordinates are zero, inverse FFT over       log P)
                   the kept axes only (4.2, eq. 4.12)
=================  =========================================  ============  ==========

Notes
-----
With ``f(n) = 1/N sum_k c_k exp(2 pi i <k, n/s>)``, the mean over an
integrated axis of length ``s`` of ``exp(2 pi i k n / s)`` is the integral of
the basis function over one period divided by its length,
``(exp(2 pi i k) - 1) / (2 pi i k) = 0`` for ``k != 0`` and 1 for ``k = 0``
(eq. 4.5-4.7 with ``t0 = 0``, ``t1 = s``): only coefficients with zero
integrated coordinates contribute, which is the convolution theorem's
box-car filter (eq. 4.10-4.12).
"""

from __future__ import annotations

import numpy as np

from ..checks import check_integer
from . import fft
from .sparse import SparseFourier

METHODS = ("sum", "time", "time-fft", "convolution")


def _split_axes(dimensions, keep_axes):
    try:
        axes = tuple(keep_axes)
    except TypeError:
        raise ValueError(f"keep_axes must be a sequence of axis numbers, got {keep_axes!r}") from None
    if any(isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) for axis in axes):
        raise ValueError(f"keep_axes must hold integer axis numbers, got {keep_axes!r}")
    keep = tuple(int(axis) for axis in axes)
    if any(not -dimensions <= axis < dimensions for axis in keep):
        raise ValueError(f"keep_axes {keep} out of range for a {dimensions}-D signal (axes 0..{dimensions - 1})")
    keep = tuple(axis % dimensions for axis in keep)
    if len(set(keep)) != len(keep):
        raise ValueError(f"keep_axes {keep_axes} repeats an axis")
    integrated = tuple(axis for axis in range(dimensions) if axis not in keep)
    return keep, integrated


def period_mean_weights(size):
    """Mean over one period of each basis function ``exp(2 pi i k n / size)``, ``k = 0 .. size-1``.

    Evaluated from the antiderivative (eq. 4.6-4.7): ``(e^{i w s} - 1) / (i w s)``
    with ``w = 2 pi k / s``; 1 at ``k = 0`` and zero up to rounding elsewhere.
    """
    frequency = np.arange(size)
    angle = 2.0 * np.pi * frequency
    with np.errstate(divide="ignore", invalid="ignore"):
        weights = (np.exp(1j * angle) - 1.0) / (1j * angle)
    weights[0] = 1.0
    return weights


def integrate(representation, keep_axes=(0, 1), method="convolution", *, chunk=None):
    """Mean of a sparse Fourier signal over every axis not in ``keep_axes``.

    Parameters
    ----------
    representation : SparseFourier
        The signal (any dimension; values may have channel axes).
    keep_axes : sequence of int, optional
        Axes that remain (default the image plane ``(0, 1)``), in output order.
    method : {'sum', 'time', 'time-fft', 'convolution'}, optional
        See the module docstring; all agree to rounding.
    chunk : int, optional
        Coefficients per block (at least 1) in the ``time`` method; by default enough for
        about 2^20 basis values per block, so its memory is O(K + P) plus a
        constant, as Table 4.1 says.

    Returns
    -------
    ndarray
        Shape ``[shape[a] for a in keep_axes] + channels``; real if the
        representation is ``real``.

    Raises
    ------
    TypeError
        ``representation`` is not a SparseFourier, or ``chunk`` not an integer.
    ValueError
        Unknown method, ``keep_axes`` out of range or repeated, or ``chunk`` below 1.

    References
    ----------
    Thesis chapter 4; Sen and Darabi (2011) for the time integration.
    """
    if not isinstance(representation, SparseFourier):
        raise TypeError(f"integrate needs a SparseFourier, got {type(representation).__name__}")
    if method not in METHODS:
        raise ValueError(f"unknown integration method {method!r}; choose one of {', '.join(METHODS)}")
    if chunk is not None:
        chunk = check_integer("chunk", chunk, 1)
    keep, integrated = _split_axes(len(representation.shape), keep_axes)
    function = {"sum": _sum, "time": _time, "time-fft": _time_fft, "convolution": _convolution}[method]
    result = function(representation, keep, integrated, chunk) if method == "time" else function(representation, keep, integrated)
    return np.array(result.real) if representation.real else np.asarray(result)


def mean_over_axes(signal, keep_axes=(0, 1), *, dimensions=None):
    """Mean of a dense grid signal over every axis not in ``keep_axes`` (the direct sum, eq. 4.1).

    The result's axes are ``keep_axes`` in that order, then any trailing
    channel axes beyond the first ``dimensions`` (default: all axes are grid axes).
    """
    signal = np.asarray(signal)
    keep, integrated = _split_axes(signal.ndim if dimensions is None else dimensions, keep_axes)
    return _in_keep_order(signal.mean(axis=integrated) if integrated else signal, keep)


def _sum(representation, keep, integrated):
    return mean_over_axes(representation.to_signal(), keep, dimensions=len(representation.shape))


def _in_keep_order(array, keep):
    """Reorder the leading axes of ``array`` (kept axes in increasing order) to ``keep`` order."""
    ranks = list(np.argsort(np.argsort(keep)))
    return np.transpose(array, ranks + list(range(len(keep), array.ndim)))


def _kept_exponentials(representation, keep, coordinates):
    """Per kept axis, ``exp(2 pi i k n / s)`` for the coefficients' k and every n: (K, s) each."""
    return [np.exp(2j * np.pi * np.outer(coordinates[:, axis], np.arange(representation.shape[axis])) / representation.shape[axis])
            for axis in keep]


def _time(representation, keep, integrated, chunk):
    shape = representation.shape
    output_shape = tuple(shape[axis] for axis in keep)
    channels = representation.channel_shape
    values = representation.values.reshape(representation.sparsity, -1)
    points = int(np.prod(output_shape, dtype=np.int64))
    chunk = chunk or max(1, (1 << 20) // max(1, points))
    result = np.zeros((points, values.shape[1]), dtype=np.complex128)
    weights = {axis: period_mean_weights(shape[axis]) for axis in integrated}
    for start in range(0, representation.sparsity, chunk):
        coordinates = np.stack(np.unravel_index(representation.indices[start:start + chunk], shape), axis=1)
        coefficient = values[start:start + chunk] / representation.size
        for axis in integrated:
            coefficient = coefficient * weights[axis][coordinates[:, axis]][:, None]
        # Evaluate every coefficient's kept basis function at every output point: O(K P).
        basis = np.ones((coordinates.shape[0], 1), dtype=np.complex128)
        for exponential in _kept_exponentials(representation, keep, coordinates):
            basis = (basis[:, :, None] * exponential[:, None, :]).reshape(coordinates.shape[0], -1)
        result += basis.T @ coefficient
    return result.reshape(output_shape + channels)


def _time_fft(representation, keep, integrated):
    shape = representation.shape
    spectrum = representation.to_spectrum(np.complex128)
    for axis in integrated:
        view = [1] * spectrum.ndim
        view[axis] = shape[axis]
        spectrum *= period_mean_weights(shape[axis]).reshape(view)
    signal = fft.ifftn(spectrum, axes=tuple(range(len(shape))))
    index = tuple(0 if axis in integrated else slice(None) for axis in range(len(shape)))
    return _in_keep_order(signal[index], keep)


def _convolution(representation, keep, integrated):
    shape = representation.shape
    coordinates = np.unravel_index(representation.indices, shape)
    on_axis = np.ones(representation.sparsity, dtype=bool)
    for axis in integrated:
        on_axis &= coordinates[axis] == 0
    output_shape = tuple(shape[axis] for axis in keep)
    channels = representation.channel_shape
    kept = np.zeros(output_shape + channels, dtype=np.complex128)
    if keep:
        target = tuple(coordinates[axis][on_axis] for axis in keep)
        kept[target] = representation.values[on_axis]
        points = int(np.prod(output_shape, dtype=np.int64))
        return fft.ifftn(kept, axes=tuple(range(len(keep)))) * (points / representation.size)
    return representation.values[on_axis].sum(axis=0) / representation.size
