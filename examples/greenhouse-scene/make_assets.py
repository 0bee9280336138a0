"""Make leaf.png (a leaf's colour with its veins), leaf_alpha.png (its outline: the `mask` BSDF's opacity),
tiles_normal.png (a tangent-space normal map of bevelled floor tiles for `normalmap`) and wear.png (where the
table's varnish is worn through to the metal: a `blendbsdf` weight) beside scene.xml.

Run from this folder: ../../.venv/bin/python make_assets.py (the files are committed; this says how they were made).
"""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
rng = np.random.default_rng(41)
# leaf: 128x128, an ellipse pointed at both ends along v, a midrib and side veins; outside it the opacity is 0.
size = 128
v, u = (np.mgrid[0:size, 0:size] + 0.5) / size
half_width = 0.42 * np.sin(np.pi * np.clip(v, 0, 1)) ** 0.8
inside = np.abs(u - 0.5) < half_width
veins = (np.abs(u - 0.5) < 0.012) | (np.abs(((v - 0.9 * np.abs(u - 0.5)) * 9) % 1 - 0.5) < 0.05)
colour = np.where(veins[..., None], [0.55, 0.7, 0.25], [0.12, 0.38, 0.08])
colour = colour * (0.85 + 0.3 * rng.random((size, size, 1)))
mi.Bitmap((np.clip(colour, 0, 1) * 255).astype(np.uint8)).write("leaf.png")
mi.Bitmap((inside * 255).astype(np.uint8)).write("leaf_alpha.png")
# tiles: 256x256 normal map, 4x4 tiles with bevelled edges (x, y, z in [-1, 1] stored as [0, 255])
y, x = (np.mgrid[0:256, 0:256] + 0.5) / 64.0
fx, fy = x % 1.0, y % 1.0
bevel = 0.12
slope_x = np.where(fx < bevel, -1.0, np.where(fx > 1 - bevel, 1.0, 0.0)) * 0.6
slope_y = np.where(fy < bevel, -1.0, np.where(fy > 1 - bevel, 1.0, 0.0)) * 0.6
normal = np.stack([-slope_x, -slope_y, np.ones_like(x)], -1)
normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
mi.Bitmap(((normal * 0.5 + 0.5) * 255).astype(np.uint8)).write("tiles_normal.png")
# wear: 128x128 grey weights, worn patches (1: bare metal) from smoothed noise
noise = rng.random((128, 128))
for _ in range(6):
    noise = (noise + np.roll(noise, 1, 0) + np.roll(noise, -1, 0) + np.roll(noise, 1, 1) + np.roll(noise, -1, 1)) / 5
noise = (noise - noise.min()) / (noise.max() - noise.min())
mi.Bitmap((np.clip((noise - 0.55) * 4, 0, 1) * 255).astype(np.uint8)).write("wear.png")
