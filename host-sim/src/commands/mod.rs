//! The commands host-sim runs, given already validated options.

pub mod demo;
pub mod dense;
pub mod egomotion;
pub mod flow;
pub mod motion;
pub mod stabilize;
pub mod synth;
pub mod synth_sequence;
pub mod track;

use std::fmt;
use std::path::Path;
use std::time::Instant;

use crate::io::{InputError, OutputError};
use crate::Frame;

/// Why a command failed once its options were accepted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CommandError {
    /// An input file or stream is missing, unreadable or malformed.
    Input(InputError),
    /// An output file cannot be written.
    Output(OutputError),
    /// The inputs were read but could not be processed.
    Processing(String),
    /// Flags that are each valid but not together (`--flag: problem`): a bad command line.
    Usage(String),
}

impl fmt::Display for CommandError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CommandError::Input(error) => error.fmt(f),
            CommandError::Output(error) => error.fmt(f),
            CommandError::Processing(problem) | CommandError::Usage(problem) => {
                f.write_str(problem)
            }
        }
    }
}

impl std::error::Error for CommandError {}

impl From<InputError> for CommandError {
    fn from(error: InputError) -> Self {
        CommandError::Input(error)
    }
}

impl From<OutputError> for CommandError {
    fn from(error: OutputError) -> Self {
        CommandError::Output(error)
    }
}

/// Checks that the frames read from `prev_path` and `next_path` have the same size.
pub(crate) fn check_same_size(
    prev_path: &Path,
    next_path: &Path,
    prev: &Frame,
    next: &Frame,
) -> Result<(), InputError> {
    if (prev.width, prev.height) == (next.width, next.height) {
        return Ok(());
    }
    let problem = format!(
        "is {}x{} but {} is {}x{}; the frames must have the same size",
        prev.width,
        prev.height,
        next_path.display(),
        next.width,
        next.height
    );
    Err(InputError::file(prev_path, problem))
}

/// Runs `core` `repeat` times (at least once) and returns its last result with the median
/// duration in seconds.
pub(crate) fn time_core<T>(
    repeat: usize,
    mut core: impl FnMut() -> Result<T, CommandError>,
) -> Result<(T, f64), CommandError> {
    let mut seconds = Vec::with_capacity(repeat.max(1));
    let mut timed_run = |seconds: &mut Vec<f64>| {
        let start = Instant::now();
        let result = core()?;
        seconds.push(start.elapsed().as_secs_f64());
        Ok::<T, CommandError>(result)
    };
    let mut result = timed_run(&mut seconds)?;
    for _ in 1..repeat {
        // The previous result is dropped after the clock stopped.
        result = timed_run(&mut seconds)?;
    }
    Ok((result, median(&mut seconds)))
}

/// The median of `values` (the mean of the two middle ones for an even count); 0 when empty.
pub(crate) fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let middle = values.len() / 2;
    match values.len() {
        0 => 0.0,
        n if n % 2 == 1 => values[middle],
        _ => (values[middle - 1] + values[middle]) / 2.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&mut []), 0.0);
    }

    #[test]
    fn core_runs_the_requested_number_of_times() {
        let mut runs = 0;
        let (last, seconds) = time_core(5, || {
            runs += 1;
            Ok(runs)
        })
        .unwrap();
        assert_eq!((runs, last), (5, 5));
        assert!(seconds >= 0.0);
    }
}
