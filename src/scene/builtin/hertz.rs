//! A rigid cylinder on a plane-strain block (oracles.md section 4).

use super::*;

/// Parameters of the Hertz line-contact scene (shared/oracles.md section 4).
#[derive(Clone, Debug)]
pub struct HertzSpec {
    /// Radius `R` of the rigid cylinder.
    pub radius: f64,
    /// Young's modulus `E` of the block.
    pub young: f64,
    /// Poisson's ratio `nu` of the block.
    pub nu: f64,
    /// Target half-width; the load is `P = a^2 pi E* / (4 R)` per unit length.
    pub half_width: f64,
    /// Elements across the target half-width.
    pub elements_across: usize,
    /// The block's element shape, in its standard formulation (hex8: incompatible modes).
    pub element: crate::element::Shape,
    /// Elements outside the fine zone: along x (graded away from it) and down the block.
    pub far_elements: [usize; 2],
}

impl Default for HertzSpec {
    fn default() -> Self {
        HertzSpec {
            radius: 10.0,
            young: 1e5,
            nu: 0.3,
            half_width: 0.5,
            elements_across: 12,
            element: crate::element::Shape::Hex8,
            far_elements: [12, 14],
        }
    }
}

impl HertzSpec {
    /// Plane-strain modulus `E* = E / (1 - nu^2)`.
    pub fn e_star(&self) -> f64 {
        self.young / (1.0 - self.nu * self.nu)
    }
    /// Load per unit length giving the target half-width.
    pub fn load(&self) -> f64 {
        self.half_width.powi(2) * std::f64::consts::PI * self.e_star() / (4.0 * self.radius)
    }
}

/// Half model (x >= 0) of a plane-strain block pushed by a bottom pressure against a rigid
/// cylinder of radius R whose lowest line touches the block's top at x = 0 (load control).
pub fn hertz(h: &HertzSpec) -> Scene {
    let a = h.half_width;
    let side = 10.0 * a; // half width of the block: 20a x 20a overall
    let depth = 20.0 * a;
    let fine = h.elements_across * 2; // fine zone 0..2a
    let thickness = a / h.elements_across as f64;
    let mut block = block_body(
        "block",
        [0.0, -depth, 0.0],
        [
            graded(side, 0.2, fine, h.far_elements[0], 8.0),
            Axis {
                length: depth,
                zones: vec![
                    Zone {
                        fraction: 0.9,
                        elements: h.far_elements[1],
                        ratio: 1.0 / 10.0,
                    },
                    Zone {
                        fraction: 0.1,
                        elements: fine,
                        ratio: 1.0,
                    },
                ],
            },
            Axis::uniform(thickness, 1),
        ],
        Material::Svk(StVenantKirchhoff::new(h.young, h.nu)),
        Kinematics::Small,
    );
    if h.element != crate::element::Shape::Hex8 {
        if let Some(b) = block.block_mut() {
            b.element = h.element;
        }
        block.formulation = None;
    }
    Scene {
        name: "hertz".into(),
        description: format!(
            "Hertz line contact, plane strain: rigid cylinder R = {} on an elastic block E = {}, nu = {}, P = {:.6e} per unit length for a = {}.",
            h.radius, h.young, h.nu, h.load(), a
        ),
        bodies: vec![block],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed_set("symmetry", "block.xmin", &[Component::X]),
            fixed_set("plane-strain", "block.all", &[Component::Z]),
        ],
        loads: vec![LoadSpec {
            name: "P".into(),
            set: "block.ymin".into(),
            component: Component::Y,
            value: 0.5 * h.load() * thickness,
            amplitude: ramp(),
        }],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![ContactSpec {
            name: "cylinder".into(),
            hitting: "block.ymax".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::Cylinder {
                    axis_point: [0.0, h.radius, 0.0],
                    axis: [0.0, 0.0, 1.0],
                    radius: h.radius,
                },
                motion: vec![],
            },
            normal: NormalLaw::Lagrange,
            friction: None,
            tangential_stiffness: None,
            constraint_scale: None,
            activation: None,
            search_radius: None,
            smoothing: None,
        }],
        steps: vec![StepSpec {
            end: 1.0,
            increments: 4,
        }],
        responses: vec![
            ResponseSpec::PressureProfile {
                name: "p".into(),
                pair: "cylinder".into(),
                along: Component::X,
                area: Default::default(),
                // one response per node: the regression data's columns
                per: ProfilePoints::Node,
            },
            ResponseSpec::TargetForce {
                name: "cylinder-force-y".into(),
                pair: "cylinder".into(),
                component: Component::Y,
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}

/// The closed-form checks of the `hertz` scene on its DDM run.
pub(crate) fn hertz_oracles(ddm: &SensitivityResults, out: &mut Vec<OracleCheck>) {
    let res = ddm;
    let (_, p_of, _) = lookups(ddm);
    // oracles.md section 4 at fixed P: p0 = 2 P / (pi a), dp0/dE = p0 / (2 E); p0
    // within 2-4 % on this mesh (12 elements across a), its derivative likewise
    let h = super::HertzSpec::default();
    let last = res.increments.last();
    let peak = last.and_then(|inc| {
        res.responses
            .iter()
            .enumerate()
            .filter(|(_, n)| n.starts_with("p["))
            .max_by(|a, b| inc.values[a.0].total_cmp(&inc.values[b.0]))
            .map(|(r, _)| r)
    });
    if let (Some(inc), Some(r)) = (last, peak) {
        let p = h.load();
        let a = (4.0 * p * h.radius / (std::f64::consts::PI * h.e_star())).sqrt();
        let p0 = 2.0 * p / (std::f64::consts::PI * a);
        out.push(row(
            "peak pressure p0 = 2 P / (pi a)",
            p0,
            inc.values[r],
            0.04,
        ));
        if let Some(pe) = p_of("E") {
            out.push(row(
                "d p0 / d E = p0 / (2 E)",
                p0 / (2.0 * h.young),
                inc.derivatives[r][pe],
                0.04,
            ));
        }
    }
}
