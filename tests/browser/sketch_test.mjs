// Browser test of the web map's sketch mode, in Debian's Chromium driven by playwright-core with
// software WebGL2. Run by scripts/browser_test.sh with the admin enabled:
//   TERRASYNTH_ADMIN_TOKEN=T MAP_TEST=tests/browser/sketch_test.mjs scripts/browser_test.sh [--bin PATH]
// The token is read from TERRASYNTH_ADMIN_TOKEN; the exemplar is a crop of the committed Tien Shan
// grid cut with the terrasynth binary (TERRASYNTH_BIN, default target/release/terrasynth).
//
// Steps: upload the exemplar and build a small dictionary through the admin API (set-up, not the
// page); then in the page: enter the token, list the exemplars and dictionaries, draw a ridge and
// two valleys by clicking on the map, submit, wait for the job to succeed (the progress bar moves),
// open the new world and check that its elevation tiles are answered 200 and the canvas is drawn.
// Asserts no console errors, uncaught exceptions or HTTP errors. Screenshots go to --out.

import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { chromium } from 'playwright-core';

const argv = process.argv.slice(2);
const arg = (name, dflt) => {
  const i = argv.indexOf(`--${name}`);
  return i >= 0 && i + 1 < argv.length ? argv[i + 1] : dflt;
};
const base = arg('url', 'http://127.0.0.1:18090').replace(/\/$/, '');
const out = arg('out', 'target/browser');
const executablePath = arg('chromium', '/usr/bin/chromium');
const token = process.env.TERRASYNTH_ADMIN_TOKEN || '';
const bin = process.env.TERRASYNTH_BIN || 'target/release/terrasynth';
const MIN_VARIANCE = 25;
const TIMEOUT_MS = 600_000;
// The store outlives a run (scripts/browser_test.sh keeps it): a fresh world name each time.
const WORLD = `browser-sketch-${Date.now()}`;

fs.mkdirSync(out, { recursive: true });
const failures = [];
const fail = (msg) => {
  failures.push(msg);
  console.error(`FAIL: ${msg}`);
};
const log = (msg) => console.log(`sketch-test: ${msg}`);
if (!token) {
  console.error('set TERRASYNTH_ADMIN_TOKEN (the server must have the admin API enabled)');
  process.exit(2);
}
const auth = { Authorization: `Bearer ${token}` };

// Set-up through the API: an exemplar (the Talas range, 256 × 256 cells) and a small dictionary.
const crop = path.join(out, 'sketch-exemplar.tif');
execFileSync(bin, ['crop', '--input', 'config/data/tienshan_west_gebco15s.tif', '--window', '1600,600,256,256', '--output', crop]);
let r = await fetch(`${base}/admin/exemplars?name=browser-talas`, {
  method: 'POST', headers: { ...auth, 'Content-Type': 'image/tiff' }, body: fs.readFileSync(crop),
});
if (r.status !== 201) throw new Error(`exemplar upload: HTTP ${r.status} ${await r.text()}`);
const exemplar = (await r.json()).id;
r = await fetch(`${base}/admin/dictionaries`, {
  method: 'POST',
  headers: { ...auth, 'Content-Type': 'application/json' },
  body: JSON.stringify({ name: 'browser-talas', exemplars: [exemplar], atoms: 16, patch: 16, stride: 16, learning: 'medoids:1' }),
});
if (r.status !== 202) throw new Error(`dictionary build: HTTP ${r.status} ${await r.text()}`);
const buildJob = (await r.json()).id;
let dictionary = null;
for (let t0 = Date.now(); Date.now() - t0 < TIMEOUT_MS;) {
  const j = await (await fetch(`${base}/admin/jobs/${buildJob}`, { headers: auth })).json();
  if (j.state === 'succeeded') { dictionary = j.result; break; }
  if (j.state !== 'queued' && j.state !== 'running') throw new Error(`dictionary build ${j.state}: ${j.error}`);
  await new Promise((res) => { setTimeout(res, 500); });
}
if (!dictionary) throw new Error('the dictionary build did not end');
log(`set-up: exemplar ${exemplar.slice(0, 12)}, dictionary ${dictionary.slice(0, 12)}`);

const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'terrasynth-chromium-'));
const context = await chromium.launchPersistentContext(userDataDir, {
  executablePath,
  headless: true,
  viewport: { width: 960, height: 600 },
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--disable-background-networking', '--disable-component-update', '--no-first-run'],
});
const responses = [];
try {
  const page = context.pages()[0] || (await context.newPage());
  page.on('console', (m) => { if (m.type() === 'error') fail(`console error: ${m.text()}`); });
  page.on('pageerror', (e) => fail(`uncaught exception: ${e.message}`));
  page.on('response', (res) => {
    responses.push({ url: res.url(), status: res.status() });
    if (res.status() >= 400) fail(`HTTP ${res.status()} for ${res.url()}`);
  });
  const waitIdle = async (what) => {
    const t0 = Date.now();
    await page.waitForFunction(() => {
      const m = window.terrasynth && window.terrasynth.map;
      return !!m && m.loaded() && m.areTilesLoaded() && !m.isMoving();
    }, null, { timeout: TIMEOUT_MS, polling: 250 });
    await page.evaluate(() => new Promise((res) => {
      window.terrasynth.map.once('idle', res);
      window.terrasynth.map.triggerRepaint();
    }));
    log(`${what}: idle after ${((Date.now() - t0) / 1000).toFixed(1)} s`);
  };
  const canvasVariance = () => page.evaluate(() => {
    const src = window.terrasynth.map.getCanvas();
    const c = document.createElement('canvas');
    c.width = 256;
    c.height = 160;
    const ctx = c.getContext('2d');
    ctx.drawImage(src, 0, 0, c.width, c.height);
    const d = ctx.getImageData(0, 0, c.width, c.height).data;
    let s = 0;
    let s2 = 0;
    const n = d.length / 4;
    for (let i = 0; i < d.length; i += 4) {
      const g = 0.299 * d[i] + 0.587 * d[i + 1] + 0.114 * d[i + 2];
      s += g;
      s2 += g * g;
    }
    return s2 / n - (s / n) ** 2;
  });

  await page.goto(`${base}/`, { waitUntil: 'load' });
  await page.waitForFunction(() => window.terrasynth && window.terrasynth.ready, null, { timeout: TIMEOUT_MS });
  await page.evaluate(() => window.terrasynth.ready);
  // A flat view at zoom 9 so that clicks land where they are aimed.
  await page.evaluate(() => window.terrasynth.map.jumpTo({ center: [70.3, 42.3], zoom: 9, pitch: 0, bearing: 0 }));
  await waitIdle('sketch view');

  await page.click('#sketch-panel summary');
  await page.fill('#sketch-token', token);
  await page.click('#sketch-load');
  await page.waitForFunction((id) => [...document.querySelectorAll('#sketch-exemplar option')].some((o) => o.value === id), exemplar, { timeout: 30_000 });
  await page.selectOption('#sketch-exemplar', exemplar);
  await page.selectOption('#sketch-dictionary', dictionary);

  // Draw by clicking on the map: a ridge across the middle, a valley above and one below.
  const box = await page.locator('#map').boundingBox();
  const at = (fx, fy) => [box.x + fx * box.width, box.y + fy * box.height];
  const draw = async (kind, pts) => {
    await page.check(`input[name="sketch-kind"][value="${kind}"]`);
    await page.click('#sketch-draw');
    for (const [fx, fy] of pts) {
      const [x, y] = at(fx, fy);
      await page.mouse.click(x, y);
      await page.waitForTimeout(150);
    }
    await page.click('#sketch-finish');
  };
  await draw('ridge', [[0.3, 0.5], [0.5, 0.45], [0.7, 0.52]]);
  await draw('valley', [[0.3, 0.3], [0.5, 0.28], [0.7, 0.32]]);
  await draw('valley', [[0.3, 0.72], [0.5, 0.7], [0.7, 0.74]]);
  const drawn = await page.evaluate(() => window.terrasynth.sketch.geojson());
  log(`drew ${drawn.features.length} lines: ${drawn.features.map((f) => `${f.properties.kind}/${f.geometry.coordinates.length}`).join(' ')}`);
  if (drawn.features.length !== 3) fail(`drew ${drawn.features.length} lines, not 3`);
  await page.screenshot({ path: path.join(out, 'sketch-drawn.png') });

  await page.fill('#sketch-name', WORLD);
  await page.click('#sketch-submit');
  await page.waitForFunction(() => !document.getElementById('sketch-open').hidden
    || /failed|cancelled|refused/.test(document.getElementById('sketch-status').textContent), null, { timeout: TIMEOUT_MS, polling: 500 });
  const statusText = await page.textContent('#sketch-status');
  log(`job: ${statusText}`);
  if (!/is ready/.test(statusText)) fail(`the sketch job did not succeed: ${statusText}`);
  const href = await page.getAttribute('#sketch-open', 'href');

  // The new world, opened from the link.
  await page.goto(`${base}${href}`, { waitUntil: 'load' });
  await page.waitForFunction(() => window.terrasynth && window.terrasynth.ready, null, { timeout: TIMEOUT_MS });
  await page.evaluate(() => window.terrasynth.ready);
  const name = await page.evaluate(() => window.terrasynth.world.name);
  if (name !== WORLD) fail(`the link opened world ${name}, not ${WORLD}`);
  await waitIdle('the new world');
  const v = await canvasVariance();
  log(`new world: canvas grey-level variance ${v.toFixed(1)}`);
  if (!(v > MIN_VARIANCE)) fail(`the new world's canvas looks blank (variance ${v.toFixed(1)})`);
  const tiles = responses.filter((x) => x.url.includes(`/tiles/${WORLD}/elevation/`) && x.status === 200);
  log(`new world: ${tiles.length} elevation tiles answered 200`);
  if (tiles.length === 0) fail('no elevation tile of the new world was answered 200');
  await page.screenshot({ path: path.join(out, 'sketch-world.png') });
} catch (e) {
  fail(`test aborted: ${e.message}`);
} finally {
  await context.close();
  fs.rmSync(userDataDir, { recursive: true, force: true });
}
if (failures.length > 0) {
  console.error(`sketch browser test FAILED (${failures.length} problems)`);
  process.exit(1);
}
log('passed');
