//! The sensitivity methods (SDM, DDM, FDM): their defaults and agreement, the elastic and the
//! plastic cantilever, branch freezing at kinks, round-off against the perturbation size, and
//! the literate examples of `examples/`.
//!
//! One test binary: each former `tests/NAME.rs` is the module `NAME` here, so
//! `cargo test --release --test methods NAME::` runs one of them. Shared fixtures are in
//! `tests/common/` (`crate::common`).

#[path = "../common/mod.rs"]
mod common;

mod adjoint;
mod anatomy;
mod beta_auto;
mod examples;
mod families;
mod field_params;
mod fields;
mod methods;
mod plastic_cantilever;
mod rigid_modes;
mod roundoff;
mod sensitivity_elastic;
mod sensitivity_kinks;
mod shards;
mod stress;
mod tangent_choice;
mod taylor;
