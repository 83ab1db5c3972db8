//! Perturbation sizes from 1e-1 down to 1e-15 (issue 8, extremes): round-off grows as beta
//! shrinks, no value is NaN or infinite, and the values that round-off dominates are flagged
//! (`IncrementSensitivity::roundoff`), while those at a well-chosen beta are not.

use fricsens::scene::builtin;
use fricsens::sensitivity::{
    run_fdm_sweep, run_inline_sweep, Method, Parameter, SensitivityResults, Settings, TangentChoice,
};

fn betas() -> Vec<f64> {
    (1..=15).map(|k| 10f64.powi(-k)).collect()
}

/// Largest relative error against `reference` (floor 1e-3 of the largest |derivative|), and
/// the number of increments with a round-off flag.
fn error_and_flags(reference: &SensitivityResults, s: &SensitivityResults) -> (f64, usize) {
    let nr = reference.responses.len();
    let np = reference.parameters.len();
    let mut worst: f64 = 0.0;
    for r in 0..nr {
        for p in 0..np {
            let scale = reference
                .increments
                .iter()
                .map(|i| i.derivatives[r][p].abs())
                .fold(0.0, f64::max);
            if scale == 0.0 {
                continue;
            }
            for (a, b) in reference.increments.iter().zip(&s.increments) {
                let (x, y) = (a.derivatives[r][p], b.derivatives[r][p]);
                worst = worst.max((x - y).abs() / x.abs().max(1e-3 * scale));
            }
        }
    }
    let flagged = s
        .increments
        .iter()
        .filter(|i| i.roundoff.iter().flatten().any(|f| *f))
        .count();
    (worst, flagged)
}

fn check(scene: &str) {
    let model = builtin(scene).unwrap().build().unwrap();
    let study = builtin(scene).unwrap().study.params;
    let params: Vec<Parameter> = study
        .iter()
        .map(|n| Parameter::by_name(&model, n).unwrap())
        .collect();
    let exact = Settings {
        tangent: TangentChoice::Exact,
        ..Settings::default()
    };
    let mut settings = vec![Settings {
        method: Method::Ddm,
        ..exact.clone()
    }];
    for m in [Method::Sdm, Method::SdmCentral] {
        for beta in betas() {
            settings.push(Settings {
                method: m,
                beta,
                ..exact.clone()
            });
        }
    }
    let (_, mut inline) = run_inline_sweep(&model, &params, &settings).unwrap();
    let ddm = inline.remove(0);
    let (_, fdm) = run_fdm_sweep(&model, &params, &betas(), true).unwrap();
    let n = ddm.increments.len();
    for s in inline.iter().chain(&fdm) {
        let m = s.method.unwrap();
        assert!(
            s.failure.is_none(),
            "{scene} {m:?} {:e}: {:?}",
            s.beta,
            s.failure
        );
        for inc in &s.increments {
            for row in &inc.derivatives {
                for d in row {
                    assert!(d.is_finite(), "{scene} {m:?} beta {:e}: {d}", s.beta);
                }
            }
        }
        let (err, flagged) = error_and_flags(&ddm, s);
        println!(
            "{scene} {:<12} beta {:.0e}: error {err:.2e}, round-off flagged {flagged} of {n}",
            m.name(),
            s.beta
        );
        // at 1e-15 every difference is below three digits of its noise: flagged everywhere
        if s.beta <= 1e-15 {
            assert_eq!(flagged, n, "{scene} {m:?}: not flagged at beta 1e-15");
        }
        // at the sweet spot of each method (sqrt(eps) for forward SDM, eps^(1/3) for central;
        // FDM's noise is the Newton tolerance 1e-9: sqrt for forward, cube root central) a
        // flag would be a false alarm
        let sweet = match m {
            Method::Sdm => 1e-8,
            Method::SdmCentral => 1e-5,
            Method::Fdm => 1e-4,
            _ => 1e-3,
        };
        // on the round-off side of the V, an SDM value off by more than 1 % is flagged
        if matches!(m, Method::Sdm | Method::SdmCentral) && s.beta < sweet && err > 1e-2 {
            assert!(
                flagged > 0,
                "{scene} {m:?} beta {:e}: error {err:.1e} not flagged",
                s.beta
            );
        }
        // ... except on values that are themselves near zero: there the difference is noise
        // relative to the value even at a good beta (below the report's error floor, 1e-3 of
        // the largest |derivative| of the response over the history)
        if (s.beta / sweet - 1.0).abs() < 1e-9 {
            for (a, b) in ddm.increments.iter().zip(&s.increments) {
                for (r, row) in b.roundoff.iter().enumerate() {
                    for (p, f) in row.iter().enumerate() {
                        let scale = ddm
                            .increments
                            .iter()
                            .map(|i| i.derivatives[r][p].abs())
                            .fold(0.0, f64::max);
                        let d = a.derivatives[r][p];
                        assert!(
                            !f || d.abs() <= 1e-3 * scale,
                            "{scene} {m:?} beta {sweet:e}: t = {} {} d/d{} = {d:e} flagged (max {scale:e})",
                            a.time,
                            ddm.responses[r],
                            ddm.parameters[p]
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn stacked_leaves_beta_down_to_1e_15() {
    check("stacked-leaves");
}

#[test]
fn uniaxial_j2_beta_down_to_1e_15() {
    check("uniaxial-j2");
}

/// oracles.md section 2: in uniaxial stress the nominal stress of St Venant-Kirchhoff does
/// not depend on nu (the lateral faces are free), dP11/dnu = 0 exactly, while dP11/dE =
/// lambda (lambda^2 - 1) / 2. DDM gives the zero to the Newton tolerance (1e-9 of the force).
#[test]
fn svk_uniaxial_stress_does_not_depend_on_nu() {
    use fricsens::sensitivity::run_sensitivity;
    let model = fricsens::scene::uniaxial_svk(1.5, 5).build().unwrap();
    let params: Vec<Parameter> = ["E", "nu"]
        .iter()
        .map(|n| Parameter::by_name(&model, n).unwrap())
        .collect();
    let settings = Settings {
        method: Method::Ddm,
        tangent: TangentChoice::Exact,
        ..Settings::default()
    };
    let (_, s) = run_sensitivity(&model, &params, &settings).unwrap();
    for inc in &s.increments {
        let lambda = 1.0 + 0.5 * inc.time;
        let p11 = 500.0 * lambda * (lambda * lambda - 1.0);
        assert!(
            (inc.values[0] - p11).abs() <= 1e-9 * p11,
            "t = {}",
            inc.time
        );
        let de = lambda * (lambda * lambda - 1.0) / 2.0;
        assert!(
            (inc.derivatives[0][0] - de).abs() <= 1e-9 * de,
            "t = {}",
            inc.time
        );
        // nu dP11/dnu against P11: zero to the force tolerance
        assert!(
            (0.3 * inc.derivatives[0][1]).abs() <= 1e-9 * p11,
            "t = {}: dP11/dnu = {}",
            inc.time,
            inc.derivatives[0][1]
        );
    }
}
