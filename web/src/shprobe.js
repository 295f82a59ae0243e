/* `.shprobe` reader for JavaScript (browser and Node), versions 1 to 4 (docs/shprobe-format.md).
 *
 * A second, independent reader of the file the bake writes, for the three.js plugin. It mirrors the C
 * reader (native/src/pb_shprobe_read.c, pb_shprobe.c, pb_shprobe_v3.c) check for check and in the same
 * order, so a file refused by one is refused by the other with the same message (web/test compares
 * them on every version, every structure and every refusal): the header first, its exact size against
 * the buffer's (limits before anything is allocated), then the records and the structure, then the
 * values (finite, in range) and the structure's references.
 *
 * Usage:
 *   import { parseShprobe, ShprobeError } from './shprobe.js';
 *   const buf = await (await fetch(url)).arrayBuffer();
 *   const probes = parseShprobe(buf, { name: url });   // throws ShprobeError on a malformed file
 *   probes.coeffs        // Float32Array, probeCount × colourCount × 3 (RGB), binary16 expanded
 */

/** The uint32 at offset 0 of every `.shprobe` file (bytes on disk "SPHR"). */
export const SHPROBE_MAGIC = 0x52485053;

/** Documented limits (native/include/schnee/pb_shprobe.h): a header above them is refused. */
export const SHPROBE_LIMITS = Object.freeze({
  maxProbes: 2 ** 24,
  maxGridCells: 2 ** 28,
  maxLeaves: 2 ** 26,
  maxHanging: 2 ** 26,
  maxTets: 2 ** 27,
  maxLattice: 2 ** 20,
  maxSplitNodes: 2 ** 28,
  maxLevel: 20,
  maxBand: 4,
});

/** A split-tree leaf node's index meaning "no leaf here" (outside the volumes). */
export const SHPROBE_SPLIT_EMPTY = 2 ** 30 - 1;

/** Structure names by the file's structure field (0..3), as native.py's and the engine's. */
export const SHPROBE_STRUCTURES = Object.freeze(['grid', 'octree', 'tetrahedra', 'kdtree']);

/* Result codes: the strings of the C pb_result_string(), so both readers classify a refusal alike. */
const FORMAT = 'malformed file';
const NON_FINITE = 'non-finite value';
const TOO_LARGE = 'input too large';

const GRID = 0, OCTREE = 1, TETRA = 2, KDTREE = 3;
const AMBIENT_CUBE = 1, FLOAT16 = 1;
const HALF_MAX = 65504;
const AXIS_TOLERANCE = 1e-4;
const HANGING_SUM_TOL = 1e-5;
const LEAF_SIZE = 48, HANGING_SIZE = 32, TET_SIZE = 32;
const U64_MAX = (1n << 64n) - 1n;
const CHANNELS = ['red', 'green', 'blue'];
const IDENTITY_AXES = [1, 0, 0, 0, 1, 0, 0, 0, 1];

/* Field offsets of versions 1 and 2 (versions 3 and 4 keep version 2's up to offset 92). */
const V1_FIELDS = { count: 8, band: 0, flags: 0, dims: 12, origin: 24, spacing: 36, axes: 0, scale: 40, ambient: 44 };
const V2_FIELDS = { count: 8, band: 12, flags: 16, dims: 20, origin: 32, spacing: 44, axes: 48, scale: 84, ambient: 88 };

/**
 * A refusal of a `.shprobe` file: `message` is "<name>: <what is wrong, with the byte offset>",
 * the same text as the C reader's (`pb_shprobe_read`).
 */
export class ShprobeError extends Error {
  /**
   * @param {string} detail what is wrong (without the file name)
   * @param {{code: string, file?: string}} info `code`: "malformed file", "non-finite value" or
   *   "input too large" (the C reader's result names); `file`: the name given to parseShprobe
   */
  constructor(detail, { code, file = '' }) {
    super(file ? `${file}: ${detail}` : detail);
    this.name = 'ShprobeError';
    /** @type {string} */
    this.code = code;
    /** @type {string} */
    this.detail = detail;
    /** @type {string} */
    this.file = file;
  }
}

/* ---- number formatting as C's printf (the messages must read as the C reader's) --------------- */

/* %.<prec>g of a double; NaN's sign comes from the bits on disk (glibc prints "-nan"). Known
 * differences, not reached by the values a message quotes so far: an exact decimal tie (123456.5 at 6
 * digits) rounds up here and to even in glibc; C truncates a message at 511 bytes (pb_error), this
 * reader does not. */
function fmtG(x, prec = 6, negativeNaN = false) {
  if (Number.isNaN(x)) return negativeNaN ? '-nan' : 'nan';
  if (x === Infinity) return 'inf';
  if (x === -Infinity) return '-inf';
  if (x === 0) return Object.is(x, -0) ? '-0' : '0';
  const [mant, e] = x.toExponential(prec - 1).split('e');
  const exp = Number(e);
  const strip = (s) => (s.includes('.') ? s.replace(/0+$/, '').replace(/\.$/, '') : s);
  if (exp < -4 || exp >= prec) {
    const a = Math.abs(exp);
    return `${strip(mant)}e${exp < 0 ? '-' : '+'}${a < 10 ? '0' : ''}${a}`;
  }
  return strip(x.toFixed(prec - 1 - exp));
}

const hex = (v) => (v >>> 0).toString(16).toUpperCase();
const hex8 = (v) => hex(v).padStart(8, '0');

/* ---- Morton codes (pb_morton.h: z most significant), exact in BigInt --------------------------- */

const SPREAD11 = new Float64Array(2048); /* 11 bits spread to every third bit (< 2^31) */
for (let v = 0; v < 2048; v++) {
  let s = 0;
  for (let b = 0; b < 11; b++) if (v & (1 << b)) s += 2 ** (3 * b);
  SPREAD11[v] = s;
}

function morton3(x, y, z) {
  x &= 0x1fffff; y &= 0x1fffff; z &= 0x1fffff;
  const lo = SPREAD11[x & 2047] + 2 * SPREAD11[y & 2047] + 4 * SPREAD11[z & 2047]; /* bits 0..32 */
  const hi = SPREAD11[x >>> 11] + 2 * SPREAD11[y >>> 11] + 4 * SPREAD11[z >>> 11]; /* bits 33..62 */
  return (BigInt(hi) << 33n) | BigInt(lo);
}

/* IEEE binary16 → float, exact; Inf/NaN stay Inf/NaN so the finite check refuses them. */
function halfToFloat(h) {
  const sign = h & 0x8000 ? -1 : 1, exp = (h >>> 10) & 0x1f, man = h & 0x3ff;
  if (exp === 0) return sign * man * 2 ** -24;
  if (exp === 31) return man ? NaN : sign * Infinity;
  return sign * (1024 + man) * 2 ** (exp - 25);
}

function toBytes(data) {
  if (data instanceof ArrayBuffer) return new Uint8Array(data);
  if (typeof SharedArrayBuffer !== 'undefined' && data instanceof SharedArrayBuffer) return new Uint8Array(data);
  if (ArrayBuffer.isView(data)) return new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
  throw new TypeError('parseShprobe: expected an ArrayBuffer or a typed array / DataView of the file');
}

/* ---- header --------------------------------------------------------------------------------------- */

function structureName(s) {
  return s === KDTREE ? 'kd corner tree' : s <= TETRA ? SHPROBE_STRUCTURES[s] : 'grid';
}

const shCount = (band) => (band + 1) * (band + 1);

/* Version 3/4 kind fields and structure counts (pb_shprobe_check_v3_kind_). */
function checkKind(version, h, positions, fail) {
  const s = h.structure;
  if (version === 4 && s !== KDTREE)
    fail(FORMAT, `structure ${s} at offset 100 in a version 4 file; version 4 holds 3 = kd corner tree only ` +
      '(the others are version 3)');
  if (version !== 4 && s === KDTREE)
    fail(FORMAT, `the kd corner tree (structure 3 at offset 100) needs version 4, not ${version}`);
  if (h.representation > AMBIENT_CUBE)
    fail(FORMAT, `unknown representation ${h.representation} at offset 92; this reader knows 0 = SH, 1 = ambient cube`);
  if (h.storage > FLOAT16)
    fail(FORMAT, `unknown storage ${h.storage} at offset 96; this reader knows 0 = float32, 1 = binary16`);
  if (s > TETRA && version !== 4)
    fail(FORMAT, `unknown structure ${s} at offset 100; this reader knows 0 = grid, 1 = octree, 2 = tetrahedra`);
  const N = h.elementCount, H = h.hangingCount;
  if (s === GRID) {
    if (N !== 0 || H !== 0)
      fail(FORMAT, `a grid file has element and hanging counts 0 (offsets 104, 108), not ${N}, ${H}`);
    return;
  }
  if (!positions) fail(FORMAT, `the ${structureName(s)} structure needs probe positions (flag bit 0 at offset 16)`);
  const tets = s === TETRA;
  const limit = tets ? SHPROBE_LIMITS.maxTets : SHPROBE_LIMITS.maxLeaves;
  const what = tets ? 'tetrahedra' : 'leaves';
  if (N > limit) fail(TOO_LARGE, `${N} ${what} (offset 104) are above the limit of ${limit}`);
  if (N === 0) fail(FORMAT, `the ${structureName(s)} structure has no ${what} (offset 104)`);
  if (tets) {
    if (H !== 0) fail(FORMAT, `tetrahedra have no hanging nodes; the count at offset 108 is ${H}`);
    for (let i = 0; i < 3; i++)
      if (h.gridDims[i] !== 0)
        fail(FORMAT, `tetrahedra have no lattice: dim ${'XYZ'[i]} at offset ${20 + 4 * i} must be 0, not ${h.gridDims[i]}`);
    return;
  }
  if (H > SHPROBE_LIMITS.maxHanging)
    fail(TOO_LARGE, `${H} hanging nodes (offset 108) are above the limit of ${SHPROBE_LIMITS.maxHanging}`);
  for (let i = 0; i < 3; i++) {
    const d = h.gridDims[i];
    if (d === 0 || d > SHPROBE_LIMITS.maxLattice)
      fail(d ? TOO_LARGE : FORMAT, `octree lattice extent ${'XYZ'[i]} at offset ${20 + 4 * i} is ${d}; ` +
        `it must be 1..${SHPROBE_LIMITS.maxLattice} min cells`);
  }
  if (s !== KDTREE) return;
  const R = h.rootLevel, K = h.splitNodeCount;
  if (R > SHPROBE_LIMITS.maxLevel) fail(FORMAT, `root level ${R} at offset 112 is out of range 0..20`);
  if (K > SHPROBE_LIMITS.maxSplitNodes)
    fail(TOO_LARGE, `${K} split-tree nodes (offset 116) are above the limit of ${SHPROBE_LIMITS.maxSplitNodes}`);
  let g = 1n;
  for (const d of h.gridDims) g *= BigInt(Math.floor((d + 2 ** R - 1) / 2 ** R));
  if (BigInt(K) < g)
    fail(FORMAT, `split-tree node count ${K} (offset 116) is below the ${g} root cells of a ` +
      `${h.gridDims[0]} x ${h.gridDims[1]} x ${h.gridDims[2]} lattice at root level ${R}`);
}

/* The exact byte layout (pb_shprobe_layout_compute_): sizes in BigInt, limits before any size is used. */
function computeLayout(h, positions, fail) {
  const v = h.version, fields = v === 1 ? V1_FIELDS : V2_FIELDS;
  const structure = v >= 3 ? h.structure : GRID;
  let header = 48, diskCoeffs = 9, colourBytes = 16;
  if (v >= 2) {
    header = v === 2 ? 96 : 128;
    diskCoeffs = v >= 3 && h.representation === AMBIENT_CUBE ? 6 : shCount(h.maxBand);
    if (v >= 3 && h.storage === FLOAT16) colourBytes = 8;
  }
  const [X, Y, Z] = h.gridDims;
  let cells = 0n;
  if (structure === GRID) {
    cells = BigInt(X) * BigInt(Y) * BigInt(Z);
    if (cells > U64_MAX) fail(FORMAT, `grid dims ${X} x ${Y} x ${Z} overflow 64 bits`);
  }
  const P = h.probeCount;
  if (P > SHPROBE_LIMITS.maxProbes)
    fail(TOO_LARGE, `probe count ${P} (offset ${fields.count}) is above the limit of ${SHPROBE_LIMITS.maxProbes} probes`);
  if (cells > BigInt(SHPROBE_LIMITS.maxGridCells))
    fail(TOO_LARGE, `grid ${X} x ${Y} x ${Z} = ${cells} cells (offset ${fields.dims}) is above the limit of ` +
      `${SHPROBE_LIMITS.maxGridCells} cells`);
  const recordSize = colourBytes * diskCoeffs + 16;
  const recordsOffset = BigInt(header);
  const positionsOffset = recordsOffset + BigInt(P) * BigInt(recordSize);
  const gridOffset = positionsOffset + (positions ? 16n * BigInt(P) : 0n);
  let main = 0n, hanging = 0n, nodes = 0n;
  if (structure === GRID) main = 4n * cells;
  else if (structure === TETRA) main = BigInt(TET_SIZE) * BigInt(h.elementCount);
  else {
    main = BigInt(LEAF_SIZE) * BigInt(h.elementCount);
    hanging = BigInt(HANGING_SIZE) * BigInt(h.hangingCount);
    if (structure === KDTREE) nodes = 4n * BigInt(h.splitNodeCount);
  }
  const hangingOffset = gridOffset + main, splitOffset = hangingOffset + hanging, total = splitOffset + nodes;
  /* Every part is >= 0, so a wrapped partial sum in C means the true total is past 2^64 - 1 too. */
  if (total > U64_MAX)
    fail(FORMAT, `file size overflows: ${P} probes, grid ${X} x ${Y} x ${Z} cells (version ${v})`);
  return {
    fields, structure, positions, diskCoeffs, colourBytes, recordSize, gridCells: Number(cells),
    recordsOffset: Number(recordsOffset), positionsOffset: Number(positionsOffset), gridOffset: Number(gridOffset),
    hangingOffset: Number(hangingOffset), splitOffset: Number(splitOffset), total,
  };
}

/* Header values: finite floats, spacing > 0 (not for tetrahedra), orthonormal axes. */
function checkHeaderValues(h, lay, negAt, fail) {
  const f = lay.fields;
  for (let i = 0; i < 3; i++)
    if (!Number.isFinite(h.gridOrigin[i]))
      fail(NON_FINITE, `grid origin[${i}] is ${fmtG(h.gridOrigin[i], 6, negAt(f.origin + 4 * i))} (offset ${f.origin + 4 * i})`);
  const sp = h.gridSpacing;
  if (!Number.isFinite(sp)) fail(NON_FINITE, `grid spacing is ${fmtG(sp, 6, negAt(f.spacing))} (offset ${f.spacing})`);
  if (!(sp > 0) && lay.structure !== TETRA) fail(FORMAT, `grid spacing is ${fmtG(sp)} (offset ${f.spacing}); it must be > 0`);
  if (!Number.isFinite(h.defaultShScale))
    fail(NON_FINITE, `default SH scale is ${fmtG(h.defaultShScale, 6, negAt(f.scale))} (offset ${f.scale})`);
  if (!Number.isFinite(h.defaultAmbient))
    fail(NON_FINITE, `default ambient is ${fmtG(h.defaultAmbient, 6, negAt(f.ambient))} (offset ${f.ambient})`);
  if (h.version < 2) return; /* version 1: identity axes, not in the file (all-zero axes were refused) */
  const a = h.gridAxes;
  for (let i = 0; i < 9; i++)
    if (!Number.isFinite(a[i]))
      fail(NON_FINITE, `grid axes[${i}] is ${fmtG(a[i], 6, negAt(f.axes + 4 * i))} (offset ${f.axes + 4 * i})`);
  for (let i = 0; i < 3; i++)
    for (let j = i; j < 3; j++) {
      const dot = a[3 * i] * a[3 * j] + a[3 * i + 1] * a[3 * j + 1] + a[3 * i + 2] * a[3 * j + 2];
      const want = i === j ? 1 : 0;
      if (Math.abs(dot - want) > AXIS_TOLERANCE)
        fail(FORMAT, `grid axes are not orthonormal: axis ${i} . axis ${j} = ${fmtG(dot)}, expected ${want} (offset ${f.axes})`);
    }
}

/* Parses and validates the header against the buffer's size (parse_header in pb_shprobe_read.c). */
function parseHeader(dv, size, negAt, fail) {
  const u32 = (o) => dv.getUint32(o, true), f32 = (o) => dv.getFloat32(o, true);
  if (size < 4) fail(FORMAT, `truncated: ${size} bytes, the magic at offset 0 needs 4`);
  /* The value found is not quoted: it would echo 4 bytes of a file that is not ours. */
  if (u32(0) !== SHPROBE_MAGIC)
    fail(FORMAT, 'not a .shprobe file (bad magic: it does not start with "SPHR" = 0x52485053)');
  if (size < 8) fail(FORMAT, `truncated: ${size} bytes, the version at offset 4 needs 8`);
  const version = u32(4);
  if (version < 1 || version > 4)
    fail(FORMAT, `unknown version ${version} at offset 4; this reader knows versions 1, 2, 3 and 4`);
  const headerSize = version === 1 ? 48 : version === 2 ? 96 : 128;
  if (size < headerSize) fail(FORMAT, `truncated: ${size} bytes, the version ${version} header needs ${headerSize}`);
  const f = version === 1 ? V1_FIELDS : V2_FIELDS;
  const h = {
    version, probeCount: u32(f.count), maxBand: 2, flags: 0, gridDims: [0, 0, 0], gridOrigin: [0, 0, 0],
    gridSpacing: 0, gridAxes: IDENTITY_AXES.slice(), defaultShScale: 0, defaultAmbient: 0,
    representation: 0, storage: 0, structure: GRID, elementCount: 0, hangingCount: 0, rootLevel: 0, splitNodeCount: 0,
  };
  if (version !== 1) {
    h.maxBand = u32(f.band);
    if (h.maxBand > SHPROBE_LIMITS.maxBand) fail(FORMAT, `max band ${h.maxBand} at offset ${f.band} is out of range 0..4`);
    h.flags = u32(f.flags);
    if (h.flags & ~1) fail(FORMAT, `unknown flags 0x${hex(h.flags)} at offset ${f.flags} (known: 0x1 = positions)`);
    for (let i = 0; i < 9; i++) h.gridAxes[i] = f32(f.axes + 4 * i);
    if (h.gridAxes.every((v) => v === 0)) fail(FORMAT, `grid axes at offset ${f.axes} are all zero`);
  }
  const positions = (h.flags & 1) !== 0;
  if (version >= 3) {
    h.representation = u32(92);
    h.storage = u32(96);
    h.structure = u32(100);
    h.elementCount = u32(104);
    h.hangingCount = u32(108);
    for (let i = 0; i < 3; i++) h.gridDims[i] = u32(f.dims + 4 * i);
    if (version === 4) {
      h.rootLevel = u32(112);
      h.splitNodeCount = u32(116);
      for (let k = 0; k < 2; k++)
        if (u32(120 + 4 * k) !== 0) fail(FORMAT, `reserved word at offset ${120 + 4 * k} is 0x${hex(u32(120 + 4 * k))}; it must be 0`);
    }
    checkKind(version, h, positions, fail);
  }
  for (let i = 0; i < 3; i++) {
    h.gridDims[i] = u32(f.dims + 4 * i);
    h.gridOrigin[i] = f32(f.origin + 4 * i);
    if (h.gridDims[i] === 0 && h.structure !== TETRA)
      fail(FORMAT, `grid dim ${'XYZ'[i]} at offset ${f.dims + 4 * i} is 0; a grid has at least one cell per axis`);
  }
  h.gridSpacing = f32(f.spacing);
  h.defaultShScale = f32(f.scale);
  h.defaultAmbient = f32(f.ambient);

  const lay = computeLayout(h, positions, fail);
  checkHeaderValues(h, lay, negAt, fail);
  const [X, Y, Z] = h.gridDims, big = BigInt(size), sname = structureName(lay.structure);
  if (big < lay.total)
    fail(FORMAT, `truncated: ${size} bytes, but ${h.probeCount} probes (max band ${h.maxBand}${positions ? ', positions' : ''}) ` +
      `and a ${X} x ${Y} x ${Z} ${sname} need ${lay.total}`);
  if (big > lay.total)
    fail(FORMAT, `${big - lay.total} bytes of trailing data after the ${sname}, which ends at offset ${lay.total}`);
  return { h, lay };
}

/* ---- contents ------------------------------------------------------------------------------------- */

function checkHanging(p, lay, negAt, fail) {
  const P = p.probeCount;
  for (let j = 0; j < p.hangingCount; j++) {
    const off = lay.hangingOffset + HANGING_SIZE * j;
    let sum = 0;
    for (let k = 0; k < 4; k++) {
      const src = p.hangingSources[4 * j + k], w = p.hangingWeights[4 * j + k];
      if (src >= P + j)
        fail(FORMAT, `hanging node ${j} source ${k} (offset ${off + 4 * k}) is ${src}; it must be a probe or an ` +
          `earlier hanging node, below ${P + j}`);
      const woff = off + 16 + 4 * k;
      if (!Number.isFinite(w)) fail(NON_FINITE, `hanging node ${j} weight ${k} is ${fmtG(w, 6, negAt(woff))} (offset ${woff})`);
      if (w < 0 || w > 1) fail(FORMAT, `hanging node ${j} weight ${k} is ${fmtG(w)} (offset ${woff}); it must be in [0, 1]`);
      sum += w;
    }
    if (Math.abs(sum - 1) > HANGING_SUM_TOL)
      fail(FORMAT, `hanging node ${j} weights sum to ${fmtG(sum, 9)} (offset ${off + 16}); they must sum to 1`);
  }
}

function checkCorners(p, i, off, nodes, fail) {
  for (let c = 0; c < 8; c++) {
    const v = p.leafCorners[8 * i + c];
    if (v < 0 || v >= nodes)
      fail(FORMAT, `leaf ${i} corner ${c} (offset ${off + 16 + 4 * c}) is ${v}; it must be a node index below ${nodes}`);
  }
}

/* Octree leaves: level <= 20, aligned and inside the lattice, Morton order without overlap. */
function checkOctree(p, lay, fail) {
  const nodes = p.probeCount + p.hangingCount, [X, Y, Z] = p.gridDims;
  let prevEnd = 0n;
  for (let i = 0; i < p.elementCount; i++) {
    const l = p.leaves.subarray(4 * i, 4 * i + 4), off = lay.gridOffset + LEAF_SIZE * i;
    if (l[3] > SHPROBE_LIMITS.maxLevel) fail(FORMAT, `leaf ${i} level ${l[3]} (offset ${off + 12}) is above 20`);
    const size = 2 ** l[3];
    for (let k = 0; k < 3; k++)
      if (l[k] % size !== 0 || l[k] + size > p.gridDims[k])
        fail(FORMAT, `leaf ${i} at (${l[0]}, ${l[1]}, ${l[2]}) level ${l[3]} (offset ${off}) is not aligned to its size ` +
          `or reaches past the lattice extent ${X} x ${Y} x ${Z}`);
    const start = morton3(l[0], l[1], l[2]);
    if (i > 0 && start < prevEnd)
      fail(FORMAT, `leaf ${i} at (${l[0]}, ${l[1]}, ${l[2]}) (offset ${off}) overlaps the leaf before it or is out of Morton order`);
    prevEnd = start + (1n << BigInt(3 * l[3]));
    checkCorners(p, i, off, nodes, fail);
  }
}

/* Kd corner tree leaves (version 4): the levels word, per-axis alignment, strict Morton order. */
function checkKdLeaves(p, lay, fail) {
  const nodes = p.probeCount + p.hangingCount, [X, Y, Z] = p.gridDims, R = p.rootLevel;
  let prev = 0n;
  for (let i = 0; i < p.elementCount; i++) {
    const l = p.leaves.subarray(4 * i, 4 * i + 4), off = lay.gridOffset + LEAF_SIZE * i;
    const lv = [l[3] & 0xff, (l[3] >>> 8) & 0xff, (l[3] >>> 16) & 0xff];
    if (l[3] >>> 24)
      fail(FORMAT, `leaf ${i} levels word 0x${hex8(l[3])} (offset ${off + 12}) has a nonzero top byte; it holds ` +
        'lx | ly << 8 | lz << 16');
    for (let k = 0; k < 3; k++)
      if (lv[k] > R)
        fail(FORMAT, `leaf ${i} level ${'xyz'[k]} is ${lv[k]} (offset ${off + 12}); it must be at most the root level ${R}`);
    for (let k = 0; k < 3; k++)
      if (l[k] % 2 ** lv[k] !== 0 || l[k] + 2 ** lv[k] > p.gridDims[k])
        fail(FORMAT, `leaf ${i} at (${l[0]}, ${l[1]}, ${l[2]}) levels (${lv[0]}, ${lv[1]}, ${lv[2]}) (offset ${off}) is not ` +
          `aligned to its size or reaches past the lattice extent ${X} x ${Y} x ${Z}`);
    const m = morton3(l[0], l[1], l[2]);
    if (i > 0 && m <= prev)
      fail(FORMAT, `leaf ${i} at (${l[0]}, ${l[1]}, ${l[2]}) (offset ${off}) is not after the leaf before it in Morton ` +
        'order of min corners');
    prev = m;
    checkCorners(p, i, off, nodes, fail);
  }
}

/* The split tree, depth first from each root cell (check_split_tree / kd_visit in pb_shprobe_v3.c):
 * every non-root node the child of exactly one split, a split's axis of level > 0 in its box, every
 * leaf reached once with its record equal to its node's box. */
function checkSplitTree(p, lay, fail) {
  const K = p.splitNodeCount, R = p.rootLevel, N = p.elementCount, cell = 2 ** R;
  const root = p.gridDims.map((d) => Math.floor((d + cell - 1) / cell));
  const G = root[0] * root[1] * root[2]; /* <= K (header check) */
  const seen = new Uint8Array((K >>> 3) + 1);
  const isSeen = (c) => seen[c >>> 3] & (1 << (c & 7));
  const mark = (c) => { seen[c >>> 3] |= 1 << (c & 7); };
  const nodeOff = (n) => lay.splitOffset + 4 * n;
  let reached = 0;
  for (let g = 0; g < G; g++) {
    mark(g);
    const stack = [{
      node: g, min: [(g % root[0]) * cell, (Math.floor(g / root[0]) % root[1]) * cell, Math.floor(g / (root[0] * root[1])) * cell],
      lv: [R, R, R],
    }];
    while (stack.length) {
      const b = stack.pop();
      const v = p.splitNodes[b.node], axis = v & 3, arg = v >>> 2, off = nodeOff(b.node);
      const box = `(${b.min[0]}, ${b.min[1]}, ${b.min[2]}) levels (${b.lv[0]}, ${b.lv[1]}, ${b.lv[2]})`;
      if (axis === 0) {
        if (arg === SHPROBE_SPLIT_EMPTY) continue;
        if (arg >= N)
          fail(FORMAT, `split-tree node ${b.node} (offset ${off}) names leaf ${arg}; leaves are below ${N} ` +
            `(or ${SHPROBE_SPLIT_EMPTY} = none)`);
        const l = p.leaves.subarray(4 * arg, 4 * arg + 4);
        if (l[0] !== b.min[0] || l[1] !== b.min[1] || l[2] !== b.min[2] || l[3] !== (b.lv[0] | (b.lv[1] << 8) | (b.lv[2] << 16)))
          fail(FORMAT, `split-tree node ${b.node} (offset ${off}) reaches leaf ${arg} at (${l[0]}, ${l[1]}, ${l[2]}) levels ` +
            `word 0x${hex(l[3])}, but the node's box is at ${box}`);
        reached++;
        continue;
      }
      const a = axis - 1;
      if (b.lv[a] === 0)
        fail(FORMAT, `split-tree node ${b.node} (offset ${off}) splits along ${'xyz'[a]} a box of level 0 on that axis, at ${box}`);
      if (arg <= b.node || arg < G || arg >= K - 1)
        fail(FORMAT, `split-tree node ${b.node} (offset ${off}) names children ${arg} and ${arg + 1}; they must come after ` +
          `it and after the ${G} root cells, below the node count ${K}`);
      for (let c = arg; c <= arg + 1; c++) {
        if (isSeen(c))
          fail(FORMAT, `split-tree node ${c} (offset ${nodeOff(c)}) is the child of two splits (the second: node ${b.node})`);
        mark(c);
      }
      const lo = { node: arg, min: b.min.slice(), lv: b.lv.slice() };
      const hi = { node: arg + 1, min: b.min.slice(), lv: b.lv.slice() };
      lo.lv[a] = hi.lv[a] = b.lv[a] - 1;
      hi.min[a] += 2 ** hi.lv[a];
      stack.push(hi, lo);
    }
  }
  for (let i = G; i < K; i++)
    if (!isSeen(i))
      fail(FORMAT, `split-tree node ${i} (offset ${nodeOff(i)}) is not the child of any split reached from the root cells`);
  if (reached !== N) fail(FORMAT, `the split tree (offset ${lay.splitOffset}) reaches ${reached} of the ${N} leaves`);
}

function checkTets(p, lay, fail) {
  const P = p.probeCount, N = p.elementCount;
  for (let i = 0; i < N; i++) {
    const off = lay.gridOffset + TET_SIZE * i, t = p.tets.subarray(4 * i, 4 * i + 4);
    for (let k = 0; k < 4; k++) {
      if (t[k] >= P)
        fail(FORMAT, `tetrahedron ${i} vertex ${k} (offset ${off + 4 * k}) is ${t[k]}; it must be a probe index below ${P}`);
      for (let m = 0; m < k; m++) if (t[m] === t[k]) fail(FORMAT, `tetrahedron ${i} (offset ${off}) repeats vertex ${t[k]}`);
      const nb = p.tetNeighbours[4 * i + k];
      if (nb < -1 || nb >= N)
        fail(FORMAT, `tetrahedron ${i} neighbour ${k} (offset ${off + 16 + 4 * k}) is ${nb}; it must be -1 or below ${N}`);
    }
  }
}

/* Per-probe values, then the grid entries or the structure (pb_shprobe_check_contents_). */
function checkContents(p, lay, negAt, fail) {
  const count = lay.diskCoeffs, cb = lay.colourBytes, chb = cb / 4, half = cb === 8;
  const what = p.representation === 'ambientCube' ? 'face' : 'coefficient';
  const coeffs = p.coeffs, n = count * 3;
  for (let i = 0; i < p.probeCount; i++) {
    const rec = lay.recordsOffset + i * lay.recordSize;
    for (let k = 0; k < n; k++) {
      const x = coeffs[i * n + k];
      if (Number.isFinite(x) && !(half && Math.abs(x) > HALF_MAX)) continue;
      const off = rec + cb * Math.floor(k / 3) + chb * (k % 3);
      const at = `probe ${i} ${what} ${Math.floor(k / 3)} ${CHANNELS[k % 3]}`;
      if (!Number.isFinite(x)) fail(NON_FINITE, `${at} is ${fmtG(x, 6, negAt(off, half))} (offset ${off})`);
      fail(FORMAT, `${at} is ${fmtG(x)} (offset ${off}); binary16 storage holds at most 65504`);
    }
    const tail = rec + cb * count;
    if (!Number.isFinite(p.probeScale[i]))
      fail(NON_FINITE, `probe ${i} scale is ${fmtG(p.probeScale[i], 6, negAt(tail))} (offset ${tail})`);
    if (!Number.isFinite(p.probeAmbient[i]))
      fail(NON_FINITE, `probe ${i} ambient is ${fmtG(p.probeAmbient[i], 6, negAt(tail + 4))} (offset ${tail + 4})`);
    if (p.version >= 2) {
      const v = p.validity[i];
      if (!Number.isFinite(v)) fail(NON_FINITE, `probe ${i} validity is ${fmtG(v, 6, negAt(tail + 8))} (offset ${tail + 8})`);
      if (v < 0 || v > 1) fail(FORMAT, `probe ${i} validity is ${fmtG(v)} (offset ${tail + 8}); it must be in [0, 1]`);
    }
    if (p.positions) {
      const off = lay.positionsOffset + 16 * i;
      for (let k = 0; k < 3; k++) {
        const x = p.positions[3 * i + k];
        if (!Number.isFinite(x)) fail(NON_FINITE, `probe ${i} position[${k}] is ${fmtG(x, 6, negAt(off + 4 * k))} (offset ${off + 4 * k})`);
      }
    }
  }
  if (lay.structure === OCTREE) {
    checkOctree(p, lay, fail);
    checkHanging(p, lay, negAt, fail);
  } else if (lay.structure === KDTREE) {
    checkKdLeaves(p, lay, fail);
    checkHanging(p, lay, negAt, fail);
    checkSplitTree(p, lay, fail);
  } else if (lay.structure === TETRA) {
    checkTets(p, lay, fail);
  } else {
    const [X, Y] = p.gridDims, P = p.probeCount;
    for (let j = 0; j < lay.gridCells; j++) {
      const v = p.grid[j];
      if (v < -1 || v >= P)
        fail(FORMAT, `grid cell (${j % X}, ${Math.floor(j / X) % Y}, ${Math.floor(j / (X * Y))}) holds ${v} ` +
          `(offset ${lay.gridOffset + 4 * j}); entries must be -1 or a probe index below the probe count ${P}`);
    }
  }
}

/**
 * Reads and validates a `.shprobe` file (versions 1 to 4: dense grid, corner octree, tetrahedra, kd
 * corner tree; SH or ambient cube; float32 or binary16), with the checks of the C reader and its
 * messages. Nothing past the size the header announces is read: a shorter or longer buffer is refused.
 *
 * @param {ArrayBuffer|ArrayBufferView} data the whole file
 * @param {{name?: string}} [options] `name`: the file's name or URL, put in front of every message
 * @returns {{
 *   name: string, version: number, probeCount: number, maxBand: number, hasPositions: boolean,
 *   representation: 'sh'|'ambientCube', storage: 'float32'|'float16',
 *   structure: 'grid'|'octree'|'tetrahedra'|'kdtree', colourCount: number,
 *   gridDims: number[], gridOrigin: number[], gridSpacing: number, gridAxes: number[][],
 *   defaultShScale: number, defaultAmbient: number,
 *   coeffs: Float32Array, probeScale: Float32Array, probeAmbient: Float32Array, validity: Float32Array,
 *   positions: Float32Array|null, grid: Int32Array|null,
 *   elementCount: number, hangingCount: number, leaves: Uint32Array|null, leafCorners: Int32Array|null,
 *   hangingSources: Uint32Array|null, hangingWeights: Float32Array|null,
 *   tets: Uint32Array|null, tetNeighbours: Int32Array|null, rootLevel: number, splitNodes: Uint32Array|null,
 *   byteLength: number
 * }} `coeffs`: probeCount × colourCount × 3 (RGB; SH index l*l + l + m, or the cube faces +X, −X, +Y,
 *   −Y, +Z, −Z), engine space; version 1 reads back max band 2. `positions` probeCount × 3 (null when
 *   the file has none); `grid` X·Y·Z probe indices (−1 empty, index x + y·X + z·X·Y), null for the
 *   sparse structures; `leaves` N × 4 (x, y, z, level; kdtree: levels packed lx | ly << 8 | lz << 16);
 *   `leafCorners` N × 8 node indices; `hangingSources`/`hangingWeights` H × 4; `tets` and
 *   `tetNeighbours` N × 4; `splitNodes` K. `gridAxes` rows X, Y, Z (identity for version 1),
 *   `validity` 1 for version 1.
 * @throws {ShprobeError} a malformed file (`code` "malformed file", "non-finite value" or
 *   "input too large", the message naming the field and its byte offset)
 */
export function parseShprobe(data, { name = '' } = {}) {
  const bytes = toBytes(data);
  const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const size = bytes.byteLength;
  const fail = (code, detail) => { throw new ShprobeError(detail, { code, file: name }); };
  /* The sign bit of the float (or binary16) at `off`: C prints a NaN with it set as "-nan". */
  const negAt = (off, half = false) => (half ? (dv.getUint16(off, true) & 0x8000) !== 0 : dv.getUint32(off, true) >>> 31 === 1);
  const { h, lay } = parseHeader(dv, size, negAt, fail);

  const P = h.probeCount, count = lay.diskCoeffs, half = lay.colourBytes === 8;
  const p = {
    name, version: h.version, probeCount: P, maxBand: h.maxBand, hasPositions: lay.positions,
    representation: h.representation === AMBIENT_CUBE ? 'ambientCube' : 'sh',
    storage: h.storage === FLOAT16 ? 'float16' : 'float32',
    structure: SHPROBE_STRUCTURES[lay.structure], colourCount: count,
    gridDims: h.gridDims.slice(), gridOrigin: h.gridOrigin.slice(), gridSpacing: h.gridSpacing,
    gridAxes: [h.gridAxes.slice(0, 3), h.gridAxes.slice(3, 6), h.gridAxes.slice(6, 9)],
    defaultShScale: h.defaultShScale, defaultAmbient: h.defaultAmbient,
    coeffs: new Float32Array(P * count * 3), probeScale: new Float32Array(P), probeAmbient: new Float32Array(P),
    validity: new Float32Array(P), positions: lay.positions ? new Float32Array(P * 3) : null, grid: null,
    elementCount: h.elementCount, hangingCount: h.hangingCount, leaves: null, leafCorners: null,
    hangingSources: null, hangingWeights: null, tets: null, tetNeighbours: null,
    rootLevel: h.rootLevel, splitNodeCount: h.splitNodeCount, splitNodes: null, byteLength: size,
  };
  for (let i = 0; i < P; i++) {
    const rec = lay.recordsOffset + i * lay.recordSize, c = i * count * 3;
    for (let k = 0; k < count; k++)
      for (let ch = 0; ch < 3; ch++)
        p.coeffs[c + 3 * k + ch] = half ? halfToFloat(dv.getUint16(rec + 8 * k + 2 * ch, true))
          : dv.getFloat32(rec + 16 * k + 4 * ch, true);
    const tail = rec + lay.colourBytes * count;
    p.probeScale[i] = dv.getFloat32(tail, true);
    p.probeAmbient[i] = dv.getFloat32(tail + 4, true);
    /* version 1: bytes 8..15 of the tail are padding (ignored) */
    p.validity[i] = h.version >= 2 ? dv.getFloat32(tail + 8, true) : 1;
    if (p.positions)
      for (let k = 0; k < 3; k++) p.positions[3 * i + k] = dv.getFloat32(lay.positionsOffset + 16 * i + 4 * k, true);
  }
  const base = lay.gridOffset, N = h.elementCount, H = h.hangingCount;
  if (lay.structure === GRID) {
    p.grid = new Int32Array(lay.gridCells);
    for (let j = 0; j < lay.gridCells; j++) p.grid[j] = dv.getInt32(base + 4 * j, true);
  } else if (lay.structure === TETRA) {
    p.tets = new Uint32Array(4 * N);
    p.tetNeighbours = new Int32Array(4 * N);
    for (let i = 0; i < N; i++)
      for (let k = 0; k < 4; k++) {
        p.tets[4 * i + k] = dv.getUint32(base + TET_SIZE * i + 4 * k, true);
        p.tetNeighbours[4 * i + k] = dv.getInt32(base + TET_SIZE * i + 16 + 4 * k, true);
      }
  } else {
    p.leaves = new Uint32Array(4 * N);
    p.leafCorners = new Int32Array(8 * N);
    for (let i = 0; i < N; i++) {
      for (let k = 0; k < 4; k++) p.leaves[4 * i + k] = dv.getUint32(base + LEAF_SIZE * i + 4 * k, true);
      for (let k = 0; k < 8; k++) p.leafCorners[8 * i + k] = dv.getInt32(base + LEAF_SIZE * i + 16 + 4 * k, true);
    }
    p.hangingSources = new Uint32Array(4 * H);
    p.hangingWeights = new Float32Array(4 * H);
    for (let j = 0; j < H; j++)
      for (let k = 0; k < 4; k++) {
        p.hangingSources[4 * j + k] = dv.getUint32(lay.hangingOffset + HANGING_SIZE * j + 4 * k, true);
        p.hangingWeights[4 * j + k] = dv.getFloat32(lay.hangingOffset + HANGING_SIZE * j + 16 + 4 * k, true);
      }
    if (lay.structure === KDTREE) {
      p.splitNodes = new Uint32Array(h.splitNodeCount);
      for (let j = 0; j < h.splitNodeCount; j++) p.splitNodes[j] = dv.getUint32(lay.splitOffset + 4 * j, true);
    }
  }
  checkContents(p, lay, negAt, fail);
  return p;
}
