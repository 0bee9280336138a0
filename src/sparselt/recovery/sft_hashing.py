"""Hashing and location of the Sparse Fourier Transform (thesis 2.3.3-2.3.5, Algorithms 5-6).

One hash permutes the spectrum (``sigma``, ``tau``), windows the permuted
samples with a flat filter and folds them into ``B`` bins at several time
shifts (:func:`hash_to_bins`); :func:`response` and :func:`model` give the
exact contribution of known coefficients to its bins through the filter's
response; :func:`locate` recovers the frequency of an occupied bin from the
phase differences between shifts (:func:`shift_schedule`). The driver that
chains them is :class:`sparselt.recovery.sft.SparseFourierTransform`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..fourier import fft
from .sft_filters import Filter

def windows(shifts, half_width):
    """Merge the windows ``[s - h, s + h]``: the offsets to read and each window's start in them."""
    starts = shifts - half_width
    ends = shifts + half_width + 1
    offsets, first = [], np.empty(shifts.size, dtype=np.int64)
    total = 0
    block_start, block_end = starts[0], ends[0]
    members = [0]
    for index in range(1, shifts.size):
        if starts[index] <= block_end:
            block_end = max(block_end, ends[index])
            members.append(index)
            continue
        offsets.append(np.arange(block_start, block_end))
        for member in members:
            first[member] = total + starts[member] - block_start
        total += block_end - block_start
        block_start, block_end, members = starts[index], ends[index], [index]
    offsets.append(np.arange(block_start, block_end))
    for member in members:
        first[member] = total + starts[member] - block_start
    return np.concatenate(offsets), first


def window_cost(shifts, half_width):
    return int(windows(np.asarray(shifts, dtype=np.int64), half_width)[0].size)


@dataclass
class Hash:
    """One hash read: its permutation, filter, shifts and ``(S, B)`` bins (in coefficient units)."""

    sigma: int
    tau: int
    filter: Filter
    shifts: np.ndarray
    bins: np.ndarray


def hash_to_bins(cache, n, filt, sigma, tau, shifts):
    """HashToBins (Algorithm 5) at every shift: ``(S, B)`` bins from the samples of one permutation."""
    shifts = np.asarray(shifts, dtype=np.int64)
    offsets, first = windows(shifts, filt.half_width)
    values = cache.read((sigma * offsets + tau) % n)
    width, bins = filt.width, filt.bins
    rows = values[first[:, None] + np.arange(width)[None, :]] * filt.taps
    start = (-filt.half_width) % bins
    padded = -(-(start + width) // bins) * bins
    buffer = np.zeros((shifts.size, padded), dtype=np.complex128)
    buffer[:, start:start + width] = rows
    folded = buffer.reshape(shifts.size, padded // bins, bins).sum(axis=1)
    return Hash(sigma, tau, filt, shifts, fft.fftn(folded, axes=(1,)))


def response(n, hashed, frequencies):
    """Where the frequencies land in a hash: bins ``(K, 2D+1)`` and weights ``(S, K, 2D+1)``.

    ``hashed.bins[s, bins[k, i]] += X[f_k] * weights[s, k, i]`` is the exact
    contribution of ``f_k`` (to the filter's ``leakage`` level); the centre
    column ``i = D`` is the bin nearest ``f_k``.
    """
    filt = hashed.filter
    frequencies = np.asarray(frequencies, dtype=np.int64)
    permuted = (hashed.sigma * frequencies) % n
    step = n // filt.bins
    centre = (permuted + step // 2) // step
    around = centre[:, None] + np.arange(-filt.neighbours, filt.neighbours + 1)[None, :]
    offset = around * step - permuted[:, None]
    table = filt.response(offset)
    rotation = np.exp(2j * np.pi * ((frequencies * hashed.tau) % n) / n)
    shift_phase = np.exp(2j * np.pi * ((permuted[None, :] * hashed.shifts[:, None]) % n) / n)
    weights = (rotation[None, :] * shift_phase)[:, :, None] * table[None, :, :]
    return around % filt.bins, weights


def model(n, hashed, frequencies, values):
    """Bins of the hash that the coefficients ``values`` at ``frequencies`` would produce."""
    bins_count = hashed.filter.bins
    shifts = hashed.shifts.size
    model = np.zeros((shifts, bins_count), dtype=np.complex128)
    if len(frequencies) == 0:
        return model
    where, weights = response(n, hashed, frequencies)
    contributions = weights * values[None, :, None]
    flat = (np.arange(shifts)[:, None, None] * bins_count + where[None, :, :]).ravel()
    size = shifts * bins_count
    model += (np.bincount(flat, contributions.real.ravel(), size)
              + 1j * np.bincount(flat, contributions.imag.ravel(), size)).reshape(shifts, bins_count)
    return model


def shift_schedule(n, bins, phase_error, ratio):
    """Shifts ``0, s_1, s_1 r, ...``: the bin fixes ``p`` to ``+- n/B``, each shift refines it ``r`` times."""
    shifts = [0]
    shift = max(1, bins // 4)
    target = min(n / 2, 3 * phase_error * n / math.pi)  # last estimate within 1/6 of an integer
    while True:
        shifts.append(shift)
        if shift >= target:
            break
        shift = int(min(shift * ratio, max(math.ceil(target), 2 * shift)))
    return np.array(shifts, dtype=np.int64)


def locate(n, hashed, residual, occupied):
    """Frequencies of the occupied bins by phase shifts, with their values and a singleton test."""
    filt = hashed.filter
    step = n // filt.bins
    u = residual[:, occupied]
    estimate = occupied.astype(np.float64) * step  # bin centres: p to +- n/B
    reference = u[0]
    for level in range(1, hashed.shifts.size):
        shift = float(hashed.shifts[level])
        fraction = np.angle(u[level] * np.conj(reference)) / (2 * np.pi)
        wraps = np.round(estimate * shift / n - fraction)
        estimate = (fraction + wraps) * n / shift
    permuted = np.round(estimate).astype(np.int64) % n
    phases = np.exp(2j * np.pi * ((permuted[None, :] * hashed.shifts[:, None]) % n) / n)
    amplitude = np.mean(u * np.conj(phases), axis=0)
    misfit = np.max(np.abs(u - amplitude[None, :] * phases) ** 2, axis=0)
    misfit /= np.maximum(np.mean(np.abs(u) ** 2, axis=0), 1e-300)
    offset = occupied * step - permuted
    offset = (offset + n // 2) % n - n // 2
    return permuted, amplitude, misfit, filt.response(offset)
