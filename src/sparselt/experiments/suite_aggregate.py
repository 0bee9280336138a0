"""A suite's summary across scenes: geometric means of speed-ups and relMSE ratios with bootstrap intervals.

Papers summarise a method over a suite of scenes by one number per budget.
sparselt gives, per (method, spp), the geometric mean over scenes of the
equal-quality speed-up over PT and of the relMSE ratio at equal time (the
comparison's headline metric, :mod:`sparselt.experiments.equal_time`), each
with a 95% interval from a two-level bootstrap: scenes resampled with
replacement (Davison & Hinkley 1997, 2.4, the hierarchical bootstrap), then
each chosen scene's ratio drawn from the distribution its comparison's own
interval states (a Student-t of ``n - 1`` degrees of freedom over its ``n``
seeds, scaled so that its 2.5% and 97.5% points are that interval's bounds,
which hold the seeds' spread, the time's uncertainty and PT's correction's: a
parametric bootstrap, Davison & Hinkley 1997, 2.2), every draw mapped to a
speed-up through that scene's own PT fits
(:func:`~sparselt.experiments.equal_time.equal_quality_speedup`). A suite of
one scene therefore states that scene's interval and verdict. (Until issue
37's fourteenth session the seeds' values were resampled: with three seeds
that gave intervals about half as wide as the seeds' t interval, and a suite
of one scene called a loss where the scene's own cell was within noise.) The counts of
verdicts, and the worst scene, sit beside them.

Only cells with a ratio enter the means: a ``reference-limited`` cell
(the reference's noise hides the method's error) or one without PT's value at
its time is counted, not averaged. A speed-up read beyond PT's ladder is a
bound; the aggregate says how many scenes' speed-ups are bounds.

References
----------
Davison, A. C., & Hinkley, D. V. (1997). Bootstrap Methods and their
Application. Cambridge University Press.
Fleming, P. J., & Wallace, J. J. (1986). How not to lie with statistics: the
correct way to summarize benchmark results. Communications of the ACM 29(3)
(the geometric mean of ratios).
"""

from __future__ import annotations

import math

import numpy as np

from .equal_time import row_floor, t_quantile

#: Bootstrap resamples of an aggregate's interval, and the generator's seed (recorded in ``suite.json``).
RESAMPLES = 2000
BOOTSTRAP_SEED = 20261204
CONFIDENCE = 0.95
#: The verdicts with a ratio (they enter the geometric means).
JUDGED = ("wins", "loses", "within noise", "one seed")
AGGREGATE_COLUMNS = (
    "method", "spp", "scenes", "scenes_judged", "speedup_geometric_mean", "speedup_ci_low", "speedup_ci_high",
    "speedup_bounded_scenes", "speedup_bound", "relmse_ratio_geometric_mean", "relmse_ratio_ci_low",
    "relmse_ratio_ci_high", "wins", "within_noise", "loses", "reference_limited", "other", "worst_scene",
    "worst_speedup", "worst_verdict", "best_scene", "best_speedup")


class SceneCell:
    """One scene's (method, spp) cell, with what the bootstrap draws: its ratio, from the interval its comparison
    states.

    Parameters
    ----------
    scene : str
    record : dict
        The cell's summary record (:func:`~sparselt.experiments.equal_time.summarize`), with its headline
        metric's ratio interval.
    rows : list of dict
        Its seeds' rows, with the equal-time columns.
    fit : BaselineFit or None
        The scene's PT fits.
    """

    def __init__(self, scene, record, rows, fit):
        self.scene, self.record, self.fit = scene, record, fit
        self.verdict = record.get("verdict", "")
        self.judged = self.verdict in JUDGED and fit is not None and isinstance(record.get("speedup_equal_quality"),
                                                                                 float)
        self.speedup = record.get("speedup_equal_quality") if self.judged else None
        self.bound = record.get("speedup_bound", "") if self.judged else ""
        if self.judged:
            metric = record["headline_metric"]
            self.metric = metric
            floors = np.array([row_floor(row, metric) for row in rows])
            numerator = np.array([row[metric] for row in rows], dtype=np.float64) - floors
            denominator = np.array([row[f"{metric}_pt_equal_time"] for row in rows], dtype=np.float64) - floors
            self.floor = row_floor(rows[0], metric)
            self.seconds = float(record["seconds_total"])
            self.ratio = float(numerator.mean() / denominator.mean())
            self.degrees = len(rows) - 1
            self.scales = _interval_scales(self.ratio, record.get(f"{metric}_ratio_ci_low"),
                                           record.get(f"{metric}_ratio_ci_high"), self.degrees)

    def draws(self, generator, shape):
        """``(log ratio, log speed-up)`` arrays of ``shape``: the ratio drawn from the distribution the cell's own
        interval states, ``log r + s T`` (``T`` a Student-t of ``n - 1`` degrees of freedom over its ``n`` seeds,
        ``s`` its interval's log half-width below or above ``r`` over T's 97.5% quantile: the seeds' spread, the
        time's uncertainty and PT's correction's, as the comparison combined them), each mapped to a speed-up at
        the cell's time as the comparison maps its ratio
        (:func:`~sparselt.experiments.equal_time.equal_quality_speedup`, bounded by PT's ladder at both ends)."""
        ratio = np.full(shape, self.ratio)
        if self.scales is not None:
            below, above = self.scales
            draw = generator.standard_t(self.degrees, shape)
            # t's tails reach beyond float range (a ratio of 0 or infinity); beyond e^+-50 no percentile moves.
            ratio = ratio * np.exp(np.clip(draw * np.where(draw < 0, below, above), -50.0, 50.0))
        fit = self.fit
        lowest, highest = fit.spp_range
        at = np.clip((self.seconds - fit.intercept) / fit.slope, lowest, highest)
        here = fit.mean_value(self.metric, at) - self.floor  # PT's debiased value at the cell's time
        spp, _ = fit.spp_reaching(self.metric, self.floor + ratio * here)
        speedup = (fit.intercept + fit.slope * spp) / self.seconds
        return np.log(ratio), np.log(speedup)


def _interval_scales(ratio, low, high, degrees):
    """``(below, above)``: the log half-widths of a ratio's interval ``[low, high]`` under and over ``ratio``,
    each over the 97.5% Student-t quantile of ``degrees``; None without a finite interval (one seed)."""
    if degrees < 1 or not all(isinstance(value, float) and math.isfinite(value) and value > 0 for value in (low, high)):
        return None
    quantile = t_quantile(degrees)
    return max(0.0, math.log(ratio / low)) / quantile, max(0.0, math.log(high / ratio)) / quantile


def _geometric_mean(values):
    values = np.asarray(values, dtype=np.float64)
    return float(np.exp(np.mean(np.log(values))))


def bootstrap_geometric_means(cells, *, resamples=RESAMPLES, seed=BOOTSTRAP_SEED):
    """Percentile intervals of the geometric means of ratio and speed-up over ``cells`` (judged
    :class:`SceneCell` s): scenes resampled with replacement, then each chosen scene's seeds and time.

    Returns
    -------
    dict
        ``ratio_low``, ``ratio_high``, ``speedup_low``, ``speedup_high``
        (``nan`` when there is no cell).
    """
    if not cells:
        return dict.fromkeys(("ratio_low", "ratio_high", "speedup_low", "speedup_high"), math.nan)
    generator = np.random.default_rng(seed)
    count = len(cells)
    chosen = generator.integers(0, count, (resamples, count))  # the scenes of each resample
    log_ratio, log_speedup = np.zeros(resamples), np.zeros(resamples)
    for index, cell in enumerate(cells):
        ratios, speedups = cell.draws(generator, (resamples, count))  # one independent draw per slot
        where = chosen == index
        log_ratio += np.where(where, ratios, 0.0).sum(axis=1)
        log_speedup += np.where(where, speedups, 0.0).sum(axis=1)
    ratios, speedups = np.exp(log_ratio / count), np.exp(log_speedup / count)
    tail = 100 * (1 - CONFIDENCE) / 2
    ratio_low, ratio_high = np.percentile(ratios, [tail, 100 - tail])
    speedup_low, speedup_high = np.percentile(speedups, [tail, 100 - tail])
    return {"ratio_low": float(ratio_low), "ratio_high": float(ratio_high), "speedup_low": float(speedup_low),
            "speedup_high": float(speedup_high)}


def aggregate(scenes, *, baseline="pt", resamples=RESAMPLES, seed=BOOTSTRAP_SEED):
    """One record per (method, spp) over a suite's scenes, with :data:`AGGREGATE_COLUMNS`.

    Parameters
    ----------
    scenes : list of (str, list of dict, BaselineFit or None, list of dict)
        Per scene: its name, its rows (with the equal-time columns), PT's
        fits and its summary records (:func:`~sparselt.experiments.equal_time.judge`).
    baseline : str
        The baseline's row (not aggregated).
    resamples, seed : int
        The bootstrap's resamples and seed (the same seed gives the same bytes).

    Returns
    -------
    list of dict
        In the order methods and budgets first appear.
    """
    cells = {}
    for name, rows, fit, summary in scenes:
        for record in summary:
            if record["method"] == baseline:
                continue
            group = [row for row in rows if row["method"] == record["method"] and row["spp"] == record["spp"]]
            cells.setdefault((record["method"], record["spp"]), []).append(SceneCell(name, record, group, fit))
    records = []
    for (method, spp), members in cells.items():
        judged = [cell for cell in members if cell.judged]
        interval = bootstrap_geometric_means(judged, resamples=resamples, seed=seed)
        bounds = {cell.bound for cell in judged if cell.bound}
        record = dict.fromkeys(AGGREGATE_COLUMNS, "")
        record.update(
            method=method, spp=spp, scenes=len(members), scenes_judged=len(judged),
            wins=sum(cell.verdict == "wins" for cell in members),
            within_noise=sum(cell.verdict == "within noise" for cell in members),
            loses=sum(cell.verdict == "loses" for cell in members),
            reference_limited=sum(cell.verdict == "reference-limited" for cell in members))
        record["other"] = len(members) - record["wins"] - record["within_noise"] - record["loses"] - record[
            "reference_limited"]
        if judged:
            record.update(
                speedup_geometric_mean=_geometric_mean([cell.speedup for cell in judged]),
                speedup_ci_low=interval["speedup_low"], speedup_ci_high=interval["speedup_high"],
                speedup_bounded_scenes=sum(bool(cell.bound) for cell in judged),
                speedup_bound="" if not bounds else (bounds.pop() if len(bounds) == 1 else "both"),
                relmse_ratio_geometric_mean=_geometric_mean([cell.ratio for cell in judged]),
                relmse_ratio_ci_low=interval["ratio_low"], relmse_ratio_ci_high=interval["ratio_high"])
            worst = min(judged, key=lambda cell: cell.speedup)
            best = max(judged, key=lambda cell: cell.speedup)
            record.update(worst_scene=worst.scene, worst_speedup=worst.speedup, worst_verdict=worst.verdict,
                          best_scene=best.scene, best_speedup=best.speedup)
        records.append(record)
    return records


def aggregate_verdict(record):
    """``wins`` / ``loses`` / ``within noise`` across the suite from the speed-up's interval (above 1 wins),
    ``no judged scene`` without one."""
    low, high = record.get("speedup_ci_low"), record.get("speedup_ci_high")
    if not isinstance(low, float) or not (math.isfinite(low) and math.isfinite(high)):
        return "no judged scene"
    if low > 1:
        return "wins"
    if high < 1:
        return "loses"
    return "within noise"
