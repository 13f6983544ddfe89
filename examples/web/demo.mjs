// dhoit's web demo, what the page (main.mjs) and its test on Dawn (scripts/web_test.mjs) share:
// the wasm module started on the page's WebGPU, and one render of every method.

// Starts the wasm module (`pkg`: its wasm-bindgen glue, `wasm`: its bytes or URL, or nothing
// for the glue's own URL) and dhoit on `navigator.gpu`: `methods` (by default the page's three)
// showing `scene` (by default the first the module offers).
export async function start(pkg, { wasm, methods, scene, width, height, budget }) {
  await pkg.default(wasm === undefined ? undefined : { module_or_path: wasm });
  methods ??= pkg.WebDemo.methods();
  scene ??= pkg.WebDemo.scenes()[0];
  const demo = await pkg.WebDemo.start(methods, scene, width, height, budget);
  return { demo, width, height, methods, scenes: pkg.WebDemo.scenes() };
}

// Every method's frame at `budget`: [{method, rgba, bytes, exact, frames, rmse}], with the
// milliseconds the render took.
export async function render({ demo }, budget) {
  if (budget !== undefined) demo.set_budget(budget);
  const t0 = performance.now();
  const views = await demo.render();
  return { views, ms: performance.now() - t0 };
}
