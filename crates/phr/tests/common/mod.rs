//! Helpers shared by the CLI tests: a temporary folder, a `phr` runner with a time limit, a
//! CSV table read by header name, image readers (PNG, PFM) and a scan for NaN and infinity.

// Each test file uses its own part of this module.
#![allow(dead_code)]

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A fresh, empty folder for one test; removed when dropped.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("phr-test-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    pub fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    pub fn write(&self, name: &str, bytes: impl AsRef<[u8]>) {
        std::fs::write(self.0.join(name), bytes).unwrap();
    }

    pub fn read(&self, name: &str) -> String {
        let path = self.0.join(name);
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    }

    /// Names of the files in the folder.
    pub fn files(&self) -> BTreeSet<String> {
        files_in(&self.0)
    }
}

/// Names of the files in a folder.
pub fn files_in(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect()
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

pub struct Output {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
    pub elapsed: Duration,
}

/// Runs `phr args...` in `dir`, killing it after a minute (a hang is a failure, not a stuck test).
pub fn phr(dir: &Path, args: &[&str]) -> Output {
    phr_within(dir, args, Duration::from_secs(60))
}

/// Runs `phr args...` in `dir`, killing it after `limit`.
pub fn phr_within(dir: &Path, args: &[&str], limit: Duration) -> Output {
    let start = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_phr"))
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_BACKTRACE")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("cannot start phr");
    // Drain the pipes while waiting: a full pipe would block the child.
    let stdout = drain(child.stdout.take().unwrap());
    let stderr = drain(child.stderr.take().unwrap());
    let deadline = start + limit;
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            child.kill().unwrap();
            let _ = child.wait();
            panic!("phr {args:?} did not finish within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let status = child.wait().unwrap();
    Output {
        code: status.code(),
        stdout: stdout.join().unwrap(),
        stderr: stderr.join().unwrap(),
        elapsed: start.elapsed(),
    }
}

fn drain(mut pipe: impl std::io::Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut bytes = Vec::new();
        let _ = pipe.read_to_end(&mut bytes);
        String::from_utf8_lossy(&bytes).into_owned()
    })
}

/// Runs `phr args...` in `dir` within `limit` and checks it succeeded; returns its output.
pub fn phr_ok(dir: &Path, args: &[&str], limit: Duration) -> Output {
    let out = phr_within(dir, args, limit);
    assert_eq!(out.code, Some(0), "phr {args:?}\nstdout:\n{}\nstderr:\n{}", out.stdout, out.stderr);
    out
}

/// A CSV file read by header name (no quoting: the CLI writes none).
pub struct Table {
    pub name: String,
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl Table {
    pub fn read(path: &Path) -> Self {
        let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        Self::parse(&path.display().to_string(), &text)
    }

    pub fn parse(name: &str, text: &str) -> Self {
        let mut lines = text.lines();
        let header: Vec<String> =
            lines.next().unwrap_or_else(|| panic!("{name} is empty")).split(',').map(String::from).collect();
        let rows: Vec<Vec<String>> = lines.map(|l| l.split(',').map(String::from).collect()).collect();
        for (i, r) in rows.iter().enumerate() {
            assert_eq!(r.len(), header.len(), "{name}: row {i} has {} fields, the header {}", r.len(), header.len());
        }
        Self { name: name.into(), header, rows }
    }

    pub fn col(&self, column: &str) -> usize {
        self.header.iter().position(|h| h == column).unwrap_or_else(|| panic!("{}: no column {column}", self.name))
    }

    pub fn str(&self, row: usize, column: &str) -> &str {
        &self.rows[row][self.col(column)]
    }

    /// A finite number (a NaN, an infinity or an empty field fails).
    pub fn num(&self, row: usize, column: &str) -> f64 {
        let s = self.str(row, column);
        let v: f64 = s.parse().unwrap_or_else(|_| panic!("{}: row {row}, {column} = {s:?} is not a number", self.name));
        assert!(v.is_finite(), "{}: row {row}, {column} = {s}", self.name);
        v
    }

    /// `None` for an empty field, else the finite number.
    pub fn opt(&self, row: usize, column: &str) -> Option<f64> {
        (!self.str(row, column).is_empty()).then(|| self.num(row, column))
    }

    /// A whole column of finite numbers.
    pub fn nums(&self, column: &str) -> Vec<f64> {
        (0..self.rows.len()).map(|r| self.num(r, column)).collect()
    }
}

/// Fails if `text` holds a NaN or an infinity as Rust, C or JSON-ish writers spell them.
pub fn assert_no_nan_or_inf(name: &str, text: &str) {
    for (line_no, line) in text.lines().enumerate() {
        for token in line.split(|c: char| !c.is_ascii_alphanumeric()) {
            let t = token.to_ascii_lowercase();
            assert!(!matches!(t.as_str(), "nan" | "inf" | "infinity"), "{name}:{}: {token} in {line:?}", line_no + 1);
        }
    }
}

/// An image as width, height and row-major RGB floats from the top row.
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<f32>,
}

impl Image {
    /// A PNG, in 8-bit units (0 to 255).
    pub fn png(path: &Path) -> Self {
        let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8();
        Self { width: img.width(), height: img.height(), rgb: img.into_raw().into_iter().map(f32::from).collect() }
    }

    /// A little-endian colour PFM (`PF`, negative scale), as `phr` writes it: bottom row first.
    pub fn pfm(path: &Path) -> Self {
        let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut header = Vec::new();
        let mut at = 0;
        while header.len() < 4 {
            let end = at + bytes[at..].iter().position(|b| b.is_ascii_whitespace()).expect("PFM header");
            if end > at {
                header.push(std::str::from_utf8(&bytes[at..end]).unwrap().to_string());
            }
            at = end + 1;
        }
        assert_eq!(header[0], "PF", "{}: not a colour PFM", path.display());
        let (width, height): (u32, u32) = (header[1].parse().unwrap(), header[2].parse().unwrap());
        assert!(header[3].parse::<f32>().unwrap() < 0.0, "{}: not little-endian", path.display());
        let floats: Vec<f32> = bytes[at..].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
        let row = 3 * width as usize;
        assert_eq!(floats.len(), row * height as usize, "{}: size", path.display());
        let rgb = floats.chunks_exact(row).rev().flatten().copied().collect();
        Self { width, height, rgb }
    }

    pub fn mean(&self) -> f64 {
        self.rgb.iter().map(|&v| f64::from(v)).sum::<f64>() / self.rgb.len() as f64
    }
}

pub fn mean_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len() as f32
}

/// A file of the repository, from its root.
pub fn repo_path(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(path)
}
