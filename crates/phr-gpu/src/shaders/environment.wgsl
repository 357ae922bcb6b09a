// HDR environment maps (`phr_render::environment`): the equirectangular lookup of Mitsuba 3's
// `envmap` (bilinear between texels, row 0 straight up) and importance sampling by luminance
// over its cells, from the CPU's tables in single precision (`EnvironmentTables`): the
// density is the cell's probability over the solid angle it covers, as on the CPU.
// `frame.environment` holds the map's width and height, `frame.rotation` its rotation's
// cosine and sine.

const ENVIRONMENT: u32 = 2u;
const PI: f32 = 3.141592653589793;

@group(0) @binding(8) var<storage, read> environment_texels: array<vec4<f32>>;
// Over rows of cells (height entries), then per row over its cells (width + 1 a row), then
// each cell's probability (width a row).
@group(0) @binding(9) var<storage, read> environment_tables: array<f32>;

fn env_width() -> u32 {
    return frame.environment.x;
}

fn env_rows() -> u32 {
    return frame.environment.y - 1u;
}

fn env_to_local(d: vec3<f32>) -> vec3<f32> {
    let c = frame.rotation.x;
    let s = frame.rotation.y;
    return vec3<f32>(c * d.x - s * d.z, d.y, s * d.x + c * d.z);
}

fn env_to_world(d: vec3<f32>) -> vec3<f32> {
    let c = frame.rotation.x;
    let s = frame.rotation.y;
    return vec3<f32>(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
}

// (u, v, sin θ) of a unit direction in the map's frame.
fn env_uv(d: vec3<f32>) -> vec3<f32> {
    var u = atan2(d.x, -d.z) / TAU;
    u = u - floor(u);
    let sin_theta = sqrt(d.x * d.x + d.z * d.z);
    let v = atan2(sin_theta, d.y) / PI;
    return vec3<f32>(u, v, min(sin_theta, 1.0));
}

// The cell holding (u, v) and the position inside it: (x, y, fx, fy).
fn env_cell(uv: vec2<f32>) -> vec4<f32> {
    let w = f32(env_width());
    var x = uv.x * w - 0.5;
    x = x - w * floor(x / w);
    let y = uv.y * f32(env_rows());
    let cx = min(u32(x), env_width() - 1u);
    let cy = min(u32(y), env_rows() - 1u);
    return vec4<f32>(f32(cx), f32(cy), x - f32(cx), y - f32(cy));
}

fn env_texel(x: u32, y: u32) -> vec3<f32> {
    return environment_texels[y * env_width() + x].xyz;
}

fn env_radiance(dir: vec3<f32>) -> vec3<f32> {
    let uvs = env_uv(env_to_local(dir));
    if !(abs(uvs.x) < F32_MAX && abs(uvs.y) < F32_MAX) {
        return vec3<f32>(0.0);
    }
    let c = env_cell(uvs.xy);
    let x = u32(c.x);
    let y = u32(c.y);
    let x1 = (x + 1u) % env_width();
    let top = lerp3(env_texel(x, y), env_texel(x1, y), c.z);
    let bottom = lerp3(env_texel(x, y + 1u), env_texel(x1, y + 1u), c.z);
    return lerp3(top, bottom, c.w);
}

// Density per solid angle with which `env_sample` picks the unit direction `dir`.
fn env_pdf(dir: vec3<f32>) -> f32 {
    let uvs = env_uv(env_to_local(dir));
    if !(abs(uvs.x) < F32_MAX && abs(uvs.y) < F32_MAX) || uvs.z <= 0.0 {
        return 0.0;
    }
    let c = env_cell(uvs.xy);
    let w = env_width();
    let rows = env_rows();
    let probability = environment_tables[(rows + 1u) + rows * (w + 1u) + u32(c.y) * w + u32(c.x)];
    return probability * f32(w * rows) / (2.0 * PI * PI * uvs.z);
}

// The last index in [start, start + n) whose table entry lies at or below `goal`, as an
// offset from `start` (0 if none).
fn env_pick(start: u32, n: u32, goal: f32) -> u32 {
    var lo = 0u;
    var hi = n;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if environment_tables[start + mid] <= goal {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return max(lo, 1u) - 1u;
}

// A direction by the map's distribution and its density (density 0: none).
fn env_sample(u1: f32, u2: f32) -> vec4<f32> {
    let w = env_width();
    let rows = env_rows();
    if !(environment_tables[rows] > 0.0) {
        return vec4<f32>(0.0);
    }
    let y = min(env_pick(0u, rows, u1), rows - 1u);
    let row = (rows + 1u) + y * (w + 1u);
    if !(environment_tables[row + w] > 0.0) {
        return vec4<f32>(0.0);
    }
    let r0 = environment_tables[y];
    let dy = clamp((u1 - r0) / (environment_tables[y + 1u] - r0), 0.0, 1.0);
    let x = min(env_pick(row, w, u2), w - 1u);
    let c0 = environment_tables[row + x];
    let weight = environment_tables[row + x + 1u] - c0;
    var dx = 0.5;
    if weight > 0.0 {
        dx = clamp((u2 - c0) / weight, 0.0, 1.0);
    }
    let u = fract((f32(x) + dx + 0.5) / f32(w));
    let v = (f32(y) + dy) / f32(rows);
    let phi = TAU * u;
    let theta = PI * v;
    let local = vec3<f32>(sin(theta) * sin(phi), cos(theta), -sin(theta) * cos(phi));
    let dir = unit(env_to_world(local));
    let pdf = env_pdf(dir);
    if !(pdf > 0.0 && pdf < F32_MAX) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(dir, pdf);
}
