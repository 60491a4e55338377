// Frame times of the web viewer in headless chromium (WebGPU on SwiftShader):
//   node web-bench.mjs URL WIDTH HEIGHT SECONDS
// Opens URL, waits until the viewer draws, orbits for SECONDS with window.pointletBench and
// prints one JSON line: frames drawn and milliseconds per frame.
import { createRequire } from 'node:module';
import { mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

const require = createRequire(process.env.PLAYWRIGHT_MODULES + '/');
const { chromium } = require('playwright-core');
const [url, width, height, seconds] = process.argv.slice(2);
const profile = mkdtempSync(join(tmpdir(), 'pointlet-bench-'));
const context = await chromium.launchPersistentContext(profile, {
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  headless: true,
  args: ['--headless', '--no-sandbox', '--enable-unsafe-webgpu',
    '--use-webgpu-adapter=swiftshader', '--disable-background-networking', '--no-first-run'],
  viewport: { width: Number(width), height: Number(height) },
  deviceScaleFactor: 1,
});
try {
  const page = await context.newPage();
  await page.goto(url);
  await page.waitForFunction(() => ['refining', 'converged', 'error', 'no-webgpu']
    .includes(window.pointletState), null, { timeout: 300000, polling: 100 });
  const state = await page.evaluate(() => window.pointletState);
  if (state === 'error' || state === 'no-webgpu') {
    throw new Error(`the viewer says ${state}: ${await page.evaluate(() => window.pointletError)}`);
  }
  const r = await page.evaluate((s) => window.pointletBench(s), Number(seconds));
  console.log(JSON.stringify({ url, width: Number(width), height: Number(height), ...r }));
} finally {
  await context.close();
  rmSync(profile, { recursive: true, force: true });
}
