"""Generates the benchmark room: a 10 x 4 x 10 m box (floor, ceiling, four walls) with a grid of
pillars and spheres, one point light, a camera, and a 20 x 8 x 20 probe grid (0.5 m cells, one
probe per cell, smoothly varying SH). Usage: /usr/bin/python3 make_room.py OUT_DIR"""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import scenegen as sg  # noqa: E402


def box(center, half):
    p, n, uv, i = sg.cube(1.0)
    return (p * np.asarray(half, np.float32) / 1.0 + np.asarray(center, np.float32), n, uv, i)


def main(out):
    out = Path(out)
    (out / "sh_coeffs").mkdir(parents=True, exist_ok=True)
    dims = (20, 8, 20)
    X, Y, Z = dims
    count = X * Y * Z
    grid = np.arange(count, dtype=np.int32).reshape(Z, Y, X)
    zz, yy, xx = np.meshgrid(np.arange(Z), np.arange(Y), np.arange(X), indexing="ij")
    c = np.zeros((count, 9, 3))
    c[:, 0] = (np.stack([0.6 + 0.3 * xx / X, 0.5 + 0.2 * yy / Y, 0.4 + 0.4 * zz / Z], -1).reshape(-1, 3) * 3.5449)
    c[:, 1] = 0.3  # brighter from above
    c[:, 3, 0] = 0.2 * (xx.reshape(-1) / X - 0.5)
    sg.write_shprobe_v1(out / "sh_coeffs" / "room.shprobe", c, grid, (-5, 0, -5), 0.5)
    b = sg.GltfBuilder()
    wall = b.material("wall", base_color=(0.8, 0.8, 0.75, 1), sh_scale=1.0, ambient_term=0.05)
    obj = b.material("object", base_color=(0.7, 0.3, 0.2, 1), sh_scale=1.0, ambient_term=0.1)
    for name, center, half in [("Floor", (0, -0.05, 0), (5, 0.05, 5)), ("Ceiling", (0, 4.05, 0), (5, 0.05, 5)),
                               ("WallN", (0, 2, -5.05), (5, 2, 0.05)), ("WallS", (0, 2, 5.05), (5, 2, 0.05)),
                               ("WallW", (-5.05, 2, 0), (0.05, 2, 5)), ("WallE", (5.05, 2, 0), (0.05, 2, 5))]:
        b.node(name, mesh=b.mesh(name, box(center, half), wall))
    pillar = b.mesh("pillar", box((0, 1, 0), (0.2, 1, 0.2)), obj)
    sphere = b.mesh("sphere", sg.uv_sphere(0.3, 48, 24), obj)
    for i in range(5):
        for k in range(5):
            x, z = -4 + 2 * i, -4 + 2 * k
            b.node(f"Pillar{i}{k}", mesh=pillar, translation=(x, 0, z))
            b.node(f"Sphere{i}{k}", mesh=sphere, translation=(x + 1, 0.3 + 0.1 * i, z + 1))
    b.light("Lamp", "point", intensity=20.0)
    b.node("Lamp", translation=(0, 3.5, 0), extensions={"KHR_lights_punctual": {"light": 0}})
    b.node("Camera", camera=b.camera("cam", 1.0, 0.05, 50.0), translation=(1.0, 1.7, 4.8),
           rotation=(-0.0871557, 0, 0, 0.9961947))  # 10° down
    b.probe_grids([sg.grid_entry("room", "sh_coeffs/room.shprobe", count, (-5, 0, -5), dims, 0.5)])
    return b.write(out / "room.gltf")


if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else "room"))
