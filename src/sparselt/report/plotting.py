"""Matplotlib for files: the non-interactive backend, chosen once, before pyplot is imported."""

from __future__ import annotations


def pyplot():
    """``matplotlib.pyplot`` on the ``Agg`` backend (figures for files; no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot_module

    return pyplot_module


__all__ = ["pyplot"]
