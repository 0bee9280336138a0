"""Sparsity analysis of a signal: Tables 5.1, 5.2, 7.1-7.3 and Figures 5.2-5.4, 7.1-7.6.

``sparselt analyze SIGNAL`` (thesis 5.3, 7.1.2, 7.2.1):

1. Gini index of magnitude and energy, per colour channel, in the canonical
   (primary sample space) and Fourier domains, for each gamma (eq. 5.1, 7.1).
2. Hard thresholding: for each gamma and each fraction of Fourier
   coefficients, the image of the thresholded signal compared to the
   signal's own image by SSIM (with the one HDR convention of
   :func:`sparselt.analysis.metrics.image_ssim`).

Output folder (an :class:`~sparselt.storage.folder.ExperimentFolder`)::

    gini.csv                  every Gini value (gamma, domain, measure, channel)
    table_5_1_fourier.md/.csv    Table 5.1 layout: per channel, Fourier domain, gamma = 1
    table_5_2_canonical.md/.csv  Table 5.2 layout: per channel, canonical domain, gamma = 1
    table_7_gamma.md/.csv     Tables 7.1-7.3 layout: gamma rows, mean over channels
    ssim.csv                  gamma, fraction, coefficients kept, SSIM, PSNR
    ssim_vs_fraction.png      Figures 5.4, 7.1, 7.2, 7.5: one line per gamma
    thresholded.png           Figures 5.2, 5.3, 7.3, 7.4, 7.6: image grid
    thresholded/              the grid's images (npy), per gamma and fraction
    cells/                    one record per gamma (its Gini and SSIM rows): a rerun resumes
    analysis.json             configuration, signal metadata, provenance

The folder's identity is the signal's identity (its acquisition
configuration, its scene's content digest and a digest of its chunk
checksums; not where it is stored), the gammas, the fractions, the grid's
fractions and the memory limit (which decides exact or streamed Gini
indices). A rerun with the same identity resumes; another is refused unless
``overwrite``; a folder holding files sparselt did not write is refused
either way. Every table is a :class:`~sparselt.report.Table`.
"""

from __future__ import annotations

import math

import numpy as np

from ..analysis.metrics import WINDOW_SIZE, image_ssim, peak_signal_to_noise_ratio, reference_exposure
from ..analysis.sparsity import signal_gini
from ..analysis.threshold import check_fraction, check_gamma, gamma_map, hard_threshold_image
from ..checks import check_integer
from ..digest import bytes_digest
from ..images import srgb_tonemap
from ..provenance import environment_record
from ..report import Table
from ..report.plotting import pyplot
from ..signal import Signal
from ..storage.folder import signal_identity
from .protocol import Experiment, run_experiment

DEFAULT_GAMMAS = (1.0, 0.5, 0.25, 0.1, 0.05)
DEFAULT_FRACTIONS = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1)
CHANNELS = ("R", "G", "B")
MEASURES = (("canonical", False, "Time"), ("canonical", True, "Time Energy"),
            ("fourier", False, "Frequency"), ("fourier", True, "Frequency Energy"))


def _check_gammas(gammas):
    gammas = tuple(check_gamma(gamma) for gamma in gammas)
    if not gammas:
        raise ValueError("give at least one gamma")
    if len(set(gammas)) != len(gammas):
        raise ValueError(f"gammas {list(gammas)} repeat a value; give each gamma once")
    return gammas


def _check_image_plane(signal):
    """Refuse a signal whose image plane is smaller than the SSIM window (every SSIM would be NaN)."""
    width, height = signal.shape[:2]
    if min(width, height) < WINDOW_SIZE:
        where = f"signal {signal.store!r}" if signal.store else "the signal"
        shape = ",".join(map(str, (max(width, WINDOW_SIZE), max(height, WINDOW_SIZE)) + tuple(signal.shape[2:])))
        raise ValueError(f"{where} has an image plane of {width}x{height} pixels, too small for SSIM (at least "
                         f"{WINDOW_SIZE}x{WINDOW_SIZE} pixels): sample it again with a larger image plane, "
                         f"e.g. --shape {shape}")


def _mapped_signal(signal, gamma):
    if gamma == 1.0:
        return signal
    data = np.asarray(signal.data)
    return Signal(data=gamma_map(data, gamma).astype(np.float32), kind=signal.kind, axes=signal.axes, meta=signal.meta)


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


def channel_table(rows, scene, domain, caption):
    """Tables 5.1/5.2 layout: per channel, the Gini index of magnitudes and energies at gamma 1 (thesis 5.4.1)."""
    table_rows = []
    for channel in CHANNELS:
        magnitude = next(r[4] for r in rows if r[0] == 1.0 and r[1] == domain and not r[2] and r[3] == channel)
        energy = next(r[4] for r in rows if r[0] == 1.0 and r[1] == domain and r[2] and r[3] == channel)
        table_rows.append((scene if channel == "R" else "", [channel, f"{magnitude:.6f}", f"{energy:.6f}"]))
    return Table(caption=caption, label_header="Scene", columns=["Channel", "Gini Magnitude", "Gini Energy"],
                 kinds=["", "ours", "ours"], rows=table_rows)


def gamma_table(rows, gammas, caption):
    """Tables 7.1-7.3 layout: per gamma, the Gini index in both domains, of magnitudes and energies (thesis 7.1.2)."""
    table_rows = []
    for gamma in gammas:
        cells = []
        for domain, energy, _ in MEASURES:
            values = [r[4] for r in rows if r[0] == gamma and r[1] == domain and r[2] == energy]
            cells.append(f"{np.mean(values):.4f}")
        table_rows.append((f"{gamma:.2f}", cells))
    return Table(caption=caption, label_header="gamma", columns=[label for _, _, label in MEASURES],
                 kinds=["ours"] * len(MEASURES), rows=table_rows,
                 notes=["Mean over the R, G, B channels; per-channel values in gini.csv."])


def gini_csv_table(rows):
    """``gini.csv``: one row per (gamma, domain, energy, channel): the Gini index and its error bound."""
    return Table(caption="Gini indices", label_header="gamma",
                 columns=["domain", "energy", "channel", "gini", "error_bound"],
                 rows=[(str(row[0]), [str(value) for value in row[1:]]) for row in rows])


def ssim_csv_table(rows):
    """``ssim.csv``: one row per (gamma, fraction): coefficients kept, SSIM and PSNR of the thresholded image."""
    return Table(caption="Hard-thresholded Fourier reconstructions", label_header="gamma",
                 columns=["fraction", "coefficients", "ssim", "psnr_db"],
                 rows=[(str(row[0]), [str(value) for value in row[1:]]) for row in rows])


def analysis_identity(signal, gammas, fractions, grid_fractions, memory_limit_bytes):
    """The identity of an analysis folder: the signal's (not its path), gammas, fractions, grid, memory limit.

    A signal without chunk checksums (one built in memory) is identified by a
    SHA-256 of its data instead.
    """
    identity = signal_identity(signal)
    if identity.get("content_digest") is None:
        data = np.ascontiguousarray(np.asarray(signal.data))
        identity = dict(identity, content_digest="sha256:" + bytes_digest(data.tobytes()))
    return {"signal": identity, "gammas": list(gammas), "fractions": list(fractions),
            "grid_fractions": list(grid_fractions), "memory_limit_bytes": memory_limit_bytes}


def analyze_signal(signal, out, *, gammas=DEFAULT_GAMMAS, fractions=DEFAULT_FRACTIONS, grid_fractions=None,
                   progress=True, memory_limit_bytes=4 * 2**30, overwrite=False):
    """Run the sparsity analysis of ``signal`` and write tables and figures into the folder ``out``.

    Parameters
    ----------
    signal : Signal
        A complete signal (``sparselt.load_signal``).
    out : str
        Output folder (an :class:`~sparselt.storage.folder.ExperimentFolder`;
        see the module docstring).
    gammas : sequence of float
        Gamma mappings (eq. 7.1); 1 means none. Each must be > 0.
    fractions : sequence of float
        Fractions in (0, 1] of Fourier coefficients kept by hard thresholding.
    grid_fractions : sequence of float, optional
        Fractions shown in the image grid, each one of ``fractions``
        (default: up to four of ``fractions``).
    progress : bool
        Print one line per step.
    memory_limit_bytes : int
        Above this the Gini indices are computed by the bounded-memory path.
    overwrite : bool
        Replace a folder holding another analysis (only the files sparselt
        wrote there).

    Returns
    -------
    dict
        ``gini`` rows ``(gamma, domain, energy, channel, value, error_bound)``,
        ``ssim`` rows ``(gamma, fraction, coefficients, ssim, psnr_db)`` and
        ``gamma_table`` (the Tables 7.1-7.3 layout in Markdown).

    Raises
    ------
    ValueError
        An image plane smaller than the 11x11-pixel SSIM window, a gamma <= 0,
        a fraction outside (0, 1], a grid fraction not among ``fractions``, or
        a folder holding another analysis (without ``overwrite``) or files
        sparselt did not write: before any work.

    References
    ----------
    Thesis 5.3 and 5.4.1 (Gini index, Tables 5.1/5.2), 7.1.2 and 7.2.1 (gamma
    mapping, Tables 7.1-7.3, hard thresholding).
    """
    experiment = AnalysisExperiment(signal, gammas=gammas, fractions=fractions, grid_fractions=grid_fractions,
                                    memory_limit_bytes=memory_limit_bytes, progress=progress)
    return run_experiment(experiment, out, overwrite=overwrite, progress=False)  # its own lines, one per step


def _cell_name(gamma):
    return f"gamma-{gamma:g}"


def _image_name(gamma, fraction):
    return f"thresholded/gamma{gamma:g}_fraction{fraction:g}.npy"


class AnalysisExperiment(Experiment):
    """``sparselt analyze`` as an experiment: one cell per gamma (its Gini rows, its SSIM rows and the grid's
    thresholded images); the report is the tables, the figures and ``analysis.json``.

    Parameters are those of :func:`analyze_signal`; :meth:`validate` checks
    and normalises them (fractions ascending, the grid's default).
    """

    kind = "analyze"
    cell_unit = "gamma"

    def __init__(self, signal, *, gammas=DEFAULT_GAMMAS, fractions=DEFAULT_FRACTIONS, grid_fractions=None,
                 memory_limit_bytes=4 * 2**30, progress=True):
        self.signal = signal
        self.gammas, self.fractions, self.grid_fractions = gammas, fractions, grid_fractions
        self.memory_limit_bytes = memory_limit_bytes
        self._identity = None
        self.say = print if progress else (lambda *arguments, **options: None)

    def validate(self):
        _check_image_plane(self.signal)
        self.gammas = _check_gammas(self.gammas)
        fractions = tuple(sorted(check_fraction(fraction) for fraction in self.fractions))
        if not fractions:
            raise ValueError("give at least one fraction")
        if len(set(fractions)) != len(fractions):
            raise ValueError(f"fractions {list(fractions)} repeat a value; give each fraction once")
        self.fractions = fractions
        if self.grid_fractions:
            grid_fractions = tuple(check_fraction(fraction) for fraction in self.grid_fractions)
            missing = [fraction for fraction in grid_fractions if fraction not in fractions]
            if missing:
                raise ValueError(f"grid fractions {missing} are not among the fractions analysed "
                                 f"({', '.join(f'{fraction:g}' for fraction in fractions)})")
            self.grid_fractions = grid_fractions
        else:
            self.grid_fractions = fractions[:: max(1, math.ceil(len(fractions) / 4))][:4]
        self.memory_limit_bytes = check_integer("memory_limit_bytes", self.memory_limit_bytes, 1)
        self._identity = None

    def identity(self):
        if self._identity is None:  # once: a signal held in memory is identified by a digest of all its data
            self._identity = analysis_identity(self.signal, self.gammas, self.fractions, self.grid_fractions,
                                               self.memory_limit_bytes)
        return self._identity

    def scene_identity(self):
        return self.signal.meta.get("scene_identity")

    def prepare(self):
        """The signal's own image (every SSIM's reference and the grid's first column); the signal's data are
        read by the first gamma that needs them."""
        return {"reference": self.signal.image().astype(np.float64), "data": None}

    def plan(self):
        return [_cell_name(gamma) for gamma in self.gammas]

    def run_cell(self, name, state, folder):
        """One gamma: the Gini indices of the gamma-mapped signal, and each fraction's thresholded image against
        the signal's image (SSIM, PSNR); the grid's images are written as ``thresholded/*.npy``."""
        gamma = next(gamma for gamma in self.gammas if _cell_name(gamma) == name)
        signal, reference = self.signal, state["reference"]
        self.say(f"analyze: Gini indices at gamma {gamma:g}")
        gini_rows = gini_table(signal, (gamma,), memory_limit_bytes=self.memory_limit_bytes)
        if state["data"] is None:
            state["data"] = np.asarray(signal.data)
        size = math.prod(signal.shape)
        gamma_ssim = []
        for fraction in self.fractions:
            image = hard_threshold_image(state["data"], fraction, gamma=gamma).transpose(1, 0, 2)
            similarity = image_ssim(image, reference)
            peak = float(np.percentile(reference, 99.9)) or 1.0
            psnr = peak_signal_to_noise_ratio(np.clip(image, 0, peak), np.clip(reference, 0, peak), data_range=peak)
            gamma_ssim.append((gamma, fraction, max(1, math.ceil(fraction * size)), similarity, psnr))
            if fraction in self.grid_fractions:
                folder.write_npy(_image_name(gamma, fraction), image)
            self.say(f"analyze: gamma {gamma:g}, fraction {fraction:.0e}: SSIM {similarity:.4f}, PSNR {psnr:.2f} dB")
        return {"gini": [list(row) for row in gini_rows], "ssim": [list(row) for row in gamma_ssim]}

    def cell_finished(self, name, record, *, resumed):
        if resumed:
            self.say(f"analyze: gamma {name[len('gamma-'):]} already done")

    def report(self, folder, state, records):
        """Tables 5.1/5.2 and 7.1-7.3, ``gini.csv``, ``ssim.csv``, the SSIM figure, the image grid and
        ``analysis.json``; returns the rows and the Tables 7.1-7.3 layout in Markdown."""
        signal, gammas, reference = self.signal, self.gammas, state["reference"]
        rows, ssim_rows, images = [], [], {}
        for gamma in gammas:
            record = records[_cell_name(gamma)]
            rows += [tuple(row) for row in record["gini"]]
            ssim_rows += [tuple(row) for row in record["ssim"]]
            for fraction in self.grid_fractions:
                images[gamma, fraction] = np.load(folder.path_of(_image_name(gamma, fraction)))
        scene = signal.meta.get("scene", "signal")
        for stem, domain, caption in (
                ("table_5_1_fourier", "fourier", f"Sparsity metrics in Fourier space ({signal.kind}, Table 5.1 layout)"),
                ("table_5_2_canonical", "canonical",
                 f"Sparsity metrics in primary sample space ({signal.kind}, Table 5.2 layout)")):
            folder.write_table(stem, channel_table(rows, scene, domain, caption))
        gammas_table = gamma_table(rows, gammas, f"Gini index of {scene} ({signal.kind}) with gamma mapping "
                                                 "(Tables 7.1-7.3 layout)")
        folder.write_table("table_7_gamma", gammas_table)
        folder.write_text("gini.csv", gini_csv_table(rows).csv())
        folder.write_text("ssim.csv", ssim_csv_table(ssim_rows).csv())
        folder.write_figure("ssim_vs_fraction.png", _plot_ssim(ssim_rows, gammas, title=f"{scene} ({signal.kind}): "
                                                                                        "hard-thresholded Fourier"),
                            dpi=120, bbox_inches="tight")
        folder.write_figure("thresholded.png", _plot_grid(images, reference, gammas, self.grid_fractions), dpi=110,
                            bbox_inches="tight")
        folder.write_json("analysis.json", {
            "signal": {key: signal.meta.get(key) for key in ("scene", "kind", "axes", "shape", "spp", "seed", "max_depth")},
            "identity": self.identity(),
            "gammas": list(gammas),
            "fractions": list(self.fractions),
            "grid_fractions": list(self.grid_fractions),
            "ssim_convention": "sparselt.analysis.metrics.image_ssim: both images times the reference's exposure, "
                               "sRGB curve, SSIM with data_range 1 per channel",
            "gamma_mapping": "T = (I / max I) ** gamma with one maximum over all channels; inverse clips T < 0 to 0",
            "provenance": environment_record(),
        })
        return {"gini": rows, "ssim": ssim_rows, "gamma_table": gammas_table.markdown()}

    def summary(self, result):
        return {"gammas": len(self.gammas), "fractions": len(self.fractions)}


def _plot_ssim(rows, gammas, *, title):
    figure, axis = pyplot().subplots(figsize=(6, 4))
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
    return figure


def _plot_grid(images, reference, gammas, fractions):
    exposure = reference_exposure(reference)
    columns = len(fractions) + 1
    figure, panels = pyplot().subplots(len(gammas), columns, figsize=(2.4 * columns, 2.5 * len(gammas)), squeeze=False)
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
    return figure
