//! The standard library's classes by the names Python asks for them (`ayllu.Node.define_stdlib`
//! and a simulated robot's `define_stdlib`), with the keyword arguments each one takes.
//!
//! Promise: the classes are `ayllu::stdlib`'s own; an unknown name is the core's
//! `UnknownClass` error, listing the names there are.

use ayllu::stdlib;
use ayllu_core::Error as CoreError;

/// The keyword arguments of `ayllu.Node.define_stdlib`: what each standard class takes.
pub struct StdlibOptions {
    /// `RandomWander`'s and `Wander`'s rate.
    pub hz: f64,
    /// `RandomWander`'s seed.
    pub seed: u64,
    /// `Vision`'s number of targets.
    pub targets: u32,
    /// `Sonar`'s number of beams.
    pub beams: usize,
    /// `Sonar`'s range.
    pub max_range: f64,
}

/// The standard library's classes a Python controller may reuse (like the paper's
/// `ayllustd.h`); see `ayllu.Node.define_stdlib`.
pub fn define_stdlib_class(
    name: &str,
    &StdlibOptions { hz, seed, targets, beams, max_range }: &StdlibOptions,
) -> Result<ayllu_core::BehaviorClass, CoreError> {
    match name {
        "SafeVelocity" => stdlib::safe_velocity_class(stdlib::SafeVelocity::default()),
        "RandomWander" => stdlib::random_wander_class(hz, seed),
        "Wander" => stdlib::wander_class(hz),
        "Observer" => stdlib::observer_class(),
        "Vision" => stdlib::vision_class(targets),
        "Base" => stdlib::base_class(),
        "Sonar" => stdlib::sonar_class(beams, max_range),
        other => Err(CoreError::UnknownClass {
            class: format!(
                "{other} (the standard library has SafeVelocity, RandomWander, Wander, Observer, Vision, Base, Sonar)"
            ),
        }),
    }
}
