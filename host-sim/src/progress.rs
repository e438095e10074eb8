//! Progress of long runs on stderr, shown only when stderr is a terminal: scripts and pipes
//! get nothing but the final error line, if any.

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

/// Least time between two updates, so printing never costs more than the work.
const UPDATE_EVERY: Duration = Duration::from_millis(200);

/// A one-line counter of processed frames, redrawn in place.
#[derive(Debug)]
pub struct Progress {
    label: &'static str,
    visible: bool,
    last_update: Option<Instant>,
}

impl Progress {
    /// A counter reading "`label` N", visible when stderr is a terminal.
    pub fn new(label: &'static str) -> Self {
        Self {
            label,
            visible: std::io::stderr().is_terminal(),
            last_update: None,
        }
    }

    /// Reports that `frames` frames are done.
    pub fn frames_done(&mut self, frames: usize) {
        if !self.visible || self.last_update.is_some_and(|t| t.elapsed() < UPDATE_EVERY) {
            return;
        }
        self.last_update = Some(Instant::now());
        let _ = write!(std::io::stderr(), "\r{} {frames}", self.label);
    }

    /// Erases the counter, so the next line on stderr starts clean.
    pub fn finish(self) {
        if self.visible && self.last_update.is_some() {
            let _ = write!(std::io::stderr(), "\r\x1b[2K");
        }
    }
}
