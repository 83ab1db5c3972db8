//! The sensitivity methods' defaults: DDM with the default settings is the exact derivative of
//! the discrete incremental solution, to the solver's accuracy.

use crate::common::{fricsens, params, scratch_path, succeeds};

use fricsens::scene::{builtin, builtin_list, Scene};
use fricsens::sensitivity::{
    run_sensitivity, Method, Parameter, SensitivityResults, Settings, TangentChoice,
};

/// The scale errors in d(response r)/d(parameter p) are measured against: the largest
/// |derivative| over the history, but at least 1e-6 of the response's largest value over the
/// parameter's. A sensitivity that is zero in exact arithmetic (the reaction that balances the
/// cantilever's dead load, in E) is the round-off of internal forces that cancel (1e-10 of that
/// logarithmic scale on the cantilever, where both solves agree to 3e-24 absolute) and has no
/// scale of its own; a sensitivity that is not zero is far above the floor (the cantilever's
/// tip deflection in E: 0.2 of it).
fn scale(s: &SensitivityResults, r: usize, p: usize, value: f64) -> f64 {
    let response = s
        .increments
        .iter()
        .map(|i| i.values[r].abs())
        .fold(0.0, f64::max);
    // A derivative that is zero (a load-controlled reaction against E) is the sum of terms of
    // about |response| / |b| that cancel to round-off: two solves agree on it to a few eps
    // of that size, not better. The floor is 1e-4 of it, so that the comparisons' 1e-10 of
    // the scale is 1e-14 of those terms, about 50 eps (at 1e-6 it was 1e-16, below one eps:
    // the cantilever's d(clamp-reaction-y)/d(E), 1.27e-15 by both methods, differed by
    // 6.5e-21 = 1e-15 of |response| / |b| once the factorization left out the prescribed
    // unknowns, and the test failed on round-off).
    let floor = 1e-4 * response / value.abs().max(f64::MIN_POSITIVE);
    s.increments
        .iter()
        .map(|i| i.derivatives[r][p].abs())
        .fold(floor, f64::max)
}

/// On every built-in scene and every parameter of its study, DDM with the default settings
/// (the converged tangent by GMRES preconditioned with Newton's last factorization) equals DDM
/// solved with a fresh factorization of the converged tangent, to 1e-10 of each sensitivity's
/// scale at every unflagged increment. Both solve the same linear system to a relative residual
/// of 1e-11 (`KRYLOV_TOL`) or better, so they differ by the condition-weighted solver tolerance.
#[test]
fn default_ddm_equals_a_fresh_factorization_on_every_builtin_scene() {
    assert_eq!(
        Settings::default().tangent,
        TangentChoice::Exact,
        "the default tangent is the converged one"
    );
    let mut compared = 0;
    for (name, _) in builtin_list() {
        let scene = builtin(name).expect("listed");
        let model = scene.build().expect("built-in scenes build");
        let params: Vec<Parameter> = scene
            .study
            .params
            .iter()
            .map(|p| Parameter::by_name(&model, p).expect("study parameters resolve"))
            .collect();
        let default = Settings::default();
        let fresh = Settings {
            krylov: false,
            ..Settings::default()
        };
        let (_, a) = run_sensitivity(&model, &params, &default).expect("default DDM");
        let (_, b) = run_sensitivity(&model, &params, &fresh).expect("factored DDM");
        assert_eq!(a.increments.len(), b.increments.len(), "{name}");
        for r in 0..a.responses.len() {
            for (p, param) in params.iter().enumerate() {
                let s = scale(&b, r, p, param.value).max(f64::MIN_POSITIVE);
                for (ia, ib) in a.increments.iter().zip(&b.increments) {
                    if !ia.kinks.is_empty() || !ib.kinks.is_empty() {
                        continue;
                    }
                    let err = (ia.derivatives[r][p] - ib.derivatives[r][p]).abs() / s;
                    assert!(
                        err <= 1e-10,
                        "{name}: d({})/d({}) at increment {}: default {:e}, fresh factorization {:e} (error {err:.2e} of the scale {s:.3e})",
                        a.responses[r],
                        a.parameters[p],
                        ia.increment,
                        ia.derivatives[r][p],
                        ib.derivatives[r][p]
                    );
                    compared += 1;
                }
            }
        }
    }
    assert!(compared > 1000, "only {compared} comparisons");
}

/// The J2 beam the issue measured against JAX-FEM and torch-fem: a cantilever of plain hex8
/// (10 x 4 x 4 elements), small strain, J2 with linear hardening, its tip pushed down over 15
/// increments (to six times the first-yield deflection 2 sigma_y L^2 / (3 E h) = 0.83) and pulled back by one.
pub(crate) fn j2_beam() -> Scene {
    Scene::from_toml(
        r#"
name = "j2-beam"
[[bodies]]
name = "beam"
origin = [0.0, 0.0, 0.0]
kinematics = "small"
formulation = "full"
x = { length = 100.0, zones = [{ fraction = 1.0, elements = 10, ratio = 1.0 }] }
y = { length = 10.0, zones = [{ fraction = 1.0, elements = 4, ratio = 1.0 }] }
z = { length = 10.0, zones = [{ fraction = 1.0, elements = 4, ratio = 1.0 }] }
material = { law = "j2", E = 200000.0, nu = 0.3, sigma_y = 250.0, H = 2000.0 }

[[prescribed]]
name = "clamp"
set = "beam.xmin"
components = ["x", "y", "z"]

[[prescribed]]
name = "tip"
set = "beam.xmax"
components = ["y"]
value = -5.0
amplitude = [[0.0, 0.0], [15.0, 1.0], [16.0, 0.6]]

[[steps]]
end = 15.0
increments = 15
[[steps]]
end = 16.0
increments = 1

[[responses]]
kind = "reaction"
name = "tip-force"
set = "beam.xmax"
component = "y"
"#,
        "j2-beam",
    )
    .expect("the J2 beam parses")
}

/// DDM with the default settings on the J2 beam equals central finite differences of reruns
/// to within the finite differences' own error, estimated from two step sizes: with steps h
/// and 2h the truncation error of D(h) is |D(h) - D(2h)| / 3 (Richardson); the estimate takes
/// the whole difference, and adds the round-off of reruns converged to a relative force
/// residual of `force_tol`: `force_tol |f| / (h b)` for a response of size `|f|`. DDM runs
/// with the default settings, the solver's included (force tolerance 1e-9); the reruns are
/// converged to 1e-13, so that their round-off is below the truncation error the comparison
/// estimates (the two nominal solutions differ by the default tolerance, 1e-9 relative).
/// Measured: the largest |DDM - FDM| is 0.01 of the estimate with the default tangent, 0.65
/// with Newton's last factorization (`--tangent last`, the old default).
///
/// The step, 3e-4 of each parameter, keeps the truncation error above that round-off (at
/// 1e-4 the two are about equal, 1e-10 of the derivative, and their estimate is noise) and
/// below the yield-onset kinks: at 1e-3 the reruns straddle a Gauss point's first yield at
/// the third increment and differ from DDM's one-sided derivative by 1e-1 of it.
#[test]
fn default_ddm_matches_central_fdm_on_the_j2_beam() {
    let (records, worst) = ddm_against_central_fdm(&j2_beam(), 3e-4, false);
    assert_eq!(records.len(), 16, "no cutback on the beam");
    println!("largest |DDM - FDM| over the FDM error estimate: {worst:.2}");
}

/// Sensitivities are exact along the steps actually taken: the J2 beam pushed to its tip
/// deflection in one increment instead of 15, with at most 5 Newton iterations per attempt,
/// needs cutbacks (the solver halves the step and carries the converged one on), and DDM along
/// those sub-increments equals central finite differences of reruns that take the same
/// sub-increments (checked: the same times), within the finite differences' error as in the
/// test above. DDM runs here at the reruns' force tolerance, 1e-13, so that both linearise
/// about the same converged states.
#[test]
fn ddm_is_exact_along_cut_back_increments() {
    let mut scene = j2_beam();
    scene.steps[0].increments = 1;
    scene.solver.max_iterations = 5;
    let (records, worst) = ddm_against_central_fdm(&scene, 3e-4, true);
    let cut: usize = records.iter().map(|r| r.cutbacks).sum();
    assert!(
        records.len() > 3 && cut > 0,
        "the 2-increment beam must be cut back: {} increments, {cut} cutbacks",
        records.len()
    );
    let asked: usize = scene.steps.iter().map(|s| s.increments).sum();
    println!(
        "{} increments taken for {asked} asked, {cut} cutbacks; largest |DDM - FDM| over the FDM error estimate: {worst:.1e}",
        records.len()
    );
}

/// DDM with default settings on `scene` (the J2 beam's parameters `sigma_y` and `E`, response
/// `tip-force`) against central FDM of reruns with steps `h` and `2h`: with steps h and 2h the
/// truncation error of D(h) is |D(h) - D(2h)| / 3 (Richardson); the estimate takes the whole
/// difference, and adds the round-off of reruns converged to a relative force residual of
/// `force_tol`: `force_tol |f| / (h b)` for a response of size `|f|`. DDM runs with the
/// default settings, the solver's included (force tolerance 1e-9); the reruns are converged to
/// 1e-13, so that their round-off is below the truncation error the comparison estimates
/// (`ddm_tight`: DDM too). Every rerun must take the increments DDM took (the same times). Returns DDM's increment
/// records and the largest |DDM - FDM| over the estimate.
fn ddm_against_central_fdm(
    scene: &Scene,
    h: f64,
    ddm_tight: bool,
) -> (Vec<fricsens::solver::IncrementRecord>, f64) {
    let mut tight = scene.clone();
    tight.solver.force_tol = 1e-13;
    let tight = tight.build().unwrap();
    let model = if ddm_tight {
        tight.clone()
    } else {
        scene.build().unwrap()
    };
    let force_tol = tight.solver.force_tol;
    let names = ["sigma_y", "E"];
    let params = params(&model, &names);
    let (res, ddm) = run_sensitivity(&model, &params, &Settings::default()).unwrap();
    // the beam yields: the comparison is in the plastic range
    let plastic = res
        .branches
        .iter()
        .flatten()
        .filter(|b| **b != fricsens::material::Branch::Elastic)
        .count();
    assert!(plastic > 0, "the beam must yield");
    let fdm = |beta: f64| {
        let s = Settings {
            method: Method::FdmCentral,
            beta,
            ..Settings::default()
        };
        let (r, d) = run_sensitivity(&tight, &params, &s).unwrap();
        let times = |rs: &[fricsens::solver::IncrementRecord]| -> Vec<f64> {
            rs.iter().map(|r| r.time).collect()
        };
        assert_eq!(
            times(&r.records),
            times(&res.records),
            "the rerun's increments"
        );
        d
    };
    let (d1, d2) = (fdm(h), fdm(2.0 * h));
    let mut worst: f64 = 0.0;
    for p in 0..names.len() {
        let b = params[p].value;
        for k in 0..ddm.increments.len() {
            let d = ddm.increments[k].derivatives[0][p];
            let f = ddm.increments[k].values[0];
            let (a, a2) = (
                d1.increments[k].derivatives[0][p],
                d2.increments[k].derivatives[0][p],
            );
            let truncation = (a - a2).abs();
            let round_off = force_tol * f.abs() / (h * b);
            let err = (d - a).abs();
            worst = worst.max(err / (truncation + round_off));
            assert!(
                err <= truncation + round_off,
                "d(tip-force)/d({}) at increment {}: DDM {d:e}, central FDM {a:e} (2h: {a2:e}); |DDM - FDM| = {err:.2e} above the FDM error estimate {truncation:.2e} + {round_off:.2e}",
                names[p],
                k + 1
            );
        }
    }
    (res.records, worst)
}

/// `fricsens sensitivity SCENE` without `--param` differentiates with respect to the scene's
/// `[study] params`, with the exact tangent by default; `fricsens run --no-vtk` writes no VTK
/// files and `--vtk-every N` every N-th increment and the last.
#[test]
fn the_command_line_takes_the_study_and_writes_vtk_as_asked() {
    let dir = scratch_path("cli");
    let run = |args: &[&str]| {
        String::from_utf8_lossy(&succeeds(fricsens().args(args)).stdout).to_string()
    };
    let sens = dir.join("sens");
    let text = run(&[
        "sensitivity",
        "uniaxial-j2",
        "--out",
        &sens.display().to_string(),
    ]);
    assert!(text.contains("tangent: exact"), "{text}");
    let header = std::fs::read_to_string(sens.join("sensitivity.csv")).unwrap();
    let header = header.lines().next().unwrap();
    let study = builtin("uniaxial-j2").unwrap().study.params;
    assert_eq!(study, ["sigma_y", "H", "E"]);
    for p in &study {
        assert!(header.contains(&format!("d(stress)/d({p})")), "{header}");
    }
    // the CSV's values and derivatives are the library's default DDM (to the CSV's 13 digits)
    let model = builtin("uniaxial-j2").unwrap().build().unwrap();
    let params: Vec<Parameter> = study
        .iter()
        .map(|n| Parameter::by_name(&model, n).unwrap())
        .collect();
    let (_, lib) = run_sensitivity(&model, &params, &Settings::default()).unwrap();
    let csv = std::fs::read_to_string(sens.join("sensitivity.csv")).unwrap();
    let last: Vec<f64> = csv
        .lines()
        .last()
        .unwrap()
        .split(',')
        .skip(3)
        .map(|v| v.parse().unwrap())
        .collect();
    let inc = lib.increments.last().unwrap();
    assert!((last[0] - inc.values[0]).abs() <= 1e-12 * inc.values[0].abs());
    for (p, d) in inc.derivatives[0].iter().enumerate() {
        assert!(
            (last[1 + p] - d).abs() <= 1e-12 * d.abs(),
            "{p}: {} {d}",
            last[1 + p]
        );
    }

    let none = dir.join("none");
    run(&[
        "run",
        "hertz",
        "--no-vtk",
        "--out",
        &none.display().to_string(),
    ]);
    assert!(none.join("history.csv").exists() && !none.join("vtk").exists());
    let every = dir.join("every");
    run(&[
        "run",
        "hertz",
        "--vtk-every",
        "3",
        "--out",
        &every.display().to_string(),
    ]);
    let mut files: Vec<String> = std::fs::read_dir(every.join("vtk"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|f| f.ends_with(".vtu"))
        .collect();
    files.sort();
    // hertz: the initial state and 4 increments; every third and the last
    assert_eq!(files, ["step_0000.vtu", "step_0003.vtu", "step_0004.vtu"]);
    std::fs::remove_dir_all(&dir).ok();
}

/// `Settings::time_limit` reaches every method's primal analysis: with a limit of zero each
/// stops at its first Newton iteration with `AnalysisError::TimeLimit` (the in-line methods,
/// the adjoint's forward run, FDM's nominal run, with a fixed step and with `--beta auto`),
/// and without a limit the same runs complete.
#[test]
fn every_method_stops_at_its_time_limit() {
    use fricsens::solver::AnalysisError;
    let model = j2_beam().build().unwrap();
    let ps = params(&model, &["sigma_y"]);
    for (method, beta_auto) in [
        (Method::Ddm, false),
        (Method::Sdm, false),
        (Method::Adjoint, false),
        (Method::Fdm, false),
        (Method::FdmCentral, true),
    ] {
        let settings = Settings {
            method,
            beta_auto,
            time_limit: Some(0.0),
            ..Settings::default()
        };
        match run_sensitivity(&model, &ps, &settings) {
            Err(AnalysisError::TimeLimit {
                increment, seconds, ..
            }) => assert_eq!((increment, seconds), (1, 0.0), "{method:?}"),
            Err(e) => panic!("{method:?}: {e}"),
            Ok(_) => panic!("{method:?}: no time limit"),
        }
        let free = Settings {
            time_limit: None,
            ..settings
        };
        assert!(run_sensitivity(&model, &ps, &free).is_ok(), "{method:?}");
    }
}

/// `fuzz --methods --time-limit inf` is a campaign without a limit, and its report says so:
/// no "inf s" in methods.md, no limit in methods.json.
#[test]
fn an_infinite_time_limit_is_no_limit() {
    let dir = scratch_path("cli-time-limit-inf");
    let campaign = [
        "fuzz",
        "--methods",
        "--seed",
        "0",
        "--time-limit",
        "inf",
        "--out",
    ];
    succeeds(fricsens().args(campaign).arg(&dir));
    let md = std::fs::read_to_string(dir.join("methods.md")).unwrap();
    assert!(
        md.contains("DDM against the adjoint on 1 scenes") && !md.contains("time limit"),
        "{md}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("methods.json")).unwrap()).unwrap();
    assert_eq!(
        json.get("time_limit"),
        Some(&serde_json::Value::Null),
        "{json}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `--time-limit` on the command line: `fricsens run` stops with an error naming the
/// increment and the limit, and still writes the results it has (the initial state's row of
/// history.csv); `fricsens sensitivity` stops alike; a negative limit is refused by name,
/// given as `--time-limit=-1` or as `--time-limit -1`.
#[test]
fn the_command_line_stops_at_its_time_limit() {
    let dir = scratch_path("cli-time-limit");
    let failing = |args: &[&str]| {
        let out = fricsens().args(args).output().unwrap();
        assert!(!out.status.success(), "{args:?} succeeded");
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    let run = dir.join("run");
    let err = failing(&[
        "run",
        "uniaxial-j2",
        "--no-vtk",
        "--time-limit",
        "0",
        "--out",
        &run.display().to_string(),
    ]);
    assert!(
        err.contains("increment 1") && err.contains("time limit of 0 s"),
        "{err}"
    );
    let history = std::fs::read_to_string(run.join("history.csv")).unwrap();
    assert_eq!(
        history.lines().count(),
        2,
        "the header and the initial state"
    );
    let sens = dir.join("sens");
    let err = failing(&[
        "sensitivity",
        "uniaxial-j2",
        "--time-limit",
        "0",
        "--out",
        &sens.display().to_string(),
    ]);
    assert!(err.contains("time limit of 0 s"), "{err}");
    for limit in [["--time-limit=-1"].as_slice(), &["--time-limit", "-1"]] {
        let err = failing(&[&["run", "uniaxial-j2"], limit].concat());
        assert!(
            err.contains("--time-limit") && err.contains("must be at least 0 s"),
            "{err}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
