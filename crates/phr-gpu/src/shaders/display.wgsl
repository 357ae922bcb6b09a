// The displayed image of the film the GPU keeps: the mean of its sums, sRGB-encoded as
// `phr_render::output::rgba8` does for the CPU's viewer, into an 8-bit texture a window draws
// (holding the encoded values, as egui's own images do).

struct Display {
    width: u32,
    height: u32,
    samples: u32,
    unused: u32,
}

@group(0) @binding(0) var<uniform> display: Display;
@group(0) @binding(1) var<storage, read> sum: array<vec4<f32>>;
@group(0) @binding(2) var image: texture_storage_2d<rgba8unorm, write>;

fn srgb_encode(x: f32) -> f32 {
    // Not finite (or negative): black, as on the CPU.
    if !(x >= 0.0 && x <= 3.4e38) {
        return 0.0;
    }
    let c = min(x, 1.0);
    if c <= 0.0031308 {
        return 12.92 * c;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

@compute @workgroup_size(8, 8)
fn show(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= display.width || id.y >= display.height {
        return;
    }
    let mean = sum[id.y * display.width + id.x].xyz / f32(max(display.samples, 1u));
    let colour = vec3(srgb_encode(mean.x), srgb_encode(mean.y), srgb_encode(mean.z));
    textureStore(image, vec2<i32>(id.xy), vec4(colour, 1.0));
}
