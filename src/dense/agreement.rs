//! Whether a grid node moves with the camera, from one comparison instead of an LK search.
//!
//! Most of a frame moves as the camera predicts. At such a node the previous frame's window,
//! moved to the prediction, lies on the next frame's pixels: their zero-mean sum of absolute
//! differences (the *mismatch*) is what noise and 8-bit rounding leave, about half a grey
//! level per pixel. A node that moves on its own by a pixel mismatches by about the window's own
//! *texture*, the sum of absolute differences between neighbouring pixels (the mismatch of a
//! one-pixel shift). So a mismatch within [`NOISE`] (half a grey level) per pixel plus a
//! fraction of the texture confirms the prediction to about that fraction of a pixel, at a
//! tenth of the cost of LK's template and iterations; anything else, and every window flatter
//! than [`MIN_TEXTURE`] (where the noise allowance would hide a pixel of motion), is left to LK.
//!
//! Zero-mean: a uniform change of brightness between the frames (auto exposure) does not count
//! as a mismatch.
//!
//! The work is four pixels per 32-bit word: the next frame is interpolated two pixels per word
//! in 16-bit lanes (weights in sixteenths of a pixel) and rounded back to bytes, and the sums of
//! absolute differences are USADA8's ([`crate::dsp::usada8`]).

use crate::dsp::usada8;
use crate::frame::ImageView;
use crate::q16::Point;

/// The mismatch of a window at its predicted position, and the texture it is judged against,
/// both in grey levels summed over the window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Agreement {
    /// Zero-mean sum of absolute differences between the previous window and the next frame
    /// sampled (bilinear) at the prediction.
    pub mismatch: u32,
    /// The smaller of the window's horizontal and vertical one-pixel self-differences, scaled
    /// to the window's pixels: the mismatch a one-pixel error would cause along the window's
    /// weaker direction.
    pub texture: u32,
    /// The window's pixels: the noise allowance and the texture floor are per pixel.
    pub pixels: u32,
}

/// Mean absolute difference between neighbouring pixels, grey levels, below which the check
/// says nothing: a flat window matches any prediction. At twice [`NOISE`], a window that moves
/// a pixel on its own mismatches by more than the check allows.
pub(crate) const MIN_TEXTURE: u32 = 2;

/// Mismatch per pixel that a right prediction may leave beyond its share of the texture, grey
/// levels Q8 (half a grey level): the 8-bit rounding of both frames and of the interpolation.
/// It lets through a prediction off by up to `NOISE / texture` px more, so that share is at
/// most a quarter of a pixel at [`MIN_TEXTURE`].
pub(crate) const NOISE: u32 = 128;

/// The widest window checked, three words a row; wider ones are left to LK (dense windows are
/// 9 px by default).
pub(crate) const MAX_CHECKED_WINDOW: usize = 12;

/// Words of a row of the widest window.
const MAX_WORDS: usize = MAX_CHECKED_WINDOW.div_ceil(4);

/// The even bytes of a word, as two 16-bit lanes.
const LANES: u32 = 0x00FF_00FF;

impl Agreement {
    /// True when the mismatch is at most [`NOISE`] per pixel plus `tolerance` (Q8: 64 is a
    /// quarter) of the texture: the prediction is right to about that fraction of a pixel
    /// along the weaker direction, plus at most a quarter of a pixel for the noise. Never for a
    /// window flatter than [`MIN_TEXTURE`].
    pub fn confirms(&self, tolerance: u32) -> bool {
        if self.is_flat() {
            return false;
        }
        // The sums are below 12 * 12 * 255 < 2^16 and the tolerance at most 2^8.
        let allowed = u64::from(tolerance) * u64::from(self.texture)
            + u64::from(NOISE) * u64::from(self.pixels);
        u64::from(self.mismatch) << 8 <= allowed
    }

    /// True for a window flatter than [`MIN_TEXTURE`], which the check says nothing about.
    pub fn is_flat(&self) -> bool {
        u64::from(self.texture) < u64::from(MIN_TEXTURE) * u64::from(self.pixels)
    }
}

/// Compares a `win` x `win` window of `prev` around pixel `centre` with `next` sampled where
/// `guess` (the centre's predicted position, Q16) moves it. Near the frame's edges the window
/// slides inward, as far as both frames need, so the border nodes are checked too.
///
/// `None` when no placement fits, or the window is wider than [`MAX_CHECKED_WINDOW`]: the
/// caller falls back to LK.
pub(crate) fn agreement(
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    centre: (usize, usize),
    guess: Point,
    win: usize,
) -> Option<Agreement> {
    if !(2..=MAX_CHECKED_WINDOW).contains(&win) || !prev.same_size(next) {
        return None;
    }
    let words = win.div_ceil(4);
    // The displacement: whole pixels and sixteenths.
    let shift = |to: i32, from: usize| -> Option<(isize, u32)> {
        let from = i32::try_from(from).ok()?.checked_mul(1 << 16)?;
        let d = to.checked_sub(from)?.checked_add(1 << 11)?;
        Some(((d >> 16) as isize, ((d >> 12) & 0xF) as u32))
    };
    let (dx, fx) = shift(guess.x.to_bits(), centre.0)?;
    let (dy, fy) = shift(guess.y.to_bits(), centre.1)?;
    // The previous window's `words` words and the next window's `words + 1`; rows: `win` in
    // the previous frame, `win + 1` in the next.
    let left = place(centre.0, win, dx, (4 * words, 4 * words + 4), prev.width())?;
    let top = place(centre.1, win, dy, (win, win + 1), prev.height())?;
    let (ox, oy) = (left.checked_add_signed(dx)?, top.checked_add_signed(dy)?);
    // Every row of either window, exactly as long as its words need, from one bounds check of
    // each window rather than one per row.
    let (prev_len, next_len) = (4 * words, 4 * words + 4);
    let at = |v: usize| isize::try_from(v).ok();
    let prev_block = prev.block(at(left)?, at(top)?, prev_len, win)?;
    let next_block = next.block(at(ox)?, at(oy)?, next_len, win + 1)?;
    let (prev_stride, next_stride) = (prev.stride(), next.stride());
    let prev_row = |r: usize| prev_block.get(r * prev_stride..r * prev_stride + prev_len);
    let next_row = |r: usize| next_block.get(r * next_stride..r * next_stride + next_len);
    // The bytes of each word inside the window, and inside its first `win - 1` columns.
    let (masks, pair_masks) = (MASKS.get(win)?, MASKS.get(win - 1)?);
    let mut sums = Sums::default();
    let mut stored = [(0u32, 0u32); MAX_WORDS * MAX_CHECKED_WINDOW];
    let mut above_prev = [0u32; MAX_WORDS];
    let mut above_next = row_words(next_row(0)?);
    for (r, out) in stored.chunks_exact_mut(MAX_WORDS).take(win).enumerate() {
        let prev_words = row_words(prev_row(r)?);
        let below_next = row_words(next_row(r + 1)?);
        let mut here = vertical(above_next[0], below_next[0], fy);
        // All MAX_WORDS words, unrolled: those past the window's are masked to nothing.
        for k in 0..MAX_WORDS {
            let right = vertical(above_next[k + 1], below_next[k + 1], fy);
            let n = horizontal(here, right.0, fx) & masks[k];
            here = right;
            let p = prev_words[k] & masks[k];
            // The first row has no row above: it counts nothing down.
            let up = if r == 0 { p } else { above_prev[k] };
            sums.add(n, p, up);
            // Pixel i beside pixel i + 1, over the row's first `win - 1` pixels: the pixels
            // one to the right are this word's last three and the next word's first. Where
            // the pair mask keeps a byte, its right neighbour lies in a complete word.
            let pm = pair_masks[k];
            let shifted = (prev_words[k] >> 8) | (prev_words[k + 1] << 24);
            sums.across = usada8(p & pm, shifted & pm, sums.across);
            out[k] = (n, p);
            above_prev[k] = p;
        }
        above_next = below_next;
    }
    let pixels = u32::try_from(win * win).ok()?;
    let mismatch = sums.zero_mean_sad(&stored, words, win, masks)?;
    // `win * (win - 1)` pairs each way, scaled to the window's `win * win` pixels.
    let texture = sums.across.min(sums.down) * pixels / u32::try_from(win * (win - 1)).ok()?;
    Some(Agreement {
        mismatch,
        texture,
        pixels,
    })
}

/// Where a window of `win` px around `centre` starts along one axis so that it needs `span.0`
/// px of the previous frame from there and `span.1` px of the next from `displacement` further
/// on, both within `0..size`: as centred as the frame allows.
fn place(
    centre: usize,
    win: usize,
    displacement: isize,
    (prev_span, next_span): (usize, usize),
    size: usize,
) -> Option<usize> {
    let lowest = usize::try_from(-displacement).unwrap_or(0);
    let highest = size.checked_sub(prev_span)?.min(
        size.checked_sub(next_span)?
            .checked_add_signed(-displacement)?,
    );
    let wanted = centre.saturating_sub(win / 2);
    (lowest <= highest).then(|| wanted.clamp(lowest, highest))
}

/// The bytes of word `k` of a row that lie in its first `len` pixels.
const fn mask(len: usize, k: usize) -> u32 {
    let valid = len.saturating_sub(4 * k);
    let valid = if valid > 4 { 4 } else { valid as u32 };
    match u32::MAX.checked_shr(32 - 8 * valid) {
        Some(m) => m,
        None => 0,
    }
}

/// [`mask`] of every word, for every row length up to [`MAX_CHECKED_WINDOW`]: the window's
/// length is checked once per node, the masks not computed again.
const MASKS: [[u32; MAX_WORDS]; MAX_CHECKED_WINDOW + 1] = {
    let mut masks = [[0; MAX_WORDS]; MAX_CHECKED_WINDOW + 1];
    let mut len = 0;
    while len <= MAX_CHECKED_WINDOW {
        let mut k = 0;
        while k < MAX_WORDS {
            masks[len][k] = mask(len, k);
            k += 1;
        }
        len += 1;
    }
    masks
};

/// The running sums of one window.
#[derive(Default)]
struct Sums {
    /// Grey levels of the previous window and of the sampled next one.
    prev: u32,
    next: u32,
    /// Absolute differences between them, before the mean difference is taken out.
    sad: u32,
    /// Absolute differences between horizontal and vertical neighbours of the previous window.
    across: u32,
    down: u32,
}

impl Sums {
    /// Adds the words `n` (sampled) and `p` (previous) of one row, with `above`, the previous
    /// window's word one row up (`p` itself on the first row).
    #[inline(always)]
    fn add(&mut self, n: u32, p: u32, above: u32) {
        self.prev = usada8(p, 0, self.prev);
        self.next = usada8(n, 0, self.next);
        self.sad = usada8(n, p, self.sad);
        self.down = usada8(p, above, self.down);
    }

    /// The sum of absolute differences less the mean difference, rounded to a grey level:
    /// the plain sum when that rounds to 0, else a second pass over the `stored` word pairs.
    fn zero_mean_sad(
        &self,
        stored: &[(u32, u32)],
        words: usize,
        win: usize,
        masks: &[u32; MAX_WORDS],
    ) -> Option<u32> {
        let pixels = i32::try_from(win * win).ok()?;
        let difference = i32::try_from(self.next).ok()? - i32::try_from(self.prev).ok()?;
        let bias = (2 * difference + difference.signum() * pixels) / (2 * pixels);
        if bias == 0 {
            return Some(self.sad);
        }
        let rows = stored.chunks_exact(MAX_WORDS).take(win);
        let words = rows.flat_map(|row| row.iter().zip(masks).take(words));
        Some(words.fold(0, |acc, (&(n, p), &m)| biased_sad(n, p, bias, m, acc)))
    }
}

/// The first `MAX_WORDS + 1` little-endian words of a row's pixels, 0 past its end.
#[inline(always)]
fn row_words(pixels: &[u8]) -> [u32; MAX_WORDS + 1] {
    core::array::from_fn(|k| {
        let chunk = pixels.get(4 * k..4 * k + 4);
        chunk
            .and_then(|c| c.try_into().ok())
            .map_or(0, u32::from_le_bytes)
    })
}

/// Rows `a` over `b` mixed `16 - fy : fy`: the even pixels' and the odd pixels' 16-bit lanes,
/// grey x 16 (at most 4,080, so no lane carries into the next).
#[inline(always)]
fn vertical(a: u32, b: u32, fy: u32) -> (u32, u32) {
    let even = (a & LANES) * (16 - fy) + (b & LANES) * fy;
    let odd = ((a >> 8) & LANES) * (16 - fy) + ((b >> 8) & LANES) * fy;
    (even, odd)
}

/// Four pixels mixed `16 - fx : fx` with their right neighbours, from the vertical lanes of
/// their word and the even lanes of the next word, rounded to bytes.
#[inline(always)]
fn horizontal((even, odd): (u32, u32), next_even: u32, fx: u32) -> u32 {
    // Pixels 2 and 4 of the word: the right neighbours of the odd pixels 1 and 3.
    let shifted = (even >> 16) | (next_even << 16);
    // Each lane at most 16 * 4,080 = 65,280, plus the rounding: below 2^16.
    let round = 0x0080_0080;
    let even_out = even * (16 - fx) + odd * fx + round;
    let odd_out = odd * (16 - fx) + shifted * fx + round;
    ((even_out >> 8) & LANES) | (((odd_out >> 8) & LANES) << 8)
}

/// `acc` plus the sum of `|n - p - bias|` over the bytes of `mask`.
fn biased_sad(n: u32, p: u32, bias: i32, mask: u32, acc: u32) -> u32 {
    let bytes = n.to_le_bytes().into_iter().zip(p.to_le_bytes());
    let used = mask.to_le_bytes().into_iter().map(|m| m != 0);
    bytes
        .zip(used)
        .filter(|&(_, used)| used)
        .map(|((n, p), _)| (i32::from(n) - i32::from(p) - bias).unsigned_abs())
        .fold(acc, |acc, d| acc + d)
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: usize = 48;
    const H: usize = 40;

    /// Smooth texture in both axes, moved by `(dx, dy)`, with a brightness offset `bias`.
    fn scene(dx: f32, dy: f32, bias: f32) -> [u8; W * H] {
        core::array::from_fn(|i| {
            let (x, y) = ((i % W) as f32 - dx, (i / W) as f32 - dy);
            let v = 120.0
                + bias
                + 50.0 * (0.45 * x).sin() * (0.35 * y).cos()
                + 25.0 * (0.2 * (x + y)).sin();
            v.round().clamp(0.0, 255.0) as u8
        })
    }

    fn check(moved: (f32, f32), predicted: (f32, f32), bias: f32) -> Agreement {
        let (a, b) = (scene(0.0, 0.0, 0.0), scene(moved.0, moved.1, bias));
        let prev = ImageView::packed(&a, W, H).unwrap();
        let next = ImageView::packed(&b, W, H).unwrap();
        let centre = (24, 20);
        let guess = Point::from_f32(24.0 + predicted.0, 20.0 + predicted.1);
        agreement(&prev, &next, centre, guess, 9).unwrap()
    }

    #[test]
    fn a_right_prediction_is_confirmed_and_a_wrong_one_is_not() {
        let quarter = 64;
        let right = check((1.3, -0.6), (1.3, -0.6), 0.0);
        assert!(right.confirms(quarter), "{right:?}");
        assert!(right.mismatch * 5 < right.texture, "{right:?}");
        // Off by a pixel: the mismatch is about the texture.
        let wrong = check((1.3, -0.6), (0.3, -0.6), 0.0);
        assert!(!wrong.confirms(quarter), "{wrong:?}");
        // Off by half a pixel: still refused at a quarter.
        let half = check((1.3, -0.6), (1.3, -0.1), 0.0);
        assert!(!half.confirms(quarter), "{half:?}");
    }

    #[test]
    fn a_uniform_brightness_change_is_not_a_mismatch() {
        let brighter = check((0.7, 0.2), (0.7, 0.2), 30.0);
        assert!(brighter.confirms(64), "{brighter:?}");
    }

    #[test]
    fn flat_windows_and_predictions_off_the_frame_are_left_to_lk() {
        let flat = [90u8; W * H];
        let view = ImageView::packed(&flat, W, H).unwrap();
        let guess = Point::from_f32(24.5, 20.0);
        let a = agreement(&view, &view, (24, 20), guess, 9).unwrap();
        assert!(!a.confirms(64), "{a:?}");
        // A prediction that leaves no room for both windows, and a window too wide.
        let off = Point::from_f32(74.5, 20.0);
        assert_eq!(agreement(&view, &view, (24, 20), off, 9), None);
        assert_eq!(agreement(&view, &view, (24, 20), guess, 13), None);
    }

    #[test]
    fn sampling_matches_bilinear_interpolation_in_f32() {
        // `prev` is `next` resampled in f32 at a shift of whole sixteenths: the check's own
        // sampling of `next` at that shift must give back the same bytes, up to rounding.
        let next = scene(0.0, 0.0, 0.0);
        let next_view = ImageView::packed(&next, W, H).unwrap();
        for (win, (dx, dy)) in [
            (9, (1.25, -0.5625)),
            (7, (0.0625, 2.875)),
            (11, (-1.5, 0.3125)),
            (12, (0.5, 0.5)),
            (5, (0.0, 0.0)),
        ] {
            let px = |x: usize, y: usize| f32::from(next_view.get(x, y).unwrap_or(0));
            let prev: [u8; W * H] = core::array::from_fn(|i| {
                let (x, y) = ((i % W) as f32 + dx, (i / W) as f32 + dy);
                let (x0, y0) = (x.floor().max(0.0) as usize, y.floor().max(0.0) as usize);
                let (tx, ty) = (x - x.floor(), y - y.floor());
                let top = px(x0, y0) * (1.0 - tx) + px(x0 + 1, y0) * tx;
                let bottom = px(x0, y0 + 1) * (1.0 - tx) + px(x0 + 1, y0 + 1) * tx;
                (top * (1.0 - ty) + bottom * ty).round() as u8
            });
            let prev_view = ImageView::packed(&prev, W, H).unwrap();
            let guess = Point::from_f32(24.0 + dx, 20.0 + dy);
            let a = agreement(&prev_view, &next_view, (24, 20), guess, win).unwrap();
            // Rounding apart, the bytes agree: at most one grey level at a quarter of them.
            assert!(a.mismatch * 4 <= a.pixels, "win {win}: {a:?}");
            assert!(a.texture > 2 * a.pixels, "win {win}: {a:?}");
        }
    }

    #[test]
    fn texture_is_the_smaller_sum_of_neighbour_differences() {
        // Seeded noise, every checked window size: the word-wise sums equal the plain ones.
        let mut state = 7u32;
        let pixels: [u8; W * H] = core::array::from_fn(|_| {
            state = state.wrapping_mul(1_103_515_245).wrapping_add(12_345);
            (state >> 16) as u8
        });
        let view = ImageView::packed(&pixels, W, H).unwrap();
        let centre = (24, 20);
        for win in 2..=MAX_CHECKED_WINDOW {
            let guess = Point::from_f32(24.0, 20.0);
            let found = agreement(&view, &view, centre, guess, win).unwrap();
            let (left, top) = (centre.0 - win / 2, centre.1 - win / 2);
            let px = |x: usize, y: usize| i32::from(pixels[(top + y) * W + left + x]);
            let (mut across, mut down) = (0, 0);
            for y in 0..win {
                for x in 0..win {
                    if x + 1 < win {
                        across += (px(x, y) - px(x + 1, y)).unsigned_abs();
                    }
                    if y + 1 < win {
                        down += (px(x, y) - px(x, y + 1)).unsigned_abs();
                    }
                }
            }
            let pixels = (win * win) as u32;
            let expected = across.min(down) * pixels / (win * (win - 1)) as u32;
            assert_eq!(found.texture, expected, "win {win}");
            assert_eq!((found.mismatch, found.pixels), (0, pixels), "win {win}");
        }
    }

    #[test]
    fn nodes_at_the_frame_edges_are_checked_from_a_window_moved_inward() {
        let (a, b) = (scene(0.0, 0.0, 0.0), scene(0.8, 0.4, 0.0));
        let prev = ImageView::packed(&a, W, H).unwrap();
        let next = ImageView::packed(&b, W, H).unwrap();
        for centre in [(0, 0), (W - 1, 0), (0, H - 1), (W - 1, H - 1), (3, 20)] {
            let guess = Point::from_f32(centre.0 as f32 + 0.8, centre.1 as f32 + 0.4);
            let found = agreement(&prev, &next, centre, guess, 9).unwrap();
            assert!(found.confirms(64), "{centre:?}: {found:?}");
        }
    }
}
