//! The corpus of bad input files in `tests/bad_inputs/` (OBJ, MTL, PLY, glTF, GLB, gzip and
//! scene files, including the inputs the loader fuzz test found): `phr render` on each must
//! exit non-zero with exactly one `error:` line that names the file (or the file it refers to)
//! and says what `EXPECTED.tsv` says, never panic, and leave no output file behind.

use std::path::PathBuf;
use std::process::Command;

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
    for (name, expected) in cases {
        let out = Command::new(env!("CARGO_BIN_EXE_phr"))
            .args(["render", "--quiet", "--width", "8", "--height", "8", "--spp", "1", "--out"])
            .arg(out_dir.join("out.png"))
            .arg(corpus().join(name))
            .env_remove("RUST_BACKTRACE")
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).replace(&format!("{}/", corpus().display()), "");
        let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
        // The file named is the input, unless the expected text names the file it refers to.
        let names_a_file = expected.split_whitespace().next().is_some_and(|w| w.contains(".") && w.ends_with(':'));
        let ok = !out.status.success()
            && !stderr.contains("panicked")
            && errors.len() == 1
            && errors[0].contains(expected)
            && (names_a_file || errors[0].contains(name))
            && std::fs::read_dir(&out_dir).unwrap().next().is_none();
        if !ok {
            failures.push(format!("{name}: exit {:?}, stderr:\n{stderr}", out.status.code()));
        }
    }
    let _ = std::fs::remove_dir_all(&out_dir);
    assert!(failures.is_empty(), "{} bad inputs mishandled:\n{}", failures.len(), failures.join("\n"));
}
