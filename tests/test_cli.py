"""The `sparselt` command: help, listing, sample -> show, render, and exit codes on bad input."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from sparselt.cli import main


def run(*arguments):
    return subprocess.run([sys.executable, "-m", "sparselt.cli", *arguments], capture_output=True, text=True)


@pytest.mark.parametrize("command", ["scenes", "sample", "render", "show", "compare", "methods"])
def test_every_command_has_help(command):
    result = run(command, "--help")
    assert result.returncode == 0 and "usage: sparselt" in result.stdout


def test_scenes_lists_the_built_in_scenes(capsys):
    assert main(["scenes"]) == 0
    listed = capsys.readouterr().out
    for name in ("cornell-box", "cornell-caustics", "dof-sculptures", "courtyard"):
        assert name in listed


def test_methods_lists_the_registered_methods(capsys):
    assert main(["methods"]) == 0
    listed = capsys.readouterr().out
    for name in ("pt", "samples-mean", "cosamp", "cosamp-thesis"):
        assert name + " " in listed


def test_sample_then_show(tmp_path, capsys):
    signal = tmp_path / "signal"
    assert main(["sample", "--scene", "cornell-box", "--kind", "dof", "--shape", "16,12,4,4", "--spp", "4",
                 "--aperture", "0.1", "--focus-distance", "3.5", "--out", str(signal), "--no-progress"]) == 0
    meta = json.loads((signal / "zarr.json").read_text())["attributes"]
    assert meta["axes"] == ["x", "y", "lens_u", "lens_v"] and meta["camera"]["aperture_radius"] == 0.1
    pictures = tmp_path / "pictures"
    assert main(["show", str(signal), "--out", str(pictures)]) == 0
    from matplotlib import image

    picture = image.imread(pictures / "image.png")
    assert picture.shape[:2] == (12, 16) and picture.max() > 0
    assert (pictures / "slices_x_y.png").exists()
    assert (pictures / "slices_lens_u_lens_v.png").exists()


def test_render_writes_exr_png_and_timing(tmp_path):
    out = tmp_path / "reference"
    assert main(["render", "--scene", "cornell-box", "--spp", "16", "--resolution", "24,16", "--out", str(out)]) == 0
    record = json.loads((out / "render.json").read_text())
    assert record["seconds"] > 0 and record["spp"] == 16 and record["resolution"] == [24, 16]
    assert record["provenance"]["versions"]["mitsuba"]
    from sparselt.rendering.mitsuba import initialize

    mi = initialize()
    exr = np.array(mi.Bitmap(str(out / "image.exr")))
    assert exr.shape == (16, 24, 3) and exr.dtype == np.float32 and exr.max() > 1.0  # HDR: the light
    assert (out / "image.png").exists()


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["sample", "--scene", "nowhere", "--kind", "path", "--shape", "4,4"], "cornell-box"),
        (["sample", "--scene", "cornell-box", "--kind", "path", "--shape", "4,4,2,2"], "has 4 axes"),
        (["sample", "--scene", "cornell-box", "--kind", "dof", "--shape", "4,4,2,2"], "--aperture"),
        (["sample", "--scene", "cornell-box", "--kind", "path", "--shape", "4,4", "--max-depth", "1", "--spp", "0"], "spp"),
        (["render", "--scene", "cornell-box", "--spp", "0"], "spp"),
        (["render", "--scene", "cornell-box", "--spp", "4", "--aperture", "-1"], "aperture"),
    ],
)
def test_bad_input_exits_non_zero_with_a_clear_message(tmp_path, arguments, message):
    result = run(*arguments, "--out", str(tmp_path / "out"))
    assert result.returncode != 0
    assert message in result.stderr
    assert "Traceback" not in result.stderr


def test_existing_output_needs_overwrite(tmp_path):
    """The same render again rewrites its folder; another render there needs --overwrite, and says what differs."""
    out = tmp_path / "out"
    arguments = ["render", "--scene", "cornell-box", "--resolution", "8,8", "--out", str(out)]
    assert run(*arguments, "--spp", "2").returncode == 0
    assert run(*arguments, "--spp", "2").returncode == 0
    result = run(*arguments, "--spp", "4")
    assert result.returncode == 2 and "--overwrite" in result.stderr and "spp: 2 recorded, 4 now" in result.stderr
    assert json.loads((out / "render.json").read_text())["spp"] == 2
    assert run(*arguments, "--spp", "4", "--overwrite").returncode == 0
    assert json.loads((out / "render.json").read_text())["spp"] == 4


def test_show_of_an_incomplete_signal_says_how_to_resume(tmp_path):
    (tmp_path / "zarr.json").write_text(json.dumps({"zarr_format": 3, "node_type": "group",
                                                    "attributes": {"format": "sparselt-signal", "status": "incomplete"}}))
    result = run("show", str(tmp_path), "--out", str(tmp_path / "pictures"))
    assert result.returncode != 0 and "resume" in result.stderr


def test_analyze_a_sampled_signal(tmp_path):
    signal = tmp_path / "signal"
    assert run("sample", "--scene", "cornell-box", "--kind", "indirect", "--shape", "16,16,4,4", "--spp", "4",
               "--out", str(signal), "--no-progress").returncode == 0
    result = run("analyze", str(signal), "--gamma", "1,0.5", "--fractions", "0.01,1", "--out", str(tmp_path / "analysis"))
    assert result.returncode == 0, result.stderr
    assert "| gamma | Time | Time Energy | Frequency | Frequency Energy |" in result.stdout
    assert (tmp_path / "analysis" / "ssim_vs_fraction.png").exists()
    bad = run("analyze", str(signal), "--gamma", "0", "--out", str(tmp_path / "bad"))
    assert bad.returncode != 0 and "gamma" in bad.stderr and "Traceback" not in bad.stderr


def test_a_ctrl_c_wrapped_by_a_drjit_custom_operation_is_an_interruption_not_an_error(monkeypatch, capsys):
    """mi.render runs its Python part inside drjit.custom, which turns a KeyboardInterrupt into a RuntimeError
    (the cause of an intermittent exit 2 instead of 130 on Ctrl-C during a compare's reference render)."""
    from sparselt import signal as signal_module
    from sparselt.rendering.mitsuba import initialize

    initialize()  # Dr.Jit with its libLLVM, in the variant dr.llvm.ad.Float needs
    import drjit as dr

    class Interrupted(dr.CustomOp):
        def eval(self, value):
            raise KeyboardInterrupt

    def load_signal(path):
        return dr.custom(Interrupted, dr.llvm.ad.Float(1.0))

    monkeypatch.setattr(signal_module, "load_signal", load_signal)
    assert main(["show", "anything", "--out", "pictures"]) == 130
    error = capsys.readouterr().err
    assert "interrupted" in error and "error:" not in error


def _compare_a_scene_file(tmp_path, shapes):
    """``compare`` (pt, 2 spp, path kind) on a 16x16 scene file holding ``shapes``: ``(result, output folder)``."""
    scene = tmp_path / "scene.xml"
    scene.write_text('<scene version="3.0.0">\n  <sensor type="perspective"><film type="hdrfilm"><integer name="width" '
                     'value="16"/><integer name="height" value="16"/></film></sensor>\n' + shapes + '</scene>\n')
    out = tmp_path / "out"
    return run("compare", "--scene", str(scene), "--kind", "path", "--methods", "pt", "--spp", "2",
               "--out", str(out)), out


def test_a_scene_with_a_medium_exits_2_before_writing_anything(tmp_path):
    """A smoke-filled sphere: `compare` names the shape and exits 2 with no output folder (the media would be left
    out of every image, the reference's too)."""
    result, out = _compare_a_scene_file(tmp_path, '  <emitter type="constant"/>\n  <shape type="sphere"><bsdf '
                                        'type="dielectric"/><medium type="homogeneous" name="interior"/></shape>\n')
    assert result.returncode == 2 and "participating media (a Sphere)" in result.stderr
    assert "Traceback" not in result.stderr and not out.exists()


def test_an_error_inside_mitsubas_render_is_reported_by_its_own_message(tmp_path):
    """A blackbody emitter loads in an RGB variant but fails when rendered; Mitsuba's render wraps the failure in
    Dr.Jit's "error while performing a custom differentiable operation. (see above)". The message says what failed,
    and nothing is written."""
    result, out = _compare_a_scene_file(tmp_path, '  <shape type="sphere"><emitter type="area"><spectrum '
                                        'type="blackbody" name="radiance"><float name="temperature" value="3200"/>'
                                        '</spectrum></emitter></shape>\n')
    assert result.returncode == 2 and "BlackBodySpectrum" in result.stderr and "non-spectral" in result.stderr
    assert "see above" not in result.stderr and "Traceback" not in result.stderr and not out.exists()


def test_a_crash_in_native_code_prints_where_python_was():
    """A segmentation fault (here faulthandler's own test fault) after the CLI has started prints Python's
    stack on standard error instead of ending the process without a word."""
    script = ("import sys\n"
              "from sparselt import cli\n"
              "cli.report_crashes()\n"
              "import faulthandler\n"
              "def inside_a_method():\n"
              "    faulthandler._sigsegv()\n"
              "inside_a_method()\n")
    environment = {name: value for name, value in os.environ.items() if name != "PYTHONFAULTHANDLER"}
    finished = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                              env=environment)
    assert finished.returncode != 0
    assert "Segmentation fault" in finished.stderr and "inside_a_method" in finished.stderr, finished.stderr
