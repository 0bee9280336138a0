"""Reports: tables, figures and static HTML pages, the thesis's numbers beside ours (issues 14 and 18).

A sink: modules here take plain rows, configurations and an experiment folder
and import nothing from ``experiments/``. One :class:`Table` is rendered to
Markdown, CSV and HTML; :func:`write_page` / :func:`page_html` make the page.
"""

from .page import Figure, Section, page_html, write_page
from .table import Table, markdown_document

__all__ = ["Figure", "Section", "Table", "markdown_document", "page_html", "write_page"]
