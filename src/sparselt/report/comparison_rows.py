"""A comparison's rows, grouped: what every report of ``sparselt compare`` averages over (thesis 8.1.1).

A row is one ``(method, spp, seed)`` cell of an equal-time comparison, a
plain dict with at least :data:`RESULT_COLUMNS`. The reports show means over
seeds per ``(method, spp)``; the helpers here are the one place that groups
and averages them. Plain Python and NumPy: nothing from ``experiments/``.
"""

from __future__ import annotations

import math

import numpy as np

#: The columns every row has, in ``results.csv``'s order.
RESULT_COLUMNS = ("method", "spp", "seed", "seconds_total", "seconds_sampling", "seconds_reconstruction",
                  "seconds_integration", "seconds_other", "path_samples", "ssim", "relmse", "luminance_ratio")
#: Columns after :data:`RESULT_COLUMNS`: the contrast ratio, PT's quality at the row's time, the repeated
#: timings and the row's (method, spp) verdict (the equal-time protocol, :mod:`sparselt.experiments.equal_time`).
EXTRA_COLUMNS = ("contrast_ratio", "flip", "relmse_pt_equal_time", "ssim_pt_equal_time", "flip_pt_equal_time",
                 "seconds_total_min",
                 "seconds_total_max", "timing_repeats", "timing_noisy", "relmse_ratio", "verdict",
                 "speedup_equal_quality")
#: ``results.csv``'s column order; any other key of the rows follows, sorted.
COLUMN_ORDER = RESULT_COLUMNS + EXTRA_COLUMNS


def baseline_of(methods):
    """The baseline's name among a comparison's method records (``{name: {'baseline': ...}}``), or None."""
    return next((name for name, record in methods.items() if record.get("baseline")), None)


def in_family(methods, family):
    """The names of the method records of ``family`` ('cosamp', 'guided', ...)."""
    return {name for name, record in methods.items() if record.get("family") == family}


def methods_in_order(rows):
    """The rows' methods, in order of first appearance."""
    return list(dict.fromkeys(row["method"] for row in rows))


def in_comparison_order(rows, methods):
    """The rows sorted as a comparison holds them: by ``methods`` (the baseline first, then the configured
    methods; any other after them, by name), then seed, then spp; a new list."""
    order = {name: index for index, name in enumerate(methods)}
    return sorted(rows, key=lambda row: (order.get(row["method"], len(order)), row["method"], row["seed"], row["spp"]))


def method_spp_groups(rows):
    """``(method, spp, rows)`` per comparison cell (its rows over seeds, by seed): methods as first seen, spp
    ascending. The one grouping of a comparison's rows (the summary, the bias test, the reports)."""
    groups = {}
    for row in rows:
        groups.setdefault(row["method"], {}).setdefault(row["spp"], []).append(row)
    for method, budgets in groups.items():
        for spp in sorted(budgets):
            yield method, spp, sorted(budgets[spp], key=lambda row: row["seed"])


def group_mean(group, key):
    """Mean of ``key`` over a cell's rows (its seeds)."""
    return float(np.mean([row[key] for row in group]))


def mean_curve(rows, quantity):
    """``[(mean seconds, mean quantity)]`` per spp of one method's rows (means over seeds), sorted by time."""
    by_spp = {}
    for row in rows:
        by_spp.setdefault(row["spp"], []).append(row)
    curve = [(group_mean(group, "seconds_total"), group_mean(group, quantity)) for group in by_spp.values()]
    return sorted(curve)


def matched_rows(rows):
    """One row per method, at matched time (the layout of thesis Figures 8.2/8.4).

    The target is the earliest time at which every method has an image: the
    largest over methods of each method's shortest run. Each method shows its
    run closest to it in log time, at the smallest seed (chosen by its value,
    never by a row's position: the rows may come in any order).

    Returns
    -------
    matched : list of dict
        One row per method, methods in order of first appearance.
    target : float
        The matched time (seconds).
    """
    if not rows:
        raise ValueError("matched_rows needs at least one row")
    methods = methods_in_order(rows)
    seed = min(row["seed"] for row in rows)
    chosen = [row for row in rows if row["seed"] == seed]
    target = max(min(row["seconds_total"] for row in chosen if row["method"] == method) for method in methods)
    matched = []
    for method in methods:
        candidates = [row for row in chosen if row["method"] == method]
        matched.append(min(candidates, key=lambda row: abs(math.log(row["seconds_total"] / target))))
    return matched, target


__all__ = ["COLUMN_ORDER", "EXTRA_COLUMNS", "RESULT_COLUMNS", "baseline_of", "group_mean", "in_comparison_order", "in_family", "matched_rows", "mean_curve",
           "method_spp_groups", "methods_in_order"]
