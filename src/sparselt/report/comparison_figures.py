"""The figures of one ``sparselt compare`` run: quality against time, the image grid, detail crops.

Thesis Figures 8.1/8.3 (SSIM and relMSE against time) and 8.2/8.4 (the
methods' images at matched time) in the thesis's layout, plus crops where the
methods disagree most. Every function returns a matplotlib figure; the
caller writes it (``folder.write_figure``), so nothing here touches a folder.
"""

from __future__ import annotations

import numpy as np

from ..images import reference_exposure, srgb_tonemap
from .comparison_rows import matched_rows, mean_curve, methods_in_order
from .plotting import pyplot


def quality_figure(rows, scene, epsilon, summary=None, fit=None):
    """SSIM and relMSE against median seconds, one line per method, log time axis (thesis Figures 8.1/8.3).

    Parameters
    ----------
    rows : list of dict
        The comparison's rows (means over seeds are plotted when there is no summary).
    scene : str
        Named in the titles.
    epsilon : float
        The relMSE's epsilon, named on its axis.
    summary : list of dict, optional
        The equal-time protocol's records per (method, spp): each point is a
        (method, spp) at its median time, with min-max time bars and the
        95% interval of its mean relMSE over seeds.
    fit : dict, optional
        PT's fit as ``compare.json`` holds it (``intercept_seconds``,
        ``seconds_per_spp``, ``relmse_per_seed``, ``spp_range``): drawn as
        a dashed curve on the relMSE panel.

    Returns
    -------
    matplotlib.figure.Figure
    """
    plot = pyplot()
    figure, (left, right) = plot.subplots(1, 2, figsize=(12.5, 4.4))
    for method in methods_in_order(rows):
        records = [record for record in summary or [] if record["method"] == method]
        if not records:
            method_rows = [row for row in rows if row["method"] == method]
            for axis, quantity in ((left, "ssim"), (right, "relmse")):
                curve = mean_curve(method_rows, quantity)
                axis.plot([point[0] for point in curve], [point[1] for point in curve], marker="o", label=method)
            continue
        records = sorted(records, key=lambda record: record["seconds_total"])
        seconds = np.array([record["seconds_total"] for record in records])
        bars = np.array([[record["seconds_total"] - record["seconds_total_min"] for record in records],
                         [record["seconds_total_max"] - record["seconds_total"] for record in records]])
        line, = left.plot(seconds, [record["ssim"] for record in records], marker="o", label=method)
        left.errorbar(seconds, [record["ssim"] for record in records], xerr=bars, fmt="none", ecolor=line.get_color(),
                      alpha=0.6)
        relmse = np.array([record["relmse"] for record in records])
        low = np.array([record["relmse_ci_low"] for record in records], dtype=float)
        high = np.array([record["relmse_ci_high"] for record in records], dtype=float)
        yerr = np.where(np.isfinite(low), [relmse - np.maximum(low, relmse * 1e-3), high - relmse], 0.0)
        right.errorbar(seconds, relmse, xerr=bars, yerr=yerr, marker="o", color=line.get_color(), label=method,
                       capsize=2)
    if fit:
        spps = np.geomspace(fit["spp_range"][0], fit["spp_range"][1], 64)
        c = np.mean([value["c"] for value in fit["relmse_per_seed"].values()]) if fit["relmse_per_seed"] else None
        if c is not None:
            floor = np.mean([value["floor"] for value in fit["relmse_per_seed"].values()])
            right.plot(fit["intercept_seconds"] + fit["seconds_per_spp"] * spps, c / spps + floor, "k--", lw=1,
                       label=f"PT fit: {c:.3g}/spp + {floor:.2g}")
    left.set(xscale="log", xlabel="seconds (median of repeats, kernels warm)", ylabel="SSIM",
             title=f"{scene}: SSIM vs time")
    right.set(xscale="log", yscale="log", xlabel="seconds (median of repeats, kernels warm)",
              ylabel=f"relMSE (epsilon = {epsilon:g}), 95% over seeds", title=f"{scene}: relMSE vs time")
    for axis in (left, right):
        axis.grid(True, which="both", alpha=0.3)
    handles, labels = right.get_legend_handles_labels()
    if handles:
        figure.legend(handles, labels, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize="small")
    figure.tight_layout()
    return figure


def matched_pictures(rows, reference, image_of):
    """The rows at matched time, the target time, and display pictures: the reference first, then each row's image.

    Parameters
    ----------
    rows : list of dict
    reference : ndarray, shape (height, width, 3)
        The linear reference image.
    image_of : callable
        ``image_of(row)`` returns a row's linear image.

    Returns
    -------
    matched : list of dict
        :func:`~sparselt.report.comparison_rows.matched_rows`.
    target : float
        The matched time (seconds).
    pictures : list of ndarray
        Tone-mapped with the reference's exposure (:func:`sparselt.images.reference_exposure`).
    """
    matched, target = matched_rows(rows)
    exposure = reference_exposure(reference)
    pictures = [srgb_tonemap(reference, exposure)] + [srgb_tonemap(image_of(row), exposure) for row in matched]
    return matched, target, pictures


def image_grid_figure(matched, target, pictures):
    """The reference and every method at matched time with SSIM, relMSE and luminance ratio (thesis Figures 8.2/8.4).

    Parameters are :func:`matched_pictures`' results. Returns the figure.
    """
    plot = pyplot()
    panels = len(matched) + 1
    columns = min(5, panels)
    lines = -(-panels // columns)
    figure, axes = plot.subplots(lines, columns, figsize=(3.3 * columns, 3.5 * lines + 0.4), squeeze=False)
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
    return figure


def disagreement_crops(images, size, count=3):
    """Top-left corners of ``count`` non-overlapping ``size`` x ``size`` windows where the images differ most.

    The disagreement is the per-pixel standard deviation across ``images``
    (display values), summed over a window; windows lie on a half-window grid.
    The reference plays no part in the choice.

    Returns
    -------
    list of (top, left)
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
        if all(abs(top - other_top) >= size or abs(left - other_left) >= size for other_top, other_left in chosen):
            chosen.append((top, left))
        if len(chosen) == count:
            break
    return chosen


def crop_grid_figure(matched, target, pictures):
    """Detail crops (rows) of the reference and every method at matched time (columns), where they differ most.

    Parameters are :func:`matched_pictures`' results. Returns the figure.
    """
    plot = pyplot()
    height, width = pictures[0].shape[:2]
    size = max(8, min(height, width) // 4)
    crops = disagreement_crops(pictures[1:], size)
    columns = len(matched) + 1
    figure, axes = plot.subplots(len(crops), columns, figsize=(2.2 * columns, 2.3 * len(crops) + 0.4), squeeze=False)
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
    return figure


__all__ = ["crop_grid_figure", "disagreement_crops", "image_grid_figure", "matched_pictures", "quality_figure"]
