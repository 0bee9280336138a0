r"""The equal-time protocol: what "equal time" and "beats path tracing" mean in a comparison (thesis 8.1.1).

The thesis's question for its applications is whether a method gains image
quality *for the same computation time* (8.1.1). This module is the one place
that answers it, from a comparison's rows (one per method, spp and seed, each
with the median of its repeated timings):

1. **Path tracing's fits.** The baseline (``pt``) runs at a ladder of
   budgets. Its median time is fitted as :math:`t = a + b \cdot spp`
   (least squares over the ladder, relative residual reported), and its
   relMSE, per seed, as :math:`r = c / spp + f` (relative least squares,
   ``f >= 0``: the floor that the reference's own noise and any bias leave).
   PT's relMSE at time ``t`` is :math:`c / spp(t) + f` with
   :math:`spp(t) = (t - a) / b`, never a piecewise interpolation of noisy
   points; its SSIM at ``t`` is interpolated in log spp between its ladder's
   runs of the same seed. A time beyond the ladder has no value (nothing is
   extrapolated): the harness extends the ladder until it passes every
   method's time, within a cap.
2. **Ratios and intervals.** Per (method, spp): the mean relMSE over seeds
   and its 95% Student-t interval; the ratio of that mean to PT's mean relMSE
   at the same (per-seed median) times, with a 95% interval by the delta
   method on the log ratio (t quantile, ``n - 1`` degrees of freedom; the
   seeds are paired; SSIM as PT's over the method's, HDR-FLIP as the
   method's over PT's, so that below 1 is better for all three), widened by the timing's own uncertainty
   (:func:`timing_uncertainty`: PT read at the method's time divided and
   multiplied by ``1 + d``). Both relMSEs first lose the reference's own floor
   (``reference_relmse_floor``, from the spread of the reference's passes):
   the ratio is of ``relmse_debiased``. Where either is not above the floor
   the verdict is ``reference-limited``. The same for SSIM (PT's over the method's, so that
   below 1 is better for both).
3. **Verdict.** ``wins`` when the relMSE ratio's interval lies below 1,
   ``loses`` when above, ``within noise`` when it covers 1, ``one seed`` when
   there is no interval. Verdicts are per budget; sentences never average
   over budgets.
4. **Equal-quality speed-up.** PT's time to reach the method's mean relMSE
   (from the fits, seeds averaged), over the method's time; its interval from
   the relMSE interval. Where the method's relMSE is below PT's floor, PT
   cannot reach it: the speed-up is infinite.
5. **Bias.** Per (method, spp) over its seeds: the fraction of pixels that
   Welch's t-test against the reference finds biased, Benjamini-Hochberg at
   1% (:func:`bias_record`, :func:`sparselt.analysis.bias.pixel_bias_test`),
   and the luminance ratio's mean with its 95% Student-t interval.

References
----------
Thesis 8.1.1 (equal-time comparison), Figures 8.1 and 8.3. Bienaymé/delta
method for ratio intervals: Casella and Berger (2002), 5.5.4. Bias: Jung,
Hanika and Dachsbacher (2020), JCGT 9(2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..report.comparison_rows import group_mean, method_spp_groups

#: Two-sided 95% intervals.
CONFIDENCE = 0.95
#: A cell whose slowest repeat took more than this many times its fastest is flagged noisy.
NOISY_TIMING_RATIO = 1.5
VERDICTS = ("wins", "loses", "within noise", "one seed", "no PT value", "reference-limited")


def _t_quantile(degrees):
    """The two-sided 95% Student-t quantile (scipy's, exact)."""
    from scipy.stats import t

    return float(t.ppf(0.5 + CONFIDENCE / 2, degrees))


def mean_interval(values):
    """``(mean, low, high)``: the mean of ``values`` and its 95% Student-t interval (``nan`` bounds for one value)."""
    values = np.asarray(values, dtype=np.float64)
    mean = float(values.mean())
    if values.size < 2:
        return mean, math.nan, math.nan
    half = _t_quantile(values.size - 1) * float(values.std(ddof=1)) / math.sqrt(values.size)
    return mean, mean - half, mean + half


def ratio_interval(numerator, denominator):
    """Ratio of means of paired samples with its 95% delta-method interval on the log scale.

    ``var(log(mean x / mean y)) ~ var(x)/(n mean x^2) + var(y)/(n mean y^2)
    - 2 cov(x, y)/(n mean x mean y)``; the interval is
    ``exp(log ratio +- t_{n-1} sd)``. ``nan`` bounds for one pair.
    """
    x, y = np.asarray(numerator, np.float64), np.asarray(denominator, np.float64)
    ratio = float(x.mean() / y.mean())
    if x.size < 2 or not ratio > 0:
        return ratio, math.nan, math.nan
    covariance = np.cov(x, y, ddof=1)
    variance = (covariance[0, 0] / x.mean() ** 2 + covariance[1, 1] / y.mean() ** 2
                - 2 * covariance[0, 1] / (x.mean() * y.mean())) / x.size
    half = _t_quantile(x.size - 1) * math.sqrt(max(variance, 0.0))
    return ratio, ratio * math.exp(-half), ratio * math.exp(half)


def verdict(low, high):
    """``wins`` / ``loses`` / ``within noise`` / ``one seed`` from a ratio's interval (below 1 is better)."""
    if not (math.isfinite(low) and math.isfinite(high)):
        return "one seed"
    if high < 1:
        return "wins"
    if low > 1:
        return "loses"
    return "within noise"


@dataclass(frozen=True)
class BaselineFit:
    """Path tracing's time and relMSE against spp, fitted on its ladder (see the module docstring).

    Attributes
    ----------
    intercept, slope : float
        ``t = intercept + slope * spp`` (seconds).
    time_residual : float
        Root-mean-square relative residual of the time fit.
    relmse : dict
        ``{seed: (c, floor)}``: ``relMSE = c / spp + floor``.
    ssim, flip : dict
        ``{seed: [(spp, value), ...]}`` sorted by spp (``flip`` empty for rows without FLIP).
    spp_range : tuple of int
        The ladder's smallest and largest spp.
    reached_seconds, lowest_seconds : float
        The times the ladder covers: from its smallest rung's fitted or
        measured time, whichever is smaller, to its largest rung's, whichever
        is larger. Between a rung's fitted and measured times PT's values are
        those of the rung itself (its spp is clamped to the ladder): PT then
        had at least the method's time, which can only favour PT.
    """

    intercept: float
    slope: float
    time_residual: float
    relmse: dict
    ssim: dict
    spp_range: tuple
    reached_seconds: float
    lowest_seconds: float
    flip: dict = field(default_factory=dict)

    def spp_at(self, seconds):
        """PT's spp at ``seconds`` from the time fit, clamped to the ladder's range."""
        spp = (seconds - self.intercept) / self.slope
        return min(max(spp, self.spp_range[0]), self.spp_range[1])

    def seconds_at(self, spp):
        return self.intercept + self.slope * spp

    def covers(self, seconds):
        """Whether ``seconds`` lies within the ladder's times (no extrapolation at either end)."""
        return self.lowest_seconds * (1 - 1e-9) <= seconds <= self.reached_seconds * (1 + 1e-9)

    def relmse_at(self, seconds, seed):
        """PT's relMSE at ``seconds`` for ``seed`` (its own seed's fit); ``nan`` beyond the ladder."""
        if not self.covers(seconds) or seed not in self.relmse:
            return math.nan
        c, floor = self.relmse[seed]
        return c / self.spp_at(seconds) + floor

    def ssim_at(self, seconds, seed):
        """PT's SSIM at ``seconds``: interpolated in log spp on the seed's ladder."""
        return self._interpolated(self.ssim, seconds, seed)

    def flip_at(self, seconds, seed):
        """PT's FLIP at ``seconds``: interpolated in log spp on the seed's ladder."""
        return self._interpolated(self.flip, seconds, seed)

    def _interpolated(self, series, seconds, seed):
        if not self.covers(seconds) or seed not in series:
            return math.nan
        points = series[seed]
        spp = self.spp_at(seconds)
        return float(np.interp(math.log(spp), [math.log(p) for p, _ in points], [v for _, v in points]))

    def seconds_for_relmse(self, relmse):
        """PT's time to reach ``relmse`` with the seeds' mean fit; ``inf`` at or below its floor."""
        c = float(np.mean([value[0] for value in self.relmse.values()]))
        floor = float(np.mean([value[1] for value in self.relmse.values()]))
        if not relmse > floor:
            return math.inf
        return self.seconds_at(c / (relmse - floor))


def fit_relmse(spps, relmses):
    """``(c, floor)`` of ``relMSE = c / spp + floor`` by relative least squares, ``floor >= 0``, ``c >= 0``."""
    x = 1.0 / np.asarray(spps, np.float64)
    r = np.asarray(relmses, np.float64)
    design = np.stack([x / r, 1.0 / r], axis=1)
    if len(r) >= 2:
        (c, floor), *_ = np.linalg.lstsq(design, np.ones_like(r), rcond=None)
        if c >= 0 and floor >= 0:
            return float(c), float(floor)
    c = float(np.sum(x / r) / np.sum((x / r) ** 2))  # floor 0
    return max(c, 0.0), 0.0


def fit_time(spps, seconds):
    """``(a, b, residual)``: the Theil-Sen line ``t = a + b spp`` and its robust relative scale.

    ``b`` is the median of the slopes between every pair of rungs and ``a``
    the median of ``t - b spp`` (Sen 1968): one rung slowed by a busy
    machine moves a least-squares line (two demo runs measured PT at 40 spp
    at 0.40 s in one and 0.09 s in the other, and the least-squares
    intercept doubled), not these medians, up to about 29% of the rungs.
    ``residual`` is 1.4826 times the median absolute relative residual (the
    standard deviation's robust estimate), which such a rung does not
    inflate either. A non-increasing line falls back to ``t = b spp``.

    References
    ----------
    Sen, P. K. (1968). Estimates of the regression coefficient based on
    Kendall's tau. Journal of the American Statistical Association 63.
    """
    x, t = np.asarray(spps, np.float64), np.asarray(seconds, np.float64)
    first, second = np.triu_indices(x.size, k=1)
    distinct = x[second] != x[first]
    slope = float(np.median((t[second] - t[first])[distinct] / (x[second] - x[first])[distinct]))
    intercept = float(np.median(t - slope * x))
    if not slope > 0:  # a ladder too short or too noisy to show time growing with spp
        slope, intercept = float(np.median(t / x)), 0.0
    fitted = np.maximum(intercept + slope * x, 1e-12)
    residual = 1.4826 * float(np.median(np.abs(t - fitted) / fitted))
    return intercept, slope, residual


def fit_baseline(rows, baseline):
    """The :class:`BaselineFit` of the baseline's rows (at least two spp), or None.

    A rung's time is the median over seeds of its cells' (median) times; the
    line is :func:`fit_time`'s. Raises nothing; fewer than two budgets give
    None (no equal-time values).
    """
    pt = [row for row in rows if row["method"] == baseline]
    spps = sorted({row["spp"] for row in pt})
    if len(spps) < 2:
        return None
    times = [float(np.median([row["seconds_total"] for row in pt if row["spp"] == spp])) for spp in spps]
    intercept, slope, residual = fit_time(spps, times)
    relmse, ssim, flip = {}, {}, {}
    for seed in sorted({row["seed"] for row in pt}):
        seed_rows = sorted((row for row in pt if row["seed"] == seed), key=lambda row: row["spp"])
        if len(seed_rows) >= 2:
            relmse[seed] = fit_relmse([row["spp"] for row in seed_rows], [row["relmse"] for row in seed_rows])
            ssim[seed] = [(row["spp"], row["ssim"]) for row in seed_rows]
            if all("flip" in row for row in seed_rows):
                flip[seed] = [(row["spp"], row["flip"]) for row in seed_rows]
    # The ladder covers from its fastest to its slowest rung, measured or fitted, whichever reaches further.
    return BaselineFit(intercept=intercept, slope=slope, time_residual=residual, relmse=relmse,
                       ssim=ssim, flip=flip, spp_range=(spps[0], spps[-1]),
                       reached_seconds=max(intercept + slope * spps[-1], times[-1]),
                       lowest_seconds=min(intercept + slope * spps[0], times[0]))


def add_equal_time_columns(rows, *, baseline="pt"):
    """Add PT's quality at each row's time (``relmse_pt_equal_time``, ``ssim_pt_equal_time``); return the fit.

    Parameters
    ----------
    rows : list of dict
        A comparison's rows (``method``, ``spp``, ``seed``, ``seconds_total``,
        ``relmse``, ``ssim``); changed in place.
    baseline : str, optional
        The baseline method's name (the registry's, :func:`sparselt.methods.baseline_name`).

    Returns
    -------
    BaselineFit or None
        None when the baseline ran at fewer than two budgets.

    Notes
    -----
    The columns are ``''`` for the baseline's own rows, without a fit, and
    where the row's time lies beyond the baseline's ladder.
    """
    fit = fit_baseline(rows, baseline)
    for row in rows:
        row["relmse_pt_equal_time"] = row["ssim_pt_equal_time"] = row["flip_pt_equal_time"] = ""
        if row["method"] == baseline or fit is None:
            continue
        for quantity, value in (("relmse", fit.relmse_at(row["seconds_total"], row["seed"])),
                                ("ssim", fit.ssim_at(row["seconds_total"], row["seed"])),
                                ("flip", fit.flip_at(row["seconds_total"], row["seed"]))):
            if math.isfinite(value):
                row[f"{quantity}_pt_equal_time"] = value
    return fit


SUMMARY_COLUMNS = ("method", "spp", "seeds", "seconds_total", "seconds_total_min", "seconds_total_max",
                   "timing_noisy", "timing_uncertainty", "relmse", "relmse_ci_low", "relmse_ci_high", "relmse_pt_equal_time",
                   "relmse_ratio", "relmse_ratio_ci_low", "relmse_ratio_ci_high", "verdict", "ssim",
                   "ssim_pt_equal_time", "ssim_ratio", "ssim_ratio_ci_low", "ssim_ratio_ci_high", "ssim_verdict",
                   "flip", "flip_pt_equal_time", "flip_ratio", "flip_ratio_ci_low", "flip_ratio_ci_high",
                   "flip_verdict",
                   "speedup_equal_quality", "speedup_ci_low", "speedup_ci_high",
                   "luminance_ratio", "luminance_ratio_ci_low", "luminance_ratio_ci_high", "bias_fraction")


def summarize(rows, fit, *, baseline="pt"):
    """One record per (method, spp) with :data:`SUMMARY_COLUMNS` (``summary.csv``); also fills the rows'
    ``relmse_ratio``, ``verdict`` and ``speedup_equal_quality`` (their intervals only in the summary)."""
    summary = []
    for method, spp, group in method_spp_groups(rows):
        record = dict.fromkeys(SUMMARY_COLUMNS, "")  # every record has every column, in order
        record.update(method=method, spp=spp, seeds=len(group))
        record["seconds_total"] = group_mean(group, "seconds_total")
        record["seconds_total_min"] = min(row.get("seconds_total_min", row["seconds_total"]) for row in group)
        record["seconds_total_max"] = max(row.get("seconds_total_max", row["seconds_total"]) for row in group)
        record["timing_noisy"] = any(bool(row.get("timing_noisy")) for row in group)
        record["relmse"], record["relmse_ci_low"], record["relmse_ci_high"] = mean_interval(
            [row["relmse"] for row in group])
        record["ssim"] = group_mean(group, "ssim")
        record["flip"] = group_mean(group, "flip") if all("flip" in row for row in group) else ""
        if all(row.get("luminance_ratio") not in ("", None) for row in group):
            record["luminance_ratio"], record["luminance_ratio_ci_low"], record["luminance_ratio_ci_high"] = (
                mean_interval([row["luminance_ratio"] for row in group]))
        _compare_with_baseline(record, group, fit, method == baseline)
        summary.append(record)
        for row in group:
            floor = row.get("reference_relmse_floor", 0.0) or 0.0
            row["relmse_ratio"] = ((row["relmse"] - floor) / (row["relmse_pt_equal_time"] - floor)
                                   if row.get("relmse_pt_equal_time") not in ("", None) else "")
            row["verdict"] = record["verdict"]
            row["speedup_equal_quality"] = record["speedup_equal_quality"]
    return summary


def timing_uncertainty(group, fit):
    """The relative uncertainty of a cell's time: its repeats' spread and PT's time-fit residual, combined.

    ``d = sqrt(s^2 + e^2)``: ``s`` the largest half-range of the repeats
    relative to their median over the cell's seeds, ``e`` the root-mean-square
    relative residual of PT's ``a + b spp`` fit. Sub-second timings on shared
    machines move by tens of percent between runs; the seeds' spread alone
    does not see it.
    """
    spreads = [(row.get("seconds_total_max", row["seconds_total"]) - row.get("seconds_total_min", row["seconds_total"]))
               / (2 * row["seconds_total"]) for row in group if row["seconds_total"] > 0]
    spread = max(spreads, default=0.0)
    return float(math.hypot(spread, fit.time_residual))


def _compare_with_baseline(record, group, fit, is_baseline):
    empty = dict.fromkeys(("relmse_pt_equal_time", "relmse_ratio", "relmse_ratio_ci_low", "relmse_ratio_ci_high",
                           "ssim_pt_equal_time", "ssim_ratio", "ssim_ratio_ci_low", "ssim_ratio_ci_high",
                           "flip_pt_equal_time", "flip_ratio", "flip_ratio_ci_low", "flip_ratio_ci_high",
                           "speedup_equal_quality", "speedup_ci_low", "speedup_ci_high"), "")
    record.update(empty, verdict="baseline" if is_baseline else "no PT value", ssim_verdict="", flip_verdict="")
    if is_baseline or fit is None:
        return
    pt_relmse = [row.get("relmse_pt_equal_time") for row in group]
    pt_ssim = [row.get("ssim_pt_equal_time") for row in group]
    if any(value in ("", None) for value in pt_relmse):
        return
    record["relmse_pt_equal_time"] = float(np.mean(pt_relmse))
    floors = {row.get("reference_relmse_floor") or 0.0 for row in group}  # one reference per comparison
    if len(floors) != 1:
        raise ValueError(f"the seeds of {record.get('method')!r} at spp {record.get('spp')} were measured against "
                         f"references of different floors {sorted(floors)}; a comparison has one reference")
    floor = floors.pop()
    numerator = np.array([row["relmse"] for row in group]) - floor
    denominator = np.array(pt_relmse, dtype=np.float64) - floor
    if np.any(numerator <= 0) or np.any(denominator <= 0):
        # Within the reference's own noise: the debiased relMSE says nothing; no win or loss is claimed.
        record.update(relmse_ratio=float(np.mean(numerator) / np.mean(denominator)), verdict="reference-limited")
    else:
        ratio, low, high = ratio_interval(numerator, denominator)
        # The time is uncertain too: PT's value is read at the method's time t, which moves between runs. Read it
        # at t / (1 + d) and t (1 + d), d the timing uncertainty, and keep the wider bounds.
        spread = timing_uncertainty(group, fit)
        record["timing_uncertainty"] = spread
        if math.isfinite(low) and spread > 0:
            late = [fit.relmse_at(min(row["seconds_total"] * (1 + spread), fit.reached_seconds), row["seed"]) - floor
                    for row in group]
            early = [fit.relmse_at(max(row["seconds_total"] / (1 + spread), fit.lowest_seconds),
                                   row["seed"]) - floor for row in group]
            if all(value > 0 for value in early + late):
                low = min(low, ratio_interval(numerator, early)[1])
                high = max(high, ratio_interval(numerator, late)[2])
        record.update(relmse_ratio=ratio, relmse_ratio_ci_low=low, relmse_ratio_ci_high=high,
                      verdict=verdict(low, high))
    if not any(value in ("", None) for value in pt_ssim):
        record["ssim_pt_equal_time"] = float(np.mean(pt_ssim))
        ratio, low, high = ratio_interval(pt_ssim, [row["ssim"] for row in group])  # PT over method: < 1 is better
        record.update(ssim_ratio=ratio, ssim_ratio_ci_low=low, ssim_ratio_ci_high=high,
                      ssim_verdict=verdict(low, high))
    pt_flip = [row.get("flip_pt_equal_time") for row in group]
    if record["flip"] != "" and not any(value in ("", None) for value in pt_flip) and min(pt_flip) > 0:
        record["flip_pt_equal_time"] = float(np.mean(pt_flip))
        ratio, low, high = ratio_interval([row["flip"] for row in group], pt_flip)  # method over PT: < 1 is better
        record.update(flip_ratio=ratio, flip_ratio_ci_low=low, flip_ratio_ci_high=high,
                      flip_verdict=verdict(low, high))
    seconds = record["seconds_total"]
    record["speedup_equal_quality"] = fit.seconds_for_relmse(record["relmse"]) / seconds
    low, high = record["relmse_ci_low"], record["relmse_ci_high"]
    if math.isfinite(low) and math.isfinite(high):
        # A lower relMSE needs more PT time: the interval's bounds swap.
        record["speedup_ci_low"] = fit.seconds_for_relmse(high) / seconds
        record["speedup_ci_high"] = fit.seconds_for_relmse(max(low, 0.0)) / seconds


#: The bias test's level and multiple-comparison correction in every comparison (:func:`bias_record`).
BIAS_LEVEL = 0.01
BIAS_CORRECTION = "benjamini-hochberg"


def bias_record(rows, image_of, reference, reference_variance, reference_degrees_of_freedom):
    """The bias test of every (method, spp) with at least two seeds: ``compare.json``'s ``bias`` record.

    Parameters
    ----------
    rows : list of dict
        The comparison's rows (their ``method``, ``spp`` and ``seed``).
    image_of : callable
        ``image_of(row)``: the row's image, ``(height, width, 3)``.
    reference : ndarray
        The reference image.
    reference_variance : ndarray or None
        The per-pixel variance of the reference's mean; None (a reference of one pass) takes it as exact.
    reference_degrees_of_freedom : int or None
        Its passes minus 1; None with ``reference_variance`` None.

    Returns
    -------
    dict
        ``level``, ``correction``, ``reference_degrees_of_freedom`` and ``cells``: one
        ``{"method", "spp", "seeds", "bias_fraction"}`` per tested (method, spp).

    Notes
    -----
    :func:`sparselt.analysis.bias.pixel_bias_test` of the method's images over seeds against the reference:
    Welch's t-test per pixel, Benjamini-Hochberg at 1% (Jung et al. 2020, JCGT 9(2)).
    """
    from ..analysis.bias import pixel_bias_test

    cells = []
    for method, spp, group in method_spp_groups(rows):
        if len(group) < 2:
            continue
        result = pixel_bias_test(np.stack([image_of(row) for row in group]), reference, reference_variance,
                                 reference_degrees_of_freedom=reference_degrees_of_freedom, level=BIAS_LEVEL,
                                 correction=BIAS_CORRECTION)
        cells.append({"method": method, "spp": spp, "seeds": len(group), "bias_fraction": result.biased_fraction})
    return {"level": BIAS_LEVEL, "correction": BIAS_CORRECTION,
            "reference_degrees_of_freedom": reference_degrees_of_freedom, "cells": cells}


def add_bias_fractions(summary, record):
    """Fill the summary's ``bias_fraction`` from a :func:`bias_record` (None: a folder without one, left empty).

    A cell whose seeds changed since the record was made (a rerun that added seeds) is left empty.
    """
    if not record:
        return summary
    fractions = {(cell["method"], cell["spp"], cell["seeds"]): cell["bias_fraction"] for cell in record["cells"]}
    for entry in summary:
        entry["bias_fraction"] = fractions.get((entry["method"], entry["spp"], entry["seeds"]), "")
    return summary


__all__ = ["BIAS_CORRECTION", "BIAS_LEVEL", "CONFIDENCE", "NOISY_TIMING_RATIO", "SUMMARY_COLUMNS", "VERDICTS",
           "BaselineFit", "add_bias_fractions", "add_equal_time_columns", "bias_record", "fit_baseline",
           "fit_relmse", "fit_time", "mean_interval", "ratio_interval", "summarize", "timing_uncertainty", "verdict"]
