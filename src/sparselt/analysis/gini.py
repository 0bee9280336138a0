"""The Gini index of a vector (thesis eq. 5.1): exact, and streamed in bounded memory with an error bound.

One idea: the sparsity measure of thesis section 5.1 applied to a vector of
magnitudes, whatever its size.

* :func:`gini_index` -- the exact Gini index of an array of magnitudes (a sort
  and a float64 rank-weighted sum).
* :func:`gini_index_streaming` / :class:`GiniHistogram` -- one pass over chunks
  of any total size in a fixed amount of memory, returning a
  :class:`GiniEstimate`: an estimate with a rigorous error bound.

:func:`sparselt.analysis.sparsity.signal_gini` applies them to the colour
channels of a signal (thesis 5.4.1, tables 5.1 and 5.2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .out_of_core import _piece_indices

__all__ = [
    "GiniEstimate",
    "GiniHistogram",
    "gini_index",
    "gini_index_streaming",
]

DEFAULT_BUCKETS = 2**23

_ABS_HINT = "pass np.abs(x) for the magnitudes of signed or complex coefficients"
_UNIT_ROUNDOFF = 2.0**-53
_LARGEST_FINITE_FLOAT32_BITS = 0x7F7FFFFF
_EXACT_BLOCK = 2**20  # values per float64 accumulation block of the exact sum
_DEFAULT_PIECE = 2**22  # values per histogram update
_HISTOGRAM_BYTES_PER_BUCKET = 48  # count, sum, sum of squares, min, max + one bincount output
_PIECE_BYTES_PER_VALUE = 64  # temporaries of one histogram update, per value


# --------------------------------------------------------------------------- exact


def _check_flag(value, name):
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def _real_values(values, name):
    """``values`` as a float32/float64 array; complex and non-numeric dtypes are refused."""
    array = np.asarray(values)
    if np.iscomplexobj(array):
        raise ValueError(f"{name} must be real non-negative magnitudes, got complex dtype {array.dtype}; {_ABS_HINT}")
    if array.dtype.kind in "biu":
        return array.astype(np.float64)
    if array.dtype.kind != "f":
        raise TypeError(f"{name} must be a numeric array, got dtype {array.dtype}")
    if array.dtype not in (np.float32, np.float64):
        return array.astype(np.float64)
    return array


def _check_sorted(sorted_values, name):
    """Validate ascending values with two look-ups: NaN sorts last, -inf and negatives first."""
    largest, smallest = sorted_values[-1], sorted_values[0]
    if np.isnan(largest):
        raise ValueError(f"{name} contain NaN; the Gini index needs finite non-negative magnitudes ({_ABS_HINT})")
    if smallest < 0:
        raise ValueError(
            f"{name} contain negative values (smallest {float(smallest)!r}); the Gini index needs non-negative "
            f"magnitudes: {_ABS_HINT}"
        )
    if np.isinf(largest):
        raise ValueError(f"{name} contain inf; the Gini index needs finite non-negative magnitudes ({_ABS_HINT})")


def _gini_from_sorted(sorted_values, *, energy):
    """Eq. 5.1 on validated ascending 1-D values, accumulated in float64 blocks."""
    count = sorted_values.size
    largest = float(sorted_values[-1])
    if largest == float(sorted_values[0]):
        return 0.0  # constant, including all zeros
    weighted_sums, totals = [], []
    for start in range(0, count, _EXACT_BLOCK):
        # Dividing by the largest value (scale invariance) keeps squares and sums finite.
        block = sorted_values[start:start + _EXACT_BLOCK].astype(np.float64) / largest
        if energy:
            np.multiply(block, block, out=block)
        ranks = np.arange(start + 1, start + block.size + 1, dtype=np.float64)
        rank_weights = (count - ranks + 0.5) / count
        weighted_sums.append(float(np.dot(block, rank_weights)))
        totals.append(float(block.sum()))
    return 1.0 - 2.0 * math.fsum(weighted_sums) / math.fsum(totals)  # the largest value is 1: no 0/0


def gini_index(magnitudes, *, energy=False):
    """Gini index of non-negative magnitudes (thesis eq. 5.1).

    Parameters
    ----------
    magnitudes : array_like of real, non-negative values
        The coefficients' magnitudes, any shape (flattened). Integer and boolean
        arrays are converted to float64; float32 stays float32 while sorting.
    energy : bool, optional
        Compute the index of the energies ``magnitudes**2`` instead (keyword only).

    Returns
    -------
    float
        ``G`` in ``[0, 1 - 1/N]``: 0 for a constant vector (all zeros
        included), ``1 - 1/N`` for a vector with a single non-zero entry.

    Raises
    ------
    ValueError
        ``magnitudes`` is empty, complex, or holds negative values, NaN or inf.
        Pass ``np.abs(x)`` for the magnitudes of signed or complex coefficients.
    TypeError
        ``magnitudes`` is not numeric, or ``energy`` is not a bool.

    See Also
    --------
    gini_index_streaming : the same index in bounded memory, with an error bound.

    Notes
    -----
    With the ``N`` values sorted ascending, :math:`c_{(1)} \\le \\dots \\le c_{(N)}`,

    .. math::

        G(c) = 1 - 2 \\sum_{i=1}^{N} \\frac{c_{(i)}}{\\|c\\|_1}
               \\left(\\frac{N - i + \\tfrac12}{N}\\right)          \\qquad (5.1)

    which equals the normalised mean absolute difference
    :math:`\\sum_{i,j} |c_i - c_j| / (2 N \\|c\\|_1)`. The energy variant applies
    (5.1) to :math:`c^2` (the ordering is the same). The computation is exact up
    to rounding: one sort (O(N log N), a copy of the input) and a float64
    rank-weighted sum in blocks of 2**20 values, after dividing by the largest
    value (by scale invariance), so squares neither overflow nor underflow.

    ``0/0`` is avoided by definition: a constant vector, all zeros included, has
    ``G = 0`` (the most egalitarian distribution; the limit of eq. 5.1 as the
    values approach a common constant).

    The index satisfies Hurley and Rickard's six properties of a sparsity
    measure (Robin Hood, scaling, rising tide, cloning, Bill Gates, babies).

    References
    ----------
    .. [1] Thesis, section 5.1 "Sparsity Metrics", eq. 5.1.
    .. [2] N. Hurley and S. Rickard, "Comparing measures of sparsity", IEEE
       Transactions on Information Theory 55(10), 4723-4741, 2009.
    """
    energy = _check_flag(energy, "energy")
    values = _real_values(magnitudes, "magnitudes")
    if values.size == 0:
        raise ValueError("magnitudes is empty; the Gini index needs at least one value")
    sorted_values = np.sort(values, axis=None)
    _check_sorted(sorted_values, "magnitudes")
    return _gini_from_sorted(sorted_values, energy=energy)


# --------------------------------------------------------------------------- streaming


@dataclass(frozen=True)
class GiniEstimate:
    """A Gini index known to lie within ``value +- error_bound``.

    Attributes
    ----------
    value : float
        The estimate (midpoint of the guaranteed interval).
    error_bound : float
        ``|G - value| <= error_bound`` for the exact index ``G`` of the values
        seen (the ranking approximation plus a floating-point allowance).
    count : int
        Number of values (with multiplicity).
    """

    value: float
    error_bound: float
    count: int

    @property
    def lower(self):
        """Lower end of the guaranteed interval."""
        return self.value - self.error_bound

    @property
    def upper(self):
        """Upper end of the guaranteed interval."""
        return self.value + self.error_bound


def _validate_buckets(buckets):
    if isinstance(buckets, (bool, np.bool_)) or not isinstance(buckets, (int, np.integer)):
        raise TypeError(f"buckets must be an integer power of two, got {buckets!r}")
    buckets = int(buckets)
    if buckets < 2 or buckets > 2**31 or buckets & (buckets - 1):
        raise ValueError(f"buckets must be a power of two between 2 and 2**31, got {buckets}")
    return buckets


class GiniHistogram:
    """Accumulator for the streaming Gini index: one pass, memory independent of the data size.

    Values are bucketed by the top bits of their float32 bit pattern (for
    non-negative floats the bit pattern orders like the value), and each bucket
    keeps the count, the sum of values, the sum of squares, the minimum and the
    maximum. One histogram yields both the magnitude and the energy index.

    Parameters
    ----------
    buckets : int, optional
        A power of two between 2 and 2**31 (keyword only). With ``2**k``
        buckets a bucket spans a relative width of ``2**-(k - 8)`` of its
        lower edge (2**-15 for the default 2**23). Memory: about 48 bytes per
        bucket (400 MB for the default).
    piece_size : int, optional
        Values processed at a time inside :meth:`add` (bounds its temporaries,
        about 64 bytes per value).

    See Also
    --------
    gini_index_streaming : the one-call interface.
    """

    def __init__(self, *, buckets=DEFAULT_BUCKETS, piece_size=_DEFAULT_PIECE):
        self.buckets = _validate_buckets(buckets)
        if isinstance(piece_size, (bool, np.bool_)) or not isinstance(piece_size, (int, np.integer)):
            raise TypeError(f"piece_size must be a positive integer, got {piece_size!r}")
        if piece_size < 1:
            raise ValueError(f"piece_size must be a positive integer, got {piece_size}")
        self.piece_size = int(piece_size)
        # Non-negative float32 patterns use the low 31 bits; keep the top log2(buckets) of them.
        self._shift = 31 - (self.buckets.bit_length() - 1)
        self.counts = np.zeros(self.buckets, dtype=np.int64)
        self.sums = np.zeros(self.buckets, dtype=np.float64)
        self.squares = np.zeros(self.buckets, dtype=np.float64)
        self.minimum = np.full(self.buckets, np.inf)
        self.maximum = np.full(self.buckets, -np.inf)
        self.updates = 0

    @staticmethod
    def memory_bytes(buckets):
        """Approximate memory of a histogram with ``buckets`` buckets, transients included."""
        return _HISTOGRAM_BYTES_PER_BUCKET * int(buckets)

    def add(self, values, *, weights=None):
        """Add a chunk of non-negative values.

        Parameters
        ----------
        values : array_like of real, non-negative, finite values
            Any shape; may be a memory map (read in pieces). Values above the
            float32 range are refused (rescale: the index is scale invariant).
        weights : array_like of non-negative integers, optional
            Multiplicity of each value, same shape as ``values`` (e.g. 2 for a
            half-spectrum coefficient that stands for a conjugate pair).

        Raises
        ------
        ValueError
            Negative, NaN, inf, complex or too large values; weights of another
            shape or with negative entries.
        TypeError
            Non-numeric values, or non-integer weights.
        """
        values = _real_values(values, "values")
        if weights is not None:
            weights = np.asarray(weights)
            if weights.shape != values.shape:
                raise ValueError(f"weights of shape {weights.shape} do not match values of shape {values.shape}")
            if weights.dtype.kind not in "biu":
                raise TypeError(f"weights must be non-negative integers, got dtype {weights.dtype}")
            if weights.size and weights.min() < 0:
                raise ValueError(f"weights must be non-negative, got {int(weights.min())}")
        for index in _piece_indices(values.shape, self.piece_size):
            piece_weights = None if weights is None else weights[index]
            self._add_piece(values[index], piece_weights)

    def _add_piece(self, values, weights):
        flat = np.ascontiguousarray(values).reshape(-1)
        if flat.size == 0:
            return
        with np.errstate(over="ignore"):
            single = flat.astype(np.float32, copy=False)
        bits = single.view(np.uint32)
        if bits.max() > _LARGEST_FINITE_FLOAT32_BITS:
            single = self._repair_negative_zeros(flat, single)
            bits = single.view(np.uint32)
        if weights is not None:
            multiplicity = np.ascontiguousarray(weights).reshape(-1)
            counted = multiplicity != 0
            if not counted.all():  # values of weight zero must not widen a bucket's [min, max]
                flat, bits, multiplicity = flat[counted], bits[counted], multiplicity[counted]
                if flat.size == 0:
                    return
        keys = (bits >> self._shift).astype(np.intp)
        low_key, high_key = int(keys.min()), int(keys.max())
        keys -= low_key
        span = high_key - low_key + 1
        window = slice(low_key, high_key + 1)
        wide = flat.astype(np.float64)
        if weights is None:
            self.counts[window] += np.bincount(keys, minlength=span)
            self.sums[window] += np.bincount(keys, weights=wide, minlength=span)
            self.squares[window] += np.bincount(keys, weights=wide * wide, minlength=span)
        else:
            multiplicity = multiplicity.astype(np.float64)
            self.counts[window] += np.rint(np.bincount(keys, weights=multiplicity, minlength=span)).astype(np.int64)
            weighted = wide * multiplicity
            self.sums[window] += np.bincount(keys, weights=weighted, minlength=span)
            weighted *= wide
            self.squares[window] += np.bincount(keys, weights=weighted, minlength=span)
        np.minimum.at(self.minimum[window], keys, wide)
        np.maximum.at(self.maximum[window], keys, wide)
        self.updates += 1

    @staticmethod
    def _repair_negative_zeros(flat, single):
        """Raise for NaN, inf, negative or out-of-range values; map -0.0 to +0.0."""
        if np.isnan(flat).any():
            raise ValueError(f"values contain NaN; the Gini index needs finite non-negative magnitudes ({_ABS_HINT})")
        if (flat < 0).any():
            raise ValueError(
                f"values contain negative values (smallest {float(flat.min())!r}); the Gini index needs "
                f"non-negative magnitudes: {_ABS_HINT}"
            )
        if np.isinf(flat).any():
            raise ValueError(f"values contain inf; the Gini index needs finite non-negative magnitudes ({_ABS_HINT})")
        if np.isinf(single).any():
            raise ValueError(
                f"values up to {float(flat.max())!r} exceed the float32 range that the streaming histogram buckets; "
                "rescale them (the Gini index is scale invariant)"
            )
        return single + np.float32(0.0)  # -0.0 + 0.0 == +0.0

    @property
    def count(self):
        """Number of values added (with multiplicity)."""
        return int(self.counts.sum())

    def estimate(self, *, energy=False):
        """The Gini index of everything added so far, with its error bound.

        Parameters
        ----------
        energy : bool, optional
            The index of the squared values (keyword only).

        Returns
        -------
        GiniEstimate

        Raises
        ------
        ValueError
            Nothing was added, or the energies underflow (rescale the values).

        Notes
        -----
        See :func:`gini_index_streaming` for the estimator and the bound.
        """
        energy = _check_flag(energy, "energy")
        occupied = np.flatnonzero(self.counts)
        if occupied.size == 0:
            raise ValueError("no values were added; the Gini index needs at least one value")
        counts = self.counts[occupied]
        total_count = int(counts.sum())
        low, high = self.minimum[occupied], self.maximum[occupied]
        if low[0] == high[-1]:  # constant (all zeros included); tested before squaring, which may underflow
            return GiniEstimate(value=0.0, error_bound=0.0, count=total_count)
        sums = self.sums[occupied]
        if energy:
            low, high, sums = low * low, high * high, self.squares[occupied]
        total = float(sums.sum())
        if total == 0.0:
            raise ValueError("the energies underflow to zero in float64; rescale the values "
                             "(the Gini index is scale invariant)")
        sizes = counts.astype(np.float64)
        before = (np.cumsum(counts) - counts).astype(np.float64)
        # Average rank weight (N - i + 1/2)/N over the ranks before+1 .. before+n of a bucket.
        average_weights = (total_count - before - sizes / 2.0) / total_count
        lower = 1.0 - 2.0 * float(np.sum(sums * average_weights)) / total
        # Largest excess of the exact rank-weighted sum over the average-rank one, per bucket.
        width = high - low
        mean = np.clip(sums / sizes, low, high)
        spread_weights = np.zeros_like(width)
        positive = width > 0
        spread_weights[positive] = (mean[positive] - low[positive]) * (high[positive] - mean[positive]) \
            / width[positive] / 2.0
        excess = np.minimum(sizes * sizes * spread_weights, width * np.floor(sizes * sizes / 4.0) / 2.0)
        spread = 2.0 * float(np.sum(excess)) / (total_count * total)
        relative = (float(counts.max()) + self.updates + 4.0) * _UNIT_ROUNDOFF
        rounding = 3.0 * relative / (1.0 - relative) + 4.0 * (math.log2(occupied.size) + 4.0) * _UNIT_ROUNDOFF
        return GiniEstimate(value=lower + spread / 2.0, error_bound=spread / 2.0 + rounding, count=total_count)


def gini_index_streaming(chunks, *, energy=False, buckets=DEFAULT_BUCKETS):
    """Gini index (eq. 5.1) of data of any size in one pass and bounded memory, with an error bound.

    Parameters
    ----------
    chunks : iterable of array_like, or one ndarray
        Non-negative real values, in any number of chunks of any shapes (an
        ndarray, e.g. a memory map, is taken as a single chunk and read in
        pieces). Only one pass is made, so a generator works.
    energy : bool, optional
        The index of the squared values (keyword only).
    buckets : int, optional
        Histogram size, a power of two (keyword only); memory is about 48
        bytes per bucket plus about 64 bytes per value of a 2**22-value piece:
        about 0.7 GB for the default 2**23, whatever the input size.

    Returns
    -------
    GiniEstimate
        ``value`` and ``error_bound`` such that the exact index lies in
        ``[value - error_bound, value + error_bound]``.

    Raises
    ------
    ValueError
        No values at all; negative, NaN, inf, complex or beyond-float32 values;
        a bad ``buckets``.
    TypeError
        Non-numeric values, a non-integer ``buckets`` or a non-bool ``energy``.

    See Also
    --------
    gini_index : the exact index of values that fit in memory.
    GiniHistogram : the accumulator, for both variants from one pass.

    Notes
    -----
    *Histogram.* For non-negative IEEE floats the bit pattern orders like the
    value, so the top ``log2(buckets)`` of the 31 low bits of the float32
    pattern is a monotone bucket key: the buckets cut the sorted order into
    contiguous runs of ranks, each spanning a relative width of at most
    ``2**(8 - log2(buckets))`` (2**-15 for 2**23 buckets; float64 input is
    keyed by its float32 rounding, which is monotone). Per bucket ``b`` we keep
    the count ``n_b``, the sum ``s_b``, the sum of squares, the minimum
    ``lo_b`` and the maximum ``hi_b`` (in float64).

    *Estimator.* Eq. 5.1 is :math:`G = 2T/(NS) - (N+1)/N` with
    :math:`T = \\sum_i i\\,c_{(i)}` and :math:`S = \\|c\\|_1`. If ``r_b``
    values precede bucket ``b``, its values hold ranks ``r_b + 1 .. r_b + n_b``;
    giving each the average rank yields :math:`\\hat T_b = (r_b + (n_b+1)/2) s_b`
    and :math:`\\hat G = 1 - 2 \\sum_b s_b (N - r_b - n_b/2) / (N S)`.

    *Bound.* Within a bucket, with the values sorted, :math:`T_b - \\hat T_b =
    \\sum_j d_j c_j` with :math:`d_j = j - (n+1)/2` (which sums to zero). It is
    :math:`\\ge 0` (Chebyshev's sum inequality: both sequences increase), and,
    writing the sorted values as a mixture of "top k values at hi, the rest at
    lo" profiles whose excess is :math:`(hi - lo)\\,k(n-k)/2`, Jensen's
    inequality on the concave :math:`k(n-k)` with the mean ``m_b = s_b/n_b``
    fixed gives

    .. math::

        0 \\le T_b - \\hat T_b \\le E_b = \\min\\left(
            \\frac{n_b^2 (m_b - lo_b)(hi_b - m_b)}{2 (hi_b - lo_b)},\\;
            \\frac{(hi_b - lo_b) \\lfloor n_b^2/4 \\rfloor}{2}\\right),

    so buckets with ``lo == hi`` (all zeros, repeated values) contribute
    nothing. Hence :math:`\\hat G \\le G \\le \\hat G + 2\\sum_b E_b/(N S)`;
    the returned ``value`` is the midpoint and ``error_bound`` the half-width
    plus a floating-point allowance ``3 eps/(1 - eps) + 4 (log2 B + 4) u``,
    ``eps = (max_b n_b + updates + 4) u``, ``u = 2**-53``, covering the
    sequential float64 sums. Since ``hi - lo <= 2**-15 lo`` (default buckets),
    the half-width is at most ``2**-15 / 8 * max_b n_b / N <= 3.8e-6``, and
    usually far less (about 1e-11 for 6.6e8 float32 values), unless values are
    denormal float32 numbers. The energy variant uses the sums of squares and
    ``lo**2, hi**2`` (twice the relative width, so at most 7.6e-6). The bound covers
    the ranking approximation and the summation, not errors already present in
    the values (e.g. FFT rounding).

    References
    ----------
    Thesis section 5.1, eq. 5.1, and Hurley and Rickard (2009), as :func:`gini_index`.
    """
    energy = _check_flag(energy, "energy")
    histogram = GiniHistogram(buckets=buckets)
    if isinstance(chunks, np.ndarray) or np.isscalar(chunks):
        chunks = (chunks,)
    for chunk in chunks:
        histogram.add(chunk)
    return histogram.estimate(energy=energy)
