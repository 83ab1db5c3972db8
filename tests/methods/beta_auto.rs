//! `--beta auto` (`fricsens::sensitivity` `auto` module): the error bars bound SDM's true
//! error against DDM, and the chosen steps reach the sweep's best error within a factor 10.

use crate::common;
use fricsens::prelude::*;
use fricsens::sensitivity::{run_sensitivity, Method, Parameter, SensitivityResults, Settings};

fn auto(model: &Model, names: &[&str], method: Method) -> SensitivityResults {
    let params = common::params(model, names);
    let settings = Settings {
        method,
        beta_auto: true,
        ..Settings::default()
    };
    run_sensitivity(model, &params, &settings).unwrap().1
}

/// Over the unflagged increments and the responses sensitive to each parameter: how many
/// derivatives the error bar bounds (none where `s` has no bars), out of how many, and the
/// largest relative error (as the report measures it, floor 1e-3).
fn bounded(
    params: &[Parameter],
    s: &SensitivityResults,
    ddm: &SensitivityResults,
) -> (usize, usize, f64) {
    let (mut ok, mut all, mut worst) = (0, 0, 0.0f64);
    for r in 0..s.responses.len() {
        for (k, p) in params.iter().enumerate() {
            let Some(scale) = ddm.sensitive_scale(r, k, p.value) else {
                continue;
            };
            for (a, d) in s.increments.iter().zip(&ddm.increments) {
                if !d.kinks.is_empty() {
                    continue;
                }
                let e = (a.derivatives[r][k] - d.derivatives[r][k]).abs();
                all += 1;
                if a.bar_bounds(r, k, e) {
                    ok += 1;
                }
                worst = worst.max(e / d.derivatives[r][k].abs().max(1e-3 * scale));
            }
        }
    }
    (ok, all, worst)
}

/// Every step `s` chose lies on `method`'s ladder, one per parameter.
fn on_the_ladder(s: &SensitivityResults, method: Method, np: usize) {
    use fricsens::sensitivity as m;
    let ladder: &[f64] = match method {
        Method::Sdm => &m::FORWARD_LADDER,
        Method::SdmCentral => &m::CENTRAL_LADDER,
        Method::Fdm => &m::FDM_FORWARD_LADDER,
        _ => &m::FDM_CENTRAL_LADDER,
    };
    for inc in &s.increments {
        assert_eq!(inc.betas.len(), np);
        assert!(
            inc.betas.iter().all(|b| ladder.contains(b)),
            "{:?}",
            inc.betas
        );
    }
}

/// The share of bounded derivatives per scene and method, and the largest error.
fn coverage_of(
    scene: &str,
    names: &[&str],
    methods: &[Method],
) -> Vec<(Method, usize, usize, f64, SensitivityResults)> {
    let model = Scene::load(scene).unwrap().build().unwrap();
    let params = common::params(&model, names);
    let ddm = common::sensitivities(&model, &params, Method::Ddm, 0.0);
    methods
        .iter()
        .copied()
        .map(|method| {
            let s = auto(&model, names, method);
            let (ok, all, worst) = bounded(&params, &s, &ddm);
            eprintln!("{scene} {method:?}: {ok}/{all} bounded, worst {worst:.1e}");
            (method, ok, all, worst, s)
        })
        .collect()
}

/// The target on each scene and method: the bars bound at least 95 % of the
/// derivatives, against DDM (exact to 1e-13), and every step chosen lies on the method's
/// ladder, one per parameter.
fn meets_the_target(cases: &[(&str, Vec<&str>, &[Method])]) {
    for (scene, names, methods) in cases {
        for (method, ok, all, _, s) in coverage_of(scene, names, methods) {
            assert!(all > 0);
            assert!(
                ok as f64 >= 0.95 * all as f64,
                "{scene} {method:?}: {ok} of {all}"
            );
            on_the_ladder(&s, method, names.len());
        }
    }
}

const SDM_BOTH: [Method; 2] = [Method::Sdm, Method::SdmCentral];
const FDM_BOTH: [Method; 2] = [Method::Fdm, Method::FdmCentral];

#[test]
fn error_bars_bound_the_true_error_in_95_percent_of_the_derivatives() {
    meets_the_target(&[
        (
            "leaf-spring-coarse",
            vec!["upper.length.x", "mu"],
            &SDM_BOTH,
        ),
        ("strip-pullout", vec!["mu", "E"], &SDM_BOTH),
        ("jenkins", vec!["mu"], &SDM_BOTH),
        ("stacked-leaves", vec!["E", "mu"], &SDM_BOTH),
    ]);
}

/// The J2 cycle by SDM and SDM central: forward SDM's bars on E and H bounded 82 % and 93 %
/// while they counted the chosen run's round-off only. The shadow's (ten times larger, and
/// signed) cancelled the truncation difference at the E step's shadow (1e-8, deep in
/// round-off): a bar of 2.6e-11 under an error of 6.5e-11 at increment 10; the bar now adds
/// it, as the chosen error is at most the difference plus the shadow's.
#[test]
fn error_bars_on_the_j2_cycle() {
    meets_the_target(&[("uniaxial-j2", vec!["H", "E", "sigma_y"], &SDM_BOTH)]);
}

/// The Klarbring oscillator by SDM and SDM central, whose stick penalty (1e6) makes the
/// round-off of the unbalance the stick force's: the perturbed design's anchor `a + db da` is
/// rounded to the ulp of the position `a` (near 0.353), so `k_t (x - a)` is quantized in steps
/// of 5.55e-11, against 2e-16 of the reference force. Counting the reference force only, the
/// bars bounded 142 of 150 each: from the slip-to-stick increment (t = 3.1) on, the chosen step
/// and its shadow agreed on a d(plane-force-x)/d mu 3.6e-6 off DDM's (between two quanta the
/// computed force drifts linearly with mu, 3.47e-6 per unit mu, which every difference shorter
/// than the sawtooth's period of about 5e-5 of mu measures). The round-off now counts each
/// frictional node's penalty times its positions (`ContactEval::cancelling`); that round-off
/// exceeds the derivative at the smallest steps, so a response is left out as zero only where
/// no two probes above their round-off agree (`PLATEAU`): without that, d(plane-force-x)/d mu
/// was left out and 1e-1 chosen, an error of 18 at t = 3.9.
#[test]
fn error_bars_on_the_klarbring_oscillator() {
    meets_the_target(&[("klarbring-2dof", vec!["mu"], &SDM_BOTH)]);
}

/// `--beta auto` for FDM and FDM central: the same plateau rule on reruns at every step of a
/// ladder, the error bar from the next step down and the noise of the Newton residual both
/// reruns actually reached. The 95 % target against DDM on the strip pull-out, the stacked
/// leaves, the SVK bar, Jenkins and (forward) the J2 cycle; every chosen step on the method's
/// ladder. Counting the chosen rerun's noise only, forward FDM on the J2 cycle bounded 166 of
/// 180 (d(stress)/dH at 13 increments, d(alpha)/dH at one) and central FDM on Jenkins 93 of
/// 98, 94 with the shadow's noise counted, and 98 since a step whose reruns leave the nominal
/// states gives way ([`fdm_steps_below_a_stick_slip_switch`]).
#[test]
fn fdm_error_bars_bound_the_true_error_in_95_percent_of_the_derivatives() {
    meets_the_target(&[
        ("strip-pullout", vec!["mu", "E"], &FDM_BOTH),
        ("stacked-leaves", vec!["E", "mu"], &FDM_BOTH),
        ("uniaxial-svk", vec!["E"], &FDM_BOTH),
        ("jenkins", vec!["mu"], &FDM_BOTH),
        ("uniaxial-j2", vec!["H", "E", "sigma_y"], &FDM_BOTH[..1]),
    ]);
}

#[test]
fn the_chosen_steps_reach_the_sweeps_best_error_within_a_factor_10() {
    // the second target, on scenes whose parameters range from exact differences
    // (linear in the parameter) to truncation-dominated ones; the sweep is SDM at every step
    // of the ladder, the best over it against the auto run's largest error. (Measured in the
    // report: equal on all of these but the strip's E, 0.4 of the best forward and 4.5 times
    // it central, its mu forward 1.2 times, the stacked leaves' E forward 4.6 times, and the
    // Klarbring oscillator, 0.03 of it forward and 0.09 central: no fixed step is best at
    // every increment there.)
    // The strip's mu forward missed it while the step was the responses' alone: through the
    // stick increments they agree exactly from 1e-1 on, while the anchors' derivatives carry a
    // truncation a decade per decade of step, which reached the pull-out's displacement later
    // (2.9e-7 against the best 3.3e-10); the history now has its own step where it asks for a
    // smaller one (`HistoryProbes`: 4.0e-10).
    use fricsens::sensitivity::{run_inline_sweep, CENTRAL_LADDER, FORWARD_LADDER};
    for (scene, names) in [
        ("jenkins", vec!["mu"]),
        ("stacked-leaves", vec!["E", "mu"]),
        ("strip-pullout", vec!["E", "mu"]),
        ("uniaxial-j2", vec!["sigma_y"]),
        ("cantilever", vec!["E"]),
        ("klarbring-2dof", vec!["mu"]),
    ] {
        let model = Scene::load(scene).unwrap().build().unwrap();
        let params = common::params(&model, &names);
        for (method, ladder) in [
            (Method::Sdm, &FORWARD_LADDER[..]),
            (Method::SdmCentral, &CENTRAL_LADDER[..]),
        ] {
            let mut settings = vec![Settings::default()];
            settings.extend(ladder.iter().map(|&beta| Settings {
                method,
                beta,
                ..Settings::default()
            }));
            settings.push(Settings {
                method,
                beta_auto: true,
                ..Settings::default()
            });
            let (_, runs) = run_inline_sweep(&model, &params, &settings).unwrap();
            let best = (runs[1..runs.len() - 1].iter())
                .map(|s| bounded(&params, s, &runs[0]).2)
                .fold(f64::INFINITY, f64::min);
            let auto = bounded(&params, &runs[runs.len() - 1], &runs[0]).2;
            eprintln!("{scene} {method:?}: auto {auto:.1e}, best {best:.1e}");
            assert!(
                auto <= 10.0 * best,
                "{scene} {method:?}: auto {auto:e}, the sweep's best {best:e}"
            );
        }
    }
}

/// The factor-10 target for FDM and FDM central on the cantilever, whose clamp reaction is
/// fixed by equilibrium (a zero derivative, noise at every step): the auto step's largest error
/// against the best of the fixed steps of the method's ladder (reruns), and the bars bounding
/// 95 %. Before the noise-only response was left out of the choice its disagreements chose
/// 1e-3 forward (an error of 9e-4 against the sweep's best 2.2e-7) and 1e-1 to 1e-2 central
/// (3.3e-3 against 4.8e-9).
#[test]
fn fdm_steps_on_the_cantilever_reach_the_sweeps_best_within_a_factor_10() {
    use fricsens::sensitivity::{FDM_CENTRAL_LADDER, FDM_FORWARD_LADDER};
    fdm_auto_against_its_ladder(
        "cantilever",
        "E",
        &[
            (Method::Fdm, &FDM_FORWARD_LADDER),
            (Method::FdmCentral, &FDM_CENTRAL_LADDER),
        ],
    );
}

/// FDM's auto step on `scene` for `param` by each method: its largest error within a factor
/// 10 of the best of the fixed steps of the method's ladder (reruns), and its bars bounding
/// 95 %, against DDM (run once for all the methods).
fn fdm_auto_against_its_ladder(scene: &str, param: &str, methods: &[(Method, &[f64])]) {
    let model = Scene::load(scene).unwrap().build().unwrap();
    let params = common::params(&model, &[param]);
    let ddm = common::sensitivities(&model, &params, Method::Ddm, 0.0);
    for &(method, ladder) in methods {
        auto_against(&model, &params, &ddm, scene, method, ladder);
    }
}

/// [`fdm_auto_against_its_ladder`] for one method.
fn auto_against(
    model: &Model,
    params: &[Parameter],
    ddm: &SensitivityResults,
    scene: &str,
    method: Method,
    ladder: &[f64],
) {
    let param = params[0].name.as_str();
    let best = (ladder.iter())
        .map(|&beta| {
            let s = common::sensitivities(model, params, method, beta);
            bounded(params, &s, ddm).2
        })
        .fold(f64::INFINITY, f64::min);
    let s = auto(model, &[param], method);
    let (ok, all, worst) = bounded(params, &s, ddm);
    eprintln!("{scene} {method:?}: auto {worst:.1e}, best {best:.1e}, {ok}/{all} bounded");
    assert!(
        worst <= 10.0 * best,
        "{scene} {method:?}: auto {worst:e}, the ladder's best {best:e}"
    );
    assert!(
        all > 0 && ok as f64 >= 0.95 * all as f64,
        "{scene} {method:?}: {ok} of {all}"
    );
}

/// FDM central where the nominal state lies within a step of a stick/slip switch: Jenkins where
/// the slide reverses (increments 16 and 36, DDM's d(T)/d mu = 1) and the Klarbring oscillator
/// where it starts to slip (increment 5, 0). The reruns at 0.1 and 0.01 of mu on either side
/// cross the switch and agree with each other on a secant across it (1e-5 and 1e-4 at Jenkins,
/// an error of 1; -0.440 and -0.435 at Klarbring), a false plateau; the step now keeps to the
/// steps whose reruns are in the nominal run's states at the increment. The auto step's
/// largest error against the best fixed step of the ladder (reruns), and the bars bounding
/// 95 %: before, Jenkins' largest error was 1.0 (94 of 98 bounded) and Klarbring's 0.435
/// absolute (147 of 150). Jenkins at increment 16 holds its states only below 1e-6 (3.0e-6
/// there, 1.3e-8 at 1e-7): while the ladder ended at 1e-6 that was its largest error, against
/// the report's sweep's best 1.5e-8 (at 1e-7); the ladder now goes down to 1e-8.
#[test]
fn fdm_steps_below_a_stick_slip_switch() {
    use fricsens::sensitivity::FDM_CENTRAL_LADDER;
    for scene in ["jenkins", "klarbring-2dof"] {
        fdm_auto_against_its_ladder(scene, "mu", &[(Method::FdmCentral, &FDM_CENTRAL_LADDER)]);
    }
}

/// The factor 10 for FDM where the report's sweep found it missed: the J2 bar's yield stress
/// forward (linear in it: 2.6e-14 at 1e-1, 6.0e-13 at 1e-2, the top of the ladder before it
/// began at 1e-1) and the stacked leaves' E central (1.0e-8 at 1e-4 where the pair 1e-4 / 1e-5
/// agreed best by 1e-4's truncation, against 6.1e-10 at 1e-5: `better_of_pair` now takes the
/// smaller step of such a pair). Each against the best fixed step of its ladder (reruns), the
/// bars bounding 95 %.
#[test]
fn fdm_steps_reach_the_ladders_best_within_a_factor_10() {
    use fricsens::sensitivity::{FDM_CENTRAL_LADDER, FDM_FORWARD_LADDER};
    fdm_auto_against_its_ladder(
        "uniaxial-j2",
        "sigma_y",
        &[(Method::Fdm, &FDM_FORWARD_LADDER)],
    );
    fdm_auto_against_its_ladder(
        "stacked-leaves",
        "E",
        &[(Method::FdmCentral, &FDM_CENTRAL_LADDER)],
    );
}
