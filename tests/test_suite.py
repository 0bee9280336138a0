"""Issue 36: ``sparselt suite`` runs a comparison per scene, aggregates with intervals, resumes, runs on Dask."""

import csv
import json
import math
import os

import numpy as np
import pytest

from sparselt.cli import main
from sparselt.experiments.suite import run_suite
from sparselt.experiments.suite_aggregate import AGGREGATE_COLUMNS
from sparselt.experiments.suite_config import read_suite
from sparselt.experiments.suite_report import SUITE_COLUMNS
from test_reproduce import chromium, rendered_dom  # noqa: F401  (the headless-browser fixture)

SUITE = """\
[suite]
name = "two-scenes"
methods = ["pt", "oidn", "bilateral:sigma_spatial=1.5"]
spp = [4, 16]
seeds = [1, 2, 3]
timing_repeats = 1
reference_spp = 256
resolution = [32, 32]
pt_ladder_max_spp = 128

[[scene]]
name = "box"
scene = "cornell-box"
kind = "path"
reason = "diffuse interreflection"

[[scene]]
name = "plane"
scene = "scenes/plane.xml"
kind = "dof"
aperture = 0.05
parameters = { tiles = 9 }

[[scene]]
name = "plane-path"
scene = "scenes/plane.xml"
kind = "path"
max_depth = 2
parameters = { tiles = 3 }
"""

XML = """<scene version="3.0.0">
  <default name="tiles" value="5"/>
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 1, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/>
      <rfilter type="box"/></film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="3"/></transform>
    <bsdf type="diffuse"><texture type="checkerboard" name="reflectance">
      <transform name="to_uv"><scale x="$tiles" y="$tiles"/></transform></texture></bsdf>
  </shape>
  <shape type="sphere"><point name="center" x="0.6" y="0.5" z="1.5"/><float name="radius" value="0.4"/>
    <bsdf type="diffuse"/></shape>
  <emitter type="constant"><rgb name="radiance" value="0.8"/></emitter>
  <shape type="sphere"><point name="center" x="-2" y="4" z="2"/><float name="radius" value="0.5"/>
    <emitter type="area"><rgb name="radiance" value="20"/></emitter></shape>
</scene>
"""


def suite_file(folder):
    (folder / "scenes").mkdir(parents=True, exist_ok=True)
    (folder / "scenes" / "plane.xml").write_text(XML)
    path = folder / "suite.toml"
    path.write_text(SUITE)
    return path


def read_csv(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A user's suite of a built-in scene and two XML scenes (one file, two parameter sets), a variant among its
    methods, run once (in-process)."""
    folder = tmp_path_factory.mktemp("suite")
    config = read_suite(suite_file(folder))
    out = folder / "out"
    result = run_suite(config, out, progress=False)
    return config, out, result


def test_suite_csv_has_every_scenes_summary_with_its_scene(finished):
    config, out, _ = finished
    rows = read_csv(out / "suite.csv")
    assert list(rows[0]) == list(SUITE_COLUMNS)
    assert {row["scene"] for row in rows} == {"box", "plane", "plane-path"}
    for name in ("box", "plane", "plane-path"):
        own = read_csv(out / "scenes" / name / "summary.csv")
        mine = [row for row in rows if row["scene"] == name]
        assert [(row["method"], row["spp"]) for row in mine] == [(row["method"], row["spp"]) for row in own]
        for row, theirs in zip(mine, own):  # the same verdicts and speed-ups as the scene's own report
            assert row["verdict"] == theirs["verdict"]
            if theirs["speedup_equal_quality"]:
                assert float(row["speedup_equal_quality"]) == pytest.approx(
                    float(theirs["speedup_equal_quality"]), rel=1e-5)
        assert all(row["machine"] == mine[0]["machine"] and "threads" in row["machine"] for row in mine)


def test_the_aggregate_is_the_geometric_mean_over_scenes_with_an_interval_around_it(finished):
    _, out, result = finished
    aggregate = read_csv(out / "aggregate.csv")
    assert list(aggregate[0]) == list(AGGREGATE_COLUMNS)
    suite = read_csv(out / "suite.csv")
    assert {(row["method"], row["spp"]) for row in aggregate} == {
        (row["method"], row["spp"]) for row in suite if row["method"] != "pt"}
    for record in aggregate:
        cells = [row for row in suite if row["method"] == record["method"] and row["spp"] == record["spp"]]
        judged = [row for row in cells if row["verdict"] in ("wins", "loses", "within noise", "one seed")]
        counts = [int(record[key]) for key in ("wins", "within_noise", "loses", "reference_limited", "other")]
        assert sum(counts) == int(record["scenes"]) == len(cells)
        assert int(record["scenes_judged"]) == len(judged)
        if not judged:
            assert record["speedup_geometric_mean"] == ""
            continue
        speedups = [float(row["speedup_equal_quality"]) for row in judged]
        assert float(record["speedup_geometric_mean"]) == pytest.approx(
            math.exp(np.mean(np.log(speedups))), rel=1e-4)
        low, high = float(record["speedup_ci_low"]), float(record["speedup_ci_high"])
        assert low <= float(record["speedup_geometric_mean"]) <= high
        ratio_low, ratio_high = float(record["relmse_ratio_ci_low"]), float(record["relmse_ratio_ci_high"])
        assert ratio_low <= float(record["relmse_ratio_geometric_mean"]) <= ratio_high
        worst = min(judged, key=lambda row: float(row["speedup_equal_quality"]))
        assert record["worst_scene"] == worst["scene"]
    assert "speed-up over PT" in result.table()


def test_a_rerun_resumes_without_running_a_scene_again_and_writes_the_same_bytes(finished):
    config, out, _ = finished
    cells = sorted((out / "scenes" / "box" / "cells").iterdir())
    before = {path.name: path.stat().st_mtime_ns for path in cells}
    aggregate = (out / "aggregate.csv").read_bytes()
    run_suite(config, out, progress=False)
    assert {path.name: path.stat().st_mtime_ns for path in sorted((out / "scenes" / "box" / "cells").iterdir())} \
        == before
    assert (out / "aggregate.csv").read_bytes() == aggregate  # the bootstrap's seed is fixed


def test_a_rerun_of_another_suite_into_the_folder_is_refused(finished, tmp_path):
    import dataclasses

    config, out, _ = finished
    other = dataclasses.replace(config, seeds=(1, 2))
    with pytest.raises(ValueError, match="another suite run"):
        run_suite(other, out, progress=False)


def test_the_page_opens_in_chromium_with_a_working_viewer_per_scene(finished, chromium):  # noqa: F811
    _, out, _ = finished
    dom = rendered_dom(chromium, out / "index.html")
    assert 'data-broken-images=""' in dom
    assert dom.count('data-ready="true"') == 3  # one viewer per scene, every image loaded
    assert "aaf" not in dom.split("<body")[0]  # nothing of another suite
    for name in ("box", "plane", "plane-path"):
        assert f'href="scenes/{name}/index.html"' in dom
        assert os.path.exists(out / "viewer" / name / "reference.png")
        errors = [path for path in os.listdir(out / "viewer" / name) if path.endswith("_error.png")]
        assert len(errors) == 3  # pt, oidn and the variant at matched time


def test_the_cli_runs_a_user_suite(tmp_path, capsys):
    path = suite_file(tmp_path)
    text = path.read_text().replace("seeds = [1, 2, 3]", "seeds = [1, 2]").replace("spp = [4, 16]", "spp = [4]")
    path.write_text(text.split("[[scene]]\nname = \"plane\"")[0])  # the built-in scene alone
    assert main(["suite", str(path), "--out", str(tmp_path / "out"), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "bilateral:sigma_spatial=1.5" in printed and "index.html" in printed


def test_a_loopback_cluster_gives_the_same_images_and_quality_as_in_process(finished, tmp_path):
    """Two worker processes each holding the resource 'machine': same images and quality columns."""
    from dask.distributed import LocalCluster

    config, out, _ = finished
    import dataclasses

    config = dataclasses.replace(config, scenes=config.scenes[:1], spps=(4,))
    local = tmp_path / "local"
    run_suite(config, local, progress=False)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                      resources={"machine": 1}) as cluster:
        remote = tmp_path / "remote"
        run_suite(config, remote, progress=False, scheduler=cluster.scheduler_address)
    images = sorted(path.name for path in (local / "scenes" / "box" / "images").iterdir() if path.suffix == ".npy")
    for name in images:
        if name.startswith("pt_"):
            continue  # PT's ladder rungs follow the timings
        assert (remote / "scenes" / "box" / "images" / name).read_bytes() == \
            (local / "scenes" / "box" / "images" / name).read_bytes(), name
    ours = {(row["method"], row["spp"]): row for row in read_csv(local / "suite.csv") if row["method"] != "pt"}
    theirs = {(row["method"], row["spp"]): row for row in read_csv(remote / "suite.csv") if row["method"] != "pt"}
    assert ours.keys() == theirs.keys() and ours
    for key, row in ours.items():
        for column in ("relmse", "relmse_trimmed", "ssim", "flip", "reference_spp", "luminance_ratio"):
            assert row[column] == theirs[key][column], (key, column)
    import json

    record = json.loads((remote / "suite.json").read_text())
    assert record["scenes"]["box"]["machine"]["threads"] == 1  # the worker's own thread count


def test_a_cluster_without_machine_workers_is_refused_naming_the_recipe(finished, tmp_path):
    from dask.distributed import LocalCluster

    config, _, _ = finished
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster:
        with pytest.raises(RuntimeError, match="--resources machine=1"):
            run_suite(config, tmp_path / "x", progress=False, scheduler=cluster.scheduler_address)


def test_an_interrupted_suite_resumes_where_it_stopped(tmp_path, monkeypatch):
    """Interrupted in its second scene, the rerun keeps the first scene's folder untouched and finishes."""
    import dataclasses

    import sparselt.experiments.suite as suite_module

    config = read_suite(suite_file(tmp_path))
    config = dataclasses.replace(config, scenes=config.scenes[:2], spps=(4,), seeds=(1, 2))
    real = suite_module.run_in_child

    def interrupted(function, comparison, out, cache_directory, **options):
        if comparison.kind == "dof":
            raise KeyboardInterrupt
        return real(function, comparison, out, cache_directory, **options)

    monkeypatch.setattr(suite_module, "run_in_child", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_suite(config, tmp_path / "out", progress=False)
    assert (tmp_path / "out" / "cells" / "box.json").exists() and not (tmp_path / "out" / "index.html").exists()
    first = {path.name: path.stat().st_mtime_ns for path in (tmp_path / "out" / "scenes" / "box").rglob("*")}
    monkeypatch.setattr(suite_module, "run_in_child", real)
    result = run_suite(config, tmp_path / "out", progress=False)
    assert {path.name: path.stat().st_mtime_ns for path in (tmp_path / "out" / "scenes" / "box").rglob("*")
            if path.name in first} == first
    assert {row["scene"] for row in result.rows} == {"box", "plane"}


BLANK = """<scene version="3.0.0">
  <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="32"/>
    <integer name="height" value="32"/></film></sensor>
  <emitter type="constant"><rgb name="radiance" value="0.5"/></emitter>
</scene>
"""


def test_a_scene_that_cannot_be_compared_is_named_and_the_others_are_aggregated(tmp_path, capsys):
    """A scene whose camera sees only a constant environment (a uniform reference: no contrast to compare) between
    two that can be compared: the suite goes on, aggregates the other two, lists the scene and its reason on the
    page and in suite.json, and exits 2 naming it. A rerun runs nothing again and says the same."""
    path = suite_file(tmp_path)
    (tmp_path / "scenes" / "blank.xml").write_text(BLANK)
    text = path.read_text().replace("seeds = [1, 2, 3]", "seeds = [1, 2]").replace("spp = [4, 16]", "spp = [4]")
    text = text.replace('methods = ["pt", "oidn", "bilateral:sigma_spatial=1.5"]', 'methods = ["pt", "bilateral"]')
    box, plane = text.split("[[scene]]\nname = \"plane\"")
    plane = plane.split("[[scene]]")[0]
    path.write_text(box + '[[scene]]\nname = "blank"\nscene = "scenes/blank.xml"\nkind = "path"\n\n'
                    + '[[scene]]\nname = "plane"' + plane)
    out = tmp_path / "out"
    for _ in range(2):
        assert main(["suite", str(path), "--out", str(out), "--no-progress"]) == 2
        message = capsys.readouterr().err
        assert "scene 'blank' could not be compared: the reference has no contrast" in message
        assert "1 of 3 scenes could not be compared" in message and "another --out" in message
    assert {row["scene"] for row in read_csv(out / "suite.csv")} == {"box", "plane"}
    # Both other scenes are aggregated; how many have a ratio depends on the cells' times at 32x32 (a 4-spp cell
    # faster than PT's 1-spp rung has no PT value on a loaded machine: a CI run once judged neither).
    assert {row["scenes"] for row in read_csv(out / "aggregate.csv")} == {"2"}
    page = (out / "index.html").read_text()
    assert "Scenes not compared" in page and "Scene blank: the reference has no contrast" in page
    record = json.loads((out / "suite.json").read_text())
    assert set(record["scenes"]) == {"box", "plane"} and "no contrast" in record["not_compared"]["blank"]


BLACK = """<scene version="3.0.0">
  <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="32"/>
    <integer name="height" value="32"/></film></sensor>
  <shape type="sphere"><point name="center" x="0" y="0" z="3"/><bsdf type="diffuse"/></shape>
</scene>
"""


def test_the_cluster_reference_stage_ends_only_the_scene_it_fails(tmp_path):
    """On a Dask cluster the references render first, from the client, and two failures there ended the whole
    suite: a reference pass whose worker dies each time it is tried (Dask's KilledWorker; here the worker is killed
    with SIGKILL while it renders, as the system kills a process out of memory, and a segmentation fault in the
    renderer ends a worker the same way), and a scene refused while its reference renders (a scene without light:
    a black reference, a ValueError). Now the first scene is listed as crashed and not recorded (a rerun tries it
    again), the second is recorded as not compared (as in-process), and the third is compared on the restarted
    worker."""
    import signal
    import threading
    import time

    import dask
    from dask.distributed import Client, LocalCluster

    path = suite_file(tmp_path)
    (tmp_path / "scenes" / "black.xml").write_text(BLACK)
    text = path.read_text().replace("seeds = [1, 2, 3]", "seeds = [1, 2]").replace("spp = [4, 16]", "spp = [4]")
    text = text.replace('methods = ["pt", "oidn", "bilateral:sigma_spatial=1.5"]', 'methods = ["pt", "bilateral"]')
    head, box = text.split("[[scene]]", 1)
    box = "[[scene]]" + box.split("[[scene]]\nname = \"plane\"")[0]
    path.write_text(head.replace("reference_spp = 256", "reference_spp = 64")  # one pass each
                    + '[[scene]]\nname = "large"\nscene = "cornell-box"\nkind = "path"\nresolution = [512, 512]\n\n'
                    + '[[scene]]\nname = "black"\nscene = "scenes/black.xml"\nkind = "path"\n\n' + box)
    config = read_suite(path)
    killed = []

    def kill_the_first_reference_pass(client, done):
        processes = client.run(os.getpid)  # asked before any task runs: a busy worker may answer late
        while not done.is_set() and not killed:
            for address, keys in client.processing().items():
                if any(str(key).startswith("sparselt-reference-pass") for key in keys):
                    os.kill(processes[address], signal.SIGKILL)
                    killed.append(address)
                    return
            time.sleep(0.02)

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0",
                          resources={"machine": 1}) as cluster, Client(cluster.scheduler_address) as client:
            done = threading.Event()
            killer = threading.Thread(target=kill_the_first_reference_pass, args=(client, done), daemon=True)
            killer.start()
            try:
                result = run_suite(config, tmp_path / "out", progress=False, scheduler=cluster.scheduler_address)
            finally:
                done.set()
                killer.join()
    assert killed
    assert result.crashed == ("large",) and "running a reference pass died every time" in result.not_compared["large"]
    assert set(result.not_compared) == {"large", "black"} and "is black" in result.not_compared["black"]
    assert {row["scene"] for row in result.rows} == {"box"}
    assert not (tmp_path / "out" / "cells" / "large.json").exists()
    assert (tmp_path / "out" / "cells" / "black.json").exists()


CRASHING_PLUGIN = '''"""A plug-in that ends its process with a segmentation fault on the kind named by SPARSELT_TEST_CRASH_KIND."""
import faulthandler
import os

import numpy as np

from sparselt.methods import Method, MethodResult, register
from sparselt.methods.pixel_samples import draw_pixel_samples


@register
class CrashOnKind(Method):
    name = "crash-on-kind"
    kinds = ("dof", "indirect", "path")
    family = "test"
    description = "path tracing, or a segmentation fault on the kind SPARSELT_TEST_CRASH_KIND names"

    def run(self, context, budget, timer):
        if os.environ.get("SPARSELT_TEST_CRASH_KIND") == context.kind:
            faulthandler._sigsegv()  # a real crash in native code, as the renderer's was
        with timer("sampling"):
            samples = draw_pixel_samples(context, budget)
        width, height = context.resolution
        image = samples.values.reshape(height, width, samples.spp, 3).mean(axis=2).astype(np.float32)
        return MethodResult(image=image, path_samples=int(samples.values.shape[0]))
'''


def crashing_suite(tmp_path, monkeypatch):
    """Two scenes (box: path, plane: dof), PT and the crashing plug-in; the plug-in on the Python path."""
    (tmp_path / "plugins").mkdir()
    (tmp_path / "plugins" / "crashing_methods.py").write_text(CRASHING_PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path / "plugins"))
    path = suite_file(tmp_path)
    text = path.read_text().replace("seeds = [1, 2, 3]", "seeds = [1, 2]").replace("spp = [4, 16]", "spp = [4]")
    text = text.replace('methods = ["pt", "oidn", "bilateral:sigma_spatial=1.5"]', 'methods = ["pt", "crash-on-kind"]')
    path.write_text(text.split("[[scene]]\nname = \"plane-path\"")[0])
    return path


def test_a_scene_whose_comparison_crashes_is_not_compared_and_a_rerun_tries_it_again(tmp_path, monkeypatch, capfd):
    """A segmentation fault in one scene's comparison (a plug-in's, in native code) ends that comparison's child
    process only: the suite aggregates the other scene, names the crashed one with its signal and where it
    happened, exits 2, and does not record it; the rerun, crash gone, compares it without running the other
    scene again."""
    path = crashing_suite(tmp_path, monkeypatch)
    out = tmp_path / "out"
    monkeypatch.setenv("SPARSELT_TEST_CRASH_KIND", "dof")
    command = ["suite", str(path), "--out", str(out), "--no-progress", "--plugin", "crashing_methods"]
    assert main(command) == 2
    error = capfd.readouterr().err  # the child's standard error is the file's, not Python's sys.stderr
    assert "scene 'plane' could not be compared: its comparison's process ended with signal 11 (SIGSEGV)" in error
    assert "Fatal Python error: Segmentation fault" in error and "crashing_methods.py" in error  # where
    assert "a rerun of the same command tries this scene again" in error
    assert "1 crashed and a rerun of the same command tries it again" in error and "another --out" not in error
    assert (out / "cells" / "box.json").exists() and not (out / "cells" / "plane.json").exists()
    assert {row["scene"] for row in read_csv(out / "suite.csv")} == {"box"}
    record = json.loads((out / "suite.json").read_text())
    assert "SIGSEGV" in record["not_compared"]["plane"] and record["crashed"] == ["plane"]
    box = {path.name: path.stat().st_mtime_ns for path in (out / "scenes" / "box").rglob("*")}
    assert main(command) == 2  # the rerun tries the crashed scene again (and says nothing of a complete folder)
    printed = capfd.readouterr()
    assert "signal 11 (SIGSEGV)" in printed.err and "is complete" not in printed.out
    monkeypatch.delenv("SPARSELT_TEST_CRASH_KIND")
    assert main(command) == 0
    assert {row["scene"] for row in read_csv(out / "suite.csv")} == {"box", "plane"}
    assert {path.name: path.stat().st_mtime_ns for path in (out / "scenes" / "box").rglob("*")
            if path.name in box} == box
    assert any(row["method"] == "crash-on-kind" and row["scene"] == "plane" for row in read_csv(out / "suite.csv"))
    assert "not_compared" not in json.loads((out / "suite.json").read_text())


def test_a_crash_on_a_cluster_worker_is_the_scenes_alone(tmp_path, monkeypatch):
    """On a Dask cluster the scene's comparison runs in a child of the worker: its crash is recorded for that
    scene, the worker lives on and compares the other scene."""
    from dask.distributed import LocalCluster

    from sparselt.methods import load_plugins

    path = crashing_suite(tmp_path, monkeypatch)
    monkeypatch.setenv("SPARSELT_TEST_CRASH_KIND", "dof")
    load_plugins(["crashing_methods"])  # the client's plug-in: the worker imports it too
    config = read_suite(path)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0",
                      resources={"machine": 1}) as cluster:
        result = run_suite(config, tmp_path / "out", progress=False, scheduler=cluster.scheduler_address)
    assert set(result.not_compared) == {"plane"} and "signal 11 (SIGSEGV)" in result.not_compared["plane"]
    assert result.crashed == ("plane",)
    assert {row["scene"] for row in result.rows} == {"box"}
    assert not (tmp_path / "out" / "cells" / "plane.json").exists()
