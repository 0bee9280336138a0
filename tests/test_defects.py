"""One test per bad-input defect found by the review (issue 8): each now fails with a clear message."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from sparselt.cli import main
from sparselt.rendering.acquire import AcquisitionConfig, NonFiniteSampleError, acquire_signal
from sparselt.rendering.scenes import SceneSpec, get_scene


def run(*arguments):
    return subprocess.run([sys.executable, "-m", "sparselt.cli", *arguments], capture_output=True, text=True)


def _bright_scene(cornell, radiance):
    objects = dict(cornell.objects)
    objects["light"] = dict(objects["light"], emitter={"type": "area", "radiance": {"type": "rgb", "value": radiance}})
    return SceneSpec(name="bright", description="huge emitter", objects=objects, camera=cornell.camera)


def _config(**changes):
    base = dict(scene="cornell-box", kind="path", shape=(6, 6, 2, 2, 2, 2, 2, 2, 2, 2), spp=64, seed=1)
    base.update(changes)
    return AcquisitionConfig(**base)


def test_cell_means_that_overflow_float32_are_refused(cornell):
    """Finite samples of radiance 5e37 whose 64-sample sums overflow: an error, not a complete signal of inf."""
    scene = _bright_scene(cornell, [5e37, 5e37, 5e37])
    with pytest.raises(NonFiniteSampleError, match="overflow float32"):
        acquire_signal(_config(), progress=False, scene_spec=scene)


def test_overflowing_cells_become_zero_with_nonfinite_zero(cornell):
    scene = _bright_scene(cornell, [5e37, 5e37, 5e37])
    signal = acquire_signal(_config(nonfinite="zero"), progress=False, scene_spec=scene)
    assert np.all(np.isfinite(signal.data)) and signal.meta["nonfinite_samples"] > 0


def test_resume_may_switch_to_nonfinite_zero(tmp_path, cornell):
    """The NaN error suggests --nonfinite zero; the same folder now accepts it and resumes."""
    from sparselt.signal import load_signal

    scene = _bright_scene(cornell, [1e39, 1.0, 1.0])
    out = tmp_path / "signal"
    with pytest.raises(NonFiniteSampleError, match="--nonfinite zero"):
        acquire_signal(_config(), out, progress=False, scene_spec=scene)
    signal = acquire_signal(_config(nonfinite="zero"), out, progress=False, scene_spec=scene)
    assert signal.meta["status"] == "complete" and load_signal(out).meta["config"]["nonfinite"] == "zero"


def test_render_refuses_more_than_32_bit_samples_per_pass(tmp_path):
    result = run("render", "--scene", "cornell-box", "--spp", "4200000", "--resolution", "32,32",
                 "--out", str(tmp_path / "r"))
    assert result.returncode == 2 and "at most 4194303 spp" in result.stderr
    assert not (tmp_path / "r" / "image.exr").exists()


XML = """<scene version="3.0.0">
  <default name="res" value="30"/>
  <integrator type="path"><boolean name="hide_emitters" value="{hide}"/></integrator>
  <sensor type="{sensor}">
    {fov}
    <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="$res"/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1.0"/></emitter>
  <shape type="sphere"><bsdf type="diffuse"/></shape>
</scene>
"""


def write_scene(folder, *, hide="false", sensor="perspective"):
    path = folder / f"scene-{sensor}-{hide}.xml"
    fov = '<float name="fov" value="45"/>' if sensor == "perspective" else ""
    path.write_text(XML.format(hide=hide, sensor=sensor, fov=fov))
    return str(path)


def test_render_of_an_xml_scene_uses_its_film_size(tmp_path):
    scene = write_scene(tmp_path)
    assert main(["render", "--scene", scene, "--spp", "4", "--out", str(tmp_path / "r")]) == 0
    record = json.loads((tmp_path / "r" / "render.json").read_text())
    assert record["resolution"] == [40, 30]


def test_hide_emitters_of_the_xml_is_honoured_and_recorded(tmp_path):
    visible = get_scene(write_scene(tmp_path, hide="false"))
    hidden = get_scene(write_scene(tmp_path, hide="true"))
    assert hidden.hide_emitters and not visible.hide_emitters
    from sparselt.experiments.render import render_reference

    shown, _ = render_reference(visible.filename, tmp_path / "a", spp=16, scene_spec=visible)
    dark, _ = render_reference(hidden.filename, tmp_path / "b", spp=16, scene_spec=hidden)
    assert shown[0, 0].mean() == pytest.approx(1.0, rel=1e-3)  # the corner sees the constant environment
    assert dark[0, 0].mean() == 0.0
    signal = acquire_signal(AcquisitionConfig(scene=hidden.filename, kind="path", shape=(8, 6, 2, 2, 2, 2, 2, 2, 2, 2),
                                              spp=4), progress=False, scene_spec=hidden)
    assert signal.meta["hide_emitters"] is True
    assert signal.image()[0, 0].mean() == 0.0


def test_orthographic_sensor_gets_a_message(tmp_path):
    scene = write_scene(tmp_path, sensor="orthographic")
    result = run("render", "--scene", scene, "--spp", "1", "--out", str(tmp_path / "r"))
    assert result.returncode == 2 and "not a perspective or thin-lens camera" in result.stderr
    assert "Traceback" not in result.stderr


def test_out_below_a_file_is_a_message_not_a_traceback(tmp_path):
    (tmp_path / "afile").write_text("x")
    result = run("render", "--scene", "cornell-box", "--spp", "1", "--resolution", "16,16",
                 "--out", str(tmp_path / "afile" / "sub"))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "not a folder" in result.stderr or "Not a directory" in result.stderr


def test_show_does_not_overwrite_without_permission(tmp_path):
    signal = tmp_path / "signal"
    assert main(["sample", "--scene", "cornell-box", "--kind", "dof", "--aperture", "0.1", "--shape", "12,12,2,2",
                 "--spp", "2", "--out", str(signal), "--no-progress"]) == 0
    pictures = tmp_path / "pictures"
    pictures.mkdir()
    (pictures / "image.png").write_bytes(b"precious")
    assert main(["show", str(signal), "--out", str(pictures)]) == 2
    assert (pictures / "image.png").read_bytes() == b"precious"
    (tmp_path / "file").write_text("x")
    assert main(["show", str(signal), "--out", str(tmp_path / "file")]) == 2
    # sparselt never deletes what it did not write, --overwrite or not (issue 18, case 3)
    assert main(["show", str(signal), "--out", str(pictures), "--overwrite"]) == 2
    assert (pictures / "image.png").read_bytes() == b"precious"
    assert main(["show", str(signal), "--out", str(tmp_path / "fresh")]) == 0
    assert main(["show", str(signal), "--out", str(tmp_path / "fresh")]) == 0  # the same pictures: rewritten


def test_empty_or_corrupt_data_file_is_a_clear_error(tmp_path):
    from sparselt.signal import load_signal

    signal = tmp_path / "signal"
    assert main(["sample", "--scene", "cornell-box", "--kind", "dof", "--aperture", "0.1", "--shape", "12,12,2,2",
                 "--spp", "2", "--out", str(signal), "--no-progress"]) == 0
    (signal / "data" / "zarr.json").write_bytes(b"")
    with pytest.raises(ValueError, match="cannot be opened"):
        load_signal(signal)
    (signal / "zarr.json").write_text("{not json")
    with pytest.raises(ValueError, match="zarr.json' is not valid JSON"):
        load_signal(signal)


def test_integrate_refuses_fractional_axes():
    from sparselt.fourier.integration import integrate
    from sparselt.fourier.sparse import SparseFourier

    representation = SparseFourier.from_signal(np.ones((4, 4, 2)))
    with pytest.raises(ValueError, match="integer axis numbers"):
        integrate(representation, keep_axes=(0, 1.7))


@pytest.mark.parametrize("arguments, error, message", [
    (dict(y=np.ones(32), tolerance=float("nan")), ValueError, "tolerance"),
    (dict(y=np.ones(32), tolerance=-1.0), ValueError, "tolerance"),
    (dict(y=np.ones(32), tolerance="tiny"), TypeError, "tolerance"),
    (dict(y=np.full(32, 1e19)), ValueError, "too large for float32"),
], ids=["nan-tolerance", "negative-tolerance", "non-numeric-tolerance", "measurements-too-large-for-float32"])
def test_cosamp_invalid_input(arguments, error, message):
    from sparselt.operators import PartialFourier
    from sparselt.recovery.cosamp import cosamp

    operator = PartialFourier((8, 8), np.arange(0, 64, 2))
    with pytest.raises(error, match=message):
        cosamp(operator, sparsity=4, **arguments)


def test_ssim_with_a_huge_data_range_does_not_overflow():
    from sparselt.analysis.metrics import structural_similarity

    rng = np.random.default_rng(0)
    image, reference = rng.random((16, 16)), rng.random((16, 16))
    expected = structural_similarity(image, reference, data_range=1.0)
    assert structural_similarity(image * 1e300, reference * 1e300, data_range=1e300) == pytest.approx(expected, rel=1e-12)


def test_byte_counts_are_readable():
    from sparselt.provenance import format_bytes

    assert format_bytes(12) == "12 B" and format_bytes(3.4e6) == "3.4 MB" and format_bytes(2e9) == "2.0 GB"
    assert format_bytes(4e7) != "0.0 GB"


def test_compare_refuses_more_than_32_bit_samples_per_pass(tmp_path):
    from sparselt.experiments.compare import ComparisonConfig, compare

    config = ComparisonConfig(scene="cornell-box", kind="dof", shape=(512, 512, 2, 2), aperture=0.1, methods=("pt",),
                              spps=(20000,))
    with pytest.raises(ValueError, match="32 bits"):
        compare(config, tmp_path / "c", progress=False)
    assert not os.path.exists(tmp_path / "c")


def test_sft_refuses_samples_whose_energy_overflows():
    from sparselt.recovery.sft import sft

    with pytest.raises(ValueError, match="overflow float64"):
        sft(lambda indices: np.full(indices.shape, 1e300), 256, 4, seed=0)


def test_every_kind_the_cli_offers_has_a_layout_and_others_are_refused(capsys):
    """The kinds ``sample --kind`` accepts are exactly those the sampler can lay out (each builds a layout),
    and a kind it does not know stops at the parser with exit 2, naming the choices."""
    from sparselt.cli import build_parser
    from sparselt.rendering.layout import path_layout

    parser = build_parser()
    sample = next(action for action in parser._subparsers._group_actions[0].choices["sample"]._actions
                  if action.dest == "kind")
    for kind in sample.choices:
        assert path_layout(kind, 3, thin_lens=kind == "dof").axes
    with pytest.raises(ValueError):
        path_layout("fog", 3)
    with pytest.raises(SystemExit) as stopped:
        main(["sample", "--scene", "cornell-box", "--kind", "fog", "--shape", "4,4", "--out", "unused"])
    assert stopped.value.code == 2
    error = capsys.readouterr().err
    assert "invalid choice: 'fog'" in error and all(kind in error for kind in sample.choices)
