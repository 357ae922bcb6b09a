//! Intel Open Image Denoise (OIDN 2.5) as a second spatial filter: its `RT` filter, a neural
//! network trained on path-traced images, given the colour and the [`Guide`]'s albedo
//! (averaged over a few jittered rays, so a little noisy) and normal (the pixel centre's) as
//! auxiliary images.
//!
//! Behind the cargo feature `oidn`: the library is not a crate but a C++ library, which
//! `tools/setup-oidn.sh` unpacks from the PyPI wheel that ships the official Linux build;
//! then `OIDN_DIR=$(tools/setup-oidn.sh) cargo build --release -p phr --features oidn`. Without
//! the feature, [`denoise`] says how to get it.

use super::Guide;
use glam::Vec3;

/// Whether this build has OIDN.
pub const AVAILABLE: bool = cfg!(feature = "oidn");

/// What a build without the feature answers.
pub const MISSING: &str = "this build has no Open Image Denoise: run tools/setup-oidn.sh, then build with \
    OIDN_DIR=$(tools/setup-oidn.sh) cargo build --release -p phr --features oidn";

/// Filters the linear HDR `colour` (row-major, the guide's size) with OIDN's `RT` filter on
/// the CPU, guided by the albedo (clamped to [0, 1], as OIDN requires) and the normals;
/// pixels the guide leaves alone (lights, the sky) keep `colour`.
#[cfg(feature = "oidn")]
pub fn denoise(colour: &[Vec3], guide: &Guide) -> Result<Vec<Vec3>, String> {
    let (w, h) = (guide.width as usize, guide.height as usize);
    assert_eq!(colour.len(), w * h, "image and guide sizes differ");
    let flat = |v: &[Vec3], f: fn(Vec3) -> Vec3| -> Vec<f32> { v.iter().flat_map(|&c| f(c).to_array()).collect() };
    let mean = colour;
    let colour = flat(colour, |c| c);
    let albedo = flat(&guide.albedo, |a| a.clamp(Vec3::ZERO, Vec3::ONE));
    let normal = flat(&guide.normal, |n| n);
    let fail = |what: &str, e: oidn::Error| format!("Open Image Denoise: {what}: {e}");
    let device = cpu_device().map_err(|e| fail("no CPU device", e))?;
    let mut filter = oidn::RayTracing::try_new(&device).map_err(|e| fail("no RT filter", e))?;
    filter.hdr(true).albedo_normal(&albedo, &normal).image_dimensions(w, h);
    let mut out = vec![0.0f32; colour.len()];
    filter.filter(&colour, &mut out).map_err(|e| fail("filtering", e))?;
    device.get_error().map_err(|e| fail("filtering", e))?;
    // As the à-trous filter does, pixels that see a light or the sky keep their mean: they are
    // exact but for their coverage noise, and the network blurs a bright lamp's edge into
    // its surroundings (cornell_obj at 16 spp: RMSE over the lamp's pixels 0.58 against 0.30).
    let kept = |i: usize| guide.footprint[i] == 0.0;
    Ok(out
        .chunks_exact(3)
        .enumerate()
        .map(|(i, c)| if kept(i) { mean[i] } else { Vec3::new(c[0], c[1], c[2]) })
        .collect())
}

/// A CPU device on as many threads as the renderer's pool (OIDN's default, every core,
/// would take more than the renderer was given, e.g. in an equal-time benchmark).
#[cfg(feature = "oidn")]
fn cpu_device() -> Result<oidn::Device, oidn::Error> {
    use oidn::sys::{oidnCommitDevice, oidnNewDevice, oidnSetDeviceInt, OIDNDeviceType_OIDN_DEVICE_TYPE_CPU};
    let threads = rayon::current_num_threads().min(i32::MAX as usize) as i32;
    // SAFETY: a device handle from `oidnNewDevice` (checked non-null) is configured, then
    // committed, before `Device::from_raw` takes it over, as that function requires.
    let device = unsafe {
        let handle = oidnNewDevice(OIDNDeviceType_OIDN_DEVICE_TYPE_CPU);
        if handle.is_null() {
            return oidn::Device::cpu(); // the crate's own constructor reports why
        }
        oidnSetDeviceInt(handle, c"numThreads".as_ptr(), threads);
        oidnCommitDevice(handle);
        oidn::Device::from_raw(handle)
    };
    device.get_error()?;
    Ok(device)
}

/// Without the feature: [`MISSING`].
#[cfg(not(feature = "oidn"))]
pub fn denoise(colour: &[Vec3], guide: &Guide) -> Result<Vec<Vec3>, String> {
    let _ = (colour, guide);
    Err(MISSING.to_string())
}
