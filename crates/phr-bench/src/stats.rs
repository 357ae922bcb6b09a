//! Statistics of repeated measurements. This machine class is noisy: reports quote medians
//! (and the spread), never single runs.

/// Median, minimum, maximum and mean of repeated measurements.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Stat {
    pub median: f64,
    pub min: f64,
    pub max: f64,
    pub mean: f64,
}

impl Stat {
    /// The statistics of `v` (at least one value; the median of an even count is the upper
    /// middle value, a measured one).
    pub fn of(mut v: Vec<f64>) -> Self {
        assert!(!v.is_empty(), "Stat::of needs at least one measurement");
        v.sort_by(f64::total_cmp);
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        Self { median: v[v.len() / 2], min: v[0], max: v[v.len() - 1], mean }
    }
}

/// Pearson's correlation coefficient.
pub fn correlation(xs: &[f64], ys: &[f64]) -> f64 {
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let cov: f64 = xs.iter().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let vx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    let vy: f64 = ys.iter().map(|y| (y - my).powi(2)).sum();
    cov / (vx * vy).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_min_max_mean() {
        let s = Stat::of(vec![5.0, 1.0, 3.0, 2.0]);
        assert_eq!((s.median, s.min, s.max, s.mean), (3.0, 1.0, 5.0, 2.75));
        assert_eq!(Stat::of(vec![7.0]).median, 7.0);
    }

    #[test]
    fn correlation_of_lines() {
        let x = [1.0, 2.0, 3.0, 4.0];
        assert!((correlation(&x, &[2.0, 4.0, 6.0, 8.0]) - 1.0).abs() < 1e-12);
        assert!((correlation(&x, &[8.0, 6.0, 4.0, 2.0]) + 1.0).abs() < 1e-12);
        assert!(correlation(&x, &[1.0, -1.0, -1.0, 1.0]).abs() < 1e-12);
    }
}
