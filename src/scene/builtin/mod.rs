//! The built-in scenes: the paper's examples and the oracle scenes, each in its own file with
//! the closed forms it is checked against.

use super::*;
use crate::contact::friction::Coulomb;
use crate::contact::{Friction, NormalLaw};
use crate::element::{Formulation, Kinematics};
use crate::material::{J2Plasticity, Material, StVenantKirchhoff};
use crate::mesh::{Axis, BlockSpec, Zone};
use crate::model::SolverSettings;
use crate::sensitivity::{IncrementSensitivity, SensitivityResults};

/// A built-in scene: its name, what it is, how it is made, the design parameters it is studied
/// with, and the closed forms its DDM run is checked against. [`BUILTIN`] registers them; a new
/// built-in scene is a file in this folder plus one entry there.
pub struct Builtin {
    /// The name `fricsens run NAME` takes.
    pub name: &'static str,
    /// One line on what it is.
    pub description: &'static str,
    /// The scene.
    pub make: fn() -> Scene,
    /// The design parameters it is studied with when the scene names none.
    pub params: &'static [&'static str],
    /// Its closed-form checks on a DDM run of it (`None`: it has none).
    pub oracles: Option<fn(&SensitivityResults, &mut Vec<OracleCheck>)>,
}

/// Every built-in scene, in the order `fricsens scenes` lists them.
pub const BUILTIN: &[Builtin] = &[
    Builtin {
        name: "cantilever",
        description: "elastic cantilever, tip dead load to alpha = P L^2/(E I) = 5, large deflection (oracles 3)",
        make: || cantilever(&CantileverSpec::large_deflection()),
        params: &["E"],
        oracles: Some(cantilever_oracles),
    },
    Builtin {
        name: "uniaxial-j2",
        description: "one hex8, J2 with linear hardening, uniaxial stress, strain cycle 0 -> +0.01 -> -0.01 (oracles 1)",
        make: || uniaxial_j2(Kinematics::Small, 10),
        params: &["sigma_y", "H", "E"],
        oracles: Some(uniaxial_j2_oracles),
    },
    Builtin {
        name: "uniaxial-svk",
        description: "one hex8, St Venant-Kirchhoff, uniaxial stress, stretch to 1.5 (oracles 2)",
        make: || uniaxial_svk(1.5, 5),
        // dP11/dnu = 0 exactly (oracles.md section 2): a relative error against a zero
        // derivative is undefined, so nu is not swept (tests check the zero)
        params: &["E"],
        oracles: Some(uniaxial_svk_oracles),
    },
    Builtin {
        name: "klarbring-2dof",
        description: "node with coupled stiffness on a rigid plane, Coulomb friction, load cycle (oracles 6)",
        make: || klarbring_2dof(10),
        params: &["mu"],
        oracles: Some(klarbring_2dof_oracles),
    },
    Builtin {
        name: "jenkins",
        description: "spring and Coulomb slider under a cyclic base displacement (oracles 5)",
        make: || jenkins(10),
        params: &["mu"],
        oracles: Some(jenkins_oracles),
    },
    Builtin {
        name: "strip-pullout",
        description: "strip on a rigid plane pulled at one end, partial slip, unloading (oracles 7)",
        make: || strip_pullout(&StripSpec::default()),
        params: &["mu", "E"],
        oracles: Some(strip_pullout_oracles),
    },
    Builtin {
        name: "hertz",
        description: "rigid cylinder on a plane-strain block, load control (oracles 4)",
        make: || hertz(&HertzSpec::default()),
        params: &["E"],
        oracles: Some(hertz_oracles),
    },
    Builtin {
        name: "contact-patch",
        description: "two blocks with matching meshes under uniform pressure, frictional",
        make: || contact_patch(Some(0.3)),
        params: &["mu"],
        oracles: None,
    },
    Builtin {
        name: "sliding-block",
        description: "deformable block slid across three faces of a deformable base, mu = 0.3",
        make: || sliding_block(Some(0.3)),
        params: &["mu"],
        oracles: None,
    },
    Builtin {
        name: "indentation",
        description: "paper 3.1: rigid block pressed into an elastic half-space, then slid 3.33 mm, mu = 0.5",
        make: || indentation(2, 10),
        params: &["mu"],
        oracles: None,
    },
    Builtin {
        name: "leaf-spring",
        description: "paper 3.2: elastoplastic two-leaf spring, block at the tip, load/unload/reload, mu = 0.5",
        make: || leaf_spring(&LeafSpringSpec::default()),
        params: &[],
        oracles: None,
    },
    Builtin {
        name: "leaf-spring-coarse",
        description: "the leaf spring on 5 mm elements, 20 mm down, back to 10, down again (quick look, tests)",
        make: || leaf_spring(&LeafSpringSpec::reduced()),
        params: &[],
        oracles: None,
    },
    Builtin {
        name: "leaf-spring-mu0",
        description: "paper 3.2 without friction (mu = 0)",
        make: || {
            leaf_spring(&LeafSpringSpec {
                mu: 0.0,
                ..LeafSpringSpec::default()
            })
        },
        params: &[],
        oracles: None,
    },
    Builtin {
        name: "stacked-leaves",
        description: "two elastic leaves clamped together, tip load, friction at the tip (oracles 8)",
        make: || stacked_leaves(&StackedLeavesSpec::default()),
        params: &[],
        oracles: Some(stacked_leaves_oracles),
    },
    Builtin {
        name: "cantilever-small",
        description: "elastic cantilever, L/h = 20, small tip load: P L^3/(3 E I) (oracles 3)",
        make: || cantilever(&CantileverSpec::small_deflection()),
        params: &["E"],
        oracles: Some(cantilever_small_oracles),
    },
];

/// Names and one-line descriptions of the built-in scenes.
pub fn builtin_list() -> Vec<(&'static str, &'static str)> {
    BUILTIN.iter().map(|b| (b.name, b.description)).collect()
}

/// A built-in scene by name, with the design parameters it is studied with.
pub fn builtin(name: &str) -> Option<Scene> {
    let b = BUILTIN.iter().find(|b| b.name == name)?;
    let mut scene = (b.make)();
    scene.name = name.to_string();
    if scene.study.params.is_empty() {
        scene.study.params = b.params.iter().map(|p| p.to_string()).collect();
    }
    Some(scene)
}

/// One closed-form check of a built-in scene: a quantity of its DDM run against its closed form.
#[derive(Clone, Debug, PartialEq)]
pub struct OracleCheck {
    /// What is checked.
    pub quantity: String,
    /// The closed form's value.
    pub expected: f64,
    /// The DDM run's value.
    pub got: f64,
    /// Largest accepted relative error (the closed form's own accuracy on this mesh, written
    /// beside each check).
    pub tolerance: f64,
}

impl OracleCheck {
    /// `|got - expected| / |expected|`.
    pub fn rel_error(&self) -> f64 {
        ((self.got - self.expected) / self.expected).abs()
    }

    /// Whether the relative error is within the tolerance.
    pub fn pass(&self) -> bool {
        self.rel_error() <= self.tolerance
    }
}

/// The closed-form checks of built-in scene `name` on its DDM run `ddm` (empty for a scene
/// without closed forms, or when the run lacks the responses or parameters they need).
pub fn oracles(name: &str, ddm: &SensitivityResults) -> Vec<OracleCheck> {
    let mut out = Vec::new();
    if let Some(f) = BUILTIN
        .iter()
        .find(|b| b.name == name)
        .and_then(|b| b.oracles)
    {
        f(ddm, &mut out);
    }
    out
}

fn row(quantity: &str, expected: f64, got: f64, tolerance: f64) -> OracleCheck {
    OracleCheck {
        quantity: quantity.to_string(),
        expected,
        got,
        tolerance,
    }
}

/// Where the oracles look in a run: a response's row, a parameter's column, the increment at a
/// pseudo-time.
#[allow(clippy::type_complexity)]
fn lookups(
    res: &SensitivityResults,
) -> (
    impl Fn(&str) -> Option<usize> + '_,
    impl Fn(&str) -> Option<usize> + '_,
    impl Fn(f64) -> Option<IncrementSensitivity> + '_,
) {
    (
        |name: &str| res.response_index(name),
        |name: &str| res.parameter_index(name),
        |t: f64| res.increment_at(t).cloned(),
    )
}

pub(crate) fn fixed_set(name: &str, set: &str, components: &[Component]) -> PrescribedSpec {
    PrescribedSpec {
        name: name.into(),
        set: set.into(),
        components: components.to_vec(),
        value: 0.0,
        amplitude: ramp(),
    }
}

pub(crate) fn block_body(
    name: &str,
    origin: [f64; 3],
    axes: [Axis; 3],
    material: Material,
    kinematics: Kinematics,
) -> BodySpec {
    let [x, y, z] = axes;
    BodySpec {
        geometry: BodyGeometry::Block(BlockSpec {
            element: crate::element::Shape::Hex8,
            name: name.into(),
            origin,
            x,
            y,
            z,
        }),
        material,
        kinematics,
        formulation: Some(Formulation::IncompatibleModes),
    }
}

pub(crate) fn graded(
    length: f64,
    fine_fraction: f64,
    fine: usize,
    coarse: usize,
    ratio: f64,
) -> Axis {
    Axis {
        length,
        zones: vec![
            Zone {
                fraction: fine_fraction,
                elements: fine,
                ratio: 1.0,
            },
            Zone {
                fraction: 1.0 - fine_fraction,
                elements: coarse,
                ratio,
            },
        ],
    }
}

mod blocks;
mod cantilever;
mod discrete;
mod hertz;
mod indentation;
mod leaf;
mod strip;
mod uniaxial;

pub use blocks::*;
pub use cantilever::*;
pub use discrete::*;
pub use hertz::*;
pub use indentation::*;
use leaf::stacked_leaves_oracles;
pub use leaf::{leaf_spring, stacked_leaves, LeafSpringSpec, StackedLeavesSpec};
pub use strip::*;
pub use uniaxial::*;
