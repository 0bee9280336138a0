"""Procedural triangle meshes, written as binary PLY files into a cache.

This module is pure Python and numpy: it never imports Mitsuba. The
procedural scenes (:mod:`sparselt.rendering.procedural`) build their detailed
geometry here and refer to it by file name (``{'type': 'ply', 'filename':
...}``), so that the renderer adapter loads it like any other mesh.

Generators
----------
:func:`box`, :func:`icosphere`, :func:`blob` (a noisy, displaced sphere),
:func:`torus_knot` (a tube around a torus knot), :func:`spiked_torus_knot`
(a twisted, spiked knot: a "dragon-like" sculpture), :func:`lathe` (a
surface of revolution, optionally fluted) with the profiles :func:`column`
and :func:`vase`, :func:`arch` (a half annulus, or an arch in a rectangular
block, extruded) and :func:`wall_with_openings`.

Every generator is deterministic (noise uses fixed seeds), and every solid is
closed once coincident vertices are welded (:meth:`TriangleMesh.welded`), with
the faces wound counter-clockwise seen from outside, which is Mitsuba's
convention for the geometric normal. Hard edges are made by *not* sharing
vertices across them, so that the area-weighted vertex normals written to
the PLY file (:meth:`TriangleMesh.vertex_normals`) are smooth where the
surface is smooth and sharp where it is creased.

Cache
-----
:func:`mesh_file` writes a mesh once to
``$SPARSELT_CACHE/meshes/<name>-<hash>.ply`` (``SPARSELT_CACHE`` defaults to
``~/.cache/sparselt``), where the hash covers the generator's parameters and
:data:`MESH_FORMAT_VERSION`, and returns the existing file on later calls.
Files are written to a temporary name in the same directory and moved into
place with :func:`os.replace`, so a reader never sees a partial file.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from ..digest import digest
from ..provenance import atomic_write_bytes

#: Bumped whenever a generator's output changes, so that stale cache files are
#: not reused (the version is part of every cache key).
MESH_FORMAT_VERSION = 1


# ---------------------------------------------------------------------------
# Mesh container and affine transforms
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """An indexed triangle mesh.

    Attributes
    ----------
    vertices : numpy.ndarray
        Vertex positions, shape ``(vertex_count, 3)``, float64.
    faces : numpy.ndarray
        Vertex indices of each triangle, shape ``(triangle_count, 3)``,
        int64, wound counter-clockwise seen from the side the surface faces.
    """

    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self):
        vertices = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        faces = np.ascontiguousarray(self.faces, dtype=np.int64).reshape(-1, 3)
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)

    @property
    def vertex_count(self):
        """Number of vertices."""
        return len(self.vertices)

    @property
    def triangle_count(self):
        """Number of triangles."""
        return len(self.faces)

    def face_cross_products(self):
        """Cross products ``(p1 - p0) x (p2 - p0)`` of the triangles.

        Returns
        -------
        numpy.ndarray
            Shape ``(triangle_count, 3)``; the direction is the geometric
            normal, the length twice the area.
        """
        corners = self.vertices[self.faces]
        return np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])

    def face_areas(self):
        """Triangle areas, shape ``(triangle_count,)``."""
        return 0.5 * np.linalg.norm(self.face_cross_products(), axis=1)

    def face_normals(self):
        """Unit geometric normals of the triangles (zero for degenerate ones)."""
        cross = self.face_cross_products()
        length = np.linalg.norm(cross, axis=1, keepdims=True)
        return np.divide(cross, length, out=np.zeros_like(cross), where=length > 0)

    def vertex_normals(self):
        """Area-weighted average of the normals of the triangles around each vertex.

        Returns
        -------
        numpy.ndarray
            Unit normals, shape ``(vertex_count, 3)``. A vertex used by no
            triangle gets ``(0, 0, 1)``.
        """
        cross = self.face_cross_products()
        normals = np.zeros_like(self.vertices)
        for corner in range(3):
            np.add.at(normals, self.faces[:, corner], cross)
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        unused = length[:, 0] == 0
        normals[unused] = (0.0, 0.0, 1.0)
        length[unused] = 1.0
        return normals / length

    def signed_volume(self):
        """Enclosed volume; positive for a closed mesh wound outwards."""
        corners = self.vertices[self.faces]
        return float(np.einsum("ij,ij->i", corners[:, 0], np.cross(corners[:, 1], corners[:, 2])).sum() / 6.0)

    def bounding_box(self):
        """Return ``(minimum, maximum)`` corners of the axis-aligned bounding box."""
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def welded(self, tolerance=1e-7):
        """Merge vertices whose positions agree to ``tolerance`` (absolute).

        Returns
        -------
        TriangleMesh
            The mesh with shared vertices; faces whose corners collapse are kept
            (they show up as degenerate triangles).
        """
        keys = np.round(self.vertices / tolerance).astype(np.int64)
        _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
        return TriangleMesh(self.vertices[first], inverse.reshape(-1)[self.faces])

    def transformed(self, matrix):
        """Apply a 4x4 affine matrix (column-vector convention).

        A matrix with negative determinant (a mirror) also reverses the
        winding, so that the faces still face outwards.

        Parameters
        ----------
        matrix : array_like
            Shape ``(4, 4)``; the last row must be ``(0, 0, 0, 1)``.
        """
        matrix = np.asarray(matrix, dtype=np.float64)
        vertices = self.vertices @ matrix[:3, :3].T + matrix[:3, 3]
        faces = self.faces if np.linalg.det(matrix[:3, :3]) > 0 else self.faces[:, ::-1]
        return TriangleMesh(vertices, faces)

    def translated(self, offset):
        """Return the mesh moved by ``offset``."""
        return self.transformed(translation_matrix(offset))

    def scaled(self, factor):
        """Return the mesh scaled about the origin by a scalar or a 3-vector."""
        return self.transformed(scaling_matrix(factor))

    def rotated(self, axis, angle_degrees):
        """Return the mesh rotated about ``axis`` through the origin (right-handed)."""
        return self.transformed(rotation_matrix(axis, angle_degrees))


def translation_matrix(offset):
    """4x4 matrix translating by ``offset``."""
    matrix = np.eye(4)
    matrix[:3, 3] = np.asarray(offset, dtype=np.float64)
    return matrix


def scaling_matrix(factor):
    """4x4 matrix scaling by a scalar or per-axis ``factor``."""
    factor = np.broadcast_to(np.asarray(factor, dtype=np.float64), (3,))
    return np.diag([factor[0], factor[1], factor[2], 1.0])


def rotation_matrix(axis, angle_degrees):
    """4x4 matrix rotating by ``angle_degrees`` about ``axis`` (Rodrigues; as Mitsuba's ``rotate``)."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    angle = math.radians(angle_degrees)
    cosine, sine = math.cos(angle), math.sin(angle)
    x, y, z = axis
    cross = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    matrix = np.eye(4)
    matrix[:3, :3] = cosine * np.eye(3) + sine * cross + (1.0 - cosine) * np.outer(axis, axis)
    return matrix


def merge(meshes):
    """Concatenate meshes into one (no vertices are shared between them).

    Parameters
    ----------
    meshes : iterable of TriangleMesh

    Returns
    -------
    TriangleMesh
    """
    meshes = list(meshes)
    if not meshes:
        return TriangleMesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))
    offsets = np.cumsum([0] + [mesh.vertex_count for mesh in meshes[:-1]])
    vertices = np.concatenate([mesh.vertices for mesh in meshes])
    faces = np.concatenate([mesh.faces + offset for mesh, offset in zip(meshes, offsets)])
    return TriangleMesh(vertices, faces)


# ---------------------------------------------------------------------------
# Building blocks: grids, fans, oriented planar pieces
# ---------------------------------------------------------------------------


def _grid_faces(rows, columns, wrap_rows=False, wrap_columns=False):
    """Triangles of a ``rows x columns`` vertex grid stored row-major.

    Each quad ``(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)`` becomes two
    triangles with the winding of that corner order.
    """
    row_count = rows if wrap_rows else rows - 1
    column_count = columns if wrap_columns else columns - 1
    i, j = np.meshgrid(np.arange(row_count), np.arange(column_count), indexing="ij")
    i, j = i.ravel(), j.ravel()
    i1, j1 = (i + 1) % rows, (j + 1) % columns
    a, b, c, d = i * columns + j, i1 * columns + j, i1 * columns + j1, i * columns + j1
    return np.concatenate([np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)])


def _grid_mesh(points, wrap_rows=False, wrap_columns=False):
    """Mesh of a grid of points with shape ``(rows, columns, 3)``."""
    rows, columns = points.shape[:2]
    return TriangleMesh(points.reshape(-1, 3), _grid_faces(rows, columns, wrap_rows, wrap_columns))


def _orient(mesh, outward):
    """Reverse the winding of ``mesh`` if its normals mostly oppose ``outward``.

    Parameters
    ----------
    mesh : TriangleMesh
        A piece with consistent winding.
    outward : array_like or callable
        A direction, or a function of the face centres (``(m, 3)``) returning
        directions (``(m, 3)``) the surface should face.
    """
    centres = mesh.vertices[mesh.faces].mean(axis=1)
    direction = outward(centres) if callable(outward) else np.broadcast_to(np.asarray(outward, float), centres.shape)
    agreement = np.einsum("ij,ij->", mesh.face_cross_products(), direction)
    return mesh if agreement >= 0 else TriangleMesh(mesh.vertices, mesh.faces[:, ::-1])


def _polygon(corners, outward):
    """A planar convex polygon (fan from the first corner), facing ``outward``."""
    corners = np.asarray(corners, dtype=np.float64)
    count = len(corners)
    faces = np.stack([np.zeros(count - 2, dtype=np.int64), np.arange(1, count - 1), np.arange(2, count)], axis=1)
    return _orient(TriangleMesh(corners, faces), outward)


# ---------------------------------------------------------------------------
# Primitive solids
# ---------------------------------------------------------------------------


def box(size=(1.0, 1.0, 1.0), center=(0.0, 0.0, 0.0)):
    """An axis-aligned box with sharp edges (each face has its own four vertices).

    Parameters
    ----------
    size : float or sequence of 3 floats
        Edge lengths along x, y, z.
    center : sequence of 3 floats
        Centre of the box.

    Returns
    -------
    TriangleMesh
        12 triangles, 24 vertices; closed once welded.
    """
    half = 0.5 * np.broadcast_to(np.asarray(size, dtype=np.float64), (3,))
    center = np.asarray(center, dtype=np.float64)
    pieces = []
    for axis in range(3):
        other1, other2 = (axis + 1) % 3, (axis + 2) % 3
        for sign in (-1.0, 1.0):
            corners = np.zeros((4, 3))
            corners[:, axis] = sign * half[axis]
            corners[:, other1] = np.array([-1, 1, 1, -1]) * half[other1]
            corners[:, other2] = np.array([-1, -1, 1, 1]) * half[other2]
            outward = np.zeros(3)
            outward[axis] = sign
            pieces.append(_polygon(corners + center, outward))
    return merge(pieces)


def icosphere(subdivisions=3, radius=1.0):
    """A geodesic sphere: an icosahedron subdivided ``subdivisions`` times.

    Returns
    -------
    TriangleMesh
        ``20 * 4**subdivisions`` triangles, closed, all vertices at distance
        ``radius`` from the origin.
    """
    golden = (1.0 + math.sqrt(5.0)) / 2.0
    vertices = np.array(
        [
            [-1, golden, 0], [1, golden, 0], [-1, -golden, 0], [1, -golden, 0],
            [0, -1, golden], [0, 1, golden], [0, -1, -golden], [0, 1, -golden],
            [golden, 0, -1], [golden, 0, 1], [-golden, 0, -1], [-golden, 0, 1],
        ],
        dtype=np.float64,
    )  # fmt: skip
    faces = np.array(
        [
            [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
            [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
            [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
            [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
        ],
        dtype=np.int64,
    )  # fmt: skip
    vertices /= np.linalg.norm(vertices, axis=1, keepdims=True)
    for _ in range(subdivisions):
        edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
        edges.sort(axis=1)
        unique_edges, inverse = np.unique(edges, axis=0, return_inverse=True)
        midpoints = vertices[unique_edges].mean(axis=1)
        midpoints /= np.linalg.norm(midpoints, axis=1, keepdims=True)
        middle = inverse.reshape(3, -1) + len(vertices)  # midpoints of edges 01, 12, 20
        a, b, c = faces.T
        ab, bc, ca = middle
        faces = np.concatenate(
            [np.stack(t, axis=1) for t in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))]
        )
        vertices = np.concatenate([vertices, midpoints])
    return TriangleMesh(vertices * radius, faces)


def _plane_wave_noise(directions, wave_count, frequency, seed, sharpness=0.0):
    """Sum of random plane waves on unit directions, roughly in ``[-1, 1]``.

    The waves have random directions, phases and frequencies in
    ``[frequency / 2, frequency]``, with amplitude falling as 1/frequency;
    ``sharpness`` in ``[0, 1]`` blends each wave towards ``1 - 2|sin|``
    (ridges).
    """
    generator = np.random.default_rng(seed)
    wave_directions = generator.normal(size=(wave_count, 3))
    wave_directions /= np.linalg.norm(wave_directions, axis=1, keepdims=True)
    frequencies = generator.uniform(0.5 * frequency, frequency, size=wave_count)
    phases = generator.uniform(0.0, 2.0 * math.pi, size=wave_count)
    amplitudes = 1.0 / frequencies
    argument = (directions @ wave_directions.T) * frequencies + phases
    smooth = np.sin(argument)
    ridged = 1.0 - 2.0 * np.abs(np.sin(0.5 * argument))
    waves = (1.0 - sharpness) * smooth + sharpness * ridged
    noise = waves @ amplitudes
    return noise / (amplitudes.sum() * 0.5)


def blob(radius=1.0, subdivisions=5, amplitude=0.18, frequency=7.0, wave_count=32, sharpness=0.35, seed=1):
    """A lumpy sphere: an icosphere displaced along its normals by plane-wave noise.

    Parameters
    ----------
    radius : float
        Radius before displacement.
    subdivisions : int
        Icosphere subdivisions (``20 * 4**subdivisions`` triangles).
    amplitude : float
        Displacement amplitude relative to ``radius`` (kept below 1 so the
        surface stays star-shaped and therefore closed and non-intersecting).
    frequency : float
        Highest angular frequency of the noise.
    wave_count : int
        Number of plane waves summed.
    sharpness : float
        0 for smooth lumps, 1 for ridged folds.
    seed : int
        Seed of the noise.

    Returns
    -------
    TriangleMesh
    """
    sphere = icosphere(subdivisions)
    noise = _plane_wave_noise(sphere.vertices, wave_count, frequency, seed, sharpness)
    noise = np.clip(noise, -1.0, 1.0)
    factor = radius * (1.0 + amplitude * noise)
    return TriangleMesh(sphere.vertices * factor[:, None], sphere.faces)


# ---------------------------------------------------------------------------
# Tubes around closed curves
# ---------------------------------------------------------------------------


def _torus_knot_curve(p, q, knot_radius, segments, height_scale=1.0):
    """Points and unit tangents of a ``(p, q)`` torus knot (``segments`` samples, periodic)."""
    angle = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
    ring = 2.0 + np.cos(q * angle)
    points = np.stack([ring * np.cos(p * angle), -height_scale * np.sin(q * angle), ring * np.sin(p * angle)], axis=1)
    # Analytic derivative.
    ring_derivative = -q * np.sin(q * angle)
    tangents = np.stack(
        [
            ring_derivative * np.cos(p * angle) - p * ring * np.sin(p * angle),
            -height_scale * q * np.cos(q * angle),
            ring_derivative * np.sin(p * angle) + p * ring * np.cos(p * angle),
        ],
        axis=1,
    )
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    return points * (knot_radius / 3.0), tangents


def _closed_curve_frames(tangents):
    """Rotation-minimising normals along a closed curve, with the holonomy spread out.

    The normal is carried from sample to sample by projection (parallel
    transport); the twist it has accumulated after a full loop is undone
    gradually, so the frames close up smoothly.
    """
    count = len(tangents)
    seed_axis = np.eye(3)[np.argmin(np.abs(tangents[0]))]
    normal = np.cross(tangents[0], seed_axis)
    normal /= np.linalg.norm(normal)
    normals = np.empty_like(tangents)
    for index in range(count):
        normal = normal - np.dot(normal, tangents[index]) * tangents[index]
        normal /= np.linalg.norm(normal)
        normals[index] = normal
    closing = normal - np.dot(normal, tangents[0]) * tangents[0]
    closing /= np.linalg.norm(closing)
    binormal0 = np.cross(tangents[0], normals[0])
    twist = math.atan2(np.dot(closing, binormal0), np.dot(closing, normals[0]))
    correction = -twist * np.arange(count) / count
    binormals = np.cross(tangents, normals)
    normals = np.cos(correction)[:, None] * normals + np.sin(correction)[:, None] * binormals
    binormals = np.cross(tangents, normals)
    return normals, binormals


def _tube(points, tangents, radii):
    """Closed tube: ``radii`` has shape ``(segments, sides)`` (radius per curve sample and angle)."""
    segments, sides = radii.shape
    normals, binormals = _closed_curve_frames(tangents)
    angle = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    offsets = np.cos(angle)[None, :, None] * normals[:, None, :] + np.sin(angle)[None, :, None] * binormals[:, None, :]
    grid = points[:, None, :] + radii[:, :, None] * offsets
    mesh = _grid_mesh(grid, wrap_rows=True, wrap_columns=True)
    # Grid quads run (along the tangent) x (around, from the normal towards the
    # binormal); (tangent x binormal) = -normal points inwards, so reverse them.
    return TriangleMesh(mesh.vertices, mesh.faces[:, ::-1])


def torus_knot(p=2, q=3, knot_radius=1.0, tube_radius=0.12, segments=512, sides=32):
    """A tube of constant radius around a ``(p, q)`` torus knot.

    Parameters
    ----------
    p, q : int
        Coprime winding numbers (``p`` times around the axis, ``q`` times
        through the hole).
    knot_radius : float
        Outer radius of the knot's centre line (before the tube).
    tube_radius : float
        Radius of the tube.
    segments, sides : int
        Samples along the curve and around the tube.

    Returns
    -------
    TriangleMesh
        ``2 * segments * sides`` triangles, closed.
    """
    points, tangents = _torus_knot_curve(p, q, knot_radius, segments)
    return _tube(points, tangents, np.full((segments, sides), float(tube_radius)))


def spiked_torus_knot(
    p=2,
    q=3,
    knot_radius=1.0,
    tube_radius=0.14,
    segments=960,
    sides=40,
    ridge_count=3,
    twists=5,
    spike_count=72,
    spike_height=0.10,
    bulge=0.3,
    height_scale=1.4,
):
    """A twisted, spiked torus knot: a serpentine "dragon-like" sculpture.

    The tube swells and narrows along the knot like a body, and ``ridge_count``
    ridges of spikes spiral around it (``twists`` full turns per loop), like
    the crest of a dragon.

    Parameters
    ----------
    p, q : int
        Winding numbers of the torus knot.
    knot_radius, tube_radius : float
        Size of the centre line and mean radius of the tube.
    segments, sides : int
        Samples along the knot and around the tube.
    ridge_count : int
        Number of spiralling ridges of spikes.
    twists : int
        Full turns of the ridges per loop (an integer, so the surface closes).
    spike_count : int
        Spikes along each ridge.
    spike_height : float
        Height of the spikes.
    bulge : float
        Relative swelling of the tube along the knot (``0`` for constant).
    height_scale : float
        Vertical stretch of the knot.

    Returns
    -------
    TriangleMesh
        ``2 * segments * sides`` triangles, closed.
    """
    points, tangents = _torus_knot_curve(p, q, knot_radius, segments, height_scale)
    along = np.arange(segments)[:, None] / segments  # in [0, 1)
    angle = 2.0 * math.pi * np.arange(sides)[None, :] / sides
    body = 1.0 + bulge * np.sin(2.0 * math.pi * (q + p) * along) * np.cos(2.0 * math.pi * 2 * along)
    ridge_phase = ridge_count * (angle - 2.0 * math.pi * twists * along)
    ridge = np.maximum(np.cos(ridge_phase), 0.0) ** 6
    spikes = np.maximum(np.cos(2.0 * math.pi * spike_count * along), 0.0) ** 3
    radii = tube_radius * body + spike_height * ridge * (0.35 + 0.65 * spikes)
    return _tube(points, tangents, radii)


# ---------------------------------------------------------------------------
# Surfaces of revolution
# ---------------------------------------------------------------------------


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def lathe(profile, segments=64, crease_angle=35.0, flutes=0, flute_depth=0.0, flute_range=None, flute_ramp=0.05):
    """A surface of revolution about the y axis, optionally fluted.

    Parameters
    ----------
    profile : array_like
        Points ``(radius, height)`` from bottom to top, shape ``(n, 2)``. A
        first or last point with radius 0 closes that end with a pole; a
        profile that starts and ends on the axis gives a closed solid. The
        profile must run counter-clockwise around the solid's cross-section
        (outer side going up, inner side going down) for the faces to point
        outwards.
    segments : int
        Samples around the axis (a multiple of ``flutes`` for even flutes).
    crease_angle : float
        Where the profile turns by more than this (degrees), the surface gets
        a hard edge (the ring of vertices is duplicated).
    flutes : int
        Number of vertical concave channels (0 for none).
    flute_depth : float
        Depth of the channels (absolute).
    flute_range : tuple of float, optional
        ``(bottom, top)`` heights between which the channels run; the whole
        profile if omitted.
    flute_ramp : float
        Height over which the channels fade in and out at their ends.

    Returns
    -------
    TriangleMesh
    """
    profile = np.asarray(profile, dtype=np.float64)
    if profile.ndim != 2 or profile.shape[1] != 2 or len(profile) < 2:
        raise ValueError("profile must be a sequence of at least two (radius, height) points")
    if np.any(profile[:, 0] < 0) or np.any(profile[1:-1, 0] <= 0):
        raise ValueError("profile radii must be positive except at the two ends")
    # Split the profile into smooth runs at creases.
    directions = np.diff(profile, axis=0)
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", directions[:-1], directions[1:]), -1.0, 1.0)))
    breaks = [0] + [index + 1 for index in np.nonzero(turn > crease_angle)[0]] + [len(profile) - 1]
    angle = 2.0 * math.pi * np.arange(segments) / segments
    cosine, sine = np.cos(angle), np.sin(angle)
    if flutes and flute_depth > 0:
        position = (flutes * angle / (2.0 * math.pi)) % 1.0
        channel = np.sqrt(np.maximum(0.0, 1.0 - (2.0 * position - 1.0) ** 2))
        bottom, top = flute_range if flute_range is not None else (profile[:, 1].min(), profile[:, 1].max())
    else:
        channel = None

    def ring_radii(radius, height):
        if channel is None:
            return np.full(segments, radius)
        mask = _smoothstep((height - bottom) / flute_ramp) * _smoothstep((top - height) / flute_ramp)
        return radius - flute_depth * mask * channel

    pieces = []
    for start, stop in zip(breaks[:-1], breaks[1:]):
        run = profile[start : stop + 1]
        has_bottom_pole, has_top_pole = run[0, 0] == 0.0, run[-1, 0] == 0.0
        body = run[int(has_bottom_pole) : len(run) - int(has_top_pole)]
        rings = np.stack(
            [np.stack([ring_radii(r, h) * cosine, np.full(segments, h), -ring_radii(r, h) * sine], axis=1) for r, h in body]
        )
        vertices = rings.reshape(-1, 3)
        faces = [_grid_faces(len(body), segments, wrap_columns=True)] if len(body) > 1 else []
        column = np.arange(segments)
        if has_bottom_pole:
            pole = len(vertices)
            vertices = np.concatenate([vertices, [[0.0, run[0, 1], 0.0]]])
            faces.append(np.stack([np.full(segments, pole), column, (column + 1) % segments], axis=1))
        if has_top_pole:
            pole = len(vertices)
            last = (len(body) - 1) * segments
            vertices = np.concatenate([vertices, [[0.0, run[-1, 1], 0.0]]])
            faces.append(np.stack([np.full(segments, pole), last + (column + 1) % segments, last + column], axis=1))
        pieces.append(TriangleMesh(vertices, np.concatenate(faces)))
    mesh = merge(pieces)
    # The grid quads run (up the profile) x (around the axis), which winds them
    # inwards for a counter-clockwise profile: reverse them in that case.
    if _profile_area(profile) > 0:
        mesh = TriangleMesh(mesh.vertices, mesh.faces[:, ::-1])
    return mesh


def _profile_area(profile):
    """Signed (shoelace) area of the profile closed along the axis; positive if counter-clockwise."""
    radius = np.concatenate([profile[:, 0], [0.0, 0.0]])
    height = np.concatenate([profile[:, 1], [profile[-1, 1], profile[0, 1]]])
    return 0.5 * float(np.sum(radius * np.roll(height, -1) - np.roll(radius, -1) * height))


def column(height=3.0, radius=0.2, flutes=20, segments=80, flute_depth=None, detail=6):
    """A classical column: square plinth-like base moulding, fluted tapering shaft, capital.

    Parameters
    ----------
    height : float
        Total height.
    radius : float
        Radius of the shaft at its foot.
    flutes : int
        Number of flutes on the shaft (0 for a smooth shaft).
    segments : int
        Samples around the axis.
    flute_depth : float, optional
        Depth of the flutes; ``0.06 * radius`` if omitted.
    detail : int
        Profile samples per moulding (more for rounder mouldings).

    Returns
    -------
    TriangleMesh
        A closed solid standing on ``y = 0``.
    """
    r, h = radius, height
    points = [(0.0, 0.0), (1.45 * r, 0.0), (1.45 * r, 0.06 * h)]

    def torus_moulding(centre_radius, centre_height, size, count, start_angle, stop_angle):
        angles = np.linspace(math.radians(start_angle), math.radians(stop_angle), count)
        return [(centre_radius + size * math.cos(a), centre_height + size * math.sin(a)) for a in angles]

    # Base: a torus (half round) and a fillet, then the shaft.
    points += torus_moulding(1.25 * r, 0.06 * h + 0.2 * r, 0.2 * r, 2 * detail, -90, 90)[1:]
    points += [(1.12 * r, 0.06 * h + 0.4 * r), (1.05 * r, 0.06 * h + 0.47 * r)]
    shaft_bottom, shaft_top = 0.06 * h + 0.5 * r, 0.86 * h
    shaft_heights = np.linspace(shaft_bottom, shaft_top, 4 * detail + 1)
    taper = 1.0 - 0.15 * ((shaft_heights - shaft_bottom) / (shaft_top - shaft_bottom)) ** 1.5
    points += [(r * t, y) for t, y in zip(taper, shaft_heights)]
    # Capital: necking ring, echinus (a quarter round flaring out), abacus slab.
    top_r = r * taper[-1]
    points += [(top_r + 0.06 * r, shaft_top + 0.03 * h), (top_r + 0.06 * r, shaft_top + 0.045 * h)]
    echinus = np.linspace(0.0, 1.0, 2 * detail)
    points += [
        (top_r + 0.06 * r + 0.55 * r * math.sin(0.5 * math.pi * t), shaft_top + 0.045 * h + 0.055 * h * t) for t in echinus[1:]
    ]
    points += [(1.5 * r, shaft_top + 0.1 * h), (1.5 * r, h), (0.0, h)]
    return lathe(
        points,
        segments=segments,
        flutes=flutes,
        flute_depth=0.06 * r if flute_depth is None else flute_depth,
        flute_range=(shaft_bottom + 0.04 * h, shaft_top - 0.02 * h),
        flute_ramp=0.03 * h,
    )


def vase(height=1.0, radius=0.35, wall=0.03, flutes=0, segments=96, detail=24, shape=0):
    """A hollow vase (or pot) with a lip: outer profile up, inner profile down.

    Parameters
    ----------
    height : float
        Height of the rim.
    radius : float
        Largest outer radius.
    wall : float
        Wall thickness.
    flutes : int
        Number of vertical flutes on the belly (0 for none).
    segments : int
        Samples around the axis.
    detail : int
        Samples along the outer profile.
    shape : int
        0: amphora-like (belly, narrow neck, flared lip); 1: flower pot
        (straight flaring sides with a rolled rim); 2: squat bowl.

    Returns
    -------
    TriangleMesh
        A closed solid standing on ``y = 0``, open (hollow) at the top.
    """
    t = np.linspace(0.0, 1.0, detail)
    if shape == 0:
        belly = 0.45 + 0.55 * np.sin(math.pi * np.minimum(t / 0.8, 1.0)) ** 0.8
        lip = 0.45 + 1.2 * np.maximum(t - 0.8, 0.0) ** 1.5
        outer = radius * np.where(t < 0.8, belly, lip)
        outer[0] = 0.55 * radius
    elif shape == 1:
        outer = radius * (0.7 + 0.3 * t)
    else:
        outer = radius * (0.55 + 0.45 * np.sin(0.5 * math.pi * np.minimum(t / 0.7, 1.0)))
    heights = height * t
    foot = 0.04 * height
    points = [(0.0, 0.0), (outer[0], 0.0)]
    points += [(r, max(y, foot)) for r, y in zip(outer, heights)][1:]
    lip = outer[-1]
    points += [(lip + 0.6 * wall, height), (lip + 0.6 * wall, height + 1.2 * wall), (lip - wall, height + 1.2 * wall)]
    inner = np.maximum(outer - wall, 0.2 * radius)
    floor = 0.08 * height
    points += [(r, y) for r, y in zip(inner[::-1], heights[::-1]) if y > floor + 1e-9 and y < height - 1e-9]
    points += [(inner[0], floor), (0.0, floor)]
    # The profile above runs up the outside and down the inside: counter-clockwise
    # in (r, h) about the wall, but ends on the axis at the inner floor; lathe
    # closes both poles, so the solid is a closed cup.
    belly = (0.1 * height, 0.75 * height) if shape == 0 else (0.1 * height, 0.95 * height)
    return lathe(
        points,
        segments=segments,
        flutes=flutes,
        flute_depth=0.25 * wall if flutes else 0.0,
        flute_range=belly,
        flute_ramp=0.08 * height,
    )


# ---------------------------------------------------------------------------
# Architecture
# ---------------------------------------------------------------------------


def arch(inner_radius=1.0, outer_radius=1.3, depth=0.4, segments=48, outer_height=None):
    """A semicircular arch extruded along z, standing on ``y = 0``.

    The opening is the half disc of ``inner_radius`` about the origin in the
    ``z = 0`` plane. With ``outer_height`` omitted the outside is the half
    circle of ``outer_radius`` (a half annulus); with it, the outside is the
    rectangle ``|x| <= outer_radius, 0 <= y <= outer_height`` (an arch cut
    into a block of wall, with flat spandrels).

    Parameters
    ----------
    inner_radius, outer_radius : float
        Radius of the opening; outer radius or half width.
    depth : float
        Extent along z (centred on ``z = 0``).
    segments : int
        Samples along the half circle.
    outer_height : float, optional
        Height of the rectangular outside (at least ``inner_radius``).

    Returns
    -------
    TriangleMesh
        Closed once welded; sharp edges between its faces.
    """
    if not 0 < inner_radius < outer_radius:
        raise ValueError("arch needs 0 < inner_radius < outer_radius")
    square = outer_height is not None
    if square and outer_height <= inner_radius:
        raise ValueError("outer_height must exceed inner_radius")
    angles = np.linspace(0.0, math.pi, segments + 1)
    corner_angles = []
    if square:
        corner = math.atan2(outer_height, outer_radius)
        corner_angles = [corner, math.pi - corner]
        angles = np.unique(np.concatenate([angles, corner_angles]))
    direction = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    direction[0], direction[-1] = (1.0, 0.0), (-1.0, 0.0)
    inner = inner_radius * direction
    if square:
        with np.errstate(divide="ignore"):
            reach = np.minimum(
                outer_radius / np.maximum(np.abs(direction[:, 0]), 1e-300),
                outer_height / np.maximum(np.abs(direction[:, 1]), 1e-300),
            )
        outer = reach[:, None] * direction
        for index in np.searchsorted(angles, corner_angles):
            outer[index] = (math.copysign(outer_radius, direction[index, 0]), outer_height)
    else:
        outer = outer_radius * direction
    half = 0.5 * depth

    def lift(points_2d, z):
        return np.column_stack([points_2d, np.full(len(points_2d), z)])

    pieces = []
    # Front and back faces: a strip of quads between the inner and outer curves.
    for z, sign in ((half, 1.0), (-half, -1.0)):
        strip = np.stack([lift(inner, z), lift(outer, z)], axis=1)
        pieces.append(_orient(_grid_mesh(strip), (0.0, 0.0, sign)))
    # Intrados (the underside of the arch), facing the centre of the opening.
    intrados = np.stack([lift(inner, half), lift(inner, -half)], axis=1)
    pieces.append(_orient(_grid_mesh(intrados), lambda c: -np.column_stack([c[:, :2], np.zeros(len(c))])))
    # Extrados (outside): one smooth run, or three flat sides split at the corners.
    runs = [(0, len(angles) - 1)]
    if square:
        first, second = np.searchsorted(angles, corner_angles)
        runs = [(0, first), (first, second), (second, len(angles) - 1)]
    for start, stop in runs:
        part = outer[start : stop + 1]
        extrados = np.stack([lift(part, half), lift(part, -half)], axis=1)
        pieces.append(_orient(_grid_mesh(extrados), lambda c: np.column_stack([c[:, :2], np.zeros(len(c))])))
    # Feet.
    for index in (0, len(angles) - 1):
        corners = [lift(inner[index : index + 1], half)[0], lift(outer[index : index + 1], half)[0],
                   lift(outer[index : index + 1], -half)[0], lift(inner[index : index + 1], -half)[0]]  # fmt: skip
        pieces.append(_polygon(corners, (0.0, -1.0, 0.0)))
    return merge(pieces)


def wall_with_openings(width, height, thickness, openings=()):
    """A wall with rectangular openings (doors, windows), built from boxes.

    The wall spans ``|x| <= width / 2``, ``0 <= y <= height``,
    ``|z| <= thickness / 2``. The solid part is cut into vertical strips at
    the openings' x edges, and each strip into boxes between the openings
    that cross it, so openings may be stacked (a window above a door).

    Parameters
    ----------
    width, height, thickness : float
        Size of the wall.
    openings : sequence of (x_min, x_max, y_min, y_max)
        Openings in wall coordinates; they must lie inside the wall and must
        not overlap each other. A door has ``y_min = 0``.

    Returns
    -------
    TriangleMesh
        A union of closed boxes (adjacent boxes touch; each is closed).

    Raises
    ------
    ValueError
        An opening outside the wall, or two overlapping openings.
    """
    half_width = 0.5 * width
    openings = sorted(tuple(float(v) for v in opening) for opening in openings)
    for x0, x1, y0, y1 in openings:
        if not (-half_width < x0 < x1 < half_width and 0 <= y0 < y1 < height):
            raise ValueError(f"opening {(x0, x1, y0, y1)} does not fit in the wall")
    for index, first in enumerate(openings):
        for second in openings[index + 1 :]:
            if first[0] < second[1] and second[0] < first[1] and first[2] < second[3] and second[2] < first[3]:
                raise ValueError(f"wall openings {first} and {second} overlap")
    edges = sorted({-half_width, half_width} | {x for opening in openings for x in opening[:2]})
    pieces = []
    for x0, x1 in zip(edges[:-1], edges[1:]):
        if x1 - x0 <= 1e-9:
            continue
        middle = 0.5 * (x0 + x1)
        gaps = sorted((y0, y1) for ox0, ox1, y0, y1 in openings if ox0 < middle < ox1)
        bottom = 0.0
        for y0, y1 in gaps + [(height, height)]:
            if y0 - bottom > 1e-9:
                pieces.append(box((x1 - x0, y0 - bottom, thickness), (middle, 0.5 * (bottom + y0), 0.0)))
            bottom = y1
    return merge(pieces)


# ---------------------------------------------------------------------------
# PLY output and cache
# ---------------------------------------------------------------------------


def ply_bytes(mesh, normals=True):
    """The mesh as a binary little-endian PLY file (float32 positions, optional normals).

    Parameters
    ----------
    mesh : TriangleMesh
    normals : bool
        Also write per-vertex normals (:meth:`TriangleMesh.vertex_normals`).

    Returns
    -------
    bytes
    """
    properties = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals else [])
    header = ["ply", "format binary_little_endian 1.0", "comment generated by sparselt.rendering.meshes",
              f"element vertex {mesh.vertex_count}"]  # fmt: skip
    header += [f"property float {name}" for name in properties]
    header += [f"element face {mesh.triangle_count}", "property list uchar int vertex_indices", "end_header"]
    columns = [mesh.vertices] + ([mesh.vertex_normals()] if normals else [])
    vertex_data = np.ascontiguousarray(np.concatenate(columns, axis=1), dtype="<f4")
    if mesh.faces.size and (mesh.faces.min() < 0 or mesh.faces.max() >= mesh.vertex_count):
        raise ValueError("face indices out of range")
    face_data = np.empty(mesh.triangle_count, dtype=[("count", "u1"), ("indices", "<i4", (3,))])
    face_data["count"] = 3
    face_data["indices"] = mesh.faces
    return ("\n".join(header) + "\n").encode("ascii") + vertex_data.tobytes() + face_data.tobytes()


def write_ply(path, mesh, normals=True):
    """Write ``mesh`` to ``path`` as binary PLY, atomically (temporary file, then :func:`os.replace`).

    Parameters
    ----------
    path : str or os.PathLike
    mesh : TriangleMesh
    normals : bool
        Also write per-vertex normals.
    """
    path = os.fspath(path)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    atomic_write_bytes(path, ply_bytes(mesh, normals))


def cache_directory():
    """Directory of cached meshes: ``$SPARSELT_CACHE/meshes`` (default ``~/.cache/sparselt/meshes``;
    :mod:`sparselt.storage.cache`)."""
    from ..storage.cache import cache_directory as cache_subfolder

    return cache_subfolder("meshes")


def _canonical(value):
    """Parameters in a JSON-stable form (tuples and arrays become lists, numpy scalars Python numbers)."""
    if isinstance(value, dict):
        return {str(key): _canonical(item) for key, item in sorted(value.items())}
    if isinstance(value, (list, tuple)):
        return [_canonical(item) for item in value]
    if isinstance(value, np.ndarray):
        return _canonical(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"mesh parameter {value!r} is not a number, string, list or dict")


def parameter_hash(name, parameters):
    """The digest (:func:`sparselt.digest.digest`) of a mesh name, its parameters and :data:`MESH_FORMAT_VERSION`."""
    return digest({"name": name, "parameters": _canonical(parameters), "version": MESH_FORMAT_VERSION})


def mesh_file(name, builder, normals=True, **parameters):
    """Path of the cached PLY file of ``builder(**parameters)``, written if missing.

    Parameters
    ----------
    name : str
        File name stem (letters, digits, ``-`` and ``_``); also part of the key.
    builder : callable
        Returns a :class:`TriangleMesh` from ``parameters``; must be
        deterministic. Its qualified name is part of the key.
    normals : bool
        Write per-vertex normals.
    **parameters
        Keyword arguments of ``builder`` (numbers, strings, lists, dicts).

    Returns
    -------
    str
        Absolute path of the PLY file.
    """
    if not name or not all(character.isalnum() or character in "-_" for character in name):
        raise ValueError(f"mesh name {name!r} must consist of letters, digits, '-' and '_'")
    key = dict(parameters, _builder=f"{builder.__module__}.{builder.__qualname__}", _normals=bool(normals))
    path = os.path.join(cache_directory(), f"{name}-{parameter_hash(name, key)}.ply")
    if not os.path.isfile(path):
        from ..storage.cache import cache_errors

        mesh = builder(**parameters)
        with cache_errors(os.path.dirname(path), "write"):
            write_ply(path, mesh, normals)
    return os.path.abspath(path)
