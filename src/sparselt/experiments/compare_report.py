"""What ``sparselt compare`` writes besides images: the CSV, the plots and Tables 8.1/8.2."""

from __future__ import annotations

import csv
import io
import math

import numpy as np

from ..images import reference_exposure, save_figure, srgb_tonemap
from ..provenance import atomic_write_bytes

# Thesis Tables 8.1 (Dragons) and 8.2 (San Miguel): SPP -> (total, sampling, CoSaMP, integration) seconds.
def _thesis_rows(table, columns):
    """``{first-column value: tuple of the other columns}`` of a thesis table (:mod:`sparselt.thesis_numbers`)."""
    from ..thesis_numbers import thesis_table, thesis_value

    rows = {}
    for row in thesis_table(table)["rows"]:
        label = row["label"]
        key = int(label.split("x")[0]) if "x" in label else int(label)
        values = (thesis_value(table, label, column) for column in columns)
        rows[key] = tuple(int(value) if float(value).is_integer() else value for value in values)
    return rows


_TIMES = ("Total", "Sampling", "CoSaMP", "Integration")
#: Thesis Tables 8.1/8.2 (CoSaMP execution times, depth of field): scene -> (table, thesis scene, {spp: times}).
THESIS_TABLES = {
    "dof-sculptures": ("8.1", "Dragons", _thesis_rows("8.1", _TIMES)),
    "courtyard": ("8.2", "San Miguel", _thesis_rows("8.2", _TIMES)),
}


def _format(value):
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def method_spp_groups(rows):
    """``(method, spp, rows)`` per comparison cell (its rows over seeds): methods as first seen, spp ascending."""
    for method in dict.fromkeys(row["method"] for row in rows):
        for spp in sorted({row["spp"] for row in rows if row["method"] == method}):
            yield method, spp, [row for row in rows if row["method"] == method and row["spp"] == spp]


def group_mean(group, key):
    """Mean of ``key`` over a cell's rows (its seeds)."""
    return float(np.mean([row[key] for row in group]))


TABLE_8_COLUMNS = ("Total", "Sampling", "CoSaMP", "Integration", "Other", "SSIM", "relMSE", "luminance ratio")


def table_8_rows(rows, scene, config):
    """Tables 8.1/8.2 (mean over seeds): ``(thesis, {method: [(spp, cells, thesis values or None)]})``.

    ``cells`` are the formatted :data:`TABLE_8_COLUMNS`; ``thesis`` is the
    :data:`THESIS_TABLES` entry of the scene (depth of field only) or ``None``,
    and its values stand beside the CoSaMP methods only. ``table_8.md`` and
    the comparison's report page are both made from this.
    """
    thesis = THESIS_TABLES.get(scene) if config.kind == "dof" else None  # Tables 8.1/8.2 are depth of field
    methods = {}
    for method, spp, group in method_spp_groups(rows):
        cells = [f"{group_mean(group, key):.3f}" for key in ("seconds_total", "seconds_sampling",
                                                             "seconds_reconstruction", "seconds_integration",
                                                             "seconds_other")]
        cells += [f"{group_mean(group, 'ssim'):.3f}", f"{group_mean(group, 'relmse'):.4g}",
                  f"{group_mean(group, 'luminance_ratio'):.3f}"]
        values = thesis[2].get(spp) if thesis and method.startswith("cosamp") else None
        methods.setdefault(method, []).append((spp, cells, values))
    return thesis, methods


def write_results_csv(path, rows, columns):
    """``results.csv``: ``columns`` first (in that order), then any other keys, sorted."""
    extra = sorted({key for row in rows for key in row} - set(columns))
    header = list(columns) + extra
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([_format(row.get(key, "")) for key in header])
    atomic_write_bytes(path, buffer.getvalue().encode())


def add_equal_time_columns(rows):
    """Add ``relmse_pt_equal_time`` and ``ssim_pt_equal_time``: PT's quality at the row's time.

    Log-log interpolation of PT's runs (relMSE), log-time for SSIM, after
    averaging PT over seeds. Empty where PT was not run or the time is outside
    PT's measured range: nothing is extrapolated.
    """
    curves = {quantity: _mean_curve([row for row in rows if row["method"] == "pt"], quantity)
              for quantity in ("relmse", "ssim")}
    for row in rows:
        for quantity, curve in curves.items():
            key = f"{quantity}_pt_equal_time"
            row[key] = ""
            if row["method"] == "pt" or len(curve) < 2:
                continue
            times, values = zip(*curve)
            time = row["seconds_total"]
            if times[0] <= time <= times[-1]:
                if quantity == "relmse":
                    row[key] = float(np.exp(np.interp(np.log(time), np.log(times), np.log(values))))
                else:
                    row[key] = float(np.interp(np.log(time), np.log(times), values))


def write_equal_time_table(path, rows, epsilon):
    """``equal_time.md``: per method and spp (mean over seeds), relMSE and SSIM against PT's at the same time.

    relMSE ratio < 1 and SSIM ratio > 1 mean the method beats path tracing at
    equal time; '-' where PT's runs do not reach that time.
    """
    lines = ["# Equal-time quality against path tracing", "",
             f"PT's relMSE and SSIM interpolated at each method's total time (mean over seeds; relMSE epsilon = "
             f"{epsilon}). relMSE ratio < 1 and SSIM ratio > 1: better than PT at equal time.", "",
             "| method | spp | seconds | relMSE | PT relMSE same time | relMSE ratio | SSIM | PT SSIM same time | "
             "SSIM ratio | luminance ratio |", "|---|---|---|---|---|---|---|---|---|---|"]
    for method, spp, group in method_spp_groups(rows):
        if method == "pt":
            continue
        mean = {key: group_mean(group, key) for key in ("seconds_total", "relmse", "ssim", "luminance_ratio")}
        pt_relmse = [row["relmse_pt_equal_time"] for row in group if row.get("relmse_pt_equal_time") != ""]
        pt_ssim = [row["ssim_pt_equal_time"] for row in group if row.get("ssim_pt_equal_time") != ""]
        if len(pt_relmse) == len(group):
            reference_relmse, reference_ssim = float(np.mean(pt_relmse)), float(np.mean(pt_ssim))
            cells = (f"{reference_relmse:.4g} | {mean['relmse'] / reference_relmse:.2f} | {mean['ssim']:.3f} | "
                     f"{reference_ssim:.3f} | {mean['ssim'] / reference_ssim:.2f}")
        else:
            cells = f"- | - | {mean['ssim']:.3f} | - | -"
        lines.append(f"| {method} | {spp} | {mean['seconds_total']:.3f} | {mean['relmse']:.4g} | {cells} | "
                     f"{mean['luminance_ratio']:.3f} |")
    atomic_write_bytes(path, ("\n".join(lines) + "\n").encode())


def _mean_curve(rows, quantity):
    """[(mean seconds, mean quantity)] per spp, sorted by time."""
    by_spp = {}
    for row in rows:
        by_spp.setdefault(row["spp"], []).append(row)
    curve = [(float(np.mean([r["seconds_total"] for r in group])), float(np.mean([r[quantity] for r in group])))
             for group in by_spp.values()]
    return sorted(curve)


def results_table(rows):
    """A plain-text table of the rows (what the CLI prints)."""
    header = f"{'method':18s} {'spp':>5s} {'seed':>4s} {'seconds':>8s} {'SSIM':>6s} {'relMSE':>9s} {'lum.':>6s} {'PT relMSE same t':>16s}"
    lines = [header, "-" * len(header)]
    for row in rows:
        equal = row.get("relmse_pt_equal_time", "")
        lines.append(f"{row['method']:18s} {row['spp']:5d} {row['seed']:4d} {row['seconds_total']:8.3f} "
                     f"{row['ssim']:6.3f} {row['relmse']:9.4g} {row['luminance_ratio']:6.3f} "
                     f"{(f'{equal:.4g}' if equal != '' else '-'):>16s}")
    return "\n".join(lines)


def plot_quality_vs_time(path, rows, scene, epsilon):
    """SSIM and relMSE against total seconds, one line per method, log time axis (Figures 8.1/8.3)."""
    pyplot = _pyplot()
    figure, (left, right) = pyplot.subplots(1, 2, figsize=(11, 4.2))
    for method in dict.fromkeys(row["method"] for row in rows):
        method_rows = [row for row in rows if row["method"] == method]
        for axis, quantity in ((left, "ssim"), (right, "relmse")):
            curve = _mean_curve(method_rows, quantity)
            axis.plot([c[0] for c in curve], [c[1] for c in curve], marker="o", label=method)
    left.set(xscale="log", xlabel="seconds (total, kernels warm)", ylabel="SSIM", title=f"{scene}: SSIM vs time")
    right.set(xscale="log", yscale="log", xlabel="seconds (total, kernels warm)",
              ylabel=f"relMSE (epsilon = {epsilon:g})", title=f"{scene}: relMSE vs time")
    for axis in (left, right):
        axis.grid(True, which="both", alpha=0.3)
        axis.legend()
    figure.tight_layout()
    save_figure(figure, path, dpi=110)


def matched_rows(rows):
    """One row per method, at matched time (Figures 8.2/8.4).

    The target is the earliest time at which every method has an image: the
    largest over methods of each method's shortest run. Each method shows its
    run closest to it in log time (first seed).
    """
    methods = list(dict.fromkeys(row["method"] for row in rows))
    seed = rows[0]["seed"] if rows else None
    chosen = [row for row in rows if row["seed"] == seed]
    target = max(min(row["seconds_total"] for row in chosen if row["method"] == method) for method in methods)
    matched = []
    for method in methods:
        candidates = [row for row in chosen if row["method"] == method]
        matched.append(min(candidates, key=lambda row: abs(math.log(row["seconds_total"] / target))))
    return matched, target


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot

    return pyplot


def matched_pictures(rows, reference, image_of):
    """The rows at matched time, the target time, and display pictures: the reference first, then each row's image.

    ``image_of(row)`` returns a row's linear image. Every picture uses the
    reference's exposure.
    """
    matched, target = matched_rows(rows)
    exposure = reference_exposure(reference)
    pictures = [srgb_tonemap(reference, exposure)] + [srgb_tonemap(image_of(row), exposure) for row in matched]
    return matched, target, pictures


def plot_image_grid(path, matched, target, pictures):
    """The reference and every method at matched time, with SSIM, relMSE and luminance ratio (from matched_pictures)."""
    pyplot = _pyplot()
    panels = len(matched) + 1
    columns = min(5, panels)
    lines = -(-panels // columns)
    figure, axes = pyplot.subplots(lines, columns, figsize=(3.3 * columns, 3.5 * lines + 0.4), squeeze=False)
    axes = axes.ravel()
    axes[0].imshow(pictures[0])
    axes[0].set_title("reference", fontsize=9)
    for axis, row, picture in zip(axes[1:], matched, pictures[1:]):
        axis.imshow(picture)
        axis.set_title(f"{row['method']} {row['spp']} spp, {row['seconds_total']:.2f} s\n"
                       f"SSIM {row['ssim']:.3f} relMSE {row['relmse']:.3g} lum x{row['luminance_ratio']:.2f}",
                       fontsize=8)
    for axis in axes:
        axis.set_xticks([])
        axis.set_yticks([])
    for axis in axes[panels:]:
        axis.set_visible(False)
    figure.suptitle(f"matched time: about {target:.2f} s", fontsize=10)
    figure.tight_layout(rect=(0, 0, 1, 0.96))
    save_figure(figure, path, dpi=110)


def write_table_8(path, rows, scene, config):
    """Tables 8.1/8.2: seconds per phase by spp for every method (mean over seeds), the thesis's beside."""
    from . import compare

    lines = [f"# Execution times (s), {scene}, kind {config.kind}, grid {'x'.join(map(str, config.shape))}, "
             f"image {'x'.join(map(str, config.output_resolution))}", "",
             "Mean over seeds; kernels warmed first; CoSaMP = the reconstruction phase; "
             f"relMSE epsilon = {compare.RELMSE_EPSILON}.", ""]
    thesis, methods = table_8_rows(rows, scene, config)
    for method, cells in methods.items():
        lines += [f"## {method}", ""]
        header = "| SPP | " + " | ".join(TABLE_8_COLUMNS) + " |"
        if thesis and method.startswith("cosamp"):
            header += f" thesis Table {thesis[0]} ({thesis[1]}): Total / Sampling / CoSaMP / Integration |"
        lines += [header, "|" + "---|" * (header.count("|") - 1)]
        for spp, values, thesis_values in cells:
            line = f"| {spp} | " + " | ".join(values) + " |"
            if thesis and method.startswith("cosamp"):
                line += (" " + " / ".join(f"{v:g}" for v in thesis_values) + " |") if thesis_values else " - |"
            lines.append(line)
        lines.append("")
    atomic_write_bytes(path, ("\n".join(lines) + "\n").encode())


def disagreement_crops(images, size, count=3):
    """Top-left corners of ``count`` non-overlapping ``size`` x ``size`` windows where the images differ most.

    The disagreement is the per-pixel standard deviation across ``images``
    (display values), summed over a window; windows lie on a half-window grid.
    The reference plays no part in the choice.
    """
    stack = np.stack(images)
    spread = stack.std(axis=0).mean(axis=-1)
    height, width = spread.shape
    step = max(1, size // 2)
    candidates = []
    for top in range(0, max(1, height - size + 1), step):
        for left in range(0, max(1, width - size + 1), step):
            candidates.append((float(spread[top:top + size, left:left + size].sum()), top, left))
    candidates.sort(reverse=True)
    chosen = []
    for _, top, left in candidates:
        if all(abs(top - t) >= size or abs(left - l) >= size for t, l in chosen):
            chosen.append((top, left))
        if len(chosen) == count:
            break
    return chosen


def plot_crop_grid(path, matched, target, pictures):
    """Detail crops (rows) of the reference and every method at matched time (columns), where they differ most."""
    pyplot = _pyplot()
    height, width = pictures[0].shape[:2]
    size = max(8, min(height, width) // 4)
    crops = disagreement_crops(pictures[1:], size)
    columns = len(matched) + 1
    figure, axes = pyplot.subplots(len(crops), columns, figsize=(2.2 * columns, 2.3 * len(crops) + 0.4),
                                   squeeze=False)
    titles = ["reference"] + [f"{row['method']}\n{row['spp']} spp, {row['seconds_total']:.2f} s" for row in matched]
    for line, (top, left) in enumerate(crops):
        for column, picture in enumerate(pictures):
            axis = axes[line][column]
            axis.imshow(picture[top:top + size, left:left + size], interpolation="nearest")
            axis.set_xticks([])
            axis.set_yticks([])
            if line == 0:
                axis.set_title(titles[column], fontsize=8)
        axes[line][0].set_ylabel(f"x {left}, y {top}", fontsize=8)
    figure.suptitle(f"detail crops where the methods differ most, matched time about {target:.2f} s", fontsize=9)
    figure.tight_layout(rect=(0, 0, 1, 0.96))
    save_figure(figure, path, dpi=110)


# Thesis Tables 6.2 (Cornell Box) and 6.3 (San Miguel): image size -> (spp, SFT importance sampling s, PT s).
_GUIDING = ("Samples per Pixel", "SFT Importance Sampling Time (s)")
_CORNELL_GUIDING = ("6.2", "Cornell Box", {size: values + pt for (size, values), pt in zip(
    _thesis_rows("6.2", _GUIDING).items(), _thesis_rows("6.2", ("Path Tracing Time (s)",)).values())})
#: Thesis Tables 6.2/6.3 (SFT importance sampling): scene -> (table, thesis scene, {image size: (spp, SFT s, PT s)}).
THESIS_GUIDING_TABLES = {
    "cornell-box": _CORNELL_GUIDING,
    "cornell-caustics": _CORNELL_GUIDING,
    "courtyard": ("6.3", "San Miguel", {size: values + pt for (size, values), pt in zip(
        _thesis_rows("6.3", _GUIDING).items(), _thesis_rows("6.3", ("Path Tracing Time",)).values())}),
}


def write_table_6(path, rows, scene, config):
    """Tables 6.2/6.3 layout for the guided methods: image size, spp, guided time, PT time at the same spp.

    Also the relMSE of both and the guided relMSE over PT's at equal time.
    """
    guided = [row for row in rows if row["method"].startswith("guided-")]
    if not guided:
        return
    width, height = config.output_resolution
    lines = [f"# Guided rendering times (s), {scene}, image {width}x{height}, map {'x'.join(map(str, config.shape))}",
             "", "Guided time includes the pilot pass, the map's reconstruction and the CDFs; mean over seeds.", "",
             "| method | image size | spp | map spp | guided time | PT time (same spp) | guided relMSE | PT relMSE | "
             "relMSE / PT at equal time |", "|---|---|---|---|---|---|---|---|---|"]
    for method, spp, group in method_spp_groups(guided):
        seconds, relmse = group_mean(group, "seconds_total"), group_mean(group, "relmse")
        pt_rows = [row for row in rows if row["method"] == "pt" and row["spp"] == spp]
        pt_seconds = f"{np.mean([r['seconds_total'] for r in pt_rows]):.3f}" if pt_rows else "-"
        pt_relmse = f"{np.mean([r['relmse'] for r in pt_rows]):.4g}" if pt_rows else "-"
        equal = [row["relmse_pt_equal_time"] for row in group if row.get("relmse_pt_equal_time") not in ("", None)]
        ratio = f"{relmse / float(np.mean(equal)):.2f}" if len(equal) == len(group) else "-"
        lines.append(f"| {method} | {width}x{height} | {spp} | {config.map_spp or 16} | {seconds:.3f} | {pt_seconds} | "
                     f"{relmse:.4g} | {pt_relmse} | {ratio} |")
    thesis = THESIS_GUIDING_TABLES.get(scene)
    if thesis:
        lines += ["", f"Thesis Table {thesis[0]} ({thesis[1]}, SFT importance sampling, 100x100x4^8 map):", "",
                  "| image size | spp | SFT importance sampling time | PT time |", "|---|---|---|---|"]
        lines += [f"| {size}x{size} | {values[0]} | {values[1]} | {values[2]} |" for size, values in thesis[2].items()]
    atomic_write_bytes(path, ("\n".join(lines) + "\n").encode())
