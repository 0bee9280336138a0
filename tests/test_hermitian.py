"""The one Hermitian top-K rule (sparselt.fourier.hermitian), stated and tested once for every caller."""

import numpy as np
import pytest

from sparselt.analysis.threshold import largest_coefficients
from sparselt.fourier import fft
from sparselt.fourier.hermitian import keep_within, largest_closed, partner_indices
from sparselt.fourier.sparse import SparseFourier


def test_rule_keeps_whole_groups_in_rank_order_up_to_k():
    # groups ranked: pair (2), self-conjugate (1), pair (2), self-conjugate (1)
    ranked = np.array([2, 1, 2, 1])
    assert keep_within(ranked, 3).tolist() == [True, True, False, False]  # exactly K
    assert keep_within(ranked, 4).tolist() == [True, True, False, False]  # K - 1: the next pair would overshoot
    assert keep_within(ranked, 1).tolist() == [False, False, False, False]  # never a lower group before a higher one
    assert keep_within(ranked, 6).tolist() == [True, True, True, True]


@pytest.mark.parametrize("shape", [(8, 6, 5), (7, 7), (16,)])
@pytest.mark.parametrize("count", [1, 2, 3, 8, 25])
def test_every_caller_gives_the_same_support(shape, count):
    rng = np.random.default_rng(sum(shape) + count)
    signal = rng.random(shape) + 0.5
    spectrum = fft.fftn(signal)
    from_spectrum = largest_coefficients(spectrum, count)
    from_representation = SparseFourier.from_signal(signal).largest(count).indices
    np.testing.assert_array_equal(from_spectrum, from_representation)
    assert from_spectrum.size in (min(count, signal.size), count - 1)
    assert set(partner_indices(shape, from_spectrum)) == set(from_spectrum)


def test_cosamp_selection_uses_the_same_rule():
    """CoSaMP's half-spectrum selection: its kept full-spectrum coefficients follow the rule."""
    from sparselt.operators import PartialFourier
    from sparselt.recovery.cosamp import _largest

    shape = (8, 6)
    operator = PartialFourier(shape, np.arange(48), dtype=np.float64)
    rng = np.random.default_rng(5)
    spectrum = operator.transform_samples(rng.random(48) + 0.5)
    energy = operator.proxy_energy(spectrum).copy()
    for budget in (1, 4, 7, 12):
        chosen = _largest(energy, budget, operator)
        counts = operator.coefficient_counts(chosen)
        assert counts.sum() <= budget and counts.sum() >= budget - 1


def test_largest_closed_on_a_subset_and_bad_count():
    shape = (6,)
    indices = np.array([0, 1, 5, 2, 4])  # pairs (1, 5), (2, 4) and the zero frequency
    energy = np.array([1.0, 3.0, 3.0, 2.0, 2.0])
    assert largest_closed(energy, 2, shape, indices=indices).tolist() == [1, 5]
    assert largest_closed(energy, 3, shape, indices=indices).tolist() == [1, 5]  # (2, 4) would overshoot: stop
    assert largest_closed(energy, 4, shape, indices=indices).tolist() == [1, 2, 4, 5]
    assert largest_closed(energy, 5, shape, indices=indices).tolist() == [0, 1, 2, 4, 5]
    with pytest.raises(ValueError, match="non-negative"):
        largest_closed(energy, -1, shape, indices=indices)
