//! Hertz's line contact (oracles.md section 4) on blocks of hex8, hex20 and tet10 elements:
//! the half-width, the peak pressure and its DDM derivative with respect to Young's modulus
//! against the closed form, and the unknowns each family needs for a given accuracy.
//!
//! The scene is the built-in `hertz` ([`crate::scene::builtin::hertz`]: a rigid cylinder
//! `R = 10` pressed by a line load into a plane-strain half block, `E = 1e5`, `nu = 0.3`,
//! target half-width `a = 0.5`) with `n` elements across the half-width, of each family in its
//! standard formulation; its pressure profile read per station (the hitting nodes at one `x`).
//! The half-width is the smooth measure of oracles.md, `a = 2 sqrt(M2 / P)` with
//! `M2 = sum f_i x_i^2` over the hitting nodes' normal forces (`int p x^2 dx = P a^2 / 4`);
//! the peak pressure is the largest station pressure, the station's normal forces over its
//! nodes' pressure areas ([`crate::element::FaceFamily::pressure_share`]: on quad8 faces the
//! corners open and the mid-sides carry the load, on tri6 faces the corners carry none).

use super::ValidateError;
use crate::element::{ElementFamily, Shape};
use crate::scene::builtin::{hertz, HertzSpec};
use crate::scene::ProfilePoints;
use crate::scene::ResponseSpec;
use crate::sensitivity::{run_sensitivity, Method, Parameter, Settings};

/// The families and the elements across the half-width of each of their meshes.
pub const LEVELS: [(Shape, &[usize]); 3] = [
    (Shape::Hex8, &[3, 6, 12, 24]),
    (Shape::Hex20, &[3, 6, 12]),
    (Shape::Tet10, &[3, 6, 12]),
];

/// One mesh of one family.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct HertzRow {
    /// The family's name.
    pub family: String,
    /// Elements across the half-width.
    pub across: usize,
    /// Unknowns (displacements and multipliers).
    pub unknowns: usize,
    /// `a` measured.
    pub half_width: f64,
    /// Its relative error against Hertz.
    pub half_width_error: f64,
    /// `p0` measured.
    pub peak: f64,
    /// Its relative error against Hertz.
    pub peak_error: f64,
    /// Relative error of DDM's `dp0/dE` against `p0 / (2 E)`.
    pub d_peak_error: f64,
    /// Wall time of the analysis with its DDM derivative (s).
    pub seconds: f64,
}

fn bad(what: String) -> ValidateError {
    ValidateError::Study {
        study: "hertz-families",
        what,
    }
}

/// The Hertz scene of `shape` with `across` elements across the half-width, its pressure
/// profile per station.
pub fn scene(shape: Shape, across: usize) -> crate::scene::Scene {
    let far = HertzSpec::default().far_elements;
    let mut s = hertz(&HertzSpec {
        element: shape,
        elements_across: across,
        // a quadratic family's mesh has the node spacing of the hex8 mesh with twice the
        // elements, far field included
        far_elements: if shape.is_quadratic() {
            far.map(|n| n / 2)
        } else {
            far
        },
        ..HertzSpec::default()
    });
    s.name = format!("hertz-{}-{across}", shape.name());
    for r in &mut s.responses {
        if let ResponseSpec::PressureProfile { per, .. } = r {
            *per = ProfilePoints::Station;
        }
    }
    s
}

/// The measurements on one mesh.
pub fn row(shape: Shape, across: usize) -> Result<HertzRow, ValidateError> {
    let spec = HertzSpec::default();
    let scene = scene(shape, across);
    let model = scene.build().map_err(|e| bad(e.to_string()))?;
    let e = Parameter::by_name(&model, "E").map_err(|e| bad(e.to_string()))?;
    let settings = Settings {
        method: Method::Ddm,
        ..Settings::default()
    };
    let start = std::time::Instant::now();
    let (res, sens) =
        run_sensitivity(&model, &[e], &settings).map_err(|source| ValidateError::Analysis {
            scene: scene.name.clone(),
            source,
        })?;
    let seconds = start.elapsed().as_secs_f64();
    let last = (res.states.len().checked_sub(1)).ok_or_else(|| bad("no state".into()))?;
    let inc = sens
        .increments
        .last()
        .ok_or_else(|| bad("no increment".into()))?;
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let pair = &model.contacts[0];
    let c = &res.contact[last];
    let flat = res.contact_flat[0];
    let (mut force, mut m2) = (0.0, 0.0);
    for (i, &n) in pair.hitting.iter().enumerate() {
        let f = c.normal_force[flat + i];
        force += f;
        m2 += f * x[n][0].powi(2);
    }
    let half_width = 2.0 * (m2 / force).sqrt();
    let (mut peak, mut d_peak) = (0.0f64, 0.0);
    for (r, resp) in model.responses.iter().enumerate() {
        if resp.name.starts_with("p_") && inc.values[r] > peak {
            (peak, d_peak) = (inc.values[r], inc.derivatives[r][0]);
        }
    }
    let p = spec.load();
    let a = (4.0 * p * spec.radius / (std::f64::consts::PI * spec.e_star())).sqrt();
    let p0 = 2.0 * p / (std::f64::consts::PI * a);
    let dp0 = p0 / (2.0 * spec.young);
    Ok(HertzRow {
        family: ElementFamily::standard(shape).name().to_string(),
        across,
        unknowns: res.states[last].len(),
        half_width,
        half_width_error: (half_width - a).abs() / a,
        peak,
        peak_error: (peak - p0).abs() / p0,
        d_peak_error: (d_peak - dp0).abs() / dp0,
        seconds,
    })
}

/// Every family on every level.
pub fn study() -> Result<Vec<HertzRow>, ValidateError> {
    let mut rows = Vec::new();
    for (shape, levels) in LEVELS {
        for &n in levels {
            rows.push(row(shape, n)?);
        }
    }
    Ok(rows)
}

/// The figure's file name.
pub const FIGURE: &str = "hertz-families.svg";

/// Errors of `a` and `p0` against unknowns, per family.
pub fn figure(rows: &[HertzRow]) -> crate::studies::plot::Figure {
    use crate::studies::plot::{Figure, Style};
    let mut f = Figure::new(
        "Hertz line contact: error of the half-width and of the peak pressure",
        "unknowns",
        "relative error",
    )
    .log_x()
    .log_y();
    for family in super::distinct(rows.iter().map(|r| r.family.as_str())) {
        let mine: Vec<&HertzRow> = rows.iter().filter(|r| r.family == family).collect();
        let series = |e: fn(&HertzRow) -> f64| -> Vec<(f64, f64)> {
            // a zero error has no place on a log axis
            (mine.iter())
                .map(|r| (r.unknowns as f64, e(r).max(1e-6)))
                .collect()
        };
        f = f.series(
            format!("{family}: p0"),
            series(|r| r.peak_error),
            Style::LinePoints,
        );
        f = f.series(
            format!("{family}: a"),
            series(|r| r.half_width_error),
            Style::Dashed,
        );
    }
    f
}

/// The report's section.
pub fn write_hertz_families(s: &mut String, rows: &[HertzRow]) {
    use std::fmt::Write;
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Hertz's line contact on hex8, hex20 and tet10 blocks\n"
    );
    let _ = writeln!(
        s,
        "The built-in `hertz` scene (a rigid cylinder R = 10 pressed by a line load into a plane-strain half block, E = 1e5, nu = 0.3, target half-width a = 0.5) with `n` elements across the half-width, each family in its standard formulation ([`hertz_families`](../src/studies/validate/hertz_families.rs)). The half-width is the smooth measure `2 sqrt(M2 / P)` of the hitting nodes' normal forces; the peak pressure the largest station pressure, over the nodes' pressure areas (on a quad8 face the corners open, since the consistent corner load of a pressure, -1/12 of the face's, is a pull, and the four mid-sides carry a quarter each; on a tri6 face the corners carry none, as the consistent weights say); `dp0/dE` by DDM against `p0 / (2 E)`. Time: the analysis with its DDM derivative. A quadratic family's mesh has the node spacing of the hex8 mesh with twice the elements, far field included.\n\n![{FIGURE}](figures/{FIGURE})\n"
    );
    // what the finest meshes agree on: the part of the error that is the model's
    let finest: Vec<&HertzRow> = (super::distinct(rows.iter().map(|r| r.family.as_str())))
        .into_iter()
        .filter_map(|f| (rows.iter().filter(|r| r.family == f)).max_by_key(|r| r.across))
        .collect();
    let (lo, hi) = (finest.iter()).fold((f64::INFINITY, 0.0f64), |(l, h), r| {
        (l.min(r.peak), h.max(r.peak))
    });
    if finest.len() > 1 && hi > 0.0 {
        let best = (finest.iter()).fold(f64::INFINITY, |m, r| m.min(r.peak_error));
        let _ = writeln!(
            s,
            "The finest mesh of each family gives p0 between {lo:.1} and {hi:.1}, {:.1e} apart; the smallest error, {best:.1e}, is about what the finest meshes converge to: the model's own difference from Hertz's half-space (a block 20a deep and 10a wide), not a mesh's.\n",
            (hi - lo) / hi
        );
    }
    let _ = writeln!(
        s,
        "| family | n | unknowns | a | error a | p0 | error p0 | error dp0/dE | time (s) |\n|---|---|---|---|---|---|---|---|---|"
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.5} | {:.2e} | {:.1} | {:.2e} | {:.2e} | {:.1} |",
            r.family,
            r.across,
            r.unknowns,
            r.half_width,
            r.half_width_error,
            r.peak,
            r.peak_error,
            r.d_peak_error,
            r.seconds
        );
    }
    // the fewest unknowns reaching 2 % on both a and p0, per family
    let _ = writeln!(
        s,
        "\n| family | fewest unknowns with a and p0 within 2 % |\n|---|---|"
    );
    for family in super::distinct(rows.iter().map(|r| r.family.as_str())) {
        let best = (rows.iter())
            .filter(|q| q.family == family && q.peak_error < 0.02 && q.half_width_error < 0.02)
            .map(|q| q.unknowns)
            .min();
        let _ = writeln!(
            s,
            "| {} | {} |",
            family,
            best.map_or("none of these meshes".to_string(), |u| u.to_string())
        );
    }
    let _ = writeln!(s);
}
