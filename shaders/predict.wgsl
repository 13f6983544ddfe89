// Batch prediction (compute, one invocation a row): the network of mlp.wgsl on rows of 12
// features, as `dhoit predict` runs it in burn and mlp::Mlp::forward on the CPU.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> rows: array<f32>;
@group(0) @binding(3) var<storage, read_write> predictions: array<f32>;

@compute @workgroup_size(PIXEL_GROUP)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let r = grid_index(wid, nwg, lid, PIXEL_GROUP);
    if (r >= params.pixels) {
        return;
    }
    var x: array<f32, FEATURES>;
    for (var i = 0u; i < FEATURES; i++) {
        x[i] = rows[FEATURES * r + i];
    }
    predictions[r] = mlp_forward(x);
}
