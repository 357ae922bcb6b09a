//! Colour textures: an 8-bit sRGB image, looked up with bilinear filtering and repeating
//! (wrapping) texture coordinates, decoded to linear colour through a 256-entry table.
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
        let name = source.name();
        let read;
        let bytes: &[u8] = match source {
            ImageSource::File(file) => {
                read = crate::load::input::read_file(file, "the texture")?;
                &read
            }
            ImageSource::Embedded { bytes, .. } => bytes,
        };
        use image::ImageFormat::{Jpeg, Png};
        let image = crate::load::input::decode_image(bytes, &name, "texture", &[Png, Jpeg])?.into_rgb8();
        let (width, height) = image.dimensions();
        let texels = image.pixels().map(|p| p.0).collect();
        Ok(Texture { width, height, texels })
    }

    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Memory the texels take, in bytes.
    pub fn bytes(&self) -> usize {
        self.texels.len() * 3
    }

    /// Linear colour of texel `(x, y)` (from the top left), coordinates wrapped.
    #[inline]
    fn texel(&self, x: i64, y: i64) -> Vec3 {
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        let [r, g, b] = self.texels[y * self.width as usize + x];
        let table = srgb_table();
        Vec3::new(table[r as usize], table[g as usize], table[b as usize])
    }

    /// The linear colour at texture coordinates `uv`, bilinearly filtered, repeating outside
    /// [0, 1]. Texel centres lie at `((x + 0.5) / width, 1 − (y + 0.5) / height)`.
    #[inline]
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        if !uv.is_finite() {
            return self.texel(0, 0);
        }
        // Continuous texel coordinates, centres at integers; wrapped into range first so
        // that huge coordinates keep their precision.
        let u = uv.x.rem_euclid(1.0) * self.width as f32 - 0.5;
        let v = (1.0 - uv.y.rem_euclid(1.0)) * self.height as f32 - 0.5;
        let (x0, y0) = (u.floor(), v.floor());
        let (fx, fy) = (u - x0, v - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = self.texel(x0, y0).lerp(self.texel(x0 + 1, y0), fx);
        let bottom = self.texel(x0, y0 + 1).lerp(self.texel(x0 + 1, y0 + 1), fx);
        top.lerp(bottom, fy)
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

    #[test]
    fn srgb_decoding() {
        let grey = Texture::from_srgb8(1, 1, vec![[128, 188, 255]]);
        let c = grey.sample(Vec2::new(0.5, 0.5));
        // sRGB 128 is linear 0.2158, 188 is 0.5029.
        assert!((c.x - 0.2158).abs() < 1e-3 && (c.y - 0.5029).abs() < 1e-3 && c.z == 1.0, "{c}");
    }
}
