//! Deformable blocks on deformable blocks: the contact patch test and the sliding block.

use super::*;

/// Contact patch test: a block pressed by a uniform pressure onto another with a matching mesh;
/// symmetry planes x = 0 and z = 0, the lower block's bottom fixed in y.
pub fn contact_patch(friction: Option<f64>) -> Scene {
    let material = Material::Svk(StVenantKirchhoff::new(1000.0, 0.3));
    let axes = || {
        [
            Axis::uniform(2.0, 4),
            Axis::uniform(1.0, 2),
            Axis::uniform(2.0, 4),
        ]
    };
    Scene {
        name: "contact-patch".into(),
        description:
            "Contact patch test: two blocks with matching meshes under a uniform pressure.".into(),
        bodies: vec![
            block_body(
                "lower",
                [0.0; 3],
                axes(),
                material.clone(),
                Kinematics::Small,
            ),
            block_body(
                "upper",
                [0.0, 1.0, 0.0],
                axes(),
                material,
                Kinematics::Small,
            ),
        ],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed_set("lower-x", "lower.xmin", &[Component::X]),
            fixed_set("upper-x", "upper.xmin", &[Component::X]),
            fixed_set("lower-z", "lower.zmin", &[Component::Z]),
            fixed_set("upper-z", "upper.zmin", &[Component::Z]),
            fixed_set("lower-y", "lower.ymin", &[Component::Y]),
        ],
        loads: vec![LoadSpec {
            name: "p".into(),
            set: "upper.ymax".into(),
            component: Component::Y,
            value: -4.0 * 10.0,
            amplitude: ramp(),
        }],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![ContactSpec {
            name: "interface".into(),
            hitting: "upper.ymin".into(),
            target: TargetSpec::Faces("lower.ymax".into()),
            normal: NormalLaw::Lagrange,
            friction: friction.map(|mu| Friction::Coulomb(Coulomb::new(mu))),
            tangential_stiffness: None,
            constraint_scale: None,
            activation: None,
            search_radius: None,
            // faceted node-to-segment contact, the paper's: the built-in scenes' results are the
            // report's regression checks (user scenes smooth by default)
            smoothing: Some(Smoothing::None),
        }],
        steps: vec![StepSpec {
            end: 1.0,
            increments: 1,
        }],
        responses: vec![ResponseSpec::PressureProfile {
            name: "p".into(),
            pair: "interface".into(),
            along: Component::X,
            area: Default::default(),
            // one response per node: the regression data's columns
            per: ProfilePoints::Node,
        }],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}

/// A deformable block (1.5 x 0.5, 3 elements) pressed by a total load of 1 onto a deformable
/// base (8 x 1, faces 1.0 long) and pulled 3 units along it: its hitting nodes cross several
/// target faces. Plane strain (z fixed), small kinematics, E = 1000, nu = 0.3.
pub fn sliding_block(friction: Option<f64>) -> Scene {
    let svk = || Material::Svk(StVenantKirchhoff::new(1000.0, 0.3));
    let axes = |n: [usize; 2], l: [f64; 2]| {
        [
            Axis::uniform(l[0], n[0]),
            Axis::uniform(l[1], n[1]),
            Axis::uniform(0.5, 1),
        ]
    };
    Scene {
        name: "sliding-block".into(),
        description: "A block pressed onto a deformable base and slid across three of its faces."
            .into(),
        bodies: vec![
            block_body(
                "base",
                [0.0, -1.0, 0.0],
                axes([8, 2], [8.0, 1.0]),
                svk(),
                Kinematics::Small,
            ),
            block_body(
                "slider",
                [1.0, 0.0, 0.0],
                axes([3, 1], [1.5, 0.5]),
                svk(),
                Kinematics::Small,
            ),
        ],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed_set("base", "base.ymin", &[Component::X, Component::Y]),
            fixed_set("plane-b", "base.all", &[Component::Z]),
            fixed_set("plane-s", "slider.all", &[Component::Z]),
            PrescribedSpec {
                name: "pull".into(),
                set: "slider.xmin".into(),
                components: vec![Component::X],
                value: 3.0,
                amplitude: vec![(0.0, 0.0), (1.0, 0.0), (2.0, 1.0)],
            },
        ],
        loads: vec![LoadSpec {
            name: "N".into(),
            set: "slider.ymax".into(),
            component: Component::Y,
            value: -1.0,
            amplitude: vec![(0.0, 0.0), (1.0, 1.0), (2.0, 1.0)],
        }],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![ContactSpec {
            name: "interface".into(),
            hitting: "slider.ymin".into(),
            target: TargetSpec::Faces("base.ymax".into()),
            normal: NormalLaw::Lagrange,
            friction: friction.map(|mu| Friction::Coulomb(Coulomb::new(mu))),
            tangential_stiffness: None,
            constraint_scale: None,
            // the slider travels 3 units: every face it may reach is a candidate
            activation: None,
            search_radius: Some(6.0),
            // faceted node-to-segment contact, the paper's: the built-in scenes' results are the
            // report's regression checks (user scenes smooth by default)
            smoothing: Some(Smoothing::None),
        }],
        steps: vec![
            StepSpec {
                end: 1.0,
                increments: 2,
            },
            StepSpec {
                end: 2.0,
                increments: 30,
            },
        ],
        responses: vec![ResponseSpec::Reaction {
            name: "pull".into(),
            set: "slider.xmin".into(),
            component: Component::X,
        }],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}
