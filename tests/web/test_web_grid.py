"""Dense grids (v1/v2 .shprobe) per pixel in the three.js page against the C core's field (docs/grid-field.md).

The plugin's GLSL (schneeDenseSample: the 0.01 margin, clamped corners, the home cell's 27-bit neighbour
mask, back faces on static surfaces, validity in N and D, one filtered tap where the kept weights are
separable and D >= 1/64, else 8 texelFetch taps, step 5's plain trilinear x validity sample) is run in
headless chromium (SwiftShader, one browser launch for the module) at random surface points of random
dense grids (15 % empty cells, 20 % invalid probes, scales, identity and rotated axes, two tilted walls
as triangles in half of them; static and movable points) and compared with native.GridField.query
(pb_grid_field_query, float64) built with the masks the page traced at load (sv_probe_visibility_masks'
rule; checked here against a numpy segment test of the same triangles)."""
import json
import shutil
import subprocess

import numpy as np
import pytest

from test_web_page import WEB, _SHADER_JS, _chromium, run_node_cases, _lambert_basis_l2, _wall, server  # noqa: F401

_JS = _SHADER_JS.replace("return [...out, probes.visRecords || 0];",
                         "return [...out, probes.visRecords || 0, ...(probes.grids[0].masks || [])];").replace(
    "records.push(px[4 * c.n]);", "records.push(px.slice(4 * c.n + 1));")


def _rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def _np_masks(cells, origin, h, R, tris):
    """sv_probe_visibility_masks in numpy: both cells' bits cleared where the segment between their
    float32 centres crosses a triangle at t in [1e-4, 1 - 1e-4] (Moller-Trumbore, double)."""
    Z, Y, X = cells.shape
    M = np.full(cells.shape, (1 << 27) - 1, np.int64)
    T = tris.reshape(-1, 3, 3)
    centre = lambda x, y, z: np.float32(np.asarray(origin) + (np.array([x, y, z]) + 0.5) @ R * h).astype(float)
    for z in range(Z):
        for y in range(Y):
            for x in range(X):
                if cells[z, y, x] < 0:
                    continue
                a = centre(x, y, z)
                for k in range(14, 27):
                    nx, ny, nz = x + k % 3 - 1, y + (k // 3) % 3 - 1, z + k // 9 - 1
                    if not (0 <= nx < X and 0 <= ny < Y and 0 <= nz < Z) or cells[nz, ny, nx] < 0:
                        continue
                    d = centre(nx, ny, nz) - a
                    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
                    pv = np.cross(d, e2)
                    det = np.einsum("ij,ij->i", e1, pv)
                    s = a - T[:, 0]
                    with np.errstate(divide="ignore", invalid="ignore"):
                        u = np.einsum("ij,ij->i", s, pv) / det
                        q = np.cross(s, e1)
                        v = (q @ d) / det
                        t = np.einsum("ij,ij->i", e2, q) / det
                    if np.any((det != 0) & (u >= 0) & (u <= 1) & (v >= 0) & (u + v <= 1) & (t >= 1e-4) & (t <= 1 - 1e-4)):
                        M[z, y, x] &= ~(1 << k)
                        M[nz, ny, nx] &= ~(1 << (26 - k))
    return M


def test_dense_grid_shader_equals_c_field(server, tmp_path):  # noqa: F811
    from schnee_probes import native
    chromium = _chromium()
    if chromium is None or shutil.which("node") is None:
        pytest.skip("chromium / node are not installed (scripts/deps.sh installs them)")
    N, cases, want = 2048, [], []
    for seed in (1, 2, 3, 4):
        rng = np.random.default_rng(100 + seed)
        dims = (6, 5, 4) if seed % 2 else (5, 4, 6)
        X, Y, Z = dims
        h, origin = 0.5, np.array([-1.0, 0.25, 0.5])
        R = np.eye(3) if seed in (1, 3) else _rotation(rng)
        occ = rng.random((Z, Y, X)) >= 0.15
        cells = np.full((Z, Y, X), -1, np.int32)
        cells[occ] = np.arange(occ.sum())
        P = int(occ.sum())
        coeffs = rng.normal(0.0, 0.3, (P, 9, 3))
        coeffs[:, 0] += 2.0
        val = np.where(rng.random(P) < 0.2, 0.0, rng.uniform(0.2, 1.0, P))
        path = tmp_path / f"grid{seed}.shprobe"
        version = 1 if seed == 1 else 2
        kw = {} if version == 1 else {"validity": val, "grid_axes": R}
        native.write_shprobe(str(path), coeffs, cells, dims, origin, h, version=version,
                             probe_scale=rng.uniform(0.5, 2.0, P), **kw)
        f = native.read_shprobe(str(path))
        c32 = np.asarray(f.coeffs, np.float64).reshape(P, 9, 3)
        v32 = np.ones(P) if version == 1 else np.asarray(f.validity, np.float64)
        s32 = np.asarray(f.probe_scale, np.float64)
        R32 = np.asarray(f.grid_axes, np.float64).reshape(3, 3)
        tris = _wall(rng, origin, dims, h) if seed >= 3 else None
        if tris is not None:  # the walls in the rotated grid's frame: tilt them with it
            tris = (np.float32((tris.reshape(-1, 3) - origin) @ R + origin).astype(float)).reshape(-1, 9)
        u = rng.uniform(-0.005, 1.005, (N, 3)) * np.array(dims)
        u[: N // 4] = np.round(u[: N // 4]) + rng.uniform(-0.004, 0.004, (N // 4, 3))  # on cell faces
        p = origin + u @ R32 * h
        n = rng.normal(size=(N, 3))
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        n[: N // 2] = (np.eye(3)[rng.integers(0, 3, N // 2)] * rng.choice([-1.0, 1.0], (N // 2, 1))) @ R32
        stat = rng.random(N) >= 0.3
        pts = np.zeros((2, N, 4), np.float32)
        pts[0, :, :3], pts[1, :, :3], pts[1, :, 3] = p, n, stat
        pts.tofile(tmp_path / f"pts{seed}.f32")
        want.append((cells, c32, v32, s32, R32, np.asarray(f.grid_origin, float), float(f.grid_spacing),
                     pts[0, :, :3].astype(float), pts[1, :, :3].astype(float), stat, tris))
        cases.append({"file": str(path), "points": str(tmp_path / f"pts{seed}.f32"), "n": N,
                      "out": str(tmp_path / f"out{seed}.f32"), "tris": [] if tris is None else tris.ravel().tolist()})
    out = run_node_cases(tmp_path, "grid_vs_c.mjs", _JS, chromium, server, cases)
    for case, (cells, c, v, s, R, o, h, p, n, stat, tris), pm in zip(cases, want, out["records"]):
        masks = np.asarray(pm, np.int64).reshape(cells.shape) if pm else np.full(cells.shape, (1 << 27) - 1)
        cleared = int(((1 << 27) - 1 - masks).astype(bool).sum())
        if tris is not None:
            ref = _np_masks(cells, o, h, R, tris)
            assert (ref == masks).all(), f"{(ref != masks).sum()} cells' masks differ from numpy's"
            assert cleared > 0
        fld = native.GridField.build(cells, o, h, c, axes=R, validity=v, scale=s, masks=masks.astype(np.uint32))
        e = np.zeros((len(p), 3))
        has = np.zeros(len(p), bool)
        for flag in (True, False):
            q = fld.query(p, normals=n, static_surface=flag)
            sel = stat == flag
            e[sel] = np.einsum("nk,nkc->nc", _lambert_basis_l2(n), q["coeffs"])[sel]
            has[sel] = (q["status"] >= 2)[sel]
        g = np.fromfile(case["out"], np.float32).reshape(-1, 4).astype(np.float64)
        got = g[:, 3] > 0.5
        assert (got == has).all(), f"{(got != has).sum()} points differ in having a value"
        d = np.abs(g[has, :3] - e[has]).max(axis=1)
        print(f"\nGLSL vs C dense grid ({case['file'].split('/')[-1]}, {'walls, ' if tris is not None else ''}"
              f"{cleared} cells with cleared mask bits): {has.sum()} of {len(p)} points with a value, |E| diff max "
              f"{d.max():.2e}, p99 {np.percentile(d, 99):.2e}, median {np.median(d):.2e}; peak {np.abs(e[has]).max():.2f}")
        assert d.max() < 2e-3 and np.percentile(d, 99) < 2e-5, (d.max(), np.percentile(d, 99))


_TETRA_JS = r"""
import { readFileSync } from 'node:fs';
const job = JSON.parse(readFileSync(process.argv[2], 'utf8'));
const { parseShprobe } = await import(job.web + '/src/shprobe.js');
const P = await import(job.web + '/src/schnee-gltf-plugin.js');
const buf = readFileSync(job.file);
const f = parseShprobe(buf.buffer.slice(buf.byteOffset, buf.byteOffset + buf.length), { name: 'tetra' });
const g = new P.ProbeGrid(f, { name: 'tetra' }, 0);
const out = job.points.map((c) => {
  const w = g.objectWeights(c, () => true);
  return w && w.size ? { w: [...w], sh: [...g.blend(w)] } : null;
});
console.log(JSON.stringify(out));
"""


def test_tetrahedra_per_object_equals_c(tmp_path):
    """A tetrahedra file's per-object weights and blended SH in the plugin (ProbeGrid.objectWeights: the
    pb_interp_query_tetra rule, validity dropped and renormalised; no occluders) equal the C's
    native.Tetrahedra.query at random object centres (run in node: the page's module)."""
    from schnee_probes import native
    if shutil.which("node") is None:
        pytest.skip("node is not installed (scripts/deps.sh installs nodejs)")
    rng = np.random.default_rng(7)
    pos = np.float32(rng.uniform(-2.0, 2.0, (60, 3)) * [1.0, 0.5, 0.8]).astype(np.float64)
    t = native.Tetrahedra.create(pos)
    coeffs = rng.normal(0.0, 0.3, (60, 9, 3))
    coeffs[:, 0] += 2.0
    val = np.where(rng.random(60) < 0.15, 0.0, 1.0)
    scale = rng.uniform(0.5, 2.0, 60)
    path = tmp_path / "tetra.shprobe"
    native.write_shprobe_v3(str(path), t, coeffs, validity=val, probe_scale=scale)
    f = native.read_shprobe(str(path))
    pts = rng.uniform(-2.2, 2.2, (48, 3)) * [1.0, 0.5, 0.8] * np.where(np.arange(48)[:, None] < 36, 0.6, 1.0)
    job = tmp_path / "job.json"
    js = tmp_path / "tetra.mjs"
    js.write_text(_TETRA_JS)
    job.write_text(json.dumps({"web": WEB.as_uri(), "file": str(path), "points": pts.tolist()}))
    r = subprocess.run(["node", str(js), str(job)], capture_output=True, text=True, timeout=60, cwd=WEB)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]
    got = json.loads(r.stdout.strip().splitlines()[-1])
    pr, wt = t.query(pts, validity=np.asarray(f.validity, np.float32))
    c = np.asarray(f.coeffs, np.float64).reshape(60, 9, 3) * np.asarray(f.probe_scale, np.float64)[:, None, None]
    inside, worst = 0, 0.0
    for i in range(len(pts)):
        want = {int(p): float(w) for p, w in zip(pr[i], wt[i]) if p >= 0 and w > 0}
        if not want:
            assert got[i] is None, (i, got[i])
            continue
        inside += 1
        gw = dict(got[i]["w"])
        assert set(gw) == set(want), (i, gw, want)
        worst = max(worst, max(abs(gw[p] - w) for p, w in want.items()))
        sh = sum(w * c[p] for p, w in want.items()).ravel()
        assert np.allclose(np.asarray(got[i]["sh"]), sh, rtol=1e-6, atol=1e-6), i
    print(f"\ntetrahedra per object, plugin vs C: {inside} of {len(pts)} centres with a value, weights max diff {worst:.1e}")
    assert inside >= 20 and worst < 1e-9
