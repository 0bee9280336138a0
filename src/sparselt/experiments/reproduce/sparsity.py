"""Chapters 5 and 7 of `sparselt reproduce`: Gini indices and hard thresholding (Tables 5.1-5.2, 7.1-7.3,
Figures 5.1-5.4 and 7.1-7.6), through `sparselt analyze`."""

from __future__ import annotations

import numpy as np

from ...report import Section, Table
from ...thesis.findings import claim_values, judge, per_thesis_row, table_claims
from ...thesis.numbers import thesis_table, thesis_value
from ...thesis.scenes import CORNELL_BOX, PATH_SPACE_ROWS, SAN_MIGUEL, table_scene
from ..sparsity_analysis import DEFAULT_FRACTIONS, analyze_signal, gini_table
from .common import figure_claim, grid_text, sampled_signal, thesis_figure

#: thesis scene of Tables 5.1/5.2 -> (our scene, kind), from :mod:`sparselt.thesis.scenes`
CHAPTER_5_SIGNALS = {label: (thesis_scene.scene, kind) for label, (thesis_scene, kind) in PATH_SPACE_ROWS.items()}
#: Figures 5.2 and 5.3: the hard-thresholded signals (full transport) of each scene.
THRESHOLDED_FIGURES = {"Cornell": "5.2", "San Miguel": "5.3"}
#: thesis table -> (our scene, kind, lens (:mod:`sparselt.thesis.scenes`), SSIM figure, thresholded figure)
GAMMA_SIGNALS = {record.table: (record.scene, record.kind, record.lens(), *figures) for record, figures in (
    (table_scene("7.1"), ("7.1", "7.3")), (table_scene("7.2"), ("7.2", "7.4")), (table_scene("7.3"), ("7.5", "7.6")))}
GAMMAS = (1.0, 0.5, 0.25, 0.1, 0.05)
#: a column of Tables 5.x / 7.x -> (domain, energy) of our Gini rows
COLUMNS = {"Gini Magnitude": None, "Gini Energy": None, "Time": ("canonical", False),
           "Time Energy": ("canonical", True), "Frequency": ("fourier", False), "Frequency Energy": ("fourier", True)}


def _value(rows, gamma, domain, energy, channel=None):
    values = [row[4] for row in rows if row[0] == gamma and row[1] == domain and row[2] == energy
              and (channel is None or row[3] == channel)]
    return float(sum(values) / len(values))


def _ssim_at(ssim_rows, gamma, fraction):
    values = [row[3] for row in ssim_rows if row[0] == gamma and row[1] == fraction]
    return float(values[0]) if values else None


def _mean_ssim(ssim_rows, gamma):
    values = [row[3] for row in ssim_rows if row[0] == gamma and np.isfinite(row[3])]
    return float(np.mean(values)) if values else None


# ---------------------------------------------------------------------------------------------- chapter 5
def chapter_5(run):
    """Tables 5.1/5.2 (per-channel Gini of path-space signals), Figure 5.1 (the scenes), Figures 5.2-5.4 (hard
    thresholding of the full-transport signals of both scenes)."""
    scale = run.scale
    shape, spp = scale.path_shape, scale.path_spp
    gini, ssim = {}, {}
    figures = [_figure_5_1(run)]
    for thesis_scene, (scene, kind) in CHAPTER_5_SIGNALS.items():
        signal = sampled_signal(scene, kind, shape, spp, run.path, f"{scene}-{kind}", run.progress)
        if thesis_scene in THRESHOLDED_FIGURES:
            analysis = analyze_signal(signal, run.sub(f"analysis-{scene}-{kind}"), gammas=(1.0,),
                                      fractions=DEFAULT_FRACTIONS, progress=False, overwrite=True)
            gini[thesis_scene], ssim[thesis_scene] = analysis["gini"], analysis["ssim"]
            kept = _ssim_at(analysis["ssim"], 1.0, 1e-4)
            figures.append(thesis_figure(
                run.page_path(f"analysis-{scene}-{kind}", "thresholded.png"), THRESHOLDED_FIGURES[thesis_scene],
                f"{scene} {kind}, {grid_text(shape)}, {spp} spp",
                [f"Ours: SSIM {kept:.3f} at 1/10^4 of the coefficients." if kept is not None else ""]))
        else:
            gini[thesis_scene] = gini_table(signal, (1.0,))
    figures.append(_figure_5_4(run, ssim))

    def ours(quantity):
        domain = "fourier" if quantity["table"] == "5.1" else "canonical"
        energy = quantity["column"] == "Gini Energy"
        return per_thesis_row(quantity, lambda label: _value(gini[label[0]], 1.0, domain, energy, label[1]))

    tables, verdicts = [], []
    for number, domain, basis in (("5.1", "fourier", "Fourier"), ("5.2", "canonical", "primary sample space")):
        rows = []
        for thesis_scene in CHAPTER_5_SIGNALS:
            for channel in ("R", "G", "B"):
                thesis = [thesis_value(number, (thesis_scene, channel), column)
                          for column in ("Gini Magnitude", "Gini Energy")]
                values = [_value(gini[thesis_scene], 1.0, domain, energy, channel) for energy in (False, True)]
                rows.append((f"{thesis_scene} ({CHAPTER_5_SIGNALS[thesis_scene][0]}) {channel}",
                             [f"{thesis[0]:.4f}", f"{values[0]:.4f}", f"{thesis[1]:.4f}", f"{values[1]:.4f}"]))
        tables.append(Table(caption=f"Table {number}: {thesis_table(number)['caption']} (ours: grid "
                                    f"{grid_text(shape)}, {spp} spp)",
                            columns=["thesis Gini", "ours", "thesis Gini energy", "ours"],
                            kinds=["thesis", "ours", "thesis", "ours"], rows=rows))
        for claim in table_claims(number):
            verdicts.append(judge(claim, claim_values(claim, ours)).sentence)
    return Section(title="Chapter 5: sparsity of path space", tables=tables, verdicts=verdicts, figures=figures,
                   introduction="Gini index (eq. 5.1) of the path-space signals, per channel, of magnitudes and "
                                "energies, and hard-thresholded Fourier reconstructions; San Miguel is our courtyard, "
                                f"the Cornell box Mitsuba's. Sizes: {scale.sizes_text('5')}.")


def _figure_5_1(run):
    """Figure 5.1: the two test scenes, rendered by Mitsuba's path tracer."""
    from ...images import reference_exposure, srgb_tonemap
    from ..render import render_reference
    from ...report.plotting import pyplot

    scenes = {CORNELL_BOX.name: CORNELL_BOX.scene, f"{SAN_MIGUEL.name} ({SAN_MIGUEL.scene})": SAN_MIGUEL.scene}
    figure, axes = pyplot().subplots(1, len(scenes), figsize=(6 * len(scenes), 6.3))
    for axis, (title, scene) in zip(axes, scenes.items()):
        image, record = render_reference(scene, run.sub(f"render-{scene}"), spp=run.scale.render_spp,
                                         resolution=run.scale.render_resolution, overwrite=True)
        axis.imshow(srgb_tonemap(image, reference_exposure(image)))
        axis.set_title(f"{title}: {record['spp']} spp, {record['seconds']:.1f} s", fontsize=12)
        axis.set_xticks([])
        axis.set_yticks([])
    figure.tight_layout()
    return thesis_figure(run.write_figure("figure_5_1.png", figure), "5.1",
                         f"Mitsuba path tracer, {grid_text(run.scale.render_resolution)}, depth 3")


def _figure_5_4(run, ssim):
    """Figure 5.4: SSIM of the hard-thresholded reconstructions against the fraction kept, both scenes."""
    from ...report.plotting import pyplot

    figure, axis = pyplot().subplots(figsize=(8, 5))
    for thesis_scene, rows in ssim.items():
        points = sorted((row[1], row[3]) for row in rows if row[0] == 1.0)
        axis.plot([p[0] for p in points], [p[1] for p in points], marker="o",
                  label=f"{thesis_scene} ({CHAPTER_5_SIGNALS[thesis_scene][0]})")
    axis.axvline(1e-4, color="grey", lw=1, ls=":")
    axis.set(xscale="log", xlabel="fraction of Fourier coefficients kept", ylabel="SSIM against the signal's image",
             title="Hard-thresholded Fourier reconstruction quality")
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize=11)
    values = [_ssim_at(rows, 1.0, 1e-4) for rows in ssim.values()]
    values = [value for value in values if value is not None and np.isfinite(value)]
    return thesis_figure(run.write_figure("figure_5_4.png", figure), "5.4", "full transport, both scenes",
                         [figure_claim("5.4", values or None, subject="both scenes")])


# ---------------------------------------------------------------------------------------------- chapter 7
def chapter_7(run):
    """Tables 7.1-7.3 (Gini of depth-of-field and indirect signals under gamma mapping, eq. 7.1) and Figures
    7.1-7.6 (SSIM against gamma and fraction kept, thresholded images)."""
    from ...thesis.numbers import _printed_number

    shape, spp = run.scale.dof_shape, run.scale.dof_spp
    tables, verdicts, figures = [], [], []
    for number, (scene, kind, lens, ssim_figure, grid_figure) in GAMMA_SIGNALS.items():
        signal = sampled_signal(scene, kind, shape, spp, run.path, f"{scene}-{kind}", run.progress, **lens)
        name = f"analysis-{scene}-{kind}"
        analysis = analyze_signal(signal, run.sub(name), gammas=GAMMAS, fractions=DEFAULT_FRACTIONS, progress=False,
                                  overwrite=True)
        rows, ssim_rows = analysis["gini"], analysis["ssim"]
        thesis = {row["label"]: row["cells"] for row in thesis_table(number)["rows"]}
        table_rows = []
        for gamma, label in zip(GAMMAS, thesis):
            cells = []
            for column, (domain, energy) in ((key, value) for key, value in COLUMNS.items() if value):
                cells += [f"{thesis[label][column]['value']:.4f}", f"{_value(rows, gamma, domain, energy):.4f}"]
            table_rows.append((f"gamma {gamma:g}", cells))
        header = []
        for column, value in COLUMNS.items():
            if value:
                header += [f"thesis {column}", "ours"]
        subject = f"{scene} {kind}, {grid_text(shape)}, {spp} spp"
        tables.append(Table(caption=f"Table {number}: {thesis_table(number)['caption']} (ours: {subject}; mean over "
                                    "R, G, B; 'Time' = primary sample space, 'Frequency' = Fourier)",
                            columns=header, kinds=["thesis", "ours"] * 4, rows=table_rows))

        def ours(quantity):
            domain, energy = COLUMNS[quantity["column"]]
            return per_thesis_row(quantity, lambda label: _value(rows, _printed_number(label), domain, energy))

        for claim in table_claims(number):
            verdicts.append(judge(claim, claim_values(claim, ours), subject=subject).sentence)
        best = max((gamma for gamma in GAMMAS if gamma < 1.0), key=lambda gamma: _mean_ssim(ssim_rows, gamma) or -1)
        measured = ([_mean_ssim(ssim_rows, best)], [_mean_ssim(ssim_rows, 1.0)])
        sentence = figure_claim(ssim_figure, measured if None not in (measured[0][0], measured[1][0]) else None,
                                subject=f"{subject}, SSIM averaged over the fractions kept; best gamma {best:g}")
        figures.append(thesis_figure(run.page_path(name, "ssim_vs_fraction.png"), ssim_figure, subject, [sentence]))
        figures.append(thesis_figure(run.page_path(name, "thresholded.png"), grid_figure, subject))
    return Section(title="Chapter 7: 4-D sparsity with gamma mapping", tables=tables, verdicts=verdicts,
                   figures=figures,
                   introduction="Gini indices of depth-of-field (Dragons = dof-sculptures, San Miguel = courtyard) "
                                "and indirect signals after the gamma mapping of eq. 7.1, and their hard-thresholded "
                                f"reconstructions. Sizes: {run.scale.sizes_text('7')}.")


__all__ = ["CHAPTER_5_SIGNALS", "GAMMAS", "GAMMA_SIGNALS", "chapter_5", "chapter_7"]
