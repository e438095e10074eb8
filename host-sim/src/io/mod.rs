//! Files in and out: single images, frame sequences (directories, y4m and, through ffmpeg, any
//! video file), CSV, JSON, and atomic output files.
//!
//! Every failure is a value that names the file, and the frame or CSV cell when there is one, so
//! the command line can report it as a single line.

pub mod atomic;
pub mod csv;
pub mod images;
pub mod jpeg;
pub mod json;
pub mod progress;
pub mod sequence;
pub mod video;
pub mod y4m;

use std::fmt;
use std::io;
use std::path::Path;

pub use atomic::AtomicFile;
pub use progress::Progress;
pub use sequence::FrameSource;

/// How inputs read from standard input are named in messages.
pub const STDIN_NAME: &str = "standard input";

/// Where in an input a problem is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Place {
    /// A frame of a sequence, counted from 0.
    Frame(usize),
    /// A line of a text file, counted from 1.
    Line(usize),
    /// A field of a CSV record: line counted from 1, column counted from 1, and its header name.
    Cell {
        /// Line, from 1.
        line: usize,
        /// Column, from 1.
        column: usize,
        /// The column's name in the header.
        name: String,
    },
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Place::Frame(index) => write!(f, "frame {index}"),
            Place::Line(line) => write!(f, "line {line}"),
            Place::Cell { line, column, name } => {
                write!(f, "line {line}, column {column} ({name})")
            }
        }
    }
}

/// A problem with an input file or stream.
///
/// Displays as `input: place: problem`, for example
/// `points.csv: line 3, column 2 (y): "abc" is not a number`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InputError {
    /// The input as the user named it (a path, or [`STDIN_NAME`]).
    pub input: String,
    /// The frame, line or cell, when the problem is in one.
    pub place: Option<Place>,
    /// What is wrong.
    pub problem: String,
}

impl InputError {
    /// A problem with `input` as a whole.
    pub fn new(input: impl Into<String>, problem: impl Into<String>) -> Self {
        Self {
            input: input.into(),
            place: None,
            problem: problem.into(),
        }
    }

    /// A problem with the file at `path` as a whole.
    pub fn file(path: &Path, problem: impl Into<String>) -> Self {
        Self::new(path.display().to_string(), problem)
    }

    /// The same problem, located at `place`.
    pub fn at(mut self, place: Place) -> Self {
        self.place = Some(place);
        self
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.place {
            Some(place) => write!(f, "{}: {}: {}", self.input, place, self.problem),
            None => write!(f, "{}: {}", self.input, self.problem),
        }
    }
}

impl std::error::Error for InputError {}

/// A problem writing an output file. Displays as `path: problem`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OutputError {
    /// The output path as the user named it.
    pub output: String,
    /// What went wrong.
    pub problem: String,
}

impl OutputError {
    /// A problem writing `path`.
    pub fn new(path: &Path, problem: impl Into<String>) -> Self {
        Self {
            output: path.display().to_string(),
            problem: problem.into(),
        }
    }
}

impl fmt::Display for OutputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.output, self.problem)
    }
}

impl std::error::Error for OutputError {}

/// A short, lower-case description of an I/O error, without the `(os error N)` suffix that
/// means nothing to users.
pub fn describe_io_error(error: &io::Error) -> String {
    match error.kind() {
        io::ErrorKind::NotFound => "no such file or directory".to_owned(),
        io::ErrorKind::PermissionDenied => "permission denied".to_owned(),
        io::ErrorKind::IsADirectory => "is a directory".to_owned(),
        io::ErrorKind::NotADirectory => "a parent of it is not a directory".to_owned(),
        io::ErrorKind::AlreadyExists => "already exists".to_owned(),
        io::ErrorKind::StorageFull => "no space left on the device".to_owned(),
        io::ErrorKind::ReadOnlyFilesystem => "the file system is read-only".to_owned(),
        io::ErrorKind::UnexpectedEof => "ends unexpectedly".to_owned(),
        _ => {
            let text = error.to_string();
            match text.find(" (os error") {
                Some(end) => text[..end].to_lowercase(),
                None => text,
            }
        }
    }
}

/// Creates the output directory `dir` and its parents, if missing.
pub fn create_output_dir(dir: &Path) -> Result<(), OutputError> {
    std::fs::create_dir_all(dir).map_err(|e| {
        // `create_dir_all` reports a file in the way as "already exists", which reads as if
        // the directory were there.
        let problem = match e.kind() {
            io::ErrorKind::AlreadyExists => "it exists and is not a directory".to_owned(),
            _ => describe_io_error(&e),
        };
        OutputError::new(dir, format!("cannot create: {problem}"))
    })
}

/// Checks that a `width` x `height` frame is one the library accepts.
pub fn check_frame_size(width: usize, height: usize) -> Result<(), String> {
    use kestrel::MAX_DIMENSION;
    if width == 0 || height == 0 {
        return Err(format!("frame is {width}x{height}; it has no pixels"));
    }
    if width > MAX_DIMENSION || height > MAX_DIMENSION {
        return Err(format!(
            "frame is {width}x{height}; at most {MAX_DIMENSION} px per side are supported"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_input_place_and_problem() {
        let cell = Place::Cell {
            line: 3,
            column: 2,
            name: "y".into(),
        };
        let error = InputError::new("p.csv", "\"abc\" is not a number").at(cell);
        assert_eq!(
            error.to_string(),
            "p.csv: line 3, column 2 (y): \"abc\" is not a number"
        );
        let frame = InputError::new("clip.y4m", "truncated").at(Place::Frame(4));
        assert_eq!(frame.to_string(), "clip.y4m: frame 4: truncated");
    }

    #[test]
    fn io_errors_lose_the_os_error_number() {
        let missing = io::Error::from(io::ErrorKind::NotFound);
        assert_eq!(describe_io_error(&missing), "no such file or directory");
        let other = io::Error::from_raw_os_error(5);
        assert!(!describe_io_error(&other).contains("os error"));
    }

    #[test]
    fn frame_sizes_are_bounded() {
        assert!(check_frame_size(4096, 1).is_ok());
        assert!(check_frame_size(4097, 1).is_err());
        assert!(check_frame_size(0, 10).is_err());
    }
}
