"""The Sparse Fourier Transform on rendered path space (thesis 6.1) and the images it gives.

The thesis reduces the ``D``-dimensional transform of a gridded path-space
signal to a 1-D one by the rank-1 lattice ``x_j = (j g mod N) / N``,
``g = (1, s_0, s_0 s_1, ...)`` (eq. 6.1). The lattice point ``x_j`` lies in
the grid cell whose C-order index is ``j`` (its coordinate on axis ``d`` is
``(j mod P_d) / P_d`` with ``P_d = s_d s_{d+1} ...``, whose ``s_d``-cell is
the ``d``-th mixed-radix digit of ``j``): evaluating the lattice point as the
mean of jittered path samples inside its cell, as ``sparselt sample`` does,
makes the 1-D signal the C-order flattening of the cell-mean signal, and its
length-``N`` spectrum is what :func:`~sparselt.recovery.sft.sft` recovers.

:class:`CellOracle` is that oracle: it renders the requested cells in batches
(one Dr.Jit launch per batch, through ``MitsubaScene.sample_cells(cells=...)``,
with the same random numbers ``sample`` uses for those cells), keeps every
value it rendered, and counts every path sample once, split by the SFT phase
that asked for it (support detection or magnitude estimation).

:func:`lattice_image` integrates the recovered 1-D spectrum into the image
(chapter 4's convolution integration in the lattice order): the non-image
axes are the ``R = prod(shape[2:])`` least significant digits, so a pixel is
the mean of a run of ``R`` consecutive lattice samples, a box-car convolution
followed by decimation, computed from the ``K`` coefficients in
``O(K + P log P)`` for ``P`` pixels, exactly. (Mapping the lattice spectrum to
the grid spectrum with eq. 6.2 and integrating there would treat each cell's
value as sitting at the lattice point's sub-cell position, an extra
sub-pixel error for a cell-mean signal.)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..checks import check_integer, check_positive_finite
from ..fourier import fft
from .sample_cache import IndexedValues
from .result import RecoveryResult
from .sft import sft

DEFAULT_BATCH_SAMPLES = 1 << 22  # path samples per renderer launch
PHASES = ("support", "magnitude")


class CellOracle:
    """Cell means of a gridded signal, read cell by cell for the SFT, every sample counted once.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(cells) -> (means, nonfinite)`` for an int64 array of flat
        C-order cell indices: ``means`` of shape ``(m, 3)`` (RGB) and the count
        of NaN/infinite samples per cell. Each call draws ``spp`` path samples
        per cell.
    shape : tuple of int
        The signal grid.
    spp : int
        Path samples per cell (per lattice point).
    batch_cells : int, optional
        Most cells per ``evaluate`` call (default: 4M path samples per call).

    Attributes
    ----------
    sft_phase : str
        The SFT phase now reading ('support' or 'magnitude'); set by the SFT.
    cells_by_phase : dict
        Distinct cells rendered per phase.
    """

    def __init__(self, evaluate, shape, spp, *, batch_cells=None):
        if not callable(evaluate):
            raise TypeError(f"evaluate must be callable as evaluate(cells) -> (means, nonfinite), got {evaluate!r}")
        self.evaluate = evaluate
        self.shape = tuple(int(size) for size in shape)
        self.size = math.prod(self.shape)
        self.spp = check_integer("samples per lattice point", spp, 1)
        self.batch_cells = batch_cells or max(1, DEFAULT_BATCH_SAMPLES // self.spp)
        self.store = IndexedValues(self.size, (3,), np.float32)  # the renderer's precision; half the copies of float64
        self.sft_phase = "support"
        self.cells_by_phase = dict.fromkeys(PHASES, 0)
        self.nonfinite = 0
        self.launches = 0
        self.seconds = 0.0

    @property
    def cells(self):
        """Distinct cells rendered so far."""
        return int(self.store.count)

    @property
    def path_samples(self):
        """Path samples drawn so far (every one, once)."""
        return self.cells * self.spp

    def samples_by_phase(self):
        return {phase: count * self.spp for phase, count in self.cells_by_phase.items()}

    def read(self, indices):
        """RGB cell means at ``indices`` (flat cells, any order), rendering only the cells not read before."""
        indices = np.asarray(indices, dtype=np.int64)
        if indices.size and (indices.min() < 0 or indices.max() >= self.size):
            raise IndexError(f"cell indices must be in [0, {self.size}), got {indices.min()}..{indices.max()}")
        missing = self.store.missing(indices)
        if missing.size:
            start = time.perf_counter()
            rendered = np.empty((missing.size, 3), dtype=np.float32)
            for first in range(0, missing.size, self.batch_cells):
                batch = missing[first:first + self.batch_cells]
                means, nonfinite = self.evaluate(batch)
                means = np.asarray(means, dtype=np.float32)
                if means.shape != (batch.size, 3):
                    raise ValueError(f"evaluate returned means of shape {means.shape} for {batch.size} cells; "
                                     f"expected ({batch.size}, 3)")
                rendered[first:first + batch.size] = means
                self.nonfinite += int(np.sum(nonfinite))
                self.launches += 1
            self.seconds += time.perf_counter() - start
            self.store.add(missing, rendered)
            self.cells_by_phase[self.sft_phase if self.sft_phase in PHASES else "support"] += int(missing.size)
            if missing.size == indices.size:  # every cell asked for is new: missing holds them, sorted and distinct
                if missing.size < 2 or np.all(indices[1:] > indices[:-1]):  # ... in the order asked for
                    return rendered
        return self.store.get(indices)

    def channel(self, channel):
        """An SFT oracle reading one RGB channel (it tells this oracle its phase)."""
        return _ChannelOracle(self, channel)


class _ChannelOracle:
    def __init__(self, parent, channel):
        self.parent, self.channel = parent, channel

    @property
    def sft_phase(self):
        return self.parent.sft_phase

    @sft_phase.setter
    def sft_phase(self, phase):
        self.parent.sft_phase = phase

    def __call__(self, indices):
        return self.parent.read(indices)[:, self.channel]


@dataclass(frozen=True)
class PathSpaceReconstruction(RecoveryResult):
    """The SFT of a rendered signal, per RGB channel, and what it cost: a
    :class:`~sparselt.recovery.result.RecoveryResult` whose ``estimate`` is the
    spectra, ``samples`` the path samples drawn, ``iterations`` the detection
    hashes over the channels, ``stop_reason`` the channels' (comma-separated).

    Attributes
    ----------
    shape : tuple of int
        The signal grid.
    spectra : tuple of SparseFourier
        Per channel, the recovered spectrum of the C-order flattened cell-mean
        signal, shape ``(N,)``, ``numpy.fft.fft`` convention (the ``estimate``).
    results : list of SparseFourierTransformResult
        The SFT record of each channel.
    path_samples, support_samples, magnitude_samples : int
        Path samples drawn in all (every distinct cell once, times spp) and
        split by the phase that first asked for them.
    cells : int
        Distinct lattice points (cells) rendered.
    spp : int
        Path samples per lattice point.
    seconds : dict
        ``sampling`` (rendering the cells) and ``reconstruction`` (the SFT's own work).
    """

    shape: tuple = ()
    results: tuple = ()
    path_samples: int = 0
    support_samples: int = 0
    magnitude_samples: int = 0
    cells: int = 0
    spp: int = 0
    nonfinite: int = 0

    @property
    def spectra(self):
        """The recovered spectrum of each channel (the record's ``estimate``)."""
        return self.estimate

    def image(self):
        """The pixel values, ``(height, width, 3)`` float32 (see :func:`lattice_image`)."""
        return np.stack([lattice_image(spectrum, self.shape) for spectrum in self.spectra], axis=-1).astype(np.float32)

    def signal(self):
        """The reconstructed cell-mean signal, ``shape + (3,)`` float32 (materializes all ``N`` cells)."""
        channels = [np.real(spectrum.to_signal()).reshape(self.shape) for spectrum in self.spectra]
        return np.stack(channels, axis=-1).astype(np.float32)


def lattice_image(spectrum, shape):
    """Mean over the non-image axes of the signal whose C-order flattening has this 1-D spectrum.

    Parameters
    ----------
    spectrum : SparseFourier
        Shape ``(N,)``, ``N = prod(shape)``, ``numpy.fft.fft`` convention.
    shape : tuple of int
        The grid, image axes ``(width, height)`` first.

    Returns
    -------
    ndarray, shape (height, width), float64
        Real part of ``z[p] = 1/R sum_{r<R} y[p R + r]``, ``R = prod(shape[2:])``:
        with ``Z[q] = sum_{l = q mod P} Y[l] D(l)``, ``D(l) = sum_r exp(2 pi i l r / N)``
        (a geometric series), ``z = ifft_P(Z) / R^2``.
    """
    shape = tuple(int(size) for size in shape)
    size = math.prod(shape)
    if tuple(spectrum.shape) != (size,):
        raise ValueError(f"spectrum of shape {spectrum.shape} does not match the grid {shape} (N = {size})")
    pixels = shape[0] * shape[1]
    run = size // pixels
    frequencies = np.asarray(spectrum.indices, dtype=np.int64)
    values = np.asarray(spectrum.values, dtype=np.complex128)
    step = np.exp(2j * np.pi * frequencies / size)
    whole = np.exp(2j * np.pi * (frequencies % pixels) / pixels)  # = step ** run
    with np.errstate(divide="ignore", invalid="ignore"):
        series = np.where(np.abs(step - 1) > 1e-12, (whole - 1) / (step - 1), run)
    series = np.where((frequencies % pixels == 0) & (frequencies != 0), 0, series)
    folded = np.zeros(pixels, dtype=np.complex128)
    np.add.at(folded, frequencies % pixels, values * series)
    flat = fft.ifftn(folded).real / run**2
    return flat.reshape(shape[0], shape[1]).T.copy()


def sft_path_space(evaluate, shape, sparsity, spp, *, alpha=4.0, snr=10.0, seed=0, magnitude_hashes=None,
                   batch_cells=None, progress=None):
    """Sparse Fourier Transform of a rendered cell-mean signal, per RGB channel (thesis 6.1).

    Parameters
    ----------
    evaluate : callable
        ``evaluate(cells) -> (means (m, 3), nonfinite (m,))``: the renderer's
        cell means (``spp`` path samples each) at flat C-order cells.
    shape : tuple of int
        The grid; ``N = prod(shape) < 2**31``.
    sparsity : int
        ``K`` per channel (thesis: ``N / 10**4``).
    spp : int
        Path samples per lattice point.
    alpha, snr, magnitude_hashes :
        As :func:`~sparselt.recovery.sft.sft` (``snr`` in dB: every lattice
        value is a noisy Monte Carlo estimate, never exactly sparse).
    seed : int
        Seed of the SFT's hashing (the same for the three channels, so they
        read mostly the same cells).

    Returns
    -------
    PathSpaceReconstruction

    Raises
    ------
    ValueError
        Bad grid, ``K`` too large for the grid, ``spp <= 0``, ``alpha < 1``:
        before any sampling.
    """
    shape = tuple(shape)
    for size in shape:
        check_integer("every axis resolution", size, 1)
    if len(shape) < 2:
        raise ValueError(f"shape {shape} needs the two image-plane axes")
    size = math.prod(shape)
    if size >= 2**31:
        raise ValueError(f"the grid {shape} has {size} cells; the SFT supports at most 2**31 - 1")
    sparsity = check_integer("sparsity", sparsity, 1, size // 2)
    check_integer("samples per lattice point", spp, 1)
    alpha = check_positive_finite(alpha, "alpha")
    if alpha < 1:
        raise ValueError(f"alpha must be at least 1 (B = alpha K buckets), got {alpha}")
    oracle = CellOracle(evaluate, shape, spp, batch_cells=batch_cells)
    results, spectra = [], []
    start = time.perf_counter()
    for channel in range(3):
        result = sft(oracle.channel(channel), size, sparsity, alpha=alpha, snr=snr, seed=seed,
                     magnitude_hashes=magnitude_hashes)
        results.append(result)
        spectra.append(result.estimate)
        if progress is not None:
            progress(channel, oracle)
    total = time.perf_counter() - start
    by_phase = oracle.samples_by_phase()
    return PathSpaceReconstruction(
        estimate=tuple(spectra), iterations=sum(result.iterations for result in results),
        samples=oracle.path_samples, stop_reason=",".join(result.stop_reason for result in results),
        shape=shape, results=tuple(results), path_samples=oracle.path_samples,
        support_samples=by_phase["support"], magnitude_samples=by_phase["magnitude"], cells=oracle.cells, spp=spp,
        seconds={"sampling": oracle.seconds, "reconstruction": max(0.0, total - oracle.seconds)},
        nonfinite=oracle.nonfinite)


def lattice_spectrum(signal):
    """The exact 1-D spectrum of a gridded signal's C-order flattening (what the SFT approximates)."""
    return fft.fftn(np.asarray(signal).reshape(-1))


def largest_energy_fraction(signal, sparsity):
    """Share of the signal's energy (less the mean) in its ``sparsity`` largest lattice coefficients.

    How compressible a rendered signal is at its grid (issue 13): 1 for an
    exactly ``K``-sparse signal, about ``K / N`` for white noise.
    """
    spectrum = np.abs(lattice_spectrum(signal)) ** 2
    spectrum[0] = 0.0
    total = float(spectrum.sum())
    if total == 0:
        return 1.0
    largest = np.partition(spectrum, spectrum.size - sparsity)[spectrum.size - sparsity:]
    return float(largest.sum() / total)
