//! The studies built on the library — applications, not part of the analysis core, compiled
//! only with the `studies` cargo feature (on by default; a library user who wants the core alone
//! writes `default-features = false` and does not compile plotters, clap or indicatif):
//!
//! * [`adjoint_study`] — the adjoint's cost against the number of parameters, and a
//!   sensitivity map over every element;
//! * [`validate`] — the validation harness: every method across a perturbation sweep on the
//!   built-in scenes, compared with DDM and the scenes' closed forms; writes the report;
//! * [`compare_laws`] — the friction laws side by side on one scene;
//! * [`ccx`] — the comparison with CalculiX;
//! * [`scaling`] — cost and memory against mesh size;
//! * [`fuzz`] — the physics fuzzer: random valid contact scenes run with default settings;
//! * [`fuzz_methods`] — DDM against the adjoint on the fuzzer's scenes;
//! * [`mesh_fuzz`] — the mesh readers' fuzzer: mutated Gmsh and Abaqus files, none may panic;
//! * [`plot`] — the SVG figures they draw.
//!
//! Nothing in the library's core imports from here.

pub mod adjoint_study;
pub mod ccx;
pub mod compare_laws;
pub mod fuzz;
pub mod fuzz_methods;
pub mod mesh_fuzz;
pub mod plot;
pub mod scaling;
pub mod validate;
