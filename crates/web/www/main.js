// The page around the wasm viewer: input, overlays, the address bar. Rendering, streaming and
// the view state live in Rust (crates/web); this file only forwards events and shows results.
// Tests read window.pointletState ('loading', 'refining', 'converged', 'error', 'no-webgpu').
import init, { open_viewer, has_webgpu } from './pointlet_web.js';

const $ = (id) => document.getElementById(id);
const canvas = $('view');
const params = new URLSearchParams(location.search);
const ui = !['off', '0', 'false'].includes(params.get('ui'));
window.pointletState = 'loading';

function say(text, html) {
  const m = $('message');
  if (html) m.innerHTML = html; else m.textContent = text;
  m.classList.remove('hidden');
}

function fail(state, text) {
  window.pointletState = state;
  window.pointletError = text;
  say(text);
}

function sizeCanvas() {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(canvas.clientWidth * dpr));
  const h = Math.max(1, Math.round(canvas.clientHeight * dpr));
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
}

// Without ?store=, list the stores the server offers.
async function listStores() {
  try {
    const r = await fetch('stores.json');
    const stores = await r.json();
    const items = stores.map((s) => `<li><a href="?store=${encodeURIComponent(s.name)}">${s.name}</a></li>`);
    say('', `<div>Pick a store:<ul>${items.join('')}</ul></div>`);
    window.pointletState = 'no-store';
  } catch (e) {
    fail('no-store', 'No store named: add ?store=NAME to the address.');
  }
}

async function main() {
  await init();
  if (!has_webgpu()) {
    fail('no-webgpu', 'This browser has no WebGPU, which the Pointlet viewer needs. ' +
      'Use a recent Chrome, Edge or Firefox with WebGPU enabled.');
    return;
  }
  if (!params.get('store')) { await listStores(); return; }
  sizeCanvas();
  let viewer;
  try {
    const base = location.pathname.replace(/[^/]*$/, '');
    viewer = await open_viewer(canvas, location.search, base);
  } catch (e) {
    const text = String(e && e.message ? e.message : e);
    fail(/adapter|WebGPU|GPU/i.test(text) ? 'no-webgpu' : 'error',
      /adapter/i.test(text) ? `WebGPU is present but offers no usable GPU adapter: ${text}` : text);
    return;
  }
  window.pointletViewer = viewer;
  if (ui) for (const el of document.querySelectorAll('.overlay')) el.classList.remove('hidden');
  setupControls(viewer);
  setupInput(viewer);
  let lastQuery = '';
  let frameTimes = [];
  let last = performance.now();
  const loop = (now) => {
    sizeCanvas();
    try {
      viewer.frame();
    } catch (e) {
      fail('error', String(e));
      return;
    }
    const state = viewer.state();
    window.pointletState = state;
    if (state !== 'converged') frameTimes.push(now - last);
    if (frameTimes.length > 60) frameTimes.shift();
    last = now;
    if (ui) {
      const avg = frameTimes.reduce((a, b) => a + b, 0) / Math.max(1, frameTimes.length);
      $('status').textContent = `${state} · ${viewer.status()} · ${avg.toFixed(1)} ms/frame`;
      placeMarkers(viewer);
    }
    const q = viewer.query();
    if (q !== lastQuery) { history.replaceState(null, '', q || location.pathname); lastQuery = q; }
    requestAnimationFrame(loop);
  };
  requestAnimationFrame(loop);
}

function setupControls(viewer) {
  const color = $('color');
  for (const m of viewer.color_modes()) color.add(new Option(m, m));
  color.value = viewer.color();
  color.onchange = () => { viewer.set_color(color.value); showLegend(viewer); };
  const size = $('size');
  size.value = params.get('size') || '1';
  size.onchange = () => viewer.set_point_size(size.value);
  const budget = $('budget');
  budget.value = String(viewer.budget());
  budget.onchange = () => viewer.set_budget(Number(budget.value));
  $('raster').onchange = (e) => {
    try { viewer.set_raster(e.target.value); } catch (err) { alert(err); }
  };
  $('edl').checked = params.get('edl') === 'on';
  $('edl').onchange = (e) => viewer.set_edl(e.target.checked);
  $('measure').onclick = () => {
    measuring = !measuring;
    picks = [];
    $('measure').textContent = measuring ? 'Click two points…' : 'Measure distance';
    $('measure-out').textContent = '';
  };
  $('screenshot').onclick = () => screenshot(viewer);
  showLegend(viewer);
}

function showLegend(viewer) {
  const legend = $('legend');
  legend.innerHTML = '';
  if (viewer.color() !== 'classification') { legend.classList.add('hidden'); return; }
  if (ui) legend.classList.remove('hidden');
  for (const line of viewer.legend()) {
    const [cls, name, rgb, hidden] = line.split('|');
    const label = document.createElement('label');
    const box = document.createElement('input');
    box.type = 'checkbox';
    box.checked = hidden !== 'hidden';
    box.onchange = () => viewer.set_class_hidden(Number(cls), !box.checked);
    const swatch = document.createElement('span');
    swatch.className = 'swatch';
    swatch.style.background = rgb;
    label.append(box, swatch, `${cls} ${name}`);
    legend.append(label);
  }
}

let measuring = false;
let picks = [];
let markers = [];

function placeMarkers(viewer) {
  const dpr = window.devicePixelRatio || 1;
  while (markers.length < picks.length) {
    const m = document.createElement('div');
    m.className = 'marker';
    document.body.append(m);
    markers.push(m);
  }
  markers.forEach((m, i) => {
    const p = picks[i] && viewer.project(picks[i][0], picks[i][1], picks[i][2]);
    m.classList.toggle('hidden', !p);
    if (p) { m.style.left = `${p[0] / dpr}px`; m.style.top = `${p[1] / dpr}px`; }
  });
}

function onMeasureClick(viewer, e) {
  const dpr = window.devicePixelRatio || 1;
  const p = viewer.pick(e.offsetX * dpr, e.offsetY * dpr);
  if (!p) { $('measure-out').textContent = 'No point there'; return; }
  if (picks.length >= 2) picks = [];
  picks.push(p);
  const f = (v) => v.map((c) => c.toFixed(3)).join(', ');
  if (picks.length === 1) {
    $('measure-out').textContent = `A: ${f(p)}`;
  } else {
    const [a, b] = picks;
    const d = Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    $('measure-out').textContent = `distance ${d.toFixed(3)}`;
    window.pointletMeasurement = d;
  }
}

function setupInput(viewer) {
  let drag = null;
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  canvas.addEventListener('pointerdown', (e) => {
    drag = { x: e.clientX, y: e.clientY, button: e.button, shift: e.shiftKey, moved: 0 };
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener('pointermove', (e) => {
    if (!drag) return;
    const dpr = window.devicePixelRatio || 1;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    drag.moved += Math.abs(dx) + Math.abs(dy);
    if (drag.button === 2 || drag.button === 1 || drag.shift) viewer.pan(dx * dpr, dy * dpr);
    else viewer.orbit(dx, dy);
  });
  canvas.addEventListener('pointerup', (e) => {
    if (drag && drag.moved < 3 && measuring && drag.button === 0) onMeasureClick(viewer, e);
    drag = null;
  });
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    viewer.zoom(Math.exp(e.deltaY * 0.001));
  }, { passive: false });
}

async function screenshot(viewer) {
  const png = await pngBlob(viewer);
  const a = document.createElement('a');
  a.href = URL.createObjectURL(png);
  a.download = `${params.get('store') || 'pointlet'}.png`;
  a.click();
  window.pointletScreenshot = png.size;
}

// The exact RGBA of the last frame as a PNG.
async function pngBlob(viewer) {
  const w = viewer.width(), h = viewer.height();
  const rgba = await viewer.read_pixels();
  const c = document.createElement('canvas');
  c.width = w; c.height = h;
  c.getContext('2d').putImageData(new ImageData(new Uint8ClampedArray(rgba.buffer), w, h), 0, 0);
  return new Promise((resolve) => c.toBlob(resolve, 'image/png'));
}

// For tests and benchmarks: the last image's pixels, base64.
window.pointletPixels = async () => {
  const rgba = await window.pointletViewer.read_pixels();
  let s = '';
  for (let i = 0; i < rgba.length; i += 0x8000) s += String.fromCharCode(...rgba.subarray(i, i + 0x8000));
  return { width: window.pointletViewer.width(), height: window.pointletViewer.height(), rgba: btoa(s) };
};

// Benchmark: orbit for `seconds` (each frame drawn under the LoD budget); milliseconds per
// frame drawn (frames wait for the GPU: at most two in flight).
window.pointletBench = (seconds) => new Promise((resolve) => {
  const v = window.pointletViewer;
  const start = performance.now();
  const first = v.frames_drawn();
  const step = (now) => {
    v.orbit(2, 0);
    if (now - start < seconds * 1000) { requestAnimationFrame(step); return; }
    const frames = v.frames_drawn() - first;
    resolve({ frames, ms_per_frame: (now - start) / Math.max(1, frames) });
  };
  requestAnimationFrame(step);
});

main().catch((e) => fail('error', String(e)));
