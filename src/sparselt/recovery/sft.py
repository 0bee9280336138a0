"""Sparse Fourier Transform (thesis 2.3, Algorithms 3-7) and rank-1 lattice reduction (thesis 6.1.1).

:func:`sft` recovers the ``K`` largest coefficients of the DFT of a length-``n``
signal that it can only *sample*: ``oracle(indices)`` returns ``x[indices]``
(one rendered path per sample, so samples are the cost that matters). It reads
a few thousand samples where a full FFT needs all ``n``. :func:`sft_lattice`
does the same for a function on ``[0, 1)^D`` whose frequencies lie in a box,
through the rank-1 lattice of eq. 6.1-6.2, without ever forming the grid
(:mod:`sparselt.recovery.lattice`; the filters are in
:mod:`sparselt.recovery.sft_filters`).

Structure (the thesis's Algorithms 3-7, Hassanieh et al. 2012, Indyk, Kapralov
and Price 2014):

1. **Permutation.** Each hash draws ``sigma`` coprime with ``n`` and an offset
   ``tau`` and reads ``y[j] = x[(sigma j + tau) mod n]``, which moves frequency
   ``f`` to ``p = sigma f mod n`` (with the phase ``exp(2 pi i f tau / n)``).
2. **Flat window** (2.3.4). ``y`` is multiplied by a filter ``G`` of
   ``w = width * B`` taps: a base window times a Dirichlet kernel one bin
   (``n / B`` frequencies) wide, so that the filter's spectrum is flat over a
   bin and falls to the ``leakage`` level within a few bins. The base window
   is Dolph-Chebyshev by default (optimal main lobe for its side-lobe level:
   fewest samples in ``benchmarks/sft.py``); Gaussian and the thesis's
   B-spline are options.
3. **HashToBins** (Algorithm 5). The windowed samples are aliased to ``B``
   terms and transformed by a ``B``-point FFT; bin ``h`` then holds
   ``sum_f X[f] exp(2 pi i (f tau + p s) / n) T(h n / B - p)`` where ``s`` is
   a time shift of the window and ``T`` the filter's exact frequency
   response, evaluated without any length-``n`` transform (a chirp-z table
   or a Taylor expansion from small FFTs, :class:`sparselt.recovery.sft_filters._Response`).
4. **Location** (Algorithm 6, with decreasing phase ambiguity instead of a
   search). The same hash is read at shifts ``0, s_1, s_1 r, s_1 r^2, ...``:
   the phase of bin ``h`` at shift ``s`` against shift 0 is
   ``2 pi p s / n mod 2 pi``. The bin gives ``p`` to ``+- n / B``; each shift
   refines it ``r`` times until it is an integer. A bin is accepted when that
   one frequency explains all its shifts (a singleton test).
5. **Iterative subtraction** (Algorithms 3-4). What is found is subtracted
   from every later hash *in the bin domain*, exactly, through ``T``; the
   next hash needs only ``B = alpha K_remaining`` bins.
6. **Magnitude** (Algorithm 7). Every bin read so far is a linear
   measurement of the found coefficients; after each hash the values are
   polished by robust least squares over all of them (bins holding
   coefficients not yet found are dropped as outliers). It costs no samples
   and makes exactly sparse recovery exact. Optional extra magnitude hashes
   give the median over hashes of each coefficient's bin estimate, which
   then picks the inlier bins.

Sample reuse. Samples are cached, so every distinct index is read (and
counted) once. The shifted windows of one hash overlap: shifts below the
window length cost only ``s`` new samples. Magnitude estimation reuses every
sample of support detection (``magnitude_samples`` is 0 by default).

Sizes. ``B`` must divide ``n``, so ``n`` should have divisors near
``alpha K``: powers of two and smooth sizes (products of small primes, like
lattice sizes) are ideal. When no suitable ``B`` exists, or the sparse
transform would read at least ``dense_fraction`` of the signal, it reads all
``n`` samples and takes one FFT (``stop_reason == 'dense'``); the sample count
never exceeds ``n``.

References
----------
Thesis sections 2.3 (Algorithms 3-7) and 6.1.1 (eq. 6.1-6.2).
H. Hassanieh, P. Indyk, D. Katabi, E. Price, "Simple and practical algorithm
for sparse Fourier transform", SODA 2012; "Nearly optimal sparse Fourier
transform", STOC 2012.
P. Indyk, M. Kapralov, E. Price, "(Nearly) sample-optimal sparse Fourier
transform", SODA 2014.
S. Pawar, K. Ramchandran, "FFAST: an algorithm for computing an exactly
k-sparse DFT in O(k log k) time", IEEE Trans. Inf. Theory 2018 (shift-based
location and sample counts).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from ..checks import check_integer
from ..fourier import fft
from ..fourier.sparse import SparseFourier
from .result import RecoveryResult
from . import sft_hashing as hashing
from .sample_cache import IndexedValues
from .sft_filters import choose_bins, divisors, make_filter, random_coprime

WINDOWS = ("chebyshev", "gaussian", "bspline")


@dataclass(frozen=True)
class SparseFourierTuning:
    """Every tuning constant of the Sparse Fourier Transform, in one place.

    Attributes
    ----------
    occupancy_factor : float
        A bin is occupied when its energy exceeds this many noise levels per bin.
    singleton_residual : float
        Largest fraction of a bin's energy one frequency may leave unexplained (singleton test) ...
    singleton_noise : float
        ... plus this many noise levels over the bin's energy (the worst of several noisy shifts).
    bin_snr : float
        With noise, later hashes keep enough bins for this SNR per bin (``B >= K bin_snr / snr``).
    minimum_response : float
        Smallest filter response at which a bin may report a frequency.
    leakage_phase_error : float
        Phase error per bin the location design tolerates from leakage alone (radians).
    relative_floor : float
        Relative level below which differences are round-off (exactly sparse signals).
    noise_quantile : float
        Quantile of bin energies taken as the noise level (most bins hold no coefficient).
    outlier_factor : float
        Least squares drops bins whose residual exceeds this many times the median residual of their hash.
    cg_tolerance : float
        Relative residual at which each least-squares correction stops (each round refines the last).
    cg_iterations : int
        Most conjugate-gradient iterations per least-squares round.
    detection_rounds : int
        Least-squares rounds after each detection hash (the final polish runs three).
    minimum_bins : int
        Fewest bins a hash may have (the noise level comes from the lower quartile of its bins).
    bins_floor : float
        Later hashes keep at least this fraction of the first hash's bins (found values stay apart).
    largest_sample : float
        Largest sample magnitude accepted: squares and sums of squares must stay finite in float64.
    """

    occupancy_factor: float = 12.0
    singleton_residual: float = 0.05
    singleton_noise: float = 8.0
    bin_snr: float = 30.0
    minimum_response: float = 0.25
    leakage_phase_error: float = 0.05
    relative_floor: float = 1e-11
    noise_quantile: float = 0.25
    outlier_factor: float = 10.0
    cg_tolerance: float = 1e-10
    cg_iterations: int = 100
    detection_rounds: int = 2
    minimum_bins: int = 4
    bins_floor: float = 0.25
    largest_sample: float = 1e150


#: The tuning every call uses unless given another.
TUNING = SparseFourierTuning()


# ---------------------------------------------------------------------------
# result record


@dataclass(frozen=True)
class SparseFourierTransformResult(RecoveryResult):
    """What :func:`sft` found and what it cost.

    Attributes
    ----------
    estimate : SparseFourier
        The ``K`` coefficients found, ``numpy.fft.fftn`` convention.
    residual_history : tuple of float
        Per detection hash: energy left in its bins after subtracting what
        was already found, over the energy of the bins.
    iterations : int
        Detection hashes (rounds of Algorithm 6).
    samples : int
        Distinct samples read (``support_samples + magnitude_samples``).
    seconds : dict
        Seconds per phase: ``setup`` (filters), ``support`` and ``magnitude``
        (computation) and ``oracle`` (inside the oracle). They add up to the
        total.
    stop_reason : str
        ``'converged'`` (a hash found nothing left), ``'stagnated'`` (K found,
        nothing new for two hashes), ``'max_iterations'`` or ``'dense'``.
    transforms : int
        Full length-``n`` FFTs (1 in the dense fallback, else 0).
    support_samples, magnitude_samples : int
        Samples spent on support detection and on magnitude estimation
        (thesis Table 6.1's columns).
    bins : tuple of int
        ``B`` of every hash, detection then magnitude.
    parameters : dict
        The resolved parameters (alpha, width, window, leakage, snr, seed, ...).
    """

    support_samples: int = 0
    magnitude_samples: int = 0
    bins: tuple = ()
    parameters: dict = field(default_factory=dict)

    @property
    def samples_per_coefficient(self):
        """Samples read per coefficient returned."""
        return self.samples / max(self.estimate.sparsity, 1)


# ---------------------------------------------------------------------------
# validation


def _check_size(n):
    n = check_integer("signal size n", n, 1)
    if n >= 2 ** 31:
        raise ValueError(f"signal size n must be below 2**31 (index products must fit in int64), got {n}")
    return n


def _check_sparsity(sparsity, n):
    sparsity = check_integer("sparsity K", sparsity, -2**62)
    if not 0 < sparsity <= n // 2:
        raise ValueError(f"sparsity K must satisfy 0 < K <= n/2 = {n // 2} for a signal of size {n}, got {sparsity}")
    return sparsity


def _check_positive(name, value, minimum, allowed):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a finite number {allowed}, got {value!r}")
    if not math.isfinite(value) or value < minimum:
        raise ValueError(f"{name} must be {allowed}, got {value}")
    return float(value)


def _check_snr(snr):
    if (isinstance(snr, bool) or not isinstance(snr, (int, float, np.integer, np.floating)) or math.isnan(snr)
            or snr == -math.inf):
        raise ValueError(f"snr must be a number of decibels or numpy.inf (exactly sparse), got {snr!r}")
    return float(snr)


def _check_window(window):
    if window not in WINDOWS:
        raise ValueError(f"window must be one of {WINDOWS}, got {window!r}")
    return window


# ---------------------------------------------------------------------------
# sample cache: every distinct index is read once


class _SampleCache:
    """Wraps the oracle: distinct indices are read once and counted per phase."""

    def __init__(self, oracle, size, largest_sample=TUNING.largest_sample):
        self.oracle = oracle
        self.size = size
        self.largest_sample = largest_sample
        self.store = IndexedValues(size, (), np.complex128)
        self.phase = "support"
        self.counts = {"support": 0, "magnitude": 0}
        self.oracle_time = 0.0

    @property
    def count(self):
        return int(self.store.count)

    @property
    def values(self):
        return self.store.values

    def _call(self, indices):
        start = time.perf_counter()
        if hasattr(self.oracle, "sft_phase"):  # an oracle that counts its own samples per phase is told the phase
            self.oracle.sft_phase = self.phase
        values = self.oracle(indices)
        self.oracle_time += time.perf_counter() - start
        values = np.asarray(values)
        if values.shape != indices.shape:
            raise ValueError(f"the oracle must return one value per index: asked for {indices.size} samples, "
                             f"got an array of shape {values.shape}")
        if not (np.issubdtype(values.dtype, np.number) and not np.issubdtype(values.dtype, np.timedelta64)):
            raise ValueError(f"the oracle must return real or complex numbers, got dtype {values.dtype}")
        if not np.all(np.isfinite(values)):
            bad = int(np.count_nonzero(~np.isfinite(values)))
            raise ValueError(f"the oracle returned {bad} NaN or infinite samples (first at index "
                             f"{int(indices[~np.isfinite(values)][0])}); samples must be finite")
        largest = float(np.abs(values).max(initial=0.0))
        if largest > self.largest_sample:
            raise ValueError(f"the oracle returned a sample of magnitude {largest:.3g}; energies (squares) of values "
                             f"above {self.largest_sample:.0e} overflow float64: divide the signal by a scale and multiply "
                             "the result back")
        return values.astype(np.complex128, copy=False)

    def read(self, indices):
        """``x[indices]`` for indices (any order, repeats allowed), reading only the new ones (sorted)."""
        indices = np.asarray(indices, dtype=np.int64)
        missing = self.store.missing(indices)
        if missing.size:
            self.store.add(missing, self._call(missing))
            self.counts[self.phase] += int(missing.size)
        return self.store.get(indices)


# ---------------------------------------------------------------------------
# the transform


def _noise_level(energy, quantile=TUNING.noise_quantile):
    """Noise energy per bin from the lower quantile of bin energies (exponential law)."""
    if energy.size < 4:
        return float(np.min(energy))
    return float(np.quantile(energy, quantile) / -math.log(1 - quantile))


def _merge(frequencies, values, new_frequencies, new_values):
    """Add ``new_values`` at ``new_frequencies`` (corrections where already present)."""
    position = np.searchsorted(frequencies, new_frequencies)
    present = np.zeros(new_frequencies.size, dtype=bool)
    if frequencies.size:
        present = frequencies[np.minimum(position, frequencies.size - 1)] == new_frequencies
    values = values.copy()
    np.add.at(values, position[present], new_values[present])
    order = np.argsort(new_frequencies[~present], kind="stable")
    frequencies = np.insert(frequencies, position[~present][order], new_frequencies[~present][order])
    values = np.insert(values, position[~present][order], new_values[~present][order])
    return frequencies, values, int(np.count_nonzero(~present))


def _conjugate_gradient(matrix, right, diagonal, tuning):
    """Solve the Hermitian positive definite ``matrix x = right``: SciPy's CG with a Jacobi preconditioner."""
    if not np.any(right):
        return np.zeros_like(right)
    preconditioner = scipy.sparse.linalg.LinearOperator(matrix.shape, matvec=lambda vector: vector / diagonal,
                                                        dtype=right.dtype)
    solution, _ = scipy.sparse.linalg.cg(matrix, right, rtol=tuning.cg_tolerance, atol=0.0,
                                         maxiter=tuning.cg_iterations, M=preconditioner)
    return solution


def _energy_statistics(energy, touched, tuning):
    """Noise level (lower quartile) of a hash's bin energies and the median energy of its touched bins."""
    stride = max(1, energy.size // 65536)  # a regular subsample is plenty for two quantiles
    level = _noise_level(energy[::stride], tuning.noise_quantile)
    spread = float(np.median(energy[touched][::stride])) if touched.any() else 0.0
    return level, spread


def _polish(n, hashes, frequencies, values, scale, tuning, rounds=3, robust_start=False, variance=math.inf):
    """Robust least squares for the values over every bin read so far (no new samples).

    Every bin of every hash (at every shift) is a linear measurement of the
    coefficients through the filter response: ``bins = A values + noise``.
    The first round solves the noise-weighted least squares over every bin
    the coefficients reach (unless ``robust_start``: the values are already
    robust estimates, such as medians); later rounds drop the bins whose residual the
    model does not explain (more than ``occupancy_factor`` noise levels and
    ``outlier_factor`` times the median residual of the hash: bins holding a
    coefficient not found yet). The normal equations are small and sparse
    (coefficients couple only through shared bins) and diagonally dominant;
    each hash's Gram matrix is formed once and the outlier bins' share is
    subtracted. ``variance`` caps the noise variance per sample. Returns the
    values and the noise level per bin of each hash.
    """
    floor = (tuning.relative_floor * scale) ** 2
    gains = np.array([hashed.filter.gain for hashed in hashes])
    sizes = [hashed.bins.size for hashed in hashes]
    starts = np.concatenate(([0], np.cumsum(sizes)))
    raw = np.concatenate([hashed.bins.ravel() for hashed in hashes])
    levels = np.empty(len(hashes))
    spread = np.zeros(len(hashes))
    if frequencies.size == 0:
        for index in range(len(hashes)):
            levels[index] = _noise_level(np.abs(raw[starts[index]:starts[index + 1]]) ** 2, tuning.noise_quantile)
        return values, gains * min(np.min(levels / gains), variance)
    blocks, grams = [], []
    for hashed, start in zip(hashes, starts):
        where, weights = hashing.response(n, hashed, frequencies)
        bins_count = hashed.filter.bins
        row = np.arange(hashed.shifts.size)[:, None, None] * bins_count + where[None, :, :]
        nonzero = weights != 0
        column = np.broadcast_to(np.arange(frequencies.size)[None, :, None], weights.shape)[nonzero]
        block = scipy.sparse.csr_matrix((weights[nonzero], (row[nonzero], column)),
                                        shape=(hashed.bins.size, frequencies.size))
        blocks.append(block)
        grams.append((block.conj().T @ block).tocsr())
    matrix = scipy.sparse.vstack(blocks, format="csr")
    adjoint = matrix.conj().T.tocsr()
    touched = np.diff(matrix.indptr) > 0
    which = np.repeat(np.arange(len(hashes)), sizes)
    for round_ in range(rounds):
        residual = raw - matrix @ values
        energy = np.abs(residual) ** 2
        for index in range(len(hashes)):
            segment = slice(starts[index], starts[index + 1])
            levels[index], spread[index] = _energy_statistics(energy[segment], touched[segment], tuning)
        levels = gains * min(np.min(levels / gains), variance)  # noise variance: the least contaminated hash
        level = levels + floor
        row_weight = 1.0 / level[which]
        normal = grams[0] * (1.0 / level[0])
        for index in range(1, len(hashes)):
            normal = normal + grams[index] * (1.0 / level[index])
        selected = touched
        if round_ > 0 or robust_start:  # drop the bins that the model does not explain (coefficients not found yet)
            limit = np.maximum(tuning.occupancy_factor * level, tuning.outlier_factor * spread)[which]
            selected = touched & (energy <= limit)
            outliers = np.flatnonzero(touched & ~selected)
            if outliers.size:
                part = matrix[outliers]
                normal = normal - part.conj().T @ scipy.sparse.diags(row_weight[outliers]) @ part
        right = adjoint @ np.where(selected, residual * row_weight, 0)
        diagonal = normal.diagonal().real
        ridge = 1e-12 * max(float(diagonal.max(initial=0.0)), 1e-300)
        tiny = diagonal <= ridge  # coefficients with no bin left: keep their values
        if tiny.any():
            normal = normal + scipy.sparse.diags(np.where(tiny, ridge, 0.0))
        values = values + _conjugate_gradient(normal.tocsr(), right, np.maximum(diagonal, ridge), tuning)
    return values, levels


def sft(oracle, n, sparsity, *, alpha=4.0, snr=np.inf, window="chebyshev", width=None, leakage=None,
        shift_ratio=None, magnitude_hashes=None, max_iterations=None, dense_fraction=0.5, seed=None, tuning=TUNING):
    r"""Sparse Fourier Transform of a signal read through ``oracle`` (thesis 2.3, Algorithms 3-7).

    Parameters
    ----------
    oracle : callable
        ``oracle(indices) -> values``: the signal at the given indices (a
        sorted int64 array of distinct indices in ``[0, n)``), one finite
        real or complex value each. No index is asked for twice. An oracle
        with a writable ``sft_phase`` attribute is told the phase reading
        ('support' or 'magnitude') before each call.
    n : int
        Signal length, ``0 < n < 2**31``. Powers of two and smooth sizes
        work best: the number of bins ``B`` must divide ``n``.
    sparsity : int
        ``K``, the number of coefficients to return, ``0 < K <= n / 2``.
    alpha : float, optional
        Bins per coefficient, ``B = alpha K`` rounded to a divisor of ``n``
        on a log scale (at least 1; default 4).
    snr : float, optional
        Expected signal-to-noise ratio in decibels (the thesis's ``R``);
        ``numpy.inf`` (default) for exactly sparse signals. It sets the
        filter's stop-band level and the location shifts; the noise level
        itself is measured from the bins.
    window : {'chebyshev', 'gaussian', 'bspline'}, optional
        Base of the flat window: Dolph-Chebyshev (default: fewest samples in
        ``benchmarks/sft.py``), Gaussian (exact to 1e-14 instead of 1e-11) or
        the thesis's B-spline (2.3.4, needs ``width >= 6``).
    width : float, optional
        Filter taps per bin, ``w = width * B`` (default 3, at least 1).
    leakage : float, optional
        Stop-band level of the filter relative to its pass band, in
        ``(0, 0.1)``; default 1e-10 for exactly sparse signals, else
        ``0.1 / sqrt(snr alpha K)`` clipped to ``[1e-10, 1e-3]``.
    shift_ratio : int, optional
        Refinement factor ``r >= 2`` between location shifts (default: the
        largest power of two the expected phase noise allows).
    magnitude_hashes : int, optional
        New single-window hashes read for magnitude estimation (default 0:
        the detection samples are reused). With at least three full-size
        hashes the values start from their median (Algorithm 7).
    max_iterations : int, optional
        Most detection hashes (default ``12 + 2 log2 K``).
    dense_fraction : float, optional
        Read all ``n`` samples and take one FFT when the sparse transform
        would read at least this fraction of them, in ``(0, 1]`` (default 0.5).
    seed : int or numpy.random.Generator, optional
        Randomness of the permutations.

    Returns
    -------
    SparseFourierTransformResult
        ``.estimate``: a :class:`~sparselt.fourier.sparse.SparseFourier` of
        shape ``(n,)`` in the ``numpy.fft.fft`` convention (``to_signal()``
        approximates the signal); ``.samples`` (distinct samples read, at
        most ``n``), ``.support_samples``, ``.magnitude_samples``,
        ``.iterations``, ``.seconds`` per phase, ``.stop_reason``, ``.bins``.

    Raises
    ------
    ValueError
        ``n`` not a positive integer below ``2**31``, ``K`` outside
        ``(0, n/2]``, ``alpha < 1``, a bad window, width, leakage, snr or
        option, or an oracle returning the wrong number of values or NaN or
        infinite values.

    Notes
    -----
    Hash ``t`` draws ``sigma`` coprime with ``n`` and ``tau``, and reads
    ``x[(sigma (j + s) + tau) mod n]`` for the ``w`` taps ``j`` of the window
    at each location shift ``s``; bin ``h`` then holds

    .. math:: u_s[h] = \sum_f X[f] e^{2 \pi i (f \tau + p s) / n} T(h n / B - p),
              \quad p = \sigma f \bmod n,

    with ``T`` the filter's exact response. Shifts ``0, B/4, B r/4, ...``
    give ``p s / n mod 1`` from phases; each refines ``p`` by ``r`` until it
    is an integer, and a bin is accepted when that one frequency explains all
    its shifts (worst shift within ``SINGLETON_RESIDUAL`` of the bin energy)
    and ``|T| >= MINIMUM_RESPONSE``. Everything found is subtracted from the
    next hash through ``T`` (exact, in the bin domain), so it only needs
    ``B = alpha K_remaining`` bins (at least ``BINS_FLOOR`` of the first).
    After every hash the values are polished by robust least squares over
    all bins read so far, which costs no samples and makes exactly sparse
    recovery exact. It stops when a hash has no occupied bin (energy above
    ``OCCUPANCY_FACTOR`` noise levels; the noise variance per sample is the
    least lower-quartile estimate over hashes), or when ``K`` are found and
    two hashes add nothing new (``'stagnated'``). The ``K`` largest are kept
    (Algorithm 3's prune) and polished again.

    References
    ----------
    Thesis 2.3 (Algorithms 3-7) and Table 6.1; Hassanieh, Indyk, Katabi and
    Price, SODA 2012 and STOC 2012; Indyk, Kapralov and Price, SODA 2014.
    """
    solver = SparseFourierTransform(oracle, n, sparsity, alpha=alpha, snr=snr, window=window, width=width,
                                    leakage=leakage, shift_ratio=shift_ratio, magnitude_hashes=magnitude_hashes,
                                    max_iterations=max_iterations, dense_fraction=dense_fraction, seed=seed,
                                    tuning=tuning)
    return solver.run()


class SparseFourierTransform:
    """The Sparse Fourier Transform as a solver: :meth:`setup`, one :meth:`step` per detection hash, :meth:`finalize`.

    Follows PyLops' solver classes (``optimization/cls_sparsity.py``): the
    constructor validates, :meth:`setup` plans the first hash (or decides on
    the dense fallback), each :meth:`step` reads one hash and adds what it
    locates (Algorithms 4-6), :meth:`finalize` estimates the magnitudes
    (Algorithm 7) and returns the result; :meth:`run` chains them, and
    :func:`sft` is the function wrapper. Parameters are those of :func:`sft`.

    Attributes
    ----------
    frequencies, values : ndarray
        What has been found so far (sorted frequencies, their values).
    iterations : int
        Detection hashes read so far.
    stop_reason : str or None
        Why detection stopped, once it has.
    """

    def __init__(self, oracle, n, sparsity, *, alpha=4.0, snr=np.inf, window="chebyshev", width=None, leakage=None,
                 shift_ratio=None, magnitude_hashes=None, max_iterations=None, dense_fraction=0.5, seed=None,
                 tuning=TUNING):
        if not isinstance(tuning, SparseFourierTuning):
            raise TypeError(f"tuning must be a SparseFourierTuning, got {type(tuning).__name__}")

        n = _check_size(n)
        sparsity = _check_sparsity(sparsity, n)
        alpha = _check_positive("alpha", alpha, 1.0, "at least 1 (B = alpha K bins)")
        snr = _check_snr(snr)
        window = _check_window(window)
        noisy = math.isfinite(snr)
        snr_linear = 10 ** (snr / 10) if noisy else math.inf
        width = 3.0 if width is None else _check_positive("width", width, 1.0, "at least 1 (taps per bin)")
        if leakage is None:
            leakage = 1e-10 if not noisy else float(np.clip(0.1 / math.sqrt(snr_linear * alpha * sparsity), 1e-10, 1e-3))
        else:
            leakage = _check_positive("leakage", leakage, 0.0, "in (0, 0.1)")
            if not 0 < leakage < 0.1:
                raise ValueError(f"leakage must be in (0, 0.1), got {leakage}")
        phase_error = tuning.leakage_phase_error
        if noisy:
            phase_error = max(phase_error, 1.5 / math.sqrt(max(snr_linear * alpha, 1.0)))
        if shift_ratio is None:
            shift_ratio = int(2 ** max(1, math.floor(math.log2(math.pi / (3 * phase_error)))))
        shift_ratio = check_integer("shift_ratio", shift_ratio, 2)
        magnitude_hashes = check_integer("magnitude_hashes", 0 if magnitude_hashes is None else magnitude_hashes, 0)
        if max_iterations is None:
            max_iterations = 12 + 2 * int(math.log2(sparsity + 1))
        max_iterations = check_integer("max_iterations", max_iterations, 1)
        dense_fraction = _check_positive("dense_fraction", dense_fraction, 0.0, "in (0, 1]")
        if not 0 < dense_fraction <= 1:
            raise ValueError(f"dense_fraction must be in (0, 1], got {dense_fraction}")
        if not callable(oracle):
            raise ValueError(f"oracle must be callable as oracle(indices) -> values, got {type(oracle).__name__}")
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        parameters = dict(n=n, sparsity=sparsity, alpha=alpha, snr=snr, window=window, width=width, leakage=leakage,
                          shift_ratio=shift_ratio, magnitude_hashes=magnitude_hashes, max_iterations=max_iterations,
                          dense_fraction=dense_fraction, seed=seed if not isinstance(seed, np.random.Generator) else None)
        self.oracle, self.n, self.sparsity, self.alpha = oracle, n, sparsity, alpha
        self.snr, self.snr_linear, self.noisy = snr, snr_linear, noisy
        self.window, self.width, self.leakage = window, width, leakage
        self.phase_error, self.shift_ratio = phase_error, shift_ratio
        self.magnitude_hashes, self.max_iterations, self.dense_fraction = magnitude_hashes, max_iterations, dense_fraction
        self.tuning, self.rng, self.parameters = tuning, rng, parameters
        self.cache = _SampleCache(oracle, n, tuning.largest_sample)
        self.timing = {"setup": 0.0, "support": 0.0, "magnitude": 0.0}
        self.filters = {}
        self.frequencies = np.zeros(0, dtype=np.int64)
        self.values = np.zeros(0, dtype=np.complex128)
        self.hashes, self.history = [], []
        self.quiet, self.rejected, self.iterations = 0, 0, 0
        self.scale = 0.0
        self.variance = math.inf  # noise variance per sample, least over hashes
        self.stop_reason = None
        self.dense_needed = False

    # -- bookkeeping ---------------------------------------------------------

    def _filter(self, bins):
        if bins not in self.filters:
            start = time.perf_counter()
            self.filters[bins] = make_filter(self.n, bins, self.width, self.window, self.leakage, self.divisors)
            self.timing["setup"] += time.perf_counter() - start
        return self.filters[bins]

    def _clock(self):
        return time.perf_counter(), self.timing["setup"], self.cache.oracle_time

    def _charge(self, phase, clock):
        """Add the time since ``clock`` to ``phase``, less filter setup and oracle time spent meanwhile."""
        start, setup_before, oracle_before = clock
        spent = time.perf_counter() - start
        spent -= (self.timing["setup"] - setup_before) + (self.cache.oracle_time - oracle_before)
        self.timing[phase] += max(spent, 0.0)

    def _result(self, reason, transforms=0):
        frequencies, values = self.frequencies, self.values
        if values.size > self.sparsity:
            keep = np.sort(np.argsort(-np.abs(values), kind="stable")[:self.sparsity])
            frequencies, values = frequencies[keep], values[keep]
        nonzero = values != 0
        estimate = SparseFourier((self.n,), frequencies[nonzero], values[nonzero])
        times = dict(self.timing)
        times["oracle"] = self.cache.oracle_time
        return SparseFourierTransformResult(
            estimate=estimate, residual_history=tuple(self.history), iterations=self.iterations,
            samples=self.cache.count, seconds=times, stop_reason=reason, transforms=transforms,
            support_samples=self.cache.counts["support"], magnitude_samples=self.cache.counts["magnitude"],
            bins=tuple(h.filter.bins for h in self.hashes), parameters=self.parameters)

    def _dense(self):
        """Read all ``n`` samples and take one FFT (the fallback when sparse would read too much)."""
        clock = self._clock()
        self.cache.phase = "support"
        signal = self.cache.read(np.arange(self.n, dtype=np.int64))
        spectrum = fft.fftn(signal)
        keep = np.sort(np.argsort(-np.abs(spectrum), kind="stable")[:self.sparsity])
        self._charge("support", clock)
        self.frequencies, self.values = keep.astype(np.int64), spectrum[keep]
        return self._result("dense", transforms=1)

    # -- the solver ----------------------------------------------------------

    def setup(self):
        """Plan the first hash; decide on the dense fallback when no suitable ``B`` exists or it is too costly."""
        start = time.perf_counter()
        n, tuning = self.n, self.tuning
        self.divisors = divisors(n)
        self.usable = self.divisors[(self.divisors >= tuning.minimum_bins) & (self.divisors <= n // 4)]
        self.first_bins = choose_bins(self.usable, self.alpha * self.sparsity) if self.usable.size else 0
        first_shifts = hashing.shift_schedule(n, self.first_bins, self.phase_error, self.shift_ratio)
        first_cost = hashing.window_cost(first_shifts, max(1, int(round(self.width * self.first_bins / 2))))
        first_width = 2 * max(1, int(round(self.width * self.first_bins / 2))) + 1
        self.dense_needed = (self.first_bins == 0 or self.first_bins < self.alpha * self.sparsity / 4
                             or 1.5 * first_cost + self.magnitude_hashes * first_width >= self.dense_fraction * n)
        self.timing["setup"] += time.perf_counter() - start
        return self

    def step(self):
        """Read one detection hash and add what it locates (Algorithms 4-6).

        Returns
        -------
        bool
            Whether detection goes on (``False`` once :attr:`stop_reason` is set).
        """
        n, tuning, cache = self.n, self.tuning, self.cache
        clock = self._clock()
        self.iterations += 1
        remaining = max(self.sparsity - self.frequencies.size, self.rejected, 1)
        least = max(tuning.bins_floor * self.first_bins, tuning.bin_snr * self.sparsity / self.snr_linear)
        bins = choose_bins(self.usable, max(self.alpha * remaining, least))
        filt = self._filter(bins)
        shifts = hashing.shift_schedule(n, bins, self.phase_error, self.shift_ratio)
        if cache.count + hashing.window_cost(shifts, filt.half_width) >= self.dense_fraction * n:
            self._charge("support", clock)
            self.stop_reason = "dense"
            return False
        sigma, tau = random_coprime(self.rng, n), int(self.rng.integers(n))
        hashed = hashing.hash_to_bins(cache, n, filt, sigma, tau, shifts)
        self.hashes.append(hashed)
        residual = hashed.bins - hashing.model(n, hashed, self.frequencies, self.values)
        energy = np.mean(np.abs(residual) ** 2, axis=0)
        raw_energy = float(np.sum(np.abs(hashed.bins[0]) ** 2))
        self.history.append(float(np.sum(np.abs(residual[0]) ** 2) / max(raw_energy, 1e-300)))
        self.scale = max(self.scale, float(np.sqrt(np.max(np.mean(np.abs(hashed.bins) ** 2, axis=0)))))
        self.variance = min(self.variance, _noise_level(energy, tuning.noise_quantile) / filt.gain)
        if self.noisy:  # the noise share of the power of every sample read so far
            self.variance = min(self.variance, float(np.mean(np.abs(cache.values) ** 2)) / (1 + self.snr_linear))
        level = self.variance * filt.gain
        threshold = max(tuning.occupancy_factor * level, (tuning.relative_floor * self.scale) ** 2)
        occupied = np.flatnonzero(energy > threshold)
        if occupied.size == 0:
            self._charge("support", clock)
            self.stop_reason = "converged"
            return False
        permuted, amplitude, misfit, response = hashing.locate(n, hashed, residual, occupied)
        singleton = misfit <= (tuning.singleton_residual
                               + tuning.singleton_noise * level / np.maximum(energy[occupied], 1e-300))
        central = np.abs(response) >= tuning.minimum_response
        accept = singleton & central
        self.rejected = int(np.count_nonzero(~singleton & central))
        found = (pow(sigma, -1, n) * permuted[accept]) % n if n > 1 else permuted[accept]
        rotation = np.exp(2j * np.pi * ((found * tau) % n) / n)
        estimates = amplitude[accept] / (response[accept] * rotation)
        # one report per frequency: the bin where the filter response is largest
        order = np.lexsort((-np.abs(response[accept]), found))
        found, estimates = found[order], estimates[order]
        first = np.ones(found.size, dtype=bool)
        first[1:] = found[1:] != found[:-1]
        frequencies, values, added = _merge(self.frequencies, self.values, found[first], estimates[first])
        values, levels = _polish(n, self.hashes, frequencies, values, self.scale, tuning,
                                 rounds=tuning.detection_rounds, variance=self.variance)
        self.variance = min(self.variance, levels[-1] / filt.gain)
        significant = np.abs(values) ** 2 > max(levels[-1], (tuning.relative_floor * self.scale) ** 2)
        self.frequencies, self.values = frequencies[significant], values[significant]
        self.quiet = self.quiet + 1 if added == 0 else 0
        self._charge("support", clock)
        if self.frequencies.size >= self.sparsity and self.quiet >= 2:
            self.stop_reason = "stagnated"
            return False
        if self.iterations >= self.max_iterations:
            self.stop_reason = "max_iterations"
            return False
        return True

    def finalize(self):
        """Magnitude estimation (Algorithm 7) and the result record; the dense fallback when planned."""
        if self.dense_needed or self.stop_reason == "dense":
            return self._dense()
        n, cache = self.n, self.cache
        clock = self._clock()
        cache.phase = "magnitude"
        frequencies, values = self.frequencies, self.values
        if frequencies.size > self.sparsity:  # prune (Algorithm 3) before the final values
            keep = np.sort(np.argsort(-np.abs(values), kind="stable")[:self.sparsity])
            frequencies, values = frequencies[keep], values[keep]
        if frequencies.size:
            full = choose_bins(self.usable, self.alpha * frequencies.size)
            filt = self._filter(full)
            for _ in range(self.magnitude_hashes):
                if cache.count + filt.width >= self.dense_fraction * n:
                    break
                hashed = hashing.hash_to_bins(cache, n, filt, random_coprime(self.rng, n), int(self.rng.integers(n)),
                                              np.zeros(1, np.int64))
                self.hashes.append(hashed)
            large = [hashed for hashed in self.hashes if hashed.filter.bins >= full / 2]
            median = len(large) >= 3
            if median:  # Algorithm 7: each full-size hash estimates every coefficient from its own bin
                estimates = []
                for hashed in large:
                    where, weights = hashing.response(n, hashed, frequencies)
                    centre = hashed.filter.neighbours
                    residual = hashed.bins[0] - hashing.model(n, hashed, frequencies, values)[0]
                    estimates.append(values + residual[where[:, centre]] / weights[0, :, centre])
                estimates = np.array(estimates)
                values = np.median(estimates.real, axis=0) + 1j * np.median(estimates.imag, axis=0)
            values = _polish(n, self.hashes, frequencies, values, self.scale, self.tuning, robust_start=median,
                             variance=self.variance)[0]
        self.frequencies, self.values = frequencies, values
        self._charge("magnitude", clock)
        return self._result(self.stop_reason or "max_iterations")

    def run(self):
        """``setup``, ``step`` until detection stops, ``finalize``: the :class:`SparseFourierTransformResult`."""
        self.setup()
        if not self.dense_needed:
            while self.step():
                pass
        return self.finalize()
