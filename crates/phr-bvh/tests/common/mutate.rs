//! A small coverage-free mutation fuzzer, shared by the loader and builder fuzz tests.
//!
//! Stable Rust has no coverage-guided fuzzer that builds here (cargo-fuzz needs nightly), so
//! the fuzz tests mutate seed inputs the way AFL's havoc stage does (bit flips, interesting
//! bytes, deletions, duplications, dictionary tokens, splices, truncations), run the target on
//! each under `catch_unwind`, and keep every input that panics. Runs are reproducible from
//! their seed. `PHR_FUZZ_SECONDS=600` turns the short CI smoke into a long run.

use std::time::{Duration, Instant};

pub struct Mutator {
    state: u64,
    dictionary: Vec<Vec<u8>>,
}

impl Mutator {
    pub fn new(seed: u64, dictionary: &[&[u8]]) -> Self {
        Self {
            state: seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1,
            dictionary: dictionary.iter().map(|d| d.to_vec()).collect(),
        }
    }

    pub fn next(&mut self) -> u64 {
        self.state ^= self.state << 13;
        self.state ^= self.state >> 7;
        self.state ^= self.state << 17;
        self.state
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    /// 1 to 8 stacked mutations of `input`, with `other` for splicing.
    pub fn mutate(&mut self, input: &[u8], other: &[u8]) -> Vec<u8> {
        let mut out = input.to_vec();
        for _ in 0..1 + self.below(8) {
            self.mutate_once(&mut out, other);
        }
        out
    }

    fn mutate_once(&mut self, out: &mut Vec<u8>, other: &[u8]) {
        const INTERESTING: &[u8] = b"\x00\xff\x7f\x80-9 \n/.,:{}[]\"e\r\t";
        let len = out.len();
        match self.below(9) {
            0 if len > 0 => {
                let i = self.below(len);
                out[i] ^= 1 << self.below(8);
            }
            1 if len > 0 => {
                let i = self.below(len);
                out[i] = INTERESTING[self.below(INTERESTING.len())];
            }
            2 if len > 0 => {
                let a = self.below(len);
                let b = (a + 1 + self.below(32)).min(len);
                out.drain(a..b);
            }
            3 if len > 0 => {
                let a = self.below(len);
                let b = (a + 1 + self.below(64)).min(len);
                let chunk = out[a..b].to_vec();
                let at = self.below(len + 1);
                out.splice(at..at, chunk);
            }
            4 | 5 if !self.dictionary.is_empty() => {
                let pick = self.below(self.dictionary.len());
                let token = self.dictionary[pick].clone();
                let at = self.below(len + 1);
                if self.below(2) == 0 || at == len {
                    out.splice(at..at, token);
                } else {
                    let end = (at + token.len()).min(len);
                    out.splice(at..end, token);
                }
            }
            6 if !other.is_empty() => {
                let at = self.below(len + 1);
                let a = self.below(other.len());
                let b = (a + 1 + self.below(256)).min(other.len());
                out.truncate(at);
                out.extend_from_slice(&other[a..b]);
            }
            7 if len > 0 => out.truncate(self.below(len)),
            _ => {
                // A number in text replaced by an extreme one.
                let extremes: [&[u8]; 8] =
                    [b"4294967295", b"-1", b"0", b"1e39", b"nan", b"-inf", b"18446744073709551616", b"1e-45"];
                let token = extremes[self.below(extremes.len())];
                let at = self.below(len + 1);
                out.splice(at..at, token.iter().copied());
            }
        }
    }
}

/// How long a fuzz test runs: `PHR_FUZZ_SECONDS`, else the given smoke budget.
pub fn budget(smoke: Duration) -> Duration {
    std::env::var("PHR_FUZZ_SECONDS").ok().and_then(|s| s.parse().ok()).map_or(smoke, Duration::from_secs)
}

/// The seed of a run: `PHR_FUZZ_SEED`, else a fixed one (CI smoke runs are reproducible),
/// else with `PHR_FUZZ_SECONDS` set, the clock (long runs explore anew each time).
pub fn seed() -> u64 {
    if let Some(s) = std::env::var("PHR_FUZZ_SEED").ok().and_then(|s| s.parse().ok()) {
        return s;
    }
    if std::env::var_os("PHR_FUZZ_SECONDS").is_some() {
        return std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(1, |d| d.as_nanos() as u64);
    }
    0x5eed
}

/// Runs `target` on mutations of `seeds` until `budget` is spent; returns the number of runs
/// and the inputs that panicked (already written to `crash_dir` as `NAME-N.bin`).
pub fn fuzz(
    name: &str,
    seeds: &[Vec<u8>],
    dictionary: &[&[u8]],
    budget: Duration,
    crash_dir: &std::path::Path,
    target: impl Fn(&[u8]) + std::panic::RefUnwindSafe,
) -> (usize, Vec<std::path::PathBuf>) {
    let seed = seed();
    eprintln!("fuzz {name}: seed {seed}, {} s (PHR_FUZZ_SEED / PHR_FUZZ_SECONDS to change)", budget.as_secs_f32());
    let mut m = Mutator::new(seed, dictionary);
    let start = Instant::now();
    let mut crashes = Vec::new();
    let mut runs = 0;
    // Panic messages of expected crashes would flood the log; the inputs are kept instead.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    for s in seeds {
        if std::panic::catch_unwind(|| target(s)).is_err() {
            crashes.push(save(crash_dir, name, crashes.len(), s));
        }
    }
    while start.elapsed() < budget && crashes.len() < 20 {
        let (a, b) = (m.below(seeds.len()), m.below(seeds.len()));
        let input = m.mutate(&seeds[a], &seeds[b]);
        runs += 1;
        if std::panic::catch_unwind(|| target(&input)).is_err() {
            crashes.push(save(crash_dir, name, crashes.len(), &input));
        }
    }
    std::panic::set_hook(hook);
    eprintln!("fuzz {name}: {runs} inputs, {} crashes", crashes.len());
    (runs, crashes)
}

fn save(dir: &std::path::Path, name: &str, n: usize, input: &[u8]) -> std::path::PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(format!("{name}-{n}.bin"));
    std::fs::write(&path, input).unwrap();
    path
}
