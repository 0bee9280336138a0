"""Re-judge the committed comparisons of ``docs/experiments`` with the current equal-time protocol.

Every comparison folder's rows (``results.csv``) go back through
:func:`sparselt.experiments.equal_time.judge`, as ``compare`` calls it, and
its ``results.csv`` derived columns, ``summary.csv``, ``equal_time.md/.csv``
and ``compare.json``'s ``pt_fit`` are rewritten; every (method, spp) whose
verdict changed is printed as a Markdown table (old, new, why), which
``docs/experiments/README.md`` carries. Nothing renders: folders without
per-pixel images keep their untrimmed relMSE as the headline metric.

A folder with the guided methods' ``table_6.md`` (its PT times at their quality) gets it again.
A suite whose scenes are re-judged gets its ``suite.csv``, ``aggregate.csv``/``.md`` and ``speedups.png`` again
(:func:`sparselt.experiments.suite_report.write_suite_tables`, the bootstrap's recorded seed). A comparison's page
(``index.html``) is written again with its tables and verdicts, noting the re-judging; its figures stay as measured.
A suite's own page keeps its first tables (its viewers' images are not published) and gets a note under its title
pointing to the re-judged ones.

Usage: ``.venv/bin/python scripts/rejudge_experiments.py [--check] [--folders a,b]`` (``--check`` writes nothing and
exits 1 if a folder would change; ``--folders`` re-judges only those folders of ``docs/experiments`` and what they
hold).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from sparselt.experiments.equal_time import DERIVED_ROW_COLUMNS, fit_record, judge
from sparselt.provenance import write_json
from sparselt.report.comparison import (PAGE_TITLE_PREFIX, comparison_page, equal_time_table, results_csv, summary_csv,
                                       table_6)
from sparselt.report.comparison_rows import COLUMN_ORDER
from sparselt.report.results import read_records_csv
from sparselt.report.table import markdown_document
from sparselt.results import reference_spp, report_config

EXPERIMENTS = Path(__file__).resolve().parents[1] / "docs" / "experiments"



def rejudge(folder):
    """``(files {name: text}, compare.json record, old summary, new summary, rows, fit)`` of one comparison
    folder."""
    record = json.loads((folder / "compare.json").read_text())
    rows = [{key: value for key, value in row.items() if key not in DERIVED_ROW_COLUMNS}
            for row in read_records_csv(folder / "results.csv")]
    fit, summary = judge(rows, baseline="pt", reference_spp=reference_spp(record), bias=record.get("bias"))
    record["pt_fit"] = fit_record(fit)
    table = equal_time_table(summary, methods=record["methods"], epsilon=record.get("relmse_epsilon", 0.01))
    files = {"results.csv": results_csv(rows, COLUMN_ORDER), "summary.csv": summary_csv(summary),
             "equal_time.md": table.markdown(), "equal_time.csv": table.csv()}
    if (folder / "table_6.md").exists():  # the guided methods' table carries PT's time at their quality
        guided = table_6(rows, record["config"]["scene"], report_config(record["config"]), methods=record["methods"])
        if guided:
            files["table_6.md"] = markdown_document(*guided)
            if (folder / "table_6.csv").exists():
                files["table_6.csv"] = guided[0].csv()
    page = folder / "index.html"
    if page.exists() and f"<title>{PAGE_TITLE_PREFIX}" in page.read_text():  # its tables and verdicts, judged again
        files["index.html"] = comparison_page(
            folder, rows, report_config(record["config"]), record["config"]["scene"], methods=record["methods"],
            summary=summary, epsilon=record.get("relmse_epsilon", 0.01), provenance=record["provenance"],
            note="Re-judged by scripts/rejudge_experiments.py (the commit that last changed this page says when): "
                 "the tables and verdicts are the equal-time protocol's of that commit; the measurements, images and "
                 "figures are the run's (provenance below).")
    old = read_records_csv(folder / "summary.csv")
    return files, record, old, summary, rows, fit


def _speedup(record):
    value = record.get("speedup_equal_quality")
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return "-"
    return f"{record.get('speedup_bound', '')}{value:.3g}x"


def changes(folder, old, new):
    """The (method, spp) whose verdict or speed-up's form changed, as Markdown rows."""
    before = {(record["method"], record["spp"]): record for record in old}
    lines = []
    for record in new:
        previous = before.get((record["method"], record["spp"]))
        if previous is None or record["verdict"] == "baseline":
            continue
        old_speedup, new_speedup = _speedup(previous), _speedup(record)
        infinite = "inf" in old_speedup
        if previous["verdict"] != record["verdict"] or infinite or record.get("speedup_bound"):
            lines.append(f"| {folder.relative_to(EXPERIMENTS)} | {record['method']} | {record['spp']} | "
                         f"{previous['verdict']} ({old_speedup}) | {record['verdict']} ({new_speedup}) |")
    return lines


class _SuiteFolder:
    """What :func:`~sparselt.experiments.suite_report.write_suite_tables` writes through, on a published folder."""

    def __init__(self, path):
        self.path = path

    def write_text(self, name, text):
        (self.path / name).write_text(text)

    def write_figure(self, name, figure):
        from sparselt.image_io import figure_bytes

        (self.path / name).write_bytes(figure_bytes(figure))


def rewrite_suite(folder, judged):
    """A published suite's tables from its re-judged scenes (``judged``: ``{name: (rows, fit, summary)}``)."""
    from sparselt.experiments.suite_report import machine_text, write_suite_tables

    record = json.loads((folder / "suite.json").read_text())
    names = [scene["name"] for scene in record["config"]["scenes"]]
    for name in names:  # scenes not re-judged on disk: judged here, in memory, for the aggregate
        if name not in judged:
            *_, summary, rows, fit = rejudge(folder / "scenes" / name)
            judged[name] = (rows, fit, summary)
    write_suite_tables(_SuiteFolder(folder), [(name, *judged[name]) for name in names],
                       {scene["name"]: scene["kind"] for scene in record["config"]["scenes"]},
                       {name: machine_text(record["scenes"][name]["machine"]) for name in names},
                       sorted(record["config"]["spps"]), resamples=record["bootstrap"]["resamples"],
                       seed=record["bootstrap"]["seed"])
    note_suite_page(folder / "index.html")


#: The note a re-judged suite's page carries under its title (its viewers' images are not published, so the page
#: itself is not written again).
SUITE_PAGE_NOTE = ('<p id="rejudged"><strong>Re-judged</strong> by scripts/rejudge_experiments.py (the commit that '
                   'last changed this note says when): the tables on this page are the run\'s first judgement; '
                   '<a href="aggregate.md">aggregate.md</a>, <a href="aggregate.csv">aggregate.csv</a> and '
                   '<a href="suite.csv">suite.csv</a> hold the equal-time protocol\'s of that commit, and each '
                   'scene\'s own report is re-judged.</p>')


def note_suite_page(page):
    """Put :data:`SUITE_PAGE_NOTE` under a suite page's title (replacing an earlier one); nothing without a page."""
    if not page.exists():
        return
    text = page.read_text()
    text = re.sub(r'\n<p id="rejudged">.*?</p>', "", text, flags=re.S)
    page.write_text(text.replace("</h1>", "</h1>\n" + SUITE_PAGE_NOTE, 1))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 if a folder would change")
    parser.add_argument("--folders", help="only these folders of docs/experiments (comma separated)")
    arguments = parser.parse_args(argv)
    roots = ([EXPERIMENTS / name for name in arguments.folders.split(",")] if arguments.folders else [EXPERIMENTS])
    for root in roots:
        if not root.is_dir():
            print(f"no folder {root}", file=sys.stderr)
            return 2
    table = ["| folder | method | spp | before (speed-up) | now (speed-up) |", "|---|---|---|---|---|"]
    stale = []
    suites = {}
    for summary_path in sorted(path for root in roots for path in root.rglob("summary.csv")):
        folder = summary_path.parent
        files, record, old, new, rows, fit = rejudge(folder)
        table += changes(folder, old, new)
        for name, text in files.items():
            if not (folder / name).exists() or (folder / name).read_text() != text:
                stale.append(f"{folder.relative_to(EXPERIMENTS)}/{name}")
                if not arguments.check:
                    (folder / name).write_text(text)
        if not arguments.check:
            write_json(folder / "compare.json", record)
        if (folder.parent.parent / "suite.json").is_file() and folder.parent.name == "scenes":
            suites.setdefault(folder.parent.parent, {})[folder.name] = (rows, fit, new)
    if not arguments.check:
        for suite, judged in suites.items():
            rewrite_suite(suite, judged)
    print("\n".join(table))
    if arguments.check and stale:
        print(f"{len(stale)} files would change: {', '.join(stale)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
