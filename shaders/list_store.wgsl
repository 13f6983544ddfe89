// The budgeted linked list's store (geometry), as Bevy's OIT appends: each visible transparent
// fragment takes the next node from one atomic counter, first come, first served, while the
// frame's F nodes (params.budget_fragments) last; its 8-byte capture key goes in the node and
// the node becomes its pixel's head, the old head its next. A fragment arriving after the last
// node is dropped (the counter still counts it: what arrived). Which fragments arrive first is
// the order the device runs them in, so where F truncates the kept set can change from run to
// run (composite::linked_list_kept takes submission order).

// Per pixel: its first node's index + 1 (0: none).
@group(1) @binding(0) var<storage, read_write> heads: array<atomic<u32>>;
// Per node: the next node's index + 1 (0: the list's end).
@group(1) @binding(1) var<storage, read_write> next: array<u32>;
@group(1) @binding(2) var<storage, read_write> keys: array<vec2<u32>>;
// Word 0: the fragments that arrived, kept or dropped.
@group(1) @binding(3) var<storage, read_write> counter: array<atomic<u32>, 4>;
// Per node, where the frame stores them (common.wgsl's stores_tints): its fragment's tint word.
@group(1) @binding(4) var<storage, read_write> tints: array<u32>;

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let f = transparent_fragment(in, front);
    if (!f.visible) {
        return vec4<f32>(0.0);
    }
    let node = atomicAdd(&counter[0], 1u);
    if (node >= params.budget_fragments) {
        return vec4<f32>(0.0);
    }
    let p = pixel_index(in.clip, params.width);
    keys[node] = key_of(in.clip.z, f.rgba8);
    if (stores_tints()) {
        tints[node] = f.tint;
    }
    next[node] = atomicExchange(&heads[p], node + 1u);
    return vec4<f32>(0.0);
}
