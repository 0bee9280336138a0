"""Acquire primary-sample-space signals: chunked, resumable, reproducible.

:func:`acquire_signal` evaluates every cell of a grid over the axes of a
signal kind as the mean of ``spp`` jittered samples of ``f(S(u))`` (thesis
3.2.2 and 5.3: "each point in these signals was estimated as the average of 64
randomly jittered samples"), in chunks that fit in memory, with a progress bar,
writing the signal folder described in :mod:`sparselt.signal`.
"""

from __future__ import annotations

import dataclasses
import math
import os
import shutil
import time
from dataclasses import dataclass

import numpy as np

from ..checks import check_integer  # noqa: F401  (re-exported: callers import it from here)
from ..measurement import available_memory, progress_bar
from ..provenance import environment_record, format_bytes, read_json, write_json
from ..signal import (
    DATA_FILE,
    FORMAT_VERSION,
    META_FILE,
    PARTIAL_DATA_FILE,
    PROGRESS_FILE,
    Signal,
    load_signal,
    signal_status,
)
from .layout import KINDS, path_layout
from .scenes import SceneSpec, get_scene

DEFAULT_SPP = 64
DEFAULT_MAX_DEPTH = 3
LANES_PER_CHUNK = 1 << 22
MAXIMUM_SPP = 1 << 16
NONFINITE_POLICIES = ("error", "zero")

THESIS_PRESETS = {
    # thesis 5.3: 100x100 image plane, 4 in each of the 8 directional dimensions (6.6e8 cells)
    "path": (100, 100) + (4,) * 8,
    "path-indirect": (100, 100) + (4,) * 8,
    # thesis 7.1.2 and 7.2.1: 250x250 image plane, 16x16 lens or secondary direction
    "dof": (250, 250, 16, 16),
    "indirect": (250, 250, 16, 16),
}


class NonFiniteSampleError(RuntimeError):
    """The renderer returned NaN or infinite path contributions."""


@dataclass(frozen=True)
class AcquisitionConfig:
    """Everything that determines a signal; recorded in its ``meta.json``.

    Attributes
    ----------
    scene : str
        Built-in scene name or path of a Mitsuba 3 XML file.
    kind : str
        One of 'path', 'path-indirect', 'dof', 'indirect'.
    shape : tuple of int
        Resolution of each axis of the kind (image plane first).
    spp : int
        Jittered samples averaged per cell (thesis: 64).
    seed : int
        Seed in ``[0, 2**32)``; same seed, same signal.
    max_depth : int
        Longest path, Mitsuba's convention (thesis: 3).
    aperture, focus_distance : float or None
        Thin-lens override of the scene's camera.
    variant : str
        Mitsuba variant.
    nonfinite : {'error', 'zero'}
        What to do when a sample is NaN or infinite: stop with an error
        (default), or count it, record the count and use 0 in its place.
    """

    scene: str
    kind: str
    shape: tuple
    spp: int = DEFAULT_SPP
    seed: int = 0
    max_depth: int = DEFAULT_MAX_DEPTH
    aperture: float | None = None
    focus_distance: float | None = None
    variant: str = "llvm_ad_rgb"
    nonfinite: str = "error"

    def record(self):
        record = dataclasses.asdict(self)
        record["shape"] = list(self.shape)
        return record


def validate_config(config):
    """Check a configuration without loading the renderer.

    Raises
    ------
    ValueError
        The first problem found, naming the bad value and what is allowed.
    """
    if config.kind not in KINDS:
        raise ValueError(f"unknown signal kind {config.kind!r}; choose one of {', '.join(KINDS)}")
    check_integer("spp", config.spp, 1, MAXIMUM_SPP - 1)
    check_integer("seed", config.seed, 0, 2**32 - 1)
    check_integer("max_depth", config.max_depth, 1)
    if config.nonfinite not in NONFINITE_POLICIES:
        raise ValueError(f"nonfinite must be one of {NONFINITE_POLICIES}, got {config.nonfinite!r}")
    if len(config.shape) < 2:
        raise ValueError(f"shape {tuple(config.shape)} needs at least the two image-plane axes")
    for size in config.shape:
        check_integer("every axis resolution", size, 1)
    cells = math.prod(config.shape)
    if cells >= 2**32:
        raise ValueError(f"shape {tuple(config.shape)} has {cells} cells; at most 2**32 - 1 are supported")


def _check_shape_matches(config, layout):
    if len(config.shape) != len(layout.axes):
        raise ValueError(
            f"shape {tuple(config.shape)} has {len(config.shape)} axes but kind {config.kind!r} at max depth "
            f"{config.max_depth} has {len(layout.axes)}: {', '.join(layout.axes)}"
        )


def signal_bytes(shape):
    """Bytes of a float32 RGB signal of this grid shape."""
    return math.prod(shape) * 3 * 4


def acquire_signal(config, path=None, *, overwrite=False, progress=True, chunk_cells=None, scene_spec=None):
    """Sample a signal, in memory or into a resumable signal folder.

    Parameters
    ----------
    config : AcquisitionConfig
        What to sample.
    path : str, optional
        Signal folder. Without it the signal is kept in memory, which is
        refused when it would take more than half of the available RAM.
    overwrite : bool, optional
        Replace an existing complete signal, or an incomplete one of a
        different configuration. An incomplete signal of the same
        configuration is always resumed.
    progress : bool, optional
        Show a progress bar (samples, rate, ETA) on standard error.
    chunk_cells : int, optional
        Cells per chunk (default: about 4M samples per chunk). The data do not
        depend on it; a resumed run keeps the chunking it started with.
    scene_spec : SceneSpec, optional
        Use this scene description instead of resolving ``config.scene``.

    Returns
    -------
    Signal

    Raises
    ------
    ValueError
        Invalid configuration, shape not matching the kind, output folder
        in the way, or not enough memory or disk.
    NonFiniteSampleError
        NaN or infinite samples with ``nonfinite='error'``; finished chunks
        are kept and the run can be resumed.
    """
    from . import mitsuba_backend

    validate_config(config)
    spec = scene_spec if scene_spec is not None else get_scene(config.scene)
    if not isinstance(spec, SceneSpec):
        raise TypeError(f"scene_spec must be a SceneSpec, got {type(spec).__name__}")
    spec = spec.with_lens(config.aperture, config.focus_distance)
    if chunk_cells is not None:
        check_integer("chunk_cells", chunk_cells, 1)
    # Cheap checks first; the layout of a scene file needs its camera, hence the renderer (checked below).
    if spec.camera is not None:
        layout = path_layout(config.kind, config.max_depth, thin_lens=spec.resolved_camera().thin_lens,
                             hide_emitters=spec.hide_emitters)
        _check_shape_matches(config, layout)
    nbytes = signal_bytes(config.shape)
    if path is None:
        available = available_memory()
        if nbytes > available // 2:
            raise ValueError(
                f"a signal of shape {tuple(config.shape)} takes {format_bytes(nbytes)}, more than half of the "
                f"{format_bytes(available)} of available memory; give an output path to store it on disk"
            )
    else:
        path = os.fspath(path)
        resumable = _prepare_folder(path, config, overwrite=overwrite)
        if resumable is None:
            free = shutil.disk_usage(os.path.dirname(os.path.abspath(path)) or ".").free
            if nbytes > free:
                raise ValueError(f"the signal takes {format_bytes(nbytes)} but only {format_bytes(free)} of disk is free "
                                 f"at {path!r}")

    scene = mitsuba_backend.MitsubaScene(spec, config.shape[:2], variant=config.variant)
    layout = path_layout(config.kind, config.max_depth, thin_lens=scene.camera.thin_lens,
                         hide_emitters=spec.hide_emitters)
    _check_shape_matches(config, layout)

    cells = math.prod(config.shape)
    if path is None:
        data = np.empty((cells, 3), dtype=np.float32)
        state = _new_state(config, chunk_cells)
    else:
        data, state = _open_folder(path, config, spec, scene, layout, chunk_cells, resumable)
    chunk = state["chunk_cells"]
    chunk_count = -(-cells // chunk)
    finished = set(state["finished_chunks"])

    bar = _progress_bar(progress, cells * config.spp, len(finished), chunk, cells, config)
    start_time = time.perf_counter()
    try:
        for index in range(chunk_count):
            if index in finished:
                continue
            first = index * chunk
            count = min(chunk, cells - first)
            means, nonfinite = scene.sample_cells(layout, config.shape, first, count, config.spp, config.seed)
            overflow = ~np.all(np.isfinite(means), axis=1)  # finite samples whose float32 sum overflowed
            if overflow.any():
                cell = first + int(np.flatnonzero(overflow)[0])
                if config.nonfinite == "error":
                    raise NonFiniteSampleError(
                        f"{int(overflow.sum())} cell means overflow float32 in cells {first}..{first + count - 1} "
                        f"(first at cell {cell}): the scene's radiance is too large to store (float32 holds up to "
                        f"3.4e38); scale the emitters down, or rerun with --nonfinite zero to store 0 in those cells. "
                        f"{len(finished)} finished chunks are kept."
                    )
                means[overflow] = 0.0
                nonfinite = nonfinite + overflow * config.spp
            bad = int(nonfinite.sum())
            if bad and config.nonfinite == "error":
                cell = first + int(np.flatnonzero(nonfinite)[0])
                raise NonFiniteSampleError(
                    f"the renderer returned {bad} NaN or infinite samples in cells {first}..{first + count - 1} "
                    f"(first at cell {cell}, grid index {tuple(int(i) for i in np.unravel_index(cell, config.shape))}); "
                    f"{len(finished)} finished chunks are kept. Rerun with --nonfinite zero to count them and "
                    "use 0 in their place."
                )
            data[first:first + count] = means
            if bad:
                state["nonfinite"][str(index)] = bad
            if path is not None:
                data.flush()
                state["finished_chunks"].append(index)
                write_json(os.path.join(path, PROGRESS_FILE), state)
            finished.add(index)
            if bar is not None:
                bar.update(count * config.spp)
    finally:
        if bar is not None:
            bar.close()
    seconds = time.perf_counter() - start_time
    nonfinite_total = int(sum(state["nonfinite"].values()))
    if nonfinite_total:
        print(f"warning: {nonfinite_total} NaN or infinite samples counted and replaced by 0")

    if path is None:
        meta = _meta(config, spec, scene, layout, status="complete")
        meta.update(nonfinite_samples=nonfinite_total, sampling_seconds=seconds)
        return Signal(data=data.reshape(tuple(config.shape) + (3,)), kind=config.kind, axes=layout.axes, meta=meta)

    del data
    partial = os.path.join(path, PARTIAL_DATA_FILE)
    if os.path.exists(partial):
        os.replace(partial, os.path.join(path, DATA_FILE))
    meta = read_json(os.path.join(path, META_FILE))
    meta.update(status="complete", nonfinite_samples=nonfinite_total, chunk_cells=chunk)
    meta["sampling_seconds"] = meta.get("sampling_seconds", 0.0) + seconds
    write_json(os.path.join(path, META_FILE), meta)
    os.remove(os.path.join(path, PROGRESS_FILE))
    return load_signal(path)


def _progress_bar(enabled, total, finished_chunks, chunk, cells, config):
    done = min(cells, finished_chunks * chunk) * config.spp if finished_chunks else 0
    return progress_bar(enabled, total=total, description=f"{config.kind} {config.scene}", unit="sample", initial=done)


def _meta(config, spec, scene, layout, *, status):
    camera = scene.camera
    return {
        "format": "sparselt-signal",
        "format_version": FORMAT_VERSION,
        "status": status,
        "config": config.record(),
        "scene": spec.name,
        "scene_description": spec.description,
        "hide_emitters": spec.hide_emitters,
        "camera": {
            "fov": camera.fov,
            "fov_axis": camera.fov_axis,
            "aperture_radius": camera.aperture_radius,
            "focus_distance": camera.focus_distance,
            "to_world": [list(operation) for operation in camera.to_world.operations],
        },
        "kind": config.kind,
        "axes": list(layout.axes),
        "dimensions": list(layout.dimensions),
        "shape": list(config.shape),
        "spp": config.spp,
        "seed": config.seed,
        "max_depth": config.max_depth,
        "variant": config.variant,
        "dtype": "float32",
        "provenance": environment_record(),
    }


def _prepare_folder(path, config, *, overwrite):
    """Decide what to do with an existing folder; return the progress to resume or ``None``."""
    status = signal_status(path)
    if os.path.exists(path) and not os.path.isdir(path):
        raise ValueError(f"output path {path!r} is an existing file, not a folder")
    if status == "incomplete" and os.path.isfile(os.path.join(path, PROGRESS_FILE)):
        meta = read_json(os.path.join(path, META_FILE))
        has_data = any(os.path.isfile(os.path.join(path, name)) for name in (PARTIAL_DATA_FILE, DATA_FILE))
        if _same_signal(meta.get("config") or {}, config.record()) and has_data:
            if meta["config"].get("nonfinite") != config.nonfinite:  # the policy may change on resume
                meta["config"]["nonfinite"] = config.nonfinite
                write_json(os.path.join(path, META_FILE), meta)
            return read_json(os.path.join(path, PROGRESS_FILE))
        if not overwrite:
            raise ValueError(
                f"{path!r} holds an unfinished signal of a different configuration; "
                "pass --overwrite to replace it, or rerun its own command to resume it"
            )
    elif status == "complete" and not overwrite:
        raise ValueError(f"signal {path!r} already exists; pass --overwrite to replace it")
    elif status is None and os.path.isdir(path) and os.listdir(path) and not overwrite:
        raise ValueError(f"output folder {path!r} exists, is not empty and is not a signal; pass --overwrite or choose another path")
    os.makedirs(path, exist_ok=True)
    if not os.access(path, os.W_OK | os.X_OK):
        raise PermissionError(f"output folder {path!r} is not writable")
    for name in (META_FILE, DATA_FILE, PARTIAL_DATA_FILE, PROGRESS_FILE):
        target = os.path.join(path, name)
        if os.path.exists(target):
            os.remove(target)
    return None


def _same_signal(recorded, requested):
    """Whether a recorded configuration is the requested one, the NaN policy aside (it may change on resume)."""
    ignore = ("nonfinite",)
    return ({k: v for k, v in recorded.items() if k not in ignore}
            == {k: v for k, v in requested.items() if k not in ignore})


def _open_folder(path, config, spec, scene, layout, chunk_cells, resumable):
    cells = math.prod(config.shape)
    partial = os.path.join(path, PARTIAL_DATA_FILE)
    if resumable is not None:
        if not os.path.exists(partial):  # killed between the final rename and the final metadata
            os.replace(os.path.join(path, DATA_FILE), partial)
        data = np.lib.format.open_memmap(partial, mode="r+")
        return data.reshape(cells, 3), resumable
    write_json(os.path.join(path, META_FILE), _meta(config, spec, scene, layout, status="incomplete"))
    data = np.lib.format.open_memmap(partial, mode="w+", dtype=np.float32, shape=tuple(config.shape) + (3,))
    state = _new_state(config, chunk_cells)
    write_json(os.path.join(path, PROGRESS_FILE), state)
    return data.reshape(cells, 3), state


def _new_state(config, chunk_cells):
    """Progress of a new acquisition: the chunking and what has been done."""
    chunk = chunk_cells or max(1, LANES_PER_CHUNK // config.spp)
    return {"chunk_cells": chunk, "chunk_count": -(-math.prod(config.shape) // chunk), "finished_chunks": [], "nonfinite": {}}
