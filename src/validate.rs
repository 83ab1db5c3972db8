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

use crate::plot::{write_svg, Figure, PlotError, Style};
use crate::response::ResponseKind;
use crate::scene::{
    builtin, leaf_spring, stacked_leaves, LeafSpringSpec, Scene, SceneError, StackedLeavesSpec,
    StripSpec,
};
use crate::sensitivity::{
    run_fdm_sweep, run_inline_sweep, Method, Parameter, SensitivityResults, Settings,
};
use crate::solver::AnalysisError;
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
    /// Show progress on the terminal.
    pub progress: bool,
}

impl Default for ValidateOptions {
    fn default() -> Self {
        ValidateOptions {
            out: PathBuf::from("validation"),
            betas: (1..=14).map(|k| 10f64.powi(-k)).collect(),
            floor: 1e-3,
            figure_beta: 1e-6,
            progress: false,
        }
    }
}

/// Why validation failed.
#[derive(Debug, thiserror::Error)]
pub enum ValidateError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("scene '{scene}': {source}")]
    Analysis {
        scene: String,
        #[source]
        source: AnalysisError,
    },
    #[error(transparent)]
    Plot(#[from] PlotError),
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
}

/// The scenes of the default validation run: the paper's indentation example and the oracle
/// scenes; the leaf spring too unless `reduced`.
pub fn default_scenes(reduced: bool) -> Vec<Scene> {
    let mut v = Vec::new();
    let named = |n: &str| builtin(n).expect("built-in scene");
    v.push(named("indentation"));
    // The leaf spring's primal takes about a minute on its default mesh and its coarse mesh
    // does not converge through the load path yet: it is validated only with `--full`.
    if !reduced {
        let mut leaf = leaf_spring(&LeafSpringSpec::default());
        leaf.name = "leaf-spring".into();
        v.push(leaf);
    }
    v.push(stacked_leaves(&StackedLeavesSpec::default()));
    for n in ["strip-pullout", "uniaxial-j2", "klarbring-2dof", "jenkins"] {
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
    pub scene: String,
    pub method: String,
    pub beta: f64,
    pub param: String,
    /// Largest relative error against DDM over responses and unflagged increments.
    pub error: f64,
    /// Wall time of the method's sensitivity work for all parameters / primal wall time.
    pub cost_ratio: f64,
}

/// A closed-form check.
#[derive(Clone, Debug, serde::Serialize)]
pub struct OracleRow {
    pub scene: String,
    pub quantity: String,
    pub expected: f64,
    pub got: f64,
    pub rel_error: f64,
    pub tolerance: f64,
    pub pass: bool,
}

/// Everything validated for one scene.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SceneValidation {
    pub scene: String,
    pub description: String,
    pub params: Vec<String>,
    pub unknowns: usize,
    pub increments: usize,
    pub primal_seconds: f64,
    /// Increments flagged non-differentiable (DDM).
    pub flagged: Vec<usize>,
    pub ddm_cost_ratio: f64,
    pub errors: Vec<ErrorRow>,
    #[serde(skip)]
    pub ddm: SensitivityResults,
    #[serde(skip)]
    pub sweeps: Vec<SensitivityResults>,
}

/// The whole validation.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Validation {
    pub scenes: Vec<SceneValidation>,
    pub oracles: Vec<OracleRow>,
    pub betas: Vec<f64>,
    pub floor: f64,
    pub wall_seconds: f64,
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
    for r in 0..nr {
        let max = |f: &dyn Fn(&crate::sensitivity::IncrementSensitivity) -> f64| {
            reference.increments.iter().map(f).fold(0.0f64, f64::max)
        };
        let scale = max(&|i| i.derivatives[r][p].abs());
        let size = max(&|i| i.values[r].abs());
        if scale == 0.0 || b.abs().max(1.0) * scale < 1e-9 * size {
            continue;
        }
        for (n, (a, b)) in reference
            .increments
            .iter()
            .zip(&other.increments)
            .enumerate()
        {
            if flagged.get(n).copied().unwrap_or(false) {
                continue;
            }
            let d = a.derivatives[r][p];
            let e = (b.derivatives[r][p] - d).abs() / d.abs().max(floor * scale);
            worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
        }
    }
    worst
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
    let params: Vec<Parameter> = scene
        .study
        .params
        .iter()
        .map(|n| Parameter::by_name(&model, n))
        .collect::<Result<_, _>>()
        .map_err(wrap)?;
    let mut settings = vec![Settings {
        method: Method::Ddm,
        ..Settings::default()
    }];
    for m in [Method::Sdm, Method::SdmCentral] {
        for &beta in &opts.betas {
            settings.push(Settings {
                method: m,
                beta,
                ..Settings::default()
            });
        }
    }
    let (primal, mut inline) = run_inline_sweep(&model, &params, &settings).map_err(wrap)?;
    let ddm = inline.remove(0);
    let (_, fdm) = run_fdm_sweep(&model, &params, &opts.betas, true).map_err(wrap)?;
    let primal_seconds = ddm.primal_seconds.max(1e-9);
    let flagged: Vec<bool> = ddm.increments.iter().map(|i| !i.kinks.is_empty()).collect();
    let mut errors = Vec::new();
    let sweeps: Vec<SensitivityResults> = inline.into_iter().chain(fdm).collect();
    for s in &sweeps {
        let method = s.method.map(|m| m.name()).unwrap_or("?").to_string();
        for (p, name) in s.parameters.iter().enumerate() {
            errors.push(ErrorRow {
                scene: scene.name.clone(),
                method: method.clone(),
                beta: s.beta,
                param: name.clone(),
                error: relative_error(&ddm, s, p, params[p].value, opts.floor, &flagged),
                cost_ratio: s.cost.wall_seconds / primal_seconds,
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
        errors,
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
    let mut out = Vec::new();
    let row = |quantity: &str, expected: f64, got: f64, tolerance: f64| {
        let rel = ((got - expected) / expected).abs();
        OracleRow {
            scene: v.scene.clone(),
            quantity: quantity.to_string(),
            expected,
            got,
            rel_error: rel,
            tolerance,
            pass: rel <= tolerance,
        }
    };
    let res = &v.ddm;
    let r_of = |name: &str| res.responses.iter().position(|r| r == name);
    let p_of = |name: &str| res.parameters.iter().position(|r| r == name);
    let at = |t: f64| {
        res.increments
            .iter()
            .find(|i| (i.time - t).abs() < 1e-9)
            .cloned()
    };
    match v.scene.as_str() {
        "stacked-leaves" => {
            let s = StackedLeavesSpec::default();
            if let (Some(r), Some(p), Some(end)) = (r_of("delta"), p_of("mu"), at(1.0)) {
                let mu = s.mu;
                let d = s.thickness;
                let expected =
                    -(s.deflection() * (1.0 - 3.0 * mu * d / (4.0 * s.length)) + 0.5 * s.clearance);
                // beam theory: shear deformation and the tip's local flexibility (~(h/L))
                out.push(row(
                    "delta at P (loading, slipping)",
                    expected,
                    end.values[r],
                    0.02,
                ));
                // oracles.md: compare d delta / d mu to 5-10 %
                out.push(row(
                    "d delta / d mu at P (loading): + P d L^2 / (8 E I)",
                    s.deflection_mu_slope(),
                    end.derivatives[r][p],
                    0.10,
                ));
            }
        }
        "strip-pullout" => {
            let s = StripSpec::default();
            let k = s.young * s.thickness * s.width * s.mu * s.n;
            if let (Some(r), Some(pm), Some(pe), Some(end)) =
                (r_of("u0"), p_of("mu"), p_of("E"), at(1.0))
            {
                let u0 = s.force * s.force / (2.0 * k);
                // oracles.md: 1-2 % with thickness / slip length < 0.05
                out.push(row("u0 = F^2 / (2 K) at F1", u0, end.values[r], 0.02));
                out.push(row(
                    "du0/dmu = -u0/mu at F1",
                    -u0 / s.mu,
                    end.derivatives[r][pm],
                    0.02,
                ));
                out.push(row(
                    "du0/dE = -u0/E at F1",
                    -u0 / s.young,
                    end.derivatives[r][pe],
                    0.02,
                ));
            }
        }
        "cantilever-small" => {
            let c = crate::scene::CantileverSpec::small_deflection();
            if let (Some(r), Some(p), Some(end)) = (
                r_of("tip-deflection"),
                p_of("E"),
                res.increments.last().cloned(),
            ) {
                let delta = c.load() * c.length.powi(3) / (3.0 * c.young * c.inertia());
                // Euler-Bernoulli: shear deflection adds ~ 3 E h^2 / (10 G L^2) = 0.2 %
                out.push(row(
                    "tip deflection P L^3 / (3 E I)",
                    -delta,
                    end.values[r],
                    0.01,
                ));
                out.push(row(
                    "d tip / d E = -tip / E",
                    delta / c.young,
                    end.derivatives[r][p],
                    0.01,
                ));
            }
        }
        _ => {}
    }
    out
}

fn sweep_of(v: &SceneValidation, m: Method, beta: f64) -> Option<&SensitivityResults> {
    v.sweeps
        .iter()
        .find(|s| s.method == Some(m) && (s.beta / beta - 1.0).abs() < 1e-9)
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
            .filter(|e| e.param == param && e.method == m.name())
            .map(|e| (e.beta, e.error))
            .collect();
        f = f.series(m.name(), pts, Style::LinePoints);
    }
    f
}

/// The time history of a response's derivative by every method at one beta.
fn history_figure(
    v: &SceneValidation,
    response: &str,
    param: &str,
    beta: f64,
    title: &str,
) -> Option<Figure> {
    let r = v.ddm.responses.iter().position(|x| x == response)?;
    let p = v.ddm.parameters.iter().position(|x| x == param)?;
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
    let start = std::time::Instant::now();
    let data = opts.out.join("data");
    let figs = opts.out.join("figures");
    for d in [&opts.out, &data, &figs] {
        std::fs::create_dir_all(d).map_err(io(d))?;
    }
    let bar = if opts.progress {
        indicatif::ProgressBar::new(scenes.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let mut out = Vec::new();
    let mut oracle_rows = Vec::new();
    for scene in scenes {
        bar.set_message(scene.name.clone());
        let v = validate_scene(scene, opts)?;
        oracle_rows.extend(oracles(&v));
        write_scene_data(&v, &data, opts.figure_beta)?;
        out.push(v);
        bar.inc(1);
    }
    bar.finish_and_clear();
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
    let validation = Validation {
        scenes: out,
        oracles: oracle_rows,
        betas: opts.betas.clone(),
        floor: opts.floor,
        wall_seconds: start.elapsed().as_secs_f64(),
    };
    write_figures(&validation, scenes, leaf_mu0.as_deref(), opts, &figs)?;
    let json = serde_json::to_string_pretty(&validation).expect("serialisable");
    write(&data.join("validation.json"), &json)?;
    write(&opts.out.join("README.md"), &report(&validation, opts))?;
    Ok(validation)
}

/// Errors of every (method, beta, parameter); sensitivity histories of DDM and of the other
/// methods at the figures' beta.
fn write_scene_data(v: &SceneValidation, dir: &Path, beta: f64) -> Result<(), ValidateError> {
    let mut e = String::from("scene,method,beta,param,error,cost_ratio\n");
    for r in &v.errors {
        let _ = writeln!(
            e,
            "{},{},{:e},{},{:e},{:e}",
            r.scene, r.method, r.beta, r.param, r.error, r.cost_ratio
        );
    }
    write(&dir.join(format!("{}-errors.csv", v.scene)), &e)?;
    let mut s =
        String::from("method,beta,increment,time,response,param,value,derivative,flagged\n");
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
                        "{m},{:e},{},{:e},{name},{pn},{:e},{:e},{}",
                        res.beta,
                        inc.increment,
                        inc.time,
                        inc.values[r],
                        inc.derivatives[r][p],
                        flagged(inc.increment)
                    );
                }
            }
        }
    }
    write(&dir.join(format!("{}-sensitivities.csv", v.scene)), &s)
}

fn write_figures(
    val: &Validation,
    scenes: &[Scene],
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
                .filter(|e| e.method == m.name())
                .map(|e| (e.cost_ratio, e.error))
                .collect();
            f = f.series(m.name(), pts, Style::Points);
        }
        write_svg(&f, &dir.join(format!("{}-cost.svg", v.scene)))?;
    }
    let beta = opts.figure_beta;
    if let Some(v) = val.scenes.iter().find(|v| v.scene == "indentation") {
        let scene = scenes.iter().find(|s| s.name == "indentation");
        if let Some(model) = scene.and_then(|s| s.build().ok()) {
            let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
            let last = v.ddm.increments.len() - 1;
            let p = v.ddm.parameters.iter().position(|n| n == "mu");
            let pts = |s: &SensitivityResults, deriv: bool| -> Vec<(f64, f64)> {
                model
                    .responses
                    .iter()
                    .enumerate()
                    .filter_map(|(r, resp)| match resp.kind {
                        ResponseKind::ContactPressure { pair, node, .. } => {
                            let xr = x[model.contacts[pair].hitting[node]][0];
                            let inc = &s.increments[last];
                            let y = if deriv {
                                inc.derivatives[r][p?]
                            } else {
                                inc.values[r]
                            };
                            (xr.abs() <= 40.0).then_some((xr, y))
                        }
                        _ => None,
                    })
                    .collect()
            };
            let fig4 = Figure::new(
                "Fig. 4: contact pressure after sliding 3.33 mm (indentation)",
                "x (mm, reference position of the surface node)",
                "contact pressure (MPa)",
            )
            .series("fricsens", pts(&v.ddm, false), Style::LinePoints);
            write_svg(&fig4, &dir.join("fig4-indentation-pressure.svg"))?;
            let mut fig5 = Figure::new(
                "Fig. 5: d(contact pressure)/d mu after sliding (indentation)",
                "x (mm, reference position of the surface node)",
                "dp / d mu (MPa)",
            )
            .series("ddm", pts(&v.ddm, true), Style::Line);
            for m in BETA_METHODS {
                if let Some(s) = sweep_of(v, m, beta) {
                    fig5 = fig5.series(
                        format!("{} (beta {beta:.0e})", m.name()),
                        pts(s, true),
                        Style::Points,
                    );
                }
            }
            write_svg(&fig5, &dir.join("fig5-indentation-dpdmu.svg"))?;
        }
    }
    if let Some(v) = val.scenes.iter().find(|v| v.scene == "leaf-spring") {
        let scene = scenes.iter().find(|s| s.name == "leaf-spring");
        let stroke = |t: f64| -> f64 {
            scene
                .and_then(|s| s.contacts.iter().find(|c| c.name == "block"))
                .and_then(|c| match &c.target {
                    crate::scene::TargetSpec::Rigid { motion, .. } => motion.first().map(|m| {
                        let a = crate::model::Amplitude {
                            points: m.amplitude.clone(),
                        };
                        -m.value * a.at(t)
                    }),
                    _ => None,
                })
                .unwrap_or(t)
        };
        if let Some(r) = v.ddm.responses.iter().position(|n| n == "block-force") {
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

fn report(val: &Validation, opts: &ValidateOptions) -> String {
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
    let _ = writeln!(s, "Sensitivity wall time for all of a scene's parameters over the primal analysis, at beta = {:.0e} (SDM and DDM share the primal run; FDM is reruns).\n", opts.figure_beta);
    let _ = writeln!(
        s,
        "| scene | parameters | DDM | SDM | SDM central | FDM | FDM central |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for v in &val.scenes {
        let cost = |m: Method| {
            v.errors
                .iter()
                .find(|e| e.method == m.name() && (e.beta / opts.figure_beta - 1.0).abs() < 1e-9)
                .map(|e| format!("{:.3}", e.cost_ratio))
                .unwrap_or_else(|| "-".into())
        };
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {} | {} | {} | {} |",
            v.scene,
            v.params.len(),
            v.ddm_cost_ratio,
            cost(Method::Sdm),
            cost(Method::SdmCentral),
            cost(Method::Fdm),
            cost(Method::FdmCentral)
        );
    }
    let _ = writeln!(s, "\n## Closed forms\n");
    let _ = writeln!(
        s,
        "| scene | quantity | expected | fricsens (DDM) | relative error | tolerance | |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for o in &val.oracles {
        let _ = writeln!(
            s,
            "| {} | {} | {:.6e} | {:.6e} | {:.2e} | {} | {} |",
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
    let _ = writeln!(s, "## Error against perturbation size\n");
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
