"""Warmed kernels are reused: nothing compiles inside a timed run, whatever the seed or where NumPy put a buffer.

Found on a scene file: ``aaf-indirect``'s allocated pass recompiled (0.7 s) on one seed in two, because Dr.Jit
writes an uploaded NumPy buffer's alignment into the kernel's code.
"""

from __future__ import annotations

import numpy as np
import pytest

from sparselt.methods import Budget, ComparisonContext, get_method, run_timed
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba.readback import UPLOAD_ALIGNMENT, to_device
from sparselt.rendering.mitsuba.runtime import initialize, modules
from sparselt.rendering.scenes import get_scene


@pytest.fixture()
def history():
    """Dr.Jit's kernel history on, cleared; yields a function returning the JIT kernels launched since."""
    initialize()
    _, dr = modules()
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    dr.kernel_history()

    def launched():
        return [entry for entry in dr.kernel_history() if entry["type"] == dr.KernelType.JIT]

    yield launched
    dr.set_flag(dr.JitFlag.KernelHistory, False)


def _kernel_hashes(launched, make):
    mi, dr = modules()
    hashes = set()
    big = np.arange(1 << 18, dtype=np.uint32)  # large: Dr.Jit copies small buffers, maps large ones
    for offset in range(0, 32, 3):  # byte offsets 0, 12, 24, ...: some multiples of 64 from the buffer's start
        values = make(mi, big[offset:offset + 100_000])
        dr.eval(values * 3 + 1)
        hashes |= {entry["hash"] for entry in launched()}
    return hashes


def test_uploads_give_one_kernel_whatever_the_numpy_buffers_alignment(history):
    assert len(_kernel_hashes(history, lambda mi, array: to_device(mi.UInt32, array, np.uint32))) == 1


def test_the_cause_numpy_buffers_uploaded_as_they_are_give_two_kernels(history):
    """Why :func:`to_device` exists: the same expression on differently aligned NumPy views compiles twice."""
    assert len(_kernel_hashes(history, lambda mi, array: mi.UInt32(array))) == 2


def test_uploads_are_aligned_copies_of_the_values():
    initialize()
    mi, _ = modules()
    values = np.arange(1, 100, dtype=np.float64)[3:]
    uploaded = to_device(mi.Float, values, np.float32)
    np.testing.assert_array_equal(np.asarray(uploaded), values.astype(np.float32))
    assert UPLOAD_ALIGNMENT == 64


def test_aaf_indirect_compiles_nothing_after_its_warm_up(history):
    """The allocated pass (explicit lanes, slots) over three seeds: every kernel launched was compiled before."""
    from sparselt.rendering.mitsuba import MitsubaScene

    scene = MitsubaScene(get_scene("cornell-box"), (24, 24))
    layout = path_layout("indirect", 3)
    context = ComparisonContext(scene=scene, layout=layout, kind="indirect", grid_shape=(24, 24, 16, 16),
                                resolution=(24, 24), max_depth=3)
    method = get_method("aaf-indirect")
    method.warm_up(context)
    history()
    for seed in (1, 2, 3):
        run_timed(method, context, Budget(spp=16, seed=seed))
        misses = [entry["hash"] for entry in history() if not entry.get("cache_hit", True)]
        assert not misses, f"seed {seed}: kernels compiled in a timed run: {misses}"
