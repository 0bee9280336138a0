"""Plain path tracing with Mitsuba's own ``path`` integrator: the equal-time baseline.

Every later equal-time comparison renders its baseline with :func:`render_reference`.
"""

from __future__ import annotations

import hashlib
import json
import os

import numpy as np

from ..images import write_png
from ..measurement import progress_bar
from ..provenance import atomic_save_npy, environment_record, read_json, write_json
from ..checks import check_integer
from .scenes import get_scene


MAXIMUM_WAVEFRONT = 2**32 - 1


def check_wavefront(resolution, spp):
    """Mitsuba renders pixels x spp samples in one wavefront, counted in 32 bits: refuse more, with the limit."""
    samples = int(resolution[0]) * int(resolution[1]) * int(spp)
    if samples > MAXIMUM_WAVEFRONT:
        largest = MAXIMUM_WAVEFRONT // (int(resolution[0]) * int(resolution[1]))
        raise ValueError(f"{resolution[0]}x{resolution[1]} pixels at {spp} spp are {samples:.3g} samples in one pass; "
                         f"Mitsuba counts them in 32 bits: at most {largest} spp at this resolution "
                         "(render several passes with different seeds and average them)")


def check_finite_image(image, name):
    """Refuse a render with NaN or infinite pixels instead of writing it."""
    bad = int(np.count_nonzero(~np.isfinite(image)))
    if bad:
        raise ValueError(f"the render of {name!r} has {bad} NaN or infinite pixel values; nothing was written. "
                         "The scene (an emitter of huge radiance, a degenerate mesh) produces them")


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
    check_wavefront(resolution, spp)
    loaded = mitsuba_backend.MitsubaScene(spec, resolution, variant=variant)
    image, seconds = loaded.render_path(spp, max_depth, seed)
    check_finite_image(image, spec.name)
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


REFERENCE_PASS_SPP = 64


def reference_cache_directory():
    """``$SPARSELT_CACHE/references`` (default ``~/.cache/sparselt/references``)."""
    root = os.environ.get("SPARSELT_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "sparselt")
    return os.path.join(root, "references")


def _scene_identity(spec, camera):
    """What determines the scene's content: the built-in name and camera, or the XML file's bytes."""
    identity = {"name": spec.name, "camera": repr(camera)}
    if spec.filename is not None:
        with open(spec.filename, "rb") as handle:
            identity["file_sha256"] = hashlib.sha256(handle.read()).hexdigest()
    return identity


def reference_quantity(kind, max_depth):
    """The image a signal kind integrates to, as depths of Mitsuba's ``path``: ``(depth, subtracted depth)``.

    ``dof`` and ``path`` integrate to ``path`` at ``max_depth``; ``indirect`` to
    ``path`` at ``max_depth`` minus ``path`` at depth 2; ``path-indirect`` to
    depth ``max_depth + 1`` minus depth 2 (see :mod:`sparselt.rendering.layout`).
    """
    if kind in ("dof", "path"):
        return max_depth, None
    if kind == "indirect":
        return max_depth, 2
    if kind == "path-indirect":
        return max_depth + 1, 2
    raise ValueError(f"unknown signal kind {kind!r}")


def cached_reference(loaded, kind, *, spp, max_depth=3, seed=0, progress=True, cache_directory=None):
    """The reference image of a comparison: Mitsuba ``path`` at ``spp``, cached by content.

    Parameters
    ----------
    loaded : MitsubaScene
        The scene with the comparison's camera and resolution (box filter).
    kind : str
        Signal kind; decides the rendered quantity (:func:`reference_quantity`).
    spp : int
        Samples per pixel, rendered in passes of :data:`REFERENCE_PASS_SPP`
        with a progress bar.
    max_depth, seed : int
        Longest path and seed (pass ``i`` uses seed ``seed * 65536 + i``).
    cache_directory : str, optional
        Default :func:`reference_cache_directory`.

    Returns
    -------
    image : ndarray, shape (height, width, 3), float32
    record : dict
        The cache key's contents, ``seconds`` of rendering, ``cached`` (whether
        this call found it in the cache) and ``path`` of the cached image.

    Notes
    -----
    The key hashes the scene (built-in name and camera, or the XML file's
    bytes), resolution, kind, depth, spp, seed and the Mitsuba and Dr.Jit
    versions: a repeated comparison re-renders nothing. Entries are written
    atomically (image first, record last); an entry without its record is
    not used.
    """
    from . import mitsuba_backend

    check_integer("reference spp", spp, 1)
    check_integer("seed", seed, 0, 2**16 - 1)
    depth, subtracted = reference_quantity(kind, max_depth)
    key = {
        "scene": _scene_identity(loaded.spec, loaded.camera),
        "resolution": [loaded.width, loaded.height],
        "kind": kind,
        "max_depth": max_depth,
        "depth": depth,
        "subtracted_depth": subtracted,
        "spp": spp,
        "seed": seed,
        "pass_spp": REFERENCE_PASS_SPP,
        "versions": mitsuba_backend.versions(),
    }
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:24]
    folder = os.path.join(cache_directory or reference_cache_directory(), digest)
    image_path, record_path = os.path.join(folder, "image.npy"), os.path.join(folder, "reference.json")
    if os.path.isfile(record_path) and os.path.isfile(image_path):
        record = read_json(record_path)
        image = np.load(image_path)
        if record.get("key") == key and image.shape == (loaded.height, loaded.width, 3):
            return image, dict(record, cached=True, path=image_path)

    passes = [min(REFERENCE_PASS_SPP, spp - start) for start in range(0, spp, REFERENCE_PASS_SPP)]
    total = np.zeros((loaded.height, loaded.width, 3), dtype=np.float64)
    seconds = 0.0
    bar = progress_bar(progress, total=spp, description=f"reference {loaded.spec.name} {spp} spp", unit="spp")
    try:
        for index, pass_spp in enumerate(passes):
            pass_seed = seed * 65536 + index
            check_wavefront((loaded.width, loaded.height), pass_spp)
            image, elapsed = loaded.render_path(pass_spp, depth, pass_seed)
            total += pass_spp * image.astype(np.float64)
            seconds += elapsed
            if subtracted is not None:
                image, elapsed = loaded.render_path(pass_spp, subtracted, pass_seed)
                total -= pass_spp * image.astype(np.float64)
                seconds += elapsed
            if bar is not None:
                bar.update(pass_spp)
    finally:
        if bar is not None:
            bar.close()
    image = (total / spp).astype(np.float32)
    if not np.all(np.isfinite(image)):
        raise ValueError(f"the reference render of {loaded.spec.name!r} has NaN or infinite pixels; check the scene")
    os.makedirs(folder, exist_ok=True)
    atomic_save_npy(image_path, image)
    mitsuba_backend.write_exr(os.path.join(folder, "image.exr"), image)
    record = {"key": key, "seconds": seconds, "provenance": environment_record()}
    write_json(record_path, record)
    return image, dict(record, cached=False, path=image_path)
