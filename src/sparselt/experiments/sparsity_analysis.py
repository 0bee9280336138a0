"""Sparsity analysis of a signal: Tables 5.1, 5.2, 7.1-7.3 and Figures 5.2-5.4, 7.1-7.6.

``sparselt analyze SIGNAL`` (thesis 5.3, 7.1.2, 7.2.1):

1. Gini index of magnitude and energy, per colour channel, in the canonical
   (primary sample space) and Fourier domains, for each gamma (eq. 5.1, 7.1).
2. Hard thresholding: for each gamma and each fraction of Fourier
   coefficients, the image of the thresholded signal compared to the
   signal's own image by SSIM (with the one HDR convention of
   :func:`sparselt.analysis.metrics.image_ssim`).

Output folder::

    gini.csv                  every Gini value (gamma, domain, measure, channel)
    table_5_1_fourier.md      Table 5.1 layout: per channel, Fourier domain, gamma = 1
    table_5_2_canonical.md    Table 5.2 layout: per channel, canonical domain, gamma = 1
    table_7_gamma.md          Tables 7.1-7.3 layout: gamma rows, mean over channels
    ssim.csv                  gamma, fraction, coefficients kept, SSIM, PSNR
    ssim_vs_fraction.png      Figures 5.4, 7.1, 7.2, 7.5: one line per gamma
    thresholded.png           Figures 5.2, 5.3, 7.3, 7.4, 7.6: image grid
    analysis.json             configuration, signal metadata, provenance
"""

from __future__ import annotations

import csv
import io
import math
import os

import numpy as np

from ..analysis.metrics import image_ssim, peak_signal_to_noise_ratio, reference_exposure
from ..analysis.sparsity import signal_gini
from ..analysis.threshold import check_fraction, check_gamma, gamma_map, hard_threshold_image
from ..images import save_figure, srgb_tonemap
from ..provenance import atomic_write_bytes, environment_record, write_json
from ..signal import Signal

DEFAULT_GAMMAS = (1.0, 0.5, 0.25, 0.1, 0.05)
DEFAULT_FRACTIONS = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1)
CHANNELS = ("R", "G", "B")
MEASURES = (("canonical", False, "Time"), ("canonical", True, "Time Energy"),
            ("fourier", False, "Frequency"), ("fourier", True, "Frequency Energy"))


def _check_gammas(gammas):
    gammas = tuple(gammas)
    if not gammas:
        raise ValueError("give at least one gamma")
    return tuple(check_gamma(gamma) for gamma in gammas)


def _mapped_signal(signal, gamma):
    if gamma == 1.0:
        return signal
    data = np.asarray(signal.data)
    return Signal(data=gamma_map(data, gamma).astype(np.float32), kind=signal.kind, axes=signal.axes, meta=signal.meta)


def _write_text(path, text):
    atomic_write_bytes(path, text.encode("utf-8"))


def _csv(rows, header):
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buffer.getvalue()


def gini_table(signal, gammas=DEFAULT_GAMMAS, *, memory_limit_bytes=4 * 2**30):
    """Gini index rows ``(gamma, domain, energy, channel, value, error_bound)`` for every gamma."""
    rows = []
    for gamma in _check_gammas(gammas):
        mapped = _mapped_signal(signal, gamma)
        for domain, energy, _ in MEASURES:
            result = signal_gini(mapped, domain=domain, energy=energy, memory_limit_bytes=memory_limit_bytes)
            for channel, (value, bound) in enumerate(zip(result.values, result.error_bounds)):
                rows.append((gamma, domain, energy, CHANNELS[channel], float(value), float(bound)))
    return rows


def _markdown_channel_table(rows, scene, domain, title):
    lines = [f"{title}", "", "| Scene | Channel | Gini Magnitude | Gini Energy |", "|---|---|---|---|"]
    for channel in CHANNELS:
        magnitude = next(r[4] for r in rows if r[0] == 1.0 and r[1] == domain and not r[2] and r[3] == channel)
        energy = next(r[4] for r in rows if r[0] == 1.0 and r[1] == domain and r[2] and r[3] == channel)
        lines.append(f"| {scene if channel == 'R' else ''} | {channel} | {magnitude:.6f} | {energy:.6f} |")
    return "\n".join(lines) + "\n"


def _markdown_gamma_table(rows, gammas, title):
    header = "| gamma | " + " | ".join(label for _, _, label in MEASURES) + " |"
    lines = [title, "", header, "|---" * (len(MEASURES) + 1) + "|"]
    for gamma in gammas:
        cells = []
        for domain, energy, _ in MEASURES:
            values = [r[4] for r in rows if r[0] == gamma and r[1] == domain and r[2] == energy]
            cells.append(f"{np.mean(values):.4f}")
        lines.append(f"| {gamma:.2f} | " + " | ".join(cells) + " |")
    lines += ["", "Mean over the R, G, B channels; per-channel values in gini.csv."]
    return "\n".join(lines) + "\n"


def analyze_signal(signal, out, *, gammas=DEFAULT_GAMMAS, fractions=DEFAULT_FRACTIONS, grid_fractions=None,
                   progress=True, memory_limit_bytes=4 * 2**30):
    """Run the sparsity analysis of ``signal`` and write tables and figures into ``out``.

    Parameters
    ----------
    signal : Signal
        A complete signal (``sparselt.load_signal``).
    out : str
        Output folder (created).
    gammas : sequence of float
        Gamma mappings (eq. 7.1); 1 means none. Each must be > 0.
    fractions : sequence of float
        Fractions in (0, 1] of Fourier coefficients kept by hard thresholding.
    grid_fractions : sequence of float, optional
        Fractions shown in the image grid (default: up to four of ``fractions``).
    progress : bool
        Print one line per step.
    memory_limit_bytes : int
        Above this the Gini indices are computed by the bounded-memory path.

    Returns
    -------
    dict
        ``gini`` rows, ``ssim`` rows and the paths written.

    Raises
    ------
    ValueError
        A gamma <= 0 or a fraction outside (0, 1].
    """
    gammas = _check_gammas(gammas)
    fractions = tuple(sorted(check_fraction(fraction) for fraction in fractions))
    if not fractions:
        raise ValueError("give at least one fraction")
    os.makedirs(out, exist_ok=True)
    say = print if progress else (lambda *arguments, **options: None)
    scene = signal.meta.get("scene", "signal")

    say(f"analyze: Gini indices for {len(gammas)} gamma values")
    rows = gini_table(signal, gammas, memory_limit_bytes=memory_limit_bytes)
    _write_text(os.path.join(out, "gini.csv"), _csv(rows, ["gamma", "domain", "energy", "channel", "gini", "error_bound"]))
    _write_text(os.path.join(out, "table_5_1_fourier.md"),
                _markdown_channel_table(rows, scene, "fourier", f"Sparsity metrics in Fourier space ({signal.kind}, Table 5.1 layout)"))
    _write_text(os.path.join(out, "table_5_2_canonical.md"),
                _markdown_channel_table(rows, scene, "canonical", f"Sparsity metrics in primary sample space ({signal.kind}, Table 5.2 layout)"))
    gamma_table = _markdown_gamma_table(rows, gammas, f"Gini index of {scene} ({signal.kind}) with gamma mapping (Tables 7.1-7.3 layout)")
    _write_text(os.path.join(out, "table_7_gamma.md"), gamma_table)

    reference = signal.image().astype(np.float64)
    data = np.asarray(signal.data)
    size = math.prod(signal.shape)
    ssim_rows = []
    images = {}
    grid_fractions = tuple(grid_fractions) if grid_fractions else fractions[:: max(1, math.ceil(len(fractions) / 4))][:4]
    for gamma in gammas:
        for fraction in fractions:
            image = hard_threshold_image(data, fraction, gamma=gamma).transpose(1, 0, 2)
            similarity = image_ssim(image, reference) if min(reference.shape[:2]) >= 11 else float("nan")
            peak = float(np.percentile(reference, 99.9)) or 1.0
            psnr = peak_signal_to_noise_ratio(np.clip(image, 0, peak), np.clip(reference, 0, peak), data_range=peak)
            ssim_rows.append((gamma, fraction, max(1, math.ceil(fraction * size)), similarity, psnr))
            if fraction in grid_fractions:
                images[gamma, fraction] = image
            say(f"analyze: gamma {gamma:g}, fraction {fraction:.0e}: SSIM {similarity:.4f}, PSNR {psnr:.2f} dB")
    _write_text(os.path.join(out, "ssim.csv"), _csv(ssim_rows, ["gamma", "fraction", "coefficients", "ssim", "psnr_db"]))
    _plot_ssim(ssim_rows, gammas, os.path.join(out, "ssim_vs_fraction.png"), title=f"{scene} ({signal.kind}): hard-thresholded Fourier")
    _plot_grid(images, reference, gammas, grid_fractions, os.path.join(out, "thresholded.png"))

    write_json(os.path.join(out, "analysis.json"), {
        "signal": {key: signal.meta.get(key) for key in ("scene", "kind", "axes", "shape", "spp", "seed", "max_depth")},
        "gammas": list(gammas),
        "fractions": list(fractions),
        "ssim_convention": "sparselt.analysis.metrics.image_ssim: both images times the reference's exposure, sRGB curve, SSIM with data_range 1 per channel",
        "gamma_mapping": "T = (I / max I) ** gamma with one maximum over all channels; inverse clips T < 0 to 0",
        "provenance": environment_record(),
    })
    return {"gini": rows, "ssim": ssim_rows, "gamma_table": gamma_table}


def _plot_ssim(rows, gammas, path, *, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot

    figure, axis = pyplot.subplots(figsize=(6, 4))
    for gamma in gammas:
        points = [(row[1], row[3]) for row in rows if row[0] == gamma]
        axis.plot([p[0] for p in points], [p[1] for p in points], marker="o", label=f"gamma = {gamma:g}")
    axis.set_xscale("log")
    axis.set_xlabel("fraction of Fourier coefficients kept")
    axis.set_ylabel("SSIM against the signal's image")
    axis.set_ylim(top=1.0)
    axis.grid(True, which="both", alpha=0.3)
    axis.legend()
    axis.set_title(title, fontsize=10)
    save_figure(figure, path, dpi=120, bbox_inches="tight")


def _plot_grid(images, reference, gammas, fractions, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot

    exposure = reference_exposure(reference)
    columns = len(fractions) + 1
    figure, panels = pyplot.subplots(len(gammas), columns, figsize=(2.4 * columns, 2.5 * len(gammas)), squeeze=False)
    for row, gamma in enumerate(gammas):
        panels[row][0].imshow(srgb_tonemap(reference, exposure))
        panels[row][0].set_title("reference", fontsize=8)
        panels[row][0].set_ylabel(f"gamma = {gamma:g}", fontsize=9)
        for column, fraction in enumerate(fractions, start=1):
            panels[row][column].imshow(srgb_tonemap(images[gamma, fraction], exposure))
            panels[row][column].set_title(f"{fraction:.0e} of coefficients", fontsize=8)
        for panel in panels[row]:
            panel.set_xticks([])
            panel.set_yticks([])
    figure.suptitle("Hard-thresholded Fourier reconstructions", fontsize=10)
    save_figure(figure, path, dpi=110, bbox_inches="tight")
