//! A rigid target pushed by a force (`force = ...` in a motion entry): its translation is an
//! unknown held by its equilibrium with the contact forces. Checked against the same scene
//! driven by displacement, by the homogeneity of an elastic contact problem in its moduli and
//! loads, and DDM against central finite differences of reruns.

use crate::common;
use fricsens::prelude::*;
use fricsens::sensitivity::Method;
use fricsens::solver::{AnalysisError, PrecheckError};

/// The issue's curved punch (rigid cylinder R = 50 on an elastic plane-strain block 40 x 20,
/// E = 1000, nu = 0.3, mu = 0.5, large kinematics), pressed in five increments: `motion` is
/// the punch's motion entries, `steps` the scene's steps.
fn punch(motion: &str, steps: &str) -> Scene {
    let text = format!(
        r#"
name = "pushed-punch"
[[bodies]]
name = "block"
origin = [-20.0, -20.0, 0.0]
[bodies.x]
length = 40.0
zones = [ {{ fraction = 0.3, elements = 6, ratio = 0.3 }}, {{ fraction = 0.4, elements = 20, ratio = 1.0 }}, {{ fraction = 0.3, elements = 6, ratio = 3.33 }} ]
[bodies.y]
length = 20.0
zones = [ {{ fraction = 0.6, elements = 8, ratio = 0.2 }}, {{ fraction = 0.4, elements = 10, ratio = 1.0 }} ]
[bodies.z]
length = 1.0
zones = [ {{ fraction = 1.0, elements = 1, ratio = 1.0 }} ]
[bodies.material]
law = "svk"
E = 1000.0
nu = 0.3

[[prescribed]]
name = "base"
set = "block.ymin"
components = ["x", "y"]
[[prescribed]]
name = "plane-strain"
set = "block.all"
components = ["z"]

[[contacts]]
name = "punch"
hitting = "block.ymax"
[contacts.target.rigid.surface]
shape = "cylinder"
axis_point = [0.0, 50.0, 0.0]
axis = [0.0, 0.0, 1.0]
radius = 50.0
{motion}
[contacts.friction]
law = "coulomb"
mu = 0.5

{steps}

[[responses]]
kind = "target-force"
name = "Fy"
pair = "punch"
component = "y"
[[responses]]
kind = "target-force"
name = "Fx"
pair = "punch"
component = "x"
[[responses]]
kind = "target-displacement"
name = "dy"
pair = "punch"
component = "y"
[[responses]]
kind = "target-displacement"
name = "dx"
pair = "punch"
component = "x"
"#
    );
    Scene::from_toml(&text, "pushed-punch.toml").expect("the scene parses")
}

const PRESS: &str = "[[steps]]\nend = 1.0\nincrements = 5\n";

fn response(model: &Model, name: &str) -> usize {
    model.responses.iter().position(|r| r.name == name).unwrap()
}

/// The force-driven punch: `amplitude` the press force's history, `fy` its magnitude.
fn pushed(fy: f64, amplitude: &[(f64, f64)], extra: &str, steps: &str) -> Model {
    let points: Vec<String> = amplitude
        .iter()
        .map(|(t, a)| format!("[{t:?}, {a:?}]"))
        .collect();
    let motion = format!(
        "[[contacts.target.rigid.motion]]\ncomponent = \"y\"\nforce = {fy:?}\namplitude = [{}]\n{extra}",
        points.join(", ")
    );
    punch(&motion, steps).build().unwrap()
}

#[test]
fn a_pushed_punch_retraces_the_displacement_driven_force_displacement_curve() {
    // the press driven by displacement: the force on the punch at every increment
    let driven = punch(
        "[[contacts.target.rigid.motion]]\ncomponent = \"y\"\nvalue = -0.25\n",
        PRESS,
    )
    .build()
    .unwrap();
    let res = common::solve(&driven);
    let (fy, dy) = (response(&driven, "Fy"), response(&driven, "dy"));
    let force: Vec<f64> = (0..res.times.len())
        .map(|k| res.response_value(&driven, fy, k))
        .collect();
    let last = *force.last().unwrap();
    assert!(last > 0.0, "the block pushes the punch up");
    // the same press driven by the force it took, through the same points of the path: the
    // applied force on the punch is minus the contact force on it
    let amplitude: Vec<(f64, f64)> = (res.times.iter().zip(&force))
        .map(|(t, f)| (*t, f / last))
        .collect();
    let model = pushed(-last, &amplitude, "", PRESS);
    let pushed_res = common::solve(&model);
    assert_eq!(pushed_res.times, res.times);
    for k in 1..res.times.len() {
        let a = |r| res.response_value(&driven, r, k);
        let b = |r| pushed_res.response_value(&model, r, k);
        // both runs stop at |R| <= 1e-9 F_ref; the indentation inherits that through the
        // contact compliance (measured: 3e-11)
        let (want, got) = (a(dy), b(dy));
        assert!(
            (got - want).abs() <= 1e-8 * want.abs(),
            "increment {k}: indentation {got:e} pushed, {want:e} driven"
        );
        assert!(
            (b(fy) - a(fy)).abs() <= 1e-9 * last,
            "increment {k}: force {:e} against {:e}",
            b(fy),
            a(fy)
        );
    }
}

#[test]
fn the_indentation_under_a_fixed_force_has_ddm_derivatives_that_match_fdm_and_homogeneity() {
    let model = pushed(-164.4673328066, &[(0.0, 0.0), (1.0, 1.0)], "", PRESS);
    let names = ["E", "punch.motion[0]", "punch.eps_t"];
    let params = common::params(&model, &names);
    let ddm = common::sensitivities(&model, &params, Method::Ddm, 0.0);
    let fdm = common::sensitivities(&model, &params[..2], Method::FdmCentral, 1e-5);
    let dy = response(&model, "dy");
    let (e, f, eps_t) = (params[0].value, params[1].value, params[2].value);
    for (k, inc) in ddm.increments.iter().enumerate() {
        let d = |j: usize| inc.derivatives[dy][j];
        let delta = inc.values[dy];
        assert!(delta < 0.0, "increment {k}: the punch moves down");
        // the indentation is homogeneous of degree zero in (E, F, eps_T): scaling the moduli,
        // the force and the tangential penalty together scales stresses and leaves every
        // displacement unchanged (nu, mu are ratios; the Lagrange constraint scale does not
        // enter the solution), so E d/dE + F d/dF + eps_T d/deps_T = 0
        let euler = e * d(0) + f * d(1) + eps_t * d(2);
        println!(
            "increment {k}: Euler sum {:.2e} relative",
            euler / (e * d(0))
        );
        // DDM solves to 1e-13 of the solution (measured: 4e-13 at worst)
        assert!(
            euler.abs() <= 1e-11 * (e * d(0)).abs(),
            "increment {k}: Euler sum {euler:e} of E dd/dE = {:e}",
            e * d(0)
        );
        // a stiffer block under the same force indents less
        assert!(d(0) > 0.0, "increment {k}: d(dy)/dE = {:e}", d(0));
        for (j, name) in names.iter().enumerate().take(2) {
            let fd = fdm.increments[k].derivatives[dy][j];
            // central differences at beta = 1e-5 of reruns converged to 1e-9 F_ref: the
            // rerun noise (about 1e-11 of the indentation) over 2 beta is a few 1e-7
            assert!(
                (fd - d(j)).abs() <= 1e-5 * d(j).abs(),
                "increment {k}, {name}: DDM {:e}, central FDM {fd:e}",
                d(j)
            );
        }
    }
}

#[test]
fn a_tangential_force_below_the_friction_limit_is_carried_and_its_slide_differentiated() {
    // pressed by P, then pushed sideways by Q = 0.3 mu P (Cattaneo-Mindlin's partial slip:
    // the punch creeps, held by a stick zone)
    let p = 164.4673328066;
    let q = 0.3 * 0.5 * p;
    let model = pushed(
        -p,
        &[(0.0, 0.0), (1.0, 1.0), (2.0, 1.0)],
        &format!(
            "[[contacts.target.rigid.motion]]\ncomponent = \"x\"\nforce = {q:?}\namplitude = [[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]]\n"
        ),
        &format!("{PRESS}[[steps]]\nend = 2.0\nincrements = 4\n"),
    );
    let names = ["mu", "E"];
    let (_, ddm, fdm) = common::ddm_and_central_fdm(&model, &names);
    let (fx, fy, dx) = (
        response(&model, "Fx"),
        response(&model, "Fy"),
        response(&model, "dx"),
    );
    let last = ddm.increments.last().unwrap();
    // the target's equilibrium: the contact forces on it balance the applied ones (to the
    // force tolerance, 1e-9 of the reference force)
    assert!(
        (last.values[fx] + q).abs() <= 1e-8 * p,
        "Fx = {:e}",
        last.values[fx]
    );
    assert!(
        (last.values[fy] - p).abs() <= 1e-8 * p,
        "Fy = {:e}",
        last.values[fy]
    );
    // its force does not depend on the design: d(Fx)/dmu is zero to round-off
    assert!(last.derivatives[fx][0].abs() <= 1e-8 * q / 0.5);
    // it slides the way it is pushed, less with more friction (a larger stick zone)
    assert!(last.values[dx] > 0.0, "dx = {:e}", last.values[dx]);
    assert!(
        last.derivatives[dx][0] < 0.0,
        "d(dx)/dmu = {:e}",
        last.derivatives[dx][0]
    );
    for (j, name) in names.iter().enumerate() {
        // the scale of the slide's derivative: while pressing it is the round-off of the
        // graded mesh's asymmetry (1e-9), measured against the slide's
        let scale = (ddm.increments.iter())
            .map(|inc| inc.derivatives[dx][j].abs())
            .fold(0.0, f64::max);
        for (k, inc) in ddm.increments.iter().enumerate() {
            let (d, fd) = (inc.derivatives[dx][j], fdm.increments[k].derivatives[dx][j]);
            // central FDM at beta = 1e-6 of reruns converged to 1e-9 F_ref: the rerun noise
            // over 2 beta (measured: 2e-6 of the slide's derivative at worst)
            assert!(
                (fd - d).abs() <= 1e-5 * scale,
                "increment {k}, {name}: DDM {d:e}, central FDM {fd:e}"
            );
        }
    }
}

#[test]
fn a_pushed_target_that_does_not_touch_is_refused_before_the_run() {
    // the punch lifted by 0.01 off the block: nothing holds it before contact
    let mut scene = punch(
        "[[contacts.target.rigid.motion]]\ncomponent = \"y\"\nforce = -10.0\n",
        PRESS,
    );
    if let fricsens::scene::TargetSpec::Rigid {
        surface: fricsens::scene::RigidSpec::Cylinder { axis_point, .. },
        ..
    } = &mut scene.contacts[0].target
    {
        axis_point[1] += 0.01;
    }
    let model = scene.build().unwrap();
    match Solver::new(&model) {
        Err(AnalysisError::Precheck(PrecheckError::PushedTargetApart {
            pair, closest, ..
        })) => {
            assert_eq!(pair, "punch");
            assert!((closest - 0.01).abs() <= 1e-12, "closest {closest:e}");
        }
        Err(e) => panic!("another error: {e}"),
        Ok(_) => panic!("a pushed target off the block was accepted"),
    }
}

#[test]
fn a_pushed_component_takes_one_force_and_no_translation() {
    let both = "[[contacts.target.rigid.motion]]\ncomponent = \"y\"\nforce = -10.0\nvalue = -0.1\n";
    let err = punch(both, PRESS).build().unwrap_err().to_string();
    assert!(
        err.contains("motion[0]") && err.contains("exactly one"),
        "{err}"
    );
    let mixed = "[[contacts.target.rigid.motion]]\ncomponent = \"y\"\nforce = -10.0\n\
                 [[contacts.target.rigid.motion]]\ncomponent = \"y\"\nvalue = -0.1\n";
    let err = punch(mixed, PRESS).build().unwrap_err().to_string();
    assert!(err.contains("motion[1].component"), "{err}");
}

#[test]
fn the_tangent_of_a_pushed_target_is_the_derivative_of_its_residual() {
    // pressed and pushed sideways into partial slip: the target's rows and columns (its
    // equilibrium, and how every contact force moves with it) against the dual derivative of
    // the residual at the last converged state
    let p = 164.4673328066;
    let model = pushed(
        -p,
        &[(0.0, 0.0), (1.0, 1.0), (2.0, 1.0)],
        &format!(
            "[[contacts.target.rigid.motion]]\ncomponent = \"x\"\nforce = {:?}\namplitude = [[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]]\n",
            0.15 * p
        ),
        &format!("{PRESS}[[steps]]\nend = 2.0\nincrements = 2\n"),
    );
    let c = common::tangent_check(&model, 1e-3);
    assert!(c.mismatch <= 1e-8, "mismatch {:e}", c.mismatch);
}
