//! Image files: PNG (sRGB, 8 bit, for looking at), EXR and PFM (linear float, for measuring),
//! and the traversal-steps heatmap. Every file is written to a temporary name next to its
//! destination and renamed into place, so a failed or interrupted write never leaves a
//! partial file behind.

use glam::Vec3;
use image::{ImageFormat, Rgb32FImage, RgbImage};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// The linear → sRGB transfer function (IEC 61966-2-1), clamped to [0, 1].
pub fn srgb_encode(x: f32) -> f32 {
    let x = if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 };
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// `pixels` (linear radiance) as 8-bit sRGB RGBA, opaque: what the viewer shows (and the
/// GPU's display kernel writes, `crates/phr-gpu/src/shaders/display.wgsl`).
pub fn rgba8(pixels: &[Vec3]) -> Vec<u8> {
    let mut out = Vec::with_capacity(pixels.len() * 4);
    for p in pixels {
        for c in p.to_array() {
            out.push((srgb_encode(c) * 255.0 + 0.5) as u8);
        }
        out.push(255);
    }
    out
}

/// Writes `pixels` (linear radiance, row-major from the top left) in the format named by the
/// extension of `path`: `.png`, `.exr` or `.pfm`.
pub fn write_image(path: &Path, width: u32, height: u32, pixels: &[Vec3]) -> io::Result<()> {
    assert_eq!(pixels.len(), width as usize * height as usize);
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "png" => {
            let img = RgbImage::from_fn(width, height, |x, y| {
                let p = pixels[(y * width + x) as usize];
                image::Rgb([p.x, p.y, p.z].map(|c| (srgb_encode(c) * 255.0 + 0.5) as u8))
            });
            write_atomically(path, |tmp| img.save_with_format(tmp, ImageFormat::Png).map_err(io::Error::other))
        }
        "exr" => {
            let img = Rgb32FImage::from_fn(width, height, |x, y| {
                let p = pixels[(y * width + x) as usize];
                image::Rgb([p.x, p.y, p.z])
            });
            write_atomically(path, |tmp| img.save_with_format(tmp, ImageFormat::OpenExr).map_err(io::Error::other))
        }
        "pfm" => write_atomically(path, |tmp| write_pfm(tmp, width, height, pixels)),
        _ => Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{}: unknown image format (use .png, .exr or .pfm)", path.display()),
        )),
    }
}

/// Portable float map, little-endian, rows bottom to top as the format wants.
fn write_pfm(path: &Path, width: u32, height: u32, pixels: &[Vec3]) -> io::Result<()> {
    let mut out = io::BufWriter::new(std::fs::File::create(path)?);
    write!(out, "PF\n{width} {height}\n-1.0\n")?;
    for y in (0..height).rev() {
        for p in &pixels[(y * width) as usize..((y + 1) * width) as usize] {
            for c in [p.x, p.y, p.z] {
                out.write_all(&c.to_le_bytes())?;
            }
        }
    }
    out.flush()
}

/// Runs `write` on a temporary path beside `path` and renames the result into place; on error
/// the temporary file is removed.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> io::Result<()>) -> io::Result<()> {
    let tmp = temporary_sibling(path);
    let result = write(&tmp).and_then(|()| std::fs::rename(&tmp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn temporary_sibling(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    // Keep the real extension last: the image encoders pick the format by it.
    let ext = path.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.partial.{ext}", std::process::id()))
}

/// A colour map from blue (few steps) through green and yellow to red (many): Google's
/// "Turbo" (Mikhailov 2019), by its polynomial approximation.
pub fn turbo(t: f32) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let r = 0.1357 + t * (4.5974 - t * (42.3277 - t * (130.5887 - t * (150.5666 - t * 58.1375))));
    let g = 0.0914 + t * (2.1856 + t * (4.8052 - t * (14.0195 - t * (4.2109 + t * 2.7747))));
    let b = 0.1067 + t * (12.5925 - t * (60.1097 - t * (109.0745 - t * (88.5066 - t * 26.8183))));
    [r, g, b].map(|c| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
}

/// Writes a heatmap PNG of per-pixel counts, scaled so that `scale_max` is red; returns that
/// maximum (the largest count if `scale_max` is `None`) so images can share one scale.
pub fn write_heatmap(path: &Path, width: u32, height: u32, counts: &[u32], scale_max: Option<u32>) -> io::Result<u32> {
    let max = scale_max.unwrap_or_else(|| counts.iter().copied().max().unwrap_or(0)).max(1);
    let img = RgbImage::from_fn(width, height, |x, y| {
        image::Rgb(turbo(counts[(y * width + x) as usize] as f32 / max as f32))
    });
    write_atomically(path, |tmp| img.save_with_format(tmp, ImageFormat::Png).map_err(io::Error::other))?;
    Ok(max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pfm_round_trip_and_no_partial_files() {
        let dir = std::env::temp_dir().join(format!("phr-output-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pixels = vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 5.0, 6.0)];
        let path = dir.join("x.pfm");
        write_image(&path, 1, 2, &pixels).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let header = b"PF\n1 2\n-1.0\n";
        assert_eq!(&bytes[..header.len()], header);
        // Bottom row first.
        let first = f32::from_le_bytes(bytes[header.len()..header.len() + 4].try_into().unwrap());
        assert_eq!(first, 4.0);
        write_image(&dir.join("y.png"), 1, 2, &pixels).unwrap();
        write_image(&dir.join("z.exr"), 1, 2, &pixels).unwrap();
        assert!(write_image(&dir.join("w.bmp"), 1, 2, &pixels).is_err());
        assert!(write_image(&dir.join("missing-dir/v.png"), 1, 2, &pixels).is_err());
        let mut names: Vec<String> =
            std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        assert_eq!(names, ["x.pfm", "y.png", "z.exr"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn srgb_endpoints() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_encode(0.214_041) - 0.5).abs() < 1e-3);
        assert_eq!(srgb_encode(f32::NAN), 0.0);
    }
}
