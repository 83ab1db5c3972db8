//! The adjoint's study (issue 28): what it costs against the number of parameters, where it
//! pays, and what a sensitivity map over every element looks like.
//!
//! * **Crossover.** The cost of DDM, SDM, FDM and the adjoint (primal included: each method is
//!   one call of [`run_sensitivity`]) against the number of parameters `N` = 1, 10, 100,
//!   1,000, 10,000 where the model has them, on the leaf spring and the indentation. The
//!   parameters are element-wise material fields (every element's `E`, then `sigma_y`, `H`,
//!   `nu`), friction per hitting node where the elements run out. A method is measured at
//!   the two smallest counts, and then while its cost, extrapolated from what it measured,
//!   stays within the budget; beyond, its cost
//!   is the least-squares line `a + b N` through its measurements (drawn dashed, marked in the
//!   CSV). The crossover against each method is where the two lines cross.
//! * **Sensitivity map.** `d(block force at the end of the leaf spring's path)/d(sigma_y of
//!   each element)` and `d/d(E of each element)` by the adjoint, written as cell data
//!   (`map.vtu`) and drawn (`map-sigma_y.svg`, `map-E.svg`), spot-checked by DDM at the five
//!   elements where `|d/d sigma_y|` is largest.
//! * **Many parameters.** Every element's `E`, `sigma_y` and `H` on the leaf spring refined
//!   (`--large`; 6: 14,832 parameters) over its whole path, the adjoint's cost against one
//!   primal analysis.

use crate::model::Model;
use crate::output::{write_vtu, ExtraFields, OutputError};
use crate::scene::{Scene, SceneError};
use crate::sensitivity::{run_sensitivity, IncrementSensitivity, Method, Parameter, Settings};
use crate::solver::AnalysisError;
use crate::studies::plot::{write_svg_stack, Figure, PlotError, Style};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Errors of the adjoint study.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AdjointStudyError {
    /// A scene does not load or build.
    #[error("scene: {0}")]
    Scene(#[from] SceneError),
    /// An analysis failed.
    #[error("analysis: {0}")]
    Analysis(#[from] AnalysisError),
    /// A field parameter does not resolve.
    #[error("parameter: {0}")]
    Parameter(#[from] crate::design::ParameterError),
    /// Writing a file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// Drawing a figure.
    #[error("{0}")]
    Plot(#[from] PlotError),
    /// Writing the VTK file.
    #[error("{0}")]
    Output(#[from] OutputError),
    /// The refined leaf spring.
    #[error("{0}")]
    Scaling(#[from] crate::studies::scaling::ScalingError),
}

/// What the study runs.
#[derive(Clone, Debug)]
pub struct StudyOptions {
    /// Output directory.
    pub out: PathBuf,
    /// The coarse leaf spring alone (checks the tool).
    pub quick: bool,
    /// Seconds a method may spend on one measurement before the larger counts are
    /// extrapolated.
    pub budget_seconds: f64,
    /// Refinement of the leaf spring for the many-parameter run (`None`: not run).
    pub large: Option<f64>,
}

/// One point of the crossover figure.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CostPoint {
    /// Scene.
    pub scene: String,
    /// Method name.
    pub method: String,
    /// Number of parameters.
    pub n: usize,
    /// Wall seconds of the whole call (primal included).
    pub seconds: f64,
    /// Measured (else extrapolated from the measurements).
    pub measured: bool,
}

/// The number of parameters beyond which the adjoint is cheaper than a method.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Crossover {
    /// Scene.
    pub scene: String,
    /// The other method.
    pub method: String,
    /// Where the fitted cost lines cross (`None`: the adjoint is never cheaper on them).
    pub n: Option<f64>,
    /// The adjoint's cost line `a + b N` (seconds).
    pub adjoint_line: (f64, f64),
    /// The method's cost line.
    pub method_line: (f64, f64),
}

/// One element of the map checked by DDM.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SpotCheck {
    /// The parameter.
    pub param: String,
    /// The adjoint's derivative.
    pub adjoint: f64,
    /// DDM's.
    pub ddm: f64,
    /// Their difference relative to the largest of the map's derivatives in that parameter.
    pub difference: f64,
}

/// The many-parameter run's element-wise fields.
const LARGE_FIELDS: [&str; 3] = ["E", "sigma_y", "H"];

/// The least reach of the many-parameter run's leaf-leaf contact search along the leaves,
/// mm: half again the millimetre the leaves slide on each other over the whole path (the
/// refined scene's `10 / r` is larger up to a refinement of 6.7).
const LARGE_MIN_REACH: f64 = 1.5;

/// The many-parameter run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Large {
    /// Refinement factor of the leaf spring.
    pub refinement: f64,
    /// Elements.
    pub elements: usize,
    /// Parameters.
    pub parameters: usize,
    /// Increments converged along the path (sub-increments of cutbacks included).
    pub increments: usize,
    /// Primal seconds.
    pub primal_seconds: f64,
    /// The adjoint's seconds beyond the primal.
    pub adjoint_seconds: f64,
    /// Of which evaluations (some of them beside the factorizations and solves: the two add
    /// up to more than the sweep where they overlap).
    pub evaluation_seconds: f64,
    /// Of which solves and factorizations.
    pub solve_seconds: f64,
    /// Responses differentiated (the functional: each at the path's end).
    pub responses: usize,
    /// Bytes the forward run kept for the sweep (its states, tangents or factors).
    pub stored_bytes: usize,
    /// DDM at the element of each field where the block force's derivative is largest.
    pub spot_checks: Vec<SpotCheck>,
}

/// The study's results.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct AdjointStudy {
    /// Every point of the crossover figure.
    pub costs: Vec<CostPoint>,
    /// The crossovers.
    pub crossovers: Vec<Crossover>,
    /// The scene of the map and its elements.
    pub map_scene: String,
    /// Seconds of the map's adjoint run (primal included), and its parameter count.
    pub map_seconds: f64,
    /// Parameters of the map.
    pub map_parameters: usize,
    /// DDM at five elements.
    pub spot_checks: Vec<SpotCheck>,
    /// The many-parameter run.
    pub large: Option<Large>,
    /// The coarse leaf spring alone (`--quick`).
    pub quick: bool,
    /// Wall seconds of the study.
    pub wall_seconds: f64,
}

const METHODS: [Method; 4] = [Method::Adjoint, Method::Ddm, Method::Sdm, Method::Fdm];

/// Settings of one measurement: the adjoint's functional at the last increment.
fn settings(model: &Model, method: Method) -> Settings {
    Settings {
        method,
        adjoint_at: model.times.last().copied().into_iter().collect(),
        ..Settings::default()
    }
}

/// The first `n` parameters of the fields `names`, in order.
fn first_params(
    model: &Model,
    names: &[String],
    n: usize,
) -> Result<Vec<Parameter>, AdjointStudyError> {
    let mut out = Vec::new();
    for name in names {
        if out.len() >= n {
            break;
        }
        out.extend(Parameter::expand(model, name)?);
    }
    out.truncate(n);
    Ok(out)
}

/// Least-squares line `a + b N` through the points (one point: through it with `a` the
/// primal's seconds).
fn fit(points: &[(f64, f64)], primal: f64) -> (f64, f64) {
    match points {
        [] => (primal, 0.0),
        [(n, t)] => (primal, ((t - primal) / n).max(0.0)),
        _ => {
            let k = points.len() as f64;
            let (sx, sy) = points
                .iter()
                .fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
            let (mx, my) = (sx / k, sy / k);
            let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
            let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
            let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
            (my - b * mx, b)
        }
    }
}

/// The crossover study on one scene.
fn crossover(
    scene: &str,
    fields: &[String],
    opts: &StudyOptions,
    study: &mut AdjointStudy,
) -> Result<(), AdjointStudyError> {
    let model = Scene::load(scene)?.build()?;
    let available = first_params(&model, fields, usize::MAX)?.len();
    let mut counts: Vec<usize> = [1, 10, 100, 1_000, 10_000]
        .into_iter()
        .filter(|n| *n <= available)
        .collect();
    if counts.last().is_some_and(|l| *l < available) {
        counts.push(available);
    }
    let mut lines = Vec::new();
    let mut primal = f64::NAN;
    for method in METHODS {
        let mut measured: Vec<(f64, f64)> = Vec::new();
        for &n in &counts {
            let line = fit(&measured, if primal.is_nan() { 0.0 } else { primal });
            let predicted = line.0 + line.1 * n as f64;
            // two points at least (a line needs them: one parameter alone does not tell the
            // method's fixed cost from its cost per parameter)
            let measure = measured.len() < 2 || predicted <= opts.budget_seconds;
            let seconds = if measure {
                let ps = first_params(&model, fields, n)?;
                let t = Instant::now();
                let (res, _) = run_sensitivity(&model, &ps, &settings(&model, method))?;
                let seconds = t.elapsed().as_secs_f64();
                if primal.is_nan() {
                    primal = res.cost.wall_seconds;
                }
                measured.push((n as f64, seconds));
                eprintln!(
                    "{scene}: {} with {n} parameters: {seconds:.2} s",
                    method.name()
                );
                seconds
            } else {
                predicted
            };
            study.costs.push(CostPoint {
                scene: scene.to_string(),
                method: method.name().to_string(),
                n,
                seconds,
                measured: measure,
            });
        }
        lines.push((method, fit(&measured, primal)));
    }
    let adjoint = lines[0].1;
    for &(method, line) in &lines[1..] {
        // a_A + b_A N = a_m + b_m N
        let n = if adjoint.0 <= line.0 && adjoint.1 <= line.1 {
            Some(1.0)
        } else if line.1 > adjoint.1 {
            Some(((adjoint.0 - line.0) / (line.1 - adjoint.1)).max(1.0))
        } else {
            None
        };
        study.crossovers.push(Crossover {
            scene: scene.to_string(),
            method: method.name().to_string(),
            n,
            adjoint_line: adjoint,
            method_line: line,
        });
    }
    Ok(())
}

/// The map: every element's `sigma_y` and `E` of the leaf spring by the adjoint, written,
/// drawn and spot-checked.
fn map(
    scene: &str,
    opts: &StudyOptions,
    study: &mut AdjointStudy,
) -> Result<(), AdjointStudyError> {
    let model = Scene::load(scene)?.build()?;
    let quantities = ["sigma_y", "E"];
    let ps = element_fields(&model, &quantities)?;
    let r = block_force(&model);
    let t = Instant::now();
    let (res, adj) = run_sensitivity(&model, &ps, &settings(&model, Method::Adjoint))?;
    study.map_seconds = t.elapsed().as_secs_f64();
    study.map_parameters = ps.len();
    study.map_scene = scene.to_string();
    let last = adj.increments.last().expect("a converged increment");
    let ne = model.mesh.n_elements();
    let per_quantity = ps.len() / quantities.len();
    let mut cells = Vec::new();
    for (qi, q) in quantities.iter().enumerate() {
        let mut v = vec![0.0; ne];
        for (k, p) in ps
            .iter()
            .enumerate()
            .skip(qi * per_quantity)
            .take(per_quantity)
        {
            if let [crate::model::DesignParam::ElementMaterial { element, .. }] = p.targets[..] {
                v[element] = last.derivatives[r][k];
            }
        }
        cells.push((format!("d({})/d({q})", model.responses[r].name), 1, v));
    }
    let k = res.states.len() - 1;
    std::fs::create_dir_all(&opts.out).map_err(|source| AdjointStudyError::Io {
        path: opts.out.clone(),
        source,
    })?;
    write_vtu(
        &opts.out.join("map.vtu"),
        &model,
        &res.states[k],
        &res.stresses[k],
        &ExtraFields {
            point: Vec::new(),
            cell: cells.clone(),
        },
    )?;
    for ((name, _, v), q) in cells.iter().zip(quantities) {
        let svg = map_svg(&model, v, name);
        let path = opts.out.join(format!("map-{q}.svg"));
        std::fs::write(&path, svg).map_err(|source| AdjointStudyError::Io { path, source })?;
    }
    // DDM at the five elements where |d/d sigma_y| is largest, both quantities
    let mut order: Vec<usize> = (0..per_quantity).collect();
    order.sort_by(|a, b| {
        last.derivatives[r][*b]
            .abs()
            .total_cmp(&last.derivatives[r][*a].abs())
    });
    let picked: Vec<usize> = (order.iter().take(5))
        .flat_map(|&k| [k, k + per_quantity])
        .collect();
    study.spot_checks = ddm_spot_checks(&model, &ps, per_quantity, last, r, &picked)?;
    Ok(())
}

/// Every element's material parameter of each of `fields`, one field after the other
/// (each over every body's elements).
fn element_fields(model: &Model, fields: &[&str]) -> Result<Vec<Parameter>, AdjointStudyError> {
    let mut ps = Vec::new();
    for q in fields {
        for body in &model.bodies {
            ps.extend(Parameter::expand(model, &format!("{}.{q}[*]", body.name))?);
        }
    }
    Ok(ps)
}

/// The leaf spring's block force among the responses (the first response elsewhere).
fn block_force(model: &Model) -> usize {
    (model.responses.iter())
        .position(|r| r.name == "block-force")
        .unwrap_or(0)
}

/// DDM at the parameters `picked` of `ps` (fields of `per_quantity` members each, one after
/// the other) against the adjoint's derivatives of response `r` at increment `last`, each
/// difference relative to the largest adjoint derivative in its field.
fn ddm_spot_checks(
    model: &Model,
    ps: &[Parameter],
    per_quantity: usize,
    last: &IncrementSensitivity,
    r: usize,
    picked: &[usize],
) -> Result<Vec<SpotCheck>, AdjointStudyError> {
    let spot: Vec<Parameter> = picked.iter().map(|&k| ps[k].clone()).collect();
    let (_, ddm) = run_sensitivity(model, &spot, &settings(model, Method::Ddm))?;
    let ddm_last = ddm.increment_at(last.time).expect("the same path");
    Ok((picked.iter().enumerate())
        .map(|(i, &k)| {
            let q = k / per_quantity;
            let scale = (q * per_quantity..(q + 1) * per_quantity)
                .map(|j| last.derivatives[r][j].abs())
                .fold(0.0, f64::max);
            let (a, d) = (last.derivatives[r][k], ddm_last.derivatives[r][i]);
            SpotCheck {
                param: ps[k].name.clone(),
                adjoint: a,
                ddm: d,
                difference: (a - d).abs() / scale.max(f64::MIN_POSITIVE),
            }
        })
        .collect())
}

/// The spot checks' table.
fn spot_table(s: &mut String, checks: &[SpotCheck]) {
    let _ = writeln!(
        s,
        "| parameter | adjoint | DDM | difference |\n|---|---|---|---|"
    );
    for c in checks {
        let _ = writeln!(
            s,
            "| {} | {:.9e} | {:.9e} | {:.1e} |",
            c.param, c.adjoint, c.ddm, c.difference
        );
    }
}

/// An SVG of a cell field over the mesh seen along z (each element's face of least z), the
/// y axis stretched so that the drawing is legible, blue (negative) to red (positive).
fn map_svg(model: &Model, v: &[f64], title: &str) -> String {
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let polys: Vec<(Vec<[f64; 2]>, f64)> = (model.mesh.elements().enumerate())
        .filter(|(e, (_, conn))| conn.len() >= 4 && v[*e].is_finite())
        .map(|(e, (_, conn))| {
            let zmin = conn.iter().map(|&n| x[n][2]).fold(f64::INFINITY, f64::min);
            let mut pts: Vec<[f64; 2]> = (conn.iter())
                .filter(|&&n| x[n][2] <= zmin + 1e-9 * (1.0 + zmin.abs()))
                .map(|&n| [x[n][0], x[n][1]])
                .collect();
            let c = pts
                .iter()
                .fold([0.0, 0.0], |a, p| [a[0] + p[0], a[1] + p[1]]);
            let c = [c[0] / pts.len() as f64, c[1] / pts.len() as f64];
            pts.sort_by(|a, b| {
                let ang = |p: &[f64; 2]| (p[1] - c[1]).atan2(p[0] - c[0]);
                ang(a).total_cmp(&ang(b))
            });
            (pts, v[e])
        })
        .collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (pts, _) in &polys {
        for p in pts {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
    }
    let (w, h) = (900.0, 300.0);
    let sx = w / (hi[0] - lo[0]).max(f64::MIN_POSITIVE);
    let sy = h / (hi[1] - lo[1]).max(f64::MIN_POSITIVE);
    let stretch = sy / sx;
    let max = polys.iter().map(|p| p.1.abs()).fold(0.0, f64::max);
    let colour = |v: f64| {
        let t = if max > 0.0 { v / max } else { 0.0 };
        let fade = |s: f64| (255.0 * (1.0 - s.abs())).round() as u8;
        if t >= 0.0 {
            format!("rgb(255,{},{})", fade(t), fade(t))
        } else {
            format!("rgb({},{},255)", fade(t), fade(t))
        }
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" font-family="sans-serif" font-size="13">"#,
        w + 40.0,
        h + 90.0
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="20" y="22">{title} per element (x along, y stretched {stretch:.1} times)</text>"#
    );
    for (pts, val) in &polys {
        let path: Vec<String> = (pts.iter())
            .map(|p| {
                format!(
                    "{:.2},{:.2}",
                    20.0 + (p[0] - lo[0]) * sx,
                    40.0 + h - (p[1] - lo[1]) * sy
                )
            })
            .collect();
        let _ = writeln!(
            s,
            r#"<polygon points="{}" fill="{}" stroke="grey" stroke-width="0.3"/>"#,
            path.join(" "),
            colour(*val)
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="20" y="{}">blue -{max:.3e} .. white 0 .. red +{max:.3e}</text>"#,
        h + 70.0
    );
    s.push_str("</svg>\n");
    s
}

/// The many-parameter run: every element's `E`, `sigma_y` and `H` of the leaf spring refined
/// by `refinement` (three element-wise fields: 10,000 parameters and more from a refinement
/// of 5, 3,430 elements), over its whole path (loading, unloading, reloading), the gradient
/// of every response at its end.
fn large(refinement: f64, study: &mut AdjointStudy) -> Result<(), AdjointStudyError> {
    use crate::studies::scaling::ScalingScene;
    let mut spec = ScalingScene::LeafSpring.leaf_spec(refinement)?;
    // the scaling study's reach along the leaves (10 / r mm) is sized for two increments;
    // over the whole path the leaves slide about 1 mm on each other
    spec.search_along = spec.search_along.max(LARGE_MIN_REACH);
    let model = crate::scene::leaf_spring(&spec).build()?;
    let ps = element_fields(&model, &LARGE_FIELDS)?;
    let (res, adj) = run_sensitivity(&model, &ps, &settings(&model, Method::Adjoint))?;
    // DDM at the element of each field where the block force's derivative is largest
    let last = adj.increments.last().expect("a converged increment");
    let r = block_force(&model);
    // every field has a member per element
    debug_assert_eq!(ps.len(), LARGE_FIELDS.len() * model.mesh.n_elements());
    let per_quantity = ps.len() / LARGE_FIELDS.len();
    let picked: Vec<usize> = (0..LARGE_FIELDS.len())
        .filter_map(|q| {
            (q * per_quantity..(q + 1) * per_quantity).max_by(|a, b| {
                last.derivatives[r][*a]
                    .abs()
                    .total_cmp(&last.derivatives[r][*b].abs())
            })
        })
        .collect();
    let spot_checks = ddm_spot_checks(&model, &ps, per_quantity, last, r, &picked)?;
    study.large = Some(Large {
        refinement,
        elements: model.mesh.n_elements(),
        parameters: ps.len(),
        // the first of the times is the initial state's
        increments: res.times.len() - 1,
        primal_seconds: adj.primal_seconds,
        adjoint_seconds: adj.cost.wall_seconds,
        evaluation_seconds: adj.cost.evaluation_seconds,
        solve_seconds: adj.cost.solve_seconds + adj.cost.factor_seconds,
        responses: adj.responses.len(),
        stored_bytes: adj.cost.stored_bytes,
        spot_checks,
    });
    Ok(())
}

/// Run the study and write `adjoint.md`, `crossover.csv`, `crossover.svg`, the map and
/// `adjoint.json` into `opts.out`.
pub fn run_study(opts: &StudyOptions) -> Result<AdjointStudy, AdjointStudyError> {
    let t0 = Instant::now();
    let mut study = AdjointStudy {
        quick: opts.quick,
        ..AdjointStudy::default()
    };
    let leaf = if opts.quick {
        "leaf-spring-coarse"
    } else {
        "leaf-spring"
    };
    let mut leaf_fields = Vec::new();
    for q in ["E", "sigma_y", "H", "nu"] {
        for body in ["upper", "lower"] {
            leaf_fields.push(format!("{body}.{q}[*]"));
        }
    }
    leaf_fields.push("leaves.mu[*]".to_string());
    leaf_fields.push("block.mu[*]".to_string());
    map(leaf, opts, &mut study)?;
    crossover(leaf, &leaf_fields, opts, &mut study)?;
    if !opts.quick {
        let fields: Vec<String> = ["slab.E[*]", "slab.nu[*]", "block.mu[*]"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        crossover("indentation", &fields, opts, &mut study)?;
    }
    if let Some(r) = opts.large {
        large(r, &mut study)?;
    }
    study.wall_seconds = t0.elapsed().as_secs_f64();
    write(&study, &opts.out)?;
    Ok(study)
}

fn write(study: &AdjointStudy, out: &Path) -> Result<(), AdjointStudyError> {
    let io = |path: PathBuf| move |source| AdjointStudyError::Io { path, source };
    std::fs::create_dir_all(out).map_err(io(out.to_path_buf()))?;
    let mut csv = String::from("scene,method,parameters,seconds,measured\n");
    for c in &study.costs {
        let _ = writeln!(
            csv,
            "{},{},{},{:.4},{}",
            c.scene, c.method, c.n, c.seconds, c.measured
        );
    }
    let p = out.join("crossover.csv");
    std::fs::write(&p, csv).map_err(io(p.clone()))?;
    let p = out.join("adjoint.json");
    let json = serde_json::to_string_pretty(study).expect("the study serialises");
    std::fs::write(&p, json).map_err(io(p.clone()))?;
    let mut scenes: Vec<&str> = study.costs.iter().map(|c| c.scene.as_str()).collect();
    scenes.dedup();
    let figs: Vec<Figure> = (scenes.iter())
        .map(|scene| {
            let mut fig = Figure::new(
                format!("{scene}: cost against the number of parameters"),
                "parameters",
                "seconds (primal included)",
            )
            .log_x()
            .log_y();
            for m in METHODS {
                let pts = |measured: bool| -> Vec<(f64, f64)> {
                    (study.costs.iter())
                        .filter(|c| c.scene == *scene && c.method == m.name())
                        .filter(|c| c.measured || !measured)
                        .map(|c| (c.n as f64, c.seconds))
                        .collect()
                };
                fig = fig.series(m.name(), pts(true), Style::LinePoints);
                let all = pts(false);
                if all.len() > pts(true).len() {
                    fig = fig.series(format!("{} (extrapolated)", m.name()), all, Style::Dashed);
                }
            }
            fig
        })
        .collect();
    write_svg_stack(&figs, &out.join("crossover.svg"))?;
    let p = out.join("adjoint.md");
    std::fs::write(&p, markdown(study)).map_err(io(p.clone()))?;
    Ok(())
}

fn markdown(study: &AdjointStudy) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "## The adjoint method\n");
    let _ = writeln!(
        s,
        "Generated by `cargo run --release -- adjoint-study{}{}` ({:.0} s). The adjoint's functional is every response at the last increment; the parameters are element-wise material fields (`BODY.PARAM[*]`: every element's `E`, then `sigma_y`, `H`, `nu`) and friction per hitting node (`PAIR.mu[*]`).\n",
        if study.quick { " --quick" } else { "" },
        study
            .large
            .as_ref()
            .map_or(String::new(), |l| format!(" --large {}", l.refinement)),
        study.wall_seconds
    );
    let _ = writeln!(s, "### Cost against the number of parameters\n");
    let _ = writeln!(s, "Each method's whole call (primal included), measured while its extrapolated cost stays within the budget, beyond it the least-squares line `a + b N` through its measurements (dashed; `measured` false in `crossover.csv`).\n");
    let _ = writeln!(s, "![crossover.svg](crossover.svg)\n");
    let _ = writeln!(s, "| scene | method | a (s) | b (s per parameter) | adjoint a (s) | adjoint b (s per parameter) | the adjoint is cheaper beyond N = |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for c in &study.crossovers {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {:.2e} | {:.3} | {:.2e} | {} |",
            c.scene,
            c.method,
            c.method_line.0,
            c.method_line.1,
            c.adjoint_line.0,
            c.adjoint_line.1,
            c.n.map_or("never".to_string(), |n| format!("{n:.1}"))
        );
    }
    let _ = writeln!(s, "\n### Sensitivity map\n");
    let _ = writeln!(
        s,
        "`d(block-force)/d(sigma_y)` and `d/d(E)` of every element of the {} at the end of its path, by one adjoint run over {} parameters ({:.2} s, primal included); cell data in `map.vtu` for ParaView.\n",
        study.map_scene, study.map_parameters, study.map_seconds
    );
    let _ = writeln!(
        s,
        "![map-sigma_y.svg](map-sigma_y.svg)\n\n![map-E.svg](map-E.svg)\n"
    );
    let _ = writeln!(s, "DDM at the five elements of largest `|d/d sigma_y|` (difference relative to the map's largest derivative in that parameter):\n");
    spot_table(&mut s, &study.spot_checks);
    if let Some(l) = &study.large {
        let _ = writeln!(s, "\n### Many parameters\n");
        let _ = writeln!(
            s,
            "The leaf spring refined {} times ({} elements), its whole path ({} converged increments): every element's `{}`, {} parameters, the gradient of each of its {} responses at the end. Primal {:.1} s; the adjoint's sweep {:.1} s ({:.2} primals: evaluations {:.1} s, solves {:.1} s), {:.0} MiB kept by the forward run for it.\n",
            l.refinement,
            l.elements,
            l.increments,
            LARGE_FIELDS.join("`, `"),
            l.parameters,
            l.responses,
            l.primal_seconds,
            l.adjoint_seconds,
            l.adjoint_seconds / l.primal_seconds,
            l.evaluation_seconds,
            l.solve_seconds,
            l.stored_bytes as f64 / (1024.0 * 1024.0)
        );
        let _ = writeln!(s, "DDM at the element of each field where `|d(block-force)/d(...)|` is largest (difference relative to that largest derivative):\n");
        spot_table(&mut s, &l.spot_checks);
    }
    s
}
