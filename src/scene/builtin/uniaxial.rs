//! One hex8 in uniaxial stress: J2 plasticity and St Venant-Kirchhoff (oracles.md sections 1, 2).

use super::*;

/// One unit hex8 of J2 material (E = 200 GPa, nu = 0.3, sigma_y = 250 MPa, H = 10 GPa; units
/// MPa and mm) in uniaxial stress: symmetry planes x = 0, y = 0, z = 0, the face x = 1 driven
/// through the axial strain cycle 0 -> +0.01 (t = 1) -> -0.01 (t = 3), `increments_per_unit`
/// increments per unit of pseudo-time. Responses: the axial stress (the reaction on the unit
/// face), the strain, and the equivalent plastic strain of Gauss point 0.
pub fn uniaxial_j2(kinematics: Kinematics, increments_per_unit: usize) -> Scene {
    let mut scene = uniaxial_cube(
        Material::J2(J2Plasticity::linear(200e3, 0.3, 250.0, 10e3)),
        kinematics,
        0.01,
        vec![(0.0, 0.0), (1.0, 1.0), (3.0, -1.0)],
        vec![
            StepSpec {
                end: 1.0,
                increments: increments_per_unit,
            },
            StepSpec {
                end: 3.0,
                increments: 2 * increments_per_unit,
            },
        ],
    );
    scene.name = "uniaxial-j2".into();
    scene.description =
        "Uniaxial stress cycle of one J2 hex8 (shared/oracles.md section 1).".into();
    scene.responses.push(ResponseSpec::History {
        name: "alpha".into(),
        body: "cube".into(),
        element: 0,
        point: 0,
        variable: "alpha".into(),
    });
    scene
}

/// shared/oracles.md section 2: one St Venant-Kirchhoff hex8 (unit cube, E = 1000, nu = 0.3,
/// large deformation) stretched to `lambda_max` in x with its lateral faces free; `stress` is
/// the nominal stress P11 (the reaction on the unit face).
pub fn uniaxial_svk(lambda_max: f64, increments: usize) -> Scene {
    let mut scene = uniaxial_cube(
        Material::Svk(StVenantKirchhoff::new(1000.0, 0.3)),
        Kinematics::Large,
        lambda_max - 1.0,
        ramp(),
        vec![StepSpec {
            end: 1.0,
            increments,
        }],
    );
    scene.name = "uniaxial-svk".into();
    scene.description = format!(
        "One St Venant-Kirchhoff hex8 stretched to lambda = {lambda_max} in uniaxial stress (shared/oracles.md section 2)."
    );
    scene
}

/// A unit cube with symmetry conditions on its three minimum faces and the x-displacement of
/// its `xmax` face prescribed (`value * amplitude(t)`); responses `stress` (reaction on
/// `xmax`, x) and `strain` (its displacement).
pub(crate) fn uniaxial_cube(
    material: Material,
    kinematics: Kinematics,
    value: f64,
    amplitude: Vec<(f64, f64)>,
    steps: Vec<StepSpec>,
) -> Scene {
    let fixed = |name: &str, set: &str, c: Component| PrescribedSpec {
        name: name.into(),
        set: set.into(),
        components: vec![c],
        value: 0.0,
        amplitude: ramp(),
    };
    Scene {
        name: "uniaxial".into(),
        description: String::new(),
        bodies: vec![BodySpec {
            geometry: BodyGeometry::Block(BlockSpec {
                element: crate::element::Shape::Hex8,
                name: "cube".into(),
                origin: [0.0; 3],
                x: Axis::uniform(1.0, 1),
                y: Axis::uniform(1.0, 1),
                z: Axis::uniform(1.0, 1),
            }),
            material,
            kinematics,
            formulation: Some(Formulation::Full),
        }],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed("sym-x", "cube.xmin", Component::X),
            fixed("sym-y", "cube.ymin", Component::Y),
            fixed("sym-z", "cube.zmin", Component::Z),
            PrescribedSpec {
                name: "strain".into(),
                set: "cube.xmax".into(),
                components: vec![Component::X],
                value,
                amplitude,
            },
        ],
        loads: vec![],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![],
        steps,
        responses: vec![
            ResponseSpec::Reaction {
                name: "stress".into(),
                set: "cube.xmax".into(),
                component: Component::X,
            },
            ResponseSpec::Displacement {
                name: "strain".into(),
                set: "cube.xmax".into(),
                component: Component::X,
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}

/// The closed-form checks of the `uniaxial-j2` scene on its DDM run.
pub(crate) fn uniaxial_j2_oracles(ddm: &SensitivityResults, out: &mut Vec<OracleCheck>) {
    let (r_of, p_of, at) = lookups(ddm);
    // oracles.md section 1 at the end of the cycle (eps = -eps_a, reversed and
    // yielding again), derivatives by dual numbers of the closed form
    use num_dual::Dual64;
    fn reversed(e: Dual64, sy: Dual64, h: Dual64, eps: f64, eps_a: f64) -> Dual64 {
        let ep1 = (e * eps_a - sy) / (e + h);
        e * (h * eps - sy - h * ep1 * 2.0) / (e + h)
    }
    let (e, sy, h) = (200e3, 250.0, 10e3);
    let c = Dual64::from;
    if let (Some(r), Some(end)) = (r_of("stress"), at(3.0)) {
        let sigma = reversed(c(e), c(sy), c(h), -0.01, 0.01).re;
        // radial return is exact on this path: solver tolerance
        out.push(row("sigma at eps = -eps_a", sigma, end.values[r], 1e-8));
        for (name, d) in [
            (
                "sigma_y",
                reversed(c(e), Dual64::new(sy, 1.0), c(h), -0.01, 0.01),
            ),
            ("H", reversed(c(e), c(sy), Dual64::new(h, 1.0), -0.01, 0.01)),
            ("E", reversed(Dual64::new(e, 1.0), c(sy), c(h), -0.01, 0.01)),
        ] {
            if let Some(p) = p_of(name) {
                out.push(row(
                    &format!("d sigma / d {name} at eps = -eps_a"),
                    d.eps,
                    end.derivatives[r][p],
                    1e-8,
                ));
            }
        }
    }
}

/// The closed-form checks of the `uniaxial-svk` scene on its DDM run.
pub(crate) fn uniaxial_svk_oracles(ddm: &SensitivityResults, out: &mut Vec<OracleCheck>) {
    let res = ddm;
    let (r_of, p_of, _) = lookups(ddm);
    // oracles.md section 2: P11 = (E/2) lambda (lambda^2 - 1), exact for one hex8
    if let (Some(r), Some(end)) = (r_of("stress"), res.increments.last()) {
        let (e, lambda) = (1000.0, 1.5);
        let p11 = 0.5 * e * lambda * (lambda * lambda - 1.0);
        out.push(row("P11 at lambda = 1.5", p11, end.values[r], 1e-10));
        if let Some(p) = p_of("E") {
            out.push(row(
                "d P11 / d E = lambda (lambda^2 - 1) / 2",
                p11 / e,
                end.derivatives[r][p],
                1e-10,
            ));
        }
    }
}
