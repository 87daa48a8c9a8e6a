//! Which handles are live. Every handle the library gives out is registered here with its
//! type and removed when freed, so a freed, foreign or mistyped handle is refused with
//! `AY_ERR_HANDLE` before it is touched (use after free is detected as long as the memory
//! was not handed out again for a handle of the same type).

use std::collections::HashMap;
use std::sync::{LazyLock, Mutex, MutexGuard};

use crate::status::{ay_status, Fail};

/// The type of a handle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Node,
    Clock,
    Class,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Node => "node",
            Kind::Clock => "clock",
            Kind::Class => "behavior class",
        }
    }
}

static LIVE: LazyLock<Mutex<HashMap<usize, Kind>>> = LazyLock::new(Mutex::default);

/// The key of a handle: its address inverted, so that the registry does not look to a leak
/// checker (LeakSanitizer, valgrind) like a pointer to the handle — a handle the program
/// forgets to free is then reported as the leak it is.
fn key<T>(p: *const T) -> usize {
    !(p as usize)
}

fn live() -> MutexGuard<'static, HashMap<usize, Kind>> {
    // A panic while holding the lock cannot leave the map half-updated (single inserts and
    // removes), so a poisoned lock is still consistent.
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Register a new handle.
pub(crate) fn add<T>(p: *const T, kind: Kind) {
    live().insert(key(p), kind);
}

/// Check that `p` is a live handle of `kind`: NULL is `AY_ERR_NULL`, anything else that is
/// not registered (freed, never made, another type) `AY_ERR_HANDLE`.
pub(crate) fn check<T>(p: *const T, kind: Kind, what: &str) -> Result<(), Fail> {
    if p.is_null() {
        return Err(Fail::null(what));
    }
    match live().get(&key(p)) {
        Some(k) if *k == kind => Ok(()),
        Some(k) => {
            Err(Fail::new(ay_status::AY_ERR_HANDLE, format!("{what} is a {} handle, not a {}", k.name(), kind.name())))
        }
        None => Err(Fail::new(
            ay_status::AY_ERR_HANDLE,
            format!("{what} is not a live {} (freed already, or never made by this library)", kind.name()),
        )),
    }
}

/// Unregister `p` (checked as by [`check`]); the caller then frees it.
pub(crate) fn remove<T>(p: *const T, kind: Kind, what: &str) -> Result<(), Fail> {
    check(p, kind, what)?;
    live().remove(&key(p));
    Ok(())
}
