"""The sizes of `sparselt reproduce`, per scale and chapter, and the time each is expected to take (issue 21).

``tiny``
    The pipeline end to end in about a minute (the tests' scale): every figure and table, numbers meaningless.
``quick``
    Minutes on 2 cores: small grids and few samples; directions mostly hold, levels do not.
``medium``
    The thesis's 4-D size (250x250x16x16) for chapter 7, 96x96x8x8 for chapter 8's nine methods at the
    thesis's first three budgets, 10-D path spaces of 1.6e7 and 4.1e7 cells (the thesis: 6.6e8); 72 minutes
    on 2 cores (measured).
``thesis``
    The thesis's sizes throughout: about a day on 2 cores (the 10-D signals dominate).

Every size a chapter runner uses comes from here, so the page can state them and a scale's identity is its
name. Expected minutes are from runs on this project's 2-core machines (quick: 5 min 9 s, medium: 72 min,
measured 2026-12-03; thesis extrapolated from rates).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

from ...thesis.tables import thesis_guiding_times, thesis_times

#: The thesis's budgets: Table 6.2's spp per image size, Table 8.1's spp (both from :mod:`sparselt.thesis.tables`).
THESIS_MAP_SPPS = tuple(values[0] for values in thesis_guiding_times("6.2").values())
THESIS_COMPARE_SPPS = tuple(thesis_times("8.1"))


@dataclass(frozen=True)
class ReproduceScale:
    """What one scale of ``sparselt reproduce`` runs, chapter by chapter.

    Attributes
    ----------
    name : str
    integration_sizes : tuple of int
        Chapter 4: grid sides s of the random 4-D signals (N = s^4), Table 4.1's fit range.
    integration_repeats : int
    path_shape : tuple of int
        Chapter 5: the 10-D path-space grid (image axes first); thesis 100x100x4^8.
    path_spp : int
    render_resolution, render_spp : tuple of int, int
        Figure 5.1: the scenes rendered by Mitsuba's path tracer.
    dof_shape : tuple of int
        Chapter 7: the 4-D depth-of-field and indirect grids; thesis 250x250x16x16.
    dof_spp : int
    table61_shape : tuple of int
        Chapter 6: the 10-D grid the SFT reconstructs (thesis 100x100x4^8).
    table61_alphas : tuple of float
        Table 6.1's alphas on the Cornell box (courtyard: the first only).
    table61_reference_spp : int
    maps_shape, maps_resolution, maps_spps, maps_reference_spp : ...
        Tables 6.2/6.3: the SFT importance map's grid, the image rendered with it, its budgets.
    compare_shape, compare_spps, compare_reference_spp, compare_seeds, compare_repeats : ...
        Chapter 8's equal-time comparisons (both scenes); seeds and repeats also those of Tables 6.2/6.3.
    compare_ladder_max_spp : int
        The cap of PT's spp ladder (``ComparisonConfig.pt_ladder_max_spp``).
    minutes : dict
        Expected wall minutes per chapter on 2 cores.
    """

    name: str
    integration_sizes: tuple
    integration_repeats: int
    path_shape: tuple
    path_spp: int
    render_resolution: tuple
    render_spp: int
    dof_shape: tuple
    dof_spp: int
    table61_shape: tuple
    table61_alphas: tuple
    table61_reference_spp: int
    maps_shape: tuple
    maps_resolution: tuple
    maps_spps: tuple
    maps_reference_spp: int
    compare_shape: tuple
    compare_spps: tuple
    compare_reference_spp: int
    compare_seeds: tuple = (1, 2, 3)
    compare_repeats: int = 3
    compare_ladder_max_spp: int = 4096
    minutes: dict = field(default_factory=dict)

    def record(self):
        """The scale as plain JSON values."""
        return {key: list(value) if isinstance(value, tuple) else value for key, value in asdict(self).items()}

    def sizes_text(self, chapter):
        """The sizes chapter ``chapter`` runs at, as a sentence for the page."""
        grid = "x".join
        text = {
            "4": f"signal sides s = {', '.join(map(str, self.integration_sizes))} (N = s^4), "
                 f"{self.integration_repeats} repeat{'s' if self.integration_repeats != 1 else ''}",
            "5": f"path space {grid(map(str, self.path_shape))} at {self.path_spp} spp; renders "
                 f"{grid(map(str, self.render_resolution))} at {self.render_spp} spp",
            "6": f"SFT grid {grid(map(str, self.table61_shape))}, alphas {', '.join(f'{a:g}' for a in self.table61_alphas)}; "
                 f"maps {grid(map(str, self.maps_shape))} guiding {grid(map(str, self.maps_resolution))} images at "
                 f"{', '.join(map(str, self.maps_spps))} spp",
            "7": f"{grid(map(str, self.dof_shape))} at {self.dof_spp} spp",
            "8": f"{grid(map(str, self.compare_shape))}, {', '.join(map(str, self.compare_spps))} spp, seeds "
                 f"{', '.join(map(str, self.compare_seeds))}, {self.compare_repeats} timing repeat"
                 f"{'s' if self.compare_repeats != 1 else ''}, reference "
                 f"{self.compare_reference_spp} spp",
        }
        return text[str(chapter)]


SCALES = {
    "tiny": ReproduceScale(
        name="tiny", integration_sizes=(16, 24, 32), integration_repeats=1,
        path_shape=(16, 16) + (2,) * 8, path_spp=1, render_resolution=(32, 32), render_spp=16,
        dof_shape=(16, 16, 4, 4), dof_spp=2,
        table61_shape=(16, 16) + (2,) * 8, table61_alphas=(4.0,), table61_reference_spp=64,
        maps_shape=(16, 16) + (2,) * 8, maps_resolution=(16, 16), maps_spps=(4, 8), maps_reference_spp=64,
        compare_shape=(16, 16, 4, 4), compare_spps=(4, 8), compare_reference_spp=64, compare_seeds=(1, 2),
        compare_repeats=1, compare_ladder_max_spp=256, minutes={"4": 0.2, "5": 0.3, "6": 0.5, "7": 0.2, "8": 1.0}),
    "quick": ReproduceScale(
        name="quick", integration_sizes=(32, 48, 64), integration_repeats=2,
        path_shape=(16, 16) + (2,) * 8, path_spp=4, render_resolution=(128, 128), render_spp=64,
        dof_shape=(64, 64, 8, 8), dof_spp=4,
        table61_shape=(16, 16) + (4,) * 4 + (2,) * 4, table61_alphas=(4.0, 16.0, 32.0), table61_reference_spp=256,
        maps_shape=(16, 16) + (2,) * 8, maps_resolution=(64, 64), maps_spps=(16, 64), maps_reference_spp=1024,
        compare_shape=(64, 64, 8, 8), compare_spps=(16, 40), compare_reference_spp=256, compare_seeds=(1, 2),
        compare_repeats=2, compare_ladder_max_spp=2048, minutes={"4": 0.3, "5": 0.2, "6": 1.5, "7": 0.4, "8": 5.0}),
    "medium": ReproduceScale(
        name="medium", integration_sizes=(32, 48, 64, 96), integration_repeats=3,
        path_shape=(50, 50) + (3,) * 8, path_spp=8, render_resolution=(256, 256), render_spp=256,
        dof_shape=(250, 250, 16, 16), dof_spp=16,
        table61_shape=(25, 25) + (4,) * 8, table61_alphas=(4.0, 16.0, 32.0), table61_reference_spp=1024,
        maps_shape=(16, 16) + (3,) * 8, maps_resolution=(128, 128), maps_spps=(64, THESIS_MAP_SPPS[1]),
        maps_reference_spp=4096, compare_shape=(96, 96, 8, 8), compare_spps=THESIS_COMPARE_SPPS[:3],
        compare_reference_spp=2048, compare_repeats=2,
        minutes={"4": 1.0, "5": 12.0, "6": 19.0, "7": 26.0, "8": 13.0}),
    "thesis": ReproduceScale(
        name="thesis", integration_sizes=(32, 48, 64, 96, 128), integration_repeats=5,
        path_shape=(100, 100) + (4,) * 8, path_spp=64, render_resolution=(512, 512), render_spp=1024,
        dof_shape=(250, 250, 16, 16), dof_spp=64,
        table61_shape=(100, 100) + (4,) * 8, table61_alphas=(4.0, 16.0, 32.0), table61_reference_spp=4096,
        maps_shape=(100, 100) + (4,) * 8, maps_resolution=(1000, 1000), maps_spps=THESIS_MAP_SPPS[:1], maps_reference_spp=16384,
        compare_shape=(250, 250, 16, 16), compare_spps=THESIS_COMPARE_SPPS, compare_reference_spp=4096,
        minutes={"4": 2.5, "5": 1200.0, "6": 180.0, "7": 60.0, "8": 120.0}),
}


def get_scale(name):
    """The :class:`ReproduceScale` called ``name``; a ValueError lists the scales."""
    if name not in SCALES:
        raise ValueError(f"scale must be one of {', '.join(SCALES)}, got {name!r}")
    return SCALES[name]
