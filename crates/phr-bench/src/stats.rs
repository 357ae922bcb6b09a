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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_min_max_mean() {
        let s = Stat::of(vec![5.0, 1.0, 3.0, 2.0]);
        assert_eq!((s.median, s.min, s.max, s.mean), (3.0, 1.0, 5.0, 2.75));
        assert_eq!(Stat::of(vec![7.0]).median, 7.0);
    }
}
