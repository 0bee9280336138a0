"""What the thesis found, as data, and verdicts that compare our numbers with it (issue 21).

``sparselt/data/thesis_findings.json`` keeps, beside the transcribed tables of
:mod:`sparselt.thesis.numbers`, the *direction* of each finding the thesis
states about a table or a figure: a claim names its quantities (a table's
column, optionally some rows, optionally divided by a constant; or a name our
experiments measure) and what the thesis says of them:

``trend``
    The quantity over the table's rows in printed order, first to last,
    ``rises`` or ``falls`` (Tables 6.1, 7.x, 8.x).
``greater``
    ``larger`` above ``smaller``: their means, or every row with ``per_row``
    (Tables 5.x, 6.2/6.3, 8.1).
``above`` / ``below``
    Every value of ``quantity`` above / below ``than``.

No direction is typed in code: :func:`judge` reads the claim, evaluates it on
the thesis's numbers (when the quantity is in a table) and on ours, and
writes one sentence on what the thesis found and one on what we found, with
the size of the gap. ``tests/test_thesis_findings.py`` checks that every
stored claim holds on the thesis's own numbers.

Examples
--------
>>> claim = table_claims("7.3")[0]
>>> claim["type"], claim["direction"]
('trend', 'falls')
>>> values = thesis_quantity(claim["quantity"])  # Table 7.3's "Time" column, gamma 1 to 0.05
>>> len(values), values[-1] < values[0]
(5, True)
>>> judge(claim, [0.83, 0.64]).agrees
True
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

from .numbers import thesis_table

FINDINGS_FILE = "thesis_findings.json"
CLAIM_TYPES = ("trend", "greater", "above", "below")


@lru_cache(maxsize=1)
def thesis_findings():
    """The stored findings: ``{"tables": {number: [claim, ...]}, "figures": {number: {"finding", "claim"?}}}``."""
    text = resources.files("sparselt.data").joinpath(FINDINGS_FILE).read_text(encoding="utf-8")
    return json.loads(text)


def table_claims(number):
    """The claims the thesis makes about Table ``number`` (an empty list when it makes none)."""
    return list(thesis_findings()["tables"].get(str(number), []))


def table_claim(number, claim_id):
    """One claim about Table ``number`` by its ``id``; a ValueError lists the known ids."""
    claims = table_claims(number)
    for claim in claims:
        if claim["id"] == claim_id:
            return claim
    raise ValueError(f"thesis table {number} has no claim {claim_id!r}; claims: "
                     f"{', '.join(claim['id'] for claim in claims) or 'none'}")


def figure_finding(number):
    """``{"finding": sentence, "section": ..., "claim": claim or absent}`` for thesis Figure ``number``."""
    figures = thesis_findings()["figures"]
    if str(number) not in figures:
        raise ValueError(f"no stored finding for thesis figure {number!r}; figures: {', '.join(figures)}")
    return figures[str(number)]


def _label_head(label):
    return label[0] if isinstance(label, list) else label


def thesis_quantity(quantity):
    """The thesis's values of a claim's quantity, one per selected row in printed order, or None.

    None when the quantity is not in a table (``{"name": ...}``: something only
    our experiments measure, such as an SSIM read off a figure).
    """
    if "table" not in quantity:
        return None
    rows = thesis_table(quantity["table"])["rows"]
    wanted = quantity.get("rows")
    divisor = float(quantity.get("divide_by", 1.0))
    values = [row["cells"][quantity["column"]]["value"] / divisor for row in rows
              if wanted is None or _label_head(row["label"]) in wanted]
    return [float(value) for value in values]


def per_thesis_row(quantity, lookup):
    """Our values of a tabulated quantity, in the thesis's row order: ``lookup(label)`` per selected row.

    ``label`` is the thesis's row label (a tuple for Tables 5.x: ``(scene, channel)``); rows where ``lookup``
    returns None (not measured here) are left out.
    """
    rows = thesis_table(quantity["table"])["rows"]
    wanted = quantity.get("rows")
    values = []
    for row in rows:
        if wanted is not None and _label_head(row["label"]) not in wanted:
            continue
        label = tuple(row["label"]) if isinstance(row["label"], list) else row["label"]
        value = lookup(label)
        if value is not None:
            values.append(float(value))
    return values


def quantity_name(quantity):
    """A short name of a quantity for sentences ('Table 7.1 Frequency', 'SSIM at fraction 1e-4')."""
    if "name" in quantity:
        return quantity["name"]
    rows = f" ({', '.join(quantity['rows'])})" if quantity.get("rows") else ""
    unit = " / N" if quantity.get("unit") == "N" else ""
    return f"Table {quantity['table']} {quantity['column']}{unit}{rows}"


@dataclass(frozen=True)
class Finding:
    """A claim of the thesis evaluated on the thesis's numbers and on ours.

    Attributes
    ----------
    claim : dict
    agrees : bool or None
        Whether our numbers go the thesis's direction (None: we have no numbers).
    thesis_holds : bool or None
        Whether the thesis's own numbers go its stated direction (None: not tabulated).
    thesis_sentence, our_sentence : str
    """

    claim: dict
    agrees: bool | None
    thesis_holds: bool | None
    thesis_sentence: str
    our_sentence: str

    @property
    def sentence(self):
        return f"{self.thesis_sentence} {self.our_sentence}"


def _as_list(values):
    if values is None:
        return None
    if isinstance(values, (int, float)):
        return [float(values)]
    return [float(value) for value in values]


def _mean(values):
    return sum(values) / len(values)


def _number(value):
    if value == 0:
        return "0"
    magnitude = abs(value)
    if magnitude >= 1e5 or magnitude < 1e-3:
        return f"{value:.3g}"
    return f"{value:.3f}" if magnitude < 10 else f"{value:.4g}"


def _holds(claim, values):
    """Whether ``values`` (a list for trend/above/below, a (larger, smaller) pair for greater) go the claim's way."""
    kind = claim["type"]
    if kind == "trend":
        if len(values) < 2:
            return None
        return values[-1] > values[0] if claim["direction"] == "rises" else values[-1] < values[0]
    if kind == "greater":
        larger, smaller = values
        if claim.get("per_row"):
            return all(big > small for big, small in zip(larger, smaller))
        return _mean(larger) > _mean(smaller)
    if kind == "above":
        return all(value > claim["than"] for value in values)
    if kind == "below":
        return all(value < claim["than"] for value in values)
    raise ValueError(f"claim {claim.get('id')!r} has type {kind!r}; types: {', '.join(CLAIM_TYPES)}")


def _evidence(claim, values):
    """The numbers behind a claim's evaluation, as text."""
    kind = claim["type"]
    if kind == "trend":
        change = values[-1] - values[0]
        return f"{_number(values[0])} -> {_number(values[-1])}, {change:+.3g}"
    if kind == "greater":
        larger, smaller = values
        if claim.get("per_row"):
            pairs = ", ".join(f"{_number(big)} vs {_number(small)}" for big, small in zip(larger, smaller))
            return f"{quantity_name(claim['larger'])} vs {quantity_name(claim['smaller'])}: {pairs}"
        return (f"{quantity_name(claim['larger'])} {_number(_mean(larger))} vs {quantity_name(claim['smaller'])} "
                f"{_number(_mean(smaller))}")
    low, high = min(values), max(values)
    spread = _number(low) if low == high else f"{_number(low)}-{_number(high)}"
    return f"{quantity_name(claim['quantity'])} {spread} against {_number(claim['than'])}"


def _gap(claim, ours, thesis):
    """How far our numbers are from the thesis's, as text ('' when the thesis has none)."""
    if thesis is None:
        return ""
    kind = claim["type"]
    if kind == "trend":
        return (f"; our change {ours[-1] - ours[0]:+.3g} against the thesis's {thesis[-1] - thesis[0]:+.3g}, "
                f"our level {_number(_mean(ours))} against {_number(_mean(thesis))}")
    if kind == "greater":
        ours_difference = _mean(ours[0]) - _mean(ours[1])
        thesis_difference = _mean(thesis[0]) - _mean(thesis[1])
        return f"; the difference is {ours_difference:+.3g} here against the thesis's {thesis_difference:+.3g}"
    return f"; our mean {_number(_mean(ours))} against the thesis's {_number(_mean(thesis))}"


def claim_values(claim, source):
    """A claim's values from ``source(quantity)``: a list, or a (larger, smaller) pair for 'greater'.

    The one place that knows which quantities a claim type names: :func:`judge` reads the thesis's values
    through it, and callers their own (``source`` returns our values of one quantity). None when ``source``
    has none of a quantity.
    """
    if claim["type"] == "greater":
        larger, smaller = _as_list(source(claim["larger"])), _as_list(source(claim["smaller"]))
        return None if larger is None or smaller is None else (larger, smaller)
    return _as_list(source(claim["quantity"]))


def judge(claim, ours, *, thesis=None, subject=""):
    """Compare our numbers with a claim of the thesis; return a :class:`Finding` with both sentences.

    Parameters
    ----------
    claim : dict
        From :func:`table_claims` or :func:`figure_finding`.
    ours : list of float, or (list, list) for a 'greater' claim, or None
        Our values of the claim's quantity (in the thesis's row order: the
        first value corresponds to the thesis's first row), or of its
        ``larger`` and ``smaller`` quantities. None: not measured.
    thesis : same shape as ``ours``, optional
        The thesis's values; default: read from its tables
        (:func:`thesis_quantity`), or none when the quantity is not tabulated.
    subject : str, optional
        What our numbers are of ('courtyard, 64x64x8x8, 4 spp'), named in our sentence.

    Returns
    -------
    Finding
    """
    if claim["type"] not in CLAIM_TYPES:
        raise ValueError(f"claim {claim.get('id')!r} has type {claim['type']!r}; types: {', '.join(CLAIM_TYPES)}")
    if thesis is None:
        thesis = claim_values(claim, thesis_quantity)
    thesis_holds = _holds(claim, thesis) if thesis is not None else None
    along = f" {claim['along']}" if claim.get("along") else ""
    thesis_sentence = f"Thesis ({claim.get('section', '')}): {claim['statement']}" + (
        f" ({_evidence(claim, thesis)}{along})." if thesis is not None else ".")
    if thesis_holds is False:
        thesis_sentence += " The thesis's own numbers do not all go this way."
    where = f" on {subject}" if subject else ""
    if ours is None:
        return Finding(claim, None, thesis_holds, thesis_sentence, f"Ours{where}: not measured.")
    ours = (_as_list(ours[0]), _as_list(ours[1])) if claim["type"] == "greater" else _as_list(ours)
    agrees = _holds(claim, ours)
    noun = "direction" if claim["type"] == "trend" else "finding"
    word = {True: f"the same {noun}", False: f"the OPPOSITE {noun}", None: "too few values to tell"}[agrees]
    our_sentence = f"Ours{where}: {word} ({_evidence(claim, ours)}{along}){_gap(claim, ours, thesis)}."
    return Finding(claim, agrees, thesis_holds, thesis_sentence, our_sentence)


__all__ = ["CLAIM_TYPES", "Finding", "claim_values", "figure_finding", "judge", "per_thesis_row", "quantity_name", "table_claim", "table_claims",
           "thesis_findings", "thesis_quantity"]
