//! The studies end to end on reduced inputs: the validation harness and its report, the
//! scaling study and the CalculiX exporter and comparison.
//!
//! One test binary: each former `tests/NAME.rs` is the module `NAME` here, so
//! `cargo test --release --test studies NAME::` runs one of them. Shared fixtures are in
//! `tests/common/` (`crate::common`).

#[path = "../common/mod.rs"]
mod common;

mod adjoint_study;
mod ccx;
mod scaling;
mod shards;
mod validation;
