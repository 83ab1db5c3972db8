//! A reduced validation run (a few betas, the small scenes): the harness agrees with the
//! independent methods and the closed forms, the adjoint in its tables with DDM, and it writes
//! the report.

use crate::common::scratch_path;

use fricsens::scene::builtin;
use fricsens::studies::validate::{default_scenes, validate, ValidateOptions};

#[test]
fn reduced_validation_agrees_and_writes_the_report() {
    let out = scratch_path("validation");
    let _ = std::fs::remove_dir_all(&out);
    let keep = [
        "stacked-leaves",
        "uniaxial-j2",
        "jenkins",
        "cantilever-small",
    ];
    let scenes: Vec<_> = default_scenes(false)
        .into_iter()
        .filter(|s| keep.contains(&s.name.as_str()))
        .collect();
    assert_eq!(scenes.len(), keep.len());
    let opts = ValidateOptions {
        out: out.clone(),
        betas: vec![1e-2, 1e-4, 1e-6, 1e-8],
        // the friction-law section on a coarse strip
        friction_laws: Some(20),
        imported: None,
        ..ValidateOptions::default()
    };
    let v = validate(&scenes, &opts).expect("validation runs");
    for s in &v.scenes {
        let best = |m: &str| {
            s.errors
                .iter()
                .filter(|e| e.method == m)
                .map(|e| e.error)
                .fold(f64::INFINITY, f64::min)
        };
        println!(
            "{}: best error fdm-central {:.2e}, sdm-central {:.2e}, sdm {:.2e}",
            s.scene,
            best("fdm-central"),
            best("sdm-central"),
            best("sdm")
        );
        // DDM against central differences of complete reruns, an independent method: the
        // issue's 1e-5 away from flagged increments
        assert!(
            best("fdm-central") <= 1e-5,
            "{}: DDM vs central FDM",
            s.scene
        );
        // SDM central evaluates the same residual at b +- db: truncation O(beta^2) leaves it
        // far below FDM's round-off floor at its best beta
        assert!(
            best("sdm-central") <= 1e-7,
            "{}: DDM vs central SDM",
            s.scene
        );
    }
    assert!(!v.oracles.is_empty());
    for o in &v.oracles {
        println!(
            "{} {}: expected {:.6e}, got {:.6e} ({:.2e}, tolerance {})",
            o.scene, o.quantity, o.expected, o.got, o.rel_error, o.tolerance
        );
        assert!(o.pass, "{} {}", o.scene, o.quantity);
    }
    for f in [
        "README.md",
        "data/validation.json",
        "data/stacked-leaves-errors.csv",
        "data/stacked-leaves-sensitivities.csv",
        "figures/stacked-leaves-mu-error.svg",
        "figures/stacked-leaves-cost.svg",
        "figures/laws-u0.svg",
        "figures/laws-du0dmu.svg",
        "data/friction-laws.json",
    ] {
        let p = out.join(f);
        assert!(p.exists(), "{} missing", p.display());
    }
    let report = std::fs::read_to_string(out.join("README.md")).unwrap();
    assert!(report.contains("| stacked-leaves | mu |"));
    assert!(report.contains("## Friction laws compared"));
    assert!(report.contains("| pressure-dependent | ground.n |"));
    // the adjoint in the comparison tables: every response at the last increment of each
    // scene, by one backward sweep, against DDM (an independent method: forward, per
    // parameter), and its row in the report's cost table
    for s in &v.scenes {
        let a = &s.adjoint;
        assert!(a.failure.is_none(), "{}: {:?}", s.scene, a.failure);
        assert_eq!(a.errors.len(), s.params.len(), "{}", s.scene);
        for (p, e) in s.params.iter().zip(&a.errors) {
            // the README's claim: the adjoint equals DDM to 1e-10 of each sensitivity's scale
            assert!(
                *e <= 1e-10,
                "{}: d/d {p}: adjoint against DDM {e:e}",
                s.scene
            );
        }
        assert!(a.cost_ratio.is_finite() && a.cost_ratio > 0.0);
        assert!(a.stored_bytes > 0, "{}", s.scene);
    }
    assert!(report.contains("| adjoint (last increment, every response) (error) |"));
    assert!(report.contains("**Adjoint.** Every response at the last increment"));
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn every_builtin_scene_declares_study_parameters_that_resolve() {
    for (name, _) in fricsens::scene::builtin_list() {
        let s = builtin(name).unwrap();
        assert_eq!(s.name, name);
        assert!(!s.study.params.is_empty(), "{name} declares no parameters");
        s.build().unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

/// The paper's examples on coarse meshes and short paths, DDM against central differences of
/// complete reruns (an independent method): the issue asks for 1e-5 away from the flagged
/// increments and from those where a rerun took sub-increments the nominal run did not (there
/// the difference measures the change of the discrete path, see
/// `IncrementSensitivity::rerun_substeps`), at the best of a few betas.
fn paper_scene_agreement(scene: fricsens::scene::Scene, fdm_tol: f64) {
    let out = scratch_path(&format!("paper-{}", scene.name));
    let _ = std::fs::remove_dir_all(&out);
    let opts = ValidateOptions {
        out: out.clone(),
        betas: vec![1e-3, 1e-4, 1e-5, 1e-6],
        reduced_fdm: vec![],
        friction_laws: None,
        refined_batch: false,
        imported: None,
        ..ValidateOptions::default()
    };
    let v = validate(std::slice::from_ref(&scene), &opts).expect("validation runs");
    let s = &v.scenes[0];
    for p in &s.params {
        let best = |m: &str| {
            s.errors
                .iter()
                // a beta where a rerun sub-stepped early compares too few increments
                .filter(|e| {
                    e.method == m
                        && &e.param == p
                        && e.error.is_finite()
                        && e.substep_excluded < s.increments / 2
                })
                .map(|e| (e.error, e.beta, e.substep_excluded))
                .min_by(|a, b| a.0.total_cmp(&b.0))
        };
        let (fdm, sdm) = (best("fdm-central"), best("sdm-central"));
        println!(
            "{} d/d {p}: fdm-central {fdm:?}, sdm-central {sdm:?} ({} of {} increments flagged)",
            s.scene,
            s.flagged.len(),
            s.increments
        );
        let (fdm, _, _) = fdm.expect("central FDM compared on most increments at some beta");
        assert!(
            fdm <= fdm_tol,
            "{} d/d {p}: DDM vs central FDM {fdm:.2e}",
            s.scene
        );
        // SDM central perturbs the same residual: O(beta^2) truncation, far below FDM's floor
        let (sdm, _, _) = sdm.expect("central SDM");
        assert!(
            sdm <= 1e-7,
            "{} d/d {p}: DDM vs central SDM {sdm:.2e}",
            s.scene
        );
    }
    let figures: &[&str] = if s.scene == "indentation" {
        &[
            "fig4-indentation-pressure.svg",
            "fig5-indentation-dpdmu.svg",
        ]
    } else {
        &[
            "fig7-leaf-force.svg",
            "fig8-leaf-dFdL.svg",
            "fig9-leaf-dFdmu.svg",
        ]
    };
    for f in figures {
        assert!(out.join("figures").join(f).exists(), "{f} missing");
    }
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn reduced_indentation_ddm_agrees_with_central_fdm() {
    let mut scene = fricsens::scene::indentation(2, 4);
    scene.name = "indentation".into();
    scene.study.params = vec!["mu".into()];
    paper_scene_agreement(scene, 1e-5);
}

/// The leaf spring, coarse: path dependent (friction and plasticity), load reversals.
#[test]
fn reduced_leaf_spring_ddm_agrees_with_central_fdm() {
    let mut scene = fricsens::scene::leaf_spring(&fricsens::scene::LeafSpringSpec::reduced());
    scene.name = "leaf-spring".into();
    paper_scene_agreement(scene, 1e-5);
}

/// The history at t = 0 is not zero for frictional contact: each hitting node's anchor is the
/// projection of its reference position, which a shape parameter moves. DDM must start from
/// dh_0/db (it started from zero, and the leaf spring's first increment was off by 1.3 % in
/// d tip / d L against central FDM). Solved with the converged tangent (the last Newton
/// factorization is off by Newton's last correction: 3.5e-6 here). A short loading of the coarse leaf spring against central
/// differences of reruns.
#[test]
fn shape_sensitivity_carries_the_initial_anchor_derivative() {
    use fricsens::scene::{leaf_spring, LeafSpringSpec};
    use fricsens::sensitivity::{run_sensitivity, Method, Parameter, Settings, TangentChoice};
    let scene = leaf_spring(&LeafSpringSpec {
        stroke: 2.5,
        unload_to: 2.5,
        load_increments: 2,
        ..LeafSpringSpec::reduced()
    });
    let model = scene.build().unwrap();
    let p = [Parameter::by_name(&model, "upper.length.x").unwrap()];
    let run = |method, beta| {
        let settings = Settings {
            method,
            beta,
            tangent: TangentChoice::Exact,
            ..Settings::default()
        };
        run_sensitivity(&model, &p, &settings).unwrap().1
    };
    let ddm = run(Method::Ddm, 0.0);
    let fdm = run(Method::FdmCentral, 1e-5);
    for (a, b) in ddm.increments.iter().zip(&fdm.increments).take(2) {
        for r in 0..a.values.len() {
            let (x, y) = (a.derivatives[r][0], b.derivatives[r][0]);
            println!(
                "t = {}: {} ddm {x:.9e} fdm {y:.9e}",
                a.time, ddm.responses[r]
            );
            if x == 0.0 && y == 0.0 {
                continue; // no plastic flow yet
            }
            // central FDM at beta 1e-5: truncation ~1e-10, Newton-tolerance noise ~1e-7
            assert!(
                (x - y).abs() <= 1e-6 * x.abs().max(y.abs()),
                "t = {} {}: ddm {x} vs fdm {y}",
                a.time,
                ddm.responses[r]
            );
        }
    }
}
