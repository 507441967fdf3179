// A coast in the web map (#15): the world's style draws the water layer above the colour map.
// usage: node tests/browser/coast_shot.mjs --url http://127.0.0.1:PORT --world NAME
//        --center LON,LAT --zoom Z --out FILE [--chromium PATH]
// Opens /?world=NAME, jumps to the centre and zoom with no pitch, waits for every tile, checks
// that water tiles were answered 200 and that no console error occurred, and writes FILE (the
// README picture tests/pictures/browser-coast.png).

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
const world = arg('world', 'coast');
const [lon, lat] = arg('center', '71.6,41.3').split(',').map(Number);
const zoom = Number(arg('zoom', '8'));
const out = arg('out', 'target/browser/coast.png');
const executablePath = arg('chromium', '/usr/bin/chromium');
fs.mkdirSync(path.dirname(out), { recursive: true });
let failed = false;
const fail = (msg) => {
  failed = true;
  console.error(`coast-shot: FAIL ${msg}`);
};
const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'terrasynth-chromium-'));
const context = await chromium.launchPersistentContext(userDataDir, {
  executablePath,
  headless: true,
  viewport: { width: 960, height: 600 },
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--no-first-run'],
});
const water = [];
try {
  const page = context.pages()[0] || (await context.newPage());
  page.on('console', (m) => {
    if (m.type() === 'error') fail(`console error: ${m.text()}`);
  });
  page.on('response', (r) => {
    if (r.url().includes('/water/')) water.push(r.status());
  });
  await page.goto(`${base}/?world=${encodeURIComponent(world)}`, { waitUntil: 'load' });
  await page.waitForFunction(() => window.terrasynth && window.terrasynth.ready, null, { timeout: 300000 });
  await page.evaluate(() => window.terrasynth.ready);
  await page.evaluate(async ([lon, lat, zoom]) => {
    const { map } = window.terrasynth;
    map.jumpTo({ center: [lon, lat], zoom, pitch: 0, bearing: 0 });
    await new Promise((resolve) => {
      const check = () => (map.loaded() && map.areTilesLoaded() ? resolve() : setTimeout(check, 250));
      check();
    });
  }, [lon, lat, zoom]);
  await page.screenshot({ path: out });
  if (water.length === 0) fail('no water tile was requested');
  if (water.some((s) => s !== 200 && s !== 304)) fail(`water tile statuses ${water}`);
  console.log(`coast-shot: ${water.length} water tiles, wrote ${out}`);
} finally {
  await context.close();
  fs.rmSync(userDataDir, { recursive: true, force: true });
}
process.exit(failed ? 1 : 0);
