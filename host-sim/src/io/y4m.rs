//! YUV4MPEG2 (`.y4m`) video: the luma (Y) plane of each frame.
//!
//! A stream is a header line `YUV4MPEG2 W<width> H<height> [C<colour space>] ...`, then for each
//! frame a line starting with `FRAME` and the planar picture: Y, then the chroma planes, whose size
//! the colour space fixes. Only 8-bit colour spaces are read; Y is already grey, so it is used as
//! is and the chroma is skipped. `ffmpeg -i clip.mp4 -f yuv4mpegpipe -` writes this format.
//!
//! Hand-written rather than the `y4m` crate (0.8), which fails host-sim/tests/hostile_input.rs:
//! a last frame cut in its picture data or in its FRAME marker ends its `read_frame` with
//! `Error::EOF`, exactly as the clean end of a stream does, so a truncated recording would pass
//! for a complete one ("last frame cut in its picture": no "truncated" error). It also accepts
//! `F30:0` and takes `C420p10` without refusing it, and its header errors ("General parsing
//! error") do not say which field is wrong, where the contract's messages must.

use std::io::{self, BufRead, Read};

use super::{check_frame_size, describe_io_error, InputError, Place};
use crate::Frame;

/// The stream signature that starts the header.
pub const SIGNATURE: &[u8] = b"YUV4MPEG2";
/// The marker that starts each frame.
const FRAME_MARKER: &[u8] = b"FRAME";
/// Longest header line accepted: far above real headers, low enough to stop at once on a
/// binary file that lacks a newline.
const MAX_HEADER_LEN: u64 = 4096;

/// How the chroma planes that follow Y are subsampled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Chroma {
    /// 4:2:0 (`C420`, `C420jpeg`, `C420paldv`, `C420mpeg2`; the default when `C` is absent).
    Half,
    /// 4:2:2 (`C422`): chroma at half width, full height.
    HalfWidth,
    /// 4:1:1 (`C411`): chroma at a quarter width, full height.
    QuarterWidth,
    /// 4:4:4 (`C444`): chroma at full resolution.
    Full,
    /// 4:4:4 with an alpha plane (`C444alpha`).
    FullWithAlpha,
    /// Luma only (`Cmono`).
    Mono,
}

impl Chroma {
    /// Parses the value of a `C` header parameter.
    fn from_tag(tag: &str) -> Option<Self> {
        Some(match tag {
            "420" | "420jpeg" | "420paldv" | "420mpeg2" => Chroma::Half,
            "422" => Chroma::HalfWidth,
            "411" => Chroma::QuarterWidth,
            "444" => Chroma::Full,
            "444alpha" => Chroma::FullWithAlpha,
            "mono" => Chroma::Mono,
            _ => return None,
        })
    }

    /// Bytes after the Y plane in each frame of `width` x `height`.
    pub fn trailing_bytes(self, width: usize, height: usize) -> usize {
        let (half_w, half_h) = (width.div_ceil(2), height.div_ceil(2));
        match self {
            Chroma::Half => 2 * half_w * half_h,
            Chroma::HalfWidth => 2 * half_w * height,
            Chroma::QuarterWidth => 2 * width.div_ceil(4) * height,
            Chroma::Full => 2 * width * height,
            Chroma::FullWithAlpha => 3 * width * height,
            Chroma::Mono => 0,
        }
    }
}

/// The parts of a y4m header that decide the frame layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Y4mHeader {
    /// Frame width in pixels.
    pub width: usize,
    /// Frame height in pixels.
    pub height: usize,
    /// The chroma layout after each Y plane.
    pub chroma: Chroma,
    /// Frames per second (`F<num>:<den>`), when the header gives it (`F0:0` means unknown).
    pub frame_rate: Option<FrameRate>,
}

/// A frame rate as the exact ratio a y4m header gives, e.g. 30000:1001 for NTSC video.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameRate {
    /// Frames...
    pub numerator: u32,
    /// ...per this many seconds.
    pub denominator: u32,
}

impl FrameRate {
    /// Frames per second.
    pub fn per_second(&self) -> f64 {
        f64::from(self.numerator) / f64::from(self.denominator)
    }

    /// Parses the value of an `F` header parameter; `Ok(None)` for `0:0`, the unknown rate.
    fn parse(value: &str) -> Result<Option<Self>, String> {
        let bad =
            || format!("y4m header has a bad frame rate \"F{value}\" (expected F<num>:<den>)");
        let (numerator, denominator) = value.split_once(':').ok_or_else(bad)?;
        let numerator: u32 = numerator.parse().map_err(|_| bad())?;
        let denominator: u32 = denominator.parse().map_err(|_| bad())?;
        match (numerator, denominator) {
            (0, 0) => Ok(None),
            (0, _) | (_, 0) => Err(bad()),
            _ => Ok(Some(Self {
                numerator,
                denominator,
            })),
        }
    }
}

impl Y4mHeader {
    /// Parses a header line (without its newline).
    pub fn parse(line: &[u8]) -> Result<Self, String> {
        let rest = line
            .strip_prefix(SIGNATURE)
            .filter(|rest| rest.is_empty() || rest.starts_with(b" "))
            .ok_or("not a y4m stream (no YUV4MPEG2 signature)")?;
        let text = std::str::from_utf8(rest).map_err(|_| "y4m header is not ASCII text")?;
        let (mut width, mut height, mut chroma) = (None, None, Chroma::Half);
        let mut frame_rate = None;
        for token in text.split(' ').filter(|t| !t.is_empty()) {
            let mut chars = token.chars();
            let (tag, value) = (chars.next(), chars.as_str());
            match tag {
                Some('W') => width = Some(parse_dimension("width", value)?),
                Some('H') => height = Some(parse_dimension("height", value)?),
                Some('C') => {
                    chroma = Chroma::from_tag(value).ok_or_else(|| {
                        format!("unsupported y4m colour space C{value} (8-bit 420, 422, 444 or mono expected)")
                    })?;
                }
                Some('F') => frame_rate = FrameRate::parse(value)?,
                // Interlacing, aspect ratio and extensions do not affect the layout.
                _ => {}
            }
        }
        let width = width.ok_or("y4m header has no width (W)")?;
        let height = height.ok_or("y4m header has no height (H)")?;
        check_frame_size(width, height)?;
        Ok(Self {
            width,
            height,
            chroma,
            frame_rate,
        })
    }

    /// Bytes of picture data per frame, all planes.
    pub fn frame_bytes(&self) -> usize {
        self.width * self.height + self.chroma.trailing_bytes(self.width, self.height)
    }
}

fn parse_dimension(name: &str, value: &str) -> Result<usize, String> {
    value
        .parse()
        .map_err(|_| format!("y4m header has a bad {name} \"{value}\""))
}

/// Reads the frames of a y4m stream one at a time.
#[derive(Debug)]
pub struct Y4mReader<R> {
    reader: R,
    header: Y4mHeader,
    /// The stream's name for messages.
    input: String,
    /// Frames read so far: the index of the next one.
    frames_read: usize,
    /// Bytes of the header line, its newline included.
    header_len: usize,
}

impl<R: BufRead> Y4mReader<R> {
    /// Reads the header of the stream `reader`, named `input` in messages.
    pub fn new(mut reader: R, input: &str) -> Result<Self, InputError> {
        let line = read_line(&mut reader, MAX_HEADER_LEN).map_err(|e| {
            InputError::new(input, format!("cannot read: {}", describe_io_error(&e)))
        })?;
        let header_len = match &line {
            Line::Complete(line) => line.len() + 1,
            _ => 0,
        };
        let header = match line {
            Line::Complete(line) => Y4mHeader::parse(&line),
            Line::End => Err("empty input; expected a y4m stream".to_owned()),
            Line::Unterminated(line) if line.starts_with(SIGNATURE) => {
                Err("y4m header line is truncated or too long".to_owned())
            }
            Line::Unterminated(_) => Err("not a y4m stream (no YUV4MPEG2 signature)".to_owned()),
        }
        .map_err(|problem| InputError::new(input, problem))?;
        Ok(Self {
            reader,
            header,
            input: input.to_owned(),
            frames_read: 0,
            header_len,
        })
    }

    /// The frames in a stream of `total` bytes whose frames carry no parameters (`FRAME\n`):
    /// what a progress bar expects of a y4m file.
    pub fn frames_in(&self, total: u64) -> usize {
        let per_frame = (b"FRAME\n".len() + self.header.frame_bytes()) as u64;
        (total.saturating_sub(self.header_len as u64) / per_frame) as usize
    }

    /// The stream's header.
    pub fn header(&self) -> &Y4mHeader {
        &self.header
    }

    /// The next frame's Y plane, `None` at the clean end of the stream.
    ///
    /// A frame cut short is an error naming its index (from 0).
    pub fn read_frame(&mut self) -> Result<Option<Frame>, InputError> {
        let index = self.frames_read;
        let error = |problem: String| InputError::new(&self.input, problem).at(Place::Frame(index));
        let io_error = |e: io::Error| error(format!("cannot read: {}", describe_io_error(&e)));
        let marker = match read_line(&mut self.reader, MAX_HEADER_LEN).map_err(io_error)? {
            Line::End => return Ok(None),
            Line::Complete(marker) => marker,
            Line::Unterminated(_) => return Err(error("truncated FRAME marker".to_owned())),
        };
        let parameters = marker.strip_prefix(FRAME_MARKER);
        if !parameters.is_some_and(|p| p.is_empty() || p.starts_with(b" ")) {
            return Err(error("expected a FRAME marker".to_owned()));
        }
        let Y4mHeader { width, height, .. } = self.header;
        let mut data = vec![0; width * height];
        let luma = read_up_to(&mut self.reader, &mut data).map_err(io_error)?;
        let chroma_len = self.header.chroma.trailing_bytes(width, height) as u64;
        let chroma = io::copy(&mut (&mut self.reader).take(chroma_len), &mut io::sink())
            .map_err(io_error)?;
        let got = luma as u64 + chroma;
        let expected = self.header.frame_bytes() as u64;
        if got < expected {
            return Err(error(format!(
                "truncated: {got} of {expected} bytes of picture data"
            )));
        }
        self.frames_read += 1;
        Ok(Some(Frame {
            width,
            height,
            data,
        }))
    }
}

/// A line read with a length limit.
enum Line {
    /// No bytes at all: the end of the stream.
    End,
    /// A line, without its newline.
    Complete(Vec<u8>),
    /// Bytes that ended (stream end or limit) before a newline.
    Unterminated(Vec<u8>),
}

fn read_line(reader: &mut impl BufRead, limit: u64) -> io::Result<Line> {
    let mut line = Vec::new();
    reader.take(limit).read_until(b'\n', &mut line)?;
    Ok(match line.pop() {
        None => Line::End,
        Some(b'\n') => Line::Complete(line),
        Some(last) => {
            line.push(last);
            Line::Unterminated(line)
        }
    })
}

/// Fills as much of `buf` as the stream holds; returns the bytes read.
fn read_up_to(reader: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A y4m stream of `frames` frames whose Y pixels are `frame index + x + y`.
    pub(crate) fn y4m_bytes(width: usize, height: usize, colour: &str, frames: usize) -> Vec<u8> {
        let mut bytes =
            format!("YUV4MPEG2 W{width} H{height} F30:1 Ip A1:1 {colour}\n").into_bytes();
        let chroma = match colour {
            "" => Chroma::Half,
            tag => Chroma::from_tag(&tag[1..]).unwrap(),
        };
        for index in 0..frames {
            bytes.extend_from_slice(b"FRAME\n");
            for y in 0..height {
                bytes.extend((0..width).map(|x| (index + x + y) as u8));
            }
            bytes.extend(std::iter::repeat_n(
                200,
                chroma.trailing_bytes(width, height),
            ));
        }
        bytes
    }

    fn read_all(bytes: &[u8]) -> Result<Vec<Frame>, InputError> {
        let mut reader = Y4mReader::new(bytes, "clip.y4m")?;
        let mut frames = Vec::new();
        while let Some(frame) = reader.read_frame()? {
            frames.push(frame);
        }
        Ok(frames)
    }

    #[test]
    fn every_colour_space_yields_the_y_plane() {
        for colour in [
            "",
            "C420jpeg",
            "C420paldv",
            "C420mpeg2",
            "C420",
            "C422",
            "C411",
            "C444",
            "C444alpha",
            "Cmono",
        ] {
            let frames = read_all(&y4m_bytes(5, 3, colour, 3)).unwrap();
            assert_eq!(frames.len(), 3, "{colour}");
            assert_eq!((frames[2].width, frames[2].height), (5, 3));
            assert_eq!(frames[2].at(4, 2), 8, "{colour}");
        }
    }

    #[test]
    fn the_frame_rate_is_read_when_given() {
        let header = |line: &[u8]| Y4mHeader::parse(line).map(|h| h.frame_rate);
        let ntsc = header(b"YUV4MPEG2 W2 H2 F30000:1001").unwrap().unwrap();
        assert!((ntsc.per_second() - 29.97).abs() < 1e-3);
        assert_eq!(header(b"YUV4MPEG2 W2 H2"), Ok(None));
        assert_eq!(header(b"YUV4MPEG2 W2 H2 F0:0"), Ok(None));
        for bad in [&b"F30"[..], b"F30:0", b"Fx:1", b"F0:1"] {
            let line = [&b"YUV4MPEG2 W2 H2 "[..], bad].concat();
            assert!(
                header(&line).unwrap_err().contains("bad frame rate"),
                "{bad:?}"
            );
        }
    }

    #[test]
    fn frame_parameters_are_allowed() {
        let mut bytes = b"YUV4MPEG2 W2 H2 Cmono\nFRAME Ixyz\n".to_vec();
        bytes.extend_from_slice(&[1, 2, 3, 4]);
        assert_eq!(read_all(&bytes).unwrap()[0].data, [1, 2, 3, 4]);
    }

    #[test]
    fn a_truncated_last_frame_names_its_index() {
        let bytes = y4m_bytes(8, 6, "C420jpeg", 3);
        let error = read_all(&bytes[..bytes.len() - 10]).unwrap_err();
        assert_eq!(error.place, Some(Place::Frame(2)));
        assert_eq!(
            error.to_string(),
            "clip.y4m: frame 2: truncated: 62 of 72 bytes of picture data"
        );
        let cut_in_marker = &bytes[..bytes.len() - 72 - 3];
        assert_eq!(
            read_all(cut_in_marker).unwrap_err().place,
            Some(Place::Frame(2))
        );
    }

    #[test]
    fn bad_headers_are_refused() {
        let problem = |bytes: &[u8]| read_all(bytes).unwrap_err().problem;
        assert!(problem(b"").starts_with("empty input"));
        assert!(problem(b"P5\n3 3\n255\n").contains("no YUV4MPEG2 signature"));
        assert!(problem(b"YUV4MPEG2X W2 H2\n").contains("no YUV4MPEG2 signature"));
        assert!(problem(b"YUV4MPEG2 H2\n").contains("no width"));
        assert!(problem(b"YUV4MPEG2 W2 Hx\n").contains("bad height"));
        assert!(
            problem(b"YUV4MPEG2 W2 H2 C420p10\n").contains("unsupported y4m colour space C420p10")
        );
        assert!(problem(b"YUV4MPEG2 W0 H2\n").contains("no pixels"));
        assert!(problem(b"YUV4MPEG2 W2 H2").contains("truncated"));
        assert!(problem(&[b'x'; 5000]).contains("no YUV4MPEG2 signature"));
    }

    #[test]
    fn a_missing_frame_marker_is_an_error() {
        let mut bytes = b"YUV4MPEG2 W2 H1 Cmono\nFRAME\n".to_vec();
        bytes.extend_from_slice(&[1, 2]);
        bytes.extend_from_slice(b"FRAMX\n\x01\x02");
        let error = read_all(&bytes).unwrap_err();
        assert_eq!(
            error.to_string(),
            "clip.y4m: frame 1: expected a FRAME marker"
        );
    }
}
