//! Robustness: bad input as typed errors, no panics (proptest fuzzing), determinism, the
//! fuzzer's regression corpus (`tests/corpus/robustness/`), extremes and non-smooth points,
//! Newton under prescribed displacements, sliding across segments and the scene files.
//!
//! One test binary: each former `tests/NAME.rs` is the module `NAME` here, so
//! `cargo test --release --test robustness NAME::` runs one of them. Shared fixtures are in
//! `tests/common/` (`crate::common`).

#[path = "../common/mod.rs"]
mod common;

mod extremes;
mod mesh_readers;
mod robustness;
mod robustness_corpus;
mod scenes;
mod sliding;
mod solver;
