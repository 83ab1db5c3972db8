//! Robustness (issue 8): bad input is a typed error that names the file, the field (its TOML
//! path) and the problem; no input makes `Scene::from_toml` or `Scene::build` panic (proptest
//! fuzz on raw text and on mutated built-in scenes); analyses and DDM sensitivities are
//! bit-identical across runs and rayon thread counts.

use crate::common::{fricsens, scratch_path, solve};

use fricsens::contact::friction::{PressureDependentCoulomb, RegularizedCoulomb};
use fricsens::contact::Friction;
use fricsens::element::{Formulation, Kinematics};
use fricsens::law::Law;
use fricsens::material::Material;
use fricsens::model::Model;
use fricsens::scene::{
    builtin, PrescribedSpec, RigidSpec, Scene, SceneError, StepSpec, TargetSpec,
};
use fricsens::scene::{cantilever, CantileverSpec, Component, ResponseSpec};
use fricsens::sensitivity::{run_sensitivity, Method, Parameter, Settings};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

// ---------------------------------------------------------------------------------------
// Bad input classes
// ---------------------------------------------------------------------------------------

fn parse_build(text: &str, file: &str) -> Result<Model, SceneError> {
    Scene::from_toml(text, file).and_then(|s| s.build())
}

/// The error of `text`, which must contain every one of `needles`.
#[track_caller]
fn rejects(text: &str, needles: &[&str]) -> String {
    let err = match parse_build(text, "case.toml") {
        Ok(_) => panic!("accepted a bad scene (expected {needles:?}):\n{text}"),
        Err(e) => e.to_string(),
    };
    for n in needles {
        assert!(err.contains(n), "`{n}` is not in the error:\n{err}");
    }
    err
}

/// The TOML of built-in scene `name` after `edit`.
fn edited(name: &str, edit: impl FnOnce(&mut Scene)) -> String {
    let mut s = builtin(name).unwrap();
    edit(&mut s);
    s.to_toml().unwrap()
}

/// The TOML of built-in scene `name` with the first `from` replaced by `to`.
#[track_caller]
fn replaced(name: &str, from: &str, to: &str) -> String {
    let text = builtin(name).unwrap().to_toml().unwrap();
    assert!(text.contains(from), "`{from}` not in the TOML of {name}");
    text.replacen(from, to, 1)
}

/// 1-based line of the first occurrence of `what` in `text`.
fn line_of(text: &str, what: &str) -> usize {
    text[..text.find(what).unwrap()].lines().count() + 1
}

#[test]
fn the_builtin_scenes_used_below_are_valid() {
    for name in [
        "contact-patch",
        "uniaxial-j2",
        "klarbring-2dof",
        "sliding-block",
        "jenkins",
    ] {
        let text = builtin(name).unwrap().to_toml().unwrap();
        parse_build(&text, name).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn malformed_toml_names_the_file_and_the_line() {
    for (from, to) in [
        ("E = 1000.0", "E = = 1000.0"),
        ("[[bodies]]", "[[bodies]"),
        ("name = \"lower\"", "name = \"lower"),
        ("nu = 0.3", "nu = 0.3.1"),
    ] {
        let text = replaced("contact-patch", from, to);
        let line = line_of(&text, to);
        let err = rejects(&text, &["case.toml", &format!("line {line}")]);
        assert!(err.starts_with("case.toml: "), "{err}");
    }
}

#[test]
fn unknown_keys_are_named_by_their_path() {
    let cases = [
        (
            "E = 1000.0",
            "E = 1000.0\nyoung = 3.0",
            "bodies[0].material.young",
        ),
        ("[[bodies]]", "[[bodies]]\nyoung = 3.0", "bodies[0].young"),
        (
            "name = \"contact-patch\"",
            "name = \"contact-patch\"\nfoo = 1",
            "foo",
        ),
        (
            "hitting = \"upper.ymin\"",
            "hitting = \"upper.ymin\"\nbogus = 2",
            "contacts[0].bogus",
        ),
        (
            "max_iterations = 30",
            "max_iterations = 30\ntolerance = 1.0",
            "solver.tolerance",
        ),
        ("[study]", "[study]\nbetas = [0.1]", "study.betas"),
        (
            "elements = 2",
            "elements = 2\nsize = 3",
            "bodies[0].y.zones[0].size",
        ),
    ];
    for (from, to, path) in cases {
        let text = replaced("contact-patch", from, to);
        rejects(&text, &[&format!("field `{path}`:"), "unknown field"]);
    }
    // a misspelt key of the normal law (an internally tagged enum: named by its table)
    let text = replaced(
        "contact-patch",
        "[contacts.normal]\nlaw = \"lagrange\"",
        "[contacts.normal]\nlaw = \"lagrange\"\nstiffnes = 5.0",
    );
    rejects(&text, &["contacts[0].normal", "stiffnes"]);
}

#[test]
fn missing_required_fields_are_named_by_their_path() {
    let cases = [
        ("E = 1000.0\n", "", "bodies[0].material.E"),
        ("increments = 1\n", "", "steps[0].increments"),
        ("hitting = \"upper.ymin\"\n", "", "contacts[0].hitting"),
        ("length = 2.0\n", "", "bodies[0].x.length"),
    ];
    for (from, to, path) in cases {
        let text = replaced("contact-patch", from, to);
        rejects(&text, &[&format!("field `{path}`:"), "missing field"]);
    }
    // in later entries of arrays of tables
    let text = builtin("contact-patch").unwrap().to_toml().unwrap();
    let second = text.rfind("E = 1000.0\n").unwrap();
    let text = format!(
        "{}{}",
        &text[..second],
        &text[second + "E = 1000.0\n".len()..]
    );
    rejects(&text, &["field `bodies[1].material.E`:", "missing field"]);
    // prescribed[3] ('upper-z') is the one entry on upper.zmin
    let text = replaced("contact-patch", "set = \"upper.zmin\"\n", "");
    rejects(&text, &["field `prescribed[3].set`:", "missing field"]);
    // a wrong type inside an array
    let text = replaced("contact-patch", "origin = [0.0,", "origin = [\"0\",");
    rejects(
        &text,
        &["field `bodies[0].origin[0]`:", "invalid type: string"],
    );
    // a whole missing table
    let text = builtin("contact-patch").unwrap().to_toml().unwrap();
    let start = text.find("[[steps]]").unwrap();
    let end = start + text[start..].find("\n\n").unwrap();
    let text = format!("{}{}", &text[..start], &text[end..]);
    rejects(&text, &["field `steps`:", "missing field"]);
}

#[test]
fn a_string_for_a_number_is_a_type_error_at_its_table() {
    let text = replaced("contact-patch", "nu = 0.3", "nu = \"0.3\"");
    rejects(&text, &["bodies[0].material", "invalid type: string"]);
    let text = replaced("contact-patch", "end = 1.0", "end = \"1.0\"");
    rejects(&text, &["field `steps[0].end`:", "invalid type: string"]);
}

fn material(s: &mut Scene) -> &mut Material {
    &mut s.bodies[0].material
}

#[test]
fn youngs_modulus_must_be_positive() {
    for e in [0.0, -1.0, -1e300] {
        let text = edited("contact-patch", |s| {
            *material(s).param_mut("E").unwrap() = e;
        });
        rejects(&text, &["field `bodies[0].material.E`:", "must be > 0"]);
    }
}

#[test]
fn poissons_ratio_must_lie_in_its_open_interval() {
    for nu in [0.5, -1.0, 0.7, -1.5, 0.5000001] {
        let text = edited("contact-patch", |s| {
            *material(s).param_mut("nu").unwrap() = nu;
        });
        rejects(&text, &["field `bodies[0].material.nu`:", "(-1, 0.5)"]);
    }
    // the J2 law checks it too
    let text = replaced("uniaxial-j2", "nu = 0.3", "nu = 0.5");
    rejects(&text, &["field `bodies[0].material.nu`:", "(-1, 0.5)"]);
}

#[test]
fn friction_coefficients_must_not_be_negative() {
    let text = replaced("contact-patch", "mu = 0.3", "mu = -0.1");
    rejects(&text, &["field `contacts[0].friction.mu`:", "must be >= 0"]);
    let text = edited("contact-patch", |s| {
        s.contacts[0].friction = Some(Friction::RegularizedCoulomb(RegularizedCoulomb::new(-1.0)))
    });
    rejects(&text, &["field `contacts[0].friction.mu`:", "must be >= 0"]);
    let text = edited("contact-patch", |s| {
        s.contacts[0].friction = Some(Friction::PressureDependent(PressureDependentCoulomb::new(
            -0.3, 1.0, 0.1,
        )))
    });
    rejects(
        &text,
        &["field `contacts[0].friction.mu0`:", "must be >= 0"],
    );
    let text = edited("contact-patch", |s| {
        s.contacts[0].friction = Some(Friction::PressureDependent(PressureDependentCoulomb::new(
            0.3, 0.0, 0.1,
        )))
    });
    rejects(&text, &["field `contacts[0].friction.p0`:", "must be > 0"]);
}

#[test]
fn the_yield_stress_must_be_positive_and_hardening_not_negative() {
    for v in ["0.0", "-250.0"] {
        let text = replaced("uniaxial-j2", "sigma_y = 250.0", &format!("sigma_y = {v}"));
        rejects(
            &text,
            &["field `bodies[0].material.sigma_y`:", "must be > 0"],
        );
    }
    let text = replaced("uniaxial-j2", "H = 10000.0", "H = -1.0");
    rejects(&text, &["field `bodies[0].material.H`:", "H < 0"]);
    // saturation needs both of its parameters, and sigma_inf >= sigma_y
    let text = replaced(
        "uniaxial-j2",
        "H = 10000.0",
        "H = 10000.0\nsigma_inf = 300.0",
    );
    rejects(&text, &["field `bodies[0].material.sigma_inf`:", "both"]);
    let text = replaced(
        "uniaxial-j2",
        "H = 10000.0",
        "H = 10000.0\nsigma_inf = 200.0\ndelta = 10.0",
    );
    rejects(
        &text,
        &[
            "field `bodies[0].material.sigma_inf`:",
            "sigma_inf >= sigma_y",
        ],
    );
}

#[test]
fn nan_and_infinite_numbers_are_rejected_where_they_stand() {
    let cases = [
        (
            "contact-patch",
            "E = 1000.0",
            "E = nan",
            "bodies[0].material.E",
        ),
        (
            "contact-patch",
            "E = 1000.0",
            "E = inf",
            "bodies[0].material.E",
        ),
        (
            "contact-patch",
            "nu = 0.3",
            "nu = -inf",
            "bodies[0].material.nu",
        ),
        (
            "contact-patch",
            "mu = 0.3",
            "mu = nan",
            "contacts[0].friction.mu",
        ),
        (
            "contact-patch",
            "length = 2.0",
            "length = inf",
            "bodies[0].x.length",
        ),
        (
            "contact-patch",
            "fraction = 1.0",
            "fraction = nan",
            "bodies[0].x.zones[0].fraction",
        ),
        (
            "contact-patch",
            "ratio = 1.0",
            "ratio = inf",
            "bodies[0].x.zones[0].ratio",
        ),
        ("contact-patch", "end = 1.0", "end = nan", "steps[0].end"),
        (
            "contact-patch",
            "value = -40.0",
            "value = -inf",
            "loads[0].value",
        ),
        (
            "contact-patch",
            "value = 0.0",
            "value = nan",
            "prescribed[0].value",
        ),
        (
            "contact-patch",
            "force_tol = 0.000000001",
            "force_tol = nan",
            "solver.force_tol",
        ),
        (
            "uniaxial-j2",
            "sigma_y = 250.0",
            "sigma_y = inf",
            "bodies[0].material.sigma_y",
        ),
        (
            "uniaxial-j2",
            "H = 10000.0",
            "H = nan",
            "bodies[0].material.H",
        ),
        (
            "sliding-block",
            "search_radius = 6.0",
            "search_radius = nan",
            "contacts[0].search_radius",
        ),
        (
            "klarbring-2dof",
            "tangential_stiffness = 1000000.0",
            "tangential_stiffness = inf",
            "contacts[0].tangential_stiffness",
        ),
        (
            "klarbring-2dof",
            "constraint_scale = 1.0",
            "constraint_scale = nan",
            "contacts[0].constraint_scale",
        ),
        (
            "klarbring-2dof",
            "stiffness = [[1.0",
            "stiffness = [[inf",
            "springs[0].stiffness",
        ),
        (
            "klarbring-2dof",
            "x = [0.0",
            "x = [nan",
            "free_nodes[0].x[0]",
        ),
        (
            "klarbring-2dof",
            "point = [0.0",
            "point = [-inf",
            "contacts[0].target.surface.point",
        ),
        (
            "klarbring-2dof",
            "normal = [0.0",
            "normal = [nan",
            "contacts[0].target.surface.normal",
        ),
        (
            "klarbring-2dof",
            "value = 0.6",
            "value = nan",
            "loads[1].value",
        ),
        (
            "jenkins",
            "value = 1.0",
            "value = inf",
            "prescribed[0].value",
        ),
    ];
    for (scene, from, to, path) in cases {
        let text = replaced(scene, from, to);
        rejects(&text, &[&format!("field `{path}`:"), "not a finite number"]);
    }
    // amplitudes
    let text = edited("contact-patch", |s| {
        s.loads[0].amplitude = vec![(0.0, 0.0), (f64::NAN, 1.0)]
    });
    rejects(
        &text,
        &["field `loads[0].amplitude`:", "not a finite number"],
    );
    let text = edited("contact-patch", |s| {
        s.prescribed[0].amplitude = vec![(0.0, f64::INFINITY)]
    });
    rejects(
        &text,
        &["field `prescribed[0].amplitude`:", "not a finite number"],
    );
    // origins
    let text = edited("contact-patch", |s| {
        s.bodies[1].block_mut().unwrap().origin[1] = f64::NAN
    });
    rejects(
        &text,
        &["field `bodies[1].origin[1]`:", "not a finite number"],
    );
    // study.beta
    let text = edited("contact-patch", |s| s.study.beta = Some(f64::NAN));
    rejects(&text, &["field `study.beta`:", "not a finite number"]);
}

/// A node-set intersection of two opposite sides of a block: no node lies on both.
const EMPTY: &str = "upper.xmin & upper.xmax";

#[test]
fn empty_sets_are_rejected() {
    let text = edited("contact-patch", |s| s.prescribed[1].set = EMPTY.into());
    rejects(&text, &["field `prescribed[1].set`:", "is empty"]);
    let text = edited("contact-patch", |s| s.loads[0].set = EMPTY.into());
    rejects(&text, &["field `loads[0].set`:", "is empty"]);
    let text = edited("contact-patch", |s| s.contacts[0].hitting = EMPTY.into());
    rejects(&text, &["field `contacts[0].hitting`:", "is empty"]);
    let text = edited("contact-patch", |s| {
        s.responses = vec![ResponseSpec::Reaction {
            name: "r".into(),
            set: EMPTY.into(),
            component: Component::Y,
        }]
    });
    rejects(&text, &["field `responses[0].set`:", "is empty"]);
    // an empty name is no set either
    let text = edited("contact-patch", |s| s.loads[0].set = String::new());
    rejects(&text, &["field `loads[0].set`:", "no node set named ''"]);
    // a prescribed entry without components
    let text = edited("contact-patch", |s| s.prescribed[0].components.clear());
    rejects(
        &text,
        &["field `prescribed[0].components`:", "no component"],
    );
}

#[test]
fn contact_pairs_naming_missing_surfaces_are_rejected() {
    let text = edited("contact-patch", |s| {
        s.contacts[0].hitting = "upper.nowhere".into()
    });
    rejects(&text, &["field `contacts[0].hitting`:", "'upper.nowhere'"]);
    let text = edited("contact-patch", |s| {
        s.contacts[0].target = TargetSpec::Faces("lower.nowhere".into())
    });
    rejects(
        &text,
        &[
            "field `contacts[0].target`:",
            "no face set named 'lower.nowhere'",
        ],
    );
    // a node set is no target surface
    let text = edited("contact-patch", |s| {
        s.contacts[0].target = TargetSpec::Faces("lower.all".into())
    });
    rejects(
        &text,
        &[
            "field `contacts[0].target`:",
            "no face set named 'lower.all'",
        ],
    );
    // responses naming a missing pair
    let text = edited("klarbring-2dof", |s| {
        s.responses = vec![ResponseSpec::TargetForce {
            name: "f".into(),
            pair: "wall".into(),
            component: Component::X,
        }]
    });
    rejects(
        &text,
        &["field `responses[0].pair`:", "no contact pair 'wall'"],
    );
    // two pairs of one name
    let text = edited("contact-patch", |s| {
        let c = s.contacts[0].clone();
        s.contacts.push(c)
    });
    rejects(&text, &["field `contacts[1].name`:", "defined twice"]);
}

#[test]
fn a_dof_prescribed_twice_is_a_conflict_naming_both_entries() {
    // the same dofs as `upper-x` (prescribed[1]: upper.xmin, x, 0) with another value
    let text = edited("contact-patch", |s| {
        s.prescribed.push(PrescribedSpec {
            name: "push".into(),
            set: "upper.xmin".into(),
            components: vec![Component::X],
            value: 0.1,
            amplitude: vec![(0.0, 0.0), (1.0, 1.0)],
        })
    });
    rejects(
        &text,
        &[
            "field `prescribed[5]`:",
            "prescribed[1] ('upper-x')",
            "prescribed[5] ('push')",
            "conflicting",
        ],
    );
    // the same value with another amplitude, on an overlapping set (an edge of upper.xmin)
    let text = edited("contact-patch", |s| {
        s.prescribed.insert(
            0,
            PrescribedSpec {
                name: "edge".into(),
                set: "upper.xmin & upper.ymax".into(),
                components: vec![Component::Y, Component::X],
                value: 0.0,
                amplitude: vec![(0.0, 1.0)],
            },
        )
    });
    rejects(
        &text,
        &[
            "field `prescribed[2]`:",
            "prescribed[0] ('edge')",
            "prescribed[2] ('upper-x')",
        ],
    );
    // one component listed twice in one entry
    let text = edited("contact-patch", |s| {
        s.prescribed[0].components = vec![Component::X, Component::X]
    });
    rejects(&text, &["field `prescribed[0]`:", "listed twice"]);
}

#[test]
fn steps_need_increments_and_increasing_end_times() {
    let text = replaced("contact-patch", "increments = 1", "increments = 0");
    rejects(&text, &["field `steps[0].increments`:", "at least 1"]);
    // sliding-block: steps end at 1 and 2
    for (k, end, after) in [(0, 0.0, "0"), (0, -1.0, "0"), (1, 1.0, "1"), (1, 0.5, "1")] {
        let text = edited("sliding-block", |s| s.steps[k].end = end);
        rejects(
            &text,
            &[
                &format!("field `steps[{k}].end`:"),
                &format!("not after {after}"),
            ],
        );
    }
    let text = edited("sliding-block", |s| s.steps.clear());
    rejects(&text, &["field `steps`:", "no load step"]);
    // too many increments: an error, not a 10^19-entry allocation
    let text = replaced(
        "contact-patch",
        "increments = 1",
        "increments = 9223372036854775807",
    );
    rejects(
        &text,
        &[
            "field `steps[0].increments`:",
            "more than 1000000 increments",
        ],
    );
    let text = edited("sliding-block", |s| {
        s.steps = vec![
            StepSpec {
                end: 1.0,
                increments: 600_000,
            },
            StepSpec {
                end: 2.0,
                increments: 600_000,
            },
        ]
    });
    rejects(&text, &["field `steps[1].increments`:", "in all steps"]);
}

#[test]
fn study_beta_must_lie_in_the_open_unit_interval() {
    for beta in [0.0, -1e-6, 1.0, 2.0, f64::INFINITY] {
        let text = edited("contact-patch", |s| s.study.beta = Some(beta));
        rejects(&text, &["field `study.beta`:"]);
    }
    for beta in [0.0, -1e-6, 1.0, 2.0] {
        let text = edited("contact-patch", |s| s.study.beta = Some(beta));
        rejects(&text, &["field `study.beta`:", "(0, 1)"]);
    }
}

#[test]
fn unknown_study_parameters_are_rejected() {
    for (scene, p) in [
        ("contact-patch", "nonexistent"),
        ("contact-patch", "sigma_y"),
        ("contact-patch", "upper.length.w"),
        ("contact-patch", "nobody.E"),
        ("contact-patch", "load.nothing"),
        ("contact-patch", "prescribed.nothing"),
        ("contact-patch", "interface.motion[0]"),
        ("contact-patch", "interface.motionx"),
        ("contact-patch", "a.b.c.d"),
        ("contact-patch", ""),
        ("klarbring-2dof", "plane.motion[0]"),
        ("klarbring-2dof", "plane.motion[3]"),
        ("klarbring-2dof", "plane.mu0"),
        // ranges of a field that select none of its members: they asked the sensitivity
        // solves for no column, and DDM and SDM panicked in the linear solver
        ("contact-patch", "upper.E[0..1]"),
        ("contact-patch", "lower.E[5..5]"),
        ("contact-patch", "lower.E[3..1]"),
        ("contact-patch", "lower.E[1000000..2000000]"),
        ("contact-patch", "interface.mu[0..1]"),
    ] {
        let text = edited(scene, |s| s.study.params = vec!["mu".into(), p.into()]);
        rejects(
            &text,
            &["field `study.params[1]`:", &format!("parameter '{p}'")],
        );
    }
}

#[test]
fn a_node_meets_a_target_through_one_pair() {
    // the pair copied under another name: two constraints of each node on one target
    let text = edited("contact-patch", |s| {
        let mut c = s.contacts[0].clone();
        c.name = "again".into();
        s.contacts.push(c);
    });
    rejects(
        &text,
        &[
            "field `contacts[1].hitting`:",
            "already meets the same target through contacts[0] ('interface')",
        ],
    );
}

#[test]
fn arrays_of_fixed_length_refuse_other_lengths() {
    // serde took the first values of a longer array and dropped the rest without a word
    for (from, to, field, length) in [
        (
            "origin = [0.0, 0.0, 0.0]",
            "origin = [0.0, 0.0, 0.0, 7.0]",
            "field `bodies[0].origin`",
            "invalid length 4, expected an array of 3 numbers",
        ),
        (
            "origin = [0.0, 0.0, 0.0]",
            "origin = [0.0]",
            "field `bodies[0].origin`",
            "invalid length 1, expected an array of 3 numbers",
        ),
        (
            "amplitude = [[0.0, 0.0], ",
            "amplitude = [[0.0, 0.0, 9.0], ",
            "field `prescribed[0].amplitude`",
            "invalid length 3, expected an array of 2 numbers",
        ),
    ] {
        let text = replaced("contact-patch", from, to);
        rejects(&text, &[field, length]);
    }
}

/// An empty list of parameters, through the library: every method runs the primal and
/// gives no derivative (DDM and SDM panicked in the linear solver's solve of no column).
#[test]
fn no_parameter_at_all_is_a_primal_run_with_no_derivative() {
    let model = builtin("contact-patch").unwrap().build().unwrap();
    for method in [Method::Ddm, Method::Sdm, Method::Fdm, Method::Adjoint] {
        let settings = Settings {
            method,
            ..Settings::default()
        };
        let (res, sens) =
            run_sensitivity(&model, &[], &settings).unwrap_or_else(|e| panic!("{method:?}: {e}"));
        assert!(res.times.len() > 1, "{method:?}");
        assert!(
            sens.increments
                .iter()
                .all(|i| i.derivatives.iter().all(|d| d.is_empty())),
            "{method:?}"
        );
    }
}

#[test]
fn responses_need_distinct_names() {
    let text = edited("contact-patch", |s| {
        let r = s.responses[0].clone();
        s.responses.push(r);
    });
    let i = builtin("contact-patch").unwrap().responses.len();
    rejects(
        &text,
        &[&format!("field `responses[{i}].name`:"), "already exists"],
    );
}

/// Found by hand reading `Parameter::by_name`: `PAIR.motion[K]` with K past the pair's rigid
/// motions (or on a pair with a deformable target) passed the name check and then panicked
/// on `expect("resolved target exists")`.
#[test]
fn regression_rigid_motion_index_out_of_range_is_an_error() {
    let text = edited("klarbring-2dof", |s| {
        s.study.params = vec!["plane.motion[7]".into()]
    });
    rejects(&text, &["field `study.params[0]`:", "has 0 rigid motions"]);
    let model = builtin("indentation").unwrap().build().unwrap();
    assert!(fricsens::sensitivity::Parameter::by_name(&model, "block.motion[1]").is_ok());
    let err = fricsens::sensitivity::Parameter::by_name(&model, "block.motion[2]")
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("has 2 rigid motions"), "{err}");
}

#[test]
fn search_radius_must_be_positive() {
    for r in [-1.0, 0.0] {
        // deformable target
        let text = edited("contact-patch", |s| s.contacts[0].search_radius = Some(r));
        rejects(
            &text,
            &["field `contacts[0].search_radius`:", "must be > 0"],
        );
        // rigid target (where the radius is not used, it is still checked)
        let text = edited("klarbring-2dof", |s| s.contacts[0].search_radius = Some(r));
        rejects(
            &text,
            &["field `contacts[0].search_radius`:", "must be > 0"],
        );
    }
    // positive but too small: a hitting node without candidate faces
    let text = edited("contact-patch", |s| {
        s.contacts[0].search_radius = Some(1e-3)
    });
    rejects(
        &text,
        &["field `contacts[0].search_radius`:", "no target face"],
    );
}

#[test]
fn element_counts_must_be_at_least_one_and_bounded() {
    let text = replaced("contact-patch", "elements = 4", "elements = 0");
    rejects(
        &text,
        &["field `bodies[0].x.zones[0].elements`:", "at least 1"],
    );
    // a zone without elements beside one with
    let text = edited("contact-patch", |s| {
        let mut z = s.bodies[1].block_mut().unwrap().y.zones[0].clone();
        z.elements = 0;
        s.bodies[1].block_mut().unwrap().y.zones.push(z);
    });
    rejects(
        &text,
        &["field `bodies[1].y.zones[1].elements`:", "at least 1"],
    );
    let text = edited("contact-patch", |s| {
        s.bodies[0].block_mut().unwrap().z.zones.clear()
    });
    rejects(&text, &["field `bodies[0].z.zones`:", "at least one zone"]);
    let text = replaced("contact-patch", "elements = 4", "elements = -4");
    rejects(&text, &["field `bodies[0].x.zones[0].elements`:", "usize"]);
    // absurd counts: typed errors before any allocation
    let text = replaced(
        "contact-patch",
        "elements = 4",
        "elements = 9223372036854775807",
    );
    rejects(
        &text,
        &["field `bodies[0].x.zones[0].elements`:", "more than 100000"],
    );
    let text = replaced(
        "contact-patch",
        "elements = 4",
        "elements = 99999999999999999999",
    );
    rejects(&text, &["field `bodies[0].x.zones[0].elements`:"]);
    // 10^5 along each axis: 10^15 elements
    let text = edited("contact-patch", |s| {
        let block = s.bodies[0].block_mut().unwrap();
        for a in [&mut block.x, &mut block.y, &mut block.z] {
            a.zones[0].elements = 100_000;
        }
    });
    let start = std::time::Instant::now();
    rejects(
        &text,
        &["field `bodies[0]`:", "more than 10000000 elements"],
    );
    assert!(start.elapsed().as_secs_f64() < 1.0);
    // several bodies that pass one by one but not together: 4 x 3.2e6 elements
    let text = edited("contact-patch", |s| {
        let mut b = s.bodies[0].clone();
        b.block_mut().unwrap().x.zones[0].elements = 200;
        b.block_mut().unwrap().y.zones[0].elements = 200;
        b.block_mut().unwrap().z.zones[0].elements = 80;
        s.bodies.clear();
        for k in 0..4 {
            let mut c = b.clone();
            c.block_mut().unwrap().name = format!("b{k}");
            s.bodies.push(c);
        }
    });
    rejects(
        &text,
        &["field `bodies[3]`:", "more than 10000000 elements"],
    );
}

#[test]
fn lengths_fractions_and_ratios_must_be_positive() {
    for v in ["0.0", "-2.0"] {
        let text = replaced("contact-patch", "length = 2.0", &format!("length = {v}"));
        rejects(&text, &["field `bodies[0].x.length`:", "must be > 0"]);
        let text = replaced(
            "contact-patch",
            "fraction = 1.0",
            &format!("fraction = {v}"),
        );
        rejects(
            &text,
            &["field `bodies[0].x.zones[0].fraction`:", "must be > 0"],
        );
        let text = replaced("contact-patch", "ratio = 1.0", &format!("ratio = {v}"));
        rejects(
            &text,
            &["field `bodies[0].x.zones[0].ratio`:", "must be > 0"],
        );
    }
    // a block beyond the f64 range
    let text = edited("contact-patch", |s| {
        s.bodies[0].block_mut().unwrap().origin[0] = 1e308;
        s.bodies[0].block_mut().unwrap().x.length = 1e308;
    });
    rejects(&text, &["field `bodies[0].x.length`:", "f64 range"]);
    // a grading whose smallest element vanishes in f64: 50 elements shrinking by 10^-300
    let text = edited("contact-patch", |s| {
        s.bodies[0].block_mut().unwrap().x.zones[0].elements = 50;
        s.bodies[0].block_mut().unwrap().x.zones[0].ratio = 1e-300;
    });
    rejects(
        &text,
        &["field `bodies[0].x.zones`:", "zero or non-finite size"],
    );
    // faces of zero area in f64 (10^-200 x 10^-200) cannot share a load by area (the block
    // 10^-200 in every direction: one thin in two directions alone is refused as degenerate
    // before, below)
    let text = edited("contact-patch", |s| {
        s.bodies[1].block_mut().unwrap().x.length = 1e-200;
        s.bodies[1].block_mut().unwrap().y.length = 1e-200;
        s.bodies[1].block_mut().unwrap().z.length = 1e-200;
    });
    rejects(&text, &["field `loads[0].set`:", "have area 0"]);
    // element faces whose sides are in a ratio below 4e-10 (a quad's centre Jacobian, a
    // quarter of its sides' product, against the contact geometry's area tolerance, 1e-10
    // of its diagonal squared) are degenerate: a zone ratio of 1e12, a block 1e-200 thick
    let text = edited("contact-patch", |s| {
        s.bodies[0].block_mut().unwrap().x.zones[0].elements = 4;
        s.bodies[0].block_mut().unwrap().x.zones[0].ratio = 1e12;
    });
    rejects(
        &text,
        &["field `bodies[0].x.zones`:", "below 4e-10", "degenerate"],
    );
    let text = edited("contact-patch", |s| {
        s.bodies[1].block_mut().unwrap().z.length = 1e-200;
    });
    rejects(&text, &["field `bodies[1].z.length`:", "degenerate"]);
    // and blocks whose thinnest faces lie a little above it build: the lower block's z
    // elements, uniform, `ratio` of its longest element across, with hexahedra at 1e-9 and
    // tetrahedra, whose triangular faces are refused only below 1e-10, at 2e-10
    let thin = |shape: Option<fricsens::element::Shape>, ratio: f64| {
        edited("contact-patch", |s| {
            if let Some(shape) = shape {
                // the shape's own formulation (the scene's hex8 have incompatible modes)
                s.bodies[0].formulation = None;
                s.bodies[0].block_mut().unwrap().element = shape;
            }
            let b = s.bodies[0].block_mut().unwrap();
            let across =
                |a: &fricsens::mesh::Axis| a.element_sizes().into_iter().fold(0.0, f64::max);
            let longest = across(&b.x).max(across(&b.y));
            let nz: usize = b.z.zones.iter().map(|z| z.elements).sum();
            b.z.length = ratio * longest * nz as f64;
        })
    };
    parse_build(&thin(None, 1e-9), "case.toml").expect("a block 1e-9 thin builds");
    rejects(
        &thin(None, 2e-10),
        &["field `bodies[0].z.length`:", "below 4e-10"],
    );
    let tet = Some(fricsens::element::Shape::Tet4);
    parse_build(&thin(tet, 2e-10), "case.toml").expect("a tetrahedral block 2e-10 thin builds");
    // a grading steep along one axis whose faces are not thin: x graded over twelve orders
    // (1e-12 of the axis) on a block whose y and z elements are as small, every face's sides
    // within a ratio of 1e-6
    let text = edited("contact-patch", |s| {
        let b = s.bodies[0].block_mut().unwrap();
        b.x.zones[0].elements = 2;
        b.x.zones[0].ratio = 1e12;
        b.y.length = 1e-6 * b.x.length;
        b.z.length = 1e-6 * b.x.length;
    });
    if let Err(e) = parse_build(&text, "case.toml") {
        assert!(!e.to_string().contains("degenerate"), "{e}");
    }
    // rigid surfaces
    let text = edited("klarbring-2dof", |s| {
        if let TargetSpec::Rigid { surface, .. } = &mut s.contacts[0].target {
            *surface = RigidSpec::Plane {
                point: [0.0; 3],
                normal: [0.0; 3],
            };
        }
    });
    rejects(
        &text,
        &[
            "field `contacts[0].target.surface.normal`:",
            "nonzero length",
        ],
    );
    let text = edited("klarbring-2dof", |s| {
        if let TargetSpec::Rigid { surface, .. } = &mut s.contacts[0].target {
            *surface = RigidSpec::Cylinder {
                axis_point: [0.0; 3],
                axis: [0.0, 0.0, 1.0],
                radius: -1.0,
            };
        }
    });
    rejects(
        &text,
        &["field `contacts[0].target.surface.radius`:", "must be > 0"],
    );
}

#[test]
fn solver_settings_must_be_usable() {
    let text = replaced("contact-patch", "max_iterations = 30", "max_iterations = 0");
    rejects(&text, &["field `solver.max_iterations`:", "at least 1"]);
    let text = replaced(
        "contact-patch",
        "max_cutbacks = 10",
        "max_cutbacks = 18446744073709551615",
    );
    rejects(&text, &["field `solver.max_cutbacks`:"]);
    let text = replaced("contact-patch", "max_cutbacks = 10", "max_cutbacks = 1000");
    rejects(&text, &["field `solver.max_cutbacks`:", "at most 64"]);
    let text = replaced(
        "contact-patch",
        "force_tol = 0.000000001",
        "force_tol = 0.0",
    );
    rejects(&text, &["field `solver.force_tol`:", "must be > 0"]);
}

/// A fresh directory for scene files of one test.
fn scratch_dir(test: &str) -> PathBuf {
    let dir = scratch_path(&format!("robustness-{test}"));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn errors_of_scene_files_name_the_file() {
    let dir = scratch_dir("files");
    // syntax error: the file and the line
    let text = replaced("contact-patch", "nu = 0.3", "nu = 0.3 0.4");
    let path = dir.join("syntax.toml");
    std::fs::write(&path, &text).unwrap();
    let line = line_of(&text, "nu = 0.3 0.4");
    let shown = path.display().to_string();
    for err in [
        Scene::from_file(&path).unwrap_err().to_string(),
        Scene::load(&shown).unwrap_err().to_string(),
    ] {
        assert!(err.starts_with(&format!("{shown}: ")), "{err}");
        assert!(err.contains(&format!("line {line}")), "{err}");
    }
    // an impossible value found by build(): Scene::load names the file and the field
    let path = dir.join("negative-e.toml");
    std::fs::write(&path, replaced("contact-patch", "E = 1000.0", "E = -5.0")).unwrap();
    let shown = path.display().to_string();
    let err = Scene::load(&shown).unwrap_err();
    assert!(matches!(err, SceneError::InFile { .. }), "{err:?}");
    let err = err.to_string();
    assert!(
        err.starts_with(&format!("{shown}: ")) && err.contains("field `bodies[0].material.E`:"),
        "{err}"
    );
    // a missing file
    let missing = dir.join("missing.toml").display().to_string();
    let err = Scene::load(&missing).unwrap_err().to_string();
    assert!(err.starts_with(&format!("{missing}: ")), "{err}");
    // the command line reports both, and fails
    for (file, field) in [
        ("syntax.toml", "line"),
        ("negative-e.toml", "bodies[0].material.E"),
    ] {
        let path = dir.join(file);
        let out = fricsens()
            .args(["run", &path.display().to_string(), "--out"])
            .arg(dir.join("out"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{file}: {stderr}");
        assert!(
            stderr.contains(&path.display().to_string()) && stderr.contains(field),
            "{file}: {stderr}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

// ---------------------------------------------------------------------------------------
// No panic on any input
// ---------------------------------------------------------------------------------------

/// Small built-in scenes the structure-aware fuzz mutates (cheap to build).
const SMALL: [&str; 7] = [
    "uniaxial-j2",
    "klarbring-2dof",
    "jenkins",
    "contact-patch",
    "cantilever-small",
    "stacked-leaves",
    "strip-pullout",
];

/// Values a number of a built-in scene is replaced with.
const NASTY: [&str; 18] = [
    "0",
    "-1",
    "1e300",
    "-1e300",
    "nan",
    "inf",
    "-inf",
    "1e-300",
    "-0.0",
    "0.5",
    "1",
    "100000",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "\"a string\"",
    "[]",
    "true",
];

/// Scenes with more elements are parsed but not built by the fuzz (building them is
/// legitimate but slow); above the model limit (10^7) they are built and must be errors.
const FUZZ_MAX_ELEMENTS: usize = 20_000;
const MODEL_MAX_ELEMENTS: usize = 10_000_000;

/// Byte ranges of the number literals of a TOML text (outside strings).
fn number_spans(text: &str) -> Vec<std::ops::Range<usize>> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let mut in_string = false;
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if c == b'"' {
            in_string = !in_string;
            i += 1;
            continue;
        }
        if in_string {
            if c == b'\\' {
                i += 1;
            }
            i += 1;
            continue;
        }
        let word = |b: u8| b.is_ascii_alphanumeric() || b"_.+-".contains(&b);
        if word(c) && (i == 0 || !word(bytes[i - 1])) {
            let mut j = i;
            while j < bytes.len() && word(bytes[j]) {
                j += 1;
            }
            let tok = &text[i..j];
            let is_key = text[j..].trim_start_matches([' ', '\t']).starts_with('=');
            if !is_key && (tok.parse::<f64>().is_ok() || tok.parse::<i64>().is_ok()) {
                out.push(i..j);
            }
            i = j;
            continue;
        }
        i += 1;
    }
    out
}

#[derive(Clone, Debug)]
enum Mutation {
    /// Replace a number literal with one of [`NASTY`].
    Replace(prop::sample::Index, prop::sample::Index),
    DeleteLine(prop::sample::Index),
    DuplicateLine(prop::sample::Index),
    /// Insert a line of the token soup.
    InsertLine(prop::sample::Index, String),
    /// Truncate at a byte (moved back to a char boundary).
    Truncate(prop::sample::Index),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        6 => (any::<prop::sample::Index>(), any::<prop::sample::Index>())
            .prop_map(|(a, b)| Mutation::Replace(a, b)),
        2 => any::<prop::sample::Index>().prop_map(Mutation::DeleteLine),
        2 => any::<prop::sample::Index>().prop_map(Mutation::DuplicateLine),
        2 => (any::<prop::sample::Index>(), toml_line())
            .prop_map(|(k, l)| Mutation::InsertLine(k, l)),
        1 => any::<prop::sample::Index>().prop_map(Mutation::Truncate),
    ]
}

fn apply(text: &str, m: &Mutation) -> String {
    match m {
        Mutation::Replace(which, value) => {
            let spans = number_spans(text);
            if spans.is_empty() {
                return text.to_string();
            }
            let r = spans[which.index(spans.len())].clone();
            format!(
                "{}{}{}",
                &text[..r.start],
                NASTY[value.index(NASTY.len())],
                &text[r.end..]
            )
        }
        Mutation::DeleteLine(k) | Mutation::DuplicateLine(k) => {
            let mut lines: Vec<&str> = text.lines().collect();
            if lines.is_empty() {
                return text.to_string();
            }
            let k = k.index(lines.len());
            if matches!(m, Mutation::DeleteLine(_)) {
                lines.remove(k);
            } else {
                lines.insert(k, lines[k]);
            }
            lines.join("\n")
        }
        Mutation::InsertLine(k, line) => {
            let mut lines: Vec<&str> = text.lines().collect();
            let k = k.index(lines.len() + 1);
            lines.insert(k, line);
            lines.join("\n")
        }
        Mutation::Truncate(at) => {
            let mut at = at.index(text.len() + 1);
            while !text.is_char_boundary(at) {
                at -= 1;
            }
            text[..at].to_string()
        }
    }
}

/// Elements a scene asks for (saturating).
fn element_count(scene: &Scene) -> usize {
    scene
        .bodies
        .iter()
        .map(|b| {
            {
                let k = b.block().expect("a generated block");
                [&k.x, &k.y, &k.z]
            }
            .iter()
            .map(|a| {
                a.zones
                    .iter()
                    .fold(0usize, |n, z| n.saturating_add(z.elements))
            })
            .fold(1usize, |n, m| n.saturating_mul(m))
        })
        .fold(0usize, |n, m| n.saturating_add(m))
}

/// What happened to one fuzz input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    /// With or without a TOML path in the message.
    ParseError {
        path: bool,
    },
    BuildError,
    Built,
    /// Parsed, with more than [`FUZZ_MAX_ELEMENTS`] (within the limit): not built.
    Skipped,
}

/// Parses `text` and builds it when it parses; a panic, an error without text, or a model
/// above the element limit is a failure naming the input.
fn no_panic(text: &str) -> Result<Outcome, TestCaseError> {
    let run = catch_unwind(AssertUnwindSafe(|| -> Result<Outcome, String> {
        let scene = match Scene::from_toml(text, "fuzz.toml") {
            Ok(s) => s,
            Err(e) => {
                let msg = e.to_string();
                return if msg.starts_with("fuzz.toml: ") {
                    Ok(Outcome::ParseError {
                        path: msg.starts_with("fuzz.toml: field `"),
                    })
                } else {
                    Err(format!("parse error without the file name: {msg}"))
                };
            }
        };
        let n = element_count(&scene);
        if n > FUZZ_MAX_ELEMENTS && n <= MODEL_MAX_ELEMENTS {
            return Ok(Outcome::Skipped);
        }
        match scene.build() {
            Ok(_) if n > MODEL_MAX_ELEMENTS => Err(format!("built a model of {n} elements")),
            Ok(_) => Ok(Outcome::Built),
            Err(e) if e.to_string().is_empty() => Err("an error without a message".into()),
            Err(_) => Ok(Outcome::BuildError),
        }
    }));
    match run {
        Ok(Ok(o)) => Ok(o),
        Ok(Err(why)) => Err(TestCaseError::fail(format!("{why}\ninput:\n{text}"))),
        Err(p) => {
            let what = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Err(TestCaseError::fail(format!(
                "PANIC ({what}) on input:\n{text}"
            )))
        }
    }
}

/// Table headers of the scene schema.
const HEADERS: [&str; 20] = [
    "[[bodies]]",
    "[bodies.x]",
    "[[bodies.x.zones]]",
    "[bodies.y]",
    "[[bodies.y.zones]]",
    "[bodies.z]",
    "[[bodies.z.zones]]",
    "[bodies.material]",
    "[[steps]]",
    "[study]",
    "[solver]",
    "[[prescribed]]",
    "[[loads]]",
    "[[contacts]]",
    "[contacts.target]",
    "[contacts.friction]",
    "[[free_nodes]]",
    "[[springs]]",
    "[[responses]]",
    "[bodies]",
];

/// Keys of the scene schema (and one that is in none of its tables).
const KEYS: [&str; 28] = [
    "name",
    "origin",
    "length",
    "fraction",
    "elements",
    "ratio",
    "law",
    "E",
    "nu",
    "sigma_y",
    "H",
    "end",
    "increments",
    "beta",
    "params",
    "set",
    "components",
    "value",
    "amplitude",
    "component",
    "hitting",
    "faces",
    "mu",
    "x",
    "a",
    "stiffness",
    "kind",
    "bogus",
];

/// Values of all TOML types, valid and not for the keys above.
const VALUES: [&str; 24] = [
    "0",
    "1",
    "-1",
    "4",
    "0.3",
    "1e300",
    "nan",
    "-inf",
    "9223372036854775807",
    "\"b\"",
    "\"svk\"",
    "\"j2\"",
    "\"b.all\"",
    "\"b.xmin & b.ymin\"",
    "\"x\"",
    "[\"x\", \"y\"]",
    "[0.0, 0.0, 0.0]",
    "[[0.0, 0.0], [1.0, 1.0]]",
    "[]",
    "{}",
    "true",
    "1979-05-27",
    "[\"mu\", \"E\", \"b.length.x\"]",
    "{ law = \"coulomb\", mu = 0.3 }",
];

/// Lines of scene TOML (headers and `key = value`), mostly well-formed: a soup of them gets
/// past the TOML syntax into the scene schema (and, for errors, into the search of their
/// TOML path).
fn toml_line() -> impl Strategy<Value = String> {
    prop_oneof![
        1 => prop::sample::select(&HEADERS[..]).prop_map(str::to_string),
        3 => (prop::sample::select(&KEYS[..]), prop::sample::select(&VALUES[..]))
            .prop_map(|(k, v)| format!("{k} = {v}")),
    ]
}

fn token_soup() -> impl Strategy<Value = String> {
    (any::<bool>(), prop::collection::vec(toml_line(), 0..60)).prop_map(|(named, lines)| {
        let head = if named { "name = \"soup\"\n" } else { "" };
        format!("{head}{}\n", lines.join("\n"))
    })
}

fn mutated_builtin() -> impl Strategy<Value = String> {
    (
        prop::sample::select(&SMALL[..]),
        prop::collection::vec(mutation(), 1..4),
    )
        .prop_map(|(name, ms)| {
            let mut text = builtin(name).unwrap().to_toml().unwrap();
            for m in &ms {
                text = apply(&text, m);
            }
            text
        })
}

/// Tallies of one fuzz campaign.
#[derive(Debug, Default)]
struct Tally {
    cases: usize,
    parse_errors: usize,
    /// Parse errors whose message names a TOML path (the search of the path ran).
    with_path: usize,
    build_errors: usize,
    built: usize,
    skipped: usize,
}

fn fuzz<S: Strategy<Value = String>>(what: &str, strategy: S, cases: u32) -> Tally {
    let mut runner = TestRunner::new(Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    });
    let tally = std::cell::RefCell::new(Tally::default());
    let start = std::time::Instant::now();
    let result = runner.run(&strategy, |text| {
        let o = no_panic(&text)?;
        let mut t = tally.borrow_mut();
        t.cases += 1;
        match o {
            Outcome::ParseError { path } => {
                t.parse_errors += 1;
                t.with_path += usize::from(path);
            }
            Outcome::BuildError => t.build_errors += 1,
            Outcome::Built => t.built += 1,
            Outcome::Skipped => t.skipped += 1,
        }
        Ok(())
    });
    let t = tally.into_inner();
    println!(
        "fuzz {what}: {cases} cases in {:.1} s: {t:?}",
        start.elapsed().as_secs_f64()
    );
    if let Err(e) = result {
        panic!("fuzz {what}: {e}");
    }
    t
}

/// Default case count of each of the four strategies: 10 000. In release on one core the four
/// campaigns took 1.5 s together (bytes 0.1 s, UTF-8 0.1 s, line soup 0.3 s, mutated built-ins
/// 0.9 s), well under the 30 s budget.
const DEFAULT_CASES: u32 = 10_000;

#[test]
fn arbitrary_bytes_never_panic() {
    let bytes = prop::collection::vec(any::<u8>(), 0..400)
        .prop_map(|b| String::from_utf8_lossy(&b).into_owned());
    fuzz("bytes", bytes, DEFAULT_CASES);
}

#[test]
fn arbitrary_utf8_never_panics() {
    fuzz("utf8", any::<String>(), DEFAULT_CASES);
}

#[test]
fn toml_line_soup_never_panics() {
    fuzz("TOML line soup", token_soup(), DEFAULT_CASES);
}

#[test]
fn mutated_builtin_scenes_never_panic() {
    let t = fuzz("mutated built-ins", mutated_builtin(), DEFAULT_CASES);
    // the campaign reaches build() both ways, not only the parser
    assert!(t.built > 0 && t.build_errors > 0, "{t:?}");
}

/// The closing-note campaign: `FRICSENS_FUZZ_CASES` cases (default 100 000) of each strategy,
/// `cargo test --release -j 1 --test robustness -- --ignored --nocapture robustness::large_fuzz`
/// (4 x 100 000 cases: 15 s in release on one core).
#[test]
#[ignore]
fn large_fuzz() {
    let cases: u32 = std::env::var("FRICSENS_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100_000);
    let start = std::time::Instant::now();
    let bytes = prop::collection::vec(any::<u8>(), 0..400)
        .prop_map(|b| String::from_utf8_lossy(&b).into_owned());
    fuzz("bytes", bytes, cases);
    fuzz("utf8", any::<String>(), cases);
    fuzz("TOML line soup", token_soup(), cases);
    fuzz("mutated built-ins", mutated_builtin(), cases);
    println!(
        "large fuzz: 4 x {cases} cases, {:.1} s, no panic",
        start.elapsed().as_secs_f64()
    );
}

#[test]
fn number_spans_find_the_numbers_of_a_scene() {
    let text = "a = 1.0\nb = [\n    -2,\n    nan,\n]\nc = \"3.0\"\nd = 1e-6\ne2 = inf\n";
    let found: Vec<&str> = number_spans(text).into_iter().map(|r| &text[r]).collect();
    assert_eq!(found, ["1.0", "-2", "nan", "1e-6", "inf"]);
}

// ---------------------------------------------------------------------------------------
// Determinism
// ---------------------------------------------------------------------------------------

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// Every converged state and the final history, as bits.
fn primal_bits(model: &Model) -> Vec<Vec<u64>> {
    let res = solve(model);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut out: Vec<Vec<u64>> = res.states.iter().map(|s| bits(s)).collect();
    out.push(bits(&res.history));
    out
}

/// DDM run: states, response values and derivatives of every increment, as bits.
fn ddm_bits(model: &Model, param: &str) -> Vec<Vec<u64>> {
    let p = Parameter::by_name(model, param).unwrap();
    let settings = Settings {
        method: Method::Ddm,
        ..Settings::default()
    };
    let (res, sens) = run_sensitivity(model, &[p], &settings).unwrap();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut out: Vec<Vec<u64>> = res.states.iter().map(|s| bits(s)).collect();
    for inc in &sens.increments {
        out.push(bits(&inc.values));
        for d in &inc.derivatives {
            out.push(bits(d));
        }
    }
    out
}

/// Panics with the first differing entry of two runs.
#[track_caller]
fn assert_same_bits(a: &[Vec<u64>], b: &[Vec<u64>], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: different number of records");
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert_eq!(x.len(), y.len(), "{what}: record {k} has different lengths");
        if let Some(i) = (0..x.len()).find(|&i| x[i] != y[i]) {
            panic!(
                "{what}: record {k} entry {i} differs: {:e} vs {:e}",
                f64::from_bits(x[i]),
                f64::from_bits(y[i])
            );
        }
    }
}

#[test]
fn contact_runs_are_bit_identical_across_runs_and_thread_counts() {
    for name in ["sliding-block", "contact-patch", "stacked-leaves"] {
        let model = builtin(name).unwrap().build().unwrap();
        let one = pool(1).install(|| primal_bits(&model));
        let again = pool(1).install(|| primal_bits(&model));
        let two = pool(2).install(|| primal_bits(&model));
        let two_again = pool(2).install(|| primal_bits(&model));
        assert!(one.len() > 2, "{name}: no increment");
        assert_same_bits(&one, &again, &format!("{name}, one thread, twice"));
        assert_same_bits(&one, &two, &format!("{name}, one thread vs two"));
        assert_same_bits(&two, &two_again, &format!("{name}, two threads, twice"));
    }
}

#[test]
fn ddm_sensitivities_are_bit_identical_across_thread_counts() {
    for (name, param) in [
        ("sliding-block", "mu"),
        ("contact-patch", "mu"),
        ("stacked-leaves", "E"),
    ] {
        let model = builtin(name).unwrap().build().unwrap();
        let one = pool(1).install(|| ddm_bits(&model, param));
        let again = pool(1).install(|| ddm_bits(&model, param));
        let two = pool(2).install(|| ddm_bits(&model, param));
        assert_same_bits(
            &one,
            &again,
            &format!("{name} d/d{param}, one thread, twice"),
        );
        assert_same_bits(&one, &two, &format!("{name} d/d{param}, one thread vs two"));
    }
}

/// Above `PAR_FACTOR_MIN_N` unknowns the factorization runs in parallel on a pool of more than
/// one thread (faer `Par::rayon`): one increment of a 21 150-unknown elastic cantilever.
#[test]
fn a_model_with_parallel_factorization_is_bit_identical_across_thread_counts() {
    let spec = CantileverSpec {
        nx: 140,
        ny: 24,
        increments: 1,
        kinematics: Kinematics::Small,
        formulation: Formulation::Full,
        ..CantileverSpec::small_deflection()
    };
    let model = cantilever(&spec).build().unwrap();
    assert!(model.dof_map().n_total >= fricsens::linalg::PAR_FACTOR_MIN_N);
    let one = pool(1).install(|| primal_bits(&model));
    let two = pool(2).install(|| primal_bits(&model));
    let two_again = pool(2).install(|| primal_bits(&model));
    assert_same_bits(
        &two,
        &two_again,
        "parallel factorization, two threads, twice",
    );
    assert_same_bits(&one, &two, "parallel factorization, one thread vs two");
}

/// `contacts[].smoothing = "normals"` where it has no meaning is a typed error naming the
/// field: on a rigid target (an analytic surface), and on quadratic target faces (curved
/// already; their smoothing would widen the local tangent beyond its duals).
#[test]
fn smoothing_is_refused_where_it_has_no_meaning() {
    use fricsens::scene::Smoothing;
    let text = edited("klarbring-2dof", |s| {
        s.contacts[0].smoothing = Some(Smoothing::Normals)
    });
    rejects(&text, &["field `contacts[0].smoothing`:", "rigid target"]);
    let text = edited("contact-patch", |s| {
        s.contacts[0].smoothing = Some(Smoothing::Normals)
    })
    .replace("[[bodies]]\n", "[[bodies]]\nelement = \"hex20\"\n")
    .replace("\"incompatible-modes\"", "\"reduced\"");
    assert!(text.contains("element = \"hex20\""));
    rejects(
        &text,
        &["field `contacts[0].smoothing`:", "linear target faces"],
    );
}
