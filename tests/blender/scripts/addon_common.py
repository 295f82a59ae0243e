"""Shared by the addon_*.py Blender scripts: import paths, scene library, result reporting."""
import json
import os
import sys

REPO = os.environ.get("SCHNEE_REPO") or os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
for p in (os.path.join(REPO, "scenes"), os.path.join(REPO, "addon")):
    if p not in sys.path:
        sys.path.insert(0, p)

import scene_lib  # noqa: E402,F401


def args():
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []


def emit(**values):
    """One machine-readable line for the pytest side."""
    print("RESULT " + json.dumps(values), flush=True)


def tiny_bake_settings(scene):
    """The hazard scripts' smallest bake: one 2 m cell, 16 px panoramas, 1 sample. Returns the
    scene's add-on properties."""
    props = scene.schnee_probes
    props.min_cell_size = props.max_cell_size = 2.0
    props.panorama_resolution = 16
    props.samples = 1
    return props


def parse_results(stdout):
    return [json.loads(line[7:]) for line in stdout.splitlines() if line.startswith("RESULT ")]


def fibonacci_sphere(n):
    import numpy as np
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = np.pi * (1 + 5 ** 0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)


def irradiance_rel_rms(native, coeffs, ref, n=2000):
    """Relative RMS difference of the irradiance of two coefficient sets over ``n`` normals."""
    import numpy as np
    d = fibonacci_sphere(n)
    e = native.irradiance(np.asarray(coeffs, dtype=np.float64), d)
    e_ref = native.irradiance(np.asarray(ref, dtype=np.float64), d)
    return float(np.sqrt(np.mean((e - e_ref) ** 2)) / np.sqrt(np.mean(e_ref ** 2)))
