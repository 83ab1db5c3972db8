//! Leaf scenes: the paper's two-leaf spring (section 3.2) and the stacked-leaves beam oracle
//! (shared/oracles.md section 8).

use super::*;

/// Dimensions, material and load path of the two-leaf spring (units: N, mm, MPa).
///
/// The paper gives no dimensions. These are chosen so that the three effects it discusses
/// appear: the tip deflection reaches 0.3 L (geometric nonlinearity: the tip moves inward by
/// about 6 % of L and the leaf rotates by 25 degrees), the clamp region yields on the first
/// loading (elastic tip deflection at first yield about 0.14 L for the upper leaf alone), and
/// the lower leaf is shorter, so the leaves touch at its tip.
#[derive(Clone, Debug)]
pub struct LeafSpringSpec {
    /// Upper leaf length L (the shape parameter `upper.length.x`).
    pub upper_length: f64,
    /// Lower leaf length.
    pub lower_length: f64,
    /// Thickness of each leaf.
    pub thickness: f64,
    /// Width of the leaves (one element across; free faces, so plane stress across).
    pub width: f64,
    /// Clearance between the leaves in the unloaded state (keeps the clamped root nodes, which
    /// can never move, out of the active contact set).
    pub clearance: f64,
    /// Young's modulus E of both leaves.
    pub young: f64,
    /// Poisson's ratio nu.
    pub nu: f64,
    /// Initial yield stress sigma_y (von Mises).
    pub sigma_y: f64,
    /// Linear isotropic hardening modulus H.
    pub hardening: f64,
    /// One friction coefficient for the leaf-leaf and block-leaf interfaces.
    pub mu: f64,
    /// Largest downward block displacement (loading and reloading).
    pub stroke: f64,
    /// Block displacement at the end of unloading.
    pub unload_to: f64,
    /// Elements along the upper leaf; the lower leaf gets the same element length.
    pub elements_along: usize,
    /// Elements through each leaf's thickness.
    pub elements_through: usize,
    /// Elements across each leaf's width (1 in the paper's model; the scaling study refines it).
    pub elements_across: usize,
    /// Reach of the leaf-leaf contact search along the leaves (mm): a lower-leaf node's
    /// candidate faces on the upper leaf lie within this distance along x (plus half an
    /// element width across). Every candidate face's nodes are coupled with the node in the
    /// sparsity pattern, so on refined meshes this should shrink with the element length.
    pub search_along: f64,
    /// Increments of loading; unloading and reloading get the same increment size.
    pub load_increments: usize,
}

impl Default for LeafSpringSpec {
    fn default() -> Self {
        LeafSpringSpec {
            upper_length: 100.0,
            // mid-face of the upper leaf's underside on the 2.5, 5 and 1 mm meshes: a tip that
            // sits under an edge between two faces flips between them from one Newton
            // iteration to the next (node-to-segment contact is only C0 there)
            lower_length: 71.5,
            thickness: 2.0,
            width: 20.0,
            clearance: 0.02,
            young: 206e3,
            nu: 0.3,
            sigma_y: 800.0,
            hardening: 2000.0,
            mu: 0.5,
            stroke: 30.0,
            unload_to: 10.0,
            elements_along: 40,
            elements_through: 2,
            elements_across: 1,
            search_along: 10.0,
            load_increments: 15,
        }
    }
}

/// Active-set gap weight of both leaf-spring pairs ([`crate::contact::ContactPair::activation`]):
/// the leaf slides under the curved block nose, and with the default weight every slide of a
/// few hundredths of a millimetre releases the loaded node under it.
pub(crate) const LEAF_ACTIVATION: f64 = 1e-3;

impl LeafSpringSpec {
    /// The paper-resolution mesh and load path (`validate --full`).
    pub fn full() -> Self {
        LeafSpringSpec {
            elements_along: 100,
            elements_through: 4,
            load_increments: 30,
            ..Self::default()
        }
    }

    /// A coarse mesh (5 mm elements) and a shorter path (20 mm down, back to 10 mm, down
    /// again; the clamp just yields) for the test suite's reduced validation.
    pub fn reduced() -> Self {
        LeafSpringSpec {
            elements_along: 20,
            stroke: 20.0,
            unload_to: 10.0,
            load_increments: 8,
            ..Self::default()
        }
    }

    /// Pseudo-times: 0 -> 1 loading, 1 -> 2 unloading, 2 -> 3 reloading. The amplitude of the
    /// block's downward motion at those times.
    fn path(&self) -> Vec<(f64, f64)> {
        vec![
            (0.0, 0.0),
            (1.0, 1.0),
            (2.0, self.unload_to / self.stroke),
            (3.0, 1.0),
        ]
    }
}

/// The paper's second example (section 3.2): an elastoplastic two-leaf spring, half model by
/// symmetry about its centre clamp, loaded at the tip of the upper leaf by a rigid block: load,
/// unload, reload. Frictional contact (one mu) between the leaves and between the upper leaf
/// and the block. Large deformation, J2 with linear isotropic hardening, incompatible-mode hex8.
///
/// Geometry (x along the leaves, y up, z across): the lower leaf occupies
/// `[0, L_lower] x [-h, 0]`, the upper leaf `[0, L] x [c, c + h]` with a clearance `c`; both are
/// clamped at x = 0. The block is rigid with a half-cylinder nose (radius 5 mm) that touches
/// the upper leaf 10 mm from its tip; it moves down by `stroke`, back up to `unload_to`, and
/// down to `stroke` again, and the leaf slides under the nose.
pub fn leaf_spring(s: &LeafSpringSpec) -> Scene {
    let h = s.thickness;
    let c = s.clearance;
    let j2 = Material::J2(J2Plasticity::linear(s.young, s.nu, s.sigma_y, s.hardening));
    let element = s.upper_length / s.elements_along as f64;
    let lower_elements = ((s.lower_length / element).round() as usize).max(1);
    let friction = Some(Friction::Coulomb(Coulomb::new(s.mu)));
    // The block's nose is a half cylinder (radius 5 mm, a rounded box as wide as its corner
    // radius) whose lowest line touches the upper leaf 10 mm from its tip. The leaf's top
    // slopes away from it on both sides, so the contact stays on the nose; as the leaf bends,
    // its tip moves inward (about 6 mm at 0.3 L) and the leaf slides under the nose, with
    // friction, towards its tip.
    let radius = 5.0;
    let half = [radius, 10.0, 2.0 * s.width];
    let push_at = s.upper_length - 10.0;
    // The nose starts 0.01 mm above the leaf: a node touching it exactly (g = 0, here the node
    // at x = 90 under the nose's lowest line) sits on the open/closed kink, and a perturbation
    // of the design (the leaf's length moves that node along the curved nose) decides which
    // side it starts on, changing the friction history from the first increment on.
    let start_gap = 0.01;
    let name = if s.mu == 0.0 {
        "leaf-spring-mu0"
    } else {
        "leaf-spring"
    };
    Scene {
        name: name.into(),
        description: format!(
            "Two-leaf spring (Chen, Hisada et al. section 3.2), half model about the centre clamp: upper leaf L = {} mm, lower leaf {} mm, both {} mm thick and {} mm wide, clearance {} mm; J2, E = {} MPa, nu = {}, sigma_y = {} MPa, H = {} MPa; large deformation; a rigid block with a half-cylinder nose (r = {radius} mm) pushes the upper leaf 10 mm from its tip down {} mm, back to {} mm, down to {} mm again; Coulomb mu = {} at both interfaces.",
            s.upper_length, s.lower_length, h, s.width, c, s.young, s.nu, s.sigma_y, s.hardening, s.stroke, s.unload_to, s.stroke, s.mu
        ),
        bodies: vec![
            block_body(
                "upper",
                [0.0, c, 0.0],
                [
                    Axis::uniform(s.upper_length, s.elements_along),
                    Axis::uniform(h, s.elements_through),
                    Axis::uniform(s.width, s.elements_across.max(1)),
                ],
                j2.clone(),
                Kinematics::Large,
            ),
            block_body(
                "lower",
                [0.0, -h, 0.0],
                [
                    Axis::uniform(s.lower_length, lower_elements),
                    Axis::uniform(h, s.elements_through),
                    Axis::uniform(s.width, s.elements_across.max(1)),
                ],
                j2,
                Kinematics::Large,
            ),
        ],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed_set("clamp-upper", "upper.xmin", &[Component::X, Component::Y, Component::Z]),
            fixed_set("clamp-lower", "lower.xmin", &[Component::X, Component::Y, Component::Z]),
        ],
        loads: vec![],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![
            ContactSpec {
                name: "leaves".into(),
                // the lower leaf's top nodes (its tip corner among them) against the upper
                // leaf's underside
                hitting: "lower.ymax".into(),
                target: TargetSpec::Faces("upper.ymin".into()),
                normal: NormalLaw::Lagrange,
                friction: friction.clone(),
                tangential_stiffness: None,
                constraint_scale: None,
                // faces within 10 mm along the leaf (the leaves slide about 1 mm on each
                // other): the default, three face diagonals, is dominated by the width and
                // couples every lower node with the whole upper leaf (a dense block in the LU)
                activation: Some(LEAF_ACTIVATION),
                search_radius: Some({
                    let half_face = 0.5 * s.width / s.elements_across.max(1) as f64;
                    (half_face * half_face + s.search_along * s.search_along).sqrt()
                }),
                // faceted node-to-segment contact, the paper's: the built-in scenes' results are the
                // report's regression checks (user scenes smooth by default)
                smoothing: Some(Smoothing::None),
            },
            ContactSpec {
                name: "block".into(),
                hitting: "upper.ymax".into(),
                target: TargetSpec::Rigid {
                    surface: RigidSpec::RoundedBox {
                        center: [
                            push_at,
                            c + h + start_gap + half[1],
                            0.5 * s.width,
                        ],
                        half_extents: half,
                        radius,
                    },
                    motion: vec![MotionSpec {
                        component: Component::Y,
                        value: Some(-s.stroke),
                        force: None,
                        amplitude: s.path(),
                    }],
                },
                normal: NormalLaw::Lagrange,
                friction,
                tangential_stiffness: None,
                constraint_scale: None,
                activation: Some(LEAF_ACTIVATION),
                search_radius: None,
                smoothing: None,
            },
        ],
        steps: vec![
            StepSpec {
                end: 1.0,
                increments: s.load_increments,
            },
            StepSpec {
                end: 2.0,
                increments: unload_increments(s),
            },
            StepSpec {
                end: 3.0,
                increments: unload_increments(s),
            },
        ],
        responses: vec![
            ResponseSpec::TargetForce {
                name: "block-force".into(),
                pair: "block".into(),
                component: Component::Y,
            },
            ResponseSpec::Displacement {
                name: "tip".into(),
                set: "upper.xmax".into(),
                component: Component::Y,
            },
            ResponseSpec::History {
                name: "alpha-root".into(),
                body: "upper".into(),
                // the element at the clamp on the upper leaf's top surface
                element: s.elements_along * (s.elements_through - 1),
                point: 7,
                variable: "alpha".into(),
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec {
            params: vec!["upper.length.x".into(), "mu".into()],
            beta: None,
        },
    }
}

fn unload_increments(s: &LeafSpringSpec) -> usize {
    let per = s.stroke / s.load_increments as f64;
    (((s.stroke - s.unload_to) / per).round() as usize).max(1)
}

/// Dimensions and load of the stacked-leaves oracle (shared/oracles.md section 8).
#[derive(Clone, Debug)]
pub struct StackedLeavesSpec {
    /// Length L of each leaf.
    pub length: f64,
    /// Thickness h of each leaf (also the distance d between their centroids).
    pub thickness: f64,
    /// Width b of the leaves.
    pub width: f64,
    /// Clearance between the leaves (the oracle's leaves touch along their length with zero
    /// pressure; a small clearance makes them touch at the tip only).
    pub clearance: f64,
    /// Young's modulus E (nu = 0).
    pub young: f64,
    /// Coulomb friction coefficient at the tip.
    pub mu: f64,
    /// Tip load on the upper leaf.
    pub load: f64,
    /// Elements along each leaf (one through the thickness).
    pub elements_along: usize,
    /// Increments per unit of pseudo-time (loading is t = 0..1, unloading t = 1..2).
    pub increments_per_unit: usize,
}

impl Default for StackedLeavesSpec {
    fn default() -> Self {
        StackedLeavesSpec {
            length: 100.0,
            thickness: 2.0,
            width: 10.0,
            clearance: 1e-3,
            young: 200e3,
            mu: 0.2,
            load: 8.0,
            elements_along: 50,
            increments_per_unit: 5,
        }
    }
}

impl StackedLeavesSpec {
    /// Bending stiffness of one leaf.
    pub(crate) fn bending_stiffness(&self) -> f64 {
        self.young * self.width * self.thickness.powi(3) / 12.0
    }

    /// Frictionless bending deflection of the loaded leaf's tip, `P L^3 / (6 E I)` (beam
    /// theory; the upper leaf also closes the clearance alone, which adds half of it).
    pub fn deflection(&self) -> f64 {
        self.load * self.length.powi(3) / (6.0 * self.bending_stiffness())
    }

    /// `|d delta / d mu| = P d L^2 / (8 E I)` on the slipping branches (d = h).
    pub(crate) fn deflection_mu_slope(&self) -> f64 {
        self.load * self.thickness * self.length.powi(2) / (8.0 * self.bending_stiffness())
    }
}

/// Two identical elastic leaves clamped at x = 0, the upper one loaded at its tip by P (t = 0
/// -> 1) and unloaded (t = 1 -> 2); Coulomb friction between them. Small kinematics, nu = 0,
/// incompatible-mode hex8 with one element through each leaf's thickness.
pub fn stacked_leaves(s: &StackedLeavesSpec) -> Scene {
    let h = s.thickness;
    let svk = Material::Svk(StVenantKirchhoff::new(s.young, 0.0));
    let axes = || {
        [
            Axis::uniform(s.length, s.elements_along),
            Axis::uniform(h, 1),
            Axis::uniform(s.width, 1),
        ]
    };
    Scene {
        name: "stacked-leaves".into(),
        description: format!(
            "Two stacked cantilever leaves with tip friction (shared/oracles.md section 8): L = {}, h = {}, b = {}, clearance {}, E = {}, nu = 0, mu = {}, tip load P = {} on the upper leaf, loaded and unloaded.",
            s.length, h, s.width, s.clearance, s.young, s.mu, s.load
        ),
        bodies: vec![
            block_body("upper", [0.0, s.clearance, 0.0], axes(), svk.clone(), Kinematics::Small),
            block_body("lower", [0.0, -h, 0.0], axes(), svk, Kinematics::Small),
        ],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed_set("clamp-upper", "upper.xmin", &[Component::X, Component::Y, Component::Z]),
            fixed_set("clamp-lower", "lower.xmin", &[Component::X, Component::Y, Component::Z]),
        ],
        loads: vec![LoadSpec {
            name: "P".into(),
            set: "upper.xmax".into(),
            component: Component::Y,
            value: -s.load,
            amplitude: vec![(0.0, 0.0), (1.0, 1.0), (2.0, 0.0)],
        }],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![ContactSpec {
            name: "leaves".into(),
            // The oracle's friction acts at the tip: the upper leaf's bottom tip edge against
            // the lower leaf's top. It slides inward relative to the lower leaf (compressed
            // against stretched fibres), so it stays on the lower faces. (Identical leaves
            // bend alike: behind the tip the gap is second order, 6e-7 mm one element back,
            // and taking those nodes as hitting nodes only makes the active set chatter.)
            hitting: "upper.xmax & upper.ymin".into(),
            target: TargetSpec::Faces("lower.ymax".into()),
            normal: NormalLaw::Lagrange,
            friction: Some(Friction::Coulomb(Coulomb::new(s.mu))),
            tangential_stiffness: None,
            constraint_scale: None,
            activation: None,
            search_radius: None,
            // faceted node-to-segment contact, the paper's: the built-in scenes' results are the
                // report's regression checks (user scenes smooth by default)
                smoothing: Some(Smoothing::None),
        }],
        steps: vec![StepSpec {
            end: 2.0,
            increments: 2 * s.increments_per_unit,
        }],
        responses: vec![
            ResponseSpec::Displacement {
                name: "delta".into(),
                set: "upper.xmax".into(),
                component: Component::Y,
            },
            ResponseSpec::Displacement {
                name: "delta-lower".into(),
                set: "lower.xmax".into(),
                component: Component::Y,
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec {
            params: vec!["mu".into(), "E".into()],
            beta: None,
        },
    }
}

/// The closed-form checks of the `stacked-leaves` scene on its DDM run.
pub fn stacked_leaves_oracles(ddm: &SensitivityResults, out: &mut Vec<OracleCheck>) {
    let (r_of, p_of, at) = lookups(ddm);
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
