"""Image quality against a reference, the one set of metrics every experiment reports (thesis 8.1.1).

:func:`quality` is what ``compare`` and ``table61`` measure of each image:
SSIM (the project's HDR convention), relMSE with epsilon :data:`RELMSE_EPSILON`,
HDR-FLIP, the luminance and contrast ratios; :func:`caustic_mask` the pixels
where ``compare --caustic-mask`` also reports relMSE.
"""

from __future__ import annotations

import numpy as np

from ..analysis.metrics import (
    contrast_ratio,
    flip_error,
    image_ssim,
    luminance_ratio,
    relative_mean_squared_error,
)
from ..images import luminance
from ..rendering.mitsuba import MitsubaScene
from ..rendering.scenes import SceneSpec

#: relMSE's epsilon: (image - reference)^2 / (reference^2 + epsilon), averaged (every report states it).
RELMSE_EPSILON = 0.01


SPECULAR_BSDFS = ("conductor", "roughconductor", "dielectric", "roughdielectric", "thindielectric", "plastic",
                  "roughplastic")


def _without_specular(value):
    """A scene dictionary whose specular and glossy BSDFs are replaced by a grey diffuse one."""
    if isinstance(value, dict):
        if value.get("type") in SPECULAR_BSDFS:
            return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}
        return {key: _without_specular(item) for key, item in value.items()}
    return value


def caustic_mask(loaded, reference, *, spp, max_depth, seed=0, fraction=0.3):
    """Pixels lit by caustics: where removing every specular BSDF darkens a surface that stays the same.

    The scene is rendered again with its conductors and dielectrics made
    diffuse (no caustic can form) at ``spp``; a pixel is in the mask when the
    surface it sees is unchanged (same albedo in both scenes, so not one of
    the replaced objects) and the caustic-free render is darker than the
    reference by more than ``fraction`` of the reference. Only the reference
    and the two scenes enter it; no method's image does. Built-in scenes
    only (a scene file's BSDFs are not rewritten).
    """
    spec = loaded.spec
    if spec.objects is None:
        raise ValueError("the caustic mask needs a built-in scene (a scene file's materials are not rewritten)")
    plain = SceneSpec(name=spec.name + "-diffuse", description="specular BSDFs made diffuse",
                      objects=_without_specular(spec.objects), camera=spec.camera, lens_overrides=spec.lens_overrides,
                      hide_emitters=spec.hide_emitters)
    other = MitsubaScene(plain, (loaded.width, loaded.height))
    without, _ = other.render_path(spp, max_depth, seed)
    albedo, _ = loaded.render_aovs(16, seed)
    albedo_plain, _ = other.render_aovs(16, seed)
    same_surface = np.abs(luminance(albedo["albedo"]) - luminance(albedo_plain["albedo"])) < 0.02
    level, level_without = luminance(reference), luminance(without)
    return same_surface & (level - level_without > fraction * level) & (level > 0)


def quality(image, reference, mask=None):
    """SSIM (the project's HDR convention), relMSE (epsilon 0.01), HDR-FLIP, luminance and contrast ratios.

    With a boolean ``mask`` (height, width), also ``relmse_caustic``: the
    relMSE over the masked pixels only.
    """
    record = {
        "ssim": image_ssim(image, reference),
        "flip": flip_error(image, reference),
        "relmse": relative_mean_squared_error(image, reference, epsilon=RELMSE_EPSILON),
        "luminance_ratio": luminance_ratio(image, reference),
        "contrast_ratio": contrast_ratio(image, reference),
    }
    if mask is not None:
        record["relmse_caustic"] = (relative_mean_squared_error(image[mask][None], reference[mask][None],
                                                                epsilon=RELMSE_EPSILON) if mask.any() else "")
    return record


__all__ = ["RELMSE_EPSILON", "SPECULAR_BSDFS", "caustic_mask", "quality"]
