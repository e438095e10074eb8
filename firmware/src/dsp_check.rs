//! The Cortex-M4 DSP instructions of `kestrel::dsp` against their portable versions, bit for
//! bit, once at boot: every function on every triple of extreme words, then on seeded random
//! words. Any mismatch, or a library built without the instructions, fails the run.

use cortex_m_semihosting::hprintln;
use kestrel::dsp::{self, portable, smlad, uhadd8, usada8};

/// Random triples per function after the extremes.
const RANDOM_CASES: u32 = 300_000;
/// Mismatches printed in full before the rest are only counted.
const PRINTED_MISMATCHES: u32 = 8;

/// Words where lanes saturate, change sign or sit at their ends.
const EXTREMES: [u32; 14] = [
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
    0x00FF_00FF,
    0xFF00_FF00,
];

/// Compares the three functions on `RANDOM_CASES` random triples and every triple of
/// `EXTREMES`, prints `dsp_check usada8=N uhadd8=N smlad=N mismatches=M asm=B` and returns
/// whether there was no mismatch and the instructions were used.
// Never inlined, so that bench/target_profile.py can leave it out of the budget run's profile.
#[inline(never)]
pub fn run() -> bool {
    let mut check = Check::default();
    for &a in &EXTREMES {
        for &b in &EXTREMES {
            for &c in &EXTREMES {
                check.case(a, b, c);
            }
        }
    }
    let mut random = XorShift32(0x6B65_7374); // "kest"
    for _ in 0..RANDOM_CASES {
        let (a, b, c) = (random.next(), random.next(), random.next());
        check.case(a, b, c);
    }
    hprintln!(
        "dsp_check usada8={} uhadd8={} smlad={} mismatches={} asm={}",
        check.cases,
        check.cases,
        check.cases,
        check.mismatches,
        dsp::ASM,
    );
    if !dsp::ASM {
        hprintln!("error dsp_check: kestrel was built without the DSP instructions");
    }
    check.mismatches == 0 && dsp::ASM
}

/// Cases compared per function so far, and mismatches over all three.
#[derive(Default)]
struct Check {
    cases: u32,
    mismatches: u32,
}

impl Check {
    /// Compares every function on `(a, b, c)`; `c` is the accumulator of USADA8 and SMLAD.
    #[inline(always)]
    fn case(&mut self, a: u32, b: u32, c: u32) {
        self.cases += 1;
        let inputs = [a, b, c];
        self.compare("usada8", inputs, usada8(a, b, c), portable::usada8(a, b, c));
        self.compare("uhadd8", [a, b, 0], uhadd8(a, b), portable::uhadd8(a, b));
        let acc = c as i32;
        let (asm, reference) = (smlad(a, b, acc), portable::smlad(a, b, acc));
        self.compare("smlad", inputs, asm as u32, reference as u32);
    }

    #[inline(always)]
    fn compare(&mut self, name: &str, [a, b, c]: [u32; 3], asm: u32, portable: u32) {
        if asm != portable {
            if self.mismatches < PRINTED_MISMATCHES {
                hprintln!(
                    "error dsp_check {} a={:#010x} b={:#010x} acc={:#010x} asm={:#010x} \
                     portable={:#010x}",
                    name,
                    a,
                    b,
                    c,
                    asm,
                    portable
                );
            }
            self.mismatches += 1;
        }
    }
}

/// Marsaglia's xorshift32: a fixed seed gives the same words on every run.
struct XorShift32(u32);

impl XorShift32 {
    #[inline(always)]
    fn next(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }
}
