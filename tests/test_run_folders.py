"""Issue 18, the commands' folders: nothing lost, nothing mixed, limits checked before work.

Each test is one of the issue's cases, run through the real commands (the
Cornell box or a small XML scene with a PLY mesh, rendered by Mitsuba).
"""

import json
import os
import subprocess
import sys
import textwrap

import pytest

from sparselt.cli import main
from sparselt.storage.folder import MANIFEST_FILE, ExperimentFolder

COMPARE = ["compare", "--scene", "cornell-box", "--kind", "dof", "--aperture", "0.1", "--shape", "16,16,2,2",
           "--methods", "pt", "--spp", "2", "--seeds", "1", "--reference-spp", "16", "--no-progress"]

PLY = """ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
element face 2
property list uchar int vertex_indices
end_header
-{s} -{s} 0
{s} -{s} 0
{s} {s} 0
-{s} {s} 0
3 0 1 2
3 0 2 3
"""

XML = """<scene version="3.0.0">
  <integrator type="path"/>
  <sensor type="perspective">
    <float name="fov" value="45"/>
    <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1.0"/></emitter>
  <shape type="ply"><string name="filename" value="quad.ply"/><bsdf type="diffuse"/></shape>
</scene>
"""


def xml_scene(folder, size=1.0):
    folder.mkdir(exist_ok=True)
    (folder / "quad.ply").write_text(PLY.format(s=size))
    (folder / "scene.xml").write_text(XML)
    return str(folder / "scene.xml")


def xml_compare(scene):
    return ["compare", "--scene", scene, "--kind", "path", "--shape", "16,16" + ",2" * 8, "--methods", "pt",
            "--spp", "2", "--seeds", "1", "--reference-spp", "16", "--no-progress"]


def tree(path):
    return sorted((os.path.relpath(os.path.join(root, name), path), os.path.getsize(os.path.join(root, name)))
                  for root, _, names in os.walk(path) for name in names)


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SPARSELT_CACHE", str(tmp_path / "cache"))


@pytest.fixture
def finished_comparison(tmp_path):
    out = tmp_path / "compare"
    assert main(COMPARE + ["--out", str(out)]) == 0
    return out


def test_case_2_overwrite_with_a_scene_that_fails_to_load_keeps_the_folder(tmp_path, finished_comparison, capsys):
    before = tree(finished_comparison)
    assert len(before) > 10
    scene = xml_scene(tmp_path / "broken")
    os.remove(tmp_path / "broken" / "quad.ply")
    assert main(xml_compare(scene) + ["--out", str(finished_comparison), "--overwrite"]) == 2
    assert "quad.ply" in capsys.readouterr().err
    assert tree(finished_comparison) == before


@pytest.mark.parametrize("command", [COMPARE, COMPARE + ["--overwrite"]])
def test_case_3_a_folder_sparselt_did_not_write_is_refused(tmp_path, command, capsys):
    out = tmp_path / "paper"
    (out / "data").mkdir(parents=True)
    (out / "paper.tex").write_text("\\section{Results}")
    (out / "data" / "table.csv").write_text("1,2")
    before = tree(out)
    assert main(command + ["--out", str(out)]) == 2
    assert "did not write" in capsys.readouterr().err
    assert tree(out) == before


def test_case_5_resuming_after_the_mesh_changed_is_refused_naming_the_file(tmp_path, capsys):
    scene = xml_scene(tmp_path / "scene")
    out = tmp_path / "compare"
    assert main(xml_compare(scene) + ["--out", str(out)]) == 0
    (tmp_path / "scene" / "quad.ply").write_text(PLY.format(s=0.5))
    capsys.readouterr()
    assert main(xml_compare(scene) + ["--out", str(out), "--spp", "2,4"]) == 2
    error = capsys.readouterr().err
    assert "scene_digest" in error and "quad.ply" in error and "--overwrite" in error
    cells = sorted(os.listdir(out / "cells"))
    assert cells == ["pt_spp2_seed1.json"]


def test_case_6_a_second_compare_into_a_running_folder_is_refused(finished_comparison, capsys):
    """Both runs take the folder's lock; while one holds it the other is refused, --overwrite or not."""
    manifest = json.loads((finished_comparison / MANIFEST_FILE).read_text())
    holder = ExperimentFolder(finished_comparison, kind="compare", identity=manifest["identity"],
                              scene=manifest["scene"])
    holder.inspect()
    before = tree(finished_comparison)
    with holder.open():
        for extra in ([], ["--overwrite"], ["--spp", "2,3"]):
            assert main(COMPARE + ["--out", str(finished_comparison)] + extra) == 2
            assert f"PID {os.getpid()}" in capsys.readouterr().err
    assert sorted(name for name, _ in tree(finished_comparison)) == sorted(name for name, _ in before)


def test_case_7_reproduce_refuses_another_scale_in_the_same_folder(tmp_path):
    from sparselt.experiments.reproduce import reproduce

    out = tmp_path / "reproduce"
    reproduce("4", "tiny", out, progress=False)
    with pytest.raises(ValueError, match="scale: 'tiny' recorded, 'thesis' now"):
        reproduce("5", "thesis", out, progress=False)
    assert json.loads((out / MANIFEST_FILE).read_text())["identity"] == {"scale": "tiny"}


def test_case_7_a_signal_of_another_configuration_is_not_reused(tmp_path):
    from sparselt.experiments.reproduce.common import sampled_signal

    small = sampled_signal("cornell-box", "dof", (12, 12, 2, 2), 1, str(tmp_path), "signal", False, aperture=0.1)
    again = sampled_signal("cornell-box", "dof", (12, 12, 2, 2), 1, str(tmp_path), "signal", False, aperture=0.1)
    assert again.meta["provenance"]["created"] == small.meta["provenance"]["created"]
    larger = sampled_signal("cornell-box", "dof", (16, 16, 2, 2), 1, str(tmp_path), "signal", False, aperture=0.1)
    assert larger.shape == (16, 16, 2, 2)


def test_case_11_a_compare_stopped_by_a_full_disk_resumes(tmp_path):
    """The first run hits a file-size limit (EFBIG, what a full disk looks like to a writer); once lifted, the
    same command resumes and completes."""
    out = tmp_path / "compare"
    arguments = COMPARE + ["--out", str(out), "--spp", "2,4"]
    script = textwrap.dedent(f"""
        import resource, signal, sys
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (3000, 3000))
        from sparselt.cli import main
        sys.exit(main({arguments!r}))
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            env=dict(os.environ, SPARSELT_CACHE=str(tmp_path / "cache")))
    assert result.returncode == 2, result.stderr
    assert "no space left" in result.stderr and "rerun the same command" in result.stderr
    assert "Traceback" not in result.stderr
    assert main(arguments) == 0
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert manifest["status"] == "complete"
    assert sorted(os.listdir(out / "cells")) == ["pt_spp2_seed1.json", "pt_spp4_seed1.json"]


@pytest.mark.parametrize("arguments, message", [
    (["--methods", "pt,cosamp", "--option", "cosamp.sparsity=0"], "option cosamp.sparsity must be an integer in [1, N/2]"),
    (["--methods", "pt,sft", "--option", "sft.alpha=0"], "option sft.alpha must be a finite number >= 1"),
    (["--methods", "pt,cosamp", "--option", "cosamp.gamma=0"], "option cosamp.gamma must be a finite number > 0"),
    (["--methods", "pt,cosamp", "--option", "*.gamma=nan"], "option cosamp.gamma must be a finite number > 0"),
    (["--methods", "pt,sft", "--option", "sft.snr=inf"], "option sft.snr must be a finite number"),
    (["--reference-spp", "99999999999"], "reference spp"),
    (["--reference-spp", "16000000", "--resolution", "512,512"], "hours"),
])
def test_case_10_and_12_values_that_mean_nothing_are_refused_before_work(tmp_path, arguments, message, capsys):
    base = [argument for argument in COMPARE]
    if "--methods" in arguments:
        index = base.index("--methods")
        del base[index:index + 2]
    if "sft" in " ".join(arguments):  # the SFT runs on path space
        base[base.index("dof")] = "path"
        base[base.index("16,16,2,2")] = "16,16" + ",4" * 8
        base.remove("--aperture")
        base.remove("0.1")
    assert main(base + arguments + ["--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert message in error and "Traceback" not in error
    assert not (tmp_path / "out").exists()


def test_case_12_table61_sparsity_zero_is_refused(tmp_path, capsys):
    assert main(["table61", "--scene", "cornell-box", "--shape", "16,16" + ",2" * 8, "--sparsity", "0",
                 "--out", str(tmp_path / "t"), "--no-progress"]) == 2
    assert "sparsity (K)" in capsys.readouterr().err
    assert not (tmp_path / "t").exists()


def test_case_15_stating_a_default_is_the_same_comparison(finished_comparison, capsys):
    capsys.readouterr()
    assert main(COMPARE + ["--out", str(finished_comparison), "--option", "*.gamma=0.25", "--option",
                           "*.map_spp=16"]) == 0
    manifest = json.loads((finished_comparison / MANIFEST_FILE).read_text())
    assert [entry["plan"] for entry in manifest["history"]] == ["new", "resume"]
    assert "compare: pt" not in capsys.readouterr().err  # the finished cell was not run again


def test_case_15_an_interrupted_compare_speaks_of_finished_work_not_chunks(tmp_path):
    import signal
    import time

    out = tmp_path / "compare"
    command = [sys.executable, "-m", "sparselt.cli"] + COMPARE + ["--out", str(out), "--reference-spp", "100000",
                                                                  "--resolution", "64,64"]
    # As from a terminal: a test runner started in the background ignores SIGINT, and its children inherit that.
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True,
                               env=dict(os.environ, SPARSELT_CACHE=str(tmp_path / "cache")),
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while not (out / MANIFEST_FILE).exists() and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.1)
    time.sleep(0.5)  # the reference is rendering now
    process.send_signal(signal.SIGINT)
    try:
        _, error = process.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        process.kill()
        pytest.fail("compare did not stop on SIGINT")
    assert process.returncode == 130, error
    assert "finished work is kept" in error and "chunks" not in error
    assert json.loads((out / MANIFEST_FILE).read_text())["status"] == "running"


@pytest.mark.parametrize("make", [lambda path: path.write_text("x"), lambda path: os.symlink(path, path)])
def test_case_13_reproduce_into_a_file_or_a_link_loop_is_a_clear_error(tmp_path, make, capsys):
    out = tmp_path / "out"
    make(out)
    assert main(["reproduce", "--chapter", "4", "--out", str(out), "--no-progress"]) == 2
    error = capsys.readouterr().err
    assert ("existing file" in error or "symbolic link loop" in error) and "File exists" not in error


def test_every_command_records_its_provenance_in_the_manifest(finished_comparison):
    manifest = json.loads((finished_comparison / MANIFEST_FILE).read_text())
    entry = manifest["history"][0]
    assert entry["versions"]["mitsuba"] and "git" in entry and "compare" in " ".join(entry["command"])
    listed = set(manifest["files"])
    on_disk = {name for name, _ in tree(finished_comparison)} - {MANIFEST_FILE}
    assert on_disk == listed


def test_case_11_render_onto_a_full_disk_leaves_no_partial_image(tmp_path):
    out = tmp_path / "render"
    arguments = ["render", "--scene", "cornell-box", "--spp", "4", "--resolution", "64,64", "--out", str(out)]
    script = textwrap.dedent(f"""
        import resource, signal, sys
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (8000, 8000))
        from sparselt.cli import main
        sys.exit(main({arguments!r}))
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert result.returncode == 2 and "no space left" in result.stderr and "image.exr" in result.stderr
    assert not (out / "image.exr").exists() and not (out / "render.json").exists()
    assert not out.exists()  # the folder this failed run created is gone (issue 38): nothing was finished in it
    assert main(arguments) == 0
    assert json.loads((out / MANIFEST_FILE).read_text())["status"] == "complete"
