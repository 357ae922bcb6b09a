//! Progress bars of the long commands, in one style, and as the benchmark library's
//! [`phr_bench::Progress`].

use indicatif::{ProgressBar, ProgressStyle};

/// A bar of `len` steps: `[=====>   ] 3/7 message (eta …)`.
pub fn bar(len: u64) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{bar:30}] {pos}/{len} {msg} (elapsed {elapsed}, eta {eta})")
            .expect("template")
            .progress_chars("=> "),
    );
    bar
}

/// The benchmark library's progress on a bar: the status as its message, notes printed above
/// it (also when it is hidden, as in a pipe).
pub struct Bar<'a>(pub &'a ProgressBar);

impl phr_bench::Progress for Bar<'_> {
    fn status(&self, message: String) {
        self.0.set_message(message);
    }

    fn note(&self, message: String) {
        self.0.suspend(|| eprintln!("{message}"));
    }

    fn advance(&self) {
        self.0.inc(1);
    }
}
