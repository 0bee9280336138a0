"""The HTML report of ``sparselt reproduce``: the thesis's numbers beside ours (issue 14)."""

from .page import Figure, Section, Table, write_page

__all__ = ["Figure", "Section", "Table", "write_page"]
