"""Make bricks.png (a noisy brick texture) and ring.obj (a torus of quads without normals) beside scene.xml.

Run from this folder: ../../.venv/bin/python make_assets.py (the files are committed; this says how they were made).
"""
import numpy as np, mitsuba as mi
mi.set_variant("scalar_rgb")
rng = np.random.default_rng(7)
# a noisy-brick texture, 256x256, sRGB PNG
y, x = np.mgrid[0:256, 0:256]
brick = ((y // 32) % 2 == 0) ^ (((x + (y // 32 % 2) * 32) // 64) % 2 == 0)
base = np.where(brick[..., None], [0.62, 0.28, 0.18], [0.8, 0.78, 0.7]) * (0.85 + 0.3 * rng.random((256, 256, 1)))
mortar = (y % 32 < 2) | ((x + (y // 32 % 2) * 32) % 64 < 2)
base[mortar] = [0.25, 0.25, 0.25]
mi.Bitmap((np.clip(base, 0, 1) * 255).astype(np.uint8)).write("bricks.png")
# a small OBJ: a torus-ish ring of quads, no normals, written by hand
lines = []
R, r, n, m = 0.5, 0.15, 48, 16
for i in range(n):
    for j in range(m):
        u, v = 2 * np.pi * i / n, 2 * np.pi * j / m
        lines.append(f"v {(R + r*np.cos(v))*np.cos(u):.5f} {r*np.sin(v):.5f} {(R + r*np.cos(v))*np.sin(u):.5f}")
for i in range(n):
    for j in range(m):
        a = i * m + j + 1; b = ((i + 1) % n) * m + j + 1; c = ((i + 1) % n) * m + (j + 1) % m + 1; d = i * m + (j + 1) % m + 1
        lines.append(f"f {a} {b} {c} {d}")
open("ring.obj", "w").write("\n".join(lines) + "\n")
