//! The validation harness: every sensitivity method on every scene across a sweep of
//! perturbation sizes, compared with direct differentiation (the exact reference) and with
//! closed forms, and written up as a report (Markdown, SVG plots, CSV/JSON data).
//!
//! Error measure. For method `m` at perturbation `beta`, parameter `p`, response `r` and
//! increment `n`:
//!
//! ```text
//! e = |D_m - D_ddm| / max(|D_ddm|, floor * max_n' |D_ddm(n')|)
//! ```
//!
//! where the floor (default 1e-3) keeps responses whose sensitivity passes through zero from
//! exploding. The error of `(m, beta, p)` is the largest `e` over responses and over the
//! increments that are not flagged as non-differentiable (a yield, contact or stick/slip
//! transition at the converged state, where a finite perturbation may cross the kink).

use crate::response::ResponseKind;
use crate::scene::{
    builtin, leaf_spring, stacked_leaves, LeafSpringSpec, Scene, SceneError, StackedLeavesSpec,
};
use crate::sensitivity::{
    run_fdm_sweep, run_inline_sweep, Method, Parameter, SensitivityCost, SensitivityResults,
    Settings, TangentChoice,
};
use crate::solver::{AnalysisError, PrimalCost};
use crate::studies::plot::{write_svg, Figure, PlotError, Style};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What `fricsens validate` runs.
#[derive(Clone, Debug)]
pub struct ValidateOptions {
    /// Report directory.
    pub out: PathBuf,
    /// Perturbation sizes of the sweep.
    pub betas: Vec<f64>,
    /// Error floor as a fraction of the largest |sensitivity| over the history.
    pub floor: f64,
    /// Beta of the overlaid curves in the paper's figures.
    pub figure_beta: f64,
    /// Scenes whose finite-difference sweep (a full rerun per beta, parameter and sign) is
    /// thinned to [`REDUCED_FDM_BETAS`] (the in-line methods keep every beta).
    pub reduced_fdm: Vec<String>,
    /// Compare the shipped friction laws on the strip pull-out with this many elements
    /// ([`crate::studies::compare_laws`]); `None` leaves the section out.
    pub friction_laws: Option<usize>,
    /// Measure the batched cost on [`refined_leaf_spring`] too (one more primal run of about
    /// a minute) when the leaf spring is validated.
    pub refined_batch: bool,
}

/// The finite-difference betas of a scene in [`ValidateOptions::reduced_fdm`] (those of the
/// sweep that are among them): every other decade of the paper's range.
pub const REDUCED_FDM_BETAS: [f64; 4] = [1e-2, 1e-4, 1e-6, 1e-8];

impl Default for ValidateOptions {
    fn default() -> Self {
        ValidateOptions {
            out: PathBuf::from("validation"),
            betas: (1..=14).map(|k| 10f64.powi(-k)).collect(),
            floor: 1e-3,
            figure_beta: 1e-6,
            // primal ~20 s (leaf spring) and ~8 s on 21,000 unknowns (Hertz): 56 and 28
            // reruns for a full sweep
            reduced_fdm: vec!["leaf-spring".into(), "hertz".into()],
            friction_laws: Some(100),
            refined_batch: true,
        }
    }
}

/// Why validation failed.
#[derive(Debug, thiserror::Error)]
pub enum ValidateError {
    /// A scene could not be built.
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("scene '{scene}': {source}")]
    /// The analysis of a scene failed.
    Analysis {
        /// Name of the scene.
        scene: String,
        /// The failure.
        #[source]
        source: AnalysisError,
    },
    /// A figure could not be written.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// The friction-law comparison failed.
    #[error(transparent)]
    Laws(#[from] crate::studies::compare_laws::CompareLawsError),
    #[error("{path}: {source}")]
    /// A report file could not be written.
    Io {
        /// The file.
        path: String,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
}

/// The scenes of the default validation run: the paper's two examples and the oracle scenes.
/// `full`: the leaf spring on its paper-resolution mesh (100 x 4 elements, 30 load
/// increments) instead of the default 40 x 2 / 15.
pub fn default_scenes(full: bool) -> Vec<Scene> {
    let mut v = Vec::new();
    let named = |n: &str| builtin(n).expect("built-in scene");
    v.push(named("indentation"));
    let mut leaf = leaf_spring(&if full {
        LeafSpringSpec::full()
    } else {
        LeafSpringSpec::default()
    });
    leaf.name = "leaf-spring".into();
    v.push(leaf);
    v.push(stacked_leaves(&StackedLeavesSpec::default()));
    for n in [
        "strip-pullout",
        "uniaxial-j2",
        "uniaxial-svk",
        "klarbring-2dof",
        "jenkins",
        "hertz",
        "cantilever",
    ] {
        v.push(named(n));
    }
    // small kinematics: the tip does not shorten (its value and derivative are round-off)
    // and the clamp reaction is fixed by equilibrium, so only the deflection is studied
    let mut c = named("cantilever-small");
    c.responses.retain(|r| r.name() == "tip-deflection");
    v.push(c);
    v
}

/// Error of one method at one beta for one parameter.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ErrorRow {
    /// Scene name.
    pub scene: String,
    /// Method name (`sdm`, `sdm-central`, `fdm`, `fdm-central`).
    pub method: String,
    /// Relative perturbation size.
    pub beta: f64,
    /// Design parameter name.
    pub param: String,
    /// Largest relative error against DDM over responses and unflagged increments.
    pub error: f64,
    /// Wall time of the method's sensitivity work for all parameters / primal wall time.
    pub cost_ratio: f64,
    /// Why the method failed at this beta (the error is then NaN).
    pub failure: Option<String>,
    /// Increments left out because a finite-difference rerun took sub-increments the
    /// nominal run did not (see `IncrementSensitivity::rerun_substeps`).
    pub substep_excluded: usize,
    /// Increments whose value of this parameter's derivative (any response) is flagged
    /// round-off dominated (`IncrementSensitivity::roundoff`).
    pub roundoff_flagged: usize,
}

/// A closed-form check.
#[derive(Clone, Debug, serde::Serialize)]
pub struct OracleRow {
    /// Scene name.
    pub scene: String,
    /// What is checked.
    pub quantity: String,
    /// Closed-form value.
    pub expected: f64,
    /// Computed value (DDM run).
    pub got: f64,
    /// `|got - expected| / |expected|`.
    pub rel_error: f64,
    /// Largest accepted relative error.
    pub tolerance: f64,
    /// Whether `rel_error <= tolerance`.
    pub pass: bool,
}

/// Everything validated for one scene.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SceneValidation {
    /// Scene name.
    pub scene: String,
    /// The scene's description.
    pub description: String,
    /// Design parameters studied.
    pub params: Vec<String>,
    /// Number of unknowns of the global system.
    pub unknowns: usize,
    /// Number of load increments.
    pub increments: usize,
    /// Wall time of the primal analysis (s).
    pub primal_seconds: f64,
    /// Increments flagged non-differentiable (DDM).
    pub flagged: Vec<usize>,
    /// Wall time of DDM's sensitivity work / primal wall time.
    pub ddm_cost_ratio: f64,
    /// DDM solved with the last Newton factorization instead of the converged tangent: its
    /// cost over the primal, and its error against the reference per parameter.
    pub ddm_last_cost_ratio: f64,
    /// Error of DDM with the last factorization against the reference, per parameter.
    pub ddm_last_errors: Vec<f64>,
    /// SDM (forward, at the report's figure beta) solved with the last Newton factorization:
    /// its cost over the primal, and its error against the reference per parameter.
    pub sdm_last_cost_ratio: f64,
    /// Error of SDM with the last factorization against the reference, per parameter.
    pub sdm_last_errors: Vec<f64>,
    /// Error of every method, beta and parameter of the sweep.
    pub errors: Vec<ErrorRow>,
    /// Where the primal run's time went.
    pub primal_cost: PrimalCost,
    /// Newton iterations (linear solves) of the converged attempts.
    pub newton_iterations: usize,
    /// Where the in-line methods' time went: DDM and SDM (at the figure beta), each with the
    /// converged tangent and with the last factorization.
    pub ledger: Vec<(String, SensitivityCost)>,
    /// The floor of one parameter over the run ([`SensitivityCost::floor_seconds`]).
    pub floor_seconds: f64,
    /// The reference DDM results.
    #[serde(skip)]
    pub ddm: SensitivityResults,
    /// The results of the sweep (SDM and SDM central in line, then the FDM reruns).
    #[serde(skip)]
    pub sweeps: Vec<SensitivityResults>,
}

/// The whole validation.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Validation {
    /// Per-scene results.
    pub scenes: Vec<SceneValidation>,
    /// Closed-form checks.
    pub oracles: Vec<OracleRow>,
    /// Perturbation sizes of the sweep.
    pub betas: Vec<f64>,
    /// Error floor as a fraction of the largest |sensitivity| over the history.
    pub floor: f64,
    /// Wall time of the whole validation (s).
    pub wall_seconds: f64,
    /// Ten parameters of the leaf spring through one primal run, on its mesh and on the mesh
    /// refined twice along and through the leaves (when the leaf spring is validated).
    pub batched: Vec<BatchedCost>,
}

/// The leaf spring's ten design parameters of the batched cost measurement: friction,
/// material, shape (both leaves' length and thickness) and the tangential penalty.
pub const LEAF_BATCH: [&str; 10] = [
    "mu",
    "E",
    "nu",
    "sigma_y",
    "H",
    "upper.length.x",
    "upper.length.y",
    "lower.length.x",
    "lower.length.y",
    "block.eps_t",
];

/// Sensitivity cost of many parameters batched through one primal run: the pseudo-loads of
/// both SDM and DDM (one `Dual64` evaluation per parameter) go in one multi-column solve per
/// increment.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BatchedCost {
    /// Scene.
    pub scene: String,
    /// The parameters.
    pub params: Vec<String>,
    /// Wall time of the primal analysis (s).
    pub primal_seconds: f64,
    /// Method (with its tangent) and its wall time for all the parameters over the primal's.
    pub ratios: Vec<(String, f64)>,
    /// Method (with its tangent) and where its time went.
    pub ledger: Vec<(String, SensitivityCost)>,
    /// Converged increments of the primal run.
    pub increments: usize,
    /// The floor of one parameter over the run ([`SensitivityCost::floor_seconds`]).
    pub floor_seconds: f64,
    /// Unknowns of the linear system.
    pub unknowns: usize,
}

/// The leaf spring of [`default_scenes`] with twice the elements along and through the
/// leaves (80 x 4 on the upper leaf), its load path unchanged: the batched cost on a mesh
/// where the floor weighs less against the primal.
pub fn refined_leaf_spring() -> Scene {
    let base = LeafSpringSpec::default();
    let mut s = leaf_spring(&LeafSpringSpec {
        elements_along: 2 * base.elements_along,
        elements_through: 2 * base.elements_through,
        ..base
    });
    s.name = format!(
        "leaf-spring, {} x {} elements",
        2 * base.elements_along,
        2 * base.elements_through
    );
    s
}

/// [`BatchedCost`] of [`LEAF_BATCH`] on `scene`, SDM (at `beta`) and DDM, both with Newton's
/// last factorization.
pub fn batched_cost(scene: &Scene, beta: f64) -> Result<BatchedCost, ValidateError> {
    let wrap = |source| ValidateError::Analysis {
        scene: scene.name.clone(),
        source,
    };
    let model = scene.build()?;
    let params = parameters(&model, &scene.name, LEAF_BATCH)?;
    let methods = [
        ("SDM, last factor", Method::Sdm),
        ("DDM, last factor", Method::Ddm),
    ];
    let settings: Vec<Settings> = methods
        .iter()
        .enumerate()
        .map(|(i, (_, m))| Settings {
            method: *m,
            beta,
            tangent: TangentChoice::Last,
            probe_floor: i == 0,
            ..Settings::default()
        })
        .collect();
    let (_, runs) = run_inline_sweep(&model, &params, &settings).map_err(wrap)?;
    let primal_seconds = runs
        .first()
        .map(|r| r.primal_seconds)
        .unwrap_or(f64::NAN)
        .max(1e-9);
    Ok(BatchedCost {
        scene: scene.name.clone(),
        params: LEAF_BATCH.iter().map(|s| s.to_string()).collect(),
        primal_seconds,
        ratios: methods
            .iter()
            .zip(&runs)
            .map(|((name, _), r)| (name.to_string(), r.cost.wall_seconds / primal_seconds))
            .collect(),
        ledger: methods
            .iter()
            .zip(&runs)
            .map(|((name, _), r)| (name.to_string(), r.cost.clone()))
            .collect(),
        increments: runs.first().map(|r| r.increments.len()).unwrap_or(0),
        floor_seconds: runs.first().map(|r| r.cost.floor_seconds).unwrap_or(0.0),
        unknowns: model.dof_map().n_total,
    })
}

/// The "where the time goes" part of the report's cost section: the primal run split into
/// assembly, factorization and solves; the in-line methods split into evaluations,
/// factorizations, solves and the rest, per parameter and increment, against the floor.
fn write_time_ledger(s: &mut String, val: &Validation) {
    let _ = writeln!(s, "\n### Where the time goes\n");
    let _ = writeln!(s, "The primal analysis (the in-line methods' own time taken out), split by the solver's own timers. Assembly: residual, tangent and contact search, line-search re-evaluations included; the rest: the predictor, the convergence checks, the bookkeeping of increments and cutbacks, the hand-over of each converged state to the observers. Newton iterations count the linear solves of the converged attempts, those that settle the contact states of each attempt's first step included; factorizations include the failed attempts before cutbacks.\n");
    let _ = writeln!(
        s,
        "| scene | unknowns | increments | Newton it. / incr. | factorizations (with failed attempts) | primal s | assembly | factorization | solve | the rest |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for v in &val.scenes {
        let c = &v.primal_cost;
        let share = |x: f64| format!("{:.0} %", 100.0 * x / v.primal_seconds.max(1e-12));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {} | {:.3} | {} | {} | {} | {} |",
            v.scene,
            v.unknowns,
            v.increments,
            v.newton_iterations as f64 / v.increments.max(1) as f64,
            c.factorizations,
            v.primal_seconds,
            share(c.assembly_seconds),
            share(c.factor_seconds),
            share(c.solve_seconds),
            share(c.rest_seconds(v.primal_seconds))
        );
    }
    let _ = writeln!(s, "\nThe in-line methods, in milliseconds per parameter and increment. The floor is measured in the same run: at every increment one f64 residual evaluation over all elements at the converged state and one single-column solve with Newton's last factorization, timed together (outside the methods' own time). \"x floor\" is the method's total over it. Evaluations: the pseudo-loads (over only the elements a parameter reaches; forward SDM only where they are fewer than half of all), the nominal state over the same elements (forward SDM), the update of the history and the responses after the solve, the forced tangents of one-sided derivatives (DDM at flagged increments). The rest: building the perturbed or seeded designs and the masks, copying vectors, kink detection, copying the tangent for forced branches, the first symbolic analysis of the sensitivity's own factorization (at an increment where Newton did not factor, the floor has no solve). Solves: with Newton's last factorization, and the GMRES steps (one solve and one product each) where a method solves with the converged tangent or a forced one; \"own tangents\" counts those tangents, solved by GMRES (with its steps) / factored.\n");
    let _ = writeln!(
        s,
        "| scene | method | % of primal / param. | own tangents: GMRES (steps) / factored | evaluations | factorizations | solves | the rest | total | floor | x floor |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let row = |s: &mut String,
               scene: &str,
               method: &str,
               c: &SensitivityCost,
               np: usize,
               n_inc: usize,
               primal: f64,
               floor: f64| {
        let per = 1e3 / (np.max(1) * n_inc.max(1)) as f64;
        let rest = c.rest_seconds();
        let floor_ms = floor * 1e3 / n_inc.max(1) as f64;
        let total = c.wall_seconds * per;
        let _ = writeln!(
            s,
            "| {scene} | {method} | {:.2} | {} ({}) / {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} |",
            100.0 * c.wall_seconds / primal.max(1e-12) / np.max(1) as f64,
            c.krylov_solves,
            c.krylov_iterations,
            c.factorizations,
            c.evaluation_seconds * per,
            c.factor_seconds * per,
            c.solve_seconds * per,
            rest * per,
            total,
            floor_ms,
            total / floor_ms.max(1e-12)
        );
    };
    for v in &val.scenes {
        for (method, c) in &v.ledger {
            row(
                s,
                &v.scene,
                method,
                c,
                v.params.len(),
                v.increments,
                v.primal_seconds,
                v.floor_seconds,
            );
        }
    }
    for b in &val.batched {
        for (method, c) in &b.ledger {
            let name = format!("{method}, {} parameters batched", b.params.len());
            row(
                s,
                &b.scene,
                &name,
                c,
                b.params.len(),
                b.increments,
                b.primal_seconds,
                b.floor_seconds,
            );
        }
    }
}

/// Relative error of `other` against `reference` for parameter `p` (see the module docs).
///
/// Responses insensitive to the parameter — `|b| max|dR/db| < 1e-9 max|R|` over the history,
/// e.g. a reaction fixed by equilibrium — are left out: their reference derivative is
/// round-off.
pub fn relative_error(
    reference: &SensitivityResults,
    other: &SensitivityResults,
    p: usize,
    b: f64,
    floor: f64,
    flagged: &[bool],
) -> f64 {
    let nr = reference.responses.len();
    let mut worst: f64 = 0.0;
    let mut compared = 0;
    let mut considered = false;
    for r in 0..nr {
        let max = |f: &dyn Fn(&crate::sensitivity::IncrementSensitivity) -> f64| {
            reference.increments.iter().map(f).fold(0.0f64, f64::max)
        };
        let scale = max(&|i| i.derivatives[r][p].abs());
        let size = max(&|i| i.values[r].abs());
        if scale == 0.0 || b.abs().max(1.0) * scale < 1e-9 * size {
            continue;
        }
        considered = true;
        for (n, (a, b)) in reference
            .increments
            .iter()
            .zip(&other.increments)
            .enumerate()
        {
            if flagged.get(n).copied().unwrap_or(false)
                || b.rerun_substeps.get(p).copied().unwrap_or(false)
            {
                continue;
            }
            compared += 1;
            let d = a.derivatives[r][p];
            let e = (b.derivatives[r][p] - d).abs() / d.abs().max(floor * scale);
            if e.is_nan() {
                return f64::NAN; // the method gave no value (a failed rerun)
            }
            worst = worst.max(e);
        }
    }
    if considered && compared == 0 {
        return f64::NAN; // nothing left to compare
    }
    worst
}

/// Resolve design parameter names on a scene's model ([`Parameter::by_name`]).
fn parameters<N: AsRef<str>>(
    model: &crate::model::Model,
    scene: &str,
    names: impl IntoIterator<Item = N>,
) -> Result<Vec<Parameter>, ValidateError> {
    names
        .into_iter()
        .map(|n| Parameter::by_name(model, n.as_ref()))
        .collect::<Result<_, _>>()
        .map_err(|source| ValidateError::Analysis {
            scene: scene.to_string(),
            source: source.into(),
        })
}

/// Run every method on one scene.
pub fn validate_scene(
    scene: &Scene,
    opts: &ValidateOptions,
) -> Result<SceneValidation, ValidateError> {
    let model = scene.build()?;
    let wrap = |source| ValidateError::Analysis {
        scene: scene.name.clone(),
        source,
    };
    let params = parameters(&model, &scene.name, scene.study.params.iter())?;
    // The reference and the swept in-line methods solve with the tangent at the converged
    // state (TangentChoice::Exact): the last Newton factorization is that tangent only to
    // within Newton's last correction, which leaves errors of the order of the Newton
    // tolerance (1e-5 on the leaf spring) in every in-line method alike. DDM with the last
    // factorization (the paper's choice, no extra factorization) is measured on its own.
    let exact = Settings {
        tangent: TangentChoice::Exact,
        ..Settings::default()
    };
    let mut settings = vec![
        Settings {
            method: Method::Ddm,
            ..exact.clone()
        },
        Settings {
            method: Method::Ddm,
            tangent: TangentChoice::Last,
            probe_floor: true,
            ..exact.clone()
        },
        Settings {
            method: Method::Sdm,
            tangent: TangentChoice::Last,
            beta: opts.figure_beta,
            ..exact.clone()
        },
    ];
    for m in [Method::Sdm, Method::SdmCentral] {
        for &beta in &opts.betas {
            settings.push(Settings {
                method: m,
                beta,
                ..exact.clone()
            });
        }
    }
    let (primal, mut inline) = run_inline_sweep(&model, &params, &settings).map_err(wrap)?;
    let ddm = inline.remove(0);
    let ddm_last = inline.remove(0);
    let sdm_last = inline.remove(0);
    if let Some(why) = &ddm.failure {
        return Err(wrap(
            crate::sensitivity::SensitivityError::Failed {
                method: "DDM",
                reason: why.clone(),
            }
            .into(),
        ));
    }
    let fdm_betas: Vec<f64> = if opts.reduced_fdm.contains(&scene.name) {
        opts.betas
            .iter()
            .copied()
            .filter(|b| REDUCED_FDM_BETAS.iter().any(|r| (b / r - 1.0).abs() < 1e-9))
            .collect()
    } else {
        opts.betas.clone()
    };
    let sdm_exact = inline
        .iter()
        .find(|s| s.method == Some(Method::Sdm) && (s.beta / opts.figure_beta - 1.0).abs() < 1e-9)
        .map(|s| s.cost.clone());
    let ledger: Vec<(String, SensitivityCost)> = [
        ("DDM", Some(ddm.cost.clone())),
        ("DDM, last factor", Some(ddm_last.cost.clone())),
        ("SDM", sdm_exact),
        ("SDM, last factor", Some(sdm_last.cost.clone())),
    ]
    .into_iter()
    .filter_map(|(name, c)| c.map(|c| (name.to_string(), c)))
    .collect();
    let (_, fdm) = run_fdm_sweep(&model, &params, &fdm_betas, true).map_err(wrap)?;
    let primal_seconds = ddm.primal_seconds.max(1e-9);
    let flagged: Vec<bool> = ddm.increments.iter().map(|i| !i.kinks.is_empty()).collect();
    let mut errors = Vec::new();
    let sweeps: Vec<SensitivityResults> = inline.into_iter().chain(fdm).collect();
    for s in &sweeps {
        let method = s.method.map(|m| m.name()).unwrap_or("?").to_string();
        for (p, name) in s.parameters.iter().enumerate() {
            let error = if s.increments.len() < ddm.increments.len() {
                f64::NAN
            } else {
                relative_error(&ddm, s, p, params[p].value, opts.floor, &flagged)
            };
            errors.push(ErrorRow {
                scene: scene.name.clone(),
                method: method.clone(),
                beta: s.beta,
                param: name.clone(),
                error,
                cost_ratio: s.cost.wall_seconds / primal_seconds,
                failure: error.is_nan().then(|| {
                    s.failure.clone().unwrap_or_else(|| {
                        "no increment to compare (every one flagged, or after a rerun's extra \
                         sub-increments)"
                            .into()
                    })
                }),
                substep_excluded: s
                    .increments
                    .iter()
                    .filter(|i| i.rerun_substeps.get(p).copied().unwrap_or(false))
                    .count(),
                roundoff_flagged: s
                    .increments
                    .iter()
                    .filter(|i| {
                        i.roundoff
                            .iter()
                            .any(|row| row.get(p).copied().unwrap_or(false))
                    })
                    .count(),
            });
        }
    }
    Ok(SceneValidation {
        scene: scene.name.clone(),
        description: scene.description.clone(),
        params: scene.study.params.clone(),
        unknowns: model.dof_map().n_total,
        increments: primal.times.len() - 1,
        primal_seconds,
        flagged: flagged
            .iter()
            .enumerate()
            .filter(|(_, f)| **f)
            .map(|(n, _)| n + 1)
            .collect(),
        ddm_cost_ratio: ddm.cost.wall_seconds / primal_seconds,
        ddm_last_cost_ratio: ddm_last.cost.wall_seconds / primal_seconds,
        ddm_last_errors: (0..params.len())
            .map(|p| relative_error(&ddm, &ddm_last, p, params[p].value, opts.floor, &flagged))
            .collect(),
        sdm_last_cost_ratio: sdm_last.cost.wall_seconds / primal_seconds,
        sdm_last_errors: (0..params.len())
            .map(|p| relative_error(&ddm, &sdm_last, p, params[p].value, opts.floor, &flagged))
            .collect(),
        errors,
        primal_cost: primal.cost.clone(),
        newton_iterations: primal.records.iter().map(|r| r.iterations).sum(),
        floor_seconds: ddm_last.cost.floor_seconds,
        ledger,
        ddm,
        sweeps,
    })
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> ValidateError + '_ {
    move |source| ValidateError::Io {
        path: path.display().to_string(),
        source,
    }
}

fn write(path: &Path, text: &str) -> Result<(), ValidateError> {
    std::fs::write(path, text).map_err(io(path))
}

/// Closed-form checks on the DDM results of the oracle scenes.
fn oracles(v: &SceneValidation) -> Vec<OracleRow> {
    crate::scene::builtin::oracles(&v.scene, &v.ddm)
        .into_iter()
        .map(|c| OracleRow {
            scene: v.scene.clone(),
            rel_error: c.rel_error(),
            pass: c.pass(),
            quantity: c.quantity,
            expected: c.expected,
            got: c.got,
            tolerance: c.tolerance,
        })
        .collect()
}

fn sweep_of(v: &SceneValidation, m: Method, beta: f64) -> Option<&SensitivityResults> {
    v.sweeps
        .iter()
        .find(|s| s.method == Some(m) && (s.beta / beta - 1.0).abs() < 1e-9)
        .filter(|s| s.failure.is_none())
}

const BETA_METHODS: [Method; 4] = [
    Method::Sdm,
    Method::SdmCentral,
    Method::Fdm,
    Method::FdmCentral,
];

/// Error-vs-beta figure of one scene and parameter.
fn v_curve(v: &SceneValidation, param: &str) -> Figure {
    let mut f = Figure::new(
        format!("{}: d/d {} — error against DDM", v.scene, param),
        "perturbation beta",
        "largest relative error",
    )
    .log_x()
    .log_y();
    for m in BETA_METHODS {
        let pts: Vec<(f64, f64)> = v
            .errors
            .iter()
            .filter(|e| e.param == param && e.method == m.name() && e.error.is_finite())
            .map(|e| (e.beta, e.error))
            .collect();
        f = f.series(m.name(), pts, Style::LinePoints);
    }
    // vertical marks: the betas at which forward SDM flagged values round-off dominated
    let flagged: Vec<f64> = v
        .errors
        .iter()
        .filter(|e| e.param == param && e.method == Method::Sdm.name() && e.roundoff_flagged > 0)
        .map(|e| e.beta)
        .collect();
    f.marks(flagged)
}

/// The time history of a response's derivative by every method at one beta.
fn history_figure(
    v: &SceneValidation,
    response: &str,
    param: &str,
    beta: f64,
    title: &str,
) -> Option<Figure> {
    let r = v.ddm.response_index(response)?;
    let p = v.ddm.parameter_index(param)?;
    let mut f = Figure::new(title, "pseudo-time t", format!("d {response} / d {param}"));
    let series = |s: &SensitivityResults| -> Vec<(f64, f64)> {
        s.increments
            .iter()
            .map(|i| (i.time, i.derivatives[r][p]))
            .collect()
    };
    f = f.series("ddm", series(&v.ddm), Style::Line);
    for m in BETA_METHODS {
        if let Some(s) = sweep_of(v, m, beta) {
            f = f.series(
                format!("{} (beta {beta:.0e})", m.name()),
                series(s),
                Style::Points,
            );
        }
    }
    let marks: Vec<f64> = v
        .flagged
        .iter()
        .map(|n| v.ddm.increments[n - 1].time)
        .collect();
    Some(f.marks(marks))
}

/// Run the validation and write the report.
pub fn validate(scenes: &[Scene], opts: &ValidateOptions) -> Result<Validation, ValidateError> {
    validate_observed(scenes, opts, &mut |_| {})
}

/// Where [`validate_observed`] is.
#[derive(Clone, Copy, Debug)]
pub enum ValidateProgress<'a> {
    /// Scene `index` (of `of`) named `name` starts.
    Scene {
        /// Its position in the list.
        index: usize,
        /// The number of scenes.
        of: usize,
        /// Its name.
        name: &'a str,
    },
    /// Every scene is done; the report is being written.
    Report,
}

/// [`validate`], telling `progress` where it is (the command line draws a progress bar with
/// it; the library draws nothing).
pub fn validate_observed(
    scenes: &[Scene],
    opts: &ValidateOptions,
    progress: &mut dyn FnMut(ValidateProgress<'_>),
) -> Result<Validation, ValidateError> {
    let start = std::time::Instant::now();
    let data = opts.out.join("data");
    let figs = opts.out.join("figures");
    for d in [&opts.out, &data, &figs] {
        std::fs::create_dir_all(d).map_err(io(d))?;
    }
    let mut out = Vec::new();
    let mut oracle_rows = Vec::new();
    for (index, scene) in scenes.iter().enumerate() {
        progress(ValidateProgress::Scene {
            index,
            of: scenes.len(),
            name: &scene.name,
        });
        let v = validate_scene(scene, opts)?;
        oracle_rows.extend(oracles(&v));
        write_scene_data(&v, &data, opts.figure_beta)?;
        out.push(v);
    }
    progress(ValidateProgress::Report);
    // the leaf spring without friction, for figure 7
    let leaf_mu0 = out.iter().find(|v| v.scene == "leaf-spring").and_then(|_| {
        let s = scenes.iter().find(|s| s.name == "leaf-spring")?;
        let mut s = s.clone();
        for c in &mut s.contacts {
            c.friction = None;
        }
        s.study.params.retain(|p| p != "mu");
        let model = s.build().ok()?;
        let mut solver = crate::solver::Solver::new(&model).ok()?;
        let res = solver
            .run(
                &crate::solver::RunOptions::default(),
                &mut crate::solver::NoObserver,
            )
            .ok()?;
        let r = model
            .responses
            .iter()
            .position(|r| r.name == "block-force")?;
        Some(
            (1..res.times.len())
                .map(|k| (res.times[k], res.response_value(&model, r, k)))
                .collect::<Vec<_>>(),
        )
    });
    let laws = match opts.friction_laws {
        Some(elements) => {
            let c = crate::studies::compare_laws::compare_laws(elements)?;
            c.write_figures(&figs)?;
            let json = serde_json::to_string_pretty(&c).expect("serialisable");
            write(&data.join("friction-laws.json"), &json)?;
            Some(c)
        }
        None => None,
    };
    let mut batched = Vec::new();
    if let Some(s) = scenes.iter().find(|s| s.name == "leaf-spring") {
        batched.push(batched_cost(s, opts.figure_beta)?);
        if opts.refined_batch {
            batched.push(batched_cost(&refined_leaf_spring(), opts.figure_beta)?);
        }
    }
    let validation = Validation {
        scenes: out,
        oracles: oracle_rows,
        betas: opts.betas.clone(),
        floor: opts.floor,
        wall_seconds: start.elapsed().as_secs_f64(),
        batched,
    };
    // the indentation's pressure profile after sliding, for figures 4 and 5 and the report
    let indentation = validation
        .scenes
        .iter()
        .find(|v| v.scene == "indentation")
        .zip(scenes.iter().find(|s| s.name == "indentation"))
        .and_then(|(v, s)| PressureProfile::new(v, s));
    write_figures(
        &validation,
        scenes,
        indentation.as_ref(),
        leaf_mu0.as_deref(),
        opts,
        &figs,
    )?;
    let json = serde_json::to_string_pretty(&validation).expect("serialisable");
    write(&data.join("validation.json"), &json)?;
    write(
        &opts.out.join("README.md"),
        &report(
            &validation,
            indentation.as_ref(),
            leaf_mu0.as_deref(),
            laws.as_ref(),
            opts,
        ),
    )?;
    Ok(validation)
}

/// Errors of every (method, beta, parameter); sensitivity histories of DDM and of the other
/// methods at the figures' beta.
fn write_scene_data(v: &SceneValidation, dir: &Path, beta: f64) -> Result<(), ValidateError> {
    let mut e = String::from("scene,method,beta,param,error,cost_ratio,roundoff_flagged,failure\n");
    for r in &v.errors {
        let _ = writeln!(
            e,
            "{},{},{:e},{},{:e},{:e},{},\"{}\"",
            r.scene,
            r.method,
            r.beta,
            r.param,
            r.error,
            r.cost_ratio,
            r.roundoff_flagged,
            r.failure.as_deref().unwrap_or("").replace('"', "'")
        );
    }
    write(&dir.join(format!("{}-errors.csv", v.scene)), &e)?;
    let mut s = String::from(
        "method,beta,increment,time,response,param,value,derivative,flagged,rerun_substeps\n",
    );
    let flagged = |n: usize| v.flagged.contains(&n);
    let at_beta = v
        .sweeps
        .iter()
        .filter(|s| (s.beta / beta - 1.0).abs() < 1e-9);
    for res in std::iter::once(&v.ddm).chain(at_beta) {
        let m = res.method.map(|m| m.name()).unwrap_or("?");
        for inc in &res.increments {
            for (r, name) in res.responses.iter().enumerate() {
                for (p, pn) in res.parameters.iter().enumerate() {
                    let _ = writeln!(
                        s,
                        "{m},{:e},{},{:e},{name},{pn},{:e},{:e},{},{}",
                        res.beta,
                        inc.increment,
                        inc.time,
                        inc.values[r],
                        inc.derivatives[r][p],
                        flagged(inc.increment),
                        inc.rerun_substeps.get(p).copied().unwrap_or(false)
                    );
                }
            }
        }
    }
    write(&dir.join(format!("{}-sensitivities.csv", v.scene)), &s)
}

/// The contact pressure responses of a scene along the surface (x of the hitting node's
/// reference position), at the last increment.
struct PressureProfile {
    /// `(response index, x)`, sorted by x.
    nodes: Vec<(usize, f64)>,
    /// Index of the parameter "mu".
    mu: Option<usize>,
}

impl PressureProfile {
    fn new(v: &SceneValidation, scene: &Scene) -> Option<Self> {
        let model = scene.build().ok()?;
        let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
        let mut nodes: Vec<(usize, f64)> = model
            .responses
            .iter()
            .enumerate()
            .filter_map(|(r, resp)| match resp.kind {
                ResponseKind::ContactPressure { pair, node, .. } => {
                    Some((r, x[model.contacts[pair].hitting[node]][0]))
                }
                _ => None,
            })
            .collect();
        nodes.sort_by(|a, b| a.1.total_cmp(&b.1));
        Some(PressureProfile {
            nodes,
            mu: v.ddm.parameter_index("mu"),
        })
    }

    /// `(x, p)` or `(x, dp/dmu)` near the block (|x| <= 40 mm), last increment.
    fn curve(&self, s: &SensitivityResults, deriv: bool) -> Vec<(f64, f64)> {
        let Some(inc) = s.increments.last() else {
            return Vec::new();
        };
        self.nodes
            .iter()
            .filter(|(_, x)| x.abs() <= 40.0)
            .filter_map(|&(r, x)| {
                let y = if deriv {
                    inc.derivatives[r][self.mu?]
                } else {
                    inc.values[r]
                };
                Some((x, y))
            })
            .collect()
    }
}

fn write_figures(
    val: &Validation,
    scenes: &[Scene],
    indentation: Option<&PressureProfile>,
    leaf_mu0: Option<&[(f64, f64)]>,
    opts: &ValidateOptions,
    dir: &Path,
) -> Result<(), ValidateError> {
    for v in &val.scenes {
        for p in &v.params {
            write_svg(
                &v_curve(v, p),
                &dir.join(format!("{}-{}-error.svg", v.scene, slug(p))),
            )?;
        }
        // cost against accuracy: every (method, beta) point, and DDM
        let mut f = Figure::new(
            format!("{}: cost against accuracy", v.scene),
            "sensitivity cost / primal analysis (all parameters)",
            "largest relative error",
        )
        .log_x()
        .log_y();
        for m in BETA_METHODS {
            let pts: Vec<(f64, f64)> = v
                .errors
                .iter()
                .filter(|e| e.method == m.name() && e.error.is_finite())
                .map(|e| (e.cost_ratio, e.error))
                .collect();
            f = f.series(m.name(), pts, Style::Points);
        }
        write_svg(&f, &dir.join(format!("{}-cost.svg", v.scene)))?;
    }
    let beta = opts.figure_beta;
    if let Some((v, prof)) = val
        .scenes
        .iter()
        .find(|v| v.scene == "indentation")
        .zip(indentation)
    {
        let fig4 = Figure::new(
            "Fig. 4: contact pressure after sliding 3.33 mm (indentation)",
            "x (mm, reference position of the surface node)",
            "contact pressure (MPa)",
        )
        .series("fricsens", prof.curve(&v.ddm, false), Style::LinePoints);
        write_svg(&fig4, &dir.join("fig4-indentation-pressure.svg"))?;
        let mut fig5 = Figure::new(
            "Fig. 5: d(contact pressure)/d mu after sliding (indentation)",
            "x (mm, reference position of the surface node)",
            "dp / d mu (MPa)",
        )
        .series("ddm", prof.curve(&v.ddm, true), Style::Line);
        for m in BETA_METHODS {
            if let Some(s) = sweep_of(v, m, beta) {
                fig5 = fig5.series(
                    format!("{} (beta {beta:.0e})", m.name()),
                    prof.curve(s, true),
                    Style::Points,
                );
            }
        }
        write_svg(&fig5, &dir.join("fig5-indentation-dpdmu.svg"))?;
    }
    if let Some(v) = val.scenes.iter().find(|v| v.scene == "leaf-spring") {
        let scene = scenes.iter().find(|s| s.name == "leaf-spring");
        let stroke = |t: f64| -> f64 {
            scene
                .and_then(|s| s.contacts.iter().find(|c| c.name == "block"))
                .and_then(|c| match &c.target {
                    crate::scene::TargetSpec::Rigid { motion, .. } => motion.first().map(|m| {
                        let a = crate::load::Amplitude {
                            points: m.amplitude.clone(),
                        };
                        -m.value * a.at(t)
                    }),
                    _ => None,
                })
                .unwrap_or(t)
        };
        if let Some(r) = v.ddm.response_index("block-force") {
            let mut fig7 = Figure::new(
                "Fig. 7: block force against block displacement (leaf spring)",
                "block displacement (mm)",
                "block force (N)",
            )
            .series(
                "mu = 0.5",
                v.ddm
                    .increments
                    .iter()
                    .map(|i| (stroke(i.time), i.values[r]))
                    .collect(),
                Style::LinePoints,
            );
            if let Some(m0) = leaf_mu0 {
                fig7 = fig7.series(
                    "mu = 0",
                    m0.iter().map(|(t, f)| (stroke(*t), *f)).collect(),
                    Style::LinePoints,
                );
            }
            write_svg(&fig7, &dir.join("fig7-leaf-force.svg"))?;
        }
        for (param, fig) in [
            ("upper.length.x", "fig8-leaf-dFdL"),
            ("mu", "fig9-leaf-dFdmu"),
        ] {
            let title = if param == "mu" {
                "Fig. 9: d(block force)/d mu (leaf spring)"
            } else {
                "Fig. 8: d(block force)/d L (leaf spring)"
            };
            if let Some(f) = history_figure(v, "block-force", param, beta, title) {
                write_svg(&f, &dir.join(format!("{fig}.svg")))?;
            }
        }
    }
    Ok(())
}

fn slug(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}

/// Best beta and smallest error of a method for one scene and parameter.
fn best(v: &SceneValidation, m: Method, param: &str) -> Option<(f64, f64)> {
    v.errors
        .iter()
        .filter(|e| e.method == m.name() && e.param == param && e.error.is_finite())
        .map(|e| (e.beta, e.error))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

fn report(
    val: &Validation,
    indentation: Option<&PressureProfile>,
    leaf_mu0: Option<&[(f64, f64)]>,
    laws: Option<&crate::studies::compare_laws::LawComparison>,
    opts: &ValidateOptions,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# fricsens verification report\n");
    let _ = writeln!(
        s,
        "Generated by `cargo run --release -- validate` ({:.0} s on this machine). Every number and figure below is written by that command from the committed code; the data behind each plot is in `data/` (CSV per scene, `validation.json`).\n",
        val.wall_seconds
    );
    let _ = writeln!(s, "## What was run\n");
    let _ = writeln!(s, "The data: `data/SCENE-errors.csv` (every method, beta and parameter), `data/SCENE-sensitivities.csv` (every response's value and derivatives at every increment, by DDM and by the other methods at beta = {:.0e}), `data/validation.json` (the tables).\n", opts.figure_beta);
    let _ = writeln!(
        s,
        "For every scene and design parameter: DDM (forward-mode dual numbers, the exact derivative of the discrete equations, the reference), and SDM, SDM central, FDM and FDM central at beta = {} (relative perturbation `db = beta max(|b|, 1)`). SDM and DDM run in line with one primal analysis (all betas on the same run); FDM reruns the analysis at `b +- db` (in parallel). Errors are relative to DDM with a floor of {} x the largest |sensitivity| of the response over the history; increments flagged as non-differentiable (yield, contact or stick/slip transition within tolerance at the converged state) are excluded and marked in the plots.\n",
        opts.betas.iter().map(|b| format!("{b:.0e}")).collect::<Vec<_>>().join(", "),
        val.floor
    );
    let thinned: Vec<&str> = val
        .scenes
        .iter()
        .filter(|v| opts.reduced_fdm.contains(&v.scene))
        .map(|v| v.scene.as_str())
        .collect();
    if !thinned.is_empty() {
        let _ = writeln!(
            s,
            "The FDM sweeps of {} (a full rerun per beta, parameter and sign) use beta = {} only; `validate --full` runs them at every beta.\n",
            thinned.join(", "),
            REDUCED_FDM_BETAS
                .iter()
                .map(|b| format!("{b:.0e}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let _ = writeln!(s, "| scene | unknowns | increments | primal (s) | parameters | flagged increments | DDM cost / primal |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for v in &val.scenes {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {} | {} | {:.3} |",
            v.scene,
            v.unknowns,
            v.increments,
            v.primal_seconds,
            v.params.join(", "),
            v.flagged.len(),
            v.ddm_cost_ratio
        );
    }
    s.push_str(&findings(val, indentation, leaf_mu0, opts));
    let _ = writeln!(s, "\n## Best perturbation size per method\n");
    let _ = writeln!(
        s,
        "Smallest error over the sweep and the beta that gives it (relative error against DDM).\n"
    );
    let _ = writeln!(
        s,
        "| scene | parameter | SDM | SDM central | FDM | FDM central |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for v in &val.scenes {
        for p in &v.params {
            let cells: Vec<String> = BETA_METHODS
                .iter()
                .map(|m| match best(v, *m, p) {
                    Some((b, e)) => format!("{e:.1e} @ {b:.0e}"),
                    None => "-".into(),
                })
                .collect();
            let _ = writeln!(s, "| {} | {} | {} |", v.scene, p, cells.join(" | "));
        }
    }
    let _ = writeln!(s, "\n## Cost\n");
    let _ = writeln!(s, "Sensitivity wall time for all of a scene's parameters over the primal analysis, at beta = {:.0e} (SDM and DDM share the primal run; FDM is reruns). DDM, SDM and SDM central solve with the tangent at the converged state (the default, `--tangent exact`), to a relative residual of {:.0e}: by GMRES preconditioned with Newton's last factorization (a few solves per increment), with a factorization of their own only where GMRES does not get there in {} steps, then refined with double-double residuals to 1e-13 of the solution, so that DDM is exact to about that and SDM's error is its own; \"last factor\" (`--tangent last`) solves with Newton's last factorization alone (the paper's choice: no solve beyond one triangular solve), and its error against the reference is the price in accuracy, its time against DDM's the price of exactness. SDM's errors include its own forward-difference error at this beta, shown beside SDM with the converged tangent; the largest error over a scene's parameters is shown. The floor is one residual evaluation and one triangular solve per parameter and increment; the updates of the history after the solve skip the elements whose Gauss points are all elastic.\n", opts.figure_beta, crate::sensitivity::KRYLOV_TOL, crate::sensitivity::KRYLOV_MAX_ITER);
    let _ = writeln!(
        s,
        "| scene | parameters | DDM | DDM, last factor (error) | SDM (error) | SDM, last factor (error) | SDM central | FDM | FDM central |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for v in &val.scenes {
        let cost = |m: Method| {
            v.errors
                .iter()
                .find(|e| e.method == m.name() && (e.beta / opts.figure_beta - 1.0).abs() < 1e-9)
                .map(|e| format!("{:.3}", e.cost_ratio))
                .unwrap_or_else(|| "-".into())
        };
        // SDM's own error at this beta (converged tangent): the last factor's error adds to it
        let sdm_errors: Vec<f64> = v
            .errors
            .iter()
            .filter(|e| {
                e.method == Method::Sdm.name() && (e.beta / opts.figure_beta - 1.0).abs() < 1e-9
            })
            .map(|e| e.error)
            .collect();
        // a failed parameter (NaN) shows as NaN, no row at this beta as "-"
        let sdm_error = if sdm_errors.is_empty() {
            "-".to_string()
        } else if sdm_errors.iter().any(|e| e.is_nan()) {
            "NaN".to_string()
        } else {
            format!("{:.1e}", sdm_errors.iter().copied().fold(0.0f64, f64::max))
        };
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {:.3} ({:.1e}) | {} ({}) | {:.3} ({:.1e}) | {} | {} | {} |",
            v.scene,
            v.params.len(),
            v.ddm_cost_ratio,
            v.ddm_last_cost_ratio,
            v.ddm_last_errors.iter().copied().fold(0.0f64, f64::max),
            cost(Method::Sdm),
            sdm_error,
            v.sdm_last_cost_ratio,
            v.sdm_last_errors.iter().copied().fold(0.0f64, f64::max),
            cost(Method::SdmCentral),
            cost(Method::Fdm),
            cost(Method::FdmCentral)
        );
    }
    for b in &val.batched {
        let _ = writeln!(
            s,
            "\n**Batched.** The {} parameters of `{}` ({}) through one primal run ({} unknowns, {:.1} s): {}. Per parameter: {}.",
            b.params.len(),
            b.scene,
            b.params.iter().map(|p| format!("`{p}`")).collect::<Vec<_>>().join(", "),
            b.unknowns,
            b.primal_seconds,
            b.ratios
                .iter()
                .map(|(m, r)| format!("{m} {:.2} % of the primal in total", 100.0 * r))
                .collect::<Vec<_>>()
                .join(", "),
            b.ratios
                .iter()
                .map(|(m, r)| format!("{m} {:.2} %", 100.0 * r / b.params.len() as f64))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    write_time_ledger(&mut s, val);
    let _ = writeln!(s, "\n## Closed forms\n");
    let _ = writeln!(
        s,
        "| scene | quantity | expected | fricsens (DDM) | relative error | tolerance | |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for o in &val.oracles {
        let _ = writeln!(
            s,
            "| {} | {} | {:.6e} | {:.6e} | {:.2e} | {:.0e} | {} |",
            o.scene,
            o.quantity,
            o.expected,
            o.got,
            o.rel_error,
            o.tolerance,
            if o.pass { "pass" } else { "**FAIL**" }
        );
    }
    let _ = writeln!(s, "\n## The paper's figures, redrawn\n");
    for (f, what) in [
        ("fig4-indentation-pressure.svg", "Contact pressure under the block after sliding (paper fig. 4)."),
        ("fig5-indentation-dpdmu.svg", "Its sensitivity to mu by every method (paper fig. 5)."),
        ("fig7-leaf-force.svg", "Leaf spring: block force against block displacement, mu = 0.5 and mu = 0 (paper fig. 7)."),
        ("fig8-leaf-dFdL.svg", "Leaf spring: d(block force)/dL over the load path (paper fig. 8)."),
        ("fig9-leaf-dFdmu.svg", "Leaf spring: d(block force)/d mu over the load path (paper fig. 9)."),
    ] {
        if opts.out.join("figures").join(f).exists() {
            let _ = writeln!(s, "{what}\n\n![{f}](figures/{f})\n");
        }
    }
    if let Some(l) = laws {
        s.push_str(&l.section());
    }
    // sections written by `fricsens scaling` and `fricsens ccx` (long, or needing CalculiX):
    // included as they were last generated
    for (file, what) in [
        ("robustness/robustness.md", "fricsens fuzz"),
        ("scaling/scaling.md", "fricsens scaling"),
        ("ccx/ccx.md", "fricsens ccx"),
    ] {
        if let Ok(text) = std::fs::read_to_string(opts.out.join(file)) {
            let dir = file.split('/').next().unwrap_or("");
            let _ = writeln!(
                s,
                "<!-- included from {file}, written by `{what}` -->\n{}\n",
                text.replace("](", &format!("]({dir}/"))
                    .replace(&format!("]({dir}/http"), "](http"),
            );
        }
    }
    let _ = writeln!(s, "## Error against perturbation size\n");
    let _ = writeln!(s, "One plot per scene and parameter: the largest error over responses and unflagged increments against beta, for each method. Vertical marks: the betas at which forward SDM flagged some of its values round-off dominated.\n");
    for v in &val.scenes {
        let _ = writeln!(s, "### {}\n\n{}\n", v.scene, v.description);
        for p in &v.params {
            let f = format!("{}-{}-error.svg", v.scene, slug(p));
            let _ = writeln!(s, "![{f}](figures/{f})\n");
        }
        let f = format!("{}-cost.svg", v.scene);
        let _ = writeln!(s, "![{f}](figures/{f})\n");
    }
    s
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The "what was found" and "what it means" sections, every number computed from the run.
fn findings(
    val: &Validation,
    indentation: Option<&PressureProfile>,
    leaf_mu0: Option<&[(f64, f64)]>,
    opts: &ValidateOptions,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "\n## What was found\n");
    let _ = writeln!(s, "**Accuracy against perturbation size.** For each method, over every scene and parameter: the best error and its beta, and the single beta whose worst error over all scenes is smallest (the beta to choose without a sweep).\n");
    let _ = writeln!(
        s,
        "| method | median best error | worst best error | median best beta | one beta for all: beta, worst error |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|");
    let mut one_beta = Vec::new();
    for m in BETA_METHODS {
        let mut errs = Vec::new();
        let mut betas = Vec::new();
        for v in &val.scenes {
            for p in &v.params {
                if let Some((b, e)) = best(v, m, p) {
                    errs.push(e);
                    betas.push(b.log10());
                }
            }
        }
        let worst_best = errs.iter().copied().fold(0.0f64, f64::max);
        // the beta minimising the worst error over every scene and parameter
        let all = val
            .betas
            .iter()
            .map(|&b| {
                let worst = val
                    .scenes
                    .iter()
                    .flat_map(|v| &v.errors)
                    .filter(|e| e.method == m.name() && (e.beta / b - 1.0).abs() < 1e-9)
                    .map(|e| {
                        if e.error.is_finite() {
                            e.error
                        } else {
                            f64::INFINITY
                        }
                    })
                    .fold(0.0f64, f64::max);
                (b, worst)
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some(a) = all {
            one_beta.push((m, a));
        }
        let _ = writeln!(
            s,
            "| {} | {:.1e} | {:.1e} | 1e{:.0} | {} |",
            m.name(),
            median(errs),
            worst_best,
            median(betas),
            all.map(|(b, e)| format!("{b:.0e}: {e:.1e}"))
                .unwrap_or_else(|| "-".into())
        );
    }
    // round-off flags: the largest beta at which each method flagged a result
    let mut flags = Vec::new();
    for m in BETA_METHODS {
        let rows: Vec<&ErrorRow> = val
            .scenes
            .iter()
            .flat_map(|v| &v.errors)
            .filter(|e| e.method == m.name() && e.roundoff_flagged > 0)
            .collect();
        let largest = rows.iter().map(|e| e.beta).fold(0.0f64, f64::max);
        if largest > 0.0 {
            flags.push(format!(
                "{} from beta = {largest:.0e} down ({} scene-parameter-beta cases)",
                m.name(),
                rows.len()
            ));
        }
    }
    if !flags.is_empty() {
        let _ = writeln!(
            s,
            "\n**Round-off flags.** A difference that keeps fewer than {} significant digits above its noise (machine precision times the cancelling forces for SDM, the Newton tolerance for FDM's reruns) flags its value round-off dominated: {}. The flags sit on the right-hand, rising side of the V-curves.\n",
            crate::sensitivity::ROUNDOFF_DIGITS,
            flags.join("; ")
        );
    }
    // cost per parameter
    let per_param = |m: Option<Method>| -> f64 {
        median(
            val.scenes
                .iter()
                .filter_map(|v| {
                    let np = v.params.len().max(1) as f64;
                    match m {
                        None => Some(v.ddm_cost_ratio / np),
                        Some(m) => v
                            .errors
                            .iter()
                            .find(|e| {
                                e.method == m.name()
                                    && (e.beta / opts.figure_beta - 1.0).abs() < 1e-9
                                    && e.failure.is_none()
                            })
                            .map(|e| e.cost_ratio / np),
                    }
                })
                .collect(),
        )
    };
    let _ = writeln!(
        s,
        "\n**Cost.** Median over the scenes of the sensitivity time per parameter over the primal analysis: DDM {:.3}, SDM {:.3}, SDM central {:.3}, FDM {:.3}, FDM central {:.3}. The in-line methods reuse the converged state and the factored tangent; finite differences rerun the analysis (FDM's ratio is below 1 where the reruns ran in parallel on the two cores, or took fewer Newton iterations than the nominal run).\n",
        per_param(None),
        per_param(Some(Method::Sdm)),
        per_param(Some(Method::SdmCentral)),
        per_param(Some(Method::Fdm)),
        per_param(Some(Method::FdmCentral)),
    );
    let pass = val.oracles.iter().filter(|o| o.pass).count();
    let worst = val
        .oracles
        .iter()
        .map(|o| o.rel_error / o.tolerance)
        .fold(0.0f64, f64::max);
    let _ = writeln!(
        s,
        "**Closed forms.** {pass} of {} checks pass (table below); the closest to its tolerance uses {:.0} % of it.\n",
        val.oracles.len(),
        100.0 * worst
    );
    let failures: Vec<&ErrorRow> = val
        .scenes
        .iter()
        .flat_map(|v| &v.errors)
        .filter(|e| e.failure.is_some())
        .collect();
    if failures.is_empty() {
        let _ = writeln!(s, "**Failures.** None: every method ran at every beta.\n");
    } else {
        let _ = writeln!(s, "**Failures.** A perturbed analysis that cannot be evaluated is a result too (the other methods went on):\n");
        for e in failures {
            let why = e.failure.as_deref().unwrap_or("");
            // the residual histories are in data/SCENE-errors.csv
            let short: String = why.chars().take(160).collect();
            let _ = writeln!(
                s,
                "- {} {} d/d {} at beta {:.0e}: {}{}",
                e.scene,
                e.method,
                e.param,
                e.beta,
                short,
                if short.len() < why.len() { " ..." } else { "" }
            );
        }
        let _ = writeln!(s);
    }
    let substeps: Vec<&ErrorRow> = val
        .scenes
        .iter()
        .flat_map(|v| &v.errors)
        .filter(|e| e.substep_excluded > 0 && e.failure.is_none())
        .collect();
    if !substeps.is_empty() {
        let _ = writeln!(s, "**Finite differences across a different step sequence.** A rerun that needs a cutback the nominal run did not take solves the path-dependent incremental problem on other steps. From that increment on, its difference measures the change of the discrete path divided by the perturbation, not the derivative: those increments are left out of FDM's errors (and marked in the data). This happened to:\n");
        for e in substeps {
            let _ = writeln!(
                s,
                "- {} {} d/d {} at beta {:.0e}: {} increments",
                e.scene, e.method, e.param, e.beta, e.substep_excluded
            );
        }
        let _ = writeln!(s);
    }
    if let (Some(prof), Some(v)) = (
        indentation,
        val.scenes.iter().find(|v| v.scene == "indentation"),
    ) {
        let p = prof.curve(&v.ddm, false);
        let d = prof.curve(&v.ddm, true);
        // the contact zone after sliding: nodes with pressure; trailing edge = smallest x
        let zone: Vec<usize> = (0..p.len()).filter(|&i| p[i].1 > 0.0).collect();
        if let (Some(&i0), Some(&i1)) = (zone.first(), zone.last()) {
            let (nu, mu) = (0.3f64, 0.5f64);
            let gamma = (mu * (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))).atan() / std::f64::consts::PI;
            let _ = writeln!(s, "**Why the indentation pressure is asymmetric** (figure 4). The block slides towards +x. After sliding, the pressure at the trailing edge (x = {:.2} mm) is {:.1} MPa and at the leading edge (x = {:.2} mm) {:.1} MPa: the sharper gradient is at the trailing (left) edge, as in the paper. The friction traction mu p drags the slab's surface in the sliding direction. On an elastic half-space a tangential surface traction also moves the surface normally, by a term proportional to (1 - 2 nu) / (2 (1 - nu)): the surface ahead of it sinks and the surface behind it rises (Johnson, Contact Mechanics, section 2.2). So a rigid flat block bears harder behind and lighter ahead. For a flat punch, the edge singularities become (a + x)^(-1/2 - gamma) and (a - x)^(-1/2 + gamma), with tan(pi gamma) = mu (1 - 2 nu) / (2 (1 - nu)) = {:.3}, so gamma = {:.3} here. The paper gives the same effect as the rigid block's reaction resisting the friction moment. The asymmetry grows with mu (figure 5): dp/dmu = {:+.1} MPa at the trailing edge and {:+.1} MPa at the leading edge.\n",
                p[i0].0, p[i0].1, p[i1].0, p[i1].1,
                (std::f64::consts::PI * gamma).tan(), gamma,
                d[i0].1, d[i1].1);
        }
    }
    if let Some(v) = val.scenes.iter().find(|v| v.scene == "leaf-spring") {
        if let (Some(r), Some(pm)) = (
            v.ddm.response_index("block-force"),
            v.ddm.parameter_index("mu"),
        ) {
            let inc = &v.ddm.increments;
            let f: Vec<(f64, f64)> = inc.iter().map(|i| (i.time, i.values[r])).collect();
            let peak = |pts: &[(f64, f64)]| {
                pts.iter()
                    .filter(|(t, _)| *t <= 1.0 + 1e-9)
                    .map(|p| p.1)
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            let at_end = |pts: &[(f64, f64)]| {
                pts.iter()
                    .filter(|(t, _)| (*t - 1.0).abs() < 1e-9)
                    .map(|p| p.1)
                    .next()
            };
            let first_unload = f.iter().find(|(t, _)| *t > 1.0 + 1e-9).map(|p| p.1);
            let _ = write!(s, "**Leaf spring** (figures 7-9). With mu = 0.5 the block force peaks at {:.0} N in loading", peak(&f));
            if let Some(m0) = leaf_mu0 {
                let _ = write!(s, "; without friction at {:.0} N, so friction raises the loading force by {:.0} %", peak(m0), 100.0 * (peak(&f) / peak(m0) - 1.0));
            }
            if let (Some(a), Some(b)) = (at_end(&f), first_unload) {
                let _ = write!(s, ". Right after unloading starts it drops from {a:.0} N to {b:.0} N in one increment: the friction forces reverse");
            }
            let dmu: Vec<f64> = inc.iter().map(|i| i.derivatives[r][pm]).collect();
            let changes = dmu.windows(2).filter(|w| w[0] * w[1] < 0.0).count();
            let (lo, hi) = dmu
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |a, &x| {
                    (a.0.min(x), a.1.max(x))
                });
            let phase = |a: f64, b: f64| {
                median(
                    inc.iter()
                        .filter(|i| i.time > a + 1e-9 && i.time <= b + 1e-9)
                        .map(|i| i.derivatives[r][pm])
                        .collect(),
                )
            };
            let _ = writeln!(s, ". dF/dmu ranges over [{lo:.0}, {hi:.0}] N along the path and changes sign {changes} times; its median is {:+.0} N in loading, {:+.0} N in unloading and {:+.0} N in reloading: the derivative depends on the path, not only on the block's position. {} of {} increments are flagged as non-differentiable (stick/slip, contact or yield transitions) and are marked in the plots.\n", phase(0.0, 1.0), phase(1.0, 2.0), phase(2.0, 3.0), v.flagged.len(), v.increments);
        }
    }
    let _ = writeln!(s, "## What it means for choosing beta and a method\n");
    for (m, (b, e)) in &one_beta {
        let _ = writeln!(
            s,
            "- **{}**: beta = {b:.0e} keeps the error below {e:.1e} on every scene here.",
            m.name()
        );
    }
    let _ = writeln!(s, "\nForward differences (SDM, FDM) trade truncation error, which is proportional to beta, against round-off, which is proportional to 1/beta. Central differences make truncation proportional to beta^2, so their best beta is larger and their best error smaller. SDM's round-off is that of one residual evaluation at a fixed state, so it goes down to about sqrt(machine epsilon). FDM's round-off is the Newton tolerance of two separate analyses divided by beta: it is worse by orders of magnitude, and its best beta is larger. DDM has no beta, is exact to the linear solve, and costs about as much as SDM. It is the method to use when the kernels are generic, as all of fricsens' are. SDM central is the check that needs no dual numbers, and FDM is the check that needs nothing but reruns. Away from the flagged increments all methods converge to DDM. At a flagged increment a finite perturbation crosses the kink, so a difference returns a mix of the one-sided derivatives.\n");
    s
}
