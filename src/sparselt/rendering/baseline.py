"""Plain path tracing with Mitsuba's own ``path`` integrator: the equal-time baseline.

Every later equal-time comparison renders its baseline with :func:`render_reference`.
"""

from __future__ import annotations

import os

from ..images import write_png
from ..provenance import environment_record, write_json
from .acquire import check_integer
from .scenes import get_scene


def render_reference(scene, out, *, spp, max_depth=3, seed=0, resolution=None, aperture=None,
                     focus_distance=None, variant="llvm_ad_rgb", scene_spec=None):
    """Render ``scene`` and write ``image.exr``, ``image.png`` and ``render.json`` into ``out``.

    Parameters
    ----------
    scene : str
        Built-in scene name or Mitsuba XML path.
    out : str
        Output folder (created; must be empty or new, see the CLI's ``--overwrite``).
    spp : int
        Samples per pixel (> 0).
    max_depth : int, optional
        Longest path, Mitsuba's convention (default 3).
    seed : int, optional
        Sampler seed.
    resolution : tuple of int, optional
        ``(width, height)``; default the scene's default resolution.
    aperture, focus_distance : float, optional
        Thin-lens override of the camera.

    Returns
    -------
    image : ndarray, shape (height, width, 3)
    record : dict
        What ``render.json`` holds, including ``seconds`` (wall time of the
        render alone, after Dr.Jit synchronisation) and samples per second.
    """
    from . import mitsuba_backend

    check_integer("spp", spp, 1)
    check_integer("max_depth", max_depth, 1)
    check_integer("seed", seed, 0, 2**32 - 1)
    spec = (scene_spec or get_scene(scene)).with_lens(aperture, focus_distance)
    resolution = tuple(resolution or spec.default_resolution)
    for size in resolution:
        check_integer("resolution", size, 1)
    loaded = mitsuba_backend.MitsubaScene(spec, resolution, variant=variant)
    image, seconds = loaded.render_path(spp, max_depth, seed)
    os.makedirs(out, exist_ok=True)
    mitsuba_backend.write_exr(os.path.join(out, "image.exr"), image)
    write_png(os.path.join(out, "image.png"), image)
    record = {
        "scene": spec.name,
        "integrator": "path",
        "spp": spp,
        "max_depth": max_depth,
        "seed": seed,
        "resolution": list(resolution),
        "aperture": loaded.camera.aperture_radius,
        "focus_distance": loaded.camera.focus_distance,
        "variant": variant,
        "seconds": seconds,
        "samples_per_second": resolution[0] * resolution[1] * spp / seconds,
        "provenance": environment_record(),
    }
    write_json(os.path.join(out, "render.json"), record)
    return image, record
