//! The derivatives of the state's fields (`Settings::fields`, `fricsens sensitivity --vtk`)
//! against the derivatives of responses that read the same quantity, by every method: a field
//! is differentiated the way each method differentiates a response, so where a response reads
//! one field value the two must agree to round-off. And across methods: SDM's and FDM's
//! fields agree with DDM's within their perturbation error.

use crate::common::params;

use fricsens::fields::{Field, Location};
use fricsens::model::node_dof;
use fricsens::prelude::*;
use fricsens::response::{ResponseKind, StressMeasure};
use fricsens::scene::ResponseSpec;

fn field<'a>(fields: &'a [Field<f64>], name: &str) -> &'a Field<f64> {
    fields
        .iter()
        .find(|f| f.name == name)
        .unwrap_or_else(|| panic!("no field {name}"))
}

fn fields_run(model: &Model, names: &[&str], method: Method) -> SensitivityResults {
    let ps = params(model, names);
    let settings = Settings {
        method,
        beta: if method == Method::Sdm { 1e-7 } else { 1e-5 },
        fields: true,
        ..Settings::default()
    };
    run_sensitivity(model, &ps, &settings).unwrap().1
}

/// The J2 beam of `methods` with the von Mises stress of its clamp element as a response:
/// the field `von_mises` of that element, differentiated by each method, is the response's
/// derivative by the same method (DDM: the same dual evaluation; SDM and FDM: the same
/// difference of the same stresses, the rerun's re-evaluated at its converged state).
#[test]
fn stress_field_derivatives_equal_the_stress_response_by_every_method() {
    let mut scene = crate::methods::j2_beam();
    scene.responses.push(ResponseSpec::Stress {
        name: "clamp-mises".into(),
        body: "beam".into(),
        element: 0,
        measure: StressMeasure::VonMises,
    });
    let model = scene.build().unwrap();
    let names = ["sigma_y", "E"];
    let mut ddm = None;
    for method in [Method::Ddm, Method::Sdm, Method::FdmCentral] {
        let s = fields_run(&model, &names, method);
        let r = s.response_index("clamp-mises").unwrap();
        assert_eq!(s.fields.len(), s.increments.len(), "{method:?}");
        let mut worst = 0.0f64;
        for (inc, f) in s.increments.iter().zip(&s.fields) {
            assert_eq!(inc.increment, f.increment);
            for (k, fields) in f.derivatives.iter().enumerate() {
                let from_field = field(fields, "von_mises").values[0];
                let from_response = inc.derivatives[r][k];
                let scale = s
                    .increments
                    .iter()
                    .map(|i| i.derivatives[r][k].abs())
                    .fold(0.0, f64::max);
                let gap = (from_field - from_response).abs() / scale;
                assert!(
                    gap.is_finite(),
                    "{method:?}: {from_field} against {from_response}"
                );
                worst = worst.max(gap);
            }
        }
        println!("{method:?}: field against response {worst:.1e} of the scale");
        // the same arithmetic on the same numbers: round-off of the evaluation (FDM's
        // re-evaluation of each rerun's converged state differs from the stored stress by
        // the evaluation's round-off over a difference at beta = 1e-5)
        let tol = if method == Method::FdmCentral {
            1e-8
        } else {
            1e-12
        };
        assert!(worst < tol, "{method:?}: {worst:.1e}");
        if method == Method::Ddm {
            ddm = Some(s);
        } else {
            // across methods: within the perturbation error of the responses' own agreement
            let d = ddm.as_ref().unwrap();
            let disp = |r: &SensitivityResults, i: usize, k: usize| {
                field(&r.fields[i].derivatives[k], "displacement")
                    .values
                    .clone()
            };
            let mut worst = 0.0f64;
            for k in 0..names.len() {
                // the scale of the parameter's displacement derivative over the history
                let scale = (0..d.fields.len())
                    .flat_map(|i| disp(d, i, k))
                    .fold(0.0f64, |m, v| m.max(v.abs()));
                for i in 0..d.fields.len() {
                    for (x, y) in disp(&s, i, k).iter().zip(disp(d, i, k)) {
                        let gap = (x - y).abs() / scale;
                        assert!(gap.is_finite(), "{method:?}: {x} against {y}");
                        worst = worst.max(gap);
                    }
                }
            }
            println!("{method:?}: displacement field against DDM {worst:.1e} of its scale");
            // forward SDM at 1e-7 (truncation, beta x curvature) and central FDM at 1e-5
            // (truncation beta^2 and the reruns' Newton tolerance over 2 db): 7.9e-8 and
            // 1.0e-6 measured
            let tol = if method == Method::FdmCentral {
                1e-5
            } else {
                1e-6
            };
            assert!(worst < tol, "{method:?}: {worst:.1e}");
        }
    }
}

/// DDM on the Hertz scene: each node's contact pressure field is its pressure response
/// (`pressure-profile` per node, nominal area), and the displacement field's derivative is
/// the state derivative `dz/db` itself.
#[test]
fn contact_field_derivatives_equal_the_pressure_responses() {
    let model = builtin("hertz").unwrap().build().unwrap();
    let ps = params(&model, &["E"]);
    let settings = Settings {
        method: Method::Ddm,
        fields: true,
        ..Settings::default()
    };
    let mut engine = Engine::new(&model, &ps, settings).keep_state_derivative(true);
    Solver::new(&model)
        .unwrap()
        .run(&RunOptions::default(), &mut engine)
        .unwrap();
    let s = engine.results;
    let mut checked = 0;
    for (inc, f) in s.increments.iter().zip(&s.fields) {
        let fields = &f.derivatives[0];
        let dz = &inc.state_derivative.as_ref().unwrap()[0];
        let u = field(fields, "displacement");
        assert_eq!(u.location, Location::Point);
        for (i, v) in u.values.iter().enumerate() {
            assert_eq!(
                *v,
                dz[node_dof(i / 3, i % 3)],
                "increment {}",
                inc.increment
            );
        }
        let p = field(fields, "contact_pressure_nominal");
        let scale = inc
            .derivatives
            .iter()
            .map(|d| d[0].abs())
            .fold(0.0, f64::max);
        for (r, resp) in model.responses.iter().enumerate() {
            if let ResponseKind::ContactPressure { pair, nodes, .. } = &resp.kind {
                let node = model.contacts[*pair].hitting[nodes[0]];
                let d = inc.derivatives[r][0];
                assert!(
                    (p.values[node] - d).abs() <= 1e-12 * scale,
                    "{}: field {} response {d}",
                    resp.name,
                    p.values[node]
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 0);
}
