"""Sparse Fourier Transform filters and bin counts (thesis 2.3.4).

The flat-window filters of :func:`sparselt.recovery.sft.sft`: a base window
(Dolph-Chebyshev, Gaussian or the thesis's B-spline) times a one-bin
Dirichlet kernel, with its exact frequency response evaluated without any
length-``n`` transform; and the number theory that picks bin counts
dividing ``n`` and random permutations coprime with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..fourier import fft

# ---------------------------------------------------------------------------
# number theory


def divisors(n):
    factors = {}
    remaining = n
    candidate = 2
    while candidate * candidate <= remaining:
        while remaining % candidate == 0:
            factors[candidate] = factors.get(candidate, 0) + 1
            remaining //= candidate
        candidate += 1 if candidate == 2 else 2
    if remaining > 1:
        factors[remaining] = factors.get(remaining, 0) + 1
    found = np.array([1], dtype=np.int64)
    for prime, power in factors.items():
        found = (found[:, None] * prime ** np.arange(power + 1, dtype=np.int64)[None, :]).ravel()
    return np.sort(found)


def choose_bins(divisors_of_n, target):
    """The divisor of n nearest ``target`` on a log scale (``B`` must divide ``n``)."""
    target = max(float(target), 1.0)
    return int(divisors_of_n[np.argmin(np.abs(np.log(divisors_of_n / target)))])


def random_coprime(rng, n):
    if n == 1:
        return 1
    while True:
        sigma = int(rng.integers(1, n))
        if math.gcd(sigma, n) == 1:
            return sigma


# ---------------------------------------------------------------------------
# filters (thesis 2.3.4)


class _Response:
    """Exact frequency response ``T(d) = sum_j G[j] exp(-2 pi i j d / n) / Z`` of a symmetric filter, ``|d| <= reach``.

    Two exact evaluators, whichever is cheaper to build: a table of every
    integer offset (Bluestein's chirp-z transform, cost ``~ w + 2 reach``), or
    a Taylor expansion in ``d`` around a coarse grid of step ``q = n / L``
    whose coefficients are ``L``-point FFTs of the moments ``j^r G[j]``
    (cost ``~ terms * L`` with ``L ~ pi w / 2``, independent of ``reach``).
    Both agree with the direct sum to about 1e-15.
    """

    TERMS = 18

    def __init__(self, taps, n, reach, divisors_of_n):
        self.reach = int(reach)
        half_width = (taps.size - 1) // 2
        candidates = divisors_of_n[divisors_of_n >= math.pi * half_width]
        grid = int(candidates[0]) if candidates.size else 0
        table_cost = 3 * (1 << (2 * taps.size + 2 * self.reach).bit_length())
        taylor_cost = self.TERMS * 2 * grid
        if grid == 0 or table_cost <= taylor_cost:
            table = _frequency_response(taps, n, self.reach).real
            self.scale = table[self.reach]
            self.table = table / self.scale
            self.coefficients = None
            return
        self.table = None
        self.step = n // grid
        self.points = int(math.ceil(self.reach / self.step)) + 1
        j = np.arange(-half_width, half_width + 1)
        ratio = -2j * np.pi * j * self.step / (2 * n)  # |ratio| <= pi h / L <= 1
        term = taps.astype(np.complex128)
        rows = np.empty((self.TERMS, 2 * self.points + 1), dtype=np.complex128)
        where = j % grid
        keep = np.arange(-self.points, self.points + 1) % grid
        for power in range(self.TERMS):
            folded = np.bincount(where, term.real, grid) + 1j * np.bincount(where, term.imag, grid)
            rows[power] = fft.fftn(folded)[keep]
            term = term * ratio / (power + 1)
        self.coefficients = rows
        self.scale = 1.0
        self.scale = float(self(np.zeros(1, dtype=np.int64))[0])
        self.coefficients = rows / self.scale

    def __call__(self, offset):
        """``T(offset)`` for integer offsets (0 where ``|offset| > reach``)."""
        offset = np.asarray(offset, dtype=np.int64)
        inside = np.abs(offset) <= self.reach
        if self.table is not None:
            return np.where(inside, self.table[np.clip(offset + self.reach, 0, 2 * self.reach)], 0.0)
        clipped = np.clip(offset, -self.reach, self.reach)
        nearest = (clipped + self.step // 2) // self.step
        fraction = (clipped - nearest * self.step) * (2.0 / self.step)
        column = nearest + self.points
        value = self.coefficients[-1, column]
        for power in range(self.TERMS - 2, -1, -1):
            value = value * fraction + self.coefficients[power, column]
        return np.where(inside, value.real, 0.0)


@dataclass(frozen=True)
class Filter:
    bins: int
    half_width: int  # taps at j = -half_width .. half_width
    taps: np.ndarray  # scaled so a hash yields coefficients: bin = X[f] * phase * response
    response: _Response  # T(d), T(0) = 1, zero beyond response.reach
    neighbours: int  # bins on each side a frequency reaches

    @property
    def width(self):
        return 2 * self.half_width + 1

    @property
    def gain(self):
        """Noise energy per bin per unit of sample noise variance: ``sum_j taps[j]^2``."""
        return float(np.sum(self.taps ** 2))

    @property
    def reach(self):
        return self.response.reach


def _chebyshev_window(length, leakage):
    """Dolph-Chebyshev window of odd ``length`` with side lobes at ``leakage`` (relative)."""
    order = length - 1
    beta = np.cosh(np.arccosh(1.0 / leakage) / order)
    x = beta * np.cos(np.pi * np.arange(length) / length)
    p = np.empty(length)
    above, below, inside = x > 1, x < -1, np.abs(x) <= 1
    p[above] = np.cosh(order * np.arccosh(x[above]))
    p[below] = np.cosh(order * np.arccosh(-x[below]))  # (-1)^order with order even
    p[inside] = np.cos(order * np.arccos(x[inside]))
    spectrum = np.real(fft.fftn(p))
    half = (length + 1) // 2
    window = np.concatenate((spectrum[half - 1:0:-1], spectrum[:half]))
    return window / window.max()


def _bspline_window(half_width, boxes):
    """The thesis's flat-window base (2.3.4): a box convolved ``boxes`` times (a B-spline), support ``2 h + 1``."""
    from scipy.interpolate import BSpline

    knots = np.linspace(-half_width - 1, half_width + 1, boxes + 1)
    window = BSpline.basis_element(knots, extrapolate=False)(np.arange(-half_width, half_width + 1))
    window = np.nan_to_num(window)
    return window / window.max()


def _frequency_response(taps, n, reach):
    """``sum_j taps[j] exp(-2 pi i j d / n)`` for ``d = -reach .. reach`` (taps at ``j = -h .. h``).

    Bluestein's chirp-z transform: ``j d = (j^2 + d^2 - (d - j)^2) / 2`` turns
    the sum into a convolution, so the table costs one FFT of about
    ``2 w + 2 reach`` points instead of a length-``n`` transform.
    """
    h = (taps.size - 1) // 2

    def chirp(m):  # exp(i pi m^2 / n), with m^2 reduced exactly modulo 2n
        m = np.asarray(m, dtype=np.int64)
        return np.exp(1j * np.pi * ((m * m) % (2 * n)) / n)

    j = np.arange(-h, h + 1)
    a = taps * np.conj(chirp(j))
    c = chirp(np.arange(-(reach + h), reach + h + 1))
    length = a.size + c.size - 1
    size = 1 << (length - 1).bit_length()
    product = fft.ifftn(fft.fftn(np.pad(a, (0, size - a.size))) * fft.fftn(np.pad(c, (0, size - c.size))))
    d = np.arange(-reach, reach + 1)
    return np.conj(chirp(d)) * product[2 * h: 2 * h + 2 * reach + 1]


def make_filter(n, bins, width, window, leakage, divisors_of_n=None):
    """Flat window for ``bins`` bins: base window times a Dirichlet kernel one bin wide (2.3.4)."""
    half_width = max(1, int(round(width * bins / 2)))
    half_width = min(half_width, (n - 1) // 2)
    j = np.arange(-half_width, half_width + 1)
    passband = n // (2 * bins)  # frequencies -passband .. passband: one bin of n / B
    with np.errstate(invalid="ignore", divide="ignore"):
        dirichlet = np.sin(np.pi * (2 * passband + 1) * j / n) / np.sin(np.pi * j / n)
    dirichlet[half_width] = 2 * passband + 1
    log_leakage = math.log(1.0 / leakage)
    if window == "gaussian":
        sigma = half_width / math.sqrt(2 * log_leakage)
        base = np.exp(-0.5 * (j / sigma) ** 2)
        lobe = 1.1 * log_leakage * n / (math.pi * half_width)
    elif window == "chebyshev":
        base = _chebyshev_window(j.size, leakage)
        lobe = 1.2 * math.log(2.0 / leakage) * n / (2 * math.pi * half_width)
    else:
        boxes = int(min(12, max(2, 2 * round(log_leakage / 2 / math.log(10) * 1.0))))
        base = _bspline_window(half_width, boxes)
        first_null = n * boxes / (2 * half_width + 2)
        lobe = first_null * max(1.0, leakage ** (-1.0 / boxes) / math.pi)
    reach = int(min(passband + math.ceil(lobe), (n - 1) // 2))
    taps = base * dirichlet
    response = _Response(taps, n, reach, divisors(n) if divisors_of_n is None else divisors_of_n)
    taps = taps * (n / response.scale)
    neighbours = int(math.ceil(reach * bins / n + 0.5))
    return Filter(bins, half_width, taps, response, neighbours)
