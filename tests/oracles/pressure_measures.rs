//! The two contact pressures: nominal (normal force over the reference tributary area) and
//! current (over the deformed one, the Cauchy pressure CalculiX and Abaqus report), on the
//! paper's rigid flat block sliding over an elastic half-space.

use crate::common;
use fricsens::prelude::*;
use fricsens::response::{PressureMeasure, ResponseKind};
use fricsens::scene::{Component, ResponseSpec};

#[test]
fn the_current_pressure_integrates_to_the_normal_force_and_ddm_equals_central_fdm() {
    let mut s = builtin::indentation(2, 3);
    s.responses
        .retain(|r| !matches!(r, ResponseSpec::PressureProfile { .. }));
    for (name, area) in [
        ("p_nominal", PressureMeasure::Nominal),
        ("p_current", PressureMeasure::Current),
    ] {
        s.responses.push(ResponseSpec::PressureProfile {
            name: name.into(),
            pair: "block".into(),
            along: Component::X,
            area,
        });
    }
    let model = s.build().unwrap();
    let (ps, ddm, fdm) = common::ddm_and_central_fdm(&model, &["mu", "E"]);
    let res = Solver::new(&model)
        .unwrap()
        .run(&Default::default(), &mut fricsens::solver::NoObserver)
        .unwrap();
    let pair = &model.contacts[0];
    let faces = pair.hitting_faces.as_ref().expect("a face-set pair");
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let kind = |r: usize| match model.responses[r].kind {
        ResponseKind::ContactPressure { node, measure, .. } => Some((node, measure)),
        _ => None,
    };
    let mut closed = 0;
    for (k, inc) in ddm.increments.iter().enumerate() {
        // the deformed tributary areas of this increment, from its displacements
        let z = &res.states[k + 1];
        let at = |n: usize| x[n] + nalgebra::Vector3::new(z[3 * n], z[3 * n + 1], z[3 * n + 2]);
        let current = faces.tributary_areas_at(at, &pair.hitting);
        let normal = &res.contact[k + 1].normal_force;
        let (mut integral, mut total) = (0.0, 0.0);
        for r in 0..model.responses.len() {
            let Some((node, measure)) = kind(r) else {
                continue;
            };
            match measure {
                PressureMeasure::Current => {
                    integral += inc.values[r] * current[node];
                    total += normal[node];
                }
                PressureMeasure::Nominal => {
                    // the two measures differ by the area ratio, and do differ where closed
                    let twin = (0..model.responses.len())
                        .find(|q| kind(*q) == Some((node, PressureMeasure::Current)))
                        .unwrap();
                    let ratio = current[node] / pair.area[node];
                    let (pn, pc) = (inc.values[r], inc.values[twin]);
                    assert!((pn - pc * ratio).abs() <= 1e-12 * pn.abs().max(1e-300));
                    if pn > 0.0 {
                        closed += 1;
                        assert!(pn != pc, "node {node}: the measures coincide");
                    }
                }
            }
        }
        assert!(
            (integral - total).abs() <= 1e-12 * total.abs(),
            "increment {}: {integral} vs {total}",
            k + 1
        );
    }
    assert!(closed > 0);
    // DDM against central FDM for every pressure, both measures
    for (p, param) in ps.iter().enumerate() {
        let scale = (ddm.increments.iter())
            .flat_map(|i| i.derivatives.iter().map(move |d| d[p].abs()))
            .fold(0.0f64, f64::max);
        let mut worst: f64 = 0.0;
        for (a, b) in ddm.increments.iter().zip(&fdm.increments) {
            for r in (0..model.responses.len()).filter(|r| kind(*r).is_some()) {
                worst = worst.max((a.derivatives[r][p] - b.derivatives[r][p]).abs() / scale);
            }
        }
        println!(
            "{}: DDM vs central FDM {worst:.2e} of {scale:.4e}",
            param.name
        );
        // central FDM, beta = 1e-6: truncation beta^2, the reruns' round-off about 1e-10
        assert!(worst < 1e-6, "{}: {worst:.2e}", param.name);
    }
}
