"""shaders/ambient_cube.glsl against native/src/pb_ambient_cube.c (the issue's "the CPU evaluator and
the GLSL one mirror each other and are tested against each other").

A compute shader that includes ambient_cube.glsl runs on lavapipe (tests/tools/vk_compute.c, built
here with cc; Khronos validation layer on, any message fails) over random probes at bands 0..4 and
normals that include the axes, signed zeros and the octant boundaries. Both GLSL functions are
compared with the C ones through the Python module: ambient_cube_from_sh (GLSL fit vs C fit) and
ambient_cube_irradiance (GLSL evaluation of the C cube vs C evaluation). The GPU computes in
float32, the C in float64: tolerance 2e-6 relative to the largest value of each probe (float32
rounding of a few terms of magnitude <= that value).
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent.parent))
from conftest import requires_native  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
pytestmark = requires_native

SHADER = """#version 450
#include "ambient_cube.glsl"
layout(local_size_x = 64) in;
layout(std430, set = 0, binding = 0) readonly buffer In { float data[]; } inp;
layout(std430, set = 0, binding = 1) writeonly buffer Out { float data[]; } outp;
// in:  [max_band, P, N], P x 25 RGB radiance coefficients, P x 6 RGB cubes (from C), N normals
// out: P x N x RGB  E of the C cube (GLSL evaluator), then P x 6 RGB cubes (GLSL fit)
void main() {
    uint band = uint(inp.data[0]), P = uint(inp.data[1]), N = uint(inp.data[2]);
    uint g = gl_GlobalInvocationID.x;
    if (g >= P * N) return;
    uint p = g / N, k = g % N;
    uint cb = 3u + P * 75u + p * 18u, nb = 3u + P * 75u + P * 18u + k * 3u;
    vec3 cube[6];
    for (int f = 0; f < 6; ++f)
        cube[f] = vec3(inp.data[cb + 3u * uint(f)], inp.data[cb + 3u * uint(f) + 1u], inp.data[cb + 3u * uint(f) + 2u]);
    vec3 e = ambient_cube_irradiance(cube, vec3(inp.data[nb], inp.data[nb + 1u], inp.data[nb + 2u]));
    outp.data[3u * g] = e.x;
    outp.data[3u * g + 1u] = e.y;
    outp.data[3u * g + 2u] = e.z;
    if (k != 0u) return;
    vec3 c[25];
    for (uint i = 0u; i < 25u; ++i) {
        uint o = 3u + p * 75u + 3u * i;
        c[i] = vec3(inp.data[o], inp.data[o + 1u], inp.data[o + 2u]);
    }
    vec3 fit[6];
    ambient_cube_from_sh(band, c, fit);
    for (int f = 0; f < 6; ++f) {
        uint o = P * N * 3u + p * 18u + 3u * uint(f);
        outp.data[o] = fit[f].x;
        outp.data[o + 1u] = fit[f].y;
        outp.data[o + 2u] = fit[f].z;
    }
}
"""


@pytest.fixture(scope="module")
def runner(tmp_path_factory):
    if not shutil.which("glslc") or not shutil.which("cc"):
        pytest.skip("glslc or cc missing (scripts/deps.sh installs them)")
    d = tmp_path_factory.mktemp("cube_glsl")
    exe = d / "vk_compute"
    subprocess.run(["cc", "-O1", "-o", str(exe), str(REPO / "tests/tools/vk_compute.c"), "-ldl"], check=True)
    (d / "t.comp").write_text(SHADER)
    subprocess.run(["glslc", "-I", str(REPO / "shaders"), str(d / "t.comp"), "-o", str(d / "t.spv")], check=True)

    def run(inp, out_floats, groups):
        (d / "in.bin").write_bytes(np.asarray(inp, dtype=np.float32).tobytes())
        r = subprocess.run([str(exe), str(d / "t.spv"), str(d / "in.bin"), str(d / "out.bin"),
                            str(out_floats * 4), str(groups)], capture_output=True, text=True,
                           env=dict(os.environ, SCHNEE_VK_VALIDATION="1"))
        if r.returncode == 2:
            pytest.skip("no Vulkan device: " + r.stderr.strip())
        assert r.returncode == 0, r.stderr
        return np.fromfile(d / "out.bin", dtype=np.float32).astype(np.float64)
    return run


def normals():
    rng = np.random.default_rng(5)
    n = rng.normal(size=(200, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
                     [-0.0, -0.0, 1.0], [0.6, -0.0, -0.8], [-0.6, 0.8, 0.0], [1, 1, 1]], dtype=np.float64)
    axes[-1] /= np.sqrt(3.0)
    return np.concatenate([axes, n])


@pytest.mark.parametrize("band", [0, 1, 2, 3, 4])
def test_glsl_matches_c(runner, band):
    from schnee_probes import _schnee_native as raw
    rng = np.random.default_rng(100 + band)
    P, nrm = 7, normals()
    N = len(nrm)
    count = (band + 1) ** 2
    coeffs = np.zeros((P, 25, 3))
    coeffs[:, :count] = rng.uniform(-1, 1, size=(P, count, 3))
    coeffs[:, 0] += 3.0
    coeffs[1] *= 40.0  # a bright probe: tolerance scales with the probe
    # The C side sees the coefficients the GPU sees (float32-rounded).
    coeffs = coeffs.astype(np.float32).astype(np.float64)
    c_cubes = np.frombuffer(raw.ambient_cube_from_sh(np.ascontiguousarray(coeffs[:, :count]), band, 0),
                            dtype=np.float64).reshape(P, 6, 3)
    c_cubes32 = c_cubes.astype(np.float32).astype(np.float64)
    inp = np.concatenate([[band, P, N], coeffs.ravel(), c_cubes32.ravel(), nrm.ravel()])
    out = runner(inp, P * N * 3 + P * 18, (P * N + 63) // 64)
    gpu_e = out[:P * N * 3].reshape(P, N, 3)
    gpu_cubes = out[P * N * 3:].reshape(P, 6, 3)
    for p in range(P):
        scale = np.abs(c_cubes[p]).max()
        np.testing.assert_allclose(gpu_cubes[p], c_cubes[p], rtol=0, atol=2e-6 * scale)
        c_e = np.frombuffer(raw.ambient_cube_irradiance(np.ascontiguousarray(c_cubes32[p]),
                                                        np.ascontiguousarray(nrm.astype(np.float32)
                                                                             .astype(np.float64))),
                            dtype=np.float64).reshape(N, 3)
        np.testing.assert_allclose(gpu_e[p], c_e, rtol=0, atol=2e-6 * scale)
    # The GPU really evaluated (not a zero buffer that matches zero input).
    assert np.abs(gpu_e).max() > 1.0
