//! HDR environment maps: a background that is an equirectangular image (Radiance `.hdr` or
//! OpenEXR), looked up bilinearly and importance-sampled by luminance, so that a small bright
//! sun lights a scene with little noise when light sampling is on.
//!
//! **Lookup**, as Mitsuba 3's `envmap` (so that its renders are our references): for a
//! direction `d` (after undoing `rotate`, in degrees about +y), `u = atan2(d.x, −d.z) / 2π`
//! (wrapped into [0, 1)) and `v = acos(d.y) / π`. Texel `(i, j)` of a `W × H` image sits at
//! `u = (i + ½) / W` (wrapping around) and `v = j / (H − 1)`: row 0 is straight up, the last
//! row straight down, and the radiance between texels is bilinear. The image's left edge looks
//! along −z and `u` grows towards +x.
//!
//! **Sampling**: the texels span `W × (H − 1)` cells. A cell is chosen with probability
//! proportional to its weight, the largest luminance of its four corners (which bounds the
//! bilinear radiance inside it) times `sin θ` at its centre (the solid angle it covers); then
//! a point uniformly inside it in `(u, v)`. The density per solid angle is
//! `p(cell) · W · (H − 1) / (2π² sin θ)`. The marginal distribution over rows of cells and
//! one conditional distribution per row are cumulative tables searched by bisection (Pharr,
//! Jakob & Humphreys, *PBR* 4th ed., §A.5 "Sampling 2D functions").

use crate::error::LoadError;
use crate::film::luminance;
use glam::{Vec2, Vec3};
use std::f32::consts::{PI, TAU};
use std::path::Path;

/// An environment map's texels and its sampling tables in single precision, each cumulative
/// table divided by its total (all zeros where the total is zero).
pub struct EnvironmentTables<'a> {
    pub width: usize,
    pub height: usize,
    pub texels: &'a [Vec3],
    /// `rotate` about +y, as cosine and sine.
    pub rotation: (f32, f32),
    /// Over the rows of cells (`height` entries, the last 1 unless the map is black).
    pub row_cdf: Vec<f32>,
    /// Per row of cells, over its cells (`width + 1` entries a row).
    pub cell_cdf: Vec<f32>,
    /// Each cell's probability (`width` a row): what the density is made of.
    pub cell_probability: Vec<f32>,
}

#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    width: usize,
    height: usize,
    /// Linear radiance, row-major from the top row, times the scene's `scale`.
    texels: Vec<Vec3>,
    /// `rotate` about +y, as cosine and sine.
    rotation: (f32, f32),
    /// Cumulative weights of the rows of cells: `row_cdf[y]` is the sum of rows `0..y`.
    row_cdf: Vec<f64>,
    /// Per row of cells, the cumulative weights of its cells (`width + 1` entries a row).
    cell_cdf: Vec<f64>,
    /// The brightest channel of any texel.
    max_radiance: f32,
}

impl EnvironmentMap {
    /// Reads `path` (Radiance `.hdr` or OpenEXR, by content), scaled by `scale` and turned
    /// `rotate` degrees about +y. Texels that are negative or not finite (also once scaled)
    /// are an error, and so are other image formats (8-bit images hold no radiance).
    pub fn load(path: &Path, scale: f32, rotate: f32) -> Result<EnvironmentMap, LoadError> {
        use image::ImageFormat::{Hdr, OpenExr};
        let bytes = crate::load::input::read_file(path, "the environment map")?;
        let image =
            crate::load::input::decode_image(&bytes, &path.display().to_string(), "environment map", &[Hdr, OpenExr])?
                .into_rgb32f();
        let (width, height) = image.dimensions();
        let texels: Vec<Vec3> = image.pixels().map(|p| Vec3::from(p.0)).collect();
        Self::new(width as usize, height as usize, texels, scale, rotate).map_err(|e| LoadError::new(path, e))
    }

    /// A map from linear texels, row-major from the top row.
    pub fn new(
        width: usize,
        height: usize,
        texels: Vec<Vec3>,
        scale: f32,
        rotate: f32,
    ) -> Result<EnvironmentMap, String> {
        if width == 0 || height < 2 || width.checked_mul(height) != Some(texels.len()) {
            return Err(format!(
                "environment map of {width} × {height} pixels: needs at least 1 × 2, and that many pixels"
            ));
        }
        if !(scale.is_finite() && scale >= 0.0 && rotate.is_finite()) {
            return Err(format!("environment map scale {scale} and rotate {rotate} must be finite, scale ≥ 0"));
        }
        if let Some(i) = texels.iter().position(|t| !t.is_finite() || t.min_element() < 0.0) {
            let t = texels[i];
            return Err(format!(
                "environment map pixel ({}, {}) is negative or not finite: ({}, {}, {})",
                i % width,
                i / width,
                t.x,
                t.y,
                t.z
            ));
        }
        let texels: Vec<Vec3> = texels.into_iter().map(|t| t * scale).collect();
        let max_radiance = texels.iter().fold(0.0f32, |m, t| m.max(t.max_element()));
        if !max_radiance.is_finite() {
            return Err(format!("environment map times scale {scale} exceeds the largest float"));
        }
        let rotation = rotate.to_radians().sin_cos();
        let mut map = EnvironmentMap {
            width,
            height,
            texels,
            rotation: (rotation.1, rotation.0),
            row_cdf: Vec::with_capacity(height),
            cell_cdf: Vec::with_capacity((height - 1) * (width + 1)),
            max_radiance,
        };
        map.tabulate();
        if !map.row_cdf[map.rows()].is_finite() {
            return Err("environment map: its luminance sums beyond the largest float".into());
        }
        Ok(map)
    }

    /// Rows of cells.
    fn rows(&self) -> usize {
        self.height - 1
    }

    /// The sampling tables (see the module's doc).
    fn tabulate(&mut self) {
        let (w, rows) = (self.width, self.rows());
        let lum: Vec<f32> = self.texels.iter().map(|&t| luminance(t)).collect();
        self.row_cdf.push(0.0);
        for y in 0..rows {
            let sin_theta = (PI * (y as f32 + 0.5) / rows as f32).sin();
            let mut sum = 0.0f64;
            self.cell_cdf.push(0.0);
            for x in 0..w {
                let x1 = (x + 1) % w;
                let corners = [lum[y * w + x], lum[y * w + x1], lum[(y + 1) * w + x], lum[(y + 1) * w + x1]];
                let brightest = corners.into_iter().fold(0.0f32, f32::max);
                sum += f64::from(brightest * sin_theta);
                self.cell_cdf.push(sum);
            }
            let total = self.row_cdf[y] + sum;
            self.row_cdf.push(total);
        }
    }

    /// Its texels and sampling tables, normalised, for a tracer elsewhere (the GPU's) that
    /// looks up and samples the map the same way in single precision.
    pub fn tables(&self) -> EnvironmentTables<'_> {
        let (w, rows) = (self.width, self.rows());
        let total = self.row_cdf[rows];
        let share = |x: f64, of: f64| if of > 0.0 { (x / of) as f32 } else { 0.0 };
        let mut cell_cdf = Vec::with_capacity(rows * (w + 1));
        let mut cell_probability = Vec::with_capacity(rows * w);
        for y in 0..rows {
            let row = &self.cell_cdf[y * (w + 1)..(y + 1) * (w + 1)];
            cell_cdf.extend(row.iter().map(|&c| share(c, row[w])));
            cell_probability.extend((0..w).map(|x| share(self.weight(x, y), total)));
        }
        EnvironmentTables {
            width: w,
            height: self.height,
            texels: &self.texels,
            rotation: self.rotation,
            row_cdf: self.row_cdf.iter().map(|&c| share(c, total)).collect(),
            cell_cdf,
            cell_probability,
        }
    }

    /// The brightest channel anywhere.
    pub fn max_radiance(&self) -> f32 {
        self.max_radiance
    }

    /// World direction to the map's frame (undoing `rotate`).
    #[inline]
    fn to_local(&self, d: Vec3) -> Vec3 {
        let (c, s) = self.rotation;
        Vec3::new(c * d.x - s * d.z, d.y, s * d.x + c * d.z)
    }

    #[inline]
    fn to_world(&self, d: Vec3) -> Vec3 {
        let (c, s) = self.rotation;
        Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
    }

    /// `(u, v)` of a unit direction in the map's frame, and `sin θ`.
    #[inline]
    fn uv(d: Vec3) -> (Vec2, f32) {
        let u = d.x.atan2(-d.z) / TAU;
        let u = u - u.floor();
        // θ and sin θ from x and z as well as y, not from y alone: accurate near the poles,
        // where acos(y) and 1 − y² lose their digits and the density needs them.
        let sin_theta = (d.x * d.x + d.z * d.z).sqrt();
        let v = sin_theta.atan2(d.y) / PI;
        (Vec2::new(u, v), sin_theta.min(1.0))
    }

    /// The cell holding `(u, v)` (cell `(x, y)` has the texels `x, x + 1` of rows `y, y + 1`
    /// at its corners), and the position inside it (each in [0, 1]).
    #[inline]
    fn cell(&self, uv: Vec2) -> ((usize, usize), Vec2) {
        let w = self.width as f32;
        let x = (uv.x * w - 0.5).rem_euclid(w);
        let y = uv.y * self.rows() as f32;
        let cx = (x as usize).min(self.width - 1);
        let cy = (y as usize).min(self.rows() - 1);
        ((cx, cy), Vec2::new(x - cx as f32, y - cy as f32))
    }

    /// Radiance arriving from the unit direction `dir`: bilinear between the texels (see the
    /// module's doc).
    #[inline]
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        let (uv, _) = Self::uv(self.to_local(dir));
        if !uv.is_finite() {
            return Vec3::ZERO;
        }
        let ((x, y), f) = self.cell(uv);
        let x1 = (x + 1) % self.width;
        let texel = |x: usize, y: usize| self.texels[y * self.width + x];
        let top = texel(x, y).lerp(texel(x1, y), f.x);
        let bottom = texel(x, y + 1).lerp(texel(x1, y + 1), f.x);
        top.lerp(bottom, f.y)
    }

    /// Density per solid angle of a cell with weight `weight` seen at `sin_theta`.
    #[inline]
    fn density(&self, weight: f64, sin_theta: f32) -> f32 {
        let total = self.row_cdf[self.rows()];
        if total <= 0.0 || sin_theta <= 0.0 {
            return 0.0;
        }
        let cells = (self.width * self.rows()) as f64;
        (weight / total * cells / (2.0 * f64::from(PI) * f64::from(PI) * f64::from(sin_theta))) as f32
    }

    /// The weight of cell `(x, y)`.
    fn weight(&self, x: usize, y: usize) -> f64 {
        let row = &self.cell_cdf[y * (self.width + 1)..];
        row[x + 1] - row[x]
    }

    /// Density per solid angle with which [`EnvironmentMap::sample`] picks the unit
    /// direction `dir`.
    pub fn pdf(&self, dir: Vec3) -> f32 {
        let (uv, sin_theta) = Self::uv(self.to_local(dir));
        if !uv.is_finite() {
            return 0.0;
        }
        let ((x, y), _) = self.cell(uv);
        self.density(self.weight(x, y), sin_theta)
    }

    /// A unit direction by the map's distribution from two uniform numbers in [0, 1), with
    /// its density per solid angle (`None` for a black map or a pole).
    pub fn sample(&self, u1: f32, u2: f32) -> Option<(Vec3, f32)> {
        let rows = self.rows();
        let total = self.row_cdf[rows];
        if total <= 0.0 {
            return None;
        }
        // The last row whose cumulative weight lies at or below the target, skipping empty
        // rows (their start equals the next one's).
        let pick = |cdf: &[f64], target: f64| cdf.partition_point(|&c| c <= target).saturating_sub(1);
        let target = f64::from(u1) * total;
        let y = pick(&self.row_cdf[..rows], target).min(rows - 1);
        let row = &self.cell_cdf[y * (self.width + 1)..(y + 1) * (self.width + 1)];
        let row_total = row[self.width];
        if row_total <= 0.0 {
            return None;
        }
        let dy = ((target - self.row_cdf[y]) / row_total).clamp(0.0, 1.0);
        let target = f64::from(u2) * row_total;
        let x = pick(&row[..self.width], target).min(self.width - 1);
        let weight = row[x + 1] - row[x];
        let dx = if weight > 0.0 { ((target - row[x]) / weight).clamp(0.0, 1.0) } else { 0.5 };
        let u = ((x as f64 + dx + 0.5) / self.width as f64).fract();
        let v = (y as f64 + dy) / rows as f64;
        let (phi, theta) = (std::f64::consts::TAU * u, std::f64::consts::PI * v);
        let (sin_theta, cos_theta) = theta.sin_cos();
        let local = Vec3::new((sin_theta * phi.sin()) as f32, cos_theta as f32, (-sin_theta * phi.cos()) as f32);
        let dir = self.to_world(local).normalize();
        // The density of the cell the direction lies in, as `pdf` finds it: where rounding
        // puts a point of this cell on its edge, the two still agree, which MIS needs.
        let pdf = self.pdf(dir);
        (pdf > 0.0 && pdf.is_finite()).then_some((dir, pdf))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 16 × 8 map: dim blue everywhere, a bright warm 2 × 1 "sun" above the horizon.
    fn sun_map(rotate: f32) -> EnvironmentMap {
        let (w, h) = (16, 8);
        let mut texels = vec![Vec3::new(0.1, 0.2, 0.4); w * h];
        texels[2 * w + 5] = Vec3::new(50.0, 40.0, 30.0);
        texels[2 * w + 6] = Vec3::new(50.0, 40.0, 30.0);
        EnvironmentMap::new(w, h, texels, 1.0, rotate).unwrap()
    }

    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f32 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// Directions round-trip through the map's coordinates, and the orientation is
    /// Mitsuba's: −z at the left edge, +x a quarter along, +y at the top row.
    #[test]
    fn orientation() {
        let (uv, _) = EnvironmentMap::uv(Vec3::NEG_Z);
        assert!((uv - Vec2::new(0.0, 0.5)).abs().max_element() < 1e-6, "{uv}");
        let (uv, _) = EnvironmentMap::uv(Vec3::X);
        assert!((uv - Vec2::new(0.25, 0.5)).abs().max_element() < 1e-6, "{uv}");
        assert!(EnvironmentMap::uv(Vec3::Y).0.y.abs() < 1e-6);
        let map = sun_map(30.0);
        let mut rng = Lcg(3);
        for _ in 0..1000 {
            let d = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5).normalize();
            assert!((map.to_world(map.to_local(d)) - d).length() < 1e-5);
        }
        // Texel (x, y) sits at u = (x + ½) / 16, v = y / 7: the sun's texels (5, 2) and (6, 2)
        // are where they should be, and halfway between texels the radiance is their mean.
        let at = |u: f32, v: f32| {
            let (theta, phi) = (PI * v, TAU * u);
            map.radiance(map.to_world(Vec3::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos())))
        };
        for (u, expected) in [(5.5, 50.0), (6.0, 50.0), (6.5, 50.0), (7.0, 25.05), (5.0, 25.05)] {
            let sun = at(u / 16.0, 2.0 / 7.0);
            assert!((sun.x - expected).abs() < 1e-2, "u = {u} / 16: {sun}");
        }
        let between_rows = at(5.5 / 16.0, 1.5 / 7.0);
        assert!((between_rows - Vec3::new(25.05, 20.1, 15.2)).length() < 1e-2, "{between_rows}");
    }

    /// The density integrates to 1 over the sphere, the sampler's directions come with the
    /// density `pdf` gives them, and they fall into pixels as often as the weights say.
    #[test]
    fn sampling_matches_its_density() {
        let map = sun_map(-75.0);
        let mut rng = Lcg(11);
        // ∫ pdf dω by uniform sphere sampling (density 1 / 4π).
        let n = 400_000;
        let mut integral = 0.0f64;
        for _ in 0..n {
            let z = 1.0 - 2.0 * rng.next();
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = TAU * rng.next();
            let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            integral += f64::from(map.pdf(d)) * 4.0 * f64::from(PI);
        }
        let integral = integral / n as f64;
        assert!((integral - 1.0).abs() < 0.02, "∫ pdf = {integral}");
        let mut counts = vec![0u32; 16 * 7];
        let m = 200_000;
        for _ in 0..m {
            let (d, pdf) = map.sample(rng.next(), rng.next()).unwrap();
            assert!((d.length() - 1.0).abs() < 1e-4);
            let again = map.pdf(d);
            assert!((pdf - again).abs() <= 1e-3 * pdf.max(again), "{pdf} vs {again} at {d}");
            let ((x, y), _) = map.cell(EnvironmentMap::uv(map.to_local(d)).0);
            counts[y * 16 + x] += 1;
        }
        let total = map.row_cdf[7];
        for y in 0..7 {
            for x in 0..16 {
                let expected = map.weight(x, y) / total * m as f64;
                let got = f64::from(counts[y * 16 + x]);
                // Five standard deviations of a binomial count.
                assert!((got - expected).abs() <= 5.0 * expected.sqrt() + 2.0, "pixel ({x}, {y}): {got} vs {expected}");
            }
        }
    }

    /// A Radiance file is read (texel for texel, up to its shared-exponent precision), an
    /// 8-bit PNG is refused by name.
    #[test]
    fn files() {
        let dir = std::env::temp_dir().join(format!("phr-envmap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pixels: Vec<image::Rgb<f32>> = (0..8).map(|i| image::Rgb([i as f32, 0.5, 2.0])).collect();
        let hdr = dir.join("sky.hdr");
        image::codecs::hdr::HdrEncoder::new(std::fs::File::create(&hdr).unwrap()).encode(&pixels, 4, 2).unwrap();
        let map = EnvironmentMap::load(&hdr, 2.0, 0.0).unwrap();
        assert_eq!((map.width, map.height), (4, 2));
        for (i, t) in map.texels.iter().enumerate() {
            assert!((*t - 2.0 * Vec3::new(i as f32, 0.5, 2.0)).abs().max_element() < 0.05, "texel {i}: {t}");
        }
        let png = dir.join("sky.png");
        image::RgbImage::new(4, 2).save(&png).unwrap();
        let e = EnvironmentMap::load(&png, 1.0, 0.0).unwrap_err().to_string();
        assert!(e.contains("sky.png") && e.contains("is Png, not one of hdr, exr"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_maps_are_refused() {
        assert!(EnvironmentMap::new(1, 2, vec![Vec3::ONE, Vec3::splat(f32::NAN)], 1.0, 0.0)
            .unwrap_err()
            .contains("pixel (0, 1)"));
        assert!(EnvironmentMap::new(1, 2, vec![Vec3::ONE, -Vec3::ONE], 1.0, 0.0).is_err());
        assert!(EnvironmentMap::new(2, 2, vec![Vec3::ONE], 1.0, 0.0).is_err());
        assert!(EnvironmentMap::new(2, 1, vec![Vec3::ONE; 2], 1.0, 0.0).is_err());
        assert!(EnvironmentMap::new(1, 2, vec![Vec3::ONE; 2], f32::INFINITY, 0.0).is_err());
        let black = EnvironmentMap::new(2, 2, vec![Vec3::ZERO; 4], 1.0, 0.0).unwrap();
        assert_eq!(black.max_radiance(), 0.0);
        assert!(black.sample(0.5, 0.5).is_none());
    }
}
