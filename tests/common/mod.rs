//! Fixtures shared by the test binaries (`tests/oracles`, `tests/methods`, `tests/robustness`,
//! `tests/studies`): each includes this directory as `crate::common`, and a test module takes
//! what it needs with `use crate::common::{...}`. Not every binary uses every fixture.
#![allow(dead_code)]

mod cli;
mod hex8;
mod sensitivity;
mod solve;

// A binary that uses none of a module's fixtures would warn of the unused re-export.
#[allow(unused_imports)]
pub use cli::*;
#[allow(unused_imports)]
pub use hex8::*;
#[allow(unused_imports)]
pub use sensitivity::*;
#[allow(unused_imports)]
pub use solve::*;
