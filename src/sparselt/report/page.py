"""One static, self-contained HTML page: per chapter, the thesis's tables beside ours, figures, verdicts.

No external resources and no server: styles are inline, images are files next
to the page referenced by relative paths. A small inline script marks, on
``load``, how many images the page has and which failed to load
(``body[data-images]``, ``body[data-broken-images]``), so a headless browser's
DOM dump tells whether the page renders.
"""

from __future__ import annotations

import html
import os
from dataclasses import dataclass, field

from ..provenance import atomic_write_bytes
from .table import TABLE_STYLE, Table

STYLE = """
body { font-family: -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; margin: 2em auto; max-width: 72em;
       color: #222; line-height: 1.45; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 2em; }
figure { display: inline-block; margin: 1em 1em 1em 0; max-width: 45%; vertical-align: top; }
figure img { max-width: 100%; border: 1px solid #ddd; } figcaption { font-size: .88em; color: #444; }
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


def page_html(folder, title, sections, provenance, *, note=""):
    """The report page as HTML text; every image and link path is relative to ``folder``, where the page goes.

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

    Raises
    ------
    ValueError
        A figure or link names a file that does not exist (the page would show a broken image or link), or an
        absolute path or URL.
    """
    folder = os.path.abspath(os.fspath(folder))
    parts = ["<!DOCTYPE html>", "<html lang=\"en\"><head><meta charset=\"utf-8\">",
             f"<title>{_escape(title)}</title><style>{STYLE}</style></head><body>",
             f"<h1>{_escape(title)}</h1>"]
    if note:
        parts.append(f"<p>{_escape(note)}</p>")
    for section in sections:
        parts.append(f"<h2>{_escape(section.title)}</h2>")
        if section.introduction:
            parts.append(f"<p>{_escape(section.introduction)}</p>")
        for verdict in section.verdicts:
            parts.append(f"<p class=\"verdict\">{_escape(verdict)}</p>")
        parts.extend(table.html() for table in section.tables)
        for figure in section.figures:
            _check_relative(folder, figure.path)
            parts.append(f"<figure><img src=\"{_escape(figure.path)}\" alt=\"{_escape(figure.caption)}\">"
                         f"<figcaption>{_escape(figure.caption)}</figcaption></figure>")
        if section.links:
            items = []
            for text, target in section.links:
                _check_relative(folder, target)
                items.append(f"<li><a href=\"{_escape(target)}\">{_escape(text)}</a></li>")
            parts.append("<ul>" + "".join(items) + "</ul>")
        if section.seconds is not None:
            parts.append(f"<p class=\"provenance\">Wall time of this chapter: {section.seconds:.1f} s.</p>")
    versions = ", ".join(f"{name} {version}" for name, version in (provenance.get("versions") or {}).items() if version)
    git = provenance.get("git") or {}
    parts.append("<h2>Provenance</h2><p class=\"provenance\">"
                 f"git {_escape(git.get('commit', 'unknown'))}{' (modified)' if git.get('dirty') else ''}; "
                 f"{_escape(provenance.get('platform', ''))}; created {_escape(provenance.get('created', ''))}; "
                 f"command <code>{_escape(' '.join(provenance.get('command') or []))}</code>; {_escape(versions)}.</p>")
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
