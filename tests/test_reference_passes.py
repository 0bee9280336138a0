"""The comparison reference in resumable 64-spp passes (thesis 8.1.1; Jung et al. 2020): one verified file per
pass, a longer reference continuing a shorter one, an interrupted one resuming, a garbled pass rendered again,
a deadline stopping at the passes that exist (never below two), and a Dask cluster giving the same bytes."""

import math
import os
import time

import numpy as np
import pytest

from sparselt.rendering.baseline import (
    REFERENCE_PASS_SPP,
    cached_reference,
    reference_pass_seed,
    reference_relmse_floor,
    reference_spp_for_floor,
)
from sparselt.rendering.reference_passes import pass_paths
from sparselt.rendering.setup import SceneSetup

RESOLUTION = (24, 24)
MAX_DEPTH = 2


@pytest.fixture(scope="module")
def setup():
    return SceneSetup(scene="cornell-box", kind="path", max_depth=MAX_DEPTH)


@pytest.fixture(scope="module")
def scene(setup):
    return setup.load(RESOLUTION).scene


class Interrupted(RuntimeError):
    """What the wrapped renderer raises in place of a pass (a killed run)."""


class CountingScene:
    """The loaded scene, recording the seed of every ``render_path`` call; raising on call ``fail_at`` (from 0)."""

    def __init__(self, scene, fail_at=None, nonfinite=False):
        self.scene, self.fail_at, self.nonfinite, self.seeds = scene, fail_at, nonfinite, []

    def __getattr__(self, name):
        return getattr(self.scene, name)

    def render_path(self, spp, max_depth, seed=0):
        if self.fail_at is not None and len(self.seeds) == self.fail_at:
            raise Interrupted(f"killed before the pass of seed {seed}")
        self.seeds.append(seed)
        image, seconds = self.scene.render_path(spp, max_depth, seed)
        if self.nonfinite:
            image = image.copy()
            image[3, 4, 1] = np.nan
        return image, seconds


def reference(scene, cache, spp, **keywords):
    return cached_reference(scene, "path", spp=spp, max_depth=MAX_DEPTH, seed=0, progress=False,
                            cache_directory=str(cache), **keywords)


def passes_of(seeds):
    """The pass indices of the seeds a renderer was called with."""
    return [seed - reference_pass_seed(0, 0) for seed in seeds]


def file_identity(path):
    status = os.stat(path)
    return status.st_ino, status.st_mtime_ns


def test_a_longer_reference_renders_only_the_missing_passes(tmp_path, scene):
    counting = CountingScene(scene)
    short, record = reference(counting, tmp_path / "cache", 2 * REFERENCE_PASS_SPP)
    assert passes_of(counting.seeds) == [0, 1] and record["passes"] == 2 and not record["cached"]
    kept = {index: file_identity(path) for index in (0, 1) for path in pass_paths(record["folder"], index)}

    counting = CountingScene(scene)
    longer, record = reference(counting, tmp_path / "cache", 5 * REFERENCE_PASS_SPP - 10)  # rounded up: 5 passes
    assert passes_of(counting.seeds) == [2, 3, 4]
    assert record["passes"] == 5 and record["spp"] == 320 and record["requested_spp"] == 310
    assert record["passes_rendered"] == 3 and record["cached"] is False and record["complete"]
    assert kept == {index: file_identity(path) for index in (0, 1) for path in pass_paths(record["folder"], index)}

    fresh, fresh_record = reference(scene, tmp_path / "fresh", 5 * REFERENCE_PASS_SPP)
    assert longer.dtype == np.float32 and longer.shape == (RESOLUTION[1], RESOLUTION[0], 3)
    assert longer.tobytes() == fresh.tobytes() and record["variance"].tobytes() == fresh_record["variance"].tobytes()
    assert fresh_record["key"] == record["key"]  # the key holds no spp
    assert short.tobytes() != longer.tobytes()

    counting = CountingScene(scene)
    again, record = reference(counting, tmp_path / "cache", 3 * REFERENCE_PASS_SPP)  # a shorter one: a prefix
    assert counting.seeds == [] and record["cached"] is True and record["passes"] == 3
    assert again.tobytes() == reference(scene, tmp_path / "three", 3 * REFERENCE_PASS_SPP)[0].tobytes()
    assert record["seconds"] > 0 and record["seconds_this_run"] == 0 and record["machines"]
    assert np.load(record["path"]).tobytes() == again.tobytes()


def test_an_interrupted_reference_resumes_without_redoing_finished_passes(tmp_path, scene):
    with pytest.raises(Interrupted):
        reference(CountingScene(scene, fail_at=3), tmp_path / "cache", 6 * REFERENCE_PASS_SPP)
    counting = CountingScene(scene)
    image, record = reference(counting, tmp_path / "cache", 6 * REFERENCE_PASS_SPP)
    assert passes_of(counting.seeds) == [3, 4, 5]
    assert record["passes"] == 6 and record["passes_rendered"] == 3
    assert record["seconds"] > record["seconds_this_run"] > 0  # the earlier run's passes are counted
    fresh, _ = reference(scene, tmp_path / "fresh", 6 * REFERENCE_PASS_SPP)
    assert image.tobytes() == fresh.tobytes()


def garble_pixels(path):
    with open(path, "rb") as handle:
        data = bytearray(handle.read())
    data[-64:] = b"\x11" * 64  # the header stays readable: only the record's SHA-256 tells
    with open(path, "wb") as handle:
        handle.write(bytes(data))


def test_a_garbled_pass_is_detected_by_its_digest_and_rendered_again(tmp_path, scene, capsys):
    image, record = reference(scene, tmp_path / "cache", 4 * REFERENCE_PASS_SPP)
    garble_pixels(pass_paths(record["folder"], 1)[0])
    os.remove(pass_paths(record["folder"], 2)[1])  # an image without its record: a run killed between the two
    capsys.readouterr()
    counting = CountingScene(scene)
    again, record = reference(counting, tmp_path / "cache", 4 * REFERENCE_PASS_SPP)
    error = capsys.readouterr().err
    assert passes_of(counting.seeds) == [1, 2] and record["cached"] is False
    assert "reference pass 1" in error and "SHA-256" in error and "reference pass 2" not in error
    assert again.tobytes() == image.tobytes()
    counting = CountingScene(scene)
    reference(counting, tmp_path / "cache", 4 * REFERENCE_PASS_SPP)
    assert counting.seeds == []  # replaced, and trusted again


def test_a_pass_with_nonfinite_pixels_is_refused_and_not_written(tmp_path, scene):
    with pytest.raises(ValueError, match=r"NaN or infinite pixels in pass 0"):
        reference(CountingScene(scene, nonfinite=True), tmp_path / "cache", REFERENCE_PASS_SPP)
    assert not any(name.endswith(".json") for _, _, names in os.walk(tmp_path) for name in names)


def test_a_past_deadline_still_gives_two_passes_and_says_so(tmp_path, scene):
    counting = CountingScene(scene)
    image, record = reference(counting, tmp_path / "cache", 10 * REFERENCE_PASS_SPP, deadline=time.monotonic() - 1)
    assert passes_of(counting.seeds) == [0, 1]
    assert record["passes"] == 2 and record["spp"] == 128 and record["requested_spp"] == 640
    assert record["requested_passes"] == 10 and record["complete"] is False and record["deadline_reached"] is True
    assert record["relmse_floor"] == pytest.approx(reference_relmse_floor(image, record["variance"], epsilon=0.01))
    assert image.tobytes() == reference(scene, tmp_path / "fresh", 2 * REFERENCE_PASS_SPP)[0].tobytes()

    reference(scene, tmp_path / "cache", 3 * REFERENCE_PASS_SPP)  # pass 2 now exists
    counting = CountingScene(scene)
    _, record = reference(counting, tmp_path / "cache", 10 * REFERENCE_PASS_SPP, deadline=time.monotonic() - 1)
    assert counting.seeds == [] and record["passes"] == 3 and record["cached"] is True

    counting = CountingScene(scene)
    _, record = reference(counting, tmp_path / "one", REFERENCE_PASS_SPP, deadline=time.monotonic() - 1)
    assert record["passes"] == 1 and record["relmse_floor"] is None  # one pass asked for: no floor
    assert np.all(np.isnan(record["variance"]))


@pytest.mark.timeout(60)
def test_a_dask_cluster_gives_the_same_bytes_as_an_in_process_render(tmp_path, scene, setup):
    from dask.distributed import LocalCluster

    local, local_record = reference(scene, tmp_path / "local", 4 * REFERENCE_PASS_SPP)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        _, first = reference(scene, tmp_path / "cluster", 4 * REFERENCE_PASS_SPP, scheduler=cluster.scheduler_address,
                             setup=setup, deadline=time.monotonic() - 1)
        remote, record = reference(scene, tmp_path / "cluster", 4 * REFERENCE_PASS_SPP,
                                   scheduler=cluster.scheduler_address, setup=setup)
    assert first["passes"] == 2 and first["passes_rendered"] == 2  # past the deadline: the floor's two passes
    assert remote.tobytes() == local.tobytes()
    assert record["variance"].tobytes() == local_record["variance"].tobytes()
    assert record["machines"] and record["passes"] == 4 and record["passes_rendered"] == 2  # resumed
    assert record["key"] == local_record["key"]


def test_cluster_arguments_are_checked(tmp_path, scene):
    with pytest.raises(ValueError, match=r"scheduler 'tcp://127.0.0.1:1' needs setup"):
        reference(scene, tmp_path, 64, scheduler="tcp://127.0.0.1:1")
    with pytest.raises(ValueError, match=r"is not the loaded scene 'cornell-box'"):
        reference(scene, tmp_path, 64, scheduler="tcp://127.0.0.1:1",
                  setup=SceneSetup(scene="cornell-caustics", kind="path", max_depth=MAX_DEPTH))
    with pytest.raises(TypeError, match=r"setup must be a SceneSetup"):
        reference(scene, tmp_path, 64, scheduler="tcp://127.0.0.1:1", setup="cornell-box")


def test_bad_arguments_are_refused(tmp_path, scene):
    with pytest.raises(TypeError, match=r"deadline must be None or a time.monotonic\(\) value, got 'soon'"):
        reference(scene, tmp_path, 64, deadline="soon")
    with pytest.raises(ValueError, match=r"deadline must be None or a finite"):
        reference(scene, tmp_path, 64, deadline=math.inf)
    with pytest.raises(ValueError, match=r"epsilon must be finite and greater than 0"):
        reference(scene, tmp_path, 64, epsilon=0.0)
    with pytest.raises(ValueError, match=r"reference spp must be in \[1, "):
        reference(scene, tmp_path, 0)


def test_reference_spp_for_floor_reaches_the_target_with_the_fewest_whole_passes():
    generator = np.random.default_rng(7)
    for _ in range(500):
        spp = int(generator.integers(1, 5000))
        floor = float(10 ** generator.uniform(-5, -1))
        target = float(floor * 10 ** generator.uniform(-2, 1))
        needed = reference_spp_for_floor(floor, spp, target)
        assert needed % REFERENCE_PASS_SPP == 0 and needed >= spp
        assert floor * spp / needed <= target * (1 + 1e-9)  # the floor falls as 1 / spp
        smaller = needed - REFERENCE_PASS_SPP
        assert smaller < spp or floor * spp / smaller > target  # one pass fewer would not do
    assert reference_spp_for_floor(0.01, 256, 0.0025) == 1024
    assert reference_spp_for_floor(0.01, 256, 0.02) == 256  # already below: never fewer passes
    assert reference_spp_for_floor(0.01, 100, 0.02) == 128  # whole passes


@pytest.mark.parametrize("arguments, error, message", [
    ((0.0, 64, 0.01), ValueError, r"floor must be finite and greater than 0"),
    ((float("nan"), 64, 0.01), ValueError, r"floor must be finite and greater than 0"),
    ((0.01, 64, -1.0), ValueError, r"target_floor must be finite and greater than 0"),
    ((0.01, 0, 0.01), ValueError, r"spp must be >= 1, got 0"),
    ((0.01, 64.0, 0.01), TypeError, r"spp must be an integer"),
])
def test_reference_spp_for_floor_refuses_bad_values(arguments, error, message):
    with pytest.raises(error, match=message):
        reference_spp_for_floor(*arguments)
