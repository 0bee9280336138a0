"""Issue 9: signal stores that cannot be corrupted, and acquisition on a real Dask cluster.

Each of the five ways a signal used to come out silently wrong (or a finished one
got lost) is reproduced with real runs of `sparselt sample` and now gives a
clear error or the correct signal.
"""

import json
import os
import signal as posix_signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from sparselt import load_signal
from sparselt.rendering.acquire import AcquisitionConfig, acquire_signal
from sparselt.storage import StoreLock, StoreLockedError

DOF = ["--scene", "cornell-box", "--kind", "dof", "--aperture", "0.1"]
SPHERE = """<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="45"/>
    <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1.0"/></emitter>
  <shape type="obj"><string name="filename" value="quad.obj"/><bsdf type="diffuse"><rgb name="reflectance" value="{albedo}"/></bsdf></shape>
</scene>
"""
QUAD = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n"


def command(out, *arguments, shape="48,48,4,4", spp=8, seed=5, chunk=256):
    return [sys.executable, "-m", "sparselt.cli", "sample", *arguments, "--shape", shape, "--spp", str(spp),
            "--seed", str(seed), "--out", str(out), "--chunk-cells", str(chunk), "--no-progress"]


def journal_lines(out):
    try:
        return (out / "chunks.jsonl").read_text().count("\n")
    except OSError:
        return 0


def wait_for(predicate, process, what, timeout=120):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return
        assert process.poll() is None, f"the run ended before {what}: {process.stderr.read() if process.stderr else ''}"
        time.sleep(0.01)
    raise AssertionError(f"timed out waiting for {what}")


def killed_run(arguments, out, *, after=4):
    """A real `sparselt sample` run SIGKILLed once it has recorded ``after`` chunks."""
    process = subprocess.Popen(arguments, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wait_for(lambda: journal_lines(out) >= after, process, f"{after} chunks were recorded")
    process.send_signal(posix_signal.SIGKILL)
    process.wait()
    return process.pid


def data_of(path):
    return np.asarray(load_signal(path).data)


def reference(tmp_path, arguments):
    out = tmp_path / "reference"
    arguments = list(arguments)
    arguments[arguments.index("--out") + 1] = str(out)
    subprocess.run(arguments, check=True, stdout=subprocess.DEVNULL)
    return data_of(out)


# -- 1. concurrent writers ----------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [5, 6])
def test_second_writer_is_refused_with_the_holders_pid_and_host(tmp_path, seed):
    """The issue's two `sample` runs into one --out at once (same or another seed): the second is refused."""
    out = tmp_path / "signal"
    first = subprocess.Popen(command(out, *DOF, shape="64,64,8,8", seed=5, chunk=16), stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True)
    try:
        wait_for(lambda: journal_lines(out) >= 1, first, "the first run started writing")
        second = subprocess.run(command(out, *DOF, shape="64,64,8,8", seed=seed, chunk=16), capture_output=True,
                                text=True)
        assert first.poll() is None, "the first run ended before the second started: make it longer"
    finally:
        first.kill()
        first.wait()
    assert second.returncode == 2 and "Traceback" not in second.stderr
    assert f"PID {first.pid}" in second.stderr and socket.gethostname() in second.stderr
    assert "is being written by" in second.stderr
    assert json.loads((out / "zarr.json").read_text())["attributes"]["seed"] == 5


def test_lock_of_a_killed_run_is_taken_over(tmp_path):
    out = tmp_path / "signal"
    arguments = command(out, *DOF, chunk=64)
    pid = killed_run(arguments, out)
    holder = json.loads((out / ".sparselt.lock").read_text())
    assert holder["pid"] == pid and holder["host"] == socket.gethostname()  # the dead run's record is still there
    resumed = subprocess.run(arguments, capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    assert f"took over the lock of a run that is gone (PID {pid}" in resumed.stdout
    assert not (out / ".sparselt.lock").exists()
    assert np.array_equal(data_of(out), reference(tmp_path, arguments))


def test_lock_is_exclusive_in_one_process_too(tmp_path):
    with StoreLock(tmp_path):
        with pytest.raises(StoreLockedError, match=f"PID {os.getpid()}"):
            StoreLock(tmp_path).acquire()
    with StoreLock(tmp_path):  # released: free again
        pass


# -- 2. the scene changed between the interrupted run and the resume ----------------------------------


def write_xml_scene(folder, albedo="0.5, 0.5, 0.5"):
    (folder / "quad.obj").write_text(QUAD)
    path = folder / "scene.xml"
    path.write_text(SPHERE.format(albedo=albedo))
    return path


@pytest.mark.parametrize("edit", ["xml", "referenced mesh"])
def test_resume_after_the_scene_was_edited_is_refused(tmp_path, edit):
    scene = write_xml_scene(tmp_path)
    out = tmp_path / "signal"
    arguments = command(out, "--scene", str(scene), "--kind", "path", shape="16,16,2,2,2,2,2,2,2,2", spp=2, chunk=256)
    killed_run(arguments, out)
    if edit == "xml":
        write_xml_scene(tmp_path, albedo="0.9, 0.1, 0.1")
    else:
        (tmp_path / "quad.obj").write_text(QUAD.replace("v 1 1 0", "v 1.5 1 0"))
    result = subprocess.run(arguments, capture_output=True, text=True)
    assert result.returncode == 2 and "has changed since it was started" in result.stderr
    assert ("scene.xml" if edit == "xml" else "quad.obj") in result.stderr
    assert json.loads((out / "zarr.json").read_text())["attributes"]["status"] == "incomplete"
    # --overwrite starts again with the new scene, and the signal is the new scene's alone.
    assert subprocess.run(arguments + ["--overwrite"], capture_output=True).returncode == 0
    assert np.array_equal(data_of(out), reference(tmp_path, arguments))


# -- 3. --overwrite with a scene that does not load ----------------------------------------------------


def test_overwrite_with_a_broken_scene_keeps_the_old_signal(tmp_path):
    scene = write_xml_scene(tmp_path)
    out = tmp_path / "signal"
    arguments = command(out, "--scene", str(scene), "--kind", "path", shape="16,16,2,2,2,2,2,2,2,2", spp=2)
    assert subprocess.run(arguments, capture_output=True).returncode == 0
    before = data_of(out)
    scene.write_text(scene.read_text().replace("</scene>", "<shape type="))  # an XML syntax error
    result = subprocess.run(arguments + ["--overwrite"], capture_output=True, text=True)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert np.array_equal(data_of(out), before)
    scene.write_text(SPHERE.format(albedo="0.5, 0.5, 0.5").replace('value="quad.obj"', 'value="missing.obj"'))
    result = subprocess.run(arguments + ["--overwrite"], capture_output=True, text=True)
    assert result.returncode == 2 and np.array_equal(data_of(out), before)


# -- 4. damaged chunks are sampled again, never trusted ------------------------------------------------


def test_truncated_or_corrupted_chunks_are_sampled_again(tmp_path):
    out = tmp_path / "signal"
    arguments = command(out, *DOF, chunk=64)
    killed_run(arguments, out, after=6)
    meta = json.loads((out / "zarr.json").read_text())["attributes"]
    chunk_files = sorted((out / "data" / "c").rglob("*"), key=lambda p: p.stat().st_mtime)
    chunk_files = [p for p in chunk_files if p.is_file() and not p.name.endswith(".partial")]
    truncated, corrupted, removed = chunk_files[0], chunk_files[1], chunk_files[2]
    truncated.write_bytes(truncated.read_bytes()[: truncated.stat().st_size // 2])
    payload = bytearray(corrupted.read_bytes())
    payload[-5] ^= 0xFF
    corrupted.write_bytes(bytes(payload))
    removed.unlink()
    result = subprocess.run(arguments[:-1], capture_output=True, text=True)  # with progress: the note is printed
    assert result.returncode == 0, result.stderr
    assert "recorded chunks" in result.stdout and "sampling them again" in result.stdout
    assert meta["status"] == "incomplete"
    assert np.array_equal(data_of(out), reference(tmp_path, arguments))


def test_a_complete_signal_with_a_missing_chunk_does_not_load(tmp_path):
    out = tmp_path / "signal"
    assert subprocess.run(command(out, *DOF, shape="16,16,2,2", chunk=64), capture_output=True).returncode == 0
    next(p for p in (out / "data" / "c").rglob("*") if p.is_file()).unlink()
    with pytest.raises(ValueError, match="damaged: 1 of 16 chunk files are missing"):
        load_signal(out)


# -- 5. limits are checked before anything is written; a full disk is a clear, resumable error -----------


def test_limits_are_checked_before_the_folder_exists(tmp_path, cornell):
    from sparselt.cli import main

    target = tmp_path / "never"
    assert main(["sample", *DOF, "--shape", "16,16,4,4", "--spp", "64", "--chunk-cells", str(2**26),
                 "--out", str(target), "--no-progress"]) == 2
    assert not target.exists()
    deep = ",".join(["2"] * 66)
    assert main(["sample", "--scene", "cornell-box", "--kind", "path", "--max-depth", "17", "--shape", deep,
                 "--spp", "1", "--out", str(target), "--no-progress"]) == 2
    assert not target.exists()
    with pytest.raises(ValueError, match="max depth <= 16"):
        acquire_signal(AcquisitionConfig(scene="cornell-box", kind="path", shape=(2, 2) + (1,) * 64, spp=1, max_depth=17),
                       target, progress=False, scene_spec=cornell)
    assert not target.exists()


@pytest.fixture
def small_disk(tmp_path):
    """A real 3 MB file system (tmpfs); skipped where mounting is not allowed."""
    mount_point = tmp_path / "disk"
    mount_point.mkdir()
    result = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(mount_point)], capture_output=True)
    if result.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here ({result.stderr.decode().strip()})")
    yield mount_point
    subprocess.run(["umount", "-l", str(mount_point)], check=False)


def test_disk_space_is_checked_with_its_unit_before_writing(small_disk, cornell):
    config = AcquisitionConfig(scene="cornell-box", kind="dof", shape=(128, 128, 8, 8), spp=1, aperture=0.1)
    with pytest.raises(ValueError, match=r"takes up to 12\.6 MB but only 3\.1 MB of disk is free"):
        acquire_signal(config, small_disk / "signal", progress=False, scene_spec=cornell)
    assert not (small_disk / "signal").exists()


def test_a_disk_that_fills_mid_run_gives_a_clear_error_and_resumes(small_disk, tmp_path):
    out = small_disk / "signal"
    arguments = command(out, *DOF, shape="48,48,8,8", spp=16, chunk=1024)  # 1.8 MB: fits the 3 MB disk
    process = subprocess.Popen(arguments, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wait_for(lambda: journal_lines(out) >= 3, process, "3 chunks were recorded")
    filler = small_disk / "filler"
    with open(filler, "wb") as handle:  # another program takes the rest of the disk
        try:
            while True:
                handle.write(b"\0" * 65536)
                handle.flush()
        except OSError:
            pass
    stderr = process.communicate(timeout=120)[1]
    assert process.returncode == 2 and "Traceback" not in stderr
    assert "no space left on the device" in stderr and "rerun the same command to resume" in stderr
    filler.unlink()
    resumed = subprocess.run(arguments, capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    assert not list((out / "data").rglob("*.partial"))
    assert np.array_equal(data_of(out), reference(tmp_path, arguments))


# -- Dask ---------------------------------------------------------------------------------------------


def test_two_local_workers_write_the_same_bytes_as_the_in_process_run(tmp_path):
    out = tmp_path / "distributed"
    arguments = command(out, *DOF, shape="32,32,4,4", chunk=128)
    result = subprocess.run(arguments + ["--workers", "2"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "dashboard at http" in result.stdout
    local = tmp_path / "local"
    subprocess.run(command(local, *DOF, shape="32,32,4,4", chunk=128), check=True, stdout=subprocess.DEVNULL)
    files = sorted(p.relative_to(local) for p in (local / "data").rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(out) for p in (out / "data").rglob("*") if p.is_file())
    for name in files:
        assert (local / name).read_bytes() == (out / name).read_bytes(), name
    assert load_signal(out).meta["chunk_crc32"] == load_signal(local).meta["chunk_crc32"]


def test_a_worker_killed_mid_run_still_gives_the_identical_signal(tmp_path):
    psutil = pytest.importorskip("psutil")
    out = tmp_path / "distributed"
    arguments = command(out, *DOF, shape="32,32,8,8", spp=16, chunk=128)
    process = subprocess.Popen(arguments + ["--workers", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(lambda: journal_lines(out) >= 4, process, "the workers recorded 4 chunks", timeout=180)
    workers = [child for child in psutil.Process(process.pid).children(recursive=True)
               if "spawn" in " ".join(child.cmdline()) or "forkserver" in " ".join(child.cmdline())]
    assert workers, "no Dask worker process found"
    os.kill(workers[0].pid, posix_signal.SIGKILL)
    stdout, stderr = process.communicate(timeout=300)
    assert process.returncode == 0, stderr
    assert journal_lines(out) == 0  # complete: the journal is folded into the metadata
    assert np.array_equal(data_of(out), reference(tmp_path, arguments))


# -- readers of big signals go chunk by chunk ---------------------------------------------------------------


def test_out_of_core_gini_and_image_read_the_store_chunk_by_chunk(tmp_path, cornell):
    from sparselt.analysis.sparsity import signal_gini

    config = AcquisitionConfig(scene="cornell-box", kind="dof", shape=(32, 32, 8, 8), spp=2, aperture=0.1)
    stored = acquire_signal(config, tmp_path / "s", progress=False, scene_spec=cornell, chunk_cells=4096)
    in_memory = acquire_signal(config, progress=False, scene_spec=cornell)
    assert not isinstance(stored.data, np.ndarray)  # lazily chunked, not loaded
    assert np.array_equal(stored.image(), in_memory.image())
    for domain in ("canonical", "fourier"):
        exact = signal_gini(in_memory, domain=domain)
        streamed = signal_gini(stored, domain=domain, memory_limit_bytes=2**20, buckets=2**12)
        assert exact.exact and not streamed.exact
        assert np.all(np.abs(streamed.values - exact.values) <= streamed.error_bounds + 1e-12)


def test_show_on_a_dask_cluster_writes_the_same_image(tmp_path):
    signal = tmp_path / "signal"
    assert subprocess.run(command(signal, *DOF, shape="32,32,4,4", chunk=1024), capture_output=True).returncode == 0
    local = subprocess.run([sys.executable, "-m", "sparselt.cli", "show", str(signal), "--out", str(tmp_path / "a")],
                           capture_output=True, text=True)
    cluster = subprocess.run([sys.executable, "-m", "sparselt.cli", "show", str(signal), "--out", str(tmp_path / "b"),
                              "--workers", "2"], capture_output=True, text=True)
    assert local.returncode == 0 and cluster.returncode == 0, cluster.stderr
    assert "dashboard at http" in cluster.stdout
    from matplotlib import image

    assert np.array_equal(image.imread(tmp_path / "a" / "image.png"), image.imread(tmp_path / "b" / "image.png"))


def test_an_fsspec_url_is_refused_with_a_message(cornell):
    config = AcquisitionConfig(scene="cornell-box", kind="dof", shape=(8, 8, 2, 2), spp=1, aperture=0.1)
    with pytest.raises(ValueError, match="only file-system paths are supported"):
        acquire_signal(config, "s3://bucket/signal", progress=False, scene_spec=cornell)


def test_a_store_recreated_with_another_chunking_is_never_written_through_a_stale_handle(tmp_path):
    """A cluster worker keeps its store handle between runs; a store rebuilt at the same path is reopened."""
    import numpy as np

    from sparselt.storage import zarr_store

    path = tmp_path / "store"
    first = zarr_store.ChunkGrid.for_cells((4, 4, 2, 2), 16)
    zarr_store.create_store(path, first, ("x", "y", "u", "v"), {})
    zarr_store.write_chunk(path, first, 0, np.ones((first.chunk(0)[1], 3)))
    zarr_store.remove_store(path)  # another process removes and recreates it: this process's cache is not told
    second = zarr_store.ChunkGrid.for_cells((4, 4, 2, 2), 32)
    zarr_store.create_store(path, second, ("x", "y", "u", "v"), {})
    _, count, region = second.chunk(1)
    values = np.arange(count * 3, dtype=np.float32).reshape(count, 3)
    zarr_store.write_chunk(path, second, 1, values)
    stored = np.asarray(zarr_store.open_data(path)[region]).reshape(count, 3)
    assert np.array_equal(stored, values)
