//! Branch freezing in SDM at a non-differentiable point: the first slip onset of the
//! two-degree-of-freedom frictional system (shared/oracles.md section 6), reached exactly at the
//! end of an increment.

use fricsens::scene::klarbring_2dof;
use fricsens::sensitivity::{run_sensitivity, Method, Parameter, Settings, TangentChoice};

fn du_dmu_at_onset(method: Method, freeze: bool, beta: f64) -> (f64, usize) {
    let model = klarbring_2dof(10).build().unwrap();
    let mu = [Parameter::by_name(&model, "plane.mu").unwrap()];
    let settings = Settings {
        method,
        beta,
        tangent: TangentChoice::Exact,
        freeze_branches: freeze,
        kink_tol: 1e-5,
        ..Settings::default()
    };
    let (_, s) = run_sensitivity(&model, &mu, &settings).unwrap();
    let inc = s
        .increments
        .iter()
        .find(|i| (i.time - 0.5).abs() < 1e-9)
        .unwrap();
    (inc.derivatives[0][0], inc.kinks.len())
}

#[test]
fn frozen_sdm_gives_the_converged_branch_and_unfrozen_sdm_straddles_the_kink() {
    let (ddm, kinks) = du_dmu_at_onset(Method::Ddm, true, 0.0);
    assert!(kinks > 0, "the onset is flagged");
    // the converged state sticks: DDM is the stick-side derivative, 0 (oracle: left value 0)
    assert!(ddm.abs() < 1e-8, "ddm {ddm}");
    // perturbations large enough to cross the kink (the onset lies ~1e-6 mu away)
    for beta in [1e-2, 1e-3] {
        let (frozen, _) = du_dmu_at_onset(Method::SdmCentral, true, beta);
        let (free, _) = du_dmu_at_onset(Method::SdmCentral, false, beta);
        println!("beta {beta:e}: frozen {frozen:.6e}, not frozen {free:.6e}");
        // frozen: finite and equal to the converged branch's derivative
        assert!(
            frozen.is_finite() && (frozen - ddm).abs() < 1e-6,
            "frozen {frozen}"
        );
        // not frozen: the perturbed evaluation at -beta slips and the one at +beta sticks, so
        // the central pseudo-load mixes the branches (r = p_n / 2, p_n = -F_n + k12 u = 1 at
        // u ~ 0) and is then solved with the converged, sticking tangent k11 + eps_T:
        // du/dmu = -p_n / (2 (k11 + eps_T)) ~ -5e-7, a number of neither branch (0 or -0.87).
        // (The converged state sits ~1e-6 short of the onset in relative terms, so the formula
        // holds where the step mu beta >> 1e-6 mu, i.e. at beta = 1e-3, to ~1e-3 / beta * 1e-6.)
        let mixed = -1.0 / (2.0 * (1.0 + 1e6));
        if beta >= 1e-3 {
            assert!(
                (free - mixed).abs() < 1e-2 * mixed.abs(),
                "not frozen {free} vs {mixed}"
            );
        }
        assert!(
            (free - ddm).abs() > 1e-8,
            "not frozen equals the stick side: {free}"
        );
        assert!(
            (free + 0.869565).abs() > 0.1,
            "not frozen equals the slip side: {free}"
        );
    }
    // a central difference of complete reruns straddles the kink too and returns the mean of
    // the one-sided derivatives, -0.4348 (oracles.md section 6)
    // (the penalty eps_T = 1e6 moves the onset ~1e-6 mu past the converged state, so the step
    // must be much larger than that: beta = 1e-4 straddles it, with a ~1e-6 / 1e-4 = 1 % bias)
    let (fdm, _) = du_dmu_at_onset(Method::FdmCentral, true, 1e-4);
    println!("central FDM at the onset: {fdm:.6}");
    assert!((fdm + 0.434783).abs() < 0.02 * 0.434783, "fdm {fdm}");
}
