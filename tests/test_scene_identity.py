"""One scene identity (issue 18, cases 4, 13, 16, 17): the reference cache keyed by the scene's full content,
corrupt cache entries rendered again, referenced files checked before Mitsuba loads them, a sensor Mitsuba
cannot sample named by its type, an aperture focused on the scene, and Mitsuba's ``-D name=value`` parameters.

Real renderer, tiny images: a 16x16 film at a few samples per pixel.
"""

import json
import os

import numpy as np
import pytest

from sparselt.cli import build_parser, main
from sparselt.experiments.compare import ComparisonConfig, validate_config
from sparselt.experiments.sft_path_space import Table61Config
from sparselt.image_io import write_exr
from sparselt.rendering import identity as identity_module
from sparselt.rendering import scenes
from sparselt.rendering.acquire import AcquisitionConfig, acquire_signal
from sparselt.rendering.mitsuba import MitsubaScene
from sparselt.experiments.render import render_reference
from sparselt.rendering.baseline import cached_reference
from sparselt.rendering.identity import scene_identity
from sparselt.rendering.meshes import box, write_ply
from sparselt.rendering.scenes import get_scene

SIZE = (16, 16)

SENSOR = """  <sensor type="{sensor}">
    <float name="fov" value="45"/>{lens}
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, {target}" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
  </sensor>
"""


def scene_xml(shapes, *, sensor="perspective", lens="", target=0, spp="4", head=""):
    """A Mitsuba scene file's text: one camera at z = 5 looking at the origin, then ``shapes``."""
    return ('<scene version="3.0.0">\n' + head + SENSOR.format(sensor=sensor, lens=lens, target=target, spp=spp)
            + shapes + "</scene>\n")


SPHERE = '  <emitter type="constant"><rgb name="radiance" value="1.0"/></emitter>\n  <shape type="sphere"/>\n'


def write(path, text):
    path.write_text(text)
    return str(path)


def write_texture(path, value):
    write_exr(str(path), np.full((4, 4, 3), value, dtype=np.float32))


@pytest.fixture
def textured_scene(tmp_path):
    """A scene file with an include (the light), a PLY mesh and a bitmap texture: every kind of reference."""
    write(tmp_path / "light.xml", '<scene version="3.0.0">\n  <emitter type="constant"><rgb name="radiance" '
                                  'value="1.0"/></emitter>\n</scene>\n')
    write_ply(tmp_path / "mesh.ply", box(size=1.0))
    write_texture(tmp_path / "texture.exr", 0.5)
    shapes = ('  <include filename="light.xml"/>\n'
              '  <shape type="ply" id="mesh">\n    <string name="filename" value="mesh.ply"/>\n'
              '    <bsdf type="diffuse"><texture type="bitmap" name="reflectance">'
              '<string name="filename" value="texture.exr"/></texture></bsdf>\n  </shape>\n')
    return write(tmp_path / "scene.xml", scene_xml(shapes))


def reference(spec, cache, spp=4):
    loaded = MitsubaScene(spec, SIZE)
    return cached_reference(loaded, "path", spp=spp, max_depth=3, progress=False, cache_directory=str(cache))


# -- case 4: the reference cache is keyed by the scene's full content ------------------------------------------


EDITS = {
    "mesh": lambda folder: write_ply(folder / "mesh.ply", box(size=1.8)),
    "texture": lambda folder: write_texture(folder / "texture.exr", 0.9),
    "include": lambda folder: write(folder / "light.xml", (folder / "light.xml").read_text().replace('"1.0"', '"3.0"')),
}


@pytest.mark.parametrize("edited", sorted(EDITS))
def test_reference_is_rendered_again_after_a_referenced_file_changes(tmp_path, textured_scene, edited):
    cache = tmp_path / "cache"
    before, record = reference(get_scene(textured_scene), cache)
    assert record["cached"] is False
    assert reference(get_scene(textured_scene), cache)[1]["cached"] is True  # unchanged: reused
    EDITS[edited](tmp_path)
    after, record = reference(get_scene(textured_scene), cache)
    assert record["cached"] is False, f"a reference of the old {edited} was reused"
    assert not np.allclose(before, after)


def test_reference_is_rendered_again_after_a_built_in_scene_changes(tmp_path, monkeypatch, cornell):
    cache = tmp_path / "cache"
    before, record = reference(cornell, cache)
    assert record["cached"] is False
    assert reference(cornell, cache)[1]["cached"] is True
    # The generator of the built-in scene now makes a brighter light: same name, same camera.
    objects = scenes.cornell_box_objects()
    objects["light"]["emitter"]["radiance"]["value"] = [2 * value for value in objects["light"]["emitter"]["radiance"]["value"]]
    changed = scenes.SceneSpec(name=cornell.name, description=cornell.description, objects=objects, camera=cornell.camera)
    after, record = reference(changed, cache)
    assert record["cached"] is False and after.mean() > 1.5 * before.mean()
    # The code generating the built-in scenes changed (same description).
    monkeypatch.setattr(identity_module, "_generator_version", lambda: "another version")
    assert reference(cornell, cache)[1]["cached"] is False


def test_reference_key_holds_the_scene_identity_and_the_resolved_camera(tmp_path, textured_scene):
    spec = get_scene(textured_scene).with_lens(0.05)
    _, record = reference(spec, tmp_path / "cache")
    scene = record["key"]["scene"]
    assert scene["identity"] == scene_identity(spec)["digest"]
    assert scene["camera"]["aperture_radius"] == 0.05
    assert scene["camera"]["focus_distance"] == pytest.approx(4.5, abs=1e-3)  # the box's front face, resolved
    assert json.loads(open(os.path.join(os.path.dirname(record["path"]), "reference.json")).read())["key"] == record["key"]


# -- case 13 (a): an unreadable cache entry is rendered again -----------------------------------------------------


def _truncate(path):
    data = open(path, "rb").read()
    open(path, "wb").write(data[:40])


def _garble_header(path):
    data = bytearray(open(path, "rb").read())
    data[:16] = b"\x00" * 16
    open(path, "wb").write(bytes(data))


def _garble_pixels(path):
    data = bytearray(open(path, "rb").read())
    data[-64:] = b"\xff" * 64
    open(path, "wb").write(bytes(data))


CORRUPTIONS = {"truncated": _truncate, "garbled-header": _garble_header, "garbled-pixels": _garble_pixels}


@pytest.mark.parametrize("corruption", sorted(CORRUPTIONS))
def test_corrupt_cached_reference_is_rendered_again(tmp_path, capsys, cornell, corruption):
    """A reference is its cached passes (the image beside them is derived): a corrupt pass is caught by the
    SHA-256 its record holds and rendered again, with a note."""
    from sparselt.rendering.reference_passes import pass_paths

    cache = tmp_path / "cache"
    image, record = reference(cornell, cache)
    CORRUPTIONS[corruption](pass_paths(record["folder"], 0)[0])
    again, record = reference(cornell, cache)
    assert record["cached"] is False
    assert np.array_equal(again, image)  # the same passes and seeds
    assert "unreadable" in capsys.readouterr().err
    third, record = reference(cornell, cache)  # the entry was replaced
    assert record["cached"] is True and np.array_equal(third, image)


def test_garbled_cache_record_is_rendered_again(tmp_path, capsys, cornell):
    from sparselt.rendering.reference_passes import pass_paths

    cache = tmp_path / "cache"
    image, record = reference(cornell, cache)
    open(pass_paths(record["folder"], 0)[1], "w").write('{"key": ')
    again, record = reference(cornell, cache)
    assert record["cached"] is False and np.array_equal(again, image)
    assert "unreadable" in capsys.readouterr().err


# -- case 13 (b): referenced files are checked before Mitsuba loads the scene ----------------------------------


def _mesh_scene(folder, plugin, filename):
    shape = f'  <shape type="{plugin}" id="part">\n    <string name="filename" value="{filename}"/>\n  </shape>\n'
    return write(folder / "scene.xml", scene_xml(SPHERE + shape))


@pytest.mark.parametrize("plugin, target, complaint", [
    ("ply", "missing.ply", "does not exist"),
    ("ply", "/etc/passwd", "not a PLY mesh"),
    ("obj", "/etc/passwd", "not a Wavefront OBJ mesh"),
    ("serialized", "/etc/passwd", "not a Mitsuba serialized mesh"),
    ("ply", "folder", "not a regular file"),
    ("obj", "binary.obj", "not a Wavefront OBJ mesh"),
], ids=["missing", "passwd-as-ply", "passwd-as-obj", "passwd-as-serialized", "folder", "binary-as-obj"])
def test_referenced_file_that_is_not_a_mesh_is_refused_before_loading(tmp_path, plugin, target, complaint):
    if target == "/etc/passwd" and not os.path.isfile(target):
        pytest.skip("no /etc/passwd here")
    (tmp_path / "folder").mkdir()
    (tmp_path / "binary.obj").write_bytes(bytes(range(256)))
    name = os.path.relpath(target, tmp_path) if os.path.isabs(target) else target  # ../../../etc/passwd
    xml = _mesh_scene(tmp_path, plugin, name)
    with pytest.raises(ValueError, match=complaint) as error:
        MitsubaScene(get_scene(xml), SIZE)
    message = str(error.value)
    assert xml in message and f'<shape type="{plugin}" id="part">' in message
    assert os.path.normpath(os.path.join(tmp_path, name)) in message


def test_missing_include_and_texture_are_named(tmp_path):
    xml = write(tmp_path / "scene.xml", scene_xml(SPHERE + '  <include filename="lights/sky.xml"/>\n'))
    with pytest.raises(ValueError, match=r"<include filename=\"lights/sky.xml\"> references .*sky.xml', which does not"):
        MitsubaScene(get_scene(xml), SIZE)
    (tmp_path / "notes.exr").write_text("not an image")
    texture = ('  <shape type="rectangle"><bsdf type="diffuse"><texture type="bitmap" name="reflectance">'
               '<string name="filename" value="notes.exr"/></texture></bsdf></shape>\n')
    xml = write(tmp_path / "scene.xml", scene_xml(SPHERE + texture))
    with pytest.raises(ValueError, match=r"<texture type=\"bitmap\" name=\"reflectance\"> references .*notes.exr', which is not an image"):
        MitsubaScene(get_scene(xml), SIZE)


def test_real_meshes_pass_the_check(tmp_path):
    write_ply(tmp_path / "mesh.ply", box(size=1.0))
    (tmp_path / "mesh.obj").write_text("# a triangle\nv 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 3\n")
    shapes = ('  <shape type="ply"><string name="filename" value="mesh.ply"/></shape>\n'
              '  <shape type="obj"><string name="filename" value="mesh.obj"/></shape>\n')
    xml = write(tmp_path / "scene.xml", scene_xml(SPHERE + shapes))
    assert len(MitsubaScene(get_scene(xml), SIZE).scene.shapes()) == 3


# -- case 13 (c): a sensor sparselt cannot sample is named by its type ----------------------------------------


def test_irradiancemeter_is_named_by_its_sensor_type(tmp_path):
    xml = write(tmp_path / "scene.xml", '<scene version="3.0.0">\n  <sensor type="irradiancemeter">\n'
                '    <film type="hdrfilm"><integer name="width" value="1"/><integer name="height" value="1"/>'
                '<rfilter type="box"/></film>\n  </sensor>\n' + SPHERE + "</scene>\n")
    with pytest.raises(ValueError, match="sensor is of type 'irradiancemeter'") as error:
        MitsubaScene(get_scene(xml), SIZE)
    assert "'perspective' or 'thinlens'" in str(error.value) and "llvm" not in str(error.value)


def test_a_sensor_it_cannot_sample_is_named_before_its_film_size(tmp_path, capsys):
    """The sensor's type is read from the XML before anything loads: a radiance meter's 1x1 film was refused as too
    small for SSIM first, and its sensor only once that was fixed. A ``$name`` type resolves (its default, or -D);
    with a supported type the film's size is what is refused."""
    xml = write(tmp_path / "scene.xml", '<scene version="3.0.0">\n  <default name="camera" value="radiancemeter"/>\n'
                '  <sensor type="$camera">\n    <film type="hdrfilm"><integer name="width" value="1"/>'
                '<integer name="height" value="1"/></film>\n  </sensor>\n' + SPHERE + "</scene>\n")
    command = ["compare", "--scene", xml, "--kind", "path", "--methods", "pt", "--spp", "4", "--no-progress"]
    assert main(command + ["--out", str(tmp_path / "meter")]) == 2
    message = capsys.readouterr().err
    assert "sensor is of type 'radiancemeter'" in message and "SSIM" not in message
    assert not (tmp_path / "meter").exists()
    assert main(command + ["-D", "camera=perspective", "--out", str(tmp_path / "perspective")]) == 2
    message = capsys.readouterr().err
    assert "too small for SSIM" in message and "sensor is of type" not in message


# -- case 16: an aperture without a focus distance focuses where the central ray hits ---------------------------


def test_aperture_alone_focuses_on_the_scene_and_is_recorded(tmp_path):
    xml = write(tmp_path / "scene.xml", scene_xml(SPHERE))
    loaded = MitsubaScene(get_scene(xml).with_lens(0.1), SIZE)
    assert loaded.camera.thin_lens and loaded.camera.focus_distance == pytest.approx(4.0, abs=1e-4)  # sphere at 5 - 1
    # An explicit focus distance wins; so does a thin-lens scene camera's own.
    assert MitsubaScene(get_scene(xml).with_lens(0.1, 7.0), SIZE).camera.focus_distance == 7.0
    own = write(tmp_path / "own.xml", scene_xml(SPHERE, sensor="thinlens", lens='\n    <float name="aperture_radius" '
                                                "value=\"0.2\"/>\n    <float name=\"focus_distance\" value=\"9\"/>"))
    assert MitsubaScene(get_scene(own).with_lens(0.1), SIZE).camera.focus_distance == pytest.approx(9.0)
    # The value used is what render.json and the signal's metadata record.
    _, record = render_reference(xml, str(tmp_path / "render"), spp=2, aperture=0.1, resolution=SIZE)
    assert record["focus_distance"] == pytest.approx(4.0, abs=1e-4)
    with open(tmp_path / "render" / "render.json") as handle:
        assert json.load(handle)["focus_distance"] == pytest.approx(4.0, abs=1e-4)
    signal = acquire_signal(AcquisitionConfig(scene=xml, kind="dof", shape=(16, 16, 2, 2), spp=1, aperture=0.1),
                            progress=False)
    assert signal.meta["camera"]["focus_distance"] == pytest.approx(4.0, abs=1e-4)


def test_aperture_alone_on_the_built_in_cornell_box_focuses_on_the_box(cornell):
    camera = MitsubaScene(cornell.with_lens(0.05), SIZE).camera
    assert 3.0 < camera.focus_distance < 4.9  # the large box, in front of the back wall at 4.9; not 1000


def test_central_ray_that_misses_keeps_the_focus_distance_and_says_so(tmp_path, capsys):
    xml = write(tmp_path / "scene.xml", scene_xml(SPHERE, target=10))  # looking away from the sphere
    loaded = MitsubaScene(get_scene(xml).with_lens(0.1), SIZE)
    assert loaded.camera.focus_distance == 1000.0
    assert "hits nothing" in capsys.readouterr().err


def test_focus_distance_help_says_what_the_default_is():
    for command in ("sample", "render", "compare"):
        parser = build_parser()
        subparsers = next(action for action in parser._actions if action.dest == "command")
        option = next(action for action in subparsers.choices[command]._actions if action.dest == "focus_distance")
        assert "central ray" in option.help and "recorded" in option.help


# -- case 17: Mitsuba's -D name=value ---------------------------------------------------------------------------


@pytest.fixture
def parameter_scene(tmp_path):
    """The sensor's sample count is $spp, whose default comes only in a later include (Mitsuba's documentation scenes)."""
    write(tmp_path / "defaults.xml", '<scene version="3.0.0">\n  <default name="spp" value="16"/>\n</scene>\n')
    return write(tmp_path / "scene.xml", scene_xml(SPHERE + '  <include filename="defaults.xml"/>\n', spp="$spp"))


def test_undefined_parameter_names_it_and_shows_how_to_pass_it(parameter_scene):
    with pytest.raises(ValueError, match=r"uses parameter \$spp without a default; pass it as -D spp=VALUE"):
        MitsubaScene(get_scene(parameter_scene), SIZE)
    loaded = MitsubaScene(get_scene(parameter_scene).with_parameters([("spp", "8")]), SIZE)
    assert loaded.spec.parameters == (("spp", "8"),)


def test_parameters_are_part_of_the_scene_identity_and_the_reference_key(tmp_path, parameter_scene):
    four, eight = (get_scene(parameter_scene).with_parameters({"spp": value}) for value in ("4", "8"))
    assert scene_identity(four)["digest"] != scene_identity(eight)["digest"]
    assert scene_identity(four)["digest"] == scene_identity(get_scene(parameter_scene).with_parameters([("spp", 4)]))["digest"]
    _, first = reference(four, tmp_path / "cache")
    _, second = reference(eight, tmp_path / "cache")
    assert first["path"] != second["path"] and second["cached"] is False


def test_parameters_resolve_referenced_file_names(tmp_path):
    write_ply(tmp_path / "bunny.ply", box(size=1.0))
    shape = '  <shape type="ply"><string name="filename" value="$mesh.ply"/></shape>\n'
    spec = get_scene(write(tmp_path / "scene.xml", scene_xml(SPHERE + shape))).with_parameters({"mesh": "bunny"})
    assert str(tmp_path / "bunny.ply") in scene_identity(spec)["files"]
    assert len(MitsubaScene(spec, SIZE).scene.shapes()) == 2


@pytest.mark.parametrize("parameters, error, message", [
    ({"spp": "4"}, ValueError, "'cornell-box' is built in and takes no parameters"),
], ids=["built-in"])
def test_parameters_of_a_built_in_scene_are_refused(cornell, parameters, error, message):
    with pytest.raises(error, match=message):
        cornell.with_parameters(parameters)


@pytest.mark.parametrize("parameters, error, message", [
    ({"2spp": "4"}, ValueError, "'2spp' is not a name"),
    ({"parallel": "4"}, ValueError, "reserved by Mitsuba's load_file"),
    ({"spp": None}, TypeError, "text or a number"),
], ids=["not-a-name", "reserved", "not-text"])
def test_bad_parameters_are_refused(parameter_scene, parameters, error, message):
    with pytest.raises(error, match=message):
        get_scene(parameter_scene).with_parameters(parameters)


def test_every_command_taking_a_scene_takes_repeatable_parameters():
    parser = build_parser()
    common = ["--scene", "scene.xml", "-D", "spp=4", "-D", "focus=2.5", "--out", "out"]
    for command, extra in (("sample", ["--kind", "path", "--shape", "8,8"]), ("render", ["--spp", "1"]),
                           ("compare", ["--kind", "path", "--shape", "16,16"]), ("table61", [])):
        arguments = parser.parse_args([command] + common + extra)
        assert arguments.parameters == (("focus", "2.5"), ("spp", "4")), command
        assert parser.parse_args([command, "--scene", "x", "--out", "o"] + extra).parameters == ()


def test_parameters_travel_through_every_configuration(parameter_scene):
    spec = validate_config(ComparisonConfig(scene=parameter_scene, kind="path", shape=(16, 16) + (2,) * 8, methods=("pt",),
                                            scene_parameters=(("spp", "4"),)))
    assert spec.parameters == (("spp", "4"),)
    assert Table61Config(scene=parameter_scene, scene_parameters=(("spp", "4"),)).record()["scene_parameters"]
    config = AcquisitionConfig(scene=parameter_scene, kind="path", shape=(16, 16, 2, 2, 2, 2), spp=1,
                               scene_parameters=(("spp", "4"),), max_depth=2)
    assert config.record()["scene_parameters"] == [["spp", "4"]]
    signal = acquire_signal(config, progress=False)
    assert signal.shape == (16, 16, 2, 2, 2, 2)


def test_cli_render_with_and_without_the_parameter(tmp_path, capsys, parameter_scene):
    assert main(["render", "--scene", parameter_scene, "--spp", "2", "--out", str(tmp_path / "without")]) == 2
    assert "pass it as -D spp=VALUE" in capsys.readouterr().err
    assert main(["render", "--scene", parameter_scene, "--spp", "2", "-D", "spp=4",
                 "--out", str(tmp_path / "with")]) == 0
    assert os.path.isfile(tmp_path / "with" / "render.json")
    assert main(["render", "--scene", "cornell-box", "--spp", "2", "-D", "spp=4", "--out", str(tmp_path / "b")]) == 2
    assert "takes no parameters" in capsys.readouterr().err


# -- participating media: refused, named ------------------------------------------------------------------------

SMOKE = ('  <shape type="sphere" id="smoke-ball"><bsdf type="dielectric"/>\n'
         '    <medium type="homogeneous" name="interior"><float name="scale" value="4"/></medium></shape>\n')


def test_a_scene_with_participating_media_is_refused_naming_the_shape(tmp_path):
    """Every estimator of sparselt, and Mitsuba's path integrator behind its baseline and references, trace surfaces
    only: a medium would be left out of every image alike. The scene is refused, the shape named; the same scene
    without the medium loads."""
    with pytest.raises(ValueError, match=r"has participating media \(shape 'smoke-ball'\).*remove the media"):
        MitsubaScene(get_scene(write(tmp_path / "smoke.xml", scene_xml(SPHERE + SMOKE))), SIZE)
    clear = SMOKE.replace('\n    <medium type="homogeneous" name="interior"><float name="scale" value="4"/></medium>', "")
    MitsubaScene(get_scene(write(tmp_path / "clear.xml", scene_xml(SPHERE + clear))), SIZE)


def test_a_film_crop_window_is_noted_once_and_the_whole_film_rendered(tmp_path, capsys):
    crop = '<integer name="crop_offset_x" value="4"/><integer name="crop_width" value="8"/>'
    path = write(tmp_path / "crop.xml", scene_xml(SPHERE).replace("</film>", crop + "</film>"))
    assert crop in open(path).read()
    first = MitsubaScene(get_scene(path), SIZE)
    MitsubaScene(get_scene(path), SIZE)
    noted = capsys.readouterr().err
    assert noted.count("crop window (8x") == 1 and "renders the whole" in noted
    assert (first.width, first.height) == SIZE


# -- the file's sensor: principal point offset kept, extra sensors named -----------------------------------------

def _centre_ray_direction(sensor):
    import mitsuba as mi

    ray, _ = sensor.sample_ray(time=0.0, sample1=0.5, sample2=mi.Point2f(0.5, 0.5), sample3=mi.Point2f(0.5, 0.5))
    return np.array([float(np.ravel(np.asarray(component))[0]) for component in ray.d])


def test_a_principal_point_offset_is_kept_by_a_pinhole_and_noted_under_a_thin_lens(tmp_path, capsys):
    """The file's off-centre view is rendered as the file frames it: the ray through the image centre is the file's
    own sensor's (off the optical axis). A thin lens (Mitsuba's has no offset) renders the centred view and says so."""
    offset = '<float name="principal_point_offset_x" value="0.25"/><float name="principal_point_offset_y" value="-0.125"/>'
    path = write(tmp_path / "offset.xml", scene_xml(SPHERE).replace('<float name="fov" value="45"/>',
                                                                   '<float name="fov" value="45"/>' + offset))
    scene = MitsubaScene(get_scene(path), SIZE)
    assert scene.principal_point == (0.25, -0.125)
    own = _centre_ray_direction(scene.scene.sensors()[0])
    ours = _centre_ray_direction(scene.sensor)
    assert np.allclose(ours, own, atol=1e-6)
    assert abs(own[0]) > 0.05 and abs(own[1]) > 0.01  # off the optical axis (the camera looks along -z)
    assert "principal point" not in capsys.readouterr().err
    lens = MitsubaScene(get_scene(path).with_lens(aperture_radius=0.1, focus_distance=5.0), SIZE)
    assert lens.principal_point == (0.0, 0.0)
    assert np.allclose(_centre_ray_direction(lens.sensor), [0.0, 0.0, -1.0], atol=1e-6)
    assert "principal point offset (0.25, -0.125) that a thin lens cannot keep" in capsys.readouterr().err


def test_a_file_with_several_sensors_renders_through_the_first_and_names_them(tmp_path, capsys):
    second = SENSOR.format(sensor="perspective", lens="", target=0, spp=4).replace(
        '<sensor type="perspective">', '<sensor type="perspective" id="overview">').replace("0, 0, 5", "5, 0, 0")
    path = write(tmp_path / "two.xml", scene_xml(SPHERE + second))
    scene = MitsubaScene(get_scene(path), SIZE)
    assert np.allclose(_centre_ray_direction(scene.sensor), [0.0, 0.0, -1.0], atol=1e-6)
    MitsubaScene(get_scene(path), SIZE)
    noted = capsys.readouterr().err
    assert noted.count("has 2 sensors") == 1 and "'overview'" in noted and "the first one" in noted


@pytest.mark.parametrize("files_depth, noted", [("8", "has max_depth 8; the 'path' kind here renders paths up to max "
                                                     "depth 3 (every method, PT and the reference alike): give "
                                                     "--max-depth 8"),
                                                ("-1", "has no depth limit (max_depth -1)"),
                                                ("3", None)], ids=["deeper", "unlimited", "same"])
def test_the_files_integrator_depth_is_noted_where_it_differs_from_the_kinds(tmp_path, capsys, files_depth, noted):
    """sparselt renders every kind to its own --max-depth; a file whose integrator names another says so, once."""
    from sparselt.rendering.setup import SceneSetup

    head = f'  <integrator type="path"><integer name="max_depth" value="{files_depth}"/></integrator>\n'
    path = write(tmp_path / f"depth{files_depth}.xml", scene_xml(SPHERE, head=head))
    for _ in range(2):
        SceneSetup(scene=path, kind="path", max_depth=3).load()
    printed = capsys.readouterr().err
    if noted is None:
        assert "max_depth" not in printed
    else:
        assert printed.count(noted) == 1, printed
