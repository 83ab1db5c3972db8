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
pub mod convergence;
mod figures;
pub mod hertz_families;
pub mod imported;
pub mod partial;
pub mod refinement;
mod report;
pub mod smoothness;
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
    /// A study's model could not be made.
    #[error("{study}: {what}")]
    Study {
        /// The study.
        study: &'static str,
        /// What failed.
        what: String,
    },
    /// An imported-geometry check failed to run.
    #[error(transparent)]
    Imported(#[from] imported::ImportedError),
    /// The friction-law comparison failed.
    #[error(transparent)]
    Laws(#[from] crate::studies::compare_laws::CompareLawsError),
    /// Shares of a sharded run that do not merge, or a partial result that cannot be read.
    #[error(transparent)]
    Shard(#[from] partial::ShardError),
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
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
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
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
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
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
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
    /// The adjoint at the last increment, every response, against DDM ([`AdjointCheck`]).
    pub adjoint: AdjointCheck,
    /// The reference DDM results.
    #[serde(skip)]
    pub ddm: SensitivityResults,
    /// The results of the sweep (SDM and SDM central in line, then the FDM reruns).
    #[serde(skip)]
    pub sweeps: Vec<SensitivityResults>,
}

/// The adjoint (`Method::Adjoint`) of one scene: every response at the last increment, one
/// backward sweep for all the parameters, against DDM there.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct AdjointCheck {
    /// Per parameter: the largest relative error against DDM over the responses sensitive to
    /// it, at the last increment (the module docs' measure, floored at `floor` times the
    /// largest DDM sensitivity over the history); NaN where the adjoint failed.
    pub errors: Vec<f64>,
    /// The adjoint's wall time (its stored forward states and its backward sweep) over the
    /// primal's ([`SceneValidation::primal_seconds`]).
    pub cost_ratio: f64,
    /// Bytes of the forward states it stored.
    pub stored_bytes: usize,
    /// Why it failed, if it did.
    pub failure: Option<String>,
}

/// The whole validation.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
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
    /// The shape-parameter benchmark and the refined SDM ([`refinement`]), with the leaf
    /// spring (the full validation).
    #[serde(default)]
    pub refinement: Option<refinement::RefinementStudy>,
    /// The element families' convergence orders on Lamé's cylinder ([`convergence`]; the
    /// full validation).
    #[serde(default)]
    pub convergence: Vec<convergence::ConvergenceRow>,
    /// Hertz's line contact on hex8, hex20 and tet10 blocks ([`hertz_families`]; the full
    /// validation).
    #[serde(default)]
    pub hertz_families: Vec<hertz_families::HertzRow>,
    /// The smoothness of `dp/dmu` along a curved punch's contact surface ([`smoothness`]; the
    /// full validation).
    #[serde(default)]
    pub smoothness: Vec<smoothness::SmoothnessRow>,
}

/// The distinct `names`, in the order of their first appearance (the families of a study's
/// rows, say).
pub(crate) fn distinct<'a>(names: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let mut out: Vec<&str> = Vec::new();
    for n in names {
        if !out.contains(&n) {
            out.push(n);
        }
    }
    out
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
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
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
    let mut auto_runs = inline.split_off(inline.len() - 2);
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
    // FDM and FDM central with --beta auto: reruns at every step of their ladders (left out
    // where the sweep's FDM is reduced, as it is there for the same cost)
    if !opts.reduced_fdm.contains(&scene.name) {
        for method in [Method::Fdm, Method::FdmCentral] {
            let settings = Settings {
                method,
                beta_auto: true,
                ..exact.clone()
            };
            let (_, run) =
                crate::sensitivity::run_sensitivity(&model, &params, &settings).map_err(wrap)?;
            auto_runs.push(run);
        }
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
    let adjoint = adjoint_at_last(&model, &params, &ddm, &exact, opts.floor, primal_seconds);
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
        adjoint,
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

/// The adjoint of every response at the last increment of `ddm`'s run, for all of `params`
/// in one backward sweep, against DDM there: per parameter the largest of
/// `|D_adj - D_ddm| / max(|D_ddm|, floor * max_n |D_ddm(n)|)` over the responses sensitive to
/// it. A flagged last increment is compared too: the adjoint and DDM's main value both follow
/// the converged branches. `primal_seconds` is the denominator of the cost.
pub(crate) fn adjoint_at_last(
    model: &crate::model::Model,
    params: &[Parameter],
    ddm: &SensitivityResults,
    settings: &Settings,
    floor: f64,
    primal_seconds: f64,
) -> AdjointCheck {
    let nan = |why: String| AdjointCheck {
        errors: vec![f64::NAN; params.len()],
        cost_ratio: f64::NAN,
        stored_bytes: 0,
        failure: Some(why),
    };
    let Some(last) = ddm.increments.last() else {
        return nan("no increment".into());
    };
    let settings = Settings {
        method: Method::Adjoint,
        adjoint_at: vec![last.time],
        ..settings.clone()
    };
    let adj = match crate::sensitivity::run_sensitivity(model, params, &settings) {
        Ok((_, adj)) => adj,
        Err(e) => return nan(e.to_string()),
    };
    let Some(at) = adj.increment_at(last.time) else {
        return nan(format!("no increment at t = {}", last.time));
    };
    let errors = (0..params.len())
        .map(|p| {
            let mut worst: f64 = 0.0;
            for r in 0..ddm.responses.len() {
                let Some(scale) = ddm.sensitive_scale(r, p, params[p].value) else {
                    continue;
                };
                let d = last.derivatives[r][p];
                let e = (at.derivatives[r][p] - d).abs() / d.abs().max(floor * scale);
                worst = if e.is_nan() { f64::NAN } else { worst.max(e) };
            }
            worst
        })
        .collect();
    AdjointCheck {
        errors,
        cost_ratio: adj.cost.wall_seconds / primal_seconds,
        stored_bytes: adj.cost.stored_bytes,
        failure: None,
    }
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
    /// Every scene is done; the rest (the friction laws, the batched cost, ...) and the report.
    Report,
}

/// One independent job of a validation run: what a share of `fricsens validate --shard K/N`
/// runs ([`run_shard`]).
#[derive(Clone, Debug, PartialEq)]
pub enum Job {
    /// Every method on scene `i` of the list.
    Scene(usize),
    /// The leaf spring without friction (the second curve of figure 7).
    LeafSpringMu0,
    /// The friction laws on the strip of this many elements ([`crate::studies::compare_laws`]).
    FrictionLaws(usize),
    /// One imported-geometry check ([`imported`]) on the folder's scenes.
    Imported(ImportedCheck, PathBuf),
    /// The leaf spring's ten batched parameters through one primal run ([`BatchedCost`]).
    Batched,
    /// The same on [`refined_leaf_spring`].
    BatchedRefined,
    /// The shape-parameter benchmark and the refined SDM ([`refinement`]).
    Refinement,
    /// The element families' convergence orders ([`convergence`]).
    Convergence,
    /// Hertz on hex8, hex20 and tet10 blocks ([`hertz_families`]).
    HertzFamilies,
    /// The smoothness of the sensitivities along a contact surface ([`smoothness`]).
    Smoothness,
}

/// The imported-geometry checks, each a job of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImportedCheck {
    /// [`imported::hertz_cylinders`], as written.
    HertzCylinders,
    /// The same with the contact pair's roles swapped.
    HertzCylindersReversed,
    /// [`imported::lame_sphere`].
    LameSphere,
    /// [`imported::morph_against_scale`].
    MorphAgainstScale,
}

impl Job {
    /// A name for messages and for the partial result's list of jobs.
    pub fn name(&self, scenes: &[Scene]) -> String {
        match self {
            Job::Scene(i) => format!("scene {}", scenes[*i].name),
            Job::LeafSpringMu0 => "leaf-spring without friction".into(),
            Job::FrictionLaws(n) => format!("friction laws on {n} elements"),
            Job::Imported(c, dir) => format!("imported {c:?} in {}", dir.display()),
            Job::Batched => "batched cost, leaf-spring".into(),
            Job::BatchedRefined => "batched cost, refined leaf-spring".into(),
            Job::Refinement => "shape parameters: cantilever refinement, refined SDM".into(),
            Job::Convergence => "element families: convergence orders on Lame's cylinder".into(),
            Job::HertzFamilies => "element families: Hertz on hex8, hex20 and tet10".into(),
            Job::Smoothness => "element families: smoothness of dp/dmu on a curved punch".into(),
        }
    }
}

/// The jobs of a validation run, in the order the unsharded run takes them: every scene,
/// then the rest.
pub fn plan(scenes: &[Scene], opts: &ValidateOptions) -> Vec<Job> {
    let mut jobs: Vec<Job> = (0..scenes.len()).map(Job::Scene).collect();
    let leaf = scenes.iter().any(|s| s.name == "leaf-spring");
    if leaf {
        jobs.push(Job::LeafSpringMu0);
    }
    if let Some(n) = opts.friction_laws {
        jobs.push(Job::FrictionLaws(n));
    }
    if let Some(dir) = &opts.imported {
        if imported::present(dir) {
            for c in [
                ImportedCheck::HertzCylinders,
                ImportedCheck::HertzCylindersReversed,
                ImportedCheck::LameSphere,
                ImportedCheck::MorphAgainstScale,
            ] {
                jobs.push(Job::Imported(c, dir.clone()));
            }
        }
    }
    if leaf {
        jobs.push(Job::Batched);
        if opts.refined_batch {
            jobs.push(Job::BatchedRefined);
        }
        jobs.push(Job::Refinement);
        jobs.push(Job::Convergence);
        jobs.push(Job::HertzFamilies);
        jobs.push(Job::Smoothness);
    }
    jobs
}

/// What a [`Job`] gives.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub enum JobOutput {
    /// [`Job::Scene`]: the scene's validation, its DDM reference and its sweep (taken out of
    /// the validation, which does not serialise them).
    Scene {
        /// Everything but the two below.
        validation: Box<SceneValidation>,
        /// [`SceneValidation::ddm`].
        ddm: Box<SensitivityResults>,
        /// [`SceneValidation::sweeps`].
        sweeps: Vec<SensitivityResults>,
    },
    /// [`Job::LeafSpringMu0`]: `(t, block force)` per increment, if the run converged.
    LeafSpringMu0 {
        /// The curve.
        curve: Option<Vec<(f64, f64)>>,
    },
    /// [`Job::FrictionLaws`].
    FrictionLaws(crate::studies::compare_laws::LawComparison),
    /// [`Job::Imported`].
    Imported(Vec<OracleRow>),
    /// [`Job::Batched`] and [`Job::BatchedRefined`].
    Batched(BatchedCost),
    /// [`Job::Refinement`].
    Refinement(refinement::RefinementStudy),
    /// [`Job::Convergence`].
    Convergence(Vec<convergence::ConvergenceRow>),
    /// [`Job::HertzFamilies`].
    HertzFamilies(Vec<hertz_families::HertzRow>),
    /// [`Job::Smoothness`].
    Smoothness(Vec<smoothness::SmoothnessRow>),
}

/// Run one job.
pub fn run_job(
    scenes: &[Scene],
    opts: &ValidateOptions,
    job: &Job,
) -> Result<JobOutput, ValidateError> {
    let leaf = || scenes.iter().find(|s| s.name == "leaf-spring");
    Ok(match job {
        Job::Scene(i) => {
            let mut v = validate_scene(&scenes[*i], opts)?;
            let ddm = Box::new(std::mem::take(&mut v.ddm));
            let sweeps = std::mem::take(&mut v.sweeps);
            JobOutput::Scene {
                validation: Box::new(v),
                ddm,
                sweeps,
            }
        }
        Job::LeafSpringMu0 => JobOutput::LeafSpringMu0 {
            curve: leaf().and_then(leaf_spring_mu0),
        },
        Job::FrictionLaws(n) => {
            JobOutput::FrictionLaws(crate::studies::compare_laws::compare_laws(*n)?)
        }
        Job::Imported(c, dir) => JobOutput::Imported(match c {
            ImportedCheck::HertzCylinders => imported::hertz_cylinders(dir, false)?,
            ImportedCheck::HertzCylindersReversed => imported::hertz_cylinders(dir, true)?,
            ImportedCheck::LameSphere => imported::lame_sphere(dir)?,
            ImportedCheck::MorphAgainstScale => imported::morph_against_scale(dir)?,
        }),
        Job::Batched => JobOutput::Batched(batched_cost(
            leaf().expect("planned with the leaf spring"),
            opts.figure_beta,
        )?),
        Job::BatchedRefined => {
            JobOutput::Batched(batched_cost(&refined_leaf_spring(), opts.figure_beta)?)
        }
        Job::Refinement => JobOutput::Refinement(refinement::refinement_study(
            leaf(),
            &opts.betas,
            opts.floor,
        )?),
        Job::Convergence => JobOutput::Convergence(convergence::study(&convergence::LEVELS)?),
        Job::HertzFamilies => JobOutput::HertzFamilies(hertz_families::study()?),
        Job::Smoothness => JobOutput::Smoothness(smoothness::study(
            &opts.out.join("data").join(smoothness::FOLDER),
        )?),
    })
}

/// The leaf spring without friction, for figure 7: `(t, block force)` per increment.
fn leaf_spring_mu0(s: &Scene) -> Option<Vec<(f64, f64)>> {
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
            .collect(),
    )
}

/// [`validate`], telling `progress` where it is (the command line draws a progress bar with
/// it; the library draws nothing).
pub fn validate_observed(
    scenes: &[Scene],
    opts: &ValidateOptions,
    progress: &mut dyn FnMut(ValidateProgress<'_>),
) -> Result<Validation, ValidateError> {
    let start = std::time::Instant::now();
    std::fs::create_dir_all(&opts.out).map_err(io(&opts.out))?;
    let jobs = plan(scenes, opts);
    let mut outputs = Vec::with_capacity(jobs.len());
    let mut reported = false;
    for job in &jobs {
        match job {
            Job::Scene(index) => progress(ValidateProgress::Scene {
                index: *index,
                of: scenes.len(),
                name: &scenes[*index].name,
            }),
            _ if !reported => {
                reported = true;
                progress(ValidateProgress::Report);
            }
            _ => {}
        }
        outputs.push(run_job(scenes, opts, job)?);
    }
    if !reported {
        progress(ValidateProgress::Report);
    }
    finish(scenes, opts, outputs, start.elapsed().as_secs_f64())
}

/// Write the report from the outputs of every job of [`plan`], in its order: the end of the
/// unsharded run and the whole of a merge. `wall_seconds`: the jobs' time.
fn finish(
    scenes: &[Scene],
    opts: &ValidateOptions,
    outputs: Vec<JobOutput>,
    wall_seconds: f64,
) -> Result<Validation, ValidateError> {
    let data = opts.out.join("data");
    let figs = opts.out.join("figures");
    for d in [&opts.out, &data, &figs] {
        std::fs::create_dir_all(d).map_err(io(d))?;
    }
    let mut out = Vec::new();
    let mut oracle_rows = Vec::new();
    let mut leaf_mu0 = None;
    let mut laws = None;
    let mut imported = Vec::new();
    let mut batched = Vec::new();
    let mut shape = None;
    let mut converged = Vec::new();
    let mut hertz = Vec::new();
    let mut smooth = Vec::new();
    for o in outputs {
        match o {
            JobOutput::Scene {
                validation,
                ddm,
                sweeps,
            } => {
                let mut v = *validation;
                v.ddm = *ddm;
                v.sweeps = sweeps;
                oracle_rows.extend(oracles(&v));
                write_scene_data(&v, &data, opts.figure_beta)?;
                out.push(v);
            }
            JobOutput::LeafSpringMu0 { curve } => leaf_mu0 = curve,
            JobOutput::FrictionLaws(c) => {
                c.write_figures(&figs)?;
                let json = serde_json::to_string_pretty(&c).expect("serialisable");
                write(&data.join("friction-laws.json"), &json)?;
                laws = Some(c);
            }
            JobOutput::Imported(rows) => imported.extend(rows),
            JobOutput::Batched(b) => batched.push(b),
            JobOutput::Convergence(rows) => {
                crate::studies::plot::write_svg(
                    &convergence::figure(&rows),
                    &figs.join(convergence::FIGURE),
                )?;
                converged = rows;
            }
            JobOutput::HertzFamilies(rows) => {
                crate::studies::plot::write_svg(
                    &hertz_families::figure(&rows),
                    &figs.join(hertz_families::FIGURE),
                )?;
                hertz = rows;
            }
            JobOutput::Smoothness(rows) => {
                crate::studies::plot::write_svg(
                    &smoothness::figure(&rows),
                    &figs.join(smoothness::FIGURE),
                )?;
                crate::studies::plot::write_svg(
                    &smoothness::figure_methods(&rows),
                    &figs.join(smoothness::FIGURE_METHODS),
                )?;
                smooth = rows;
            }
            JobOutput::Refinement(r) => {
                crate::studies::plot::write_svg(
                    &refinement::figure(&r),
                    &figs.join(refinement::FIGURE),
                )?;
                shape = Some(r);
            }
        }
    }
    // figure 7's second curve belongs with a validated leaf spring
    if !out.iter().any(|v| v.scene == "leaf-spring") {
        leaf_mu0 = None;
    }
    let validation = Validation {
        scenes: out,
        oracles: oracle_rows,
        imported,
        betas: opts.betas.clone(),
        floor: opts.floor,
        wall_seconds,
        batched,
        refinement: shape,
        convergence: converged,
        hertz_families: hertz,
        smoothness: smooth,
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

/// The scenes of a validation run: `names` (built-in names or TOML files; a name of
/// [`default_scenes`] takes that scene, e.g. the leaf spring on its validation mesh), or the
/// default scenes when `names` is empty. `full` as in [`default_scenes`].
pub fn resolve_scenes(names: &[String], full: bool) -> Result<Vec<Scene>, SceneError> {
    let defaults = default_scenes(full);
    if names.is_empty() {
        return Ok(defaults);
    }
    names
        .iter()
        .map(|n| match defaults.iter().find(|s| &s.name == n) {
            Some(s) => Ok(s.clone()),
            None => Scene::load(n),
        })
        .collect()
}

/// Everything the jobs of a sharded validation run depend on: shares of one run have the same
/// ([`merge_shards`] checks it, naming what differs).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ValidateSweep {
    /// The version of fricsens that ran the share.
    pub version: String,
    /// The scenes as named on the command line ([`resolve_scenes`]; empty: the defaults).
    pub names: Vec<String>,
    /// `--full`.
    pub full: bool,
    /// Each scene's name and its definition as TOML ([`Scene::to_toml`]).
    pub scenes: Vec<(String, String)>,
    /// [`ValidateOptions::betas`].
    pub betas: Vec<f64>,
    /// [`ValidateOptions::floor`].
    pub floor: f64,
    /// [`ValidateOptions::figure_beta`].
    pub figure_beta: f64,
    /// [`ValidateOptions::reduced_fdm`].
    pub reduced_fdm: Vec<String>,
    /// [`ValidateOptions::friction_laws`].
    pub friction_laws: Option<usize>,
    /// [`ValidateOptions::refined_batch`].
    pub refined_batch: bool,
    /// [`ValidateOptions::imported`].
    pub imported: Option<PathBuf>,
    /// The names of the jobs ([`plan`], [`Job::name`]).
    pub jobs: Vec<String>,
}

impl ValidateSweep {
    /// The sweep of `scenes` (resolved from `names` and `full`) with `opts`.
    pub fn new(names: &[String], full: bool, scenes: &[Scene], opts: &ValidateOptions) -> Self {
        ValidateSweep {
            version: env!("CARGO_PKG_VERSION").into(),
            names: names.to_vec(),
            full,
            scenes: scenes
                .iter()
                .map(|s| (s.name.clone(), s.to_toml().unwrap_or_default()))
                .collect(),
            betas: opts.betas.clone(),
            floor: opts.floor,
            figure_beta: opts.figure_beta,
            reduced_fdm: opts.reduced_fdm.clone(),
            friction_laws: opts.friction_laws,
            refined_batch: opts.refined_batch,
            imported: opts.imported.clone(),
            jobs: plan(scenes, opts).iter().map(|j| j.name(scenes)).collect(),
        }
    }

    /// The first thing in which `other` differs from this sweep.
    fn differs(&self, other: &ValidateSweep) -> Option<String> {
        let bits = |v: &[f64]| v.iter().map(|b| b.to_bits()).collect::<Vec<_>>();
        if self.version != other.version {
            return Some(format!(
                "fricsens versions ({} and {})",
                self.version, other.version
            ));
        }
        if self.names != other.names || self.full != other.full {
            return Some("scenes (as named on the command line, and --full)".into());
        }
        for ((a, ta), (b, tb)) in self.scenes.iter().zip(&other.scenes) {
            if a != b {
                return Some(format!("scenes ({a} and {b})"));
            }
            if ta != tb {
                return Some(format!("definitions of scene '{a}'"));
            }
        }
        if self.scenes.len() != other.scenes.len() {
            return Some("numbers of scenes".into());
        }
        if bits(&self.betas) != bits(&other.betas) {
            return Some("betas".into());
        }
        if self.floor.to_bits() != other.floor.to_bits() {
            return Some("error floors".into());
        }
        if self.figure_beta.to_bits() != other.figure_beta.to_bits() {
            return Some("figure betas".into());
        }
        if self.reduced_fdm != other.reduced_fdm {
            return Some("scenes whose FDM sweep is thinned (--full)".into());
        }
        if self.friction_laws != other.friction_laws {
            return Some("friction-law comparisons".into());
        }
        if self.refined_batch != other.refined_batch {
            return Some("batched-cost measurements".into());
        }
        if self.imported != other.imported {
            return Some("imported-geometry folders".into());
        }
        if self.jobs != other.jobs {
            return Some("lists of jobs".into());
        }
        None
    }

    /// The options of the run, writing into `out`.
    pub fn options(&self, out: PathBuf) -> ValidateOptions {
        ValidateOptions {
            out,
            betas: self.betas.clone(),
            floor: self.floor,
            figure_beta: self.figure_beta,
            reduced_fdm: self.reduced_fdm.clone(),
            friction_laws: self.friction_laws,
            refined_batch: self.refined_batch,
            imported: self.imported.clone(),
        }
    }
}

/// What one share of a validation run wrote (`OUT/partial-K-of-N.json`, kind `validate`).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ValidatePartial {
    /// `validate`.
    pub kind: String,
    /// Which share.
    pub shard: Shard,
    /// The run it is a share of.
    pub sweep: ValidateSweep,
    /// The share's wall time (s).
    pub wall_seconds: f64,
    /// `(job, its output)` for this share's jobs, the outputs in [`partial::to_exact_json`]'s
    /// form.
    pub jobs: Vec<(usize, serde_json::Value)>,
}

use crate::sensitivity::Shard;

/// The kind tag of a validation run's partial result.
pub const PARTIAL_KIND: &str = "validate";

/// Run share `shard` of the validation of `scenes` (resolved from `names` and `full` by
/// [`resolve_scenes`], which the merge repeats) and write `opts.out/partial-K-of-N.json`;
/// returns its path. `progress` sees each job's name as it starts.
pub fn run_shard(
    names: &[String],
    full: bool,
    scenes: &[Scene],
    opts: &ValidateOptions,
    shard: Shard,
    progress: &mut dyn FnMut(&str),
) -> Result<PathBuf, ValidateError> {
    let start = std::time::Instant::now();
    std::fs::create_dir_all(&opts.out).map_err(io(&opts.out))?;
    let sweep = ValidateSweep::new(names, full, scenes, opts);
    let mut jobs = Vec::new();
    for (j, job) in plan(scenes, opts).iter().enumerate() {
        if !shard.takes(j) {
            continue;
        }
        progress(&sweep.jobs[j]);
        let out = run_job(scenes, opts, job)?;
        let value = partial::to_exact_json(&out).map_err(|why| partial::ShardError::Read {
            path: sweep.jobs[j].clone(),
            why: format!("cannot be written: {why}"),
        })?;
        jobs.push((j, value));
    }
    let p = ValidatePartial {
        kind: PARTIAL_KIND.into(),
        shard,
        sweep,
        wall_seconds: start.elapsed().as_secs_f64(),
        jobs,
    };
    let path = partial::partial_path(&opts.out, shard);
    let json = serde_json::to_string(&p).expect("serialisable");
    write(&path, &json)?;
    Ok(path)
}

/// Merge the shares of one validation run (`files`: every `partial-K-of-N.json` once) and
/// write the report into `out`: the unsharded run's `data/*.csv`, `data/validation.json`,
/// figures and `README.md` (its timings aside: `wall_seconds` is the sum of the shares').
pub fn merge_shards(files: &[PathBuf], out: &Path) -> Result<Validation, ValidateError> {
    let mut partials = Vec::new();
    for f in files {
        let v = partial::read_partial(f, PARTIAL_KIND)?;
        let p: ValidatePartial =
            serde_json::from_value(v).map_err(|e| partial::ShardError::Read {
                path: f.display().to_string(),
                why: format!("not a partial result of a validation run: {e}"),
            })?;
        partials.push((f.display().to_string(), p));
    }
    let (first_file, first) = partials.first().ok_or(partial::ShardError::Empty)?;
    for (file, p) in &partials {
        if let Some(what) = first.sweep.differs(&p.sweep) {
            return Err(partial::ShardError::Mismatch {
                a: first_file.clone(),
                b: file.clone(),
                what,
            }
            .into());
        }
    }
    partial::check_coverage(
        &partials
            .iter()
            .map(|(f, p)| (p.shard, f.clone()))
            .collect::<Vec<_>>(),
    )?;
    let sweep = first.sweep.clone();
    let scenes = resolve_scenes(&sweep.names, sweep.full)?;
    for (s, (name, toml)) in scenes.iter().zip(&sweep.scenes) {
        if &s.name != name || &s.to_toml().unwrap_or_default() != toml {
            return Err(partial::ShardError::SceneChanged(name.clone()).into());
        }
    }
    if scenes.len() != sweep.scenes.len() {
        return Err(partial::ShardError::SceneChanged(
            sweep.scenes.last().map(|s| s.0.clone()).unwrap_or_default(),
        )
        .into());
    }
    let opts = sweep.options(out.to_path_buf());
    if plan(&scenes, &opts)
        .iter()
        .map(|j| j.name(&scenes))
        .ne(sweep.jobs.iter().cloned())
    {
        return Err(partial::ShardError::Mismatch {
            a: first_file.clone(),
            b: "this merge".into(),
            what: "lists of jobs".into(),
        }
        .into());
    }
    let wall_seconds: f64 = partials.iter().map(|(_, p)| p.wall_seconds).sum();
    let mut shares = Vec::new();
    for (file, p) in partials {
        let mut jobs = Vec::new();
        for (j, value) in p.jobs {
            let o: JobOutput =
                partial::from_exact_json(value).map_err(|why| partial::ShardError::Read {
                    path: file.clone(),
                    why: format!("job {j}: {why}"),
                })?;
            jobs.push((j, o));
        }
        shares.push((p.shard, jobs));
    }
    let outputs = partial::collect_jobs(&sweep.jobs, shares)?;
    finish(&scenes, &opts, outputs, wall_seconds)
}
