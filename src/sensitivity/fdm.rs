//! FDM: finite differences of complete reruns, and the sweeps of every method across
//! perturbation sizes that the validation harness runs.

use super::*;
use crate::model::Model;
use crate::solver::{AnalysisError, Converged, NoObserver, Observer, Results, RunOptions, Solver};
use std::time::Instant;

/// The model with parameter `p` set to `b_0 + db`.
pub(super) fn perturbed_model(model: &Model, p: &Parameter, db: f64) -> Model {
    let mut m = model.clone();
    for t in &p.targets {
        m.set_param(*t, p.value + db);
    }
    m
}

/// The fields ([`crate::fields`]) of a run of `model` at each of the nominal `times`.
fn fields_at_times(
    model: &Model,
    res: &Results,
    times: &[f64],
) -> Result<Vec<Vec<crate::fields::Field<f64>>>, AnalysisError> {
    let asm = crate::assembly::Assembler::new(model, &[])?;
    times
        .iter()
        .map(|t| {
            let k = res
                .increment_at(*t)
                .ok_or_else(|| AnalysisError::from(SensitivityError::NoIncrementAt { time: *t }))?;
            fields::results_fields(model, &asm, res, k)
        })
        .collect()
}

/// Response values at the nominal increment times of a run (cutback sub-increments skipped).
pub(super) fn responses_at(
    model: &Model,
    res: &Results,
    times: &[f64],
) -> Result<Vec<Vec<f64>>, AnalysisError> {
    let mut out = Vec::with_capacity(times.len());
    for t in times {
        let k = res
            .increment_at(*t)
            .ok_or_else(|| AnalysisError::from(SensitivityError::NoIncrementAt { time: *t }))?;
        out.push(
            (0..model.responses.len())
                .map(|r| res.response_value(model, r, k))
                .collect(),
        );
    }
    Ok(out)
}

/// The relative residual `|R_free| / F_ref` Newton reached at each of `times` in a run (at a
/// time the run did not take, the largest it reached).
fn reached_at(res: &Results, times: &[f64]) -> Vec<f64> {
    let relative = |r: &crate::solver::IncrementRecord| {
        let last = r.residuals.last().copied().unwrap_or(0.0);
        if r.reference_force > 0.0 {
            last / r.reference_force
        } else {
            last
        }
    };
    let worst = res.records.iter().map(relative).fold(0.0, f64::max);
    times
        .iter()
        .map(|t| {
            res.increment_at(*t)
                .filter(|k| *k >= 1)
                .and_then(|k| res.records.get(k - 1))
                .map_or(worst, relative)
        })
        .collect()
}

/// Several in-line engines observing one primal run. An engine that fails (e.g. an SDM
/// perturbation so large that the perturbed geometry is degenerate) is stopped and its error
/// kept; the primal run and the other engines go on.
pub(super) struct Engines<'a> {
    engines: Vec<Engine<'a>>,
    errors: Vec<Option<AnalysisError>>,
}

impl Observer for Engines<'_> {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        for (e, err) in self.engines.iter_mut().zip(&mut self.errors) {
            if err.is_none() {
                if let Err(x) = e.converged(c) {
                    e.results.failure =
                        Some(format!("increment {} (t = {}): {x}", c.index, c.time));
                    *err = Some(x);
                }
            }
        }
        Ok(())
    }
}

/// In-line methods (SDM, SDM central, DDM) at several settings — a perturbation sweep — on
/// one primal run: each engine does its own work after every converged increment and keeps
/// its own cost; `primal_seconds` of every result is the primal run alone.
pub fn run_inline_sweep(
    model: &Model,
    params: &[Parameter],
    settings: &[Settings],
) -> Result<(Results, Vec<SensitivityResults>), AnalysisError> {
    if let Some(s) = settings.iter().find(|s| !s.method.is_inline()) {
        return Err(SensitivityError::NotInline {
            method: s.method.name(),
        }
        .into());
    }
    let (res, out, _) = inline_sweep(model, params, settings, &mut |_| {})?;
    Ok((res, out))
}

/// [`run_inline_sweep`] with each engine's error, if it failed.
#[allow(clippy::type_complexity)]
pub(super) fn inline_sweep(
    model: &Model,
    params: &[Parameter],
    settings: &[Settings],
    watch: &mut dyn FnMut(&Converged<'_>),
) -> Result<(Results, Vec<SensitivityResults>, Vec<Option<AnalysisError>>), AnalysisError> {
    let mut engines = Engines {
        engines: settings
            .iter()
            .map(|s| Engine::new(model, params, s.clone()))
            .collect(),
        errors: settings.iter().map(|_| None).collect(),
    };
    let mut solver = Solver::new(model)?;
    // one run for every setting: the shortest limit asked
    let opts = RunOptions::limited(
        (settings.iter())
            .filter_map(|s| s.time_limit)
            .reduce(f64::min),
    );
    let res = solver.run(&opts, &mut Watched(&mut engines, watch))?;
    // the engines' own work and their floor probes are not the primal run's
    let inline: f64 = engines
        .engines
        .iter()
        .map(|e| own_seconds(&e.results))
        .sum();
    let out = engines
        .engines
        .into_iter()
        .map(|e| {
            let mut s = e.results;
            s.primal_seconds = res.cost.wall_seconds - inline;
            s
        })
        .collect();
    Ok((res, out, engines.errors))
}

/// An in-line engine's own time in a primal run it observed: its work, its floor probes, its
/// anatomy and fields.
fn own_seconds(s: &SensitivityResults) -> f64 {
    let c = &s.cost;
    c.wall_seconds + c.floor_seconds + c.anatomy_seconds + c.fields_seconds
}

/// One in-line method (DDM, SDM, SDM central) as [`run_sensitivity_watched`] runs it, but
/// keeping what it computed when the analysis stops: on failure, the error with the
/// sensitivities of the increments that converged (the engine's failure stops the run at once,
/// with the same error). The Python package's partial results.
#[allow(clippy::type_complexity)]
pub fn run_inline_keeping(
    model: &Model,
    params: &[Parameter],
    settings: &Settings,
    watch: &mut dyn FnMut(&Converged<'_>),
) -> Result<(Results, SensitivityResults), Box<(AnalysisError, SensitivityResults)>> {
    let mut engine = Engine::new(model, params, settings.clone());
    let opts = RunOptions::limited(settings.time_limit);
    let run = Solver::new(model).and_then(|mut s| s.run(&opts, &mut Watched(&mut engine, watch)));
    let mut sens = engine.results;
    let primal = |wall: f64, s: &SensitivityResults| wall - own_seconds(s);
    match run {
        Ok(res) => {
            sens.primal_seconds = primal(res.cost.wall_seconds, &sens);
            if let Some(why) = &sens.failure {
                let e = SensitivityError::Failed {
                    method: settings.method.name(),
                    reason: why.clone(),
                };
                return Err(Box::new((e.into(), sens)));
            }
            Ok((res, sens))
        }
        Err(e) => {
            sens.primal_seconds = e
                .partial()
                .map_or(f64::NAN, |p| primal(p.cost.wall_seconds, &sens));
            Err(Box::new((e, sens)))
        }
    }
}

/// Finite differences at several perturbation sizes from one nominal run: the reruns at
/// `b + db` serve forward and central differences, those at `b - db` central ones; they run
/// in parallel. Returns `[forward, central]` per beta when `central` is set, else forward only.
/// A rerun that fails fails only the differences that need it: their `failure` says why.
pub fn run_fdm_sweep(
    model: &Model,
    params: &[Parameter],
    betas: &[f64],
    central: bool,
) -> Result<(Results, Vec<SensitivityResults>), AnalysisError> {
    fdm_sweep(model, params, betas, central, false, None, &mut |_| {})
}

/// An observer followed by a look at each converged increment (a progress display).
struct Watched<'a, O: Observer>(&'a mut O, &'a mut dyn FnMut(&Converged<'_>));

impl<O: Observer> Observer for Watched<'_, O> {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), AnalysisError> {
        self.0.converged(c)?;
        (self.1)(c);
        Ok(())
    }
}

/// [`run_fdm_sweep`], `watch` seeing each converged increment of the nominal run.
pub(super) fn fdm_sweep(
    model: &Model,
    params: &[Parameter],
    betas: &[f64],
    central: bool,
    fields: bool,
    time_limit: Option<f64>,
    watch: &mut dyn FnMut(&Converged<'_>),
) -> Result<(Results, Vec<SensitivityResults>), AnalysisError> {
    let (nominal, base) = fdm_nominal(model, time_limit, watch)?;
    let base_fields = if fields {
        let t = Instant::now();
        let f = fields_at_times(model, &nominal, &base.times)?;
        (f, t.elapsed().as_secs_f64())
    } else {
        (Vec::new(), 0.0)
    };
    let jobs = fdm_jobs(params.len(), betas.len(), central);
    let runs = run_reruns(model, params, betas, &base.times, &jobs, fields, time_limit);
    let out = assemble(
        model,
        params,
        betas,
        central,
        &base,
        &base_fields,
        &jobs,
        runs,
    );
    Ok((nominal, out))
}

/// `--beta auto` for FDM and FDM central (the rule of SDM's `auto`, on reruns): the reruns at every
/// step of a ladder a decade apart ([`FDM_FORWARD_LADDER`], [`FDM_CENTRAL_LADDER`]); at every
/// increment and for each parameter the step taken is one of the two neighbouring steps whose
/// differences agree best over the responses sensitive to it (Stepleman & Winarsky's plateau;
/// the larger, or the smaller where the pair's difference is the larger's truncation:
/// the `auto` module's `better_of_pair`), and the error bar is twice the sum of the difference
/// from the next step down (a tenth of the chosen one, already run; the step above where the
/// chosen one is the ladder's last) and the noise both steps' reruns actually carry: the
/// relative residual Newton reached in each run at that increment, times
/// the response's size over the history, over the step (not the tolerance, which the last
/// quadratic Newton step usually beats by orders). A chosen step whose reruns are not in the
/// nominal run's states at an increment (contact states, Gauss points' branches) differences
/// across a switch there, and gives way to the steps whose reruns are. Costs a rerun (two,
/// central) per step of the ladder and parameter.
pub fn fdm_auto(
    model: &Model,
    params: &[Parameter],
    central: bool,
    time_limit: Option<f64>,
    watch: &mut dyn FnMut(&Converged<'_>),
) -> Result<(Results, SensitivityResults), AnalysisError> {
    let ladder: &[f64] = if central {
        &FDM_CENTRAL_LADDER
    } else {
        &FDM_FORWARD_LADDER
    };
    let (nominal, base) = fdm_nominal(model, time_limit, watch)?;
    let jobs = fdm_jobs(params.len(), ladder.len(), central);
    let runs = run_reruns(model, params, ladder, &base.times, &jobs, false, time_limit);
    // reached[b][k][side]
    let (np, nb, nr, ni) = (
        params.len(),
        ladder.len(),
        model.responses.len(),
        base.times.len(),
    );
    let mut reached = vec![vec![[None, None]; np]; nb];
    let mut held = vec![vec![[None, None]; np]; nb];
    for (&(b, k, sign), r) in jobs.iter().zip(&runs) {
        let side = usize::from(sign < 0.0);
        reached[b][k][side] = r.as_ref().ok().map(|r| r.reached.clone());
        held[b][k][side] = r.as_ref().ok().map(|r| r.states.clone());
    }
    let sweep = assemble(
        model,
        params,
        ladder,
        central,
        &base,
        &(Vec::new(), 0.0),
        &jobs,
        runs,
    );
    // [forward, central] per step: the method asked for
    let probes: Vec<&SensitivityResults> = if central {
        sweep.iter().skip(1).step_by(2).collect()
    } else {
        sweep.iter().collect()
    };
    let size: Vec<f64> = (0..nr)
        .map(|r| base.values.iter().map(|v| v[r].abs()).fold(0.0, f64::max))
        .collect();
    let d = |b: usize, i: usize, r: usize, k: usize| probes[b].increments[i].derivatives[r][k];
    // the noise of step b's difference at increment i, per unit size
    let noise = |b: usize, i: usize, k: usize| -> f64 {
        let db = params[k].step(ladder[b]).abs();
        let rho =
            |side: usize| -> f64 { (reached[b][k][side].as_ref()).map_or(f64::INFINITY, |v| v[i]) };
        let other = if central { rho(1) } else { base.reached[i] };
        (rho(0) + other) / if central { 2.0 * db } else { db }
    };
    // whether step b's reruns of parameter k are in the nominal run's states at increment i
    // (a rerun that failed is not: its difference is not a number)
    let holds = |b: usize, i: usize, k: usize| -> bool {
        (0..if central { 2 } else { 1 })
            .all(|side| (held[b][k][side].as_ref()).is_some_and(|s| s.get(i) == base.states.get(i)))
    };
    let mut out = SensitivityResults {
        method: Some(if central {
            Method::FdmCentral
        } else {
            Method::Fdm
        }),
        beta: f64::NAN,
        parameters: params.iter().map(|p| p.name.clone()).collect(),
        responses: model.responses.iter().map(|r| r.name.clone()).collect(),
        primal_seconds: base.primal_seconds,
        ..Default::default()
    };
    for p in &probes {
        out.cost.wall_seconds += p.cost.wall_seconds;
        out.cost.primal_reruns += p.cost.primal_reruns;
    }
    let failures: Vec<&str> = probes.iter().filter_map(|p| p.failure.as_deref()).collect();
    for i in 0..ni {
        let mut inc = IncrementSensitivity {
            increment: i + 1,
            time: base.times[i],
            values: base.values[i].clone(),
            derivatives: vec![vec![f64::NAN; np]; nr],
            error_bars: vec![vec![f64::INFINITY; np]; nr],
            roundoff: vec![vec![false; np]; nr],
            rerun_substeps: vec![false; np],
            betas: vec![f64::NAN; np],
            ..Default::default()
        };
        for (k, p) in params.iter().enumerate() {
            // each sensitive response's largest probe; a probe that failed is NaN. A
            // response is insensitive where every probe is within the noise it expects of
            // zero: a derivative that is zero (a reaction fixed by equilibrium) has nothing
            // but noise, which grows down the ladder, and its disagreements, the smallest at
            // the largest steps, chose the step for every response (the cantilever's tip
            // deflection: 1e-3 chosen, an error of 9e-4 against the sweep's best 2e-7).
            // Every probe, not any as SDM's rule has it: the reruns' noise at the smallest
            // steps is above many a genuine derivative
            let b0 = p.value.abs().max(1.0);
            let scales: Vec<Option<f64>> = (0..nr)
                .map(|r| {
                    let (mut s, mut zero) = (0.0f64, true);
                    for b in 0..nb {
                        let v = d(b, i, r, k).abs();
                        if v.is_finite() {
                            s = s.max(v);
                            zero &= v <= auto::NOISE_AGREEMENT * noise(b, i, k) * size[r];
                        }
                    }
                    (s > 0.0 && !zero && b0 * s >= 1e-9 * base.values[i][r].abs()).then_some(s)
                })
                .collect();
            let disagreement = |b: usize| {
                (0..nr)
                    .filter_map(|r| {
                        let s = scales[r]?;
                        let x = (d(b, i, r, k) - d(b + 1, i, r, k)).abs() / s;
                        Some(if x.is_nan() { f64::INFINITY } else { x })
                    })
                    .fold(0.0, f64::max)
            };
            let Some(j) = (0..nb - 1)
                .map(|b| (b, disagreement(b)))
                .filter(|(_, x)| x.is_finite())
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(b, _)| b)
                .or_else(|| (0..nb).find(|b| d(*b, i, 0, k).is_finite()))
            else {
                continue; // every step failed: NaN, with the failures said
            };
            // a step whose reruns leave the nominal run's states at this increment (stick
            // where it slips, plastic where it is elastic) differences across a switch: their
            // secant can agree with its neighbour's, a false plateau (Jenkins where the slide
            // reverses: the reruns at 0.1 and 0.01 of mu agree to 1e-4 on 1e-5 and 1e-4
            // where the derivative is 1). The rule then keeps to the steps that hold them:
            // their plateau, else the largest of them. (Only where the chosen step's reruns
            // leave them: a chosen step that holds them keeps its value, on the nominal
            // branches, whatever its shadow's; the bar then measures the switch.)
            let holding: Vec<bool> = (0..nb).map(|b| holds(b, i, k)).collect();
            let j = if holding[j] || !holding.contains(&true) {
                j
            } else {
                (0..nb - 1)
                    .filter(|&b| holding[b] && holding[b + 1])
                    .map(|b| (b, disagreement(b)))
                    .filter(|(_, x)| x.is_finite())
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .map_or_else(|| holding.iter().position(|h| *h).unwrap_or(j), |(b, _)| b)
            };
            // the better of the pair, where the smaller step holds the states too
            let last_roundoff = (0..nr)
                .filter_map(|r| Some(noise(nb - 1, i, k) * size[r] / scales[r]?))
                .fold(0.0, f64::max);
            let order = if central { 2 } else { 1 };
            // (a pair whose reruns leave the states is no evidence of truncation)
            let evidence = |b: usize| {
                if holding[b] && holding[b + 1] || !holding.contains(&true) {
                    disagreement(b)
                } else {
                    f64::INFINITY
                }
            };
            let j = match auto::better_of_pair(evidence, j, nb - 1, order, last_roundoff) {
                n if holding[n] || !holding.contains(&true) => n,
                _ => j,
            };
            let shadow = if j + 1 < nb {
                j + 1
            } else {
                j.saturating_sub(1)
            };
            inc.betas[k] = ladder[j];
            inc.rerun_substeps[k] = probes[j].increments[i].rerun_substeps[k];
            for (r, size_r) in size.iter().enumerate() {
                let v = d(j, i, r, k);
                inc.derivatives[r][k] = v;
                inc.roundoff[r][k] = probes[j].increments[i].roundoff[r][k];
                let gap = (v - d(shadow, i, r, k)).abs();
                // the chosen error is at most the gap plus the shadow's, whose noise is signed
                inc.error_bars[r][k] =
                    auto::bar(gap, (noise(j, i, k) + noise(shadow, i, k)) * size_r);
            }
        }
        out.increments.push(inc);
    }
    if out
        .increments
        .iter()
        .all(|inc| inc.betas.iter().all(|b| b.is_nan()))
        && !failures.is_empty()
    {
        out.failure = Some(failures.join("; "));
    }
    Ok((nominal, out))
}

/// FDM's `--beta auto` ladder (forward): relative steps a decade apart, from where truncation
/// dominates to where the reruns' Newton noise does. It starts at 1e-1, as SDM's does: where a
/// parameter enters linearly, the largest step has the least noise (the J2 bar's yield stress:
/// 2.6e-14 at 1e-1, 6.0e-13 at 1e-2, the ladder's top before).
pub const FDM_FORWARD_LADDER: [f64; 8] = [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8];

/// FDM central's `--beta auto` ladder. It goes down to 1e-8: where the nominal state lies
/// within a step of a stick/slip switch, only steps below it are free of the switch, and the
/// step taken needs a neighbour below it that agrees (Jenkins where it starts to slip back:
/// 3.0e-6 at 1e-6, 1.3e-8 at 1e-7, 8.7e-9 at 1e-8).
pub const FDM_CENTRAL_LADDER: [f64; 8] = [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8];

/// The nominal run of an FDM sweep and what every rerun is compared with.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FdmBase {
    /// The nominal run's increment times (cut-back ones included): the reruns take the same.
    pub times: Vec<f64>,
    /// `[i][r]`: response `r` at `times[i]`.
    pub values: Vec<Vec<f64>>,
    /// Wall time of the nominal run (s).
    pub primal_seconds: f64,
    /// `[i]`: the relative residual `|R_free| / F_ref` Newton reached at `times[i]`.
    #[serde(default)]
    pub reached: Vec<f64>,
    /// `[i]`: the signature of the states at `times[i]` (the contact states and the Gauss
    /// points' branches, hashed). Read by `--beta auto` alone, which is not sharded: not
    /// written into a share's partial result.
    #[serde(skip)]
    pub states: Vec<u64>,
}

/// A signature of a run's states at each of `times`: its hitting nodes' contact states (open,
/// closed, stick, slip) and its Gauss points' branches (elastic, plastic), hashed (FNV-1a; 0
/// at a time the run did not take, which no run's states give but by a collision). Two runs
/// with equal signatures at a time have every node in the same contact state and every
/// Gauss point on the same branch there, up to a hash collision; the contact faces and the
/// slip directions are not compared. Needs the run's states kept (`RunOptions::keep_states`,
/// the default).
fn states_at(res: &Results, times: &[f64]) -> Vec<u64> {
    times
        .iter()
        .map(|t| {
            let Some(k) = res.increment_at(*t) else {
                return 0;
            };
            let mut h = 0xcbf2_9ce4_8422_2325_u64;
            let mut eat = |b: u8| {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0100_0000_01b3);
            };
            for c in res.contact.get(k).map_or(&[][..], |e| &e.choice[..]) {
                eat(c.state as u8);
            }
            eat(0xff);
            for b in res.branches.get(k).map_or(&[][..], |v| &v[..]) {
                eat(*b as u8);
            }
            h
        })
        .collect()
}

fn fdm_nominal(
    model: &Model,
    time_limit: Option<f64>,
    watch: &mut dyn FnMut(&Converged<'_>),
) -> Result<(Results, FdmBase), AnalysisError> {
    let t0 = Instant::now();
    let mut solver = Solver::new(model)?;
    let opts = RunOptions::limited(time_limit);
    let nominal = solver.run(&opts, &mut Watched(&mut NoObserver, watch))?;
    let primal_seconds = t0.elapsed().as_secs_f64();
    let times: Vec<f64> = nominal.times[1..].to_vec();
    let values = responses_at(model, &nominal, &times)?;
    let reached = reached_at(&nominal, &times);
    let states = states_at(&nominal, &times);
    Ok((
        nominal,
        FdmBase {
            times,
            values,
            primal_seconds,
            reached,
            states,
        },
    ))
}

/// The reruns of an FDM sweep, `(beta index, parameter, sign)`, in a fixed order: the
/// order [`Shard`] deals them out in.
fn fdm_jobs(np: usize, nb: usize, central: bool) -> Vec<(usize, usize, f64)> {
    let signs: &[f64] = if central { &[1.0, -1.0] } else { &[1.0] };
    (0..nb)
        .flat_map(|b| (0..np).flat_map(move |k| signs.iter().map(move |s| (b, k, *s))))
        .collect()
}

/// Run the reruns `jobs` in parallel; a rerun that fails gives why, naming its parameter and
/// side.
fn run_reruns(
    model: &Model,
    params: &[Parameter],
    betas: &[f64],
    times: &[f64],
    jobs: &[(usize, usize, f64)],
    fields: bool,
    time_limit: Option<f64>,
) -> Vec<Result<Rerun, String>> {
    use rayon::prelude::*;
    // the reruns follow the nominal run's increments, cut-back ones included, so that every
    // difference is taken between states of the same load level
    let mut model = model.clone();
    model.times = times.to_vec();
    let model = &model;
    jobs.par_iter()
        .map(|&(b, k, sign)| {
            let t = Instant::now();
            let p = &params[k];
            let run = || -> Result<Rerun, AnalysisError> {
                let m = perturbed_model(model, p, sign * p.step(betas[b]));
                let r = Solver::new(&m)?.run(&RunOptions::limited(time_limit), &mut NoObserver)?;
                // the first time the rerun needed a sub-increment the nominal run did not take
                let substep_from = r.times[1..]
                    .iter()
                    .find(|t| {
                        !times
                            .iter()
                            .any(|n| (*n - **t).abs() <= 1e-12 * n.abs().max(1.0))
                    })
                    .copied();
                Ok(Rerun {
                    values: responses_at(model, &r, times)?,
                    reached: reached_at(&r, times),
                    states: states_at(&r, times),
                    fields: if fields {
                        fields_at_times(&m, &r, times)?
                    } else {
                        Vec::new()
                    },
                    seconds: t.elapsed().as_secs_f64(),
                    substep_from,
                })
            };
            run().map_err(|e| {
                let side = usize::from(sign < 0.0);
                format!("rerun with {} {} beta: {e}", p.name, ["+", "-"][side])
            })
        })
        .collect()
}

/// One share of an FDM sweep's reruns (`--shard K/N`): the jobs whose position in the
/// sweep's fixed order is `K - 1` modulo `N`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Shard {
    /// `K`, from 1.
    pub index: usize,
    /// `N`.
    pub count: usize,
}

impl Shard {
    /// `K/N` with `1 <= K <= N`.
    pub fn parse(text: &str) -> Result<Shard, String> {
        let bad = || format!("--shard takes K/N with 1 <= K <= N, got `{text}`");
        let (k, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            k.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// Whether job `j` (in the sweep's order) is this share's.
    pub fn takes(self, j: usize) -> bool {
        j % self.count == self.index - 1
    }
}

/// What one share of an FDM sweep computed, to be merged with the others' ([`merge_fdm`]).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct FdmPartial {
    /// Which share.
    pub shard: Shard,
    /// The parameters' names, in order.
    pub params: Vec<String>,
    /// The relative perturbations.
    pub betas: Vec<f64>,
    /// Central differences (reruns at both signs).
    pub central: bool,
    /// The nominal run (every share runs it: the reruns take its increments).
    pub base: FdmBase,
    /// `(job, its rerun or why it failed)` for this share's jobs.
    pub reruns: Vec<(usize, Result<Rerun, String>)>,
}

/// Run share `shard` of the FDM sweep of `params` at `betas`: the nominal run and this
/// share's reruns.
pub fn run_fdm_shard(
    model: &Model,
    params: &[Parameter],
    betas: &[f64],
    central: bool,
    shard: Shard,
) -> Result<FdmPartial, AnalysisError> {
    let (_, base) = fdm_nominal(model, None, &mut |_| {})?;
    let all = fdm_jobs(params.len(), betas.len(), central);
    let mine: Vec<usize> = (0..all.len()).filter(|j| shard.takes(*j)).collect();
    let jobs: Vec<_> = mine.iter().map(|j| all[*j]).collect();
    let runs = run_reruns(model, params, betas, &base.times, &jobs, false, None);
    Ok(FdmPartial {
        shard,
        params: params.iter().map(|p| p.name.clone()).collect(),
        betas: betas.to_vec(),
        central,
        base,
        reruns: mine.into_iter().zip(runs).collect(),
    })
}

/// Why shares do not merge.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MergeError {
    /// Nothing to merge.
    #[error("no partial results to merge")]
    Empty,
    /// Two shares of different sweeps (parameters, betas, differences, share count or
    /// nominal run).
    #[error("shard {a} and shard {b} are not of the same sweep: their {what} differ")]
    Mismatch {
        /// One share.
        a: String,
        /// The other.
        b: String,
        /// What differs.
        what: &'static str,
    },
    /// A rerun no share ran, or two ran.
    #[error("rerun {job} of {of}: {why}")]
    Coverage {
        /// The job's position in the sweep.
        job: usize,
        /// The sweep's number of jobs.
        of: usize,
        /// Missing, or run twice.
        why: &'static str,
    },
    /// The shares' parameters are not the model's.
    #[error("parameter {0}: not in the shares' sweep, or in another order")]
    Parameter(String),
}

/// Merge the shares of one FDM sweep into the results [`run_fdm_sweep`] gives (the same
/// numbers bit for bit: the same reruns, differenced in the same order).
pub fn merge_fdm(
    model: &Model,
    params: &[Parameter],
    partials: &[FdmPartial],
) -> Result<Vec<SensitivityResults>, MergeError> {
    let first = partials.first().ok_or(MergeError::Empty)?;
    let name = |p: &FdmPartial| format!("{}/{}", p.shard.index, p.shard.count);
    for p in partials {
        let what = if p.params != first.params {
            Some("parameters")
        } else if p
            .betas
            .iter()
            .map(|b| b.to_bits())
            .ne(first.betas.iter().map(|b| b.to_bits()))
        {
            Some("betas")
        } else if p.central != first.central {
            Some("difference (forward or central)")
        } else if p.shard.count != first.shard.count {
            Some("share counts")
        } else if p.base.times != first.base.times || p.base.values != first.base.values {
            Some("nominal runs")
        } else {
            None
        };
        if let Some(what) = what {
            return Err(MergeError::Mismatch {
                a: name(first),
                b: name(p),
                what,
            });
        }
    }
    // the model's parameters must be the sweep's, in its order
    let names: Vec<&str> = params.iter().map(|p| p.name.as_str()).collect();
    if names != first.params {
        let differs = (0..names.len().max(first.params.len()))
            .find(|&i| names.get(i).copied() != first.params.get(i).map(|n| n.as_str()))
            .expect("the lists differ");
        let name = names
            .get(differs)
            .copied()
            .unwrap_or(&first.params[differs]);
        return Err(MergeError::Parameter(name.to_string()));
    }
    let jobs = fdm_jobs(params.len(), first.betas.len(), first.central);
    let mut runs: Vec<Option<Result<Rerun, String>>> = vec![None; jobs.len()];
    for (j, r) in partials.iter().flat_map(|p| p.reruns.iter()) {
        let slot = runs.get_mut(*j).ok_or(MergeError::Coverage {
            job: *j,
            of: jobs.len(),
            why: "not a rerun of this sweep",
        })?;
        if slot.is_some() {
            return Err(MergeError::Coverage {
                job: *j,
                of: jobs.len(),
                why: "run by two shares",
            });
        }
        *slot = Some(r.clone());
    }
    let runs = runs
        .into_iter()
        .enumerate()
        .map(|(job, r)| {
            r.ok_or(MergeError::Coverage {
                job,
                of: jobs.len(),
                why: "run by no share",
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let (betas, central) = (first.betas.clone(), first.central);
    Ok(assemble(
        model,
        params,
        &betas,
        central,
        &first.base,
        &(Vec::new(), 0.0),
        &jobs,
        runs,
    ))
}

/// The differences of an FDM sweep from its nominal run and its reruns (`runs[j]` of
/// `jobs[j]`).
#[allow(clippy::too_many_arguments)]
#[allow(clippy::type_complexity)]
fn assemble(
    model: &Model,
    params: &[Parameter],
    betas: &[f64],
    central: bool,
    base_run: &FdmBase,
    base_fields: &(Vec<Vec<crate::fields::Field<f64>>>, f64),
    jobs: &[(usize, usize, f64)],
    runs: Vec<Result<Rerun, String>>,
) -> Vec<SensitivityResults> {
    let fields = !base_fields.0.is_empty();
    let (times, base, primal_seconds) =
        (&base_run.times, &base_run.values, base_run.primal_seconds);
    // reruns[b][k][0: plus, 1: minus]; a rerun that fails (a perturbed design that does not
    // converge, or whose geometry is degenerate) fails only the differences that need it
    let mut reruns: Vec<Vec<[RerunSlot; 2]>> = vec![vec![[None, None]; params.len()]; betas.len()];
    for (&(b, k, sign), r) in jobs.iter().zip(runs) {
        let side = usize::from(sign < 0.0);
        reruns[b][k][side] = Some(r);
    }
    let nr = model.responses.len();
    let np = params.len();
    let size: Vec<f64> = (0..nr)
        .map(|r| base.iter().map(|v| v[r].abs()).fold(0.0, f64::max))
        .collect();
    let mut out = Vec::new();
    for (b, &beta) in betas.iter().enumerate() {
        let variants: &[bool] = if central { &[false, true] } else { &[false] };
        for &is_central in variants {
            let mut derivs = vec![vec![vec![f64::NAN; np]; nr]; times.len()];
            let mut roundoff = vec![vec![vec![false; np]; nr]; times.len()];
            let mut substep_from = vec![f64::INFINITY; np];
            let mut failures = Vec::new();
            let mut field_derivs = vec![vec![Vec::new(); np]; if fields { times.len() } else { 0 }];
            let mut seconds = 0.0;
            let mut count = 0;
            for (k, p) in params.iter().enumerate() {
                let db = p.step(beta);
                let sides: &[usize] = if is_central { &[0, 1] } else { &[0] };
                let mut used = Vec::new();
                for &side in sides {
                    match reruns[b][k][side].as_ref().expect("every rerun ran") {
                        Ok(r) => used.push(r),
                        Err(why) => failures.push(why.clone()),
                    }
                }
                if used.len() < sides.len() {
                    continue; // this parameter's derivatives stay NaN
                }
                for r in &used {
                    seconds += r.seconds;
                    count += 1;
                    substep_from[k] = substep_from[k].min(r.substep_from.unwrap_or(f64::INFINITY));
                }
                for (i, f) in field_derivs.iter_mut().enumerate() {
                    f[k] = if is_central {
                        fields::difference(&used[0].fields[i], &used[1].fields[i], 2.0 * db)
                    } else {
                        fields::difference(&used[0].fields[i], &base_fields.0[i], db)
                    };
                }
                for i in 0..times.len() {
                    for r in 0..nr {
                        let delta = if is_central {
                            used[0].values[i][r] - used[1].values[i][r]
                        } else {
                            used[0].values[i][r] - base[i][r]
                        };
                        derivs[i][r][k] = delta / if is_central { 2.0 * db } else { db };
                        // each rerun's response is converged to the Newton tolerance relative
                        // to the response's size over the history (in practice much better:
                        // the last Newton steps are quadratic), so a difference below that
                        // tolerance itself is indistinguishable from convergence noise
                        roundoff[i][r][k] = (delta != 0.0
                            && delta.abs() < model.solver.force_tol * size[r])
                            || roundoff_dominated(db, p.value, f64::EPSILON);
                    }
                }
            }
            out.push(SensitivityResults {
                method: Some(if is_central {
                    Method::FdmCentral
                } else {
                    Method::Fdm
                }),
                beta,
                parameters: params.iter().map(|p| p.name.clone()).collect(),
                responses: model.responses.iter().map(|r| r.name.clone()).collect(),
                increments: times
                    .iter()
                    .enumerate()
                    .map(|(i, t)| IncrementSensitivity {
                        increment: i + 1,
                        time: *t,
                        values: base[i].clone(),
                        derivatives: derivs[i].clone(),
                        rerun_substeps: substep_from.iter().map(|f| *t >= *f).collect(),
                        roundoff: roundoff[i].clone(),
                        ..Default::default()
                    })
                    .collect(),
                cost: SensitivityCost {
                    wall_seconds: seconds,
                    primal_reruns: count,
                    fields_seconds: base_fields.1,
                    ..Default::default()
                },
                primal_seconds,
                failure: (!failures.is_empty()).then(|| failures.join("; ")),
                anatomy: Vec::new(),
                fields: field_derivs
                    .into_iter()
                    .zip(times.iter())
                    .enumerate()
                    .map(|(i, (derivatives, t))| fields::IncrementFields {
                        increment: i + 1,
                        time: *t,
                        derivatives,
                    })
                    .collect(),
            });
        }
    }
    out
}

/// A rerun of the FDM sweep once run: its responses, or why it failed.
type RerunSlot = Option<Result<Rerun, String>>;

/// One finite-difference rerun: responses (and fields, if asked) at the nominal times.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Rerun {
    values: Vec<Vec<f64>>,
    /// Not kept in a share's partial result (`--shard` writes no fields).
    #[serde(skip)]
    fields: Vec<Vec<crate::fields::Field<f64>>>,
    seconds: f64,
    substep_from: Option<f64>,
    /// `[i]`: the relative residual Newton reached at the nominal run's `times[i]`.
    #[serde(default)]
    reached: Vec<f64>,
    /// `[i]`: the signature of its states at the nominal run's `times[i]` ([`states_at`]);
    /// not kept in a share's partial result (`--beta auto` alone reads it).
    #[serde(skip)]
    states: Vec<u64>,
}
