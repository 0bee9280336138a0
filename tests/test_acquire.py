"""Signal stores: durable chunks, resume after a kill, provenance, and every bad input."""

import json
import os
import signal as posix_signal
import subprocess
import sys
import time

import numpy as np
import pytest

from sparselt import IncompleteSignalError, NonFiniteSampleError, load_signal
from sparselt.rendering.acquire import AcquisitionConfig, acquire_signal
from sparselt.rendering.scenes import SceneSpec

PATH_SHAPE = (8, 6, 2, 2, 2, 2, 2, 2, 2, 2)


def _config(**changes):
    values = dict(scene="cornell-box", kind="path", shape=PATH_SHAPE, spp=4, seed=2)
    values.update(changes)
    return AcquisitionConfig(**values)


def test_folder_round_trip_records_provenance(tmp_path, cornell):
    memory = acquire_signal(_config(), progress=False, scene_spec=cornell)
    signal = acquire_signal(_config(), tmp_path / "signal", progress=False, scene_spec=cornell)
    assert np.array_equal(np.asarray(signal.data), memory.data)
    assert signal.shape == PATH_SHAPE and signal.data.shape == PATH_SHAPE + (3,)
    assert signal.kind == "path" and signal.axes[:2] == ("x", "y") and len(signal.axes) == 10
    meta = signal.meta
    assert meta["status"] == "complete" and meta["seed"] == 2 and meta["spp"] == 4 and meta["max_depth"] == 3
    assert meta["scene"] == "cornell-box"
    for package in ("mitsuba", "drjit", "numpy", "sparselt"):
        assert meta["provenance"]["versions"][package]
    assert "git" in meta["provenance"]
    assert signal.image().shape == (6, 8, 3)
    assert not os.path.exists(tmp_path / "signal" / "chunks.jsonl")
    assert not os.path.exists(tmp_path / "signal" / ".sparselt.lock")
    assert len(meta["chunk_crc32"]) == meta["chunk_count"]


def test_store_is_readable_by_xarray_and_dask_without_sparselt(tmp_path, cornell):
    import dask.array
    import xarray

    signal = acquire_signal(_config(), tmp_path / "s", progress=False, scene_spec=cornell, chunk_cells=300)
    dataset = xarray.open_zarr(tmp_path / "s", consolidated=False)
    assert dataset["data"].dims == signal.axes + ("channel",) and dataset.attrs["seed"] == 2
    lazy = dask.array.from_zarr(str(tmp_path / "s"), component="data")
    assert lazy.chunksize == tuple(signal.meta["chunk_shape"]) + (3,)
    assert np.array_equal(lazy.compute(), np.asarray(signal.data))


def test_same_seed_any_chunking_same_bytes(tmp_path, cornell):
    stored = [np.asarray(acquire_signal(_config(), tmp_path / str(chunk), progress=False, scene_spec=cornell,
                                        chunk_cells=chunk).data) for chunk in (97, 256, 300, 100000)]
    for data in stored[1:]:
        assert data.tobytes() == stored[0].tobytes()


def test_image_is_the_mean_over_non_image_axes_transposed(tmp_path, cornell):
    signal = acquire_signal(_config(), tmp_path / "s", progress=False, scene_spec=cornell)
    data = np.asarray(signal.data, dtype=np.float64)
    expected = data.reshape(8, 6, -1, 3).mean(axis=2).transpose(1, 0, 2)
    assert np.allclose(signal.image(rows_per_block=3), expected, rtol=1e-6)


def test_existing_signal_needs_overwrite(tmp_path, cornell):
    first = acquire_signal(_config(), tmp_path / "s", progress=False, scene_spec=cornell)
    again = acquire_signal(_config(), tmp_path / "s", progress=False, scene_spec=cornell)  # complete: returned as is
    assert again.meta["provenance"] == first.meta["provenance"]
    with pytest.raises(ValueError, match=r"another configuration \(seed: 2 recorded, 5 now\); pass --overwrite"):
        acquire_signal(_config(seed=5), tmp_path / "s", progress=False, scene_spec=cornell)
    replaced = acquire_signal(_config(seed=5), tmp_path / "s", overwrite=True, progress=False, scene_spec=cornell)
    assert replaced.meta["seed"] == 5


def test_non_signal_folder_is_not_touched(tmp_path, cornell):
    (tmp_path / "thesis.md").write_text("precious")
    with pytest.raises(ValueError, match="not a signal"):
        acquire_signal(_config(), tmp_path, progress=False, scene_spec=cornell)
    assert (tmp_path / "thesis.md").read_text() == "precious"


def test_output_under_a_file_is_refused_naming_it(tmp_path, cornell):
    # A path under a regular file cannot be created, by root or anyone else.
    (tmp_path / "file").write_text("x")
    target = tmp_path / "file" / "signal"
    with pytest.raises(ValueError) as raised:
        acquire_signal(_config(), target, progress=False, scene_spec=cornell)
    assert raised.type is ValueError
    assert str(raised.value) == (f"output path {str(target)!r} cannot be created: {str(tmp_path / 'file')!r} is a "
                                 "file, not a folder; choose another --out")
    assert (tmp_path / "file").read_text() == "x"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_output_in_a_read_only_folder_is_refused_naming_it(tmp_path, cornell):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    target = locked / "signal"
    with pytest.raises(ValueError) as raised:
        acquire_signal(_config(), target, progress=False, scene_spec=cornell)
    assert raised.type is ValueError
    assert str(raised.value) == (f"cannot create the output folder {str(target)!r}: no permission to write there; "
                                 "choose another --out")


def test_resume_after_kill_gives_the_same_data(tmp_path):
    """SIGKILL a real `sparselt sample` run mid-way, check nothing loads, resume, compare."""
    shape = "24,24,2,2,2,2,2,2,2,2"
    out = tmp_path / "killed"
    command = [sys.executable, "-m", "sparselt.cli", "sample", "--scene", "cornell-box", "--kind", "path",
               "--shape", shape, "--spp", "8", "--seed", "9", "--out", str(out), "--chunk-cells", "512", "--no-progress"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    journal = out / "chunks.jsonl"
    deadline = time.time() + 120
    finished = 0
    while time.time() < deadline and process.poll() is None:
        try:
            finished = journal.read_text().count("\n")
        except OSError:
            finished = 0
        if finished >= 5:
            break
        time.sleep(0.02)
    assert process.poll() is None, "the run finished before it could be killed; make the signal larger"
    process.send_signal(posix_signal.SIGKILL)
    process.wait()
    assert 5 <= finished < 288
    with pytest.raises(IncompleteSignalError, match="resume"):
        load_signal(out)
    assert json.loads((out / "zarr.json").read_text())["attributes"]["status"] == "incomplete"

    resumed = subprocess.run(command, capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    reference = tmp_path / "reference"
    subprocess.run(command[:command.index("--out") + 1] + [str(reference), "--no-progress"], check=True,
                   stdout=subprocess.DEVNULL)
    assert np.array_equal(np.asarray(load_signal(out).data), np.asarray(load_signal(reference).data))


def test_resume_with_another_configuration_is_refused(tmp_path, cornell):
    out = tmp_path / "s"
    acquire_signal(_config(), out, progress=False, scene_spec=cornell, chunk_cells=64)
    # Turn it into an interrupted run of this configuration, then ask for another one.
    group = json.loads((out / "zarr.json").read_text())
    group["attributes"]["status"] = "incomplete"
    (out / "zarr.json").write_text(json.dumps(group))
    (out / "chunks.jsonl").write_text("")
    with pytest.raises(ValueError, match="different configuration"):
        acquire_signal(_config(seed=3), out, progress=False, scene_spec=cornell)
    # The same configuration resumes.
    assert acquire_signal(_config(), out, progress=False, scene_spec=cornell).meta["status"] == "complete"


def _infinite_light_scene(cornell):
    objects = dict(cornell.objects)
    objects["light"] = dict(objects["light"], emitter={"type": "area", "radiance": {"type": "rgb", "value": [1e39, 1.0, 1.0]}})
    return SceneSpec(name="infinite-light", description="overflowing emitter", objects=objects, camera=cornell.camera)


def test_nonfinite_samples_stop_the_run_with_a_count(tmp_path, cornell):
    scene = _infinite_light_scene(cornell)
    with pytest.raises(NonFiniteSampleError, match="NaN or infinite samples"):
        acquire_signal(_config(), tmp_path / "s", progress=False, scene_spec=scene)
    with pytest.raises(IncompleteSignalError):
        load_signal(tmp_path / "s")


def test_nonfinite_samples_counted_and_zeroed_on_request(cornell):
    signal = acquire_signal(_config(nonfinite="zero"), progress=False, scene_spec=_infinite_light_scene(cornell))
    assert signal.meta["nonfinite_samples"] > 0
    assert np.all(np.isfinite(signal.data))


@pytest.mark.parametrize("arguments, error, message", [
    (dict(spp=0), ValueError, "spp"),
    (dict(spp=-3), ValueError, "spp"),
    (dict(seed=-1), ValueError, "seed"),
    (dict(shape=(8, 8, 4, 4)), ValueError, "has 4 axes but kind 'path'"),
    (dict(shape=(8,)), ValueError, "two image-plane axes"),
    (dict(shape=(8, 0, 2, 2)), ValueError, "every shape entry"),
    (dict(kind="dof", shape=(8, 8, 4, 4)), ValueError, "--aperture"),
    (dict(kind="volumes"), ValueError, "choose one of"),
    (dict(max_depth=0), ValueError, "max_depth"),
    (dict(nonfinite="ignore"), ValueError, "nonfinite"),
    # 4.1e9 cells of 12 bytes: 49 GB, more than half the memory of any machine this runs on.
    (dict(kind="indirect", shape=(2000, 2000, 32, 32)), ValueError, "give an output path"),
    (dict(shape=(1000, 1000, 4, 4, 4, 4, 4, 4, 4, 4)), ValueError, "2\\*\\*32"),
], ids=["spp-zero", "negative-spp", "negative-seed", "shape-of-another-kind", "one-axis-shape", "zero-resolution",
        "dof-on-a-pinhole-camera", "unknown-kind", "max-depth-zero", "unknown-nonfinite",
        "too-large-for-memory-without-a-path", "more-than-2**32-cells"])
def test_acquire_signal_invalid_configuration(arguments, error, message, cornell):
    """The configuration (changes to _config) is refused before anything is rendered."""
    with pytest.raises(error, match=message):
        acquire_signal(_config(**arguments), progress=False, scene_spec=cornell)


def test_unknown_scene_is_refused_with_the_names():
    with pytest.raises(ValueError, match="cornell-caustics"):
        acquire_signal(_config(scene="san-miguel"), progress=False)


def test_refused_configuration_creates_no_folder(tmp_path, cornell):
    target = tmp_path / "never"
    with pytest.raises(ValueError, match="--aperture"):
        acquire_signal(_config(kind="dof", shape=(8, 8, 4, 4)), target, progress=False, scene_spec=cornell)
    assert not target.exists()
