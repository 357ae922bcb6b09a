//! How many rays the interleaved traversal ([`super::WideBvh::closest_hit_interleaved`])
//! should keep in flight, from the size of what it traces; applied by
//! [`super::WideBvh::closest_hit_batch`] and [`super::WideBvh::any_hit_batch`].
//!
//! Interleaving pays for memory waits: where the tree and its triangles do not fit the
//! last-level cache, each node visit waits on memory, and the more rays share the wait the
//! better (`phr bench-rays`, the dragon's 65 MB: 1.7–1.8× the single ray's rate with 4 rays,
//! 1.3× with 2). Where they fit, the waits are short and the rays are bound by branch
//! mispredictions more than by loads: 2 rays gain 0–17 %, 4 lose up to 26 % (Sponza's 5 MB,
//! Conference's 23 MB). Measurements in `docs/bench-rays/history.md`.

/// Rays at once when the traced bytes exceed the last-level cache.
pub const FROM_MEMORY: usize = 4;

/// Rays at once when they fit.
pub const FROM_CACHE: usize = 2;

/// Whether `bytes` (nodes and primitive data) fit this CPU's last-level cache.
pub fn fits_cache(bytes: usize) -> bool {
    bytes <= last_level_cache()
}

/// The size of this CPU's last-level cache in bytes (Linux's sysfs; 32 MiB where it cannot
/// be read).
pub fn last_level_cache() -> usize {
    use std::sync::OnceLock;
    static SIZE: OnceLock<usize> = OnceLock::new();
    *SIZE.get_or_init(|| {
        (0..8)
            .rev()
            .find_map(|i| {
                let text = std::fs::read_to_string(format!("/sys/devices/system/cpu/cpu0/cache/index{i}/size")).ok()?;
                parse_cache_size(text.trim())
            })
            .unwrap_or(32 << 20)
    })
}

/// A sysfs cache size (`32768K`, `1M`, or bytes) in bytes.
fn parse_cache_size(text: &str) -> Option<usize> {
    let (digits, unit) = match text.as_bytes().last()? {
        b'K' => (&text[..text.len() - 1], 1 << 10),
        b'M' => (&text[..text.len() - 1], 1 << 20),
        b'G' => (&text[..text.len() - 1], 1 << 30),
        _ => (text, 1),
    };
    digits.parse::<usize>().ok().map(|n| n * unit)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cache_sizes_parse_as_sysfs_writes_them() {
        assert_eq!(parse_cache_size("32768K"), Some(32 << 20));
        assert_eq!(parse_cache_size("1M"), Some(1 << 20));
        assert_eq!(parse_cache_size("2G"), Some(2 << 30));
        assert_eq!(parse_cache_size("512"), Some(512));
        assert_eq!(parse_cache_size("K"), None);
        assert_eq!(parse_cache_size(""), None);
        assert_eq!(parse_cache_size("12Q"), None);
    }

    #[test]
    fn small_trees_fit_the_cache_and_large_ones_do_not() {
        assert!(last_level_cache() > 0);
        assert!(fits_cache(1 << 10));
        assert!(!fits_cache(usize::MAX));
    }
}
