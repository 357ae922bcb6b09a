//! The film: per-pixel sums of samples and of their squares, in double precision, so the
//! progressive mean and the variance of that mean (what `compare_images.py --test-var` wants)
//! are exact however many frames accumulate.

use glam::Vec3;

#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    /// The sums of the samples and of their squares, meaningful only with `samples > 0`: a
    /// cleared film keeps the old sums, which the next frame overwrites instead of adding to.
    /// (Zeroing them, 3 MB at 256², took 0.3 ms on one thread, and a moving view clears the
    /// film every frame.)
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
        let fresh = self.samples == 0;
        for (total, s) in self.sum.iter_mut().zip(sum).chain(self.sum_sq.iter_mut().zip(sum_sq)) {
            for c in 0..3 {
                total[c] = if fresh { 0.0 + s[c] } else { total[c] + s[c] };
            }
        }
        self.samples += samples;
    }

    /// Discards the samples (the view changed): the sums are left as they are, no longer
    /// counted, and overwritten by the next frame.
    pub fn clear(&mut self) {
        self.samples = 0;
    }

    /// Adds one frame: one sample per pixel, row-major from the top left.
    pub fn add_frame(&mut self, frame: &[Vec3]) {
        assert_eq!(frame.len(), self.sum.len());
        // In parallel: one addition per pixel either way, so the same sums on any thread count.
        use rayon::prelude::*;
        // `0.0 + v`, not `v`: the sums a zeroed film gave, to the bit (a −0 sample sums to +0).
        let fresh = self.samples == 0;
        self.sum.par_iter_mut().zip(self.sum_sq.par_iter_mut()).zip(frame).with_min_len(4096).for_each(
            |((s, q), x)| {
                for c in 0..3 {
                    let v = x[c] as f64;
                    (s[c], q[c]) = if fresh { (0.0 + v, 0.0 + v * v) } else { (s[c] + v, q[c] + v * v) };
                }
            },
        );
        self.samples += 1;
    }

    /// The mean of the samples so far (linear radiance), row-major from the top left.
    pub fn mean(&self) -> Vec<Vec3> {
        if self.samples == 0 {
            return vec![Vec3::ZERO; self.sum.len()];
        }
        let inv = 1.0 / self.samples as f64;
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

    /// A cleared film keeps its old sums in memory; nothing it gives shows them.
    #[test]
    fn a_cleared_film_forgets_its_samples() {
        let frames = [[Vec3::splat(f32::NAN), Vec3::new(5.0, -1.0, 2.0)], [Vec3::ONE, Vec3::splat(7.0)]];
        // A −0.0 sample first after a clear: the sums hold +0.0, as when a clear zeroed them.
        let (new, newer) =
            ([Vec3::new(-0.0, 1.0, 2.0), Vec3::splat(3.0)], [Vec3::splat(1.5), Vec3::new(-0.0, 4.0, 1.0)]);
        let bits = |sums: &[[f64; 3]]| sums.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        let mut fresh = Film::new(2, 1);
        fresh.add_frame(&new);
        fresh.add_frame(&newer);
        let mut sums = Film::new(2, 1);
        sums.add_frame(&newer);
        let (sum, sum_sq) = (sums.sum.clone(), sums.sum_sq.clone());
        for add_sums in [false, true] {
            let mut film = Film::new(2, 1);
            frames.iter().for_each(|f| film.add_frame(f));
            film.clear();
            assert_eq!((film.samples, film.mean()), (0, vec![Vec3::ZERO; 2]));
            assert_eq!(film.variance_of_mean(), vec![Vec3::ZERO; 2]);
            film.add_frame(&new);
            assert_eq!(film.mean(), new.to_vec());
            assert_eq!(film.sum[0][0].to_bits(), 0.0f64.to_bits(), "−0.0 summed into a cleared film");
            match add_sums {
                true => film.add_sums(&sum, &sum_sq, 1),
                false => film.add_frame(&newer),
            }
            assert_eq!((bits(&film.sum), bits(&film.sum_sq)), (bits(&fresh.sum), bits(&fresh.sum_sq)));
            assert_eq!(film.variance_of_mean(), fresh.variance_of_mean());
            film.clear();
            film.add_sums(&sum, &sum_sq, 1);
            assert_eq!((bits(&film.sum), film.samples), (bits(&sum), 1));
        }
    }
}
