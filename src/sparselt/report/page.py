"""One static, self-contained HTML page: per chapter, the thesis's tables beside ours, figures, verdicts.

No external resources and no server: styles are inline, images are files next
to the page referenced by relative paths. A table of contents at the top links
every section (an ``<h2>`` with an ``id``) and, under it, every table's and
figure's caption (each an anchor of its own). Figures show at their own size, at most the content column;
each image is a link to its file, so a click opens it at full size. A small
inline script marks, on ``load``, how many images the page has and which
failed to load (``body[data-images]``, ``body[data-broken-images]``), so a
headless browser's DOM dump tells whether the page renders.
"""

from __future__ import annotations

import html
import os
import re
from dataclasses import dataclass, field

from ..provenance import atomic_write_bytes
from .table import TABLE_STYLE, Table

STYLE = """
body { font-family: -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; margin: 2em auto; max-width: 90em;
       padding: 0 1.5em; color: #222; line-height: 1.45; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 2em; }
p { max-width: 68em; }
figure { display: block; margin: 1.5em 0; width: 100%; }
figure a { display: inline-block; max-width: 100%; }
figure img { display: block; max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { font-size: .88em; color: #444; margin-top: .3em; }
.finding { font-size: .9em; margin: .3em 0 0 0; color: #333; }
nav.contents { background: #fafafa; border: 1px solid #ddd; padding: .5em 1.2em; margin: 1em 0 2em 0; font-size: .92em; }
nav.contents p { margin: .3em 0; font-weight: bold; } nav.contents ul { margin: .2em 0; padding-left: 1.4em; }
nav.contents ul ul { font-size: .92em; color: #444; }
.verdict { background: #f0f4fa; border-left: 4px solid #4a6fa5; padding: .6em 1em; margin: 1em 0; }
.provenance { font-size: .85em; color: #555; } code { font-size: .95em; }
""" + TABLE_STYLE

SELF_CHECK = """
window.addEventListener('load', function () {
  var images = Array.prototype.slice.call(document.images);
  var broken = images.filter(function (image) { return !(image.complete && image.naturalWidth > 0); })
                     .map(function (image) { return image.getAttribute('src'); });
  document.body.setAttribute('data-images', String(images.length));
  document.body.setAttribute('data-broken-images', broken.join(' '));
});
"""


@dataclass
class Figure:
    """An image file (path relative to the page) under the thesis's caption."""

    path: str
    caption: str
    findings: list = field(default_factory=list)  # sentences under the caption: the thesis's finding, then ours


@dataclass
class Section:
    """One chapter of the report."""

    title: str
    introduction: str = ""
    tables: list = field(default_factory=list)
    figures: list = field(default_factory=list)
    verdicts: list = field(default_factory=list)
    links: list = field(default_factory=list)  # (text, relative path)
    seconds: float | None = None
    markup: str = ""  # trusted HTML written by sparselt itself (an image viewer), after the figures

    @classmethod
    def from_record(cls, record):
        """A section from its JSON record (``dataclasses.asdict`` of one)."""
        record = dict(record)
        record["tables"] = [Table.from_record(table) for table in record.get("tables", [])]
        record["figures"] = [Figure(**figure) for figure in record.get("figures", [])]
        record["links"] = [tuple(link) for link in record.get("links", [])]
        return cls(**record)


def _escape(text):
    return html.escape(str(text), quote=True)


def anchor_identifier(text, used):
    """An HTML ``id`` made from ``text`` (lower case, runs of other characters as ``-``), unique among ``used``.

    Parameters
    ----------
    text : str
        A section title or caption.
    used : set of str
        The identifiers given so far on the page; the new one is added.

    Returns
    -------
    str
        For example ``"chapter-4-fourier-integration"``; ``"-2"``, ``"-3"``,
        ... appended when taken.
    """
    return _unique(re.sub(r"[^a-z0-9]+", "-", str(text).lower()).strip("-")[:60].strip("-") or "part", used)


def _unique(base, used):
    """``base``, or ``base-2``, ``base-3``, ... the first not in ``used``; added to ``used``."""
    identifier, number = base, 1
    while identifier in used:
        number += 1
        identifier = f"{base}-{number}"
    used.add(identifier)
    return identifier


def _figure_html(figure, identifier):
    """A figure at its own size (at most the content column); its image a link to the file (opens at full size)."""
    path, caption = _escape(figure.path), _escape(figure.caption)
    return (f"<figure id=\"{_escape(identifier)}\"><a href=\"{path}\" title=\"open at full size\">"
            f"<img src=\"{path}\" alt=\"{caption}\"></a><figcaption>{caption}</figcaption>"
            + "".join(f"<p class=\"finding\">{_escape(finding)}</p>" for finding in figure.findings)
            + "</figure>")


def _contents(entries):
    """The table of contents: per section a link, and under it its tables' and figures' captions."""
    items = []
    for identifier, title, parts in entries:
        nested = "".join(f"<li><a href=\"#{_escape(part)}\">{_escape(caption)}</a></li>" for part, caption in parts)
        items.append(f"<li><a href=\"#{_escape(identifier)}\">{_escape(title)}</a>"
                     + (f"<ul>{nested}</ul>" if nested else "") + "</li>")
    return "<nav class=\"contents\"><p>Contents</p><ul>" + "".join(items) + "</ul></nav>"


def page_html(folder, title, sections, provenance, *, note="", head=""):
    """The report page as HTML text; every image and link path is relative to ``folder``, where the page goes.

    The page opens with a table of contents: one link per section (its
    ``<h2>``'s ``id``, :func:`anchor_identifier` of its title) and, nested
    under it, one per table and figure caption (ids ``<section>-table-<n>``
    and ``<section>-figure-<n>``), then the provenance. Each figure shows at
    its own size, at most the content column, and its image links to its file.

    Parameters
    ----------
    folder : str
        The folder the page is written into (figure and link paths are checked against it).
    title : str
    sections : sequence of Section
    provenance : dict
        :func:`~sparselt.provenance.environment_record` (versions, git revision, command).
    note : str, optional
        A paragraph under the title.
    head : str, optional
        Trusted markup for the page's ``<head>`` (the image viewer's styles and script).

    Raises
    ------
    ValueError
        A figure or link names a file that does not exist (the page would show a broken image or link), or an
        absolute path or URL.
    """
    folder = os.path.abspath(os.fspath(folder))
    used, contents, body = {"contents"}, [], []
    for section in sections:
        identifier = anchor_identifier(section.title, used)
        entries = []
        body.append(f"<h2 id=\"{_escape(identifier)}\">{_escape(section.title)}</h2>")
        if section.introduction:
            body.append(f"<p>{_escape(section.introduction)}</p>")
        for verdict in section.verdicts:
            body.append(f"<p class=\"verdict\">{_escape(verdict)}</p>")
        for number, table in enumerate(section.tables, 1):
            table_identifier = _unique(f"{identifier}-table-{number}", used)
            entries.append((table_identifier, table.caption))
            body.append(table.html(identifier=table_identifier))
        for number, figure in enumerate(section.figures, 1):
            _check_relative(folder, figure.path)
            figure_identifier = _unique(f"{identifier}-figure-{number}", used)
            entries.append((figure_identifier, figure.caption))
            body.append(_figure_html(figure, figure_identifier))
        if section.markup:
            body.append(section.markup)
        if section.links:
            items = []
            for text, target in section.links:
                _check_relative(folder, target)
                items.append(f"<li><a href=\"{_escape(target)}\">{_escape(text)}</a></li>")
            body.append("<ul>" + "".join(items) + "</ul>")
        if section.seconds is not None:
            body.append(f"<p class=\"provenance\">Wall time of this chapter: {section.seconds:.1f} s.</p>")
        contents.append((identifier, section.title, entries))
    provenance_identifier = _unique("provenance", used)
    contents.append((provenance_identifier, "Provenance", []))
    versions = ", ".join(f"{name} {version}" for name, version in (provenance.get("versions") or {}).items() if version)
    git = provenance.get("git") or {}
    body.append(f"<h2 id=\"{provenance_identifier}\">Provenance</h2><p class=\"provenance\">"
                f"git {_escape(git.get('commit', 'unknown'))}{' (modified)' if git.get('dirty') else ''}; "
                f"{_escape(provenance.get('platform', ''))}; created {_escape(provenance.get('created', ''))}; "
                f"command <code>{_escape(' '.join(provenance.get('command') or []))}</code>; {_escape(versions)}.</p>")
    parts = ["<!DOCTYPE html>", "<html lang=\"en\"><head><meta charset=\"utf-8\">",
             f"<title>{_escape(title)}</title><style>{STYLE}</style>{head}</head><body>",
             f"<h1>{_escape(title)}</h1>"]
    if note:
        parts.append(f"<p>{_escape(note)}</p>")
    parts.append(_contents(contents))
    parts += body
    parts.append(f"<script>{SELF_CHECK}</script></body></html>")
    return "\n".join(parts) + "\n"


def write_page(path, title, sections, provenance, *, note=""):
    """Write the report page ``path`` atomically (:func:`page_html`); return ``path``.

    Inside an experiment folder, write :func:`page_html`'s text through the
    folder instead (``folder.write_text('index.html', ...)``), so its manifest
    lists the page.

    Raises
    ------
    ValueError
        As :func:`page_html`.
    """
    text = page_html(os.path.dirname(os.path.abspath(path)), title, sections, provenance, note=note)
    atomic_write_bytes(path, text.encode("utf-8"))
    return path


def _check_relative(folder, target):
    if os.path.isabs(target) or "://" in target:
        raise ValueError(f"report links must be relative paths, got {target!r}")
    if not os.path.exists(os.path.join(folder, target)):
        raise ValueError(f"the report refers to {target!r}, which does not exist in {folder!r}")
