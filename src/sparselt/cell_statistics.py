"""Per-cell statistics of samples: cell means (thesis 8.1.1) and the sample variance from running sums.

Two computations every estimator needs, each in one place:

* :func:`cell_means`: the measurement of each grid cell that received
  samples, the mean of their values (thesis 8.1.1: CoSaMP's measurements;
  the pixel mean of path tracing is the same with a pixel as the cell).
  :func:`sparselt.methods.pixel_samples.cell_means` (luminance of a
  :class:`~sparselt.methods.pixel_samples.PixelSamples`, blocked on every core
  when the grid allows), the wedge's per-tile measurements and
  :func:`sparselt.operators.mean_per_cell` call it.
* :func:`variance_from_sums`: the unbiased per-sample variance from a count,
  a sum and a sum of squares (per pixel, per cell, per pass), for the
  reference's noise floor, the filters' noise level, the axis-aligned
  allocation and the guided methods' defensive weights.

Both are NumPy expressions whose floating-point operations are fixed: the
results are the same bits whichever caller asks.
"""

from __future__ import annotations

import numpy as np

#: The floating-point forms of :func:`variance_from_sums` (algebraically equal; see its Notes).
VARIANCE_FORMS = ("mean", "total", "moment")


def cell_means(cells, weights, size=None):
    """Mean of the weights of the samples in each cell that received any (``numpy.bincount`` sums).

    Parameters
    ----------
    cells : ndarray of int, shape (samples,)
        Each sample's flat cell index (non-negative; below ``size`` when given).
    weights : ndarray, shape (samples,)
        Each sample's value, real or complex (summed in float64 / complex128).
    size : int, optional
        The grid's number of cells: counts and sums over the whole grid, the
        fastest for dense samples. Default: over the distinct cells only (one
        sort), for sparse cells of a large grid.

    Returns
    -------
    cells : ndarray of int64, sorted
        Cells that received at least one sample.
    means : ndarray of float64 (complex128 for complex weights)
        The mean of each such cell's weights: the sum in sample order
        (``numpy.bincount``) over the count.
    counts : ndarray of int64
        Samples in each.

    Notes
    -----
    Sums run in increasing sample order whichever ``size``, so every
    implementation that sums a cell's samples in that order (the blocked
    kernel :func:`sparselt.kernels.pixel_block_cell_sums`, a per-tile
    regrouping, ``numpy.add.at``) gives the same bits.

    References
    ----------
    Thesis 8.1.1: a cell that receives samples is measured by their mean.
    """
    weights = np.asarray(weights)
    if size is None:
        measured, index, counts = np.unique(cells, return_inverse=True, return_counts=True)
        bins = measured.size
    else:
        index, bins = cells, size
        all_counts = np.bincount(cells, minlength=size)
        measured = np.flatnonzero(all_counts)
        counts = all_counts[measured]

    def sums_of(values):
        if np.iscomplexobj(values):
            sums = np.empty(measured.size, dtype=np.complex128)
            sums.real, sums.imag = sums_of(values.real), sums_of(values.imag)
            return sums
        sums = np.bincount(index, weights=values, minlength=bins)
        return sums if size is None else sums[measured]

    return measured, sums_of(weights) / counts, counts


def variance_from_sums(total, squares, count, *, form="mean", ddof=1, denominator=None):
    """The sample variance from a count, a sum and a sum of squares, elementwise.

    Parameters
    ----------
    total, squares : ndarray or float
        ``sum x`` and ``sum x^2`` (float64), per element (pixel, cell, channel).
    count : ndarray or float
        ``n``, the number of samples (or the total weight) of each element; broadcasts against ``total``.
    form : {'mean', 'total', 'moment'}
        Which floating-point expression (Notes); each caller keeps the one its
        numbers were produced with, bit for bit.
    ddof : int, optional
        Delta degrees of freedom: the centred sum is divided by ``n - ddof``
        (default 1: unbiased).
    denominator : ndarray or float, optional
        Divide the centred sum by this instead of ``n - ddof`` (forms 'mean'
        and 'total'): ``passes - 1`` for the reference's passes of ``n_i``
        samples each, whose centred sum weights each pass mean by ``n_i``.

    Returns
    -------
    ndarray or float
        The variance, clamped at 0 below (rounding can make the centred sum
        slightly negative).

    Raises
    ------
    ValueError
        An unknown ``form``, or ``denominator`` with form 'moment'.

    Notes
    -----
    With ``m = total / n``, the three forms are algebraically equal:

    ``'mean'``
        ``max(squares - n m m, 0) / (n - ddof)`` (the reference's passes, the
        guided methods' defensive weights);
    ``'total'``
        ``max(squares - total total / n, 0) / (n - ddof)`` (the filters' noise
        level);
    ``'moment'``
        ``max(squares / n - m m, 0) n / (n - ddof)`` (the axis-aligned
        filters' per-pixel variance).

    They round differently (in the last bits), so each caller names its own
    and its results stay what they were.
    """
    if form not in VARIANCE_FORMS:
        raise ValueError(f"form must be one of {', '.join(VARIANCE_FORMS)}, got {form!r}")
    if form == "moment":
        if denominator is not None:
            raise ValueError("denominator applies to the forms 'mean' and 'total', not 'moment'")
        mean = total / count
        return np.maximum(squares / count - mean * mean, 0.0) * count / (count - ddof)
    if form == "mean":
        mean = total / count
        centred = np.maximum(squares - count * mean * mean, 0.0)
    else:
        centred = np.maximum(squares - total * total / count, 0.0)
    return centred / (count - ddof if denominator is None else denominator)


__all__ = ["VARIANCE_FORMS", "cell_means", "variance_from_sums"]
