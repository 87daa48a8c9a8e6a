//! Which handles are live. Every handle the library gives out is registered here with its
//! type and removed when freed, so a freed, foreign or mistyped handle is refused with
//! `AY_ERR_HANDLE` before it is touched (use after free is detected as long as the memory
//! was not handed out again for a handle of the same type).

use std::cell::Cell;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{LazyLock, Mutex, MutexGuard};

use crate::status::{ay_status, Fail};

/// The type of a handle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Node,
    Clock,
    Class,
    ServedWorld,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Node => "node",
            Kind::Clock => "clock",
            Kind::Class => "behavior class",
            Kind::ServedWorld => "served world",
        }
    }
}

static LIVE: LazyLock<Mutex<HashMap<usize, Kind>>> = LazyLock::new(Mutex::default);

/// Bumped whenever a handle is removed: a thread's memory of the last handle it checked is
/// good only while no handle has been removed since.
static REMOVALS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    /// The last handle this thread found live: (key, kind, REMOVALS then). A hot loop of calls
    /// on one node checks it without the lock.
    static LAST: Cell<(usize, Option<Kind>, u64)> = const { Cell::new((0, None, 0)) };
}

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
    let removals = REMOVALS.load(Ordering::Acquire);
    if LAST.with(Cell::get) == (key(p), Some(kind), removals) {
        return Ok(());
    }
    match live().get(&key(p)) {
        Some(k) if *k == kind => {
            LAST.with(|l| l.set((key(p), Some(kind), removals)));
            Ok(())
        }
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
    let mut live = live();
    live.remove(&key(p));
    // Under the lock, before the caller frees it: no thread can still take it for live.
    REMOVALS.fetch_add(1, Ordering::AcqRel);
    Ok(())
}
