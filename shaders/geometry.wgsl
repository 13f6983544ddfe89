// Vertex stage of every geometry pass: positions and colours come from storage buffers indexed
// by vertex_index (three vertices per triangle, in submission order), so the stage can read its
// triangle's other vertices for the face normal of the headlight shading.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> colors: array<vec4<f32>>;

@vertex
fn vs_main(@builtin(vertex_index) vid: u32) -> VertexOut {
    let tri = vid / 3u;
    let p0 = positions[3u * tri].xyz;
    let p1 = positions[3u * tri + 1u].xyz;
    let p2 = positions[3u * tri + 2u].xyz;
    let n = normalize(cross(p1 - p0, p2 - p0));
    let facing = abs(dot(n, params.forward.xyz));
    let shade = AMBIENT + (1.0 - AMBIENT) * facing;
    let c = colors[vid];
    let c0 = colors[3u * tri];
    let same = all(c0 == colors[3u * tri + 1u]) && all(c0 == colors[3u * tri + 2u]);
    var out: VertexOut;
    out.flat_color = vec4<f32>(c0.rgb * shade, c0.a);
    out.uniform_color = select(0u, 1u, same);
    out.clip = params.view_proj * vec4<f32>(positions[vid].xyz, 1.0);
    out.color = vec4<f32>(c.rgb * shade, c.a);
    out.primitive = tri;
    out.facing = facing;
    return out;
}

// The fragment's colour as the pipeline stores it: the triangle's own when its vertices share
// one, else interpolated; clamped, 8 bits a channel.
fn fragment_rgba8(in: VertexOut) -> u32 {
    let color = select(in.color, in.flat_color, in.uniform_color != 0u);
    return pack_rgba8(clamp(color, vec4<f32>(0.0), vec4<f32>(1.0)));
}
