"""Scene registry and the exactness of the built-in Cornell box."""

import numpy as np
import pytest

from sparselt.rendering.mitsuba import MitsubaScene, initialize, sensor_dictionary, to_mitsuba_dict
from sparselt.rendering.scenes import SceneSpec, get_scene, scene_names


def test_registry_has_the_scenes_of_the_issue():
    names = scene_names()
    for name in ("cornell-box", "cornell-caustics", "dof-sculptures", "courtyard"):
        assert name in names


@pytest.mark.parametrize("arguments, error, message", [
    (("sponza",), ValueError, "cornell-box"),  # the message lists the names
    (("{tmp_path}/missing.xml",), ValueError, "does not exist"),
], ids=["unknown-scene", "missing-scene-file"])
def test_get_scene_invalid_input(tmp_path, arguments, error, message):
    arguments = [argument.format(tmp_path=tmp_path) for argument in arguments]
    with pytest.raises(error, match=message):
        get_scene(*arguments)


def test_cornell_box_is_exactly_mitsubas(cornell):
    mi = initialize()
    reference = mi.cornell_box()
    ours = to_mitsuba_dict(cornell.objects)
    for key, value in reference.items():
        if key in ("sensor", "integrator", "type"):
            continue
        assert key in ours, key
        mine = ours[key]
        if "to_world" in value:
            assert np.array_equal(np.array(value["to_world"].matrix), np.array(mine["to_world"].matrix)), key
        stripped = {k: v for k, v in value.items() if k != "to_world"}
        assert stripped == {k: v for k, v in mine.items() if k != "to_world"}, key
    assert set(ours) - {"type"} == set(reference) - {"sensor", "integrator", "type"}
    sensor = reference["sensor"]
    ours_sensor = sensor_dictionary(cornell.camera, 256, 256)
    assert np.array_equal(np.array(sensor["to_world"].matrix), np.array(ours_sensor["to_world"].matrix))
    for key in ("fov", "fov_axis", "near_clip", "far_clip"):
        assert sensor[key] == ours_sensor[key]
    assert ours_sensor["film"]["rfilter"] == {"type": "box"}


def test_lens_override_validates(cornell):
    with pytest.raises(ValueError, match="aperture radius"):
        cornell.with_lens(aperture_radius=-1.0)
    with pytest.raises(ValueError, match="--aperture"):
        cornell.with_lens(focus_distance=2.0)
    camera = cornell.with_lens(aperture_radius=0.1, focus_distance=3.0).resolved_camera()
    assert camera.thin_lens and camera.focus_distance == 3.0


def test_scene_file_camera_is_read_back(tmp_path):
    """An XML scene given by path: its sensor becomes our camera, resized and box-filtered."""
    xml = tmp_path / "scene.xml"
    xml.write_text(
        """<scene version="3.0.0">
  <sensor type="thinlens">
    <float name="fov" value="45"/>
    <float name="aperture_radius" value="0.2"/>
    <float name="focus_distance" value="4"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="48"/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1.0"/></emitter>
  <shape type="sphere"><bsdf type="diffuse"/></shape>
</scene>"""
    )
    spec = get_scene(str(xml))
    assert isinstance(spec, SceneSpec) and spec.filename == str(xml)
    scene = MitsubaScene(spec, (20, 10))
    assert scene.camera.thin_lens and abs(scene.camera.aperture_radius - 0.2) < 1e-6
    assert abs(scene.camera.focus_distance - 4.0) < 1e-5
    image, _ = scene.render_path(4, 2)
    assert image.shape == (10, 20, 3)
    # The sphere (albedo 0.5 under unit sky) is in the middle, the sky at the corners.
    assert abs(image[0, 0].mean() - 1.0) < 1e-3
    assert image[5, 10].mean() < 0.9
