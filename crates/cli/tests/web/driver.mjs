// Drives headless chromium (WebGPU on SwiftShader) through the web viewer for tests/web.rs:
//   node driver.mjs BASE_URL QUERY WIDTH HEIGHT OUT_DIR
// Writes OUT_DIR/pixels.rgba (the converged image), OUT_DIR/canvas.png (a page screenshot of
// the canvas) and prints one JSON line of findings. Exits non-zero with a message on failure.
import { createRequire } from 'node:module';
import { mkdtempSync, writeFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

const require = createRequire(process.env.PLAYWRIGHT_MODULES + '/');
const { chromium } = require('playwright-core');
const [base, query, width, height, out] = process.argv.slice(2);
const W = Number(width), H = Number(height);
const timeout = Number(process.env.POINTLET_WEB_TIMEOUT_MS || 240000);

const args = ['--headless', '--no-sandbox', '--enable-unsafe-webgpu',
  '--use-webgpu-adapter=swiftshader', '--disable-background-networking',
  '--disable-component-update', '--disable-sync', '--no-first-run'];
const profile = mkdtempSync(join(tmpdir(), 'pointlet-chromium-'));
const found = {};

async function waitState(page, states, what) {
  try {
    await page.waitForFunction((s) => s.includes(window.pointletState), states, { timeout, polling: 100 });
  } catch (e) {
    const st = await page.evaluate(() => [window.pointletState, window.pointletError,
      document.getElementById('message').textContent, document.getElementById('status').textContent]);
    throw new Error(`${what}: state ${JSON.stringify(st)} after ${timeout} ms`);
  }
  return page.evaluate(() => window.pointletState);
}

const context = await chromium.launchPersistentContext(profile, {
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  headless: true,
  args,
  viewport: { width: W, height: H },
  deviceScaleFactor: 1,
});
try {
  const page = await context.newPage();
  const logs = [];
  page.on('console', (m) => logs.push(`${m.type()}: ${m.text()}`));
  page.on('pageerror', (e) => logs.push(`pageerror: ${e.message}`));

  // 1. The shared view with every overlay hidden: converge, read the image.
  const t0 = Date.now();
  await page.goto(`${base}/${query}`);
  const state = await waitState(page, ['converged', 'error', 'no-webgpu'], 'the view with ui=off');
  if (state !== 'converged') {
    throw new Error(`the page says ${state}: ${await page.evaluate(() => window.pointletError)}\n${logs.join('\n')}`);
  }
  found.converge_ms = Date.now() - t0;
  const px = await page.evaluate(() => window.pointletPixels());
  writeFileSync(join(out, 'pixels.rgba'), Buffer.from(px.rgba, 'base64'));
  found.width = px.width;
  found.height = px.height;
  found.overlays_visible = await page.evaluate(() =>
    [...document.querySelectorAll('.overlay')].filter((e) => !e.classList.contains('hidden')).length);
  await page.locator('#view').screenshot({ path: join(out, 'canvas.png') });
  found.status = await page.evaluate(() => window.pointletViewer.status());
  if (process.env.POINTLET_WEB_BENCH) {
    found.bench = await page.evaluate((n) => window.pointletBench(n), Number(process.env.POINTLET_WEB_BENCH));
  }

  // 2. With overlays: colour by classification (the legend appears), measure two points.
  const ui = query.replace(/&?ui=off/, '');
  await page.setViewportSize({ width: 800, height: 600 });
  await page.goto(`${base}/${ui}`);
  await waitState(page, ['converged'], 'the view with overlays');
  await page.selectOption('#color', 'classification');
  await waitState(page, ['refining', 'converged'], 'recolouring');
  await waitState(page, ['converged'], 'the recoloured view');
  found.color = await page.evaluate(() => window.pointletViewer.color());
  found.legend_entries = await page.locator('#legend label').count();
  found.url_after_color = await page.evaluate(() => location.search);
  await page.click('#measure');
  // Two points: the middle of the canvas and a bit to the side, wherever points are drawn.
  const lit = await page.evaluate(async () => {
    const p = await window.pointletPixels();
    const bytes = Uint8Array.from(atob(p.rgba), (c) => c.charCodeAt(0));
    const pts = [];
    for (let y = Math.floor(p.height * 0.3); y < p.height * 0.7 && pts.length < 2; y += 7) {
      for (let x = Math.floor(p.width * 0.3); x < p.width * 0.7 && pts.length < 2; x += 13) {
        const i = 4 * (y * p.width + x);
        if (bytes[i] + bytes[i + 1] + bytes[i + 2] > 0 &&
            (pts.length === 0 || Math.hypot(x - pts[0][0], y - pts[0][1]) > 40)) pts.push([x, y]);
      }
    }
    return pts;
  });
  for (const [x, y] of lit) await page.mouse.click(x + 0.5, y + 0.5);
  found.measure_text = await page.locator('#measure-out').textContent();
  found.measurement = await page.evaluate(() => window.pointletMeasurement ?? null);
  await page.click('#screenshot');
  await page.waitForFunction(() => window.pointletScreenshot > 0, null, { timeout: 30000 });
  found.screenshot_bytes = await page.evaluate(() => window.pointletScreenshot);

  // 3. A browser without WebGPU gets a plain message.
  const bare = await context.newPage();
  await bare.addInitScript(() => Object.defineProperty(navigator, 'gpu', { value: undefined }));
  await bare.goto(`${base}/${query}`);
  await waitState(bare, ['no-webgpu', 'error', 'converged'], 'the page without WebGPU');
  found.without_webgpu = await bare.evaluate(() => [window.pointletState, document.getElementById('message').textContent]);
  found.console_errors = logs.filter((l) => l.startsWith('error') || l.startsWith('pageerror'));
  console.log(JSON.stringify(found));
} finally {
  await context.close();
  rmSync(profile, { recursive: true, force: true });
}
