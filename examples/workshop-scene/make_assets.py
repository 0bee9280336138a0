"""Make slide.png (the projector's slide: a test card of coloured bars and a grid), panel.exr (the ceiling panel's
radiance: a warm tube behind a ribbed diffuser), planks.png (the bench's wood), patina.png (the kettle's tarnish,
the conductor's specular reflectance), bristles.txt (a brush's bristles: control points and radii of B-spline
curves) and stool.obj (a low-poly stool with flat faces) beside scene.xml.

Run from this folder: ../../.venv/bin/python make_assets.py (the files are committed; this says how they were made).
"""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
rng = np.random.default_rng(53)
# slide: 96x64, seven colour bars over the top two thirds, a white grid over a dark grey below
v, u = (np.mgrid[0:64, 0:96] + 0.5) / np.array([64, 96])[:, None, None]
bars = np.array([[1, 1, 1], [1, 1, 0], [0, 1, 1], [0, 1, 0], [1, 0, 1], [1, 0, 0], [0, 0, 1]], dtype=float)
slide = np.where((v < 0.66)[..., None], bars[np.minimum((u * 7).astype(int), 6)] * 0.85, 0.12)
grid = (v >= 0.66) & ((np.abs((u * 12) % 1 - 0.5) > 0.42) | (np.abs((v * 12) % 1 - 0.5) > 0.42))
slide[grid] = 0.9
mi.Bitmap((slide * 255).astype(np.uint8)).write("slide.png")
# panel: 32x128 HDR radiance, ribbed: bright ribs along u, a warm tint, dimmer towards the ends
v, u = (np.mgrid[0:32, 0:128] + 0.5) / np.array([32, 128])[:, None, None]
ribs = 0.55 + 0.45 * np.cos(2 * np.pi * 10 * v) ** 2
ends = np.sin(np.pi * u) ** 0.3
panel = (ribs * ends)[..., None] * np.array([30.0, 26.0, 20.0])
mi.Bitmap(panel.astype(np.float32)).write("panel.exr")
# planks: 128x128, five boards with grain streaks and a dark joint between boards
v, u = (np.mgrid[0:128, 0:128] + 0.5) / 128
board = (v * 5).astype(int)
grain = 0.5 + 0.5 * np.sin(60 * u + 7 * np.sin(13 * v + board) + board * 2.1)
wood = np.array([0.45, 0.28, 0.14]) * (0.75 + 0.35 * grain[..., None])
wood[np.abs((v * 5) % 1 - 0.5) > 0.47] *= 0.3
mi.Bitmap((np.clip(wood, 0, 1) * 255).astype(np.uint8)).write("planks.png")
# patina: 64x64, copper-coloured metal with greenish tarnished blotches (smoothed noise)
noise = rng.random((64, 64))
for _ in range(5):
    noise = (noise + np.roll(noise, 1, 0) + np.roll(noise, -1, 0) + np.roll(noise, 1, 1) + np.roll(noise, -1, 1)) / 5
noise = (noise - noise.min()) / (noise.max() - noise.min())
tarnish = np.clip((noise - 0.5) * 3, 0, 1)[..., None]
patina = (1 - tarnish) * np.array([0.95, 0.64, 0.54]) + tarnish * np.array([0.3, 0.45, 0.35])
mi.Bitmap((patina * 255).astype(np.uint8)).write("patina.png")
# bristles: 40 curves of 6 control points each, from the brush's ferrule (y = 0.25) fanning down to the bench
with open("bristles.txt", "w") as file:
    for index in range(40):
        angle, spread = rng.uniform(0, 2 * np.pi), rng.uniform(0.0, 0.05)
        for step in range(6):
            t = step / 5
            x = 0.015 * np.cos(angle) + spread * t * t * np.cos(angle)
            z = 0.015 * np.sin(angle) + spread * t * t * np.sin(angle)
            file.write(f"{x:.4f} {0.25 - 0.22 * t:.4f} {z:.4f} {0.004 * (1 - 0.6 * t):.4f}\n")
        file.write("\n")
# stool: an octagonal seat on four square legs, flat faces (face normals in the scene)
vertices, faces = [], []


def add_box(low, high):
    base = len(vertices)
    for corner in range(8):
        vertices.append([high[i] if corner >> i & 1 else low[i] for i in range(3)])
    for a, b, c, d in ((0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)):
        faces.extend([(base + a, base + b, base + c), (base + a, base + c, base + d)])


ring = [(0.18 * np.cos(k * np.pi / 4 + np.pi / 8), 0.18 * np.sin(k * np.pi / 4 + np.pi / 8)) for k in range(8)]
base = len(vertices)
for height in (0.42, 0.46):
    vertices.extend([[x, height, z] for x, z in ring])
vertices.extend([[0, 0.42, 0], [0, 0.46, 0]])
for k in range(8):
    j = (k + 1) % 8
    faces.append((base + 16, base + j, base + k))            # underside
    faces.append((base + 17, base + 8 + k, base + 8 + j))    # top
    faces.extend([(base + k, base + j, base + 8 + j), (base + k, base + 8 + j, base + 8 + k)])
for x, z in ((-0.1, -0.1), (0.1, -0.1), (-0.1, 0.1), (0.1, 0.1)):
    add_box((x - 0.02, 0.0, z - 0.02), (x + 0.02, 0.42, z + 0.02))
with open("stool.obj", "w") as file:
    file.writelines(f"v {x:.4f} {y:.4f} {z:.4f}\n" for x, y, z in vertices)
    file.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces)
