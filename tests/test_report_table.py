"""The report table (issue 18): one object, three renderings that agree; report/ is a sink.

Markdown, CSV and HTML come from the same :class:`sparselt.report.Table`;
each must survive hostile cell text (commas, quotes, pipes, newlines, HTML
metacharacters) and show the same rows and columns as the others.
"""

import ast
import csv
import io
import re
from html.parser import HTMLParser
from pathlib import Path

import pytest

from sparselt.report import Table
from sparselt.report.page import STYLE
from sparselt.report.table import thesis_display_text
from sparselt.thesis.numbers import thesis_tables

HOSTILE = 'a, "quoted" | piped\nsecond line'


def _table():
    return Table(caption="Table 9.9: <b>hostile</b> & co", columns=["thesis value", "ours", "note"],
                 kinds=["thesis", "ours", ""],
                 rows=[("first", ["0,849482", "0.8512", HOSTILE]), ("x < y & z > w", ["1", 2, None])],
                 notes=["Mean over seeds | three channels."], label_header="scene")


def _markdown_grid(text):
    """The cells of a Markdown pipe table: split at unescaped pipes, ``\\|`` and ``<br>`` decoded."""
    rows = []
    for line in text.splitlines():
        if not line.startswith("|") or set(line) <= set("|-"):
            continue
        cells = re.split(r"(?<!\\)\|", line.strip())[1:-1]
        rows.append([cell.strip().replace("\\|", "|").replace("<br>", "\n") for cell in cells])
    return rows


class _HtmlGrid(HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.rows, self.classes, self._cell = [], [], None

    def handle_starttag(self, tag, attributes):
        if tag == "tr":
            self.rows.append([])
            self.classes.append([])
        elif tag in ("td", "th"):
            self._cell = ""
            self.classes[-1].append(dict(attributes).get("class", ""))
        elif tag == "br" and self._cell is not None:
            self._cell += "\n"

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self.rows[-1].append(self._cell)
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data


def _html_grid(text):
    parser = _HtmlGrid()
    parser.feed(text)
    return parser


def test_a_hostile_cell_round_trips_through_the_csv_reader():
    table = _table()
    rows = list(csv.reader(io.StringIO(table.csv())))
    assert rows[0] == ["scene", "thesis value", "ours", "note"]
    assert rows[1] == ["first", "0.849482", "0.8512", HOSTILE]  # the thesis's decimal comma shown as a point
    assert rows[2] == ["x < y & z > w", "1", "2", ""]  # numbers as text as given, None empty
    assert len(rows) == 3  # no caption, no notes: header and rows only


def test_markdown_escapes_pipes_and_keeps_one_line_per_row():
    text = _table().markdown()
    assert text.startswith("# Table 9.9: <b>hostile</b> & co\n")
    assert 'a, "quoted" \\| piped<br>second line' in text
    table_lines = [line for line in text.splitlines() if line.startswith("|")]
    assert len(table_lines) == 4  # header, rule, two rows: the newline did not break the row
    assert all(len(re.findall(r"(?<!\\)\|", line)) == 5 for line in table_lines)
    assert "Mean over seeds \\| three channels." in text


def test_html_escapes_markup_and_shades_thesis_columns():
    text = _table().html()
    assert "<b>" not in text and "&lt;b&gt;hostile&lt;/b&gt; &amp; co" in text
    assert "x &lt; y &amp; z &gt; w" in text and "&quot;quoted&quot;" in text
    parsed = _html_grid(text)
    assert parsed.classes[0] == ["label", "thesis", "ours", ""]
    for classes in parsed.classes[1:]:
        assert classes == ["label", "thesis", "ours", ""]
    assert re.search(r"td\.thesis[^{]*\{[^}]*background", STYLE)  # the page shades them
    assert re.search(r"td\.ours[^{]*\{[^}]*background", STYLE)
    assert '<p class="table-note">Mean over seeds | three channels.</p>' in text


def test_the_three_renderings_have_the_same_rows_and_columns():
    table = _table()
    expected = table.grid()
    assert list(csv.reader(io.StringIO(table.csv()))) == expected
    assert _markdown_grid(table.markdown()) == expected
    assert _html_grid(table.html()).rows == expected
    assert len(expected) == 1 + len(table.rows) and all(len(row) == 1 + len(table.columns) for row in expected)


def test_a_table_survives_its_json_record():
    from dataclasses import asdict
    import json

    table = _table()
    again = Table.from_record(json.loads(json.dumps(asdict(table))))
    assert again == table and again.thesis_columns == [0]
    legacy = {"caption": "c", "columns": ["a"], "kinds": ["thesis"], "rows": [["r", ["1"]]]}  # before notes existed
    assert Table.from_record(legacy).grid() == [["", "a"], ["r", "1"]]


@pytest.mark.parametrize("printed, shown", [
    ("0,849482", "0.849482"),  # Table 5.1, Cornell R, Gini Magnitude
    ("0,845120", "0.845120"),  # trailing zeros kept: the thesis's digits
    ("0,689", "0.689"),  # a three-digit fraction after 0 is a decimal, not thousands
    ("489", "489"),  # Table 6.2: integers unchanged
    ("553647600", "553647600"),  # Table 6.1: total samples
    ("$O(N)$", "O(N)"),  # Table 4.1
    ("$O(KP)$", "O(KP)"),
    ("$O(K + P)$", "O(K + P)"),
    ("$O(N \\log(N))$", "O(N log N)"),
    ("$O(P \\log(P))$", "O(P log P)"),
    ("O(P \\log(P))", "O(P log P)"),  # dollars already stripped by the caller (thesis_complexity)
    ("$N^{2}$", "N\u00b2"), ("$N^2 \\cdot K$", "N\u00b2 \u00b7 K"), ("$\\alpha$", "\u03b1"),
    ("553,647,600", "553,647,600"), ("71,722", "71,722"),  # thousands separators are not decimal commas
    ("-", "-"), ("", ""), ("a note, with a comma", "a note, with a comma"),
])
def test_thesis_display_text(printed, shown):
    assert thesis_display_text(printed) == shown


def test_every_thesis_cell_displays_with_a_decimal_point_and_no_latex():
    """Every cell of thesis_tables.json: numbers read back as the transcribed value, formulas as plain text."""
    cells = [cell for table in thesis_tables()["tables"].values() for row in table["rows"]
             for cell in row["cells"].values()]
    assert len(cells) > 100
    for cell in cells:
        shown = thesis_display_text(cell["text"])
        assert "," not in shown and "$" not in shown and "\\" not in shown and "{" not in shown, (cell, shown)
        if cell["value"] is not None:
            assert float(shown) == pytest.approx(cell["value"], rel=1e-12), cell


def test_thesis_cells_are_shown_converted_in_every_rendering_and_kept_as_given():
    table = Table(caption="c", columns=["thesis", "ours", "setting"], kinds=["thesis", "ours", ""],
                  rows=[("r", ["$O(N \\log(N))$", "0,5", "0,5"]), ("s", ["0,6042", "1", "x"])])
    assert table.rows[1] == ("s", ["0,6042", "1", "x"])  # the printed text stays in the object (and its record)
    assert table.grid()[1:] == [["r", "O(N log N)", "0,5", "0,5"], ["s", "0.6042", "1", "x"]]  # only thesis cells
    assert "| s | 0.6042 | 1 | x |" in table.markdown() and "0,6042" not in table.markdown()
    assert "<td class=\"thesis\">O(N log N)</td>" in table.html() and "\\log" not in table.html()
    assert "0.6042" in table.csv() and "0,6042" not in table.csv()
    assert '<table id="t-1">' in table.html(identifier="t-1")


def test_thesis_display_text_needs_text():
    with pytest.raises(TypeError, match="a string"):
        thesis_display_text(0.5)


@pytest.mark.parametrize("arguments, error, message", [
    (dict(caption="c", columns=["a", "b"], rows=[("r", ["1"])]), ValueError, r"row 'r' has 1 cells for 2 columns"),
    (dict(caption="c", columns=["a"], rows=[], kinds=["thesis", "ours"]), ValueError, "kinds has 2 entries"),
    (dict(caption="c", columns=["a"], rows=[], kinds=["mine"]), ValueError, "'mine' is not one of"),
    (dict(caption=3, columns=["a"], rows=[]), TypeError, "caption"),
    (dict(caption="c", columns=[1], rows=[]), TypeError, "headers"),
], ids=["short-row", "kinds-length", "unknown-kind", "caption-type", "header-type"])
def test_table_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        Table(**arguments)


# ------------------------------------------------------------------------------ report/ is a sink

REPORT = Path(__file__).resolve().parents[1] / "src" / "sparselt" / "report"


def _imports(path):
    """Every module a file imports: absolute names, and relative ones resolved against sparselt.report."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = ["sparselt", "report"][: max(0, 2 - node.level + 1)] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            names.append(module)
            names += [f"{module}.{alias.name}" for alias in node.names]  # `from .. import experiments`
    return names


def test_report_imports_nothing_from_experiments():
    files = sorted(REPORT.glob("*.py"))
    assert {path.name for path in files} >= {"__init__.py", "table.py", "page.py", "comparison.py"}
    for path in files:
        for name in _imports(path):
            assert not (name == "sparselt.experiments" or name.startswith("sparselt.experiments.")), (path.name, name)


def test_the_import_check_sees_relative_imports(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("from ..experiments.compare import compare\nfrom .. import experiments\nimport sparselt.experiments\n")
    names = _imports(sample)
    assert "sparselt.experiments.compare" in names and "sparselt.experiments" in names
