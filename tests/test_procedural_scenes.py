"""Procedural meshes and scenes (pure Python side: no renderer)."""

import subprocess
import sys

import numpy as np
import pytest

from sparselt.rendering import meshes, procedural
from sparselt.rendering.scenes import SCENES, Transform, get_scene, scene_names


def read_ply(path):
    """Independent minimal reader of our binary PLY (float xyz[nxnynz], uchar-int faces)."""
    with open(path, "rb") as handle:
        content = handle.read()
    end = content.index(b"end_header\n") + len(b"end_header\n")
    header = content[:end].decode("ascii").splitlines()
    assert header[0] == "ply" and header[1] == "format binary_little_endian 1.0"
    vertex_count = int(next(line.split()[2] for line in header if line.startswith("element vertex")))
    face_count = int(next(line.split()[2] for line in header if line.startswith("element face")))
    assert "property list uchar int vertex_indices" in header
    properties = [line.split()[2] for line in header if line.startswith("property float")]
    vertices = np.frombuffer(content, dtype="<f4", count=vertex_count * len(properties), offset=end)
    vertices = vertices.reshape(-1, len(properties))
    faces = np.frombuffer(content, dtype=[("n", "u1"), ("i", "<i4", (3,))], count=face_count,
                          offset=end + vertices.nbytes)
    assert end + vertices.nbytes + faces.nbytes == len(content)  # nothing left over
    return properties, vertices, faces


def assert_closed_and_valid(mesh):
    """Indices in range, no degenerate triangles, closed and wound outwards once welded."""
    assert mesh.faces.min() >= 0 and mesh.faces.max() < mesh.vertex_count
    scale = float(np.max(np.ptp(mesh.vertices, axis=0)))
    assert mesh.face_areas().min() > 1e-10 * scale**2
    welded = mesh.welded()
    assert welded.face_areas().min() > 1e-10 * scale**2  # welding collapsed nothing
    directed = np.concatenate([welded.faces[:, [0, 1]], welded.faces[:, [1, 2]], welded.faces[:, [2, 0]]])
    _, counts = np.unique(directed, axis=0, return_counts=True)
    assert counts.max() == 1  # no edge used twice in the same direction: consistent winding
    reverse = set(map(tuple, directed[:, ::-1]))
    assert all(tuple(edge) in reverse for edge in directed)  # every edge has its twin: closed
    assert welded.signed_volume() > 0  # wound outwards


SMALL_SOLIDS = {
    "box": lambda: meshes.box((1.0, 2.0, 3.0), center=(0.5, -1.0, 2.0)),
    "icosphere": lambda: meshes.icosphere(2),
    "blob": lambda: meshes.blob(subdivisions=3, seed=3),
    "torus-knot": lambda: meshes.torus_knot(segments=96, sides=10),
    "spiked-torus-knot": lambda: meshes.spiked_torus_knot(segments=240, sides=16, spike_count=24),
    "column": lambda: meshes.column(flutes=8, segments=32, detail=3),
    "vase-amphora": lambda: meshes.vase(flutes=8, segments=32, detail=10, shape=0),
    "vase-pot": lambda: meshes.vase(segments=24, detail=8, shape=1),
    "vase-bowl": lambda: meshes.vase(segments=24, detail=8, shape=2),
    "lathe-cylinder": lambda: meshes.lathe([(0, 0), (1, 0), (1, 2), (0, 2)], segments=16),
    "arch-round": lambda: meshes.arch(1.0, 1.3, 0.4, segments=16),
    "arch-square": lambda: meshes.arch(0.7, 1.0, 0.5, segments=16, outer_height=1.2),
}


@pytest.mark.parametrize("name", sorted(SMALL_SOLIDS))
def test_solids_are_closed_and_valid(name):
    assert_closed_and_valid(SMALL_SOLIDS[name]())


def test_volumes_match_the_shapes():
    assert meshes.box((1.0, 2.0, 3.0)).signed_volume() == pytest.approx(6.0)
    cylinder = meshes.lathe([(0, 0), (1, 0), (1, 2), (0, 2)], segments=256)
    assert cylinder.signed_volume() == pytest.approx(2 * np.pi, rel=1e-3)
    assert meshes.arch(1.0, 1.3, 0.4, segments=256).signed_volume() == pytest.approx(
        0.4 * 0.5 * np.pi * (1.3**2 - 1.0), rel=1e-3)
    assert meshes.arch(0.7, 1.0, 0.5, segments=256, outer_height=1.2).signed_volume() == pytest.approx(
        0.5 * (2.0 * 1.2 - 0.5 * np.pi * 0.7**2), rel=1e-3)
    # A mirror keeps the faces facing outwards.
    assert meshes.box((1, 2, 3)).scaled((-1.0, 1.0, 1.0)).signed_volume() == pytest.approx(6.0)


def test_wall_with_openings():
    openings = [(-2.0, -1.0, 0.0, 2.2), (0.0, 1.0, 1.0, 2.0), (0.0, 1.0, 2.2, 2.8)]  # a door, two stacked windows
    wall = meshes.wall_with_openings(6.0, 3.0, 0.3, openings)
    assert wall.faces.min() >= 0 and wall.faces.max() < wall.vertex_count and wall.face_areas().min() > 0
    assert wall.signed_volume() == pytest.approx(0.3 * (18.0 - 2.2 - 1.0 - 0.6))
    low, high = wall.bounding_box()
    assert np.allclose(low, (-3.0, 0.0, -0.15)) and np.allclose(high, (3.0, 3.0, 0.15))
    with pytest.raises(ValueError, match="overlap"):
        meshes.wall_with_openings(6.0, 3.0, 0.3, [(-1.0, 1.0, 0.5, 2.0), (0.0, 2.0, 1.0, 2.5)])
    with pytest.raises(ValueError, match="does not fit"):
        meshes.wall_with_openings(6.0, 3.0, 0.3, [(2.0, 4.0, 0.5, 2.0)])


@pytest.mark.parametrize("name", ["box", "icosphere", "torus-knot", "column", "arch-square"])
@pytest.mark.parametrize("normals", [True, False])
def test_ply_round_trip(tmp_path, name, normals):
    mesh = SMALL_SOLIDS[name]()
    path = tmp_path / "mesh.ply"
    meshes.write_ply(path, mesh, normals=normals)
    properties, vertices, faces = read_ply(path)
    assert properties == (["x", "y", "z", "nx", "ny", "nz"] if normals else ["x", "y", "z"])
    assert np.allclose(vertices[:, :3], mesh.vertices, atol=1e-6)
    assert np.all(faces["n"] == 3) and np.array_equal(faces["i"], mesh.faces)
    if normals:
        normal = vertices[:, 3:]
        assert np.allclose(np.linalg.norm(normal, axis=1), 1.0, atol=1e-4)
        # Normals agree with the winding: the mean normal at each face points along its geometric normal.
        assert (np.einsum("ij,ij->i", normal[mesh.faces].mean(axis=1), mesh.face_normals()) > 0).all()
    assert not [entry for entry in tmp_path.iterdir() if entry.name != "mesh.ply"]  # no temporary left


def test_generators_are_deterministic():
    assert meshes.ply_bytes(meshes.blob(subdivisions=3, seed=5)) == meshes.ply_bytes(meshes.blob(subdivisions=3, seed=5))
    assert meshes.ply_bytes(meshes.blob(subdivisions=3, seed=5)) != meshes.ply_bytes(meshes.blob(subdivisions=3, seed=6))
    first = meshes.spiked_torus_knot(segments=120, sides=12)
    assert meshes.ply_bytes(first) == meshes.ply_bytes(meshes.spiked_torus_knot(segments=120, sides=12))


def test_mesh_files_are_deterministic_and_cached(tmp_path, monkeypatch):
    monkeypatch.setenv("SPARSELT_CACHE", str(tmp_path))
    first = meshes.mesh_file("test-knot", meshes.torus_knot, segments=64, sides=8)
    assert first.startswith(str(tmp_path / "meshes" / "test-knot-")) and first.endswith(".ply")
    content = open(first, "rb").read()
    again = meshes.mesh_file("test-knot", meshes.torus_knot, segments=64, sides=8)
    assert again == first and open(again, "rb").read() == content
    other = meshes.mesh_file("test-knot", meshes.torus_knot, segments=65, sides=8)
    assert other != first
    assert meshes.ply_bytes(meshes.torus_knot(segments=64, sides=8)) == content
    # An existing file is reused, not rewritten.
    with open(first, "ab") as handle:
        handle.write(b"marker")
    assert open(meshes.mesh_file("test-knot", meshes.torus_knot, segments=64, sides=8), "rb").read().endswith(b"marker")
    with pytest.raises(ValueError, match="letters"):
        meshes.mesh_file("bad/name", meshes.torus_knot)


def _all_values(value):
    if isinstance(value, dict):
        for item in value.values():
            yield from _all_values(item)
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _all_values(item)
    else:
        yield value


def _ply_triangles(objects):
    total = 0
    for entry in objects.values():
        if isinstance(entry, dict) and entry.get("type") == "ply":
            properties, _, faces = read_ply(entry["filename"])
            assert properties[:3] == ["x", "y", "z"]
            total += len(faces)
    return total


@pytest.mark.parametrize("name", ["dof-sculptures", "courtyard", "sunlit-room"])
def test_scenes_are_registered_dictionaries_without_sensor(name):
    assert name in scene_names() and name in SCENES
    spec = get_scene(name)
    assert spec.name == name and spec.filename is None and spec.objects["type"] == "scene"
    assert not any(isinstance(entry, dict) and entry.get("type") in ("perspective", "thinlens") for entry in spec.objects.values())
    assert "sensor" not in spec.objects and "integrator" not in spec.objects
    for key, entry in spec.objects.items():
        if isinstance(entry, dict) and "to_world" in entry:
            assert isinstance(entry["to_world"], Transform), key
    assert not any(isinstance(value, np.ndarray) for value in _all_values(spec.objects))
    assert isinstance(spec.camera.to_world, Transform)
    assert any(isinstance(entry, dict) and entry.get("type") == "constant" for entry in spec.objects.values())


def test_dof_scene_focuses_on_the_middle_sculpture():
    spec = get_scene("dof-sculptures")
    camera = spec.camera
    assert camera.thin_lens and camera.aperture_radius > 0
    origin = np.array(procedural.DOF_CAMERA_ORIGIN)
    view = np.array(procedural.DOF_CAMERA_TARGET) - origin
    view /= np.linalg.norm(view)
    depths = sorted((np.array([x, 0.5 * size, z]) - origin) @ view for _, (x, z), size, _ in procedural.DOF_SCULPTURES)
    assert 4 <= len(depths) <= 6
    middle = depths[len(depths) // 2]
    assert abs(camera.focus_distance - middle) < 0.1 * middle
    assert depths[0] < 0.7 * middle and depths[-1] > 1.4 * middle  # objects in front and behind
    # Strong blur: the circle of confusion of the nearest and farthest sculptures
    # spans several percent of the image width.
    width = 2 * np.tan(np.radians(camera.fov / 2))
    for depth in (depths[0], depths[-1]):
        blur = 2 * camera.aperture_radius * abs(1 / depth - 1 / camera.focus_distance)
        assert blur / width > 0.04
    assert spec.objects["key-light"]["emitter"]["type"] == "area"
    assert 150_000 < _ply_triangles(spec.objects) < 400_000


def test_courtyard_is_dense_and_has_openings():
    spec = get_scene("courtyard")
    assert not spec.camera.thin_lens and spec.camera.aperture_radius is None
    assert _ply_triangles(spec.objects) > 300_000
    assert spec.objects["sun"]["type"] == "directional"
    layout = procedural._courtyard_layout()
    assert sum(len(placements) for placements in layout.values()) > 100
    walls = [placement for placement in layout["plaster"] if placement["kind"] == "wall"]
    assert sum(len(placement["parameters"]["openings"]) for placement in walls) > 20


def test_scene_modules_do_not_import_the_renderer():
    code = ("import sys; from sparselt.rendering.scenes import scene_names; scene_names(); "
            "import sparselt.rendering.meshes; assert 'mitsuba' not in sys.modules and 'drjit' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
