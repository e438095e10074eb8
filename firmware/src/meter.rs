//! Counting executed instructions with SysTick.
//!
//! QEMU has no cycle counter (DWT reads 0). Under `-icount shift=0` every instruction advances
//! virtual time by exactly 1 ns, and SysTick on its external reference clock (HCLK / 8 = 21 MHz
//! on the netduinoplus2 model) ticks every 1000 / 21 = 47.62 instructions, deterministically.
//! [`calibrate`] checks that ratio against a loop of known length at every boot.

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;

/// SysTick is a 24-bit down-counter.
const COUNTER_MASK: u32 = 0x00FF_FFFF;
/// Instructions per 21 reference-clock ticks: 1 ns per instruction, 21 ticks per microsecond.
const INSTRUCTIONS_PER_21_TICKS: u64 = 1000;

/// SysTick ticks: the raw measure; convert with [`instructions`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord)]
pub struct Ticks(pub u64);

impl core::ops::Add for Ticks {
    type Output = Ticks;
    fn add(self, other: Ticks) -> Ticks {
        Ticks(self.0 + other.0)
    }
}

impl core::ops::AddAssign for Ticks {
    fn add_assign(&mut self, other: Ticks) {
        self.0 += other.0;
    }
}

/// Instructions executed in `ticks`, rounded to the nearest.
pub fn instructions(ticks: Ticks) -> u64 {
    (ticks.0 * INSTRUCTIONS_PER_21_TICKS + 10) / 21
}

/// A free-running SysTick on the reference clock.
pub struct Meter {
    _syst: SYST,
}

impl Meter {
    /// Starts SysTick counting down from its largest reload value, without interrupts.
    pub fn new(mut syst: SYST) -> Self {
        syst.disable_interrupt();
        syst.set_clock_source(SystClkSource::External);
        syst.set_reload(COUNTER_MASK);
        syst.clear_current();
        syst.enable_counter();
        Self { _syst: syst }
    }

    /// Runs `work` and returns its result with the ticks it took.
    ///
    /// One measurement must stay below 2^24 ticks (about 800 M instructions): the counter wraps
    /// silently after that.
    pub fn measure<R>(&self, work: impl FnOnce() -> R) -> (R, Ticks) {
        let start = SYST::get_current();
        let result = work();
        let end = SYST::get_current();
        (
            result,
            Ticks(u64::from(start.wrapping_sub(end) & COUNTER_MASK)),
        )
    }
}

/// Splits one run of work into consecutive laps, for work that reports its own steps (the
/// tracker calls back as each of its stages ends).
pub struct Stopwatch {
    last: u32,
}

impl Stopwatch {
    /// Starts timing now.
    pub fn start(_meter: &Meter) -> Self {
        Self {
            last: SYST::get_current(),
        }
    }

    /// Ticks since the start or the previous lap.
    pub fn lap(&mut self) -> Ticks {
        let now = SYST::get_current();
        let ticks = self.last.wrapping_sub(now) & COUNTER_MASK;
        self.last = now;
        Ticks(u64::from(ticks))
    }
}

/// The outcome of timing a loop of known instruction count.
pub struct Calibration {
    /// Instructions the loop executes between the two runs' difference.
    pub loop_instructions: u64,
    /// Ticks that difference took.
    pub ticks: Ticks,
}

impl Calibration {
    /// Instructions per tick as measured, in thousandths.
    pub fn milli_instructions_per_tick(&self) -> u64 {
        (self.loop_instructions * 1000 + self.ticks.0 / 2) / self.ticks.0.max(1)
    }

    /// Deviation of [`instructions`] from the loop's known count, in parts per million.
    pub fn error_ppm(&self) -> i64 {
        let measured = instructions(self.ticks) as i64;
        let known = self.loop_instructions as i64;
        (measured - known) * 1_000_000 / known.max(1)
    }
}

/// Times a two-instruction loop at two lengths; the difference cancels the call overhead.
pub fn calibrate(meter: &Meter) -> Calibration {
    const SHORT: u32 = 100_000;
    const LONG: u32 = 1_100_000;
    let ((), short) = meter.measure(|| spin(SHORT));
    let ((), long) = meter.measure(|| spin(LONG));
    Calibration {
        loop_instructions: 2 * u64::from(LONG - SHORT),
        ticks: Ticks(long.0 - short.0),
    }
}

/// Executes exactly `2 * iterations` instructions in its loop: `subs` and `bne`.
#[inline(never)]
fn spin(iterations: u32) {
    // SAFETY: only decrements a scratch register; touches no memory.
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {n}, #1",
            "bne 2b",
            n = inout(reg) iterations => _,
            options(nomem, nostack),
        );
    }
}
