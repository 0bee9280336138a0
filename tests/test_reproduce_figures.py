"""Issue 21: `sparselt reproduce` at the tiny scale puts every data figure and table of the thesis on its page,
each figure an image a real browser loads, each table with the thesis's column and ours."""

import re
from html.parser import HTMLParser

import pytest
from test_reproduce import chromium, rendered_dom  # noqa: F401  (the headless-browser fixture)

from sparselt.experiments.reproduce import reproduce

#: The thesis's data figures (not its diagrams: 2.x, 3.1, 8.5, 8.14) and numeric tables.
DATA_FIGURES = (["4.1", "4.2"] + [f"5.{n}" for n in range(1, 5)] + [f"6.{n}" for n in range(1, 8)]
                + [f"7.{n}" for n in range(1, 7)] + [f"8.{n}" for n in range(1, 5)] + [f"8.{n}" for n in range(6, 14)]
                + [f"8.{n}" for n in range(15, 18)])
TABLES = ["4.1", "5.1", "5.2", "6.1", "6.2", "6.3", "7.1", "7.2", "7.3", "8.1", "8.2"]


class _Page(HTMLParser):
    """Figures (caption -> image source) and tables (caption -> header cell classes) of a page."""

    def __init__(self):
        super().__init__()
        self.figures, self.tables, self._in = {}, {}, None
        self._image = self._table = None
        self._text = ""

    def handle_starttag(self, tag, attributes):
        attributes = dict(attributes)
        if tag == "img":
            self._image = attributes["src"]
        elif tag == "table":
            self._table = []
        elif tag == "th" and self._table is not None:
            self._table.append(attributes.get("class", ""))
        if tag in ("figcaption", "caption"):
            self._in, self._text = tag, ""

    def handle_data(self, data):
        if self._in:
            self._text += data

    def handle_endtag(self, tag):
        if tag == "figcaption":
            self.figures[self._text] = self._image
        elif tag == "caption":
            self._caption = self._text
        elif tag == "table":
            self.tables[self._caption] = self._table
            self._table = None
        if tag == self._in:
            self._in = None


@pytest.fixture(scope="module")
def tiny_page(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce") / "tiny"
    return reproduce("all", "tiny", out, progress=False)


def _numbers(caption):
    """The thesis figure or table numbers a caption names ('Figures 6.4 and 6.5: ...' -> ['6.4', '6.5'])."""
    head = caption.split(":")[0]
    return re.findall(r"\d+\.\d+", head) if re.match(r"(Figures?|Table) ", head) else []


def test_every_data_figure_has_an_image_that_loads(tiny_page, chromium):  # noqa: F811
    dom = rendered_dom(chromium, tiny_page)
    assert 'data-broken-images=""' in dom
    page = _Page()
    page.feed(dom)
    shown = {number for caption, image in page.figures.items() if image for number in _numbers(caption)}
    assert not set(DATA_FIGURES) - shown, f"missing figures: {sorted(set(DATA_FIGURES) - shown)}"
    for caption in page.figures:
        if _numbers(caption):
            below = dom.split(f"<figcaption>{caption}</figcaption>", 1)[1]
            assert below.startswith('<p class="finding">Thesis ('), caption  # the thesis's finding under it


def test_every_table_has_thesis_and_our_columns(tiny_page):
    page = _Page()
    page.feed(open(tiny_page, encoding="utf-8").read())
    for number in TABLES:
        tables = [classes for caption, classes in page.tables.items() if caption.startswith(f"Table {number}:")]
        assert len(tables) == 1, (number, list(page.tables))
        assert "thesis" in tables[0] and "ours" in tables[0], number


def test_verdicts_compare_with_the_direction_the_thesis_reports(tiny_page):
    text = open(tiny_page, encoding="utf-8").read()
    verdicts = re.findall(r'<p class="verdict">(.*?)</p>', text)
    for claim in ("the canonical Gini falls", "Fourier Gini (magnitude) rises", "needs more path samples than",
                  "energy is sparsely distributed in the Fourier domain", "CoSaMP takes longer than sampling"):
        matching = [verdict for verdict in verdicts if claim in verdict]
        assert matching, claim
        assert all(re.search(r"Ours[^:]*: the (same|OPPOSITE) (direction|finding)", verdict)
                   for verdict in matching), matching
    assert any("Equal spp (cornell-caustics" in verdict for verdict in verdicts)
    assert "0,6" not in text and "\\log" not in text  # decimal points, LaTeX as text
