//! The film: per-pixel sums of samples and of their squares, in double precision, so the
//! progressive mean and the variance of that mean (what `compare_images.py --test-var` wants)
//! are exact however many frames accumulate.

use glam::Vec3;

#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    sum: Vec<[f64; 3]>,
    sum_sq: Vec<[f64; 3]>,
    /// Samples per pixel accumulated so far (one per frame).
    pub samples: u32,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self { width, height, sum: vec![[0.0; 3]; n], sum_sq: vec![[0.0; 3]; n], samples: 0 }
    }

    /// Adds sums accumulated elsewhere (the GPU's kernel): per pixel the sum of `samples`
    /// samples and of their squares, row-major from the top left.
    pub fn add_sums(&mut self, sum: &[[f64; 3]], sum_sq: &[[f64; 3]], samples: u32) {
        let n = self.sum.len();
        assert!(
            sum.len() == n && sum_sq.len() == n,
            "{n} pixels, {} sums, {} sums of squares",
            sum.len(),
            sum_sq.len()
        );
        for (total, s) in self.sum.iter_mut().zip(sum).chain(self.sum_sq.iter_mut().zip(sum_sq)) {
            for c in 0..3 {
                total[c] += s[c];
            }
        }
        self.samples += samples;
    }

    /// Discards everything (the view changed).
    pub fn clear(&mut self) {
        self.sum.iter_mut().for_each(|s| *s = [0.0; 3]);
        self.sum_sq.iter_mut().for_each(|s| *s = [0.0; 3]);
        self.samples = 0;
    }

    /// Adds one frame: one sample per pixel, row-major from the top left.
    pub fn add_frame(&mut self, frame: &[Vec3]) {
        assert_eq!(frame.len(), self.sum.len());
        // In parallel: one addition per pixel either way, so the same sums on any thread count.
        use rayon::prelude::*;
        self.sum.par_iter_mut().zip(self.sum_sq.par_iter_mut()).zip(frame).with_min_len(4096).for_each(
            |((s, q), x)| {
                for c in 0..3 {
                    let v = x[c] as f64;
                    s[c] += v;
                    q[c] += v * v;
                }
            },
        );
        self.samples += 1;
    }

    /// The mean of the samples so far (linear radiance), row-major from the top left.
    pub fn mean(&self) -> Vec<Vec3> {
        let inv = 1.0 / self.samples.max(1) as f64;
        self.sum.iter().map(|s| Vec3::new((s[0] * inv) as f32, (s[1] * inv) as f32, (s[2] * inv) as f32)).collect()
    }

    /// Per-pixel variance of the mean, `(S2/n - (S1/n)²) / (n - 1)`, 0 with fewer than 2 samples.
    pub fn variance_of_mean(&self) -> Vec<Vec3> {
        let n = self.samples as f64;
        if self.samples < 2 {
            return vec![Vec3::ZERO; self.sum.len()];
        }
        self.sum
            .iter()
            .zip(&self.sum_sq)
            .map(|(s, q)| {
                let var = |c: usize| ((q[c] / n - (s[c] / n).powi(2)).max(0.0) / (n - 1.0)) as f32;
                Vec3::new(var(0), var(1), var(2))
            })
            .collect()
    }
}

/// The weights of ITU-R BT.709 for a linear Rec. 709 colour's luminance.
pub const LUMINANCE_WEIGHTS: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// The luminance of a linear Rec. 709 colour.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::from_array(LUMINANCE_WEIGHTS))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_variance() {
        let mut f = Film::new(1, 1);
        for x in [1.0f32, 2.0, 3.0, 4.0] {
            f.add_frame(&[Vec3::splat(x)]);
        }
        assert_eq!(f.mean()[0], Vec3::splat(2.5));
        // Sample variance with 1/n: 1.25; of the mean: 1.25 / 3.
        assert!((f.variance_of_mean()[0].x - 1.25 / 3.0).abs() < 1e-6);
    }
}
