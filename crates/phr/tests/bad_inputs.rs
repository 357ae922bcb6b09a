//! The corpus of bad input files in `tests/bad_inputs/` (OBJ, MTL, PLY, glTF, GLB, gzip and
//! scene files, including the inputs the loader fuzz test found): `phr render` on each must
//! exit non-zero with exactly one `error:` line that names the file (or the file it refers to)
//! and says what `EXPECTED.tsv` says, never panic, stay within [`MAX_RSS_MIB`] of memory, and
//! leave no output file behind.

use std::os::unix::process::ExitStatusExt;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};

/// The peak resident memory allowed for any case: a bad file is refused before its claims
/// (10¹² faces, 20 GiB of gzip) cost memory. The cases peak at about 6 MiB.
const MAX_RSS_MIB: i64 = 64;

/// Waits for `child`; returns its exit status and its peak resident set in KiB (`wait4`'s
/// `ru_maxrss`, the child's own).
fn wait_with_peak_rss(child: Child) -> (ExitStatus, i64) {
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: `rusage` is plain data, valid when zeroed; `wait4` writes both out-parameters
    // and reaps the child, which `Child` leaves alone when dropped.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let reaped = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(reaped, pid, "wait4: {}", std::io::Error::last_os_error());
    (ExitStatus::from_raw(status), usage.ru_maxrss)
}

fn corpus() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/bad_inputs"))
}

/// Files in the folder that are not inputs themselves.
const SUPPORT: &[&str] = &["EXPECTED.tsv", "bad.mtl"];

#[test]
fn every_bad_input_gets_one_clear_error() {
    let manifest = std::fs::read_to_string(corpus().join("EXPECTED.tsv")).unwrap();
    let cases: Vec<(&str, &str)> = manifest
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| l.split_once('\t').unwrap_or_else(|| panic!("EXPECTED.tsv: no tab in {l:?}")))
        .collect();
    assert!(cases.len() >= 40, "only {} cases", cases.len());
    // Every file of the corpus is a case: a new bad file cannot sit there untested.
    let mut files: Vec<String> = std::fs::read_dir(corpus())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|f| !SUPPORT.contains(&f.as_str()))
        .collect();
    files.sort();
    let mut listed: Vec<String> = cases.iter().map(|(f, _)| f.to_string()).collect();
    listed.sort();
    assert_eq!(files, listed, "the corpus and EXPECTED.tsv disagree");

    let out_dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("bad-inputs-{}", std::process::id()));
    std::fs::create_dir_all(&out_dir).unwrap();
    let mut failures = Vec::new();
    let mut peak_mib = 0;
    for (name, expected) in cases {
        let stderr_path = out_dir.with_extension("stderr");
        let child = Command::new(env!("CARGO_BIN_EXE_phr"))
            .args(["render", "--quiet", "--width", "8", "--height", "8", "--spp", "1", "--out"])
            .arg(out_dir.join("out.png"))
            .arg(corpus().join(name))
            .env_remove("RUST_BACKTRACE")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&stderr_path).unwrap())
            .spawn()
            .unwrap();
        let (status, peak_kib) = wait_with_peak_rss(child);
        peak_mib = peak_mib.max(peak_kib / 1024);
        let stderr = std::fs::read_to_string(&stderr_path).unwrap().replace(&format!("{}/", corpus().display()), "");
        let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
        // The file named is the input, unless the expected text names the file it refers to.
        let names_a_file = expected.split_whitespace().next().is_some_and(|w| w.contains(".") && w.ends_with(':'));
        let ok = !status.success()
            && peak_kib <= MAX_RSS_MIB * 1024
            && !stderr.contains("panicked")
            && errors.len() == 1
            && errors[0].contains(expected)
            && (names_a_file || errors[0].contains(name))
            && std::fs::read_dir(&out_dir).unwrap().next().is_none();
        if !ok {
            let peak = peak_kib / 1024;
            failures.push(format!("{name}: exit {:?}, peak {peak} MiB, stderr:\n{stderr}", status.code()));
        }
    }
    let _ = std::fs::remove_dir_all(&out_dir);
    let _ = std::fs::remove_file(out_dir.with_extension("stderr"));
    eprintln!("peak resident memory of any case: {peak_mib} MiB");
    assert!(failures.is_empty(), "{} bad inputs mishandled:\n{}", failures.len(), failures.join("\n"));
}
