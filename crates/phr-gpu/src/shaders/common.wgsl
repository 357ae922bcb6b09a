// What every kernel shares: 64-bit integers (WGSL has none) for the CPU's random numbers,
// the scene's buffers, and the closest-hit traversal of the CPU's 8-wide BVH.
//
// The primitive tests are those of `phr_bvh::triangle::intersect_triangle_edges` and
// `phr_bvh::sphere::Sphere::intersect`, the box test that of `phr_bvh::Aabb::intersect`, and
// the tie rule that of `phr_render::geometry` (at equal distance the lower primitive number
// wins), so the GPU finds the hits the CPU finds.

// ---- 64-bit unsigned integers as (low, high) ---------------------------------------------

fn mulhi32(a: u32, b: u32) -> u32 {
    let a0 = a & 0xffffu;
    let a1 = a >> 16u;
    let b0 = b & 0xffffu;
    let b1 = b >> 16u;
    let p00 = a0 * b0;
    let p01 = a0 * b1;
    let p10 = a1 * b0;
    let p11 = a1 * b1;
    let mid = (p00 >> 16u) + (p01 & 0xffffu) + (p10 & 0xffffu);
    return p11 + (p01 >> 16u) + (p10 >> 16u) + (mid >> 16u);
}

fn mul64(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    return vec2<u32>(a.x * b.x, mulhi32(a.x, b.x) + a.x * b.y + a.y * b.x);
}

fn add64(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    let lo = a.x + b.x;
    return vec2<u32>(lo, a.y + b.y + select(0u, 1u, lo < a.x));
}

// a >> n for 0 < n < 32.
fn shr64(a: vec2<u32>, n: u32) -> vec2<u32> {
    return vec2<u32>((a.x >> n) | (a.y << (32u - n)), a.y >> n);
}

// SplitMix64's finaliser (`phr_render::sampler::mix64`).
fn mix64(z0: vec2<u32>) -> vec2<u32> {
    var z = mul64(z0 ^ shr64(z0, 30u), vec2<u32>(0x1ce4e5b9u, 0xbf58476du));
    z = mul64(z ^ shr64(z, 27u), vec2<u32>(0x133111ebu, 0x94d049bbu));
    return z ^ shr64(z, 31u);
}

// ---- PCG32, seeded as `phr_render::sampler::Pcg32::for_pixel` ----------------------------

struct Pcg {
    state: vec2<u32>,
    inc: vec2<u32>,
}

const PCG_MULTIPLIER: vec2<u32> = vec2<u32>(0x4c957f2du, 0x5851f42du);

fn pcg_next(rng: ptr<function, Pcg>) -> u32 {
    let old = (*rng).state;
    (*rng).state = add64(mul64(old, PCG_MULTIPLIER), (*rng).inc);
    // ((old >> 18) ^ old) >> 27, truncated; rotation old >> 59.
    let xorshifted = shr64(shr64(old, 18u) ^ old, 27u).x;
    let rot = old.y >> 27u;
    return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
}

fn pcg_new(seed: vec2<u32>, stream: vec2<u32>) -> Pcg {
    // inc = (stream << 1) | 1
    var rng = Pcg(vec2<u32>(0u, 0u), vec2<u32>((stream.x << 1u) | 1u, (stream.y << 1u) | (stream.x >> 31u)));
    pcg_next(&rng);
    rng.state = add64(rng.state, seed);
    pcg_next(&rng);
    return rng;
}

fn pcg_for_pixel(seed: vec2<u32>, frame: u32, pixel: u32) -> Pcg {
    let key = mix64(seed ^ mix64(vec2<u32>(pixel, frame)));
    return pcg_new(key, mix64(key ^ vec2<u32>(0x4c957f2du, 0x5851f42du)));
}

// Uniform in [0, 1).
fn next_f32(rng: ptr<function, Pcg>) -> f32 {
    return f32(pcg_next(rng) >> 8u) * (1.0 / 16777216.0);
}

const TAU: f32 = 6.283185307179586;

fn unit_vector(rng: ptr<function, Pcg>) -> vec3<f32> {
    let z = 1.0 - 2.0 * next_f32(rng);
    let r = sqrt(max(1.0 - z * z, 0.0));
    let phi = TAU * next_f32(rng);
    return vec3<f32>(r * cos(phi), r * sin(phi), z);
}

fn in_unit_sphere(rng: ptr<function, Pcg>) -> vec3<f32> {
    let v = unit_vector(rng);
    let x = next_f32(rng);
    return v * select(0.0, pow(x, 1.0 / 3.0), x > 0.0);
}

// ---- The scene ---------------------------------------------------------------------------

// A node of the 8-wide BVH (`GpuNode`, the CPU's `phr_bvh::wide::WideNode<8>`): its
// children's boxes as rows min_x, max_x, min_y, max_y, min_z, max_z of 8 lanes, row `r`'s
// lanes 4h..4h + 3 at `bounds[2r + h]`; per slot the child (interior: its node; leaf: its
// first primitive record) and the primitive count (interior: 0; empty slot: EMPTY_SLOT).
struct Node {
    bounds: array<vec4<f32>, 12>,
    child: array<vec4<u32>, 2>,
    count: array<vec4<u32>, 2>,
}

// A primitive in leaf order (`GpuPrim`). Triangle: `a` = v0, `b` = e1, `c` = e2. Sphere: `a`
// = centre, `b.x` = radius. `material` with SPHERE set for spheres and MASKED for triangles
// with an alpha mask; `number` the primitive's number in the scene; `emitter` its emitter's
// number plus one (0: not a light to sample).
struct Prim {
    a: vec3<f32>,
    material: u32,
    b: vec3<f32>,
    number: u32,
    c: vec3<f32>,
    emitter: u32,
}

const EMPTY_SLOT: u32 = 0xffffffffu;
const SPHERE: u32 = 0x80000000u;
// A triangle whose material has an alpha mask to test.
const MASKED: u32 = 0x40000000u;
const NO_TEXTURE: u32 = 0xffffffffu;
const NO_HIT: u32 = 0xffffffffu;
const STACK: u32 = 128u;
const EPSILON: f32 = 1.1920929e-7;
const EDGE_TOLERANCE: f32 = 8.0 * EPSILON;
const MAX_EDGE_SLACK: f32 = 1.0e-5;
const ROBUST_SLAB: f32 = 1.0 + 6.0 * EPSILON;
// The largest f32, standing for infinity (WGSL has no infinite constant): distances are
// below it, a ray's open end is at it.
const F32_MAX: f32 = 0x1.fffffep+127;

// The tree's nodes and the primitives, each over up to four bindings: a large scene's arrays
// exceed what one storage binding may see (lavapipe: 128 MiB). Binding k holds elements
// k·N.. of N per binding. The pipeline's constants (`Split`) say how many bindings each uses:
// one, for most scenes, folds the accessors down to a plain load (the general form costs
// lavapipe 30 % of a frame).
@group(0) @binding(0) var<storage, read> nodes: array<Node>;
@group(0) @binding(1) var<storage, read> prims: array<Prim>;
@group(0) @binding(10) var<storage, read> nodes1: array<Node>;
@group(0) @binding(11) var<storage, read> nodes2: array<Node>;
@group(0) @binding(12) var<storage, read> nodes3: array<Node>;
@group(0) @binding(13) var<storage, read> prims1: array<Prim>;
@group(0) @binding(14) var<storage, read> prims2: array<Prim>;
@group(0) @binding(15) var<storage, read> prims3: array<Prim>;
override nodes_per_binding: u32;
override prims_per_binding: u32;
override node_bindings: u32;
override prim_bindings: u32;

fn node_at(i: u32) -> Node {
    if node_bindings == 1u || i < nodes_per_binding {
        return nodes[i];
    }
    let k = i / nodes_per_binding;
    let j = i - k * nodes_per_binding;
    if k == 1u {
        return nodes1[j];
    }
    if k == 2u {
        return nodes2[j];
    }
    return nodes3[j];
}

fn prim_at(i: u32) -> Prim {
    if prim_bindings == 1u || i < prims_per_binding {
        return prims[i];
    }
    let k = i / prims_per_binding;
    let j = i - k * prims_per_binding;
    if k == 1u {
        return prims1[j];
    }
    if k == 2u {
        return prims2[j];
    }
    return prims3[j];
}

// A material (`GpuMaterial`): its `kind` (LAMBERTIAN, METAL, ...), `a` its albedo or emission;
// metal: `b.x` fuzz, `b.y` 1 for RTIOW v3's fuzz in the ball; glass: `b.x` its index of
// refraction; emitter: `b.x` 1 if two-sided; its colour texture's number (NO_TEXTURE: none;
// diffuse surfaces alone use it, as on the CPU) and its alpha mask's number in `textures`.
struct Material {
    a: vec3<f32>,
    kind: u32,
    b: vec2<f32>,
    texture: u32,
    mask: u32,
}

@group(0) @binding(2) var<storage, read> materials: array<Material>;
// Colour textures and alpha masks (`phr_render::texture`): sRGB texels `r | g << 8 | b << 16`
// or coverage values, one image after the other; each image's first texel, width, height and
// (masks) the bits of its threshold; three texture coordinates
// per triangle, in scene order (empty without textures).
@group(0) @binding(5) var<storage, read> texels: array<u32>;
@group(0) @binding(6) var<storage, read> textures: array<vec4<u32>>;
@group(0) @binding(7) var<storage, read> uvs: array<vec2<f32>>;

// The texture coordinates at barycentrics (u, v) of triangle `prim` (zero without any).
fn uv_at(prim: u32, u: f32, v: f32) -> vec2<f32> {
    let corner = 3u * prim;
    if corner + 2u >= arrayLength(&uvs) {
        return vec2<f32>(0.0);
    }
    let a = uvs[corner];
    return a + (uvs[corner + 1u] - a) * u + (uvs[corner + 2u] - a) * v;
}

// Image `t`'s texel (x, y), from the top left, coordinates wrapped.
fn texel_bits(t: vec4<u32>, x: i32, y: i32) -> u32 {
    let w = i32(t.y);
    let h = i32(t.z);
    return texels[t.x + u32(((y % h) + h) % h * w + ((x % w) + w) % w)];
}

// The bilinear footprint of `uv` on image `t` (`texture::footprint`): the top left texel of
// the four (x0, y0) and the weights of the right and lower ones; a weight of −1 for
// coordinates that are not finite.
fn footprint(t: vec4<u32>, uv: vec2<f32>) -> vec4<f32> {
    if !(abs(uv.x) < F32_MAX && abs(uv.y) < F32_MAX) {
        return vec4<f32>(0.0, 0.0, -1.0, 0.0);
    }
    let u = fract(uv.x) * f32(t.y) - 0.5;
    let v = (1.0 - fract(uv.y)) * f32(t.z) - 0.5;
    let x0 = floor(u);
    let y0 = floor(v);
    return vec4<f32>(x0, y0, u - x0, v - y0);
}

// glam's `lerp`, `a + (b − a) t` (WGSL's `mix` rounds otherwise).
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    return a + (b - a) * t;
}

fn lerp3(a: vec3<f32>, b: vec3<f32>, t: f32) -> vec3<f32> {
    return a + (b - a) * t;
}

// glam's `normalize`, `v · (1 / |v|)` (WGSL's `normalize` rounds otherwise).
fn unit(v: vec3<f32>) -> vec3<f32> {
    return v * (1.0 / length(v));
}

// glam's `normalize_or`: the unit vector, or `fallback` where `1 / |v|` is zero or not finite.
fn unit_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let rcp = 1.0 / length(v);
    if rcp > 0.0 && rcp <= F32_MAX {
        return v * rcp;
    }
    return fallback;
}

fn coverage(t: vec4<u32>, x: i32, y: i32) -> f32 {
    return f32(texel_bits(t, x, y)) / 255.0;
}

// `AlphaMask::covers`: the bilinearly filtered coverage reaches the mask's threshold.
fn covers(mask: u32, uv: vec2<f32>) -> bool {
    let t = textures[mask];
    let threshold = bitcast<f32>(t.w);
    let f = footprint(t, uv);
    if f.z < 0.0 {
        return coverage(t, 0, 0) >= threshold;
    }
    let x = i32(f.x);
    let y = i32(f.y);
    let top = lerp(coverage(t, x, y), coverage(t, x + 1, y), f.z);
    let bottom = lerp(coverage(t, x, y + 1), coverage(t, x + 1, y + 1), f.z);
    return lerp(top, bottom, f.w) >= threshold;
}


struct Ray {
    origin: vec3<f32>,
    dir: vec3<f32>,
    inv_dir: vec3<f32>,
    tmin: f32,
    tmax: f32,
}

// `phr_bvh::ray::safe_recip`: no infinite inverse, so the slab test sees no NaN.
fn make_ray(origin: vec3<f32>, dir: vec3<f32>, tmin: f32, tmax: f32) -> Ray {
    let tiny = select(vec3<f32>(1.0e-30), vec3<f32>(-1.0e-30), dir < vec3<f32>(0.0));
    let safe = select(dir, tiny, abs(dir) < vec3<f32>(1.0e-30));
    return Ray(origin, dir, 1.0 / safe, tmin, tmax);
}

// Entry distances into four child boxes (rows min_x, max_x, .., max_z of four lanes; their
// slots' counts), F32_MAX for those missed and for empty slots: per lane the robust slab test
// of `phr_bvh::wide::simd` (min and max of the two planes give its near and far plane).
fn children_entry(
    x0: vec4<f32>,
    x1: vec4<f32>,
    y0: vec4<f32>,
    y1: vec4<f32>,
    z0: vec4<f32>,
    z1: vec4<f32>,
    counts: vec4<u32>,
    ray: Ray,
) -> vec4<f32> {
    let tx0 = (x0 - ray.origin.x) * ray.inv_dir.x;
    let tx1 = (x1 - ray.origin.x) * ray.inv_dir.x;
    let ty0 = (y0 - ray.origin.y) * ray.inv_dir.y;
    let ty1 = (y1 - ray.origin.y) * ray.inv_dir.y;
    let tz0 = (z0 - ray.origin.z) * ray.inv_dir.z;
    let tz1 = (z1 - ray.origin.z) * ray.inv_dir.z;
    let tnear = max(max(min(tx0, tx1), min(ty0, ty1)), max(min(tz0, tz1), vec4<f32>(ray.tmin)));
    let tfar = min(min(max(tx0, tx1), max(ty0, ty1)), min(max(tz0, tz1), vec4<f32>(ray.tmax))) * ROBUST_SLAB;
    let hit = (tnear <= tfar) & (counts != vec4<u32>(EMPTY_SLOT));
    return select(vec4<f32>(F32_MAX), tnear, hit);
}

struct Hit {
    t: f32,
    u: f32,
    v: f32,
    // Index into `prims` (NO_HIT: none).
    slot: u32,
    // The primitive's number in the scene.
    prim: u32,
    // The part it belongs to (its instance; 0 in a scene of one tree).
    part: u32,
}

// Möller–Trumbore with the CPU's edge tolerance. Returns (t, u, v), t = F32_MAX for a miss.
fn intersect_triangle(ray: Ray, v0: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>) -> vec3<f32> {
    let miss = vec3<f32>(F32_MAX, 0.0, 0.0);
    let p = cross(ray.dir, e2);
    let det = dot(e1, p);
    if !(abs(det) > 0.0 && abs(det) < F32_MAX) {
        return miss;
    }
    let inv_det = 1.0 / det;
    let s = ray.origin - v0;
    let q = cross(s, e1);
    let u = dot(s, p) * inv_det;
    let v = dot(ray.dir, q) * inv_det;
    let abs_inv_det = abs(inv_det);
    let tol_u = min(EDGE_TOLERANCE * dot(abs(s), abs(p)) * abs_inv_det, MAX_EDGE_SLACK);
    let tol_v = min(EDGE_TOLERANCE * dot(abs(ray.dir), abs(q)) * abs_inv_det, MAX_EDGE_SLACK);
    if u < -tol_u || v < -tol_v || u + v > 1.0 + tol_u + tol_v {
        return miss;
    }
    let t = dot(e2, q) * inv_det;
    if t > ray.tmin && t <= ray.tmax && t < F32_MAX {
        return vec3<f32>(t, u, v);
    }
    return miss;
}

fn intersect_sphere(ray: Ray, center: vec3<f32>, radius: f32) -> f32 {
    let r = abs(radius);
    let f = ray.origin - center;
    let a = dot(ray.dir, ray.dir);
    let b = -dot(f, ray.dir);
    let l = f + (b / a) * ray.dir;
    let disc = a * (r * r - dot(l, l));
    if disc < 0.0 {
        return F32_MAX;
    }
    let sq = sqrt(disc);
    // `b.signum()`: the sign bit, so that −0 counts as negative.
    let q = b + select(sq, -sq, (bitcast<u32>(b) & 0x80000000u) != 0u);
    var t0 = 0.0;
    var t1 = 0.0;
    if q != 0.0 {
        t0 = q / a;
        t1 = (dot(f, f) - r * r) / q;
    }
    let near = min(t0, t1);
    let far = max(t0, t1);
    if near > ray.tmin && near <= ray.tmax {
        return near;
    }
    if far > ray.tmin && far <= ray.tmax {
        return far;
    }
    return F32_MAX;
}

// Tests primitive `slot` against `ray` and keeps it in `best` if it is closer (or as close
// with a lower number); shrinks `ray.tmax` to the best distance.
fn test_prim(slot: u32, ray: ptr<function, Ray>, best: ptr<function, Hit>) {
    let prim = prim_at(slot);
    let number = prim.number;
    var hit = vec3<f32>(F32_MAX, 0.0, 0.0);
    let bits = prim.material;
    if (bits & SPHERE) == 0u {
        hit = intersect_triangle(*ray, prim.a, prim.b, prim.c);
        // Where its material's alpha mask does not cover it, a triangle is no hit.
        if (bits & MASKED) != 0u && hit.x < F32_MAX {
            let mask = materials[bits & ~MASKED].mask;
            if !covers(mask, uv_at(number, hit.y, hit.z)) {
                return;
            }
        }
    } else {
        hit.x = intersect_sphere(*ray, prim.a, prim.b.x);
    }
    if hit.x == F32_MAX {
        return;
    }
    if hit.x < (*ray).tmax || (hit.x == (*ray).tmax && ((*best).slot == NO_HIT || number < (*best).prim)) {
        (*ray).tmax = hit.x;
        *best = Hit(hit.x, hit.y, hit.z, slot, number, current_part);
    }
}

// The closest hit of `ray` (slot NO_HIT: none).
fn closest_hit(ray: Ray) -> Hit {
    return search(ray, false);
}

// Whether anything lies on `ray` within (tmin, tmax]: a shadow ray's query.
fn any_hit(ray: Ray) -> bool {
    return search(ray, true).slot != NO_HIT;
}

// The closest hit of `ray`, or with `stop_at_first` the first found: through the one tree, or
// through every instance (a part, or a copy of a mesh placed many times) whose world box the
// ray meets before the closest hit so far, in its object space (`Geometry::intersect`; with
// the tie rule the order of the instances does not matter, but for copies of one mesh, whose
// triangles share their numbers: a ray through two at exactly one distance may take either,
// as on the CPU): one after the other when they are few, else down the top-level tree,
// nearest first.
fn search(ray: Ray, stop_at_first: bool) -> Hit {
    var best = Hit(F32_MAX, 0.0, 0.0, NO_HIT, NO_HIT, 0u);
    current_part = 0u;
    if instance_count == 0u {
        return traverse(ray, stop_at_first, 0u, best);
    }
    var world = ray;
    if top_root == 0u {
        for (var k = 0u; k < instance_count; k++) {
            let inst = instances[k];
            if (inst.flags & INSTANCE_EMPTY) != 0u || box_entry(inst.lo, inst.hi, world) == F32_MAX {
                continue;
            }
            if search_instance(k, &world, stop_at_first, &best) {
                return best;
            }
        }
        return best;
    }
    top_sp = 0u;
    top_push(0.0, top_root);
    loop {
        if top_sp == 0u {
            break;
        }
        top_sp--;
        let entry = top_stack[top_sp];
        // (An open ray's `tmax` is F32_MAX, whose product would overflow.)
        if world.tmax < F32_MAX && top_stack_t[top_sp] > world.tmax * ROBUST_SLAB {
            continue;
        }
        if (entry & TOP_INSTANCE) != 0u {
            if search_instance(entry & ~TOP_INSTANCE, &world, stop_at_first, &best) {
                return best;
            }
            continue;
        }
        let n = node_at(entry);
        let lo = children_entry(
            n.bounds[0], n.bounds[2], n.bounds[4], n.bounds[6], n.bounds[8], n.bounds[10], n.count[0], world
        );
        let hi = children_entry(
            n.bounds[1], n.bounds[3], n.bounds[5], n.bounds[7], n.bounds[9], n.bounds[11], n.count[1], world
        );
        // The nearest child last, so that it is popped first: the others in one round, the
        // nearest (and any as near) in a second.
        let m = min(lo, hi);
        let nearest = min(min(m.x, m.y), min(m.z, m.w));
        for (var round = 0u; round < 2u; round++) {
            let last = round == 1u;
            top_child(lo.x, n.child[0].x, n.count[0].x, nearest, last);
            top_child(lo.y, n.child[0].y, n.count[0].y, nearest, last);
            top_child(lo.z, n.child[0].z, n.count[0].z, nearest, last);
            top_child(lo.w, n.child[0].w, n.count[0].w, nearest, last);
            top_child(hi.x, n.child[1].x, n.count[1].x, nearest, last);
            top_child(hi.y, n.child[1].y, n.count[1].y, nearest, last);
            top_child(hi.z, n.child[1].z, n.count[1].z, nearest, last);
            top_child(hi.w, n.child[1].w, n.count[1].w, nearest, last);
        }
    }
    return best;
}

// Searches instance `k`'s tree with `world` in its object space, keeping a closer hit in
// `best` and shortening `world` to it; returns whether the search is over (the first hit
// found, with `stop_at_first`).
fn search_instance(k: u32, world: ptr<function, Ray>, stop_at_first: bool, best: ptr<function, Hit>) -> bool {
    let inst = instances[k];
    current_part = k;
    *best = traverse(object_ray(inst, *world), stop_at_first, inst.root, *best);
    if (*best).slot == NO_HIT {
        return false;
    }
    (*world).tmax = (*best).t;
    return stop_at_first;
}


// Entry distance into the box lo..hi, or F32_MAX (`phr_bvh::Aabb::intersect`).
fn box_entry(lo: vec3<f32>, hi: vec3<f32>, ray: Ray) -> f32 {
    let t0 = (lo - ray.origin) * ray.inv_dir;
    let t1 = (hi - ray.origin) * ray.inv_dir;
    let near = min(t0, t1);
    let far = max(t0, t1);
    let tnear = max(max(near.x, near.y), max(near.z, ray.tmin));
    let tfar = min(min(far.x, far.y), min(far.z, ray.tmax)) * ROBUST_SLAB;
    return select(F32_MAX, tnear, tnear <= tfar);
}

// The top-level walk's stack (`TOP_STACK` in `scene.rs`): per entry a node of the top-level
// tree, or an instance's number with TOP_INSTANCE set, and its entry distance.
const TOP_STACK: u32 = 64u;
const TOP_INSTANCE: u32 = 0x80000000u;
var<private> top_stack: array<u32, TOP_STACK>;
var<private> top_stack_t: array<f32, TOP_STACK>;
var<private> top_sp: u32;
// The top-level tree's root node, 0 when there is none (the first tree starts at node 0):
// few instances are searched one after the other (`DIRECT_INSTANCES` in `scene.rs` says why).
override top_root: u32;

fn top_push(t: f32, entry: u32) {
    top_stack[top_sp] = entry;
    top_stack_t[top_sp] = t;
    top_sp++;
}

// A child of a top-level node entered at `t` (F32_MAX: missed), pushed in the first round
// if it is farther than the nearest, in the `last` round if it is as near: a node, or (a
// leaf slot) the instance whose number it holds.
fn top_child(t: f32, child: u32, count: u32, nearest: f32, last: bool) {
    if t == F32_MAX || (t == nearest) != last {
        return;
    }
    top_push(t, select(child, child | TOP_INSTANCE, count != 0u));
}

// ---- Parts placed by instances (`phr_bvh::instance::Instance`) ---------------------------

// A part of a two-level scene (`GpuInstance`): world to object and object to world as
// columns (linear part, then translation), the columns of the normals' matrix (the transpose
// of world to object's linear part), its world box, its tree's root and flags.
struct Instance {
    to_object: array<vec4<f32>, 4>,
    to_world: array<vec4<f32>, 4>,
    normal: array<vec4<f32>, 3>,
    lo: vec3<f32>,
    root: u32,
    hi: vec3<f32>,
    flags: u32,
}

const INSTANCE_IDENTITY: u32 = 1u;
const INSTANCE_MIRRORS: u32 = 2u;
const INSTANCE_EMPTY: u32 = 4u;

@group(0) @binding(16) var<storage, read> instances: array<Instance>;
override instance_count: u32;
// The part the traversal is in (what `test_prim` records in a hit).
var<private> current_part: u32;

// glam's `Affine3A::transform_point3`: x·c0 + y·c1 + z·c2 + t, in that order.
fn point_by(m: array<vec4<f32>, 4>, p: vec3<f32>) -> vec3<f32> {
    return m[0].xyz * p.x + m[1].xyz * p.y + m[2].xyz * p.z + m[3].xyz;
}

// glam's `transform_vector3` (and a `Mat3A` times a vector): x·c0 + y·c1 + z·c2.
fn vector_by(c0: vec3<f32>, c1: vec3<f32>, c2: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    return c0 * v.x + c1 * v.y + c2 * v.z;
}

// `Instance::object_ray`: the ray in the part's object space, the same interval.
fn object_ray(inst: Instance, ray: Ray) -> Ray {
    if (inst.flags & INSTANCE_IDENTITY) != 0u {
        return ray;
    }
    let m = inst.to_object;
    return make_ray(point_by(m, ray.origin), vector_by(m[0].xyz, m[1].xyz, m[2].xyz, ray.dir), ray.tmin, ray.tmax);
}

// The traversal stack: per entry a child (node index or first primitive record), its
// primitive count (0: a node) and its entry distance. Per invocation (module scope, so that
// `consider` reaches it without pointers).
var<private> stack_child: array<u32, STACK>;
var<private> stack_count: array<u32, STACK>;
var<private> stack_t: array<f32, STACK>;
var<private> sp: u32;
// The nearest and the second nearest hit child of the node being visited (F32_MAX: none
// yet).
var<private> near_t: f32;
var<private> near_child: u32;
var<private> near_count: u32;
var<private> second_t: f32;
var<private> second_child: u32;
var<private> second_count: u32;

fn push(t: f32, child: u32, count: u32) {
    stack_child[sp] = child;
    stack_count[sp] = count;
    stack_t[sp] = t;
    sp++;
}

// One child of the node being visited, at entry distance `t` (F32_MAX: missed): the nearest
// and the second nearest so far are kept, the others pushed.
fn consider(t: f32, child: u32, count: u32) {
    if t == F32_MAX {
        return;
    }
    if t < second_t {
        if second_t < F32_MAX {
            push(second_t, second_child, second_count);
        }
        if t < near_t {
            second_t = near_t;
            second_child = near_child;
            second_count = near_count;
            near_t = t;
            near_child = child;
            near_count = count;
        } else {
            second_t = t;
            second_child = child;
            second_count = count;
        }
    } else {
        push(t, child, count);
    }
}

// The closest hit of `ray0`, or with `stop_at_first` the first found: the CPU's walk of the
// wide tree. A node's nearest hit child is visited next and its second nearest pushed last
// (popped next), the others pushed before it unsorted, all with their entry distances;
// popped entries that start beyond the closest hit so far are skipped. (The tie rule makes
// the closest hit independent of the order; a full sort, as the CPU's, cost lavapipe more
// than it saved.)
fn traverse(ray0: Ray, stop_at_first: bool, root: u32, best0: Hit) -> Hit {
    var ray = ray0;
    var best = best0;
    sp = 0u;
    var index = root;
    var count = 0u;
    loop {
        if count == 0u {
            let n = node_at(index);
            let lo = children_entry(
                n.bounds[0], n.bounds[2], n.bounds[4], n.bounds[6], n.bounds[8], n.bounds[10], n.count[0], ray
            );
            let hi = children_entry(
                n.bounds[1], n.bounds[3], n.bounds[5], n.bounds[7], n.bounds[9], n.bounds[11], n.count[1], ray
            );
            near_t = F32_MAX;
            second_t = F32_MAX;
            consider(lo.x, n.child[0].x, n.count[0].x);
            consider(lo.y, n.child[0].y, n.count[0].y);
            consider(lo.z, n.child[0].z, n.count[0].z);
            consider(lo.w, n.child[0].w, n.count[0].w);
            consider(hi.x, n.child[1].x, n.count[1].x);
            consider(hi.y, n.child[1].y, n.count[1].y);
            consider(hi.z, n.child[1].z, n.count[1].z);
            consider(hi.w, n.child[1].w, n.count[1].w);
            // The second nearest on top, to be popped first once the nearest is done.
            if second_t < F32_MAX {
                push(second_t, second_child, second_count);
            }
            if near_t < F32_MAX {
                index = near_child;
                count = near_count;
                continue;
            }
        } else {
            for (var i = 0u; i < count; i++) {
                test_prim(index + i, &ray, &best);
                if stop_at_first && best.slot != NO_HIT {
                    return best;
                }
            }
        }
        // Pop the next pending entry that may still hold a closer hit.
        var next = false;
        loop {
            if sp == 0u {
                break;
            }
            sp--;
            // (An open ray's `tmax` is F32_MAX, whose product would overflow: every entry is
            // nearer.)
            if ray.tmax >= F32_MAX || stack_t[sp] <= ray.tmax * ROBUST_SLAB {
                index = stack_child[sp];
                count = stack_count[sp];
                next = true;
                break;
            }
        }
        if !next {
            break;
        }
    }
    return best;
}
