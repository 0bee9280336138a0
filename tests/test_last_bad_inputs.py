"""Issue 38: the last bad-input cases of the hostile-input trial, each a one-line error naming the value and the fix
(exit 2), nothing left behind; and a rerun of a finished command exits 0 saying it is complete.

Full disks and read-only caches are simulated in-process (the operating system's errors raised where it raises
them, without a path where it gives none); ``/proc/nope`` and symbolic-link loops are real.
"""

import errno
import json
import os

import numpy as np
import pytest

from sparselt import provenance
from sparselt.cli import _describe, main
from sparselt.rendering import meshes
from sparselt.signal import Signal
from sparselt.storage import folder as folder_module
from sparselt.storage import lock as lock_module
from sparselt.storage import zarr_store
from sparselt.storage.cache import CacheError
from sparselt.storage.folder import MANIFEST_FILE, ExperimentFolder
from sparselt.storage.lock import LOCK_FILE

COMPARE = ["compare", "--scene", "cornell-box", "--kind", "path", "--methods", "pt",
           "--spp", "1", "--seeds", "1", "--resolution", "16,16", "--reference-spp", "64", "--no-progress"]
SAMPLE = ["sample", "--scene", "cornell-box", "--kind", "dof", "--aperture", "0.1", "--shape", "12,12,2,2",
          "--spp", "1", "--chunk-cells", "48", "--no-progress"]  # 12 chunks, one per x


def error_line(capsys):
    """Standard error of the last command: exactly one line, no traceback."""
    error = capsys.readouterr().err
    lines = error.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in error, error
    return lines[0]


def synthetic_signal(shape, store="/signals/synthetic"):
    data = np.random.default_rng(3).random(tuple(shape) + (3,)).astype(np.float32) ** 4
    axes = ("x", "y", "lens_u", "lens_v")[:len(shape)]
    return Signal(data=data, kind="dof", axes=axes, meta={"scene": "synthetic"}, store=store)


def use_signal(monkeypatch, signal):
    """`show` and `analyze` read this signal, whatever path they are given."""
    import sparselt.signal

    monkeypatch.setattr(sparselt.signal, "load_signal", lambda path: signal)


# -- 1. analyze on a signal too small for SSIM ----------------------------------------------------------------


def test_case_1_analyze_refuses_an_image_plane_smaller_than_the_ssim_window(tmp_path, monkeypatch, capsys):
    use_signal(monkeypatch, synthetic_signal((1, 1, 1, 1), store="/signals/tiny"))
    out = tmp_path / "analysis"
    assert main(["analyze", "signal", "--out", str(out)]) == 2
    line = error_line(capsys)
    assert "'/signals/tiny' has an image plane of 1x1 pixels, too small for SSIM (at least 11x11 pixels)" in line
    assert "--shape 11,11,1,1" in line
    assert "nan" not in capsys.readouterr().out.lower()
    assert not out.exists()


# -- 2-5. a cache that cannot be used names SPARSELT_CACHE, its value and the fix --------------------------------


def test_case_2_a_cache_variable_naming_a_file(tmp_path, monkeypatch, capsys):
    cache = tmp_path / "cachefile"
    cache.write_text("not a folder")
    monkeypatch.setenv("SPARSELT_CACHE", str(cache))
    out = tmp_path / "compare"
    assert main(COMPARE + ["--out", str(out)]) == 2
    line = error_line(capsys)
    assert f"cache folder {str(cache / 'references')!r}" in line
    assert f"{str(cache)!r} is a file, not a folder" in line
    assert f"SPARSELT_CACHE={cache}" in line and "set SPARSELT_CACHE to a folder you can write" in line
    assert not out.exists() and cache.read_text() == "not a folder"


def test_case_2_the_mesh_cache_too(tmp_path, monkeypatch):
    cache = tmp_path / "cachefile"
    cache.write_text("x")
    monkeypatch.setenv("SPARSELT_CACHE", str(cache))
    with pytest.raises(CacheError, match=f"{str(cache)!r} is a file, not a folder .*SPARSELT_CACHE={cache}\\); "
                                         "set SPARSELT_CACHE to a folder you can write"):
        meshes.mesh_file("box", meshes.box)


def test_case_3_a_read_only_cache_points_at_the_cache_not_at_out(tmp_path, monkeypatch, capsys):
    cache = tmp_path / "rocache"
    real_makedirs = os.makedirs

    def makedirs(path, *arguments, **options):  # what a read-only mount answers
        if os.fspath(path).startswith(str(cache)):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), os.fspath(path))
        return real_makedirs(path, *arguments, **options)

    monkeypatch.setattr(os, "makedirs", makedirs)
    monkeypatch.setenv("SPARSELT_CACHE", str(cache))
    out = tmp_path / "compare"
    assert main(COMPARE + ["--out", str(out)]) == 2
    line = error_line(capsys)
    assert f"cannot create the cache folder {str(cache / 'references')!r}: the file system is read-only" in line
    assert f"SPARSELT_CACHE={cache}" in line and "set SPARSELT_CACHE to a folder you can write" in line
    assert "--out" not in line and not out.exists()


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs /proc")
def test_case_4_a_cache_under_proc(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("SPARSELT_CACHE", "/proc/nope")
    out = tmp_path / "compare"
    assert main(COMPARE + ["--out", str(out)]) == 2
    line = error_line(capsys)
    assert "cannot create the cache folder '/proc/nope/references'" in line and "'/proc/nope'" in line
    assert "SPARSELT_CACHE=/proc/nope" in line and "set SPARSELT_CACHE to a folder you can write" in line
    assert not out.exists()


def test_case_5_a_full_cache_is_told_from_a_full_out(tmp_path, monkeypatch, capsys):
    """compare writes to two places: a full disk under the cache names the cache and its variable."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("SPARSELT_CACHE", str(cache))
    real = provenance.atomic_write

    def atomic_write(path, write):
        if os.fspath(path).startswith(str(cache)):
            write = _no_space
        return real(path, write)

    monkeypatch.setattr(provenance, "atomic_write", atomic_write)
    out = tmp_path / "compare"
    assert main(COMPARE + ["--out", str(out)]) == 2
    line = error_line(capsys)
    assert "no space left for the cache on the device holding" in line and str(cache / "references") in line
    assert f"SPARSELT_CACHE={cache}" in line and "set SPARSELT_CACHE to a folder on another disk" in line
    assert not out.exists()  # nothing was finished in it


# -- 6-9. --out on a full disk: the path named, nothing left behind ---------------------------------------------


def _no_space(*arguments):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # as the operating system raises it: no path


class _FullDiskOs:
    """``os`` for the lock module, whose writes meet a full disk."""

    def __getattr__(self, name):
        return getattr(os, name)

    write = staticmethod(_no_space)


COMMANDS = {
    "compare": lambda out: COMPARE + ["--out", out],
    "show": lambda out: ["show", "signal", "--out", out],
    "render": lambda out: ["render", "--scene", "cornell-box", "--spp", "1", "--resolution", "16,16", "--out", out],
    "analyze": lambda out: ["analyze", "signal", "--gamma", "1", "--fractions", "0.1,1", "--out", out],
}


@pytest.mark.parametrize("where", ["lock", "first file"])
@pytest.mark.parametrize("command", list(COMMANDS))
def test_cases_6_to_9_out_on_a_full_disk(command, where, tmp_path, monkeypatch, capsys):
    use_signal(monkeypatch, synthetic_signal((12, 12, 2, 2)))
    if where == "lock":  # the disk is full before anything is written: the lock's record cannot be written
        monkeypatch.setattr(lock_module, "os", _FullDiskOs())
    else:  # room for the lock, not for the first file
        real = provenance.atomic_write
        full = lambda path, write: real(path, _no_space)  # noqa: E731
        monkeypatch.setattr(provenance, "atomic_write", full)
        monkeypatch.setattr(folder_module, "atomic_write", full)
    out = tmp_path / "parent" / "out"
    assert main(COMMANDS[command](str(out))) == 2
    line = error_line(capsys)
    assert "no space left on the device holding" in line and str(out) in line and "free some space" in line
    assert ": (" not in line
    assert not (tmp_path / "parent").exists()  # the folders it created, its lock included, are gone


def test_a_full_disk_in_an_existing_folder_keeps_its_work_and_leaves_no_lock(tmp_path, monkeypatch):
    out = tmp_path / "run"
    first = ExperimentFolder(out, kind="test", identity={"size": 1})
    first.inspect()
    with first.open():
        first.record_cell("one", {"value": 1})
    again = ExperimentFolder(out, kind="test", identity={"size": 1})
    again.inspect()
    with pytest.raises(zarr_store.DiskFullError, match="no space left on the device holding .*two.json"):
        with again.open():
            monkeypatch.setattr(folder_module, "atomic_write", lambda path, write: provenance.atomic_write(
                path, _no_space))
            again.record_cell("two", {"value": 2})
    assert sorted(os.listdir(out)) == ["cells", MANIFEST_FILE]  # its work kept, no lock, no temporary file
    assert os.listdir(out / "cells") == ["one.json"]


def test_an_os_error_without_a_path_has_no_dangling_colon():
    line = _describe(OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))
    assert line == "No space left on device (the disk is full); free some space, or choose another disk"


# -- 10. --out through a symbolic-link loop ---------------------------------------------------------------------


@pytest.mark.parametrize("below", [False, True], ids=["the-loop", "inside-the-loop"])
def test_case_10_sample_into_a_symbolic_link_loop(below, tmp_path, capsys):
    os.symlink(tmp_path / "loopB", tmp_path / "loopA")
    os.symlink(tmp_path / "loopA", tmp_path / "loopB")
    out = tmp_path / "loopA" / "signal" if below else tmp_path / "loopA"
    assert main(SAMPLE + ["--out", str(out)]) == 2
    line = error_line(capsys)
    assert f"output path {str(out)!r} is a symbolic link loop; choose another --out" in line
    assert "File exists" not in line
    assert sorted(os.listdir(tmp_path)) == ["loopA", "loopB"]


# -- 11. a render too large for one pass names the largest resolution that fits ---------------------------------


@pytest.mark.parametrize("spp, largest", [(1, "65535x65535"), (4, "32767x32767")])
def test_case_11_a_huge_render_names_the_largest_resolution(spp, largest, tmp_path, capsys):
    out = tmp_path / "render"
    assert main(["render", "--scene", "cornell-box", "--spp", str(spp), "--resolution", "100000,100000",
                 "--out", str(out)]) == 2
    line = error_line(capsys)
    assert f"100000x100000 pixels at {spp} spp" in line
    assert f"the largest resolution of this shape that fits in one pass at {spp} spp is {largest}" in line
    assert "at most 0 spp" not in line and "several passes" not in line
    assert not out.exists()


def test_case_11_a_resolution_that_fits_at_fewer_spp_says_both():
    from sparselt.rendering.baseline import check_wavefront

    with pytest.raises(ValueError, match=r"fits in one pass at 4096 spp is 1365x767, and at 1920x1080 at most 2071 "
                                         r"spp fit \(render several passes"):
        check_wavefront((1920, 1080), 4096)


# -- the rerun of a finished command: exit 0, "complete", no chunk read ------------------------------------------


@pytest.fixture
def sampled(tmp_path, capsys):
    out = tmp_path / "signal"
    assert main(SAMPLE + ["--out", str(out)]) == 0
    capsys.readouterr()
    return out


@pytest.fixture
def chunk_reads(monkeypatch):
    """How many chunks were read and checked against their CRC-32 (the in-process cache of verified chunks is
    emptied first, as in a new process)."""
    zarr_store._VERIFIED_CHUNKS.clear()
    reads = []
    real = zarr_store.VerifiedArray._read

    def read(self, index, into=None):
        reads.append(index)
        return real(self, index, into)

    monkeypatch.setattr(zarr_store.VerifiedArray, "_read", read)
    return reads


def test_rerun_of_a_complete_sample_exits_0_saying_complete_without_reading_chunks(sampled, chunk_reads, capsys):
    before = (sampled / "zarr.json").read_bytes()
    assert main(SAMPLE + ["--out", str(sampled)]) == 0
    output = capsys.readouterr()
    assert f"{sampled} is complete" in output.out and "nothing to do" in output.out and not output.err
    assert chunk_reads == []
    assert (sampled / "zarr.json").read_bytes() == before
    assert main(SAMPLE + ["--out", str(sampled), "--verify"]) == 0  # reads every chunk
    assert "every chunk matches its CRC-32" in capsys.readouterr().out
    assert sorted(chunk_reads) == list(range(12))


def test_rerun_with_other_settings_is_still_refused_naming_the_difference(sampled, capsys):
    arguments = SAMPLE + ["--out", str(sampled)]
    arguments[arguments.index("--spp") + 1] = "2"
    assert main(arguments) == 2
    line = error_line(capsys)
    assert f"signal {str(sampled)!r} already exists with another configuration (spp: 1 recorded, 2 now)" in line
    assert "pass --overwrite to replace it" in line


def _chunk_file(store, index):
    return store / "data" / zarr_store.ChunkGrid((12, 12, 2, 2), (1, 12, 2, 2)).chunk_key(index)


def test_a_damaged_chunk_is_still_repaired_by_a_rerun_reading_only_it(sampled, chunk_reads, capsys):
    pristine = zarr_store.read_chunk(sampled, zarr_store.ChunkGrid((12, 12, 2, 2), (1, 12, 2, 2)), 0)
    target = _chunk_file(sampled, 3)
    target.write_bytes(target.read_bytes()[: target.stat().st_size // 2])
    assert main(SAMPLE + ["--out", str(sampled)]) == 0
    assert "wrote" in capsys.readouterr().out
    assert sorted(set(chunk_reads)) == [3]  # only the changed chunk was read to find the damage
    from sparselt import load_signal

    signal = load_signal(sampled)
    assert np.array_equal(np.asarray(signal.data)[0].reshape(-1, 3), pristine)
    np.asarray(signal.data)  # every chunk reads and matches its CRC-32


def test_damage_a_files_metadata_cannot_show_is_repaired_with_verify(sampled, capsys):
    """A bit flipped in place with the file's size and time unchanged (a failing disk): a plain rerun cannot see it,
    the read error says to rerun with --verify, and that repairs it."""
    from sparselt import load_signal
    from sparselt.storage import CorruptSignalError

    target = _chunk_file(sampled, 2)
    status = target.stat()
    payload = bytearray(target.read_bytes())
    payload[len(payload) // 2] ^= 0x10
    target.write_bytes(bytes(payload))
    os.utime(target, ns=(status.st_atime_ns, status.st_mtime_ns))
    zarr_store._VERIFIED_CHUNKS.clear()
    with pytest.raises(CorruptSignalError, match="rerun the same `sparselt sample` command with --verify"):
        np.asarray(load_signal(sampled).data)
    assert main(SAMPLE + ["--out", str(sampled), "--verify"]) == 0
    zarr_store._VERIFIED_CHUNKS.clear()
    np.asarray(load_signal(sampled).data)


def test_a_store_completed_before_chunk_signatures_is_verified_once(sampled, chunk_reads, capsys):
    group = json.loads((sampled / "zarr.json").read_text())
    del group["attributes"]["chunk_files"]
    (sampled / "zarr.json").write_text(json.dumps(group))
    assert main(SAMPLE + ["--out", str(sampled)]) == 0
    assert "is complete" in capsys.readouterr().out and sorted(chunk_reads) == list(range(12))
    assert len(json.loads((sampled / "zarr.json").read_text())["attributes"]["chunk_files"]) == 12
    zarr_store._VERIFIED_CHUNKS.clear()
    chunk_reads.clear()
    assert main(SAMPLE + ["--out", str(sampled)]) == 0
    assert "is complete" in capsys.readouterr().out and chunk_reads == []


def test_rerun_of_a_complete_compare_says_complete(tmp_path, capsys):
    out = tmp_path / "compare"
    assert main(COMPARE + ["--out", str(out)]) == 0
    capsys.readouterr()
    assert main(COMPARE + ["--out", str(out)]) == 0
    assert f"compare: {out} is complete" in capsys.readouterr().out
    assert json.loads((out / MANIFEST_FILE).read_text())["status"] == "complete"
    assert not (out / LOCK_FILE).exists()
