//! The shape-parameter benchmark (the Abaqus Benchmarks' cantilever, 1.17.1): SDM's error for
//! a length and a thickness as the mesh is refined at fixed steps, with and without the
//! refined SDM (`Settings::rigid_modes`, [`crate::sensitivity::rigid`]), and the refined SDM on
//! the leaf spring's length.
//!
//! The cantilever is the benchmark's: 100 long, 2 deep (1 wide), linear elastic
//! (E = 1e7, nu = 0.3), a resultant tip load of 1, a linear (small-deformation) analysis;
//! incompatible-mode hex8 with square elements, 50 to 400 along the length (1 to 8 through the
//! depth). Each shape parameter is given two design velocities:
//! * **the end moved** (`L-end`, `h-top`): only the free end's nodes move along the axis (the
//!   top face's nodes through the depth), so the perturbation stretches the last column (row)
//!   of elements alone, by a relative `db / l_e` that grows with the refinement;
//! * **the whole body scaled** (`beam.length.x`, `beam.length.y`): every element stretched by
//!   the same relative `db / L`.
//!
//! Every derivative is compared with DDM's on the same mesh: `|SDM - DDM| / |DDM|` of the tip
//! deflection's derivative.

use super::*;
use crate::scene::builtin::{cantilever, CantileverSpec};
use crate::scene::{MapSpec, ShapeSpec};

/// Elements along the cantilever's length (a quarter as many through the depth per 50).
pub const ELEMENTS: [usize; 4] = [50, 100, 200, 400];

/// The fixed relative steps of the study: forward and central (each about 0.1 % error on the
/// coarsest mesh for the end-moved length by plain SDM, the benchmark's choice of step).
pub const STEPS: [(Method, f64); 2] = [(Method::Sdm, 1e-6), (Method::SdmCentral, 1e-3)];

/// The cantilever's design parameters: `(name, velocity, dimension)`.
pub const CANTILEVER_PARAMS: [(&str, &str, &str); 4] = [
    ("L-end", "end moved", "length"),
    ("h-top", "end moved", "thickness"),
    ("beam.length.x", "whole body scaled", "length"),
    ("beam.length.y", "whole body scaled", "thickness"),
];

/// The leaf spring's shape parameter the refined SDM is applied to.
pub const LEAF_PARAM: &str = "upper.length.x";

/// One SDM derivative of the cantilever study.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct CantileverRow {
    /// Elements along the length.
    pub elements: usize,
    /// The parameter ([`CANTILEVER_PARAMS`]).
    pub param: String,
    /// SDM or SDM central.
    pub method: String,
    /// The refined SDM.
    pub refined: bool,
    /// The relative step.
    pub beta: f64,
    /// The largest relative stretch of an element, `db max|grad V|`.
    pub stretch: f64,
    /// `|SDM - DDM| / |DDM|` of the tip deflection's derivative.
    pub error: f64,
    /// DDM's derivative.
    pub ddm: f64,
}

/// One SDM run on the leaf spring's length.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct LeafRow {
    /// SDM or SDM central.
    pub method: String,
    /// The refined SDM.
    pub refined: bool,
    /// The relative step.
    pub beta: f64,
    /// The relative error against DDM as the sweep measures it (largest over responses and
    /// unflagged increments).
    pub error: f64,
    /// The sensitivity's wall time over the primal's.
    pub cost_ratio: f64,
}

/// The whole study.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct RefinementStudy {
    /// The cantilever's derivatives.
    pub cantilever: Vec<CantileverRow>,
    /// The leaf spring's length (empty without the leaf spring).
    pub leaf: Vec<LeafRow>,
}

/// The benchmark's cantilever with `nx` elements along its length.
pub fn benchmark_cantilever(nx: usize) -> Scene {
    let spec = CantileverSpec {
        length: 100.0,
        height: 2.0,
        width: 1.0,
        young: 1e7,
        nu: 0.3,
        nx,
        ny: (nx / 50).max(1),
        // a resultant tip load of 1: alpha = P L^2 / (E I)
        alpha: 1.0 * 100f64.powi(2) / (1e7 * 1.0 * 2f64.powi(3) / 12.0),
        increments: 1,
        kinematics: crate::element::Kinematics::Small,
        formulation: crate::element::Formulation::IncompatibleModes,
    };
    let mut s = cantilever(&spec);
    s.name = format!("cantilever-{nx}");
    let translate = |name: &str, nodes: &str, direction: [f64; 3]| ShapeSpec {
        name: name.into(),
        nodes: nodes.into(),
        value: None,
        map: MapSpec::Translate { direction },
    };
    s.shapes = vec![
        translate("L-end", "beam.xmax", [1.0, 0.0, 0.0]),
        translate("h-top", "beam.ymax", [0.0, 1.0, 0.0]),
    ];
    s.study.params = CANTILEVER_PARAMS.iter().map(|p| p.0.to_string()).collect();
    s
}

/// The largest relative stretch `db max|grad V|` parameter `param` gives an element of the
/// benchmark's cantilever with `nx` elements along its length at relative step `beta`.
pub fn stretch(param: &str, nx: usize, beta: f64) -> f64 {
    let (l_e, h_e) = (100.0 / nx as f64, 2.0 / (nx / 50).max(1) as f64);
    match param {
        // value 0: the step is beta itself, over one element
        "L-end" => beta / l_e,
        "h-top" => beta / h_e,
        // a scale: db = beta b, over the whole length b
        _ => beta,
    }
}

fn run(
    scene: &Scene,
    params: &[Parameter],
    settings: &[Settings],
) -> Result<Vec<SensitivityResults>, ValidateError> {
    let model = scene.build()?;
    let (_, out) =
        run_inline_sweep(&model, params, settings).map_err(|source| ValidateError::Analysis {
            scene: scene.name.clone(),
            source,
        })?;
    Ok(out)
}

/// The settings of one SDM variant.
fn sdm(method: Method, beta: f64, refined: bool) -> Settings {
    Settings {
        method,
        beta,
        rigid_modes: refined,
        ..Settings::default()
    }
}

/// The cantilever's rows on `elements` meshes (module docs).
pub fn cantilever_rows(elements: &[usize]) -> Result<Vec<CantileverRow>, ValidateError> {
    let mut rows = Vec::new();
    for &nx in elements {
        let scene = benchmark_cantilever(nx);
        let model = scene.build()?;
        let params = parameters(&model, &scene.name, scene.study.params.iter())?;
        let mut settings = vec![Settings::default()];
        let mut variants = Vec::new();
        for (method, beta) in STEPS {
            for refined in [false, true] {
                settings.push(sdm(method, beta, refined));
                variants.push((method, beta, refined));
            }
        }
        let out = run(&scene, &params, &settings)?;
        let r = (out[0].responses.iter())
            .position(|r| r == "tip-deflection")
            .expect("the cantilever's response");
        let value = |s: &SensitivityResults, p: usize| {
            s.increments
                .last()
                .map_or(f64::NAN, |i| i.derivatives[r][p])
        };
        for (p, param) in params.iter().enumerate() {
            let ddm = value(&out[0], p);
            for (s, &(method, beta, refined)) in out[1..].iter().zip(&variants) {
                rows.push(CantileverRow {
                    elements: nx,
                    param: param.name.clone(),
                    method: method.name().into(),
                    refined,
                    beta,
                    stretch: stretch(&param.name, nx, beta),
                    error: (value(s, p) - ddm).abs() / ddm.abs(),
                    ddm,
                });
            }
        }
    }
    Ok(rows)
}

/// The leaf spring's length by SDM and SDM central, plain and refined, at every `betas`.
pub fn leaf_rows(leaf: &Scene, betas: &[f64], floor: f64) -> Result<Vec<LeafRow>, ValidateError> {
    let model = leaf.build()?;
    let params = parameters(&model, &leaf.name, [LEAF_PARAM].iter())?;
    let mut settings = vec![Settings::default()];
    let mut variants = Vec::new();
    for method in [Method::Sdm, Method::SdmCentral] {
        for refined in [false, true] {
            for &beta in betas {
                settings.push(sdm(method, beta, refined));
                variants.push((method, beta, refined));
            }
        }
    }
    let out = run(leaf, &params, &settings)?;
    let flagged: Vec<bool> = (out[0].increments.iter())
        .map(|i| !i.kinks.is_empty())
        .collect();
    Ok(out[1..]
        .iter()
        .zip(variants)
        .map(|(s, (method, beta, refined))| LeafRow {
            method: method.name().into(),
            refined,
            beta,
            error: relative_error(&out[0], s, 0, params[0].value, floor, &flagged),
            cost_ratio: s.cost.wall_seconds / s.primal_seconds.max(1e-9),
        })
        .collect())
}

/// The study: the cantilever on [`ELEMENTS`], and the leaf spring's length where `leaf` is
/// given.
pub fn refinement_study(
    leaf: Option<&Scene>,
    betas: &[f64],
    floor: f64,
) -> Result<RefinementStudy, ValidateError> {
    Ok(RefinementStudy {
        cantilever: cantilever_rows(&ELEMENTS)?,
        leaf: match leaf {
            Some(l) => leaf_rows(l, betas, floor)?,
            None => Vec::new(),
        },
    })
}

/// The figure's file name.
pub const FIGURE: &str = "cantilever-refinement.svg";

/// Error against the number of elements along the length, per parameter, method and variant.
pub fn figure(study: &RefinementStudy) -> crate::studies::plot::Figure {
    use crate::studies::plot::{Figure, Style};
    let mut f = Figure::new(
        "The benchmark cantilever: SDM's error for shape parameters at fixed steps",
        "elements along the length",
        "|SDM - DDM| / |DDM| of d(tip deflection)/d(b)",
    )
    .log_x()
    .log_y();
    for (param, velocity, dimension) in CANTILEVER_PARAMS {
        for (method, beta) in STEPS {
            for refined in [false, true] {
                let pts: Vec<(f64, f64)> = (study.cantilever.iter())
                    .filter(|r| r.param == param && r.method == method.name())
                    .filter(|r| r.refined == refined)
                    .map(|r| (r.elements as f64, r.error))
                    .filter(|(_, e)| *e > 0.0 && e.is_finite())
                    .collect();
                let label = format!(
                    "{}{} {dimension}, {velocity} (beta {beta:.0e})",
                    if refined { "refined " } else { "" },
                    method.name(),
                );
                let style = if refined {
                    Style::Dashed
                } else {
                    Style::LinePoints
                };
                f = f.series(label, pts, style);
            }
        }
    }
    f
}

/// The report's subsection.
pub fn write_refinement(s: &mut String, study: &RefinementStudy) {
    use std::fmt::Write;
    if study.cantilever.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n### Shape parameters: the benchmark cantilever and the refined SDM\n"
    );
    let _ = writeln!(
        s,
        "The Abaqus Benchmarks' cantilever (1.17.1): 100 long, 2 deep, a tip load of 1, linear elastic, a linear analysis; incompatible-mode hex8 on square elements, {} along the length (1 to 8 through the depth). SDM forward (beta {:.0e}) and central (beta {:.0e}) at the same steps on every mesh, against DDM on the same mesh, for the tip deflection's derivative in the length and the thickness, each given two design velocities: the free end's nodes moved along the axis (`L-end`; the top face's through the depth, `h-top`), which stretches only the last column (row) of elements, by `db / l_e`; and the whole beam scaled (`beam.length.x`, `beam.length.y`), every element by `db / L`. The refined SDM (`--rigid-modes`) differentiates each element's rigid rotation exactly and differences only its deformation ([`rigid`](../src/sensitivity/rigid.rs) module): the perturbation of an element's reference is turned with the element, and the tangent times that turn is taken out of the difference, exactly.\n",
        ELEMENTS.map(|n| n.to_string()).join(", "),
        STEPS[0].1,
        STEPS[1].1
    );
    let _ = writeln!(
        s,
        "| parameter | velocity | method | variant | {} |",
        ELEMENTS.map(|n| format!("{n} elements")).join(" | ")
    );
    let _ = writeln!(s, "|---|---|---|---|{}", "---|".repeat(ELEMENTS.len()));
    for (param, velocity, _) in CANTILEVER_PARAMS {
        for (method, _) in STEPS {
            for refined in [false, true] {
                let cells: Vec<String> = ELEMENTS
                    .iter()
                    .map(|&n| {
                        (study.cantilever.iter())
                            .find(|r| {
                                r.elements == n
                                    && r.param == param
                                    && r.method == method.name()
                                    && r.refined == refined
                            })
                            .map_or("-".into(), |r| format!("{:.1e}", r.error))
                    })
                    .collect();
                let _ = writeln!(
                    s,
                    "| {param} | {velocity} | {} | {} | {} |",
                    method.name(),
                    if refined { "refined" } else { "plain" },
                    cells.join(" | ")
                );
            }
        }
    }
    // the error per unit of the stretched elements' relative stretch: the rigid rotation's
    // amplification, plain and refined
    let per_stretch = |param: &str, method: Method, refined: bool| -> Vec<f64> {
        (study.cantilever.iter())
            .filter(|r| r.param == param && r.method == method.name() && r.refined == refined)
            .map(|r| {
                let order = if method == Method::SdmCentral { 2 } else { 1 };
                r.error / r.stretch.powi(order)
            })
            .collect()
    };
    let range = |v: &[f64]| {
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(0.0, f64::max);
        format!("{lo:.1e} to {hi:.1e}")
    };
    let gain = |param: &str, method: Method| -> Vec<f64> {
        (per_stretch(param, method, false).iter())
            .zip(per_stretch(param, method, true))
            .map(|(p, r)| p / r)
            .collect()
    };
    let growth = |param: &str, method: Method, refined: bool| -> f64 {
        let e: Vec<f64> = (study.cantilever.iter())
            .filter(|r| r.param == param && r.method == method.name() && r.refined == refined)
            .map(|r| r.error)
            .collect();
        e.last().copied().unwrap_or(f64::NAN) / e.first().copied().unwrap_or(f64::NAN)
    };
    let _ = writeln!(
        s,
        "\nWith the end moved, plain SDM's error grows with the refinement, {:.0}-fold (forward) and {:.0}-fold (central) from {} to {} elements for the length: the benchmark's finding. It is the product of two factors. The stretched elements' relative stretch `e = db / l_e` grows with the refinement at a fixed step, and a forward (central) difference's truncation is proportional to `e` (`e^2`): that growth is common to every difference of the element forces. The rigid rotation multiplies it: the error per unit `e` (`e^2`) is {} (forward) and {} (central) for plain SDM on the length, mesh-independent for these continuum elements of constant aspect, because at fixed nodal displacements a rigid rotation `theta` of a stretched element is a shear strain `theta e` answered by the shear stiffness. The refined SDM removes that factor: its error per unit `e` (`e^2`) is {} and {}, so at the benchmark's steps it is {} times below plain SDM's on the meshes (forward; central {}), but it still grows with the refinement in proportion to `e` at a fixed step. What stops that growth is a step sized to the elements it stretches (`db` proportional to `l_e`), or `--beta auto`, which chooses the step on each mesh. With the whole beam scaled, `e = db / L` does not change with the mesh and neither SDM's error grows; the refined SDM's is {} per unit beta for the length against plain SDM's {} (forward). (Continuum elements differ here from beams: a beam element's stiffness against the spurious transverse deflection `theta l_e db` grows as `1 / l_e^3`, which is why beam meshes show the error growing as the square of the number of elements.)\n",
        growth("L-end", Method::Sdm, false),
        growth("L-end", Method::SdmCentral, false),
        ELEMENTS[0],
        ELEMENTS[ELEMENTS.len() - 1],
        range(&per_stretch("L-end", Method::Sdm, false)),
        range(&per_stretch("L-end", Method::SdmCentral, false)),
        range(&per_stretch("L-end", Method::Sdm, true)),
        range(&per_stretch("L-end", Method::SdmCentral, true)),
        range(&gain("L-end", Method::Sdm)),
        range(&gain("L-end", Method::SdmCentral)),
        range(&per_stretch("beam.length.x", Method::Sdm, true)),
        range(&per_stretch("beam.length.x", Method::Sdm, false)),
    );
    let _ = writeln!(s, "![cantilever refinement](figures/{FIGURE})\n");
    if study.leaf.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "**The leaf spring's length** (`{LEAF_PARAM}`), plain and refined, relative error against DDM as the sweep measures it:\n"
    );
    let betas: Vec<f64> = {
        let mut b: Vec<f64> = study.leaf.iter().map(|r| r.beta).collect();
        b.sort_by(|a, c| c.total_cmp(a));
        b.dedup();
        b
    };
    let _ = writeln!(
        s,
        "| method | variant | {} |",
        betas
            .iter()
            .map(|b| format!("beta {b:.0e}"))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let _ = writeln!(s, "|---|---|{}", "---|".repeat(betas.len()));
    for method in [Method::Sdm, Method::SdmCentral] {
        for refined in [false, true] {
            let cells: Vec<String> = betas
                .iter()
                .map(|b| {
                    (study.leaf.iter())
                        .find(|r| r.method == method.name() && r.refined == refined && r.beta == *b)
                        .map_or("-".into(), |r| format!("{:.1e}", r.error))
                })
                .collect();
            let _ = writeln!(
                s,
                "| {} | {} | {} |",
                method.name(),
                if refined { "refined" } else { "plain" },
                cells.join(" | ")
            );
        }
    }
    // the truncation regime: steps above both variants' best, where both errors are below 1
    let ratio = |method: Method| -> Vec<f64> {
        let of = |refined: bool| -> Vec<&LeafRow> {
            (study.leaf.iter())
                .filter(|r| r.method == method.name() && r.refined == refined)
                .collect()
        };
        let best_beta = |rows: &[&LeafRow]| {
            rows.iter()
                .min_by(|a, b| a.error.total_cmp(&b.error))
                .map_or(f64::INFINITY, |r| r.beta)
        };
        let (plain, refined) = (of(false), of(true));
        let floor = best_beta(&plain).max(best_beta(&refined));
        plain
            .iter()
            .filter_map(|p| {
                let r = refined.iter().find(|r| r.beta == p.beta)?;
                (p.beta > floor && p.error < 1.0 && r.error < 1.0).then(|| p.error / r.error)
            })
            .collect()
    };
    let cost = |method: Method, refined: bool| -> f64 {
        let mut v: Vec<f64> = (study.leaf.iter())
            .filter(|r| r.method == method.name() && r.refined == refined)
            .map(|r| r.cost_ratio)
            .collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let _ = writeln!(
        s,
        "\nIn the truncation regime (the steps above both variants' best, errors below 1) the refined forward SDM's error on the leaf length is {} times smaller than plain SDM's (central: {}). What is left is not the elements' rigid rotation: it is what the refined SDM still differences as plain SDM does (contact, friction and loads, and the elements' deformation); `--explain` splits plain SDM's error only. Where round-off dominates (the smallest steps) the two are alike. Cost, the sensitivity's wall time over the primal's (median over the steps): forward {:.3} refined against {:.3} plain, central {:.3} against {:.3}: the refined SDM adds one tangent assembly over the coloured passes per increment, and evaluates the elements of every colour a parameter reaches once per moving parameter (twice central).",
        range(&ratio(Method::Sdm)),
        range(&ratio(Method::SdmCentral)),
        cost(Method::Sdm, true),
        cost(Method::Sdm, false),
        cost(Method::SdmCentral, true),
        cost(Method::SdmCentral, false),
    );
}
