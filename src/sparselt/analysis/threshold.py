"""Hard thresholding in the Fourier basis and gamma mapping (thesis 5.2, 5.4.2, 7.1.1).

Hard thresholding keeps a fraction of the largest-energy Fourier coefficients
of a signal and integrates the result to an image: the best case of any
K-sparse reconstruction (thesis 5.4.2). Gamma mapping (eq. 7.1) compresses the
dynamic range before the transform; then the sparse representation is of the
*mapped* signal, so the whole signal must be reconstructed, un-mapped and only
then integrated (7.1.1), instead of the cheap convolution integration.
"""

from __future__ import annotations

import math

import numpy as np

from ..fourier import fft
from ..fourier.integration import integrate, mean_over_axes
from ..fourier.hermitian import largest_closed
from ..fourier.sparse import SparseFourier


def check_gamma(gamma):
    """Validate a gamma of eq. 7.1: a positive finite number."""
    if isinstance(gamma, bool) or not isinstance(gamma, (int, float, np.floating)) or not (gamma > 0 and math.isfinite(gamma)):
        raise ValueError(f"gamma must be a positive finite number (eq. 7.1 uses 0 < gamma <= 1), got {gamma!r}")
    return float(gamma)


def check_fraction(fraction):
    """Validate a fraction of coefficients: a number in (0, 1]."""
    if isinstance(fraction, bool) or not isinstance(fraction, (int, float, np.floating)) or not (0 < fraction <= 1):
        raise ValueError(f"fraction of coefficients must be in (0, 1], got {fraction!r}")
    return float(fraction)


def gamma_map(signal, gamma, *, maximum=None):
    """Gamma tone mapping, eq. 7.1: ``T = (I / max(I)) ** gamma``.

    Parameters
    ----------
    signal : ndarray
        Non-negative linear values (all channels share one maximum, so
        colours are preserved up to the curve).
    gamma : float
        Exponent, > 0 (the thesis uses 0 < gamma <= 1).
    maximum : float, optional
        ``max(I)``; computed from ``signal`` when omitted. Keep it to invert.

    Returns
    -------
    ndarray
        Values in ``[0, 1]``, float64 unless the input is float32.

    Raises
    ------
    ValueError
        gamma <= 0, negative or non-finite values.
    """
    gamma = check_gamma(gamma)
    signal = np.asarray(signal)
    if not np.all(np.isfinite(signal)) or signal.size and signal.min() < 0:
        raise ValueError("gamma mapping needs finite non-negative values")
    maximum = float(signal.max(initial=0.0)) if maximum is None else float(maximum)
    if maximum <= 0:
        return np.zeros_like(signal, dtype=np.result_type(signal.dtype, np.float32))
    return (signal / maximum) ** gamma


def inverse_gamma_map(mapped, gamma, maximum):
    """Inverse of :func:`gamma_map`: ``I = max(I) * T ** (1 / gamma)``.

    Values below zero (a thresholded reconstruction can undershoot) are
    clipped to zero first, since ``T ** (1 / gamma)`` is undefined there.
    """
    gamma = check_gamma(gamma)
    return float(maximum) * np.clip(mapped, 0.0, None) ** (1.0 / gamma)


def largest_coefficients(spectrum, count):
    """Flat indices of the ``count`` largest-energy entries of a real signal's full spectrum.

    The top-K rule of :mod:`sparselt.fourier.hermitian`: Hermitian partners
    are kept together and the result has ``count`` or ``count - 1`` entries.
    O(N) by partial sorting.
    """
    spectrum = np.asarray(spectrum)
    return largest_closed(np.abs(spectrum.ravel()) ** 2, count, spectrum.shape)


def hard_threshold_image(data, fraction, *, gamma=1.0, keep_axes=(0, 1)):
    """Image of a signal after keeping a fraction of its Fourier coefficients per channel.

    Parameters
    ----------
    data : ndarray, shape ``grid + (channels,)``
        Signal cells (e.g. ``Signal.data``), non-negative.
    fraction : float
        Fraction in (0, 1] of the coefficients kept in each channel
        (``ceil(fraction * N)``, rounded up to keep Hermitian pairs).
    gamma : float, optional
        Gamma mapping before the transform (1 means none).
    keep_axes : sequence of int, optional
        Axes of the image (default ``(0, 1)``, the image plane).

    Returns
    -------
    ndarray, shape ``[grid[a] for a in keep_axes] + (channels,)``
        Mean over the other axes, in the signal's axis order (for ``Signal``
        data transpose ``(1, 0, 2)`` to get ``(height, width, 3)``).

    Notes
    -----
    Without gamma mapping the image is computed by convolution integration
    (thesis 4.2) straight from the sparse representation. With gamma mapping
    the mapped signal is reconstructed in full, un-mapped (negative values
    clipped to 0) and averaged (thesis 7.1.1).
    """
    fraction = check_fraction(fraction)
    gamma = check_gamma(gamma)
    data = np.asarray(data)
    grid = data.shape[:-1]
    axes = tuple(range(len(grid)))
    size = math.prod(grid)
    count = max(1, math.ceil(fraction * size))
    maximum = float(data.max(initial=0.0))
    channels = []
    for channel in range(data.shape[-1]):
        values = data[..., channel]
        mapped = gamma_map(values, gamma, maximum=maximum) if gamma != 1.0 else values
        spectrum = fft.fftn(np.asarray(mapped, dtype=np.float32 if values.dtype == np.float32 else np.float64), axes=axes)
        kept = largest_coefficients(spectrum, count)
        representation = SparseFourier(grid, kept, spectrum.ravel()[kept], real=True, tolerance=1e-3)
        if gamma == 1.0:
            channels.append(integrate(representation, keep_axes, "convolution"))
        else:
            reconstruction = inverse_gamma_map(representation.to_signal(), gamma, maximum)
            channels.append(mean_over_axes(reconstruction, keep_axes))
    return np.stack(channels, axis=-1)
