//! Progress on long runs: one line on stderr, redrawn in place, only when stderr is a
//! terminal, so that scripts and logs see nothing.

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

/// The shortest time between two redraws.
const REDRAW: Duration = Duration::from_millis(100);
/// Width of the bar, characters.
const BAR: usize = 30;

/// A progress line for `label`, counting frames.
#[derive(Debug)]
pub struct Progress {
    label: &'static str,
    total: Option<usize>,
    shown: bool,
    last_draw: Option<Instant>,
}

impl Progress {
    /// A progress line for `total` frames (`None` when unknown, as for a stream); silent
    /// unless stderr is a terminal.
    pub fn new(label: &'static str, total: Option<usize>) -> Self {
        Self {
            label,
            total,
            shown: std::io::stderr().is_terminal(),
            last_draw: None,
        }
    }

    /// Reports that `done` frames are finished.
    pub fn update(&mut self, done: usize) {
        if !self.shown || self.last_draw.is_some_and(|t| t.elapsed() < REDRAW) {
            return;
        }
        self.last_draw = Some(Instant::now());
        let line = render(self.label, done, self.total);
        let _ = write!(std::io::stderr().lock(), "\r{line}");
    }

    /// Clears the line, leaving stderr as it was for the messages that follow.
    pub fn finish(self) {
        if self.shown && self.last_draw.is_some() {
            let _ = write!(std::io::stderr().lock(), "\r\x1b[2K");
        }
    }
}

/// The progress line: a bar and a count when the total is known, a count otherwise.
fn render(label: &str, done: usize, total: Option<usize>) -> String {
    match total {
        Some(total) if total > 0 => {
            let filled = (done.min(total) * BAR) / total;
            format!(
                "{label} [{}{}] {done}/{total} frames",
                "#".repeat(filled),
                " ".repeat(BAR - filled)
            )
        }
        _ => format!("{label}: {done} frames"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_line_shows_a_bar_when_the_total_is_known() {
        assert_eq!(
            render("track", 15, Some(30)),
            format!("track [{}{}] 15/30 frames", "#".repeat(15), " ".repeat(15))
        );
        assert_eq!(render("track", 7, None), "track: 7 frames");
        assert_eq!(render("track", 9, Some(0)), "track: 9 frames");
    }
}
