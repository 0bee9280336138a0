"""The report table: one object rendered to Markdown, CSV and HTML (issue 18).

Every table sparselt writes (the thesis's Tables 4.1-8.2 beside ours, a
comparison's ``results.csv``, ``table_8.md``, ``equal_time.md``, an analysis's
Gini tables) is a :class:`Table`: a caption, column headers, rows of a label
and one cell per column, which columns hold the thesis's values and which
ours, and optional notes. The three renderings come from the same object, so
the ``.md`` a reader opens, the ``.csv`` a script reads and the report page
always show the same rows and columns.

Cells are text as given: numbers are formatted by the caller (a table of
measurements decides its own significant digits), and written unchanged,
except the thesis's: a cell of a ``'thesis'`` column is shown through
:func:`thesis_display_text` (decimal point for the thesis's decimal comma,
plain text for its LaTeX), in every rendering.
"""

from __future__ import annotations

import csv
import html
import io
import re
from dataclasses import dataclass, field

#: What a column holds: the thesis's printed values, our measurements, or neither (a setting, a label).
COLUMN_KINDS = ("thesis", "ours", "")

#: The table part of the report page's style sheet: thesis columns shaded beige, ours green.
TABLE_STYLE = """
table { border-collapse: collapse; margin: 1em 0; font-size: .92em; }
th, td { border: 1px solid #ccc; padding: .3em .6em; text-align: right; }
th { background: #f3f3f3; } td.label, th.label { text-align: left; }
td.thesis, th.thesis { background: #f7f3ea; } td.ours, th.ours { background: #eef5ee; }
p.table-note { font-size: .88em; color: #444; margin: -.6em 0 1em 0; }
"""


#: A number printed with a decimal comma (``"0,25"``, ``"-12,5"``): one comma, digits on both sides.
_DECIMAL_COMMA = re.compile(r"[+-]?\d+,\d+")
#: A number printed with comma thousands separators (``"71,722"``, ``"553,647,600"``): never a decimal comma.
_THOUSANDS = re.compile(r"[+-]?[1-9]\d{0,2}(,\d{3})+")
#: LaTeX commands of the thesis's formulas and the plain text each becomes.
_LATEX_SYMBOLS = {
    "cdot": "\u00b7", "times": "\u00d7", "approx": "\u2248", "leq": "\u2264", "geq": "\u2265", "le": "\u2264",
    "ge": "\u2265", "infty": "\u221e", "pm": "\u00b1", "alpha": "\u03b1", "beta": "\u03b2", "gamma": "\u03b3",
    "delta": "\u03b4", "epsilon": "\u03b5", "lambda": "\u03bb", "mu": "\u03bc", "sigma": "\u03c3",
    "Omega": "\u03a9", "omega": "\u03c9", "log": "log", "ln": "ln", "exp": "exp", "sqrt": "\u221a",
    "left": "", "right": "", "mathcal": "", "mathrm": "", "text": "", "operatorname": "",
}
#: The commands of :data:`_LATEX_SYMBOLS` that are binary operators (written between spaces).
_OPERATORS = {"cdot", "times", "approx", "leq", "geq", "le", "ge", "pm"}
#: Superscript and subscript forms of the characters that have one.
_SUPERSCRIPTS = str.maketrans("0123456789+-=()n", "\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079"
                              "\u207a\u207b\u207c\u207d\u207e\u207f")
_SUBSCRIPTS = str.maketrans("0123456789+-=()", "\u2080\u2081\u2082\u2083\u2084\u2085\u2086\u2087\u2088\u2089"
                            "\u208a\u208b\u208c\u208d\u208e")


def _script(match, table, marker):
    """``^{2}`` -> ``²``, ``_1`` -> ``₁``; a script without such characters stays ``^(...)``/``_(...)``."""
    body = match.group(1) if match.group(1) is not None else match.group(2)
    converted = body.translate(table)
    if all(character != original or character.isspace() for character, original in zip(converted, body)):
        return converted
    return f"{marker}{body}" if len(body) == 1 else f"{marker}({body})"


def _command(match):
    """A LaTeX command's plain text: an operator (``·``) between spaces, a word (``log``) with one before a symbol."""
    name, following = match.group(1), match.group(2)
    plain = _LATEX_SYMBOLS.get(name, name)
    if name in _OPERATORS:
        return f" {plain} "
    return plain + " " if plain.isalpha() and (following.isalnum() or following in "{\\") else plain


def _plain_mathematics(text):
    """LaTeX mathematics (without its dollars) as plain text: commands, scripts, braces, spacing."""
    text = re.sub(r"\\[,;:! ]", " ", text)  # thin and other spaces
    text = re.sub(r"\\frac\s*\{([^{}]*)\}\s*\{([^{}]*)\}",
                  lambda match: "/".join(part if len(part.strip()) == 1 else f"({part.strip()})"
                                         for part in match.groups()), text)
    # A function of one symbol loses its parentheses: \log(N) -> log N.
    text = re.sub(r"\\(log|ln|exp)\s*\(\s*([A-Za-z0-9]+)\s*\)", r"\1 \2", text)
    text = re.sub(r"\\([A-Za-z]+)\s*(?=(.?))", _command, text)
    text = re.sub(r"\^\s*(?:\{([^{}]*)\}|(\w))", lambda match: _script(match, _SUPERSCRIPTS, "^"), text)
    text = re.sub(r"_\s*(?:\{([^{}]*)\}|(\w))", lambda match: _script(match, _SUBSCRIPTS, "_"), text)
    text = text.replace("{", "").replace("}", "")
    text = re.sub(r"\s+([)\],])", r"\1", text)  # "log N )" -> "log N)"
    text = re.sub(r"([(\[])\s+", r"\1", text)
    return re.sub(r"\s{2,}", " ", text).strip()


def thesis_display_text(text):
    r"""A thesis cell's printed text as the report shows it: decimal point, LaTeX as plain text.

    Parameters
    ----------
    text : str
        The cell as the thesis prints it (``thesis_tables.json``'s ``"text"``,
        or a caller's text made from it).

    Returns
    -------
    str
        ``text`` with a decimal comma made a decimal point (``"0,25"`` ->
        ``"0.25"``) and LaTeX mathematics made plain text (``"$O(N \log(N))$"``
        -> ``"O(N log N)"``, ``"$O(K + P)$"`` -> ``"O(K + P)"``, ``"$N^{2}$"``
        -> ``"N²"``); any other text unchanged.

    Raises
    ------
    TypeError
        ``text`` is not a string.

    Notes
    -----
    A number is converted only when the whole text is one number with one
    comma between digits; a number with comma thousands separators
    (``"71,722"``, ``"553,647,600"``, as Python's ``f"{n:,}"`` writes them)
    is left as it is. The thesis's cells hold no such numbers: its decimals
    all have a leading ``0`` or a fraction of another length than three.
    Mathematics is converted in every ``$...$`` span, or in the whole text
    when it has a LaTeX command but no dollars (a caller stripped them):
    ``\log``, ``\ln``, ``\exp`` of one symbol lose their parentheses
    (``\log(P)`` -> ``log P``), ``\cdot`` becomes ``·``, ``\frac{a}{b}``
    ``a/b``, Greek letters
    their characters, ``^{2}``/``^2`` and ``_{1}`` superscript and
    subscript characters, and braces are removed.

    References
    ----------
    The thesis's tables, as transcribed in ``sparselt/data/thesis_tables.json``.
    """
    if not isinstance(text, str):
        raise TypeError(f"thesis_display_text takes the cell's text (a string), got {type(text).__name__}")
    stripped = text.strip()
    if _DECIMAL_COMMA.fullmatch(stripped) and not _THOUSANDS.fullmatch(stripped):
        return stripped.replace(",", ".")
    if "$" in text:
        return re.sub(r"\$([^$]*)\$", lambda match: _plain_mathematics(match.group(1)), text)
    if re.search(r"\\[A-Za-z]", text):
        return _plain_mathematics(text)
    return text


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
        The HTML shades thesis and our columns differently; every rendering
        shows a thesis cell through :func:`thesis_display_text` (decimal
        point, plain-text mathematics), while :attr:`rows` keeps it as given.
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
        outside :data:`COLUMN_KINDS`; the message names the row or the kind.
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
            if kind not in COLUMN_KINDS:
                raise ValueError(f"column kind {kind!r} is not one of {', '.join(map(repr, COLUMN_KINDS))}")
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

    def display_rows(self):
        """:attr:`rows` as every rendering shows them: thesis cells through :func:`thesis_display_text`.

        Returns
        -------
        list of (str, list of str)
            Per row, its label and its cells; a cell of a ``'thesis'``
            column with a decimal point and plain-text mathematics, every
            other cell as given.
        """
        thesis = set(self.thesis_columns)
        return [(label, [thesis_display_text(text) if index in thesis else text for index, text in enumerate(cells)])
                for label, cells in self.rows]

    def grid(self):
        """Header and rows as lists of text, label first: what every rendering shows (:meth:`display_rows`)."""
        return [self.header()] + [[label] + list(cells) for label, cells in self.display_rows()]

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
        lines += ["| " + " | ".join(cell(text) for text in [label] + cells) + " |"
                  for label, cells in self.display_rows()]
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

    def html(self, *, identifier=""):
        """The table as an HTML fragment: ``<table>`` with its caption, then the notes as ``<p class="table-note">``.

        Parameters
        ----------
        identifier : str, optional
            The table's ``id`` (an anchor a page's table of contents links to); none when empty.
        """
        def escape(text):
            return html.escape(text, quote=True).replace("\n", "<br>")

        def kind(index):
            return f" class=\"{self.kinds[index]}\"" if self.kinds[index] else ""

        header = "".join(f"<th{kind(index)}>{escape(column)}</th>" for index, column in enumerate(self.columns))
        anchor = f" id=\"{escape(identifier)}\"" if identifier else ""
        lines = [f"<table{anchor}><caption>{escape(self.caption)}</caption>",
                 f"<tr><th class=\"label\">{escape(self.label_header)}</th>{header}</tr>"]
        for label, cells in self.display_rows():
            row = "".join(f"<td{kind(index)}>{escape(text)}</td>" for index, text in enumerate(cells))
            lines.append(f"<tr><td class=\"label\">{escape(label)}</td>{row}</tr>")
        lines.append("</table>")
        lines += [f"<p class=\"table-note\">{escape(note)}</p>" for note in self.notes]
        return "\n".join(lines)


def markdown_document(*parts):
    """Markdown blocks (text, or a :class:`Table`'s :meth:`~Table.markdown` with ``'##'`` headings) as one document."""
    blocks = [part.markdown(heading="##") if isinstance(part, Table) else part for part in parts]
    return "\n".join(block.rstrip("\n") + "\n" for block in blocks if block)


__all__ = ["COLUMN_KINDS", "TABLE_STYLE", "Table", "markdown_document", "thesis_display_text"]
