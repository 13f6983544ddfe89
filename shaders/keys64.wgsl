// What the passes that still use 64-bit integers share (SHADER_INT64): the capture key. A pass that includes this cannot run on a device without
// 64-bit integers (WebGPU, most of Metal); the portable passes (wgsl::shaders::PORTABLE) do
// not.

// The 64-bit capture key: window depth bits high (non-negative floats order like their bits),
// RGBA8 low, as fragment::fragment_key.
fn fragment_key(depth: f32, rgba8: u32) -> u64 {
    let d = select(0.0, depth, depth > 0.0);
    return (u64(bitcast<u32>(d)) << 32u) | u64(rgba8);
}
