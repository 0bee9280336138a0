"""Issue 18, signals: stores verified on read, repaired by a rerun, replaced only once the new one is complete.

Every store here is a real signal sampled with the renderer (a 16 x 16 x 2 x 2
dof signal of the Cornell box in 8 chunks), damaged the way the issue found
them damaged, then read through ``load_signal`` as every command does.
"""

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from sparselt import SparseFourier, integrate, load_signal
from sparselt.operators import mean_per_cell
from sparselt.rendering import acquire
from sparselt.rendering.acquire import AcquisitionConfig, NonFiniteSampleError, acquire_signal
from sparselt.rendering.scenes import SceneSpec
from sparselt.signal import Signal
from sparselt.storage import CorruptSignalError, zarr_store

CONFIG = AcquisitionConfig(scene="cornell-box", kind="dof", shape=(16, 16, 2, 2), spp=1, seed=3, aperture=0.1)
CHUNK_CELLS = 128  # 8 chunks of 2 x 16 x 2 x 2 cells
REPAIR = "rerun the same `sparselt sample` command with --verify to repair it"


def sample(path, config=CONFIG, **options):
    options.setdefault("progress", False)
    return acquire_signal(config, path, chunk_cells=CHUNK_CELLS, **options)


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    """A complete store and its data (each test damages a copy)."""
    path = tmp_path_factory.mktemp("pristine") / "signal"
    sample(path)
    return path, np.asarray(load_signal(path).data)


@pytest.fixture(scope="module")
def other_seed(tmp_path_factory):
    """A store of the same layout with another seed: its chunks are valid, but not this signal's."""
    path = tmp_path_factory.mktemp("other") / "signal"
    sample(path, AcquisitionConfig(**{**CONFIG.__dict__, "seed": 4}))
    return path


def copy_of(pristine, tmp_path):
    path = tmp_path / "signal"
    shutil.copytree(pristine[0], path)
    return path


def chunk_file(path, index):
    return path / "data" / zarr_store.ChunkGrid((16, 16, 2, 2), (2, 16, 2, 2)).chunk_key(index)


def edit_attributes(path, change, file="zarr.json"):
    group = json.loads((path / file).read_text())
    change(group["attributes"] if file == "zarr.json" else group)
    (path / file).write_text(json.dumps(group))


def chunk_signatures(path):
    return {p.relative_to(path): (p.stat().st_ino, p.stat().st_mtime_ns)
            for p in (path / "data" / "c").rglob("*") if p.is_file()}


# -- 8. every chunk read is checked against its CRC-32 ------------------------------------------------------


def flip_bit(path, index):
    target = chunk_file(path, index)
    payload = bytearray(target.read_bytes())
    payload[len(payload) // 2] ^= 0x10
    target.write_bytes(bytes(payload))


def truncate(path, index):
    target = chunk_file(path, index)
    target.write_bytes(target.read_bytes()[: target.stat().st_size // 2])


def garble(path, index):
    target = chunk_file(path, index)
    target.write_bytes(np.random.default_rng(index).integers(0, 256, target.stat().st_size, dtype=np.uint8).tobytes())


CHUNK_DAMAGE = {
    "one bit flipped": flip_bit,
    "truncated": truncate,
    "garbled": garble,
    "a valid chunk of another signal": None,  # copied in by the test (needs the other store)
}


@pytest.mark.parametrize("damage", list(CHUNK_DAMAGE))
def test_a_damaged_chunk_is_refused_on_read_and_repaired_by_a_rerun(damage, pristine, other_seed, tmp_path):
    path = copy_of(pristine, tmp_path)
    if CHUNK_DAMAGE[damage] is None:
        shutil.copyfile(chunk_file(other_seed, 5), chunk_file(path, 5))
    else:
        CHUNK_DAMAGE[damage](path, 5)
    signal = load_signal(path)  # lazy: nothing read yet
    expected = f"chunk 5 of signal '{path}'.*{REPAIR}"
    with pytest.raises(CorruptSignalError, match=expected):
        signal.image()
    with pytest.raises(CorruptSignalError, match=expected):
        np.asarray(signal.data)
    with pytest.raises(CorruptSignalError, match=expected):
        signal.data[10:12, 3]  # any read touching chunk 5 (x in 10..11)
    assert np.array_equal(signal.data[0:10], pristine[1][0:10])  # the intact chunks still read
    with pytest.raises(CorruptSignalError, match=expected):
        load_signal(path, mmap=False)

    before = chunk_signatures(path)
    repaired = sample(path)  # the same command again: only the damaged chunk is sampled again
    assert np.array_equal(np.asarray(repaired.data), pristine[1])
    after = chunk_signatures(path)
    changed = sorted(str(name) for name in before if before[name] != after[name])
    assert changed == [str(chunk_file(path, 5).relative_to(path))]
    assert repaired.meta["chunk_crc32"] == load_signal(pristine[0]).meta["chunk_crc32"]
    assert not (path / "chunks.jsonl").exists()


def test_random_bit_flips_never_give_wrong_values(pristine, tmp_path):
    """The issue's 30 random flips: each read either gives the right values or refuses."""
    rng = np.random.default_rng(18)
    refused = 0
    for trial in range(30):
        path = tmp_path / str(trial)
        shutil.copytree(pristine[0], path)
        target = chunk_file(path, int(rng.integers(8)))
        payload = bytearray(target.read_bytes())
        payload[int(rng.integers(len(payload)))] ^= 1 << int(rng.integers(8))
        target.write_bytes(bytes(payload))
        try:
            values = np.asarray(load_signal(path).data)
        except CorruptSignalError:
            refused += 1
            continue
        assert np.array_equal(values, pristine[1]), f"trial {trial}: wrong values were read"
    assert refused >= 25


@pytest.mark.parametrize("change, message", [
    (lambda a: a.update(chunk_crc32=[0] * 8), "are all zero"),
    (lambda a: a.update(chunk_crc32=a["chunk_crc32"][:7]), "records 7 chunk checksums .* for its 8 chunks"),
    (lambda a: a.pop("chunk_crc32"), "'chunk_crc32' is missing"),
    (lambda a: a.update(chunk_crc32=["x"] * 8), "must be a list of CRC-32 values"),
], ids=["zeroed", "wrong-length", "missing", "not-integers"])
def test_unusable_checksums_are_refused_and_repaired(change, message, pristine, tmp_path):
    path = copy_of(pristine, tmp_path)
    edit_attributes(path, change)
    with pytest.raises(CorruptSignalError, match=f"{message}.*{REPAIR} \\(every chunk is sampled again\\)"):
        load_signal(path)
    assert np.array_equal(np.asarray(sample(path).data), pristine[1])


def test_show_on_a_damaged_store_is_one_clear_line(pristine, tmp_path):
    """`sparselt show` exits 2 naming store, chunk and remedy; no asyncio 'never retrieved' spam."""
    path = copy_of(pristine, tmp_path)
    truncate(path, 2)
    garble(path, 6)
    result = subprocess.run([sys.executable, "-m", "sparselt.cli", "show", str(path), "--out", str(tmp_path / "out")],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr and "never retrieved" not in result.stderr, result.stderr
    assert "chunk 2 of signal" in result.stderr and str(path) in result.stderr and REPAIR in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr


def test_the_cluster_path_verifies_chunks_too(pristine, tmp_path):
    from sparselt.distributed import dask_client

    path = copy_of(pristine, tmp_path)
    intact = load_signal(pristine[0])
    damaged = copy_of(pristine, tmp_path / "damaged")
    flip_bit(damaged, 1)
    with dask_client(workers=1, say=lambda text: None) as client:
        assert np.allclose(load_signal(path).image(client=client), intact.image(), rtol=1e-6, atol=0)
        with pytest.raises(CorruptSignalError, match="chunk 1 of signal"):
            load_signal(damaged).image(client=client)


# -- 9, 13. metadata this version does not know are refused, naming the attribute ---------------------------


@pytest.mark.parametrize("file, change, message", [
    ("zarr.json", lambda a: a.update(format_version=99), "has format_version 99 .* reads format_version 2 only"),
    ("zarr.json", lambda a: a.update(kind="bogus"), "has kind 'bogus' .* the kinds are path, path-indirect, dof, indirect"),
    ("zarr.json", lambda a: a.pop("shape"), "lacks the attribute 'shape'"),
    ("zarr.json", lambda a: a.pop("axes"), "lacks the attribute 'axes'"),
    ("zarr.json", lambda a: a.update(shape=[16, 16, 2, "2"]), "'shape' must list at least two positive integers"),
    ("data/zarr.json", lambda a: a.update(data_type="float64"), "data type float64, expected float32"),
], ids=["format-version-99", "kind-bogus", "no-shape", "no-axes", "shape-not-integers", "float64-data"])
def test_unknown_or_incomplete_metadata_are_refused(file, change, message, pristine, tmp_path):
    path = copy_of(pristine, tmp_path)
    edit_attributes(path, change, file)
    with pytest.raises(ValueError, match=message) as error:
        load_signal(path)
    assert not isinstance(error.value, KeyError)


# -- 1. --overwrite keeps the old signal until the new one is complete --------------------------------------


def _infinite_light_scene():
    from sparselt.rendering.scenes import get_scene

    cornell = get_scene("cornell-box")
    objects = dict(cornell.objects)
    objects["light"] = dict(objects["light"], emitter={"type": "area", "radiance": {"type": "rgb", "value": [1e39, 1.0, 1.0]}})
    return SceneSpec(name="infinite-light", description="overflowing emitter", objects=objects, camera=cornell.camera)


def siblings(path):
    return sorted(name for name in os.listdir(path.parent) if name.startswith(f".{path.name}.sparselt-"))


def test_overwrite_with_nan_samples_keeps_the_old_signal_and_resumes_beside_it(pristine, tmp_path, monkeypatch):
    path = copy_of(pristine, tmp_path)
    scene = _infinite_light_scene()
    with pytest.raises(NonFiniteSampleError):
        sample(path, overwrite=True, scene_spec=scene)
    old = load_signal(path)  # not "incomplete 0/8 chunks": the old signal is whole
    assert old.meta["status"] == "complete" and np.array_equal(np.asarray(old.data), pristine[1])
    assert siblings(path) == [f".{path.name}.sparselt-new"]

    # The replacement is stopped again after 3 chunks; the next run resumes it beside the old signal.
    zero = AcquisitionConfig(**{**CONFIG.__dict__, "nonfinite": "zero"})
    calls = []
    real = acquire.sample_chunk

    def stopped_after_three(job):
        calls.append(job.index)
        if len(calls) > 3:
            raise KeyboardInterrupt
        return real(job)

    monkeypatch.setattr(acquire, "sample_chunk", stopped_after_three)
    with pytest.raises(KeyboardInterrupt):
        sample(path, zero, overwrite=True, scene_spec=scene)
    assert np.array_equal(np.asarray(load_signal(path).data), pristine[1])
    calls.clear()
    monkeypatch.setattr(acquire, "sample_chunk", lambda job: calls.append(job.index) or real(job))
    new = sample(path, zero, overwrite=True, scene_spec=scene)
    assert len(calls) == 5  # the 3 chunks of the stopped run were kept
    assert new.meta["nonfinite_samples"] > 0 and new.meta["scene"] == "infinite-light"
    assert np.array_equal(np.asarray(load_signal(path).data),
                          acquire_signal(zero, progress=False, scene_spec=scene).data)
    assert siblings(path) == []


class Crash(Exception):
    """Stands for a kill at one point of the swap."""


def crash_before_the_exchange(monkeypatch):
    monkeypatch.setattr(zarr_store, "replace_store", lambda new, path: (_ for _ in ()).throw(Crash()))


def crash_after_the_exchange(monkeypatch):
    real = zarr_store._exchange
    monkeypatch.setattr(zarr_store, "_exchange", lambda first, second: real(first, second) and (_ for _ in ()).throw(Crash()))


def crash_after_rename(count):
    def inject(monkeypatch):
        monkeypatch.setattr(zarr_store, "_exchange", lambda first, second: False)  # a file system without it
        real, done = os.rename, []

        def rename(source, target):
            real(source, target)
            done.append(source)
            if len(done) == count:
                raise Crash()

        monkeypatch.setattr(zarr_store.os, "rename", rename)
    return inject


@pytest.mark.parametrize("crash, under_the_name", [
    (crash_before_the_exchange, "old"),
    (crash_after_the_exchange, "new"),
    (crash_after_rename(1), None),  # the fallback's window: the next run finishes the swap
    (crash_after_rename(2), "new"),
], ids=["before-the-exchange", "after-the-exchange", "fallback-between-the-renames", "fallback-after-the-renames"])
def test_a_replacement_killed_at_any_point_loses_nothing(crash, under_the_name, pristine, tmp_path, monkeypatch):
    path = copy_of(pristine, tmp_path)
    seed = AcquisitionConfig(**{**CONFIG.__dict__, "seed": 11})
    new_data = acquire_signal(seed, progress=False).data
    with monkeypatch.context() as patch:
        crash(patch)
        with pytest.raises(Crash):
            sample(path, seed, overwrite=True)
    if under_the_name is None:
        assert not path.exists()
        assert {zarr_store.store_status(path.parent / name) for name in siblings(path)} == {"complete"}
        with pytest.raises(FileNotFoundError, match="interrupted: rerun the `sparselt sample` command"):
            load_signal(path)
    else:
        data = np.asarray(load_signal(path).data)
        assert np.array_equal(data, pristine[1] if under_the_name == "old" else new_data)
    again = sample(path, seed, overwrite=True)  # the next run cleans up and finishes
    assert np.array_equal(np.asarray(again.data), new_data)
    assert siblings(path) == []


# -- 3. a folder sparselt did not write is never emptied ----------------------------------------------------


@pytest.mark.parametrize("files, store, named", [
    ({"paper.tex": "precious", "data/notes.txt": "notes"}, False, "'data/notes.txt', 'paper.tex'"),
    ({"data/notes.txt": "notes"}, False, "'data/notes.txt'"),
    ({"paper.tex": "precious"}, True, "'paper.tex'"),
    ({"data/c/0/notes.txt": "notes"}, True, "'data/c/0/notes.txt'"),
], ids=["foreign-folder", "foreign-data-folder", "store-with-a-foreign-file", "foreign-file-among-chunks"])
@pytest.mark.parametrize("overwrite", [False, True])
def test_a_foreign_folder_is_refused_and_nothing_is_deleted(files, store, named, overwrite, pristine, tmp_path):
    path = copy_of(pristine, tmp_path) if store else tmp_path / "folder"
    for name, text in files.items():
        (path / name).parent.mkdir(parents=True, exist_ok=True)
        (path / name).write_text(text)
    before = sorted(str(p.relative_to(path)) for p in path.rglob("*"))
    with pytest.raises(ValueError, match=f"did not write \\({named}\\)"):
        sample(path, AcquisitionConfig(**{**CONFIG.__dict__, "seed": 12}), overwrite=overwrite)
    assert sorted(str(p.relative_to(path)) for p in path.rglob("*")) == before
    for name, text in files.items():
        assert (path / name).read_text() == text
    if store:
        assert np.array_equal(np.asarray(load_signal(path).data), pristine[1])


# -- 10. --workers beyond the machine's cores is refused before any cluster starts --------------------------


def test_too_many_workers_are_refused_before_anything_starts(pristine, tmp_path):
    from sparselt.cli import main
    from sparselt.distributed import check_worker_count, dask_client

    cores = os.cpu_count()
    with pytest.raises(ValueError, match=f"workers must be at most {cores}, the CPU cores of this machine.*got 1000"):
        check_worker_count(1000)
    target = tmp_path / "never"
    with pytest.raises(ValueError, match=f"at most {cores}.*got {cores + 1}"):
        sample(target, workers=cores + 1)
    assert not target.exists()
    with pytest.raises(ValueError, match=f"at most {cores}"):
        with dask_client(workers=cores + 1):
            pass
    assert main(["show", str(pristine[0]), "--out", str(tmp_path / "show"), "--workers", str(cores + 1)]) == 2
    assert main(["sample", "--scene", "cornell-box", "--kind", "dof", "--aperture", "0.1", "--shape", "8,8,2,2",
                 "--spp", "1", "--out", str(target), "--no-progress", "--workers", str(cores + 1)]) == 2
    assert not target.exists()


# -- 15. sampling_seconds is the total over every run ------------------------------------------------------


def test_sampling_seconds_counts_the_run_that_was_killed(tmp_path, monkeypatch):
    import time

    path = tmp_path / "signal"
    real, calls, resumed_seconds = acquire.sample_chunk, [], []

    def slow_then_killed(job):
        calls.append(job.index)
        if len(calls) > 3:
            raise KeyboardInterrupt
        time.sleep(0.4)
        return real(job)

    def timed(job):
        started = time.perf_counter()
        record = real(job)
        resumed_seconds.append(time.perf_counter() - started)
        return record

    monkeypatch.setattr(acquire, "sample_chunk", slow_then_killed)
    with pytest.raises(KeyboardInterrupt):
        sample(path)
    monkeypatch.setattr(acquire, "sample_chunk", timed)
    resumed = sample(path)
    assert len(resumed_seconds) == 5
    # The killed run's three 0.4 s chunks are counted, and so is the resumed run's sampling.
    assert resumed.meta["sampling_seconds"] >= 3 * 0.4 + sum(resumed_seconds)


# -- 14. API arguments that meant nothing are refused, naming them -----------------------------------------


@pytest.mark.parametrize("call, error, message", [
    (lambda: SparseFourier.from_signal(np.float32(1)), ValueError, "signal must have at least one grid axis"),
    (lambda: SparseFourier.from_signal(np.array(["a", "b"])), TypeError, "signal must be an array of numbers"),
    (lambda: Signal(data=np.zeros((4, 3), np.float32), kind="dof", axes=("x",)), ValueError,
     "at least the two image-plane axes"),
    (lambda: Signal(np.zeros((4, 4, 2, 3), np.float32), "dof", ("x", "y", "u")).image(rows_per_block=0), ValueError,
     "rows_per_block must be >= 1, got 0"),
    (lambda: Signal(np.zeros((4, 4, 2, 3), np.float32), "dof", ("x", "y", "u")).image(rows_per_block=1.5), TypeError,
     "rows_per_block must be an integer"),
    (lambda: mean_per_cell([3, -1], [1.0, 2.0]), ValueError, "cells must be flat cell indices >= 0, got -1"),
    (lambda: mean_per_cell([0.5, 1.0], [1.0, 2.0]), TypeError, "cells must be integer cell indices"),
    (lambda: integrate(SparseFourier.from_signal(np.ones((4, 4))), method="time", chunk=0), ValueError,
     "chunk must be >= 1, got 0"),
], ids=["from-signal-scalar", "from-signal-strings", "signal-one-axis", "rows-per-block-zero", "rows-per-block-float",
        "negative-cell", "float-cells", "integrate-chunk-zero"])
def test_api_arguments_are_checked(call, error, message):
    with pytest.raises(error, match=message):
        call()
