/* Load time of .shprobe files in the page's code path (bench/bench_web_load.py, issue 32's bench row).
 *
 *   node bench_load.mjs JOB.json   ->  prints one JSON line of results
 * JOB: { chromium, base: "http://127.0.0.1:PORT" (the repository root served over HTTP), runs,
 *        files: [{ label, url (relative to base), path (the same file on disk) }] }
 *
 * Browser (Debian chromium headless, playwright-core, WebGL2 on SwiftShader as drive_page.mjs), per file
 * and run, in one page that imports web/src/ through the page's import map:
 *   fetch   fetch(url, { cache: 'no-store' }) + arrayBuffer()         (local HTTP server)
 *   parse   parseShprobe (web/src/shprobe.js: every check of the C reader)
 *   build   ProbeGrid (tree cell map, hanging expansion) + SchneeProbes.buildTexture: the N / D texels
 *           of the per-pixel 3D texture and the trees' brick levels per min cell on the CPU (the
 *           plugin's work before the GPU sees anything)
 *   upload  renderer.initTexture of both (texImage3D, RGBA32F or RGBA16F as the plugin picks; R32F) + a 1-pixel
 *           readPixels, so the GPU process has executed the upload when the clock stops
 * Node: parseShprobe of the same bytes read from disk (no fetch), `runs` times.
 * Every figure is in milliseconds; each list holds the runs in order (run 0 is the cold one). */
import { readFileSync } from 'node:fs';
import { performance } from 'node:perf_hooks';
import { chromium } from 'playwright-core';
import { parseShprobe } from '../src/shprobe.js';

const job = JSON.parse(readFileSync(process.argv[2], 'utf8'));
const runs = job.runs || 5;
const out = { runs, node: {}, browser: {}, userAgent: null, textureType: null };

for (const f of job.files) {
  const bytes = readFileSync(f.path);
  const ab = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  const t = [];
  let info;
  for (let r = 0; r < runs; r++) {
    const t0 = performance.now();
    const p = parseShprobe(ab, { name: f.label });
    t.push(performance.now() - t0);
    info = { bytes: bytes.byteLength, probes: p.probeCount, version: p.version, structure: p.structure,
      colours: p.colourCount, dims: [...p.gridDims] };
  }
  out.node[f.label] = { parse: t, ...info };
}

const HTML = `<!doctype html><html><head><meta charset="utf-8"><link rel="icon" href="data:,">
<script type="importmap">{ "imports": { "three": "./node_modules/three/build/three.module.js",
  "three/addons/": "./node_modules/three/examples/jsm/" } }</script></head><body>bench</body></html>`;

const browser = await chromium.launch({
  executablePath: job.chromium,
  args: ['--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});
try {
  const page = await browser.newPage();
  const errors = [];
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  page.on('pageerror', (e) => errors.push(`pageerror: ${e.message}`));
  await page.route('**/web/__bench_load.html', (route) => route.fulfill({ status: 200, body: HTML, contentType: 'text/html' }));
  await page.goto(`${job.base}/web/__bench_load.html`);
  for (const f of job.files) {
    const r = await page.evaluate(async ({ url, label, runs }) => {
      const THREE = await import('three');
      const { parseShprobe } = await import('./src/shprobe.js');
      const { ProbeGrid, SchneeProbes } = await import('./src/schnee-gltf-plugin.js');
      if (!window.__renderer) window.__renderer = new THREE.WebGLRenderer({ canvas: document.createElement('canvas') });
      const renderer = window.__renderer, gl = renderer.getContext();
      const useFloat = renderer.extensions.has('OES_texture_float_linear');
      const px = new Uint8Array(4);
      const res = { fetch: [], parse: [], build: [], upload: [], total: [], texture: null };
      for (let k = 0; k < runs; k++) {
        const t0 = performance.now();
        const buf = await (await fetch(url, { cache: 'no-store' })).arrayBuffer();
        const t1 = performance.now();
        const file = parseShprobe(buf, { name: label });
        const t2 = performance.now();
        const grid = new ProbeGrid(file, { name: label, uri: url }, 0);
        const probes = new SchneeProbes({ grids: [grid], fallback: new Float64Array(3), objects: [] });
        const tex = probes.buildTexture(useFloat);
        const t3 = performance.now();
        renderer.initTexture(tex);
        renderer.initTexture(probes.levelTexture);
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
        const t4 = performance.now();
        const glErr = gl.getError();
        if (glErr !== gl.NO_ERROR) throw new Error(`GL error ${glErr} after the upload of ${label}`);
        res.texture = { w: tex.image.width, h: tex.image.height, d: tex.image.depth,
          type: useFloat ? 'RGBA32F' : 'RGBA16F', bytes: tex.image.data.byteLength,
          levelBytes: probes.levelTexture.image.data.byteLength };
        tex.dispose();
        probes.levelTexture.dispose();
        res.fetch.push(t1 - t0); res.parse.push(t2 - t1); res.build.push(t3 - t2); res.upload.push(t4 - t3);
        res.total.push(t4 - t0);
      }
      return res;
    }, { url: f.url, label: f.label, runs });
    out.browser[f.label] = r;
  }
  out.userAgent = await page.evaluate(() => navigator.userAgent);
  out.gpu = await page.evaluate(() => {
    const gl = window.__renderer.getContext(), e = gl.getExtension('WEBGL_debug_renderer_info');
    return e ? gl.getParameter(e.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
  });
  out.errors = errors;
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
