"""The thesis's findings as data (issue 21): every stored direction holds on the thesis's own numbers, and the
verdict generator says 'same' for numbers that go the thesis's way and 'OPPOSITE' for numbers that do not."""

import pytest

from sparselt.thesis.findings import figure_finding, judge, table_claim, table_claims, thesis_findings, thesis_quantity
from sparselt.thesis.numbers import thesis_tables

ALL_CLAIMS = [(number, claim) for number, claims in thesis_findings()["tables"].items() for claim in claims]


@pytest.mark.parametrize("number,claim", ALL_CLAIMS, ids=[f"{n}-{c['id']}" for n, c in ALL_CLAIMS])
def test_every_stored_direction_holds_on_the_thesis_numbers(number, claim):
    assert number in thesis_tables()["tables"]
    finding = judge(claim, None)
    if claim.get("quantity", claim.get("larger", {})).get("table"):
        assert finding.thesis_holds is True, finding.thesis_sentence
    assert finding.agrees is None and "not measured" in finding.our_sentence


def test_every_figure_claim_is_well_formed():
    for number, record in thesis_findings()["figures"].items():
        assert record["finding"].endswith("."), number
        if "claim" in record:
            judge(record["claim"], [1.0, 2.0] if record["claim"]["type"] != "greater" else ([2.0], [1.0]))


def _opposite(claim, values):
    """Numbers that go against the claim: a reversed trend, swapped sides, or values across the threshold."""
    if claim["type"] == "trend":
        return list(reversed(values))
    if claim["type"] == "greater":
        return values[1], values[0]
    return [2 * claim["than"] - value for value in values]


# One claim per chapter: our numbers shaped like the thesis's (its own values, moved), agreeing then disagreeing.
PER_CHAPTER = [("4", None), ("5.1", "fourier-energy-sparse"), ("5.2", "direct-light-sparser"),
               ("6.1", "more-samples-than-cells"), ("6.2", "sft-guiding-slower"), ("7.1", "fourier-sparser"),
               ("7.2", "fourier-gini-falls"), ("7.3", "canonical-denser"), ("8.1", "cosamp-dominates"),
               ("8.2", "total-rises")]


@pytest.mark.parametrize("number,claim_id", PER_CHAPTER[1:])
def test_the_verdict_agrees_with_agreeing_numbers_and_not_with_disagreeing_ones(number, claim_id):
    claim = table_claim(number, claim_id)
    if claim["type"] == "greater":
        thesis = (thesis_quantity(claim["larger"]), thesis_quantity(claim["smaller"]))
        agreeing = ([value * 1.01 for value in thesis[0]], [value * 0.99 for value in thesis[1]])
    else:
        thesis = thesis_quantity(claim["quantity"])
        agreeing = [value * 1.001 for value in thesis]
    same = judge(claim, agreeing, subject="a test")
    noun = "direction" if claim["type"] == "trend" else "finding"
    assert same.agrees is True and f"the same {noun}" in same.our_sentence and "a test" in same.our_sentence
    other = judge(claim, _opposite(claim, agreeing))
    assert other.agrees is False and f"the OPPOSITE {noun}" in other.our_sentence
    assert "Thesis" in other.thesis_sentence and claim["statement"] in other.thesis_sentence


def test_chapter_4_and_8_figure_claims_judge_measured_ratios():
    speed = table_claim("4.1", "convolution-fastest")
    assert judge(speed, ([0.9], [0.01])).agrees is True and judge(speed, ([0.01], [0.9])).agrees is False
    loses = figure_finding("8.1")["claim"]
    assert judge(loses, [2.3, 45.0]).agrees is True
    assert judge(loses, [2.3, 0.8]).agrees is False  # one budget where CoSaMP beats PT breaks "at every budget"
    better = figure_finding("8.8")["claim"]
    assert judge(better, [0.9]).agrees is True and judge(better, [1.2]).agrees is False


def test_the_gap_is_stated_in_numbers():
    claim = table_claim("7.3", "canonical-denser")
    sentence = judge(claim, [0.83, 0.70, 0.64]).our_sentence
    assert "-0.19" in sentence and "-0.648" in sentence  # our change against the thesis's (0.689 -> 0.0413)


def test_unknown_claims_and_figures_are_named_errors():
    with pytest.raises(ValueError, match="claims: canonical-denser"):
        table_claim("7.1", "nonsense")
    with pytest.raises(ValueError, match="figures"):
        figure_finding("9.9")
    assert table_claims("2.1") == []
