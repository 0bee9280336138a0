"""Procedural meshes and scenes (pure Python side: no renderer)."""

import numpy as np
import pytest

from sparselt.rendering import meshes, procedural
from sparselt.rendering.scenes import get_scene


def read_ply(path):
    """Independent minimal reader of our binary PLY (float xyz[nxnynz], uchar-int faces)."""
    with open(path, "rb") as handle:
        content = handle.read()
    end = content.index(b"end_header\n") + len(b"end_header\n")
    header = content[:end].decode("ascii").splitlines()
    vertex_count = int(next(line.split()[2] for line in header if line.startswith("element vertex")))
    face_count = int(next(line.split()[2] for line in header if line.startswith("element face")))
    properties = sum(1 for line in header if line.startswith("property float"))
    vertices = np.frombuffer(content, dtype="<f4", count=vertex_count * properties, offset=end).reshape(-1, properties)
    faces = np.frombuffer(content, dtype=[("n", "u1"), ("i", "<i4", (3,))], count=face_count,
                          offset=end + vertices.nbytes)
    return vertices, faces


@pytest.mark.parametrize("mesh", [
    meshes.box((1.0, 2.0, 3.0)),
    meshes.icosphere(2),
    meshes.torus_knot(segments=64, sides=8),
    meshes.column(flutes=8, segments=32, detail=3),
])
def test_ply_round_trip(tmp_path, mesh):
    path = tmp_path / "mesh.ply"
    meshes.write_ply(path, mesh)
    vertices, faces = read_ply(path)
    assert np.allclose(vertices[:, :3], mesh.vertices, atol=1e-6)
    assert np.all(faces["n"] == 3) and np.array_equal(faces["i"], mesh.faces)
    normals = vertices[:, 3:]
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-4)


@pytest.mark.parametrize("builder", [meshes.icosphere, meshes.blob, meshes.box])
def test_closed_meshes_have_positive_volume_and_no_degenerate_triangles(builder):
    mesh = builder()
    assert mesh.faces.min() >= 0 and mesh.faces.max() < mesh.vertex_count
    assert mesh.face_areas().min() > 0
    assert mesh.signed_volume() > 0  # closed and wound outwards


def test_mesh_files_are_deterministic_and_cached(tmp_path, monkeypatch):
    monkeypatch.setenv("SPARSELT_CACHE", str(tmp_path))
    first = meshes.mesh_file("test-knot", meshes.torus_knot, segments=64, sides=8)
    content = open(first, "rb").read()
    again = meshes.mesh_file("test-knot", meshes.torus_knot, segments=64, sides=8)
    assert again == first and open(again, "rb").read() == content
    other = meshes.mesh_file("test-knot", meshes.torus_knot, segments=65, sides=8)
    assert other != first
    assert meshes.ply_bytes(meshes.torus_knot(segments=64, sides=8)) == content


def test_dof_scene_focuses_on_the_middle_sculpture():
    spec = get_scene("dof-sculptures")
    camera = spec.camera
    assert camera.thin_lens and camera.aperture_radius > 0
    origin = np.array(procedural.DOF_CAMERA_ORIGIN)
    distances = sorted(np.linalg.norm(origin - np.array([x, 0.0, z])) for _, (x, z), _, _ in procedural.DOF_SCULPTURES)
    middle = distances[len(distances) // 2]
    assert abs(camera.focus_distance - middle) < 0.1 * middle
    assert distances[0] < 0.7 * middle and distances[-1] > 1.4 * middle  # objects in front and behind


def test_courtyard_is_dense_and_has_openings():
    spec = get_scene("courtyard")
    assert not spec.camera.thin_lens
    triangles = 0
    for entry in spec.objects.values():
        if isinstance(entry, dict) and entry.get("type") == "ply":
            with open(entry["filename"], "rb") as handle:
                header = handle.read(400).decode("ascii", errors="ignore")
            triangles += int(header.split("element face ")[1].split()[0])
    assert triangles > 100_000
    assert spec.objects["sun"]["type"] == "directional"
