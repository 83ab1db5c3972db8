//! Closed-form and independent-value checks: beam theory and the elastica, the contact
//! oracles, J2 plasticity, every material and friction law through its interface, the hex8
//! element (incompatible modes, F-bar and locking) and the contact tangent and normal laws.
//!
//! One test binary: each former `tests/NAME.rs` is the module `NAME` here, so
//! `cargo test --release --test oracles NAME::` runs one of them. Shared fixtures are in
//! `tests/common/` (`crate::common`).

#[path = "../common/mod.rs"]
mod common;

mod cantilever;
mod contact_laws;
mod contact_oracles;
mod contact_tangent;
mod element;
mod families;
mod friction_laws;
mod imported;
mod loads;
mod locking;
mod materials;
mod mesh_in_code;
mod plasticity;
mod pressure_measures;
mod pushed_target;
mod shape_maps;
mod springs;
