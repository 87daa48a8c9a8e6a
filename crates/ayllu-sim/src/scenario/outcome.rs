//! What a run gives back: its [`Outcome`] (metrics, trace hash, coverage, the recording if
//! asked, radio totals), or a [`SimError`] saying why it could not be built or stepped.
//!
//! An outcome is plain data (serde both ways): it can be kept, written and compared without
//! the run that made it.

use ayllu_core::Error;
use serde::{Deserialize, Serialize};

use crate::bounds::InvalidScenario;
use crate::metrics::Metrics;
use crate::recording::{CoverageSeries, Recording};

/// Radio totals of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RadioStats {
    /// Radio emissions by all robots (a group message counts once).
    pub sent: u64,
    /// Deliveries made (one per receiver).
    pub delivered: u64,
    /// Deliveries dropped by the loss draw (one per receiver).
    pub lost: u64,
    /// Deliveries cut by the range limit or a partition (one per receiver).
    pub cut: u64,
    /// The emissions' encoded size in bytes ([`crate::radio::wire_len`]).
    #[serde(default)]
    pub bytes: u64,
}

/// Why a run could not be built or stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum SimError {
    /// The scenario has a field out of bounds ([`Scenario::validate`](super::Scenario::validate)): nothing was built.
    Scenario(InvalidScenario),
    /// A node refused something while the run was built or stepped (a controller that cannot be
    /// built, a port written with a value of another type...).
    Node(Error),
}

impl From<InvalidScenario> for SimError {
    fn from(e: InvalidScenario) -> Self {
        SimError::Scenario(e)
    }
}

impl From<Error> for SimError {
    fn from(e: Error) -> Self {
        SimError::Node(e)
    }
}

impl std::fmt::Display for SimError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SimError::Scenario(e) => e.fmt(f),
            SimError::Node(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for SimError {}

/// What a run produced.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// The run's figures of merit (docs/cmommt.md, "The metrics").
    pub metrics: Metrics,
    /// SHA-256 of every frame, hex.
    pub trace_hash: String,
    /// Coverage over time (one sample per frame).
    pub coverage: CoverageSeries,
    /// Every frame, if the scenario asked for it (`Scenario::record`).
    pub recording: Option<Recording>,
    /// Radio totals over the run.
    pub radio: RadioStats,
}
