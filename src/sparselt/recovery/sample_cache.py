"""Values read at distinct indices of a long signal, looked up in O(1): the SFT's sample caches.

The Sparse Fourier Transform reads a few percent of a signal of up to 2^31
entries, one hash at a time, and must never read an index twice (the oracle is
a renderer: every read costs path samples). :class:`IndexedValues` keeps the
values in the order they were read. Up to :data:`DENSE_LIMIT` entries it also
keeps an ``int32`` slot per signal index (``0`` = not read, else position + 1),
so looking up and adding ``m`` indices costs ``O(m)`` however many were read
before. Beyond that a dense table would cost ``O(n)`` memory traffic (a
sparse read of a 6.5e8-cell signal touches most of its pages), so the read
indices are kept sorted instead: ``O(m log m)`` lookups and an ``O(count)``
merge per added batch, which the SFT makes once per hash.
"""

from __future__ import annotations

import numpy as np

from .. import kernels

#: Largest signal given a dense slot table (256 MB of int32).
DENSE_LIMIT = 1 << 26


class IndexedValues:
    """Values at distinct indices of ``[0, size)``.

    Parameters
    ----------
    size : int
        Signal length (below ``2**31``).
    value_shape : tuple of int
        Shape of one value (``()`` for scalars, ``(3,)`` for RGB).
    dtype : numpy dtype
        Type of the values.
    """

    def __init__(self, size, value_shape=(), dtype=np.complex128):
        self.size = int(size)
        self.dense = self.size <= DENSE_LIMIT
        self._slots = np.zeros(self.size if self.dense else 0, dtype=np.int32)
        self._sorted = np.zeros(0, dtype=np.int64)  # sparse mode: read indices, sorted ...
        self._positions = np.zeros(0, dtype=np.int64)  # ... and where their values are
        self._values = np.zeros((16,) + tuple(value_shape), dtype=dtype)
        self._indices = np.zeros(16, dtype=np.int64)
        self.count = 0

    @property
    def values(self):
        """Every value read, in reading order."""
        return self._values[:self.count]

    @property
    def indices(self):
        """Every index read, in reading order."""
        return self._indices[:self.count]

    def missing(self, indices):
        """The distinct indices among ``indices`` not read yet, sorted."""
        indices = np.asarray(indices, dtype=np.int64)
        if self.dense:
            return _distinct_sorted(kernels.unnumbered(self._slots, np.ascontiguousarray(indices)))
        if not self._sorted.size:
            return _distinct_sorted(indices)
        where = np.minimum(np.searchsorted(self._sorted, indices), self._sorted.size - 1)
        return _distinct_sorted(indices[self._sorted[where] != indices])

    def add(self, indices, values):
        """Record ``values`` at new, distinct, sorted ``indices``."""
        indices = np.asarray(indices, dtype=np.int64)
        needed = self.count + indices.size
        if needed > self._indices.size:
            capacity = max(needed, 2 * self._indices.size)
            grown = np.empty((capacity,) + self._values.shape[1:], self._values.dtype)  # only [:count] is ever read
            grown[:self.count] = self._values[:self.count]
            self._values = grown
            grown = np.empty(capacity, np.int64)
            grown[:self.count] = self._indices[:self.count]
            self._indices = grown
        self._values[self.count:needed] = values
        self._indices[self.count:needed] = indices
        if self.dense:
            kernels.number_slots(self._slots, np.ascontiguousarray(indices), self.count)
        else:
            positions = np.arange(self.count, needed, dtype=np.int64)
            insert_at = np.searchsorted(self._sorted, indices)
            self._sorted = np.insert(self._sorted, insert_at, indices)
            self._positions = np.insert(self._positions, insert_at, positions)
        self.count = needed

    def get(self, indices):
        """Values at ``indices``, all of which were read."""
        indices = np.asarray(indices, dtype=np.int64)
        if self.dense:
            return kernels.gather_slotted(self._values, self._slots, np.ascontiguousarray(indices))
        return self._values[self._positions[np.searchsorted(self._sorted, indices)]]


def _distinct_sorted(values):
    """``numpy.unique`` by sorting (NumPy 2's hash-based unique is ~10x slower on millions of int64),
    free when the values are already strictly increasing (what the SFT asks for)."""
    if values.size < 2:
        return values.copy()
    if np.all(values[1:] > values[:-1]):
        return values.copy()
    ordered = np.sort(values)
    keep = np.empty(ordered.size, dtype=bool)
    keep[0] = True
    np.not_equal(ordered[1:], ordered[:-1], out=keep[1:])
    return ordered[keep]
