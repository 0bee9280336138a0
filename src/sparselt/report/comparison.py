"""The report page of one ``sparselt compare`` run: Tables 8.1/8.2 beside the thesis, equal-time verdicts, figures."""

from __future__ import annotations

import os

import numpy as np

from .page import Figure, Section, Table, write_page


def equal_time_verdicts(rows):
    """One sentence per method from its relMSE against PT's at the same time (mean of the ratios over spp)."""
    verdicts = []
    for method in dict.fromkeys(row["method"] for row in rows):
        if method == "pt":
            continue
        group = [row for row in rows if row["method"] == method and row.get("relmse_pt_equal_time") not in ("", None)]
        if not group:
            verdicts.append(f"{method}: PT's runs do not reach its time, so no equal-time comparison.")
            continue
        ratio = float(np.mean([row["relmse"] / row["relmse_pt_equal_time"] for row in group]))
        spps = sorted({row["spp"] for row in group})
        if ratio < 1:
            verdicts.append(f"{method} beats PT at equal time by {100 * (1 - ratio):.0f}% relMSE "
                            f"(mean over spp {', '.join(map(str, spps))}).")
        else:
            verdicts.append(f"{method} loses to PT at equal time: {ratio:.2f}x PT's relMSE "
                            f"(mean over spp {', '.join(map(str, spps))}).")
    return verdicts


def comparison_section(folder, prefix, rows, config, scene, *, title=None):
    """The report section of the comparison in ``folder``; file paths start with ``prefix`` (the folder
    relative to the page). Its tables are ``table_8.md``'s (:func:`~sparselt.experiments.compare_report.table_8_rows`)."""
    from ..experiments.compare_report import TABLE_8_COLUMNS, table_8_rows  # not at the top: compare imports this module

    thesis, methods = table_8_rows(rows, scene, config)
    tables = []
    for method, cells in methods.items():
        columns, kinds = list(TABLE_8_COLUMNS), ["ours"] * len(TABLE_8_COLUMNS)
        if thesis:
            columns.append(f"thesis Table {thesis[0]} ({thesis[1]}): total / sampling / CoSaMP / integration s")
            kinds.append("thesis")
        table_rows = [(f"{method}, {spp} spp", values + ([" / ".join(f"{v:g}" for v in thesis_values)
                                                          if thesis_values else "-"] if thesis else []))
                      for spp, values, thesis_values in cells]
        caption = (f"Table {thesis[0]} layout: execution times (s), {scene}" if thesis
                   else f"Execution times (s) and quality, {scene}") + f" ({method})"
        tables.append(Table(caption=caption, columns=columns, kinds=kinds, rows=table_rows))
    join = (lambda name: f"{prefix}/{name}") if prefix else (lambda name: name)
    figures = [Figure(join(name), caption) for name, caption in (
        ("quality_vs_time.png", "Figures 8.1/8.3 layout: relMSE and SSIM against time"),
        ("image_grid.png", "Figures 8.2/8.4 layout: the methods at matched time beside the reference"),
        ("crop_grid.png", "Details where the methods disagree most"))
        if os.path.exists(os.path.join(folder, name))]
    links = [(name, join(name)) for name in ("results.csv", "equal_time.md", "table_8.md", "table_6.md", "compare.json")
             if os.path.exists(os.path.join(folder, name))]
    return Section(
        title=title or (f"{scene}, kind {config.kind}, grid {'x'.join(map(str, config.shape))}, "
                        f"image {'x'.join(map(str, config.output_resolution))}"),
        introduction=f"{scene}, kind {config.kind}, grid {'x'.join(map(str, config.shape))}, image "
                     f"{'x'.join(map(str, config.output_resolution))}: every method at every budget against a cached "
                     "Mitsuba reference; relMSE epsilon 0.01; equal time means every second counted (pilot samples, "
                     "reconstruction, filtering), kernels warmed first.",
        tables=tables, figures=figures, verdicts=equal_time_verdicts(rows), links=links)


def write_comparison_page(out, rows, config, scene, provenance):
    """``out/index.html`` for a comparison folder; returns its path."""
    section = comparison_section(out, "", rows, config, scene)
    return write_page(os.path.join(out, "index.html"), f"sparselt compare: {scene}", [section], provenance)
