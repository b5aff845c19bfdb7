//! Stack high-water mark: [`paint`] fills the free stack below the caller with a pattern,
//! [`used`] finds how deep it has been overwritten since. Between the two, the deepest stack
//! use of the code that ran is measured (on the machine's real instruction set, release build).

const PATTERN: u32 = 0xA5A5_5A5A;

/// Words left untouched right below the caller's frame when painting.
const MARGIN: usize = 64;

/// Deepest stack measured, in bytes below the caller (the mps2 machine has 4 MiB of RAM; its
/// whole free stack would take long to paint).
const DEPTH: usize = 32 * 1024;

extern "C" {
    static mut _stack_end: u32;
    static mut _stack_start: u32;
}

fn bounds() -> (usize, usize) {
    // Only the symbols' addresses are taken, never their values.
    (
        core::ptr::addr_of!(_stack_end) as usize,
        core::ptr::addr_of!(_stack_start) as usize,
    )
}

/// Fills the stack between its end (lowest address) and the current frame with the pattern.
pub fn paint() {
    let (end, _) = bounds();
    let sp = cortex_m::register::msp::read() as usize - MARGIN * 4;
    let mut p = end.max(sp.saturating_sub(DEPTH));
    while p < sp {
        // SAFETY: [end, sp) is free stack below every live frame: nothing else uses it.
        unsafe { core::ptr::write_volatile(p as *mut u32, PATTERN) };
        p += 4;
    }
}

/// Bytes of stack used at the deepest point since [`paint`] (from the top of RAM; call it from
/// the same frame as `paint`), and the bytes the stack can grow to in all.
pub fn used() -> (usize, usize) {
    let (end, start) = bounds();
    let sp = cortex_m::register::msp::read() as usize - MARGIN * 4;
    let mut p = end.max(sp.saturating_sub(DEPTH));
    // SAFETY: reading the free stack area painted by `paint`.
    while p < start && unsafe { core::ptr::read_volatile(p as *const u32) } == PATTERN {
        p += 4;
    }
    (start - p, start - end)
}

/// Bytes of stack in use now (from the top of RAM to the caller's frame): subtracted from
/// [`used`], it leaves what the code run since [`paint`] needed below the caller.
pub fn depth() -> usize {
    let (_, start) = bounds();
    start - cortex_m::register::msp::read() as usize
}
