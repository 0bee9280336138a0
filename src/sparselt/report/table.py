"""The report table: one object rendered to Markdown, CSV and HTML (issue 18).

Every table sparselt writes (the thesis's Tables 4.1-8.2 beside ours, a
comparison's ``results.csv``, ``table_8.md``, ``equal_time.md``, an analysis's
Gini tables) is a :class:`Table`: a caption, column headers, rows of a label
and one cell per column, which columns hold the thesis's values and which
ours, and optional notes. The three renderings come from the same object, so
the ``.md`` a reader opens, the ``.csv`` a script reads and the report page
always show the same rows and columns.

Cells are text as given: numbers are formatted by the caller (a table of
measurements decides its own significant digits), and written unchanged.
"""

from __future__ import annotations

import csv
import html
import io
from dataclasses import dataclass, field

#: What a column holds: the thesis's printed values, our measurements, or neither (a setting, a label).
KINDS = ("thesis", "ours", "")

#: The table part of the report page's style sheet: thesis columns shaded beige, ours green.
TABLE_STYLE = """
table { border-collapse: collapse; margin: 1em 0; font-size: .92em; }
th, td { border: 1px solid #ccc; padding: .3em .6em; text-align: right; }
th { background: #f3f3f3; } td.label, th.label { text-align: left; }
td.thesis, th.thesis { background: #f7f3ea; } td.ours, th.ours { background: #eef5ee; }
p.table-note { font-size: .88em; color: #444; margin: -.6em 0 1em 0; }
"""


def _text(cell):
    """A cell as text: ``None`` is empty, anything else ``str()`` (numbers as the caller formatted them)."""
    return "" if cell is None else str(cell)


@dataclass
class Table:
    """A table of a report: caption, columns, labelled rows, thesis and our columns, notes.

    Attributes
    ----------
    caption : str
        What the table shows; for a thesis table, its number and caption
        (e.g. ``"Table 4.1: Complexity Comparison ..."``).
    columns : list of str
        Column headers after the row label.
    rows : list of (str, list)
        Per row, its label and one cell per column. Cells are text, or
        numbers written with ``str()``; ``None`` is an empty cell.
    kinds : list of str, optional
        Per column, ``'thesis'`` (the thesis's printed value), ``'ours'``
        (what this toolkit measured) or ``''`` (neither); default all ``''``.
        The HTML shades thesis and our columns differently.
    notes : list of str, optional
        Lines printed under the table (Markdown and HTML; not in the CSV,
        which holds only the header and the rows).
    label_header : str, optional
        Header of the row-label column (the CSV's first header; empty in
        Markdown and HTML when not given).

    Raises
    ------
    ValueError
        ``kinds`` or a row of another length than ``columns``, or a kind
        outside :data:`KINDS`; the message names the row or the kind.
    TypeError
        A column header, label or note that is not a string.

    Notes
    -----
    :meth:`markdown` escapes ``|`` as ``\\|`` and writes a line break inside
    a cell as ``<br>``; :meth:`csv` quotes through :mod:`csv` (commas, quotes
    and newlines round-trip through :func:`csv.reader`); :meth:`html` escapes
    ``<``, ``&``, ``>`` and quotes, and marks each cell with its column's kind
    as its class (shaded by :data:`TABLE_STYLE`).
    """

    caption: str
    columns: list
    rows: list
    kinds: list | None = None
    notes: list = field(default_factory=list)
    label_header: str = ""

    def __post_init__(self):
        if not isinstance(self.caption, str):
            raise TypeError(f"caption must be a string, got {type(self.caption).__name__}")
        self.columns = [self._header(column) for column in self.columns]
        self.kinds = [""] * len(self.columns) if self.kinds is None else list(self.kinds)
        if len(self.kinds) != len(self.columns):
            raise ValueError(f"kinds has {len(self.kinds)} entries for {len(self.columns)} columns; give one per column")
        for kind in self.kinds:
            if kind not in KINDS:
                raise ValueError(f"column kind {kind!r} is not one of {', '.join(map(repr, KINDS))}")
        rows = []
        for label, cells in self.rows:
            cells = [_text(cell) for cell in cells]
            if len(cells) != len(self.columns):
                raise ValueError(f"row {label!r} has {len(cells)} cells for {len(self.columns)} columns "
                                 f"({', '.join(self.columns)}); give one per column")
            rows.append((_text(label), cells))
        self.rows = rows
        self.notes = [self._header(note) for note in self.notes]
        self.label_header = self._header(self.label_header)

    @staticmethod
    def _header(text):
        if not isinstance(text, str):
            raise TypeError(f"column headers, notes and the label header must be strings, got {text!r}")
        return text

    @classmethod
    def from_record(cls, record):
        """A table from its JSON record (``dataclasses.asdict`` of one, as a report section stores it)."""
        return cls(**{key: record[key] for key in ("caption", "columns", "rows", "kinds", "notes", "label_header")
                      if key in record})

    @property
    def thesis_columns(self):
        """Indices of the columns that hold the thesis's values."""
        return [index for index, kind in enumerate(self.kinds) if kind == "thesis"]

    def header(self):
        """The full header: the label column's, then :attr:`columns`."""
        return [self.label_header] + list(self.columns)

    def grid(self):
        """Header and rows as lists of text, label first: what every rendering shows."""
        return [self.header()] + [[label] + list(cells) for label, cells in self.rows]

    # ------------------------------------------------------------------ renderings
    def markdown(self, *, heading="#"):
        """The table as Markdown: the caption as a heading, a pipe table, the notes.

        Parameters
        ----------
        heading : str, optional
            Heading marker of the caption (``'#'``, ``'##'``, ...); ``''``
            writes the caption as a plain line.
        """
        def cell(text):
            return text.replace("|", "\\|").replace("\r\n", "<br>").replace("\n", "<br>")

        lines = [f"{heading} {self.caption}" if heading else self.caption, ""]
        lines.append("| " + " | ".join(cell(text) for text in self.header()) + " |")
        lines.append("|" + "---|" * (len(self.columns) + 1))
        lines += ["| " + " | ".join(cell(text) for text in [label] + cells) + " |" for label, cells in self.rows]
        if self.notes:
            lines.append("")
            lines += [cell(note) for note in self.notes]
        return "\n".join(lines) + "\n"

    def csv(self):
        """The table as CSV (:mod:`csv` quoting): the header row, then one row per row; no caption or notes."""
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerows(self.grid())
        return buffer.getvalue()

    def html(self):
        """The table as an HTML fragment: ``<table>`` with its caption, then the notes as ``<p class="table-note">``."""
        def escape(text):
            return html.escape(text, quote=True).replace("\n", "<br>")

        def kind(index):
            return f" class=\"{self.kinds[index]}\"" if self.kinds[index] else ""

        header = "".join(f"<th{kind(index)}>{escape(column)}</th>" for index, column in enumerate(self.columns))
        lines = [f"<table><caption>{escape(self.caption)}</caption>",
                 f"<tr><th class=\"label\">{escape(self.label_header)}</th>{header}</tr>"]
        for label, cells in self.rows:
            row = "".join(f"<td{kind(index)}>{escape(text)}</td>" for index, text in enumerate(cells))
            lines.append(f"<tr><td class=\"label\">{escape(label)}</td>{row}</tr>")
        lines.append("</table>")
        lines += [f"<p class=\"table-note\">{escape(note)}</p>" for note in self.notes]
        return "\n".join(lines)


def markdown_document(*parts):
    """Markdown blocks (text, or a :class:`Table`'s :meth:`~Table.markdown` with ``'##'`` headings) as one document."""
    blocks = [part.markdown(heading="##") if isinstance(part, Table) else part for part in parts]
    return "\n".join(block.rstrip("\n") + "\n" for block in blocks if block)


__all__ = ["KINDS", "TABLE_STYLE", "Table", "markdown_document"]
