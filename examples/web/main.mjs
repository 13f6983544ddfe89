// The page: dhoit's wasm on the browser's WebGPU (demo.mjs), one canvas a method, the budget a
// slider. Rendering is awaited, never blocking the page; a slider moved while a frame renders
// is taken when it ends.
import * as pkg from './pkg/dhoit_web.js';
import { start, render } from './demo.mjs';

const WIDTH = 320, HEIGHT = 240;
const NAMES = { dkb: 'DKB (learned)', vkb: 'VKB', abuffer: 'A-buffer (exact)' };
const $ = (id) => document.getElementById(id);

function status(text, error = false) {
  $('status').textContent = text;
  $('status').className = error ? 'error' : '';
}

function kib(bytes) {
  return `${(bytes / 1024).toFixed(0)} KiB`;
}

async function main() {
  if (!navigator.gpu) {
    status('This browser has no WebGPU (navigator.gpu): try a recent Chrome, Edge or Safari.', true);
    return;
  }
  const app = await start(pkg, { width: WIDTH, height: HEIGHT, budget: `${$('budget').value}%` });
  for (const s of app.scenes) $('scene').add(new Option(s, s));
  const figures = {};
  for (const m of app.methods) {
    const fig = document.createElement('figure');
    const canvas = Object.assign(document.createElement('canvas'), { width: WIDTH, height: HEIGHT });
    const caption = document.createElement('figcaption');
    fig.append(canvas, caption);
    $('views').append(fig);
    figures[m] = { ctx: canvas.getContext('2d'), caption };
  }
  let busy = false, again = false;
  async function draw() {
    if (busy) { again = true; return; }
    busy = true;
    try {
      do {
        again = false;
        if ($('scene').value !== app.demo.scene()) app.demo.set_scene($('scene').value);
        const budget = `${$('budget').value}%`;
        $('budget-label').textContent = budget;
        status(`Rendering at ${budget}...`);
        const { views, ms } = await render(app, budget);
        for (const v of views) {
          const f = figures[v.method];
          f.ctx.putImageData(new ImageData(new Uint8ClampedArray(v.rgba.buffer), WIDTH, HEIGHT), 0, 0);
          const error = v.method === 'abuffer' ? 'the reference' : `RMSE ${v.rmse.toPrecision(2)} against it`;
          f.caption.innerHTML = `<b>${NAMES[v.method] ?? v.method}</b><br>${kib(v.bytes)}, ` +
            `${v.exact ? 'every fragment kept' : error}`;
        }
        status(`${views.length} methods in ${ms.toFixed(0)} ms on ${app.demo.adapter()}`);
      } while (again);
    } catch (e) {
      status(`dhoit: ${e.message ?? e}`, true);
    } finally {
      busy = false;
    }
  }
  $('budget').addEventListener('input', draw);
  $('scene').addEventListener('change', draw);
  await draw();
}

main().catch((e) => status(`dhoit: ${e.message ?? e}`, true));
