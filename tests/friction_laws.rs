//! Every shipped friction law through the one `FrictionLaw` interface: the contact tangent
//! (forward AD, no hand-written derivative) against the dual-number derivative of the residual,
//! and DDM against central finite differences of complete reruns for each of the law's
//! parameters along a load-unload path (which exercises the history sensitivities).

use fricsens::assembly::{Assembler, Evaluation};
use fricsens::linalg::SparseMatrix;
use fricsens::model::Model;
use fricsens::scene::{strip_pullout, FrictionSpec, StripSpec};
use fricsens::sensitivity::{run_sensitivity, Method, Parameter, Settings, TangentChoice};
use fricsens::solver::{NoObserver, RunOptions, Solver};
use num_dual::Dual64;

fn laws() -> Vec<(&'static str, FrictionSpec, Vec<&'static str>)> {
    vec![
        (
            "coulomb",
            FrictionSpec::Coulomb { mu: 0.5 },
            vec!["ground.mu"],
        ),
        (
            "regularized",
            FrictionSpec::RegularizedCoulomb { mu: 0.5 },
            vec!["ground.mu"],
        ),
        (
            "pressure-dependent",
            // per-node normal force ~ n L / (2 (elements + 1)) ~ 0.12 here; p0 = 0.1
            FrictionSpec::PressureDependent {
                mu0: 0.5,
                p0: 0.1,
                n: 0.2,
            },
            vec!["ground.mu0", "ground.n"],
        ),
    ]
}

fn model(friction: FrictionSpec) -> Model {
    let s = StripSpec {
        elements: 20,
        ..StripSpec::default()
    };
    let mut scene = strip_pullout(&s);
    scene.contacts[0].friction = Some(friction);
    scene.build().unwrap()
}

#[test]
fn each_law_has_a_tangent_equal_to_the_dual_derivative_of_its_residual() {
    for (name, law, _) in laws() {
        let mut m = model(law);
        m.times.retain(|t| *t <= 0.5 + 1e-12); // partial slip
        let res = Solver::new(&m)
            .unwrap()
            .run(&RunOptions::default(), &mut NoObserver)
            .unwrap();
        let k_inc = res.states.len() - 1;
        let (z, hist) = (&res.states[k_inc], &res.histories[k_inc - 1]);
        let asm = Assembler::new(&m, &[]).unwrap();
        let ne = m.mesh.elements.len();
        let mut k = SparseMatrix::new(asm.pattern.clone());
        let mut ev = Evaluation::<f64>::new(&asm, ne);
        asm.evaluate(
            &m,
            &m.lifted::<f64>(&[]),
            z,
            hist,
            0.5,
            None,
            Some(&mut k),
            &mut ev,
        )
        .unwrap();
        let v: Vec<f64> = (0..z.len())
            .map(|i| 1e-3 * ((i as f64) * 0.61).cos())
            .collect();
        let zd: Vec<Dual64> = z.iter().zip(&v).map(|(a, b)| Dual64::new(*a, *b)).collect();
        let hd: Vec<Dual64> = hist.iter().map(|h| Dual64::from(*h)).collect();
        let mut evd = Evaluation::<Dual64>::new(&asm, ne);
        asm.evaluate(
            &m,
            &m.lifted::<Dual64>(&[]),
            &zd,
            &hd,
            0.5,
            None,
            None,
            &mut evd,
        )
        .unwrap();
        let mut kv = vec![0.0; z.len()];
        k.mul_vec(&v, &mut kv).unwrap();
        let scale = kv.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        for (i, (r, kvi)) in evd.residual.iter().zip(&kv).enumerate() {
            assert!(
                (r.eps - kvi).abs() <= 1e-8 * scale,
                "{name}: unknown {i}: {} vs {kvi}",
                r.eps
            );
        }
    }
}

#[test]
fn each_law_ddm_equals_central_fdm_along_loading_and_unloading() {
    for (name, law, params) in laws() {
        let m = model(law);
        let ps: Vec<Parameter> = params
            .iter()
            .map(|p| Parameter::by_name(&m, p).unwrap())
            .collect();
        let run = |method, beta| {
            let settings = Settings {
                method,
                beta,
                tangent: TangentChoice::Exact,
                ..Settings::default()
            };
            run_sensitivity(&m, &ps, &settings).unwrap().1
        };
        let ddm = run(Method::Ddm, 0.0);
        let fdm = run(Method::FdmCentral, 1e-6);
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
