//! Peak stack of a call, measured by stack painting.
//!
//! Before the call, the free stack below the current stack pointer (down to
//! the end of the statics, at most [`WINDOW`] bytes) is filled with a
//! pattern; after it, the lowest word that no longer holds the pattern marks
//! the deepest point the call reached. Nothing else runs on this core (no
//! interrupts are enabled), so memory below the stack pointer is free.

use core::ptr;

/// The paint: an odd pattern that a return address or a small integer is
/// unlikely to equal.
const PAINT: u32 = 0x5AA5_C33C;
/// Most bytes painted below the stack pointer.
pub const WINDOW: usize = 64 * 1024;

extern "C" {
    /// End of the statics (`.bss`, `.uninit`): the lowest address the stack
    /// may reach (defined by cortex-m-rt's `link.x`).
    static _stack_end: u32;
}

/// The peak stack of one call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Peak {
    /// Bytes below the caller's stack pointer that the call wrote.
    Bytes(usize),
    /// The whole painted window was used: the peak is at least this.
    AtLeast(usize),
}

impl core::fmt::Display for Peak {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Peak::Bytes(n) => write!(f, "{n}"),
            Peak::AtLeast(n) => write!(f, ">={n}"),
        }
    }
}

#[inline(always)]
fn stack_pointer() -> usize {
    let sp: usize;
    // SAFETY: reads a register, no memory access.
    unsafe {
        core::arch::asm!("mov {}, sp", out(reg) sp, options(nomem, nostack, preserves_flags))
    };
    sp
}

/// Runs `f` and returns its result and its peak stack use below this
/// function's frame (which includes the call of `f` itself).
///
/// `f` should call an `#[inline(never)]` function so that its work happens
/// in frames below this one, not inlined into it.
#[inline(never)]
pub fn measure<R>(f: impl FnOnce() -> R) -> (R, Peak) {
    let top = stack_pointer() & !3;
    // Only the symbol's address is taken, never its value.
    let floor = ptr::addr_of!(_stack_end) as usize;
    let lo = (top.saturating_sub(WINDOW).max(floor) + 3) & !3;
    let mut a = lo;
    while a < top {
        // SAFETY: [lo, top) lies between the end of the statics and the
        // stack pointer: stack memory that no live frame uses.
        unsafe { ptr::write_volatile(a as *mut u32, PAINT) };
        a += 4;
    }
    let r = f();
    let mut a = lo;
    // SAFETY: the same region, read back.
    while a < top && unsafe { ptr::read_volatile(a as *const u32) } == PAINT {
        a += 4;
    }
    let peak = if a == lo && lo < top {
        Peak::AtLeast(top - lo)
    } else {
        Peak::Bytes(top - a)
    };
    (r, peak)
}
