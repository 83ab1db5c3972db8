//! Issue 8: extremes, hard increments and non-smooth points. Every check is against a closed
//! form (shared/oracles.md), an invariant, or an independent method (finite differences of
//! complete reruns); the tolerances say where they come from.

// Index loops over responses, parameters and increments read like the formulas they check.
#![allow(clippy::needless_range_loop)]

use crate::common::{fricsens, scratch_path, sens, try_solve};

use fricsens::contact::friction::Coulomb;
use fricsens::contact::ContactState;
use fricsens::contact::Friction;
use fricsens::element::{Formulation, Kinematics};
use fricsens::material::{Material, StVenantKirchhoff};
use fricsens::mesh::{Axis, BlockSpec, NodePlace};
use fricsens::model::{Amplitude, DesignParam, Model, NodalLoad, SolverSettings};
use fricsens::response::{Response, ResponseKind};
use fricsens::scene::{
    cantilever, jenkins, klarbring_2dof, sliding_block, uniaxial_j2, uniaxial_svk, BodyGeometry,
    BodySpec, CantileverSpec, Component, ContactSpec, FreeNodeSpec, LoadSpec, PrescribedSpec,
    ResponseSpec, RigidSpec, Scene, SpringSpec, StepSpec, StudySpec, TargetSpec,
};
use fricsens::sensitivity::{
    run_sensitivity, IncrementSensitivity, Method, Parameter, SensitivityResults, Settings,
    TangentChoice,
};
use fricsens::solver::{AnalysisError, Results};
use num_dual::Dual64;

fn at(s: &SensitivityResults, t: f64) -> &IncrementSensitivity {
    s.increments
        .iter()
        .find(|i| (i.time - t).abs() < 1e-9)
        .unwrap_or_else(|| panic!("no increment at t = {t}"))
}

/// Piecewise-linear amplitude of the Jenkins and Klarbring cycles: 0 -> 1 (t = 1) -> -1
/// (t = 3) -> 1 (t = 5).
fn cycle(t: f64) -> f64 {
    Amplitude {
        points: vec![(0.0, 0.0), (1.0, 1.0), (3.0, -1.0), (5.0, 1.0)],
    }
    .at(t)
}

// ---------------------------------------------------------------------------------------------
// 1. mu = 0

/// At mu = 0 the derivative with respect to mu is the right derivative (mu >= 0): the slider
/// (Jenkins, oracles.md 5) slips from the first increment on, T = 0 and dT/dmu = s N with s
/// the direction of the base's motion over the increment; the 2-dof node (oracles.md 6) follows
/// u = F_t / k11 with du/dmu = s (k11 F_n - k12 F_t) / k11^2. DDM against the formulas, forward
/// FDM of reruns (mu = +db) against DDM. A central difference evaluates mu = -db: see below.
#[test]
fn mu_zero_derivatives_are_the_right_derivatives_of_the_closed_forms() {
    // Jenkins: k = 1, N = 1, U_a = 1
    let mut scene = jenkins(10);
    scene.contacts[0].friction = Some(Friction::Coulomb(Coulomb::new(0.0)));
    let model = scene.build().unwrap();
    let ddm = sens(&model, &["plane.mu"], Method::Ddm, 0.0);
    // in slip T is linear in mu (T = s mu N): a forward difference has no truncation error
    // while mu = db keeps every increment slipping (the stick phase after a reversal lasts
    // 2 db N / k = 2e-3 of base travel, inside one increment of 0.1)
    let fwd = sens(&model, &["plane.mu"], Method::Fdm, 1e-3);
    let mut t_prev = 0.0;
    for (d, f) in ddm.increments.iter().zip(&fwd.increments) {
        let s = (cycle(d.time) - cycle(t_prev)).signum();
        t_prev = d.time;
        let (t_val, dt, ft) = (d.values[0], d.derivatives[0][0], f.derivatives[0][0]);
        println!("jenkins mu = 0, t = {:.1}: T {t_val:.3e}, dT/dmu DDM {dt:.15} FDM {ft:.12} (s N = {s})", d.time);
        assert!(t_val.abs() < 1e-12, "t = {}: T = {t_val}", d.time);
        assert!((dt - s).abs() < 1e-12, "t = {}: dT/dmu = {dt}", d.time);
        // Newton stops at |R| <= 1e-11 F_ref (F_ref ~ 1): at most 1e-11 / db = 1e-8
        assert!((ft - s).abs() < 1e-8, "t = {}: forward FDM {ft}", d.time);
    }
    // Klarbring: k11 = 1, k12 = 0.5, F_n = -1, F_t = 0.6 cycle(t)
    let mut scene = klarbring_2dof(10);
    scene.contacts[0].friction = Some(Friction::Coulomb(Coulomb::new(0.0)));
    let model = scene.build().unwrap();
    let ddm = sens(&model, &["plane.mu"], Method::Ddm, 0.0);
    let fwd = sens(&model, &["plane.mu"], Method::Fdm, 1e-3);
    let (k11, k12, f_n) = (1.0, 0.5, -1.0);
    let mut t_prev = 0.0;
    for (d, f) in ddm.increments.iter().zip(&fwd.increments) {
        let f_t = 0.6 * cycle(d.time);
        let s = (cycle(d.time) - cycle(t_prev)).signum();
        t_prev = d.time;
        let du = s * (k11 * f_n - k12 * f_t) / (k11 * k11);
        let (u, dd, fd) = (d.values[0], d.derivatives[0][0], f.derivatives[0][0]);
        println!(
            "klarbring mu = 0, t = {:.1}: u {u:.12} ({:.12}), du/dmu DDM {dd:.12} FDM {fd:.9} oracle {du:.12}",
            d.time,
            f_t / k11
        );
        assert!((u - f_t / k11).abs() < 1e-12, "t = {}: u = {u}", d.time);
        assert!(
            (dd - du).abs() < 1e-10 * du.abs(),
            "t = {}: {dd} vs {du}",
            d.time
        );
        // the forward difference at db = 1e-3 is the secant of the slip formula
        // u(mu) = (F_t + s mu F_n) / (k11 + s mu k12), s (k11 F_n - k12 F_t) / (k11 (k11 +
        // s db k12)): off the derivative by k12 db = 5e-4 relative (the curvature), exact up
        // to the Newton tolerance 1e-11 / db = 1e-8
        let secant = s * (k11 * f_n - k12 * f_t) / (k11 * (k11 + s * 1e-3 * k12));
        assert!(
            (fd - secant).abs() < 1e-8,
            "t = {}: forward FDM {fd} vs the secant {secant}",
            d.time
        );
    }
    // A central difference at mu = 0 reruns the model at mu = -db. No check stops it (a scene
    // with mu < 0 is rejected, `Model::set_param` in a rerun is not checked): the return map's
    // limit mu p_n goes negative, every closed node slips, and its tangential force points
    // along the slip (anti-friction). That continues the slip formula to mu < 0, so the rerun
    // converges and the central difference equals the right derivative here; but it evaluates
    // a non-physical model. Forward FDM stays in mu >= 0 and is the right independent check.
    let mut negative = model.clone();
    negative.set_param(DesignParam::Friction { pair: 0, index: 0 }, -1e-3);
    let res = try_solve(&negative).unwrap();
    let k = res.increment_at(1.0).unwrap();
    let (u, u_formula) = (
        res.response_value(&negative, 0, k),
        (0.6 - 1e-3 * f_n) / (k11 - 1e-3 * k12),
    );
    println!("klarbring at mu = -1e-3, t = 1: u {u:.12} (slip formula continued: {u_formula:.12}; frictionless 0.6)");
    assert!(u > 0.6 && (u - u_formula).abs() < 1e-10, "{u}");
    let central = sens(&model, &["plane.mu"], Method::FdmCentral, 1e-6);
    let mut worst: f64 = 0.0;
    for (d, c) in ddm.increments.iter().zip(&central.increments) {
        let (dd, cd) = (d.derivatives[0][0], c.derivatives[0][0]);
        worst = worst.max((cd - dd).abs() / dd.abs());
        // the Newton tolerance 1e-11 over the step 2e-6
        assert!(
            (cd - dd).abs() < 1e-5 * dd.abs(),
            "t = {}: central {cd} vs {dd}",
            d.time
        );
    }
    println!("central FDM at mu = 0 (reruns at mu = +-1e-6): largest relative difference to DDM {worst:.1e}");
}

// ---------------------------------------------------------------------------------------------
// 2. mu = 10: sticking

/// mu N = 10 is ten times the largest spring force k U_a = 1 of the Jenkins element: the slider
/// sticks throughout. With the penalty stick the spring and the penalty act in series:
/// T = k U eps_T / (k + eps_T) (the rigid-stick oracle T = k U up to k / eps_T = 1e-6), and
/// the stick branch does not involve mu: dT/dmu = 0 exactly, by DDM and by central FDM.
#[test]
fn mu_ten_sticks_with_zero_mu_sensitivity() {
    let mut scene = jenkins(10);
    scene.contacts[0].friction = Some(Friction::Coulomb(Coulomb::new(10.0)));
    let eps_t = scene.contacts[0].tangential_stiffness.unwrap();
    let model = scene.build().unwrap();
    let ddm = sens(&model, &["plane.mu"], Method::Ddm, 0.0);
    let fdm = sens(&model, &["plane.mu"], Method::FdmCentral, 1e-6);
    let k = 1.0;
    let mut worst: f64 = 0.0;
    for (d, f) in ddm.increments.iter().zip(&fdm.increments) {
        let u = cycle(d.time);
        let series = k * u * eps_t / (k + eps_t);
        let t_val = d.values[0];
        worst = worst.max((t_val - series).abs());
        // the Newton tolerance (1e-11 of F_ref ~ 1) bounds the error
        assert!(
            (t_val - series).abs() < 1e-10,
            "t = {}: T {t_val} vs {series}",
            d.time
        );
        // the rigid-stick oracle, up to the penalty's compliance k / (k + eps_T)
        assert!(
            (t_val - k * u).abs() <= 1.01 * k / eps_t * (k * u).abs() + 1e-10,
            "t = {}: T {t_val} vs rigid stick {}",
            d.time,
            k * u
        );
        assert_eq!(d.derivatives[0][0], 0.0, "t = {}: DDM dT/dmu", d.time);
        assert!(
            f.derivatives[0][0].abs() < 1e-12,
            "t = {}: FDM dT/dmu {}",
            d.time,
            f.derivatives[0][0]
        );
    }
    println!("jenkins mu = 10: largest |T - k U eps/(k + eps)| {worst:.2e}");

    // a deformable contact scene at mu = 10: the block (normal load N = 1) on the base, pulled
    // 3 units: it sticks while the bodies shear (pull < mu N), then slides at pull ~ mu N
    let model = sliding_block(Some(10.0)).build().unwrap();
    let params: Vec<Parameter> = ["mu", "E"]
        .iter()
        .map(|n| Parameter::by_name(&model, n).unwrap())
        .collect();
    let settings = |method| Settings {
        method,
        beta: 1e-6,
        tangent: TangentChoice::Exact,
        ..Settings::default()
    };
    let (res, ddm) = run_sensitivity(&model, &params, &settings(Method::Ddm)).unwrap();
    let (_, fdm) = run_sensitivity(&model, &params, &settings(Method::FdmCentral)).unwrap();
    let young = params[1].value;
    let pull_max = ddm
        .increments
        .iter()
        .fold(0.0f64, |m, i| m.max(i.values[0].abs()));
    let (mut stuck, mut worst) = (0, [0.0f64; 2]);
    for (k, (d, f)) in ddm.increments.iter().zip(&fdm.increments).enumerate() {
        let all_stick = res.contact[k + 1]
            .choice
            .iter()
            .all(|c| matches!(c.state, ContactState::Stick | ContactState::Open));
        if all_stick {
            stuck += 1;
            assert_eq!(d.derivatives[0][0], 0.0, "t = {}: stuck, d/dmu", d.time);
        }
        // scales: d pull/d mu ~ N = 1 in slip, d pull/dE ~ pull/E. Newton stops at 1e-9 of the
        // load; its last, quadratic step leaves far less, which a central difference over
        // 2 db = 2e-6 b turns into at most ~1e-6 of these scales.
        for (p, scale) in [(0, 1.0), (1, pull_max / young)] {
            let diff = (d.derivatives[0][p] - f.derivatives[0][p]).abs() / scale;
            worst[p] = worst[p].max(diff);
            assert!(
                diff < 1e-6,
                "t = {}: d/d{} DDM {} FDM {}",
                d.time,
                ddm.parameters[p],
                d.derivatives[0][p],
                f.derivatives[0][p]
            );
        }
    }
    let last = ddm.increments.last().unwrap();
    println!(
        "sliding block mu = 10: {stuck} increments all stuck (d pull/d mu = 0), pull at the end {:.4} (mu N = 10), d pull/d mu {:.4}; DDM vs central FDM, largest difference over the scale: mu {:.1e}, E {:.1e}",
        last.values[0], last.derivatives[0][0], worst[0], worst[1]
    );
    assert!(stuck >= 2, "the block never stuck");
    // it slides at the end: the pull is near mu N and depends on mu
    assert!((last.values[0].abs() - 10.0).abs() < 0.5 && last.derivatives[0][0].abs() > 0.5);
}

// ---------------------------------------------------------------------------------------------
// 3. nu = 0.499 with F-bar

/// Thick-walled cylinder (Lame), plane strain: inner radius a, outer b, internal pressure p,
/// small strains. `u(r) = A r + B / r` with `A = p a^2 / (2 (lambda + mu) (b^2 - a^2))`,
/// `B = p a^2 b^2 / (2 mu (b^2 - a^2))`; returns (u(a), u(b)). Dual numbers give its
/// derivatives.
fn lame(e: Dual64, nu: Dual64, p: f64, a: f64, b: f64) -> (Dual64, Dual64) {
    let lambda = e * nu / ((nu + 1.0) * (nu * (-2.0) + 1.0));
    let mu = e / ((nu + 1.0) * 2.0);
    let big_a = Dual64::from(p * a * a / (2.0 * (b * b - a * a))) / (lambda + mu);
    let big_b = Dual64::from(p * a * a * b * b / (2.0 * (b * b - a * a))) / mu;
    (big_a * a + big_b / a, big_a * b + big_b / b)
}

const RING: (f64, f64, f64, f64) = (1.0, 2.0, 0.1, 1.0); // a, b, thickness, pressure

/// A quarter of the thick cylinder: a block `[a, b] x [0, 1] x [0, t]` mapped onto
/// `(r cos(pi/2 y), r sin(pi/2 y), z)`, symmetry on both cut planes, z fixed (plane strain),
/// the pressure as consistent nodal forces on the inner polygon. Responses: the radial
/// displacement at the inner and outer radius on the x axis.
fn ring_model(formulation: Formulation, young: f64, nu: f64, nr: usize, nt: usize) -> Model {
    let (a, b, th, p) = RING;
    let fixed = |name: &str, set: &str, c: Component| PrescribedSpec {
        name: name.into(),
        set: set.into(),
        components: vec![c],
        value: 0.0,
        amplitude: vec![(0.0, 0.0), (1.0, 1.0)],
    };
    let scene = Scene {
        name: "lame".into(),
        description: String::new(),
        bodies: vec![BodySpec {
            geometry: BodyGeometry::Block(BlockSpec {
                element: fricsens::element::Shape::Hex8,
                name: "ring".into(),
                origin: [a, 0.0, 0.0],
                x: Axis::uniform(b - a, nr),
                y: Axis::uniform(1.0, nt),
                z: Axis::uniform(th, 1),
            }),
            material: Material::Svk(StVenantKirchhoff::new(young, nu)),
            kinematics: Kinematics::Small,
            formulation: Some(formulation),
        }],
        free_nodes: vec![],
        springs: vec![],
        prescribed: vec![
            fixed("sym-y", "ring.ymin", Component::Y),
            fixed("sym-x", "ring.ymax", Component::X),
            fixed("plane", "ring.all", Component::Z),
        ],
        loads: vec![],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![],
        steps: vec![StepSpec {
            end: 1.0,
            increments: 1,
        }],
        responses: vec![],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    };
    let mut model = scene.build().unwrap();
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let polar = |c: &nalgebra::Vector3<f64>| {
        let th = std::f64::consts::FRAC_PI_2 * c[1];
        [c[0] * th.cos(), c[0] * th.sin(), c[2]]
    };
    for (n, place) in model.mesh.places.iter_mut().enumerate() {
        *place = NodePlace::Free(polar(&x[n]));
    }
    // consistent nodal forces of a uniform pressure on the inner polygon: each chord of
    // length c and outward normal n carries p c t n, a quarter to each of its four nodes
    let inner: Vec<usize> = model.mesh.node_sets["ring.xmin"].clone();
    let mut wx = vec![0.0; inner.len()];
    let mut wy = vec![0.0; inner.len()];
    let y = |n: usize| polar(&x[n]);
    // the inner nodes come in pairs (z = 0, z = t) at the arc positions k / nt, k = 0..nt
    let node = |k: usize, zi: usize| {
        let mut v: Vec<usize> = inner
            .iter()
            .copied()
            .filter(|n| (x[*n][1] * nt as f64 - k as f64).abs() < 1e-9)
            .collect();
        v.sort_by(|i, j| x[*i][2].total_cmp(&x[*j][2]));
        assert_eq!(v.len(), 2);
        v[zi]
    };
    let index = |n: usize| inner.iter().position(|m| *m == n).unwrap();
    for k in 0..nt {
        let (p0, p1) = (y(node(k, 0)), y(node(k + 1, 0)));
        let (dx, dy) = (p1[0] - p0[0], p1[1] - p0[1]);
        let c = (dx * dx + dy * dy).sqrt();
        // outward from the fluid into the solid: away from the axis
        let nrm = [dy / c, -dx / c];
        for kk in [k, k + 1] {
            for zi in 0..2 {
                let i = index(node(kk, zi));
                wx[i] += 0.25 * c * th * nrm[0];
                wy[i] += 0.25 * c * th * nrm[1];
            }
        }
    }
    for (name, component, weights) in [("px", 0, wx), ("py", 1, wy)] {
        model.loads.push(NodalLoad {
            name: name.into(),
            nodes: inner.clone(),
            weights,
            component,
            value: p,
            amplitude: Amplitude::ramp(),
        });
    }
    let on_x_axis = |set: &str| -> Vec<usize> {
        model.mesh.node_sets[set]
            .iter()
            .copied()
            .filter(|n| x[*n][1] == 0.0)
            .collect()
    };
    model.responses = vec![
        Response {
            name: "u_a".into(),
            kind: ResponseKind::Displacement {
                nodes: on_x_axis("ring.xmin"),
                component: 0,
            },
        },
        Response {
            name: "u_b".into(),
            kind: ResponseKind::Displacement {
                nodes: on_x_axis("ring.xmax"),
                component: 0,
            },
        },
    ];
    model
}

/// tests/oracles/locking.rs checks F-bar on plastic incompressibility (Prandtl's punch) and in
/// bending, but has no nearly incompressible elastic problem with a closed form. Here: Lame's
/// thick cylinder (a = 1, b = 2, plane strain, load control) at nu = 0.499 with F-bar, and its
/// sensitivities to E and nu: DDM against central FDM, against the invariant du/dE = -u/E
/// (linear elasticity under load control at fixed nu) and against the derivative of the closed
/// form in nu, which converges at O(h^2).
///
/// Measured (8 x 16 elements): F-bar u(a), u(b) 0.19 % below Lame; full integration 28.8 %
/// below (volumetric locking); du/dnu 0.75 % and 0.09 % off Lame, 0.19 % and 0.02 % on
/// 16 x 32.
#[test]
fn nearly_incompressible_thick_cylinder_with_f_bar_and_its_sensitivities() {
    let (a, b, _, p) = RING;
    let (young, nu) = (1000.0, 0.499);
    let (ua, ub) = lame(Dual64::from(young), Dual64::new(nu, 1.0), p, a, b);
    let lame_u = [ua.re, ub.re];
    let lame_du = [ua.eps, ub.eps];
    let error = |f, nr, nt| {
        let model = ring_model(f, young, nu, nr, nt);
        let res = try_solve(&model).unwrap();
        let e = [0, 1].map(|r| res.response_value(&model, r, 1) / lame_u[r] - 1.0);
        println!(
            "{f:?} {nr} x {nt}: u(a), u(b) {:+.3} %, {:+.3} % off Lame",
            100.0 * e[0],
            100.0 * e[1]
        );
        e
    };
    // F-bar: O(h^2) discretisation error, here also the polygonal inner and outer boundary
    // (chord sag (pi/32)^2 / 8 = 1.2e-3 of the radius)
    for e in error(Formulation::FBar, 8, 16) {
        assert!(e.abs() < 0.005, "F-bar: {e}");
    }
    // full integration locks: far too stiff
    for e in error(Formulation::Full, 8, 16) {
        assert!(e < -0.2, "full integration: {e}");
    }
    let mut du_error = Vec::new();
    for (nr, nt) in [(8, 16), (16, 32)] {
        let model = ring_model(Formulation::FBar, young, nu, nr, nt);
        let ddm = sens(&model, &["E", "nu"], Method::Ddm, 0.0);
        let d = &ddm.increments[0];
        let e = [0, 1].map(|r| d.derivatives[r][1] / lame_du[r] - 1.0);
        println!(
            "{nr} x {nt}: du/dnu at a, b: {:.6e}, {:.6e} (Lame {:.6e}, {:.6e}; {:+.3} %, {:+.3} %)",
            d.derivatives[0][1],
            d.derivatives[1][1],
            lame_du[0],
            lame_du[1],
            100.0 * e[0],
            100.0 * e[1]
        );
        du_error.push(e);
        for r in 0..2 {
            // u is proportional to 1/E: DDM solves K du/dE = -K u / E, exact up to the
            // round-off of the solve, cond(K) eps ~ (lambda/mu = 500) x (mesh ~ 1e3) x 1e-16
            let (du_de, u) = (d.derivatives[r][0], d.values[r]);
            assert!(
                (du_de + u / young).abs() < 1e-9 * u / young,
                "{du_de} vs {}",
                -u / young
            );
        }
        if nr == 8 {
            // central FDM of reruns. beta = 1e-4: truncation ~ beta^2 u'''/u' ~ 1e-8; the
            // reruns' round-off cond(K) eps u / (beta nu u') ~ 1e-12 x 6 / 5e-5 ~ 1e-7 (at
            // beta = 1e-6 it reaches 1e-5)
            let fdm = sens(&model, &["E", "nu"], Method::FdmCentral, 1e-4);
            let f = &fdm.increments[0];
            for r in 0..2 {
                for q in 0..2 {
                    let (dd, ff) = (d.derivatives[r][q], f.derivatives[r][q]);
                    println!(
                        "    {} d/d{}: DDM {dd:.9e} FDM {ff:.9e}",
                        model.responses[r].name, ddm.parameters[q]
                    );
                    assert!((dd - ff).abs() < 1e-6 * dd.abs(), "{dd} vs {ff}");
                }
            }
        }
    }
    for r in 0..2 {
        // the coarse mesh within 1 %, and the error falls at O(h^2) (by 4, asserted > 3)
        assert!(du_error[0][r].abs() < 0.01, "du/dnu: {:?}", du_error[0]);
        assert!(
            du_error[1][r].abs() < du_error[0][r].abs() / 3.0,
            "du/dnu does not converge: {du_error:?}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// 4. a slender leaf

/// A leaf with L/h = 100 (L = 10, h = b = 0.1, 100 elements along), small tip load and small
/// kinematics: tip deflection P L^3 / (3 E I) within 2 % with incompatible modes and one or two
/// elements through the thickness (oracles.md 3), and d delta / dE = -delta / E (linear
/// elasticity under load control, fixed nu) to solver precision.
#[test]
fn slender_leaf_matches_beam_theory_and_the_e_scaling() {
    for ny in [1, 2] {
        let spec = CantileverSpec {
            length: 10.0,
            height: 0.1,
            width: 0.1,
            nx: 100,
            ny,
            ..CantileverSpec::small_deflection()
        };
        let model = cantilever(&spec).build().unwrap();
        let s = sens(&model, &["E"], Method::Ddm, 0.0);
        let inc = &s.increments[0];
        let delta = -inc.values[0];
        let d_delta = -inc.derivatives[0][0];
        let exact = spec.load() * spec.length.powi(3) / (3.0 * spec.young * spec.inertia());
        let err = delta / exact - 1.0;
        println!(
            "L/h = 100, {ny} element(s) through the thickness: delta {delta:.6e}, P L^3/(3 E I) {exact:.6e} ({:+.3} %); d delta/dE {d_delta:.6e}, -delta/E {:.6e}",
            100.0 * err,
            -delta / spec.young
        );
        assert!(err.abs() < 0.02, "ny = {ny}: error {err}");
        // DDM solves K du/dE = -K u / E: exact but for the round-off of the solves, bounded
        // by cond(K) eps. cond(K) ~ (stiffest element mode, E b l_e / h_e = 2e4) / (softest
        // beam mode, ~ E I (1.875 / L)^4 l_e ~ 1e-4) ~ 2e8: 4e-8 (measured 2.5e-8 with two
        // elements through the thickness, below 1e-8 with one)
        assert!(
            (d_delta + delta / spec.young).abs() < 1e-7 * delta / spec.young,
            "ny = {ny}: {d_delta} vs {}",
            -delta / spec.young
        );
    }
}

// ---------------------------------------------------------------------------------------------
// 5. very small and very large increments

const E: f64 = 200e3;
const SY: f64 = 250.0;
const H: f64 = 10e3;

/// oracles.md 1: the uniaxial stress along 0 -> 0.01 (t = 1) -> -0.01 (t = 3), reversal at
/// eps_a = 0.01; `plastic` forces the branch of the loading path at first yield (where both
/// formulas give the same stress and different derivatives), `None` takes the elastic one.
fn j2_stress(e: Dual64, sy: Dual64, h: Dual64, t: f64, plastic: Option<bool>) -> Dual64 {
    let ea = 0.01;
    if t <= 1.0 {
        let eps = ea * t;
        if plastic.unwrap_or(e.re * eps > sy.re) {
            e * (sy + h * eps) / (e + h)
        } else {
            e * eps
        }
    } else {
        let eps = ea * (1.0 - (t - 1.0));
        let ep1 = (e * ea - sy) / (e + h);
        let elastic = e * (sy + h * ea) / (e + h) - e * (ea - eps);
        if elastic.re >= -(sy + h * ep1).re {
            elastic
        } else {
            e * (h * eps - sy - h * ep1 * 2.0) / (e + h)
        }
    }
}

/// (value, [d/dsigma_y, d/dH, d/dE]) of the oracle.
fn j2_oracle(t: f64, plastic: Option<bool>) -> (f64, [f64; 3]) {
    let c = Dual64::from;
    let v = j2_stress(c(E), c(SY), c(H), t, plastic).re;
    let d = [
        j2_stress(c(E), Dual64::new(SY, 1.0), c(H), t, plastic).eps,
        j2_stress(c(E), c(SY), Dual64::new(H, 1.0), t, plastic).eps,
        j2_stress(Dual64::new(E, 1.0), c(SY), c(H), t, plastic).eps,
    ];
    (v, d)
}

/// Radial return is exact on the proportional uniaxial path: one increment per unit of
/// pseudo-time (strain steps of 0.01, eight times the yield strain, and a reversal from
/// +0.01 to 0 in one step) and a thousand (steps of 1e-5) both give the closed form for the
/// stress and its derivatives to 1e-8 (measured: 2e-14 and 3e-13). A contact scene driven in
/// one huge increment either converges (after cutbacks) or stops with a typed error; never a
/// panic or a NaN: the sliding block pressed and slid 3 units in one increment converges after
/// 4 cutbacks to full slip (pull = mu N), the Jenkins slider taken to U = 1 in one increment
/// slips (T = mu N).
#[test]
fn tiny_and_huge_increments() {
    for per_unit in [1, 1000] {
        let model = uniaxial_j2(Kinematics::Small, per_unit).build().unwrap();
        let s = sens(&model, &["sigma_y", "H", "E"], Method::Ddm, 0.0);
        assert_eq!(s.increments.len(), 3 * per_unit);
        let mut worst: f64 = 0.0;
        let mut check = |what: &str, t: f64, got: f64, want: f64, floor: f64| {
            let err = (got - want).abs() / want.abs().max(floor);
            worst = worst.max(err);
            assert!(
                err <= 1e-8,
                "{per_unit} per unit, t = {t}, {what}: {got} vs {want}"
            );
        };
        // where a derivative vanishes (dsigma/dH at first yield), relative to a thousandth of
        // its natural scale sigma_y / p
        let floor = [1e-3, 1e-3 * SY / H, 1e-3 * SY / E];
        for inc in &s.increments {
            let (v, d) = j2_oracle(inc.time, None);
            check("sigma", inc.time, inc.values[0], v, 1.0);
            if !inc.kinks.is_empty() {
                // first yield ends increment 125 of the thousand: the state sits on the kink
                // (item 8); its one-sided derivatives are the elastic and plastic closed forms
                assert!(
                    (inc.time - 0.125).abs() < 1e-12,
                    "flagged at t = {}",
                    inc.time
                );
                let sides = inc.one_sided.as_ref().expect("one-sided derivatives");
                let (lower, upper) = sides.both().expect("both sides");
                let (_, elastic) = j2_oracle(inc.time, Some(false));
                let (_, plastic) = j2_oracle(inc.time, Some(true));
                println!(
                    "{per_unit} per unit, t = {}: flagged; derivatives {:?}, elastic side {:?}, plastic side {:?}",
                    inc.time, inc.derivatives[0], lower[0], upper[0]
                );
                for p in 0..3 {
                    check("elastic side", inc.time, lower[0][p], elastic[p], floor[p]);
                    check("plastic side", inc.time, upper[0][p], plastic[p], floor[p]);
                }
                continue;
            }
            for p in 0..3 {
                check(
                    &s.parameters[p],
                    inc.time,
                    inc.derivatives[0][p],
                    d[p],
                    floor[p],
                );
            }
        }
        println!("{per_unit} increment(s) per unit: largest relative error {worst:.2e}");
    }

    // contact scenes in one increment
    let mut block = sliding_block(Some(0.3));
    block.steps = vec![StepSpec {
        end: 2.0,
        increments: 1,
    }];
    let mut slider = jenkins(10);
    slider.steps = vec![StepSpec {
        end: 5.0,
        increments: 1,
    }];
    for (name, scene) in [("sliding block", block), ("jenkins", slider)] {
        let model = scene.build().unwrap();
        match try_solve(&model) {
            Ok(res) => {
                let cutbacks: Vec<usize> = res.records.iter().map(|r| r.cutbacks).collect();
                let last = res.times.len() - 1;
                let values: Vec<f64> = (0..model.responses.len())
                    .map(|r| res.response_value(&model, r, last))
                    .collect();
                println!(
                    "{name} in one increment: {} sub-increments (cutbacks {cutbacks:?}), final responses {values:?}",
                    res.records.len()
                );
                assert!(values.iter().all(|v| v.is_finite()), "{name}: {values:?}");
                assert!(res.states[last].iter().all(|v| v.is_finite()), "{name}");
                assert_eq!(res.times.last(), model.times.last());
                // both end sliding: the pull (block, N = 1) and the spring force (slider,
                // N = 1) equal mu N = 0.3, the block's up to the slope of the bent base
                // (~1e-3, tests/robustness/sliding.rs)
                let tol = if name == "jenkins" { 1e-9 } else { 1e-2 };
                assert!(
                    (values[0].abs() / 0.3 - 1.0).abs() < tol,
                    "{name}: {}",
                    values[0]
                );
            }
            Err(e) => {
                println!("{name} in one increment: {e}");
                assert!(matches!(e, AnalysisError::Diverged { .. }), "{name}: {e}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 6. tangential penalty from soft to stiff

/// The 2-dof system (oracles.md 6: k11 = 1, k12 = 0.5, F_n = -1, mu = 0.3, F_t = 0.6 cycle)
/// with the tangential penalty eps_T swept from 1e1 to 1e9 (k11 = 1 is the structural
/// stiffness). With the penalty, a stick phase that starts at the state u* (F_t*) of the last
/// slip (or at u* = 0, F_t* = 0) follows
///
/// ```text
/// u = u* + (F_t - F_t*) / (k11 + eps_T),   du/deps_T = -(F_t - F_t*) / (k11 + eps_T)^2
/// ```
///
/// (the anchor is u* - s mu r_n* / eps_T, and k11 u* = F_t* - s mu r_n*). So:
/// * stick-phase values converge to the rigid-stick oracle (u = u*) with the error
///   (F_t - F_t*) / (k11 + eps_T): O(k / eps_T) of the free displacement, e.g. at t = 3.4
///   (F_t - F_t* = 0.24) 2.2e-2 at eps_T = 10, 2.4e-7 at 1e6, 2.4e-10 at 1e9;
/// * their mu-sensitivities do not depend on eps_T at all: du/dmu = du*/dmu (0 before the
///   first slip, 0.968858 after the reversal at t = 3), measured equal for every eps_T to
///   1e-12 — the penalty shifts the stick state by an amount free of mu;
/// * slip-phase values and mu-sensitivities are independent of eps_T (the slip force is
///   mu r_n whatever eps_T), and du/deps_T = 0 there;
/// * what eps_T does move is the end of a stick phase: slip resumes after an extra
///   2 mu r_n / eps_T of load (10 % later at eps_T = 10), so an increment near an onset can
///   stick at one eps_T and slip at another. The points below are away from onsets.
#[test]
fn tangential_penalty_from_soft_to_stiff() {
    let (k11, k12, f_n, mu) = (1.0, 0.5, -1.0, 0.3);
    let slip = |f_t: f64, s: f64| {
        let den = k11 + s * mu * k12;
        (
            (f_t + s * mu * f_n) / den,
            s * (k11 * f_n - k12 * f_t) / (den * den),
        )
    };
    // (time, F_t* and u*, du*/dmu of the phase's start): stick before the first slip, and
    // after the reversal at t = 3 (slip back to F_t = -0.6)
    let (u_rev, du_rev) = slip(-0.6, -1.0);
    let stick = [(0.3, 0.0, 0.0, 0.0), (3.4, -0.6, u_rev, du_rev)];
    let mut previous: Option<[f64; 2]> = None;
    for e in 1..=9 {
        let eps = 10f64.powi(e);
        let mut scene = klarbring_2dof(10);
        scene.contacts[0].tangential_stiffness = Some(eps);
        let model = scene.build().unwrap();
        let s = sens(&model, &["plane.mu", "plane.eps_t"], Method::Ddm, 0.0);
        let mut errors = [0.0; 2];
        let mut line = format!("eps_T = {eps:.0e}:");
        for (k, &(t, ft_star, u_star, du_star)) in stick.iter().enumerate() {
            let i = at(&s, t);
            let df = 0.6 * cycle(t) - ft_star;
            let (u, du_dmu, du_deps) = (i.values[0], i.derivatives[0][0], i.derivatives[0][1]);
            errors[k] = (u - u_star).abs();
            line += &format!(
                " stick t = {t}: u - u_rigid {:.4e} (dF/(k11 + eps) {:.4e}), du/dmu - rigid {:.1e}, du/deps {:.4e};",
                u - u_star,
                df / (k11 + eps),
                du_dmu - du_star,
                du_deps
            );
            // Newton stops at 1e-11 of F_ref ~ 1: states within ~1e-11 / k11, carried into the
            // stick phase by the anchor of the last slip
            assert!((u - u_star - df / (k11 + eps)).abs() < 1e-10, "{line}");
            assert!((du_dmu - du_star).abs() < 1e-10, "{line}");
            // the derivative's round-off grows as eps_T x 1e-16 of its size (4e-7 at 1e9)
            let want = -df / (k11 + eps).powi(2);
            assert!((du_deps - want).abs() < 1e-6 * want.abs(), "{line}");
            // slip: independent of eps_T, no sensitivity to it (round-off again eps_T x 1e-16
            // relative to the stick-phase one)
            for (tt, dir) in [(1.0, 1.0), (3.0, -1.0), (4.0, 1.0), (5.0, 1.0)] {
                let j = at(&s, tt);
                let (u_s, du_s) = slip(0.6 * cycle(tt), dir);
                assert!(
                    (j.values[0] - u_s).abs() < 1e-10,
                    "t = {tt}: {}",
                    j.values[0]
                );
                assert!((j.derivatives[0][0] - du_s).abs() < 1e-10, "t = {tt}");
                assert!(j.derivatives[0][1].abs() < 1e-6 * want.abs(), "t = {tt}");
            }
        }
        println!("{line}");
        // the O(k / eps_T) trend: a ten times stiffer penalty, a ten times smaller error
        // ((k11 + 10 eps) / (k11 + eps) = 9.1 at eps = 1e1, -> 10)
        if let Some(prev) = previous {
            for k in 0..2 {
                let ratio = prev[k] / errors[k];
                assert!(
                    (9.0..10.001).contains(&ratio),
                    "eps_T = {eps:e}: ratio {ratio}"
                );
            }
        }
        previous = Some(errors);
    }
}

// ---------------------------------------------------------------------------------------------
// 7. hard increments

/// One St Venant-Kirchhoff cube (E = 1000, nu = 0.3) under a compressive dead load of
/// `load` on its unit face: the nominal stress P11 = (E/2) lambda (lambda^2 - 1) has its limit
/// point at lambda = 1/sqrt(3), |P11| = 192.45 (oracles.md 2): beyond it there is no
/// equilibrium.
fn compressed_cube(load: f64, increments: usize) -> Scene {
    let mut scene = uniaxial_svk(1.5, increments);
    scene.name = "svk-dead-load".into();
    scene.prescribed.retain(|p| p.name != "strain");
    scene.loads = vec![LoadSpec {
        name: "P".into(),
        set: "cube.xmax".into(),
        component: Component::X,
        value: -load,
        amplitude: vec![(0.0, 0.0), (1.0, 1.0)],
    }];
    scene
}

/// What a failed analysis must say: the increment, its time, the residual history of the last
/// attempt (or that an element inverted before there was a residual); and it must keep the
/// converged increments before it. Returns the partial results.
fn check_failure(what: &str, err: &AnalysisError) -> Results {
    let msg = err.to_string();
    println!("{what}: {msg}");
    let partial = err
        .partial()
        .expect("a failed increment keeps the results before it");
    assert!(
        !partial.records.is_empty(),
        "{what}: no converged increment"
    );
    let AnalysisError::Diverged {
        increment,
        time,
        residuals,
        ..
    } = err
    else {
        panic!("{what}: not a Newton failure: {msg}");
    };
    assert_eq!(*increment, partial.records.len() + 1, "{what}");
    // cutback stops at the minimum increment (the nominal one halved max_cutbacks times)
    // instead of creeping towards the limit point in steps shrinking to round-off
    let step = match err {
        AnalysisError::Diverged { step, .. } => *step,
        _ => unreachable!(),
    };
    assert!(
        step > 1e-6,
        "{what}: step {step:e} went below the minimum increment"
    );
    assert!(*time > *partial.times.last().unwrap(), "{what}");
    assert!(
        msg.contains(&format!("increment {increment} (t = {time:.6})")),
        "{msg}"
    );
    // the residual history of the last attempt; empty only when its first evaluation failed
    // (an inverted element has no residual), which the reason then says
    assert!(
        msg.contains("residual history of the last attempt: ["),
        "{what}: {msg}"
    );
    assert!(
        !residuals.is_empty() || msg.contains("inverted"),
        "{what}: no residual history: {msg}"
    );
    partial.clone()
}

/// A hopeless increment ends in `Err` naming the increment, the time and the residual history,
/// with the converged increments in `partial()`, and `fricsens run FILE` writes those to
/// history.csv: a dead load 1.5 times the compressive limit load of a St Venant-Kirchhoff cube
/// (no equilibrium beyond it), and a prescribed compression that flattens the cube (lambda 1
/// -> -0.5: the element inverts at lambda = 0). An increment that is too large at first
/// converges after cutbacks: the large-deflection cantilever taken to alpha = 50 in one
/// increment ends where ten increments end.
///
/// Finding: both failing runs crawl up to the singular point in 333-334 converged
/// sub-increments, the last steps 9e-17: the cutback count restarts after every converged
/// sub-increment, so `max_cutbacks` does not bound the step, and the attempt budget
/// (64 (max_cutbacks + 1) = 704) ends the run. Before this branch that error reported
/// "0 cutbacks" and an empty residual history.
#[test]
fn hard_increments_fail_with_a_useful_error_and_cutbacks_rescue_large_ones() {
    let limit = 1000.0 / 2.0 * (1.0 / 3f64.sqrt()) * (1.0 - 1.0 / 3.0);
    let scene = compressed_cube(1.5 * limit, 10);
    let model = scene.build().unwrap();
    let err = try_solve(&model).expect_err("no equilibrium beyond the limit point");
    let partial = check_failure("dead load beyond the limit point", &err);
    // the converged increments end at the limit point, t = 1 / 1.5
    let t_last = *partial.times.last().unwrap();
    println!(
        "  {} converged (sub-)increments, the last at t = {t_last:.12}",
        partial.records.len()
    );
    assert!(t_last <= 1.0 / 1.5 + 1e-9 && t_last > 0.6, "{t_last}");

    let model = uniaxial_svk(-0.5, 10).build().unwrap();
    let err = try_solve(&model).expect_err("the element inverts");
    let partial = check_failure("compression through lambda = 0", &err);
    // lambda = 1 - 1.5 t reaches 0 at t = 2/3
    assert!(*partial.times.last().unwrap() < 2.0 / 3.0);

    // the command line on the first scene as a file: fails, says why, writes the history
    let dir = scratch_path("extremes");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("dead-load.toml");
    std::fs::write(&file, scene.to_toml().unwrap()).unwrap();
    let out = fricsens()
        .args(["run", &file.display().to_string(), "--out"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("increment") && stderr.contains("residual history"),
        "{stderr}"
    );
    let model = scene.build().unwrap();
    let partial = try_solve(&model).unwrap_err().partial().unwrap().clone();
    let csv = std::fs::read_to_string(dir.join("out").join("history.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    // a header, the initial state and every converged increment
    assert_eq!(rows.len(), 1 + partial.times.len(), "{}", rows[0]);
    let last_time: f64 = rows
        .last()
        .unwrap()
        .split(',')
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    assert!((last_time - partial.times.last().unwrap()).abs() < 1e-9);
    std::fs::remove_dir_all(&dir).ok();

    // cutbacks rescue an increment that is too large
    let tip = |increments: usize| {
        let spec = CantileverSpec {
            alpha: 50.0,
            increments,
            ..CantileverSpec::large_deflection()
        };
        let model = cantilever(&spec).build().unwrap();
        let res = try_solve(&model).unwrap();
        let w = res.response_value(&model, 0, res.times.len() - 1);
        (res, w)
    };
    let (one, w_one) = tip(1);
    let (ten, w_ten) = tip(10);
    let cutbacks: Vec<usize> = one.records.iter().map(|r| r.cutbacks).collect();
    println!(
        "alpha = 50 in one increment: {} sub-increments, cutbacks {cutbacks:?}; tip deflection {w_one:.9e} (ten increments: {w_ten:.9e}, {} cutbacks)",
        one.records.len(),
        ten.records.iter().map(|r| r.cutbacks).sum::<usize>()
    );
    assert!(cutbacks.iter().sum::<usize>() > 0, "no cutback");
    assert_eq!(one.times.last(), Some(&1.0));
    // elasticity: the equilibrium does not depend on the path to it (Newton stops at 1e-9 of
    // the load: the states agree to that times the conditioning)
    assert!(
        (w_one - w_ten).abs() < 1e-6 * w_ten.abs(),
        "{w_one} vs {w_ten}"
    );
}

// ---------------------------------------------------------------------------------------------
// 8. non-smooth points

/// A node on a spring (k = 1 in every direction) pushed by F = 1 (t = 0 -> 1, ten increments)
/// towards the frictionless rigid plane y = -g, g = 0.5: it touches at t = 0.5, an increment
/// end. Responses: its y-displacement and the force on the plane.
fn closing_node() -> Scene {
    Scene {
        name: "closing-node".into(),
        description: String::new(),
        bodies: vec![],
        free_nodes: vec![FreeNodeSpec {
            name: "node".into(),
            x: [0.0; 3],
        }],
        springs: vec![SpringSpec {
            a: "node".into(),
            b: None,
            stiffness: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        }],
        prescribed: vec![],
        loads: vec![LoadSpec {
            name: "F".into(),
            set: "node".into(),
            component: Component::Y,
            value: -1.0,
            amplitude: vec![(0.0, 0.0), (1.0, 1.0)],
        }],
        pressures: vec![],
        shapes: vec![],
        contacts: vec![ContactSpec {
            name: "plane".into(),
            hitting: "node".into(),
            target: TargetSpec::Rigid {
                surface: RigidSpec::Plane {
                    point: [0.0, -0.5, 0.0],
                    normal: [0.0, 1.0, 0.0],
                },
                motion: vec![],
            },
            normal: fricsens::contact::NormalLaw::Lagrange,
            friction: None,
            tangential_stiffness: None,
            constraint_scale: Some(1.0),
            activation: None,
            search_radius: None,
            smoothing: None,
        }],
        steps: vec![StepSpec {
            end: 1.0,
            increments: 10,
        }],
        responses: vec![
            ResponseSpec::Displacement {
                name: "v".into(),
                set: "node".into(),
                component: Component::Y,
            },
            ResponseSpec::TargetForce {
                name: "plane-force-y".into(),
                pair: "plane".into(),
                component: Component::Y,
            },
        ],
        solver: SolverSettings::default(),
        study: StudySpec::default(),
    }
}

/// Non-smooth points reached exactly at an increment end are flagged (`kinks`) and carry the
/// one-sided derivatives (`one_sided`), which match the closed-form left and right derivatives
/// (the stick/slip onset is tests/oracles/contact_oracles.rs's Klarbring test):
/// * yield onset: one J2 hex8 in uniaxial stress, 8 increments per unit, the first ending at
///   eps = sigma_y / E. Elastic side: dsigma/dE = eps, dsigma/dsigma_y = dsigma/dH = 0,
///   d alpha = 0; plastic side (oracles.md 1): dsigma/dsigma_y = E/(E+H),
///   dsigma/dE = H (sigma_y + H eps)/(E+H)^2, dsigma/dH = 0 (E eps = sigma_y),
///   d alpha/dsigma_y = -1/(E+H), d alpha/dE = (sigma_y + H eps)/(E+H)^2.
/// * contact closing: a node on a spring k = 1 under the load F a(t) (F = -1, a = t) towards
///   a frictionless plane at distance g = 0.5, touching at t = 0.5. Open side: v = F a / k,
///   so dv/dF = a / k and d(plane force)/dF = 0; closed side: v = -g, dv/dF = 0, and the
///   plane force F a + k g gives d/dF = a.
///
/// Finding: at the yield onset the 8 Gauss points' trial yield ratios are +-1e-16, so the
/// converged state mixes elastic and plastic points and the two-sided `derivatives` of that
/// increment are neither side (dsigma/dsigma_y = 0.2185 between 0 and 0.952; 0.4517 with
/// 1000 increments per unit). The flag and `one_sided` are right; the increments after it are
/// right again (the plastic return does not depend on the carried derivative of alpha).
#[test]
fn non_smooth_points_are_flagged_with_one_sided_derivatives() {
    // DDM forwards, and the adjoint backwards with the forced branches at the flagged
    // increment alone: each meets the closed forms
    for method in [Method::Ddm, Method::Adjoint] {
        println!("{}", method.name());
        one_sided_meet_the_closed_forms(method);
    }
}

/// [`non_smooth_points_are_flagged_with_one_sided_derivatives`] by `method`.
fn one_sided_meet_the_closed_forms(method: Method) {
    let model = uniaxial_j2(Kinematics::Small, 8).build().unwrap();
    let s = sens(&model, &["sigma_y", "H", "E"], method, 0.0);
    let flagged: Vec<f64> = s
        .increments
        .iter()
        .filter(|i| !i.kinks.is_empty())
        .map(|i| i.time)
        .collect();
    assert_eq!(flagged, vec![0.125], "flagged increments");
    let inc = at(&s, 0.125);
    assert_eq!(inc.kinks.len(), 8, "{:?}", inc.kinks);
    assert!(inc
        .kinks
        .iter()
        .all(|k| k.kind == fricsens::sensitivity::KinkKind::Yield));
    let sides = inc.one_sided.as_ref().expect("one-sided derivatives");
    let (lower, upper) = sides.both().expect("both sides");
    let eps = SY / E;
    let (_, elastic) = j2_oracle(0.125, Some(false));
    let (_, plastic) = j2_oracle(0.125, Some(true));
    assert_eq!(elastic, [0.0, 0.0, eps]);
    let d_alpha = [-1.0 / (E + H), 0.0, (SY + H * eps) / ((E + H) * (E + H))];
    println!(
        "yield onset: derivatives {:?}; elastic side {:?} (oracle {elastic:?}); plastic side {:?} (oracle {plastic:?}); d alpha plastic side {:?} (oracle {d_alpha:?})",
        inc.derivatives[0], lower[0], upper[0], upper[2]
    );
    let scale = [1.0, SY / H, SY / E];
    for p in 0..3 {
        // one hex8 in a homogeneous state: exact to round-off
        let close = |a: f64, b: f64, s: f64| (a - b).abs() <= 1e-10 * b.abs().max(s);
        assert!(close(lower[0][p], elastic[p], scale[p]), "elastic {p}");
        assert!(close(upper[0][p], plastic[p], scale[p]), "plastic {p}");
        assert!(lower[2][p] == 0.0, "alpha, elastic side {p}");
        assert!(
            close(upper[2][p], d_alpha[p], scale[p] / E),
            "alpha, plastic side {p}: {} vs {}",
            upper[2][p],
            d_alpha[p]
        );
    }
    // the increments after the onset: back on the plastic closed form
    for t in [0.25, 0.375, 1.0] {
        let (_, want) = j2_oracle(t, None);
        let got = &at(&s, t).derivatives[0];
        for p in 0..3 {
            assert!((got[p] - want[p]).abs() <= 1e-10 * want[p].abs().max(scale[p]));
        }
    }

    let model = closing_node().build().unwrap();
    let s = sens(&model, &["load.F"], method, 0.0);
    for inc in &s.increments {
        println!(
            "closing node t = {:.1}: v {:.3}, plane force {:.3}; d/dF {:?}; kinks {:?}; one-sided {:?}",
            inc.time, inc.values[0], inc.values[1], inc.derivatives, inc.kinks, inc.one_sided
        );
        if (inc.time - 0.5).abs() > 1e-9 {
            assert!(inc.kinks.is_empty(), "t = {}: {:?}", inc.time, inc.kinks);
            continue;
        }
        assert!(
            inc.kinks.len() == 1 && inc.kinks[0].kind == fricsens::sensitivity::KinkKind::Contact,
            "{:?}",
            inc.kinks
        );
        let sides = inc.one_sided.as_ref().expect("one-sided derivatives");
        let a = 0.5;
        // [response][parameter]: v, plane force
        assert_eq!(sides.lower, Some(vec![vec![a], vec![0.0]]), "open side");
        assert_eq!(sides.upper, Some(vec![vec![0.0], vec![a]]), "closed side");
    }
}

/// A side whose forced solve fails is left out, and the run keeps everything else. A free node
/// pressed on a rigid plane (N = 1, Lagrange), held along it by friction alone (Coulomb,
/// mu = 0.25, tangential penalty k = 1000), under a tangential load ramped to exactly mu N
/// at t = 1 and held: from there on it sits at the onset of slip, flagged. Its stick side is
/// the converged state's (`u = T / k`: du/dT = 1 / k, du/dmu = 0); on its slip side nothing
/// resists sliding, the forced tangent is singular and that side's derivative unbounded.
/// DDM and the adjoint both give the converged branches' derivatives and the stick side,
/// and say of the slip side at each flagged increment that it failed and why.
#[test]
fn a_one_sided_solve_that_fails_leaves_that_side_out_and_keeps_the_run() {
    let text = r#"
name = "slip-onset-free-node"
bodies = []
[[free_nodes]]
name = "slider"
x = [0.0, 0.0, 0.0]
[[springs]]
a = "slider"
stiffness = [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
[[loads]]
name = "N"
set = "slider"
component = "y"
value = -1.0
amplitude = [[0.0, 1.0], [2.0, 1.0]]
[[loads]]
name = "T"
set = "slider"
component = "x"
value = 0.25
amplitude = [[0.0, 0.0], [1.0, 1.0], [2.0, 1.0]]
[[contacts]]
name = "plane"
hitting = "slider"
tangential_stiffness = 1000.0
constraint_scale = 1.0
[contacts.target.rigid]
motion = []
[contacts.target.rigid.surface]
shape = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
[contacts.normal]
law = "lagrange"
[contacts.friction]
law = "coulomb"
mu = 0.25
[[steps]]
end = 2.0
increments = 4
[[responses]]
kind = "displacement"
name = "slider-u"
set = "slider"
component = "x"
"#;
    let model = Scene::from_toml(text, "slip-onset-free-node.toml")
        .unwrap()
        .build()
        .unwrap();
    let k = 1000.0;
    for method in [Method::Ddm, Method::Adjoint] {
        let s = sens(&model, &["mu", "load.T"], method, 0.0);
        assert_eq!(s.increments.len(), 4, "{method:?}: every increment");
        for inc in &s.increments {
            println!(
                "{method:?} t = {}: u {:.6e}, d/d(mu, T) {:?}; one-sided {:?}",
                inc.time, inc.values[0], inc.derivatives[0], inc.one_sided
            );
            let t = inc.time.min(1.0);
            assert!((inc.values[0] - 0.25 * t / k).abs() <= 1e-12 / k, "u");
            // the converged branches' derivatives, exact: the stick state's
            let want = [0.0, t / k];
            for (got, want) in inc.derivatives[0].iter().zip(want) {
                assert!(
                    (got - want).abs() <= 1e-12 / k,
                    "{method:?} t = {}",
                    inc.time
                );
            }
            if inc.time < 1.0 {
                assert!(inc.kinks.is_empty() && inc.one_sided.is_none());
                continue;
            }
            assert!(
                !inc.kinks.is_empty(),
                "{method:?} t = {}: flagged",
                inc.time
            );
            let sides = inc.one_sided.as_ref().expect("one-sided derivatives");
            // the stick side is the converged state's, solved with its tangent: the same
            assert_eq!(
                sides.lower.as_deref(),
                Some(&inc.derivatives[..]),
                "stick side"
            );
            assert_eq!(sides.upper, None, "{method:?}: the slip side is unbounded");
            assert_eq!(sides.failed.len(), 1, "{:?}", sides.failed);
            let why = &sides.failed[0];
            assert!(
                why.contains(&format!("increment {}", inc.increment))
                    && why.contains("upper (plastic / slip / closed)")
                    && why.contains("singular"),
                "{why}"
            );
        }
    }
    // from the command line, with default settings: the run succeeds, its summary says which
    // side failed where, and sensitivity.json has that side null and the other's numbers
    let dir = scratch_path("one-sided-failure");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("slip-onset-free-node.toml");
    std::fs::write(&file, text).unwrap();
    for (method, at) in [("ddm", &[][..]), ("adjoint", &["--at", "all"][..])] {
        let out = fricsens()
            .args([
                "sensitivity",
                &file.display().to_string(),
                "--method",
                method,
            ])
            .args(["--param", "mu"])
            .args(at)
            .arg("--out")
            .arg(dir.join(method))
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let lines = (stdout.lines())
            .filter(|l| l.starts_with("one-sided derivatives: increment"))
            .count();
        assert_eq!(lines, 3, "{method}: one line a flagged increment\n{stdout}");
        let json = std::fs::read_to_string(dir.join(method).join("sensitivity.json")).unwrap();
        let json: serde_json::Value = serde_json::from_str(&json).unwrap();
        let last = &json["increments"][3]["one_sided"];
        assert!(last["upper"].is_null(), "{method}: {last}");
        assert_eq!(
            last["lower"],
            serde_json::json!([[0.0]]),
            "{method}: {last}"
        );
        assert_eq!(last["failed"].as_array().map(Vec::len), Some(1), "{method}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// 9. a singular tangent says which unknowns nothing holds

/// The error of a run that fails on a singular tangent must name what makes it singular.
#[track_caller]
fn singular_error(scene: Scene, needles: &[&str]) {
    let model = scene.build().expect("the scene builds");
    let err = match try_solve(&model) {
        Ok(_) => panic!("a model with a singular tangent converged"),
        Err(e) => e.to_string(),
    };
    for n in ["singular tangent", "with a zero row"]
        .iter()
        .chain(needles)
    {
        assert!(err.contains(n), "`{n}` is not in the error:\n{err}");
    }
}

/// Found by an audit of bad input: a spring of zero stiffness (or from a node to itself)
/// holds nothing, and the run failed with "singular tangent" alone; a node prescribed in
/// every component that closes against a Lagrange pair leaves its multiplier nothing to act
/// on, likewise.
#[test]
fn a_singular_tangent_names_the_unknowns_nothing_holds() {
    // the closing node's spring of zero stiffness: nothing holds the node in x (nor in y and
    // z: the pair is open at the start)
    let mut s = closing_node();
    s.springs[0].stiffness = [[0.0; 3]; 3];
    singular_error(s.clone(), &["node 0 x", "node 0 z"]);
    // the same with a prescribed motion elsewhere (a second node on a spring, driven): the
    // attempt now fails in the predictor's linearised step, whose error says the same
    s.free_nodes.push(FreeNodeSpec {
        name: "driven".into(),
        x: [3.0, 0.0, 0.0],
    });
    s.springs.push(SpringSpec {
        a: "driven".into(),
        b: None,
        stiffness: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    });
    s.prescribed.push(PrescribedSpec {
        name: "drive".into(),
        set: "driven".into(),
        components: vec![Component::X],
        value: 0.1,
        amplitude: vec![(0.0, 0.0), (1.0, 1.0)],
    });
    singular_error(s, &["node 0 x", "node 0 z"]);
    // the node driven into the plane in every component: the multiplier of its closed
    // Lagrange constraint has no free unknown to act on
    let mut s = closing_node();
    s.loads.clear();
    s.prescribed.push(PrescribedSpec {
        name: "driven".into(),
        set: "node".into(),
        components: vec![Component::X, Component::Y, Component::Z],
        value: -1.0,
        amplitude: vec![(0.0, 0.0), (1.0, 1.0)],
    });
    singular_error(s, &["the contact multiplier of pair 'plane' node 0"]);
}

/// Found by the same audit: a load on a node nothing holds went to a reaction without a word
/// (the node pinned as untouched, `up = 0`, the reaction -1).
#[test]
fn a_load_on_a_node_nothing_holds_is_an_error_naming_it() {
    let mut s = closing_node();
    s.springs.clear();
    s.contacts.clear();
    s.responses.truncate(1);
    let model = s.build().expect("the scene builds");
    let err = match try_solve(&model) {
        Ok(_) => panic!("a load on a node nothing holds was accepted"),
        Err(e) => e.to_string(),
    };
    assert!(
        err.contains("load 'F': node 0 is held by no element, spring or contact pair"),
        "{err}"
    );
}
