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

use crate::scene::{
    builtin, leaf_spring, stacked_leaves, LeafSpringSpec, Scene, SceneError, StackedLeavesSpec,
};
use crate::sensitivity::{
    run_fdm_sweep, run_inline_sweep, Method, Parameter, SensitivityCost, SensitivityResults,
    Settings, TangentChoice,
};
use crate::solver::{AnalysisError, PrimalCost};
use crate::studies::plot::PlotError;
use std::path::{Path, PathBuf};

pub mod anatomy;
pub mod auto_step;
mod figures;
pub mod imported;
mod report;
pub mod tangent;
pub mod taylor;
use figures::*;
use report::*;

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
    /// The folder of the imported-geometry scenes (`meshes/`): their closed forms go into the
    /// report ([`imported`]); `None`, or a folder without them, leaves the section out.
    pub imported: Option<PathBuf>,
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
            imported: Some(PathBuf::from("meshes")),
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
    /// An imported-geometry check failed to run.
    #[error(transparent)]
    Imported(#[from] imported::ImportedError),
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
    /// The Taylor test of DDM's derivative per parameter ([`taylor`]).
    pub taylor: Vec<taylor::TaylorRow>,
    /// SDM's error anatomy per parameter and variant at the figure beta ([`anatomy`]).
    pub anatomy: Vec<anatomy::AnatomyRow>,
    /// The last factorization's error against Newton's last correction ([`tangent`]).
    pub tangent: tangent::TangentStudy,
    /// `--beta auto` against DDM ([`auto_step`]).
    pub auto: Vec<auto_step::AutoRow>,
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
    /// Closed-form and independent checks of the scenes around imported meshes.
    pub imported: Vec<OracleRow>,
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
pub(crate) const LEAF_BATCH: [&str; 10] = [
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
pub(crate) fn batched_cost(scene: &Scene, beta: f64) -> Result<BatchedCost, ValidateError> {
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

/// Relative error of `other` against `reference` for parameter `p` (see the module docs): the
/// largest of [`increment_errors`].
///
/// Responses insensitive to the parameter — `|b| max|dR/db| < 1e-9 max|R|` over the history,
/// e.g. a reaction fixed by equilibrium — are left out: their reference derivative is
/// round-off.
pub(crate) fn relative_error(
    reference: &SensitivityResults,
    other: &SensitivityResults,
    p: usize,
    b: f64,
    floor: f64,
    flagged: &[bool],
) -> f64 {
    let Some(errors) = increment_errors(reference, other, p, b, floor, flagged) else {
        return 0.0; // no response sensitive to the parameter
    };
    let mut worst: f64 = 0.0;
    let mut compared = 0;
    for e in errors.into_iter().flatten() {
        if e.is_nan() {
            return f64::NAN; // the method gave no value (a failed rerun)
        }
        compared += 1;
        worst = worst.max(e);
    }
    if compared == 0 {
        return f64::NAN; // nothing left to compare
    }
    worst
}

/// Per increment, the relative error of `other` against `reference` for parameter `p`, the
/// largest over the responses sensitive to it ([`relative_error`]); `None` at increments left
/// out (flagged, or after a rerun's extra sub-increments). `None` altogether where no response
/// is sensitive to the parameter.
pub(crate) fn increment_errors(
    reference: &SensitivityResults,
    other: &SensitivityResults,
    p: usize,
    b: f64,
    floor: f64,
    flagged: &[bool],
) -> Option<Vec<Option<f64>>> {
    let nr = reference.responses.len();
    let mut out: Vec<Option<f64>> =
        vec![None; reference.increments.len().min(other.increments.len())];
    let mut considered = false;
    for r in 0..nr {
        let Some(scale) = reference.sensitive_scale(r, p, b) else {
            continue;
        };
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
            let d = a.derivatives[r][p];
            let e = (b.derivatives[r][p] - d).abs() / d.abs().max(floor * scale);
            // a NaN (a method that gave no value) sticks
            out[n] = Some(match out[n] {
                None => e,
                Some(w) if w.is_nan() || e.is_nan() => f64::NAN,
                Some(w) => w.max(e),
            });
        }
    }
    considered.then_some(out)
}

/// Resolve design parameter names on a scene's model ([`Parameter::by_name`]).
pub(super) fn parameters<N: AsRef<str>>(
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
pub(crate) fn validate_scene(
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
    // SDM and SDM central at the figure beta are explained: their anatomy is timed apart and
    // leaves their values and cost as they are
    for m in [Method::Sdm, Method::SdmCentral] {
        for &beta in &opts.betas {
            settings.push(Settings {
                method: m,
                beta,
                explain: (beta / opts.figure_beta - 1.0).abs() < 1e-9,
                ..exact.clone()
            });
        }
    }
    // DDM with Newton's last factorization and one refinement step against the converged
    // tangent (the cheap fix of the last factorization's error)
    settings.push(Settings {
        method: Method::Ddm,
        tangent: TangentChoice::Refined,
        refine_steps: 1,
        ..exact.clone()
    });
    // SDM and SDM central with --beta auto
    for m in [Method::Sdm, Method::SdmCentral] {
        settings.push(Settings {
            method: m,
            beta_auto: true,
            ..exact.clone()
        });
    }
    let (primal, mut inline) = run_inline_sweep(&model, &params, &settings).map_err(wrap)?;
    let auto_runs = inline.split_off(inline.len() - 2);
    let ddm_refined = inline.pop().expect("pushed last");
    let explained: Vec<&SensitivityResults> =
        inline.iter().filter(|s| !s.anatomy.is_empty()).collect();
    let anatomy = anatomy::anatomy_rows(&scene.name, &explained, &params, opts.floor);
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
        taylor: taylor::taylor_rows(
            &scene.name,
            &ddm,
            &sweeps,
            &params,
            &flagged,
            opts.figure_beta,
        ),
        ledger,
        anatomy,
        auto: auto_step::auto_rows(&ddm, &auto_runs, &params, opts.floor, &flagged),
        tangent: tangent::tangent_study(
            &ddm,
            &ddm_last,
            &ddm_refined,
            &primal,
            &params,
            opts.floor,
            &flagged,
            primal_seconds,
        ),
        ddm,
        sweeps,
    })
}

pub(super) fn io(path: &Path) -> impl Fn(std::io::Error) -> ValidateError + '_ {
    move |source| ValidateError::Io {
        path: path.display().to_string(),
        source,
    }
}

pub(super) fn write(path: &Path, text: &str) -> Result<(), ValidateError> {
    std::fs::write(path, text).map_err(io(path))
}

impl OracleRow {
    /// A check of `scene` as a report row (its relative error and verdict computed).
    pub fn new(scene: &str, c: crate::scene::builtin::OracleCheck) -> Self {
        OracleRow {
            scene: scene.to_string(),
            rel_error: c.rel_error(),
            pass: c.pass(),
            quantity: c.quantity,
            expected: c.expected,
            got: c.got,
            tolerance: c.tolerance,
        }
    }
}

/// Closed-form checks on the DDM results of the oracle scenes.
pub(super) fn oracles(v: &SceneValidation) -> Vec<OracleRow> {
    crate::scene::builtin::oracles(&v.scene, &v.ddm)
        .into_iter()
        .map(|c| OracleRow::new(&v.scene, c))
        .collect()
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
    let imported = match &opts.imported {
        Some(dir) => imported::imported_oracles(dir)?,
        None => Vec::new(),
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
        imported,
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
