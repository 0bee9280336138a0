"""The comparison reference: Mitsuba's own ``path`` integrator in independent 64-spp passes, cached per pass.

Every equal-time comparison measures against :func:`cached_reference`
(thesis 8.1.1): the mean of ``ceil(spp / 64)`` passes, each with its own seed
(:func:`reference_pass_seed`, disjoint from every method seed), and the
per-pixel variance of that mean from the passes' spread (Jung et al. 2020),
whose share of every relMSE against it is :func:`reference_relmse_floor`.
Each pass is cached as its own verified file
(:mod:`sparselt.rendering.reference_passes`), so a longer reference renders
only the passes it lacks, a killed run resumes, a deadline stops at the
passes that exist, and the passes may be rendered on a Dask cluster with the
same bytes. :func:`reference_spp_for_floor` sizes a reference for a target
floor. ``sparselt render`` is :mod:`sparselt.experiments.render`.
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
import numbers
import os
import sys
import time

import numpy as np

from ..cell_statistics import variance_from_sums
from ..checks import check_integer, check_positive_finite
from ..digest import bytes_digest, digest, file_digest
from ..measurement import progress_bar
from ..provenance import atomic_write_bytes, environment_record, read_json, write_json
from ..storage.cache import cache_directory, cache_errors, usable_cache_directory
from .identity import scene_identity
from .reference_passes import PassJob, read_pass, render_passes, write_pass

MAXIMUM_WAVEFRONT = 2**32 - 1


def check_wavefront(resolution, spp):
    """Mitsuba renders pixels x spp samples in one wavefront, counted in 32 bits: refuse more, naming the largest
    resolution of the same shape that fits at ``spp`` (and the largest spp that fits at ``resolution``, if any)."""
    width, height, spp = int(resolution[0]), int(resolution[1]), int(spp)
    samples = width * height * spp
    if samples <= MAXIMUM_WAVEFRONT:
        return
    if spp > MAXIMUM_WAVEFRONT:
        raise ValueError(f"{spp} spp are more samples than Mitsuba counts in one pass even for one pixel (at most "
                         f"{MAXIMUM_WAVEFRONT}, in 32 bits): render several passes with different seeds and average "
                         "them")
    fitting_width, fitting_height = largest_resolution(width, height, spp)
    largest_spp = MAXIMUM_WAVEFRONT // (width * height)
    message = (f"{width}x{height} pixels at {spp} spp are {samples:.3g} samples in one pass; Mitsuba counts them in "
               f"32 bits (at most {MAXIMUM_WAVEFRONT}): the largest resolution of this shape that fits in one pass at "
               f"{spp} spp is {fitting_width}x{fitting_height}")
    if largest_spp >= 1:
        message += (f", and at {width}x{height} at most {largest_spp} spp fit (render several passes with different "
                    "seeds and average them for more)")
    raise ValueError(message)


def largest_resolution(width, height, spp):
    """The largest ``(width', height')`` of the aspect ratio of ``width x height`` whose ``width' * height' * spp``
    samples fit in one pass (:data:`MAXIMUM_WAVEFRONT`); at least 1x1."""
    scale = math.sqrt(MAXIMUM_WAVEFRONT / (width * height * spp))
    fitting_width, fitting_height = max(1, int(width * scale)), max(1, int(height * scale))
    while fitting_width * fitting_height * spp > MAXIMUM_WAVEFRONT:
        if fitting_width > 1 and (fitting_height == 1 or fitting_width * height >= fitting_height * width):
            fitting_width -= 1
        elif fitting_height > 1:
            fitting_height -= 1
        else:
            break
    return fitting_width, fitting_height


def check_finite_image(image, name):
    """Refuse a render with NaN or infinite pixels instead of writing it."""
    bad = int(np.count_nonzero(~np.isfinite(image)))
    if bad:
        raise ValueError(f"the render of {name!r} has {bad} NaN or infinite pixel values; nothing was written. "
                         "The scene (an emitter of huge radiance, a degenerate mesh) produces them")


REFERENCE_PASS_SPP = 64

#: Reference passes draw their Mitsuba seeds from ``[REFERENCE_SEED_BASE, 2**32)`` and the comparison's methods
#: theirs from below :data:`METHOD_SEED_LIMIT` (a guided method's pilot, ``seed ^ 0x5A5A5A5A``, included): a
#: path-traced cell at the reference's pass size would otherwise replay one of its passes exactly and look
#: better than it is (PT at 64 spp, seeds 1-3, against a reference of seed 0 did: relMSE x spp 0.65 against
#: 0.94-1.08 at its neighbouring rungs).
REFERENCE_SEED_BASE = 0xC0000000
METHOD_SEED_LIMIT = 2**30
REFERENCE_SEED_LIMIT = 2**14
REFERENCE_MAX_PASSES = 2**16


def reference_pass_seed(seed, index):
    """Mitsuba's seed for pass ``index`` of a reference of ``seed``; disjoint from every method seed.

    ``REFERENCE_SEED_BASE + seed * REFERENCE_MAX_PASSES + index``, for ``seed`` below :data:`REFERENCE_SEED_LIMIT` and ``index``
    below :data:`REFERENCE_MAX_PASSES`: always in ``[REFERENCE_SEED_BASE, 2**32)``, above any seed a comparison
    gives a method (``< METHOD_SEED_LIMIT``, with the guided methods' ``seed ^ 0x5A5A5A5A`` below ``2**31``).
    """
    check_integer("reference seed", seed, 0, REFERENCE_SEED_LIMIT - 1)
    check_integer("reference pass", index, 0, REFERENCE_MAX_PASSES - 1)
    return REFERENCE_SEED_BASE + seed * REFERENCE_MAX_PASSES + index


def reference_cache_directory():
    """``$SPARSELT_CACHE/references`` (default ``~/.cache/sparselt/references``; :mod:`sparselt.storage.cache`)."""
    return cache_directory("references")


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


#: Bumped when the layout of a cache entry changes, so that older entries are simply not used. 2: one verified
#: file per pass (``passes/``), no ``spp`` in the key, the Mitsuba variant in it.
REFERENCE_CACHE_FORMAT = 2


def reference_key(loaded, kind, *, max_depth, seed):
    """What identifies a reference's passes: scene content, camera, resolution, quantity, seed, renderer.

    The key holds no spp: a reference of any length is a prefix of the same
    passes (see :func:`cached_reference`).
    """
    from .mitsuba import versions
    from .mitsuba.runtime import modules

    depth, subtracted = reference_quantity(kind, max_depth)
    key = {
        "format": REFERENCE_CACHE_FORMAT,
        "scene": {"name": loaded.spec.name, "identity": scene_identity(loaded.spec)["digest"],
                  "camera": dataclasses.asdict(loaded.camera)},
        "resolution": [loaded.width, loaded.height],
        "kind": kind,
        "max_depth": max_depth,
        "depth": depth,
        "subtracted_depth": subtracted,
        "seed": seed,
        "pass_spp": REFERENCE_PASS_SPP,
        "pass_seeds": "reference_pass_seed",  # not the earlier seed * 65536 + i, which PT's cells could replay
        "variant": modules()[0].variant(),
        "versions": versions(),
    }
    return json.loads(json.dumps(key))  # as read back from reference.json (tuples become lists)


def _check_cluster_setup(setup, loaded, key):
    """The setup a cluster's workers load must be the scene ``loaded`` is: same content, variant."""
    from .setup import SceneSetup

    if not isinstance(setup, SceneSetup):
        raise TypeError(f"setup must be a SceneSetup (the workers load the scene from it), got "
                        f"{type(setup).__name__}")
    if setup.scene_identity["digest"] != key["scene"]["identity"] or setup.variant != key["variant"]:
        raise ValueError(f"setup (scene {setup.scene!r}, variant {setup.variant!r}) is not the loaded scene "
                         f"{loaded.spec.name!r} (variant {key['variant']!r}): give the SceneSetup the scene was "
                         "loaded from")


def cached_reference(loaded, kind, *, spp, max_depth=3, seed=0, progress=True, cache_directory=None,
                     scheduler=None, setup=None, deadline=None, epsilon=0.01):
    """The reference image of a comparison: the mean of Mitsuba ``path`` passes, each cached by content.

    Parameters
    ----------
    loaded : MitsubaScene
        The scene with the comparison's camera and resolution (box filter).
    kind : str
        Signal kind; decides the rendered quantity (:func:`reference_quantity`).
    spp : int
        Samples per pixel asked for, rounded up to whole passes of
        :data:`REFERENCE_PASS_SPP` (``ceil(spp / 64)`` passes).
    max_depth, seed : int
        Longest path and seed (pass ``i`` uses Mitsuba's seed :func:`reference_pass_seed` ``(seed, i)``, disjoint
        from every method seed).
    progress : bool
        A progress bar over the passes.
    cache_directory : str, optional
        Default :func:`reference_cache_directory`.
    scheduler : str, optional
        Render the missing passes on this Dask cluster (``tcp://host:port``),
        each written to the cache as it lands. Needs ``setup``.
    setup : SceneSetup, optional
        The picklable setup ``loaded`` was loaded from; each worker loads it
        at ``loaded``'s resolution, once per worker process.
    deadline : float, optional
        A :func:`time.monotonic` time: once it has passed no new pass is
        started (beyond the first two, so that a floor exists), and the
        reference is the passes that exist, contiguous from pass 0.
    epsilon : float
        The relMSE epsilon of ``record['relmse_floor']`` (:func:`reference_relmse_floor`).

    Returns
    -------
    image : ndarray, shape (height, width, 3), float32
    record : dict
        ``key`` (:func:`reference_key`), ``spp`` (64 x the passes used),
        ``requested_spp``, ``requested_passes``, ``passes`` (used),
        ``complete`` (every requested pass used), ``deadline_reached``,
        ``pass_spp``, ``seconds`` (the used passes' render seconds, whenever
        they were rendered), ``seconds_this_run`` (the render seconds of the
        passes this call rendered), ``passes_rendered`` (their number),
        ``machines`` (sorted hosts that rendered the used passes),
        ``variance`` (float32, the per-pixel variance of the mean from the
        passes' spread; NaN with one pass), ``relmse_floor`` (None when
        unknown), ``cached`` (no pass was rendered by this call), ``folder``
        and ``path`` (``image.npy``, the image as returned).

    Raises
    ------
    ValueError
        A bad ``spp``, ``seed``, ``kind``, ``deadline`` or ``epsilon``; more
        samples per pass than Mitsuba can count (:func:`check_wavefront`);
        ``scheduler`` without ``setup``, or a ``setup`` of another scene; a
        pass with NaN or infinite pixels (nothing of it is written).
    TypeError
        A value of the wrong type.

    Notes
    -----
    The image is the mean of passes ``0 .. P-1`` accumulated in float64 in
    pass-index order, so its bytes do not depend on where or in which order
    the passes were rendered (Mitsuba's ``path`` is bit-deterministic for a
    seed across processes and thread counts). With ``m = 64`` spp per pass
    and pass means ``x_i`` the variance of the mean is
    ``sum_i m (x_i - mean)^2 / (P - 1) / (m P)`` per pixel and channel
    (Jung et al. 2020; thesis 8.1.1).

    The key hashes the scene's content identity
    (:func:`~sparselt.rendering.identity.scene_identity`: an XML file with
    every file it references and its ``-D`` parameters, or a built-in scene's
    description and generator code), the resolved camera (lens and focus
    included), resolution, kind, depth, seed, variant and the Mitsuba and
    Dr.Jit versions, but not the spp: a longer reference continues a shorter
    one. Each pass is ``passes/{i:05d}.npy`` with its record
    ``passes/{i:05d}.json`` (SHA-256, seed, seconds, machine) written after
    it, both atomically; a pass without its record is missing, and one that
    does not match its record is rendered again with a note on standard
    error. ``image.npy``, ``image.exr``, ``variance.npy`` and
    ``reference.json`` are written beside them for convenience; the passes
    are the truth.
    """
    check_integer("reference spp", spp, 1, REFERENCE_PASS_SPP * REFERENCE_MAX_PASSES)
    check_integer("reference seed", seed, 0, REFERENCE_SEED_LIMIT - 1)
    epsilon = check_positive_finite(epsilon, "epsilon", hint="the relMSE epsilon of the reference's floor")
    if deadline is not None:
        if isinstance(deadline, bool) or not isinstance(deadline, numbers.Real):
            raise TypeError(f"deadline must be None or a time.monotonic() value, got {deadline!r}")
        if not math.isfinite(deadline):
            raise ValueError(f"deadline must be None or a finite time.monotonic() value, got {deadline!r}")
    if scheduler is not None and setup is None:
        raise ValueError(f"scheduler {scheduler!r} needs setup, the SceneSetup the scene was loaded from: the "
                         "workers cannot receive a Mitsuba scene and load it from the setup")
    depth, subtracted = reference_quantity(kind, max_depth)
    check_wavefront((loaded.width, loaded.height), REFERENCE_PASS_SPP)
    key = reference_key(loaded, kind, max_depth=max_depth, seed=seed)
    if setup is not None:
        _check_cluster_setup(setup, loaded, key)
    folder = os.path.join(usable_cache_directory(cache_directory or reference_cache_directory()), digest(key))
    shape = (loaded.height, loaded.width, 3)
    requested = -(-spp // REFERENCE_PASS_SPP)
    minimum = min(2, requested)
    seeds = [reference_pass_seed(seed, index) for index in range(requested)]

    records = {}
    for index in range(requested):
        found = read_pass(folder, index, shape=shape, seed=seeds[index], spp=REFERENCE_PASS_SPP)
        if found is not None:
            records[index] = found[1]

    def contiguous():
        count = 0
        while count in records:
            count += 1
        return count

    def out_of_time():
        return deadline is not None and time.monotonic() >= deadline

    def should_stop():
        return out_of_time() and contiguous() >= minimum

    missing = [index for index in range(requested) if index not in records]
    if out_of_time():
        missing = [index for index in missing if index < minimum]
    rendered = []
    bar = progress_bar(progress and bool(missing), total=requested * REFERENCE_PASS_SPP, unit="spp",
                       description=f"reference {loaded.spec.name} {requested * REFERENCE_PASS_SPP} spp",
                       initial=(requested - len(missing)) * REFERENCE_PASS_SPP)

    def land(index, image, seconds, machine):
        if not np.all(np.isfinite(image)):
            raise ValueError(f"the reference render of {loaded.spec.name!r} has NaN or infinite pixels in pass "
                             f"{index} (seed {seeds[index]}); check the scene. Finished passes are kept")
        with cache_errors(folder, "write"):
            records[index] = write_pass(folder, index, image, seed=seeds[index], spp=REFERENCE_PASS_SPP,
                                        seconds=seconds, machine=machine)
        rendered.append(index)
        if bar is not None:
            bar.update(REFERENCE_PASS_SPP)

    def make_job(index, concurrency=None, scene_key=None):
        return PassJob(setup=setup, resolution=(loaded.width, loaded.height), scene_key=scene_key, index=index,
                       pass_seed=seeds[index], pass_spp=REFERENCE_PASS_SPP, depth=depth, subtracted_depth=subtracted,
                       concurrency=concurrency)

    try:
        if scheduler is None or not missing:
            render_passes(missing, scene=loaded, make_job=make_job, land=land, should_stop=should_stop)
        else:
            from ..distributed import dask_client, tasks_per_host

            scene_key = f"{setup.digest()}-{loaded.width}x{loaded.height}"
            with dask_client(scheduler=scheduler, say=lambda text: print(text, file=sys.stderr) if progress else None) \
                    as client:
                concurrency = tasks_per_host(client)
                render_passes(missing, scene=loaded, client=client, land=land, should_stop=should_stop,
                              make_job=lambda index: make_job(index, concurrency, scene_key))
    finally:
        if bar is not None:
            bar.close()

    used = min(contiguous(), requested)
    image, variance = _mean_of_passes(folder, used, shape, seeds)
    if not np.all(np.isfinite(image)):
        raise ValueError(f"the reference render of {loaded.spec.name!r} has NaN or infinite pixels; check the scene")
    used_records = [records[index] for index in range(used)]
    floor = reference_relmse_floor(image, variance, epsilon=epsilon)
    record = {
        "key": key,
        "spp": used * REFERENCE_PASS_SPP,
        "requested_spp": spp,
        "requested_passes": requested,
        "passes": used,
        "complete": used == requested,
        "deadline_reached": used < requested,
        "pass_spp": REFERENCE_PASS_SPP,
        "seconds": float(sum(entry["seconds"] for entry in used_records)),
        "seconds_this_run": float(sum(records[index]["seconds"] for index in rendered)),
        "passes_rendered": len(rendered),
        "machines": sorted({entry["machine"] for entry in used_records}),
        "relmse_floor": None if math.isnan(floor) else floor,
    }
    with cache_errors(folder, "write"):
        path = _write_outputs(folder, image, variance,
                              dict(record, pass_sha256=[entry["sha256"] for entry in used_records]))
    return image, dict(record, variance=variance, cached=not rendered, folder=folder, path=path)


def _mean_of_passes(folder, passes, shape, seeds):
    """The mean of passes ``0 .. passes-1`` (float32) and the variance of that mean (float32, NaN for one pass),
    accumulated in float64 in pass-index order from the verified files."""
    total = np.zeros(shape, dtype=np.float64)
    squares = np.zeros_like(total)
    for index in range(passes):
        found = read_pass(folder, index, shape=shape, seed=seeds[index], spp=REFERENCE_PASS_SPP)
        if found is None:
            raise ValueError(f"reference pass {index} in {folder!r} changed while the reference was being made "
                             "(another process?); run again")
        total += REFERENCE_PASS_SPP * found[0]
        squares += REFERENCE_PASS_SPP * found[0] * found[0]
    spp = passes * REFERENCE_PASS_SPP
    image = (total / spp).astype(np.float32)
    # The variance of the reference's mean per pixel and channel, from the spread of its passes: the per-sample
    # variance estimated as sum_i m (x_i - mean)^2 / (passes - 1), divided by spp. NaN with a single pass.
    if passes > 1:
        variance = (variance_from_sums(total, squares, spp, denominator=passes - 1) / spp).astype(np.float32)
    else:
        variance = np.full(shape, np.nan, dtype=np.float32)
    return image, variance


def _write_outputs(folder, image, variance, summary):
    """``image.npy``, ``image.exr``, ``variance.npy`` and ``reference.json`` for the passes used, atomically,
    unless the folder already holds exactly these; return the image's path."""
    from ..image_io import write_exr

    image_bytes, variance_bytes = io.BytesIO(), io.BytesIO()
    np.save(image_bytes, image)
    np.save(variance_bytes, variance)
    summary = dict(summary, image_sha256=bytes_digest(image_bytes.getvalue()),
                   variance_sha256=bytes_digest(variance_bytes.getvalue()))
    image_path, record_path = os.path.join(folder, "image.npy"), os.path.join(folder, "reference.json")
    variance_path = os.path.join(folder, "variance.npy")
    try:
        written = read_json(record_path)
        same = all(written.get(name) == summary[name] for name in ("key", "pass_sha256", "image_sha256",
                                                                   "variance_sha256"))
        same = same and all(file_digest(path) == summary[name] for path, name in (
            (image_path, "image_sha256"), (variance_path, "variance_sha256")))
    except (OSError, ValueError, AttributeError):
        same = False
    if not same:
        os.makedirs(folder, exist_ok=True)
        if os.path.lexists(record_path):
            os.remove(record_path)  # the outputs are stale until their new summary is written
        atomic_write_bytes(image_path, image_bytes.getvalue())
        write_exr(os.path.join(folder, "image.exr"), image)
        atomic_write_bytes(variance_path, variance_bytes.getvalue())
        write_json(record_path, dict(summary, provenance=environment_record()))
    return image_path


def reference_relmse_floor(reference, variance, *, epsilon):
    """The reference's own contribution to every relMSE against it: ``mean(var / (reference^2 + epsilon))``.

    An image ``I`` compared with a noisy reference ``R = T + e`` (``e`` of
    variance ``v``, independent of ``I``) has ``E[(I - R)^2] = E[(I - T)^2] + v``:
    the reference adds ``v / (R^2 + epsilon)`` per pixel and channel to relMSE
    whatever the image. NaN when the variance is unknown (one pass).
    """
    reference = np.asarray(reference, dtype=np.float64)
    return float(np.mean(np.asarray(variance, dtype=np.float64) / (reference * reference + epsilon)))


def reference_spp_for_floor(floor, spp, target_floor):
    """The reference spp whose relMSE floor would be at most ``target_floor``: a multiple of 64, at least ``spp``.

    Parameters
    ----------
    floor : float
        The floor (:func:`reference_relmse_floor`) measured at ``spp``; positive.
    spp : int
        The spp that floor was measured at.
    target_floor : float
        The floor wanted; positive.

    Returns
    -------
    int
        ``ceil(spp * floor / target_floor / 64) * 64``, and at least ``spp``
        rounded up to whole passes.

    Raises
    ------
    ValueError, TypeError
        A floor or target that is not positive and finite, an spp below 1.

    Notes
    -----
    The floor is the mean of ``variance / (reference^2 + epsilon)`` and the
    variance is that of a mean of independent passes, so it falls as
    ``1 / spp``: ``floor(s) = floor * spp / s`` (Jung et al. 2020; thesis
    8.1.1). The estimate is itself noisy (the floor of a few passes is a
    rough measure); sizing again from the longer reference's floor converges.
    """
    floor = check_positive_finite(floor, "floor", hint="the reference's relMSE floor at spp")
    target_floor = check_positive_finite(target_floor, "target_floor", hint="the relMSE floor wanted")
    spp = check_integer("spp", spp, 1)
    passes = max(math.ceil(spp * floor / target_floor / REFERENCE_PASS_SPP - 1e-9), -(-spp // REFERENCE_PASS_SPP))
    return int(passes * REFERENCE_PASS_SPP)
