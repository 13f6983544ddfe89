// The web demo's wasm build on Dawn (Chrome's WebGPU, as a browser gives it to a page: no
// optional feature, WebGPU's default limits), its frames held to the native build's on
// WebGPU's core device (`dhoit-web DIR`): run by scripts/web.sh test.
//   dawn.sh run scripts/web_test.mjs PKG_DIR NATIVE_DIR
// With WEB_SUMMARY=FILE, what it measured as JSON there (scripts/web_summary.py tabulates it).
import { readFileSync, writeFileSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { pathToFileURL } from 'node:url';

const [pkgDir, nativeDir] = process.argv.slice(2);
if (!pkgDir || !nativeDir) {
  console.error('usage: web_test.mjs PKG_DIR NATIVE_DIR');
  process.exit(2);
}
const { create, globals } = await import(process.env.DAWN_WEBGPU);
Object.assign(globalThis, globals);
// What wgpu's WebGPU backend looks for: a window global and its navigator's gpu.
Object.defineProperty(globalThis, 'navigator', { value: { gpu: create([]) }, configurable: true });
globalThis.Window ??= class Window {};

const native = JSON.parse(readFileSync(join(nativeDir, 'native.json'), 'utf8'));
const demoJs = await import(pathToFileURL(resolve('examples/web/demo.mjs')));
const pkg = await import(pathToFileURL(resolve(pkgDir, 'dhoit_web.js')));
const [width, height] = native.size;
const app = await demoJs.start(pkg, {
  wasm: readFileSync(join(pkgDir, 'dhoit_web_bg.wasm')),
  methods: native.methods, scene: native.scene, width, height, budget: native.budget,
});
console.log(`web: wasm on ${app.demo.adapter()}: ${native.methods.join(', ')}; ${native.scene} ${width}x${height} at ${native.budget}`);
// The hosts' f32 maths differ in their last bits (wasm's libm and the native one's sines): the
// page renders the native host's camera and vertices, so the frames compare what the GPUs did.
const words = (file) => new Uint32Array(new Uint8Array(readFileSync(join(nativeDir, file))).buffer);
const nativeGeometry = words('geometry.u32');
const differing = (a, b) => a.length === b.length ? a.filter((w, i) => w !== b[i]).length : `all ${b.length}`;
const host = {
  camera_differ: differing(app.demo.camera_bits(), native.camera), camera_words: native.camera.length,
  vertex_differ: differing(app.demo.geometry_bits(), nativeGeometry), vertex_words: nativeGeometry.length,
};
console.log(`web: the page's host computed ${host.camera_differ} of ${host.camera_words} camera words ` +
  `and ${host.vertex_differ} of ${host.vertex_words} vertex words ` +
  'otherwise than the native host; it renders the native ones');
app.demo.set_camera_bits(Uint32Array.from(native.camera));
app.demo.set_geometry_bits(nativeGeometry);
const { views, ms } = await demoJs.render(app);
let failed = false;
const summary = { adapter: app.demo.adapter(), host, scene: native.scene, size: [width, height], budget: native.budget, ms, views: [] };
for (const v of views) {
  const want = native.views.find((n) => n.method === v.method);
  const ref = readFileSync(join(nativeDir, `${v.method}.rgba`));
  const refLinear = new Float32Array(new Uint8Array(readFileSync(join(nativeDir, `${v.method}.f32`))).buffer);
  // The GPU's frame, bit for bit: the linear image the resolve wrote.
  let floats = v.linear.length === refLinear.length ? 0 : -1, worst = 0;
  const pixels = new Set();
  for (let i = 0; floats >= 0 && i < refLinear.length; i++) {
    if (v.linear[i] === refLinear[i]) continue;
    floats++;
    worst = Math.max(worst, Math.abs(v.linear[i] - refLinear[i]));
    pixels.add(Math.floor(i / 3));
  }
  for (const p of [...pixels].slice(0, 4)) {
    const at = (a) => [...a.slice(3 * p, 3 * p + 3)].map((c) => c.toFixed(6)).join(' ');
    console.log(`web:   ${v.method} pixel (${p % width}, ${Math.floor(p / width)}): ${at(v.linear)} here, ${at(refLinear)} native`);
  }
  // Its 8-bit sRGB encoding, made on the host: wasm's powf and the native libm's may round a
  // channel apart by one.
  let differ = 0, most = 0;
  for (let i = 0; i < ref.length; i++) {
    const d = Math.abs(ref[i] - v.rgba[i]);
    if (d) differ++;
    most = Math.max(most, d);
  }
  const same = v.rgba.length === ref.length && v.bytes === want.bytes && v.exact === want.exact;
  console.log(`web: ${v.method.padEnd(8)} ${v.bytes} B (native ${want.bytes}), exact ${v.exact}, ` +
    `${v.frames} frame(s), RMSE vs the A-buffer ${v.rmse.toFixed(5)} (native ${want.rmse.toFixed(5)}); ` +
    `linear values differing from the native frame: ${floats} of ${refLinear.length} (by at most ${worst}); ` +
    `sRGB8 channels: ${differ} of ${ref.length}, by at most ${most}`);
  summary.views.push({
    method: v.method, frames: v.frames, bytes: v.bytes, native_bytes: want.bytes, exact: v.exact,
    linear_differ: floats, linear_values: refLinear.length, srgb_differ: differ, srgb_channels: ref.length,
    srgb_most: most, order_independent: want.order_independent, rmse_ratio: v.rmse / want.rmse,
  });
  if (!want.order_independent) {
    // Past its pool, the list keeps the fragments the GPU ran first (which differ run to run,
    // natively too): held to the same bytes and an error against the A-buffer between 2/3 and
    // 3/2 of the native frame's.
    const near = v.rmse <= 1.5 * want.rmse && v.rmse >= want.rmse / 1.5;
    console.log(`web:   ${v.method} keeps the fragments the GPU runs first: held to the native ` +
      `frame's bytes and its error within 1.5x (${(v.rmse / want.rmse).toFixed(3)}x)`);
    if (!same || !near) failed = true;
  } else if (!same || floats !== 0 || most > 1) failed = true;
}
console.log(`web: ${views.length} methods rendered in ${ms.toFixed(0)} ms`);
if (process.env.WEB_SUMMARY) writeFileSync(process.env.WEB_SUMMARY, JSON.stringify(summary, null, 1));
if (failed) {
  console.error('web: the wasm frames differ from the native ones');
  process.exit(1);
}
console.log('web: the wasm build on Dawn gives the native frames, bit for bit (the list: its bytes, and its error within 1.5x)');
process.exit(0);
