//! placeholder
pub use ayllu_core as core;
