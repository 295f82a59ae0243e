/* The JavaScript .shprobe reader against the C reader (native.read_shprobe through the CPython
 * module), on files the project's real writer made (web/test/make_fixtures.py): every version (1-4),
 * structure (grid, octree, tetrahedra, kd corner tree), representation (SH, ambient cube) and storage
 * (float32, binary16). Expected values are the C reader's, compared exactly (float32 values and
 * binary16 expanded to float are exact in both); every refusal must carry the C reader's result code
 * and the same message, word for word, from the file reader (with the path) and the memory reader. */
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import { SHPROBE_STRUCTURES, ShprobeError, parseShprobe } from '../src/shprobe.js';
import { fixtures } from './fixtures.js';

const { entries } = fixtures();
const group = (g) => entries.filter((e) => e.group === g);

function plain(v) {
  return ArrayBuffer.isView(v) ? Array.from(v) : v;
}

/* Reads one fixture with the JS reader and checks it decides as the C reader did. */
function agreesWithC(e) {
  const bytes = readFileSync(e.path);
  let js, err;
  try {
    js = parseShprobe(bytes, { name: e.path });
  } catch (x) {
    err = x;
  }
  if (e.c.ok) {
    assert.equal(err, undefined, `${e.name}: the C reader accepts it, the JS reader refuses: ${err && err.message}`);
    for (const [k, want] of Object.entries(e.c.values)) assert.deepStrictEqual(plain(js[k]), want, `${e.name}: ${k}`);
    return js;
  }
  assert.ok(err, `${e.name}: the C reader refuses it (${e.c.message}), the JS reader accepts it`);
  assert.ok(err instanceof ShprobeError, `${e.name}: not a ShprobeError: ${err && err.stack}`);
  assert.equal(err.code, e.c.code, `${e.name}: result code`);
  assert.equal(err.message, e.c.message, `${e.name}: message`);
  assert.equal(err.file, e.path);
  let mem;
  try {
    parseShprobe(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength));
  } catch (x) {
    mem = x;
  }
  assert.equal(mem && mem.message, e.c.memoryMessage, `${e.name}: message without a file name`);
  return err;
}

test('every version, structure, representation and storage reads back as the C reader reads it', () => {
  const valid = group('valid');
  const seen = { version: new Set(), structure: new Set(), representation: new Set(), storage: new Set(), maxBand: new Set() };
  for (const e of valid) {
    assert.ok(e.c.ok, `${e.name}: the C reader refuses a file of the real writer: ${e.c.message}`);
    const p = agreesWithC(e);
    for (const k of Object.keys(seen)) seen[k].add(p[k]);
    assert.equal(p.coeffs.length, p.probeCount * p.colourCount * 3);
  }
  assert.deepStrictEqual([...seen.version].sort(), [1, 2, 3, 4]);
  assert.deepStrictEqual([...seen.structure].sort(), [...SHPROBE_STRUCTURES].sort());
  assert.deepStrictEqual([...seen.representation].sort(), ['ambientCube', 'sh']);
  assert.deepStrictEqual([...seen.storage].sort(), ['float16', 'float32']);
  assert.deepStrictEqual([...seen.maxBand].sort(), [0, 1, 2, 3, 4]);
  assert.ok(valid.length >= 25, `${valid.length} valid files`);
});

test('binary16 colours expand exactly (zero, -0, subnormals, 65504)', () => {
  const e = entries.find((x) => x.name === 'v3_grid_sh_f16.shprobe');
  const p = parseShprobe(readFileSync(e.path));
  const first = Array.from(p.coeffs.subarray(0, 8));
  assert.deepStrictEqual(first, [0, -0, 2 ** -24, -(2 ** -24), 1023 * 2 ** -24, 65504, -65504, 0.333251953125]);
});

test('every refusal of the C reader: same result code and message', async (t) => {
  const refusals = group('refusal');
  assert.ok(refusals.length >= 100, `${refusals.length} malformed variants`);
  for (const e of refusals)
    await t.test(e.name, () => {
      if (e.expect !== null) {
        assert.ok(!e.c.ok, `fixture: the C reader accepts ${e.name}, meant to be refused (${e.expect})`);
        assert.ok(e.c.message.includes(e.expect), `fixture: C says "${e.c.message}", meant "${e.expect}"`);
      }
      agreesWithC(e);
    });
});

test('seeded random corruptions: the same verdict, values or message as the C reader', () => {
  const random = group('random');
  assert.ok(random.length >= 200);
  for (const e of random) agreesWithC(e);
  const refused = random.filter((e) => !e.c.ok).length;
  assert.ok(refused > 50 && refused < random.length, `${refused} of ${random.length} refused: both verdicts exercised`);
});

test('reads a view of the file inside a larger buffer, never past the view', () => {
  const e = entries.find((x) => x.name === 'v4_kd_seed1.shprobe');
  const file = readFileSync(e.path);
  const big = new Uint8Array(file.length + 64).fill(0xff);
  big.set(file, 32);
  const view = big.subarray(32, 32 + file.length);
  const p = parseShprobe(view, { name: 'view' });
  assert.deepStrictEqual(Array.from(p.splitNodes), e.c.values.splitNodes);
  assert.deepStrictEqual(Array.from(parseShprobe(new DataView(big.buffer, 32, file.length)).coeffs), e.c.values.coeffs);
  assert.throws(() => parseShprobe(big.subarray(32, 32 + file.length + 1), { name: 'x' }),
    { name: 'ShprobeError', code: 'malformed file', message: /^x: 1 bytes of trailing data after the kd corner tree/ });
  assert.throws(() => parseShprobe('SPHR'), TypeError);
});
