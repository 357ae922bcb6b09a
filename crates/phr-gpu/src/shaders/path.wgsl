// The path tracer of `phr_render::integrator`, one path per pixel per dispatch, at most
// `max_depth` segments, the materials of `phr_render::material`: the thesis's estimator
// (implicit lights, BSDF sampling only), or light sampling with MIS and Russian roulette
// (`LightSet` of `phr_render::lights`, the CPU's `advance_with_lights` step by step). Each
// pixel's random numbers are the CPU's (`Pcg32::for_pixel`, `Pcg32::pixel_jitter`), drawn in
// the same order, so the two converge to the same image; adds the sample and its square to the
// accumulation buffers.

struct Frame {
    width: u32,
    height: u32,
    // The frame's number (which sample of each pixel it is).
    number: u32,
    // Maximum ray segments per path.
    max_depth: u32,
    // The seed's low and high halves.
    seed: vec2<u32>,
    // 0 constant, 1 gradient, 2 environment map.
    background: u32,
    // 1: light sampling with MIS; 0: the implicit estimator.
    light_sampling: u32,
    // Light sampling: the sky's probability, the number of emitters to pick from.
    sky_probability: f32,
    light_count: u32,
    // An environment map's width and height, and its rotation's cosine and sine.
    environment: vec2<u32>,
    rotation: vec2<f32>,
    // 1 / width, 1 / height.
    inv_size: vec2<f32>,
    origin: vec4<f32>,
    forward: vec4<f32>,
    horizontal: vec4<f32>,
    vertical: vec4<f32>,
    // Constant: `sky_a`. Gradient: `sky_a` at the bottom, `sky_b` at the top.
    sky_a: vec4<f32>,
    sky_b: vec4<f32>,
}


const LAMBERTIAN: u32 = 0u;
const METAL: u32 = 1u;
const DIELECTRIC: u32 = 2u;
const EMISSIVE: u32 = 3u;
const RR_START: u32 = 3u;
const FRAC_1_PI: f32 = 0.3183098861837907;
const TRIANGLE_OFFSET: f32 = 1.0e-6;
const SPHERE_OFFSET: f32 = 1500.0 / 16777216.0;

// An emitter (`GpuLight`): a triangle (`a` = v0, `b` = e1, `c` = e2) or a sphere (`a` =
// centre, `b.x` = radius); its material with SPHERE for spheres, its area, the probability of
// picking it.
struct Light {
    a: vec3<f32>,
    material: u32,
    b: vec3<f32>,
    area: f32,
    c: vec3<f32>,
    selection: f32,
}

@group(0) @binding(3) var<storage, read> lights: array<Light>;
@group(0) @binding(4) var<storage, read> light_cdf: array<f32>;
@group(1) @binding(0) var<uniform> frame: Frame;
@group(1) @binding(1) var<storage, read_write> sum: array<vec4<f32>>;
@group(1) @binding(2) var<storage, read_write> sum_sq: array<vec4<f32>>;
// Rays traced, as a 64-bit count (low, high).
@group(1) @binding(3) var<storage, read_write> ray_count: array<atomic<u32>, 2>;

// `Pcg32::pixel_jitter`: point `frame` of the R2 sequence, rotated by the pixel's own random
// offset, in 32-bit fixed point (the CPU adds in f64; both wrap into [0, 1)).
fn pixel_jitter(seed: vec2<u32>, n: u32, pixel: u32) -> vec2<f32> {
    var rotation = pcg_for_pixel(seed ^ vec2<u32>(0x4f6cdd1du, 0x2545f491u), 0xffffffffu, pixel);
    let ox = (pcg_next(&rotation) >> 8u) << 8u;
    let oy = (pcg_next(&rotation) >> 8u) << 8u;
    // round(2^32 / φ₂) and round(2^32 / φ₂²), φ₂ the plastic number.
    let x = 0x80000000u + n * 3242174889u + ox;
    let y = 0x80000000u + n * 2447445414u + oy;
    return vec2<f32>(f32(x >> 8u), f32(y >> 8u)) * (1.0 / 16777216.0);
}

fn sky(unit_dir: vec3<f32>) -> vec3<f32> {
    if frame.background == 0u {
        return frame.sky_a.xyz;
    }
    if frame.background == ENVIRONMENT {
        return env_radiance(unit_dir);
    }
    let a = 0.5 * (unit_dir.y + 1.0);
    return (1.0 - a) * frame.sky_a.xyz + a * frame.sky_b.xyz;
}

fn schlick(cos_theta: f32, eta: f32) -> f32 {
    let r = (1.0 - eta) / (1.0 + eta);
    let r0 = r * r;
    let m = 1.0 - cos_theta;
    // `powi(5)`: (m²)² m.
    let m2 = m * m;
    return r0 + (1.0 - r0) * (m2 * m2 * m);
}

fn refract_dir(v: vec3<f32>, n: vec3<f32>, eta: f32, cos_theta: f32) -> vec3<f32> {
    let perp = eta * (v + cos_theta * n);
    let parallel = -sqrt(abs(1.0 - dot(perp, perp))) * n;
    return perp + parallel;
}

// A hit's surface: position, unit normal, side, material, offset for new rays.
struct Surface {
    position: vec3<f32>,
    normal: vec3<f32>,
    front: bool,
    material: u32,
    offset: f32,
    // The emitter's number plus one (0: not a light to sample).
    emitter: u32,
    // Texture coordinates (zero on spheres and meshes without any).
    uv: vec2<f32>,
}

// `Geometry::surface_point`: the local surface in the part's object space, then placed in the
// world by its instance.
fn surface_at(ray: Ray, hit: Hit) -> Surface {
    let prim = prim_at(hit.slot);
    let bits = prim.material;
    var flags = INSTANCE_IDENTITY;
    var inst: Instance;
    if instance_count > 0u {
        inst = instances[hit.part];
        flags = inst.flags;
    }
    var local = ray;
    if (flags & INSTANCE_IDENTITY) == 0u {
        local = object_ray(inst, ray);
    }
    var p: vec3<f32>;
    var n: vec3<f32>;
    var rel: f32;
    var uv = vec2<f32>(0.0);
    if (bits & SPHERE) == 0u {
        uv = uv_at(hit.prim, hit.u, hit.v);
        p = prim.a + prim.b * hit.u + prim.c * hit.v;
        n = unit_or(cross(prim.b, prim.c), vec3<f32>(0.0, 0.0, 1.0));
        rel = TRIANGLE_OFFSET;
    } else {
        let c = prim.a;
        let radius = prim.b.x;
        let on_ray = local.origin + local.dir * hit.t;
        p = c + (on_ray - c) * (abs(radius) / length(on_ray - c));
        n = unit_or((p - c) / radius, vec3<f32>(0.0, 1.0, 0.0));
        rel = SPHERE_OFFSET;
    }
    if (flags & INSTANCE_IDENTITY) == 0u {
        // A mirroring transform turns a triangle's e1 × e2 around; a sphere's outward normal
        // stays outward.
        let flip = (flags & INSTANCE_MIRRORS) != 0u && (bits & SPHERE) == 0u;
        let m = inst.normal;
        n = unit_or(vector_by(m[0].xyz, m[1].xyz, m[2].xyz, select(n, -n, flip)), vec3<f32>(0.0, 0.0, 1.0));
        p = point_by(inst.to_world, p);
    }
    let front = dot(ray.dir, n) < 0.0;
    let ap = abs(p);
    let offset = rel * (1.0 + max(max(ap.x, ap.y), ap.z));
    return Surface(p, n, front, bits & ~(SPHERE | MASKED), offset, prim.emitter, uv);
}

fn srgb_decode(c: u32) -> f32 {
    let x = f32(c) / 255.0;
    if x <= 0.04045 {
        return x / 12.92;
    }
    return pow((x + 0.055) / 1.055, 2.4);
}

// Linear colour of texel (x, y) (from the top left, wrapped) of texture `t`.
fn texel(t: vec4<u32>, x: i32, y: i32) -> vec3<f32> {
    let c = texel_bits(t, x, y);
    return vec3<f32>(srgb_decode(c & 255u), srgb_decode((c >> 8u) & 255u), srgb_decode((c >> 16u) & 255u));
}

// `Texture::sample`: bilinear, repeating, texel centres at ((x + 0.5) / w, 1 − (y + 0.5) / h).
fn sample_texture(index: u32, uv: vec2<f32>) -> vec3<f32> {
    let t = textures[index];
    let f = footprint(t, uv);
    if f.z < 0.0 {
        return texel(t, 0, 0);
    }
    let x = i32(f.x);
    let y = i32(f.y);
    let top = lerp3(texel(t, x, y), texel(t, x + 1, y), f.z);
    let bottom = lerp3(texel(t, x, y + 1), texel(t, x + 1, y + 1), f.z);
    return lerp3(top, bottom, f.w);
}

// A diffuse hit's scattering weight `weight` times its material's texture at the hit, if it has
// one (`PathTracer::textured`).
fn textured(m: Material, s: Surface, weight: vec3<f32>) -> vec3<f32> {
    if m.kind == LAMBERTIAN && m.texture != NO_TEXTURE {
        return weight * sample_texture(m.texture, s.uv);
    }
    return weight;
}

fn spawn_origin(s: Surface, dir: vec3<f32>) -> vec3<f32> {
    let side = select(-s.normal, s.normal, dot(dir, s.normal) >= 0.0);
    return s.position + s.offset * side;
}

// `Material::scatter`: the next direction and its weight in `xyz` of the two, or w = 0 in the
// weight: absorbed.
struct Scatter {
    dir: vec3<f32>,
    weight: vec4<f32>,
}

fn scatter(m: Material, dir: vec3<f32>, normal: vec3<f32>, front: bool, rng: ptr<function, Pcg>) -> Scatter {
    let facing = select(-normal, normal, front);
    let kind = m.kind;
    let absorbed = Scatter(vec3<f32>(0.0), vec4<f32>(0.0));
    if kind == LAMBERTIAN {
        var d = facing + unit_vector(rng);
        let ad = abs(d);
        if max(max(ad.x, ad.y), ad.z) < 1.0e-8 {
            d = facing;
        }
        return Scatter(d, vec4<f32>(m.a, 1.0));
    }
    if kind == METAL {
        let reflected = unit(reflect(unit(dir), facing));
        var jitter: vec3<f32>;
        if m.b.y != 0.0 {
            jitter = in_unit_sphere(rng);
        } else {
            jitter = unit_vector(rng);
        }
        let d = reflected + min(m.b.x, 1.0) * jitter;
        if dot(d, facing) > 0.0 {
            return Scatter(d, vec4<f32>(m.a, 1.0));
        }
        return absorbed;
    }
    if kind == DIELECTRIC {
        let unit_dir = unit(dir);
        let ior = m.b.x;
        let eta = select(ior, 1.0 / ior, front);
        let cos_theta = min(dot(-unit_dir, facing), 1.0);
        let sin_theta = sqrt(max(1.0 - cos_theta * cos_theta, 0.0));
        var d: vec3<f32>;
        if eta * sin_theta > 1.0 || schlick(cos_theta, eta) > next_f32(rng) {
            d = reflect(unit_dir, facing);
        } else {
            d = refract_dir(unit_dir, facing, eta, cos_theta);
        }
        return Scatter(d, vec4<f32>(1.0, 1.0, 1.0, 1.0));
    }
    return absorbed;
}

fn emitted(m: Material, front: bool) -> vec3<f32> {
    if m.kind == EMISSIVE && (front || m.b.x != 0.0) {
        return m.a;
    }
    return vec3<f32>(0.0);
}

// What a path gathered and how many rays it traced.
struct PathSample {
    radiance: vec3<f32>,
    rays: u32,
}

// The thesis's estimator: BSDF sampling alone (`advance_implicit`).
fn trace_implicit(camera_ray: Ray, rng: ptr<function, Pcg>) -> PathSample {
    var ray = camera_ray;
    var radiance = vec3<f32>(0.0);
    var throughput = vec3<f32>(1.0);
    var rays = 0u;
    for (var segment = 0u; segment < frame.max_depth; segment++) {
        rays++;
        let hit = closest_hit(ray);
        if hit.slot == NO_HIT {
            radiance += throughput * sky(unit(ray.dir));
            break;
        }
        let surface = surface_at(ray, hit);
        let m = materials[surface.material];
        radiance += throughput * emitted(m, surface.front);
        let s = scatter(m, ray.dir, surface.normal, surface.front, rng);
        if s.weight.w == 0.0 {
            break;
        }
        throughput *= textured(m, surface, s.weight.xyz);
        ray = make_ray(spawn_origin(surface, s.dir), s.dir, 0.0, F32_MAX);
    }
    return PathSample(radiance, rays);
}

@compute @workgroup_size(8, 8)
fn render(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = frame.width;
    let height = frame.height;
    if id.x >= width || id.y >= height {
        return;
    }
    let pixel = id.y * width + id.x;
    let seed = frame.seed;
    var rng = pcg_for_pixel(seed, frame.number, pixel);
    let jitter = pixel_jitter(seed, frame.number, pixel);
    // `Camera::ray`.
    let sx = 2.0 * (f32(id.x) + jitter.x) * frame.inv_size.x - 1.0;
    let sy = 2.0 * (f32(id.y) + jitter.y) * frame.inv_size.y - 1.0;
    let camera_dir = unit(frame.forward.xyz + sx * frame.horizontal.xyz - sy * frame.vertical.xyz);
    let ray = make_ray(frame.origin.xyz, camera_dir, 0.0, F32_MAX);
    var sample: PathSample;
    if frame.light_sampling == 0u {
        sample = trace_implicit(ray, &rng);
    } else {
        sample = trace_with_lights(ray, &rng);
    }
    let radiance = sample.radiance;
    sum[pixel] += vec4<f32>(radiance, 0.0);
    sum_sq[pixel] += vec4<f32>(radiance * radiance, 0.0);
    let low = atomicAdd(&ray_count[0], sample.rays);
    if low + sample.rays < low {
        atomicAdd(&ray_count[1], 1u);
    }
}
