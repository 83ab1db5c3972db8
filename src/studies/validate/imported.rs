//! The imported-geometry oracles: scenes around Gmsh meshes (`meshes/`, made by
//! `meshes/make_meshes.py`) against closed forms and independent methods.
//!
//! * **Two-body Hertz** (`hertz-cylinders.toml`, both master/slave directions): two elastic
//!   cylinders of different radii and moduli, plane strain. `1/R = 1/R1 + 1/R2`,
//!   `1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2`, half-width `a = sqrt(4 P R / (pi E*))`, peak
//!   `p0 = 2 P / (pi a)`, `d p0 / d E1 = p0 / (2 E*) dE*/dE1` at fixed load. The half-width is
//!   measured by the smooth second moment of the nodal forces (`shared/oracles.md` section 4:
//!   `integral p x^2 = P a^2 / 4`).
//! * **Lamé** (`lame-octant.toml`): a thick elastic sphere under internal pressure, an octant.
//!   The bore's displacement and its derivatives in E, nu and the inner radius a (a shape
//!   parameter through a boundary-driven design velocity field), against the closed form
//!   differentiated exactly by dual numbers; `du/da` also against central FDM of reruns.
//! * **Morph against scale**: a morph to `lame-octant-scaled.msh` (the same mesh scaled by
//!   1.05) and the scale map that describes the same change give the same DDM sensitivity.

use super::OracleRow;
use crate::response::ResponseKind;
use crate::scalar::Scalar;
use crate::scene::{MapSpec, Scene, SceneError, ShapeSpec, TargetSpec};
use crate::sensitivity::{run_sensitivity, Method, Parameter, Settings};
use crate::solver::AnalysisError;
use std::path::Path;

/// Why an imported-geometry check could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImportedError {
    /// A scene could not be read or built.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A design parameter is not in the scene.
    #[error(transparent)]
    Parameter(#[from] crate::design::ParameterError),
    /// A sensitivity run stopped part way.
    #[error("{scene}: {why}")]
    Failed {
        /// The scene.
        scene: String,
        /// What stopped it.
        why: String,
    },
    /// An analysis failed.
    #[error("{scene}: {source}")]
    Analysis {
        /// The scene.
        scene: String,
        /// The failure.
        #[source]
        source: AnalysisError,
    },
}

fn row(scene: &str, quantity: &str, expected: f64, got: f64, tolerance: f64) -> OracleRow {
    let check = crate::scene::builtin::OracleCheck {
        quantity: quantity.to_string(),
        expected,
        got,
        tolerance,
    };
    OracleRow::new(scene, check)
}

fn sensitivities(
    model: &crate::model::Model,
    scene: &str,
    names: &[&str],
    method: Method,
    beta: f64,
) -> Result<crate::sensitivity::SensitivityResults, ImportedError> {
    let analysis = |source| ImportedError::Analysis {
        scene: scene.to_string(),
        source,
    };
    let params = (names.iter())
        .map(|n| Parameter::by_name(model, n))
        .collect::<Result<Vec<_>, _>>()?;
    let settings = Settings {
        method,
        beta,
        ..Settings::default()
    };
    let (_, res) = run_sensitivity(model, &params, &settings).map_err(analysis)?;
    match &res.failure {
        Some(why) => Err(ImportedError::Failed {
            scene: scene.to_string(),
            why: why.clone(),
        }),
        None => Ok(res),
    }
}

/// Two-body Hertz line contact of `meshes/hertz-cylinders.toml` (module docs).
#[derive(Clone, Copy, Debug)]
pub struct TwoCylinders {
    /// Radius of the upper cylinder.
    pub r1: f64,
    /// Radius of the lower cylinder.
    pub r2: f64,
    /// Young's modulus of the upper cylinder.
    pub e1: f64,
    /// Poisson's ratio of the upper cylinder.
    pub nu1: f64,
    /// Young's modulus of the lower cylinder.
    pub e2: f64,
    /// Poisson's ratio of the lower cylinder.
    pub nu2: f64,
    /// Load per unit length.
    pub p: f64,
}

impl TwoCylinders {
    /// The scene's values (its file's header derives the load from a = 0.3).
    pub const SCENE: TwoCylinders = TwoCylinders {
        r1: 8.0,
        r2: 12.0,
        e1: 2e5,
        nu1: 0.3,
        e2: 1e5,
        nu2: 0.25,
        // the half model's nodal load over its half length per unit thickness 0.025
        p: 13.21875 * 2.0 / 0.025,
    };

    /// Plane-strain contact modulus `E*`.
    pub fn e_star(&self) -> f64 {
        1.0 / ((1.0 - self.nu1 * self.nu1) / self.e1 + (1.0 - self.nu2 * self.nu2) / self.e2)
    }

    /// Effective radius `R`.
    pub fn radius(&self) -> f64 {
        1.0 / (1.0 / self.r1 + 1.0 / self.r2)
    }

    /// Contact half-width `a`.
    pub fn half_width(&self) -> f64 {
        (4.0 * self.p * self.radius() / (std::f64::consts::PI * self.e_star())).sqrt()
    }

    /// Peak pressure `p0`.
    pub fn peak(&self) -> f64 {
        2.0 * self.p / (std::f64::consts::PI * self.half_width())
    }

    /// `d p0 / d E1` at fixed load: `p0 = sqrt(P E* / (pi R))`,
    /// `dE*/dE1 = E*^2 (1 - nu1^2) / E1^2`.
    pub fn dpeak_de1(&self) -> f64 {
        let es = self.e_star();
        self.peak() / (2.0 * es) * es * es * (1.0 - self.nu1 * self.nu1) / (self.e1 * self.e1)
    }
}

/// Hertz between the two Gmsh cylinders, the upper one hitting (or, `reverse`, the lower):
/// equilibrium of the nodal forces, half-width, peak pressure and `d p0 / d E1`.
pub fn hertz_cylinders(meshes: &Path, reverse: bool) -> Result<Vec<OracleRow>, ImportedError> {
    let h = TwoCylinders::SCENE;
    let mut s = Scene::from_file(&meshes.join("hertz-cylinders.toml"))?;
    let name = if reverse {
        s.contacts[0].hitting = "lower.lower-contact".into();
        s.contacts[0].target = TargetSpec::Faces("upper.upper-contact".into());
        "hertz-cylinders (lower hits)"
    } else {
        "hertz-cylinders (upper hits)"
    };
    let model = s.build()?;
    let res = sensitivities(&model, name, &["upper.E"], Method::Ddm, 0.0)?;
    let last = res.increments.last().expect("increments");
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let share: Vec<Vec<f64>> = (model.contacts.iter())
        .map(|c| c.pressure_areas_at(|n| x[n]))
        .collect();
    // nodal normal forces f = p A at the hitting nodes, their x, the peak pressure
    let (mut force, mut moment2) = (0.0, 0.0);
    let mut peak = (0.0f64, 0.0f64);
    for (r, resp) in model.responses.iter().enumerate() {
        // the nominal pressures times their reference areas are the nodal forces (the scene's
        // profile is nominal; a current one would need the deformed areas)
        if let ResponseKind::ContactPressure {
            pair,
            ref nodes,
            measure: crate::response::PressureMeasure::Nominal,
        } = resp.kind
        {
            // a station's nodes share their x
            let n = model.contacts[pair].hitting[nodes[0]];
            let area = nodes.iter().map(|i| share[pair][*i]);
            let f = last.values[r] * area.sum::<f64>();
            force += f;
            moment2 += f * x[n].x * x[n].x;
            if last.values[r] > peak.0 {
                peak = (last.values[r], last.derivatives[r][0]);
            }
        }
    }
    // the smooth measure of oracles.md: M2 = integral p x^2 = P a^2 / 4 (the half model's
    // sums over x >= 0 have the same ratio)
    let a_eff = 2.0 * (moment2 / force).sqrt();
    Ok(vec![
        // the normal forces' y components carry the load exactly; their sum exceeds it by
        // the curvature, 1 - cos(a / R1) = 7e-4 at the edge of the zone
        row(
            name,
            "sum of nodal normal forces = P (half model)",
            0.5 * h.p * 0.025,
            force,
            7e-4,
        ),
        // the 3 % and 4 % (the mesh has 18 elements across the half-width)
        row(
            name,
            "half-width a = sqrt(4 P R / (pi E*))",
            h.half_width(),
            a_eff,
            0.03,
        ),
        row(
            name,
            "peak pressure p0 = 2 P / (pi a)",
            h.peak(),
            peak.0,
            0.03,
        ),
        row(
            name,
            "d p0 / d E1 = p0 / (2 E*) dE*/dE1",
            h.dpeak_de1(),
            peak.1,
            0.04,
        ),
    ])
}

/// Lamé's bore displacement of a thick sphere (inner a, outer b) under internal pressure p,
/// generic so that a dual number gives its derivatives exactly.
pub fn lame_bore<S: Scalar>(p: f64, a: S, b: f64, e: S, nu: S) -> S {
    let l = S::lift;
    let a3 = a * a * a;
    let b3 = l(b * b * b);
    a * l(p) / (e * (b3 - a3)) * ((l(1.0) - nu * l(2.0)) * a3 + (nu + l(1.0)) * b3 * l(0.5))
}

/// The Lamé octant: `u(a)` and its derivatives in E, nu and a against the closed form, and
/// `du/da` against central FDM of reruns.
pub fn lame_sphere(meshes: &Path) -> Result<Vec<OracleRow>, ImportedError> {
    use num_dual::Dual64;
    let name = "lame-octant";
    let model = Scene::from_file(&meshes.join("lame-octant.toml"))?.build()?;
    let res = sensitivities(&model, name, &["E", "nu", "a"], Method::Ddm, 0.0)?;
    let last = res.increments.last().expect("increments");
    let (p, a, b, e, nu) = (1.0, 1.0, 2.0, 1000.0, 0.3);
    let (d, s) = (Dual64::from, Dual64::new);
    let fdm = sensitivities(&model, name, &["a"], Method::FdmCentral, 1e-6)?;
    let fdm_a = fdm.increments.last().expect("increments").derivatives[0][0];
    // the 1 % for the displacement; the derivatives carry the same discretisation
    // error (du/dE = -u/E exactly), du/dnu and du/da a derivative of it: 1 % as well
    Ok(vec![
        row(
            name,
            "bore displacement u(a)",
            lame_bore(p, a, b, e, nu),
            last.values[0],
            0.01,
        ),
        row(
            name,
            "du(a)/dE",
            lame_bore(p, d(a), b, s(e, 1.0), d(nu)).eps,
            last.derivatives[0][0],
            0.01,
        ),
        row(
            name,
            "du(a)/dnu",
            lame_bore(p, d(a), b, d(e), s(nu, 1.0)).eps,
            last.derivatives[0][1],
            0.01,
        ),
        row(
            name,
            "du(a)/da (boundary-driven velocity field)",
            lame_bore(p, s(a, 1.0), b, d(e), d(nu)).eps,
            last.derivatives[0][2],
            0.01,
        ),
        // central FDM, beta = 1e-6: truncation 1e-12, the reruns' round-off about 1e-10
        row(
            name,
            "du(a)/da: DDM against central FDM of reruns (expected)",
            fdm_a,
            last.derivatives[0][2],
            1e-6,
        ),
    ])
}

/// A morph to the 1.05-scaled Lamé mesh against the scale map: `d/db = 0.05 d/ds`.
pub fn morph_against_scale(meshes: &Path) -> Result<Vec<OracleRow>, ImportedError> {
    let name = "lame-octant (morph)";
    let mut s = Scene::from_file(&meshes.join("lame-octant.toml"))?;
    s.study.params.clear();
    s.shapes = vec![
        ShapeSpec {
            name: "morph".into(),
            nodes: "shell".into(),
            value: None,
            map: MapSpec::Morph {
                mesh: "lame-octant-scaled.msh".into(),
                set: None,
            },
        },
        ShapeSpec {
            name: "scale".into(),
            nodes: "shell.all".into(),
            value: None,
            map: MapSpec::Scale {
                centre: [0.0; 3],
                axis: None,
            },
        },
    ];
    let model = s.build()?;
    let res = sensitivities(&model, name, &["morph", "scale"], Method::Ddm, 0.0)?;
    let last = res.increments.last().expect("increments");
    Ok(vec![row(
        name,
        "d u(a) / d morph = 0.05 d u(a) / d scale (expected)",
        0.05 * last.derivatives[0][1],
        last.derivatives[0][0],
        1e-10,
    )])
}

/// Whether `meshes` holds the imported-geometry scenes.
pub fn present(meshes: &Path) -> bool {
    meshes.join("hertz-cylinders.toml").exists()
}

/// Every imported-geometry check, if `meshes` holds the scenes (else none). The validation
/// runs them as jobs of their own (`Job::Imported`), in this order.
pub fn imported_oracles(meshes: &Path) -> Result<Vec<OracleRow>, ImportedError> {
    if !present(meshes) {
        return Ok(Vec::new());
    }
    let mut rows = hertz_cylinders(meshes, false)?;
    rows.extend(hertz_cylinders(meshes, true)?);
    rows.extend(lame_sphere(meshes)?);
    rows.extend(morph_against_scale(meshes)?);
    Ok(rows)
}
