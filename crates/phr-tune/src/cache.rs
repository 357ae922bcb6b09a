//! The normalisation maxima of the thesis's objective (`max b`, `max c` over the search box),
//! cached in a JSON file so that a later optimisation of the same scene and box skips the two
//! normalisation builds.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Maxima {
    pub max_build_cost: f64,
    pub max_sah_cost: f64,
}

/// Reads the maxima stored under `key` (missing or unreadable file: none).
pub fn load(path: &Path, key: &str) -> Option<Maxima> {
    let text = std::fs::read_to_string(path).ok()?;
    let map: BTreeMap<String, Maxima> = serde_json::from_str(&text).ok()?;
    map.get(key).copied()
}

/// Stores `maxima` under `key`, keeping the other entries.
pub fn store(path: &Path, key: &str, maxima: Maxima) -> std::io::Result<()> {
    let mut map: BTreeMap<String, Maxima> =
        std::fs::read_to_string(path).ok().and_then(|t| serde_json::from_str(&t).ok()).unwrap_or_default();
    map.insert(key.to_string(), maxima);
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    let tmp = path.with_extension("json.partial");
    std::fs::write(&tmp, serde_json::to_string_pretty(&map).map_err(std::io::Error::other)?)?;
    std::fs::rename(tmp, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_other_keys() {
        let dir = std::env::temp_dir().join(format!("phr-tune-cache-{}", std::process::id()));
        let path = dir.join("maxima.json");
        let a = Maxima { max_build_cost: 1.0, max_sah_cost: 2.0 };
        let b = Maxima { max_build_cost: 3.0, max_sah_cost: 4.0 };
        assert_eq!(load(&path, "a"), None);
        store(&path, "a", a).unwrap();
        store(&path, "b", b).unwrap();
        assert_eq!(load(&path, "a"), Some(a));
        assert_eq!(load(&path, "b"), Some(b));
        std::fs::remove_dir_all(dir).unwrap();
    }
}
