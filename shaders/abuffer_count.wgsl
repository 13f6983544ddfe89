// A-buffer pass 1 (geometry): count the fragments of every pixel.

@group(1) @binding(0) var<storage, read_write> counts: array<atomic<u32>>;

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    atomicAdd(&counts[pixel_index(in.clip, params.width)], 1u);
    return vec4<f32>(0.0);
}
