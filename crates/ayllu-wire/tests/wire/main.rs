//! The wire: golden vectors (`spec/vectors/`, byte for byte), transaction vectors, codec
//! properties over random input, and the reports' JSON round trip. `AYLLU_BLESS=1 cargo test -p
//! ayllu-wire --test wire` rewrites the committed vectors (then review the diff).
//!
//! One test binary (not one per file) keeps the test build short.

mod places;
mod properties;
mod reports;
mod transaction_vectors;
mod vectors;
