//! Frame sequences: a directory of images, a y4m file, y4m on standard input, or a video file
//! (decoded by ffmpeg).

use std::ffi::OsStr;
use std::fmt;
use std::fs::{self, File};
use std::io::{self, BufRead, BufReader};
use std::path::{Path, PathBuf};

use super::images::{has_image_extension, read_grey};
use super::video::VideoReader;
use super::y4m::{Y4mReader, SIGNATURE};
use super::{describe_io_error, InputError, Place, STDIN_NAME};
use crate::Frame;

/// The frames of a sequence, decoded one at a time.
///
/// Yields `Result<Frame, InputError>`. Every frame has the size of the first; a frame of
/// another size, like any unreadable frame, is an error naming it, after which the source yields
/// nothing more, so a consumer keeps the results of the frames before the bad one. A sequence
/// without any frame yields a single error, so no command silently processes nothing.
pub struct FrameSource {
    /// The sequence's name for messages.
    name: String,
    frames: Frames,
    /// Index (from 0) of the next frame.
    next_index: usize,
    /// Width and height of the first frame.
    size: Option<(usize, usize)>,
    finished: bool,
    /// Bytes of a y4m file (not a stream), for the frame count.
    file_len: Option<u64>,
}

/// Where the frames come from.
enum Frames {
    /// Image files in file-name order, not yet decoded.
    Files(std::vec::IntoIter<PathBuf>),
    /// A y4m stream.
    Y4m(Y4mReader<Box<dyn BufRead>>),
    /// A video file, decoded by ffmpeg as it is read.
    Video(VideoReader),
}

impl fmt::Debug for FrameSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("FrameSource")
            .field("name", &self.name)
            .field("next_index", &self.next_index)
            .finish_non_exhaustive()
    }
}

impl FrameSource {
    /// Opens `input` as the contract's INPUT: `-` is y4m on standard input, a directory holds one
    /// image per frame in file-name order, a `.y4m` file is y4m, and any other file is a video
    /// that ffmpeg decodes (see [`crate::io::video`]), unless it starts like a y4m stream.
    /// A file named like a frame image is read as y4m (and refused as one), as it always was.
    ///
    /// Problems found without decoding (a missing input, a bad y4m header, a directory entry that
    /// is not an image, a video without ffmpeg) are reported here, before any frame is processed.
    pub fn open(input: &OsStr) -> Result<Self, InputError> {
        if input == "-" {
            return Self::from_y4m(Box::new(io::stdin().lock()), STDIN_NAME);
        }
        let path = Path::new(input);
        let cannot_open = |e: io::Error| {
            InputError::file(path, format!("cannot open: {}", describe_io_error(&e)))
        };
        if fs::metadata(path).map_err(cannot_open)?.is_dir() {
            return Self::from_directory(path);
        }
        let file = File::open(path).map_err(cannot_open)?;
        let file_len = file.metadata().ok().map(|m| m.len());
        let mut reader = BufReader::new(file);
        if !named_as_y4m(path) && !starts_as_y4m(&mut reader) {
            return Self::from_video(path);
        }
        let mut source = Self::from_y4m(Box::new(reader), &path.display().to_string())?;
        source.file_len = file_len;
        Ok(source)
    }

    /// A sequence of the frames of the video file at `path`, decoded by ffmpeg.
    pub fn from_video(path: &Path) -> Result<Self, InputError> {
        let video = VideoReader::open(path)?;
        Ok(Self::new(path.display().to_string(), Frames::Video(video)))
    }

    /// A sequence of the image files in `directory`, in file-name order; hidden files (names
    /// starting with `.`) are skipped.
    ///
    /// File names are compared byte by byte, so frame numbers must be zero-padded
    /// (`0009.png` before `0010.png`).
    pub fn from_directory(directory: &Path) -> Result<Self, InputError> {
        let files = list_frame_files(directory)?;
        Ok(Self::new(
            directory.display().to_string(),
            Frames::Files(files.into_iter()),
        ))
    }

    /// A sequence read from the y4m stream `reader`, named `name` in messages.
    pub fn from_y4m(reader: Box<dyn BufRead>, name: &str) -> Result<Self, InputError> {
        let stream = Y4mReader::new(reader, name)?;
        Ok(Self::new(name.to_owned(), Frames::Y4m(stream)))
    }

    fn new(name: String, frames: Frames) -> Self {
        Self {
            name,
            frames,
            next_index: 0,
            size: None,
            finished: false,
            file_len: None,
        }
    }

    /// The sequence's name as used in messages.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The number of frames, when known before reading them: for a directory, its image files
    /// (a bad one still ends the sequence early); for a y4m file, its frames by its size;
    /// `None` for a y4m stream and a video.
    pub fn frame_count(&self) -> Option<usize> {
        match &self.frames {
            Frames::Files(files) => Some(self.next_index + files.len()),
            Frames::Y4m(stream) => self.file_len.map(|len| stream.frames_in(len)),
            Frames::Video(_) => None,
        }
    }

    /// Frames per second, when the input says (a y4m header with a frame rate, a video's
    /// rate as ffmpeg gives it); image directories carry no timing.
    pub fn frame_rate(&self) -> Option<f64> {
        let header = match &self.frames {
            Frames::Files(_) => return None,
            Frames::Y4m(stream) => stream.header(),
            Frames::Video(video) => video.header(),
        };
        header.frame_rate.map(|rate| rate.per_second())
    }

    /// The next frame and the name of the file it came from, `None` at the end.
    fn read_next(&mut self, index: usize) -> Result<Option<(Frame, String)>, InputError> {
        match &mut self.frames {
            Frames::Files(files) => {
                let Some(path) = files.next() else {
                    return Ok(None);
                };
                let frame = read_grey(&path).map_err(|e| e.at(Place::Frame(index)))?;
                Ok(Some((frame, path.display().to_string())))
            }
            Frames::Y4m(stream) => Ok(stream.read_frame()?.map(|frame| (frame, self.name.clone()))),
            Frames::Video(video) => Ok(video
                .read_frame(index)?
                .map(|frame| (frame, self.name.clone()))),
        }
    }

    /// Checks that the frame at `index`, read from `source`, has the sequence's size.
    fn check_size(
        &mut self,
        frame: Frame,
        index: usize,
        source: &str,
    ) -> Result<Frame, InputError> {
        let size = (frame.width, frame.height);
        match self.size {
            None => self.size = Some(size),
            Some(first) if first != size => {
                let problem = format!(
                    "frame is {}x{} but the first frame is {}x{}",
                    size.0, size.1, first.0, first.1
                );
                return Err(InputError::new(source, problem).at(Place::Frame(index)));
            }
            Some(_) => {}
        }
        Ok(frame)
    }
}

impl Iterator for FrameSource {
    type Item = Result<Frame, InputError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.finished {
            return None;
        }
        let index = self.next_index;
        let item = match self.read_next(index) {
            Ok(Some((frame, source))) => self.check_size(frame, index, &source),
            Ok(None) if index == 0 => Err(InputError::new(&self.name, "no frames")),
            Ok(None) => {
                self.finished = true;
                return None;
            }
            Err(error) => Err(error),
        };
        match item {
            Ok(_) => self.next_index += 1,
            Err(_) => self.finished = true,
        }
        Some(item)
    }
}

/// True when `path`'s name says it is no video: a `.y4m` file, or a frame image.
fn named_as_y4m(path: &Path) -> bool {
    let y4m = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("y4m"));
    y4m || has_image_extension(path)
}

/// True when the stream starts with the y4m signature, so that a y4m file under another name
/// (`clip.yuv`, `clip`) is read as before videos were. A stream that cannot be read counts as
/// y4m, for the y4m reader to report the error as before.
fn starts_as_y4m(reader: &mut impl BufRead) -> bool {
    reader
        .fill_buf()
        .map_or(true, |bytes| bytes.starts_with(SIGNATURE))
}

/// The visible entries of `directory`, sorted by name, each checked to be an image file.
fn list_frame_files(directory: &Path) -> Result<Vec<PathBuf>, InputError> {
    let cannot_list = |e: io::Error| {
        InputError::file(directory, format!("cannot list: {}", describe_io_error(&e)))
    };
    let mut files = Vec::new();
    for entry in fs::read_dir(directory).map_err(cannot_list)? {
        let entry = entry.map_err(cannot_list)?;
        if !entry.file_name().as_encoded_bytes().starts_with(b".") {
            files.push(entry.path());
        }
    }
    files.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
    for path in &files {
        if path.is_dir() {
            return Err(InputError::file(path, "is a directory, not a frame image"));
        }
        if !has_image_extension(path) {
            return Err(InputError::file(
                path,
                "not a frame image (expected .png, .jpg, .jpeg, .pgm or .bmp)",
            ));
        }
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::y4m::tests::y4m_bytes;
    use image::{GrayImage, Luma};
    use std::io::Write;
    use std::process::{Command, Stdio};

    fn scratch_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("host-sim-seq-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// Writes a `width` x `height` PNG whose every pixel is `value`.
    fn write_png(path: &Path, width: u32, height: u32, value: u8) {
        GrayImage::from_pixel(width, height, Luma([value]))
            .save(path)
            .unwrap();
    }

    fn first_pixels(source: FrameSource) -> Vec<u8> {
        source.map(|frame| frame.unwrap().data[0]).collect()
    }

    #[test]
    fn directory_frames_come_in_file_name_order_without_hidden_files() {
        let dir = scratch_dir("order");
        for (name, value) in [("b.png", 4), ("0010.png", 2), ("a.PNG", 3), ("0009.png", 1)] {
            write_png(&dir.join(name), 4, 3, value);
        }
        write_png(&dir.join(".hidden.png"), 9, 9, 0);
        fs::write(dir.join(".DS_Store"), "junk").unwrap();
        let mut source = FrameSource::open(dir.as_os_str()).unwrap();
        assert_eq!(source.frame_count(), Some(4));
        assert!(source.next().is_some());
        assert_eq!(source.frame_count(), Some(4));
        let source = FrameSource::open(dir.as_os_str()).unwrap();
        assert_eq!(first_pixels(source), [1, 2, 3, 4]);
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_non_image_file_is_named_before_any_frame_is_read() {
        let dir = scratch_dir("nonimage");
        write_png(&dir.join("0001.png"), 4, 3, 1);
        fs::write(dir.join("notes.txt"), "hello").unwrap();
        let error = FrameSource::open(dir.as_os_str()).unwrap_err();
        assert_eq!(error.input, dir.join("notes.txt").display().to_string());
        assert!(error.problem.starts_with("not a frame image"));
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_frame_of_another_size_stops_the_sequence() {
        let dir = scratch_dir("sizes");
        write_png(&dir.join("0.png"), 4, 3, 1);
        write_png(&dir.join("1.png"), 4, 3, 2);
        write_png(&dir.join("2.png"), 5, 3, 3);
        write_png(&dir.join("3.png"), 4, 3, 4);
        let mut source = FrameSource::open(dir.as_os_str()).unwrap();
        assert!(source.next().unwrap().is_ok());
        assert!(source.next().unwrap().is_ok());
        let error = source.next().unwrap().unwrap_err();
        let expected = format!(
            "{}: frame 2: frame is 5x3 but the first frame is 4x3",
            dir.join("2.png").display()
        );
        assert_eq!(error.to_string(), expected);
        assert!(source.next().is_none());
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_corrupt_frame_names_file_and_index() {
        let dir = scratch_dir("corrupt");
        write_png(&dir.join("0.png"), 4, 3, 1);
        fs::write(dir.join("1.png"), "not a png").unwrap();
        let error = FrameSource::open(dir.as_os_str())
            .unwrap()
            .find_map(Result::err)
            .unwrap();
        assert_eq!(error.place, Some(Place::Frame(1)));
        assert!(error.input.ends_with("1.png"));
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn empty_sequences_are_an_error() {
        let dir = scratch_dir("empty");
        let mut source = FrameSource::open(dir.as_os_str()).unwrap();
        assert_eq!(source.next().unwrap().unwrap_err().problem, "no frames");
        assert!(source.next().is_none());
        let header_only = FrameSource::from_y4m(Box::new(&b"YUV4MPEG2 W2 H2\n"[..]), "e.y4m");
        let mut source = header_only.unwrap();
        assert!(source.next().unwrap().is_err());
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn y4m_files_and_missing_inputs() {
        let dir = scratch_dir("y4m");
        let clip = dir.join("clip.y4m");
        fs::write(&clip, y4m_bytes(6, 4, "C422", 3)).unwrap();
        assert_eq!(
            first_pixels(FrameSource::open(clip.as_os_str()).unwrap()),
            [0, 1, 2]
        );
        let missing = dir.join("missing.y4m");
        let error = FrameSource::open(missing.as_os_str()).unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "{}: cannot open: no such file or directory",
                missing.display()
            )
        );
        fs::remove_dir_all(dir).unwrap();
    }

    /// Environment variable that turns the stdin test into the child that reads the pipe.
    const STDIN_CHILD: &str = "HOST_SIM_TEST_STDIN_CHILD";

    /// Runs this test binary again as the child of the stdin test, feeding it `input`.
    fn run_stdin_child(test_name: &str, input: Vec<u8>) -> String {
        let mut child = Command::new(std::env::current_exe().unwrap())
            .args([test_name, "--exact", "--nocapture", "--test-threads=1"])
            .env(STDIN_CHILD, "1")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut stdin = child.stdin.take().unwrap();
        // The child may stop reading early on a bad stream; a broken pipe is expected then.
        let _ = stdin.write_all(&input);
        drop(stdin);
        let output = child.wait_with_output().unwrap();
        String::from_utf8(output.stdout).unwrap()
    }

    /// In the child: reads standard input as a sequence and prints what it found.
    fn report_stdin_sequence() {
        let mut frames = 0;
        let outcome = FrameSource::open(OsStr::new("-")).and_then(|source| {
            for frame in source {
                let frame = frame?;
                frames += 1;
                println!(
                    "frame {}x{} first {}",
                    frame.width, frame.height, frame.data[0]
                );
            }
            Ok(())
        });
        match outcome {
            Ok(()) => println!("end after {frames}"),
            Err(error) => println!("error: {error}"),
        }
    }

    #[test]
    fn stdin_is_read_as_y4m() {
        if std::env::var_os(STDIN_CHILD).is_some() {
            return report_stdin_sequence();
        }
        let name = "io::sequence::tests::stdin_is_read_as_y4m";
        let output = run_stdin_child(name, y4m_bytes(5, 3, "Cmono", 2));
        assert!(output.contains("frame 5x3 first 0\n"), "{output}");
        assert!(output.contains("frame 5x3 first 1\n"), "{output}");
        assert!(output.contains("end after 2\n"), "{output}");
    }

    #[test]
    fn truncated_stdin_names_standard_input_and_the_frame() {
        if std::env::var_os(STDIN_CHILD).is_some() {
            return report_stdin_sequence();
        }
        let name = "io::sequence::tests::truncated_stdin_names_standard_input_and_the_frame";
        let mut bytes = y4m_bytes(5, 3, "C444", 2);
        bytes.truncate(bytes.len() - 1);
        let output = run_stdin_child(name, bytes);
        assert!(
            output.contains("error: standard input: frame 1: truncated: 44 of 45 bytes"),
            "{output}"
        );
    }
}
