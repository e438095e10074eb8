//! Stack high-water mark.
//!
//! cortex-m-rt's `paint-stack` feature fills the RAM between `_stack_end` (the end of the
//! statics) and `_stack_start` (the initial stack pointer) with a known word before `main`. The
//! stack grows down from `_stack_start`; the lowest word that no longer holds the paint marks the
//! deepest the stack has been. [`repaint`] restarts the measurement for one part of the run.

use cortex_m_rt::STACK_PAINT_VALUE;

extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
}

/// The stack's RAM: `_stack_end..._stack_start`; only the symbols' addresses are used.
fn bounds() -> (usize, usize) {
    let bottom = core::ptr::addr_of!(_stack_end) as usize;
    let top = core::ptr::addr_of!(_stack_start) as usize;
    (bottom, top)
}

/// Bytes of stack used at the deepest point since boot or the last [`repaint`], counted from the
/// top of RAM.
pub fn peak() -> usize {
    let (bottom, top) = bounds();
    let mut word = bottom;
    // SAFETY: every word in [bottom, top) is RAM reserved for the stack; reads are aligned.
    while word < top && unsafe { core::ptr::read_volatile(word as *const u32) } == STACK_PAINT_VALUE
    {
        word += 4;
    }
    top - word
}

/// Bytes below the stack pointer left unpainted by [`repaint`]: the compiler may read the stack
/// pointer before pushing this function's own frame, which must not be painted over.
const REPAINT_GUARD: usize = 256;

/// Paints the free stack below the current stack pointer again, so that the next [`peak`]
/// measures only what runs after this call (anything deeper than [`REPAINT_GUARD`] below the
/// caller's stack pointer). Returns the high-water mark up to this call, which it erases.
#[inline(never)]
pub fn repaint() -> usize {
    let so_far = peak();
    let (bottom, _) = bounds();
    let below = (cortex_m::register::msp::read() as usize & !3).saturating_sub(REPAINT_GUARD);
    let mut word = bottom;
    while word < below {
        // SAFETY: the words between the statics and the stack pointer are unused stack RAM; no
        // interrupt is enabled that could be using them.
        unsafe { core::ptr::write_volatile(word as *mut u32, STACK_PAINT_VALUE) };
        word += 4;
    }
    so_far
}

/// Bytes of stack in use at this call, counted from the top of RAM.
#[inline(always)]
pub fn depth() -> usize {
    let (_, top) = bounds();
    top - cortex_m::register::msp::read() as usize
}

/// Bytes reserved for the stack: everything between the statics and the top of RAM.
pub fn size() -> usize {
    let (bottom, top) = bounds();
    top - bottom
}
