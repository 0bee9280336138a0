"""Numbers printed in the tables of the thesis, for comparison with this toolkit's results.

Every numeric table of the thesis "Sparse Reconstruction of Multidimensional
Light Transport Signals" is transcribed in ``sparselt/data/thesis_tables.json``:
thesis chapter 4, Table 4.1 (integration complexities, no numeric cells);
chapter 5, Tables 5.1 and 5.2 (Gini indices of path space); chapter 6,
Tables 6.1 to 6.3 (sparse Fourier transform sample counts and times);
chapter 7, Tables 7.1 to 7.3 (Gini indices under gamma tone mapping);
chapter 8, Tables 8.1 and 8.2 (CoSaMP execution times).

Each cell keeps both its value (a JSON number, or ``null`` when the cell is not
a number) and its text as printed (the thesis uses a decimal comma, e.g.
``"0,849482"``). Row labels are the printed text of the first column, or a list
of the printed texts when a table has several label columns (Tables 5.1 and
5.2: scene and channel).

Every number of a thesis table that sparselt shows (a report's "thesis"
column, a verdict's range, the thesis-scale settings of ``reproduce``) is read
here, never typed elsewhere (``tests/test_thesis_number_sources.py`` greps
the package for the tables' literals): :func:`thesis_value` for one cell,
:func:`thesis_rows` for a table's rows, :func:`thesis_text` for a cell as
printed (Table 4.1's complexities).

Examples
--------
>>> thesis_value("6.1", "4", "Total Samples")
717225300.0
>>> thesis_value("7.1", 0.25, "Time")
0.4384
>>> thesis_value("5.1", ("Cornell", "R"), "Gini Energy")
0.999931
>>> thesis_rows("6.2", ("Samples per Pixel",))[0]
('1000x1000', (489,))
>>> thesis_text("4.1", "Convolution Integration", "Memory Complexity")
'$O(K + P)$'
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources

TABLES_FILE = "thesis_tables.json"


@lru_cache(maxsize=1)
def thesis_tables():
    """All transcribed thesis tables.

    Read once from ``thesis_tables.json`` in the :mod:`sparselt.data` package
    and cached; do not modify the returned dictionary.

    Returns
    -------
    dict
        ``{"source": "thesis.md", "tables": {number: table}}`` where each
        table has ``"caption"``, ``"columns"`` (all headers as printed, label
        columns first), ``"label_columns"``, ``"rows"`` (each with ``"label"``
        and ``"cells"``, a mapping from column header to
        ``{"value": number or None, "text": printed text}``) and ``"notes"``.
    """
    text = resources.files("sparselt.data").joinpath(TABLES_FILE).read_text(encoding="utf-8")
    return json.loads(text)


def thesis_table(number):
    """One transcribed thesis table.

    Parameters
    ----------
    number : str or float
        Table number as printed, e.g. ``"6.2"`` for thesis chapter 6,
        Table 6.2 (a float such as ``6.2`` is accepted too).

    Returns
    -------
    dict
        The table, as described in :func:`thesis_tables`.

    Raises
    ------
    ValueError
        If the thesis has no such numeric table; the message lists the known
        tables.
    """
    tables = thesis_tables()["tables"]
    key = str(number).strip()
    if key not in tables:
        raise ValueError(f"unknown thesis table {number!r}; known tables: {', '.join(tables)}")
    return tables[key]


def _printed_number(text):
    """The number a printed label denotes (decimal comma allowed), or ``None``."""
    try:
        return float(str(text).strip().replace(",", "."))
    except ValueError:
        return None


def _label_matches(label, wanted):
    """Whether a row label (printed text, or list of texts) matches the requested label."""
    if isinstance(label, list):
        if isinstance(wanted, (list, tuple)):
            return len(wanted) == len(label) and all(_label_matches(part, want) for part, want in zip(label, wanted))
        return False
    if isinstance(wanted, (int, float)) and not isinstance(wanted, bool):
        return _printed_number(label) == float(wanted)
    if isinstance(wanted, str):
        if label == wanted.strip():
            return True
        number = _printed_number(wanted)
        return number is not None and _printed_number(label) == number
    return False


def thesis_value(table, row_label, column):
    """The value of one cell of a thesis table, as a float.

    Parameters
    ----------
    table : str or float
        Table number, e.g. ``"6.3"`` for thesis chapter 6, Table 6.3.
    row_label : str, float or sequence of str
        Row label as printed (``"4000x4000"``, ``"1,00"``); a number matches a
        numeric label (``0.25`` matches ``"0,25"``). For Tables 5.1 and 5.2
        (thesis chapter 5) give ``(scene, channel)``, e.g.
        ``("San Miguel", "G")``.
    column : str
        Column header as printed, e.g. ``"Path Tracing Time (s)"``.

    Returns
    -------
    float
        The cell's value (the printed text is in :func:`thesis_table`).

    Raises
    ------
    ValueError
        If the table, row or column does not exist, or the cell is not a
        number (every cell of thesis chapter 4, Table 4.1); the message names
        what is missing and lists what exists.
    """
    cells = _row(table, row_label)["cells"]
    if column not in cells:
        raise ValueError(f"thesis table {table} has no column {column!r}; value columns: {', '.join(cells)}")
    cell = cells[column]
    if cell["value"] is None:
        raise ValueError(f"thesis table {table}, row {row_label!r}, column {column!r} is not a number "
                         f"(printed as {cell['text']!r})")
    return float(cell["value"])


def _row(table, row_label):
    data = thesis_table(table)
    rows = [row for row in data["rows"] if _label_matches(row["label"], row_label)]
    if not rows:
        known = "; ".join(str(row["label"]) for row in data["rows"])
        raise ValueError(f"thesis table {table} has no row {row_label!r}; rows: {known}")
    return rows[0]


def thesis_text(table, row_label, column):
    """The printed text of one cell of a thesis table (LaTeX as printed, decimal commas kept).

    Parameters
    ----------
    table : str or float
        Table number, e.g. ``"4.1"`` for thesis chapter 4, Table 4.1, whose
        cells are complexity expressions (``"$O(K + P)$"``) with no value.
    row_label : str, float or sequence of str
        As in :func:`thesis_value`.
    column : str
        Column header as printed.

    Returns
    -------
    str

    Raises
    ------
    ValueError
        If the table, row or column does not exist; the message lists what exists.
    """
    cells = _row(table, row_label)["cells"]
    if column not in cells:
        raise ValueError(f"thesis table {table} has no column {column!r}; value columns: {', '.join(cells)}")
    return cells[column]["text"]


def thesis_rows(table, columns):
    """Every row of a numeric thesis table: ``[(label, (value of each column, ...)), ...]`` in printed order.

    Parameters
    ----------
    table : str or float
        Table number, e.g. ``"8.1"`` (thesis chapter 8, Table 8.1).
    columns : sequence of str
        Column headers as printed, e.g. ``("Total", "Sampling")``.

    Returns
    -------
    list of (label, tuple of float)
        Labels as printed (``"1000x1000"``, ``"40"``); integral values as
        ``int`` (``489``, not ``489.0``), others as ``float``.

    Raises
    ------
    ValueError
        As :func:`thesis_value`, for an unknown table or column or a
        non-numeric cell.
    """
    rows = []
    for row in thesis_table(table)["rows"]:
        values = tuple(thesis_value(table, row["label"], column) for column in columns)
        rows.append((row["label"], tuple(int(value) if value.is_integer() else value for value in values)))
    return rows
