/* Drives web/index.html in headless Chromium (playwright-core from web/node_modules, Debian's chromium,
 * WebGL2 on SwiftShader) for tests/web/test_web_page.py.
 *
 *   node drive_page.mjs JOB.json   ->  prints one JSON line of results
 * JOB: { chromium, pages: [{ url, frame: {w, h, out}, fulfil: {pattern, file} }] }: each page is opened,
 * its console errors and page errors collected, window.schnee.ready awaited; with `frame` the glTF
 * camera's linear float frame (RGBA float32, row 0 at the bottom) is written to `out`; with `fulfil`
 * requests matching `pattern` get the bytes of `file` instead (a malformed .shprobe). */
import { readFileSync, writeFileSync } from 'node:fs';
import { chromium } from 'playwright-core';

const job = JSON.parse(readFileSync(process.argv[2], 'utf8'));
const browser = await chromium.launch({
  executablePath: job.chromium,
  args: ['--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});
const results = [];
try {
  for (const pg of job.pages) {
    const page = await browser.newPage({ viewport: { width: pg.viewport?.w || 640, height: pg.viewport?.h || 360 } });
    const errors = [];
    page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
    page.on('pageerror', (e) => errors.push(`pageerror: ${e.message}`));
    if (pg.fulfil) {
      const body = readFileSync(pg.fulfil.file);
      await page.route(pg.fulfil.pattern, (route) => route.fulfill({ status: 200, body, contentType: 'application/octet-stream' }));
    }
    await page.goto(pg.url);
    const state = await page.evaluate(async () => {
      const s = await window.schnee.ready;
      const p = s.probes;
      return {
        ready: s.ready, error: s.error, timing: s.timing,
        webgl2: !!document.createElement('canvas').getContext('webgl2'),
        objects: p ? p.objects.map((o) => ({ name: o.name, grid: o.grid, weights: o.weights ? [...o.weights] : null })) : null,
      };
    });
    const r = { url: pg.url, errors, state };
    r.errorBox = { visible: await page.isVisible('#error'), text: await page.textContent('#error') };
    if (pg.frame) {
      const b64 = await page.evaluate(([w, h]) => window.schnee.readLinear(w, h), [pg.frame.w, pg.frame.h]);
      writeFileSync(pg.frame.out, Buffer.from(b64, 'base64'));
    }
    if (pg.screenshot) await page.screenshot({ path: pg.screenshot });
    results.push(r);
    await page.close();
  }
} finally {
  await browser.close();
}
console.log(JSON.stringify(results));
