"""Warmed kernels are reused: nothing compiles inside a timed run, whatever the seed or where NumPy put a buffer.

Found on a scene file: ``aaf-indirect``'s allocated pass recompiled (0.7 s) on one seed in two, because Dr.Jit
writes an uploaded NumPy buffer's alignment into the kernel's code.
"""

from __future__ import annotations

import numpy as np
import pytest

from sparselt.methods import Budget, ComparisonContext, get_method, run_timed, warm_up
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
    # Large: Dr.Jit copies small buffers and maps large ones. The buffer's start is made a multiple of 64 bytes
    # (where malloc puts 1 MiB depends on the process's history: on CI it was 16 bytes past one), so the views
    # below start at byte offsets 0 (aligned), 12, 24, ... (not).
    raw = np.empty((1 << 20) + 64, dtype=np.uint8)
    start = -raw.ctypes.data % 64
    big = raw[start:start + (1 << 20)].view(np.uint32)
    big[...] = np.arange(big.size, dtype=np.uint32)
    assert big.ctypes.data % 64 == 0
    for offset in range(0, 32, 3):
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


def _not_warmed(entry):
    """A kernel this process had not launched before: compiled now, or read from Dr.Jit's disk cache (whose
    contents depend on what ran on this machine before, so a hit there proves nothing about the warm-up)."""
    return not entry.get("cache_hit", True) or entry.get("cache_disk", False)


def _aaf_indirect_runs(history, *, max_depth=3, before_warm_up=lambda: None, row="aaf-indirect:single_launch_below=0"):
    """``aaf-indirect`` on cornell-box at 24x24, warmed by the harness, then three timed seeds: the kernels of
    each run that were not warmed, as ``{seed: [(hash, head of code), ...]}``."""
    from sparselt.rendering.mitsuba import MitsubaScene

    scene = MitsubaScene(get_scene("cornell-box"), (24, 24))
    layout = path_layout("indirect", max_depth)
    context = ComparisonContext(scene=scene, layout=layout, kind="indirect", grid_shape=(24, 24, 16, 16),
                                resolution=(24, 24), max_depth=max_depth)
    method = get_method(row)
    before_warm_up()
    warm_up(method, context)
    history()
    misses = {}
    for seed in (1, 2, 3):
        run_timed(method, context, Budget(spp=16, seed=seed))
        misses[seed] = [(entry["hash"], _first_lines(entry)) for entry in history() if _not_warmed(entry)]
    return misses


@pytest.mark.parametrize("row", ["aaf-indirect:single_launch_below=0", "aaf-indirect:single_launch_below=0:"
                                 "allocation_gain=1000", "aaf-indirect"])
def test_aaf_indirect_compiles_nothing_after_its_warm_up(history, row):
    """Over three seeds, whichever way the run goes (the pilot in halves then the allocated pass, blocks and
    single lanes; the same with the rest uniform; one launch, the default on this small image), every kernel
    launched was launched before."""
    misses = _aaf_indirect_runs(history, row=row)
    assert not any(misses.values()), f"kernels not warmed, by seed: {misses}"


def test_a_scene_left_as_garbage_changes_no_kernel_of_the_timed_runs(history):
    """Found in the test suite on a fresh machine: a comparison on another scene, then ``aaf-indirect``, compiled
    two kernels in the first timed run. Dr.Jit writes the live BSDF and emitter instances into the code of the
    kernels that call them, and the other scene was collected between the warm-up and the run. The harness
    collects before its warm-up and before each run. At a depth no other test runs ``aaf-indirect`` at: a kernel
    another test launched would hide a missing warm-up."""
    from sparselt.rendering.mitsuba import MitsubaScene

    def leave_garbage():
        other = MitsubaScene(get_scene("dof-sculptures"), (8, 8))  # its own BSDFs and emitters, rendered once
        context = ComparisonContext(scene=other, layout=path_layout("indirect", 3), kind="indirect",
                                    grid_shape=(8, 8, 16, 16), resolution=(8, 8), max_depth=3)
        pt = get_method("pt")
        pt.warm_up(context)
        run_timed(pt, context, Budget(spp=2, seed=1))
        cycle = [other, context]
        cycle.append(cycle)  # freed only by the cyclic collector, at a moment of its choosing

    misses = _aaf_indirect_runs(history, max_depth=4, before_warm_up=leave_garbage)
    assert not any(misses.values()), f"kernels not warmed, by seed: {misses}"


def _first_lines(entry, count=40):
    """The head of a launched kernel's code, for a failure message."""
    code = entry.get("ir")
    text = code.getvalue() if hasattr(code, "getvalue") else str(code)
    return "\n".join(text.splitlines()[:count])
