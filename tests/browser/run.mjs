// Browser tests: Debian's Chromium (headless, WebGL through SwiftShader) driven by playwright-core
// opens citymesh's pages on the Karlsruhe data and on the demo city, waits for tiles, and checks:
// no page errors or failed requests, buildings visible (the screenshot differs from an empty
// scene where the city is), the 3D Tiles load in CesiumJS and in 3d-tiles-renderer, and their
// content lies inside the bounding volumes the client computes. Screenshots go to
// artifacts/browser/.
//
// Usage: node tests/browser/run.mjs   (after `cargo build --release`; reads ../shared/data or
// $CITYMESH_DATA_DIR). Prints "N passed, M failed" and exits 1 on any failure.
import { chromium } from 'playwright-core';
import { PNG } from 'pngjs';
import { spawn } from 'node:child_process';
import { createServer } from 'node:http';
import { mkdirSync, existsSync, rmSync } from 'node:fs';
import { readFile, writeFile } from 'node:fs/promises';
import { resolve, dirname, extname } from 'node:path';
import { fileURLToPath } from 'node:url';

const root = resolve(dirname(fileURLToPath(import.meta.url)), '../..');
const data = resolve(process.env.CITYMESH_DATA_DIR ?? resolve(root, '../shared/data'));
const bin = resolve(root, 'target/release/citymesh');
const artifacts = resolve(root, 'artifacts/browser');
mkdirSync(artifacts, { recursive: true });
const chromiumPath = process.env.CHROMIUM ?? '/usr/bin/chromium';
if (!existsSync(bin)) { console.error(`${bin} is missing: run cargo build --release`); process.exit(2); }
if (!existsSync(chromiumPath)) { console.error(`${chromiumPath} is missing: apt-get install chromium`); process.exit(2); }

/** A local imagery server on 127.0.0.1: every XYZ tile a plain 256 x 256 grey PNG. */
function startImagery() {
  const png = new PNG({ width: 256, height: 256 });
  for (let i = 0; i < png.data.length; i += 4) { png.data[i] = png.data[i + 1] = png.data[i + 2] = 120; png.data[i + 3] = 255; }
  const body = PNG.sync.write(png, { colorType: 2 });
  const server = createServer((req, res) => { res.writeHead(200, { 'content-type': 'image/png' }); res.end(body); });
  return new Promise((ok) => server.listen(0, '127.0.0.1', () => ok({ url: `http://127.0.0.1:${server.address().port}`, server })));
}

/** A plain static file server over `dir` on 127.0.0.1 (what a CDN or object store does: files
 * as they are, with the CORS header that lets another origin's page read them). */
function startStatic(dir) {
  const types = { '.json': 'application/json', '.glb': 'model/gltf-binary', '.subtree': 'application/octet-stream' };
  const server = createServer(async (req, res) => {
    // Repeated slashes are one, as nginx and Python's http.server take them.
    const path = resolve(dir, '.' + decodeURIComponent(req.url.split('?')[0]).replace(/\/+/g, '/'));
    try {
      if (!path.startsWith(dir)) throw new Error('outside');
      const body = await readFile(path);
      res.writeHead(200, { 'content-type': types[extname(path)] ?? 'application/octet-stream', 'access-control-allow-origin': '*' });
      res.end(body);
    } catch {
      res.writeHead(404, { 'access-control-allow-origin': '*' });
      res.end();
    }
  });
  return new Promise((ok) => server.listen(0, '127.0.0.1', () => ok({ url: `http://127.0.0.1:${server.address().port}`, server })));
}

/** Runs `citymesh export ARGS` to the end. */
function runExport(args) {
  return new Promise((ok, fail) => {
    const child = spawn(bin, ['export', '--quiet', '--cache-db', ':memory:', '--log-level', 'warn', ...args], { cwd: root, stdio: ['ignore', 'inherit', 'inherit'] });
    child.on('exit', (code) => (code === 0 ? ok() : fail(new Error(`citymesh export exited with ${code}`))));
  });
}

function startServer(name, args) {
  return new Promise((ok, fail) => {
    const child = spawn(bin, ['serve', '--listen', '127.0.0.1:0', '--cache-db', ':memory:', '--log-level', 'info', ...args],
      { cwd: root, stdio: ['ignore', 'pipe', 'inherit'] });
    let out = '';
    const timer = setTimeout(() => fail(new Error(`${name}: no "listening" line`)), 30000);
    child.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/listening on (http:\/\/[0-9.:]+)\//);
      if (m) { clearTimeout(timer); ok({ url: m[1], child }); }
    });
    child.on('exit', (code) => fail(new Error(`${name}: exited with ${code}`)));
  });
}

/** Mean absolute difference of two PNG screenshots inside a central box (fractions of size). */
function difference(a, b, box = [0.25, 0.25, 0.75, 0.75]) {
  const A = PNG.sync.read(a), B = PNG.sync.read(b);
  let sum = 0, n = 0;
  for (let y = Math.floor(A.height * box[1]); y < A.height * box[3]; y++) {
    for (let x = Math.floor(A.width * box[0]); x < A.width * box[2]; x++) {
      const i = (y * A.width + x) * 4;
      sum += Math.abs(A.data[i] - B.data[i]) + Math.abs(A.data[i + 1] - B.data[i + 1]) + Math.abs(A.data[i + 2] - B.data[i + 2]);
      n++;
    }
  }
  return sum / n / 3;
}

/** Pixels of `shot` that differ from `empty` (the same camera without the city) by more than a
 * few levels (the same camera draws the ground to the same pixels): what the buildings cover. */
function coveredPixels(shot, empty) {
  const A = PNG.sync.read(shot), B = PNG.sync.read(empty);
  let n = 0;
  for (let i = 0; i < A.data.length; i += 4) {
    const d = Math.abs(A.data[i] - B.data[i]) + Math.abs(A.data[i + 1] - B.data[i + 1]) + Math.abs(A.data[i + 2] - B.data[i + 2]);
    if (d > 3) n++;
  }
  return n;
}

/** Pixels painted magenta (red and blue well above green), shaded or not. */
function magentaPixels(shot) {
  const A = PNG.sync.read(shot);
  let n = 0;
  for (let i = 0; i < A.data.length; i += 4) {
    const [r, g, b] = [A.data[i], A.data[i + 1], A.data[i + 2]];
    if (r > 40 && b > 40 && g < 0.5 * Math.min(r, b)) n++;
  }
  return n;
}

/** Two screenshots of one size side by side, as one PNG. */
function sideBySide(left, right) {
  const A = PNG.sync.read(left), B = PNG.sync.read(right);
  const out = new PNG({ width: A.width + B.width, height: Math.max(A.height, B.height) });
  PNG.bitblt(A, out, 0, 0, A.width, A.height, 0, 0);
  PNG.bitblt(B, out, 0, 0, B.width, B.height, A.width, 0);
  return PNG.sync.write(out);
}

const browser = await chromium.launch({
  executablePath: chromiumPath,
  args: ['--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'],
});
let passed = 0, failed = 0;

// CITYMESH_BROWSER_ONLY=REGEX runs only the checks whose names match (while working on one).
const only = process.env.CITYMESH_BROWSER_ONLY ? new RegExp(process.env.CITYMESH_BROWSER_ONLY) : null;

async function check(name, fn) {
  if (only && !only.test(name)) return;
  try {
    await fn();
    passed++;
    console.log(`test ${name} ... ok`);
  } catch (e) {
    failed++;
    console.log(`test ${name} ... FAILED\n  ${e.stack ?? e}`);
  }
}

/** Opens a page, records errors and failed requests, waits for `ready` (a JS expression). */
async function open(url, ready, timeout = 120000) {
  const page = await browser.newPage({ viewport: { width: 1000, height: 700 } });
  const problems = [];
  const glbs = [];
  page.on('response', (r) => { if (/\.glb(\?|$)/.test(r.url())) glbs.push(r.url()); });
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('requestfailed', (r) => problems.push(`request failed: ${r.url()} ${r.failure()?.errorText}`));
  page.on('response', (r) => { if (r.status() >= 400) problems.push(`HTTP ${r.status()}: ${r.url()}`); });
  page.on('console', (m) => { if (m.type() === 'error') problems.push(`console error: ${m.text()}`); });
  await page.goto(url);
  await page.waitForFunction(ready, null, { timeout, polling: 250 });
  await page.waitForTimeout(500);
  return { page, problems, glbs };
}

const servers = [];
let imagery = null;
let files = null;
try {
  const karlsruhe = await startServer('karlsruhe', ['--dem-dir', `${data}/dem`, '--osm', `${data}/osm/karlsruhe-kirchfeld.osm.pbf`]);
  const demo = await startServer('demo', ['--dem-dir', resolve(root, 'target/no-dem')]);
  servers.push(karlsruhe.child, demo.child);
  imagery = await startImagery();

  /** Throws unless every GLB the page fetched was asked in `encoding` (`null`: the default;
   * for meshopt, the 3D Tiles default, either: CesiumJS passes the tileset's query on). */
  const assertEncoding = (glbs, encoding) => {
    const ok = encoding === null || encoding === 'meshopt' ? [null, 'meshopt'] : [encoding];
    const wrong = glbs.filter((u) => !ok.includes(new URL(u).searchParams.get('encoding')));
    if (!glbs.length || wrong.length) throw new Error(`GLBs not in encoding ${encoding}: ${wrong.slice(0, 3).join(', ') || 'none fetched'}`);
  };
  // Each page with each encoding on Karlsruhe; the defaults on the demo city.
  const runs = [['karlsruhe', karlsruhe, 'plain'], ['karlsruhe', karlsruhe, 'quantized'], ['karlsruhe', karlsruhe, 'meshopt'],
    ['demo city', demo, null]];
  for (const [city, server, encoding] of runs) {
    const name = encoding ? `${city} (${encoding})` : city;
    const suffix = encoding ? `?encoding=${encoding}` : '';
    const file = (page) => `${artifacts}/${page}-${city.replace(' ', '-')}${encoding ? '-' + encoding : ''}.png`;
    await check(`viewer shows the buildings of ${name}`, async () => {
      const full = await open(`${server.url}/${suffix}`, 'window.citymeshViewer && window.citymeshViewer.ready');
      const s = await full.page.evaluate(() => window.citymeshViewer);
      if (s.tilesLoaded !== s.tilesWanted || s.tilesFailed) throw new Error(`tiles: ${JSON.stringify(s)}`);
      // The viewer asks for meshopt by default.
      assertEncoding(full.glbs, encoding ?? 'meshopt');
      const shot = await full.page.screenshot({ path: file('viewer') });
      const empty = await open(`${server.url}/?empty`, 'window.citymeshViewer && window.citymeshViewer.ready');
      const blank = await empty.page.screenshot({ path: file('viewer-empty') });
      const diff = difference(shot, blank);
      if (full.problems.length || empty.problems.length) throw new Error([...full.problems, ...empty.problems].join('\n'));
      if (!(diff > 20)) throw new Error(`the city barely differs from an empty scene: ${diff.toFixed(1)}`);
      console.log(`  ${s.tilesLoaded} tiles; mean difference from the empty scene ${diff.toFixed(1)}`);
      await full.page.close(); await empty.page.close();
    });

    await check(`CesiumJS loads the 3D Tiles of ${name}`, async () => {
      const c = await open(`${server.url}/cesium${suffix}`, 'window.citymeshCesium && (window.citymeshCesium.ready || window.citymeshCesium.errors.length)', 180000);
      const s = await c.page.evaluate(() => window.citymeshCesium);
      const shot = await c.page.screenshot({ path: file('cesium') });
      // Content is meshopt unless asked otherwise: only other encodings appear in its URIs.
      assertEncoding(c.glbs, encoding);
      if (s.errors.length) throw new Error(s.errors.join('\n'));
      if (c.problems.length) throw new Error(c.problems.join('\n'));
      if (!(s.tilesLoaded > 0)) throw new Error('no tile loaded');
      // The globe alone is one flat colour: the city adds contrast in the middle.
      const img = PNG.sync.read(shot);
      const colours = new Set();
      for (let i = 0; i < img.data.length; i += 4 * 97) colours.add((img.data[i] >> 3) << 10 | (img.data[i + 1] >> 3) << 5 | img.data[i + 2] >> 3);
      if (colours.size < 20) throw new Error(`the view is nearly uniform (${colours.size} colours)`);
      console.log(`  ${s.tilesLoaded} tiles loaded; ${colours.size} colours`);
      await c.page.close();
    });

    await check(`3d-tiles-renderer loads the 3D Tiles of ${name}`, async () => {
      const t = await open(`${server.url}/3dtiles-renderer${suffix}`, 'window.citymeshTilesRenderer && (window.citymeshTilesRenderer.ready || window.citymeshTilesRenderer.errors.length)');
      const s = await t.page.evaluate(() => window.citymeshTilesRenderer);
      await t.page.screenshot({ path: file('3dtiles-renderer') });
      assertEncoding(t.glbs, encoding);
      if (s.errors.length) throw new Error(s.errors.join('\n'));
      if (t.problems.length) throw new Error(t.problems.join('\n'));
      if (!(s.modelsLoaded > 0)) throw new Error('no model loaded');
      console.log(`  ${s.modelsLoaded} models loaded`);
      await t.page.close();
    });
  }

  await check('CesiumJS opens at the camera in the URL, keeps the camera in the URL, and credits OpenStreetMap', async () => {
    const want = { lon: 8.3995, lat: 49.0525, height: 1200, heading: 30, pitch: -50 };
    const c = await open(`${karlsruhe.url}/cesium?${new URLSearchParams(Object.entries(want).map(([k, v]) => [k, String(v)]))}`,
      'window.citymeshCesium && (window.citymeshCesium.ready || window.citymeshCesium.errors.length)', 180000);
    const s = await c.page.evaluate(() => window.citymeshCesium);
    if (s.errors.length) throw new Error(s.errors.join('\n'));
    if (c.problems.length) throw new Error(c.problems.join('\n'));
    const got = s.camera;
    const off = (k, tolerance) => Math.abs(got[k] - want[k]) > tolerance;
    if (off('lon', 1e-6) || off('lat', 1e-6) || off('height', 0.5) || off('heading', 0.1) || off('pitch', 0.1)) {
      throw new Error(`the camera is at ${JSON.stringify(got)}, not ${JSON.stringify(want)}`);
    }
    if (!(s.tilesLoaded > 0)) throw new Error('no tile loaded from the URL\'s camera');
    const credits = await c.page.evaluate(() => document.querySelector('.cesium-widget-credits')?.textContent ?? '');
    if (!credits.includes('OpenStreetMap')) throw new Error(`credits: ${credits}`);
    // The user moves: the URL follows, so the view can be shared.
    await c.page.evaluate(() => window.citymeshCesiumViewer.camera.setView({
      destination: Cesium.Cartesian3.fromDegrees(8.401, 49.0531, 900) }));
    await c.page.waitForFunction(() => new URLSearchParams(location.search).get('lon') === '8.401000', null, { timeout: 20000 });
    const shared = new URL(c.page.url()).searchParams;
    if (shared.get('lat') !== '49.053100' || Math.abs(Number(shared.get('height')) - 900) > 0.5) throw new Error(`URL: ${shared}`);
    console.log(`  camera ${JSON.stringify(got)}; ${s.tilesLoaded} tiles; URL after moving: ?${shared}`);
    await c.page.close();
  });

  /** Opens `page` (its state in window[stateName]) looking straight down on the PLAZA INN hotel
   * (way 142104398), clicks the middle of the view, and checks that the panel shows the
   * building's OSM id and name and that the building changed colour (highlighted). */
  const pickBuilding = async (base, page, stateName, query = '') => {
    const camera = 'lon=8.3936613&lat=49.0439723&height=420&heading=0&pitch=-90';
    const c = await open(`${base}/${page}?${camera}${query}`,
      `window.${stateName} && (window.${stateName}.ready || window.${stateName}.errors.length)`, 180000);
    const s = await c.page.evaluate((n) => window[n], stateName);
    if (s.errors.length || c.problems.length) throw new Error([...s.errors, ...c.problems].join('\n'));
    const { width, height } = c.page.viewportSize();
    const pixel = async () => {
      const shot = PNG.sync.read(await c.page.screenshot());
      const i = (Math.floor(height / 2) * shot.width + Math.floor(width / 2)) * 4;
      return [shot.data[i], shot.data[i + 1], shot.data[i + 2]];
    };
    const before = await pixel();
    await c.page.mouse.click(width / 2, height / 2);
    await c.page.waitForFunction((n) => window[n].picked, stateName, { timeout: 20000 });
    await c.page.waitForTimeout(500);
    const picked = await c.page.evaluate((n) => window[n].picked, stateName);
    const panel = await c.page.textContent('#picked');
    const after = await pixel();
    await c.page.screenshot({ path: `${artifacts}/${page}-picked${query ? '-export' : ''}.png` });
    if (`${picked.osm_type}/${picked.osm_id}` !== 'way/142104398') throw new Error(`picked ${JSON.stringify(picked)}`);
    if (!panel.includes('way/142104398') || !panel.includes('PLAZA INN Karlsruhe Nord')) throw new Error(`panel: ${panel}`);
    if (picked.roof_source !== 'tag' || Number(picked.height) !== 12) throw new Error(`properties: ${JSON.stringify(picked)}`);
    const moved = before.reduce((sum, v, k) => sum + Math.abs(v - after[k]), 0);
    if (!(moved > 15)) throw new Error(`the building was not highlighted: ${before} -> ${after}`);
    console.log(`  picked ${picked.osm_type}/${picked.osm_id} (${picked.name}); pixel ${before} -> ${after}`);
    await c.page.close();
  };
  await check('CesiumJS: a click on a building shows its OSM id and properties and highlights it', () =>
    pickBuilding(karlsruhe.url, 'cesium', 'citymeshCesium'));
  await check('3d-tiles-renderer: a click on a building shows its OSM id and properties and highlights it', () =>
    pickBuilding(karlsruhe.url, '3dtiles-renderer', 'citymeshTilesRenderer'));

  // Cesium's own "colour by height" style for Cesium OSM Buildings (its 3D Tiles feature
  // styling example), unchanged: the PLAZA INN (12 m) takes the colour of ">= 10".
  await check('CesiumJS: the colour-by-height style written for Cesium OSM Buildings colours citymesh buildings', async () => {
    const h = "${feature['cesium#estimatedHeight']}";
    const style = { color: { conditions: [
      [`${h} >= 300`, 'rgba(45, 0, 75, 0.5)'], [`${h} >= 200`, 'rgb(102, 71, 151)'],
      [`${h} >= 100`, 'rgb(170, 162, 204)'], [`${h} >= 50`, 'rgb(224, 226, 238)'],
      [`${h} >= 25`, 'rgb(252, 230, 200)'], [`${h} >= 10`, 'rgb(248, 176, 87)'],
      [`${h} >= 5`, 'rgb(198, 106, 11)'], ['true', 'rgb(127, 59, 8)']] } };
    const camera = 'lon=8.3936613&lat=49.0439723&height=420&heading=0&pitch=-90';
    const c = await open(`${karlsruhe.url}/cesium?${camera}&style=${encodeURIComponent(JSON.stringify(style))}`,
      'window.citymeshCesium && (window.citymeshCesium.ready || window.citymeshCesium.errors.length)', 180000);
    const s = await c.page.evaluate(() => window.citymeshCesium);
    if (s.errors.length || c.problems.length) throw new Error([...s.errors, ...c.problems].join('\n'));
    const { width, height } = c.page.viewportSize();
    const got = await c.page.evaluate(([x, y]) => {
      const f = window.citymeshCesiumViewer.scene.pick(new Cesium.Cartesian2(x, y));
      if (!(f instanceof Cesium.Cesium3DTileFeature)) return null;
      return { id: String(f.getProperty('elementId')), type: f.getProperty('elementType'),
        height: f.getPropertyInherited('cesium#estimatedHeight'), colour: f.color.toCssColorString() };
    }, [width / 2, height / 2]);
    await c.page.screenshot({ path: `${artifacts}/cesium-style-by-height.png` });
    if (!got) throw new Error('no building under the centre of the view');
    if (got.id !== '142104398' || got.type !== 'way' || got.height !== 12) throw new Error(`picked ${JSON.stringify(got)}`);
    if (got.colour !== 'rgb(248,176,87)') throw new Error(`coloured ${got.colour}`);
    console.log(`  way/${got.id}: cesium#estimatedHeight ${got.height} -> ${got.colour}`);
    await c.page.close();
  });

  // A static export of the same buildings, served by a plain file server: picking works there.
  const exported = resolve(artifacts, 'export');
  rmSync(exported, { recursive: true, force: true });
  const exportServed = async () => {
    if (!files) {
      await runExport(['--bbox', '8.380,49.035,8.415,49.065', '--out', exported, '--osm', `${data}/osm/karlsruhe-kirchfeld.osm.pbf`, '--dem-dir', `${data}/dem`]);
      files = await startStatic(exported);
    }
    return `&tileset=${encodeURIComponent(`${files.url}/tileset.json`)}`;
  };
  await check('CesiumJS: picking works on a static export served by a plain file server', async () =>
    pickBuilding(karlsruhe.url, 'cesium', 'citymeshCesium', await exportServed()));
  await check('3d-tiles-renderer: picking works on a static export served by a plain file server', async () =>
    pickBuilding(karlsruhe.url, '3dtiles-renderer', 'citymeshTilesRenderer', await exportServed()));

  // What a client loads to show a 5 km x 5 km area from above (docs/clients.md quotes it): the
  // tileset over a 4.9 km square around Kirchfeld (under the 25 km² limit), the camera at 7 km
  // looking straight down.
  const overview = async (page, ready) => {
    const bbox = '8.366,49.031,8.433,49.075';
    const tab = await browser.newPage({ viewport: { width: 1000, height: 700 } });
    let requests = 0, bytes = 0;
    tab.on('response', (r) => {
      if (!/\.glb(\?|$)/.test(r.url()) || r.status() !== 200) return;
      requests++;
      bytes += Number(r.headers()['content-length'] ?? 0);
    });
    await tab.goto(`${karlsruhe.url}/${page}?bbox=${bbox}&lon=8.3995&lat=49.0525&height=7000&heading=0&pitch=-90`);
    await tab.waitForFunction(`${ready} && (${ready}.ready || ${ready}.errors.length)`, null, { timeout: 300000, polling: 250 });
    await tab.waitForTimeout(1000);
    const s = await tab.evaluate(`${ready}`);
    await tab.screenshot({ path: `${artifacts}/${page}-overview.png` });
    if (s.errors.length) throw new Error(s.errors.join('\n'));
    if (!(requests > 0)) throw new Error('no content loaded');
    console.log(`  overview of ${bbox}: ${requests} content requests, ${(bytes / 1e6).toFixed(2)} MB`);
    await tab.close();
  };
  // What a person sees over Kirchfeld at the default view, from 1,500 m and from 300 m: the
  // pixels the buildings cover at the levels of detail the client picks must be at least 90 %
  // of those they cover at full detail from the same camera (the coarse levels once dropped
  // small houses, and a default view showed 73 of 3,014 buildings). A building pixel is one
  // that changes when the buildings alone are hidden (the ground stays). Both views are saved
  // side by side; the buildings (features) in the tiles each client draws are printed.
  const views = [['default view', null], ['1500 m', 1500], ['300 m', 300]];
  const coverage = async (page, settle, setDetail, markBuildings, marks, place, drawn) => {
    for (const [label, height] of views) {
      const t = await open(`${karlsruhe.url}/${page}`, `${settle}`, 180000);
      if (height !== null) {
        await t.page.evaluate(place, height);
        await t.page.waitForTimeout(500);
        await t.page.waitForFunction(settle, null, { timeout: 180000, polling: 250 });
      }
      const shoot = async () => { await t.page.waitForTimeout(500); return t.page.screenshot(); };
      // The buildings' pixels at the detail the client chose, then at full detail.
      const buildingPixels = async () => {
        const shot = await shoot();
        const features = await t.page.evaluate(drawn);
        await t.page.evaluate(markBuildings, true);
        const marked = await shoot();
        await t.page.evaluate(markBuildings, false);
        return { shot, features, pixels: marks(marked, shot) };
      };
      const coarse = await buildingPixels();
      await t.page.evaluate(setDetail, true);
      await t.page.waitForTimeout(500);
      await t.page.waitForFunction(settle, null, { timeout: 300000, polling: 250 });
      const full = await buildingPixels();
      const name = label.replace(/[ ,]/g, '-');
      await writeFile(`${artifacts}/${page}-detail-${name}.png`, sideBySide(coarse.shot, full.shot));
      if (t.problems.length) throw new Error(t.problems.join('\n'));
      const [c, f] = [coarse.pixels, full.pixels];
      console.log(`  ${label}: buildings cover ${c} px as drawn, ${f} px at full detail (${(100 * c / f).toFixed(1)} %); drawn: ${coarse.features} and ${full.features}`);
      if (!(f > 1000)) throw new Error(`${label}: the full-detail view shows almost no buildings (${f} px)`);
      if (!(c >= 0.9 * f)) throw new Error(`${label}: only ${(100 * c / f).toFixed(1)} % of the building pixels full detail shows`);
      await t.page.close();
    }
  };
  await check('CesiumJS draws at least 90 % of what full detail shows at the default view, 1,500 m and 300 m', () =>
    coverage('cesium',
      'window.citymeshCesium && window.citymeshCesium.ready && window.citymeshCesiumTileset.tilesLoaded',
      (full) => { window.citymeshCesiumTileset.maximumScreenSpaceError = full ? 0.01 : 16; },
      // Buildings painted magenta (a style colours features; the ground has none).
      (mark) => {
        const tileset = window.citymeshCesiumTileset;
        tileset.colorBlendMode = mark ? Cesium.Cesium3DTileColorBlendMode.REPLACE : Cesium.Cesium3DTileColorBlendMode.HIGHLIGHT;
        // Content without buildings (ground alone) has no property table, and CesiumJS styles
        // such content as one feature: only what has an elementId turns magenta.
        tileset.style = mark ? new Cesium.Cesium3DTileStyle({ color: { conditions: [
          ['${elementId} !== undefined', "color('#ff00ff')"], ['true', "color('#ffffff')"]] } }) : undefined;
      },
      (marked) => magentaPixels(marked),
      (height) => {
        const viewer = window.citymeshCesiumViewer;
        const c = Cesium.Cartographic.fromCartesian(window.citymeshCesiumTileset.boundingSphere.center);
        // Looking north at 45 degrees down onto the middle of the city.
        viewer.camera.setView({
          destination: Cesium.Cartesian3.fromRadians(c.longitude, c.latitude - height / 6371000, height),
          orientation: { heading: 0, pitch: -Math.PI / 4, roll: 0 },
        });
      },
      () => `${window.citymeshCesiumTileset._selectedTiles.reduce((n, t) => n + (t.content?.featuresLength ?? 0), 0)} buildings`));
  await check('3d-tiles-renderer draws at least 90 % of what full detail shows at the default view, 1,500 m and 300 m', () =>
    coverage('3dtiles-renderer',
      'window.citymeshTilesRenderer && window.citymeshTilesRenderer.ready && window.citymeshTilesRenderer.tiles.loadProgress === 1',
      // The library's own default error target (16 px) for the view a person gets.
      (full) => {
        const tiles = window.citymeshTilesRenderer.tiles;
        window.citymeshDefaultErrorTarget ??= tiles.errorTarget;
        tiles.errorTarget = full ? 0.01 : window.citymeshDefaultErrorTarget;
      },
      // Buildings hidden (building primitives are the ones with feature ids; the ground has
      // none): the pixels that change are theirs.
      (mark) => {
        window.citymeshTilesRenderer.tiles.group.traverse((o) => {
          if (o.isMesh && o.geometry.getAttribute('_feature_id_0')) o.visible = !mark;
        });
      },
      (hidden, shot) => coveredPixels(shot, hidden),
      (height) => window.citymeshTilesRenderer.lookFrom(height),
      () => {
        let n = 0;
        window.citymeshTilesRenderer.tiles.forEachLoadedModel((model) => { if (model.parent) n++; });
        return `${n} tiles`;
      }));

  // The fly buttons, as a person uses them: the page opens on the whole tileset (the region),
  // "Street" flies to 300 m above the middle of the data and the buildings in front are drawn in
  // full detail (zoom-15 leaves of the world tileset), "Region" flies back to the first view.
  // Both views are saved side by side.
  const flights = async (page, settle, drawn) => {
    const t = await open(`${karlsruhe.url}/${page}`, settle, 180000);
    const state = page === 'cesium' ? 'citymeshCesium' : 'citymeshTilesRenderer';
    const camera = () => t.page.evaluate((n) => window[n].camera, state);
    const settled = async () => {
      await t.page.waitForTimeout(500);
      await t.page.waitForFunction(settle, null, { timeout: 180000, polling: 250 });
      await t.page.waitForTimeout(500);
    };
    const first = await camera();
    const atRegion = await t.page.evaluate(drawn);
    const regionShot = await t.page.screenshot();
    await t.page.click('#to-street');
    await t.page.waitForFunction((n) => Math.abs(window[n].camera.height - 415) < 5, state, { timeout: 60000, polling: 250 });
    await settled();
    const street = await camera();
    const atStreet = await t.page.evaluate(drawn);
    const streetShot = await t.page.screenshot();
    await writeFile(`${artifacts}/${page}-fly-region-street.png`, sideBySide(regionShot, streetShot));
    await t.page.click('#to-region');
    await t.page.waitForFunction(([n, h]) => Math.abs(window[n].camera.height - h) < 0.01 * h, [state, first.height], { timeout: 60000, polling: 250 });
    await settled();
    const back = await camera();
    const again = await t.page.evaluate(drawn);
    if (t.problems.length) throw new Error(t.problems.join('\n'));
    console.log(`  region at ${first.height.toFixed(0)} m: ${JSON.stringify(atRegion)}; street at ${street.height.toFixed(0)} m, pitch ${street.pitch.toFixed(0)}: ${JSON.stringify(atStreet)}; back at ${back.height.toFixed(0)} m: ${JSON.stringify(again)}`);
    if (!(first.height > 1000)) throw new Error(`the page opened at ${first.height} m, not on the region`);
    if (!(Math.abs(street.pitch + 30) < 1)) throw new Error(`the street view looks ${street.pitch} degrees down, not 30`);
    if (!(atStreet.leaves > 0 && atStreet.leafBuildings >= 100)) throw new Error(`at the street the buildings are not in full detail: ${JSON.stringify(atStreet)}`);
    if (!(atRegion.buildings > 0 && again.buildings > 0)) throw new Error('the region shows no buildings');
    if (Math.abs(back.lon - first.lon) > 1e-4 || Math.abs(back.lat - first.lat) > 1e-4) throw new Error(`"Region" went to ${JSON.stringify(back)}, not back to ${JSON.stringify(first)}`);
    await t.page.close();
  };
  await check('CesiumJS: "Street" flies from the region to full detail at 300 m, "Region" flies back', () =>
    flights('cesium',
      'window.citymeshCesium && window.citymeshCesium.ready && window.citymeshCesiumTileset.tilesLoaded',
      () => {
        let leaves = 0, leafBuildings = 0, buildings = 0;
        for (const t of window.citymeshCesiumTileset._selectedTiles) {
          const n = t.content?.featuresLength ?? 0;
          buildings += n;
          if (/\/15\/\d+\/\d+\.glb/.test(t.content?.url ?? '')) { leaves++; leafBuildings += n; }
        }
        return { leaves, leafBuildings, buildings };
      }));
  await check('3d-tiles-renderer: "Street" goes from the region to full detail at 300 m, "Region" goes back', () =>
    flights('3dtiles-renderer',
      'window.citymeshTilesRenderer && window.citymeshTilesRenderer.ready && window.citymeshTilesRenderer.tiles.loadProgress === 1',
      () => {
        let leaves = 0, leafBuildings = 0, buildings = 0;
        for (const t of window.citymeshTilesRenderer.tiles.visibleTiles) {
          const scene = t.engineData?.scene;
          if (!scene) continue;
          // The buildings a tile draws: its property table's rows.
          let n = 0;
          n = scene.userData?.structuralMetadata?.tableAccessors?.[0]?.count ?? 0;
          buildings += n;
          if (/(^|\/)15\/\d+\/\d+\.glb/.test(t.content?.uri ?? '')) { leaves++; leafBuildings += n; }
        }
        return { leaves, leafBuildings, buildings };
      }));

  await check('CesiumJS: a 5 km x 5 km overview from above loads (requests and bytes printed)', () =>
    overview('cesium', 'window.citymeshCesium'));
  await check('3d-tiles-renderer: a 5 km x 5 km overview from above loads (requests and bytes printed)', () =>
    overview('3dtiles-renderer', 'window.citymeshTilesRenderer'));

  // Bounded content as 3d-tiles-renderer sees it: every vertex of every loaded content lies in
  // the bounding volume the client computed for its tile (an OBB around the tile's region).
  // With implicit tiling it derives each tile's volume from the root's square and ignores the
  // subtree's measured regions: that count is printed, for comparison.
  const outsideItsTile = async (extra) => {
    const t = await open(`${karlsruhe.url}/3dtiles-renderer?lon=8.3965&lat=49.0445&height=400&heading=20&pitch=-25${extra}`,
      'window.citymeshTilesRenderer && (window.citymeshTilesRenderer.ready || window.citymeshTilesRenderer.errors.length)');
    const report = await t.page.evaluate(() => {
      const tiles = window.citymeshTilesRenderer.tiles;
      let models = 0, vertices = 0, outside = 0, worst = 0;
      // Loaded models out of view are detached from the tileset's group: a vertex goes to the
      // tileset's frame through the local matrices up to the model's, not through matrixWorld.
      tiles.forEachLoadedModel((model, tile) => {
        models++;
        const volume = tile.cached.boundingVolume;
        model.updateMatrixWorld(true);
        model.traverse((o) => {
          const position = o.isMesh && o.geometry.getAttribute('position');
          if (!position) return;
          const m = o.matrix.clone();
          for (let p = o.parent; p && p !== model.parent; p = p.parent) m.premultiply(p.matrix);
          const v = o.position.clone();
          for (let i = 0; i < position.count; i++) {
            v.fromBufferAttribute(position, i).applyMatrix4(m);
            const d = volume.distanceToPoint(v);
            vertices++;
            if (d > 0.01) { outside++; worst = Math.max(worst, d); }
          }
        });
      });
      return { models, vertices, outside, worst };
    });
    const s = await t.page.evaluate(() => window.citymeshTilesRenderer);
    if (s.errors.length) throw new Error(s.errors.join('\n'));
    if (t.problems.length) throw new Error(t.problems.join('\n'));
    await t.page.close();
    if (!(report.models > 0 && report.vertices > 0)) throw new Error(`nothing checked: ${JSON.stringify(report)}`);
    return report;
  };
  await check('3d-tiles-renderer: every vertex of loaded content lies inside its tile\'s bounding volume', async () => {
    const explicit = await outsideItsTile('');
    if (explicit.outside) throw new Error(`${explicit.outside} vertices outside, up to ${explicit.worst.toFixed(2)} m: ${JSON.stringify(explicit)}`);
    const implicit = await outsideItsTile('&tiling=implicit');
    console.log(`  explicit tiling: ${explicit.models} models, ${explicit.vertices} vertices, 0 outside; ` +
      `implicit tiling (for comparison): ${implicit.outside} of ${implicit.vertices} outside, up to ${implicit.worst.toFixed(1)} m`);
  });

  await check('3d-tiles-renderer opens at the camera in the URL and keeps the camera in the URL', async () => {
    const want = { lon: 8.3995, lat: 49.0525, height: 1200, heading: 30, pitch: -50 };
    const t = await open(`${karlsruhe.url}/3dtiles-renderer?${new URLSearchParams(Object.entries(want).map(([k, v]) => [k, String(v)]))}`,
      'window.citymeshTilesRenderer && (window.citymeshTilesRenderer.ready || window.citymeshTilesRenderer.errors.length)');
    const s = await t.page.evaluate(() => window.citymeshTilesRenderer);
    if (s.errors.length) throw new Error(s.errors.join('\n'));
    if (t.problems.length) throw new Error(t.problems.join('\n'));
    const got = s.camera;
    const off = (k, tolerance) => Math.abs(got[k] - want[k]) > tolerance;
    if (off('lon', 1e-6) || off('lat', 1e-6) || off('height', 0.5) || off('heading', 0.1) || off('pitch', 0.1)) {
      throw new Error(`the camera is at ${JSON.stringify(got)}, not ${JSON.stringify(want)}`);
    }
    const shared = new URL(t.page.url()).searchParams;
    if (shared.get('lon') !== '8.399500' || shared.get('pitch') !== '-50.0') throw new Error(`URL: ${shared}`);
    const credit = await t.page.textContent('#credit');
    if (!credit.includes('OpenStreetMap')) throw new Error(`credit: ${credit}`);
    // The user drags: the URL follows.
    await t.page.mouse.move(500, 350);
    await t.page.mouse.down();
    await t.page.mouse.move(650, 420, { steps: 10 });
    await t.page.mouse.up();
    await t.page.waitForFunction(() => new URLSearchParams(location.search).get('lon') !== '8.399500', null, { timeout: 20000 });
    console.log(`  camera ${JSON.stringify(got)}; after dragging: ?${new URL(t.page.url()).searchParams}`);
    await t.page.close();
  });

  await check('viewer shows roofs classified by queued jobs (roofs=classified)', async () => {
    const server = await startServer('classifying', ['--dem-dir', `${data}/dem`, '--osm', `${data}/osm/karlsruhe-kirchfeld.osm.pbf`,
      '--roof-classifier', '--imagery-url', `${imagery.url}/{z}/{x}/{y}.png`, '--imagery-id', 'grey', '--classify-workers', '1']);
    servers.push(server.child);
    const posted = await fetch(`${server.url}/classify`, { method: 'POST', headers: { 'content-type': 'application/json' },
      body: JSON.stringify({ bbox: '8.38,49.04,8.42,49.07' }) });
    if (posted.status !== 202) throw new Error(`POST /classify: ${posted.status} ${await posted.text()}`);
    const batch = await posted.json();
    for (let i = 0; ; i++) {
      const p = await (await fetch(`${server.url}/classify/${batch.id}`)).json();
      if (p.finished) { if (p.jobs.done !== batch.counts.queued) throw new Error(JSON.stringify(p)); break; }
      if (i > 1200) throw new Error(`the batch did not finish: ${JSON.stringify(p)}`);
      await new Promise((r) => setTimeout(r, 250));
    }
    const v = await open(`${server.url}/?roofs=classified`, 'window.citymeshViewer && window.citymeshViewer.ready && window.citymeshViewer.stats');
    const s = await v.page.evaluate(() => window.citymeshViewer);
    await v.page.screenshot({ path: `${artifacts}/viewer-classified.png` });
    if (v.problems.length) throw new Error(v.problems.join('\n'));
    if (s.tilesLoaded !== s.tilesWanted || s.tilesFailed) throw new Error(`tiles: ${JSON.stringify(s)}`);
    if (s.roofs !== 'classified' || !s.stats.classified_roofs) throw new Error(`not classified: ${JSON.stringify(s.stats)}`);
    if (!(s.stats.roof_shape_from_classifier_percent > 0)) throw new Error(`no classified roof: ${JSON.stringify(s.stats)}`);
    const panel = await v.page.textContent('#stats');
    if (!panel.includes('roof shapes from the classifier')) throw new Error(`panel: ${panel}`);
    // The tiles the viewer asked for carry the classified roofs.
    const tile = await fetch(`${server.url}/tiles/16/34297/22491.glb?roofs=classified`);
    const roofsHeader = tile.headers.get('x-citymesh-roofs');
    if (!roofsHeader) throw new Error('no X-Citymesh-Roofs');
    console.log(`  ${batch.counts.queued} jobs; ${s.stats.roof_shape_from_classifier_percent.toFixed(1)} % of the view's roofs from the classifier; tile: ${roofsHeader}`);
    await v.page.close();
  });

  await check('viewer shows Kirchfeld with roofs=osm and roofs=inferred side by side', async () => {
    // The same view twice: untagged roofs flat (the paper's default), then inferred by the roof
    // prior from Kirchfeld's tagged buildings; the two screenshots side by side in one PNG.
    const view = `lon=8.3940&lat=49.0480&zoom=17&radius=1&camera=-120,160,220`;
    const shots = [];
    for (const roofs of ['osm', 'inferred']) {
      const v = await open(`${karlsruhe.url}/?${view}&roofs=${roofs}`,
        'window.citymeshViewer && window.citymeshViewer.ready && window.citymeshViewer.stats');
      const s = await v.page.evaluate(() => window.citymeshViewer);
      if (v.problems.length) throw new Error(v.problems.join('\n'));
      if (s.tilesLoaded !== s.tilesWanted || s.tilesFailed) throw new Error(`tiles: ${JSON.stringify(s)}`);
      if (s.roofs !== roofs) throw new Error(`asked ${roofs}, shown ${s.roofs}`);
      if (roofs === 'inferred') {
        if (!v.glbs.length || !v.glbs.every((u) => u.includes('roofs=inferred'))) throw new Error(`tiles without roofs=inferred: ${v.glbs[0]}`);
        if (!(s.stats.roof_shape_inferred_percent > 20)) throw new Error(`inferred: ${JSON.stringify(s.stats)}`);
        const panel = await v.page.textContent('#stats');
        if (!panel.includes('roof shapes inferred')) throw new Error(`panel: ${panel}`);
      }
      shots.push({ png: PNG.sync.read(await v.page.screenshot({ path: `${artifacts}/viewer-roofs-${roofs}.png` })), stats: s.stats });
      await v.page.close();
    }
    const [a, b] = shots.map((x) => x.png);
    const both = new PNG({ width: a.width + b.width, height: Math.max(a.height, b.height) });
    PNG.bitblt(a, both, 0, 0, a.width, a.height, 0, 0);
    PNG.bitblt(b, both, 0, 0, b.width, b.height, a.width, 0);
    await writeFile(`${artifacts}/viewer-roofs-osm-vs-inferred.png`, PNG.sync.write(both));
    const diff = difference(PNG.sync.write(a), PNG.sync.write(b));
    if (!(diff > 2)) throw new Error(`the inferred roofs barely change the view: ${diff.toFixed(2)}`);
    const [osm, inferred] = shots.map((x) => x.stats.flat_roof_percent.toFixed(1));
    console.log(`  flat roofs ${osm} % -> ${inferred} %; mean difference ${diff.toFixed(1)}; viewer-roofs-osm-vs-inferred.png`);
  });

  await check('viewer shows hipped and gabled roofs over L, T and U outlines (straight skeleton)', async () => {
    // Six buildings in OSM XML around (8.4 E, 49.01 N): L, T and U, hipped in front, gabled
    // behind; wings 6 m wide, 9 m tall, no roof:height.
    const outlines = [
      [[0, 0], [20, 0], [20, 6], [6, 6], [6, 14], [0, 14]],
      [[0, 10], [6, 10], [6, 0], [12, 0], [12, 10], [18, 10], [18, 16], [0, 16]],
      [[0, 0], [20, 0], [20, 15], [14, 15], [14, 6], [6, 6], [6, 15], [0, 15]],
    ];
    const [lon0, lat0] = [8.4, 49.01];
    const a = 6378137, e2 = 6.69437999014e-3, phi = lat0 * Math.PI / 180, w = Math.sqrt(1 - e2 * Math.sin(phi) ** 2);
    const mLon = a / w * Math.cos(phi) * Math.PI / 180, mLat = a * (1 - e2) / (w * w * w) * Math.PI / 180;
    let nodes = '', ways = '', id = 1;
    outlines.forEach((ring, k) => ['hipped', 'gabled'].forEach((shape, row) => {
      const ids = ring.map(([x, y]) => {
        const [lon, lat] = [lon0 + (x + k * 40 - 30) / mLon, lat0 + (y + row * 30) / mLat];
        nodes += `<node id="${id}" lat="${lat.toFixed(9)}" lon="${lon.toFixed(9)}"/>\n`;
        return id++;
      });
      ways += `<way id="${id++}">${[...ids, ids[0]].map((n) => `<nd ref="${n}"/>`).join('')}` +
        `<tag k="building" v="yes"/><tag k="height" v="9"/><tag k="roof:shape" v="${shape}"/></way>\n`;
    }));
    const osm = resolve(artifacts, 'winged-outlines.osm');
    await writeFile(osm, `<?xml version="1.0" encoding="UTF-8"?>\n<osm version="0.6">\n${nodes}${ways}</osm>\n`);
    const server = await startServer('winged', ['--dem-dir', resolve(root, 'target/no-dem'), '--osm', osm]);
    servers.push(server.child);
    const v = await open(`${server.url}/?lon=${lon0}&lat=${lat0 + 0.0002}&zoom=18&radius=1&camera=-40,45,60`,
      'window.citymeshViewer && window.citymeshViewer.ready && window.citymeshViewer.stats');
    const s = await v.page.evaluate(() => window.citymeshViewer);
    await v.page.screenshot({ path: `${artifacts}/viewer-winged-roofs.png` });
    if (v.problems.length) throw new Error(v.problems.join('\n'));
    if (s.tilesLoaded !== s.tilesWanted || s.tilesFailed) throw new Error(`tiles: ${JSON.stringify(s)}`);
    if (s.stats.buildings.generated !== 6) throw new Error(`buildings: ${JSON.stringify(s.stats.buildings)}`);
    if (s.stats.roof_shape_from_tag_percent !== 100) throw new Error(`roof shapes: ${JSON.stringify(s.stats)}`);
    console.log(`  ${s.tilesLoaded} tiles; ${s.stats.buildings.generated} buildings; screenshot viewer-winged-roofs.png`);
    await v.page.close();
  });
} catch (e) {
  failed++;
  console.log(`browser tests could not run: ${e.stack ?? e}`);
} finally {
  await browser.close();
  imagery?.server.close();
  files?.server.close();
  for (const s of servers) s.kill('SIGTERM');
}
console.log(`${passed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
