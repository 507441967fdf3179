// terrasynth web map: the world's elevation as MapLibre 3D terrain with hillshade, switchable
// overlays (colour map, splat set 0 in false colour, vegetation, drainage), a world picker fed by
// /worlds, and a readout of zoom, cursor position and the elevation decoded from the terrarium
// tile under the cursor. MapLibre is loaded from this server (/vendor/maplibre-gl/), never a CDN.
// Sketch mode: draw ridge and valley lines (click to add points, "Finish line" or double-click
// to end one), choose an exemplar and a dictionary (listed with the admin token), submit to
// POST /admin/worlds/sketch, follow the job's progress and open the new world.
// The browser test drives the page through `window.terrasynth`.

const OVERLAYS = [
  { layer: 'color', label: 'Colour map', visible: true },
  { layer: 'splat', label: 'Splat set 0', query: 'set=0', visible: false },
  { layer: 'vegetation', label: 'Vegetation', visible: false },
  { layer: 'drainage', label: 'Drainage', visible: true },
];

const $ = (id) => document.getElementById(id);

function showMessage(text) {
  const m = $('message');
  m.textContent = text;
  m.hidden = false;
}

async function getJson(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  return r.json();
}

async function loadMapLibre() {
  try {
    const lib = await import('/vendor/maplibre-gl/maplibre-gl.mjs');
    const css = document.createElement('link');
    css.rel = 'stylesheet';
    css.href = '/vendor/maplibre-gl/maplibre-gl.css';
    document.head.appendChild(css);
    return lib;
  } catch (e) {
    showMessage('MapLibre GL JS is not installed on this server, so the map cannot be drawn. '
      + 'Run scripts/install_web.sh in the terrasynth directory (it runs npm ci) and reload. '
      + `(${e.message})`);
    return null;
  }
}

// Decoded terrarium tiles for the elevation readout, by "z/x/y" (the last 64).
const elevationTiles = new Map();

function elevationTile(world, z, x, y) {
  const key = `${z}/${x}/${y}`;
  let p = elevationTiles.get(key);
  if (!p) {
    p = fetch(`/tiles/${world}/elevation/${key}.png`)
      .then((r) => (r.ok ? r.blob() : null))
      .then((b) => (b ? createImageBitmap(b, { colorSpaceConversion: 'none', premultiplyAlpha: 'none' }) : null))
      .then((img) => {
        if (!img) return null;
        const c = new OffscreenCanvas(img.width, img.height);
        const ctx = c.getContext('2d', { willReadFrequently: true });
        ctx.drawImage(img, 0, 0);
        return ctx.getImageData(0, 0, img.width, img.height);
      })
      .catch(() => null);
    elevationTiles.set(key, p);
    if (elevationTiles.size > 64) elevationTiles.delete(elevationTiles.keys().next().value);
  }
  return p;
}

// Elevation in metres at (lon, lat) decoded from the zoom-z terrarium tile, or null.
async function elevationAt(world, z, lon, lat) {
  const n = 2 ** z;
  const latR = (Math.max(-85.05112878, Math.min(85.05112878, lat)) * Math.PI) / 180;
  const fx = ((lon + 180) / 360) * n;
  const fy = ((1 - Math.log(Math.tan(latR) + 1 / Math.cos(latR)) / Math.PI) / 2) * n;
  const x = Math.floor(fx);
  const y = Math.floor(fy);
  if (x < 0 || y < 0 || x >= n || y >= n) return null;
  const img = await elevationTile(world, z, x, y);
  if (!img) return null;
  const px = Math.min(img.width - 1, Math.floor((fx - x) * img.width));
  const py = Math.min(img.height - 1, Math.floor((fy - y) * img.height));
  const i = (py * img.width + px) * 4;
  const d = img.data;
  return d[i] * 256 + d[i + 1] + d[i + 2] / 256 - 32768;
}

// The style layer showing `layer`'s tiles, if the world's style has one.
function findOverlayLayer(map, layer) {
  const style = map.getStyle();
  for (const l of style.layers) {
    if (l.type !== 'raster' || !l.source) continue;
    const src = style.sources[l.source] || {};
    const urls = [src.url || '', ...(src.tiles || [])].join(' ');
    if (l.id === layer || urls.includes(`/${layer}/`) || urls.includes(`/${layer}.json`)) return l.id;
  }
  return null;
}

// Makes sure the map has a raster layer for `o` (from its TileJSON when the style has none) and
// returns its id.
async function ensureOverlay(map, world, o) {
  const existing = findOverlayLayer(map, o.layer);
  if (existing) return existing;
  const tj = await getJson(`/tiles/${world}/${o.layer}.json`);
  const tiles = tj.tiles.map((t) => (o.query && !t.includes(o.query) ? `${t}${t.includes('?') ? '&' : '?'}${o.query}` : t));
  const id = `overlay-${o.layer}`;
  map.addSource(id, {
    type: 'raster', tiles, tileSize: 256, minzoom: tj.minzoom, maxzoom: tj.maxzoom, bounds: tj.bounds,
    attribution: tj.attribution,
  });
  map.addLayer({ id, type: 'raster', source: id, layout: { visibility: 'none' } });
  return id;
}

async function main() {
  const params = new URLSearchParams(location.search);
  let worlds = [];
  try {
    worlds = await getJson('/worlds');
  } catch (e) {
    showMessage(`Cannot list the worlds: ${e.message}`);
    return;
  }
  if (worlds.length === 0) {
    showMessage('This server has no worlds.');
    return;
  }
  const world = worlds.find((w) => w.name === params.get('world')) || worlds[0];
  const picker = $('world');
  for (const w of worlds) {
    const opt = document.createElement('option');
    opt.value = w.name;
    opt.textContent = w.title || w.name;
    opt.selected = w.name === world.name;
    picker.appendChild(opt);
  }
  picker.addEventListener('change', () => {
    const p = new URLSearchParams(location.search);
    p.set('world', picker.value);
    location.search = p.toString();
  });
  const links = $('tilejson-links');
  for (const url of world.tilejson || []) {
    const a = document.createElement('a');
    a.href = url;
    a.textContent = url.split('/').pop().replace('.json', '');
    links.appendChild(a);
    links.appendChild(document.createTextNode(' '));
  }

  const maplibregl = await loadMapLibre();
  if (!maplibregl) return;

  const [lon, lat, zoom] = world.center;
  const map = new maplibregl.Map({
    container: 'map',
    style: `/styles/${world.name}.json`,
    center: [lon, lat],
    zoom: Math.max(world.minzoom, zoom),
    pitch: 60,
    maxPitch: 80,
    maxZoom: world.maxzoom + 2,
    // The browser test reads the drawn pixels back.
    canvasContextAttributes: { preserveDrawingBuffer: true },
  });
  map.addControl(new maplibregl.NavigationControl({ visualizePitch: true }));
  map.on('error', (e) => console.error('map error:', e.error ? e.error.message : e));

  const exaggeration = $('exaggeration');
  const ready = new Promise((resolve) => map.once('load', resolve)).then(async () => {
    if (!map.getTerrain()) {
      const style = map.getStyle();
      const dem = Object.keys(style.sources).find((k) => style.sources[k].type === 'raster-dem');
      if (dem) map.setTerrain({ source: dem, exaggeration: Number(exaggeration.value) });
    } else {
      map.setTerrain({ ...map.getTerrain(), exaggeration: Number(exaggeration.value) });
    }
    const box = $('layers');
    for (const o of OVERLAYS) {
      let id;
      try {
        id = await ensureOverlay(map, world.name, o);
      } catch (e) {
        console.warn(`layer ${o.layer} unavailable: ${e.message}`);
        continue;
      }
      o.id = id;
      const label = document.createElement('label');
      const cb = document.createElement('input');
      cb.type = 'checkbox';
      cb.id = `layer-${o.layer}`;
      cb.checked = o.visible;
      cb.addEventListener('change', () => setOverlay(o.layer, cb.checked));
      label.append(cb, ` ${o.label}`);
      box.appendChild(label);
      map.setLayoutProperty(id, 'visibility', o.visible ? 'visible' : 'none');
    }
  });

  function setOverlay(layer, on) {
    const o = OVERLAYS.find((v) => v.layer === layer);
    if (!o || !o.id) return false;
    map.setLayoutProperty(o.id, 'visibility', on ? 'visible' : 'none');
    const cb = $(`layer-${layer}`);
    if (cb) cb.checked = on;
    return true;
  }

  exaggeration.addEventListener('input', () => {
    $('exaggeration-value').textContent = exaggeration.value;
    const t = map.getTerrain();
    if (t) map.setTerrain({ ...t, exaggeration: Number(exaggeration.value) });
  });

  const showZoom = () => { $('readout-zoom').textContent = map.getZoom().toFixed(2); };
  map.on('zoom', showZoom);
  showZoom();
  let pending = 0;
  map.on('mousemove', async (e) => {
    const { lng, lat: la } = e.lngLat;
    $('readout-lon').textContent = lng.toFixed(5);
    $('readout-lat').textContent = la.toFixed(5);
    const ticket = ++pending;
    const z = Math.max(world.minzoom, Math.min(world.maxzoom, Math.floor(map.getZoom())));
    const h = await elevationAt(world.name, z, lng, la);
    if (ticket === pending) $('readout-elevation').textContent = h === null ? '–' : `${h.toFixed(1)} m`;
  });

  const sketch = sketchMode(map, ready);
  window.terrasynth = { map, world, ready, setOverlay, overlays: OVERLAYS, elevationAt, sketch };
}

// The sketch mode's state and controls; returns the functions the browser test calls.
function sketchMode(map, ready) {
  const lines = []; // { kind, coordinates: [[lon, lat], ...] }
  let current = null;
  const kind = () => document.querySelector('input[name="sketch-kind"]:checked').value;
  const token = () => $('sketch-token').value.trim();
  const status = (t) => { $('sketch-status').textContent = t; };

  function geojson() {
    const all = current && current.coordinates.length >= 2 ? [...lines, current] : lines;
    return {
      type: 'FeatureCollection',
      features: all.map((l) => ({
        type: 'Feature',
        properties: { kind: l.kind },
        geometry: { type: 'LineString', coordinates: l.coordinates },
      })),
    };
  }

  function redraw() {
    const src = map.getSource('sketch');
    if (src) src.setData(geojson());
    $('sketch-count').textContent = `${lines.length} line${lines.length === 1 ? '' : 's'}`;
  }

  ready.then(() => {
    map.addSource('sketch', { type: 'geojson', data: geojson() });
    map.addLayer({
      id: 'sketch-lines',
      type: 'line',
      source: 'sketch',
      paint: {
        'line-width': 3,
        'line-color': ['match', ['get', 'kind'], 'ridge', '#d72323', '#1e46e1'],
      },
    });
  });

  function startLine() {
    current = { kind: kind(), coordinates: [] };
    $('sketch-finish').disabled = false;
    map.doubleClickZoom.disable();
    map.getCanvas().style.cursor = 'crosshair';
    status(`drawing a ${current.kind}: click to add points`);
  }

  function finishLine() {
    if (current && current.coordinates.length >= 2) lines.push(current);
    current = null;
    $('sketch-finish').disabled = true;
    map.doubleClickZoom.enable();
    map.getCanvas().style.cursor = '';
    status('');
    redraw();
  }

  // Adds a whole line (the browser test draws through this as well as through clicks).
  function addLine(k, coordinates) {
    lines.push({ kind: k, coordinates });
    redraw();
  }

  map.on('click', (e) => {
    if (!current) return;
    current.coordinates.push([e.lngLat.lng, e.lngLat.lat]);
    redraw();
  });
  map.on('dblclick', () => { if (current) finishLine(); });

  // The world's bounds: the lines' bounding box with a margin of a fifth of its size (at least
  // 32 cells).
  function bounds(cell) {
    const pts = lines.flatMap((l) => l.coordinates);
    const xs = pts.map((p) => p[0]);
    const ys = pts.map((p) => p[1]);
    const [w, e, s, n] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
    const mx = Math.max((e - w) / 5, 16 * cell);
    const my = Math.max((n - s) / 5, 16 * cell);
    return [w - mx, s - my, e + mx, n + my];
  }

  async function loadChoices() {
    const ex = await fetch('/admin/exemplars', { headers: { Authorization: `Bearer ${token()}` } });
    if (!ex.ok) { status(`exemplars: HTTP ${ex.status}`); return false; }
    const fill = (id, items, label) => {
      const sel = $(id);
      sel.replaceChildren();
      for (const it of items) {
        const o = document.createElement('option');
        o.value = it.id;
        o.textContent = label(it);
        sel.appendChild(o);
      }
    };
    fill('sketch-exemplar', await ex.json(), (e) => `${e.name} (${e.width}×${e.height})`);
    fill('sketch-dictionary', await getJson('/dictionaries'), (d) => d.name || d.id.slice(0, 12));
    status('');
    return true;
  }

  async function submit() {
    if (current) finishLine();
    if (lines.length === 0) { status('draw at least one line'); return null; }
    const cell = Number($('sketch-cell').value);
    const name = $('sketch-name').value.trim();
    const body = {
      name,
      sketch: geojson(),
      bounds: bounds(cell),
      cell_size: cell,
      exemplars: [$('sketch-exemplar').value],
      dictionaries: [$('sketch-dictionary').value],
      seed: 1,
    };
    const auth = { Authorization: `Bearer ${token()}` };
    const r = await fetch('/admin/worlds/sketch', {
      method: 'POST',
      headers: { ...auth, 'Content-Type': 'application/json' },
      body: JSON.stringify(body),
    });
    const job = await r.json();
    if (r.status !== 202) { status(`refused: ${job.detail || r.status}`); return null; }
    const bar = $('sketch-progress');
    bar.hidden = false;
    for (;;) {
      const j = await (await fetch(`/admin/jobs/${job.id}`, { headers: auth })).json();
      bar.value = j.progress;
      status(`${j.stage} ${(100 * j.progress).toFixed(0)} %`);
      if (j.state === 'succeeded') {
        const link = $('sketch-open');
        link.href = `/?world=${encodeURIComponent(j.result)}`;
        link.hidden = false;
        status(`world ${j.result} is ready`);
        return j;
      }
      if (j.state !== 'queued' && j.state !== 'running') {
        status(`${j.state}: ${j.error || ''}`);
        return j;
      }
      await new Promise((res) => { setTimeout(res, 500); });
    }
  }

  $('sketch-draw').addEventListener('click', startLine);
  $('sketch-finish').addEventListener('click', finishLine);
  $('sketch-clear').addEventListener('click', () => { lines.length = 0; current = null; redraw(); });
  $('sketch-load').addEventListener('click', loadChoices);
  $('sketch-submit').addEventListener('click', submit);
  return { addLine, startLine, finishLine, loadChoices, submit, geojson, bounds };
}

main();
