// The instance tiles (#17) in the web map: MapLibre GL JS (an independent MVT decoder) renders
// the instances layers of the world's style at zooms 15 and 16 over spruce forest and steppe east
// of the Ala-Archa (74.75°E, 42.66°N), with the colour map under them.
// usage: node tests/browser/instances_test.mjs --url http://127.0.0.1:PORT --out DIR [--chromium PATH]
// Checks: instance tiles answered 200 with the MVT type, gzip-coded, rendered features with the MVT's
// properties (species, height_m, radius_m, rotation_deg, age), more than one species, no console
// error. Writes DIR/instances-z16.png (the README picture).

import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { chromium } from 'playwright-core';

const argv = process.argv.slice(2);
const arg = (name, dflt) => {
  const i = argv.indexOf(`--${name}`);
  return i >= 0 ? argv[i + 1] : dflt;
};
const base = arg('url', 'http://127.0.0.1:8080');
const out = arg('out', 'target/browser');
const executablePath = arg('chromium', '/usr/bin/chromium');
fs.mkdirSync(out, { recursive: true });
const log = (msg) => console.log(`instances-test: ${msg}`);
let failed = false;
const fail = (msg) => {
  failed = true;
  console.error(`instances-test: FAIL ${msg}`);
};

const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'terrasynth-chromium-'));
const context = await chromium.launchPersistentContext(userDataDir, {
  executablePath,
  headless: true,
  viewport: { width: 960, height: 600 },
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--no-first-run'],
});
const mvt = [];
try {
  const page = context.pages()[0] || (await context.newPage());
  page.on('console', (m) => {
    if (m.type() === 'error') fail(`console error: ${m.text()}`);
  });
  page.on('pageerror', (e) => fail(`uncaught exception: ${e.message}`));
  page.on('response', (r) => {
    if (r.url().includes('/instances/') && r.url().endsWith('.mvt')) {
      const h = r.headers();
      mvt.push({ url: r.url(), status: r.status(), type: h['content-type'], coding: h['content-encoding'] });
    }
  });
  await page.goto(`${base}/`, { waitUntil: 'load' });
  await page.waitForFunction(() => window.terrasynth && window.terrasynth.ready, null, { timeout: 120000 });
  await page.evaluate(() => window.terrasynth.ready);
  for (const zoom of [15, 16]) {
    const found = await page.evaluate(async (zoom) => {
      const { map } = window.terrasynth;
      map.jumpTo({ center: [74.752, 42.662], zoom, pitch: 0, bearing: 0 });
      const idle = () => new Promise((resolve) => {
        const check = () => (map.loaded() && map.areTilesLoaded() ? resolve() : setTimeout(check, 250));
        check();
      });
      await idle();
      await new Promise((r) => setTimeout(r, 1500));
      await idle();
      const layers = map.getStyle().layers.filter((l) => l.source === 'instances').map((l) => l.id);
      const feats = map.queryRenderedFeatures({ layers });
      return {
        layers,
        count: feats.length,
        species: [...new Set(feats.map((f) => f.properties.species))],
        sample: feats.slice(0, 1).map((f) => f.properties),
      };
    }, zoom);
    log(`zoom ${zoom}: layers ${found.layers.join(', ')}; ${found.count} rendered instances of ${found.species.join(', ')}; e.g. ${JSON.stringify(found.sample)}`);
    if (found.count < 20) fail(`zoom ${zoom}: only ${found.count} instances rendered`);
    if (found.species.length < 2) fail(`zoom ${zoom}: one species only`);
    const p = found.sample[0] || {};
    for (const k of ['species', 'height_m', 'radius_m', 'rotation_deg', 'age']) {
      if (!(k in p)) fail(`zoom ${zoom}: property ${k} missing`);
    }
    if (zoom === 16) await page.screenshot({ path: path.join(out, 'instances-z16.png') });
  }
  const bad = mvt.filter((r) => r.status !== 200 && r.status !== 304);
  log(`${mvt.length} instance tiles answered, ${bad.length} not 200/304`);
  if (mvt.length === 0) fail('no instance tile was requested');
  if (bad.length) fail(`instance tiles failed: ${JSON.stringify(bad.slice(0, 3))}`);
  if (mvt.some((r) => r.status === 200 && r.type !== 'application/vnd.mapbox-vector-tile')) fail('wrong content type');
  // The browser accepts gzip: the tiles it rendered came gzip-coded.
  const plain = mvt.filter((r) => r.status === 200 && r.coding !== 'gzip');
  if (plain.length) fail(`instance tiles not gzip-coded: ${JSON.stringify(plain.slice(0, 3))}`);
} finally {
  await context.close();
}
if (failed) process.exit(1);
log('ok');
