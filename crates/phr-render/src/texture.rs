//! Colour textures: an 8-bit sRGB image, looked up with bilinear filtering and repeating
//! (wrapping) texture coordinates, decoded to linear colour through a 256-entry table. And
//! alpha masks ([`AlphaMask`]): 8-bit coverage, filtered the same way and cut at one half.
//!
//! Texels stay 8-bit (4 bytes each: Sponza's textures take 18 × 4 MB instead of 18 × 12 MB as
//! linear floats); decoding happens per lookup, on the four texels the filter reads, so the
//! filter blends linear values as it should. `v` runs upwards as in OBJ and glTF's flipped
//! convention: `v = 0` is the image's bottom row.

use crate::error::LoadError;
use crate::load::ImageSource;
use glam::{Vec2, Vec3};
use std::sync::OnceLock;

#[derive(Clone, Debug)]
pub struct Texture {
    width: u32,
    height: u32,
    /// Row-major from the top row, sRGB.
    texels: Vec<[u8; 3]>,
}

/// sRGB decoding of each 8-bit value (IEC 61966-2-1).
fn srgb_table() -> &'static [f32; 256] {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|i| {
            let c = i as f32 / 255.0;
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        })
    })
}

impl Texture {
    /// An image of `width × height` sRGB texels, row-major from the top.
    pub fn from_srgb8(width: u32, height: u32, texels: Vec<[u8; 3]>) -> Texture {
        assert!(width > 0 && height > 0 && texels.len() == width as usize * height as usize, "texture size");
        Texture { width, height, texels }
    }

    /// Reads an image (PNG or JPEG, from a file or from bytes inside an asset), naming it in
    /// any error.
    pub fn load(source: &ImageSource) -> Result<Texture, LoadError> {
        let image = read_image(source, "texture")?.into_rgb8();
        let (width, height) = image.dimensions();
        let texels = image.pixels().map(|p| p.0).collect();
        Ok(Texture { width, height, texels })
    }

    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The texels, row-major from the top row, sRGB (what a tracer elsewhere, the GPU's,
    /// uploads and filters the same way).
    pub fn srgb_texels(&self) -> &[[u8; 3]] {
        &self.texels
    }

    /// Memory the texels take, in bytes.
    pub fn bytes(&self) -> usize {
        self.texels.len() * 3
    }

    /// Linear colour of texel `(x, y)` (from the top left), coordinates wrapped.
    #[inline]
    fn texel(&self, x: i64, y: i64) -> Vec3 {
        let [r, g, b] = self.texels[wrapped(self.width, self.height, x, y)];
        let table = srgb_table();
        Vec3::new(table[r as usize], table[g as usize], table[b as usize])
    }

    /// The linear colour at texture coordinates `uv`, bilinearly filtered, repeating outside
    /// [0, 1]. Texel centres lie at `((x + 0.5) / width, 1 − (y + 0.5) / height)`.
    #[inline]
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let Some((x0, y0, fx, fy)) = footprint(self.width, self.height, uv) else { return self.texel(0, 0) };
        let top = self.texel(x0, y0).lerp(self.texel(x0 + 1, y0), fx);
        let bottom = self.texel(x0, y0 + 1).lerp(self.texel(x0 + 1, y0 + 1), fx);
        top.lerp(bottom, fy)
    }
}

/// A PNG or JPEG image (`what` it is for, in errors), from a file or from bytes inside an
/// asset.
fn read_image(source: &ImageSource, what: &str) -> Result<image::DynamicImage, LoadError> {
    let read;
    let bytes: &[u8] = match source {
        ImageSource::File(file) => {
            read = crate::load::input::read_file(file, &format!("the {what}"))?;
            &read
        }
        ImageSource::Embedded { bytes, .. } => bytes,
    };
    use image::ImageFormat::{Jpeg, Png};
    crate::load::input::decode_image(bytes, &source.name(), what, &[Png, Jpeg])
}

/// The row-major index of texel `(x, y)` (from the top left) of a `width × height` image,
/// coordinates wrapped.
#[inline]
fn wrapped(width: u32, height: u32, x: i64, y: i64) -> usize {
    let x = x.rem_euclid(i64::from(width)) as usize;
    let y = y.rem_euclid(i64::from(height)) as usize;
    y * width as usize + x
}

/// The bilinear footprint of `uv` on a `width × height` image with repeating coordinates: the
/// top left texel `(x0, y0)` of the four (from the image's top left, not yet wrapped) and the
/// weights `fx`, `fy` of the right and lower ones. `None` for non-finite coordinates.
#[inline]
fn footprint(width: u32, height: u32, uv: Vec2) -> Option<(i64, i64, f32, f32)> {
    if !uv.is_finite() {
        return None;
    }
    // Continuous texel coordinates, centres at integers; wrapped into range first so that
    // huge coordinates keep their precision.
    let u = uv.x.rem_euclid(1.0) * width as f32 - 0.5;
    let v = (1.0 - uv.y.rem_euclid(1.0)) * height as f32 - 0.5;
    let (x0, y0) = (u.floor(), v.floor());
    Some((x0 as i64, y0 as i64, u - x0, v - y0))
}

/// Where a surface is, by an image: an MTL `map_d` (a grey image, or the alpha channel of
/// one that has it; Crytek's Sponza cuts its leaves and chains out so). The coverage is
/// filtered like a colour texture's and the surface is there where it is at least one half:
/// an alpha test, as rasterisers and Embree's filter functions do it, so a mask is a cutout
/// with sharp edges, not a blend.
#[derive(Clone, Debug)]
pub struct AlphaMask {
    width: u32,
    height: u32,
    /// Row-major from the top row; 255 is fully there.
    coverage: Vec<u8>,
    /// The surface is there where the filtered coverage reaches it: one half, or a glTF
    /// material's alpha cutoff over its base colour's alpha.
    threshold: f32,
}

impl AlphaMask {
    /// A mask of `width × height` coverage values, row-major from the top.
    pub fn new(width: u32, height: u32, coverage: Vec<u8>) -> AlphaMask {
        assert!(width > 0 && height > 0 && coverage.len() == width as usize * height as usize, "mask size");
        AlphaMask { width, height, coverage, threshold: 0.5 }
    }

    /// The mask with the surface there where the coverage reaches `threshold` instead of one
    /// half.
    pub fn with_threshold(self, threshold: f32) -> AlphaMask {
        AlphaMask { threshold, ..self }
    }

    /// Reads a mask image (PNG or JPEG): its alpha channel if it has one, else its grey
    /// level. Errors name the image.
    pub fn load(source: &ImageSource) -> Result<AlphaMask, LoadError> {
        let image = read_image(source, "alpha mask")?;
        let (width, height) = (image.width(), image.height());
        let coverage = if image.color().has_alpha() {
            image.into_rgba8().pixels().map(|p| p.0[3]).collect()
        } else {
            image.into_luma8().into_raw()
        };
        Ok(AlphaMask::new(width, height, coverage))
    }

    /// Memory the mask takes, in bytes.
    pub fn bytes(&self) -> usize {
        self.coverage.len()
    }

    /// Its size, its coverage values (row-major from the top row) and its threshold: what a
    /// tracer elsewhere (the GPU's) uploads to test the same way.
    pub fn parts(&self) -> ((u32, u32), &[u8], f32) {
        ((self.width, self.height), &self.coverage, self.threshold)
    }

    #[inline]
    fn value(&self, x: i64, y: i64) -> f32 {
        f32::from(self.coverage[wrapped(self.width, self.height, x, y)]) / 255.0
    }

    /// Whether the surface is there at texture coordinates `uv`: the bilinearly filtered
    /// coverage (repeating outside [0, 1], texel centres as [`Texture::sample`]'s) reaches the
    /// threshold (one half unless [`AlphaMask::with_threshold`] says otherwise).
    #[inline]
    pub fn covers(&self, uv: Vec2) -> bool {
        let Some((x0, y0, fx, fy)) = footprint(self.width, self.height, uv) else {
            return self.value(0, 0) >= self.threshold;
        };
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let top = lerp(self.value(x0, y0), self.value(x0 + 1, y0), fx);
        let bottom = lerp(self.value(x0, y0 + 1), self.value(x0 + 1, y0 + 1), fx);
        lerp(top, bottom, fy) >= self.threshold
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        // 4 × 2: a row of four colours over a row of their inverses.
        let top = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]];
        let texels = top.iter().copied().chain(top.iter().map(|t| t.map(|c| 255 - c))).collect();
        Texture::from_srgb8(4, 2, texels)
    }

    #[test]
    fn texel_centres_return_the_texel() {
        let t = checker();
        for y in 0..2 {
            for x in 0..4 {
                let uv = Vec2::new((x as f32 + 0.5) / 4.0, 1.0 - (y as f32 + 0.5) / 2.0);
                let expected = t.texel(x, y);
                assert!((t.sample(uv) - expected).abs().max_element() < 1e-6, "texel ({x}, {y}) at {uv}");
            }
        }
        // The top row is v near 1.
        assert_eq!(t.texel(0, 0), Vec3::X);
        assert!((t.sample(Vec2::new(0.125, 0.75)) - Vec3::X).length() < 1e-6);
    }

    #[test]
    fn filtering_blends_linear_values_and_wraps() {
        let t = checker();
        // Half-way between the red and green texels of the top row.
        let mid = t.sample(Vec2::new(0.25, 0.75));
        assert!((mid - Vec3::new(0.5, 0.5, 0.0)).length() < 1e-6, "{mid}");
        // u = 0 lies between the last texel and the first: wrapped, not clamped.
        let edge = t.sample(Vec2::new(0.0, 0.75));
        assert!((edge - Vec3::new(1.0, 0.5, 0.5)).length() < 1e-6, "{edge}");
        // Repeats: u + 3 and v − 2 give the same colour.
        let a = t.sample(Vec2::new(0.3, 0.6));
        assert!((t.sample(Vec2::new(3.3, -1.4)) - a).length() < 1e-5);
    }

    /// A mask covers where its filtered value reaches one half: at its texel centres as the
    /// texels say, between a full and an empty texel up to half way, and repeating.
    #[test]
    fn masks_cut_at_one_half() {
        // 2 × 1: the left texel there, the right one not.
        let mask = AlphaMask::new(2, 1, vec![255, 0]);
        assert!(mask.covers(Vec2::new(0.25, 0.5)));
        assert!(!mask.covers(Vec2::new(0.75, 0.5)));
        // Texel centres at u = 0.25 and 0.75: the value crosses one half at u = 0.5 (and at
        // u = 0, wrapped).
        assert!(mask.covers(Vec2::new(0.49, 0.5)) && !mask.covers(Vec2::new(0.51, 0.5)));
        assert!(mask.covers(Vec2::new(0.01, 0.5)) && !mask.covers(Vec2::new(0.99, 0.5)));
        assert!(mask.covers(Vec2::new(3.25, -7.0)) && !mask.covers(Vec2::new(-2.25, 0.5)));
        // A value below one half covers nothing; one of exactly 128 (0.502) covers.
        assert!(!AlphaMask::new(1, 1, vec![127]).covers(Vec2::new(0.5, 0.5)));
        assert!(AlphaMask::new(1, 1, vec![128]).covers(Vec2::new(0.5, 0.5)));
    }

    /// The alpha channel of an image that has one, else its grey level.
    #[test]
    fn masks_read_alpha_or_grey() {
        let dir = std::env::temp_dir().join(format!("phr-mask-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let rgba = image::RgbaImage::from_fn(2, 1, |x, _| image::Rgba([255, 255, 255, if x == 0 { 0 } else { 255 }]));
        rgba.save(dir.join("rgba.png")).unwrap();
        let grey = image::GrayImage::from_fn(2, 1, |x, _| image::Luma([if x == 0 { 255 } else { 0 }]));
        grey.save(dir.join("grey.png")).unwrap();
        let rgba = AlphaMask::load(&ImageSource::File(dir.join("rgba.png"))).unwrap();
        assert!(!rgba.covers(Vec2::new(0.25, 0.5)) && rgba.covers(Vec2::new(0.75, 0.5)));
        let grey = AlphaMask::load(&ImageSource::File(dir.join("grey.png"))).unwrap();
        assert!(grey.covers(Vec2::new(0.25, 0.5)) && !grey.covers(Vec2::new(0.75, 0.5)));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn srgb_decoding() {
        let grey = Texture::from_srgb8(1, 1, vec![[128, 188, 255]]);
        let c = grey.sample(Vec2::new(0.5, 0.5));
        // sRGB 128 is linear 0.2158, 188 is 0.5029.
        assert!((c.x - 0.2158).abs() < 1e-3 && (c.y - 0.5029).abs() < 1e-3 && c.z == 1.0, "{c}");
    }
}
