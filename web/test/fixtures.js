/* The fixtures of the reader's tests: `.shprobe` files written by the project's real writer and the C
 * reader's verdict on each (web/test/make_fixtures.py). Made once per test process in a temporary
 * folder, or taken from SHPROBE_FIXTURES (a folder make_fixtures.py filled). The Python that runs it:
 * SCHNEE_PYTHON, else /usr/bin/python3 (Debian's, with numpy), else python3; the native module must be
 * built (scripts/build.sh). */
import { spawnSync } from 'node:child_process';
import { existsSync, mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

const HERE = dirname(fileURLToPath(import.meta.url));
export const REPO = resolve(HERE, '..', '..');

function python() {
  if (process.env.SCHNEE_PYTHON) return process.env.SCHNEE_PYTHON;
  return existsSync('/usr/bin/python3') ? '/usr/bin/python3' : 'python3';
}

let cached = null;

/** @returns {{dir: string, entries: Array<object>}} the manifest's entries (make_fixtures.py) */
export function fixtures() {
  if (cached) return cached;
  let dir = process.env.SHPROBE_FIXTURES;
  if (!dir) {
    const made = mkdtempSync(join(tmpdir(), 'shp-'));
    process.on('exit', () => rmSync(made, { recursive: true, force: true }));
    dir = made;
    const env = { ...process.env, PYTHONPATH: [join(REPO, 'addon'), process.env.PYTHONPATH].filter(Boolean).join(':') };
    const r = spawnSync(python(), [join(HERE, 'make_fixtures.py'), dir], { env, encoding: 'utf8' });
    if (r.status !== 0)
      throw new Error(`make_fixtures.py failed (${python()}, exit ${r.status}${r.error ? `, ${r.error.message}` : ''}):\n` +
        `${r.stdout}\n${r.stderr}`);
  }
  const manifest = JSON.parse(readFileSync(join(dir, 'manifest.json'), 'utf8'));
  cached = { dir, entries: manifest.entries };
  return cached;
}
