//! Flight recording from C: `ay_node_record` writes everything that enters a node's core, and
//! the values its ports accepted, into an MCAP file that Foxglove opens and `ayllu replay`
//! plays back (spec/flight-recorder.md); `ay_recording_check` replays one and says whether it
//! reproduced every accepted value. A C process's body is not needed to replay: what each
//! activation did is in the recording.

use std::ffi::c_char;
use std::path::Path;

use ayllu::replay::{Recording, Replay};
use ayllu::RecordOptions;

use crate::cstr::{put, text};
use crate::node::{ay_node, with_node};
use crate::status::{ay_status, boundary, Fail};

fn failed(e: impl std::fmt::Display) -> Fail {
    Fail::new(ay_status::AY_ERR_TRANSPORT, e.to_string())
}

/// Start recording `node` into the MCAP file `path` (numbered segments follow it:
/// `run.1.mcap`, ...), all segments together at most `max_bytes` (0: the default, 1 GiB; at
/// least 65536). Call it before defining classes: a replay rebuilds the node from its first
/// definition. The file is written by a thread of the library's and closed by
/// `ay_node_stop_recording` or `ay_node_free`.
///
/// Ownership: borrows its arguments for the call; keeps nothing of `path`.
/// Thread-safety: the node's thread. Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`,
/// `AY_ERR_INVALID` (path not UTF-8, max_bytes under 65536), `AY_ERR_TRANSPORT` (the file
/// cannot be created, the node already records, or classes were defined already).
///
/// # Safety
/// `node` is NULL or a pointer from this library; `path` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_record(node: *mut ay_node, path: *const c_char, max_bytes: u64) -> ay_status {
    boundary("ay_node_record", || {
        // SAFETY: the C caller's promise on `path`.
        let path = unsafe { text(path, "path") }?;
        if max_bytes != 0 && max_bytes < 65_536 {
            return Err(Fail::invalid("max_bytes must be 0 (the default) or at least 65536"));
        }
        let options =
            if max_bytes == 0 { RecordOptions::default() } else { RecordOptions::default().max_bytes(max_bytes) };
        with_node(node, |s| s.node.record(path, options).map_err(failed))
    })
}

/// Start a rolling recording of `node` into `path`: as `ay_node_record`, but only about the
/// last `keep_last_s` seconds are kept (a checkpoint of the node every quarter of that opens a
/// new segment, and the segments before the window are deleted; `ayllu replay` starts from
/// the oldest checkpoint kept). For a robot that records all the time.
///
/// Ownership: borrows its arguments for the call; keeps nothing of `path`.
/// Thread-safety: the node's thread. Errors: as `ay_node_record`, and `AY_ERR_PERIOD`
/// (`keep_last_s` not a positive number of seconds).
///
/// # Safety
/// `node` is NULL or a pointer from this library; `path` is NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn ay_node_record_last(
    node: *mut ay_node,
    path: *const c_char,
    max_bytes: u64,
    keep_last_s: f64,
) -> ay_status {
    boundary("ay_node_record_last", || {
        // SAFETY: the C caller's promise on `path`.
        let path = unsafe { text(path, "path") }?;
        if max_bytes != 0 && max_bytes < 65_536 {
            return Err(Fail::invalid("max_bytes must be 0 (the default) or at least 65536"));
        }
        let window = ayllu::Duration::try_from_positive_secs(keep_last_s)?;
        let options =
            if max_bytes == 0 { RecordOptions::default() } else { RecordOptions::default().max_bytes(max_bytes) };
        let options = options.keep_last(std::time::Duration::from_nanos(window.as_nanos()));
        with_node(node, |s| s.node.record(path, options).map_err(failed))
    })
}

/// Stop recording `node` and close its files; `*written` (if not NULL) gets the number of
/// journal entries written. Not recording is not an error (`*written` is 0).
///
/// Ownership: borrows its arguments for the call. Thread-safety: the node's thread.
/// Errors: `AY_ERR_NULL`, `AY_ERR_HANDLE`, `AY_ERR_BUSY`, `AY_ERR_TRANSPORT` (writing the
/// file failed; what was written up to then is a valid recording).
///
/// # Safety
/// `node` is NULL or a pointer from this library; `written` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_node_stop_recording(node: *mut ay_node, written: *mut u64) -> ay_status {
    boundary("ay_node_stop_recording", || {
        let stats = with_node(node, |s| Ok(s.node.stop_recording()))?;
        if !written.is_null() {
            // SAFETY: non-null, and the C caller's promise on `written`.
            unsafe { put(written, stats.as_ref().map_or(0, |s| s.written), "written") }?;
        }
        match stats.and_then(|s| s.error) {
            Some(e) => Err(failed(format!("recording failed: {e}"))),
            None => Ok(()),
        }
    })
}

/// Replay the recording `path` to its end, checking every value its ports accepted against
/// the recording bit for bit; `*checked` (if not NULL) gets how many were compared.
///
/// Ownership: borrows its arguments for the call. Thread-safety: any thread.
/// Errors: `AY_ERR_NULL`, `AY_ERR_INVALID` (path not UTF-8), `AY_ERR_TRANSPORT` (the file
/// cannot be read or is not a flight recording, or the replay diverged: the message says
/// where and what).
///
/// # Safety
/// `path` is NULL or NUL-terminated; `checked` is NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn ay_recording_check(path: *const c_char, checked: *mut u64) -> ay_status {
    boundary("ay_recording_check", || {
        // SAFETY: the C caller's promise on `path`.
        let path = unsafe { text(path, "path") }?;
        let recording = Recording::open(Path::new(path)).map_err(failed)?;
        let mut replay = Replay::new(&recording);
        replay.run_to_end().map_err(failed)?;
        if !checked.is_null() {
            // SAFETY: non-null, and the C caller's promise on `checked`.
            unsafe { put(checked, replay.checked() as u64, "checked") }?;
        }
        Ok(())
    })
}
