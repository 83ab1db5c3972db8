//! The adjoint's study (issue 28), its reduced path end to end: the coarse leaf spring's
//! crossover (every method measured while a measurement takes at most 2 s, the rest
//! extrapolated), its sensitivity map and the map's DDM spot checks, and the many-parameter
//! run on the leaf spring coarsened by half (its whole path, three fields). The study itself
//! is `fricsens adjoint-study --large 6` (minutes).

use fricsens::scene::{leaf_spring, LeafSpringSpec};
use fricsens::solver::{NoObserver, RunOptions, Solver};
use fricsens::studies::adjoint_study::{run_study, StudyOptions};
use std::path::PathBuf;

#[test]
fn quick_study_writes_the_crossover_and_a_map_that_ddm_confirms() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("adjoint-quick");
    let _ = std::fs::remove_dir_all(&dir);
    let study = run_study(&StudyOptions {
        out: dir.clone(),
        quick: true,
        budget_seconds: 2.0,
        large: Some(0.5),
    })
    .unwrap();
    for f in [
        "adjoint.md",
        "crossover.csv",
        "crossover.svg",
        "map.vtu",
        "map-E.svg",
        "map-sigma_y.svg",
        "adjoint.json",
    ] {
        assert!(dir.join(f).exists(), "{f} written");
    }
    // DDM at five elements, both quantities: the same derivatives to the solves' round-off
    assert_eq!(study.spot_checks.len(), 10);
    for c in &study.spot_checks {
        assert!(c.difference < 1e-10, "{c:?}");
        assert!(c.adjoint != 0.0, "{c:?}: an element the block force sees");
    }
    // every method measured at the two smallest counts (the rest depends on the timings)
    for c in &study.costs {
        assert!(c.seconds.is_finite() && c.seconds > 0.0, "{c:?}");
        if c.n <= 10 {
            assert!(c.measured, "{c:?}");
        }
    }
    // one crossover per other method (their values are timings: the study reports them,
    // no test asserts them)
    assert_eq!(study.crossovers.len(), 3);
    // the many-parameter run: every element's E, sigma_y and H over the built-in scene's
    // whole path (15 loading increments, 10 unloading, 10 reloading), DDM at the largest
    // derivative of each field
    let large = study.large.expect("the many-parameter run");
    assert_eq!(large.parameters, 3 * large.elements);
    // its elements and converged increments against a primal run of its own of the same
    // scene, built here from the public spec (the leaf spring coarsened by half: 20 elements
    // along the upper leaf, 2 through, the leaf-leaf search 10 / 0.5 mm along the leaves)
    let spec = LeafSpringSpec {
        elements_along: 20,
        elements_through: 2,
        search_along: 20.0,
        ..LeafSpringSpec::default()
    };
    let model = leaf_spring(&spec).build().unwrap();
    let res = Solver::new(&model)
        .unwrap()
        .run(&RunOptions::default(), &mut NoObserver)
        .unwrap();
    assert_eq!(large.elements, model.mesh.n_elements());
    assert_eq!(large.increments, res.records.len());
    assert!(large.increments >= 35, "the whole path: {large:?}");
    let fields: Vec<&str> = (large.spot_checks.iter())
        .map(|c| c.param.split(['.', '[']).nth(1).unwrap_or(""))
        .collect();
    assert_eq!(fields, ["E", "sigma_y", "H"]);
    for c in &large.spot_checks {
        assert!(c.difference < 1e-10, "{c:?}");
        assert!(c.adjoint != 0.0, "{c:?}");
    }
}
