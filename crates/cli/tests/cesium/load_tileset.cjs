// Loads an exported tileset in CesiumJS inside headless Chromium (WebGL on SwiftShader) and
// screenshots it from a given camera. Serves the page, Cesium and the tileset itself on a
// loopback port; nothing else is reached (no ion token, no imagery, no terrain, no globe).
// Usage: node load_tileset.cjs TOOLS_DIR TILESET_DIR OUT.png EYE TARGET UP FOV_DEG SIZE
'use strict';
const http = require('http');
const fs = require('fs');
const path = require('path');

const [toolsDir, tilesetDir, outPng, eye, target, up, fovDeg, size] = process.argv.slice(2);
const { chromium } = require(path.join(toolsDir, 'node_modules', 'playwright-core'));
const cesiumDir = path.join(toolsDir, 'node_modules', 'cesium', 'Build', 'Cesium');
const vec = (s) => s.split(',').map(Number);

const page = `<!doctype html><html><head><meta charset="utf-8">
<style>html,body,#c{margin:0;padding:0;width:${size}px;height:${size}px;overflow:hidden;background:#000}
#c .cesium-widget,#c canvas{width:100%;height:100%;display:block}</style>
<script src="/cesium/Cesium.js"></script></head><body><div id="c"></div><script>
window.CESIUM_BASE_URL = '/cesium/';
async function run() {
  const widget = new Cesium.CesiumWidget('c', {
    baseLayer: false, globe: false, skyBox: false, skyAtmosphere: false,
    requestRenderMode: false, creditContainer: document.createElement('div'),
    contextOptions: { webgl: { preserveDrawingBuffer: true } },
  });
  const scene = widget.scene;
  scene.backgroundColor = Cesium.Color.BLACK;
  if (scene.sun) scene.sun.show = false;
  if (scene.moon) scene.moon.show = false;
  scene.fog.enabled = false;
  const tileset = await Cesium.Cesium3DTileset.fromUrl('/tileset/tileset.json', { maximumScreenSpaceError: 0 });
  scene.primitives.add(tileset);
  let loaded = false;
  tileset.allTilesLoaded.addEventListener(() => { loaded = true; });
  const eye = new Cesium.Cartesian3(...${JSON.stringify(vec(eye))});
  const target = new Cesium.Cartesian3(...${JSON.stringify(vec(target))});
  const upHint = new Cesium.Cartesian3(...${JSON.stringify(vec(up))});
  const direction = Cesium.Cartesian3.normalize(Cesium.Cartesian3.subtract(target, eye, new Cesium.Cartesian3()), new Cesium.Cartesian3());
  const right = Cesium.Cartesian3.normalize(Cesium.Cartesian3.cross(direction, upHint, new Cesium.Cartesian3()), new Cesium.Cartesian3());
  const upv = Cesium.Cartesian3.cross(right, direction, new Cesium.Cartesian3());
  widget.camera.frustum.fov = Cesium.Math.toRadians(${Number(fovDeg)});
  widget.camera.setView({ destination: eye, orientation: { direction, up: upv } });
  window.tilesetState = () => ({ loaded: loaded && tileset.tilesLoaded, tiles: tileset.statistics.numberOfLoadedTilesTotal, points: tileset.statistics.numberOfPointsSelected });
}
run().catch((e) => { window.tilesetError = String(e && e.stack || e); });
</script></body></html>`;

const types = { '.js': 'text/javascript', '.json': 'application/json', '.glb': 'model/gltf-binary', '.css': 'text/css', '.wasm': 'application/wasm' };
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(req.url.split('?')[0]);
  let file = null;
  if (url === '/') {
    res.writeHead(200, { 'content-type': 'text/html' });
    return res.end(page);
  }
  for (const [prefix, root] of [['/cesium/', cesiumDir], ['/tileset/', tilesetDir]]) {
    if (url.startsWith(prefix)) {
      const resolved = path.resolve(root, '.' + url.slice(prefix.length - 1));
      if (resolved.startsWith(path.resolve(root))) file = resolved;
    }
  }
  if (!file || !fs.existsSync(file) || !fs.statSync(file).isFile()) {
    res.writeHead(404);
    return res.end();
  }
  res.writeHead(200, { 'content-type': types[path.extname(file)] || 'application/octet-stream' });
  fs.createReadStream(file).pipe(res);
});

(async () => {
  await new Promise((r) => server.listen(0, '127.0.0.1', r));
  const port = server.address().port;
  const userDir = fs.mkdtempSync(path.join(require('os').tmpdir(), 'pointlet-chromium-'));
  const browser = await chromium.launchPersistentContext(userDir, {
    executablePath: '/usr/bin/chromium',
    headless: true,
    viewport: { width: Number(size), height: Number(size) },
    args: ['--headless', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'],
  });
  let failed = false;
  try {
    const tab = browser.pages()[0] || await browser.newPage();
    const logs = [];
    tab.on('console', (m) => logs.push(m.text()));
    tab.on('pageerror', (e) => logs.push(String(e)));
    await tab.goto(`http://127.0.0.1:${port}/`);
    const started = Date.now();
    let state = null;
    let settled = 0;
    while (Date.now() - started < 120000) {
      const error = await tab.evaluate(() => window.tilesetError);
      if (error) throw new Error(error);
      state = await tab.evaluate(() => window.tilesetState && window.tilesetState());
      // Loaded and still loaded a moment later: nothing more was requested.
      settled = state && state.loaded ? settled + 1 : 0;
      if (settled >= 3) break;
      await tab.waitForTimeout(250);
    }
    if (settled < 3) throw new Error(`tiles not loaded after 120 s: ${JSON.stringify(state)}; ${logs.join(' | ')}`);
    await tab.waitForTimeout(500);
    await tab.locator('#c canvas').screenshot({ path: outPng });
    console.log(JSON.stringify({ ...state, seconds: (Date.now() - started) / 1000 }));
  } catch (e) {
    console.error(String(e && e.stack || e));
    failed = true;
  } finally {
    await browser.close();
    server.close();
    fs.rmSync(userDir, { recursive: true, force: true });
  }
  process.exit(failed ? 1 : 0);
})();
