//! Video files (mp4, mkv, avi, mov, webm, ...): decoded by ffmpeg, read as y4m while it runs.
//!
//! host-sim decodes no video codec itself. It runs
//!
//! ```text
//! ffmpeg -nostdin -v error -xerror -i file:FILE -map 0:v:0 -vsync passthrough \
//!        -f yuv4mpegpipe -pix_fmt gray -
//! ```
//!
//! and reads ffmpeg's standard output with the y4m reader, one frame at a time as ffmpeg
//! writes it, so a long video never sits in memory whole.
//!
//! - `-pix_fmt gray`: full-range 8-bit grey. ffmpeg stretches a video's 16-235 luma to 0-255,
//!   which is the grey a folder of the same frames as PNG gives, and every bit depth and colour
//!   model arrives in the one layout (`Cmono`) the reader takes.
//! - `-vsync passthrough`: each decoded frame once. The y4m muxer would otherwise repeat frames
//!   to turn a variable frame rate into a constant one, and a tracker would see still pairs.
//! - `-map 0:v:0`: the first video stream; audio and subtitles are ignored.
//! - `-v error -xerror`: ffmpeg prints only errors and stops at the first one instead of
//!   concealing the damage. A truncated or damaged file therefore ends the sequence after the
//!   frames ffmpeg delivered, with an error naming the next frame and ffmpeg's first line. Any
//!   line ffmpeg prints counts, since on some damage (a Matroska file cut short) it still
//!   exits with status 0.
//! - `file:`: the name is a file, never a protocol or a `concat:` list.
//!
//! ffmpeg's error output is read on a thread as it runs, so that it never blocks on a full
//! pipe. The process is always reaped, and killed first when the frames are dropped before
//! their end (a command that stops early).

use std::ffi::OsString;
use std::io::{self, BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Child, ChildStderr, ChildStdout, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use super::y4m::{Y4mHeader, Y4mReader};
use super::{describe_io_error, InputError, Place};
use crate::Frame;

/// What to tell a user whose video cannot be read because ffmpeg is missing.
const INSTALL_FFMPEG: &str = "is read as a video file (it is not y4m), which needs ffmpeg on the \
     PATH: install ffmpeg (e.g. apt install ffmpeg) and try again";

/// The frames of a video file, decoded by an ffmpeg process as they are read.
#[derive(Debug)]
pub struct VideoReader {
    frames: Y4mReader<BufReader<EndAware<ChildStdout>>>,
    /// Set once ffmpeg's output reached its end: ffmpeg has stopped writing.
    output_ended: Arc<AtomicBool>,
    ffmpeg: Ffmpeg,
    /// The file's name for messages.
    name: String,
}

impl VideoReader {
    /// Starts ffmpeg on the video file at `path` and reads the stream's header.
    ///
    /// A file ffmpeg cannot decode at all fails here, with ffmpeg's first line.
    pub fn open(path: &Path) -> Result<Self, InputError> {
        let name = path.display().to_string();
        let (mut ffmpeg, stdout) =
            Ffmpeg::spawn(path).map_err(|problem| InputError::new(&name, problem))?;
        let output = EndAware::new(stdout);
        let output_ended = Arc::clone(&output.ended);
        match Y4mReader::new(BufReader::new(output), &name) {
            Ok(frames) => Ok(Self {
                frames,
                output_ended,
                ffmpeg,
                name,
            }),
            Err(error) => Err(ffmpeg.blame(error, output_ended.load(Ordering::Relaxed))),
        }
    }

    /// The header of the stream ffmpeg writes.
    pub fn header(&self) -> &Y4mHeader {
        self.frames.header()
    }

    /// The next frame, `None` once ffmpeg has delivered every frame and exited cleanly.
    ///
    /// `index` is the frame's index, for the error when ffmpeg failed after the frame before.
    pub fn read_frame(&mut self, index: usize) -> Result<Option<Frame>, InputError> {
        match self.frames.read_frame() {
            Ok(Some(frame)) => Ok(Some(frame)),
            Ok(None) => match self.ffmpeg.finish() {
                None => Ok(None),
                Some(problem) => Err(InputError::new(&self.name, problem).at(Place::Frame(index))),
            },
            Err(error) => {
                let ended = self.output_ended.load(Ordering::Relaxed);
                Err(self.ffmpeg.blame(error, ended))
            }
        }
    }
}

/// A running ffmpeg, and the first line of its error output.
#[derive(Debug)]
struct Ffmpeg {
    child: Child,
    /// The thread reading ffmpeg's error output; `None` once joined.
    errors: Option<JoinHandle<Option<String>>>,
    /// True once the process has been waited for.
    reaped: bool,
}

impl Ffmpeg {
    /// Starts ffmpeg decoding the video at `path` to y4m on its standard output.
    fn spawn(path: &Path) -> Result<(Self, ChildStdout), String> {
        let mut url = OsString::from("file:");
        url.push(path);
        let mut child = decoding(&url).spawn().map_err(|e| match e.kind() {
            io::ErrorKind::NotFound => INSTALL_FFMPEG.to_owned(),
            _ => format!("cannot run ffmpeg: {}", describe_io_error(&e)),
        })?;
        let pipes = child.stdout.take().zip(child.stderr.take());
        let mut ffmpeg = Self {
            child,
            errors: None,
            reaped: false,
        };
        let Some((stdout, stderr)) = pipes else {
            ffmpeg.stop();
            return Err("cannot run ffmpeg: its output is not a pipe".to_owned());
        };
        let prefix = format!("{}: ", url.to_string_lossy());
        match read_errors(stderr, prefix) {
            Ok(thread) => ffmpeg.errors = Some(thread),
            Err(e) => {
                ffmpeg.stop();
                return Err(format!("cannot run ffmpeg: {}", describe_io_error(&e)));
            }
        }
        Ok((ffmpeg, stdout))
    }

    /// The error to report for `error` of the y4m reader. When ffmpeg's output had `ended`,
    /// ffmpeg stopped, and its own report says why when it failed; otherwise the stream
    /// itself is at fault and ffmpeg, still running, is stopped.
    fn blame(&mut self, error: InputError, ended: bool) -> InputError {
        if !ended {
            self.stop();
            return error;
        }
        match self.finish() {
            Some(problem) => InputError { problem, ..error },
            None => error,
        }
    }

    /// Waits for ffmpeg to exit; the problem when it failed or printed an error.
    fn finish(&mut self) -> Option<String> {
        let status = self.child.wait();
        self.reaped = true;
        let first_line = self
            .errors
            .take()
            .and_then(|thread| thread.join().ok().flatten());
        match (first_line, status) {
            (Some(line), _) => Some(format!("cannot decode: ffmpeg: {line}")),
            (None, Ok(status)) if status.success() => None,
            (None, Ok(status)) => Some(format!("cannot decode: ffmpeg stopped ({status})")),
            (None, Err(e)) => Some(format!(
                "cannot decode: lost track of ffmpeg: {}",
                describe_io_error(&e)
            )),
        }
    }

    /// Kills ffmpeg and reaps it.
    fn stop(&mut self) {
        // An error means that it had exited already, which the wait collects.
        let _ = self.child.kill();
        self.finish();
    }
}

impl Drop for Ffmpeg {
    fn drop(&mut self) {
        if !self.reaped {
            self.stop();
        }
    }
}

/// The ffmpeg command that decodes `url` to y4m on its standard output (see the module's
/// documentation for each option), with its output and errors piped.
fn decoding(url: &OsString) -> Command {
    let mut command = Command::new("ffmpeg");
    command
        .args(["-nostdin", "-v", "error", "-xerror", "-i"])
        .arg(url)
        .args(["-map", "0:v:0", "-vsync", "passthrough"])
        .args(["-f", "yuv4mpegpipe", "-pix_fmt", "gray", "-"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    command
}

/// A thread that reads ffmpeg's error output as it comes and returns its first line.
fn read_errors(stderr: ChildStderr, prefix: String) -> io::Result<JoinHandle<Option<String>>> {
    std::thread::Builder::new()
        .name("ffmpeg errors".to_owned())
        .spawn(move || first_error_line(stderr, &prefix))
}

/// Reads `stderr` to its end and returns its first non-empty line, without the context that
/// means nothing to users: `prefix` (ffmpeg's name for the input) and a library's
/// `[h264 @ 0x55d6c0a1e2c0] `.
fn first_error_line(stderr: ChildStderr, prefix: &str) -> Option<String> {
    let mut first = None;
    for line in BufReader::new(stderr).split(b'\n') {
        let Ok(line) = line else { break };
        let line = String::from_utf8_lossy(&line);
        let line = without_context(line.trim(), prefix);
        if first.is_none() && !line.is_empty() {
            first = Some(line.to_owned());
        }
    }
    first
}

/// `line` without a leading `prefix` or `[component @ 0xADDRESS] `.
fn without_context<'a>(line: &'a str, prefix: &str) -> &'a str {
    let line = line.strip_prefix(prefix).unwrap_or(line);
    match line
        .strip_prefix('[')
        .and_then(|rest| rest.split_once("] "))
    {
        Some((component, message)) if component.contains(" @ ") => message,
        _ => line,
    }
}

/// A reader that tells whether it reached the end of its stream, through a flag its owner can
/// keep after handing the reader over.
#[derive(Debug)]
struct EndAware<R> {
    inner: R,
    /// Set once a read found no more bytes.
    ended: Arc<AtomicBool>,
}

impl<R> EndAware<R> {
    fn new(inner: R) -> Self {
        Self {
            inner,
            ended: Arc::new(AtomicBool::new(false)),
        }
    }
}

impl<R: Read> Read for EndAware<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        if n == 0 && !buf.is_empty() {
            self.ended.store(true, Ordering::Relaxed);
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// A 320x240 test clip of `frames` frames, made by ffmpeg in a fresh directory named after
    /// `test`; `None`, with a note, when ffmpeg is not on the PATH.
    fn test_clip(test: &str, frames: usize) -> Option<PathBuf> {
        let dir =
            std::env::temp_dir().join(format!("host-sim-video-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let clip = dir.join("clip.mp4");
        let made = Command::new("ffmpeg")
            .args([
                "-nostdin",
                "-v",
                "error",
                "-f",
                "lavfi",
                "-i",
                "testsrc=size=320x240:rate=10",
            ])
            .args(["-frames:v", &frames.to_string(), "-pix_fmt", "yuv420p"])
            .arg(&clip)
            .status();
        match made {
            Ok(status) if status.success() => Some(clip),
            _ => {
                eprintln!("skipped: ffmpeg is not on the PATH");
                None
            }
        }
    }

    /// True while process `pid` exists, a zombie included.
    fn exists(pid: u32) -> bool {
        Path::new(&format!("/proc/{pid}")).exists()
    }

    #[test]
    #[cfg(target_os = "linux")]
    fn every_frame_is_read_then_ffmpeg_is_reaped() {
        let Some(clip) = test_clip("whole", 12) else {
            return;
        };
        let mut video = VideoReader::open(&clip).unwrap();
        let pid = video.ffmpeg.child.id();
        let mut frames = 0;
        while let Some(frame) = video.read_frame(frames).unwrap() {
            assert_eq!((frame.width, frame.height), (320, 240));
            frames += 1;
        }
        assert_eq!(frames, 12);
        assert_eq!(
            video.header().frame_rate.map(|r| r.per_second()),
            Some(10.0)
        );
        assert!(!exists(pid), "ffmpeg {pid} left behind");
        let _ = std::fs::remove_dir_all(clip.parent().unwrap());
    }

    #[test]
    #[cfg(target_os = "linux")]
    fn a_reader_dropped_early_kills_and_reaps_ffmpeg() {
        // 40 frames of 76,800 bytes: far more than a pipe holds, so ffmpeg is still writing.
        let Some(clip) = test_clip("early", 40) else {
            return;
        };
        let mut video = VideoReader::open(&clip).unwrap();
        let pid = video.ffmpeg.child.id();
        assert!(video.read_frame(0).unwrap().is_some());
        assert!(exists(pid));
        drop(video);
        assert!(!exists(pid), "ffmpeg {pid} left behind");
        let _ = std::fs::remove_dir_all(clip.parent().unwrap());
    }

    #[test]
    fn ffmpeg_lines_lose_their_addresses_and_the_file_name() {
        let prefix = "file:clip.mp4: ";
        let cases = [
            (
                "[h264 @ 0x55d656935ac0] error while decoding MB 0 0, bytestream -61",
                "error while decoding MB 0 0, bytestream -61",
            ),
            (
                "[mov,mp4,m4a,3gp,3g2,mj2 @ 0x56257a4b4900] moov atom not found",
                "moov atom not found",
            ),
            (
                "file:clip.mp4: Invalid data found when processing input",
                "Invalid data found when processing input",
            ),
            ("[not context] kept", "[not context] kept"),
            (
                "Error marking filters as finished",
                "Error marking filters as finished",
            ),
        ];
        for (line, expected) in cases {
            assert_eq!(without_context(line, prefix), expected);
        }
    }

    #[test]
    fn the_end_of_a_stream_is_remembered() {
        let mut reader = EndAware::new(&b"ab"[..]);
        let mut buf = [0; 4];
        assert_eq!(reader.read(&mut buf).unwrap(), 2);
        assert!(!reader.ended.load(Ordering::Relaxed));
        assert_eq!(reader.read(&mut buf).unwrap(), 0);
        assert!(reader.ended.load(Ordering::Relaxed));
    }
}
