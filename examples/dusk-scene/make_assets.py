"""Make sky.exr (a dusk sky for the `envmap` emitter: a horizon glow and a small sun low in the west, about 4000
times the zenith's radiance), bumps.png (a height map of hammered dents for a `bumpmap`), screen.png (what the
emissive screen shows) and torus.ply (a binary PLY torus with vertex normals) beside scene.xml.

Run from this folder: ../../.venv/bin/python make_assets.py (the files are committed; this says how they were made).
"""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
rng = np.random.default_rng(23)
# sky: 256x128 latitude-longitude, float32 RGB. Rows are elevation (top: zenith), columns azimuth.
height, width = 128, 256
theta = (np.arange(height) + 0.5) / height * np.pi          # 0 at the zenith
phi = (np.arange(width) + 0.5) / width * 2 * np.pi
elevation = np.pi / 2 - theta[:, None]
horizon = np.exp(-np.abs(elevation) / 0.18)
sky = (np.array([0.05, 0.07, 0.16]) * (1 - horizon[..., None])
       + np.array([0.9, 0.45, 0.2]) * horizon[..., None] * (0.6 + 0.4 * np.cos(phi - 0.9))[None, :, None])
sky[elevation[:, 0] < 0] = np.array([0.04, 0.035, 0.03])  # the ground below the horizon
sun_theta, sun_phi = np.pi / 2 - 0.12, 0.9
distance = np.arccos(np.clip(np.sin(theta[:, None]) * np.sin(sun_theta) * np.cos(phi[None, :] - sun_phi)
                             + np.cos(theta[:, None]) * np.cos(sun_theta), -1, 1))
sky[distance < 0.035] = np.array([400.0, 260.0, 150.0])
mi.Bitmap(sky.astype(np.float32)).write("sky.exr")
# bumps: 256x256 grey height map, overlapping round dents
y, x = np.mgrid[0:256, 0:256]
bumps = np.zeros((256, 256))
for cx, cy, r in zip(rng.uniform(0, 256, 90), rng.uniform(0, 256, 90), rng.uniform(6, 20, 90)):
    d2 = ((x - cx + 128) % 256 - 128) ** 2 + ((y - cy + 128) % 256 - 128) ** 2
    bumps -= np.exp(-d2 / (r * r))
bumps = (bumps - bumps.min()) / (bumps.max() - bumps.min())
mi.Bitmap((bumps * 255).astype(np.uint8)).write("bumps.png")
# screen: 128x80, coloured bars and a bright window, the emitted radiance's texture
y, x = np.mgrid[0:80, 0:128]
bars = np.array([[0.9, 0.9, 0.9], [0.9, 0.8, 0.1], [0.1, 0.8, 0.8], [0.1, 0.8, 0.1],
                 [0.8, 0.1, 0.8], [0.8, 0.1, 0.1], [0.1, 0.1, 0.8]])
screen = bars[(x * 7) // 128]
screen[(y > 52)] *= 0.15
screen[(x > 84) & (x < 116) & (y > 58) & (y < 74)] = [1.0, 1.0, 1.0]
mi.Bitmap((screen * 255).astype(np.uint8)).write("screen.png")
# torus: major radius 1, minor 0.35, 96 x 32 quads split into triangles, binary little-endian PLY with normals
major, minor, around, tube = 1.0, 0.35, 96, 32
u = np.arange(around) / around * 2 * np.pi
v = np.arange(tube) / tube * 2 * np.pi
U, V = np.meshgrid(u, v, indexing="ij")
centre = np.stack([np.cos(U), np.zeros_like(U), np.sin(U)], -1)
normal = np.stack([np.cos(U) * np.cos(V), np.sin(V), np.sin(U) * np.cos(V)], -1)
position = major * centre + minor * normal
i, j = np.meshgrid(np.arange(around), np.arange(tube), indexing="ij")
a = i * tube + j
b = ((i + 1) % around) * tube + j
c = ((i + 1) % around) * tube + (j + 1) % tube
d = i * tube + (j + 1) % tube
faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
vertices = np.concatenate([position.reshape(-1, 3), normal.reshape(-1, 3)], axis=1).astype("<f4")
header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\n"
          "property float x\nproperty float y\nproperty float z\n"
          "property float nx\nproperty float ny\nproperty float nz\n"
          f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
records = np.zeros(len(faces), dtype=[("count", "u1"), ("indices", "<i4", 3)])
records["count"], records["indices"] = 3, faces
with open("torus.ply", "wb") as handle:
    handle.write(header.encode("ascii"))
    handle.write(vertices.tobytes())
    handle.write(records.tobytes())
