//! Progress bars of long runs, on stderr (indicatif), one look for both CLIs:
//! `   calibrate [=========>          ] 1200/4400 00:00:03 eta 8s`.
//!
//! indicatif draws only when stderr is a terminal, so logs and pipes get no bar; `--quiet`
//! hides it on a terminal too. Two kinds: [`steps`] counts steps of a known number (points of
//! a sweep, cycles of a calibration), [`fraction`] shows a share of a duration (a recording
//! on the board's clock), set with [`set_fraction`].

pub use indicatif::ProgressBar;
use indicatif::ProgressStyle;

/// Positions of a [`fraction`] bar per whole.
const FRACTION_STEPS: u64 = 1000;

fn bar(len: u64, quiet: bool, what: &str, counts: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let template = format!("{{msg:>12}} [{{bar:40}}] {counts} {{elapsed_precise}} eta {{eta}}");
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template(&template)
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// A bar of `len` steps named `what` (hidden when `quiet`).
pub fn steps(len: u64, quiet: bool, what: &str) -> ProgressBar {
    bar(len, quiet, what, "{pos}/{len}")
}

/// A bar of a share of the whole, in percent, named `what` (hidden when `quiet`).
pub fn fraction(quiet: bool, what: &str) -> ProgressBar {
    bar(FRACTION_STEPS, quiet, what, "{percent:>3} %")
}

/// Sets a [`fraction`] bar to `done` (0 to 1) of the whole.
pub fn set_fraction(bar: &ProgressBar, done: f64) {
    bar.set_position((done.clamp(0.0, 1.0) * FRACTION_STEPS as f64) as u64);
}
