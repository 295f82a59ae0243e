/* Schnee probes for three.js: a GLTFLoader plugin that lights MeshStandardMaterial meshes with the
 * baked SH probes of a glTF exported by the add-on (docs/export.md: VULKAN_SCHNEE_engine_properties,
 * VULKAN_SCHNEE_materials, VULKAN_SCHNEE_node).
 *
 * Usage:
 *   import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
 *   import { SchneeProbesPlugin } from './schnee-gltf-plugin.js';
 *   const loader = new GLTFLoader().register((parser) => new SchneeProbesPlugin(parser, { mode: 'material' }));
 *   const gltf = await loader.loadAsync('scene.gltf');   // rejects with the ShprobeError of a bad file
 *   scene.add(gltf.scene);
 *   gltf.userData.schneeProbes.setMode('object');         // 'material' | 'off' | 'object' | 'pixel'
 *
 * Shading (DESIGN.md §3, docs/engine.md "Shading"): the indirect diffuse term of every lit mesh is
 * replaced by  base · (shScale · probeScale · max(E(n), 0) / π + ambientTerm)  with E(n) from the SH
 * (no Condon–Shortley phase, A_l = π, 2π/3, π/4, 0, −π/24), engine space = glTF space (Y-up).
 * - off: the fallback probe 0 (the glTF sky's SH, else a uniform radiance of 0.2).
 * - per object: the interpolated probe at the centre of the object's world bounds, as schnee-view's
 *   sv_probe_query.c: octree / kd-tree files blend the leaf's corners (hanging corners expanded through
 *   their rules), dense grids take docs/grid-field.md's movable rule; every weighted probe is judged by the
 *   segment probe → centre through the static scene (the object itself left out); the first grid with a
 *   value wins, else probe 0.
 * - per pixel: one 3D texture (hardware trilinear) per scene holding N = Σ w s c and D = Σ w per texel
 *   (docs/grid-field.md "Texture", docs/probe-bricks.md "Texels" at level 0); the fragment takes N / D.
 *   Trees follow the engine's brick rule (shaders/bricks_surface.glsl, pb_bricks_sample_surface): each
 *   min cell's brick level (a second, nearest-filtered 3D texture), the face margin, on static surfaces
 *   the back-face weights of the brick cell's 8 corners, and the visibility: texels and 64-B records of
 *   blocked brick cells traced at load through the static scene's triangles (schnee-vis.js, as
 *   sv_bricks_vis.c); one filtered tap where the kept weights are separable, else 8 texelFetch taps. Dense
 *   grids: docs/grid-field.md (neighbour masks traced at load, back faces, one or 8 taps, step 5 the plain trilinear sample).
 */
import * as THREE from 'three';
import { parseShprobe, ShprobeError } from './shprobe.js';
import { SegmentGrid, traceBox, pairValue, visRamp, VIS_CLEAR } from './schnee-vis.js';

export { ShprobeError };

const PI = Math.PI;
/** A_l of DESIGN.md §3 for l = 0..4. */
export const SH_BAND_FACTORS = [PI, (2 * PI) / 3, PI / 4, 0, -PI / 24];
const Y0 = 0.282094792;
/** schnee-view's fallback radiance (SV_FALLBACK_RADIANCE): probe 0 without a sky. */
export const FALLBACK_RADIANCE = 0.2;
const MAX_COEFFS = 25;
const MODES = ['off', 'object', 'pixel'];

/** Real SH basis of DESIGN.md §3 (no Condon–Shortley phase) at unit d = (x, y, z), l = 0..4. */
export function shBasis(x, y, z) {
  const x2 = x * x, y2 = y * y, z2 = z * z;
  return [
    Y0,
    0.488602512 * y, 0.488602512 * z, 0.488602512 * x,
    1.092548431 * x * y, 1.092548431 * y * z, 0.315391565 * (3 * z2 - 1), 1.092548431 * x * z, 0.546274215 * (x2 - y2),
    0.590043590 * y * (3 * x2 - y2), 2.890611443 * x * y * z, 0.457045799 * y * (5 * z2 - 1), 0.373176333 * z * (5 * z2 - 3),
    0.457045799 * x * (5 * z2 - 1), 1.445305721 * z * (x2 - y2), 0.590043590 * x * (x2 - 3 * y2),
    2.503342942 * x * y * (x2 - y2), 1.770130770 * y * z * (3 * x2 - y2), 0.946174696 * x * y * (7 * z2 - 1),
    0.669046544 * y * z * (7 * z2 - 3), 0.105785547 * (35 * z2 * z2 - 30 * z2 + 3), 0.669046544 * x * z * (7 * z2 - 3),
    0.473087348 * (x2 - y2) * (7 * z2 - 1), 1.770130770 * x * z * (x2 - 3 * y2), 0.625835735 * (x2 * x2 - 6 * x2 * y2 + y2 * y2),
  ];
}

/** Irradiance E(n) (RGB) of radiance SH `sh` (Float array, count × 3) at unit normal n. */
export function shIrradiance(sh, count, n) {
  const Y = shBasis(n[0], n[1], n[2]);
  const e = [0, 0, 0];
  for (let i = 0; i < count; i++) {
    const a = SH_BAND_FACTORS[Math.floor(Math.sqrt(i))] * Y[i];
    for (let c = 0; c < 3; c++) e[c] += a * sh[3 * i + c];
  }
  return e;
}

/* ---- GLSL ------------------------------------------------------------------------------------------ */

/** The fragment code the plugin injects (uniforms, schneeGridSample, schneeIrradiance): exported for tests. */
export const SCHNEE_GLSL_COMMON = /* glsl */ `
#define SCHNEE_MAX_COEFFS ${MAX_COEFFS}
#define SCHNEE_MAX_GRIDS 4
#define SCHNEE_MAX_GROUPS 19
uniform vec3 schneeSH[SCHNEE_MAX_COEFFS];
uniform int schneeCount;
uniform int schneeMode;
uniform float schneeShScale;
uniform float schneeAmbient;
uniform highp sampler3D schneeTex;
uniform int schneeGridCount;
uniform vec4 schneeGridA[SCHNEE_MAX_GRIDS];  // origin xyz, spacing
uniform vec4 schneeGridB[SCHNEE_MAX_GRIDS];  // dims xyz, kind (0 dense: texels at cell centres; 1 lattice)
uniform vec4 schneeGridC[SCHNEE_MAX_GRIDS];  // atlas texel z base, colour count, groups, level atlas z base
uniform highp sampler3D schneeLevelTex;       // trees: each min cell's brick level L, -1 = no leaf (nearest)
uniform int schneeStatic;                     // 1: a static surface (back-face weights), 0: movable
uniform highp sampler2D schneeVisRec;         // visibility records: 16 RGBA texels of bytes each, 64 a row
uniform vec3 schneeGridAxes[3 * SCHNEE_MAX_GRIDS];
uniform vec3 schneeTexSize;
varying vec3 vSchneeWorldPos;

// A_l · Y_i(n), DESIGN.md §3 (l = 3 has A_3 = 0).
void schneeBasis(vec3 n, out float ay[SCHNEE_MAX_COEFFS]) {
  float x = n.x, y = n.y, z = n.z, x2 = x * x, y2 = y * y, z2 = z * z;
  const float PI_ = 3.14159265358979, A1 = 2.0 * PI_ / 3.0, A2 = PI_ / 4.0, A4 = -PI_ / 24.0;
  ay[0] = PI_ * 0.282094792;
  ay[1] = A1 * 0.488602512 * y; ay[2] = A1 * 0.488602512 * z; ay[3] = A1 * 0.488602512 * x;
  ay[4] = A2 * 1.092548431 * x * y; ay[5] = A2 * 1.092548431 * y * z; ay[6] = A2 * 0.315391565 * (3.0 * z2 - 1.0);
  ay[7] = A2 * 1.092548431 * x * z; ay[8] = A2 * 0.546274215 * (x2 - y2);
  for (int i = 9; i < 16; i++) ay[i] = 0.0;
  ay[16] = A4 * 2.503342942 * x * y * (x2 - y2); ay[17] = A4 * 1.770130770 * y * z * (3.0 * x2 - y2);
  ay[18] = A4 * 0.946174696 * x * y * (7.0 * z2 - 1.0); ay[19] = A4 * 0.669046544 * y * z * (7.0 * z2 - 3.0);
  ay[20] = A4 * 0.105785547 * (35.0 * z2 * z2 - 30.0 * z2 + 3.0); ay[21] = A4 * 0.669046544 * x * z * (7.0 * z2 - 3.0);
  ay[22] = A4 * 0.473087348 * (x2 - y2) * (7.0 * z2 - 1.0); ay[23] = A4 * 1.770130770 * x * z * (x2 - 3.0 * y2);
  ay[24] = A4 * 0.625835735 * (x2 * x2 - 6.0 * x2 * y2 + y2 * y2);
}

// One filtered tap (hardware trilinear) of grid g's channel groups at texel coordinate tt (grid-local,
// group 0's slab), then E(n) = sum_i A_l(i) Y_i(n) N_i / D. False when D <= dmin.
bool schneeTapD(vec3 tt, vec4 C, float nz, float ay[SCHNEE_MAX_COEFFS], float dmin, out vec3 e, out float D) {
  vec3 tc = (tt + 0.5) / schneeTexSize;
  float zstep = nz / schneeTexSize.z;
  tc.z += C.x / schneeTexSize.z;
  int count = int(C.y), groups = int(C.z);
  vec4 g0 = texture(schneeTex, tc);
  D = g0.w;
  e = vec3(0.0);
  if (!(D > dmin)) return false;
  e = ay[0] * g0.rgb;
  // channels 0-2 N0, 3 D, then N1 .. N(count-1) RGB packed consecutively
  float ch[4 * SCHNEE_MAX_GROUPS];
  for (int k = 0; k < 4 * SCHNEE_MAX_GROUPS; k++) ch[k] = 0.0;
  for (int gi = 1; gi < SCHNEE_MAX_GROUPS; gi++) {
    if (gi >= groups) break;
    vec4 v = texture(schneeTex, vec3(tc.xy, tc.z + float(gi) * zstep));
    ch[4 * gi] = v.x; ch[4 * gi + 1] = v.y; ch[4 * gi + 2] = v.z; ch[4 * gi + 3] = v.w;
  }
  for (int i = 1; i < SCHNEE_MAX_COEFFS; i++) {
    if (i >= count) break;
    int o = 4 + 3 * (i - 1);
    e += ay[i] * vec3(ch[o], ch[o + 1], ch[o + 2]);
  }
  e /= D;
  return true;
}
bool schneeTap(vec3 tt, vec4 C, float nz, float ay[SCHNEE_MAX_COEFFS], float dmin, out vec3 e) {
  float D;
  return schneeTapD(tt, C, nz, ay, dmin, e, D);
}

// The 8-tap form (bricks_surface.glsl brick_tap8 = pb_bricks.c cell_weighted): texelFetch of the cell's 8
// corner texels t0 + s * bits(k), exact weights w; E = sum_i A_l(i) Y_i(n) N'_i / D'. False when D' <= 0.
// The same with each corner clamped into [0, tmax] (dense grids: clamped corners) and D' > dmin.
bool schneeTap8c(ivec3 t0, int s, ivec3 tmax, vec4 C, int nz, float w[8], float ay[SCHNEE_MAX_COEFFS], float dmin, out vec3 e) {
  int count = int(C.y), groups = int(C.z);
  vec3 acc = vec3(0.0);
  float D = 0.0;
  e = vec3(0.0);
  for (int k = 0; k < 8; k++) {
    if (w[k] == 0.0) continue;
    ivec3 tk = clamp(t0 + s * ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1), ivec3(0), tmax) + ivec3(0, 0, int(C.x));
    vec4 v0 = texelFetch(schneeTex, tk, 0);
    D += w[k] * v0.w;
    acc += w[k] * ay[0] * v0.rgb;
    for (int gi = 1; gi < SCHNEE_MAX_GROUPS; gi++) {
      if (gi >= groups) break;
      vec4 v = texelFetch(schneeTex, tk + ivec3(0, 0, gi * nz), 0);
      for (int j = 0; j < 4; j++) { // channel 4 gi + j = N_i colour c % 3, i = 1 + c / 3
        int c = 4 * gi + j - 4, i = 1 + c / 3;
        if (i < count) acc[c % 3] += w[k] * ay[i] * v[j];
      }
    }
  }
  if (!(D > dmin)) return false;
  e = acc / D;
  return true;
}
bool schneeTap8(ivec3 t0, int s, vec4 C, int nz, float w[8], float ay[SCHNEE_MAX_COEFFS], out vec3 e) {
  return schneeTap8c(t0, s, ivec3(1 << 20), C, nz, w, ay, 0.0, e);
}

// bricks.glsl brick_separable (pb_bricks_separable): w'_k (sum w')^2 = prod_a M_a(bit_a(k)) within 1e-5
// relative for every k; f1 = the per-axis means of the kept weights.
bool schneeSeparable(float w[8], out vec3 f1) {
  float sw = 0.0;
  vec3 m0 = vec3(0.0), m1 = vec3(0.0);
  for (int k = 0; k < 8; k++) {
    vec3 o = vec3(float(k & 1), float((k >> 1) & 1), float((k >> 2) & 1));
    sw += w[k];
    m1 += w[k] * o;
    m0 += w[k] * (1.0 - o);
  }
  f1 = sw > 0.0 ? m1 / sw : vec3(0.0);
  if (!(sw > 0.0)) return false;
  for (int k = 0; k < 8; k++) {
    vec3 m = mix(m0, m1, vec3(float(k & 1), float((k >> 1) & 1), float((k >> 2) & 1)));
    float lhs = w[k] * sw * sw, rhs = m.x * m.y * m.z;
    if (!(abs(lhs - rhs) <= 1e-5 * max(lhs, rhs))) return false;
  }
  return true;
}

// A tap of the brick region r0 (brick cells of si min cells) at brick-local xt in [0, 4]: level 0 one
// filtered tap; level L >= 1 the trilinear of the brick cell's 8 corner texels (texelFetch): the texture
// holds every lattice point, and the visibility texels are not trilinear inside a brick cell, so the
// points between a brick's texels must not be read (pb_bricks.c cell_filtered reads only its texels).
bool schneeBrickTap(ivec3 r0, int si, vec3 xt, vec4 C, float nz, float ay[SCHNEE_MAX_COEFFS], out vec3 e) {
  if (si == 1) return schneeTap(vec3(r0) + xt, C, nz, ay, 0.0, e);
  vec3 k0 = min(floor(xt), vec3(3.0)), f = xt - k0;
  float w[8];
  for (int k = 0; k < 8; k++) {
    vec3 w3 = mix(1.0 - f, f, vec3(float(k & 1), float((k >> 1) & 1), float((k >> 2) & 1)));
    w[k] = w3.x * w3.y * w3.z;
  }
  return schneeTap8(r0 + si * ivec3(k0), si, C, int(nz), w, ay, e);
}

// Dense grids per pixel: pb_grid_field_sample_surface_texture (docs/grid-field.md "The rule" steps 2-5,
// bricks.glsl grid_tex_irradiance). u: the point's grid coordinates (in the box with the 0.01 margin; the
// page's normal bias is 0, as schnee-view's default). The level atlas holds per cell R/G = the 27-bit
// neighbour mask (low 16 / high 11 bits, traced at load through the static scene as
// sv_probe_visibility_masks), B = 1 where the cell holds a probe.
bool schneeDenseSample(int g, vec3 u, vec3 nrm, bool isStatic, float ay[SCHNEE_MAX_COEFFS], out vec3 e) {
  vec4 B = schneeGridB[g], C = schneeGridC[g];
  ivec3 dims = ivec3(B.xyz), lz = ivec3(0, 0, int(C.w));
  vec3 rn = vec3(dot(nrm, schneeGridAxes[3 * g]), dot(nrm, schneeGridAxes[3 * g + 1]), dot(nrm, schneeGridAxes[3 * g + 2]));
  vec3 c = u - 0.5;
  ivec3 i0 = ivec3(floor(c));
  vec3 f = c - vec3(i0);
  ivec3 home = clamp(ivec3(floor(u + 0.01 * rn)), ivec3(0), dims - 1); // 3. the home cell 0.01 cells along n
  vec4 hm = texelFetch(schneeLevelTex, home + lz, 0);
  uint vis = uint(hm.r + 0.5) | (uint(hm.g + 0.5) << 16u);
  float w[8];
  for (int k = 0; k < 8; k++) { // 4. trilinear x (mask ? 0 : back face); validity is in N and D
    ivec3 o = ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);
    ivec3 ci = clamp(i0 + o, ivec3(0), dims - 1);
    ivec3 d = ci - home;
    bool masked = all(lessThanEqual(abs(d), ivec3(1))) && (vis & (1u << uint(d.x + 1 + 3 * (d.y + 1) + 9 * (d.z + 1)))) == 0u;
    float b = isStatic ? smoothstep(-0.1, 0.1, dot(vec3(ci) + 0.5 - u, rn)) : 1.0;
    vec3 w3 = mix(1.0 - f, f, vec3(o));
    w[k] = w3.x * w3.y * w3.z * (masked ? 0.0 : b);
  }
  float sw = 0.0;
  for (int k = 0; k < 8; k++) sw += w[k];
  vec3 f1;
  float D;
  // 5. separable: one filtered tap at clamp(i0 + f', 0, dims - 1), kept where D >= 1/64; else 8 exact taps
  if (schneeSeparable(w, f1) && schneeTapD(clamp(vec3(i0) + f1, vec3(0.0), B.xyz - 1.0), C, B.z, ay, 0.0, e, D) &&
      D >= 1.0 / 64.0) {
    if (sw * D > 1e-6) return true;
  } else if (schneeTap8c(i0, 1, dims - 1, C, int(B.z), w, ay, 1e-6, e)) {
    return true;
  }
  // 5. no weight left: the plain trilinear x validity sample (no mask, no back face), the texture's own
  // N / D at the point, 8 exact taps (its D may be tiny); D <= 1e-6 too: no value (the next grid)
  for (int k = 0; k < 8; k++) {
    vec3 w3 = mix(1.0 - f, f, vec3(ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1)));
    w[k] = w3.x * w3.y * w3.z;
  }
  return schneeTap8c(i0, 1, dims - 1, C, int(B.z), w, ay, 1e-6, e);
}

// Per pixel: grid g at world point p with normal n (false: no value here, the next grid). Trees follow
// bricks_surface.glsl brick_surface_irradiance (pb_bricks_sample_surface) without visibility texels or
// records: locate the min cell (with the face margin) and its brick level L (schneeLevelTex), the brick
// cell k0 of size 2^L in the brick region r0; on a static surface each corner's trilinear weight times its
// back-face weight smoothstep(-0.1, 0.1, dot(x_k - u_s, n) / 2^L); separable kept weights: one filtered tap
// at r0 + 2^L (k0 + f'), else 8 texelFetch taps; no weight left or D <= 0: the plain sample. The level-0
// texture holds the brick texels' values (the same lattice points), so the taps read the same N and D.
bool schneeGridSample(int g, vec3 p, vec3 nrm, bool isStatic, float ay[SCHNEE_MAX_COEFFS], out vec3 e) {
  vec4 A = schneeGridA[g], B = schneeGridB[g], C = schneeGridC[g];
  vec3 d = p - A.xyz;
  vec3 u = vec3(dot(d, schneeGridAxes[3 * g]), dot(d, schneeGridAxes[3 * g + 1]), dot(d, schneeGridAxes[3 * g + 2])) / A.w;
  e = vec3(0.0);
  if (B.w < 0.5) { // dense grid: 0.01-cell margin, texels at cell centres (docs/grid-field.md)
    if (any(lessThan(u, vec3(-0.01))) || any(greaterThan(u, B.xyz + 0.01))) return false;
    return schneeDenseSample(g, u, nrm, isStatic, ay, e);
  }
  // octree / kd lattice: texels at lattice points; the 0.01-cell margin, u clamped into [0, E]
  // (bricks_surface.glsl brick_locate: walls modelled on the lattice's faces)
  if (any(lessThan(u, vec3(-0.01))) || any(greaterThan(u, B.xyz + 0.01))) return false;
  vec3 us = u; // the surface point's lattice coordinates (the page has no normal bias: schnee-view's default 0)
  u = clamp(u, vec3(0.0), B.xyz);
  ivec3 q = ivec3(min(floor(u), B.xyz - 1.0));
  ivec3 lz = ivec3(0, 0, int(C.w));
  float L = texelFetch(schneeLevelTex, q + lz, 0).r;
  bool found = L >= 0.0;
  for (int m = 1; !found && m < 8; ++m) { // the face margin: the first occupied q - m within 0.01 below
    ivec3 r = q;
    bool ok = true;
    for (int a = 0; a < 3; ++a) {
      if (((m >> a) & 1) == 0) continue;
      if (!(q[a] > 0 && u[a] - float(q[a]) < 0.01)) ok = false;
      r[a] = q[a] - 1;
    }
    if (!ok) continue;
    float Lr = texelFetch(schneeLevelTex, r + lz, 0).r;
    if (Lr < 0.0) continue;
    q = r;
    u = clamp(u, vec3(q), vec3(q) + 1.0);
    L = Lr;
    found = true;
  }
  if (!found) return false;
  int Li = int(L + 0.5), si = 1 << Li;
  float s = float(si);
  ivec3 r0 = (q >> (Li + 2)) << (Li + 2);
  vec3 x = clamp((u - vec3(r0)) / s, vec3(0.0), vec3(4.0));
  float nz = B.z + 1.0;
  vec3 k0 = min(floor(x), vec3(3.0));
  vec3 f = x - k0;
  // a. the brick cell's record (blocked): kept at the level texture's G of its min corner's min cell
  ivec3 lo = r0 + si * ivec3(k0);
  float rec = -1.0;
  if (all(lessThan(vec3(lo), B.xyz))) rec = texelFetch(schneeLevelTex, lo + lz, 0).g;
  bool blocked = rec >= 0.0;
  if (isStatic || blocked) {
    float w[8];
    float sw = 0.0, wbsum = 0.0;
    for (int k = 0; k < 8; k++) { // b. trilinear, c. back faces (static only)
      vec3 o = vec3(float(k & 1), float((k >> 1) & 1), float((k >> 2) & 1));
      vec3 w3 = mix(1.0 - f, f, o);
      w[k] = w3.x * w3.y * w3.z;
      if (isStatic) w[k] *= smoothstep(-0.1, 0.1, dot((vec3(r0) + s * (k0 + o) - us) / s, nrm));
      wbsum += w[k];
    }
    if (blocked) { // d. the visibility ramp of the cell's record, v_c blended over the back-face weights
      int ri = int(rec + 0.5);
      ivec2 rb = ivec2(16 * (ri % 64), ri / 64);
      float V[64];
      for (int j = 0; j < 16; j++) {
        vec4 t = texelFetch(schneeVisRec, rb + ivec2(j, 0), 0);
        for (int c = 0; c < 4; c++) V[4 * j + c] = t[c] >= 255.0 ? 1.0 : 1.0 - 127.5 / max(t[c], 1.0);
      }
      float wv[8];
      for (int c = 0; c < 8; c++) {
        float v = 0.0;
        for (int k = 0; k < 8; k++) v += w[k] * V[8 * k + c];
        v = wbsum > 0.0 ? v / wbsum : 0.0;
        wv[c] = w[c] * smoothstep(0.5, 0.75, v);
      }
      for (int c = 0; c < 8; c++) w[c] = wv[c];
    }
    for (int k = 0; k < 8; k++) sw += w[k];
    if (sw > 0.0) {
      vec3 f1;
      if (schneeSeparable(w, f1)) {
        if (schneeBrickTap(r0, si, k0 + f1, C, nz, ay, e)) return true;
      } else if (schneeTap8(r0 + si * ivec3(k0), si, C, int(nz), w, ay, e)) {
        return true;
      }
    }
  }
  return schneeBrickTap(r0, si, x, C, nz, ay, e); // the plain sample
}

vec3 schneeIrradiance(vec3 p, vec3 n) {
  float ay[SCHNEE_MAX_COEFFS];
  schneeBasis(n, ay);
  vec3 e;
  if (schneeMode == 2)
    for (int g = 0; g < SCHNEE_MAX_GRIDS; g++) {
      if (g >= schneeGridCount) break;
      if (schneeGridSample(g, p, n, schneeStatic == 1, ay, e)) return e;
    }
  e = vec3(0.0);
  for (int i = 0; i < SCHNEE_MAX_COEFFS; i++) {
    if (i >= schneeCount) break;
    e += ay[i] * schneeSH[i];
  }
  return e;
}
`;

/* ---- probe structures on the CPU --------------------------------------------------------------------- */

const trilinear8 = (t) => {
  const w = new Float64Array(8);
  for (let c = 0; c < 8; c++)
    w[c] = (c & 1 ? t[0] : 1 - t[0]) * (c & 2 ? t[1] : 1 - t[1]) * (c & 4 ? t[2] : 1 - t[2]);
  return w;
};

const mergeAdd = (list, p, w) => {
  const prev = list.get(p);
  list.set(p, (prev || 0) + w);
};

/** One grid of the scene: the parsed file plus what its queries need. */
export class ProbeGrid {
  constructor(file, entry, index) {
    this.file = file;
    this.entry = entry;
    this.index = index;
    this.name = entry.name || `grid ${index}`;
    this.kind = file.structure;
    this.count = file.colourCount;
    this.isCube = file.representation === 'ambientCube';
    if (this.kind === 'octree' || this.kind === 'kdtree') this._buildTree();
  }

  /* Lattice cell -> leaf map and each hanging node's expansion over probes (pb_cotree.c's exp_*, from
   * the file's rules). */
  _buildTree() {
    const f = this.file, [X, Y, Z] = f.gridDims, cells = X * Y * Z;
    if (cells > 2 ** 26) throw new Error(`${this.name}: lattice of ${cells} cells is too large for this viewer`);
    this.cellLeaf = new Int32Array(cells).fill(-1);
    const N = f.elementCount;
    this.levels = new Uint32Array(3 * N);
    for (let i = 0; i < N; i++) {
      const L = f.leaves[4 * i + 3];
      const lv = this.kind === 'kdtree' ? [L & 255, (L >> 8) & 255, (L >> 16) & 255] : [L, L, L];
      this.levels.set(lv, 3 * i);
      const lo = [f.leaves[4 * i], f.leaves[4 * i + 1], f.leaves[4 * i + 2]];
      const hi = lo.map((v, k) => Math.min(v + 2 ** lv[k], f.gridDims[k]));
      for (let z = lo[2]; z < hi[2]; z++)
        for (let y = lo[1]; y < hi[1]; y++)
          for (let x = lo[0]; x < hi[0]; x++) this.cellLeaf[x + X * (y + Y * z)] = i;
    }
    const P = f.probeCount;
    this.expansion = [];
    for (let j = 0; j < f.hangingCount; j++) {
      const m = new Map();
      for (let k = 0; k < 4; k++) {
        const src = f.hangingSources[4 * j + k], w = f.hangingWeights[4 * j + k];
        if (!(w > 0)) continue;
        if (src < P) mergeAdd(m, src, w);
        else for (const [p, we] of this.expansion[src - P]) mergeAdd(m, p, w * we);
      }
      this.expansion.push(m);
    }
  }

  /**
   * Each min cell's brick level (docs/probe-bricks.md "Bricks and levels": regions of 4 * 2^L min cells,
   * aligned, visited top down; a region whose overlapped leaves all have every axis level >= L is a brick of
   * level L), -1 where no leaf holds the cell (the indirection's occupancy bit clear). Float32Array X*Y*Z.
   */
  brickLevels() {
    const [X, Y, Z] = this.file.gridDims, INF = 255, cells = X * Y * Z;
    const cellMin = new Uint8Array(cells);
    let top = 0;
    for (let c = 0; c < cells; c++) {
      const li = this.cellLeaf[c];
      if (li < 0) { cellMin[c] = INF; continue; }
      const m = Math.min(this.levels[3 * li], this.levels[3 * li + 1], this.levels[3 * li + 2]);
      cellMin[c] = m;
      if (m > top) top = m;
    }
    /* region minima per level: level 0 pools 4^3 cells, each further level 2^3 regions */
    const regs = [];
    let cur = cellMin, cx = X, cy = Y, cz = Z;
    for (let L = 0; L <= top; L++) {
      const k = L === 0 ? 4 : 2, dx = Math.ceil(cx / k), dy = Math.ceil(cy / k), dz = Math.ceil(cz / k);
      const out = new Uint8Array(dx * dy * dz).fill(INF);
      for (let z = 0; z < cz; z++)
        for (let y = 0; y < cy; y++)
          for (let x = 0; x < cx; x++) {
            const o = Math.floor(x / k) + dx * (Math.floor(y / k) + dy * Math.floor(z / k)), v = cur[x + cx * (y + cy * z)];
            if (v < out[o]) out[o] = v;
          }
      regs.push({ a: out, dx, dy });
      cur = out; cx = dx; cy = dy; cz = dz;
    }
    const lv = new Float32Array(cells);
    for (let z = 0; z < Z; z++)
      for (let y = 0; y < Y; y++)
        for (let x = 0; x < X; x++) {
          const c = x + X * (y + Y * z);
          if (this.cellLeaf[c] < 0) { lv[c] = -1; continue; }
          for (let L = top; L >= 0; L--) {
            const R = regs[L], sh = L + 2;
            if (R.a[(x >> sh) + R.dx * ((y >> sh) + R.dy * (z >> sh))] >= L) { lv[c] = L; break; }
          }
        }
    return lv;
  }

  /* pb_interp.c locate_point_cell: the leaf of unit cell q, else (within 0.01 of a lower face) below. */
  _locate(u, q) {
    const [X, Y] = this.file.gridDims, at = (r) => this.cellLeaf[r[0] + X * (r[1] + Y * r[2])];
    let li = at(q);
    for (let m = 1; li < 0 && m < 8; m++) {
      let ok = true;
      const r = [0, 0, 0];
      for (let k = 0; k < 3; k++) {
        const down = (m >> k) & 1;
        if (down && !(q[k] > 0 && u[k] - q[k] < 0.01)) ok = false;
        r[k] = down ? q[k] - 1 : q[k];
      }
      if (ok) li = at(r);
    }
    return li;
  }

  /** Tree weights at world point p over the probes, before validity / visibility (Map probe -> w), or null. */
  treeWeights(p) {
    const f = this.file, u = [0, 0, 0], q = [0, 0, 0];
    for (let k = 0; k < 3; k++) {
      u[k] = (p[k] - f.gridOrigin[k]) / f.gridSpacing;
      if (!(u[k] >= 0) || !(u[k] <= f.gridDims[k])) return null;
      const fl = Math.floor(u[k]);
      q[k] = fl >= f.gridDims[k] ? f.gridDims[k] - 1 : fl;
    }
    const li = this._locate(u, q);
    if (li < 0) return null;
    const t = [0, 0, 0];
    for (let k = 0; k < 3; k++) {
      const v = (u[k] - f.leaves[4 * li + k]) / 2 ** this.levels[3 * li + k];
      t[k] = v < 0 ? 0 : v > 1 ? 1 : v;
    }
    const w8 = trilinear8(t), out = new Map(), P = f.probeCount;
    for (let c = 0; c < 8; c++) {
      if (w8[c] <= 0) continue;
      const node = f.leafCorners[8 * li + c];
      if (node < P) mergeAdd(out, node, w8[c]);
      else for (const [pp, we] of this.expansion[node - P]) mergeAdd(out, pp, w8[c] * we);
    }
    return out;
  }

  /**
   * The dense grid's 27-bit neighbour masks (sv_probe_visibility_masks): for each pair of occupied
   * neighbouring cells, the segment between their centres (float32) traced through the static scene
   * (`seg(a, b)` < 1: blocked) clears both cells' bits. this.masks: Uint32Array per cell, this.maskCleared.
   */
  buildMasks(seg) {
    const f = this.file, [X, Y, Z] = f.gridDims, G = f.grid;
    const M = new Uint32Array(X * Y * Z).fill(0x7ffffff);
    const centre = (x, y, z) => this._cellCentre([x, y, z]).map(Math.fround);
    let cleared = 0;
    for (let z = 0; z < Z; z++)
      for (let y = 0; y < Y; y++)
        for (let x = 0; x < X; x++) {
          const ci = x + X * (y + Y * z);
          if (G[ci] < 0) continue;
          const a = centre(x, y, z);
          for (let k = 14; k < 27; k++) {
            const nx = x + (k % 3) - 1, ny = y + (Math.floor(k / 3) % 3) - 1, nz = z + Math.floor(k / 9) - 1;
            if (nx < 0 || ny < 0 || nz < 0 || nx >= X || ny >= Y || nz >= Z) continue;
            const cj = nx + X * (ny + Y * nz);
            if (G[cj] < 0) continue;
            if (seg(a, centre(nx, ny, nz)) < 1) {
              M[ci] &= ~(1 << k); M[cj] &= ~(1 << (26 - k));
              cleared++;
            }
          }
        }
    this.masks = M;
    this.maskCleared = cleared;
  }

  /**
   * pb_interp_query_tetra: the tetrahedron with the largest smallest barycentric (accepted >= -1e-9) among
   * those whose bounds hold c, its barycentrics clamped at 0 and merged per probe, then finish_weights
   * (zero, invalid and hidden probes dropped, renormalised); null outside.
   */
  tetraWeights(c, visible) {
    const f = this.file, P = f.positions, T = f.tets, n = T.length / 4;
    if (!this._tetInv) { /* per tetrahedron: the inverse of [p1 - p0, p2 - p0, p3 - p0] (double) and p0 */
      const inv = new Float64Array(12 * n);
      for (let i = 0; i < n; i++) {
        const q = [0, 1, 2, 3].map((k) => [P[3 * T[4 * i + k]], P[3 * T[4 * i + k] + 1], P[3 * T[4 * i + k] + 2]]);
        const m = [1, 2, 3].map((k) => [0, 1, 2].map((a) => q[k][a] - q[0][a])); /* columns */
        const [a, b, cc] = m;
        const cr = (x, y) => [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]];
        const bc = cr(b, cc), ca = cr(cc, a), ab = cr(a, b);
        const det = a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2];
        for (let k = 0; k < 3; k++) { inv[12 * i + k] = bc[k] / det; inv[12 * i + 3 + k] = ca[k] / det; inv[12 * i + 6 + k] = ab[k] / det; }
        inv[12 * i + 9] = q[0][0]; inv[12 * i + 10] = q[0][1]; inv[12 * i + 11] = q[0][2];
      }
      this._tetInv = inv;
    }
    const o = this._tetInv;
    let best = -1, bestMin = -1e-9;
    const bl = [0, 0, 0, 0];
    for (let i = 0; i < n; i++) {
      const d0 = c[0] - o[12 * i + 9], d1 = c[1] - o[12 * i + 10], d2 = c[2] - o[12 * i + 11];
      const l1 = o[12 * i] * d0 + o[12 * i + 1] * d1 + o[12 * i + 2] * d2;
      const l2 = o[12 * i + 3] * d0 + o[12 * i + 4] * d1 + o[12 * i + 5] * d2;
      const l3 = o[12 * i + 6] * d0 + o[12 * i + 7] * d1 + o[12 * i + 8] * d2;
      const l0 = 1 - l1 - l2 - l3, mn = Math.min(l0, l1, l2, l3);
      if (mn >= bestMin) {
        bestMin = mn; best = i; bl[0] = l0; bl[1] = l1; bl[2] = l2; bl[3] = l3;
        if (mn >= 0) break;
      }
    }
    if (best < 0) return null;
    const w = new Map();
    for (let k = 0; k < 4; k++) mergeAdd(w, T[4 * best + k], Math.max(bl[k], 0));
    const out = new Map();
    let sum = 0;
    for (const [p, wi] of w) {
      if (!(wi > 0) || !(f.validity[p] > 0)) continue;
      if (!visible([P[3 * p], P[3 * p + 1], P[3 * p + 2]], c)) continue;
      out.set(p, wi);
      sum += wi;
    }
    if (!(sum > 0)) return null;
    for (const [p, wi] of out) out.set(p, wi / sum);
    return out;
  }

  _cellCentre(ci) {
    const f = this.file, h = f.gridSpacing, a = f.gridAxes;
    const l = [(ci[0] + 0.5) * h, (ci[1] + 0.5) * h, (ci[2] + 0.5) * h];
    return [0, 1, 2].map((k) => f.gridOrigin[k] + l[0] * a[0][k] + l[1] * a[1][k] + l[2] * a[2][k]);
  }

  /**
   * Per-object weights at world point c (Map probe -> normalised weight), or null for no value;
   * `visible(from, to)` judges a segment through the static scene.
   */
  objectWeights(c, visible) {
    const f = this.file;
    if (this.kind === 'octree' || this.kind === 'kdtree') {
      const w = this.treeWeights(c);
      if (!w) return null;
      /* pb_interp.c finish_weights: zero weights, invalid and hidden probes dropped, renormalised. */
      const out = new Map();
      let sum = 0;
      for (const [p, wi] of w) {
        if (!(wi > 0) || !(f.validity[p] > 0)) continue;
        if (f.positions && !visible([f.positions[3 * p], f.positions[3 * p + 1], f.positions[3 * p + 2]], c)) continue;
        out.set(p, wi);
        sum += wi;
      }
      if (!(sum > 0)) return null;
      for (const [p, wi] of out) out.set(p, wi / sum);
      return out;
    }
    if (this.kind === 'tetrahedra') return this.tetraWeights(c, visible);
    if (this.kind !== 'grid') return null;
    /* docs/grid-field.md "Per object": the movable rule (no normal: no back faces), no masks, each corner
     * judged by the segment from its cell's centre to c; none left: step 5, the weights without that test. */
    const dims = f.gridDims, h = f.gridSpacing, a = f.gridAxes, u = [0, 0, 0];
    const d = [0, 1, 2].map((k) => c[k] - f.gridOrigin[k]);
    for (let k = 0; k < 3; k++) {
      u[k] = (d[0] * a[k][0] + d[1] * a[k][1] + d[2] * a[k][2]) / h;
      if (u[k] < -0.01 || u[k] > dims[k] + 0.01) return null;
    }
    const clampi = (v, k) => Math.min(Math.max(v, 0), dims[k] - 1);
    const i0 = u.map((v) => Math.floor(v - 0.5)), fr = u.map((v, k) => v - 0.5 - i0[k]);
    const cell = (ci) => f.grid[ci[0] + dims[0] * (ci[1] + dims[1] * ci[2])];
    const out = new Map(), corners = [];
    let sum = 0;
    for (let k = 0; k < 8; k++) {
      const ci = [0, 1, 2].map((ax) => clampi(i0[ax] + ((k >> ax) & 1), ax));
      const p = cell(ci);
      if (p < 0) continue;
      let w = Math.max(f.validity[p], 0);
      for (let ax = 0; ax < 3; ax++) w *= (k >> ax) & 1 ? fr[ax] : 1 - fr[ax];
      if (!(w > 0)) continue;
      corners.push([ci, p, w]);
      if (!visible(this._cellCentre(ci), c)) continue;
      mergeAdd(out, p, w);
      sum += w;
    }
    if (!(sum > 1e-6)) {
      /* step 5 (every weighted corner hidden): the field's weights without the segment test */
      out.clear();
      sum = 0;
      for (const [, p, w] of corners) {
        mergeAdd(out, p, w);
        sum += w;
      }
      if (!(sum > 1e-6)) return null;
    }
    for (const [p, w] of out) out.set(p, w / sum);
    return out;
  }

  /** Σ w s c over a weight map: SH (count × 3) of the blend. */
  blend(weights) {
    const f = this.file, n = this.count, sh = new Float64Array(3 * n);
    for (const [p, w] of weights) {
      const ws = w * f.probeScale[p];
      for (let i = 0; i < 3 * n; i++) sh[i] += ws * f.coeffs[3 * n * p + i];
    }
    return sh;
  }

  /**
   * The engine's anti-leak data of a tree (pb_bricks.c leaf_tables / build_records, sv_bricks_vis.c):
   * `seg(a, b)` is the static scene's segment function. Sets `pairVis` (the leaves' 64-B pair tables,
   * for the visibility texels), `records` (Uint8Array, 64 B per blocked brick cell) and `cellRecord`
   * (Int32Array per min cell: the record of the brick cell whose min corner is this cell, else -1).
   */
  buildVisibility(seg) {
    if (this.kind !== 'octree' && this.kind !== 'kdtree') return;
    const f = this.file, N = f.elementCount, [X, Y, Z] = f.gridDims, h = f.gridSpacing, o = f.gridOrigin;
    const pv = new Uint8Array(64 * N), blockedLeaf = new Uint8Array(N);
    let segments = 0;
    const counted = (a, b) => { segments++; return seg(a, b); };
    for (let i = 0; i < N; i++) {
      const lo = [f.leaves[4 * i], f.leaves[4 * i + 1], f.leaves[4 * i + 2]];
      blockedLeaf[i] = traceBox(o, h, lo, this.levels.subarray(3 * i, 3 * i + 3), counted, pv, 64 * i) ? 1 : 0;
    }
    const lv = this.brickLevels();
    this._levels = lv;
    const cellRecord = new Int32Array(X * Y * Z).fill(-1), recs = [];
    const rec = new Uint8Array(64);
    let traced = 0;
    for (let z = 0; z < Z; z++)
      for (let y = 0; y < Y; y++)
        for (let x = 0; x < X; x++) {
          const c = x + X * (y + Y * z), L = lv[c];
          if (L < 0) continue;
          const li = this.cellLeaf[c], s = 1 << L, m = s - 1;
          /* a brick cell's min corner: aligned to 2^L inside its region (regions are 4 * 2^L aligned) */
          if ((x & m) || (y & m) || (z & m) || !blockedLeaf[li]) continue;
          traced++;
          if (!traceBox(o, h, [x, y, z], [L, L, L], counted, rec, 0)) continue;
          cellRecord[c] = recs.length;
          recs.push(rec.slice());
        }
    this.pairVis = pv;
    this.blockedLeaf = blockedLeaf;
    this.cellRecord = cellRecord;
    this.records = new Uint8Array(64 * recs.length);
    recs.forEach((r, i) => this.records.set(r, 64 * i));
    this.visInfo = { blockedLeaves: blockedLeaf.reduce((a, b) => a + b, 0), tracedCells: traced, records: recs.length, segments };
  }

  /* texel_value's leaf of lattice point X (pb_bricks.c: the first of the 8 unit cells X - bits(m) inside
   * the lattice that a leaf holds), its weights with the leaf's pair table where there is one
   * (pb_interp.c leaf_weights with pair_visibility: the ramped weights, else the plain ones), each list
   * finished as finish_weights (zero weights dropped, renormalised). Map probe -> W, or null. */
  _texelWeights(X) {
    const f = this.file, [DX, DY, DZ] = f.gridDims, dims = f.gridDims;
    let li = -1;
    for (let m = 0; m < 8 && li < 0; m++) {
      const q = [0, 1, 2].map((a) => X[a] - ((m >> a) & 1));
      if (q.some((v, a) => v < 0 || v >= dims[a])) continue;
      li = this.cellLeaf[q[0] + DX * (q[1] + DY * q[2])];
    }
    if (li < 0) return null;
    void DZ;
    const t = [0, 1, 2].map((k) => {
      const v = (X[k] - f.leaves[4 * li + k]) / 2 ** this.levels[3 * li + k];
      return v < 0 ? 0 : v > 1 ? 1 : v;
    });
    const w8 = trilinear8(t), P = f.probeCount;
    const expand = (w) => {
      const out = new Map();
      for (let c = 0; c < 8; c++) {
        if (!(w[c] > 0)) continue;
        const node = f.leafCorners[8 * li + c];
        if (node < P) mergeAdd(out, node, w[c]);
        else for (const [pp, we] of this.expansion[node - P]) mergeAdd(out, pp, w[c] * we);
      }
      let sum = 0;
      for (const [p, wi] of out) if (wi > 0) sum += wi; else out.delete(p);
      if (!(sum > 0)) return null;
      for (const [p, wi] of out) out.set(p, wi / sum);
      return out;
    };
    if (this.pairVis) {
      const wv = new Float64Array(8);
      for (let c = 0; c < 8; c++) {
        let v = 0;
        for (let k = 0; k < 8; k++) v += w8[k] * pairValue(this.pairVis[64 * li + 8 * k + c]);
        wv[c] = w8[c] > 0 ? w8[c] * visRamp(v) : 0;
      }
      const r = expand(wv);
      if (r) return r;
    }
    return expand(w8);
  }

  /**
   * The per-pixel texture's texels, N (count RGB) and D per texel, in the channel packing of
   * docs/grid-field.md (0-2 N0, 3 D, then N1..: `groups` RGBA texels). Dense grids: a texel per cell at
   * its centre, N = v s c, D = v. Trees: a texel per lattice point (level 0 bricks, docs/probe-bricks.md
   * "Texels": N = Σ W m s c, D = Σ W m, without the visibility texels).
   */
  texels() {
    const f = this.file, n = this.count, groups = Math.ceil((3 * n + 1) / 4);
    const dense = this.kind === 'grid';
    const dims = dense ? f.gridDims.slice() : f.gridDims.map((v) => v + 1);
    const total = dims[0] * dims[1] * dims[2];
    const slabs = groups;
    const data = new Float32Array(total * slabs * 4);
    const put = (t, ch, v) => { data[4 * (t + total * (ch >> 2)) + (ch & 3)] = v; };
    const write = (t, weights) => {
      let D = 0;
      const N = new Float64Array(3 * n);
      for (const [p, w0] of weights) {
        const m = dense ? Math.max(f.validity[p], 0) * w0 : f.validity[p] > 0 ? w0 : 0;
        if (!(m > 0)) continue;
        D += m;
        for (let i = 0; i < 3 * n; i++) N[i] += m * f.probeScale[p] * f.coeffs[3 * n * p + i];
      }
      put(t, 0, N[0]); put(t, 1, N[1]); put(t, 2, N[2]); put(t, 3, D);
      for (let i = 3; i < 3 * n; i++) put(t, i + 1, N[i]);
    };
    for (let z = 0; z < dims[2]; z++)
      for (let y = 0; y < dims[1]; y++)
        for (let x = 0; x < dims[0]; x++) {
          const t = x + dims[0] * (y + dims[1] * z);
          if (dense) {
            const p = f.grid[t];
            if (p >= 0) write(t, new Map([[p, 1]]));
          } else {
            const w = this._texelWeights([x, y, z]);
            if (w) write(t, w);
          }
        }
    return { dims, groups, slabs, data };
  }
}

/* ---- the static scene's segment test ----------------------------------------------------------------- */

/** World-space triangles of the scene's meshes, tagged by object, for sv_probe_visible's segment test. */
class StaticScene {
  constructor(objects) {
    let n = 0;
    for (const o of objects) for (const m of o.meshes) n += triCount(m.geometry);
    this.tris = new Float32Array(9 * n);
    this.owner = new Int32Array(n);
    let t = 0;
    const v = new THREE.Vector3();
    objects.forEach((o, oi) => {
      for (const m of o.meshes) {
        m.updateWorldMatrix(true, false);
        const pos = m.geometry.attributes.position, idx = m.geometry.index, cnt = triCount(m.geometry);
        for (let i = 0; i < cnt; i++) {
          for (let k = 0; k < 3; k++) {
            const vi = idx ? idx.getX(3 * i + k) : 3 * i + k;
            v.fromBufferAttribute(pos, vi).applyMatrix4(m.matrixWorld);
            this.tris[9 * t + 3 * k] = v.x; this.tris[9 * t + 3 * k + 1] = v.y; this.tris[9 * t + 3 * k + 2] = v.z;
          }
          this.owner[t++] = oi;
        }
      }
    });
  }

  /** The triangles of the objects not moved (9 numbers each): the engine's static occluder. */
  staticTriangles(movable) {
    const out = [];
    for (let t = 0; t < this.owner.length; t++)
      if (!movable[this.owner[t]]) for (let k = 0; k < 9; k++) out.push(this.tris[9 * t + k]);
    return out;
  }

  /** Whether the segment a -> b (ends left out by 1e-4 of its length) misses every triangle of every
   * static object but `self` (both sides count, as the engine's occluder). */
  clear(a, b, self, movable) {
    const T = this.tris, dx = b[0] - a[0], dy = b[1] - a[1], dz = b[2] - a[2];
    for (let t = 0; t < this.owner.length; t++) {
      const o = this.owner[t];
      if (o === self || movable[o]) continue;
      const i = 9 * t;
      const e1x = T[i + 3] - T[i], e1y = T[i + 4] - T[i + 1], e1z = T[i + 5] - T[i + 2];
      const e2x = T[i + 6] - T[i], e2y = T[i + 7] - T[i + 1], e2z = T[i + 8] - T[i + 2];
      const px = dy * e2z - dz * e2y, py = dz * e2x - dx * e2z, pz = dx * e2y - dy * e2x;
      const det = e1x * px + e1y * py + e1z * pz;
      if (Math.abs(det) < 1e-12) continue;
      const inv = 1 / det, sx = a[0] - T[i], sy = a[1] - T[i + 1], sz = a[2] - T[i + 2];
      const uu = (sx * px + sy * py + sz * pz) * inv;
      if (uu < 0 || uu > 1) continue;
      const qx = sy * e1z - sz * e1y, qy = sz * e1x - sx * e1z, qz = sx * e1y - sy * e1x;
      const vv = (dx * qx + dy * qy + dz * qz) * inv;
      if (vv < 0 || uu + vv > 1) continue;
      const tt = (e2x * qx + e2y * qy + e2z * qz) * inv;
      if (tt >= 1e-4 && tt <= 1 - 1e-4) return false;
    }
    return true;
  }
}

/** An RGBA 3D texture of `data` (W × H × D texels), clamped at its edges, filtered by `filter`. */
function rgbaTexture3D(data, W, H, D, type, filter) {
  const tex = new THREE.Data3DTexture(data, W, H, D);
  tex.format = THREE.RGBAFormat;
  tex.type = type;
  tex.minFilter = tex.magFilter = filter;
  tex.wrapS = tex.wrapT = tex.wrapR = THREE.ClampToEdgeWrapping;
  tex.unpackAlignment = 1;
  tex.needsUpdate = true;
  return tex;
}

function triCount(g) {
  return g.index ? g.index.count / 3 : g.attributes.position.count / 3;
}

/* ---- the scene's probes --------------------------------------------------------------------------------- */

/**
 * What the plugin attaches to `gltf.userData.schneeProbes`: the grids, the objects (one per glTF node
 * with a mesh, as schnee-view's objects), their per-object SH and the shading uniforms.
 */
export class SchneeProbes {
  constructor({ grids, fallback, objects, mode, visibility }) {
    this.visibility = visibility;
    this.grids = grids;
    this.fallback = fallback; /* Float64Array, count × 3 */
    this.objects = objects;
    this.mode = mode || 'material';
    this.texture = null;
    this.gridUniforms = null;
    this.movable = new Uint8Array(objects.length);
    this.statics = new StaticScene(objects);
    this.assignAll();
  }

  /** Per-object query of every object (sv_probes_assign). */
  assignAll() {
    this.objects.forEach((o, i) => this.assign(i));
  }

  assign(i) {
    const o = this.objects[i];
    o.box = new THREE.Box3();
    for (const m of o.meshes) {
      m.updateWorldMatrix(true, false);
      if (!m.geometry.boundingBox) m.geometry.computeBoundingBox();
      o.box.union(m.geometry.boundingBox.clone().applyMatrix4(m.matrixWorld));
    }
    o.sh = this.fallback;
    o.count = this.fallback.length / 3;
    o.weights = null;
    o.grid = -1;
    if (o.box.isEmpty()) return;
    const c3 = o.box.getCenter(new THREE.Vector3());
    const c = [c3.x, c3.y, c3.z];
    const visible = (from, to) => this.statics.clear(from, to, i, this.movable);
    for (const g of this.grids) {
      const w = g.objectWeights(c, visible);
      if (!w || w.size === 0) continue;
      o.sh = g.blend(w);
      o.count = g.count;
      o.weights = w;
      o.grid = g.index;
      break;
    }
    o.centre = c;
    this._writeUniforms(o);
  }

  /** Marks object i movable (it left the static scene) and re-queries every object. */
  moved(i) {
    this.movable[i] = 1;
    this.assignAll();
  }

  /** 'material' (each material's / node's probeMode), 'off', 'object' or 'pixel'. */
  setMode(mode) {
    if (mode !== 'material' && !MODES.includes(mode)) throw new Error(`unknown probe mode '${mode}'`);
    this.mode = mode;
    for (const o of this.objects) this._writeUniforms(o);
  }

  _writeUniforms(o) {
    for (const m of o.meshes) {
      const u = m.userData.schneeUniforms;
      if (!u) continue;
      let mode = this.mode === 'material' ? m.userData.schneeMode : this.mode;
      /* tetrahedra per pixel fall back to per object (the engine keeps them in storage buffers) */
      if (mode === 'pixel' && o.grid >= 0 && this.grids.some((g) => g.index === o.grid && g.kind === 'tetrahedra')) mode = 'object';
      const modeIndex = MODES.indexOf(mode);
      const sh = mode === 'object' ? o.sh : this.fallback;
      const count = Math.min(sh.length / 3, MAX_COEFFS);
      for (let i = 0; i < MAX_COEFFS; i++)
        u.schneeSH.value[i].set(i < count ? sh[3 * i] : 0, i < count ? sh[3 * i + 1] : 0, i < count ? sh[3 * i + 2] : 0);
      u.schneeCount.value = count;
      u.schneeMode.value = modeIndex;
      u.schneeStatic.value = this.movable[this.objects.indexOf(o)] ? 0 : 1;
    }
  }

  /** The per-pixel atlas: every dense SH grid and tree, their channel groups as z slabs of one 3D texture. */
  buildTexture(useFloat) {
    const parts = [];
    let seg = null;
    const tv = performance.now();
    for (const g of this.grids) {
      if (g.isCube || !(g.kind === 'grid' || g.kind === 'octree' || g.kind === 'kdtree')) continue;
      if (parts.length >= 4) break;
      if (this.visibility !== false) {
        /* the engine's static scene at load (sv_static_occluder: every object not moved) */
        if (!seg) {
          const grid = new SegmentGrid(this.statics.staticTriangles(this.movable));
          seg = (a, b) => grid.firstHit(a, b);
          this.visTriangles = grid.count;
        }
        if (this.visTriangles) { if (g.kind === 'grid') g.buildMasks(seg); else g.buildVisibility(seg); }
      }
      parts.push({ g, ...g.texels() });
    }
    this.visMs = performance.now() - tv;
    const W = Math.max(1, ...parts.map((p) => p.dims[0])), H = Math.max(1, ...parts.map((p) => p.dims[1]));
    let Dz = 0;
    for (const p of parts) { p.zBase = Dz; Dz += p.slabs * p.dims[2]; }
    Dz = Math.max(Dz, 1);
    const data = new Float32Array(W * H * Dz * 4);
    for (const p of parts) {
      const [X, Y, Z] = p.dims;
      for (let s = 0; s < p.slabs * Z; s++)
        for (let y = 0; y < Y; y++)
          for (let x = 0; x < X; x++) {
            const src = 4 * (x + X * (y + Y * s)), dst = 4 * (x + W * (y + H * (p.zBase + s)));
            for (let c = 0; c < 4; c++) data[dst + c] = p.data[src + c];
          }
    }
    if (useFloat) {
      this.texture = rgbaTexture3D(data, W, H, Dz, THREE.FloatType, THREE.LinearFilter);
    } else {
      const half = new Uint16Array(data.length);
      for (let i = 0; i < data.length; i++) half[i] = THREE.DataUtils.toHalfFloat(data[i]);
      this.texture = rgbaTexture3D(half, W, H, Dz, THREE.HalfFloatType, THREE.LinearFilter);
    }
    /* The trees' brick levels per min cell, their own atlas (nearest, R32F), z slabs as above. */
    const trees = parts; /* dense grids too: their masks and occupancy (below) */
    const LW = Math.max(1, ...trees.map((p) => p.g.file.gridDims[0])), LH = Math.max(1, ...trees.map((p) => p.g.file.gridDims[1]));
    let LD = 0;
    for (const p of trees) { p.levelBase = LD; LD += p.g.file.gridDims[2]; }
    /* R: the level; G: the visibility record of the brick cell whose min corner is this min cell (index
     * into the record texture, the grid's records after the earlier grids'), -1 = none (not blocked). */
    const lvData = new Float32Array(4 * LW * LH * Math.max(LD, 1)).fill(-1);
    const allRecs = [];
    let recBase = 0;
    for (const p of trees) {
      const [X, Y, Z] = p.g.file.gridDims;
      if (p.g.kind === 'grid') { /* R, G: the 27-bit neighbour mask (low 16, high 11 bits), B: the cell holds a probe */
        const M = p.g.masks, G = p.g.file.grid;
        for (let c = 0, z = 0; z < Z; z++)
          for (let y = 0; y < Y; y++)
            for (let x = 0; x < X; x++, c++) {
              const o = 4 * (x + LW * (y + LH * (p.levelBase + z))), m = M ? M[c] : 0x7ffffff;
              lvData[o] = m & 0xffff; lvData[o + 1] = m >>> 16; lvData[o + 2] = G[c] >= 0 ? 1 : 0;
            }
        continue;
      }
      const lv = p.g._levels || p.g.brickLevels(), cr = p.g.cellRecord;
      for (let z = 0; z < Z; z++)
        for (let y = 0; y < Y; y++)
          for (let x = 0; x < X; x++) {
            const c = x + X * (y + Y * z), o = 4 * (x + LW * (y + LH * (p.levelBase + z)));
            lvData[o] = lv[c];
            if (cr && cr[c] >= 0) lvData[o + 1] = recBase + cr[c];
          }
      if (p.g.records) { allRecs.push(p.g.records); recBase += p.g.records.length / 64; }
    }
    /* The records: 64 bytes = 16 RGBA texels (one byte a channel, as floats), 64 records a row. */
    const RW = 16 * 64, RH = Math.max(1, Math.ceil(recBase / 64));
    const recData = new Float32Array(4 * RW * RH);
    let ri = 0;
    for (const R of allRecs)
      for (let r = 0; r < R.length / 64; r++, ri++) {
        const base = 4 * (16 * (ri % 64) + RW * Math.floor(ri / 64));
        for (let j = 0; j < 64; j++) recData[base + j] = R[64 * r + j];
      }
    const recTex = new THREE.DataTexture(recData, RW, RH, THREE.RGBAFormat, THREE.FloatType);
    recTex.minFilter = recTex.magFilter = THREE.NearestFilter;
    recTex.needsUpdate = true;
    this.recordTexture = recTex;
    this.visRecords = recBase;
    this.levelTexture = rgbaTexture3D(lvData, LW, LH, Math.max(LD, 1), THREE.FloatType, THREE.NearestFilter);
    const A = [], B = [], C = [], axes = [];
    for (let i = 0; i < 4; i++) {
      const p = parts[i];
      if (!p) {
        A.push(new THREE.Vector4()); B.push(new THREE.Vector4()); C.push(new THREE.Vector4());
        axes.push(new THREE.Vector3(1, 0, 0), new THREE.Vector3(0, 1, 0), new THREE.Vector3(0, 0, 1));
        continue;
      }
      const f = p.g.file;
      A.push(new THREE.Vector4(...f.gridOrigin, f.gridSpacing));
      B.push(new THREE.Vector4(...f.gridDims, p.g.kind === 'grid' ? 0 : 1));
      C.push(new THREE.Vector4(p.zBase, p.g.count, p.groups, p.levelBase || 0));
      for (const r of f.gridAxes) axes.push(new THREE.Vector3(...r));
    }
    this.gridUniforms = {
      schneeTex: { value: this.texture }, schneeLevelTex: { value: this.levelTexture }, schneeVisRec: { value: recTex }, schneeGridCount: { value: parts.length }, schneeGridA: { value: A },
      schneeGridB: { value: B }, schneeGridC: { value: C }, schneeGridAxes: { value: axes },
      schneeTexSize: { value: new THREE.Vector3(W, H, Dz) },
    };
    return this.texture;
  }

  /** The probe view: a small sphere per probe shaded with max(E(n), 0)/π of its own SH (× scale). */
  probeView({ radius = 0.08 } = {}) {
    const group = new THREE.Group();
    group.name = 'SchneeProbeView';
    for (const g of this.grids) {
      const f = g.file;
      if (!f.positions && g.kind !== 'grid') continue;
      const pos = [];
      if (f.positions) for (let p = 0; p < f.probeCount; p++) pos.push([p, f.positions.subarray(3 * p, 3 * p + 3)]);
      else {
        const [X, Y] = f.gridDims;
        f.grid.forEach((p, t) => { if (p >= 0) pos.push([p, g._cellCentre([t % X, Math.floor(t / X) % Y, Math.floor(t / (X * Y))])]); });
      }
      const n = Math.min(g.count, 9);
      const geo = new THREE.SphereGeometry(radius, 16, 8);
      const ib = new THREE.InstancedMesh(geo, null, pos.length);
      const attrs = [];
      for (let k = 0; k < 7; k++) attrs.push(new Float32Array(4 * pos.length));
      const m = new THREE.Matrix4();
      pos.forEach(([p, at], j) => {
        ib.setMatrixAt(j, m.makeTranslation(at[0], at[1], at[2]));
        for (let i = 0; i < n; i++)
          for (let c = 0; c < 3; c++) {
            const ch = 3 * i + c;
            attrs[ch >> 2][4 * j + (ch & 3)] = f.coeffs[3 * g.count * p + ch] * f.probeScale[p];
          }
      });
      attrs.forEach((a, k) => geo.setAttribute(`sh${k}`, new THREE.InstancedBufferAttribute(a, 4)));
      ib.material = new THREE.ShaderMaterial({
        vertexShader: /* glsl */ `
          attribute vec4 sh0, sh1, sh2, sh3, sh4, sh5, sh6;
          varying vec3 vN; varying vec4 s0, s1, s2, s3, s4, s5, s6;
          void main() {
            vN = normal; s0 = sh0; s1 = sh1; s2 = sh2; s3 = sh3; s4 = sh4; s5 = sh5; s6 = sh6;
            gl_Position = projectionMatrix * viewMatrix * modelMatrix * instanceMatrix * vec4(position, 1.0);
          }`,
        fragmentShader: /* glsl */ `
          varying vec3 vN; varying vec4 s0, s1, s2, s3, s4, s5, s6;
          void main() {
            vec3 n = normalize(vN);
            float c[28] = float[28](s0.x, s0.y, s0.z, s0.w, s1.x, s1.y, s1.z, s1.w, s2.x, s2.y, s2.z, s2.w,
              s3.x, s3.y, s3.z, s3.w, s4.x, s4.y, s4.z, s4.w, s5.x, s5.y, s5.z, s5.w, s6.x, s6.y, s6.z, s6.w);
            float x = n.x, y = n.y, z = n.z, PI_ = 3.14159265358979;
            float ay[9] = float[9](PI_ * 0.282094792, 2.0 * PI_ / 3.0 * 0.488602512 * y, 2.0 * PI_ / 3.0 * 0.488602512 * z,
              2.0 * PI_ / 3.0 * 0.488602512 * x, PI_ / 4.0 * 1.092548431 * x * y, PI_ / 4.0 * 1.092548431 * y * z,
              PI_ / 4.0 * 0.315391565 * (3.0 * z * z - 1.0), PI_ / 4.0 * 1.092548431 * x * z, PI_ / 4.0 * 0.546274215 * (x * x - y * y));
            vec3 e = vec3(0.0);
            for (int i = 0; i < 9; i++) e += ay[i] * vec3(c[3 * i], c[3 * i + 1], c[3 * i + 2]);
            gl_FragColor = vec4(max(e, 0.0) / PI_, 1.0);
            #include <tonemapping_fragment>
            #include <colorspace_fragment>
          }`,
      });
      ib.name = `probes ${g.name}`;
      group.add(ib);
    }
    return group;
  }
}

/* ---- material injection ------------------------------------------------------------------------------- */

function injectMaterial(material, uniforms, cacheKey) {
  material.onBeforeCompile = (shader) => {
    Object.assign(shader.uniforms, uniforms);
    shader.vertexShader = shader.vertexShader
      .replace('#include <common>', '#include <common>\nvarying vec3 vSchneeWorldPos;')
      .replace('#include <project_vertex>',
        '#include <project_vertex>\n\tvSchneeWorldPos = (modelMatrix * vec4(transformed, 1.0)).xyz;');
    shader.fragmentShader = shader.fragmentShader
      .replace('#include <common>', `#include <common>\n${SCHNEE_GLSL_COMMON}`)
      /* three's own indirect diffuse (ambient / hemisphere / light probes) is replaced, not added to; its
       * energy-conserving split would also scale our term, so the probe term is added afterwards. */
      .replace('#include <lights_fragment_end>', `irradiance = vec3(0.0);
#include <lights_fragment_end>
{
  vec3 schneeN = normalize((vec4(normal, 0.0) * viewMatrix).xyz);
  vec3 schneeE = schneeIrradiance(vSchneeWorldPos, schneeN);
  reflectedLight.indirectDiffuse += diffuseColor.rgb * (schneeShScale * max(schneeE, vec3(0.0)) / PI + schneeAmbient);
}`);
  };
  material.customProgramCacheKey = () => `schnee-probes-${cacheKey}`;
  material.needsUpdate = true;
}

/* ---- the GLTFLoader plugin ------------------------------------------------------------------------------ */

const EXT_SCENE = 'VULKAN_SCHNEE_engine_properties';
const EXT_MATERIAL = 'VULKAN_SCHNEE_materials';
const EXT_NODE = 'VULKAN_SCHNEE_node';
const EXT_LIGHT = 'VULKAN_SCHNEE_light';

/**
 * GLTFLoader plugin. Options: `mode` ('material' default, 'off', 'object', 'pixel'), `sky` (false:
 * probe 0 is the constant 0.2 radiance even when the glTF has a sky, as schnee-view --no-sky),
 * `direct` (false: KHR_lights_punctual lights removed, as --no-direct; true: kept, intensity ×
 * VULKAN_SCHNEE_light.intensityScale, baked lights removed), `floatTexture` (true: RGBA32F 3D texture
 * when the context filters it, else RGBA16F), `renderer` (for that check), `onLoad(probes, timing)`.
 */
export class SchneeProbesPlugin {
  constructor(parser, opts = {}) {
    this.parser = parser;
    this.name = EXT_SCENE;
    this.opts = opts;
  }

  async _loadGrids(ext) {
    const grids = [];
    const entries = Array.isArray(ext.shProbeGrids) ? ext.shProbeGrids : [];
    const loader = new THREE.FileLoader(this.parser.options.manager);
    loader.setResponseType('arraybuffer');
    loader.setRequestHeader(this.parser.options.requestHeader || {});
    const path = this.parser.options.path || '';
    const bufs = await Promise.all(entries.map((e) => {
      if (typeof e.uri !== 'string') throw new Error(`${EXT_SCENE}.shProbeGrids entry without a uri`);
      return loader.loadAsync(THREE.LoaderUtils.resolveURL(e.uri, path));
    }));
    entries.forEach((e, i) => {
      const file = parseShprobe(bufs[i], { name: e.uri });
      for (const [key, val] of [['probeCount', file.probeCount], ['maxBand', file.maxBand]])
        if (e[key] !== undefined && e[key] !== val)
          console.warn(`Schnee: shProbeGrids[${i}] '${e.name}': ${key} ${e[key]} in the glTF, ${val} in ${e.uri}; using the file`);
      if (file.structure === 'tetrahedra')
        console.warn(`Schnee: shProbeGrids[${i}] '${e.name}': tetrahedra are lit per object only; per pixel falls back to per object there`);
      grids.push(new ProbeGrid(file, e, i));
    });
    return grids;
  }

  async afterRoot(gltf) {
    const t0 = performance.now();
    const json = this.parser.json;
    const sceneIndex = json.scene || 0;
    const ext = (json.scenes && json.scenes[sceneIndex] && json.scenes[sceneIndex].extensions || {})[EXT_SCENE] || {};
    const grids = await this._loadGrids(ext);
    const tLoad = performance.now() - t0;

    let fallback;
    const sky = ext.sky;
    if (this.opts.sky !== false && sky && Array.isArray(sky.sh) && sky.sh.length) {
      fallback = new Float64Array(sky.sh.flat().slice(0, 3 * MAX_COEFFS));
    } else {
      const l00 = FALLBACK_RADIANCE * Y0 * 4 * PI;
      fallback = new Float64Array([l00, l00, l00]);
    }

    /* Objects: glTF nodes with a mesh, their three meshes (one per primitive). */
    const assoc = this.parser.associations;
    const objects = [];
    const root = gltf.scene;
    root.updateMatrixWorld(true);
    root.traverse((obj) => {
      const a = assoc.get(obj);
      if (!a || a.nodes === undefined) return;
      const node = json.nodes[a.nodes];
      if (node.mesh === undefined) return;
      const meshes = [];
      if (obj.isMesh) meshes.push(obj);
      else for (const ch of obj.children) if (ch.isMesh && !(assoc.get(ch) && assoc.get(ch).nodes !== undefined)) meshes.push(ch);
      objects.push({ name: node.name || `node ${a.nodes}`, node: a.nodes, object: obj, meshes });
    });

    /* Per-primitive probe mode: node > material > 'object' (docs/export.md "Node"). */
    for (const o of objects) {
      const nodeExt = (json.nodes[o.node].extensions || {})[EXT_NODE];
      let nodeMode;
      if (nodeExt !== undefined) {
        if (nodeExt && typeof nodeExt === 'object' && MODES.includes(nodeExt.probeMode)) nodeMode = nodeExt.probeMode;
        else if (nodeExt && typeof nodeExt === 'object' && nodeExt.probeMode !== undefined)
          console.warn(`Schnee: node '${o.name}': unknown ${EXT_NODE}.probeMode ${JSON.stringify(nodeExt.probeMode)}; following its materials`);
        else if (!nodeExt || typeof nodeExt !== 'object') console.warn(`Schnee: node '${o.name}': ${EXT_NODE} is not an object; ignored`);
      }
      for (const m of o.meshes) {
        if (!m.material || !m.material.isMeshStandardMaterial) continue;
        const ma = assoc.get(m.material);
        const mj = ma && ma.materials !== undefined ? json.materials[ma.materials] : null;
        const me = (mj && mj.extensions || {})[EXT_MATERIAL] || {};
        let mode = me.probeMode === undefined ? 'object' : me.probeMode;
        if (!MODES.includes(mode)) throw new Error(`material '${mj.name}': unknown ${EXT_MATERIAL}.probeMode ${JSON.stringify(mode)}`);
        if (nodeMode) mode = nodeMode;
        const shScale = typeof me.shScale === 'number' ? me.shScale : 1.0;
        const ambient = typeof me.ambientTerm === 'number' ? me.ambientTerm : 0.1;
        m.material = m.material.clone(); /* one per mesh: the per-object SH are its own uniforms */
        m.userData.schneeMode = mode;
        m.userData.schneeUniforms = {
          schneeSH: { value: Array.from({ length: MAX_COEFFS }, () => new THREE.Vector3()) },
          schneeCount: { value: 1 }, schneeMode: { value: 1 }, schneeStatic: { value: 1 },
          schneeShScale: { value: shScale }, schneeAmbient: { value: ambient },
        };
      }
    }

    const probes = new SchneeProbes({ grids, fallback, objects, mode: this.opts.mode });
    const r = this.opts.renderer;
    const canFloat = !!(r && r.extensions && r.extensions.has('OES_texture_float_linear'));
    probes.buildTexture(this.opts.floatTexture !== false && canFloat);
    for (const o of objects)
      for (const m of o.meshes)
        if (m.userData.schneeUniforms) {
          Object.assign(m.userData.schneeUniforms, probes.gridUniforms);
          injectMaterial(m.material, m.userData.schneeUniforms, 'v2');
        }
    probes.setMode(probes.mode);

    /* Lights: engine units (intensity × intensityScale); baked ones are in the probes. */
    const lights = [];
    root.traverse((obj) => { if (obj.isLight) lights.push(obj); });
    const lightDefs = ((json.extensions || {}).KHR_lights_punctual || {}).lights || [];
    for (const l of lights) {
      const a = assoc.get(l) || (l.parent && assoc.get(l.parent));
      const def = a && a.nodes !== undefined && json.nodes[a.nodes].extensions && json.nodes[a.nodes].extensions.KHR_lights_punctual
        ? lightDefs[json.nodes[a.nodes].extensions.KHR_lights_punctual.light] : null;
      const le = def && def.extensions && def.extensions[EXT_LIGHT];
      if (this.opts.direct === false || (le && le.mode === 'baked')) { l.parent.remove(l); continue; }
      if (le && typeof le.intensityScale === 'number') l.intensity *= le.intensityScale;
    }

    probes.timing = { loadMs: tLoad, totalMs: performance.now() - t0, visMs: probes.visMs, visRecords: probes.visRecords,
      visTriangles: probes.visTriangles || 0 };
    gltf.userData.schneeProbes = probes;
    if (this.opts.onLoad) this.opts.onLoad(probes);
  }
}
