//! libayllu's Rust-side tests: the committed C header is cbindgen's output byte for byte
//! (`header`), and the paper's Fig. 2 in C as a team of processes (`cmommt_team`, ignored by
//! default: the C Makefile runs it with the C program it built).
//!
//! One test binary (not one per file) keeps the test build short.

mod cmommt_team;
mod header;
