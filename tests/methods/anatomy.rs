//! SDM's error anatomy (`Settings::explain`, `fricsens::sensitivity::anatomy`): the parts add
//! up to SDM's error against DDM, explaining does not change SDM's values, and a term a
//! parameter does not enter carries no error.

use crate::common;
use fricsens::prelude::*;
use fricsens::sensitivity::anatomy::Term;
use fricsens::sensitivity::{run_sensitivity, Method, SensitivityResults, Settings};

fn explained(model: &Model, names: &[&str], method: Method, beta: f64) -> SensitivityResults {
    let params = common::params(model, names);
    let settings = Settings {
        method,
        beta,
        explain: true,
        ..Settings::default()
    };
    run_sensitivity(model, &params, &settings).unwrap().1
}

/// Each parameter's derivative scale (largest DDM magnitude over the run), per response.
fn scales(s: &SensitivityResults) -> Vec<Vec<f64>> {
    (0..s.responses.len())
        .map(|r| {
            (0..s.parameters.len())
                .map(|k| {
                    s.anatomy
                        .iter()
                        .map(|a| a.reference[r][k].abs())
                        .fold(0.0, f64::max)
                })
                .collect()
        })
        .collect()
}

#[test]
fn the_parts_add_up_to_sdms_error_against_ddm() {
    // every term of the residual among them: elastic and plastic elements, contact normal and
    // friction (the leaf spring), loads (the stacked leaves' tip load), a spring (Jenkins)
    for (scene, names) in [
        ("leaf-spring-coarse", vec!["upper.length.x", "mu"]),
        ("stacked-leaves", vec!["E", "mu"]),
        ("jenkins", vec!["mu"]),
        ("uniaxial-j2", vec!["H", "E"]),
    ] {
        let model = Scene::load(scene).unwrap().build().unwrap();
        let params = common::params(&model, &names);
        let ddm = common::sensitivities(&model, &params, Method::Ddm, 0.0);
        for (method, beta) in [(Method::Sdm, 1e-3), (Method::SdmCentral, 1e-2)] {
            let plain = common::sensitivities(&model, &params, method, beta);
            let s = explained(&model, &names, method, beta);
            let scale = scales(&s);
            assert_eq!(s.anatomy.len(), s.increments.len(), "{scene}");
            let mut worst: f64 = 0.0;
            let mut large = 0;
            for (n, a) in s.anatomy.iter().enumerate() {
                for (r, scale) in scale.iter().enumerate() {
                    for k in 0..names.len() {
                        // explaining changes nothing SDM computes
                        let d = s.increments[n].derivatives[r][k];
                        assert_eq!(d.to_bits(), plain.increments[n].derivatives[r][k].to_bits());
                        // the anatomy's reference is DDM (solved to 1e-13 of the solution)
                        let reference = ddm.increments[n].derivatives[r][k];
                        let sc = scale[k];
                        assert!(
                            (a.reference[r][k] - reference).abs() <= 1e-12 * sc,
                            "{scene} {method:?}: reference {} against DDM {reference}",
                            a.reference[r][k]
                        );
                        let p = &a.parts[r][k];
                        assert!(((d - reference) - p.total).abs() <= 1e-12 * sc);
                        // a response insensitive to the parameter (a reaction fixed by
                        // equilibrium) has a round-off derivative: left out, as in the report
                        let size = s
                            .increments
                            .iter()
                            .map(|i| i.values[r].abs())
                            .fold(0.0, f64::max);
                        if params[k].value.abs().max(1.0) * sc < 1e-9 * size {
                            continue;
                        }
                        // everywhere to the round-off of the differences (eps times the
                        // response's size over the step, the residual's likewise through the
                        // solve) and of the solves (1e-13 of the solution)
                        let h = params[k].step(beta);
                        let roundoff = 10.0 * f64::EPSILON * size / h + 1e-12 * sc;
                        assert!(
                            (p.sum() - p.total).abs() <= roundoff,
                            "{scene} {method:?} increment {n} {} {}: {} against {} (scale {sc:e}, size {size:e}, reference {reference:e}, SDM {d:e})",
                            s.responses[r],
                            s.parameters[k],
                            p.sum(),
                            p.total
                        );
                        // and where the error is at least 1e-2 of the scale (truncation, what
                        // the anatomy explains) to 1e-10 of the error
                        if p.total.abs() >= 1e-2 * sc {
                            let miss = (p.sum() - p.total).abs() / p.total.abs();
                            worst = worst.max(miss);
                            large += 1;
                        }
                    }
                }
            }
            assert!(worst <= 1e-10, "{scene} {method:?}: {worst:e}");
            // the leaf spring's length: errors far above the scale at these steps
            if scene == "leaf-spring-coarse" && method == Method::Sdm {
                assert!(large > 10, "{large} errors of at least 1e-2 of the scale");
            }
        }
    }
}

#[test]
fn a_term_the_parameter_does_not_enter_carries_no_error() {
    // the hardening modulus enters only the return map; elements on the elastic branch see it
    // through the plastic strain's derivative alone, in which their stress is linear (S = C
    // (E - E^p)): their part is round-off, the return map's is truncation, of order 1
    let model = Scene::load("uniaxial-j2").unwrap().build().unwrap();
    let s = explained(&model, &["H"], Method::Sdm, 1e-4);
    let scale = scales(&s);
    let at = |t: Term| Term::ALL.iter().position(|x| *x == t).unwrap();
    let (elastic, plastic) = (at(Term::ElasticElements), at(Term::PlasticElements));
    let mut truncation_dominated = 0;
    for a in &s.anatomy {
        for (r, row) in a.parts.iter().enumerate() {
            let e = &row[0];
            for (i, v) in e.terms.iter().enumerate() {
                if i != elastic && i != plastic {
                    assert_eq!(
                        v.value,
                        0.0,
                        "{:?} at increment {}",
                        Term::ALL[i],
                        a.increment
                    );
                }
            }
            assert!(e.terms[elastic].value.abs() <= 1e-12 * scale[r][0]);
            if e.terms[plastic].value.abs() > 1e-6 * scale[r][0] {
                let order = e.terms[plastic].order().unwrap();
                assert!((order - 1.0).abs() < 0.05, "order {order}");
                truncation_dominated += 1;
            }
        }
    }
    assert!(truncation_dominated > 0, "the return map is nonlinear in H");
    // mu enters only the friction forces (the stacked leaves are elastic)
    let model = Scene::load("stacked-leaves").unwrap().build().unwrap();
    let s = explained(&model, &["mu"], Method::Sdm, 1e-4);
    let friction = at(Term::Friction);
    for a in &s.anatomy {
        for row in &a.parts {
            for (i, e) in row[0].terms.iter().enumerate() {
                if i != friction {
                    assert_eq!(
                        e.value,
                        0.0,
                        "{:?} at increment {}",
                        Term::ALL[i],
                        a.increment
                    );
                }
            }
        }
    }
}
