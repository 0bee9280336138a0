"""The thesis tables transcribed in sparselt/data/thesis_tables.json."""

from pathlib import Path

import pytest

from sparselt.thesis.numbers import thesis_table, thesis_tables, thesis_value

THESIS = Path(__file__).resolve().parents[2] / "shared" / "thesis" / "thesis.md"
TABLE_NUMBERS = ["4.1", "5.1", "5.2", "6.1", "6.2", "6.3", "7.1", "7.2", "7.3", "8.1", "8.2"]


@pytest.fixture(scope="module")
def thesis_lines():
    if not THESIS.exists():
        pytest.skip(f"thesis text not available at {THESIS}")
    return THESIS.read_text(encoding="utf-8").splitlines()


def _text_before_caption(lines, number, window=30):
    """The lines printed just above the caption 'Table N.M: ...' (the table rows precede it)."""
    (index,) = [i for i, line in enumerate(lines) if line.startswith(f"Table {number}: ")]
    return lines[max(0, index - window):index], lines[index]


def test_every_table_is_present_and_non_empty():
    tables = thesis_tables()["tables"]
    assert sorted(tables, key=lambda n: tuple(map(int, n.split(".")))) == TABLE_NUMBERS
    for number in TABLE_NUMBERS:
        table = thesis_table(number)
        assert table["caption"] and table["rows"] and table["notes"]
        assert table["columns"][: len(table["label_columns"])] == table["label_columns"]
        value_columns = table["columns"][len(table["label_columns"]):]
        for row in table["rows"]:
            assert list(row["cells"]) == value_columns
            for cell in row["cells"].values():
                assert cell["text"]


def test_values_agree_with_printed_text():
    for number in TABLE_NUMBERS:
        for row in thesis_table(number)["rows"]:
            for cell in row["cells"].values():
                printed = cell["text"].replace(",", ".")
                if cell["value"] is None:
                    with pytest.raises(ValueError):
                        float(printed)
                else:
                    assert cell["value"] == float(printed)


def test_only_table_4_1_has_non_numeric_cells():
    for number in TABLE_NUMBERS:
        values = [cell["value"] for row in thesis_table(number)["rows"] for cell in row["cells"].values()]
        if number == "4.1":
            assert all(value is None for value in values)
        else:
            assert None not in values


def test_every_row_is_printed_above_its_caption(thesis_lines):
    for number in TABLE_NUMBERS:
        table = thesis_table(number)
        block, caption_line = _text_before_caption(thesis_lines, number)
        assert caption_line == f"Table {number}: {table['caption']}"
        for position, row in enumerate(table["rows"]):
            labels = row["label"] if isinstance(row["label"], list) else [row["label"]]
            texts = [cell["text"] for cell in row["cells"].values()]
            printed = "\t".join(labels + texts)
            # Tables 5.1 and 5.2 print the scene only on the first row of each group.
            printed_without_scene = "\t".join([""] + labels[1:] + texts)
            assert printed in block or printed_without_scene in block, (number, row["label"])
            assert len(texts) >= 2
            for text in texts:
                assert any(text in line for line in block), (number, row["label"], text)


@pytest.mark.parametrize(
    ("table", "row", "column", "expected"),
    [
        ("5.1", ("Cornell", "R"), "Gini Magnitude", 0.849482),
        ("5.2", ("San Miguel Indirect Only", "B"), "Gini Energy", 0.986865),
        ("6.1", "4", "Total Samples", 717225300),
        ("6.1", "4", "Samples per Pixel", 71722),
        ("6.1", 32, "Support Detection", 3019898520),
        ("6.2", "2000x2000", "Samples per Pixel", 197),
        ("6.2", "2000x2000", "SFT Importance Sampling Time (s)", 387),
        ("6.2", "2000x2000", "Path Tracing Time (s)", 304),
        ("6.3", "4000x4000", "Samples per Pixel", 124),
        ("6.3", "4000x4000", "SFT Importance Sampling Time (s)", 5316),
        ("6.3", "4000x4000", "Path Tracing Time", 5172),
        ("7.1", "0,25", "Time", 0.4384),
        ("7.2", 1.0, "Frequency Energy", 0.9537),
        ("7.3", 0.05, "Time", 0.0413),
        ("8.1", "327", "Total", 51.6),
        ("8.2", "40", "Integration", 0.012),
    ],
)
def test_spot_values_without_the_thesis_file(table, row, column, expected):
    assert thesis_value(table, row, column) == pytest.approx(expected, rel=0, abs=0)


def test_printed_text_is_kept():
    assert thesis_table("5.1")["rows"][1]["cells"]["Gini Magnitude"]["text"] == "0,845120"
    assert thesis_table("4.1")["rows"][0]["cells"]["Time Complexity"]["text"] == "$O(N)$"


def test_unknown_table_names_it_and_the_known_ones():
    with pytest.raises(ValueError, match=r"9\.9") as error:
        thesis_table("9.9")
    for number in TABLE_NUMBERS:
        assert number in str(error.value)


def test_unknown_row_and_column_are_named():
    with pytest.raises(ValueError, match="8000x8000") as error:
        thesis_value("6.2", "8000x8000", "Samples per Pixel")
    assert "2000x2000" in str(error.value)
    with pytest.raises(ValueError, match="Rendering Time") as error:
        thesis_value("6.2", "2000x2000", "Rendering Time")
    assert "Path Tracing Time (s)" in str(error.value)
    with pytest.raises(ValueError, match="not a number"):
        thesis_value("4.1", "Sum Integration", "Time Complexity")
    with pytest.raises(ValueError, match=r"9\.9"):
        thesis_value("9.9", "4", "Total Samples")
