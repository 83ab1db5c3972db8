//! The literate examples in `examples/` run as tests. Each example's `study` function holds the
//! assertions its doc comment states (agreement between methods, closed forms, signs), so a
//! change that breaks what an example claims fails here, not only when someone runs it.
//!
//! The "bring your own friction law" example is built and executed the same way: a law defined
//! in the example file gets SDM, DDM and FDM with no hand-written derivative, and the example's
//! `main` asserts that the three agree.
//!
//! The indentation study (about 40 s on two cores) is ignored by default:
//! `cargo test --release --test methods -- --ignored examples::`.

use crate::common::scratch_path;

#[allow(dead_code)]
#[path = "../../examples/choose_your_beta.rs"]
mod choose_your_beta;

#[allow(dead_code)]
#[path = "../../examples/leaf_spring.rs"]
mod leaf_spring;

#[allow(dead_code)]
#[path = "../../examples/indentation_study.rs"]
mod indentation_study;

#[allow(dead_code)]
#[path = "../../examples/curved_punch.rs"]
mod curved_punch;

#[path = "../../examples/own_friction_law.rs"]
pub(crate) mod own_friction_law;

#[test]
fn bring_your_own_friction_law_example_runs_and_the_three_methods_agree() {
    own_friction_law::main();
}

#[test]
fn choose_your_beta_sweeps_and_writes_the_v_curves() {
    let svg = scratch_path("beta").with_extension("svg");
    let s = choose_your_beta::study(&svg).expect("the sweep runs");
    assert_eq!(s.errors.len(), 4);
    assert!(s.errors.iter().all(|e| e.len() == s.betas.len()));
    assert!(std::fs::metadata(&svg).expect("SVG written").len() > 0);
    let _ = std::fs::remove_file(&svg);
}

/// About 10 s of computing (the primal, DDM and four FDM reruns of the coarse spring).
#[test]
fn leaf_spring_is_path_dependent_and_ddm_agrees_with_central_fdm() {
    let s = leaf_spring::study().expect("the study runs");
    // loading -> unloading and unloading -> reloading
    assert!(s.sign_changes >= 2, "{} sign changes", s.sign_changes);
    assert!(s.fdm_difference.iter().all(|d| *d <= 1e-5));
}

#[test]
#[ignore = "about 40 s: the paper's indentation mesh, DDM, SDM and four FDM reruns"]
fn indentation_study_methods_agree() {
    let s = indentation_study::study(2, 5).expect("the study runs");
    assert!(s.max_difference.iter().all(|d| *d <= 1e-5));
}

/// About 15 s of computing: the punch-on-slab scene (Gmsh mesh), DDM and SDM for four
/// parameters, central FDM of the radius and mu (four reruns).
#[test]
fn curved_punch_from_gmsh_radius_and_mu_agree_across_methods() {
    let s = curved_punch::study().expect("the study runs");
    assert!(s.max_difference.iter().all(|d| *d <= 1e-4));
    assert!(s.homogeneity <= 1e-8);
}
