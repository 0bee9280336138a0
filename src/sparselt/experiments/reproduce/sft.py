"""Chapter 6 of `sparselt reproduce`: the SFT on rendered path space (Table 6.1, Figures 6.1/6.2) and SFT
importance maps guiding a render (Tables 6.2/6.3, Figures 6.3-6.7), on the Cornell box and the courtyard."""

from __future__ import annotations

import math

from ...report import Section
from ...thesis.findings import judge, table_claims
from ...thesis.scenes import SAN_MIGUEL, table_scene
from ...thesis.tables import table_6_1, thesis_table_6_1
from .common import figure_claim, grid_text, thesis_figure

#: Figures 6.3-6.7: our guided-map scene (:mod:`sparselt.thesis.scenes`) -> (its thesis table, image-grid figure,
#: crop-grid figures)
MAP_SCENES = {table_scene(table).scene: (table, grid, crops)
              for table, grid, crops in (("6.2", "6.3", ("6.4", "6.5")), ("6.3", "6.6", ("6.7",)))}
#: Table 6.1 on both scenes: our scene -> (thesis figure, alphas: 'all' of the scale's, or the first only); the
#: thesis ran Table 6.1's scene, and shows San Miguel's Figure 6.2 beside it.
TABLE_61_SCENES = {table_scene("6.1").scene: ("6.1", "all"), SAN_MIGUEL.scene: ("6.2", "first")}
#: Above this many cells Table 6.1's alpha 32 (which reads every cell) is not run: several complex arrays of
#: the signal (10 GiB each at the thesis's 6.55e8 cells) exceed this machine's 24 GB.
DENSE_LIMIT_CELLS = 2 * 10**8


def chapter_6(run):
    """Table 6.1 and Figures 6.1/6.2 (`sparselt table61`), then the importance-map comparisons."""
    from ..quality import RELMSE_EPSILON
    from ..sft_path_space import Table61Config, run_table61

    scale = run.scale
    shape = scale.table61_shape
    size = math.prod(shape)
    thesis = thesis_table_6_1()
    thesis_scene = table_scene("6.1").scene
    alphas = tuple(alpha for alpha in scale.table61_alphas if alpha < 32 or size <= DENSE_LIMIT_CELLS)
    left_out = [alpha for alpha in scale.table61_alphas if alpha not in alphas]
    table_rows, figures, verdicts, links = [], [], [], []
    results = {}
    for scene, (figure_number, which) in TABLE_61_SCENES.items():
        config = Table61Config(scene=scene, shape=shape, alphas=alphas if which == "all" else alphas[:1],
                               noise_spps=(), reference_spp=scale.table61_reference_spp)
        rows = run_table61(config, run.sub(f"table61-{scene}"), progress=run.progress)
        results[scene] = rows
        table_rows += [dict(row, scene=scene) for row in rows]
        measured = ([row["sft"]["relmse"] for row in rows], [row["pt_equal_samples"]["relmse"] for row in rows])
        subject = f"{scene}, {grid_text(shape)}, alpha {rows[0]['alpha']:g}"
        figures.append(thesis_figure(run.page_path(f"table61-{scene}", "figure_6_1.png"), figure_number, subject,
                                     [figure_claim(figure_number, measured, subject=f"{scene}, every alpha run")]))
        links += [(f"table_6_1.md ({scene})", run.page_path(f"table61-{scene}", "table_6_1.md"))]
    cornell = results[thesis_scene]
    for claim in table_claims("6.1"):
        ours = [row["total_samples"] / size for row in cornell]
        run_alphas = ", ".join(f"{row['alpha']:g}" for row in cornell)
        verdicts.append(judge(claim, ours, subject=f"{thesis_scene} {grid_text(shape)}, alpha {run_alphas}").sentence)
    notes = []
    if left_out:
        notes.append(f"Alpha {', '.join(f'{alpha:g}' for alpha in left_out)} not run: it reads every cell (1.0 N "
                     f"at the quick and medium scales), and at {size:,} cells one complex array of the signal alone "
                     f"is {size * 16 / 2**30:.0f} GiB; the SFT holds several, beyond this machine's 24 GB.")
    thesis_alphas = [alpha for alpha in thesis if float(alpha) not in alphas]
    if thesis_alphas and not left_out:
        notes.append(f"Thesis alphas {', '.join(map(str, thesis_alphas))} are not run at this scale.")
    table = table_6_1(table_rows, caption_suffix=f" (ours: grid {grid_text(shape)}, K = N/10^4, 1 path sample per "
                                                 f"lattice point; the thesis ran {thesis_scene})",
                      epsilon=RELMSE_EPSILON, notes=notes)
    maps = [_map_section(run, scene, *values) for scene, values in MAP_SCENES.items()]
    return Section(title="Chapter 6: the Sparse Fourier Transform on path space",
                   introduction=f"The SFT with the renderer as its oracle (6.1), then SFT importance maps guiding "
                                f"a render (6.2). Sizes: {scale.sizes_text('6')}.",
                   tables=[table] + [item for section in maps for item in section.tables],
                   verdicts=verdicts + [item for section in maps for item in section.verdicts],
                   figures=figures + [item for section in maps for item in section.figures],
                   links=links + [item for section in maps for item in section.links])


def _map_section(run, scene, table_number, grid_figure, crop_figures):
    """Tables 6.2/6.3 and the guided images: PT and guided-sft at the same spp and at equal time."""
    from ...report.comparison import comparison_section, guided_budgets, table_6
    from ..compare import ComparisonConfig, compare

    scale = run.scale
    config = ComparisonConfig(
        scene=scene, kind="path", shape=scale.maps_shape, resolution=scale.maps_resolution,
        methods=("pt", "guided-sft"), spps=scale.maps_spps, reference_spp=scale.maps_reference_spp,
        seeds=scale.compare_seeds, timing_repeats=scale.compare_repeats,
        pt_ladder_max_spp=scale.compare_ladder_max_spp,
        options={"guided-sft": {"map_spp": 1, "mode": "global"}})
    name = f"maps-{scene}"
    result = compare(config, run.sub(name), progress=run.progress, overwrite=True)
    section = comparison_section(run.sub(name), run.page_path(name), result.rows, config, scene,
                                 methods=result.methods, summary=result.summary)
    width, height = config.output_resolution
    # Table 6.2/6.3 beside our budgets: the single run's own table (report.comparison.table_6), first.
    section.tables = table_6(result.rows, scene, config, methods=result.methods)[1:] + section.tables
    _, budgets = guided_budgets(result.rows, result.methods)
    ours = [(budget["spp"], budget["seconds"], budget["relmse"], budget["pt_seconds"], budget["pt_relmse"])
            for budget in budgets]
    for claim in table_claims(table_number):
        section.verdicts.insert(0, judge(claim, ([mine[1] for mine in ours], [mine[3] for mine in ours]),
                                         subject=f"{scene} {width}x{height}").sentence)
    same_spp = "; ".join(f"at {spp} spp guided-sft takes {seconds:.3g} s against PT's {pt_seconds:.3g} s, "
                         f"relMSE {relmse:.3g} against {pt_relmse:.3g}"
                         for spp, seconds, relmse, pt_seconds, pt_relmse in ours)
    section.verdicts.insert(1, f"Equal spp ({scene}, the thesis's comparison): {same_spp}.")
    measured = ([mine[2] for mine in ours], [mine[4] for mine in ours])
    prefix = run.page_path(name)
    section.figures = [
        thesis_figure(f"{prefix}/image_grid.png", grid_figure, f"{scene}, {width}x{height}",
                      [figure_claim(grid_figure, measured, subject=f"{scene}, every budget")]),
        thesis_figure(f"{prefix}/crop_grid.png", crop_figures, f"{scene}: where the images differ most")]
    return section


__all__ = ["MAP_SCENES", "TABLE_61_SCENES", "chapter_6"]
