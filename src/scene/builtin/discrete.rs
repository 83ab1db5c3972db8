//! Discrete oracles: a node on a rigid plane with coupled stiffness, and the Jenkins element
//! (oracles.md sections 5, 6).

use super::*;

/// shared/oracles.md section 6: a node at the origin with stiffness
/// `K = [[k11, k12], [k12, k22]]` against the rigid plane y = 0, normal load `F_n = -1`, tangential
/// load `F_t` 0 -> 0.6 (t = 1) -> -0.6 (t = 3) -> 0.6 (t = 5), Coulomb `mu = 0.3`.
pub fn klarbring_2dof(increments_per_unit: usize) -> Scene {
    Scene {
        name: "klarbring-2dof".into(),
        description: "Two-degree-of-freedom frictional system (shared/oracles.md section 6)."
            .into(),
        bodies: vec![],
        free_nodes: vec![FreeNodeSpec {
            name: "node".into(),
            x: [0.0; 3],
        }],
        springs: vec![SpringSpec {
            a: "node".into(),
            b: None,
            stiffness: [[1.0, 0.5, 0.0], [0.5, 1.0, 0.0], [0.0, 0.0, 1.0]],
        }],
        prescribed: vec![],
        loads: vec![
            LoadSpec {
                name: "Fn".into(),
                set: "node".into(),
                component: Component::Y,
                value: -1.0,
                amplitude: vec![(0.0, 1.0), (5.0, 1.0)],
            },
            LoadSpec {
                name: "Ft".into(),
                set: "node".into(),
                component: Component::X,
                value: 0.6,
                amplitude: vec![(0.0, 0.0), (1.0, 1.0), (3.0, -1.0), (5.0, 1.0)],
            },
        ],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![ContactSpec {
            name: "plane".into(),
            hitting: "node".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::Plane {
                    point: [0.0; 3],
                    normal: [0.0, 1.0, 0.0],
                },
                motion: vec![],
            },
            normal: NormalLaw::Lagrange,
            friction: Some(Friction::Coulomb(Coulomb::new(0.3))),
            // The oracle's stick is rigid; the penalty leaves an elastic slip |t| / eps_T in
            // stick phases (1e-7 here). Slipping states, where the worked values are, do not
            // depend on it. A stiffer penalty buys little: the stick force's round-off grows
            // as eps_T |u| 1e-16.
            tangential_stiffness: Some(1e6),
            constraint_scale: Some(1.0),
            activation: None,
            search_radius: None,
            smoothing: None,
        }],
        steps: vec![StepSpec {
            end: 5.0,
            increments: 5 * increments_per_unit,
        }],
        responses: vec![
            ResponseSpec::Displacement {
                name: "u".into(),
                set: "node".into(),
                component: Component::X,
            },
            ResponseSpec::TargetForce {
                name: "plane-force-x".into(),
                pair: "plane".into(),
                component: Component::X,
            },
            ResponseSpec::TargetForce {
                name: "plane-force-y".into(),
                pair: "plane".into(),
                component: Component::Y,
            },
        ],
        // the oracle is exact: converge close to round-off (the stick force carries
        // eps_T |u| 1e-16 ~ 1e-11 of noise), not to the default 1e-9
        solver: SolverSettings {
            force_tol: 1e-11,
            ..SolverSettings::default()
        },
        study: StudySpec::default(),
    }
}

/// shared/oracles.md section 5: a slider (node on the rigid plane y = 0 under the normal force
/// `N = 1`) tied by a spring `k = 1` to a base whose displacement `U(t)` cycles 0 -> U_a (t = 1)
/// -> -U_a (t = 3) -> U_a (t = 5), `U_a = 1`, Coulomb `mu = 0.3`.
pub fn jenkins(increments_per_unit: usize) -> Scene {
    Scene {
        name: "jenkins".into(),
        description: "Jenkins element: spring and Coulomb slider (shared/oracles.md section 5)."
            .into(),
        bodies: vec![],
        free_nodes: vec![
            FreeNodeSpec {
                name: "slider".into(),
                x: [0.0; 3],
            },
            FreeNodeSpec {
                name: "base".into(),
                x: [-1.0, 0.0, 0.0],
            },
        ],
        springs: vec![
            SpringSpec {
                a: "slider".into(),
                b: Some("base".into()),
                stiffness: [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
            },
            // holds the slider in y before contact closes and in z (no effect in contact)
            SpringSpec {
                a: "slider".into(),
                b: None,
                stiffness: [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            },
        ],
        prescribed: vec![
            PrescribedSpec {
                name: "U".into(),
                set: "base".into(),
                components: vec![Component::X],
                value: 1.0,
                amplitude: vec![(0.0, 0.0), (1.0, 1.0), (3.0, -1.0), (5.0, 1.0)],
            },
            fixed_set("base-yz", "base", &[Component::Y, Component::Z]),
        ],
        loads: vec![LoadSpec {
            name: "N".into(),
            set: "slider".into(),
            component: Component::Y,
            value: -1.0,
            amplitude: vec![(0.0, 1.0), (5.0, 1.0)],
        }],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![ContactSpec {
            name: "plane".into(),
            hitting: "slider".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::Plane {
                    point: [0.0; 3],
                    normal: [0.0, 1.0, 0.0],
                },
                motion: vec![],
            },
            normal: NormalLaw::Lagrange,
            friction: Some(Friction::Coulomb(Coulomb::new(0.3))),
            tangential_stiffness: Some(1e6),
            constraint_scale: Some(1.0),
            activation: None,
            search_radius: None,
            smoothing: None,
        }],
        steps: vec![StepSpec {
            end: 5.0,
            increments: 5 * increments_per_unit,
        }],
        responses: vec![
            ResponseSpec::Reaction {
                name: "T".into(),
                set: "base".into(),
                component: Component::X,
            },
            ResponseSpec::Displacement {
                name: "slider-u".into(),
                set: "slider".into(),
                component: Component::X,
            },
        ],
        // the oracle is exact: converge close to round-off (the stick force carries
        // eps_T |u| 1e-16 ~ 1e-11 of noise), not to the default 1e-9
        solver: SolverSettings {
            force_tol: 1e-11,
            ..SolverSettings::default()
        },
        study: StudySpec::default(),
    }
}

/// The closed-form checks of the `klarbring-2dof` scene on its DDM run.
pub(crate) fn klarbring_2dof_oracles(ddm: &SensitivityResults, out: &mut Vec<OracleCheck>) {
    let (r_of, p_of, at) = lookups(ddm);
    // oracles.md section 6, slip in direction s; exact for the discrete system
    let slip = |ft: f64, s: f64| {
        let (k11, k12, fn_, mu) = (1.0, 0.5, -1.0, 0.3);
        let den = k11 + s * mu * k12;
        (
            (ft + s * mu * fn_) / den,
            s * (k11 * fn_ - k12 * ft) / (den * den),
        )
    };
    if let (Some(r), Some(p)) = (r_of("u"), p_of("mu")) {
        for (t, ft, s, what) in [
            (1.0, 0.6, 1.0, "first loading"),
            (3.0, -0.6, -1.0, "slipping back"),
            (4.0, 0.0, 1.0, "reloading"),
        ] {
            if let Some(inc) = at(t) {
                let (u, du) = slip(ft, s);
                out.push(row(
                    &format!("u at F_t = {ft} ({what})"),
                    u,
                    inc.values[r],
                    1e-9,
                ));
                out.push(row(
                    &format!("du/dmu at F_t = {ft} ({what})"),
                    du,
                    inc.derivatives[r][p],
                    1e-8,
                ));
            }
        }
    }
}

/// The closed-form checks of the `jenkins` scene on its DDM run.
pub(crate) fn jenkins_oracles(ddm: &SensitivityResults, out: &mut Vec<OracleCheck>) {
    let (r_of, p_of, at) = lookups(ddm);
    // oracles.md section 5 (k = 1, N = 1, mu = 0.3): slipping at the turning points,
    // T = s mu N and dT/dmu = s N, exact to round-off
    if let (Some(r), Some(p)) = (r_of("T"), p_of("mu")) {
        for (t, s) in [(1.0, 1.0), (3.0, -1.0)] {
            if let Some(inc) = at(t) {
                out.push(row(
                    &format!("T = s mu N at t = {t} (slipping)"),
                    s * 0.3,
                    inc.values[r],
                    1e-10,
                ));
                out.push(row(
                    &format!("dT/dmu = s N at t = {t}"),
                    s,
                    inc.derivatives[r][p],
                    1e-10,
                ));
            }
        }
    }
}
