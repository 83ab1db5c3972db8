//! The strip pulled out along a rigid plane (oracles.md section 7).

use super::*;

/// Parameters of the strip pull-out scene (shared/oracles.md section 7).
#[derive(Clone, Debug)]
pub struct StripSpec {
    /// Length `L` along x.
    pub length: f64,
    /// Thickness `t` along y.
    pub thickness: f64,
    /// Width `b` along z.
    pub width: f64,
    /// Young's modulus `E`.
    pub young: f64,
    /// Coulomb friction coefficient `mu`.
    pub mu: f64,
    /// Normal load per unit length.
    pub n: f64,
    /// Largest pull force.
    pub force: f64,
    /// Elements along the length.
    pub elements: usize,
    /// Load increments per unit of pseudo-time (the history runs to t = 2).
    pub increments_per_unit: usize,
}

impl Default for StripSpec {
    fn default() -> Self {
        StripSpec {
            // thin: the 1D oracle holds where the slip zone exceeds 20 thicknesses
            length: 10.0,
            thickness: 0.02,
            width: 0.1,
            young: 1e5,
            mu: 0.5,
            n: 1.0,
            force: 1.5,
            elements: 100,
            increments_per_unit: 10,
        }
    }
}

/// A strip on the rigid plane y = 0 under a normal load `n` per unit length, pulled at
/// x = L by a force F: 0 -> F_1 (t = 1) -> 0 (t = 2). Small kinematics, nu = 0.
pub fn strip_pullout(s: &StripSpec) -> Scene {
    Scene {
        name: "strip-pullout".into(),
        description: format!(
            "Frictional strip pull-out (shared/oracles.md section 7): L = {}, t = {}, b = {}, E = {}, mu = {}, n = {}, F1 = {}.",
            s.length, s.thickness, s.width, s.young, s.mu, s.n, s.force
        ),
        bodies: vec![block_body(
            "strip",
            [0.0; 3],
            [
                Axis::uniform(s.length, s.elements),
                Axis::uniform(s.thickness, 1),
                Axis::uniform(s.width, 1),
            ],
            Material::Svk(StVenantKirchhoff::new(s.young, 0.0)),
            Kinematics::Small,
        )],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![fixed_set("plane-z", "strip.all", &[Component::Z])],
        loads: vec![
            LoadSpec {
                name: "n".into(),
                set: "strip.ymax".into(),
                component: Component::Y,
                value: -s.n * s.length,
                amplitude: vec![(0.0, 1.0), (2.0, 1.0)],
            },
            LoadSpec {
                name: "F".into(),
                set: "strip.xmax".into(),
                component: Component::X,
                value: s.force,
                amplitude: vec![(0.0, 0.0), (1.0, 1.0), (2.0, 0.0)],
            },
        ],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![ContactSpec {
            name: "ground".into(),
            hitting: "strip.ymin".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::Plane {
                    point: [0.0; 3],
                    normal: [0.0, 1.0, 0.0],
                },
                motion: vec![],
            },
            normal: NormalLaw::Lagrange,
            friction: Some(Friction::Coulomb(Coulomb::new(s.mu))),
            // 10 x the axial stiffness EA/h of one element: the elastic slip (mu n h / eps_T)
            // stays below 1e-4 of u0, and Newton is not crippled by a tangent dominated by
            // the penalty (1e4 x EA/h made the slip front advance one node per iteration)
            tangential_stiffness: Some(10.0 * s.young * s.thickness * s.width * s.elements as f64 / s.length),
            constraint_scale: None,
            activation: None,
            search_radius: None,
            smoothing: None,
        }],
        steps: vec![StepSpec {
            end: 2.0,
            increments: 2 * s.increments_per_unit,
        }],
        responses: vec![ResponseSpec::Displacement {
            name: "u0".into(),
            set: "strip.xmax".into(),
            component: Component::X,
        }],
        // unloading leaves most of the strip stuck with friction forces locked in at the
        // forward slip limit; from an extrapolated start Newton spreads slip far beyond the
        // reverse-slip zone and lifts nodes off until cut back (observed; the locked-in forces
        // are the likely cause): 113 increments instead of 31 at 200 elements
        // (SolverSettings::extrapolate)
        solver: SolverSettings {
            extrapolate: false,
            ..SolverSettings::default()
        },
        study: StudySpec::default(),
    }
}

/// The closed-form checks of the `strip-pullout` scene on its DDM run.
pub(crate) fn strip_pullout_oracles(ddm: &SensitivityResults, out: &mut Vec<OracleCheck>) {
    let (r_of, p_of, at) = lookups(ddm);
    let s = StripSpec::default();
    let k = s.young * s.thickness * s.width * s.mu * s.n;
    if let (Some(r), Some(pm), Some(pe), Some(end)) = (r_of("u0"), p_of("mu"), p_of("E"), at(1.0)) {
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
