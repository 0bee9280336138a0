"""Every committed experiment's numbers reproduce from its folder (issue 34, thesis 8.1.1 and 6.1).

``docs/experiments/`` holds measured runs. Each comparison folder's cell rows
(``results.csv``) go back through the project's own equal-time protocol
(:func:`~sparselt.experiments.equal_time.add_equal_time_columns`,
:func:`~sparselt.experiments.equal_time.summarize`, as ``compare`` calls
them) and its report tables (:mod:`sparselt.report.comparison`), and every
committed number derived from the rows must come out again: ``summary.csv``,
the rows' equal-time columns, PT's fit in ``compare.json``, ``equal_time``,
``table_8`` and our ``table_6`` (the thesis's table beside it holds the
thesis's numbers, not the run's). Nothing renders; the module reads text.

Tolerances
----------
Strings, integers and verdicts are compared exactly. ``results.csv`` prints
six significant digits, so the recomputation starts from inputs rounded by
up to 5e-6 relative. The protocol subtracts nearly equal numbers (an
interval's ``mean - t s / sqrt(n)``, ``relMSE - floor``, a time minus PT's
fitted time) and so amplifies that rounding: in the committed folders by at
most 6.2e-4 relative (PT's time-fit residual), 1e-4 for every summary value.
The files are fixed, so :data:`RELATIVE` = 1e-3 is a deterministic bound
above that, and far below what any change to the protocol moves (a quantile,
a fit or the floor's handling moves these numbers by percent). Tables print
3 or 4 digits: a printed number must lie within one unit of its last printed
digit of the committed one (two values closer than half a unit print at most
one unit apart), and the text around the numbers must be equal.

The one exception: the twelve folders committed before the equal-time
protocol (commit e087a97, 2026-12-02; their ``compare_summary.json`` marks
them) have no ``summary.csv``, and their rows' PT values at equal time came
from the protocol it replaced (PT's mean curve interpolated in log-log, not
its fits), so their ``equal_time.md`` is not recomputed;
:func:`test_pre_protocol_tables_reproduce` checks the rest. The Table 6.1
folders and ``reproduce-medium``'s Table 4.1 are checked from their
records; :data:`NOT_RECOMPUTED` names what needs rendering to recompute.
"""

import csv
import io
import json
import math
import re
from pathlib import Path

import pytest

from sparselt.experiments.equal_time import DERIVED_ROW_COLUMNS, judge  # stripped, recomputed, compared
from sparselt.experiments.integration_report import (
    IntegrationMeasurement,
    complexity_table,
    measurement_table,
    summarise,
)
from sparselt.report.comparison import equal_time_table, table_6, table_8
from sparselt.results import reference_spp, report_config

EXPERIMENTS = Path(__file__).resolve().parents[1] / "docs" / "experiments"
#: Relative tolerance for numbers recomputed from ``results.csv``'s six printed digits (module docstring).
RELATIVE = 1e-3
INTEGER_COLUMNS = {"spp", "seed", "seeds", "path_samples", "timing_repeats", "reference_spp", "reference_spp_needed",
                   "pt_ladder_spp"}
BOOLEAN_COLUMNS = {"timing_noisy", "reference_limited", "outlier_dominated", "verdicts_disagree"}
TEXT_COLUMNS = {"method", "verdict", "ssim_verdict", "flip_verdict", "relmse_verdict", "relmse_trimmed_verdict",
                "headline_metric", "speedup_bound", "speedup_ci_low_bound", "speedup_ci_high_bound"}

#: Comparison folders of the current protocol (``summary.csv``), reproduce's nested ones included.
COMPARISONS = sorted(path.parent for path in EXPERIMENTS.rglob("summary.csv"))
#: Comparison folders written before the equal-time protocol (issues 10-13, 2026-12-01).
PRE_PROTOCOL = sorted(path.parent for path in EXPERIMENTS.glob("*/compare_summary.json"))
TABLE_6_1 = sorted(EXPERIMENTS.glob("table61-*"))
#: Committed suites (``sparselt suite``, issue 36): their scenes are comparison folders, checked as such.
SUITES = sorted(path.parent for path in EXPERIMENTS.rglob("suite.json"))
#: Their ``table_6_1.md``'s columns of our numbers: ``table_6_1.csv``'s column and the format it was printed with.
TABLE_6_1_PRINTED = {
    "alpha": ("alpha", "g"), "spp/point": ("samples_per_point", "g"), "support detection": ("support_samples", ","),
    "magnitude estimation": ("magnitude_samples", ","), "total samples": ("total_samples", ","),
    "samples per pixel": ("samples_per_pixel", ".1f"), "lattice points / N": ("lattice_fraction", ".3f"),
    "SFT SSIM": ("sft_ssim", ".3f"), "SFT relMSE": ("sft_relmse", ".3g"),
    "PT same samples SSIM": ("pt_equal_samples_ssim", ".3f"),
    "PT same samples relMSE": ("pt_equal_samples_relmse", ".3g"),
    "PT same time relMSE": ("pt_equal_time_relmse", ".3g"), "seconds": ("seconds", ".1f"),
}
#: Committed folders whose numbers need rendering or signals to recompute (none is cheap).
NOT_RECOMPUTED = {
    "study-l1-iterations": "its rows are renders scored against references that are not committed (its scripts "
                           "re-render them)",
    "compressibility-16x16": "its script acquires four 16x16x4^8 path signals (about 2.5 minutes)",
    "gradient-shift-map": "its ratios are per-pixel statistics of rendered base and offset paths",
    "reproduce-medium": "chapters 5-7 and its page summarise signals and SFT records not committed (figures and "
                        "Markdown only); its four comparison folders (chapter6/maps-*, chapter8/compare-*) and "
                        "chapter 4's Table 4.1 are checked",
}


# ------------------------------------------------------------------------------------------------ reading
def _value(column, text):
    if text == "" or column in TEXT_COLUMNS:
        return text
    if column in INTEGER_COLUMNS:
        return int(text)
    if column in BOOLEAN_COLUMNS:
        return {"True": True, "False": False}[text]
    return float(text)


def read_records(path):
    """A committed CSV (``results.csv``, ``summary.csv``) as typed dicts, through the csv module."""
    with open(path, newline="") as handle:
        return [{column: _value(column, text) for column, text in row.items()} for row in csv.DictReader(handle)]


def markdown_tables(text):
    """The pipe tables of a Markdown document, each a list of rows of cells (separator lines left out)."""
    tables, previous = [], ""
    for line in text.splitlines():
        if line.startswith("|") and not set(line) <= set("|-"):
            if not previous.startswith("|"):
                tables.append([])
            tables[-1].append([cell.strip() for cell in line.strip().strip("|").split("|")])
        previous = line
    return tables


def markdown_rows(text):
    """The rows of a Markdown document's first pipe table."""
    return markdown_tables(text)[0]


def csv_rows(text):
    return list(csv.reader(io.StringIO(text)))


def comparison_setup(folder):
    """The scene, duck-typed configuration, method records and epsilon the report functions take."""
    if (folder / "compare.json").exists():
        record = json.loads((folder / "compare.json").read_text())
        methods = record["methods"]
    else:  # the pre-protocol record: roles were read from the names then (guided methods by their prefix)
        record = json.loads((folder / "compare_summary.json").read_text())
        names = dict.fromkeys(row["method"] for row in read_records(folder / "results.csv"))
        methods = {name: {"baseline": name == "pt", "family": "guided" if name.startswith("guided-") else None,
                          "options": {"map_spp": record["config"].get("map_spp") or 16}} for name in names}
    return record["config"]["scene"], report_config(record["config"]), methods, record["relmse_epsilon"]


# ------------------------------------------------------------------------------------------------ comparing
#: Columns that are differences of printed numbers, with the absolute error six printed digits allow them:
#: ``timing_uncertainty``'s spread is ``(max - min) / (2 median)`` of a cell's times, each printed to six digits
#: (5e-6 relative at most), so it errs by up to 5e-6 however small it is (a spread of 0.0025 came back 0.15% off).
ABSOLUTE = {"timing_uncertainty": 1e-5}


def same_number(committed, recomputed, relative=RELATIVE, absolute=0.0):
    """Equal as ``relative`` (:data:`RELATIVE`) or ``absolute`` allows (floats; both NaN or the same infinity
    count as equal), else exactly."""
    if isinstance(committed, float) and isinstance(recomputed, (int, float)) and not isinstance(recomputed, bool):
        if math.isnan(committed):
            return math.isnan(recomputed)
        return math.isclose(recomputed, committed, rel_tol=relative, abs_tol=absolute)
    return committed == recomputed


#: A row's ratio column -> (the method's relMSE, PT's at equal time, the reference's floor) columns it is built from.
RATIO_INPUTS = {"relmse_ratio": ("relmse", "relmse_pt_equal_time", "reference_relmse_floor"),
                "relmse_trimmed_ratio": ("relmse_trimmed", "relmse_trimmed_pt_equal_time",
                                         "reference_relmse_floor_trimmed")}


def ratio_tolerance(row, column):
    """:data:`RELATIVE`, or more where a row's ratio ``(m - f) / (p - f)`` subtracts a floor ``f`` close to ``m`` or
    ``p``: six printed digits (5e-6 relative) then err by ``5e-6 (|m| + |f|) / |m - f|`` and the same for ``p``,
    times 10 for the rounding of the inputs' own inputs (a reference-limited row, whose ratio is not claimed)."""
    names = RATIO_INPUTS.get(column)
    values = [row.get(name) for name in names] if names else []
    if len(values) != 3 or not all(isinstance(value, float) and math.isfinite(value) for value in values):
        return RELATIVE
    method, pt, floor = values
    if method == floor or pt == floor:
        return RELATIVE
    amplification = (abs(method) + abs(floor)) / abs(method - floor) + (abs(pt) + abs(floor)) / abs(pt - floor)
    return max(RELATIVE, 5e-5 * amplification)


NUMBER = re.compile(r"(?<![\w.])\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def _unit(text):
    """One unit of the last printed digit of a number as printed (``'0.0123'`` -> 1e-4, ``'8.9e-05'`` -> 1e-6)."""
    mantissa, _, exponent = text.partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 10.0 ** (int(exponent or 0) - decimals)


def same_printed(committed, recomputed):
    """Two table cells equal as printed: the same text around the numbers, each number within one printed unit."""
    committed, recomputed = committed.replace(",", ""), recomputed.replace(",", "")  # thousands separators
    if NUMBER.split(committed) != NUMBER.split(recomputed):
        return False
    pairs = list(zip(NUMBER.findall(committed), NUMBER.findall(recomputed)))
    return all(abs(float(a) - float(b)) <= max(_unit(a), _unit(b)) * (1 + 1e-9) for a, b in pairs)


def assert_same_tables(committed_rows, recomputed_rows, name):
    assert len(committed_rows) == len(recomputed_rows), f"{name}: {len(committed_rows)} rows committed, " \
                                                        f"{len(recomputed_rows)} recomputed"
    for committed, recomputed in zip(committed_rows, recomputed_rows):
        assert len(committed) == len(recomputed), f"{name}: {committed} against {recomputed}"
        different = [(a, b) for a, b in zip(committed, recomputed) if not same_printed(a, b)]
        assert not different, f"{name}, row {committed[:2]}: committed against recomputed {different}"


# ------------------------------------------------------------------------------------------------ recomputing
def recompute(folder):
    """The folder's rows (derived columns recomputed), summary and PT fit, from ``results.csv`` alone."""
    committed = read_records(folder / "results.csv")
    rows = [{key: value for key, value in row.items() if key not in DERIVED_ROW_COLUMNS} for row in committed]
    record = json.loads((folder / "compare.json").read_text())
    fit, summary = judge(rows, baseline="pt", reference_spp=reference_spp(record), bias=record.get("bias"))
    return committed, rows, summary, fit


def _name(folder):
    return str(folder.relative_to(EXPERIMENTS))


def test_every_committed_folder_is_checked_or_named():
    """A folder added to docs/experiments without a check here fails, rather than going unchecked."""
    covered = {path.relative_to(EXPERIMENTS).parts[0] for path in COMPARISONS + PRE_PROTOCOL + TABLE_6_1 + SUITES}
    folders = {path.name for path in EXPERIMENTS.iterdir() if path.is_dir()}
    assert folders - covered - set(NOT_RECOMPUTED) == set()
    assert len(COMPARISONS) >= 13 and len(PRE_PROTOCOL) == 12 and len(TABLE_6_1) == 2
    assert not set(COMPARISONS) & set(PRE_PROTOCOL)


@pytest.mark.parametrize("folder", COMPARISONS, ids=_name)
def test_summary_and_equal_time_columns_reproduce(folder):
    committed, rows, summary, fit = recompute(folder)
    expected = read_records(folder / "summary.csv")
    assert [(record["method"], record["spp"]) for record in summary] == [
        (record["method"], record["spp"]) for record in expected]
    for record, want in zip(summary, expected):
        # Every committed column is recomputed; a column added to the protocol since is not in old folders.
        different = {key: (value, record.get(key, "missing")) for key, value in want.items()
                     if not same_number(value, record.get(key, "missing"), absolute=ABSOLUTE.get(key, 0.0))}
        assert not different, f"{record['method']} at {record['spp']} spp: committed, recomputed: {different}"
    for row, want in zip(rows, committed):
        different = {key: (want.get(key, ""), row.get(key, "")) for key in DERIVED_ROW_COLUMNS
                     if not same_number(want.get(key, ""), row.get(key, ""), ratio_tolerance(want, key))}
        assert not different, f"{row['method']} {row['spp']} spp seed {row['seed']}: {different}"
    pt_fit = json.loads((folder / "compare.json").read_text())["pt_fit"]
    # The intercept is a difference of times: its rounding error scales with the ladder's shortest time, not with
    # itself (sunlit-room's is -0.26 ms beside a 0.2 s rung).
    assert math.isclose(pt_fit["intercept_seconds"], fit.intercept, rel_tol=RELATIVE,
                        abs_tol=RELATIVE * fit.slope * fit.spp_range[0])
    assert same_number(pt_fit["seconds_per_spp"], fit.slope)
    # A relative residual is itself a relative error: the times' six printed digits (5e-6 relative each) move it by
    # about 1e-5 absolute however small it is (checker-dof's 0.0076 moved by 1.4e-5).
    assert math.isclose(pt_fit["time_relative_residual"], fit.time_residual, rel_tol=RELATIVE, abs_tol=1e-4)
    assert list(pt_fit["spp_range"]) == list(fit.spp_range)
    for seed, (slope, floor) in fit.relmse.items():
        assert same_number(pt_fit["relmse_per_seed"][str(seed)]["c"], slope)
        # The floor is an intercept too: its rounding error scales with the ladder's smallest relMSE, c / (largest
        # spp), not with itself (cornell-box's 2.4e-7 came back 0.12% off).
        assert math.isclose(pt_fit["relmse_per_seed"][str(seed)]["floor"], floor, rel_tol=RELATIVE,
                            abs_tol=RELATIVE * abs(slope) / fit.spp_range[1])


@pytest.mark.parametrize("folder", COMPARISONS, ids=_name)
def test_comparison_tables_reproduce(folder):
    _, rows, summary, _ = recompute(folder)
    scene, config, methods, epsilon = comparison_setup(folder)
    tables = {"equal_time": equal_time_table(summary, methods=methods, epsilon=epsilon),
              "table_8": table_8(rows, scene, config, methods=methods, epsilon=epsilon)}
    checked = 0
    for stem, table in tables.items():
        for suffix, parse, text in ((".csv", csv_rows, table.csv()), (".md", markdown_rows, table.markdown())):
            if (folder / (stem + suffix)).exists():
                assert_same_tables(parse((folder / (stem + suffix)).read_text()), parse(text), stem + suffix)
                checked += 1
    if (folder / "table_6.md").exists():
        guided = table_6(rows, scene, config, methods=methods)
        assert_same_tables(markdown_rows((folder / "table_6.md").read_text()), guided[0].grid(), "table_6.md")
    assert checked >= 2  # equal_time and table_8, as .csv or .md


@pytest.mark.parametrize("folder", PRE_PROTOCOL, ids=_name)
def test_pre_protocol_tables_reproduce(folder):
    """Folders of the replaced protocol: what today's report code still computes the same way.

    ``table_8.md``: each method's means over seeds per spp (times per phase, SSIM, relMSE, luminance ratio),
    read by column from the old per-method layout; ``table_6.md``: our table, every column (its ratio from the
    rows' committed PT values). ``equal_time.md`` is the replaced protocol's (module docstring).
    """
    rows = read_records(folder / "results.csv")
    scene, config, methods, epsilon = comparison_setup(folder)
    if (folder / "table_8.md").exists():
        # The old layout: a "## method" section per method, columns SPP .. luminance ratio (then the thesis's).
        committed, method = [], None
        for line in (folder / "table_8.md").read_text().splitlines():
            if line.startswith("## "):
                method = line[3:]
            elif line.startswith("| ") and not line.startswith("| SPP"):
                committed.append([method] + [cell.strip() for cell in line.strip("|").split("|")][:9])
        today = table_8(rows, scene, config, methods=methods, epsilon=epsilon).grid()
        assert today[0][:10] == ["method", "SPP", "Total", "Sampling", "Reconstruction", "Integration", "Other",
                                 "SSIM", "relMSE", "luminance ratio"]  # "CoSaMP" then: the reconstruction phase
        assert_same_tables(committed, [row[:10] for row in today[1:]], "table_8.md")
    if (folder / "table_6.md").exists():
        guided = table_6(rows, scene, config, methods=methods)
        assert_same_tables(markdown_rows((folder / "table_6.md").read_text()), guided[0].grid(), "table_6.md")


@pytest.mark.parametrize("folder", TABLE_6_1, ids=_name)
def test_table_6_1_reproduces_from_its_records(folder):
    """``table_6_1.csv`` holds each run's record (``records/alpha*_spp*.json``) as written; the Markdown prints it.

    ``compressibility.md`` prints ``records/compressibility.json``. The thesis's columns hold the thesis's
    numbers, not the run's, and are not compared.
    """
    with open(folder / "table_6_1.csv", newline="") as handle:
        table = list(csv.DictReader(handle))
    pixels = math.prod(json.loads((folder / "table61.json").read_text())["config"]["shape"][:2])
    for row in table:
        alpha, spp = float(row["alpha"]), int(row["samples_per_point"])
        record = json.loads((folder / "records" / f"alpha{alpha:g}_spp{spp}.json").read_text())
        expected = {"support_samples": record["support_samples"], "magnitude_samples": record["magnitude_samples"],
                    "total_samples": record["total_samples"],
                    "samples_per_pixel": record["total_samples"] / pixels,
                    "lattice_fraction": record["lattice_points"] / record["cells"],
                    "sft_ssim": record["sft"]["ssim"], "sft_relmse": record["sft"]["relmse"],
                    "pt_equal_samples_ssim": record["pt_equal_samples"]["ssim"],
                    "pt_equal_samples_relmse": record["pt_equal_samples"]["relmse"],
                    "pt_equal_time_relmse": record["pt_equal_time"]["relmse"], "seconds": record["seconds"]}
        # Full precision (repr) in this CSV: equal to the last bit.
        assert {key: float(row[key]) for key in expected} == {key: float(value) for key, value in expected.items()}
    printed = markdown_rows((folder / "table_6_1.md").read_text())
    columns = printed[0]
    assert len(printed) == len(table) + 1
    for cells, row in zip(printed[1:], table):
        for column, (key, digits) in TABLE_6_1_PRINTED.items():
            value = int(row[key]) if digits == "," else float(row[key])
            assert same_printed(cells[columns.index(column)], format(value, digits)), (column, cells)
    compressibility = json.loads((folder / "records" / "compressibility.json").read_text())
    printed = markdown_rows((folder / "compressibility.md").read_text())
    labels = printed[0][1:]  # K/N, 10 K/N, 1%, 10%
    assert [cells[0] for cells in printed[1:]] == [str(row["spp"]) for row in compressibility["rows"]]
    for cells, row in zip(printed[1:], compressibility["rows"]):
        expected = [f"{row[label]['energy']:.1%} ({row[label]['coefficients']})" for label in labels]
        assert all(map(same_printed, cells[1:], expected)), (cells, expected)


def test_table_4_1_reproduces_from_its_measurements():
    """``reproduce-medium``'s Table 4.1 (``integration.md``): fitted exponents, times, peaks from its measurements."""
    folder = EXPERIMENTS / "reproduce-medium" / "chapter4" / "integration"
    measurements = []
    with open(folder / "integration.csv", newline="") as handle:
        for row in csv.DictReader(handle):
            def number(key, kind=int, row=row):
                return None if row[key] == "" else kind(row[key])
            measurements.append(IntegrationMeasurement(
                method=row["method"], size=int(row["s"]), signal_size=int(row["N"]), coefficients=int(row["K"]),
                points=int(row["P"]), status=row["status"], reason=row["reason"], seconds=number("seconds", float),
                run_seconds=tuple(float(value) for value in row["run_seconds"].split(";") if value),
                peak_bytes=number("peak_bytes"), baseline_bytes=number("baseline_bytes"),
                estimated_bytes=number("estimated_bytes"), peak_reset=number("peak_reset", lambda text: text == "True"),
                contributing_coefficients=number("contributing_coefficients"),
                uniform_contributing_coefficients=number("uniform_contributing_coefficients"),
                image_max=number("image_max", float), check_error=number("check_error", float)))
    config = {"methods": list(dict.fromkeys(item.method for item in measurements)),
              "sizes": sorted({item.size for item in measurements})}
    result = summarise(tuple(measurements), config["sizes"], config["methods"])
    committed = markdown_tables((folder / "integration.md").read_text())
    for index, table in enumerate((complexity_table(result, config), measurement_table(result, config, "time"),
                                   measurement_table(result, config, "memory"))):
        assert_same_tables(committed[index], table.grid(), table.caption)



@pytest.mark.parametrize("folder", SUITES, ids=_name)
def test_a_suites_aggregate_reproduces_from_its_scenes(folder):
    """``aggregate.csv`` comes out again from the scenes' ``results.csv`` (the bootstrap's seed is recorded)."""
    from sparselt.experiments.suite_aggregate import aggregate

    record = json.loads((folder / "suite.json").read_text())
    assert record["status"] == "complete" and record["bootstrap"]["resamples"] > 0
    scenes = []
    for scene in record["config"]["scenes"]:
        _, rows, summary, fit = recompute(folder / "scenes" / scene["name"])
        scenes.append((scene["name"], rows, fit, summary))
    recomputed = aggregate(scenes, resamples=record["bootstrap"]["resamples"], seed=record["bootstrap"]["seed"])
    with open(folder / "aggregate.csv", newline="") as handle:
        expected = list(csv.DictReader(handle))
    assert [(row["method"], str(row["spp"])) for row in recomputed] == [(row["method"], row["spp"])
                                                                        for row in expected]
    for row, want in zip(recomputed, expected):
        for key, text in want.items():
            mine = row[key]
            if isinstance(mine, (int, float)) and text:
                assert same_number(float(text), float(mine)), (row["method"], row["spp"], key, text, mine)
            else:
                assert text == ("" if mine in ("", None) else str(mine)), (row["method"], row["spp"], key)
