/* The anti-leak data of the engine's bricks (docs/probe-bricks.md "Back faces and visibility", step 5),
 * built in the browser from the static scene's triangles, as schnee-view builds it at load
 * (engine/src/sv_bricks_vis.c with the static scene's tracer):
 * - SegmentGrid.firstHit(a, b): sv_segment_first_hit / the C tests' triangle segment function
 *   (native/python/mod_bricks.c planes_segment): the first crossing of a -> b with any triangle (both
 *   sides, Möller–Trumbore in double) as a fraction of its length in [1e-4, 1 − 1e-4], else 1; a uniform
 *   grid of triangle bounds accelerates it;
 * - traceBox: pb_vis_trace_box (native/src/pb_cotree.c): the 8 × 8 pair table of a lattice box, segments
 *   on its edges / faces traced moved by ±PB_VIS_SHIFT min cells across the axes their ends share;
 * - pairValue / visRamp: pb_vis_pair_value, smoothstep(1/2, 1/2 + PB_VIS_RAMP, v).
 */

export const VIS_RAMP = 0.25;
export const VIS_SHIFT = 1e-3;
export const VIS_CLEAR = 255;

/** V(k, c) of a stored byte (pb_vis_pair_value). */
export const pairValue = (q) => (q >= VIS_CLEAR ? 1 : 1 - 127.5 / (q ? q : 1));

/** smoothstep(1/2, 1/2 + VIS_RAMP, v) (pb_interp.c vis_ramp). */
export function visRamp(v) {
  let x = (v - 0.5) / VIS_RAMP;
  x = x < 0 ? 0 : x > 1 ? 1 : x;
  return x * x * (3 - 2 * x);
}

/** Triangles (9 numbers each, world space) in a uniform grid of their bounds. */
export class SegmentGrid {
  constructor(tris) {
    const T = (this.tris = Float64Array.from(tris));
    const n = (this.count = T.length / 9);
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < 3 * n; i++)
      for (let a = 0; a < 3; a++) {
        const v = T[3 * i + a];
        if (v < lo[a]) lo[a] = v;
        if (v > hi[a]) hi[a] = v;
      }
    if (!n) { this.dims = [1, 1, 1]; this.lo = [0, 0, 0]; this.cell = 1; this.start = new Uint32Array(2); this.items = new Uint32Array(0); this.stamp = new Uint32Array(0); return; }
    const ext = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-6);
    const cell = (this.cell = ext / 48);
    this.lo = lo.map((v) => v - 1e-6 * ext);
    this.dims = [0, 1, 2].map((a) => Math.max(1, Math.ceil((hi[a] + 1e-6 * ext - this.lo[a]) / cell)));
    const [X, Y, Z] = this.dims, cells = X * Y * Z;
    const counts = new Uint32Array(cells + 1);
    const range = (i, fn) => {
      const b0 = [0, 0, 0], b1 = [0, 0, 0];
      for (let a = 0; a < 3; a++) {
        const v0 = T[9 * i + a], v1 = T[9 * i + 3 + a], v2 = T[9 * i + 6 + a];
        b0[a] = this._ci(Math.min(v0, v1, v2), a);
        b1[a] = this._ci(Math.max(v0, v1, v2), a);
      }
      for (let z = b0[2]; z <= b1[2]; z++)
        for (let y = b0[1]; y <= b1[1]; y++)
          for (let x = b0[0]; x <= b1[0]; x++) fn(x + X * (y + Y * z));
    };
    for (let i = 0; i < n; i++) range(i, (c) => counts[c + 1]++);
    for (let c = 0; c < cells; c++) counts[c + 1] += counts[c];
    this.start = counts.slice();
    this.items = new Uint32Array(counts[cells]);
    const fill = counts.slice(0, cells);
    for (let i = 0; i < n; i++) range(i, (c) => { this.items[fill[c]++] = i; });
    this.stamp = new Uint32Array(n);
    this.tick = 0;
  }

  _ci(v, a) {
    const c = Math.floor((v - this.lo[a]) / this.cell);
    return c < 0 ? 0 : c >= this.dims[a] ? this.dims[a] - 1 : c;
  }

  /** The first crossing of a -> b as a fraction of its length (hits in [1e-4, 1 − 1e-4]), else 1. */
  firstHit(a, b) {
    if (!this.count) return 1;
    const T = this.tris, dx = b[0] - a[0], dy = b[1] - a[1], dz = b[2] - a[2];
    if (++this.tick === 0xffffffff) { this.stamp.fill(0); this.tick = 1; }
    const tick = this.tick, [X, Y] = this.dims;
    const c0 = [0, 1, 2].map((k) => this._ci(Math.min(a[k], b[k]) - 1e-9, k));
    const c1 = [0, 1, 2].map((k) => this._ci(Math.max(a[k], b[k]) + 1e-9, k));
    let t = 1;
    for (let z = c0[2]; z <= c1[2]; z++)
      for (let y = c0[1]; y <= c1[1]; y++)
        for (let x = c0[0]; x <= c1[0]; x++) {
          const c = x + X * (y + Y * z);
          for (let j = this.start[c], e = this.start[c + 1]; j < e; j++) {
            const tri = this.items[j];
            if (this.stamp[tri] === tick) continue;
            this.stamp[tri] = tick;
            const i = 9 * tri;
            const e1x = T[i + 3] - T[i], e1y = T[i + 4] - T[i + 1], e1z = T[i + 5] - T[i + 2];
            const e2x = T[i + 6] - T[i], e2y = T[i + 7] - T[i + 1], e2z = T[i + 8] - T[i + 2];
            const sx = a[0] - T[i], sy = a[1] - T[i + 1], sz = a[2] - T[i + 2];
            const px = dy * e2z - dz * e2y, py = dz * e2x - dx * e2z, pz = dx * e2y - dy * e2x;
            const det = e1x * px + e1y * py + e1z * pz;
            if (det === 0) continue;
            const su = (sx * px + sy * py + sz * pz) / det;
            if (su < 0 || su > 1) continue;
            const qx = sy * e1z - sz * e1y, qy = sz * e1x - sx * e1z, qz = sx * e1y - sy * e1x;
            const sv = (dx * qx + dy * qy + dz * qz) / det;
            if (sv < 0 || su + sv > 1) continue;
            const h = (e2x * qx + e2y * qy + e2z * qz) / det;
            if (h >= 1e-4 && h <= 1 - 1e-4 && h < t) t = h;
          }
        }
    return t;
  }
}

/**
 * pb_vis_trace_box: the pair table of the lattice box [lo, lo + 2^lv] (origin, spacing h) into
 * out[off + 8k + c] = round(255 t) in [1, 255]; returns whether some pair is blocked.
 */
export function traceBox(origin, h, lo, lv, seg, out, off = 0) {
  const p = [];
  for (let c = 0; c < 8; c++)
    p.push([0, 1, 2].map((k) => origin[k] + (lo[k] + ((c >> k) & 1 ? 2 ** lv[k] : 0)) * h));
  let blocked = false;
  const a = [0, 0, 0], b = [0, 0, 0];
  for (let k = 0; k < 8; k++)
    for (let c = 0; c < 8; c++) {
      let f = 1;
      const flat = 7 & ~(k ^ c);
      const combos = 1 << ((flat & 1) + ((flat >> 1) & 1) + ((flat >> 2) & 1));
      for (let m = 0; k !== c && m < combos; m++) {
        let bit = 0;
        for (let ax = 0; ax < 3; ax++) {
          let d = 0;
          if ((flat >> ax) & 1) d = ((m >> bit++) & 1 ? VIS_SHIFT : -VIS_SHIFT) * h;
          a[ax] = p[c][ax] + d;
          b[ax] = p[k][ax] + d;
        }
        const fm = seg(a, b);
        if (fm < f) f = fm;
      }
      /* NaN or beyond the ends: clear; a hit at the very start still leaves 1/255 (C lround: half away). */
      let q = !(f < 1) ? VIS_CLEAR : Math.round(255 * (f > 0 ? f : 0));
      q = q < 1 ? 1 : q > VIS_CLEAR ? VIS_CLEAR : q;
      out[off + 8 * k + c] = q;
      if (q !== VIS_CLEAR) blocked = true;
    }
  return blocked;
}
