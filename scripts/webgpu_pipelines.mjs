// Creates every pipeline in a manifest (examples/webgpu_pipelines.rs writes it) on a real
// WebGPU, Dawn (Chrome's), with a device as a page gets one: no optional feature, WebGPU's
// default limits. Prints each failure and a summary; exits 1 on any validation error.
// Usage (through scripts/dawn.sh run): webgpu_pipelines.mjs MANIFEST.json
import { readFileSync } from 'node:fs';
const { create, globals } = await import(process.env.DAWN_WEBGPU);
Object.assign(globalThis, globals);
const manifest = JSON.parse(readFileSync(process.argv[2], 'utf8'));
// Dawn answers its promises (compilation info, error scopes) while node's loop is alive.
const keep = setInterval(() => {}, 5);
const gpu = create([]); // kept: the adapter and device die with it
const adapter = await gpu.requestAdapter();
if (!adapter) { console.error('no WebGPU adapter (scripts/dawn.sh setup first)'); process.exit(1); }
const device = await adapter.requestDevice(); // no optional feature, default limits
console.log(`Dawn on ${adapter.info.description || adapter.info.architecture}: ` +
  `${device.features.size} features, ${device.limits.maxStorageBuffersPerShaderStage} storage buffers a stage`);
const modules = new Map();
let created = 0;
const failed = [];
for (const p of manifest.pipelines) {
  if (process.env.DAWN_VERBOSE) console.log("creating", p.label, JSON.stringify(p.stages).slice(0, 200));
  if (!p.code) { failed.push(`${p.label}: no WGSL recorded`); continue; }
  device.pushErrorScope('validation');
  let module = modules.get(p.code);
  if (!module) {
    module = device.createShaderModule({ label: p.label, code: p.code });
    modules.set(p.code, module);
    for (const m of (await module.getCompilationInfo()).messages) {
      if (m.type === 'error') failed.push(`${p.label}: WGSL ${m.lineNum}:${m.linePos} ${m.message}`);
    }
  }
  const s = p.stages;
  if (s.compute) {
    device.createComputePipeline({ label: p.label, layout: 'auto', compute: { module, entryPoint: s.compute } });
  } else {
    const desc = {
      label: p.label, layout: 'auto',
      vertex: { module, entryPoint: s.vertex },
      primitive: { topology: 'triangle-list', cullMode: 'none' },
      fragment: { module, entryPoint: s.fragment, targets: s.targets.map(t => t && ({ format: t.format, ...(t.blend ? { blend: t.blend } : {}) })) },
    };
    if (s.depthStencil) desc.depthStencil = s.depthStencil;
    device.createRenderPipeline(desc);
  }
  const err = await device.popErrorScope();
  if (err) failed.push(`${p.label}: ${err.message}`);
  else created++;
}
for (const f of failed) console.error('FAILED', f);
console.log(`${created} of ${manifest.pipelines.length} pipelines created (${modules.size} shader modules) ` +
  `for ${manifest.methods.join(', ')}; ${failed.length} errors`);
clearInterval(keep);
process.exit(failed.length === 0 && created > 0 ? 0 : 1);
