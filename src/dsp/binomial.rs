//! The innermost operation of the Gaussian pyramid filter: one row of outputs from the five
//! source rows under it, `[1 4 6 4 1]^T [1 4 6 4 1] / 256`, rounded, at every second column.
//!
//! The filter's loop ([`crate::pyramid`]) is the same on every target: it hands each row's inner
//! outputs, whose kernels lie within the row, to [`binomial_row`] and filters the few mirrored
//! columns at the row's two ends itself. [`portable::binomial_row`] is the kernel's one
//! definition, two pixels per 32-bit word, which the Cortex-M4 runs; x86-64 runs SSE2 code
//! instead ([`super::sse2`]), eight outputs a block, which gives the same bytes on every input
//! (the tests below compare them on seeded random rows with the extremes 0 and 255).

/// Outputs `2, 3, ...` of one row into `out`: `out[j]` is the kernel over source columns
/// `2j + 2 ..= 2j + 6` of the five `rows`.
///
/// `out` holds an even number of outputs and each row at least `2 * out.len() + 8` pixels (whole
/// words up to the last pair's kernel): the pyramid's inner outputs always do. Outputs past what
/// the rows hold are left unwritten.
#[inline(always)]
pub(crate) fn binomial_row(rows: &[&[u8]; 5], out: &mut [u8]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        super::sse2::binomial_row(rows, out);
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        portable::binomial_row(rows, out);
    }
}

/// The kernel's definition, on every target: what the Cortex-M4 runs, and the reference that
/// the SSE2 version is held to.
pub(crate) mod portable {
    /// The even and odd columns' vertical sums of four source columns, two 16-bit lanes each.
    // Plain arithmetic, as in `pyramid`: every lane's sum is at most `16 * 255`, below its
    // 16 bits, so no addition carries out of a lane or the word.
    #[allow(clippy::arithmetic_side_effects)]
    #[inline(always)]
    fn vertical_lanes(words: [u32; 5]) -> (u32, u32) {
        const LANES: u32 = 0x00FF_00FF;
        let even = words.map(|w| w & LANES);
        let odd = words.map(|w| (w >> 8) & LANES);
        let sum = |[a, b, c, d, e]: [u32; 5]| a + e + 4 * (b + d) + 6 * c;
        (sum(even), sum(odd))
    }

    /// [`super::binomial_row`], two outputs per source word.
    ///
    /// A word of four source pixels splits into its even and odd columns, two 16-bit lanes
    /// each; the vertical `[1 4 6 4 1]` sums of both lanes take one addition each (a sum is at
    /// most `16 * 255`, so lanes never carry into each other). With `E` and `O` the even and odd
    /// columns' vertical sums, output `x` is `E[x-1] + 4 O[x-1] + 6 E[x] + 4 O[x] + E[x+1]`: two
    /// outputs per word, again one addition per term (at most `256 * 255 + 128 < 2^16`).
    // Plain arithmetic, as in `pyramid`, by the bounds above: the hot loop of the Cortex-M4's
    // pyramid, where checked operations would cost a compare per term; the two output bytes
    // are masked into the low 16 bits before the narrowing cast.
    #[allow(clippy::arithmetic_side_effects, clippy::cast_possible_truncation)]
    #[inline(never)]
    pub(crate) fn binomial_row(rows: &[&[u8]; 5], out: &mut [u8]) {
        let word = |c: &[u8]| c.try_into().map_or(0, u32::from_le_bytes);
        let [r0, r1, r2, r3, r4] = rows.map(|r| r.chunks_exact(4));
        let mut lanes = r0
            .zip(r1)
            .zip(r2)
            .zip(r3.zip(r4))
            .map(|(((a, b), c), (d, e))| vertical_lanes([a, b, c, d, e].map(word)));
        let (Some((mut even, mut odd)), Some((mut next_even, mut next_odd))) =
            (lanes.next(), lanes.next())
        else {
            // Rows of fewer than two words have no inner pairs: the pyramid passes an empty
            // output then, so there is nothing to write.
            debug_assert!(
                out.is_empty(),
                "{} outputs from rows under two words",
                out.len()
            );
            return;
        };
        for (pair, (after_even, after_odd)) in out.chunks_exact_mut(2).zip(lanes) {
            // The previous word's high lane beside this word's low lane, and so on.
            let left = (even >> 16) | (next_even << 16);
            let right = (next_even >> 16) | (after_even << 16);
            let odd_left = (odd >> 16) | (next_odd << 16);
            let sum = left + right + 6 * next_even + 4 * (odd_left + next_odd) + 0x0080_0080;
            let pixels = ((sum >> 8) & 0xFF) | ((sum >> 16) & 0xFF00);
            pair.copy_from_slice(&(pixels as u16).to_le_bytes());
            (even, odd, next_even, next_odd) = (next_even, next_odd, after_even, after_odd);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded xorshift stream of pixels, a quarter of them 0 or 255.
    fn pixels(seed: u32) -> impl Iterator<Item = u8> {
        let mut x = seed;
        core::iter::repeat_with(move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            match x % 8 {
                0 => 0,
                1 => 255,
                _ => (x >> 24) as u8,
            }
        })
    }

    /// Each output is the 5x5 kernel over its columns, and the SSE2 kernel (on x86-64) gives
    /// the portable kernel's bytes, for every output count up to past several SSE2 blocks and
    /// rows from the shortest allowed to several blocks longer.
    #[test]
    fn binomial_rows_agree_with_the_kernel_and_the_reference() {
        const LONGEST: usize = 2 * 48 + 8 + 40;
        let mut source = pixels(0xC0FF_EE11);
        for _ in 0..20 {
            let storage: [[u8; LONGEST]; 5] =
                core::array::from_fn(|_| core::array::from_fn(|_| source.next().unwrap_or(0)));
            for len in (0..=48).step_by(2) {
                // Rows as short as allowed, and longer, as the pyramid's are.
                for extra in [0, 1, 2, 3, 17, 40] {
                    let rows = storage.each_ref().map(|r| &r[..2 * len + 8 + extra]);
                    let mut reference = [0u8; 48];
                    let mut native = [0u8; 48];
                    portable::binomial_row(&rows, &mut reference[..len]);
                    binomial_row(&rows, &mut native[..len]);
                    assert_eq!(reference[..len], native[..len], "{len} outputs, +{extra}");
                    for (j, &o) in reference[..len].iter().enumerate() {
                        let k = [1u32, 4, 6, 4, 1];
                        let sum: u32 = rows
                            .iter()
                            .zip(k)
                            .map(|(r, kj)| {
                                let across: u32 =
                                    (0..5).map(|i| k[i] * u32::from(r[2 * j + 2 + i])).sum();
                                kj * across
                            })
                            .sum();
                        assert_eq!(u32::from(o), (sum + 128) >> 8, "output {j} of {len}");
                    }
                }
            }
        }
    }
}
