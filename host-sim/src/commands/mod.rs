//! The commands host-sim runs, given already validated options.

pub mod egomotion;
pub mod flow;
pub mod stabilize;
pub mod synth;
pub mod synth_sequence;

use std::fmt;

use crate::io::{InputError, OutputError};

/// Why a command failed once its options were accepted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CommandError {
    /// An input file or stream is missing, unreadable or malformed.
    Input(InputError),
    /// An output file cannot be written.
    Output(OutputError),
    /// The inputs were read but could not be processed.
    Processing(String),
}

impl fmt::Display for CommandError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CommandError::Input(error) => error.fmt(f),
            CommandError::Output(error) => error.fmt(f),
            CommandError::Processing(problem) => f.write_str(problem),
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
