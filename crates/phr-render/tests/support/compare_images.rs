//! The team's image comparison tool (`shared/reference/tools/compare_images.py`), run from
//! tests: the CPU's reference tests and the GPU's (`crates/phr-gpu/tests`) include this file.
// Each test crate that includes it uses part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// `shared/`, next to the repository.
pub fn shared() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared"))
}

/// A Python that can run the comparison tool: `python3` if it imports numpy and OpenEXR, else
/// the one of a virtual environment made for it under the target folder (the first test that
/// needs it creates it with `python3 -m venv` and pip; later runs reuse it). Panics, saying
/// what to install, when neither works: the comparison is never skipped.
pub fn python() -> &'static Path {
    static PYTHON: OnceLock<PathBuf> = OnceLock::new();
    PYTHON.get_or_init(|| {
        let ready = |python: &Path| {
            Command::new(python).args(["-c", "import numpy, OpenEXR"]).output().is_ok_and(|o| o.status.success())
        };
        let system = PathBuf::from("python3");
        if ready(&system) {
            return system;
        }
        let venv = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("compare-images-venv");
        let venv_python = venv.join("bin/python3");
        if !ready(&venv_python) {
            let run = |cmd: &mut Command| cmd.status().is_ok_and(|s| s.success());
            let made = run(Command::new("python3").arg("-m").arg("venv").arg(&venv))
                && run(Command::new(&venv_python).args(["-m", "pip", "install", "--quiet", "numpy", "OpenEXR"]));
            assert!(
                made && ready(&venv_python),
                "the image comparison needs Python 3 with numpy and OpenEXR, and making a virtual environment \
                 with them in {} failed: install them (`python3 -m pip install numpy OpenEXR`) or the venv module",
                venv.display()
            );
        }
        venv_python
    })
}

/// The noise the comparison expects of the image under test.
pub enum Noise<'a> {
    /// The mean of this many samples of the reference's own estimator.
    Spp(u32),
    /// This image of the variance of its mean.
    Variance(&'a Path),
}

/// Runs `compare_images.py TEST REFERENCE --check`: whether it passed, and what it printed.
pub fn compare(test: &Path, reference: &Path, noise: Noise) -> (bool, String) {
    let mut compare = Command::new(python());
    compare.arg(shared().join("reference/tools/compare_images.py")).arg(test).arg(reference).arg("--check");
    match noise {
        Noise::Spp(spp) => compare.args(["--test-spp", &spp.to_string()]),
        Noise::Variance(path) => compare.arg("--test-var").arg(path),
    };
    let result = compare.output().expect("cannot run the comparison tool");
    let text = format!("{}{}", String::from_utf8_lossy(&result.stdout), String::from_utf8_lossy(&result.stderr));
    (result.status.success() && text.contains("PASS"), text)
}
