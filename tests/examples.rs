//! The "bring your own friction law" example, built and executed as part of the test suite: a
//! law defined in the example file gets SDM, DDM and FDM with no hand-written derivative, and
//! the example's `main` asserts that the three agree.

#[path = "../examples/own_friction_law.rs"]
mod own_friction_law;

#[test]
fn bring_your_own_friction_law_example_runs_and_the_three_methods_agree() {
    own_friction_law::main();
}
