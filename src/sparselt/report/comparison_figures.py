"""The figures of one ``sparselt compare`` run: quality against time, the image grid, error maps, detail crops.

Thesis Figures 8.1/8.3 (SSIM and relMSE against time) and 8.2/8.4 (the
methods' images at matched time) in the thesis's layout, each method's
per-pixel relative squared error at the same matched time, plus crops where
the methods disagree most. Every function returns a matplotlib figure; the
caller writes it (``folder.write_figure``), so nothing here touches a folder.
"""

from __future__ import annotations

import numpy as np

from ..analysis.metrics import pixel_relative_squared_error
from ..images import reference_exposure, srgb_tonemap
from .comparison_rows import matched_rows, mean_curve, methods_in_order
from .plotting import pyplot

#: Font sizes (points, at the figures' native 110 dpi): the page shows the figures across its content column.
TITLE_FONT_SIZE = 11
LABEL_FONT_SIZE = 10
SUPTITLE_FONT_SIZE = 12
#: A generous average glyph width of the default font, in em: what a title line is assumed to need.
_GLYPH_WIDTH = 0.62
#: Line height, in em, of multi-line titles (matplotlib's default line spacing is 1.2).
_LINE_HEIGHT = 1.3
#: The percentiles, over every shown error map's positive pixels, that bound the error maps' one colour scale.
ERROR_SCALE_PERCENTILES = (1.0, 99.9)
#: The colour map of the error maps (perceptually uniform, dark for small errors).
ERROR_COLOUR_MAP = "inferno"


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
        95% interval of its mean over seeds of the verdicts' metric
        (``headline_metric``: the trimmed relMSE, or relMSE).
    fit : BaselineFit, optional
        PT's fit (:class:`~sparselt.experiments.equal_time.BaselineFit`):
        its corrected, held curve (``mean_value``, the verdicts' reading) of
        the verdicts' metric drawn dashed on the relMSE panel against its
        time line.

    Returns
    -------
    matplotlib.figure.Figure
    """
    plot = pyplot()
    figure, (left, right) = plot.subplots(1, 2, figsize=(12.5, 4.4))
    # The verdicts' metric (the trimmed relMSE, or relMSE where the protocol falls back to it) is the one drawn.
    metric = next((record.get("headline_metric") for record in summary or [] if record.get("headline_metric")),
                  "relmse")
    name = "trimmed relMSE (top 0.1%)" if metric == "relmse_trimmed" else "relMSE"
    for method in methods_in_order(rows):
        records = [record for record in summary or [] if record["method"] == method]
        if not records:
            method_rows = [row for row in rows if row["method"] == method]
            for axis, quantity in ((left, "ssim"), (right, metric)):
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
        relmse = np.array([record[metric] for record in records])
        low = np.array([record[f"{metric}_ci_low"] for record in records], dtype=float)
        high = np.array([record[f"{metric}_ci_high"] for record in records], dtype=float)
        yerr = np.where(np.isfinite(low), [relmse - np.maximum(low, relmse * 1e-3), high - relmse], 0.0)
        right.errorbar(seconds, relmse, xerr=bars, yerr=yerr, marker="o", color=line.get_color(), label=method,
                       capsize=2)
    baseline = fit if fit is not None and metric in fit.fits else None
    if baseline is not None:
        spps = np.geomspace(*baseline.spp_range, 64)
        c, floor = baseline.mean_fit(metric)
        exponent = baseline.exponent(metric)
        power = "spp" if exponent == 1.0 else f"spp^{exponent:g}"
        corrected = metric in baseline.corrections
        # The fit as the verdicts read it: times the rungs' mean measured/fitted, held non-increasing.
        right.plot(baseline.intercept + baseline.slope * spps, baseline.mean_value(metric, spps), "k--", lw=1,
                   label=f"PT fit: {c:.3g}/{power} + {floor:.2g}" + (", rung-corrected" if corrected else ""))
    left.set(xscale="log", xlabel="seconds (median of repeats, kernels warm)", ylabel="SSIM",
             title=f"{scene}: SSIM vs time")
    right.set(xscale="log", yscale="log", xlabel="seconds (median of repeats, kernels warm)",
              ylabel=f"{name}, eps {epsilon:g}, 95% over seeds", title=f"{scene}: {name} vs time")
    for axis in (left, right):
        axis.grid(True, which="both", alpha=0.3)
    handles, labels = right.get_legend_handles_labels()
    if handles:
        figure.legend(handles, labels, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=LABEL_FONT_SIZE)
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


def _seconds_text(seconds):
    """Seconds for a title: two decimals from 0.1 s, else three significant digits (``0.00412``)."""
    return f"{seconds:.2f}" if seconds >= 0.1 else f"{seconds:.3g}"


def matched_time_text(matched, target):
    """What the panels show, honestly: the target time and the range of the panels' own times.

    Parameters
    ----------
    matched : list of dict
        The rows shown (:func:`~sparselt.report.comparison_rows.matched_rows`).
    target : float
        The matched time (seconds): the largest of the methods' shortest runs.

    Returns
    -------
    str
        For example ``"each method at its run closest to 0.35 s (panels 0.06-19.22 s)"``.
    """
    seconds = [row["seconds_total"] for row in matched]
    low, high = min(seconds), max(seconds)
    panels = (f"panel {_seconds_text(low)} s" if _seconds_text(low) == _seconds_text(high)
              else f"panels {_seconds_text(low)}-{_seconds_text(high)} s")
    return f"each method at its run closest to {_seconds_text(target)} s ({panels})"


def _text_width(lines, font_size):
    """Inches a block of title lines needs at ``font_size`` points (a generous estimate)."""
    return max(len(line) for line in lines) * _GLYPH_WIDTH * font_size / 72


def _text_height(line_count, font_size):
    """Inches ``line_count`` lines of ``font_size`` points take."""
    return line_count * _LINE_HEIGHT * font_size / 72


def _wrapped(text, width_inches, font_size):
    """``text`` wrapped to lines that fit ``width_inches`` at ``font_size`` points."""
    import textwrap

    return textwrap.wrap(text, width=max(20, int(width_inches * 72 / (_GLYPH_WIDTH * font_size))))


def _panel_grid(plot, columns, panel_width, image_height, title_lines, suptitle, *, left=0.1, gap_width=0.25,
                right=0.1):
    """A figure of rows x ``columns`` image axes placed by hand, each row with room for its titles.

    Row ``i`` is ``title_lines[i]`` lines of :data:`TITLE_FONT_SIZE` plus the
    image, so a row's titles never reach into the images of the row above
    (``tight_layout`` cannot promise that for images of fixed aspect). The
    suptitle is wrapped to the figure's width above the first row; ``right``
    inches stay free right of the last column (a colour bar's room).

    Returns
    -------
    figure : matplotlib.figure.Figure
    axes : ndarray of Axes, shape (len(title_lines), columns)
    """
    width = left + columns * panel_width + (columns - 1) * gap_width + right
    heading = _wrapped(suptitle, width - 0.2, SUPTITLE_FONT_SIZE)
    heading_height = _text_height(len(heading), SUPTITLE_FONT_SIZE) + 0.15
    title_heights = [_text_height(count, TITLE_FONT_SIZE) + 0.12 if count else 0.0 for count in title_lines]
    gap_height = 0.15
    height = heading_height + sum(title_heights) + len(title_lines) * (image_height + gap_height) + 0.1 - gap_height
    figure = plot.figure(figsize=(width, height))
    axes = np.empty((len(title_lines), columns), dtype=object)
    top = heading_height
    for line, title_height in enumerate(title_heights):
        top += title_height
        for column in range(columns):
            axes[line, column] = figure.add_axes((
                (left + column * (panel_width + gap_width)) / width, 1 - (top + image_height) / height,
                panel_width / width, image_height / height))
        top += image_height + gap_height
    figure.text(0.5, 1 - 0.08 / height, "\n".join(heading), ha="center", va="top", fontsize=SUPTITLE_FONT_SIZE)
    return figure, axes


def image_grid_figure(matched, target, pictures):
    """The reference and every method at matched time with SSIM, relMSE and luminance ratio (thesis Figures 8.2/8.4).

    Parameters are :func:`matched_pictures`' results. Returns the figure.

    Notes
    -----
    The heading states the target time and the range of the panels' own
    times (:func:`matched_time_text`): a method whose runs are all slower
    or faster than the target shows its nearest run, and its title says
    which. Titles are :data:`TITLE_FONT_SIZE` points at the native 110 dpi,
    each row with room for its three title lines.
    """
    plot = pyplot()
    panels = len(matched) + 1
    columns = min(5, panels)
    lines = -(-panels // columns)
    titles = [["reference"]] + [
        [row["method"], f"{row['spp']} spp, {_seconds_text(row['seconds_total'])} s, lum x{row['luminance_ratio']:.2f}",
         f"SSIM {row['ssim']:.3f}, relMSE {row['relmse']:.3g}"] for row in matched]
    panel_width = max(2.8, max(_text_width(title, TITLE_FONT_SIZE) for title in titles) + 0.1)
    height, width = pictures[0].shape[:2]
    figure, axes = _panel_grid(plot, columns, panel_width, panel_width * height / width,
                               [max(len(title) for title in titles)] * lines, matched_time_text(matched, target))
    axes = axes.ravel()
    for axis, title, picture in zip(axes, titles, pictures):
        axis.imshow(picture, aspect="auto")
        axis.set_title("\n".join(title), fontsize=TITLE_FONT_SIZE)
    for axis in axes:
        axis.set_xticks([])
        axis.set_yticks([])
    for axis in axes[panels:]:
        axis.set_visible(False)
    return figure


def error_maps(matched, reference, image_of, *, epsilon):
    """Each matched row's per-pixel relative squared error against the reference (relMSE's per-pixel terms).

    Parameters
    ----------
    matched : list of dict
        The rows at matched time, as the image grid shows them
        (:func:`matched_pictures`' first result).
    reference : ndarray, shape (height, width, 3)
        The linear reference image.
    image_of : callable
        ``image_of(row)`` returns a row's linear image.
    epsilon : float
        relMSE's epsilon.

    Returns
    -------
    list of ndarray, shape (height, width)
        :func:`sparselt.analysis.metrics.pixel_relative_squared_error`, one per
        row: each map's mean over pixels is the row image's relMSE
        (:func:`~sparselt.analysis.metrics.relative_mean_squared_error`).
    """
    return [pixel_relative_squared_error(image_of(row), reference, epsilon=epsilon) for row in matched]


def shared_error_scale(maps, *, percentiles=ERROR_SCALE_PERCENTILES):
    """The limits ``(low, high)`` of one logarithmic colour scale for all ``maps``: percentiles of their pixels.

    Parameters
    ----------
    maps : sequence of ndarray
        Non-negative error maps (:func:`error_maps`); the scale is computed
        over all of them together, so every panel reads on the same scale.
    percentiles : (float, float), optional
        Lower and upper percentile, ``0 <= lower < upper <= 100`` (default
        :data:`ERROR_SCALE_PERCENTILES`).

    Returns
    -------
    (float, float)
        ``0 < low < high``: the percentiles of every map's positive, finite
        pixels (a logarithmic scale cannot show zero). When they coincide
        (a constant error), the decade centred on that value; when no pixel
        is positive (every image equals the reference), ``(1e-6, 1e-5)``.

    Raises
    ------
    ValueError
        If ``maps`` is empty, or the percentiles are not ``0 <= lower <
        upper <= 100``.
    """
    if len(maps) == 0:
        raise ValueError("shared_error_scale needs at least one error map; got none")
    lower, upper = (float(value) for value in percentiles)
    if not 0 <= lower < upper <= 100:
        raise ValueError(f"percentiles must satisfy 0 <= lower < upper <= 100; got {tuple(percentiles)!r}")
    values = np.concatenate([np.asarray(error, dtype=np.float64).ravel() for error in maps])
    positive = values[np.isfinite(values) & (values > 0)]
    if positive.size == 0:
        return 1e-6, 1e-5
    low, high = (float(value) for value in np.percentile(positive, [lower, upper]))
    if not high > low:
        low, high = low / np.sqrt(10.0), high * np.sqrt(10.0)
    return low, high


def error_map_figure(matched, target, maps, *, epsilon, scale=None):
    """Each method's per-pixel relative squared error at matched time, in false colour on one shared log scale.

    Parameters
    ----------
    matched : list of dict
        The rows at matched time (:func:`matched_pictures`' first result: the
        image grid's panels, the reference aside).
    target : float
        The matched time (seconds).
    maps : list of ndarray, shape (height, width)
        :func:`error_maps` of ``matched``, in its order.
    epsilon : float
        relMSE's epsilon, named on the colour bar.
    scale : (float, float), optional
        The colour scale's limits; default :func:`shared_error_scale` of ``maps``.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        If ``matched`` is empty, ``maps`` and ``matched`` differ in length, or as :func:`shared_error_scale`.

    Notes
    -----
    Every panel uses the same :class:`matplotlib.colors.LogNorm` and one colour
    bar: values outside the scale are shown at its ends (the bar's
    triangles), zeros at its lower end. Each title names the method's row,
    spp, seconds and its relMSE (the map's mean over pixels, so the title
    describes exactly what the panel shows).
    """
    if not matched:
        raise ValueError("error_map_figure needs at least one matched row; got none")
    if len(maps) != len(matched):
        raise ValueError(f"error_map_figure needs one map per matched row; got {len(maps)} maps for "
                         f"{len(matched)} rows")
    from matplotlib.colors import LogNorm

    plot = pyplot()
    low, high = shared_error_scale(maps) if scale is None else scale
    norm = LogNorm(vmin=low, vmax=high)
    panels = len(matched)
    columns = min(5, panels)
    lines = -(-panels // columns)
    titles = [[row["method"], f"{row['spp']} spp, {_seconds_text(row['seconds_total'])} s",
               f"relMSE {float(np.mean(error)):.3g}"] for row, error in zip(matched, maps)]
    height, width = np.shape(maps[0])[:2]
    label = f"relative squared error (ε = {epsilon:g})"
    short_label = label.replace(" (", "\n(")  # for a short bar: two lines
    # Panels wide enough for their titles, and their rows tall enough for the colour bar's label on two lines.
    panel_width = max(2.2, max(_text_width(title, TITLE_FONT_SIZE) for title in titles) + 0.1,
                      _text_width(short_label.splitlines(), LABEL_FONT_SIZE) * width / (height * lines))
    figure, axes = _panel_grid(
        plot, columns, panel_width, panel_width * height / width, [3] * lines,
        f"per-pixel relative squared error against the reference, one log colour scale for all panels; "
        f"{matched_time_text(matched, target)}", right=1.25)
    for axis, title, error in zip(axes.ravel(), titles, maps):
        image = axis.imshow(np.clip(error, low, high), cmap=ERROR_COLOUR_MAP, norm=norm, aspect="auto",
                            interpolation="nearest")
        axis.set_title("\n".join(title), fontsize=TITLE_FONT_SIZE)
    for axis in axes.ravel():
        axis.set_xticks([])
        axis.set_yticks([])
    for axis in axes.ravel()[panels:]:
        axis.set_visible(False)
    figure_width = figure.get_size_inches()[0]
    first, last = axes[0, columns - 1].get_position(), axes[-1, 0].get_position()
    bar = figure.add_axes((first.x1 + 0.15 / figure_width, last.y0, 0.15 / figure_width, first.y1 - last.y0))
    colour_bar = figure.colorbar(image, cax=bar, extend="both")
    if _text_width([label], LABEL_FONT_SIZE) > (first.y1 - last.y0) * figure.get_size_inches()[1]:
        label = short_label
    colour_bar.set_label(label, fontsize=LABEL_FONT_SIZE)
    colour_bar.ax.tick_params(labelsize=LABEL_FONT_SIZE - 1)
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

    Notes
    -----
    Column titles are :data:`TITLE_FONT_SIZE` points and the crops' positions
    (y labels) :data:`LABEL_FONT_SIZE` points at the native 110 dpi; the
    heading states the target and the panels' times (:func:`matched_time_text`).
    """
    plot = pyplot()
    height, width = pictures[0].shape[:2]
    size = max(8, min(height, width) // 4)
    crops = disagreement_crops(pictures[1:], size)
    columns = len(matched) + 1
    titles = [["reference"]] + [[row["method"], f"{row['spp']} spp, {_seconds_text(row['seconds_total'])} s"]
                                for row in matched]
    panel_width = max(1.5, max(_text_width(title, TITLE_FONT_SIZE) for title in titles) + 0.08)
    figure, axes = _panel_grid(
        plot, columns, panel_width, panel_width, [max(len(title) for title in titles)] + [0] * (len(crops) - 1),
        f"detail crops where the methods differ most; {matched_time_text(matched, target)}",
        left=0.35, gap_width=0.12)
    for line, (top, left) in enumerate(crops):
        for column, picture in enumerate(pictures):
            axis = axes[line][column]
            axis.imshow(picture[top:top + size, left:left + size], interpolation="nearest", aspect="auto")
            axis.set_xticks([])
            axis.set_yticks([])
            if line == 0:
                axis.set_title("\n".join(titles[column]), fontsize=TITLE_FONT_SIZE)
        axes[line][0].set_ylabel(f"x {left}, y {top}", fontsize=LABEL_FONT_SIZE)
    return figure


__all__ = ["ERROR_COLOUR_MAP", "ERROR_SCALE_PERCENTILES", "LABEL_FONT_SIZE", "SUPTITLE_FONT_SIZE", "TITLE_FONT_SIZE",
           "crop_grid_figure", "disagreement_crops", "error_map_figure", "error_maps", "image_grid_figure",
           "matched_pictures", "matched_time_text", "quality_figure", "shared_error_scale"]
