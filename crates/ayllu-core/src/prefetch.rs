//! Hints to the processor to start loading memory that will be read soon, for the core's
//! callers that know what a node will touch a little before it touches it (a simulator
//! visiting a thousand nodes in turn: `NodeCore::prefetch_receive`, `prefetch_target`).
//!
//! Promise: a hint changes nothing and never faults, whatever the address (a prefetch of an
//! unmapped or stale address is dropped by the processor); off x86-64 it compiles to nothing.

/// Bytes per cache line on the machines this is tuned for.
pub(crate) const LINE: usize = 64;

/// Start loading the line holding `at`.
#[inline(always)]
pub(crate) fn line<T>(at: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch only hints the cache and never faults, whatever the address.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(at.cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = at;
}

/// Start loading the `count` lines from the one holding `at` on.
#[inline(always)]
pub(crate) fn lines<T>(at: *const T, count: usize) {
    let first = at.cast::<u8>();
    // `wrapping_add`: no claim that the addresses are in bounds (they are not read).
    for k in 0..count {
        line(first.wrapping_add(k * LINE));
    }
}
