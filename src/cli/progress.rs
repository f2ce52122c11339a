//! Progress of long commands on stderr: an `indicatif` bar while solving and
//! a one-line summary at the end, **only when stderr is a terminal**
//! (`std::io::IsTerminal`). Otherwise nothing is drawn or printed: scripts
//! and tests parse stdout and stderr, and a command that succeeds leaves
//! stderr empty. There is deliberately no environment variable to force
//! either way.
//!
//! The work is cut into `stages` (e.g. one per wavelength and phase), each
//! worth [`STEPS`] positions of the bar; within a stage the solver reports an
//! approximate fraction done (`solver::OnOrders` through
//! `solver::accuracy`), which is not monotone across the levels of a
//! tolerance search, so the bar only moves forward.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// Bar positions per stage.
pub const STEPS: u64 = 1000;

/// A progress bar on stderr, or nothing when stderr is not a terminal.
pub struct Progress {
    bar: Option<ProgressBar>,
    /// Furthest position reported (the bar never moves back).
    furthest: AtomicU64,
    /// The stage whose message is shown (`usize::MAX`: none yet).
    current: AtomicUsize,
}

impl Progress {
    /// A bar over `stages` stages if stderr is a terminal and there is work.
    pub fn new(stages: usize) -> Self {
        let tty = std::io::stderr().is_terminal();
        Self::with_terminal(tty, stages)
    }

    fn with_terminal(tty: bool, stages: usize) -> Self {
        let bar = (tty && stages > 0).then(|| {
            let bar = ProgressBar::with_draw_target(
                Some(stages as u64 * STEPS),
                ProgressDrawTarget::stderr(),
            );
            bar.set_style(
                ProgressStyle::with_template(
                    "polbrdf: [{elapsed_precise}] {wide_bar} {percent:>3}% {msg}",
                )
                .expect("progress template"),
            );
            bar
        });
        Self {
            bar,
            furthest: AtomicU64::new(0),
            current: AtomicUsize::new(usize::MAX),
        }
    }

    /// Whether anything is shown (stderr is a terminal).
    pub fn is_shown(&self) -> bool {
        self.bar.is_some()
    }

    /// Stage `k` started: say what it does (repeated calls for the same
    /// stage are cheap: the message is set once).
    pub fn stage(&self, k: usize, message: &str) {
        if let Some(bar) = &self.bar
            && self.current.swap(k, Ordering::Relaxed) != k
        {
            bar.set_message(message.to_string());
            self.advance(k as u64 * STEPS);
        }
    }

    /// A sink for the fraction done within stage `k` (for the solver's
    /// progress callbacks; called on the solving thread).
    pub fn within(&self, k: usize) -> impl Fn(f64) + Sync + '_ {
        move |x: f64| {
            if self.bar.is_some() {
                let x = if x.is_finite() {
                    x.clamp(0.0, 1.0)
                } else {
                    0.0
                };
                self.advance(k as u64 * STEPS + (x * STEPS as f64) as u64);
            }
        }
    }

    fn advance(&self, position: u64) {
        if let Some(bar) = &self.bar {
            let p = self.furthest.fetch_max(position, Ordering::Relaxed);
            bar.set_position(p.max(position));
        }
    }

    /// Clear the bar and, when shown, print `summary` on stderr.
    pub fn finish(&self, summary: Option<String>) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
            if let Some(s) = summary {
                eprintln!("{s}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nothing_is_shown_without_a_terminal_or_work() {
        let p = Progress::with_terminal(false, 4);
        assert!(!p.is_shown());
        p.stage(1, "x");
        p.within(1)(0.5);
        p.finish(Some("summary".into()));
        assert!(!Progress::with_terminal(true, 0).is_shown());
    }

    #[test]
    fn the_bar_only_moves_forward() {
        let p = Progress::with_terminal(true, 3);
        let bar = p.bar.as_ref().unwrap().clone();
        p.within(1)(0.5);
        assert_eq!(bar.position(), STEPS + STEPS / 2);
        // A tolerance search restarting its estimate, and garbage.
        p.within(1)(0.2);
        p.within(1)(f64::NAN);
        assert_eq!(bar.position(), STEPS + STEPS / 2);
        p.stage(2, "next");
        assert_eq!(bar.position(), 2 * STEPS);
        p.within(2)(7.0);
        assert_eq!(bar.position(), 3 * STEPS);
        p.finish(None);
    }
}
