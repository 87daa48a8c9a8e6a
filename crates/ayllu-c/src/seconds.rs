//! Spans of time from C: seconds arrive as a `double` and become the runtime's [`Duration`]
//! here, for every period, lifespan, window and step the library takes.
//!
//! Promise: NaN, infinite and negative seconds never reach the runtime; they come back as
//! `AY_ERR_PERIOD` with the name of what was given (`the period`, `lifespan`, ...).

use ayllu_core::Duration;

use crate::status::Fail;

/// Seconds from C as an optional span: 0 means none; negative, NaN, infinite are refused.
pub(crate) fn optional_secs(secs: f64, what: &str) -> Result<Option<Duration>, Fail> {
    if secs == 0.0 {
        return Ok(None);
    }
    let d = Duration::try_from_secs_f64(secs).map_err(|e| Fail::from(e).context(what))?;
    Ok(Some(d))
}

/// Seconds from C as a required span: the core's `Duration::try_from_positive_secs` (the
/// check the CLI and Python use too), zero, negative, NaN and infinite refused in its words.
pub(crate) fn required_secs(secs: f64, what: &str) -> Result<Duration, Fail> {
    Duration::try_from_positive_secs(secs).map_err(|e| Fail::from(e).context(what))
}
