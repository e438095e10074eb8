//! Progress on long runs, drawn by indicatif on stderr, only when stderr is a terminal, so that
//! scripts and logs see nothing.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A progress bar for a command, counting frames.
#[derive(Debug)]
pub struct Progress {
    bar: ProgressBar,
}

impl Progress {
    /// A bar for `total` frames (a spinner with a count when `None`, as for a stream); hidden
    /// unless stderr is a terminal.
    pub fn new(label: &'static str, total: Option<usize>) -> Self {
        let bar = match std::io::stderr().is_terminal() {
            false => ProgressBar::hidden(),
            true => {
                let bar = ProgressBar::with_draw_target(
                    total.map(|t| t as u64),
                    ProgressDrawTarget::stderr(),
                );
                let template = match total {
                    Some(_) => {
                        "{prefix} [{bar:30}] {pos}/{len} frames ({elapsed} so far, {eta} left)"
                    }
                    None => "{prefix} {spinner} {pos} frames ({elapsed} so far)",
                };
                let style = ProgressStyle::with_template(template)
                    .expect("a valid template")
                    .progress_chars("#> ");
                bar.with_style(style).with_prefix(label)
            }
        };
        Self { bar }
    }

    /// Reports that `done` frames are finished.
    pub fn update(&mut self, done: usize) {
        self.bar.set_position(done as u64);
    }

    /// Clears the bar, leaving stderr as it was for the messages that follow.
    pub fn finish(self) {
        self.bar.finish_and_clear();
    }
}
