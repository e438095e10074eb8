//! Stack high-water mark.
//!
//! cortex-m-rt's `paint-stack` feature fills the RAM between `_stack_end` (the end of the
//! statics) and `_stack_start` (the initial stack pointer) with a known word before `main`. The
//! stack grows down from `_stack_start`; the lowest word that no longer holds the paint marks the
//! deepest the stack has been.

use cortex_m_rt::STACK_PAINT_VALUE;

extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
}

/// Bytes of stack used so far at the deepest point.
pub fn peak() -> usize {
    // Only the symbols' addresses are used; the linker script defines both.
    let bottom = core::ptr::addr_of!(_stack_end) as usize;
    let top = core::ptr::addr_of!(_stack_start) as usize;
    let mut word = bottom;
    // SAFETY: every word in [bottom, top) is RAM that cortex-m-rt painted; reads are aligned.
    while word < top && unsafe { core::ptr::read_volatile(word as *const u32) } == STACK_PAINT_VALUE
    {
        word += 4;
    }
    top - word
}

/// Bytes reserved for the stack: everything between the statics and the top of RAM.
pub fn size() -> usize {
    let bottom = core::ptr::addr_of!(_stack_end) as usize;
    let top = core::ptr::addr_of!(_stack_start) as usize;
    top - bottom
}
