"""The equal-time protocol (issue 20): PT's fits, ratio intervals, per-budget verdicts, equal-quality speed-up.

Rows are synthetic (plain dicts, as a comparison's cells hold them), so every
expected value is known exactly.
"""

import dataclasses
import math

import numpy as np
import pytest

from sparselt.experiments.equal_time import (
    add_equal_time_columns,
    correction_uncertainty,
    equal_quality_speedup,
    fit_baseline,
    fit_record,
    fit_relmse,
    fit_time,
    headline_metric,
    mean_interval,
    ratio_interval,
    summarize,
    verdict,
)
from sparselt.report.comparison import equal_time_verdicts, verdict_sentence

SEEDS = (1, 2, 3)


def pt_rows(spps=(8, 16, 32, 64, 128), intercept=0.05, slope=0.01, c=(0.5, 0.55, 0.45), floor=0.001):
    """PT rows exactly on t = a + b spp and relMSE = c_seed / spp + floor."""
    return [{"method": "pt", "spp": spp, "seed": seed, "seconds_total": intercept + slope * spp,
             "relmse": c[index] / spp + floor, "ssim": 1 - 1 / math.sqrt(spp)}
            for spp in spps for index, seed in enumerate(SEEDS)]


def method_rows(name, spp, seconds, relmses):
    return [{"method": name, "spp": spp, "seed": seed, "seconds_total": seconds, "relmse": relmse, "ssim": 0.9}
            for seed, relmse in zip(SEEDS, relmses)]


def test_relmse_fit_recovers_c_and_floor_exactly():
    spps = np.array([4, 8, 16, 32, 64])
    c, floor = fit_relmse(spps, 0.3 / spps + 0.002)
    assert c == pytest.approx(0.3, rel=1e-9) and floor == pytest.approx(0.002, rel=1e-7)
    c, floor = fit_relmse(spps, 0.3 / spps)  # no floor: a fitted floor below 0 is refitted at 0
    assert floor >= 0 and c == pytest.approx(0.3, rel=1e-6)


def test_baseline_fit_gives_pt_at_any_time_within_its_ladder():
    fit = fit_baseline(pt_rows(), "pt")
    assert (fit.intercept, fit.slope) == (pytest.approx(0.05), pytest.approx(0.01))
    assert fit.time_residual < 1e-9 and fit.spp_range == (8, 128)
    seconds = 0.05 + 0.01 * 50  # PT at 50 spp, between ladder points
    assert fit.relmse_at(seconds, 2) == pytest.approx(0.55 / 50 + 0.001, rel=1e-6)
    assert math.isnan(fit.relmse_at(0.05 + 0.01 * 200, 1))  # beyond the ladder: nothing extrapolated
    assert fit.seconds_for_relmse(0.5 / 25 + 0.001) == pytest.approx(0.05 + 0.01 * 25, rel=1e-6)
    assert fit.seconds_for_relmse(0.0005) == math.inf  # below PT's floor
    assert fit_baseline(pt_rows(spps=(8,)), "pt") is None


def test_time_fit_follows_the_rungs_not_one_slowed_repeat():
    """One rung slowed fourfold (a busy machine) moves neither the line nor its residual scale much."""
    spps = np.array([8, 16, 32, 40, 64, 128, 256, 512, 1024], np.float64)
    times = 0.02 + 0.002 * spps
    slowed = times.copy()
    slowed[3] *= 4
    intercept, slope, residual = fit_time(spps, slowed)
    assert intercept == pytest.approx(0.02, rel=1e-3) and slope == pytest.approx(0.002, rel=1e-3)
    assert residual < 1e-3
    least_squares = np.polyfit(spps, slowed, 1)[1]  # what the least-squares line does with the same rung
    assert abs(least_squares - 0.02) > 0.01


def test_a_time_between_the_lowest_rungs_measured_and_fitted_times_reads_that_rung():
    """The ladder covers from its fastest rung's measured time, PT's spp clamped to the rung: never below it."""
    rows = pt_rows(spps=(8, 16, 32, 64, 128, 256, 512))
    for row in rows:
        if row["spp"] == 8:
            row["seconds_total"] = 0.1  # measured faster than the line's 0.13
    fit = fit_baseline(rows, "pt")
    assert fit.lowest_seconds == pytest.approx(0.1)
    assert fit.spp_at(0.11) == 8 and fit.relmse_at(0.11, 1) == pytest.approx(0.5 / 8 + 0.001, rel=1e-6)
    assert math.isnan(fit.relmse_at(0.05, 1))  # faster than any PT image of the ladder


def test_mean_interval_is_the_student_t_interval():
    values = [1.0, 2.0, 4.0]
    mean, low, high = mean_interval(values)
    half = 4.302652729911275 * np.std(values, ddof=1) / math.sqrt(3)  # t_{0.975, 2}
    assert (mean, low, high) == (pytest.approx(7 / 3), pytest.approx(7 / 3 - half), pytest.approx(7 / 3 + half))
    assert all(math.isnan(bound) for bound in mean_interval([3.0])[1:])


def test_ratio_interval_covers_the_true_ratio_about_95_percent_of_the_time():
    """400 experiments of 5 paired seeds with a true ratio of 0.8: coverage within 3 binomial standard errors."""
    rng = np.random.default_rng(20)
    covered, trials = 0, 400
    for _ in range(trials):
        denominator = rng.lognormal(np.log(0.02), 0.3, 5)
        numerator = 0.8 * rng.lognormal(np.log(0.02), 0.3, 5)  # the same law: the ratio of means is 0.8
        _, low, high = ratio_interval(numerator, denominator)
        covered += low <= 0.8 <= high
    rate = covered / trials
    assert abs(rate - 0.95) <= 3 * math.sqrt(0.95 * 0.05 / trials) + 0.02, rate


def test_verdict_from_the_interval():
    assert verdict(0.7, 0.9) == "wins" and verdict(1.1, 1.3) == "loses" and verdict(0.9, 1.2) == "within noise"
    assert verdict(math.nan, math.nan) == "one seed"


def test_per_budget_verdicts_that_flip_are_said_per_budget():
    """A method that loses at 16 spp and wins at 40: the sentence says both, no mean over budgets."""
    rows = pt_rows()
    at = 0.05 + 0.01 * 40  # the method's times: PT reaches 40 spp then
    pt_relmse = [c / 40 + 0.001 for c in (0.5, 0.55, 0.45)]
    rows += method_rows("flipper", 16, at, [2.1 * value for value in pt_relmse])
    rows += method_rows("flipper", 40, at, [0.84 * value * factor for value, factor in zip(pt_relmse,
                                                                                             (0.98, 1.0, 1.02))])
    for row in rows:  # FLIP falling with spp for PT; the method's half of PT's
        row["flip"] = 0.5 / math.sqrt(row["spp"]) if row["method"] == "pt" else 0.25 / math.sqrt(40)
    fit = add_equal_time_columns(rows, baseline="pt")
    summary = summarize(rows, fit, baseline="pt")
    by_spp = {record["spp"]: record for record in summary if record["method"] == "flipper"}
    # PT reaches 40 spp at the method's time; its FLIP is interpolated linearly in log spp between 32 and 64
    assert by_spp[40]["flip_ratio"] == pytest.approx(0.5, rel=0.02)
    assert by_spp[16]["verdict"] == "loses" and by_spp[16]["relmse_ratio"] == pytest.approx(2.1, rel=1e-6)
    assert by_spp[40]["verdict"] == "wins" and by_spp[40]["relmse_ratio"] == pytest.approx(0.84, rel=1e-3)
    sentence = verdict_sentence("flipper", summary)
    assert "wins at 40 spp (relMSE 0.84x [" in sentence and "loses at 16 spp (relMSE 2.10x [" in sentence
    methods = {"pt": {"baseline": True}, "flipper": {"baseline": False}}
    assert equal_time_verdicts(summary, methods=methods) == [sentence]


def test_equal_quality_speedup_from_the_fit():
    rows = pt_rows()
    relmse = 0.5 / 64 + 0.001  # what PT reaches at 64 spp, at 0.69 s; the method gets it in 0.2 s
    rows += method_rows("fast", 8, 0.2, [relmse * f for f in (0.99, 1.0, 1.01)])
    summary = summarize(rows, add_equal_time_columns(rows, baseline="pt"), baseline="pt")
    record = next(record for record in summary if record["method"] == "fast")
    pt_seconds = 0.05 + 0.01 * (0.5 / (relmse - 0.001))
    assert record["speedup_equal_quality"] == pytest.approx(pt_seconds / 0.2, rel=1e-6)
    assert record["speedup_ci_low"] < record["speedup_equal_quality"] < record["speedup_ci_high"]
    assert all(row["verdict"] == record["verdict"] for row in rows if row["method"] == "fast")


def curved_pt_rows(exponent, spps=(8, 16, 32, 64, 128, 256, 512, 1024), noise=0.0, seed=3):
    """PT rows whose trimmed relMSE falls as c / spp^exponent + floor (times on t = a + b spp), the untrimmed
    relMSE as 1 / spp, both with relative noise."""
    generator = np.random.default_rng(seed)
    rows = pt_rows(spps=spps)
    for row, c in zip(rows, [0.4, 0.5, 0.45] * len(spps)):
        row["relmse_trimmed"] = (c / row["spp"] ** exponent + 0.0005) * (1 + noise * generator.standard_normal())
        row["relmse"] *= 1 + noise * generator.standard_normal()
    return rows


def test_a_trimmed_metric_slower_than_one_over_spp_gets_its_exponent_and_reads_pt_at_its_curve():
    """A ladder on c / spp^0.6 + floor: 1 / spp leaves a large residual, the exponent is recovered (with 2% noise
    within 0.05), PT's value halfway up the ladder is the curve's, and the untrimmed relMSE keeps 1 / spp."""
    exact = fit_baseline(curved_pt_rows(0.6), "pt")
    assert exact.exponent("relmse_trimmed") == pytest.approx(0.6) and exact.exponent("relmse") == 1.0
    assert exact.residuals["relmse_trimmed"] < 1e-6
    seconds = 0.05 + 0.01 * 100
    assert exact.value_at("relmse_trimmed", seconds, 2) == pytest.approx(0.5 / 100 ** 0.6 + 0.0005, rel=1e-6)
    noisy = fit_baseline(curved_pt_rows(0.6, noise=0.02), "pt")
    assert abs(noisy.exponent("relmse_trimmed") - 0.6) <= 0.05
    assert noisy.exponent("relmse") == 1.0  # never fitted for the untrimmed metric
    ladder = np.array([8, 16, 32, 64, 128, 256, 512, 1024.0])
    c, floor = fit_relmse(ladder, 0.5 / ladder ** 0.6 + 0.0005)  # the 1 / spp line on the same ladder
    assert abs((c / 100 + floor) / (0.5 / 100 ** 0.6 + 0.0005) - 1) > 0.2  # what it read there was off by > 20%
    record = fit_record(exact)
    assert record["relmse_trimmed_exponent"] == pytest.approx(0.6) and "relmse_exponent" not in record


def test_a_ladder_on_one_over_spp_keeps_exponent_one_and_the_same_fits():
    """Monte Carlo's rate, with noise: exponent 1, and the fits are exactly fit_relmse's per seed."""
    rows = curved_pt_rows(1.0, noise=0.05)
    fit = fit_baseline(rows, "pt")
    assert fit.exponents == {} and fit.exponent("relmse_trimmed") == 1.0
    for seed in SEEDS:
        ladder = sorted((row["spp"], row["relmse_trimmed"]) for row in rows if row["seed"] == seed)
        assert fit.fits["relmse_trimmed"][seed] == fit_relmse([spp for spp, _ in ladder], [v for _, v in ladder])
    assert "relmse_trimmed_exponent" not in fit_record(fit)


def test_no_exponent_for_short_ladders_or_a_trimmed_error_that_rises():
    """Fewer than four rungs: the line. A trimmed error that rises with spp (sunlit-room's fireflies) fits no
    power in range: the line, whose residual then hands the headline to the untrimmed relMSE."""
    assert fit_baseline(curved_pt_rows(0.6, spps=(8, 16, 32)), "pt").exponents == {}
    rows = curved_pt_rows(1.0)
    for row in rows:
        row["relmse_trimmed"] = 0.001 * row["spp"] ** 0.5
    fit = fit_baseline(rows, "pt")
    assert fit.exponents == {} and headline_metric(rows, fit) == "relmse"


def test_equal_quality_speedup_follows_the_curved_fit():
    """With PT's trimmed relMSE on c / spp^0.6 + floor: a method at PT's own value has speed-up 1 at PT's time,
    and one reaching PT's 512-spp value at 256 spp's time has speed-up PT's 512-spp time over its own."""
    rows = curved_pt_rows(0.6)
    target = [c / 512 ** 0.6 + 0.0005 for c in (0.4, 0.5, 0.45)]
    seconds = 0.05 + 0.01 * 256
    rows += [{"method": "fast", "spp": 8, "seed": seed, "seconds_total": seconds, "relmse": 0.5 / 512,
              "relmse_trimmed": value, "ssim": 0.9} for seed, value in zip(SEEDS, target)]
    fit = add_equal_time_columns(rows, baseline="pt")
    summary = summarize(rows, fit, baseline="pt")
    record = next(record for record in summary if record["method"] == "fast")
    assert record["headline_metric"] == "relmse_trimmed" and record["headline_exponent"] == pytest.approx(0.6)
    assert record["speedup_equal_quality"] == pytest.approx((0.05 + 0.01 * 512) / seconds, rel=1e-3)


def bent_pt_rows(bend, spps=(8, 16, 32, 64, 128, 256), noise=0.0, seed=5):
    """PT rows whose untrimmed relMSE is c / spp + floor times ``bend(spp)`` (a shape the line does not have), the
    same in every seed, with relative noise per row."""
    generator = np.random.default_rng(seed)
    rows = pt_rows(spps=spps)
    for row in rows:
        row["relmse"] *= bend(row["spp"]) * (1 + noise * generator.standard_normal())
    return rows


def test_the_local_correction_reads_every_rung_at_its_measured_mean_and_is_one_on_the_model():
    """On c / spp + floor exactly the correction is 1 (no reading moves); where every seed bends the same way off
    the line, PT's value at a rung's time is that rung's measured mean (to the seeds' fits' small differences of
    shape), per seed its own fit times the mean bend."""
    exact = fit_baseline(pt_rows(), "pt")
    spps, means, errors = exact.corrections["relmse"]
    assert spps.tolist() == [8, 16, 32, 64, 128] and np.allclose(means, 1.0) and np.allclose(errors, 0.0, atol=1e-12)
    assert exact.relmse_at(0.05 + 0.01 * 50, 2) == pytest.approx(0.55 / 50 + 0.001, rel=1e-9)

    def bend(spp):
        return 1.0 + 0.15 * math.sin(math.log2(spp))

    rows = bent_pt_rows(bend)
    fit = fit_baseline(rows, "pt")
    for spp in (16, 64, 128):
        measured = np.mean([row["relmse"] for row in rows if row["spp"] == spp])
        at = 0.05 + 0.01 * spp
        assert np.mean([fit.relmse_at(at, seed) for seed in SEEDS]) == pytest.approx(measured, rel=1e-3)
        assert fit.mean_value("relmse", spp) == pytest.approx(measured, rel=1e-3)
    record = fit_record(fit)["relmse_rung_correction"]
    assert [entry["spp"] for entry in record] == [8, 16, 32, 64, 128, 256]


def test_the_corrected_curve_never_rises_and_its_inverse_is_exact():
    """mean_value is non-increasing over the ladder even where rung noise near a floor lifts a rung; spp_reaching
    inverts it to float precision inside the ladder and gives the rung with '<' or '>' beyond it."""
    rows = bent_pt_rows(lambda spp: 1.6 if spp == 128 else 1.0)  # one rung 60% above the line in every seed
    fit = fit_baseline(rows, "pt")
    grid = np.geomspace(8, 256, 400)
    values = fit.mean_value("relmse", grid)
    assert np.all(np.diff(values) <= 1e-15)
    targets = fit.mean_value("relmse", np.array([10.0, 40.0, 90.0]))
    spp, bound = fit.spp_reaching("relmse", targets)
    assert np.allclose(fit.mean_value("relmse", spp), targets, rtol=1e-9) and bound.tolist() == ["", "", ""]
    spp, bound = fit.spp_reaching("relmse", np.array([1.0, 1e-9]))
    assert spp.tolist() == [8.0, 256.0] and bound.tolist() == ["<", ">"]
    for ratio in (1.0, 0.5, 2.0):  # the speed-up is 1 at a ratio of 1 and falls as the ratio grows
        speedup, _ = equal_quality_speedup(fit, "relmse", ratio, 0.05 + 0.01 * 40, 0.0)
        assert speedup == pytest.approx(1.0, rel=1e-9) if ratio == 1.0 else (speedup > 1) == (ratio < 1)


def test_the_local_correction_moves_a_verdict_the_line_misread_and_its_error_widens_the_interval():
    """PT's error 15% above its line at 32-64 spp in every seed: the line reads PT too good there and a method
    15% worse than the line's reading seems to lose; corrected, PT's own measured error makes it a tie. With seed
    noise on the bend, the correction's standard error widens the interval."""
    def bend(spp):
        return 1.15 if spp in (32, 64) else 1.0

    line_at_48 = [c / 48 + 0.001 for c in (0.5, 0.55, 0.45)]
    at = 0.05 + 0.01 * 48
    method = method_rows("m", 8, at, [1.15 * value * f for value, f in zip(line_at_48, (0.99, 1.0, 1.01))])
    rows = bent_pt_rows(bend) + method
    summary = summarize(rows, add_equal_time_columns(rows, baseline="pt"), baseline="pt")
    record = next(record for record in summary if record["method"] == "m")
    assert record["relmse_ratio"] == pytest.approx(1.0, abs=0.02) and record["verdict"] == "within noise"
    line = dataclasses.replace(fit_baseline(rows, "pt"), corrections={})  # the fit alone, as before the correction
    line_ratio = np.mean([row["relmse"] for row in method]) / np.mean([line.relmse_at(at, seed) for seed in SEEDS])
    assert line_ratio > 1.08  # the line, pulled up a little by the bend, still reads PT about 10% too good
    noisy_rows = bent_pt_rows(bend, noise=0.05) + [dict(row) for row in method]
    fit = add_equal_time_columns(noisy_rows, baseline="pt")
    assert correction_uncertainty(fit, "relmse", at, 3) > 0
    assert correction_uncertainty(fit, "relmse", at, 1) == 0.0


def test_a_time_beyond_the_ladder_has_no_pt_value_and_says_so():
    rows = pt_rows() + method_rows("slow", 8, 10.0, [0.01, 0.011, 0.012])
    summary = summarize(rows, add_equal_time_columns(rows, baseline="pt"), baseline="pt")
    record = next(record for record in summary if record["method"] == "slow")
    assert record["verdict"] == "no PT value" and record["relmse_ratio"] == ""
    assert "has no equal-time PT value" in verdict_sentence("slow", summary)


def test_the_reference_variance_from_its_passes_matches_independent_references(tmp_path):
    """16 independent 256 spp references (4 passes each) of the real Cornell box: the variance each estimates from
    its own passes agrees with the spread between them. Per pixel and channel the ratio of the two estimates is
    noisy (chi-square with 15 and 48 degrees of freedom) and the radiance heavy-tailed, so the test takes the
    median ratio over the lit pixels: near 1 (measured 1.03; bounds far outside its spread)."""
    from sparselt.rendering.baseline import cached_reference, reference_relmse_floor
    from sparselt.rendering.mitsuba import MitsubaScene
    from sparselt.rendering.scenes import get_scene

    scene = MitsubaScene(get_scene("cornell-box"), (16, 16))
    images, variances = [], []
    for seed in range(16):
        image, record = cached_reference(scene, "path", spp=256, seed=seed, progress=False,
                                         cache_directory=str(tmp_path))
        images.append(image.astype(np.float64))
        variances.append(record["variance"].astype(np.float64))
    empirical = np.var(np.stack(images), axis=0, ddof=1)
    estimated = np.mean(np.stack(variances), axis=0)
    lit = empirical > 0
    assert 0.8 < np.median(estimated[lit] / empirical[lit]) < 1.3
    again, record = cached_reference(scene, "path", spp=256, seed=0, progress=False, cache_directory=str(tmp_path))
    assert record["cached"] and np.array_equal(record["variance"], variances[0].astype(np.float32))
    floor = reference_relmse_floor(images[0], variances[0], epsilon=0.01)
    assert floor == pytest.approx(np.mean(variances[0] / (images[0] ** 2 + 0.01)))
    _, single = cached_reference(scene, "path", spp=64, seed=0, progress=False, cache_directory=str(tmp_path))
    assert np.isnan(reference_relmse_floor(images[0], single["variance"], epsilon=0.01))  # one pass: unknown


def test_no_path_traced_cell_replays_a_pass_of_the_reference(tmp_path):
    """A reference of seed 0 in two 64 spp passes, and PT at 64 spp with seeds 0 and 1 (what the comparison gives
    its cells): before the reference's seeds were moved out of the methods' range these two images were its
    passes, bit for bit, so their mean equalled the reference. Now every pixel's difference is noise of the size
    the passes' own variance predicts: over the lit pixels, the mean squared difference of the two independent
    128 spp estimates over twice the reference's mean estimated variance is about 1 (not 0; measured 0.91)."""
    from sparselt.rendering.baseline import (
        METHOD_SEED_LIMIT, REFERENCE_PASS_SPP, REFERENCE_SEED_BASE, cached_reference, reference_pass_seed)
    from sparselt.rendering.mitsuba import MitsubaScene
    from sparselt.rendering.scenes import get_scene

    assert REFERENCE_SEED_BASE >= 2**31 > (METHOD_SEED_LIMIT - 1) ^ 0x5A5A5A5A
    assert reference_pass_seed(0, 0) == REFERENCE_SEED_BASE and reference_pass_seed(2**14 - 1, 2**16 - 1) == 2**32 - 1
    scene = MitsubaScene(get_scene("cornell-box"), (16, 16))
    reference, record = cached_reference(scene, "path", spp=2 * REFERENCE_PASS_SPP, seed=0, progress=False,
                                         cache_directory=str(tmp_path))
    cells = [scene.render_path(REFERENCE_PASS_SPP, 3, seed)[0].astype(np.float64) for seed in (0, 1)]
    difference = np.mean(cells, axis=0) - reference
    lit = record["variance"] > 0
    assert not np.allclose(difference, 0.0, atol=1e-6)
    standardised = np.mean(difference[lit] ** 2) / np.mean(2 * record["variance"][lit])
    assert 0.5 < standardised < 2.0


def test_timing_uncertainty_widens_the_ratio_interval():
    """PT is read at the method's time divided and multiplied by 1 + d: a spread of repeats widens the interval."""
    at = 0.05 + 0.01 * 40
    pt_relmse = [c / 40 + 0.001 for c in (0.5, 0.55, 0.45)]
    steady = pt_rows() + method_rows("m", 16, at, [0.9 * v * f for v, f in zip(pt_relmse, (0.98, 1.0, 1.02))])
    shaky = [dict(row) for row in steady]
    for row in shaky:
        if row["method"] == "m":
            row.update(seconds_total_min=0.8 * at, seconds_total_max=1.2 * at)
    records = {}
    for name, rows in (("steady", steady), ("shaky", shaky)):
        summary = summarize(rows, add_equal_time_columns(rows, baseline="pt"), baseline="pt")
        records[name] = next(record for record in summary if record["method"] == "m")
    assert records["steady"]["timing_uncertainty"] == pytest.approx(0.0, abs=1e-9)
    assert records["shaky"]["timing_uncertainty"] == pytest.approx(0.2, rel=1e-6)
    assert records["steady"]["verdict"] == "wins"  # 0.9x with a tight interval
    assert records["shaky"]["relmse_ratio_ci_low"] < records["steady"]["relmse_ratio_ci_low"]
    assert records["shaky"]["relmse_ratio_ci_high"] > records["steady"]["relmse_ratio_ci_high"] > 0.9


def _rung_times(per_spp, intercept=0.0, seeds=2):
    """A deterministic fake PT: ``intercept + per_spp * spp`` seconds at every seed, and the rungs it ran."""
    ran = []

    def run_rung(spp):
        ran.append(spp)
        return [intercept + per_spp * spp * (1.0 + 0.01 * seed) for seed in range(seeds)]

    return run_rung, ran


def test_every_rung_of_the_ladder_is_run_down_to_one_spp():
    """The downward ladder once listed 1 spp without running it (a cell with no repeats: compare failed at the
    end with timing_repeats=1 when a method was faster than PT at 2 spp). Times: 0.01 s per spp."""
    from sparselt.experiments.comparison_cells import ladder_search

    run_rung, ran = _rung_times(0.01, seeds=1)
    ladder = ladder_search(run_rung, [0.005, 0.09], smallest_budget=4, maximum_spp=64)  # 0.005 s: below 1 spp's
    assert ladder["spps"] == [1, 2, 4, 8, 16] and set(ladder["spps"]) <= set(ran)
    assert ladder["reached_seconds"] == pytest.approx(0.16) and not ladder["capped"]
    assert ladder["target_seconds"] == 0.09 and ladder["fastest_seconds"] == 0.005 and ladder["max_spp"] == 64


def test_the_ladder_doubles_from_half_the_smallest_budget_until_it_passes_every_other_time():
    from sparselt.experiments.comparison_cells import ladder_search

    run_rung, ran = _rung_times(0.01, intercept=0.02)
    ladder = ladder_search(run_rung, [0.1, 0.5, 0.3], smallest_budget=10, maximum_spp=4096)
    # 5 spp: 0.07 s; 10: 0.12; 20: 0.22; 40: 0.42; 80: 0.82 > 0.5 (median over the seeds: the mean of two here).
    assert ladder["spps"] == [5, 10, 20, 40, 80] and ran == [5, 10, 20, 40, 80, 5]
    assert ladder["reached_seconds"] == pytest.approx(0.82 + 0.005 * 0.8) and not ladder["capped"]


def test_the_ladder_runs_two_rungs_at_least_and_stops_at_its_cap():
    from sparselt.experiments.comparison_cells import ladder_search

    run_rung, _ = _rung_times(0.01)
    assert ladder_search(run_rung, [0.0001], smallest_budget=40, maximum_spp=4096)["spps"][-2:] == [20, 40]
    run_rung, ran = _rung_times(0.01)
    ladder = ladder_search(run_rung, [100.0], smallest_budget=8, maximum_spp=64)  # 64 spp: 0.64 s, never 100 s
    assert ladder["capped"] and ladder["spps"] == [4, 8, 16, 32, 64] and max(ran) == 64


def test_the_ladder_resumes_from_a_ladder_already_run():
    """The second search (after the rounds, medians moved) starts from the top rung and adds rungs above it."""
    from sparselt.experiments.comparison_cells import ladder_search

    run_rung, ran = _rung_times(0.01)
    ladder = ladder_search(run_rung, [0.5], smallest_budget=8, maximum_spp=4096, start=[4, 8, 16, 32])
    assert ladder["spps"] == [4, 8, 16, 32, 64] and ran == [32, 64, 4]
    run_rung, ran = _rung_times(0.01)
    ladder = ladder_search(run_rung, [0.05, 0.2], smallest_budget=8, maximum_spp=4096, start=[4, 8, 16, 32])
    assert ladder["spps"] == [4, 8, 16, 32] and ran == [32, 4]  # covered already: the top and bottom rungs read
    run_rung, ran = _rung_times(0.01)
    ladder = ladder_search(run_rung, [0.03, 0.2], smallest_budget=8, maximum_spp=4096, start=[4, 8, 16, 32])
    # A method now faster (0.03 s) than PT's smallest rung (0.04 s): the ladder extends downwards.
    assert ladder["spps"] == [2, 4, 8, 16, 32] and ran == [32, 4, 2]


def test_the_ladder_climbs_until_pt_reaches_the_best_methods_error():
    """Times alone would stop at 16 spp (0.2 s > 0.15 s); PT's error 1/spp reaches the best method's 0.01 only at
    128 spp, so the ladder goes on to 128 (within its cap) and the speed-up is read, not bounded."""
    from sparselt.experiments.comparison_cells import ladder_search

    def run_rung(spp):
        return [0.01 * spp + 0.04]

    ladder = ladder_search(run_rung, [0.15], smallest_budget=8, maximum_spp=4096,
                           rung_error=lambda spp: 1.0 / spp, target_error=0.01)
    assert ladder["spps"][-1] == 128 and not ladder["capped"]
    assert ladder_search(run_rung, [0.15], smallest_budget=8, maximum_spp=4096)["spps"][-1] == 16
    capped = ladder_search(run_rung, [0.15], smallest_budget=8, maximum_spp=64,
                           rung_error=lambda spp: 1.0 / spp, target_error=0.01)
    assert capped["spps"][-1] == 64 and capped["capped"]



def test_the_quality_figure_draws_pt_as_the_verdicts_read_it():
    """The dashed PT curve of the quality-vs-time figure is the fit's corrected, held curve (mean_value) against
    its time line: a ladder with one rung 60% above the line shows that rung's measured mean, not the line."""
    from sparselt.report.comparison_figures import quality_figure
    from sparselt.report.plotting import pyplot

    rows = bent_pt_rows(lambda spp: 1.6 if spp == 128 else 1.0)
    fit = fit_baseline(rows, "pt")
    figure = quality_figure(rows, "bent", 0.01, None, fit)  # no summary: the rows' means, the untrimmed relMSE
    line = next(line for axis in figure.axes for line in axis.get_lines() if line.get_label().startswith("PT fit"))
    spps = (np.asarray(line.get_xdata()) - fit.intercept) / fit.slope
    assert np.allclose(line.get_ydata(), fit.mean_value("relmse", spps), rtol=1e-9)
    assert "rung-corrected" in line.get_label()
    measured = np.mean([row["relmse"] for row in rows if row["spp"] == 128])
    assert fit.mean_value("relmse", 128) == pytest.approx(measured, rel=1e-3)
    pyplot().close(figure)


def test_a_noise_free_baseline_is_refused_and_a_nearly_converged_one_is_not():
    """PT whose image equals the reference up to float rounding at every budget (exactly 0 at one; the camera sees
    only the environment) leaves nothing to compare: refused by name, before any ratio of rounding errors. A PT
    with a small but real error is judged as usual."""
    rows = pt_rows(c=(1e-12, 1e-12, 1e-12), floor=0.0) + method_rows("oidn", 16, 0.2, [1e-13] * 3)
    for row in rows:
        if row["method"] == "pt" and row["spp"] == 64:
            row["relmse"] = 0.0
    with pytest.raises(ValueError, match=r"pt's relMSE against the reference is at most .* no noise"):
        add_equal_time_columns(rows, baseline="pt")
    rows = pt_rows(c=(1e-6, 1.1e-6, 0.9e-6), floor=0.0) + method_rows("oidn", 16, 0.2, [1e-8] * 3)
    assert add_equal_time_columns(rows, baseline="pt") is not None
