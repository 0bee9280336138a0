"""Hermitian (conjugate-pair) bookkeeping and the one top-K rule, for every caller.

The spectrum of a real signal is Hermitian: ``c(-k) = conj(c(k))``. Entry
``k`` and its *partner* ``-k mod shape`` have equal energy and must be kept or
dropped together, or the kept coefficients no longer describe a real signal.
Entries equal to their own partner (``k = -k``: the zero frequency and, along
even axes, the Nyquist frequencies) are *self-conjugate* and stand alone.

**The top-K rule** (:func:`keep_within`, :func:`largest_closed`): rank the
groups (a pair, or one self-conjugate entry) by energy, highest first, ties by
the smaller flat index; keep groups in that order while the number of kept
entries stays at most ``K``. The result has ``K`` entries, or ``K - 1`` when
the next group is a pair that would overshoot (an odd ``K`` after pairs, say):
it never exceeds ``K`` and never splits a pair. :meth:`SparseFourier.largest`,
:func:`sparselt.analysis.threshold.largest_coefficients` and CoSaMP's
selection (on half-spectrum entries that count 1 or 2) all apply it.
"""

from __future__ import annotations

import numpy as np


def partner_indices(shape, indices):
    """Flat index of ``-k mod shape`` for each flat index ``k`` (the Hermitian partner)."""
    from .sparse import check_shape

    shape = check_shape(shape)
    coordinates = np.unravel_index(np.asarray(indices, dtype=np.int64), shape)
    negated = tuple((-coordinate) % size for coordinate, size in zip(coordinates, shape))
    return np.ravel_multi_index(negated, shape).astype(np.int64)


def keep_within(ranked_counts, budget):
    """Mask of the ranked groups kept by the top-K rule: cumulative entry count at most ``budget``.

    ``ranked_counts`` holds the number of entries (1 or 2) of each group, best
    group first.
    """
    return np.cumsum(ranked_counts) <= budget


def largest_closed(energy, count, shape, indices=None):
    """Flat indices (sorted) of the entries the top-K rule keeps.

    Parameters
    ----------
    energy : ndarray
        Energy of each entry (of the full spectrum, or of the entries at ``indices``).
    count : int
        ``K``, at least 0.
    shape : tuple of int
        Shape of the full spectrum.
    indices : ndarray of int, optional
        Flat spectrum index of each entry of ``energy`` (default: every entry,
        in order). The partner of every listed entry must be listed too.

    Returns
    -------
    ndarray of int64
        ``K`` or ``K - 1`` flat indices (all of them when ``K`` reaches the
        number of entries), closed under the partner map.
    """
    energy = np.asarray(energy, dtype=np.float64).reshape(-1)
    count = int(count)
    if count < 0:
        raise ValueError(f"count must be non-negative, got {count}")
    flat = np.arange(energy.size, dtype=np.int64) if indices is None else np.asarray(indices, dtype=np.int64)
    if count >= flat.size:
        return np.sort(flat)
    # Candidates: the count + 1 most energetic entries and their partners hold every group the rule keeps.
    take = min(flat.size, count + 1)
    candidates = np.argpartition(energy, flat.size - take)[flat.size - take:]
    positions = np.argsort(flat, kind="stable")
    partners = partner_indices(shape, flat[candidates])
    partner_positions = positions[np.searchsorted(flat[positions], partners)]
    candidates = np.union1d(candidates, partner_positions)
    members = flat[candidates]
    groups = np.minimum(members, partner_indices(shape, members))
    unique_groups, first, sizes = np.unique(groups, return_index=True, return_counts=True)
    group_energy = np.zeros(unique_groups.size)
    np.maximum.at(group_energy, np.searchsorted(unique_groups, groups), energy[candidates])
    order = np.lexsort((unique_groups, -group_energy))
    kept = unique_groups[order][keep_within(sizes[order], count)]
    return np.sort(members[np.isin(groups, kept)])


def real_fft_multiplicity(size, kept):
    """How many full-spectrum entries each frequency ``0 .. kept - 1`` of a real FFT of length ``size`` stands for.

    Frequencies ``j`` and ``size - j`` are partners (2); ``j = 0`` and, for an
    even size, ``j = size / 2`` are self-conjugate (1).
    """
    index = np.arange(kept)
    self_conjugate = (index == 0) | ((size % 2 == 0) & (2 * index == size))
    return np.where(self_conjugate, 1, 2).astype(np.uint8)
