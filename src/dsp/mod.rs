//! Cortex-M4 DSP instructions on packed words: sums of absolute byte differences, halving byte
//! adds and dual 16-bit multiply-adds; and the kernels built on them that the LK window loops
//! and the pyramid filter run innermost, in SSE2 on x86-64.
//!
//! This is the one module of the crate with `unsafe` code, and the one home of code that
//! differs by target: `asm!` for the Cortex-M4 here, SSE2 intrinsics for x86-64 in `sse2`,
//! each with its portable version as the reference that tests compare it with bit for bit.
//!
//! The Cortex-M4 and M7 (ARMv7E-M) do four byte or two halfword operations in one instruction,
//! which LLVM does not emit from plain Rust: a SAD loop compiles to byte loads and subtractions,
//! never to USADA8. Each function here is that instruction where the target has it and its
//! portable equivalent elsewhere; [`portable`] holds the portable versions on every target, as
//! the reference that tests and the firmware compare the instructions with, bit for bit.
//!
//! The instructions are used on targets with the DSP extension: every `thumbv7em-*` target
//! (the crate's build script sets `cfg(kestrel_dsp)` for them, since stable Rust does not
//! expose `target_feature = "dsp"` to `cfg`), and [`ASM`] says whether this build does.
//!
//! Words hold their lanes little-endian, as `u32::from_le_bytes` reads four pixels of a row:
//! byte 0 (bits 0-7) is the first pixel, halfword 0 (bits 0-15) the low half.
//!
//! ```
//! use kestrel::dsp;
//! // The SAD of 8 pixels: two words per row.
//! let prev = [10u8, 20, 30, 40, 50, 60, 70, 80];
//! let next = [12u8, 18, 30, 45, 50, 50, 70, 90];
//! let word = |row: &[u8; 8], i: usize| u32::from_le_bytes([row[i], row[i + 1], row[i + 2], row[i + 3]]);
//! let sad = dsp::usada8(word(&prev, 0), word(&next, 0), 0);
//! let sad = dsp::usada8(word(&prev, 4), word(&next, 4), sad);
//! assert_eq!(sad, 2 + 2 + 0 + 5 + 0 + 10 + 0 + 10);
//! ```

/// True when this build runs the DSP instructions themselves, false when it runs [`portable`].
///
/// ```
/// // Off ARM the functions are the portable versions; a thumbv7em build runs the instructions.
/// #[cfg(not(target_arch = "arm"))]
/// assert!(!kestrel::dsp::ASM);
/// ```
pub const ASM: bool = cfg!(all(target_arch = "arm", kestrel_dsp));

pub(crate) mod binomial;
pub(crate) mod runs;
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
mod sse2;

/// USADA8: `acc` plus the sum of the absolute differences of the four bytes of `a` and `b`.
///
/// The sum wraps modulo 2^32, as the instruction's does (it cannot wrap unless `acc` is within
/// 1020 of `u32::MAX`).
///
/// ```
/// use kestrel::dsp::usada8;
/// assert_eq!(usada8(0x01_02_03_04, 0x04_03_02_01, 100), 100 + 3 + 1 + 1 + 3);
/// assert_eq!(usada8(0xFFFF_FFFF, 0, 0), 4 * 255);
/// assert_eq!(usada8(0xFFFF_FFFF, 0, u32::MAX), 4 * 255 - 1);
/// ```
#[inline(always)]
pub fn usada8(a: u32, b: u32, acc: u32) -> u32 {
    #[cfg(all(target_arch = "arm", kestrel_dsp))]
    {
        instructions::usada8(a, b, acc)
    }
    #[cfg(not(all(target_arch = "arm", kestrel_dsp)))]
    {
        portable::usada8(a, b, acc)
    }
}

/// UHADD8: the halving add of each byte pair, `(a_i + b_i) >> 1`, truncating as the
/// instruction does (the sum is formed in 9 bits, so it never saturates).
///
/// ```
/// use kestrel::dsp::uhadd8;
/// assert_eq!(uhadd8(0x01_FF_10_03, 0x02_FF_20_00), 0x01_FF_18_01);
/// ```
#[inline(always)]
pub fn uhadd8(a: u32, b: u32) -> u32 {
    #[cfg(all(target_arch = "arm", kestrel_dsp))]
    {
        instructions::uhadd8(a, b)
    }
    #[cfg(not(all(target_arch = "arm", kestrel_dsp)))]
    {
        portable::uhadd8(a, b)
    }
}

/// SMLAD: `acc + lo16(a) * lo16(b) + hi16(a) * hi16(b)`, with the halves as signed 16-bit
/// numbers.
///
/// The sum wraps modulo 2^32, as the instruction's does: SMLAD forms the exact sum, keeps its
/// low 32 bits and sets the sticky Q flag on signed overflow (not reported here). Only the
/// products of two -32768 halves, or a large `acc`, can overflow: 2 x (-32768)^2 is 2^31.
///
/// ```
/// use kestrel::dsp::smlad;
/// // (3, -2) . (5, 7) + 1 = 15 - 14 + 1, halves written (lo, hi).
/// let a = u32::from_le_bytes([3, 0, 0xFE, 0xFF]); // lo 3, hi -2
/// let b = u32::from_le_bytes([5, 0, 7, 0]); // lo 5, hi 7
/// assert_eq!(smlad(a, b, 1), 2);
/// // The one product pair that overflows wraps to i32::MIN.
/// assert_eq!(smlad(0x8000_8000, 0x8000_8000, 0), i32::MIN);
/// ```
#[inline(always)]
pub fn smlad(a: u32, b: u32, acc: i32) -> i32 {
    #[cfg(all(target_arch = "arm", kestrel_dsp))]
    {
        instructions::smlad(a, b, acc)
    }
    #[cfg(not(all(target_arch = "arm", kestrel_dsp)))]
    {
        portable::smlad(a, b, acc)
    }
}

/// `floor(2^63 / v)` for `v` in `(2^31, 2^32)`, the reciprocal LK's 2x2 solve scales by: one
/// 64-bit division on x86-64, [`portable::div_2_63`]'s long division in 16-bit digits
/// elsewhere (a Cortex-M4 divides 32 bits by 32 in hardware, 64 bits in a library routine of
/// some two hundred instructions). The same quotient on every target.
#[inline(always)]
pub(crate) fn div_2_63(v: u32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        // Below 2^32 for v > 2^31.
        #[allow(clippy::cast_possible_truncation)]
        let quotient = (1u64 << 63).checked_div(u64::from(v)).unwrap_or(0) as u32;
        quotient
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        portable::div_2_63(v)
    }
}

/// The portable versions: the reference semantics of each instruction, on every target.
///
/// ```
/// use kestrel::dsp;
/// let (a, b) = (0x8000_7FFF, 0x7FFF_8000);
/// assert_eq!(dsp::usada8(a, b, 7), dsp::portable::usada8(a, b, 7));
/// assert_eq!(dsp::uhadd8(a, b), dsp::portable::uhadd8(a, b));
/// assert_eq!(dsp::smlad(a, b, 7), dsp::portable::smlad(a, b, 7));
/// ```
pub mod portable {
    /// [`super::usada8`] in plain Rust: `acc` plus the byte-wise absolute differences.
    ///
    /// ```
    /// use kestrel::dsp::portable::usada8;
    /// assert_eq!(usada8(0x00_00_00_FF, 0x00_00_01_00, 1), 1 + 255 + 1);
    /// ```
    #[inline(always)]
    pub fn usada8(a: u32, b: u32, acc: u32) -> u32 {
        a.to_le_bytes()
            .into_iter()
            .zip(b.to_le_bytes())
            .fold(acc, |sum, (x, y)| {
                sum.wrapping_add(u32::from(x.abs_diff(y)))
            })
    }

    /// [`super::uhadd8`] in plain Rust, all four lanes at once: `a + b = 2 (a & b) + (a ^ b)`
    /// per byte, so the halved sum is `(a & b) + ((a ^ b) >> 1)`, with the bit that the shift
    /// moves across each lane boundary masked off. No lane can carry into the next.
    ///
    /// ```
    /// use kestrel::dsp::portable::uhadd8;
    /// assert_eq!(uhadd8(0xFF_01_80_00, 0xFF_00_80_01), 0xFF_00_80_00);
    /// ```
    #[inline(always)]
    pub fn uhadd8(a: u32, b: u32) -> u32 {
        // Each lane of the sum is at most 255: the addition never carries or wraps.
        (a & b).wrapping_add(((a ^ b) >> 1) & 0x7F7F_7F7F)
    }

    /// [`super::smlad`] in plain Rust, wrapping modulo 2^32 as the instruction does.
    ///
    /// ```
    /// use kestrel::dsp::portable::smlad;
    /// assert_eq!(smlad(0x0002_FFFF, 0x0003_0004, 10), 10 - 4 + 6);
    /// assert_eq!(smlad(0x8000_8000, 0x8000_8000, -1), i32::MAX);
    /// ```
    #[inline(always)]
    pub fn smlad(a: u32, b: u32, acc: i32) -> i32 {
        let (a_lo, a_hi) = halves(a);
        let (b_lo, b_hi) = halves(b);
        // Each product is exact in i32 (at most 2^30); only the sums can wrap, and wrapping
        // each addition gives the exact sum modulo 2^32.
        let low = a_lo.wrapping_mul(b_lo);
        let high = a_hi.wrapping_mul(b_hi);
        acc.wrapping_add(low).wrapping_add(high)
    }

    /// `floor(2^63 / v)` for `v` in `(2^31, 2^32)`, by long division in 16-bit digits (Knuth's
    /// algorithm D with a normalised divisor): two 32 / 32-bit hardware divisions, where a 64-bit
    /// division is a library routine of some two hundred instructions on a Cortex-M4.
    #[allow(clippy::arithmetic_side_effects, clippy::cast_possible_truncation)]
    #[cfg_attr(target_arch = "x86_64", allow(dead_code))]
    pub(crate) fn div_2_63(v: u32) -> u32 {
        const B: u64 = 1 << 16;
        let (high, low) = (v >> 16, u64::from(v & 0xFFFF));
        // One 16-bit quotient digit of `top * 2^16 / v` (`top < v`, so 32 bits), with its estimate
        // from the divisor's high half corrected down (by at most two).
        let digit = |top: u32| {
            let (mut q, mut r) = (u64::from(top / high), u64::from(top % high));
            let top = u64::from(top);
            while q >= B || q * low > B * r {
                q -= 1;
                r += u64::from(high);
                if r >= B {
                    break;
                }
            }
            // The remainder is below the divisor: 32 bits.
            (q, (top * B - q * u64::from(v)) as u32)
        };
        // The dividend 2^63 is the digits [2^31 : 0 : 0] in base 2^16 over a 32-bit divisor.
        let (q1, rest) = digit(1 << 31);
        let (q0, _) = digit(rest);
        (q1 * B + q0) as u32
    }

    /// The signed low and high halfwords of `word`.
    #[inline(always)]
    fn halves(word: u32) -> (i32, i32) {
        let [b0, b1, b2, b3] = word.to_le_bytes();
        (
            i32::from(i16::from_le_bytes([b0, b1])),
            i32::from(i16::from_le_bytes([b2, b3])),
        )
    }
}

/// The instructions themselves.
///
/// Each `asm!` block is one register-to-register instruction: it reads its input registers and
/// writes its output register, touches no memory and no stack (`pure, nomem, nostack`), so it
/// cannot break any of Rust's memory guarantees. USADA8 and UHADD8 leave the flags alone
/// (`preserves_flags`); SMLAD may set the sticky Q flag, so it does not claim to.
#[cfg(all(target_arch = "arm", kestrel_dsp))]
mod instructions {
    use core::arch::asm;

    #[inline(always)]
    pub(super) fn usada8(a: u32, b: u32, acc: u32) -> u32 {
        let result: u32;
        // SAFETY: a register-only instruction, see the module's documentation.
        unsafe {
            asm!(
                "usada8 {result}, {a}, {b}, {acc}",
                result = lateout(reg) result,
                a = in(reg) a,
                b = in(reg) b,
                acc = in(reg) acc,
                options(pure, nomem, nostack, preserves_flags),
            );
        }
        result
    }

    #[inline(always)]
    pub(super) fn uhadd8(a: u32, b: u32) -> u32 {
        let result: u32;
        // SAFETY: a register-only instruction, see the module's documentation.
        unsafe {
            asm!(
                "uhadd8 {result}, {a}, {b}",
                result = lateout(reg) result,
                a = in(reg) a,
                b = in(reg) b,
                options(pure, nomem, nostack, preserves_flags),
            );
        }
        result
    }

    #[inline(always)]
    pub(super) fn smlad(a: u32, b: u32, acc: i32) -> i32 {
        let result: i32;
        // SAFETY: a register-only instruction, see the module's documentation.
        unsafe {
            asm!(
                "smlad {result}, {a}, {b}, {acc}",
                result = lateout(reg) result,
                a = in(reg) a,
                b = in(reg) b,
                acc = in(reg) acc,
                options(pure, nomem, nostack),
            );
        }
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Words where lanes saturate, change sign or sit at their ends.
    const EXTREMES: [u32; 12] = [
        0,
        0xFFFF_FFFF,
        0x8000_8000,
        0x7FFF_7FFF,
        0x8000_7FFF,
        0x7FFF_8000,
        0x0001_0001,
        0xFFFF_0001,
        0x8080_8080,
        0x7F7F_7F7F,
        0x0101_0101,
        0xFEFE_FEFE,
    ];

    /// A seeded SplitMix64 stream of words.
    fn words(seed: u64) -> impl Iterator<Item = u32> {
        let mut state = seed;
        core::iter::repeat_with(move || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 32) as u32
        })
    }

    /// Every pair of extremes, then many seeded random triples.
    fn cases() -> impl Iterator<Item = (u32, u32, u32)> {
        let extremes = EXTREMES.iter().flat_map(|&a| {
            EXTREMES
                .iter()
                .flat_map(move |&b| EXTREMES.map(|c| (a, b, c)))
        });
        let mut random = words(0x5EED);
        let random = core::iter::repeat_with(move || {
            let a = random.next().unwrap();
            let b = random.next().unwrap();
            (a, b, random.next().unwrap())
        });
        extremes.chain(random.take(1_000_000))
    }

    fn byte(word: u32, i: u32) -> i64 {
        i64::from((word >> (8 * i)) & 0xFF)
    }

    fn half(word: u32, i: u32) -> i64 {
        let h = (word >> (16 * i)) & 0xFFFF;
        if h >= 0x8000 {
            i64::from(h) - 0x1_0000
        } else {
            i64::from(h)
        }
    }

    #[test]
    fn usada8_is_the_byte_wise_sad_plus_acc() {
        for (a, b, acc) in cases() {
            let sad: i64 = (0..4).map(|i| (byte(a, i) - byte(b, i)).abs()).sum();
            let expected = ((i64::from(acc) + sad) % (1 << 32)) as u32;
            assert_eq!(
                portable::usada8(a, b, acc),
                expected,
                "{a:#x} {b:#x} {acc:#x}"
            );
            assert_eq!(usada8(a, b, acc), expected);
        }
    }

    #[test]
    fn uhadd8_halves_each_byte_sum() {
        for (a, b, _) in cases() {
            let expected = (0..4).fold(0u32, |word, i| {
                word | (((byte(a, i) + byte(b, i)) >> 1) as u32) << (8 * i)
            });
            assert_eq!(portable::uhadd8(a, b), expected, "{a:#x} {b:#x}");
            assert_eq!(uhadd8(a, b), expected);
        }
    }

    #[test]
    fn smlad_is_the_dual_signed_product_sum_modulo_2_32() {
        for (a, b, acc) in cases() {
            let acc = acc as i32;
            let exact = i64::from(acc) + half(a, 0) * half(b, 0) + half(a, 1) * half(b, 1);
            // The low 32 bits of the exact sum, as a signed number.
            let expected = exact.rem_euclid(1 << 32) as u32 as i32;
            assert_eq!(portable::smlad(a, b, acc), expected, "{a:#x} {b:#x} {acc}");
            assert_eq!(smlad(a, b, acc), expected);
        }
    }

    #[test]
    fn the_extremes_give_the_instruction_results() {
        assert_eq!(usada8(0, 0xFFFF_FFFF, 0), 1020);
        assert_eq!(usada8(0xFFFF_FFFF, 0, u32::MAX - 1019), 0);
        assert_eq!(uhadd8(0xFFFF_FFFF, 0xFFFF_FFFF), 0xFFFF_FFFF);
        assert_eq!(uhadd8(0xFFFF_FFFF, 0), 0x7F7F_7F7F);
        assert_eq!(smlad(0x7FFF_7FFF, 0x7FFF_7FFF, 0), 2 * 32767 * 32767);
        assert_eq!(smlad(0x8000_8000, 0x7FFF_7FFF, 0), -2 * 32768 * 32767);
        assert_eq!(smlad(0x8000_8000, 0x8000_8000, 0), i32::MIN);
        assert_eq!(
            smlad(0x7FFF_7FFF, 0x7FFF_7FFF, i32::MAX),
            i32::MAX.wrapping_add(2 * 32767 * 32767)
        );
    }
}
