//! PX4FLOW's block matching, as a baseline to measure Kestrel against.
//!
//! PX4FLOW, the classic flow sensor (STM32F407, 64x64 binned MT9V034 frames at 250-400 Hz),
//! computes its flow by SAD block matching. This crate is that algorithm, written anew from
//! its published description and the reference firmware's `compute_flow`
//! (`src/modules/flow/flow.c` of [PX4/Flow](https://github.com/PX4/Flow)), on Kestrel's
//! borrowed frames:
//!
//! 1. The central [`CROP`] x [`CROP`] pixels of each frame stand in for PX4FLOW's 64x64 image;
//!    they are copied into a caller-owned [`Workspace`], so that every block is read at
//!    constant offsets as flow.c reads its 64-byte rows.
//! 2. [`BLOCKS`] blocks of [`BLOCK`] x [`BLOCK`] on a 5x5 grid, placed as flow.c places them:
//!    from `r + 1` to `64 - (r + 1) - 8` in steps of `(64 - 2 (r + 1) - 8) / 5 + 1` for a
//!    search radius `r` (with `r = 4`: 5, 15, 25, 35, 45).
//! 3. A texture test per block (flow.c's `compute_diff`): the sum of the absolute differences
//!    between neighbouring pixels of the block's central 4x4, vertically and horizontally (24
//!    differences); a block below [`Config::feature_threshold`] is skipped.
//! 4. A full search of the block's SAD in the next frame over every integer shift within
//!    ±[`Config::search_radius`] px; the first smallest SAD in row order wins.
//! 5. Acceptance: a best SAD below [`Config::sad_threshold`] makes the block valid.
//! 6. Half-pixel refinement (flow.c's `compute_subpixel`): the SAD against the 8 half-pixel
//!    neighbours of the best match, each interpolated by halving adds (`UHADD8`) of two pixels
//!    (the diagonals of two such averages, truncated twice, as flow.c does); a neighbour with a
//!    smaller SAD than the integer match moves the block's flow by half a pixel on each axis it
//!    lies along.
//! 7. The flow is the mean of the valid blocks' displacements, in px per frame (x right, y
//!    down: how far the image content moved from the previous frame to the next), and the
//!    quality is `valid x 255 / 25`; with [`MIN_VALID_BLOCKS`] - 1 = 10 valid blocks or fewer
//!    the flow is 0 with quality 0 (flow.c: `meancount > 10`).
//!
//! Every SAD of 8 pixels is two [`kestrel::dsp::usada8`] on little-endian words, the USADA8
//! instruction on the Cortex-M4. flow.c's histogram filter (`BFLOW_HIST_FIL`, off by default)
//! and its gyro compensation (`BFLOW_GYRO_COM`, off by default) are left out.
//!
//! ```
//! use kestrel::ImageView;
//! use px4flow::{BlockMatcher, Config, Workspace};
//!
//! // A textured 80x80 frame and the same frame moved 2 px right and 1 px down.
//! let texture = |x: usize, y: usize| ((x * 7 + y * 13) % 31 * 8 + (x * y) % 5) as u8;
//! let prev: Vec<u8> = (0..80 * 80).map(|i| texture(i % 80 + 10, i / 80 + 10)).collect();
//! let next: Vec<u8> = (0..80 * 80).map(|i| texture(i % 80 + 8, i / 80 + 9)).collect();
//! let prev = ImageView::packed(&prev, 80, 80).unwrap();
//! let next = ImageView::packed(&next, 80, 80).unwrap();
//!
//! let matcher = BlockMatcher::new(Config::default())?;
//! let mut workspace = Workspace::new(); // the two 64x64 crops, caller-owned
//! let flow = matcher.flow(&prev, &next, &mut workspace)?;
//! assert_eq!((flow.x, flow.y, flow.quality), (2.0, 1.0, 255));
//! # Ok::<(), px4flow::Error>(())
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
// Kestrel's rules: no panics on any input (no unwrap, expect, panic or unreachable, no
// indexing that can go out of bounds, no arithmetic that can overflow, no narrowing casts).
// Every pixel read is a `get`, every offset a wrapping or checked operation on values the
// geometry checks bound. Tests may panic.
#![cfg_attr(
    not(test),
    warn(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::todo,
        clippy::unimplemented,
        clippy::unreachable,
        clippy::indexing_slicing,
        clippy::arithmetic_side_effects,
        clippy::cast_possible_truncation
    )
)]

use kestrel::dsp::{uhadd8, usada8};
use kestrel::ImageView;

/// Side of the central crop matched, px: PX4FLOW's image is 64x64 (`BOTTOM_FLOW_IMAGE_WIDTH`,
/// `BOTTOM_FLOW_IMAGE_HEIGHT` in its `settings.h`).
pub const CROP: usize = 64;
/// Side of a block, px (flow.c's `TILE_SIZE`).
pub const BLOCK: usize = 8;
/// Blocks along each side of the grid (flow.c's `NUM_BLOCKS`).
pub const BLOCKS_PER_SIDE: usize = 5;
/// Blocks in all.
pub const BLOCKS: usize = BLOCKS_PER_SIDE * BLOCKS_PER_SIDE;
/// The fewest valid blocks that give a flow (flow.c: `meancount > 10`).
pub const MIN_VALID_BLOCKS: usize = 11;
/// The largest search radius accepted, px: the largest for which flow.c's block placement
/// still fits 5 blocks per side, 5 px apart, in the 64 px crop.
pub const MAX_SEARCH_RADIUS: u8 = 16;

// The quality's divisor below is this count.
const _: () = assert!(BLOCKS == 25);

/// The matcher's parameters, PX4FLOW's defaults by [`Config::default`].
///
/// ```
/// let config = px4flow::Config::default();
/// assert_eq!((config.search_radius, config.feature_threshold, config.sad_threshold), (4, 40, 5000));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Config {
    /// Largest integer shift searched on each axis, px. Default 4: PX4/Flow's
    /// `BOTTOM_FLOW_SEARCH_WINDOW_SIZE` (`PARAM_MAX_FLOW_PIXEL`, `BFLOW_MAX_PIX`) in its
    /// `settings.h` until 2016; it has been 8 since commit 5e69f1d. At most
    /// [`MAX_SEARCH_RADIUS`].
    pub search_radius: u8,
    /// Texture test: a block whose central 4x4 neighbour-difference sum is below this is
    /// skipped. Default 40: `BFLOW_F_THLD` (`PARAM_BOTTOM_FLOW_FEATURE_THRESHOLD`) in PX4/Flow's
    /// `settings.c` since commit 9eb8fb3 (2017; 30 before, 20 from 2016).
    pub feature_threshold: u32,
    /// A block's best SAD must be below this to count. Default 5000: `BFLOW_V_THLD`
    /// (`PARAM_BOTTOM_FLOW_VALUE_THRESHOLD`) in PX4/Flow's `settings.c`, "irrelevant with this
    /// value" by its own comment (78 grey levels per pixel on average).
    pub sad_threshold: u32,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            search_radius: 4,
            feature_threshold: 40,
            sad_threshold: 5000,
        }
    }
}

/// Why the matcher refused its settings or its frames.
///
/// ```
/// use px4flow::{BlockMatcher, Config, Error};
/// let wide = Config { search_radius: 17, ..Config::default() };
/// assert_eq!(BlockMatcher::new(wide).unwrap_err(), Error::SearchRadius);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// The two frames differ in width or height.
    FrameSizeMismatch,
    /// A frame is narrower or lower than the [`CROP`] px the blocks and their search need.
    FrameTooSmall,
    /// The search radius is above [`MAX_SEARCH_RADIUS`]: no room for the 5x5 grid of blocks
    /// and their search in the crop.
    SearchRadius,
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Error::FrameSizeMismatch => "the two frames differ in size",
            Error::FrameTooSmall => "frame is smaller than the 64x64 crop",
            Error::SearchRadius => "search radius leaves no room for 5x5 blocks in the crop",
        })
    }
}

impl core::error::Error for Error {}

/// The flow between two frames.
///
/// ```
/// let flow = px4flow::Flow { x: 0.5, y: -1.0, quality: 204, valid_blocks: 20 };
/// assert!(flow.is_valid());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Flow {
    /// Mean horizontal displacement of the valid blocks, px per frame, positive to the right;
    /// a multiple of 1 / (2 x valid blocks). 0 when the flow is invalid.
    pub x: f32,
    /// Mean vertical displacement, px per frame, positive down. 0 when the flow is invalid.
    pub y: f32,
    /// `valid_blocks x 255 / 25`, or 0 (invalid) with fewer than [`MIN_VALID_BLOCKS`].
    pub quality: u8,
    /// Blocks that passed the texture test and the SAD threshold.
    pub valid_blocks: u8,
}

impl Flow {
    /// True when the flow is usable: quality above 0.
    ///
    /// ```
    /// assert!(!px4flow::Flow::default().is_valid());
    /// ```
    pub const fn is_valid(&self) -> bool {
        self.quality > 0
    }
}

/// What became of one block.
///
/// ```
/// use px4flow::BlockStatus;
/// assert_ne!(BlockStatus::Flat, BlockStatus::Matched);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BlockStatus {
    /// Below the texture threshold: not searched.
    #[default]
    Flat,
    /// Searched, but the best SAD was not below the SAD threshold.
    Rejected,
    /// Valid: its displacement counts towards the flow.
    Matched,
}

/// One block's match, for diagnostics ([`BlockMatcher::flow_with_blocks`]).
///
/// ```
/// let block = px4flow::BlockMatch::default();
/// assert_eq!(block.displacement(), (0.0, 0.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BlockMatch {
    /// Left column of the block in the previous frame, px from the crop's left edge.
    pub x: u8,
    /// Top row of the block, px from the crop's top edge.
    pub y: u8,
    /// The texture measure of its central 4x4 (sum of 24 neighbour differences).
    pub texture: u32,
    /// The best integer-shift SAD (`u32::MAX` for a flat block, not searched).
    pub sad: u32,
    /// Displacement found, in half pixels (x right, y down); (0, 0) unless matched.
    pub half_px: (i8, i8),
    /// What became of it.
    pub status: BlockStatus,
}

impl BlockMatch {
    /// The displacement in pixels.
    ///
    /// ```
    /// let block = px4flow::BlockMatch { half_px: (3, -8), ..Default::default() };
    /// assert_eq!(block.displacement(), (1.5, -4.0));
    /// ```
    pub fn displacement(&self) -> (f32, f32) {
        (
            f32::from(self.half_px.0) / 2.0,
            f32::from(self.half_px.1) / 2.0,
        )
    }
}

/// PX4FLOW's block matcher with checked settings.
///
/// ```
/// use px4flow::{BlockMatcher, Config};
/// let matcher = BlockMatcher::new(Config { search_radius: 8, ..Config::default() })?;
/// // Blocks as the current PX4/Flow firmware places them for its 8 px search.
/// assert_eq!(matcher.block_origins(), [9, 17, 25, 33, 41]);
/// # Ok::<(), px4flow::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockMatcher {
    config: Config,
    /// Block origins along each axis of the crop.
    origins: [u8; BLOCKS_PER_SIDE],
}

impl BlockMatcher {
    /// A matcher with `config`, or [`Error::SearchRadius`] for a search radius above
    /// [`MAX_SEARCH_RADIUS`].
    ///
    /// ```
    /// use px4flow::{BlockMatcher, Config};
    /// assert_eq!(BlockMatcher::new(Config::default())?.block_origins(), [5, 15, 25, 35, 45]);
    /// # Ok::<(), px4flow::Error>(())
    /// ```
    pub fn new(config: Config) -> Result<Self, Error> {
        if config.search_radius > MAX_SEARCH_RADIUS {
            return Err(Error::SearchRadius);
        }
        // flow.c: pixLo = r + 1, pixHi = 64 - (r + 1) - 8, pixStep = (pixHi - pixLo) / 5 + 1;
        // for r <= 16 that is 5 blocks at least 5 px apart.
        let low = usize::from(config.search_radius).saturating_add(1);
        let high = CROP.saturating_sub(low).saturating_sub(BLOCK);
        let step = (high.saturating_sub(low) / BLOCKS_PER_SIDE).saturating_add(1);
        let mut origins = [0u8; BLOCKS_PER_SIDE];
        let mut placed = (low..high).step_by(step);
        for slot in &mut origins {
            let origin = placed.next().ok_or(Error::SearchRadius)?;
            *slot = u8::try_from(origin).map_err(|_| Error::SearchRadius)?;
        }
        if placed.next().is_some() {
            return Err(Error::SearchRadius);
        }
        Ok(Self { config, origins })
    }

    /// The settings.
    ///
    /// ```
    /// use px4flow::{BlockMatcher, Config};
    /// assert_eq!(BlockMatcher::new(Config::default())?.config(), Config::default());
    /// # Ok::<(), px4flow::Error>(())
    /// ```
    pub const fn config(&self) -> Config {
        self.config
    }

    /// Where the blocks start along each axis of the crop, px (flow.c's `pixLo`, `pixStep`).
    ///
    /// ```
    /// use px4flow::{BlockMatcher, Config};
    /// let matcher = BlockMatcher::new(Config { search_radius: 2, ..Config::default() })?;
    /// assert_eq!(matcher.block_origins(), [3, 14, 25, 36, 47]);
    /// # Ok::<(), px4flow::Error>(())
    /// ```
    pub const fn block_origins(&self) -> [u8; BLOCKS_PER_SIDE] {
        self.origins
    }

    /// The flow from `prev` to `next`, matched on the central [`CROP`] x [`CROP`] pixels of
    /// both (the crop starts at `((width - 64) / 2, (height - 64) / 2)`), which are copied
    /// into `workspace` first.
    ///
    /// ```
    /// use kestrel::ImageView;
    /// use px4flow::{BlockMatcher, Config, Error, Workspace};
    /// let matcher = BlockMatcher::new(Config::default())?;
    /// let mut workspace = Workspace::new();
    /// let flat = [128u8; 64 * 64];
    /// let flat = ImageView::packed(&flat, 64, 64).unwrap();
    /// let flow = matcher.flow(&flat, &flat, &mut workspace)?;
    /// assert_eq!((flow.quality, flow.valid_blocks), (0, 0));
    /// let small = ImageView::packed(&[0; 63 * 64], 63, 64).unwrap();
    /// assert_eq!(matcher.flow(&small, &small, &mut workspace), Err(Error::FrameTooSmall));
    /// assert_eq!(matcher.flow(&flat, &small, &mut workspace), Err(Error::FrameSizeMismatch));
    /// # Ok::<(), px4flow::Error>(())
    /// ```
    pub fn flow(
        &self,
        prev: &ImageView<'_>,
        next: &ImageView<'_>,
        workspace: &mut Workspace,
    ) -> Result<Flow, Error> {
        let mut blocks = [BlockMatch::default(); BLOCKS];
        self.flow_with_blocks(prev, next, workspace, &mut blocks)
    }

    /// Like [`BlockMatcher::flow`], with every block's match written to `blocks`, row by row.
    ///
    /// ```
    /// use kestrel::ImageView;
    /// use px4flow::{BlockMatcher, BlockStatus, Config, Workspace, BLOCKS};
    /// let matcher = BlockMatcher::new(Config::default())?;
    /// let flat = [0u8; 64 * 64];
    /// let flat = ImageView::packed(&flat, 64, 64).unwrap();
    /// let mut blocks = [Default::default(); BLOCKS];
    /// matcher.flow_with_blocks(&flat, &flat, &mut Workspace::new(), &mut blocks)?;
    /// assert!(blocks.iter().all(|b| b.status == BlockStatus::Flat));
    /// assert_eq!((blocks[6].x, blocks[6].y), (15, 15));
    /// # Ok::<(), px4flow::Error>(())
    /// ```
    pub fn flow_with_blocks(
        &self,
        prev: &ImageView<'_>,
        next: &ImageView<'_>,
        workspace: &mut Workspace,
        blocks: &mut [BlockMatch; BLOCKS],
    ) -> Result<Flow, Error> {
        if !prev.same_size(next) {
            return Err(Error::FrameSizeMismatch);
        }
        copy_centre(prev, &mut workspace.prev)?;
        copy_centre(next, &mut workspace.next)?;
        let (prev, next) = (&workspace.prev, &workspace.next);
        let mut valid = 0u8;
        let mut sum = (0i32, 0i32);
        let cells = self
            .origins
            .iter()
            .flat_map(|&y| self.origins.iter().map(move |&x| (x, y)));
        for ((x, y), block) in cells.zip(blocks.iter_mut()) {
            *block = self.match_block(prev, next, usize::from(x), usize::from(y));
            block.x = x;
            block.y = y;
            if block.status == BlockStatus::Matched {
                valid = valid.saturating_add(1);
                sum.0 = sum.0.saturating_add(i32::from(block.half_px.0));
                sum.1 = sum.1.saturating_add(i32::from(block.half_px.1));
            }
        }
        if usize::from(valid) < MIN_VALID_BLOCKS {
            return Ok(Flow {
                valid_blocks: valid,
                ..Flow::default()
            });
        }
        // Half pixels summed over at most 25 blocks: exact in f32.
        let halves = 2.0 * f32::from(valid);
        let quality = u16::from(valid).saturating_mul(255) / 25;
        Ok(Flow {
            x: sum.0 as f32 / halves,
            y: sum.1 as f32 / halves,
            quality: u8::try_from(quality).unwrap_or(u8::MAX),
            valid_blocks: valid,
        })
    }

    /// The texture test, the search and the refinement of the block at (`x`, `y`) of the
    /// crop. The placement in [`BlockMatcher::new`] keeps every pixel they read inside it.
    fn match_block(&self, prev: &Crop, next: &Crop, x: usize, y: usize) -> BlockMatch {
        let texture = texture(prev, x, y);
        let mut block = BlockMatch {
            texture,
            sad: u32::MAX,
            ..BlockMatch::default()
        };
        if texture < self.config.feature_threshold {
            return block;
        }
        let Some(template) = template(prev, x, y) else {
            return block;
        };
        // The search, in flow.c's order: rows of shifts from the top, the first strictly
        // smallest SAD kept.
        let radius = usize::from(self.config.search_radius);
        let (left, top) = (x.wrapping_sub(radius), y.wrapping_sub(radius));
        let side = radius.wrapping_mul(2).wrapping_add(1);
        let mut best = (u32::MAX, 0usize, 0usize);
        for row in 0..side {
            let start = offset_of(left, top.wrapping_add(row));
            for column in 0..side {
                let sad = sad_8x8(&template, next, start.wrapping_add(column));
                if sad < best.0 {
                    best = (sad, column, row);
                }
            }
        }
        let (sad, column, row) = best;
        block.sad = sad;
        if sad >= self.config.sad_threshold {
            block.status = BlockStatus::Rejected;
            return block;
        }
        let (dx, dy) = (shift(column, radius), shift(row, radius));
        let (mx, my) = (left.wrapping_add(column), top.wrapping_add(row));
        let (sx, sy) = half_pixel(next, &template, mx, my, sad);
        block.half_px = (
            dx.wrapping_mul(2).wrapping_add(sx),
            dy.wrapping_mul(2).wrapping_add(sy),
        );
        block.status = BlockStatus::Matched;
        block
    }
}

/// `index - radius` as a signed shift (both at most 2 x 16 + 1, so it fits an `i8`).
fn shift(index: usize, radius: usize) -> i8 {
    let shift = i16::try_from(index)
        .unwrap_or(0)
        .wrapping_sub(i16::try_from(radius).unwrap_or(0));
    i8::try_from(shift).unwrap_or(0)
}

/// Storage for the matcher: the central crops of both frames, 8 KB. Keep one per matcher
/// (in a `static` on a microcontroller) and lend it to every call.
///
/// ```
/// let workspace = px4flow::Workspace::new();
/// assert_eq!(core::mem::size_of_val(&workspace), 2 * 64 * 64);
/// ```
#[derive(Debug, Clone)]
// The next frame's crop first: the search reads it at the workspace's own address plus small
// offsets, which Thumb-2 loads encode in the instruction (up to 4095 bytes).
#[repr(C)]
pub struct Workspace {
    next: Crop,
    prev: Crop,
}

impl Workspace {
    /// A zeroed workspace (a `const fn`, for statics).
    ///
    /// ```
    /// static mut WORKSPACE: px4flow::Workspace = px4flow::Workspace::new();
    /// ```
    pub const fn new() -> Self {
        Self {
            next: [0; CROP * CROP],
            prev: [0; CROP * CROP],
        }
    }
}

impl Default for Workspace {
    fn default() -> Self {
        Self::new()
    }
}

/// A central crop, row by row, [`CROP`] bytes apart: PX4FLOW's 64x64 image. Its fixed stride
/// lets every read of a block use constant offsets, as flow.c's assembly does.
type Crop = [u8; CROP * CROP];

/// A block's 8 rows of 8 pixels, as two little-endian words per row.
type Template = [[u32; 2]; BLOCK];

/// Bytes from the first pixel of an 8x8 block to the end of its last row.
const BLOCK_SPAN: usize = (BLOCK - 1) * CROP + BLOCK;
/// The same for the 10x10 pixels around a block that the half-pixel refinement reads.
const AROUND_SPAN: usize = (BLOCK + 1) * CROP + BLOCK + 2;
/// The same for the 4x4 centre of a block that the texture test reads.
const CENTRE_SPAN: usize = 3 * CROP + 4;

/// Copies the central crop of `frame` into `crop`, or refuses a frame smaller than it.
fn copy_centre(frame: &ImageView<'_>, crop: &mut Crop) -> Result<(), Error> {
    let left = frame
        .width()
        .checked_sub(CROP)
        .ok_or(Error::FrameTooSmall)?
        / 2;
    let top = frame
        .height()
        .checked_sub(CROP)
        .ok_or(Error::FrameTooSmall)?
        / 2;
    for (y, row) in crop.chunks_exact_mut(CROP).enumerate() {
        let pixels = frame.row(top.saturating_add(y));
        let pixels = pixels
            .get(left..left.saturating_add(CROP))
            .ok_or(Error::FrameTooSmall)?;
        row.copy_from_slice(pixels);
    }
    Ok(())
}

/// The offset of pixel (`x`, `y`) in a crop (wrapping for coordinates off it, which the
/// reads then refuse).
#[inline(always)]
fn offset_of(x: usize, y: usize) -> usize {
    y.wrapping_mul(CROP).wrapping_add(x)
}

/// The `N` bytes of `crop` from `offset`, or `None` past its end.
#[inline(always)]
fn span<const N: usize>(crop: &Crop, offset: usize) -> Option<&[u8; N]> {
    crop.get(offset..offset.checked_add(N)?)?.try_into().ok()
}

/// The little-endian word at `offset` of `bytes` (0 past its end: with the constant offsets
/// used here, never).
#[inline(always)]
fn word<const N: usize>(bytes: &[u8; N], offset: usize) -> u32 {
    match bytes.get(offset..offset.wrapping_add(4)) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => 0,
    }
}

/// The block at (`x`, `y`) as words.
fn template(crop: &Crop, x: usize, y: usize) -> Option<Template> {
    let pixels = span::<BLOCK_SPAN>(crop, offset_of(x, y))?;
    let mut template = [[0; 2]; BLOCK];
    for (k, words) in template.iter_mut().enumerate() {
        let row = k.wrapping_mul(CROP);
        *words = [word(pixels, row), word(pixels, row.wrapping_add(4))];
    }
    Some(template)
}

/// The SAD of `template` and the 8x8 pixels of `crop` from `offset`: two USADA8 per row, as
/// flow.c's `ABSDIFF`; `u32::MAX` if the block is not inside the crop.
#[inline(always)]
fn sad_8x8(template: &Template, crop: &Crop, offset: usize) -> u32 {
    let Some(pixels) = span::<BLOCK_SPAN>(crop, offset) else {
        return u32::MAX;
    };
    let mut acc = 0;
    for (k, &[t0, t1]) in template.iter().enumerate() {
        let row = k.wrapping_mul(CROP);
        acc = usada8(t0, word(pixels, row), acc);
        acc = usada8(t1, word(pixels, row.wrapping_add(4)), acc);
    }
    acc
}

/// flow.c's `compute_diff`: over the central 4x4 of the block at (`x`, `y`), the absolute
/// differences of vertically neighbouring pixels (three pairs of rows) and of horizontally
/// neighbouring ones (three pairs of columns, each column packed into a word); 0 when the
/// block is not inside the crop.
fn texture(crop: &Crop, x: usize, y: usize) -> u32 {
    let Some(pixels) = span::<CENTRE_SPAN>(crop, offset_of(x.wrapping_add(2), y.wrapping_add(2)))
    else {
        return 0;
    };
    let rows = [0, CROP, 2 * CROP, 3 * CROP].map(|row| word(pixels, row));
    let [r0, r1, r2, r3] = rows;
    let mut acc = usada8(r0, r1, 0);
    acc = usada8(r1, r2, acc);
    acc = usada8(r2, r3, acc);
    // Column k packed top to bottom from the most significant byte, as flow.c packs it.
    let [c0, c1, c2, c3] = [0, 1, 2, 3].map(|k| {
        let pixel = |row: u32| row.to_le_bytes().get(k).copied().unwrap_or(0);
        u32::from_be_bytes(rows.map(pixel))
    });
    acc = usada8(c0, c1, acc);
    acc = usada8(c1, c2, acc);
    usada8(c2, c3, acc)
}

/// flow.c's `compute_subpixel`: the SADs of `template` against the 8 half-pixel neighbours of
/// the match at (`x`, `y`), and the half-pixel step (-1, 0 or 1 per axis) towards the first
/// one below `sad`, the integer match's, or (0, 0) if none is.
///
/// Directions 0-7 run clockwise on screen (y down) from the right: right, down-right, down,
/// down-left, left, up-left, up, up-right. The straight neighbours are the halving adds of the
/// match's pixels with their neighbours; the diagonals average two of those again.
fn half_pixel(crop: &Crop, template: &Template, x: usize, y: usize, sad: u32) -> (i8, i8) {
    const STEPS: [(i8, i8); 8] = [
        (1, 0),
        (1, 1),
        (0, 1),
        (-1, 1),
        (-1, 0),
        (-1, -1),
        (0, -1),
        (1, -1),
    ];
    // The 10x10 pixels from (x - 1, y - 1).
    let origin = offset_of(x.wrapping_sub(1), y.wrapping_sub(1));
    let Some(pixels) = span::<AROUND_SPAN>(crop, origin) else {
        return (0, 0);
    };
    let mut acc = [0u32; 8];
    for (k, row_template) in template.iter().enumerate() {
        // Row k of the match is row k + 1 of the 10x10 pixels.
        let here = k.wrapping_add(1).wrapping_mul(CROP);
        let (above, below) = (here.wrapping_sub(CROP), here.wrapping_add(CROP));
        for (half, &t) in row_template.iter().enumerate() {
            // The words left of, at and right of the match's 4 pixels in this half.
            let column = half.wrapping_mul(4);
            let at = |row: usize, d: usize| word(pixels, row.wrapping_add(column).wrapping_add(d));
            let (a_l, a_c, a_r) = (at(above, 0), at(above, 1), at(above, 2));
            let (h_l, h_c, h_r) = (at(here, 0), at(here, 1), at(here, 2));
            let (b_l, b_c, b_r) = (at(below, 0), at(below, 1), at(below, 2));
            let s0 = uhadd8(h_c, h_r);
            let s1 = uhadd8(b_c, b_r);
            let s2 = uhadd8(h_c, b_c);
            let s3 = uhadd8(b_c, b_l);
            let s4 = uhadd8(h_c, h_l);
            let s5 = uhadd8(a_c, a_l);
            let s6 = uhadd8(h_c, a_c);
            let s7 = uhadd8(a_c, a_r);
            let neighbours = [
                s0,
                uhadd8(s0, s1),
                s2,
                uhadd8(s3, s4),
                s4,
                uhadd8(s4, s5),
                s6,
                uhadd8(s7, s0),
            ];
            for (sum, neighbour) in acc.iter_mut().zip(neighbours) {
                *sum = usada8(t, neighbour, *sum);
            }
        }
    }
    let mut best = (sad, (0, 0));
    for (&sum, &step) in acc.iter().zip(&STEPS) {
        if sum < best.0 {
            best = (sum, step);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    #[test]
    fn block_placement_follows_flow_c() {
        // flow.c: pixLo = r + 1, pixHi = 64 - (r + 1) - 8, pixStep = (pixHi - pixLo) / 5 + 1.
        for radius in 0..=u8::MAX {
            let config = Config {
                search_radius: radius,
                ..Config::default()
            };
            let Ok(matcher) = BlockMatcher::new(config) else {
                assert!(radius > MAX_SEARCH_RADIUS);
                continue;
            };
            let low = usize::from(radius) + 1;
            let high = 64 - low - 8;
            let expected: Vec<usize> = (low..high).step_by((high - low) / 5 + 1).collect();
            let origins: Vec<usize> = matcher.block_origins().map(usize::from).to_vec();
            assert_eq!(origins, expected, "radius {radius}");
            // Every pixel the search and the refinement read lies inside the crop.
            assert!(origins[0] > usize::from(radius));
            assert!(origins[4] + usize::from(radius) + BLOCK + 1 < CROP);
        }
    }

    #[test]
    fn texture_counts_the_central_4x4_differences() {
        // A horizontal ramp of 3 per column: 12 horizontal differences of 3, no vertical.
        let pixels: Vec<u8> = (0..64 * 64).map(|i| ((i % 64) * 3) as u8).collect();
        let view = ImageView::packed(&pixels, 64, 64).unwrap();
        let mut crop = [0; CROP * CROP];
        copy_centre(&view, &mut crop).unwrap();
        assert_eq!(texture(&crop, 5, 5), 12 * 3);
        // A vertical ramp of 5 per row: 12 vertical differences.
        let pixels: Vec<u8> = (0..64 * 64).map(|i| ((i / 64) * 5) as u8).collect();
        let view = ImageView::packed(&pixels, 64, 64).unwrap();
        copy_centre(&view, &mut crop).unwrap();
        assert_eq!(texture(&crop, 15, 25), 12 * 5);
    }

    #[test]
    fn the_crop_is_the_frame_centre() {
        let pixels: Vec<u8> = (0..160 * 120).map(|i| (i % 160 + i / 160) as u8).collect();
        let view = ImageView::packed(&pixels, 160, 120).unwrap();
        let mut crop = [0; CROP * CROP];
        copy_centre(&view, &mut crop).unwrap();
        // (48, 28) of the frame is (0, 0) of the crop.
        assert_eq!(crop[0], (48 + 28) as u8);
        assert_eq!(crop[63 * 64 + 63], (48 + 63 + 28 + 63) as u8);
    }
}
