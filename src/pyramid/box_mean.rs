//! The 2 x 2 box-mean level filter ([`super::PyramidFilter::Box`]), by UHADD8.

use super::Downsample;
use crate::frame::ImageView;

/// [`super::PyramidFilter::Box`]: each output pixel is `avg(avg(a, c), avg(b, d))` of its 2 x 2
/// block `[a b; c d]`, with `avg` the truncating halving add; four output pixels per pair of
/// source words with [`crate::dsp::uhadd8`].
pub(super) struct BoxMean;

impl Downsample for BoxMean {
    fn downsample(src: &ImageView<'_>, dst: &mut [u8], w: usize, h: usize) {
        let (sw, sh) = (src.width(), src.height());
        // Output columns 0..whole come from whole source words.
        let whole = (sw / 8) * 4;
        for (y, out_row) in dst.chunks_exact_mut(w).take(h).enumerate() {
            let top = src.row(2 * y);
            let bottom = src.row((2 * y + 1).min(sh - 1));
            let (words, rest) = out_row.split_at_mut(whole.min(w));
            box_words(top, bottom, words);
            for (k, o) in rest.iter_mut().enumerate() {
                let x = 2 * (whole + k);
                let px =
                    |row: &[u8], x: usize| u32::from(row.get(x.min(sw - 1)).copied().unwrap_or(0));
                let (a, b) = (px(top, x), px(top, x + 1));
                let (c, d) = (px(bottom, x), px(bottom, x + 1));
                *o = (((a + c) / 2 + (b + d) / 2) / 2) as u8;
            }
        }
    }
}

/// Four output pixels per two source words of each row: the vertical halving adds of the
/// words, then the horizontal ones of their even and odd bytes.
#[inline(never)]
fn box_words(top: &[u8], bottom: &[u8], out: &mut [u8]) {
    use crate::dsp::uhadd8;
    const EVEN: u32 = 0x00FF_00FF;
    let word = |c: &[u8]| c.try_into().map_or(0, u32::from_le_bytes);
    let pairs = top.chunks_exact(8).zip(bottom.chunks_exact(8));
    for (quad, (t, b)) in out.chunks_exact_mut(4).zip(pairs) {
        let (t0, t1) = t.split_at(4);
        let (b0, b1) = b.split_at(4);
        let columns = |t: &[u8], b: &[u8]| {
            let v = uhadd8(word(t), word(b));
            // Lanes 0 and 2 hold the two outputs of these four columns.
            uhadd8(v & EVEN, (v >> 8) & EVEN)
        };
        let (low, high) = (columns(t0, b0), columns(t1, b1));
        let pixels = (low & 0xFF)
            | ((low >> 8) & 0xFF00)
            | ((high & 0xFF) << 16)
            | ((high << 8) & 0xFF00_0000);
        quad.copy_from_slice(&pixels.to_le_bytes());
    }
}
