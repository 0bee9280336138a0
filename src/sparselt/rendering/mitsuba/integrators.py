"""Mitsuba's own integrators on a loaded scene: ``path`` (the baseline and the reference) and ``aov`` (features).

Both launch through :func:`~sparselt.rendering.mitsuba.launch.launch`, so
their seeds are folded like every estimator's.
"""

from __future__ import annotations

import time

import numpy as np

from .launch import launch
from .runtime import modules


def render_path(scene, spp, max_depth, seed=0):
    """Render with Mitsuba's own ``path`` integrator (no Russian roulette; the scene's emitter visibility).

    Parameters
    ----------
    scene : MitsubaScene
    spp : int
        Samples per pixel.
    max_depth : int
        Mitsuba's ``max_depth``.
    seed : int, optional
        Any non-negative integer (:func:`~sparselt.rendering.mitsuba.launch.fold_seed`).

    Returns
    -------
    image : ndarray, shape (height, width, 3), float32
    seconds : float
        Wall time of the render, synchronised with ``dr.sync_thread``.
    """
    def work(folded_seed):
        mi, dr = modules()
        integrator = mi.load_dict({"type": "path", "max_depth": int(max_depth), "rr_depth": 1 << 30,
                                   "hide_emitters": bool(scene.spec.hide_emitters)})
        dr.sync_thread()
        start = time.perf_counter()
        image = mi.render(scene.scene, sensor=scene.sensor, integrator=integrator, spp=int(spp), seed=folded_seed)
        array = np.array(image, dtype=np.float32)
        dr.sync_thread()
        return array, time.perf_counter() - start

    return launch(work, seed, path_samples=scene.width * scene.height * int(spp))


def render_aovs(scene, spp, seed=0):
    """Albedo, shading normal and depth from Mitsuba's ``aov`` integrator (the denoisers' feature buffers).

    Same camera, film and box filter as :func:`render_path`; ``spp``
    samples per pixel, so the buffers are anti-aliased and, for a thin
    lens, blurred by the aperture like the image.

    Returns
    -------
    buffers : dict
        ``albedo`` (height, width, 3), ``normal`` (height, width, 3, world
        space, not renormalised after averaging), ``depth`` (height, width):
        float32.
    seconds : float
        Wall time, synchronised with ``dr.sync_thread``.
    """
    def work(folded_seed):
        mi, dr = modules()
        integrator = mi.load_dict({"type": "aov", "aovs": "albedo:albedo,normal:sh_normal,depth:depth"})
        dr.sync_thread()
        start = time.perf_counter()
        image = mi.render(scene.scene, sensor=scene.sensor, integrator=integrator, spp=int(spp), seed=folded_seed)
        array = np.array(image, dtype=np.float32)
        dr.sync_thread()
        seconds = time.perf_counter() - start
        channels = array.shape[-1]
        if channels < 7:
            raise RuntimeError(f"Mitsuba's aov integrator returned {channels} channels, expected albedo, normal and "
                               "depth (7)")
        buffers = {"albedo": array[..., -7:-4], "normal": array[..., -4:-1], "depth": array[..., -1]}
        return buffers, seconds

    return launch(work, seed, path_samples=0, feature_samples=scene.width * scene.height * int(spp))
