"""Verdicts that survive hard scenes (issue 35): the trimmed relMSE and its outlier share, reference-limited cells
with the reference they need, speed-ups that are lower bounds beyond PT's ladder (never infinite), and a ratio
and a speed-up that always agree.

Rows are synthetic (plain dicts, as a comparison's cells hold them) so that every expected value is known.
"""

import math

import numpy as np
import pytest

from sparselt.analysis.metrics import (
    pixel_relative_squared_error,
    relative_mean_squared_error,
    trimmed_pixel_count,
    trimmed_relative_mean_squared_error,
)
from sparselt.experiments.equal_time import (
    REFERENCE_LIMITED_SHARE,
    equal_quality_speedup,
    judge,
)
from sparselt.rendering.baseline import reference_spp_for_floor
from sparselt.report.comparison import equal_time_table, verdict_sentence

SEEDS = (1, 2, 3)
METHODS = {"pt": {"baseline": True}, "m": {}}


# ------------------------------------------------------------------------------------------- the trimmed metric
def test_trimmed_relmse_discards_the_top_tenth_of_a_percent_and_at_least_one_pixel():
    assert trimmed_pixel_count(100) == 1 and trimmed_pixel_count(4096) == 4 and trimmed_pixel_count(1) == 0
    assert trimmed_pixel_count(1920 * 1080) == 2073
    generator = np.random.default_rng(5)
    reference = generator.uniform(0.2, 1.0, (64, 64, 3))
    image = reference + generator.normal(0.0, 0.05, reference.shape)
    image[10, 20] += 500.0  # one firefly
    errors = pixel_relative_squared_error(image, reference)
    assert errors.mean() == pytest.approx(relative_mean_squared_error(image, reference), rel=1e-12)
    trimmed, share, kept = trimmed_relative_mean_squared_error(image, reference)
    assert kept.sum() == 64 * 64 - 4 and not kept[10, 20]
    assert trimmed == pytest.approx(np.sort(errors.ravel())[:-4].mean(), rel=1e-12)
    assert share > 0.99  # the firefly holds nearly all of relMSE
    assert trimmed < 1e-2 < relative_mean_squared_error(image, reference)


def test_outlier_share_is_small_for_uniform_noise_and_zero_for_equal_images():
    generator = np.random.default_rng(6)
    reference = generator.uniform(0.2, 1.0, (100, 100, 3))
    image = reference * (1 + generator.normal(0.0, 0.05, reference.shape))
    _, share, _ = trimmed_relative_mean_squared_error(image, reference)
    assert 0.001 < share < 0.02  # 10 of 10,000 pixels: about their share of the sum, not half of it
    assert trimmed_relative_mean_squared_error(reference, reference)[:2] == (0.0, 0.0)


# ------------------------------------------------------------------------------------------- synthetic rows
def pt_rows(spps=(8, 16, 32, 64, 128, 256, 512), intercept=0.01, slope=0.001, c=(1.0, 1.1, 0.9), floor=0.0,
            reference_floor=0.0):
    """PT rows exactly on t = a + b spp and relMSE = c_seed / spp + floor + the reference's floor."""
    return [{"method": "pt", "spp": spp, "seed": seed, "seconds_total": intercept + slope * spp,
             "relmse": c[index] / spp + floor + reference_floor, "ssim": 0.9,
             "reference_relmse_floor": reference_floor, "reference_spp": 1024}
            for spp in spps for index, seed in enumerate(SEEDS)]


def method_rows(spp, seconds, relmses, reference_floor=0.0, **columns):
    return [dict({"method": "m", "spp": spp, "seed": seed, "seconds_total": seconds, "relmse": relmse, "ssim": 0.9,
                  "reference_relmse_floor": reference_floor, "reference_spp": 1024}, **columns)
            for seed, relmse in zip(SEEDS, relmses)]


def record_of(rows):
    _, summary = judge(rows, baseline="pt")
    return next(record for record in summary if record["method"] == "m")


def test_a_noisy_reference_makes_a_cell_reference_limited_naming_the_reference_it_needs():
    """The reference's floor 0.05 against a method measured at 0.06: its debiased error (0.01) is below the
    floor, so no ratio, verdict or speed-up is claimed, and the sentence names the reference that would
    resolve it: the floor must fall below 0.01, 1024 x 0.05 / 0.01 = 5120 spp."""
    floor = 0.05
    rows = pt_rows(reference_floor=floor) + method_rows(16, 0.05, [0.059, 0.06, 0.061], reference_floor=floor)
    record = record_of(rows)
    assert record["verdict"] == "reference-limited"
    assert record["relmse_ratio"] == "" and record["speedup_equal_quality"] == "" and record["speedup_ci_low"] == ""
    assert record["reference_spp_needed"] == 5120
    assert reference_spp_for_floor(floor, 1024, 0.01) == 5120
    sentence = verdict_sentence("m", [record])
    assert "reference-limited" in sentence and "5120" in sentence and "inf" not in sentence
    # The same method against a reference 100 times better is judged (0.01 against PT's 0.025 at 40 spp).
    rows = pt_rows(reference_floor=floor / 100) + method_rows(16, 0.05, [0.0104, 0.0105, 0.0106],
                                                              reference_floor=floor / 100)
    assert record_of(rows)["verdict"] == "wins"


def test_the_reference_limited_rule_is_half_of_the_measured_error():
    assert REFERENCE_LIMITED_SHARE == 0.5
    floor = 0.01
    pt_at_40 = 1.0 / 40 + floor
    below = record_of(pt_rows(reference_floor=floor) + method_rows(16, 0.05, [0.0199] * 3, reference_floor=floor))
    above = record_of(pt_rows(reference_floor=floor) + method_rows(16, 0.05, [0.0201, 0.0202, 0.0203],
                                                                    reference_floor=floor))
    assert below["verdict"] == "reference-limited" and above["verdict"] == "wins"
    assert above["relmse_pt_equal_time"] == pytest.approx(pt_at_40, rel=1e-9)


def test_a_speedup_beyond_the_ladder_is_a_lower_bound_never_infinite():
    """PT's ladder ends at 512 spp (0.522 s); a method at 0.05 s with relMSE 0.001 would need PT at about 1000
    spp: the speed-up is written '> 10.4x (PT's ladder ends at 512 spp)'. Below PT's fitted floor (a biased PT) the
    old protocol said 'inf'; now the same lower bound."""
    for pt_floor in (0.0, 0.002):
        rows = pt_rows(floor=pt_floor) + method_rows(16, 0.05, [0.00099, 0.001, 0.00101])
        record = record_of(rows)
        assert record["speedup_bound"] == ">" and record["pt_ladder_spp"] == 512
        assert record["speedup_equal_quality"] == pytest.approx((0.01 + 0.512) / 0.05, rel=1e-9)
        assert math.isfinite(record["speedup_ci_low"]) and math.isfinite(record["speedup_ci_high"])
        assert record["speedup_ci_high_bound"] == ">"  # its interval's upper end too
        table = equal_time_table([record], methods=METHODS).markdown()
        assert "> 10.4x [" in table and ">10.4] (PT's ladder ends at 512 spp)" in table and "inf" not in table
        assert "(PT's ladder ends at 512 spp)" in verdict_sentence("m", [record])


def test_the_speedup_is_one_at_a_ratio_of_one_and_decreases_with_it():
    rows = pt_rows(floor=0.001) + method_rows(16, 0.05, [0.02, 0.021, 0.022])
    fit, _ = judge(rows, baseline="pt")
    assert equal_quality_speedup(fit, "relmse", 1.0, 0.05, 0.0) == (pytest.approx(1.0, rel=1e-9), "")
    values = [equal_quality_speedup(fit, "relmse", ratio, 0.05, 0.0)[0] for ratio in np.linspace(0.2, 3.0, 30)]
    assert all(a >= b for a, b in zip(values, values[1:]))


@pytest.mark.parametrize("case", range(40))
def test_the_ratio_and_the_speedup_give_the_same_verdict_under_noisy_timings(case):
    """Random methods with noisy repeats (the timing's uncertainty widens the ratio's interval): the speed-up's
    interval excludes 1 exactly when the ratio's does, on the same side."""
    generator = np.random.default_rng(1000 + case)
    seconds = generator.uniform(0.03, 0.4)
    pt_spp = (seconds - 0.01) / 0.001
    level = generator.uniform(0.3, 2.5) * 1.0 / pt_spp
    relmses = level * (1 + generator.normal(0, generator.uniform(0.01, 0.3), 3))
    spread = generator.uniform(0.0, 0.5)
    rows = pt_rows(floor=0.0005) + method_rows(16, seconds, np.abs(relmses) + 1e-6,
                                               seconds_total_min=seconds * (1 - spread / 2),
                                               seconds_total_max=seconds * (1 + spread / 2))
    record = record_of(rows)
    assert record["verdict"] in ("wins", "loses", "within noise")
    low, high = record["speedup_ci_low"], record["speedup_ci_high"]
    speedup_verdict = "wins" if low > 1 else "loses" if high < 1 else "within noise"
    assert speedup_verdict == record["verdict"], record


def test_rows_and_cells_decided_by_a_few_pixels_are_marked():
    rows = pt_rows() + method_rows(16, 0.05, [0.02, 0.021, 0.022])
    for row, share in zip(rows[-3:], (0.4, 0.7, 0.9)):
        row.update(outlier_share=share)
    for row in rows[:-3]:
        row.update(outlier_share=0.1)
    _, summary = judge(rows, baseline="pt")
    record = next(entry for entry in summary if entry["method"] == "m")
    assert record["outlier_share"] == pytest.approx(2.0 / 3) and record["outlier_dominated"] is True
    assert [row["outlier_dominated"] for row in rows[-3:]] == [False, True, True]
    assert "0.67 !" in equal_time_table([record], methods=METHODS).markdown()
    assert "more than half of its relMSE" in verdict_sentence("m", [record])


def test_a_trimmed_metric_that_pt_does_not_follow_hands_the_headline_to_the_untrimmed_one():
    """Sunlight through glass at a few spp: PT's trimmed relMSE rises with spp (measured on sunlit-room: 0.09 at
    8 and 16 spp, 2.0 at 32, 4.6 at 64, 2.2 at 256) because trimming discards the only pixels that found the sun.
    No c/spp fit describes it, so the untrimmed relMSE decides, and the table says why."""
    rows = pt_rows(spps=(8, 16, 32, 64, 128, 256))
    trimmed = {8: 0.088, 16: 0.084, 32: 1.97, 64: 4.59, 128: 3.27, 256: 2.18}
    for row in rows:
        row.update(relmse_trimmed=trimmed[row["spp"]] * (1 + 0.01 * row["seed"]), reference_relmse_floor_trimmed=0.0)
    method = method_rows(16, 0.05, [0.02, 0.021, 0.022], relmse_trimmed=0.01, reference_relmse_floor_trimmed=0.0)
    fit, summary = judge(rows + method, baseline="pt")
    assert fit.residuals["relmse_trimmed"] > 0.5 > fit.residuals["relmse"]
    record = next(entry for entry in summary if entry["method"] == "m")
    assert record["headline_metric"] == "relmse" and record["verdict"] == record["relmse_verdict"]
    assert "The untrimmed relMSE decides here" in equal_time_table([record], methods=METHODS).markdown()
    clean = pt_rows(spps=(8, 16, 32, 64, 128, 256))  # a trimmed metric that follows c/spp stays the headline
    for row in clean:
        row.update(relmse_trimmed=0.8 * row["relmse"], reference_relmse_floor_trimmed=0.0)
    _, summary = judge(clean + method, baseline="pt")
    assert summary[-1]["headline_metric"] == "relmse_trimmed"
