//! Manual clocks from C: time a test or a simulator moves by hand (rule S8). A node opened
//! with one ([`crate::node::ay_node_open_manual`]) sees only the time the clock is told.

use ayllu::{Clock, ManualClock};
use ayllu_core::Instant;

use crate::cstr::put;
use crate::registry::{self, Kind};
use crate::seconds::required_secs;
use crate::status::{ay_status, boundary, Fail};

/// A manual clock (opaque). Nodes opened with it share its time.
#[allow(non_camel_case_types)]
pub struct ay_clock {
    pub(crate) clock: ManualClock,
}

pub(crate) fn with_clock<T>(p: *const ay_clock, f: impl FnOnce(&ay_clock) -> Result<T, Fail>) -> Result<T, Fail> {
    registry::check(p, Kind::Clock, "clock")?;
    // SAFETY: registered clock pointers come from Box::into_raw in ay_clock_new and are
    // unregistered before they are freed; the clock's state is atomic, so shared access from
    // any thread is sound.
    f(unsafe { &*p })
}

/// A new manual clock at time 0.
///
/// Ownership: `*out` belongs to the caller; free it with `ay_clock_free` (nodes opened with it
/// keep their own share of its time and may outlive it). Thread-safety: a clock may be used
/// from any thread. Errors: `AY_ERR_NULL` (out).
///
/// # Safety
/// `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_clock_new(out: *mut *mut ay_clock) -> ay_status {
    boundary("ay_clock_new", || {
        if out.is_null() {
            return Err(Fail::null("out"));
        }
        let p = Box::into_raw(Box::new(ay_clock { clock: ManualClock::new() }));
        registry::add(p, Kind::Clock);
        // SAFETY: `out` is non-null and valid for a write (caller's promise).
        unsafe { out.write(p) };
        Ok(())
    })
}

/// Free a clock. Nodes opened with it keep working (time then stands still for them).
///
/// Ownership: takes the clock. Thread-safety: not while another thread uses it.
/// Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE` (freed already).
///
/// # Safety
/// `clock` is NULL or a pointer from this library (checked against the live handles).
#[no_mangle]
pub unsafe extern "C" fn ay_clock_free(clock: *mut ay_clock) -> ay_status {
    boundary("ay_clock_free", || {
        registry::remove(clock, Kind::Clock, "clock")?;
        // SAFETY: came from Box::into_raw in ay_clock_new and was just unregistered.
        drop(unsafe { Box::from_raw(clock) });
        Ok(())
    })
}

/// Move the clock forward by `seconds` (above zero).
///
/// Thread-safety: any thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_PERIOD` (zero,
/// negative, NaN or infinite).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `clock` is NULL or a pointer from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_clock_advance(clock: *mut ay_clock, seconds: f64) -> ay_status {
    boundary("ay_clock_advance", || {
        let d = required_secs(seconds, "the step")?;
        with_clock(clock, |c| {
            c.clock.advance(d);
            Ok(())
        })
    })
}

/// Set the clock to `seconds` after its origin; earlier than now is ignored (time never goes
/// backwards).
///
/// Thread-safety: any thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_PERIOD`
/// (negative, NaN or infinite).
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `clock` is NULL or a pointer from this library.
#[no_mangle]
pub unsafe extern "C" fn ay_clock_set(clock: *mut ay_clock, seconds: f64) -> ay_status {
    boundary("ay_clock_set", || {
        let d = ayllu_core::Duration::try_from_secs_f64(seconds)?;
        with_clock(clock, |c| {
            c.clock.set(Instant::ZERO + d);
            Ok(())
        })
    })
}

/// The clock's time (seconds since its origin) into `*out`.
///
/// Thread-safety: any thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`.
///
/// Ownership: borrows its arguments for the call; keeps nothing.
///
/// # Safety
/// `clock` is NULL or a pointer from this library; `out` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_clock_now(clock: *const ay_clock, out: *mut f64) -> ay_status {
    boundary("ay_clock_now", || {
        // SAFETY: the C caller's promise on `out`.
        with_clock(clock, |c| unsafe { put(out, c.clock.now().as_secs_f64(), "out") })
    })
}
