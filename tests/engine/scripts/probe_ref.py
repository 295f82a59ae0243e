"""CPU (numpy) reference of schnee-view's probe lighting, written from the documents, not the shaders.

- SH basis and irradiance: DESIGN.md §3 (bands 0..2).
- Per-pixel interpolation: docs/engine.md "Per-pixel probes" — trilinear weights over the 8
  neighbouring cell centres (indices clamped to the grid; the box holds p with a 0.01-cell
  margin), times validity, times the back-face
  weight smoothstep(-0.1, 0.1, dot(c - p, n) / spacing); cells of -1 skipped, weights
  renormalised; all weights 0 -> the cell holding p; first grid whose box holds p wins.
- Not modelled: the engine's visibility masks (docs/engine.md step 3): compare only scenes where no
  triangle crosses a segment between neighbouring cell centres (then every bit is set).
- Ambient cube: docs/ambient-cube.md §1 (E_cube) and §2 (the least-squares fit's closed form, written
  here from the derivation: the even part keeps the Y_0, Y_6, Y_8 terms of E, the odd part the
  linear term times 5/4).
- Equirect mapping: DESIGN.md §3 (Blender d = (e.x, -e.z, e.y)).
- Direct light of a point light: docs/engine.md "Shading" (Lambert + normalised Blinn-Phong,
  range window, 1/d^2).
"""
import numpy as np

A_L2 = np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5)


def sh_basis_l2(n):
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    return np.stack([
        np.full_like(x, 0.282094792),
        0.488602512 * y, 0.488602512 * z, 0.488602512 * x,
        1.092548431 * x * y, 1.092548431 * y * z, 0.315391565 * (3 * z * z - 1),
        1.092548431 * x * z, 0.546274215 * (x * x - y * y)], axis=-1)


def irradiance(coeffs, n):
    """E(n) for L2 radiance coefficients coeffs (9, 3); n (..., 3) unit."""
    return np.einsum("...i,i,ic->...c", sh_basis_l2(np.asarray(n, float)), A_L2, np.asarray(coeffs, float)[:9])


def uniform_coeffs(radiance):
    """Radiance SH of a uniform environment: L_00 = L * Y0 * 4 pi."""
    c = np.zeros((9, 3))
    c[0] = np.asarray(radiance, float) * 0.282094792 * 4 * np.pi
    return c


K00, K1, K2B, K2C = 0.282094792, 0.488602512, 0.315391565, 0.546274215


def cube_from_sh(coeffs):
    """Least-squares ambient cube (6, 3), faces +X, -X, +Y, -Y, +Z, -Z, of L2 radiance coeffs (9, 3)
    (docs/ambient-cube.md §2: e_i = A_l L_i; s_x = K00 e0 - K2B e6 + K2C e8, s_y = K00 e0 - K2B e6
    - K2C e8, s_z = K00 e0 + 2 K2B e6; d_x, d_y, d_z = 5/4 K1 (e3, e1, e2); C_+- = s +- d)."""
    e = A_L2[:, None] * np.asarray(coeffs, float)[:9]
    s = [K00 * e[0] - K2B * e[6] + K2C * e[8], K00 * e[0] - K2B * e[6] - K2C * e[8], K00 * e[0] + 2 * K2B * e[6]]
    d = [1.25 * K1 * e[3], 1.25 * K1 * e[1], 1.25 * K1 * e[2]]
    return np.array([s[0] + d[0], s[0] - d[0], s[1] + d[1], s[1] - d[1], s[2] + d[2], s[2] - d[2]])


def cube_irradiance(cube, n):
    """E_cube(n) = sum_i n_i^2 C_{sign(n_i) i} (docs/ambient-cube.md §1) for cube (6, 3), n (..., 3)."""
    n = np.asarray(n, float)
    cube = np.asarray(cube, float)
    out = 0.0
    for a in range(3):
        face = np.where(n[..., a] < 0, 2 * a + 1, 2 * a)
        out = out + (n[..., a] ** 2)[..., None] * cube[face]
    return out


def smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def grid_irradiance(p, n, grid, origin, spacing, coeffs, validity=None, evaluate=irradiance, backface=True):
    """Per-pixel E(n) at points p (N, 3) with normals n (N, 3) for one axis-aligned grid
    (grid: int (Z, Y, X) of probe indices / -1, coeffs (count, 9, 3)). Returns (E (N, 3), held (N,)).
    evaluate(coeffs[k], n): irradiance of one probe (cube_irradiance with cubes for the ambient cube).
    backface=False: a movable object's rule (no back-face weights, docs/engine.md)."""
    p = np.asarray(p, float)
    n = np.asarray(n, float)
    Z, Y, X = grid.shape
    dims = np.array([X, Y, Z])
    validity = np.ones(len(coeffs)) if validity is None else np.asarray(validity, float)
    u = (p - np.asarray(origin, float)) / spacing
    held = np.all((u >= -0.01) & (u <= dims + 0.01), axis=1)  # 1/100-cell margin (docs/engine.md)
    c = u - 0.5
    i0 = np.floor(c).astype(int)
    f = c - i0
    e = np.zeros((len(p), 3))
    plain = np.zeros((len(p), 3))  # step 5: trilinear x validity alone (no back face)
    wsum = np.zeros(len(p))
    dsum = np.zeros(len(p))
    for k in range(8):
        o = np.array([k & 1, (k >> 1) & 1, (k >> 2) & 1])
        ci = np.clip(i0 + o, 0, dims - 1)
        idx = grid[ci[:, 2], ci[:, 1], ci[:, 0]]
        tri = np.prod(np.where(o == 1, f, 1 - f), axis=1)
        centre = np.asarray(origin, float) + (ci + 0.5) * spacing
        t = np.einsum("ij,ij->i", centre - p, n) / spacing
        v = np.where(idx >= 0, validity[np.maximum(idx, 0)], 0.0)
        w = tri * (smoothstep(-0.1, 0.1, t) if backface else 1.0) * v
        w = np.where((idx >= 0) & (w > 0), w, 0.0)
        d = np.where(idx >= 0, tri * np.maximum(v, 0.0), 0.0)
        ek = np.stack([evaluate(coeffs[j], n[i]) if j >= 0 else np.zeros(3) for i, j in enumerate(idx)])
        e += w[:, None] * ek
        plain += d[:, None] * ek
        wsum += w
        dsum += d
    out = np.where(wsum[:, None] > 1e-6, e / np.maximum(wsum, 1e-30)[:, None], 0.0)
    # Every weight 0 (step 5, docs/grid-field.md): the plain trilinear x validity weights, no value when their
    # sum is 0 too.
    low = held & (wsum <= 1e-6) & (dsum > 1e-6)
    out[low] = plain[low] / dsum[low, None]
    held = held & ((wsum > 1e-6) | (dsum > 1e-6))
    return out, held


def sky_uv(d):
    """Equirect (u, v) in [0, 1] of engine-space unit directions d (..., 3)."""
    phi = np.arctan2(-d[..., 2], d[..., 0])
    return (np.pi - phi) / (2 * np.pi), np.arccos(np.clip(d[..., 1], -1, 1)) / np.pi


def sample_equirect(img, d):
    """Bilinear lookup (u wraps, v clamps) of an (H, W, 3) equirect image, as a GPU sampler does."""
    h, w = img.shape[:2]
    u, v = sky_uv(d)
    x = u * w - 0.5
    y = v * h - 0.5
    x0 = np.floor(x).astype(int)
    y0 = np.floor(y).astype(int)
    tx, ty = (x - x0)[..., None], (y - y0)[..., None]
    out = 0
    for dy in (0, 1):
        for dx in (0, 1):
            xi = (x0 + dx) % w
            yi = np.clip(y0 + dy, 0, h - 1)
            wgt = (tx if dx else 1 - tx) * (ty if dy else 1 - ty)
            out = out + wgt * img[yi, xi]
    return out


def equirect_dirs(w, h):
    """Engine-space direction of each texel centre of a w x h panorama (DESIGN.md §3)."""
    i, r = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    phi = np.pi - 2 * np.pi * i / w
    th = np.pi * r / h
    bx, by, bz = np.sin(th) * np.cos(phi), np.sin(th) * np.sin(phi), np.cos(th)
    return np.stack([bx, bz, -by], axis=-1), (2 * np.pi / w) * (np.cos(th - np.pi / (2 * h)) - np.cos(th + np.pi / (2 * h)))


def project_l2(img):
    """Radiance SH (9, 3) of an equirect image with exact per-pixel solid angles (DESIGN.md §3)."""
    h, w = img.shape[:2]
    d, dw = equirect_dirs(w, h)
    return np.einsum("hwi,hw,hwc->ic", sh_basis_l2(d), dw, img)


def point_light_direct(p, n, cam, albedo, light_pos, radiance, metallic=0.0, roughness=1.0, range_=0.0,
                       spot=None, specular=True):
    """docs/engine.md "Shading": [(1 - metallic) base/pi + F0 (s+8)/(8 pi) (n.h)^s] * radiance * atten * (n.l)
    for a point light of intensity*colour `radiance` (candela) at light_pos; atten = 1/d^2 times the
    range window clamp(1 - (d/range)^4, 0, 1); s = max(2/r^4 - 2, 1), r = max(roughness, 0.05);
    F0 = mix(0.04, base, metallic). p, n: (..., 3) positions and unit normals; cam: eye position.
    spot = (unit direction the light points to, inner, outer cone angles): a spot light, atten times
    clamp(cos·scale + offset, 0, 1)² with KHR_lights_punctual's scale = 1 / max(0.001, cos(inner) -
    cos(outer)), offset = -cos(outer)·scale. specular=False: the Lambert term alone (--no-specular)."""
    p, n = np.asarray(p, float), np.asarray(n, float)
    albedo, radiance = np.asarray(albedo, float), np.asarray(radiance, float)
    d = np.asarray(light_pos, float) - p
    dist2 = np.maximum((d * d).sum(-1), 1e-8)
    l = d / np.sqrt(dist2)[..., None]
    atten = 1.0 / dist2
    if range_ > 0:
        atten = atten * np.clip(1.0 - (dist2 / range_ ** 2) ** 2, 0.0, 1.0)
    if spot is not None:
        axis, inner, outer = spot
        scale = 1.0 / max(0.001, np.cos(inner) - np.cos(outer))
        cone = np.clip(-(l @ np.asarray(axis, float)) * scale - np.cos(outer) * scale, 0.0, 1.0)
        atten = atten * cone * cone
    v = np.asarray(cam, float) - p
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    h = l + v
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    r = np.clip(roughness, 0.05, 1.0)
    s = max(2.0 / r ** 4 - 2.0, 1.0)
    f0 = 0.04 * (1 - metallic) + albedo * metallic
    nl = np.maximum((n * l).sum(-1), 0.0)
    spec = (s + 8) / (8 * np.pi) * np.maximum((n * h).sum(-1), 0.0) ** s
    brdf = (1 - metallic) * albedo / np.pi + (f0 * spec[..., None] if specular else 0.0)
    return brdf * radiance * (atten * nl)[..., None]


def sphere_normals(W, H, yfov, cam_z):
    """Unit sphere at the origin seen by a camera at (0, 0, cam_z) looking down −Z (vertical fov
    yfov, W×H pixels): per pixel the hit point (= its normal), whether the pixel-centre ray hits,
    and n·(−ray)."""
    i, j = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    t = np.tan(yfov / 2)
    d = np.stack([(2 * i / W - 1) * t * (W / H), (1 - 2 * j / H) * t, -np.ones_like(i)], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    o = np.array([0.0, 0.0, cam_z])
    b = d @ o
    disc = b * b - (o @ o - 1.0)
    hit = disc > 0
    s = -b - np.sqrt(np.where(hit, disc, 0.0))
    p = o + s[..., None] * d
    return p, hit, -(p * d).sum(-1)
