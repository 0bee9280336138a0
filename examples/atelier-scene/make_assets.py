"""Make planks.png (wooden floor planks with grain), tiles.png (a tiled wall) and vase.obj (a surface of revolution
with vertex normals and texture coordinates) beside scene.xml.

Run from this folder: ../../.venv/bin/python make_assets.py (the files are committed; this says how they were made).
"""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
rng = np.random.default_rng(11)
# planks: 512x512, eight planks across, each its own tint, fine grain along the plank, dark seams
y, x = np.mgrid[0:512, 0:512]
plank = x // 64
tint = rng.uniform(0.75, 1.15, 8)[plank]
grain = 0.5 + 0.5 * np.sin(y / 3.0 + 7.0 * np.sin(x / 23.0 + plank) + rng.random((512, 512)) * 0.8)
wood = np.stack([0.55, 0.36, 0.2]) * (tint * (0.8 + 0.25 * grain))[..., None]
wood[(x % 64) < 2] = [0.08, 0.05, 0.03]
mi.Bitmap((np.clip(wood, 0, 1) * 255).astype(np.uint8)).write("planks.png")
# tiles: 256x256, 8x8 glazed tiles in two colours with grout lines
y, x = np.mgrid[0:256, 0:256]
odd = ((x // 32) + (y // 32)) % 2 == 1
tiles = np.where(odd[..., None], [0.85, 0.82, 0.72], [0.2, 0.38, 0.55]) * (0.92 + 0.08 * rng.random((256, 256, 1)))
tiles[((x % 32) < 2) | ((y % 32) < 2)] = [0.5, 0.5, 0.48]
mi.Bitmap((np.clip(tiles, 0, 1) * 255).astype(np.uint8)).write("tiles.png")
# vase: a profile r(h) turned about the y axis, 64 segments x 40 rings, smooth normals
segments, rings = 64, 40
heights = np.linspace(0.0, 1.0, rings)
radius = 0.18 + 0.14 * np.sin(np.pi * heights * 1.2) - 0.08 * heights ** 3
slope = np.gradient(radius, heights)
lines = []
for ring, (h, r, dr) in enumerate(zip(heights, radius, slope)):
    for segment in range(segments):
        angle = 2 * np.pi * segment / segments
        c, s = np.cos(angle), np.sin(angle)
        normal = np.array([c, -dr, s]) / np.sqrt(1 + dr * dr)
        lines.append(f"v {r * c:.5f} {h:.5f} {r * s:.5f}")
        lines.append(f"vn {normal[0]:.5f} {normal[1]:.5f} {normal[2]:.5f}")
        lines.append(f"vt {segment / segments:.5f} {h:.5f}")
for ring in range(rings - 1):
    for segment in range(segments):
        a = ring * segments + segment + 1
        b = ring * segments + (segment + 1) % segments + 1
        c, d = a + segments, b + segments
        lines.append(f"f {a}/{a}/{a} {c}/{c}/{c} {d}/{d}/{d} {b}/{b}/{b}")
open("vase.obj", "w").write("\n".join(lines) + "\n")
