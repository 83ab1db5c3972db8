//! Field parameters: a material parameter per element (`BODY.PARAM[E]`), a friction parameter
//! per hitting node (`PAIR.PARAM[N]`), a reference coordinate per node and axis
//! (`SET.x[N]`). Checked by invariants, by the adjoint against DDM and by reruns:
//! * a field's derivatives sum to its whole parameter's: every element's `sigma_y` (`E`)
//!   moved together is the body's, every hitting node's `mu` the pair's, every node of a body
//!   moved along `y` the body's `origin.y`;
//! * the adjoint's field passes (a colour's members seeded together) give DDM's derivatives;
//! * a Taylor test of the adjoint's gradient in a random field direction, against reruns of
//!   the model with every element's and node's own values set.

use crate::common::taylor_remainders;
use fricsens::design::{DesignParam, ParameterError};
use fricsens::prelude::*;
use fricsens::scene::Scene;
use fricsens::sensitivity::{run_sensitivity, SensitivityResults};

/// Every parameter the names stand for, fields expanded.
fn expand(model: &Model, names: &[&str]) -> Vec<Parameter> {
    (names.iter())
        .flat_map(|n| Parameter::expand(model, n).unwrap())
        .collect()
}

fn run(model: &Model, ps: &[Parameter], method: Method) -> SensitivityResults {
    let settings = Settings {
        method,
        ..Settings::default()
    };
    run_sensitivity(model, ps, &settings).unwrap().1
}

/// The leaf spring (coarse): J2 plasticity in both leaves, Coulomb friction between them and
/// at the block, load, unload and reload.
fn leaf_spring() -> Model {
    Scene::load("leaf-spring-coarse").unwrap().build().unwrap()
}

/// The fields and the whole parameter each sums to.
const FIELDS: [(&str, &str); 4] = [
    ("upper.sigma_y[*]", "upper.sigma_y"),
    ("upper.E[*]", "upper.E"),
    ("leaves.mu[*]", "leaves.mu"),
    ("upper.all.y[*]", "upper.origin.y"),
];

#[test]
fn field_derivatives_sum_to_the_whole_parameter_and_the_adjoint_gives_ddms() {
    let model = leaf_spring();
    let mut names = Vec::new();
    let mut groups = Vec::new();
    for (field, whole) in FIELDS {
        let members = Parameter::expand(&model, field).unwrap().len();
        assert!(members > 1, "{field}: {members} members");
        groups.push((names.len(), members, field));
        names.push(field);
        names.push(whole);
    }
    let ps = expand(&model, &names);
    let ddm = run(&model, &ps, Method::Ddm);
    let adj = run(&model, &ps, Method::Adjoint);
    // the adjoint at the last increment (its default functional)
    let last = ddm.increments.last().unwrap();
    let adj_last = adj.increments.last().unwrap();
    assert_eq!(adj_last.increment, last.increment);
    let mut offset = 0;
    for &(_, members, field) in &groups {
        let whole = offset + members;
        for (r, name) in ddm.responses.iter().enumerate() {
            for inc in &ddm.increments {
                let row = &inc.derivatives[r][offset..whole];
                let sum: f64 = row.iter().sum();
                // the sum of `members` derivatives, each to the round-off of its solve:
                // 1e-10 of the sum of their magnitudes (a rigid translation's terms cancel to
                // 1e-2 of their magnitude in the block force)
                let magnitude: f64 = row.iter().map(|d| d.abs()).sum();
                let d = inc.derivatives[r][whole];
                assert!(
                    (sum - d).abs() <= 1e-10 * magnitude.max(d.abs()),
                    "{field} / {name} at increment {}: sum {sum:e}, whole {d:e}",
                    inc.increment
                );
            }
            // adjoint = DDM on every member, to 1e-10 of the field's largest derivative
            let scale = (offset..=whole)
                .map(|k| last.derivatives[r][k].abs())
                .fold(0.0, f64::max);
            for (k, p) in ps.iter().enumerate().take(whole + 1).skip(offset) {
                let (x, y) = (last.derivatives[r][k], adj_last.derivatives[r][k]);
                assert!(
                    (x - y).abs() <= 1e-10 * scale,
                    "{} / {name}: DDM {x:e}, adjoint {y:e} (field scale {scale:e})",
                    p.name
                );
            }
        }
        offset = whole + 1;
    }
}

/// The remainder `|f(b + h d) - f(b) - h df.d|` of the block force at the end of the path
/// falls as `h^2` over three decades, `d` a random direction over every element's `sigma_y`
/// and `E` of the upper leaf and every hitting node's `mu` (relative to each value): the
/// reruns set each element's and node's own value (`Model::set_param` on the field targets).
#[test]
fn adjoint_field_gradient_passes_a_taylor_test() {
    let model = leaf_spring();
    let ps = expand(&model, &["upper.sigma_y[*]", "upper.E[*]", "leaves.mu[*]"]);
    let (_, adj) = run_sensitivity(
        &model,
        &ps,
        &Settings {
            method: Method::Adjoint,
            ..Settings::default()
        },
    )
    .unwrap();
    let r = 0;
    let last = adj.increments.last().unwrap();
    let rem = taylor_remainders(&model, &ps, last, r, &[1e-1, 1e-2, 1e-3, 1e-4]);
    for w in rem.windows(2) {
        // h^2: a factor 100 per decade; 30 allows the path's own curvature to vary
        assert!(w[1] < w[0] / 30.0, "remainders {rem:?}");
    }
}

#[test]
fn field_names_resolve_or_say_what_is_wrong() {
    let model = leaf_spring();
    let e = model.mesh.group_elements(model.bodies[0].group).start;
    let p = Parameter::by_name(&model, &format!("upper.sigma_y[{e}]")).unwrap();
    assert_eq!(
        p.targets,
        [DesignParam::ElementMaterial {
            element: e,
            index: 2
        }]
    );
    assert_eq!(
        p.value,
        Parameter::by_name(&model, "upper.sigma_y").unwrap().value
    );
    // an element of the other body
    let other = model.mesh.group_elements(model.bodies[1].group).start;
    assert!(matches!(
        Parameter::by_name(&model, &format!("upper.E[{other}]")),
        Err(ParameterError::NotOn { what: "element", number, .. }) if number == other
    ));
    assert!(matches!(
        Parameter::expand(&model, "upper.E[x]"),
        Err(ParameterError::FieldSyntax { .. })
    ));
    assert!(matches!(
        Parameter::expand(&model, "upper.all.w[*]"),
        Err(ParameterError::Axis { .. })
    ));
    // a range keeps the members it holds
    let range = Parameter::expand(&model, &format!("upper.E[{}..{}]", e, e + 3)).unwrap();
    assert_eq!(range.len(), 3);
    // and one that holds none, empty, reversed or beyond the body, is an error naming the
    // field's members (it asked the sensitivity solves for no column: a panic in the solver)
    let n_upper = model.mesh.group_elements(model.bodies[0].group).len();
    for bad in [
        format!("upper.E[{e}..{e}]"),
        format!("upper.E[{}..{e}]", e + 3),
        format!("upper.E[{other}..{}]", other + 2),
        "upper.E[1000000..2000000]".to_string(),
    ] {
        match Parameter::expand(&model, &bad) {
            Err(ParameterError::EmptyRange {
                count, numbered, ..
            }) => {
                assert_eq!(count, n_upper, "{bad}");
                let last = e + n_upper - 1;
                assert_eq!(numbered, format!(" (numbered {e} to {last})"), "{bad}");
            }
            r => panic!("{bad}: {r:?}"),
        }
    }
    // setting a member moves it alone
    let mut m = model.clone();
    m.set_param(p.targets[0], 2.0 * p.value);
    assert_eq!(m.param_value(p.targets[0]), Some(2.0 * p.value));
    let next = DesignParam::ElementMaterial {
        element: e + 1,
        index: 2,
    };
    assert_eq!(m.param_value(next), Some(p.value));
}
