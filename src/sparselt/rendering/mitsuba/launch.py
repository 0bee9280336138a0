"""The one seam every estimator's render goes through: where the seed enters and the samples are counted.

Each sampling or rendering entry point of
:class:`~sparselt.rendering.mitsuba.scene.MitsubaScene` (its PSS estimators
and Mitsuba's own integrators) hands its work to :func:`launch` as a
function of a 32-bit seed. :func:`launch` checks the caller's seed, folds it
to 32 bits (:func:`fold_seed`), adds the path samples the work traces to
every open :func:`count_samples`, and runs it.

Notes
-----
Mitsuba's samplers and the TEA hash that seeds every lane
(:mod:`sparselt.rendering.mitsuba.lanes`) take 32-bit seeds; nanobind
refuses a larger Python integer ("sample_tea_32(): incompatible function
arguments"). A method that derives seeds by arithmetic (``budget.seed +
7919``, ``seed * 1000 + pass``) may leave 32 bits, so the fold accepts
every non-negative integer.
"""

from __future__ import annotations

import contextlib
import dataclasses
import numbers

#: Seeds below this pass through :func:`fold_seed` unchanged.
SEED_LIMIT = 2**32
_MASK_64 = (1 << 64) - 1
_GOLDEN_GAMMA = 0x9E3779B97F4A7C15  # SplitMix64's increment: 2^64 / golden ratio


def _mix64(value):
    """SplitMix64's output function (Stafford's "Mix13"): a bijection of 64-bit integers with full avalanche."""
    value = ((value ^ (value >> 30)) * 0xBF58476D1CE4E5B9) & _MASK_64
    value = ((value ^ (value >> 27)) * 0x94D049BB133111EB) & _MASK_64
    return value ^ (value >> 31)


def fold_seed(seed):
    """The 32-bit seed the renderer uses for a caller's seed: any non-negative integer.

    Parameters
    ----------
    seed : int
        A non-negative integer of any size (NumPy integers included).

    Returns
    -------
    int
        ``seed`` itself when ``seed < 2**32`` (so every image rendered with
        such a seed is unchanged); otherwise a 32-bit hash of it.

    Raises
    ------
    TypeError
        ``seed`` is not an integer (a bool, a float, a string).
    ValueError
        ``seed`` is negative.

    Notes
    -----
    A seed ``s >= 2**32`` is cut into 64-bit words ``w_0, w_1, ...`` from
    the least significant one, and hashed as SplitMix64 would absorb them:
    ``h <- mix64((h XOR w_k) + gamma mod 2**64)`` from ``h = 0``, with
    ``gamma = 0x9E3779B97F4A7C15`` and ``mix64`` SplitMix64's output
    function; the fold is ``(h >> 32) XOR (h AND 0xFFFFFFFF)``. It is a pure
    function of ``s`` (the same on every machine and run). Distinct large
    seeds, and a large seed and a small one, share a 32-bit seed with
    probability about ``2**-32`` per pair, as any 32-bit seed must.

    References
    ----------
    G. L. Steele, D. Lea and C. H. Flood, "Fast splittable pseudorandom number
    generators", OOPSLA 2014 (SplitMix64); D. Stafford, "Better bit mixing"
    (2011), variant 13.
    """
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise TypeError(f"seed must be a non-negative integer, got {seed!r} ({type(seed).__name__})")
    seed = int(seed)
    if seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed}")
    if seed < SEED_LIMIT:
        return seed
    state = 0
    while seed:
        state = _mix64(((state ^ (seed & _MASK_64)) + _GOLDEN_GAMMA) & _MASK_64)
        seed >>= 64
    return (state >> 32) ^ (state & 0xFFFFFFFF)


@dataclasses.dataclass(eq=False)  # each count is its own: open blocks are told apart by identity
class SampleCount:
    """What the renderer drew while a :func:`count_samples` block was open.

    Attributes
    ----------
    path_samples : int
        Paths traced: one per PSS sample, base and offset paths alike, and
        every sample of Mitsuba's ``path`` integrator.
    feature_samples : int
        Samples of feature buffers (Mitsuba's ``aov`` integrator), which
        trace no path.
    """

    path_samples: int = 0
    feature_samples: int = 0


_open_counts = []


@contextlib.contextmanager
def count_samples():
    """Count every sample the renderer draws inside the ``with`` block; yields a :class:`SampleCount`.

    Blocks nest: an inner block's samples count in the outer one too.
    """
    count = SampleCount()
    _open_counts.append(count)
    try:
        yield count
    finally:
        _open_counts.remove(count)


def launch(work, seed, *, path_samples, feature_samples=0):
    """Run one estimator's render ``work(folded_seed)``: the seed folded, its samples counted.

    Parameters
    ----------
    work : callable
        Takes the 32-bit seed (:func:`fold_seed` of ``seed``) and runs the
        render (one or several Dr.Jit kernels); its result is returned.
    seed : int
        The caller's seed, any non-negative integer.
    path_samples, feature_samples : int
        Paths the render traces and feature-buffer samples it draws
        (:class:`SampleCount`).

    Raises
    ------
    TypeError, ValueError
        ``seed`` is not a non-negative integer (:func:`fold_seed`), before
        anything renders.
    """
    folded = fold_seed(seed)
    for count in _open_counts:
        count.path_samples += int(path_samples)
        count.feature_samples += int(feature_samples)
    return work(folded)
