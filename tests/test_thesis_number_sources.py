"""Thesis numbers come only from `sparselt.thesis.numbers` (issue 18).

Two checks: no module of the package types a number printed in a thesis
table (a grep over the source for every such literal), and the reports that
show Table 4.1 (whose cells are complexity expressions, not numbers) read it
through `thesis_numbers`: a changed transcription shows up in them.
"""

import copy
import re
from pathlib import Path

import pytest

import sparselt.thesis.numbers as thesis_numbers
from sparselt.experiments.integration_report import (
    THESIS_ROWS,
    IntegrationBenchmarkResult,
    complexity_table,
    thesis_complexity,
)
from sparselt.thesis.numbers import thesis_tables

SOURCE = Path(__file__).resolve().parents[1] / "src" / "sparselt"


def _significant_digits(text):
    digits = re.sub(r"[^0-9,.]", "", text)
    if "," in digits or "." in digits:
        digits = digits.rstrip("0").rstrip(",.")
    return len(re.sub(r"[^0-9]", "", digits).lstrip("0"))


def _thesis_literals():
    """Every numeric cell of every thesis table with three or more significant digits, as printed and with a point."""
    literals = set()
    for table in thesis_tables()["tables"].values():
        for row in table["rows"]:
            for cell in row["cells"].values():
                if cell["value"] is not None and _significant_digits(cell["text"]) >= 3:
                    literals |= {cell["text"], cell["text"].replace(",", ".")}
    return literals


def _occurrences(text, literals):
    found = []
    for literal in literals:
        if re.search(r"(?<![\w.,])" + re.escape(literal) + r"(?![\w]|[.,]\d)", text):
            found.append(literal)
    return found


def test_the_literal_scan_finds_a_typed_thesis_number(tmp_path):
    literals = _thesis_literals()
    assert {"489", "717225300", "0,849482", "0.849482", "51.6", "5316"} <= literals
    assert _occurrences("spps=(16, 64) if quick else (489,)", literals) == ["489"]
    assert _occurrences("x = 4890 + 1489 + 48.9", literals) == []


def test_no_module_types_a_number_of_a_thesis_table():
    literals = _thesis_literals()
    offenders = {}
    for path in sorted(SOURCE.rglob("*.py")):
        if path.relative_to(SOURCE).as_posix() == "thesis/numbers.py":  # its docstring's examples show what the transcription holds
            continue
        found = _occurrences(path.read_text(encoding="utf-8"), literals)
        if found:
            offenders[str(path.relative_to(SOURCE))] = sorted(found)
    assert not offenders, f"thesis numbers typed outside sparselt.thesis.numbers: {offenders}"


@pytest.fixture
def changed_table_4_1(monkeypatch):
    """The transcription with every Table 4.1 complexity replaced by a marker naming its row and column."""
    tables = copy.deepcopy(thesis_tables())
    for row in tables["tables"]["4.1"]["rows"]:
        for column, cell in row["cells"].items():
            cell["text"] = f"$MARK({row['label']}, {column})$"
    monkeypatch.setattr(thesis_numbers, "thesis_tables", lambda: tables)
    return tables


def _result():
    methods = tuple(THESIS_ROWS)
    return IntegrationBenchmarkResult(
        measurements=(), time_exponents={method: 1.0 for method in methods},
        memory_exponents={method: None for method in methods},
        fit_sizes={"time": {method: [] for method in methods}, "memory": {method: [] for method in methods}},
        ratio_size=None, speed_ratio=None, memory_ratio=None, agreement_passed=None)


def test_integration_report_reads_table_4_1_from_thesis_numbers(changed_table_4_1):
    assert thesis_complexity("convolution") == ("MARK(Convolution Integration, Time Complexity)",
                                                "MARK(Convolution Integration, Memory Complexity)")
    table = complexity_table(_result(), {"methods": list(THESIS_ROWS), "sizes": [8]})
    for method, label in THESIS_ROWS.items():
        assert f"MARK({label}, Time Complexity)" in table.markdown()
        assert f"MARK({label}, Memory Complexity)" in table.csv()
    assert [table.columns[index] for index in table.thesis_columns] == ["Table 4.1 time", "Table 4.1 memory"]


def test_reproduce_reads_table_4_1_from_thesis_numbers(changed_table_4_1):
    from sparselt.experiments.reproduce import table_4_1

    table = table_4_1(_result(), (8, 12))
    assert [label for label, _ in table.rows] == list(THESIS_ROWS.values())
    for label, cells in table.rows:
        assert cells[0] == f"MARK({label}, Time Complexity)" and cells[2] == f"MARK({label}, Memory Complexity)"


def test_table_4_1_rows_are_the_thesis_rows():
    labels = [row["label"] for row in thesis_tables()["tables"]["4.1"]["rows"]]
    assert list(THESIS_ROWS.values()) == labels
    assert thesis_complexity("sum") == ("O(N)", "O(N)")
    with pytest.raises(ValueError, match="no row for method 'magic'; methods: sum, time, time-fft, convolution"):
        thesis_complexity("magic")


def test_thesis_rows_and_text_read_the_transcription():
    from sparselt.thesis.numbers import thesis_rows, thesis_text

    assert thesis_rows("6.2", ("Samples per Pixel",)) == [("1000x1000", (489,)), ("2000x2000", (197,)),
                                                         ("4000x4000", (124,))]
    assert thesis_rows("8.1", ("Total",))[-1] == ("327", (51.6,))
    assert thesis_text("5.1", ("Cornell", "G"), "Gini Magnitude") == "0,845120"
    with pytest.raises(ValueError, match="no column 'Seconds'"):
        thesis_text("6.2", "1000x1000", "Seconds")
    with pytest.raises(ValueError, match="no row '9x9'"):
        thesis_text("6.2", "9x9", "Samples per Pixel")
    with pytest.raises(ValueError, match=r"unknown thesis table '9\.9'"):
        thesis_rows("9.9", ("Total",))


def test_the_comparison_reports_read_tables_6_and_8_from_thesis_numbers():
    from sparselt.report.comparison import THESIS_GUIDING_TABLES, THESIS_TABLES

    assert THESIS_TABLES["dof-sculptures"][2][327] == (51.6, 16, 35.3, 0.182)
    assert THESIS_GUIDING_TABLES["courtyard"][2][4000] == (124, 5316, 5172)
    assert THESIS_GUIDING_TABLES["cornell-caustics"][2][1000] == (489, 238, 199)
