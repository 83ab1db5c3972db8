//! The cantilever scenes (oracles.md section 3).

use super::*;

/// Parameters of the cantilever scenes.
#[derive(Clone, Debug)]
pub struct CantileverSpec {
    /// Length `L` along x.
    pub length: f64,
    /// Height `h` along y (the bending direction).
    pub height: f64,
    /// Width `b` along z.
    pub width: f64,
    /// Young's modulus `E`.
    pub young: f64,
    /// Poisson's ratio `nu`.
    pub nu: f64,
    /// Elements along the length.
    pub nx: usize,
    /// Elements through the height.
    pub ny: usize,
    /// Load parameter alpha = P L^2 / (E I) at the end of the history.
    pub alpha: f64,
    /// Number of equal load increments.
    pub increments: usize,
    /// Small or large deformation.
    pub kinematics: Kinematics,
    /// Hex8 element formulation.
    pub formulation: Formulation,
}

impl CantileverSpec {
    /// L/h = 50, nu = 0, alpha up to 5 (the elastica table).
    pub fn large_deflection() -> Self {
        CantileverSpec {
            length: 10.0,
            height: 0.2,
            width: 0.2,
            young: 1.0e5,
            nu: 0.0,
            nx: 50,
            ny: 2,
            alpha: 5.0,
            increments: 10,
            kinematics: Kinematics::Large,
            formulation: Formulation::IncompatibleModes,
        }
    }

    /// L/h = 20, 2 elements through the thickness, small load.
    pub fn small_deflection() -> Self {
        CantileverSpec {
            length: 2.0,
            height: 0.1,
            width: 0.1,
            young: 1.0e5,
            nu: 0.0,
            nx: 20,
            ny: 2,
            alpha: 1e-4,
            increments: 1,
            kinematics: Kinematics::Small,
            formulation: Formulation::IncompatibleModes,
        }
    }

    /// Second moment of area of the section.
    pub fn inertia(&self) -> f64 {
        self.width * self.height.powi(3) / 12.0
    }

    /// The tip load that gives `alpha`.
    pub fn load(&self) -> f64 {
        self.alpha * self.young * self.inertia() / self.length.powi(2)
    }
}

/// A cantilever along x, clamped at x = 0, dead load in -y on the tip face.
pub fn cantilever(c: &CantileverSpec) -> Scene {
    Scene {
        name: "cantilever".into(),
        description: format!(
            "Cantilever L = {}, h = {}, b = {}, E = {}, nu = {}; tip dead load P = alpha E I / L^2 with alpha = {} in -y, clamped at x = 0.",
            c.length, c.height, c.width, c.young, c.nu, c.alpha
        ),
        bodies: vec![BodySpec {
            geometry: BodyGeometry::Block(BlockSpec {
                element: crate::element::Shape::Hex8,
                name: "beam".into(),
                origin: [0.0, 0.0, 0.0],
                x: Axis::uniform(c.length, c.nx),
                y: Axis::uniform(c.height, c.ny),
                z: Axis {
                    length: c.width,
                    zones: vec![Zone {
                        fraction: 1.0,
                        elements: 1,
                        ratio: 1.0,
                    }],
                },
            }),
            material: Material::Svk(StVenantKirchhoff::new(c.young, c.nu)),
            kinematics: c.kinematics,
            formulation: Some(c.formulation),
        }],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![PrescribedSpec {
            name: "clamp".into(),
            set: "beam.xmin".into(),
            components: vec![Component::X, Component::Y, Component::Z],
            value: 0.0,
            amplitude: ramp(),
        }],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![],
        loads: vec![LoadSpec {
            name: "tip".into(),
            set: "beam.xmax".into(),
            component: Component::Y,
            value: -c.load(),
            amplitude: ramp(),
        }],
        steps: vec![StepSpec {
            end: 1.0,
            increments: c.increments,
        }],
        responses: vec![
            ResponseSpec::Displacement {
                name: "tip-deflection".into(),
                set: "beam.xmax".into(),
                component: Component::Y,
            },
            ResponseSpec::Displacement {
                name: "tip-shortening".into(),
                set: "beam.xmax".into(),
                component: Component::X,
            },
            ResponseSpec::Reaction {
                name: "clamp-reaction-y".into(),
                set: "beam.xmin".into(),
                component: Component::Y,
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}

/// The closed-form checks of the `cantilever-small` scene on its DDM run.
pub(crate) fn cantilever_small_oracles(ddm: &SensitivityResults, out: &mut Vec<OracleCheck>) {
    let res = ddm;
    let (r_of, p_of, _) = lookups(ddm);
    let c = super::CantileverSpec::small_deflection();
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

/// The closed-form checks of the `cantilever` scene on its DDM run.
pub(crate) fn cantilever_oracles(ddm: &SensitivityResults, out: &mut Vec<OracleCheck>) {
    let (r_of, p_of, at) = lookups(ddm);
    // oracles.md section 3, the elastica table (nu = 0, L/h = 50): w/L and
    // dw/dE = -(alpha L / E) f'; 1-3 % expected for a bending-capable hex8
    let c = super::CantileverSpec::large_deflection();
    if let (Some(r), Some(p)) = (r_of("tip-deflection"), p_of("E")) {
        for (alpha, w_l, fp) in [
            (1.0, 0.30172, 0.2489),
            (2.0, 0.49346, 0.1426),
            (5.0, 0.71379, 0.0362),
        ] {
            if let Some(inc) = at(alpha / c.alpha) {
                out.push(row(
                    &format!("w / L at alpha = {alpha}"),
                    w_l,
                    -inc.values[r] / c.length,
                    0.03,
                ));
                out.push(row(
                    &format!("dw/dE = -(alpha L / E) f' at alpha = {alpha}"),
                    -(alpha * c.length / c.young) * fp,
                    -inc.derivatives[r][p],
                    0.03,
                ));
            }
        }
    }
}
