"""One p-value helper for every statistical test (model: Mitsuba 3's ``chi2.py``)."""

from __future__ import annotations

import numpy as np
from scipy import stats

SIGNIFICANCE = 0.01


def chi_square_p_value(observed, expected, *, minimum_expected=5.0):
    """Pearson chi-square goodness-of-fit p-value; cells expecting fewer than ``minimum_expected`` are pooled.

    As Mitsuba's ``chi2.py``: sort cells by expected count, pool the smallest
    until the pool reaches the minimum, and test the rest cell by cell.
    """
    observed = np.asarray(observed, dtype=np.float64).ravel()
    expected = np.asarray(expected, dtype=np.float64).ravel()
    order = np.argsort(expected)
    observed, expected = observed[order], expected[order]
    pooled_expected = pooled_observed = 0.0
    start = 0
    while start < expected.size and (pooled_expected < minimum_expected or expected[start] < minimum_expected):
        if pooled_expected >= minimum_expected and expected[start] >= minimum_expected:
            break
        pooled_expected += expected[start]
        pooled_observed += observed[start]
        start += 1
    bins_expected = np.concatenate([[pooled_expected], expected[start:]]) if pooled_expected > 0 else expected[start:]
    bins_observed = np.concatenate([[pooled_observed], observed[start:]]) if pooled_expected > 0 else observed[start:]
    statistic = float(np.sum((bins_observed - bins_expected) ** 2 / bins_expected))
    degrees = bins_expected.size - 1
    return float(stats.chi2.sf(statistic, degrees)) if degrees > 0 else 1.0


def sidak_threshold(tests, significance=SIGNIFICANCE):
    """Per-test significance so that ``tests`` independent tests together keep ``significance`` (Sidak)."""
    return 1.0 - (1.0 - significance) ** (1.0 / tests)
