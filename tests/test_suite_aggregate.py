"""Issue 36: the suite's geometric means and their two-level bootstrap intervals, on synthetic suites."""

import dataclasses
import math

import numpy as np
import pytest

from sparselt.experiments.equal_time import BaselineFit, equal_quality_speedup, ratio_interval, verdict
from sparselt.experiments.suite_aggregate import aggregate, aggregate_verdict


def fit(slope=0.01, c=1.0, spp_range=(1, 10**6)):
    """PT with t = slope * spp and relMSE = c / spp (no floor), over a ladder wide enough for every ratio here."""
    return BaselineFit(intercept=0.0, slope=slope, time_residual=0.0, fits={"relmse": {1: (c, 0.0)}}, ssim={},
                       spp_range=spp_range, reached_seconds=slope * spp_range[1],
                       lowest_seconds=slope * spp_range[0])


def scene(name, method_errors, pt_errors, *, seconds=1.0, verdict="within noise", interval=None, baseline=None):
    """One scene's (rows, fit, summary) for method ``m`` at 16 spp: per seed its relMSE and PT's at its time; the
    cell's ratio interval ``interval``, or the seeds' own (:func:`ratio_interval`)."""
    pt_fit = baseline or fit()
    rows = [{"method": "m", "spp": 16, "seed": seed, "relmse": error, "relmse_pt_equal_time": pt,
             "reference_relmse_floor": 0.0, "seconds_total": seconds}
            for seed, (error, pt) in enumerate(zip(method_errors, pt_errors), 1)]
    ratio, low, high = ratio_interval(method_errors, pt_errors)
    low, high = interval or (low, high)
    speedup, bound = equal_quality_speedup(pt_fit, "relmse", ratio, seconds, 0.0)
    record = {"method": "m", "spp": 16, "verdict": verdict, "headline_metric": "relmse", "seconds_total": seconds,
              "speedup_equal_quality": speedup, "speedup_bound": bound, "relmse_ratio": ratio,
              "relmse_ratio_ci_low": low, "relmse_ratio_ci_high": high}
    return (name, rows, pt_fit, [record])


def test_the_geometric_mean_of_a_suite_is_that_of_its_scenes():
    scenes = [scene("a", [0.5, 0.5, 0.5], [1.0, 1.0, 1.0]), scene("b", [2.0, 2.0, 2.0], [1.0, 1.0, 1.0]),
              scene("c", [1.0, 1.0, 1.0], [1.0, 1.0, 1.0])]
    (record,) = aggregate(scenes)
    assert record["relmse_ratio_geometric_mean"] == pytest.approx(1.0)
    # relMSE = c / spp: a ratio r at equal time is a speed-up 1 / r.
    assert record["speedup_geometric_mean"] == pytest.approx(1.0)
    assert record["worst_scene"] == "b" and record["worst_speedup"] == pytest.approx(0.5)
    assert record["best_scene"] == "a" and record["best_speedup"] == pytest.approx(2.0)
    assert record["scenes"] == record["scenes_judged"] == 3 and record["within_noise"] == 3


def test_identical_seeds_and_one_scene_give_a_point_interval():
    (record,) = aggregate([scene("a", [0.25] * 3, [1.0] * 3)])
    assert record["speedup_ci_low"] == pytest.approx(4.0) and record["speedup_ci_high"] == pytest.approx(4.0)
    assert record["relmse_ratio_ci_low"] == pytest.approx(0.25)
    assert aggregate_verdict(record) == "wins"


def test_a_suite_of_one_scene_states_that_scenes_own_interval_and_verdict():
    """One scene: the aggregate's relMSE-ratio interval is the comparison's own, to the bootstrap's Monte Carlo
    error, the seeds' t interval (2 degrees of freedom) and an asymmetric one (as timing widens a cell) alike, and
    so is the verdict; the speed-up's interval is that interval mapped through PT's fit (relMSE = c / spp: a ratio
    r is a speed-up 1 / r). Resampling the three seeds' values instead gave about half the log width and called
    the first cell a loss (as on greenhouse-dof, where the cell was within noise)."""
    method, pt = [1.02, 1.31, 1.12], [1.0, 1.05, 0.97]
    ratio, low, high = ratio_interval(method, pt)
    assert verdict(low, high) == "within noise" and ratio > 1.1
    for bounds in ((low, high), (ratio / 1.3, ratio * 1.05)):
        (record,) = aggregate([scene("a", method, pt, interval=bounds)], resamples=20000)
        assert record["relmse_ratio_ci_low"] == pytest.approx(bounds[0], rel=0.03)
        assert record["relmse_ratio_ci_high"] == pytest.approx(bounds[1], rel=0.03)
        assert record["speedup_ci_low"] == pytest.approx(1 / bounds[1], rel=0.03)
        assert record["speedup_ci_high"] == pytest.approx(1 / bounds[0], rel=0.03)
        assert aggregate_verdict(record) == verdict(*bounds)


def test_the_interval_widens_with_the_spread_between_scenes_and_with_each_scenes_own():
    def width(records):
        return math.log(records[0]["speedup_ci_high"] / records[0]["speedup_ci_low"])

    narrow = aggregate([scene(f"s{i}", [0.5 * 1.05 ** i] * 3, [1.0] * 3) for i in range(6)])
    wide = aggregate([scene(f"s{i}", [0.5 * 1.5 ** i] * 3, [1.0] * 3) for i in range(6)])
    assert width(wide) > 3 * width(narrow)
    quiet = aggregate([scene("a", [0.5] * 3, [1.0] * 3)])
    noisy = aggregate([scene("a", [0.5] * 3, [1.0] * 3, interval=(0.4, 0.62))])  # e.g. widened by the timing
    assert width(quiet) == pytest.approx(0.0, abs=1e-12) and width(noisy) > 0.2


def test_the_same_seed_gives_the_same_interval_and_another_seed_a_close_one():
    generator = np.random.default_rng(3)
    scenes = [scene(f"s{i}", list(generator.uniform(0.3, 0.6, 3)), list(generator.uniform(0.9, 1.1, 3)))
              for i in range(5)]
    first, again = aggregate(scenes), aggregate(scenes)
    assert first == again
    other = aggregate(scenes, seed=11)
    assert other[0]["speedup_ci_low"] == pytest.approx(first[0]["speedup_ci_low"], rel=0.1)


def test_reference_limited_and_unjudged_cells_are_counted_not_averaged():
    scenes = [scene("a", [0.5] * 3, [1.0] * 3, verdict="wins"),
              scene("b", [9.0] * 3, [1.0] * 3, verdict="reference-limited"),
              scene("c", [9.0] * 3, [1.0] * 3, verdict="no PT value")]
    (record,) = aggregate(scenes)
    assert (record["wins"], record["reference_limited"], record["other"], record["scenes_judged"]) == (1, 1, 1, 1)
    assert record["speedup_geometric_mean"] == pytest.approx(2.0)


def test_a_speed_up_beyond_pt_s_ladder_is_marked_as_a_bound():
    short = fit(spp_range=(1, 32))  # PT's ladder ends at 32 spp = 0.32 s
    (record,) = aggregate([scene("a", [0.001] * 3, [1.0] * 3, seconds=0.16, baseline=short)])
    assert record["speedup_bound"] == ">" and record["speedup_bounded_scenes"] == 1
    assert record["speedup_geometric_mean"] == pytest.approx(2.0)  # the ladder's end: a lower bound
    assert record["speedup_ci_high"] == pytest.approx(2.0)


def test_the_interval_covers_the_suites_true_geometric_mean_about_95_percent_of_the_time():
    """200 simulated suites of 11 scenes: per-scene log ratios N(mu, 0.4), each scene's 3 seeds with 20% noise.

    The interval is for the population's geometric mean exp(mu). A percentile bootstrap over 11 scenes
    covers a little less than its nominal 95%; 200 suites estimate the coverage to within +-0.03 (two standard
    errors), so below 0.85 would be a real fault.
    """
    generator = np.random.default_rng(36)
    covered, trials = 0, 200
    for _ in range(trials):
        scenes = []
        for index in range(11):
            ratio = math.exp(generator.normal(math.log(0.5), 0.4))
            pt = generator.uniform(0.5, 2.0)
            errors = ratio * pt * (1 + 0.2 * generator.standard_normal(3))
            scenes.append(scene(f"s{index}", list(np.abs(errors)), [pt] * 3))
        (record,) = aggregate(scenes, resamples=500, seed=int(generator.integers(2**31)))
        covered += record["relmse_ratio_ci_low"] <= 0.5 <= record["relmse_ratio_ci_high"]
    assert covered / trials >= 0.85


def test_pt_local_correction_moves_the_bootstrap_speedup():
    """A fit whose rungs measured PT 30% above the model at 64 spp: the bootstrap's speed-up is the comparison's
    (equal_quality_speedup on the corrected curve), not the model's; the correction's own uncertainty is in the
    cell's interval, which the bootstrap draws from (above)."""
    rungs = np.array([1.0, 64.0, 4096.0])
    bent = dataclasses.replace(fit(spp_range=(1, 4096)),
                               corrections={"relmse": (rungs, np.array([1.0, 1.3, 1.0]), np.zeros(3))})
    (plain,) = aggregate([scene("a", [0.5] * 3, [1.0] * 3, seconds=0.64, baseline=fit(spp_range=(1, 4096)))])
    (corrected,) = aggregate([scene("a", [0.5] * 3, [1.0] * 3, seconds=0.64, baseline=bent)])
    expected, _ = equal_quality_speedup(bent, "relmse", 0.5, 0.64, 0.0)
    assert corrected["speedup_geometric_mean"] == pytest.approx(expected, rel=1e-9)
    assert corrected["speedup_ci_low"] == pytest.approx(expected, rel=1e-9)  # identical seeds: a point
    assert plain["speedup_geometric_mean"] == pytest.approx(2.0, rel=1e-9) and abs(expected - 2.0) > 0.05
