"""A suite's report (``sparselt suite``, :mod:`sparselt.experiments.suite`): ``suite.csv``, ``aggregate.csv``/``.md``, ``speedups.png``, the viewers' images and the page.

Written from the scenes' comparison folders (each judged again by the one
equal-time protocol, :func:`sparselt.results.judged_comparison`), so a
resumed suite and a fresh one report the same values.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field

import numpy as np

from ..images import reference_exposure
from ..provenance import environment_record
from ..report.comparison_figures import ERROR_COLOUR_MAP, error_maps, shared_error_scale
from ..report.comparison_rows import matched_rows
from ..report.page import Figure, Section, page_html
from ..report.plotting import pyplot
from ..report.table import Table
from ..report.viewer import viewer_assets, viewer_html
from .equal_time import SUMMARY_COLUMNS
from .quality import RELMSE_EPSILON
from .suite_aggregate import (
    AGGREGATE_COLUMNS,
    BOOTSTRAP_SEED,
    CONFIDENCE,
    RESAMPLES,
    aggregate,
    aggregate_verdict,
)

SUITE_COLUMNS = ("scene", "kind", "machine") + SUMMARY_COLUMNS
VIEWER = "viewer"


@dataclass
class SuiteResult:
    """What ``sparselt suite`` returns: the folder, the aggregate's records, the scenes' summary rows."""

    out: str
    aggregate: list
    rows: list = field(default_factory=list)
    seconds: float = 0.0
    #: Scene name -> why its comparison could not be made (left out of every table).
    not_compared: dict = field(default_factory=dict)
    #: The scenes of ``not_compared`` whose comparison's process crashed (not recorded: a rerun tries them again).
    crashed: tuple = ()

    def table(self):
        """The aggregate as printed text."""
        table = aggregate_table(self.aggregate)
        widths = [max(len(str(cell)) for cell in column) for column in zip(*table.grid())]
        return "\n".join("  ".join(str(cell).ljust(width) for cell, width in zip(line, widths)).rstrip()
                         for line in table.grid())


def _format(value):
    if isinstance(value, bool):
        return "True" if value else "False"
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.6g}"
    return "" if value is None else str(value)


def csv_text(records, columns):
    """``records`` (dicts) as CSV text with ``columns``, floats to 6 significant digits."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for record in records:
        writer.writerow([_format(record.get(column, "")) for column in columns])
    return buffer.getvalue()


def _interval_text(value, low, high, bound=""):
    if not isinstance(value, float):
        return "-"
    if isinstance(low, float) and math.isfinite(low):
        return f"{bound}{value:.3g}x [{low:.3g}, {high:.3g}]"
    return f"{bound}{value:.3g}x"


def aggregate_table(records):
    """The aggregate as a :class:`~sparselt.report.table.Table` (markdown, HTML and text)."""
    header = ["spp", "speed-up over PT (geometric mean, 95% interval)", "relMSE ratio at equal time",
              "verdict across scenes", "wins / within noise / loses / reference-limited / other", "worst scene"]
    rows = []
    for record in records:
        bound = {">": ">", "<": "<", "both": "~"}.get(record["speedup_bound"], "")
        speedup = _interval_text(record["speedup_geometric_mean"], record["speedup_ci_low"],
                                 record["speedup_ci_high"], bound)
        ratio = _interval_text(record["relmse_ratio_geometric_mean"], record["relmse_ratio_ci_low"],
                               record["relmse_ratio_ci_high"])
        counts = " / ".join(str(record[key]) for key in ("wins", "within_noise", "loses", "reference_limited", "other"))
        worst = (f"{record['worst_scene']} ({record['worst_speedup']:.3g}x, {record['worst_verdict']})"
                 if record["worst_scene"] else "-")
        rows.append((record["method"], [str(record["spp"]), speedup, ratio, aggregate_verdict(record), counts, worst]))
    caption = (f"Every method over the suite's scenes, per budget: the geometric mean over scenes of the "
               f"equal-quality speed-up over PT and of the relMSE ratio at equal time (headline metric: relMSE with "
               f"the top 0.1% of pixel errors discarded, epsilon {RELMSE_EPSILON}), {int(100 * CONFIDENCE)}% "
               f"bootstrap intervals over scenes and seeds ({RESAMPLES} resamples); '>' marks a mean with a "
               "speed-up read beyond PT's ladder (a lower bound). Reference-limited cells are counted, not averaged.")
    return Table(caption=caption, columns=header, rows=rows, label_header="method")


def speedup_figure(scenes, records, spps):
    """Per budget, a heat map of every (method, scene) speed-up, one logarithmic colour scale (1 = PT)."""
    from matplotlib.colors import LogNorm

    plot = pyplot()
    methods = list(dict.fromkeys(record["method"] for record in records))
    names = [name for name, *_ in scenes]
    figure, axes = plot.subplots(1, len(spps), figsize=(2.5 + 0.45 * len(names) * len(spps), 1.8 + 0.35 * len(methods)),
                                 squeeze=False)
    norm = LogNorm(vmin=1 / 8, vmax=8)
    image = None
    for axis, spp in zip(axes[0], spps):
        values = np.full((len(methods), len(names)), np.nan)
        labels = np.full(values.shape, "", dtype=object)
        for column, (name, _, _, summary) in enumerate(scenes):
            for record in summary:
                if record["spp"] != spp or record["method"] not in methods:
                    continue
                row = methods.index(record["method"])
                speedup = record.get("speedup_equal_quality")
                if isinstance(speedup, float):
                    values[row, column] = speedup
                    labels[row, column] = f"{record.get('speedup_bound', '')}{speedup:.2g}"
                elif record.get("verdict") == "reference-limited":
                    labels[row, column] = "ref"
        image = axis.imshow(np.clip(values, 1 / 8, 8), cmap="RdBu", norm=norm, aspect="auto")
        for (row, column), text in np.ndenumerate(labels):
            if text:
                axis.text(column, row, text, ha="center", va="center", fontsize=7)
        axis.set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=8)
        axis.set_yticks(range(len(methods)), methods if axis is axes[0][0] else [""] * len(methods), fontsize=8)
        axis.set_title(f"{spp} spp", fontsize=9)
    ticks = [1 / 8, 1 / 4, 1 / 2, 1, 2, 4, 8]
    bar = figure.colorbar(image, ax=list(axes[0]), shrink=0.8, ticks=ticks)
    bar.ax.set_yticklabels(["1/8", "1/4", "1/2", "1", "2", "4", "8"])
    bar.ax.minorticks_off()
    bar.set_label("equal-quality speed-up over PT\n(blue: faster than PT)", fontsize=8)
    return figure


def _error_png(error, low, high):
    from matplotlib import image as matplotlib_image

    buffer = io.BytesIO()
    logarithm = np.log10(np.clip(np.nan_to_num(error, nan=high), low, high))
    matplotlib_image.imsave(buffer, logarithm, cmap=ERROR_COLOUR_MAP, vmin=math.log10(low), vmax=math.log10(high),
                            format="png")
    return buffer.getvalue()


def write_viewer_images(folder, name, scene_folder, rows):
    """The scene's viewer images under ``viewer/NAME/``: the reference, every method at matched time and its
    per-pixel relative squared error on one log scale; returns the viewer's entries and its legend."""
    from ..methods.variants import variant_file_name
    from .comparison_cells import IMAGES, cell_name

    reference = np.load(f"{scene_folder}/{IMAGES}/reference.npy")
    exposure = reference_exposure(reference)
    matched, target = matched_rows(rows)
    images = [np.load(f"{scene_folder}/{IMAGES}/{cell_name(row['method'], row['spp'], row['seed'])}.npy")
              for row in matched]
    loaded = dict(zip(map(id, matched), images))
    errors = error_maps(matched, reference, lambda row: loaded[id(row)], epsilon=RELMSE_EPSILON)
    low, high = shared_error_scale(errors)
    base = f"{VIEWER}/{name}"
    folder.write_png(f"{base}/reference.png", reference, exposure=exposure)
    entries = []
    for row, image, error in zip(matched, images, errors):
        stem = f"{base}/{variant_file_name(row['method'])}_spp{row['spp']}"
        folder.write_png(f"{stem}.png", image, exposure=exposure)
        folder.write_bytes(f"{stem}_error.png", _error_png(error, low, high))
        caption = (f"{row['spp']} spp, {row['seconds_total']:.3g} s, relMSE {row['relmse']:.3g}"
                   + (f", trimmed {row['relmse_trimmed']:.3g}" if isinstance(row.get("relmse_trimmed"), float)
                      else ""))
        entries.append({"label": row["method"], "image": f"{stem}.png", "error": f"{stem}_error.png",
                        "caption": caption})
    legend = (f"per-pixel relative squared error (epsilon {RELMSE_EPSILON}), log scale {low:.2g} to {high:.2g}; "
              f"images at matched time {target:.3g} s (each method's run nearest to it, seed "
              f"{min(row['seed'] for row in rows)})")
    return {"label": "reference", "image": f"{base}/reference.png", "caption": ""}, entries, legend


def machine_text(machine):
    """Where a scene was timed, in words: host, processors and the renderer's threads (when recorded)."""
    threads = f", {machine['threads']} threads" if machine.get("threads") else ""
    return f"{machine['host']} ({machine['cpus']} cpus{threads})"


def scene_sentences(name, summary):
    """The scene's best and worst method at each budget, in words."""
    sentences = []
    for spp in sorted({record["spp"] for record in summary}):
        judged = [record for record in summary if record["spp"] == spp
                  and isinstance(record.get("speedup_equal_quality"), float)]
        if not judged:
            continue
        best = max(judged, key=lambda record: record["speedup_equal_quality"])
        worst = min(judged, key=lambda record: record["speedup_equal_quality"])
        sentences.append(f"{name}, {spp} spp: best {best['method']} {best['speedup_bound']}"
                         f"{best['speedup_equal_quality']:.3g}x ({best['verdict']}); worst {worst['method']} "
                         f"{worst['speedup_bound']}{worst['speedup_equal_quality']:.3g}x ({worst['verdict']}).")
    return sentences


def write_suite_tables(folder, scenes, kinds, machines, spps, **aggregate_options):
    """A suite's tables from its judged scenes: ``suite.csv``, ``aggregate.csv``/``.md`` and ``speedups.png``.

    ``scenes``: ``(name, rows, fit, summary)`` per scene, in the suite's
    order; ``kinds`` and ``machines``: text per scene name; ``folder``: anything
    with ``write_text(name, text)`` and ``write_figure(name, figure)``. The
    suite's run and ``scripts/rejudge_experiments.py`` (a published suite
    re-judged) both write them so. Returns ``(aggregate records, suite.csv's
    rows, the aggregate's Table)``.
    """
    suite_rows = [dict(record, scene=name, kind=kinds[name], machine=machines[name])
                  for name, _, _, summary in scenes for record in summary]
    folder.write_text("suite.csv", csv_text(suite_rows, SUITE_COLUMNS))
    aggregated = aggregate(scenes, **aggregate_options)
    folder.write_text("aggregate.csv", csv_text(aggregated, AGGREGATE_COLUMNS))
    table = aggregate_table(aggregated)
    folder.write_text("aggregate.md", table.markdown())
    folder.write_figure("speedups.png", speedup_figure(scenes, aggregated, spps))
    return aggregated, suite_rows, table


def write_suite_outputs(folder, config, records, *, seconds, not_compared=None, crashed=()):
    """Every report file of a finished suite (see :mod:`sparselt.experiments.suite`); returns a :class:`SuiteResult`.

    ``not_compared``: scene name -> why its comparison could not be made; those scenes are left out of every table
    and listed in their own section of the page and in ``suite.json``. ``crashed``: those of them whose
    comparison's process crashed (``suite.json``'s ``crashed``)."""
    from ..results import judged_comparison
    from .suite import SCENES, SUITE_FILE

    not_compared = dict(not_compared or {})
    compared = [scene for scene in config.scenes if scene.name not in not_compared]
    scenes = []
    for scene in compared:
        rows, fit, summary, attributes = judged_comparison(folder.path_of(f"{SCENES}/{scene.name}"))
        scenes.append((scene.name, rows, fit, summary))
    aggregated, suite_rows, table = write_suite_tables(
        folder, scenes, {scene.name: scene.kind for scene in compared},
        {name: machine_text(records[name]["machine"]) for name, *_ in scenes}, sorted(config.spps))

    left_out = f" ({len(not_compared)} more could not be compared: below)" if not_compared else ""
    sections = [Section(title="Across the suite", tables=[table], introduction=(
        f"Suite {config.name}: {len(compared)} scenes{left_out}, methods {', '.join(config.methods)}, "
        f"{', '.join(map(str, config.spps))} spp, seeds {', '.join(map(str, config.seeds))}, "
        f"{config.timing_repeats} timing repeats, reference {config.reference_spp}."),
        links=[("suite.csv: every scene's summary", "suite.csv"), ("aggregate.csv", "aggregate.csv"),
               ("suite.json: configuration, machines, seconds", SUITE_FILE)])]
    sections[0].figures = [Figure("speedups.png", "Equal-quality speed-up over PT of every method on every scene "
                                   "('ref': reference-limited; '>' beyond PT's ladder)")]
    if not_compared:
        sections.append(Section(title="Scenes not compared", introduction=" ".join(
            f"Scene {name}: {message}." for name, message in not_compared.items())))
    for index, (scene, (name, rows, fit, summary)) in enumerate(zip(compared, scenes)):
        reference, entries, legend = write_viewer_images(folder, name, folder.path_of(f"{SCENES}/{name}"), rows)
        record = records[name]
        introduction = (f"{scene.reason + ' ' if scene.reason else ''}Scene {scene.scene!r}, kind {scene.kind}; "
                        f"timed on {machine_text(record['machine'])}; reference "
                        f"{record.get('reference', {}).get('spp', '?')} spp; {record['seconds']:.0f} s.")
        sections.append(Section(title=f"Scene {name}", introduction=introduction,
                                verdicts=scene_sentences(name, summary),
                                markup=viewer_html(entries, reference=reference, identifier=f"viewer-{index}",
                                                   legend=legend),
                                links=[(f"{name}: the comparison's own report", f"{SCENES}/{name}/index.html")]))
    folder.write_text("index.html", page_html(folder.path, f"sparselt suite: {config.name}", sections,
                                              environment_record(), head=viewer_assets()))
    record = folder.read_json(SUITE_FILE)
    record.update(status="complete", seconds=seconds, scenes={name: records[name] for name, *_ in scenes},
                  bootstrap={"resamples": RESAMPLES, "seed": BOOTSTRAP_SEED, "confidence": CONFIDENCE,
                             "levels": "scenes, then seeds within each scene"},
                  relmse_epsilon=RELMSE_EPSILON)
    record.pop("not_compared", None)
    record.pop("crashed", None)
    if not_compared:
        record["not_compared"] = not_compared
    if crashed:
        record["crashed"] = list(crashed)
    folder.write_json(SUITE_FILE, record)
    return SuiteResult(out=folder.path, aggregate=aggregated, rows=suite_rows, seconds=seconds,
                       not_compared=not_compared, crashed=tuple(crashed))

