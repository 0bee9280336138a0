"""The built-in ``standard`` suite: eleven scenes, each a difficulty papers test, at three scales (issue 36).

``sparselt suite --suite standard --scale quick|default|paper`` runs it; a
scale sets the image size (128x128, 256x256, 1024x576), the reference's time
limit per scene and PT's ladder. Its methods are the ones that compete at
equal time (PT, the denoiser, the filters, the axis-aligned filters and
gradient-domain PT, each where its kind allows); the thesis's sparse methods
(CoSaMP, SFT, guided sampling) cost 5 to 300 times PT's time per image at
these sizes (measured on dof-sculptures, 128x128, 16 spp: guided-bilateral
27.8 s against PT's 0.1 s) and lose, so they join only when asked
(``--methods``).

Each scene states why it is in the suite (:data:`STANDARD_SCENES`); the
scenes themselves are in :mod:`sparselt.rendering.procedural`,
:mod:`sparselt.rendering.scenes` and :mod:`sparselt.rendering.standard_scenes`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from .suite_config import SuiteConfig, SuiteScene, validate_suite

#: The methods of the standard suite, each on the scenes whose kind it supports.
STANDARD_METHODS = ("pt", "oidn", "gaussian", "bilateral", "aov-bilateral", "aaf-dof", "aaf-indirect",
                    "gradient-l2", "gradient-l1")
#: The quick scale's methods: the best of each family (the demo's too).
QUICK_METHODS = ("pt", "oidn", "bilateral", "aaf-dof", "aaf-indirect", "gradient-l1")


@dataclass(frozen=True)
class Scale:
    """A scale of the standard suite: image size, budgets, seeds, timing repeats, reference and ladder limits."""

    name: str
    resolution: tuple
    methods: tuple
    spps: tuple = (16, 64)
    seeds: tuple = (1, 2, 3)
    timing_repeats: int = 3
    reference_minutes: float = 4.0
    pt_ladder_max_spp: int = 1024


SCALES = {
    "quick": Scale("quick", (128, 128), QUICK_METHODS, timing_repeats=2, reference_minutes=1.0,
                   pt_ladder_max_spp=512),
    # 4096, not 1024: at 1024 spp PT's ladder ended before the best methods' quality on 5 of 11 scenes at 64 spp
    # (their speed-ups were lower bounds, docs/experiments/suite-shift-auto); the ladder stops where PT's error
    # reaches every method's, so the cap costs time only where it was censoring.
    "default": Scale("default", (256, 256), STANDARD_METHODS, timing_repeats=2, reference_minutes=3.0,
                     pt_ladder_max_spp=4096),
    "paper": Scale("paper", (1024, 576), STANDARD_METHODS, reference_minutes=30.0, pt_ladder_max_spp=2048),
}

#: (suite name, scene, kind, max depth, why it is in the suite); scenes of
#: :mod:`sparselt.rendering.standard_scenes` take their kind and depth from its ``SUITE_SETTINGS``.
STANDARD_SCENES = (
    ("cornell-box", "cornell-box", "path", 3,
     "Mitsuba's Cornell box: diffuse interreflection under a small area light, the field's first test."),
    ("dof-sculptures", "dof-sculptures", "dof", 3,
     "Depth of field over glossy sculptures and a checkered floor: the thesis's chapter 8 scene."),
    ("courtyard", "courtyard", "indirect", 3,
     "Diffuse indirect light in an open courtyard with plants and fine geometry: the thesis's second scene."),
    ("sunlit-room", "sunlit-room", "indirect", 5,
     "Sunlight through window glass into a closed room: every sunlit path is a caustic PT finds by chance."),
)
NEW_SCENES = ("checker-dof", "glossy-interior", "soft-shadows", "thin-geometry", "mirror-room", "outdoor-texture",
              "glass-caustic")


def standard_scenes():
    """The standard suite's scenes as :class:`SuiteScene` s (without methods: the scale chooses them)."""
    from ..rendering.standard_scenes import SUITE_SETTINGS

    scenes = [SuiteScene(name=name, scene=scene, kind=kind, max_depth=depth, reason=reason)
              for name, scene, kind, depth, reason in STANDARD_SCENES]
    for name in NEW_SCENES:
        settings = SUITE_SETTINGS[name]
        scenes.append(SuiteScene(name=name, scene=name, kind=settings["kind"], max_depth=settings["max_depth"],
                                 reason=settings["reason"]))
    return scenes


def applicable_methods(methods, kind):
    """The methods of ``methods`` (names or variants) whose method supports ``kind``, in order."""
    from ..methods import method_class
    from ..methods.variants import parse_method_variant

    return tuple(row for row in methods if kind in method_class(parse_method_variant(row)[0]).kinds)


def standard_suite(scale="default", *, methods=None, scenes=None):
    """The standard suite at ``scale``.

    Parameters
    ----------
    scale : {'quick', 'default', 'paper'}
    methods : sequence of str, optional
        Replace the scale's methods (names or variants); each scene runs
        those that support its kind.
    scenes : sequence of str, optional
        Only these of the suite's scenes (by name), e.g. the demo's two.

    Returns
    -------
    SuiteConfig

    Raises
    ------
    ValueError
        An unknown scale or scene name, or a method no scene can run.
    """
    if scale not in SCALES:
        raise ValueError(f"scale {scale!r} is not one of {', '.join(SCALES)}")
    chosen = SCALES[scale]
    rows = tuple(methods) if methods else chosen.methods
    every = standard_scenes()
    if scenes is not None:
        known = [scene.name for scene in every]
        unknown = [name for name in scenes if name not in known]
        if unknown:
            raise ValueError(f"the standard suite has no scene {unknown[0]!r}; its scenes: {', '.join(known)}")
        every = [scene for scene in every if scene.name in scenes]
    members = []
    for scene in every:
        applicable = applicable_methods(rows, scene.kind)
        if "pt" not in applicable:
            applicable = ("pt",) + applicable
        members.append(replace(scene, methods=applicable))
    unused = [row for row in rows if not any(row in scene.methods for scene in members)]
    if unused:
        raise ValueError(f"method {unused[0]!r} supports none of the suite's kinds "
                         f"({', '.join(sorted({scene.kind for scene in members}))})")
    config = SuiteConfig(name=f"standard-{scale}", methods=rows, spps=chosen.spps, scenes=tuple(members),
                         seeds=chosen.seeds, timing_repeats=chosen.timing_repeats, reference_spp="auto",
                         reference_minutes=chosen.reference_minutes, resolution=chosen.resolution,
                         pt_ladder_max_spp=chosen.pt_ladder_max_spp,
                         description=f"sparselt's standard suite at the {scale} scale", source=f"standard:{scale}")
    validate_suite(config)
    return config
