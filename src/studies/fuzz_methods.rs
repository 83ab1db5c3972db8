//! DDM against the adjoint on the physics fuzzer's generated scenes ([`super::fuzz`]).
//!
//! The two go through the same kernels by independent ways: DDM forward, one dual direction
//! per parameter, increment after increment; the adjoint backward, one column per response and
//! increment, with the history multipliers carried back through the return maps and friction
//! laws (its local derivatives in reverse mode, or on forward duals where more than 64
//! columns are alive at an increment: the adjoint's default either way). On the built-in
//! scenes they agree to 1e-10 of each sensitivity's scale; here they must agree on scenes
//! nobody tuned for: rigid cylinders, spheres, rounded punches and planes or a second
//! deformable block, every normal and friction law, elastic and J2 materials, smoothed
//! normals, any path. [`check`] runs both on one scene, with each one's default settings, for
//! the parameters the scene declares ([`design_parameters`]), and compares every derivative at
//! every increment, the flagged increments and their one-sided sides included (which
//! increments are flagged, which sides each method has, and the responses' values must be the
//! same too). `fricsens fuzz --methods` runs it on thousands of seeds; the default test suite
//! on sixteen. The scale is meant for generated scenes, whose responses of one kind are the
//! components of one force.

use crate::model::Model;
use crate::response::ResponseKind;
use crate::scene::{Scene, TargetSpec};
use crate::sensitivity::{run_sensitivity, Method, Parameter, SensitivityResults, Settings};
use crate::solver::AnalysisError;
use std::mem::Discriminant;

/// Agreement asked of the adjoint and DDM: of each derivative's scale ([`check`]).
pub const TOLERANCE: f64 = 1e-10;

/// The smallest log-sensitivity `|b / R dR/db|` a derivative's scale is taken at (`R` the
/// largest value of the responses of its kind over the path, `b` the parameter's value). A
/// column of derivatives all below it is round-off whatever its digits: a slipping
/// indenter's force against the distance it slides (1e-19 against a force of 3e-2, on the
/// fuzzer's seed 246: both methods' columns are noise of 1e-17). Such a column is compared
/// to [`TOLERANCE`] times this times `R / |b|`, about 500 roundings of the response over the
/// parameter. (The scale of [`SensitivityResults::sensitive_scale`], per response, would
/// compare a component zero by symmetry, as a symmetric indenter's horizontal force, at its
/// own size: round-off of the other component's.)
pub const FLOOR: f64 = 1e-3;

/// The design parameters a generated scene declares, by name: every material parameter of
/// every body (`E` and `nu`; a J2 body's yield stress and hardening too), the first parameter
/// of the first frictional pair's law (`mu`, `mu0`), the first block's length along x (a shape
/// parameter), and the magnitude of the first motion entry of the first rigid target (a load
/// path's).
pub fn design_parameters(scene: &Scene) -> Vec<String> {
    let mut out = Vec::new();
    for b in &scene.bodies {
        let m = &b.material;
        let names = m.param_names().iter().take(m.params().len());
        out.extend(names.map(|p| format!("{}.{p}", b.name())));
    }
    let friction = (scene.contacts.iter())
        .find_map(|c| Some((&c.name, c.friction.as_ref()?.param_names().first()?)));
    if let Some((pair, first)) = friction {
        out.push(format!("{pair}.{first}"));
    }
    if let Some(b) = scene.bodies.iter().find(|b| b.block().is_some()) {
        out.push(format!("{}.length.x", b.name()));
    }
    let moving = scene
        .contacts
        .iter()
        .find(|c| matches!(&c.target, TargetSpec::Rigid { motion, .. } if !motion.is_empty()));
    if let Some(c) = moving {
        out.push(format!("{}.motion[0]", c.name));
    }
    out
}

/// What [`check`] found on one scene.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct MethodsCheck {
    /// The seed (or the scene's position in a list).
    pub seed: u64,
    /// The parameters compared.
    pub parameters: Vec<String>,
    /// Derivatives compared (the converged branches' and the one-sided sides both methods
    /// have).
    pub derivatives: usize,
    /// The largest `|adjoint - DDM|` over its derivative's scale.
    pub worst: f64,
    /// Where: `increment N, RESPONSE, PARAMETER` (and the side).
    pub worst_at: String,
    /// Every derivative off by more than [`TOLERANCE`] of its scale, one line each.
    pub disagreements: Vec<String>,
    /// Both methods failed alike (the primal analysis), or one ran out of time: why. Not a
    /// disagreement: the fuzzer's own campaign counts those.
    pub skipped: Option<String>,
}

impl MethodsCheck {
    /// Whether the methods agree (or the scene was skipped).
    pub fn agrees(&self) -> bool {
        self.disagreements.is_empty()
    }
}

fn run(
    model: &Model,
    params: &[Parameter],
    method: Method,
    time_limit: Option<f64>,
) -> Result<SensitivityResults, AnalysisError> {
    let settings = Settings {
        method,
        time_limit,
        ..Settings::default()
    };
    run_sensitivity(model, params, &settings).map(|r| r.1)
}

/// Whether `e` is a failure of the primal analysis (which the physics fuzzer's campaign
/// counts), not of a sensitivity method.
fn primal_failure(e: &AnalysisError) -> bool {
    matches!(
        e,
        AnalysisError::Diverged { .. }
            | AnalysisError::TimeLimit { .. }
            | AnalysisError::Precheck(_)
    )
}

/// DDM and the adjoint (every increment) on `scene`, each with its default settings, for
/// [`design_parameters`]; every derivative compared: `|adjoint - DDM| <= TOLERANCE * scale`.
/// The scale of a response and parameter is the largest `|derivative|` (either method's, the
/// converged branches' and the sides') over the path of the responses of the same kind (both
/// components of a target's force: a component zero by symmetry has derivatives of round-off
/// alone), and at least [`FLOOR`] times that kind's largest value over the parameter's value
/// (taken as 1 where it is smaller, as [`SensitivityResults::sensitive_scale`] does: `mu = 0`).
/// Each method's primal analysis may take `time_limit` (the two carry different work per
/// increment, so one may pass it alone). Skipped only where both methods fail in the primal
/// analysis (Newton, a time limit, a pre-check), where DDM runs out of time (the adjoint is
/// not run), or where the adjoint does and DDM ran or failed in the primal; a
/// scene with nothing to compare, a method failing alone or otherwise, or tables that differ
/// in their shape, increments, flagged points, one-sided sides or values disagree.
pub fn check(seed: u64, scene: &Scene, time_limit: Option<f64>) -> MethodsCheck {
    let mut out = MethodsCheck {
        seed,
        parameters: design_parameters(scene),
        ..MethodsCheck::default()
    };
    let model = match scene.build() {
        Ok(m) => m,
        Err(e) => {
            out.disagreements.push(format!("scene: {e}"));
            return out;
        }
    };
    if out.parameters.is_empty() || model.responses.is_empty() {
        out.disagreements
            .push("nothing to compare: no parameter or no response".to_string());
        return out;
    }
    let params: Result<Vec<Parameter>, _> = (out.parameters.iter())
        .map(|n| Parameter::by_name(&model, n))
        .collect();
    let params = match params {
        Ok(p) => p,
        Err(e) => {
            out.disagreements.push(format!("parameter: {e}"));
            return out;
        }
    };
    let ddm = run(&model, &params, Method::Ddm, time_limit);
    match verdict(ddm, || run(&model, &params, Method::Adjoint, time_limit)) {
        Verdict::Compare(ddm, adj) => {
            if let Err(why) = compare(&model, &params, &ddm, &adj, &mut out) {
                out.disagreements.push(why);
            }
        }
        Verdict::Skip(why) => out.skipped = Some(why),
        Verdict::Disagree(why) => out.disagreements.push(why),
    }
    out
}

/// What the two runs' outcomes make of a scene ([`verdict`]).
#[derive(Debug)]
enum Verdict {
    /// Both ran: compare them.
    Compare(Box<SensitivityResults>, Box<SensitivityResults>),
    /// Skipped: why.
    Skip(String),
    /// A disagreement before any comparison: why.
    Disagree(String),
}

/// The verdict on DDM's outcome and the adjoint's (run by `adjoint`, and not at all where
/// DDM ran out of time: the scene is skipped whatever the adjoint would do). Skipped where
/// both fail in the primal analysis (the adjoint's time-out is one: DDM's failure is then
/// the reason given), or where the adjoint runs out of time and DDM ran; any other failure,
/// of either, disagrees.
fn verdict(
    ddm: Result<SensitivityResults, AnalysisError>,
    adjoint: impl FnOnce() -> Result<SensitivityResults, AnalysisError>,
) -> Verdict {
    if let Err(e @ AnalysisError::TimeLimit { .. }) = &ddm {
        return Verdict::Skip(format!("DDM: {e}"));
    }
    match (ddm, adjoint()) {
        (Ok(d), Ok(a)) => Verdict::Compare(Box::new(d), Box::new(a)),
        (Err(d), Err(a)) if primal_failure(&d) && primal_failure(&a) => {
            Verdict::Skip(d.to_string())
        }
        (Ok(_), Err(a @ AnalysisError::TimeLimit { .. })) => Verdict::Skip(format!("adjoint: {a}")),
        (d, a) => {
            let why = |r: &Result<SensitivityResults, AnalysisError>| match r {
                Ok(_) => "ran".to_string(),
                Err(e) => e.to_string(),
            };
            Verdict::Disagree(format!("DDM {}; adjoint {}", why(&d), why(&a)))
        }
    }
}

/// The comparison of [`check`], into `out`; `Err` where the two results differ in their
/// shape (responses, parameters, increments, flagged points, one-sided sides).
fn compare(
    model: &Model,
    params: &[Parameter],
    ddm: &SensitivityResults,
    adj: &SensitivityResults,
    out: &mut MethodsCheck,
) -> Result<(), String> {
    let (nr, np) = (model.responses.len(), params.len());
    if (ddm.responses.len(), ddm.parameters.len()) != (nr, np)
        || ddm.responses != adj.responses
        || ddm.parameters != adj.parameters
    {
        return Err("the two methods' responses or parameters differ".to_string());
    }
    if ddm.increments.len() != adj.increments.len() {
        return Err(format!(
            "DDM has {} increments, the adjoint {}",
            ddm.increments.len(),
            adj.increments.len()
        ));
    }
    // every table of both methods, (increment, side, DDM's, the adjoint's), its shape checked
    let mut tables = Vec::new();
    let shaped = |t: &[Vec<f64>]| t.len() == nr && t.iter().all(|row| row.len() == np);
    for (d, a) in ddm.increments.iter().zip(&adj.increments) {
        let k = d.increment;
        if a.increment != k || a.values != d.values {
            return Err(format!(
                "increment {k}: the two methods' increments or response values differ"
            ));
        }
        if d.kinks != a.kinks {
            return Err(format!("increment {k}: the flagged points differ"));
        }
        tables.push((k, "", &d.derivatives, &a.derivatives));
        match (&d.one_sided, &a.one_sided) {
            (None, None) => {}
            (Some(ds), Some(as_)) => {
                for (side, x, y) in [
                    (" (lower side)", &ds.lower, &as_.lower),
                    (" (upper side)", &ds.upper, &as_.upper),
                ] {
                    match (x, y) {
                        (Some(x), Some(y)) => tables.push((k, side, x, y)),
                        (None, None) => {}
                        _ => return Err(format!("increment {k}{side}: one method has it")),
                    }
                }
            }
            _ => {
                return Err(format!(
                    "increment {k}: one method has one-sided derivatives"
                ))
            }
        }
    }
    if let Some((k, side, ..)) = (tables.iter()).find(|(_, _, x, y)| !shaped(x) || !shaped(y)) {
        return Err(format!("increment {k}{side}: a table of another shape"));
    }
    // each kind's and parameter's scale
    let kind = |r: usize| -> Discriminant<ResponseKind> {
        std::mem::discriminant(&model.responses[r].kind)
    };
    let mut size = vec![0.0f64; nr];
    for inc in ddm.increments.iter() {
        for (s, v) in size.iter_mut().zip(&inc.values) {
            *s = s.max(v.abs());
        }
    }
    let mut column = vec![vec![0.0f64; np]; nr];
    for (_, _, x, y) in &tables {
        for (c, (xr, yr)) in column.iter_mut().zip(x.iter().zip(y.iter())) {
            for (m, (v, w)) in c.iter_mut().zip(xr.iter().zip(yr)) {
                *m = m.max(v.abs()).max(w.abs());
            }
        }
    }
    let scale = |r: usize, p: usize| -> f64 {
        let b = params[p].value.abs().max(1.0);
        (0..nr)
            .filter(|q| kind(*q) == kind(r))
            .map(|q| column[q][p].max(FLOOR * size[q] / b))
            .fold(0.0, f64::max)
    };
    let name = |r: usize, p: usize| format!("{}, {}", ddm.responses[r], ddm.parameters[p]);
    for (k, side, x, y) in tables {
        for (r, (xr, yr)) in x.iter().zip(y.iter()).enumerate() {
            for (p, (&v, &w)) in xr.iter().zip(yr).enumerate() {
                out.derivatives += 1;
                let at = || format!("increment {k}, {}{side}", name(r, p));
                let s = scale(r, p);
                if !(v.is_finite() && w.is_finite()) {
                    out.disagreements
                        .push(format!("{}: DDM {v:e}, adjoint {w:e}", at()));
                    continue;
                }
                if s == 0.0 {
                    // every derivative of the kind zero and the responses too: only equal
                    // zeros agree
                    if v != w {
                        out.disagreements
                            .push(format!("{}: DDM {v:e}, adjoint {w:e}, scale 0", at()));
                    }
                    continue;
                }
                let err = (w - v).abs() / s;
                if err > out.worst {
                    out.worst = err;
                    out.worst_at = at();
                }
                if err > TOLERANCE {
                    out.disagreements.push(format!(
                        "{}: DDM {v:e}, adjoint {w:e}, {err:.1e} of the scale {s:.1e}",
                        at()
                    ));
                }
            }
        }
    }
    Ok(())
}

/// A campaign of [`check`]s: the table `fricsens fuzz --methods` prints and writes.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Campaign {
    /// Scenes run.
    pub scenes: usize,
    /// Scenes compared (neither skipped).
    pub compared: usize,
    /// Scenes both methods failed on alike (the primal analysis), or one ran out of time on.
    pub skipped: usize,
    /// Seconds each method's primal analysis was allowed (`None`: no limit).
    pub time_limit: Option<f64>,
    /// Scenes with a derivative off by more than [`TOLERANCE`] of its scale.
    pub disagreeing: usize,
    /// Derivatives compared over all scenes.
    pub derivatives: usize,
    /// The largest `|adjoint - DDM|` over its scale, its seed and where.
    pub worst: f64,
    /// Seed of the largest (`None`: nothing compared).
    pub worst_seed: Option<u64>,
    /// Where in that scene.
    pub worst_at: String,
    /// Every scene's check.
    pub checks: Vec<MethodsCheck>,
}

impl Campaign {
    /// The campaign of `checks`, each method's primal analysis allowed `time_limit` seconds
    /// (an infinite one is none, as [`crate::solver::RunOptions`] takes it).
    pub fn of(checks: Vec<MethodsCheck>, time_limit: Option<f64>) -> Self {
        let time_limit = time_limit.filter(|s| s.is_finite());
        let compared: Vec<&MethodsCheck> = checks.iter().filter(|c| c.skipped.is_none()).collect();
        let worst = (compared.iter()).max_by(|a, b| a.worst.total_cmp(&b.worst));
        Campaign {
            scenes: checks.len(),
            compared: compared.len(),
            skipped: checks.len() - compared.len(),
            time_limit,
            disagreeing: checks.iter().filter(|c| !c.agrees()).count(),
            derivatives: compared.iter().map(|c| c.derivatives).sum(),
            worst: worst.map_or(0.0, |c| c.worst),
            worst_seed: worst.map(|c| c.seed),
            worst_at: worst.map_or(String::new(), |c| c.worst_at.clone()),
            checks,
        }
    }

    /// The summary, as Markdown: the counts, the largest difference, every disagreement.
    pub fn markdown(&self) -> String {
        let worst = match self.worst_seed {
            Some(seed) => format!(
                "the largest |adjoint - DDM| is {:.1e} of its scale (seed {seed}, {})",
                self.worst, self.worst_at
            ),
            None => "nothing compared".to_string(),
        };
        let limit = match self.time_limit {
            Some(s) => format!(" and a time limit of {s} s on its primal analysis"),
            None => String::new(),
        };
        let out_of_time = match self.time_limit {
            Some(_) => ", or one ran out of time",
            None => "",
        };
        let mut s = format!(
            "DDM against the adjoint on {} scenes (`fricsens fuzz --methods`, each method with \
             its default settings{limit}): {} compared, {} skipped (both methods failed in the primal \
             analysis{out_of_time}), {} derivatives at every increment, the flagged ones' one-sided \
             sides included; {worst}; {} scene(s) disagree (over {TOLERANCE:e} of the scale, or \
             in what the two tables hold).\n",
            self.scenes, self.compared, self.skipped, self.derivatives, self.disagreeing,
        );
        for c in self.checks.iter().filter(|c| !c.agrees()) {
            s.push_str(&format!(
                "\n- seed {}: {}",
                c.seed,
                c.disagreements.join("; ")
            ));
        }
        s.push('\n');
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensitivity::SensitivityError;
    use crate::solver::Results;

    fn out_of_time() -> AnalysisError {
        AnalysisError::TimeLimit {
            increment: 3,
            time: 0.5,
            seconds: 120.0,
            partial: Box::new(Results::default()),
        }
    }

    /// A failure of a sensitivity method (not of the primal analysis).
    fn method_failure() -> AnalysisError {
        SensitivityError::NoIncrementAt { time: 0.5 }.into()
    }

    /// A Newton failure of the primal analysis.
    fn diverged() -> AnalysisError {
        AnalysisError::Diverged {
            increment: 3,
            time: 0.5,
            step: 0.125,
            cutbacks: 10,
            residuals: vec![1.0, 2.0],
            reason: "iteration limit".to_string(),
            partial: Box::new(Results::default()),
        }
    }

    fn ran() -> Result<SensitivityResults, AnalysisError> {
        Ok(SensitivityResults::default())
    }

    /// DDM out of time: skipped without running the adjoint. The adjoint out of time: skipped
    /// where DDM ran or failed in the primal analysis (DDM's failure the reason then), a
    /// disagreement where DDM failed otherwise. Both failed in the primal: skipped; one of
    /// them alone, or either otherwise: a disagreement. Both ran: compared.
    #[test]
    fn a_method_out_of_time_skips_the_scene_unless_the_other_failed_otherwise() {
        let skip = |v: Verdict| match v {
            Verdict::Skip(why) => why,
            other => panic!("not skipped: {other:?}"),
        };
        let why = skip(verdict(Err(out_of_time()), || -> Result<_, _> {
            panic!("the adjoint runs after DDM ran out of time")
        }));
        assert!(
            why.starts_with("DDM: ") && why.contains("time limit"),
            "{why}"
        );
        let why = skip(verdict(ran(), || Err(out_of_time())));
        assert!(
            why.starts_with("adjoint: ") && why.contains("time limit"),
            "{why}"
        );
        let why = skip(verdict(Err(diverged()), || Err(out_of_time())));
        assert!(why.contains("iteration limit"), "{why}");
        let why = skip(verdict(Err(diverged()), || Err(diverged())));
        assert!(why.contains("iteration limit"), "{why}");
        assert!(matches!(
            verdict(Err(diverged()), ran),
            Verdict::Disagree(_)
        ));
        assert!(matches!(
            verdict(ran(), || Err(diverged())),
            Verdict::Disagree(_)
        ));
        assert!(matches!(
            verdict(Err(method_failure()), || Err(out_of_time())),
            Verdict::Disagree(_)
        ));
        assert!(matches!(
            verdict(ran(), || Err(method_failure())),
            Verdict::Disagree(_)
        ));
        assert!(matches!(
            verdict(Err(method_failure()), ran),
            Verdict::Disagree(_)
        ));
        assert!(matches!(verdict(ran(), ran), Verdict::Compare(..)));
    }

    /// A scene the methods run out of time on is skipped, not counted as a disagreement,
    /// and the campaign's summary says what the limit was.
    #[test]
    fn a_scene_out_of_time_is_skipped_not_a_disagreement() {
        let c = check(0, &crate::studies::fuzz::generate(0), Some(0.0));
        assert!(c.agrees(), "{:?}", c.disagreements);
        let why = c.skipped.clone().expect("skipped");
        assert!(
            why.starts_with("DDM: ") && why.contains("time limit"),
            "{why}"
        );
        let campaign = Campaign::of(vec![c], Some(0.0));
        assert_eq!(
            (campaign.compared, campaign.skipped, campaign.disagreeing),
            (0, 1, 0)
        );
        let md = campaign.markdown();
        assert!(
            md.contains("a time limit of 0 s") && md.contains("or one ran out of time"),
            "{md}"
        );
    }

    /// An infinite time limit is none, as the analysis takes it: no "inf s" in the summary
    /// and no limit in methods.json; a finite one is kept.
    #[test]
    fn an_infinite_time_limit_is_none() {
        for limit in [None, Some(f64::INFINITY)] {
            let campaign = Campaign::of(Vec::new(), limit);
            assert_eq!(campaign.time_limit, None, "{limit:?}");
            let md = campaign.markdown();
            assert!(
                !md.contains("time limit") && !md.contains("out of time"),
                "{md}"
            );
            let json = serde_json::to_value(&campaign).unwrap();
            assert_eq!(json.get("time_limit"), Some(&serde_json::Value::Null));
        }
        assert_eq!(
            Campaign::of(Vec::new(), Some(120.0)).time_limit,
            Some(120.0)
        );
    }
}
