// Closest hits of a batch of rays: what `phr_render::geometry::Geometry::intersect` answers on
// the CPU, for checking the GPU's traversal against it and for timing it alone.

// origin.xyz, tmin; dir.xyz, tmax.
struct QueryRay {
    origin: vec4<f32>,
    dir: vec4<f32>,
}

// The closest hit's distance, barycentrics and primitive number (NO_HIT: none).
struct Answer {
    t: f32,
    u: f32,
    v: f32,
    prim: u32,
}

@group(1) @binding(0) var<storage, read> queries: array<QueryRay>;
@group(1) @binding(1) var<storage, read_write> answers: array<Answer>;

@compute @workgroup_size(64)
fn closest(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x + id.y * 65535u * 64u;
    if i >= arrayLength(&queries) {
        return;
    }
    let q = queries[i];
    let hit = closest_hit(make_ray(q.origin.xyz, q.dir.xyz, q.origin.w, min(q.dir.w, F32_MAX)));
    answers[i] = Answer(hit.t, hit.u, hit.v, hit.prim);
}
