//! Frames a fuzz input describes: geometry (size, stride, a buffer that may be short) and
//! content. Raw bytes alone rarely give LK or the detectors anything to lock on to, so the
//! content can also be a smooth seeded texture, moved by a sub-pixel shift and a gain and bias
//! change between frames, or one of the hostile patterns a camera produces.

use arbitrary::Arbitrary;
use kestrel::ImageView;

/// What the pixels show.
#[derive(Arbitrary, Debug, Clone)]
pub enum Content {
    /// The fuzzer's bytes, repeated to fill the frame.
    Raw(Vec<u8>),
    /// One grey level everywhere (black, white, saturated).
    Flat(u8),
    /// A smooth seeded texture: blobs a few pixels across, with corners LK can follow.
    Texture { seed: u32, contrast: u8 },
    /// Periodic stripes: the aperture problem.
    Stripes { period: u8, vertical: bool },
    /// A single bright pixel on black.
    Dot { x: u8, y: u8, value: u8 },
}

/// How a frame differs from the scene: a shift in 1/4 px, then `gain / 64` and `bias`.
#[derive(Arbitrary, Debug, Clone, Copy, Default)]
pub struct Change {
    pub dx: i8,
    pub dy: i8,
    pub gain: u8,
    pub bias: i8,
}

/// A frame's geometry and content.
#[derive(Arbitrary, Debug, Clone)]
pub struct Picture {
    pub width: u8,
    pub height: u8,
    /// Extra bytes per row beyond the width.
    pub padding: u8,
    /// Bytes cut from the end of the buffer (a half-written frame).
    pub short: u8,
    pub content: Content,
    pub change: Change,
}

/// A frame a sequence target (the tracker's, the flow sensor's) is given, at `size` unless it
/// says otherwise.
#[derive(Arbitrary, Debug)]
pub enum FrameInput {
    /// The scene, moved and relit.
    Scene(Change),
    /// Another picture at the sequence's size.
    Other(Picture),
    /// A picture at its own size (usually not the sequence's).
    Resized(Picture),
}

impl FrameInput {
    /// The frame, with `scene` as the sequence's picture and `size` its frames' size.
    pub fn render(&self, scene: &Picture, (w, h): (usize, usize)) -> Frame {
        match self {
            FrameInput::Scene(change) => Picture {
                change: *change,
                ..scene.clone()
            }
            .render_at(w, h),
            FrameInput::Other(picture) => picture.render_at(w, h),
            FrameInput::Resized(picture) => picture.render(),
        }
    }
}

/// A frame buffer and the geometry it is meant to have.
#[derive(Debug, Clone)]
pub struct Frame {
    pub pixels: Vec<u8>,
    pub width: usize,
    pub height: usize,
    pub stride: usize,
}

impl Frame {
    /// The frame as a view, or `None` when the library refuses its geometry.
    pub fn view(&self) -> Option<ImageView<'_>> {
        ImageView::new(&self.pixels, self.width, self.height, self.stride).ok()
    }
}

impl Picture {
    /// Renders the picture at `width` x `height` (at least 1 x 1), ignoring its own size.
    pub fn render_at(&self, width: usize, height: usize) -> Frame {
        let (width, height) = (width.max(1), height.max(1));
        let stride = width + usize::from(self.padding % 8);
        let len = (stride * (height - 1) + width).saturating_sub(usize::from(self.short % 4));
        let mut pixels = vec![0u8; len];
        for (i, p) in pixels.iter_mut().enumerate() {
            let (x, y) = (i % stride, i / stride);
            *p = self.pixel(x, y, i);
        }
        Frame {
            pixels,
            width,
            height,
            stride,
        }
    }

    /// Renders the picture at its own size (1..=64 px per side: small frames fuzz faster and
    /// still reach every border case).
    pub fn render(&self) -> Frame {
        self.render_at(
            usize::from(self.width % 64) + 1,
            usize::from(self.height % 64) + 1,
        )
    }

    fn pixel(&self, x: usize, y: usize, i: usize) -> u8 {
        let c = self.change;
        let (fx, fy) = (
            x as f32 - f32::from(c.dx) / 4.0,
            y as f32 - f32::from(c.dy) / 4.0,
        );
        let value = match &self.content {
            Content::Raw(bytes) if bytes.is_empty() => 0.0,
            Content::Raw(bytes) => f32::from(bytes[i % bytes.len()]),
            Content::Flat(v) => f32::from(*v),
            Content::Texture { seed, contrast } => texture(*seed, fx, fy, *contrast),
            Content::Stripes { period, vertical } => {
                let p = f32::from(period % 16 + 2);
                let t = if *vertical { fx } else { fy };
                if t.rem_euclid(p) < p / 2.0 {
                    230.0
                } else {
                    20.0
                }
            }
            Content::Dot {
                x: dx,
                y: dy,
                value,
            } => {
                let hit = fx.round() == f32::from(*dx % 64) && fy.round() == f32::from(*dy % 64);
                if hit {
                    f32::from(*value)
                } else {
                    0.0
                }
            }
        };
        let gain = if c.gain == 0 {
            1.0
        } else {
            f32::from(c.gain) / 64.0
        };
        (value * gain + f32::from(c.bias)).clamp(0.0, 255.0) as u8
    }
}

/// Bilinear value noise on a 5 px lattice of seeded random levels.
fn texture(seed: u32, x: f32, y: f32, contrast: u8) -> f32 {
    const CELL: f32 = 5.0;
    let (gx, gy) = (x / CELL, y / CELL);
    let (x0, y0) = (gx.floor(), gy.floor());
    let (tx, ty) = (gx - x0, gy - y0);
    let at = |i: f32, j: f32| lattice(seed, i as i32, j as i32);
    let top = at(x0, y0) * (1.0 - tx) + at(x0 + 1.0, y0) * tx;
    let bottom = at(x0, y0 + 1.0) * (1.0 - tx) + at(x0 + 1.0, y0 + 1.0) * tx;
    let level = top * (1.0 - ty) + bottom * ty;
    128.0 + (level - 0.5) * (f32::from(contrast) + 40.0)
}

/// A random level in `0..1` for lattice point (`i`, `j`).
fn lattice(seed: u32, i: i32, j: i32) -> f32 {
    let mut h = seed ^ (i as u32).wrapping_mul(0x9E37_79B9) ^ (j as u32).wrapping_mul(0x85EB_CA6B);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    (h & 0xFFFF) as f32 / 65535.0
}
