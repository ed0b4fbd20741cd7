#!/usr/bin/env node
// What CesiumJS and 3d-tiles-renderer load and draw from the world tileset (`/3dtiles/tileset.json`)
// of a running server, at four camera heights over one point: 300 km and 30 km looking straight
// down, 3 km and 300 m looking north 45 degrees down. Each view opens in a fresh browser context
// (nothing cached), waits until loading settles, then prints the requests made for tileset files
// and content (contents by zoom), the bytes received (as sent, compressed), and the features
// drawn by zoom (blocks up to zoom 14, buildings at the leaves, zoom 15). Screenshots go to artifacts/views/.
//
//   node scripts/measure-views.mjs http://127.0.0.1:8080 LON LAT
import { chromium } from 'playwright-core';
import { mkdirSync } from 'node:fs';
import { resolve, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';

const [base, lon, lat] = process.argv.slice(2);
if (!base || !Number.isFinite(Number(lon)) || !Number.isFinite(Number(lat))) {
  console.error('usage: node scripts/measure-views.mjs SERVER_URL LON LAT');
  process.exit(2);
}
const artifacts = resolve(dirname(fileURLToPath(import.meta.url)), '../artifacts/views');
mkdirSync(artifacts, { recursive: true });

const views = [[300000, -90], [30000, -90], [3000, -45], [300, -45]];
const clients = {
  cesium: {
    page: 'cesium',
    settled: 'window.citymeshCesium && (window.citymeshCesium.errors.length || (window.citymeshCesium.ready && window.citymeshCesiumTileset.tilesLoaded))',
    errors: 'window.citymeshCesium.errors',
    // The tiles drawn in the last frame: their content's URL and feature count.
    drawn: () => window.citymeshCesiumTileset._selectedTiles
      .filter((t) => t.content && t.content.url)
      .map((t) => [t.content.url, t.content.featuresLength ?? 0]),
  },
  '3d-tiles-renderer': {
    page: '3dtiles-renderer',
    settled: 'window.citymeshTilesRenderer && (window.citymeshTilesRenderer.errors.length || (window.citymeshTilesRenderer.ready && window.citymeshTilesRenderer.tiles.loadProgress === 1))',
    errors: 'window.citymeshTilesRenderer.errors',
    // Models in view are attached to the tileset's group; the feature count is the largest
    // feature id + 1 over the model's meshes.
    drawn: () => {
      const out = [];
      window.citymeshTilesRenderer.tiles.forEachLoadedModel((model, tile) => {
        if (!model.parent) return;
        let features = 0;
        model.traverse((o) => {
          const ids = o.isMesh && o.geometry.getAttribute('_feature_id_0');
          if (ids) for (let i = 0; i < ids.count; i++) features = Math.max(features, ids.getX(i) + 1);
        });
        out.push([tile.content.uri, features]);
      });
      return out;
    },
  },
};

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  args: ['--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'],
});
for (const [name, client] of Object.entries(clients)) {
  for (const [height, pitch] of views) {
    const context = await browser.newContext({ viewport: { width: 1000, height: 700 } });
    const page = await context.newPage();
    let files = 0, contents = 0, bytes = 0;
    const sizes = [];
    const requested = {};
    page.on('requestfinished', (r) => {
      if (!r.url().includes('/3dtiles/')) return;
      if (/\.glb(\?|$)/.test(r.url())) {
        contents++;
        const z = Number(/(\d+)\/\d+\/\d+\.glb/.exec(r.url())?.[1]);
        requested[z] = (requested[z] ?? 0) + 1;
      } else files++;
      sizes.push(r.sizes().then((s) => { bytes += s.responseBodySize + s.responseHeadersSize; }));
    });
    const started = Date.now();
    await page.goto(`${base}/${client.page}?lon=${lon}&lat=${lat}&height=${height}&heading=0&pitch=${pitch}`);
    await page.waitForFunction(client.settled, null, { timeout: 600000, polling: 250 });
    await page.waitForTimeout(1000);
    await page.waitForFunction(client.settled, null, { timeout: 600000, polling: 250 });
    const seconds = (Date.now() - started) / 1000;
    await Promise.all(sizes);
    const errors = await page.evaluate(client.errors);
    const drawn = await page.evaluate(client.drawn);
    const byZoom = {};
    for (const [url, features] of drawn) {
      const z = Number(/(\d+)\/\d+\/\d+\.glb/.exec(url)?.[1]);
      byZoom[z] = byZoom[z] ?? { tiles: 0, features: 0 };
      byZoom[z].tiles++;
      byZoom[z].features += features;
    }
    const label = height >= 1000 ? `${height / 1000} km` : `${height} m`;
    await page.screenshot({ path: `${artifacts}/${name}-${label.replace(' ', '')}.png` });
    const zooms = Object.entries(byZoom).map(([z, v]) => `z${z}: ${v.tiles} tiles, ${v.features} ${z < 15 ? 'blocks' : 'buildings'}`).join('; ');
    const loaded = Object.entries(requested).map(([z, n]) => `z${z} ${n}`).join(', ');
    console.log(`${name} at ${label} (pitch ${pitch}): ${files + contents} requests (${files} tileset files, ${contents} contents: ${loaded}), ${(bytes / 1e6).toFixed(2)} MB, settled in ${seconds.toFixed(0)} s; drawn ${zooms || 'nothing'}${errors.length ? `; ERRORS: ${errors.join(' | ')}` : ''}`);
    await context.close();
  }
}
await browser.close();
