"""The reports of one ``sparselt compare`` run: results.csv, Tables 8.1/8.2 and 6.2/6.3 layouts, the page.

The equal-time comparison (thesis 8.1.1: *is there a gain in image quality
for the same computation time?*) hands its finished rows to
:func:`write_comparison_outputs`, which writes every report file through the
run's :class:`~sparselt.storage.folder.ExperimentFolder`:

``results.csv``
    One row per (method, spp, seed): :data:`COLUMN_ORDER` first, then any
    other key, sorted.
``quality_vs_time.png``, ``image_grid.png``, ``crop_grid.png``
    Thesis Figures 8.1/8.3 and 8.2/8.4 layouts (:mod:`.comparison_figures`).
``error_maps.png``
    Each method's per-pixel relative squared error at matched time (the image
    grid's panels), one shared logarithmic colour scale.
``table_8.md``, ``table_8.csv``
    Time per phase and quality per method and spp (mean over seeds), thesis
    Tables 8.1/8.2 beside the CoSaMP methods (depth of field).
``equal_time.md``, ``equal_time.csv``
    Each method's relMSE and SSIM over path tracing's at the same time.
``table_6.md``, ``table_6.csv``
    Guided methods in the layout of thesis Tables 6.2/6.3 (when any ran).
``methods.md``, ``methods.csv``
    Every method's family, role, source and resolved options.
``index.html``
    The page: Table 8 beside the thesis, the figures, equal-time verdicts.

This package is a sink: it takes plain rows (dicts with
:data:`~sparselt.report.comparison_rows.RESULT_COLUMNS`), a duck-typed
configuration (attributes ``kind``, ``shape``, ``output_resolution``,
``spps``, ``methods``), the methods' records (``{name: {'baseline',
'family', 'thesis_procedure', 'options', 'description'}}``, as
``compare.json`` holds them) and the folder, and imports nothing from
``experiments/``. Reports choose rows by the methods' roles (the baseline,
a family), never by their names. Thesis numbers come from
:mod:`sparselt.thesis` only (its tables and scene correspondence).

References
----------
Thesis chapter 8 (8.1.1, Tables 8.1 and 8.2, Figures 8.1-8.4) and 6.2
(Tables 6.2 and 6.3).
"""

from __future__ import annotations

import math
import os

import numpy as np

from ..thesis.numbers import thesis_table
from ..thesis.tables import (
    THESIS_GUIDING_TABLES,
    THESIS_TABLES,
    THESIS_TIMES,
    equal_time_thesis,
    guiding_table,
    guiding_thesis,
)
from .comparison_figures import (
    crop_grid_figure,
    error_map_figure,
    error_maps,
    image_grid_figure,
    matched_pictures,
    quality_figure,
)
from .comparison_rows import (
    COLUMN_ORDER,
    EXTRA_COLUMNS,
    RESULT_COLUMNS,
    baseline_of,
    group_mean,
    in_family,
    method_spp_groups,
    methods_in_order,
)
from .page import Figure, Section, page_html
from .results import RESULT_ROW_ORDER, dataset_csv, results_dataset, summary_dataset
from .table import Table, markdown_document

#: The relMSE's epsilon when a caller does not say (the comparison's, thesis 8.1.1).
DEFAULT_EPSILON = 0.01
#: Table 8's measured columns (means over seeds). "Reconstruction" is every method's reconstruction phase
#: (``seconds_reconstruction``): CoSaMP for the CoSaMP methods, a filter, the importance map (an SFT or CoSaMP) of
#: a guided method; only for the CoSaMP methods is it what the thesis's "CoSaMP" column times.
TABLE_8_COLUMNS = ("Total", "Sampling", "Reconstruction", "Integration", "Other", "SSIM", "relMSE",
                   "luminance ratio")


def _format(value):
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _runs(config):
    seeds = getattr(config, "seeds", None)
    repeats = getattr(config, "timing_repeats", None)
    text = []
    if seeds is not None:
        text.append(f"{len(seeds)} seed{'s' if len(seeds) != 1 else ''} ({', '.join(map(str, seeds))})"
                    + (": one seed gives no intervals, so no verdict excludes noise" if len(seeds) == 1 else ""))
    if repeats is not None:
        text.append(f"each cell timed {repeats} time{'s' if repeats != 1 else ''} (median kept)")
    return ", ".join(text) or "seeds and repeats as configured"


def _grid(config):
    return (f"kind {config.kind}, grid {'x'.join(map(str, config.shape))}, "
            f"image {'x'.join(map(str, config.output_resolution))}")


# ---------------------------------------------------------------------------------------------- tables
def results_csv(rows, columns=COLUMN_ORDER):
    """``results.csv``'s text, a view of the rows' Dataset (:func:`~sparselt.report.results.results_dataset`).

    ``columns`` first (in that order), then any other key of the rows,
    sorted; one row per (method, seed, spp) cell run, methods as first seen,
    then seed and spp ascending (:data:`~sparselt.report.results.RESULT_ROW_ORDER`).
    Floats with six significant digits; a missing value (a key a row lacks,
    ``''``, ``NaN``) is an empty cell.
    """
    return dataset_csv(results_dataset(rows), columns, row_order=RESULT_ROW_ORDER)


def summary_csv(summary):
    """``summary.csv``'s text, a view of the summary's Dataset (:func:`~sparselt.report.results.summary_dataset`):
    ``method``, ``spp``, then the records' keys in their order; one row per (method, spp)."""
    return dataset_csv(summary_dataset(summary))


def table_8(rows, scene, config, *, methods, epsilon=DEFAULT_EPSILON):
    """Tables 8.1/8.2 layout: seconds per phase and quality per method and spp, the thesis's beside (one Table).

    Means over seeds. The column "Reconstruction" is each method's
    ``seconds_reconstruction`` (see :data:`TABLE_8_COLUMNS`); the thesis's
    "CoSaMP" column keeps its label as "thesis CoSaMP". The thesis's four
    times stand beside the methods of family ``'cosamp'`` only, for the
    scenes of :data:`~sparselt.thesis.tables.THESIS_TABLES` at kind ``dof``
    (Tables 8.1/8.2 are depth of field; :func:`sparselt.thesis.tables.equal_time_thesis`),
    captioned then as the thesis's table; ``table_8.md``, the page and
    ``sparselt reproduce``'s chapter 8 are all made from this one object.
    """
    thesis = equal_time_thesis(scene, config.kind)
    cosamp = in_family(methods, "cosamp")
    columns, kinds = ["SPP"] + list(TABLE_8_COLUMNS), [""] + ["ours"] * len(TABLE_8_COLUMNS)
    if thesis:
        columns += [f"thesis {name}" for name in THESIS_TIMES]
        kinds += ["thesis"] * len(THESIS_TIMES)
    table_rows = []
    for method, spp, group in method_spp_groups(rows):
        cells = [str(spp)] + [f"{group_mean(group, key):.3f}" for key in (
            "seconds_total", "seconds_sampling", "seconds_reconstruction", "seconds_integration", "seconds_other")]
        cells += [f"{group_mean(group, 'ssim'):.3f}", f"{group_mean(group, 'relmse'):.4g}",
                  f"{group_mean(group, 'luminance_ratio'):.3f}"]
        if thesis:
            values = thesis[2].get(spp) if method in cosamp else None
            cells += [f"{value:g}" for value in values] if values else ["-"] * len(THESIS_TIMES)
        table_rows.append((method, cells))
    notes = ["Mean over seeds; kernels warmed first; Reconstruction = each method's reconstruction phase (CoSaMP "
             "for the CoSaMP methods; a filter, or a guided method's importance map, SFT or CoSaMP, for the others); "
             f"relMSE epsilon = {epsilon}."]
    if thesis:
        notes.append(f"Thesis: Table {thesis[0]} ({thesis[1]}), beside the CoSaMP methods at the same spp.")
    caption = (f"Table {thesis[0]}: {thesis_table(thesis[0])['caption']} (ours: {scene} = {thesis[1]}, {_grid(config)}; "
               "times (s) and quality per method)" if thesis else f"execution times (s) and quality, {scene}, {_grid(config)}")
    return Table(caption=caption[0].upper() + caption[1:], columns=columns, kinds=kinds, rows=table_rows,
                 notes=notes, label_header="method")


def _number(value, digits=3):
    return f"{value:.{digits}g}" if isinstance(value, float) and math.isfinite(value) else (
        "inf" if isinstance(value, float) and math.isinf(value) else "-")


def _with_interval(record, key, digits=3):
    value = record.get(key, "")
    if not isinstance(value, float):
        return "-"
    low, high = record.get(f"{key}_ci_low", ""), record.get(f"{key}_ci_high", "")
    if isinstance(low, float) and math.isfinite(low) and isinstance(high, float):
        return f"{_number(value, digits)} [{_number(low, digits)}, {_number(high, digits)}]"
    return _number(value, digits)


#: A metric's name in the reports.
METRIC_NAMES = {"relmse_trimmed": "relMSE (top 0.1% trimmed)", "relmse": "relMSE"}


def equal_time_table(summary, *, methods, epsilon=DEFAULT_EPSILON):
    """``equal_time.md``: per method and spp, quality against PT's at the same time, with intervals and verdicts.

    ``summary`` holds one record per (method, spp) from the equal-time protocol
    (:func:`sparselt.experiments.equal_time.summarize`): times are medians of
    repeated runs (min-max beside), qualities means over seeds with 95%
    intervals. The headline metric (``headline_metric``: the trimmed relMSE,
    or relMSE for folders measured before it) decides the verdict and the
    speed-up; the untrimmed relMSE's and FLIP's ratios and verdicts stand
    beside it. Every ratio below 1 means better than PT at equal time.
    """
    baseline = baseline_of(methods)
    records = [record for record in summary if record["method"] != baseline]
    baseline_bias = {record["spp"]: record.get("bias_fraction", "") for record in summary
                     if record["method"] == baseline}
    headline = records[0].get("headline_metric") or "relmse" if records else "relmse"
    others = [metric for metric in METRIC_NAMES if metric != headline
              and any(record.get(metric) not in ("", None) for record in records)]
    table_rows = []
    for record in records:
        seconds = (f"{record['seconds_total']:.3f} ({record['seconds_total_min']:.3f}-"
                   f"{record['seconds_total_max']:.3f}){' noisy' if record.get('timing_noisy') else ''}")
        cells = [str(record["spp"]), str(record["seeds"]), seconds, _with_interval(record, headline, 4),
                 _number(record.get(f"{headline}_pt_equal_time", ""), 4), _with_interval(record, f"{headline}_ratio"),
                 _verdict_text(record)]
        for metric in others:
            cells.append(_ratio_and_verdict(record, metric))
        cells += [_ratio_and_verdict(record, "flip"), _with_interval(record, "ssim_ratio"), _speedup_text(record),
                  _outlier_text(record), _bias_text(record, baseline_bias.get(record["spp"], ""))]
        table_rows.append((record["method"], cells))
    columns = (["spp", "seeds", "seconds (min-max)", f"{METRIC_NAMES[headline]} [95%]", "PT same time",
                "ratio [95%]", "verdict"] + [f"{METRIC_NAMES[metric]} ratio, verdict" for metric in others]
               + ["FLIP ratio, verdict", "SSIM ratio [95%]", "speed-up at equal quality [95%]", "outlier share",
                  "biased pixels (PT's)"])
    fallback = headline == "relmse" and any(record.get("relmse_trimmed") not in ("", None) for record in records)
    exponent = next((record["headline_exponent"] for record in records if record.get("headline_exponent")), None)
    return Table(
        caption="Equal-time quality against path tracing",
        columns=columns, kinds=[""] * 2 + ["ours"] * (len(columns) - 2), rows=table_rows, label_header="method",
        notes=(["The untrimmed relMSE decides here: PT's trimmed relMSE does not fall as c/spp + floor over its "
                "ladder (relative residual above 50%), as where trimming discards the few pixels that found a rare "
                "light."] if fallback else [])
        + ([f"PT's {METRIC_NAMES[headline]} falls more slowly than 1/spp over its ladder (c/spp + floor left a "
            f"relative residual above 20%, as where a few pixels per image find a rare bright path): its fits are "
            f"c/spp^k + floor with k = {exponent:g} for every seed."] if exponent else []) + [f"Times: median of each cell's repeated runs (every second counted, kernels warmed first). The "
               f"verdict and the speed-up use {METRIC_NAMES[headline]}; relMSE's epsilon = {epsilon}. PT's value "
               f"at a time comes from its fits (time = a + b spp; relMSE = c/spp + floor per seed) over its automatic "
               f"spp ladder, each times the rungs' mean measured/fitted ratio (interpolated in log spp, held "
               f"non-increasing), so that the fit reads every rung at its measured mean. Ratios: the method's mean "
               f"over seeds over PT's mean at the same times, both less the reference's own floor, with a 95% "
               f"delta-method interval widened by the timing's uncertainty and by that ratio's standard error; "
               f"'wins' or 'loses' only when the interval excludes 1. 'reference-limited': the reference's floor is "
               f"at least half of the method's or PT's measured error, so no ratio or speed-up is claimed; the "
               f"verdict names the reference spp that would resolve it. SSIM ratio: PT's over the method's; FLIP "
               f"ratio (HDR-FLIP): the method's over PT's; below 1 is better for every ratio. Speed-up: PT's time to "
               f"reach the method's error over the method's time, its interval the ratio's mapped through PT's "
               f"fits; '>' a lower bound where PT would need more spp than its ladder ran. Outlier share: the share "
               f"of relMSE in the top 0.1% of pixels (marked '!' above 0.5: a few pixels decide the untrimmed "
               f"metric). Biased pixels: the fraction Welch's t-test against the reference finds biased "
               f"(Benjamini-Hochberg at 1%), PT's at the same spp beside it: with few seeds the test also flags "
               f"some of an unbiased PT's pixels (skewed pixel means at low spp), so read the two together."])


def _verdict_text(record):
    """The headline verdict, with the reference spp a reference-limited cell needs and a disagreement mark."""
    text = record["verdict"]
    if text == "reference-limited" and record.get("reference_spp_needed") not in ("", None):
        text += f" (needs a reference of about {record['reference_spp_needed']} spp)"
    if record.get("verdicts_disagree") is True:
        text += " *"
    return text


def _ratio_and_verdict(record, metric):
    key = "flip_ratio" if metric == "flip" else f"{metric}_ratio"
    verdict = record.get(f"{metric}_verdict", "")
    if not verdict:
        return "-"
    if not isinstance(record.get(key), float):
        return verdict
    return f"{_with_interval(record, key)} {verdict}"


def _bias_text(record, baseline):
    fraction = record.get("bias_fraction", "")
    if not isinstance(fraction, float):
        return "-"
    return f"{_number(fraction, 2)} ({_number(baseline, 2)})" if isinstance(baseline, float) else _number(fraction, 2)


def _outlier_text(record):
    share = record.get("outlier_share", "")
    if not isinstance(share, float):
        return "-"
    return f"{share:.2f}{' !' if record.get('outlier_dominated') is True else ''}"


def _speedup_text(record):
    """The equal-quality speed-up with its interval; a bound beyond PT's ladder as '> 12x (PT's ladder ends at
    2048 spp)', never infinite."""
    value = record.get("speedup_equal_quality", "")
    if not isinstance(value, float):
        return "-"
    bound = record.get("speedup_bound", "")
    text = f"{bound} {_number(value)}x" if bound else f"{_number(value)}x"
    low, high = record.get("speedup_ci_low", ""), record.get("speedup_ci_high", "")
    if isinstance(low, float) and isinstance(high, float):
        low_text = (record.get("speedup_ci_low_bound") or "") + _number(low)
        high_text = (record.get("speedup_ci_high_bound") or "") + _number(high)
        text += f" [{low_text}, {high_text}]"
    if bound:
        side = "ends" if bound == ">" else "starts"
        text += f" (PT's ladder {side} at {record.get('pt_ladder_spp', '?')} spp)"
    return text


def guided_budgets(rows, methods):
    """The guided method the thesis's Tables 6.2/6.3 stand beside, and its budgets beside path tracing's.

    The method is the first of family ``'guided'`` that is a thesis procedure
    (else the first of the family). Each budget (increasing spp, where the
    baseline ran at the same spp) is ``{'spp', 'seconds', 'relmse',
    'pt_seconds', 'pt_relmse'}``, means over seeds
    (:func:`sparselt.thesis.tables.guiding_table`'s input).

    Returns
    -------
    (str or None, list of dict)
    """
    family = [method for method in methods_in_order(rows) if method in in_family(methods, "guided")]
    chosen = next((method for method in family if methods[method].get("thesis_procedure")), family[0] if family else None)
    baseline = baseline_of(methods)
    budgets = []
    for method, spp, group in method_spp_groups([row for row in rows if row["method"] == chosen]):
        plain = [row for row in rows if row["method"] == baseline and row["spp"] == spp]
        if plain:
            budgets.append({"spp": spp, "seconds": group_mean(group, "seconds_total"),
                            "relmse": group_mean(group, "relmse"), "pt_seconds": group_mean(plain, "seconds_total"),
                            "pt_relmse": group_mean(plain, "relmse")})
    return chosen, sorted(budgets, key=lambda budget: budget["spp"])


def table_6(rows, scene, config, *, methods):
    """Tables 6.2/6.3 layout for the guided methods: ``[ours, the thesis's beside ours]`` (the latter for its scenes).

    Ours: image size, spp, map spp, guided time, PT time at the same spp,
    both relMSEs and the guided relMSE over PT's at equal time (mean over
    seeds). For the scenes of :func:`sparselt.thesis.tables.guiding_thesis`,
    thesis Table 6.2/6.3 beside the budgets of :func:`guided_budgets`
    (:func:`sparselt.thesis.tables.guiding_table`, as ``sparselt reproduce``
    shows it). Empty when no method of family ``'guided'`` ran.
    """
    family = in_family(methods, "guided")
    baseline = baseline_of(methods)
    guided = [row for row in rows if row["method"] in family]
    if not guided:
        return []
    width, height = config.output_resolution
    table_rows = []
    for method, spp, group in method_spp_groups(guided):
        seconds, relmse = group_mean(group, "seconds_total"), group_mean(group, "relmse")
        pt_rows = [row for row in rows if row["method"] == baseline and row["spp"] == spp]
        pt_seconds = f"{group_mean(pt_rows, 'seconds_total'):.3f}" if pt_rows else "-"
        pt_relmse = f"{group_mean(pt_rows, 'relmse'):.4g}" if pt_rows else "-"
        equal = [row["relmse_pt_equal_time"] for row in group if row.get("relmse_pt_equal_time") not in ("", None)]
        ratio = f"{relmse / float(np.mean(equal)):.2f}" if len(equal) == len(group) else "-"
        map_spp = methods[method].get("options", {}).get("map_spp", "-")
        table_rows.append((method, [f"{width}x{height}", str(spp), str(map_spp), f"{seconds:.3f}", pt_seconds,
                                    f"{relmse:.4g}", pt_relmse, ratio]))
    tables = [Table(
        caption=f"Guided rendering times (s), {scene}, image {width}x{height}, map {'x'.join(map(str, config.shape))}",
        columns=["image size", "spp", "map spp", "guided time", "PT time (same spp)", "guided relMSE", "PT relMSE",
                 "relMSE / PT at equal time"],
        kinds=["", "", "", "ours", "ours", "ours", "ours", "ours"], rows=table_rows, label_header="method",
        notes=["Guided time includes the pilot pass, the map's reconstruction and the CDFs; mean over seeds."])]
    thesis = guiding_thesis(scene)
    if thesis:
        chosen, budgets = guided_budgets(rows, methods)
        seeds = getattr(config, "seeds", None)
        tables.append(guiding_table(thesis[0], budgets, resolution=(width, height), subject=(
            f"{scene} = {thesis[1]}, {chosen}, map {'x'.join(map(str, config.shape))}, mean over "
            + (f"{len(seeds)} seeds" if seeds is not None else "seeds"))))
    return tables


def results_table(rows):
    """A plain-text table of the rows (what the CLI prints)."""
    width = max([18] + [len(str(row["method"])) for row in rows])  # a variant's row name is written in full
    header = (f"{'method':{width}s} {'spp':>5s} {'seed':>4s} {'seconds':>8s} {'SSIM':>6s} {'relMSE':>9s} {'lum.':>6s} "
              f"{'PT relMSE same t':>16s}")
    lines = [header, "-" * len(header)]
    for row in rows:
        equal = row.get("relmse_pt_equal_time", "")
        lines.append(f"{row['method']:{width}s} {row['spp']:5d} {row['seed']:4d} {row['seconds_total']:8.3f} "
                     f"{row['ssim']:6.3f} {row['relmse']:9.4g} {row['luminance_ratio']:6.3f} "
                     f"{(f'{equal:.4g}' if equal not in ('', None) else '-'):>16s}")
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------- the page
def equal_time_verdicts(summary, *, methods):
    """One sentence per method, budget by budget, from the protocol's verdicts (never a mean over budgets)."""
    baseline = baseline_of(methods)
    return [verdict_sentence(method, summary) for method in dict.fromkeys(record["method"] for record in summary)
            if method != baseline]


_WORDING = {"wins": "wins", "loses": "loses", "within noise": "is within noise",
            "one seed": "has one seed (no interval)",
            "no PT value": "has no equal-time PT value (PT's ladder did not reach its time)",
            "reference-limited": "is reference-limited (the reference's own noise is at least half of its error or "
                                 "PT's)"}


def verdict_sentence(method, summary):
    """The sentence on ``method`` from its summary records, grouped by verdict with each budget's figures.

    Example: "cosamp wins at 40 and 81 spp (relMSE (top 0.1% trimmed) 0.77x [0.70, 0.85] and 0.81x [0.75, 0.88]
    PT's at equal time; speed-up 1.3x [1.2, 1.4] and > 4x (PT's ladder ends at 4096 spp)); is within noise at
    16 spp (...)." A reference-limited budget names the reference it needs; a budget whose untrimmed or FLIP
    verdict differs from the headline's says so.
    """
    records = [record for record in summary if record["method"] == method]
    parts = []
    for name, wording in _WORDING.items():
        chosen = [record for record in records if record["verdict"] == name]
        if not chosen:
            continue
        spps = _and([str(record["spp"]) for record in chosen])
        if name == "no PT value":
            parts.append(f"{wording} at {spps} spp")
            continue
        if name == "reference-limited":
            needed = [f"{record['spp']} spp needs about {record['reference_spp_needed']}"
                      for record in chosen if record.get("reference_spp_needed") not in ("", None)]
            parts.append(f"{wording} at {spps} spp" + (f" (a reference of more spp would resolve it: "
                                                       f"{_and(needed)})" if needed else ""))
            continue
        metric = METRIC_NAMES.get(chosen[0].get("headline_metric") or "relmse", "relMSE")
        figures = _and([_ratio_text(record) for record in chosen])
        speedups = _and([_speedup_text(record) for record in chosen])
        parts.append(f"{wording} at {spps} spp ({metric} {figures} PT's at equal time; speed-up {speedups})")
    sentence = f"{method} " + "; ".join(parts) + "." if parts else f"{method}: no runs."
    disagreeing = [record for record in records if record.get("verdicts_disagree") is True]
    for record in disagreeing:
        others = [f"{METRIC_NAMES.get(metric, 'FLIP')} {record.get(f'{metric}_verdict')}"
                  for metric in ("relmse", "flip") if record.get(f"{metric}_verdict")
                  and metric != record.get("headline_metric")]
        sentence += f" At {record['spp']} spp the other metrics disagree: {_and(others)}."
    dominated = [str(record["spp"]) for record in records if record.get("outlier_dominated") is True]
    if dominated:
        sentence += (f" At {_and(dominated)} spp the top 0.1% of pixels hold more than half of its relMSE (a few "
                     "pixels decide the untrimmed metric).")
    return sentence


def _ratio_text(record):
    metric = record.get("headline_metric") or "relmse"
    ratio = record.get(f"{metric}_ratio", record.get("relmse_ratio"))
    low, high = record.get(f"{metric}_ratio_ci_low"), record.get(f"{metric}_ratio_ci_high")
    text = f"{ratio:.2f}x"
    if isinstance(low, float) and math.isfinite(low):
        text += f" [{low:.2f}, {high:.2f}]"
    return text


def _and(items):
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


FIGURES = (("quality_vs_time.png", "Figures 8.1/8.3 layout: relMSE and SSIM against time"),
           ("image_grid.png", "Figures 8.2/8.4 layout: the methods at matched time beside the reference"),
           ("error_maps.png", ("Per-pixel relative squared error of each method in the image grid, against the "
                               "reference; one logarithmic colour scale shared by all panels")),
           ("crop_grid.png", "Details where the methods disagree most"))
LINKS = ("results.csv", "summary.csv", "equal_time.md", "table_8.md", "table_8.csv", "table_6.md", "methods.md", "compare.json")


def methods_table(methods, rows=None):
    """Every method of the comparison: family, whether it is the thesis's procedure, source and resolved options.

    ``rows`` (optional) restricts and orders it to the methods that have rows.
    """
    names = methods_in_order(rows) if rows else list(methods)
    table_rows = []
    for name in names:
        record = methods.get(name, {})
        role = "baseline" if record.get("baseline") else ("thesis procedure" if record.get("thesis_procedure")
                                                          else "")
        options = ", ".join(f"{key}={_format(value)}" for key, value in (record.get("options") or {}).items())
        table_rows.append((name, [record.get("family", ""), role, options or "-", record.get("source", "")]))
    return Table(caption="Methods: roles and resolved options", columns=["family", "role", "options", "source"],
                 kinds=["ours"] * 4, rows=table_rows, label_header="method",
                 notes=["Every option at the value the runs used (defaults resolved); 'sparselt methods NAME' "
                        "describes them."])


def comparison_section(folder_path, prefix, rows, config, scene, *, methods, summary, title=None,
                       epsilon=DEFAULT_EPSILON):
    """The report section of the comparison in ``folder_path``: Table 8 beside the thesis, figures, verdicts, links.

    Parameters
    ----------
    folder_path : str
        The comparison's folder; only the figures and files it holds are shown or linked.
    prefix : str
        The folder relative to the page ('' when the page is in it); every path starts with it.
    rows : list of dict
    config
        ``kind``, ``shape``, ``output_resolution`` (see the module docstring).
    scene : str
    methods : dict
        The methods' records (roles, options), as ``compare.json`` holds them.
    summary : list of dict
        The equal-time protocol's record per (method, spp).
    title : str, optional
        Default: the scene, kind, grid and image size.
    epsilon : float, optional
        The relMSE's epsilon (stated in the introduction and under Table 8).

    Returns
    -------
    Section
    """
    folder_path = os.fspath(folder_path)

    def join(name):
        return f"{prefix}/{name}" if prefix else name

    figures = [Figure(join(name), caption) for name, caption in FIGURES
               if os.path.exists(os.path.join(folder_path, name))]
    links = [(name, join(name)) for name in LINKS if os.path.exists(os.path.join(folder_path, name))]
    return Section(
        title=title or f"{scene}, {_grid(config)}",
        introduction=f"{scene}, {_grid(config)}: every method at every budget against a cached Mitsuba reference; "
                     f"{_runs(config)}; relMSE epsilon {epsilon:g}; equal time means every second counted (pilot "
                     "samples, reconstruction, filtering), kernels warmed first, PT's quality at a method's time "
                     "taken from fits over its automatic spp ladder.",
        tables=[table_8(rows, scene, config, methods=methods, epsilon=epsilon), methods_table(methods, rows)],
        figures=figures, verdicts=equal_time_verdicts(summary, methods=methods), links=links)


# ---------------------------------------------------------------------------------------------- the one entry point
def write_comparison_outputs(folder, rows, reference, config, scene, *, methods, summary, epsilon, image_of,
                             provenance, fit=None, columns=COLUMN_ORDER):
    """Write every report file of a comparison through its folder (see the module docstring); return their names.

    Parameters
    ----------
    folder : sparselt.storage.folder.ExperimentFolder
        The comparison's folder, open (``with folder.open(): ...``).
    rows : list of dict
        Every finished cell's row, with the equal-time columns
        (:func:`sparselt.experiments.equal_time.add_equal_time_columns`).
    reference : ndarray, shape (height, width, 3)
        The linear reference image (its exposure is every picture's).
    config
        Duck-typed: ``kind``, ``shape``, ``output_resolution``, ``spps``,
        ``methods`` (``map_spp`` when present).
    scene : str
        The scene's name.
    methods : dict
        ``{name: record}``: each method's roles (``baseline``, ``family``,
        ``thesis_procedure``), ``options`` and ``source``, as ``compare.json``
        holds them.
    summary : list of dict
        The equal-time protocol's record per (method, spp)
        (:func:`sparselt.experiments.equal_time.summarize`): ``summary.csv``,
        the equal-time table and the verdicts.
    epsilon : float
        The relMSE's epsilon.
    image_of : callable
        ``image_of(row)`` returns a row's linear ``(height, width, 3)`` image.
    provenance : dict
        :func:`~sparselt.provenance.environment_record`, shown on the page.
    fit : BaselineFit, optional
        PT's fit (drawn on the relMSE plot: :func:`~sparselt.report.comparison_figures.quality_figure`).
    columns : sequence of str, optional
        ``results.csv``'s leading columns (default :data:`COLUMN_ORDER`).

    Returns
    -------
    list of str
        The names written, relative to the folder.
    """
    written = []

    def text(name, content):
        folder.write_text(name, content)
        written.append(name)

    def figure(name, made):
        folder.write_figure(name, made, dpi=110)
        written.append(name)

    text("results.csv", results_csv(rows, columns))
    text("summary.csv", summary_csv(summary))
    figure("quality_vs_time.png", quality_figure(rows, scene, epsilon, summary, fit))
    if rows:
        matched = matched_pictures(rows, reference, image_of)
        figure("image_grid.png", image_grid_figure(*matched))
        figure("crop_grid.png", crop_grid_figure(*matched))
        at_time, target, _ = matched
        figure("error_maps.png", error_map_figure(at_time, target, error_maps(at_time, reference, image_of,
                                                                               epsilon=epsilon), epsilon=epsilon))
    for stem, table in (("table_8", table_8(rows, scene, config, methods=methods, epsilon=epsilon)),
                        ("equal_time", equal_time_table(summary, methods=methods, epsilon=epsilon)),
                        ("methods", methods_table(methods, rows))):
        folder.write_table(stem, table)
        written += [stem + ".md", stem + ".csv"]
    guided = table_6(rows, scene, config, methods=methods)
    if guided:
        text("table_6.md", markdown_document(*guided))
        text("table_6.csv", guided[0].csv())
    text("index.html", comparison_page(folder.path, rows, config, scene, methods=methods, summary=summary,
                                       epsilon=epsilon, provenance=provenance))
    return written


#: Every comparison page's title starts so (:func:`comparison_page`).
PAGE_TITLE_PREFIX = "sparselt compare: "


def comparison_page(folder_path, rows, config, scene, *, methods, summary, epsilon, provenance, note=""):
    """A comparison's page (``index.html``) as HTML text: its :func:`comparison_section` under the title
    :data:`PAGE_TITLE_PREFIX` + ``scene``, with ``provenance`` and an optional ``note`` under the title (what
    :func:`write_comparison_outputs` writes, and the committed folders' re-judging)."""
    section = comparison_section(folder_path, "", rows, config, scene, methods=methods, summary=summary,
                                 epsilon=epsilon)
    return page_html(folder_path, PAGE_TITLE_PREFIX + scene, [section], provenance, note=note)


__all__ = ["COLUMN_ORDER", "DEFAULT_EPSILON", "EXTRA_COLUMNS", "RESULT_COLUMNS", "TABLE_8_COLUMNS", "THESIS_GUIDING_TABLES",
           "THESIS_TABLES", "THESIS_TIMES", "PAGE_TITLE_PREFIX", "comparison_page", "comparison_section", "equal_time_table", "equal_time_verdicts",
           "guided_budgets", "methods_table", "results_csv",
           "results_table", "summary_csv", "table_6", "table_8", "verdict_sentence", "write_comparison_outputs"]
