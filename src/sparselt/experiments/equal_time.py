"""Path tracing's quality at each run's time: the equal-time columns of a comparison (thesis 8.1.1).

The thesis's question for its applications is whether a method gains image
quality *for the same computation time* (8.1.1). A comparison runs path
tracing (``pt``) at several budgets; :func:`add_equal_time_columns` gives
every other run the relMSE and SSIM path tracing reaches at that run's total
time, interpolated between PT's measured budgets and never extrapolated.

References
----------
Thesis section 8.1.1 (equal-time comparison), Figures 8.1 and 8.3.
"""

from __future__ import annotations

import numpy as np

from ..report.comparison_rows import mean_curve


def add_equal_time_columns(rows, *, baseline="pt"):
    """Add ``relmse_pt_equal_time`` and ``ssim_pt_equal_time`` to every row: PT's quality at the row's time.

    Parameters
    ----------
    rows : list of dict
        A comparison's rows (``method``, ``spp``, ``seconds_total``,
        ``relmse``, ``ssim``); changed in place.
    baseline : str, optional
        The baseline method's name (the registry's, :func:`sparselt.methods.baseline_name`).

    Notes
    -----
    PT's runs are first averaged over seeds per spp
    (:func:`~sparselt.report.comparison_rows.mean_curve`). relMSE is
    interpolated log-log (relMSE ~ 1/time for an unbiased estimator), SSIM
    against log time. The columns are ``''`` for PT's own rows, where PT ran
    at fewer than two budgets, and where the row's time lies outside PT's
    measured range: nothing is extrapolated.
    """
    curves = {quantity: mean_curve([row for row in rows if row["method"] == baseline], quantity)
              for quantity in ("relmse", "ssim")}
    for row in rows:
        for quantity, curve in curves.items():
            key = f"{quantity}_pt_equal_time"
            row[key] = ""
            if row["method"] == baseline or len(curve) < 2:
                continue
            times, values = zip(*curve)
            time = row["seconds_total"]
            if times[0] <= time <= times[-1]:
                if quantity == "relmse":
                    row[key] = float(np.exp(np.interp(np.log(time), np.log(times), np.log(values))))
                else:
                    row[key] = float(np.interp(np.log(time), np.log(times), values))


__all__ = ["add_equal_time_columns"]
