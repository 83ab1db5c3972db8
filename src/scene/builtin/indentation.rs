//! The paper's example 3.1: a rigid block pressed into an elastic half-space, then slid.

use super::*;

/// The paper's first example (section 3.1): a rigid block with rounded corners pressed into an
/// elastic half-space, then slid so that finite sliding occurs.
///
/// Plane strain through a one-element-thick slab (out-of-plane displacement fixed), 500 mm x
/// 250 mm, graded from 1.67 mm elements under and around the block to a coarse region; small
/// deformation, elasticity (E = 200 GPa, nu = 0.3, units N and mm). The block is 20 mm wide
/// with 1 mm corner radii; it is pressed down u_y = -0.01 mm (t = 0..1), then slid
/// u_x = 3.33 mm (t = 1..2, two fine elements); Coulomb friction mu = 0.5.
pub fn indentation(press_increments: usize, slide_increments: usize) -> Scene {
    indentation_mesh(press_increments, slide_increments, 1.0)
}

/// Largest refinement factor [`indentation_refined`] accepts (about 4 x 10^6 unknowns).
pub const MAX_INDENTATION_REFINEMENT: f64 = 16.0;

/// [`indentation`] on a mesh refined (or coarsened) in the plane by `refinement`: every
/// zone of the x and y axes gets `round(refinement * n)` elements (at least one) where the
/// paper's mesh has `n`, with the same zone extents and grading, so the fine elements are
/// `1.67 / refinement` mm wide. Geometry, material, contact, load path and the slab's
/// one-element thickness (plane strain) are unchanged; `refinement = 1` is [`indentation`].
/// Fails on a refinement that is not finite or lies outside `(0, MAX_INDENTATION_REFINEMENT]`.
pub fn indentation_refined(
    press_increments: usize,
    slide_increments: usize,
    refinement: f64,
) -> Result<Scene, SceneError> {
    if !(refinement.is_finite() && refinement > 0.0 && refinement <= MAX_INDENTATION_REFINEMENT) {
        return Err(invalid(
            "refinement",
            format!("must lie in (0, {MAX_INDENTATION_REFINEMENT}], got {refinement}"),
        ));
    }
    Ok(indentation_mesh(
        press_increments,
        slide_increments,
        refinement,
    ))
}

pub(crate) fn indentation_mesh(
    press_increments: usize,
    slide_increments: usize,
    refinement: f64,
) -> Scene {
    let refine = |n: usize| ((n as f64 * refinement).round() as usize).max(1);
    let h: f64 = 1.67;
    let fine_width: f64 = 60.0; // -30 .. +30 mm around the block's start and its slide
    let fine = (fine_width / h).round() as usize;
    let side = (500.0 - fine_width) / 2.0;
    let x = Axis {
        length: 500.0,
        zones: vec![
            Zone {
                fraction: side / 500.0,
                elements: refine(12),
                ratio: 1.0 / 12.0,
            },
            Zone {
                fraction: fine_width / 500.0,
                elements: refine(fine),
                ratio: 1.0,
            },
            Zone {
                fraction: side / 500.0,
                elements: refine(12),
                ratio: 12.0,
            },
        ],
    };
    let fine_depth = 10.0 * h;
    let y = Axis {
        length: 250.0,
        zones: vec![
            Zone {
                fraction: (250.0 - fine_depth) / 250.0,
                elements: refine(14),
                ratio: 1.0 / 14.0,
            },
            Zone {
                fraction: fine_depth / 250.0,
                elements: refine(10),
                ratio: 1.0,
            },
        ],
    };
    Scene {
        name: "indentation".into(),
        description: "Rigid block indenting and sliding on an elastic half-space (Chen, Hisada et al. section 3.1): plane strain, E = 200 GPa, nu = 0.3, block 20 mm wide with 1 mm corner radii, pressed 0.01 mm then slid 3.33 mm, mu = 0.5.".into(),
        bodies: vec![BodySpec {
            geometry: BodyGeometry::Block(BlockSpec {
                element: crate::element::Shape::Hex8,
                name: "slab".into(),
                origin: [-250.0, -250.0, 0.0],
                x,
                y,
                z: Axis::uniform(h, 1),
            }),
            material: Material::Svk(StVenantKirchhoff::new(200e3, 0.3)),
            kinematics: Kinematics::Small,
            formulation: Some(Formulation::IncompatibleModes),
        }],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed_set("base", "slab.ymin", &[Component::X, Component::Y]),
            fixed_set("plane-strain", "slab.all", &[Component::Z]),
        ],
        loads: vec![],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![ContactSpec {
            name: "block".into(),
            hitting: "slab.ymax".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::RoundedBox {
                    center: [-10.0 + 0.0, 10.0, 0.5 * h],
                    half_extents: [10.0, 10.0, 100.0],
                    radius: 1.0,
                },
                motion: vec![
                    MotionSpec {
                        component: Component::Y,
                        value: Some(-0.01),
                        force: None,
                        amplitude: vec![(0.0, 0.0), (1.0, 1.0), (2.0, 1.0)],
                    },
                    MotionSpec {
                        component: Component::X,
                        value: Some(3.33),
                        force: None,
                        amplitude: vec![(0.0, 0.0), (1.0, 0.0), (2.0, 1.0)],
                    },
                ],
            },
            normal: NormalLaw::Lagrange,
            friction: Some(Friction::Coulomb(Coulomb::new(0.5))),
            tangential_stiffness: None,
            constraint_scale: None,
            activation: None,
            search_radius: None,
            smoothing: None,
        }],
        steps: vec![
            StepSpec {
                end: 1.0,
                increments: press_increments,
            },
            StepSpec {
                end: 2.0,
                increments: slide_increments,
            },
        ],
        responses: vec![
            ResponseSpec::TargetForce {
                name: "block-force-x".into(),
                pair: "block".into(),
                component: Component::X,
            },
            ResponseSpec::TargetForce {
                name: "block-force-y".into(),
                pair: "block".into(),
                component: Component::Y,
            },
            ResponseSpec::PressureProfile {
                name: "p".into(),
                pair: "block".into(),
                along: Component::X,
                area: Default::default(),
                // one response per node: the regression data's columns
                per: ProfilePoints::Node,
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}
