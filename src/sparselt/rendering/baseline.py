"""Plain path tracing with Mitsuba's own ``path`` integrator: the equal-time baseline.

Every equal-time comparison measures against :func:`cached_reference`; ``sparselt render`` is :mod:`sparselt.experiments.render`.
"""

from __future__ import annotations

import dataclasses
import io
import json
import os
import sys

import numpy as np

from ..measurement import progress_bar
from ..provenance import atomic_write_bytes, environment_record, read_json, write_json
from ..cell_statistics import variance_from_sums
from ..checks import check_integer
from ..digest import bytes_digest, digest
from .identity import scene_identity


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
    """``$SPARSELT_CACHE/references`` (default ``~/.cache/sparselt/references``)."""
    root = os.environ.get("SPARSELT_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "sparselt")
    return os.path.join(root, "references")


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
        Longest path and seed (pass ``i`` uses Mitsuba's seed :func:`reference_pass_seed` ``(seed, i)``, disjoint
        from every method seed).
    cache_directory : str, optional
        Default :func:`reference_cache_directory`.

    Returns
    -------
    image : ndarray, shape (height, width, 3), float32
    record : dict
        The cache key's contents, ``seconds`` of rendering, ``cached`` (whether
        this call found it in the cache), ``path`` of the cached image and
        ``variance``: the per-pixel variance of the reference's mean from the
        spread of its passes (NaN with one pass; see :func:`reference_relmse_floor`).

    Notes
    -----
    The key hashes the scene's content identity
    (:func:`~sparselt.rendering.identity.scene_identity`: an XML file with
    every file it references and its ``-D`` parameters, or a built-in scene's
    description and generator code), the resolved camera (lens and focus
    included), resolution, kind, depth, spp, seed and the Mitsuba and Dr.Jit
    versions: a repeated comparison re-renders nothing, and an edited scene
    is rendered again. Entries are written atomically (image first, record
    last, with the image's SHA-256); an entry without its record is not used,
    and an unreadable or garbled one is rendered again and replaced, with a
    note on standard error.
    """
    from ..image_io import write_exr
    from .mitsuba import versions

    check_integer("reference spp", spp, 1, REFERENCE_PASS_SPP * REFERENCE_MAX_PASSES)
    check_integer("reference seed", seed, 0, REFERENCE_SEED_LIMIT - 1)
    depth, subtracted = reference_quantity(kind, max_depth)
    key = {
        "scene": {"name": loaded.spec.name, "identity": scene_identity(loaded.spec)["digest"],
                  "camera": dataclasses.asdict(loaded.camera)},
        "resolution": [loaded.width, loaded.height],
        "kind": kind,
        "max_depth": max_depth,
        "depth": depth,
        "subtracted_depth": subtracted,
        "spp": spp,
        "seed": seed,
        "pass_spp": REFERENCE_PASS_SPP,
        "pass_seeds": "reference_pass_seed",  # not the earlier seed * 65536 + i, which PT's cells could replay
        "per_pass_variance": True,
        "versions": versions(),
    }
    key = json.loads(json.dumps(key))  # as read back from reference.json (tuples become lists)
    key_digest = digest(key)
    folder = os.path.join(cache_directory or reference_cache_directory(), key_digest)
    image_path, record_path = os.path.join(folder, "image.npy"), os.path.join(folder, "reference.json")
    variance_path = os.path.join(folder, "variance.npy")
    if os.path.isfile(record_path) and os.path.isfile(image_path) and os.path.isfile(variance_path):
        try:
            record, image = _read_cache_entry(record_path, image_path)
            variance = _read_variance(record, variance_path, image.shape)
        except (OSError, ValueError, EOFError) as error:
            print(f"sparselt: note: the cached reference {folder!r} is unreadable ({error}); rendering it again",
                  file=sys.stderr)
        else:
            if record.get("key") == key and image.shape == (loaded.height, loaded.width, 3):
                return image, dict(record, cached=True, path=image_path, variance=variance)

    passes = [min(REFERENCE_PASS_SPP, spp - start) for start in range(0, spp, REFERENCE_PASS_SPP)]
    total = np.zeros((loaded.height, loaded.width, 3), dtype=np.float64)
    squares = np.zeros_like(total)
    seconds = 0.0
    bar = progress_bar(progress, total=spp, description=f"reference {loaded.spec.name} {spp} spp", unit="spp")
    try:
        for index, pass_spp in enumerate(passes):
            pass_seed = reference_pass_seed(seed, index)
            check_wavefront((loaded.width, loaded.height), pass_spp)
            image, elapsed = loaded.render_path(pass_spp, depth, pass_seed)
            pass_image = image.astype(np.float64)
            seconds += elapsed
            if subtracted is not None:
                image, elapsed = loaded.render_path(pass_spp, subtracted, pass_seed)
                pass_image -= image.astype(np.float64)
                seconds += elapsed
            total += pass_spp * pass_image
            squares += pass_spp * pass_image * pass_image
            if bar is not None:
                bar.update(pass_spp)
    finally:
        if bar is not None:
            bar.close()
    image = (total / spp).astype(np.float32)
    # The variance of the reference's mean per pixel and channel, from the spread of its passes: the per-sample
    # variance estimated as sum_i m_i (x_i - mean)^2 / (passes - 1), divided by spp. NaN with a single pass.
    if len(passes) > 1:
        variance = (variance_from_sums(total, squares, spp, denominator=len(passes) - 1) / spp).astype(np.float32)
    else:
        variance = np.full(image.shape, np.nan, dtype=np.float32)
    if not np.all(np.isfinite(image)):
        raise ValueError(f"the reference render of {loaded.spec.name!r} has NaN or infinite pixels; check the scene")
    os.makedirs(folder, exist_ok=True)
    if os.path.lexists(record_path):
        os.remove(record_path)  # the entry is invalid until its new record is written
    buffer = io.BytesIO()
    np.save(buffer, image)
    atomic_write_bytes(image_path, buffer.getvalue())
    write_exr(os.path.join(folder, "image.exr"), image)
    variance_buffer = io.BytesIO()
    np.save(variance_buffer, variance)
    atomic_write_bytes(variance_path, variance_buffer.getvalue())
    record = {"key": key, "image_sha256": bytes_digest(buffer.getvalue()),
              "variance_sha256": bytes_digest(variance_buffer.getvalue()), "seconds": seconds,
              "provenance": environment_record()}
    write_json(record_path, record)
    return image, dict(record, cached=False, path=image_path, variance=variance)


def _read_variance(record, variance_path, shape):
    """The cached per-pixel variance of a reference's mean; ValueError if it does not match its record."""
    with open(variance_path, "rb") as handle:
        data = handle.read()
    if bytes_digest(data) != record.get("variance_sha256"):
        raise ValueError(f"{variance_path!r} does not match the SHA-256 its record holds")
    variance = np.load(io.BytesIO(data), allow_pickle=False)
    if variance.shape != shape:
        raise ValueError(f"{variance_path!r} holds an array of shape {variance.shape}, not {shape}")
    return variance


def reference_relmse_floor(reference, variance, *, epsilon):
    """The reference's own contribution to every relMSE against it: ``mean(var / (reference^2 + epsilon))``.

    An image ``I`` compared with a noisy reference ``R = T + e`` (``e`` of
    variance ``v``, independent of ``I``) has ``E[(I - R)^2] = E[(I - T)^2] + v``:
    the reference adds ``v / (R^2 + epsilon)`` per pixel and channel to relMSE
    whatever the image. NaN when the variance is unknown (one pass).
    """
    reference = np.asarray(reference, dtype=np.float64)
    return float(np.mean(np.asarray(variance, dtype=np.float64) / (reference * reference + epsilon)))


def _read_cache_entry(record_path, image_path):
    """A reference cache entry's record and image; ValueError if either is garbled (the image is checked
    against the SHA-256 its record holds)."""
    record = read_json(record_path)
    if not isinstance(record, dict):
        raise ValueError(f"{record_path!r} does not hold a record")
    with open(image_path, "rb") as handle:
        data = handle.read()
    expected = record.get("image_sha256")
    if expected is not None and bytes_digest(data) != expected:
        raise ValueError(f"{image_path!r} does not match the SHA-256 its record holds")
    image = np.load(io.BytesIO(data), allow_pickle=False)
    if image.dtype != np.float32 or image.ndim != 3:
        raise ValueError(f"{image_path!r} holds a {image.dtype} array of shape {image.shape}, not a float32 image")
    return record, image
