// Browser test of the web map at `/`, in Debian's Chromium driven by playwright-core, with
// software WebGL2 (SwiftShader). Run by scripts/browser_test.sh, which starts the release server;
// usage: node tests/browser/map_test.mjs --url http://127.0.0.1:PORT --out DIR [--chromium PATH]
//
// Asserts: no console errors, no uncaught exceptions, no failed requests and no HTTP error
// responses; elevation tiles and tiles of every overlay layer (colour, splat, vegetation,
// drainage) requested and answered 200/304; the canvas is not blank (pixel variance above a
// threshold) at the start and after a scripted fly-to at zoom 13; the readout shows a plausible
// decoded elevation; the README's minimal page (/minimal.html) draws terrain without console
// errors. Writes screenshots and the tile request sequence (a trace for
// scripts/loadtest.sh --trace) to DIR.

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
const LAYERS = ['color', 'splat', 'vegetation', 'drainage'];
// Minimum variance of the canvas's grey levels (0..255) for it to count as drawn: a blank or
// single-colour canvas has ~0; a rendered hillshaded terrain has hundreds.
const MIN_VARIANCE = 25;
// Software WebGL on a 2-core machine is slow: generous waits (the test fails, not hangs, after).
const IDLE_TIMEOUT_MS = 300_000;
const SCREENSHOT_TIMEOUT_MS = 180_000;

fs.mkdirSync(out, { recursive: true });
const failures = [];
const fail = (msg) => {
  failures.push(msg);
  console.error(`FAIL: ${msg}`);
};
const log = (msg) => console.log(`browser-test: ${msg}`);

const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'terrasynth-chromium-'));
const context = await chromium.launchPersistentContext(userDataDir, {
  executablePath,
  headless: true,
  viewport: { width: 960, height: 600 },
  args: [
    '--no-sandbox',
    '--use-angle=swiftshader',
    '--enable-unsafe-swiftshader',
    '--disable-background-networking',
    '--disable-component-update',
    '--no-first-run',
  ],
});

const responses = []; // { url, status }
const tileRequests = []; // request URLs of tiles, in order
try {
  const page = context.pages()[0] || (await context.newPage());
  page.on('console', (m) => {
    if (m.type() === 'error') fail(`console error: ${m.text()}`);
  });
  page.on('pageerror', (e) => fail(`uncaught exception: ${e.message}`));
  page.on('requestfailed', (r) => {
    // Requests MapLibre aborts itself (tiles scrolled out of view) are not failures.
    const why = r.failure() ? r.failure().errorText : '';
    if (!why.includes('ERR_ABORTED')) fail(`request failed: ${r.url()} (${why})`);
  });
  page.on('request', (r) => {
    if (r.url().startsWith(`${base}/tiles/`) && !r.url().endsWith('.json')) tileRequests.push(r.url());
    if (!r.url().startsWith(base) && !r.url().startsWith('data:') && !r.url().startsWith('blob:')) {
      fail(`request outside the server: ${r.url()}`);
    }
  });
  page.on('response', (r) => {
    responses.push({ url: r.url(), status: r.status() });
    if (r.status() >= 400) fail(`HTTP ${r.status()} for ${r.url()}`);
  });

  const waitIdle = async (what) => {
    const t0 = Date.now();
    await page.waitForFunction(
      () => {
        const m = window.terrasynth && window.terrasynth.map;
        return !!m && m.loaded() && m.areTilesLoaded() && !m.isMoving();
      },
      null,
      { timeout: IDLE_TIMEOUT_MS, polling: 250 },
    );
    // Let a last frame render.
    await page.evaluate(
      () =>
        new Promise((r) => {
          window.terrasynth.map.once('idle', r);
          window.terrasynth.map.triggerRepaint();
        }),
    );
    log(`${what}: idle after ${((Date.now() - t0) / 1000).toFixed(1)} s`);
  };
  // Grey-level variance of the map's canvas, read inside MapLibre's `render` event right after a
  // frame is drawn: that also works on pages whose WebGL canvas does not preserve its drawing
  // buffer (the README's minimal page), where a later read sees an empty buffer.
  const canvasVariance = () =>
    page.evaluate(
      () =>
        new Promise((resolve) => {
          const map = window.terrasynth.map;
          map.once('render', () => {
            const c = document.createElement('canvas');
            c.width = 256;
            c.height = 160;
            const ctx = c.getContext('2d');
            ctx.drawImage(map.getCanvas(), 0, 0, c.width, c.height);
            const d = ctx.getImageData(0, 0, c.width, c.height).data;
            let s = 0;
            let s2 = 0;
            const n = d.length / 4;
            for (let i = 0; i < d.length; i += 4) {
              const g = 0.299 * d[i] + 0.587 * d[i + 1] + 0.114 * d[i + 2];
              s += g;
              s2 += g * g;
            }
            resolve(s2 / n - (s / n) ** 2);
          });
          map.triggerRepaint();
        }),
    );
  const checkDrawn = async (what) => {
    const v = await canvasVariance();
    log(`${what}: canvas grey-level variance ${v.toFixed(1)}`);
    if (!(v > MIN_VARIANCE)) fail(`${what}: canvas looks blank (variance ${v.toFixed(1)} ≤ ${MIN_VARIANCE})`);
  };
  const answered = (layer) =>
    responses.filter((r) => r.url.includes(`/tiles/`) && r.url.includes(`/${layer}/`) && (r.status === 200 || r.status === 304));

  log(`opening ${base}/`);
  await page.goto(`${base}/`, { waitUntil: 'load' });
  await page.waitForFunction(() => window.terrasynth && window.terrasynth.ready, null, { timeout: IDLE_TIMEOUT_MS });
  await page.evaluate(() => window.terrasynth.ready);
  const hasTerrain = await page.evaluate(() => !!window.terrasynth.map.getTerrain());
  if (!hasTerrain) fail('the map has no 3D terrain');
  await waitIdle('first view');
  await checkDrawn('first view');
  await page.screenshot({ timeout: SCREENSHOT_TIMEOUT_MS, path: path.join(out, 'overview.png') });

  // Over the mountains (Kyrgyz Ala-Too, zoom 11), where every layer has something to show,
  // switch each overlay on alone.
  await page.evaluate(() => window.terrasynth.map.jumpTo({ center: [74.6, 42.45], zoom: 11, pitch: 55 }));
  await waitIdle('zoom 11 over the Ala-Too');
  for (const layer of LAYERS) {
    const ok = await page.evaluate(
      (l) => {
        for (const o of window.terrasynth.overlays) window.terrasynth.setOverlay(o.layer, o.layer === l);
        return window.terrasynth.setOverlay(l, true);
      },
      layer,
    );
    if (!ok) {
      fail(`layer ${layer} cannot be switched on`);
      continue;
    }
    await waitIdle(`layer ${layer}`);
    const n = answered(layer).length;
    log(`layer ${layer}: ${n} tiles answered 200/304, canvas variance ${(await canvasVariance()).toFixed(1)}`);
    if (n === 0) fail(`no ${layer} tile was answered 200/304`);
    await page.screenshot({ timeout: SCREENSHOT_TIMEOUT_MS, path: path.join(out, `layer-${layer}.png`) });
  }
  if (answered('elevation').length === 0) fail('no elevation tile was answered 200/304');

  // Colour map and drainage together, then a fly-to at zoom 13 over the Kyrgyz Ala-Too.
  await page.evaluate(() => {
    for (const o of window.terrasynth.overlays) window.terrasynth.setOverlay(o.layer, o.layer === 'color' || o.layer === 'drainage');
  });
  await waitIdle('colour + drainage');
  await page.screenshot({ timeout: SCREENSHOT_TIMEOUT_MS, path: path.join(out, 'color-drainage.png') });
  await page.evaluate(() => window.terrasynth.map.flyTo({ center: [74.55, 42.62], zoom: 13, pitch: 65, bearing: 20, duration: 3000 }));
  await waitIdle('fly-to zoom 13');
  const zoom = await page.evaluate(() => window.terrasynth.map.getZoom());
  if (Math.abs(zoom - 13) > 0.01) fail(`zoom after the fly-to is ${zoom}, not 13`);
  await checkDrawn('zoom 13');
  if (!(await page.evaluate(() => !!window.terrasynth.map.getTerrain()))) fail('no terrain after the fly-to');
  await page.screenshot({ timeout: SCREENSHOT_TIMEOUT_MS, path: path.join(out, 'zoom13.png') });

  // A short pan and zoom, as a user would, for the recorded trace.
  for (const [dx, dy] of [[300, 0], [0, 200], [-300, 0]]) {
    await page.evaluate(([x, y]) => window.terrasynth.map.panBy([x, y], { duration: 500 }), [dx, dy]);
    await waitIdle(`pan ${dx},${dy}`);
  }
  await page.evaluate(() => window.terrasynth.map.zoomTo(14, { duration: 800 }));
  await waitIdle('zoom 14');

  // The readout decodes the elevation under the cursor from the terrarium tile.
  const box = await page.locator('#map').boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height * 0.7);
  await page.waitForFunction(() => /m$/.test(document.getElementById('readout-elevation').textContent), null, { timeout: 30_000 });
  const readout = await page.evaluate(() => ({
    zoom: document.getElementById('readout-zoom').textContent,
    lon: document.getElementById('readout-lon').textContent,
    lat: document.getElementById('readout-lat').textContent,
    elevation: document.getElementById('readout-elevation').textContent,
  }));
  log(`readout: ${JSON.stringify(readout)}`);
  const h = parseFloat(readout.elevation);
  if (!(h > 200 && h < 7500)) fail(`readout elevation ${readout.elevation} is not a plausible Tien Shan height`);
  if (!(Math.abs(parseFloat(readout.lon) - 74.55) < 0.5)) fail(`readout longitude ${readout.lon} is not near the view`);

  // The README's minimal MapLibre page, as the server serves it (the same file): terrain drawn,
  // no console error (the listeners above stay on).
  log(`opening ${base}/minimal.html`);
  await page.goto(`${base}/minimal.html`, { waitUntil: 'load' });
  // `window.map` is the page's <div id="map"> (a named property of window) until the module
  // script, after its dynamic import of MapLibre, replaces it with the map: wait for the map.
  await page.waitForFunction(() => !!window.map && typeof window.map.loaded === 'function', null,
    { timeout: IDLE_TIMEOUT_MS });
  await page.evaluate(() => { window.terrasynth = { map: window.map }; });
  await waitIdle('minimal page');
  await checkDrawn('minimal page');
  const terrain = await page.evaluate(() => !!window.map.getTerrain());
  if (!terrain) fail('minimal page: no 3D terrain');
  await page.screenshot({ path: path.join(out, 'minimal.png'), timeout: SCREENSHOT_TIMEOUT_MS });
} catch (e) {
  fail(`test aborted: ${e.message}`);
} finally {
  await context.close();
  fs.rmSync(userDataDir, { recursive: true, force: true });
}

fs.writeFileSync(path.join(out, 'browser-trace.txt'), tileRequests.join('\n') + '\n');
log(`${tileRequests.length} tile requests recorded in ${path.join(out, 'browser-trace.txt')}`);
if (failures.length > 0) {
  console.error(`browser test FAILED (${failures.length} problems)`);
  process.exit(1);
}
log('passed');
