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
    let res = solver.run(&RunOptions::default(), &mut Watched(&mut engines, watch))?;
    // the engines' own work and their floor probes are not the primal run's
    let inline: f64 = engines
        .engines
        .iter()
        .map(|e| {
            let c = &e.results.cost;
            c.wall_seconds + c.floor_seconds + c.anatomy_seconds + c.fields_seconds
        })
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
    fdm_sweep(model, params, betas, central, false, &mut |_| {})
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
    watch: &mut dyn FnMut(&Converged<'_>),
) -> Result<(Results, Vec<SensitivityResults>), AnalysisError> {
    let (nominal, base) = fdm_nominal(model, watch)?;
    let base_fields = if fields {
        let t = Instant::now();
        let f = fields_at_times(model, &nominal, &base.times)?;
        (f, t.elapsed().as_secs_f64())
    } else {
        (Vec::new(), 0.0)
    };
    let jobs = fdm_jobs(params.len(), betas.len(), central);
    let runs = run_reruns(model, params, betas, &base.times, &jobs, fields);
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

/// The nominal run of an FDM sweep and what every rerun is compared with.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FdmBase {
    /// The nominal run's increment times (cut-back ones included): the reruns take the same.
    pub times: Vec<f64>,
    /// `[i][r]`: response `r` at `times[i]`.
    pub values: Vec<Vec<f64>>,
    /// Wall time of the nominal run (s).
    pub primal_seconds: f64,
}

fn fdm_nominal(
    model: &Model,
    watch: &mut dyn FnMut(&Converged<'_>),
) -> Result<(Results, FdmBase), AnalysisError> {
    let t0 = Instant::now();
    let mut solver = Solver::new(model)?;
    let nominal = solver.run(&RunOptions::default(), &mut Watched(&mut NoObserver, watch))?;
    let primal_seconds = t0.elapsed().as_secs_f64();
    let times: Vec<f64> = nominal.times[1..].to_vec();
    let values = responses_at(model, &nominal, &times)?;
    Ok((
        nominal,
        FdmBase {
            times,
            values,
            primal_seconds,
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
                let r = Solver::new(&m)?.run(&RunOptions::default(), &mut NoObserver)?;
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
    let (_, base) = fdm_nominal(model, &mut |_| {})?;
    let all = fdm_jobs(params.len(), betas.len(), central);
    let mine: Vec<usize> = (0..all.len()).filter(|j| shard.takes(*j)).collect();
    let jobs: Vec<_> = mine.iter().map(|j| all[*j]).collect();
    let runs = run_reruns(model, params, betas, &base.times, &jobs, false);
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
}
