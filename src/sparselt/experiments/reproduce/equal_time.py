"""Chapter 8 of `sparselt reproduce`: the CoSaMP pipeline, the filters and the importance maps against PT at
equal time on both scenes (Tables 8.1/8.2, Figures 8.1-8.4 and 8.6-8.17 but the flowcharts), through `sparselt compare`."""

from __future__ import annotations

import numpy as np

from ...report import Section
from ...thesis.findings import claim_values, figure_finding, judge, table_claims, thesis_findings
from ...thesis.scenes import EQUAL_TIME_TABLES, table_scene
from .common import thesis_figure

CHAPTER_8_METHODS = ("pt", "samples-mean", "cosamp", "cosamp-thesis", "bilateral", "cosamp-bilateral", "oidn",
                     "guided-cosamp", "guided-bilateral")
#: our scene -> (thesis table, thesis scene, gamma (8.1.1), lens), from :mod:`sparselt.thesis.scenes`
SCENES = {record.scene: (record.table, record.thesis_scene.name, record.thesis_scene.gamma, record.lens())
          for record in map(table_scene, EQUAL_TIME_TABLES)}
#: The thesis's figure groups (``thesis_findings.json``: each chapter-8 figure's group, scene and layout) ->
#: the method families shown beside PT; None: only the method the group's claim is about.
GROUP_FAMILIES = {"reconstruction": ("ablation", "cosamp"), "filters": ("filter", "denoiser"), "guided": ("guided",),
                  "guided-bilateral": None}
LAYOUTS = ("quality", "images", "crops")
#: Tables 8.1/8.2's phases, as printed, and the result column holding ours.
PHASE_COLUMNS = {"Total": "seconds_total", "Sampling": "seconds_sampling", "CoSaMP": "seconds_reconstruction",
                 "Integration": "seconds_integration"}


def thesis_figures_of(thesis_scene):
    """``{group: {layout: [figure numbers]}}`` of the thesis's chapter-8 figures of ``thesis_scene``."""
    groups = {}
    for number, record in thesis_findings()["figures"].items():
        place = record.get("comparison")
        if place and place["scene"] == thesis_scene:
            groups.setdefault(place["group"], {}).setdefault(place["layout"], []).append(number)
    return groups


def chapter_8(run, plugin_methods=()):
    """Both scenes' equal-time comparisons, one section; ``plugin_methods`` (``--plugin``) run beside."""
    sections = [_scene_section(run, scene, tuple(plugin_methods)) for scene in SCENES]
    return Section(title="Chapter 8: CoSaMP reconstruction, filtering and the equal-time comparison",
                   introduction="The thesis's depth-of-field pipeline (CoSaMP at gamma 0.25 for the Dragons = "
                                "dof-sculptures, 0.5 for San Miguel = courtyard; sparsity 1/200) and every method "
                                "built on it, against PT at equal time. Sizes: " + run.scale.sizes_text("8") + ". "
                                + sections[0].introduction,
                   tables=[table for section in sections for table in section.tables],
                   verdicts=[verdict for section in sections for verdict in section.verdicts],
                   figures=[figure for section in sections for figure in section.figures],
                   links=[link for section in sections for link in section.links])


def _scene_section(run, scene, plugin_methods):
    from ...report.comparison import comparison_section
    from ..compare import ComparisonConfig, compare

    number, _, gamma, lens = SCENES[scene]
    scale = run.scale
    config = ComparisonConfig(
        scene=scene, kind="dof", shape=scale.compare_shape, methods=CHAPTER_8_METHODS + plugin_methods,
        spps=scale.compare_spps, seeds=scale.compare_seeds, timing_repeats=scale.compare_repeats,
        pt_ladder_max_spp=scale.compare_ladder_max_spp,
        reference_spp=scale.compare_reference_spp, options={"*": {"gamma": gamma}}, **lens)
    name = f"compare-{scene}"
    result = compare(config, run.sub(name), progress=run.progress, overwrite=True)
    section = comparison_section(run.sub(name), run.page_path(name), result.rows, config, scene,
                                 methods=result.methods, summary=result.summary)
    section.verdicts = [f"{scene}: {verdict}" for verdict in section.verdicts]
    # Table 8.1/8.2 is the single run's own (report.comparison.table_8): the thesis's times beside the CoSaMP methods.
    procedure = "cosamp-thesis"
    groups = {spp: [row for row in result.rows if row["method"] == procedure and row["spp"] == spp]
              for spp in config.spps}
    means = {spp: {key: float(np.mean([row[key] for row in group])) for key in PHASE_COLUMNS.values()}
             for spp, group in groups.items() if group}
    spps = sorted(means)
    for claim in table_claims(number):
        ours = claim_values(claim, lambda quantity: [means[spp][PHASE_COLUMNS[quantity["column"]]] for spp in spps])
        section.verdicts.insert(0, judge(claim, ours, subject=f"{scene} {procedure}, "
                                                              f"{', '.join(map(str, spps))} spp").sentence)
    section.figures = _group_figures(run, name, scene, result)
    return section


def _group_figures(run, name, scene, result):
    """The thesis's figures of ``scene``: per group of methods (with PT), quality against time, the images at
    matched time and detail crops, written into the chapter folder."""
    from ...report.comparison_figures import crop_grid_figure, image_grid_figure, matched_pictures, quality_figure
    from ..comparison_cells import IMAGES, cell_name
    from ..quality import RELMSE_EPSILON

    folder = run.sub(name)
    reference = np.load(f"{folder}/{IMAGES}/reference.npy")

    def image_of(row):
        return np.load(f"{folder}/{IMAGES}/{cell_name(row['method'], row['spp'], row['seed'])}.npy")

    families = {method: record.get("family") for method, record in result.methods.items()}
    baseline = next(method for method, record in result.methods.items() if record.get("baseline"))
    figures = []
    for group, layouts in thesis_figures_of(SCENES[scene][1]).items():
        claims = [figure_finding(number)["claim"] for number in layouts.get("quality", [])
                  if "claim" in figure_finding(number)]
        wanted = GROUP_FAMILIES[group]
        shown = ({method for method, family in families.items() if family in wanted} if wanted is not None
                 else {claim["method"] for claim in claims}) | {baseline}
        rows = [row for row in result.rows if row["method"] in shown]
        summary = [record for record in result.summary if record["method"] in shown]
        if len(shown) < 2 or not rows:
            continue
        subject = f"{scene}, {', '.join(sorted(shown - {baseline}))} and {baseline}"
        findings = []
        for claim in claims:
            ratios = [record["relmse_ratio"] for record in result.summary
                      if record["method"] == claim["method"] and isinstance(record.get("relmse_ratio"), float)]
            findings.append(judge(claim, ratios or None, subject=f"{scene} {claim['method']}, per budget (relMSE; "
                                                                 "the thesis measured SSIM)").our_sentence)
        matched = matched_pictures(rows, reference, image_of)
        makers = {"quality": lambda: quality_figure(rows, scene, RELMSE_EPSILON, summary, None),
                  "images": lambda: image_grid_figure(*matched), "crops": lambda: crop_grid_figure(*matched)}
        for layout in LAYOUTS:
            if layout in layouts:
                path = run.write_figure(f"{group}-{scene}-{layout}.png", makers[layout]())
                figures.append(thesis_figure(path, layouts[layout], subject, findings if layout == "quality" else ()))
    return figures


__all__ = ["CHAPTER_8_METHODS", "GROUP_FAMILIES", "SCENES", "chapter_8", "thesis_figures_of"]
