//! Every shipped friction law through the one `FrictionLaw` interface: the contact tangent
//! (forward AD, no hand-written derivative) against the dual-number derivative of the residual,
//! and DDM against central finite differences of complete reruns for each of the law's
//! parameters along a load-unload path (which exercises the history sensitivities).

use crate::common;

use fricsens::contact::friction::{Coulomb, PressureDependentCoulomb, RegularizedCoulomb};
use fricsens::contact::Friction;
use fricsens::model::Model;
use fricsens::scene::{strip_pullout, StripSpec};
use fricsens::sensitivity::{run_sensitivity, Method, Parameter, Settings, TangentChoice};

fn laws() -> Vec<(&'static str, Friction, Vec<&'static str>)> {
    vec![
        (
            "coulomb",
            Friction::Coulomb(Coulomb::new(0.5)),
            vec!["ground.mu"],
        ),
        (
            "regularized",
            Friction::RegularizedCoulomb(RegularizedCoulomb::new(0.5)),
            vec!["ground.mu"],
        ),
        (
            "pressure-dependent",
            // per-node normal force ~ n L / (2 (elements + 1)) ~ 0.12 here; p0 = 0.1
            Friction::PressureDependent(PressureDependentCoulomb::new(0.5, 0.1, 0.2)),
            vec!["ground.mu0", "ground.n"],
        ),
        (
            // a shipped law through the user-law path: type-erased, differentiated on its own
            // inputs and carried by the chain rule
            "coulomb as a user law",
            Friction::user(Coulomb::new(0.5)).unwrap(),
            vec!["ground.mu"],
        ),
        (
            "pressure-dependent as a user law",
            Friction::user(PressureDependentCoulomb::new(0.5, 0.1, 0.2)).unwrap(),
            vec!["ground.mu0", "ground.p0", "ground.n"],
        ),
    ]
}

fn model(friction: Friction) -> Model {
    let s = StripSpec {
        elements: 20,
        ..StripSpec::default()
    };
    let mut m = strip_pullout(&s).build().unwrap();
    m.contacts[0].friction = Some(friction);
    m
}

#[test]
fn each_law_has_a_tangent_equal_to_the_dual_derivative_of_its_residual() {
    for (name, law, _) in laws() {
        let mut m = model(law);
        m.times.retain(|t| *t <= 0.5 + 1e-12); // partial slip
        let c = common::tangent_check(&m, 1e-3);
        assert!(c.mismatch <= 1e-8, "{name}: {}", c.mismatch);
    }
}

#[test]
fn each_law_ddm_equals_central_fdm_along_loading_and_unloading() {
    for (name, law, params) in laws() {
        let m = model(law);
        let (ps, ddm, fdm) = common::ddm_and_central_fdm(&m, &params);
        let mut worst: f64 = 0.0;
        for (a, b) in ddm.increments.iter().zip(&fdm.increments) {
            for p in 0..ps.len() {
                let (d, f) = (a.derivatives[0][p], b.derivatives[0][p]);
                // relative to the largest sensitivity over the path (the floor keeps
                // near-zero values from exploding)
                let floor = ddm
                    .increments
                    .iter()
                    .fold(0.0f64, |m, i| m.max(i.derivatives[0][p].abs()));
                worst = worst.max((d - f).abs() / floor);
            }
        }
        println!(
            "{name}: DDM vs central FDM, largest difference {worst:.2e} of the largest sensitivity"
        );
        assert!(worst < 1e-6, "{name}: {worst}");
    }
}

#[test]
fn a_user_law_reproduces_the_shipped_law_it_wraps() {
    // the same Coulomb law through the enum and through the type-erased user path: the primal
    // path and the DDM sensitivities agree to round-off (the chain rule is exact to first
    // order, so the only differences are the order of floating-point operations)
    let run = |friction: Friction| {
        let m = model(friction);
        let p = [Parameter::by_name(&m, "ground.mu").unwrap()];
        let settings = Settings {
            method: Method::Ddm,
            tangent: TangentChoice::Exact,
            ..Settings::default()
        };
        run_sensitivity(&m, &p, &settings).unwrap()
    };
    let (shipped_primal, shipped) = run(Friction::Coulomb(Coulomb::new(0.5)));
    let (user_primal, user) = run(Friction::user(Coulomb::new(0.5)).unwrap());
    assert_eq!(shipped_primal.states.len(), user_primal.states.len());
    for (a, b) in shipped_primal.states.iter().zip(&user_primal.states) {
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-12 * scale, "{x} vs {y}");
        }
    }
    let scale = shipped
        .increments
        .iter()
        .fold(0.0f64, |m, i| m.max(i.derivatives[0][0].abs()));
    for (a, b) in shipped.increments.iter().zip(&user.increments) {
        let (x, y) = (a.derivatives[0][0], b.derivatives[0][0]);
        assert!((x - y).abs() <= 1e-12 * scale, "{x} vs {y}");
    }
}

#[test]
fn a_user_law_with_too_many_parameters_is_a_typed_error() {
    use fricsens::contact::friction::{
        FrictionBranch, FrictionLaw, FrictionUpdate, UserFrictionError, MAX_USER_PARAMS,
    };
    use fricsens::scalar::Scalar;
    use nalgebra::Vector3;
    #[derive(Clone, Debug)]
    struct Many(Vec<f64>);
    impl fricsens::law::Law for Many {
        fn name(&self) -> &'static str {
            "many"
        }
        fn param_names(&self) -> &'static [&'static str] {
            &["a"; MAX_USER_PARAMS + 1]
        }
        fn params(&self) -> &[f64] {
            &self.0
        }
        fn params_mut(&mut self) -> &mut [f64] {
            &mut self.0
        }
    }
    impl FrictionLaw for Many {
        fn return_map<S: Scalar>(
            &self,
            _p: &[S],
            t: &Vector3<S>,
            _p_n: S,
            _margin: f64,
            _frozen: Option<FrictionBranch>,
        ) -> FrictionUpdate<S> {
            FrictionUpdate {
                traction: *t,
                branch: FrictionBranch::Stick,
                slip_ratio: -1.0,
            }
        }
    }
    let err = Friction::user(Many(vec![0.1; MAX_USER_PARAMS + 1])).unwrap_err();
    assert!(matches!(
        err,
        UserFrictionError::TooManyParameters { count: 13, .. }
    ));
    assert!(err.to_string().contains("'many'"), "{err}");
    let err = Friction::user(Many(vec![0.1; 2])).unwrap_err();
    assert!(
        matches!(err, UserFrictionError::ParameterCount { .. }),
        "{err}"
    );
}

#[test]
fn a_scene_with_a_user_law_builds_but_is_not_written_as_toml() {
    // a scene file cannot name a law defined in code: writing one is a typed error, not a panic
    let mut scene = strip_pullout(&StripSpec {
        elements: 10,
        ..StripSpec::default()
    });
    scene.contacts[0].friction = Some(Friction::user(Coulomb::new(0.5)).unwrap());
    assert!(scene.build().is_ok());
    let err = scene.to_toml().unwrap_err();
    assert!(
        matches!(err, fricsens::scene::SceneError::NotWritable { .. }),
        "{err}"
    );
}
