//! Runs the Python package's tests (`tests/python`, pytest) as part of `cargo test`: makes a
//! virtual environment under the target folder (reused by later runs), installs pytest, numpy
//! and maturin into it, installs this package with `pip install` as a user would, builds the
//! `phr` command line the render tests compare with, and runs pytest. Fails with pytest's
//! output if any Python test fails, and says what to install if the environment cannot be
//! made.
//!
//! trimesh, matplotlib and embreex (the example and the hits against Embree's) are installed
//! too; where they cannot be, their tests are reported skipped with the reason, and where
//! they are, a skipped test fails the run.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn workspace_dir() -> PathBuf {
    crate_dir().join("../..").canonicalize().expect("the workspace folder")
}

fn output(command: &mut Command) -> Output {
    let shown = format!("{command:?}");
    command.output().unwrap_or_else(|e| panic!("cannot run {shown}: {e}"))
}

/// The `phr` binary `cargo build --release` makes (the target folder is the test's
/// temporary folder's parent, wherever `CARGO_TARGET_DIR` puts it).
fn phr_binary() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).parent().expect("the target folder").join("release/phr")
}

/// Runs `command`, panicking with its output if it fails.
fn run(command: &mut Command, what: &str) {
    let shown = format!("{command:?}");
    let out = output(command);
    assert!(
        out.status.success(),
        "{what} failed: {shown}\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The virtual environment's `bin` folder, with pytest, numpy and maturin, and whether the
/// optional packages (trimesh, matplotlib, embreex) installed too.
fn venv() -> (PathBuf, bool) {
    let venv = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("phr-py-venv");
    let python = venv.join("bin/python3");
    if !python.exists() {
        run(
            Command::new("python3").args(["-m", "venv"]).arg(&venv),
            "making a virtual environment (needs python3 with its venv module)",
        );
    }
    run(
        Command::new(&python).args(["-m", "pip", "install", "--quiet", "maturin>=1.16,<2", "numpy", "pytest"]),
        "installing maturin, numpy and pytest from PyPI",
    );
    let optional = ["trimesh", "matplotlib", "embreex"];
    let out = output(Command::new(&python).args(["-m", "pip", "install", "--quiet"]).args(optional));
    if !out.status.success() {
        eprintln!(
            "warning: could not install {optional:?}; their tests will be skipped:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    (venv.join("bin"), out.status.success())
}

/// `PATH` with `dir` first (maturin's build backend runs the `maturin` it finds there).
fn path_with(dir: &Path) -> std::ffi::OsString {
    let mut paths = vec![dir.to_path_buf()];
    paths.extend(std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()));
    std::env::join_paths(paths).expect("a PATH")
}

#[test]
fn python_package_tests_pass() {
    let root = workspace_dir();
    let (bin, optional_installed) = venv();
    let path = path_with(&bin);
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    run(
        Command::new(&cargo).current_dir(&root).args(["build", "--release", "--quiet", "-p", "phr"]),
        "building the phr command line",
    );
    run(
        Command::new(bin.join("python3"))
            .current_dir(&root)
            .env("PATH", &path)
            .args(["-m", "pip", "install", "--quiet", "--no-build-isolation", "--force-reinstall", "--no-deps"])
            .arg(crate_dir()),
        "pip install crates/phr-py",
    );
    let out = output(
        Command::new(bin.join("python3"))
            .current_dir(&root)
            .env("PATH", &path)
            .env("PHR_BIN", phr_binary())
            .env("PHR_SHARED", root.join("../shared"))
            .args(["-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider"])
            .arg(crate_dir().join("tests/python")),
    );
    let report = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    println!("{report}");
    assert!(out.status.success(), "the Python tests failed:\n{report}");
    // With every package installed nothing may be skipped (a skip would hide a check).
    let summary = report.lines().rev().find(|l| l.contains(" passed")).unwrap_or_default();
    assert!(!optional_installed || !summary.contains("skipped"), "Python tests were skipped:\n{report}");
}
