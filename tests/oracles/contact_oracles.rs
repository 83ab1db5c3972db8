//! Frictional contact against closed forms: the two-degree-of-freedom system (oracles.md
//! section 6), the Jenkins element (section 5), the strip pull-out (section 7), Hertz line
//! contact (section 4) and the contact patch test.

// Index loops over responses, parameters and unknowns read like the formulas they check.
#![allow(clippy::needless_range_loop)]

use crate::common::solve;

use fricsens::scene::{
    contact_patch, hertz, jenkins, klarbring_2dof, strip_pullout, HertzSpec, StripSpec,
};
use fricsens::sensitivity::{run_sensitivity, Method, Parameter, Settings, TangentChoice};

/// oracles.md section 6, slip in direction s: u and du/dmu
fn klarbring_slip(ft: f64, s: f64, mu: f64) -> (f64, f64) {
    let (k11, k12, fn_) = (1.0, 0.5, -1.0);
    let den = k11 + s * mu * k12;
    (
        (ft + s * mu * fn_) / den,
        s * (k11 * fn_ - k12 * ft) / (den * den),
    )
}

#[test]
fn klarbring_two_dof_displacement_and_sensitivity_at_the_worked_points() {
    let model = klarbring_2dof(10).build().unwrap();
    let mu = Parameter::by_name(&model, "plane.mu").unwrap();
    let settings = Settings {
        method: Method::Ddm,
        tangent: TangentChoice::Exact,
        ..Settings::default()
    };
    let (_, sens) = run_sensitivity(&model, &[mu], &settings).unwrap();
    let at = |t: f64| {
        sens.increments
            .iter()
            .find(|i| (i.time - t).abs() < 1e-9)
            .unwrap()
    };
    // worked values (oracles.md section 6), and the formulas at the same points
    for (t, ft, s, u_worked, du_worked) in [
        (1.0, 0.6, 1.0, 0.260870, -0.982987),
        (3.0, -0.6, -1.0, -0.352941, 0.968858),
        (4.0, 0.0, 1.0, -0.260870, -0.756144),
    ] {
        let inc = at(t);
        let (u, du) = klarbring_slip(ft, s, 0.3);
        println!(
            "t = {t}: u {:.9} ({u:.9}), du/dmu {:.9} ({du:.9})",
            inc.values[0], inc.derivatives[0][0]
        );
        assert!(
            (u - u_worked).abs() < 1e-6 && (du - du_worked).abs() < 1e-6,
            "formula vs worked"
        );
        assert!(
            (inc.values[0] - u).abs() <= 1e-10 * u.abs(),
            "t = {t}: u {} vs {u}",
            inc.values[0]
        );
        assert!(
            (inc.derivatives[0][0] - du).abs() <= 1e-8 * du.abs(),
            "t = {t}: du/dmu {} vs {du}",
            inc.derivatives[0][0]
        );
    }
}

#[test]
fn klarbring_first_slip_onset_is_flagged_with_one_sided_derivatives() {
    // with 10 increments per unit, t = 0.5 (F_t = 0.3) ends exactly at the first slip onset
    let model = klarbring_2dof(10).build().unwrap();
    let mu = Parameter::by_name(&model, "plane.mu").unwrap();
    let settings = Settings {
        method: Method::Ddm,
        tangent: TangentChoice::Exact,
        kink_tol: 1e-5,
        ..Settings::default()
    };
    let (_, sens) = run_sensitivity(&model, &[mu], &settings).unwrap();
    let inc = sens
        .increments
        .iter()
        .find(|i| (i.time - 0.5).abs() < 1e-9)
        .unwrap();
    assert!(!inc.kinks.is_empty(), "slip onset not flagged");
    let sides = inc.one_sided.as_ref().expect("one-sided derivatives");
    let (stick, slip) = sides.both().expect("both sides");
    // oracle: left (stick) 0, right (slip) -0.869565 = s (k11 F_n - k12 F_t) / (k11 + mu k12)^2
    let (_, right) = klarbring_slip(0.3, 1.0, 0.3);
    println!(
        "onset: stick {:.3e}, slip {:.9} (oracle {right:.9})",
        stick[0][0], slip[0][0]
    );
    assert!(stick[0][0].abs() < 1e-8, "stick side {}", stick[0][0]);
    assert!(
        (slip[0][0] - right).abs() < 1e-6 * right.abs(),
        "slip side {}",
        slip[0][0]
    );
    // the converged state is on one side of the onset: that side is the derivative itself, so
    // only the other side's forced tangent is solved with (one solve with a tangent of its own
    // per increment for the exact tangent, plus one; the converged tangents' each a
    // factorization or a GMRES solve preconditioned with Newton's factor, `Settings::krylov`,
    // the forced one a factorization: it may be singular, which GMRES need not report)
    assert_eq!(
        sens.cost.factorizations + sens.cost.krylov_solves,
        sens.increments.len() + 1,
        "factorizations {} + GMRES solves {}",
        sens.cost.factorizations,
        sens.cost.krylov_solves
    );
    // the forced side factored, not solved by GMRES: against the same run without the
    // one-sided derivatives, one factorization more and the same GMRES solves
    let mu = Parameter::by_name(&model, "plane.mu").unwrap();
    let without = Settings {
        one_sided: false,
        ..settings.clone()
    };
    let (_, plain) = run_sensitivity(&model, &[mu], &without).unwrap();
    assert_eq!(
        (sens.cost.factorizations, sens.cost.krylov_solves),
        (plain.cost.factorizations + 1, plain.cost.krylov_solves),
        "the forced side's solve"
    );
    // the adjoint, backwards with the flagged points forced at that increment alone: the
    // same sides (its main value the converged branches', DDM's)
    let settings = Settings {
        method: Method::Adjoint,
        ..settings
    };
    let mu = Parameter::by_name(&model, "plane.mu").unwrap();
    let (_, adj) = run_sensitivity(&model, &[mu], &settings).unwrap();
    let a = (adj.increments.iter())
        .find(|i| (i.time - 0.5).abs() < 1e-9)
        .unwrap();
    assert_eq!(a.kinks, inc.kinks, "the same flagged points");
    let sides = a
        .one_sided
        .as_ref()
        .expect("the adjoint's one-sided derivatives");
    let (lower, upper) = sides.both().expect("both sides");
    println!(
        "adjoint: stick {:.3e}, slip {:.9}",
        lower[0][0], upper[0][0]
    );
    assert!(lower[0][0].abs() < 1e-8, "stick side {}", lower[0][0]);
    assert!(
        (upper[0][0] - right).abs() < 1e-6 * right.abs(),
        "slip side {}",
        upper[0][0]
    );
    // other increments are not flagged
    let flagged: Vec<f64> = sens
        .increments
        .iter()
        .filter(|i| !i.kinks.is_empty())
        .map(|i| i.time)
        .collect();
    println!("flagged increments at t = {flagged:?}");
}

#[test]
fn jenkins_friction_force_and_its_mu_derivative_along_the_cycle() {
    // k = 1, N = 1, mu = 0.3, U_a = 1: slip when |T| reaches mu N
    let model = jenkins(10).build().unwrap();
    let mu = Parameter::by_name(&model, "plane.mu").unwrap();
    let settings = Settings {
        method: Method::Ddm,
        tangent: TangentChoice::Exact,
        ..Settings::default()
    };
    let (_, sens) = run_sensitivity(&model, &[mu], &settings).unwrap();
    let (n, m) = (1.0, 0.3); // normal force, mu (spring k = 1)
    let mut slips = 0;
    for inc in &sens.increments {
        let t = inc.time;
        let tension = inc.values[0]; // reaction at the base = spring force on the base side
        let dtdmu = inc.derivatives[0][0];
        // analytic Jenkins path: U(t) piecewise linear; slider stuck until |k (U - us)| = mu N
        let (u_base, dir) = if t <= 1.0 {
            (t, 1.0)
        } else if t <= 3.0 {
            (1.0 - (t - 1.0), -1.0)
        } else {
            (-1.0 + (t - 3.0), 1.0)
        };
        let _ = u_base;
        let slipping = (tension.abs() - m * n).abs() < 1e-10 * m * n && tension.signum() == dir;
        if slipping {
            slips += 1;
            // T = s mu N and dT/dmu = s N (oracles.md section 5; the base reaction has the
            // spring force's sign)
            assert!((dtdmu - dir * n).abs() < 1e-8, "t = {t}: dT/dmu {dtdmu}");
        }
        assert!(
            tension.abs() <= m * n * (1.0 + 1e-10),
            "t = {t}: |T| = {tension} above mu N"
        );
    }
    assert!(slips > 10, "too few slipping increments ({slips})");
}

#[test]
fn contact_patch_test_transmits_a_uniform_pressure() {
    for mu in [None, Some(0.3)] {
        let model = contact_patch(mu).build().unwrap();
        let res = solve(&model);
        for r in 0..model.responses.len() {
            let p = res.response_value(&model, r, 1);
            assert!(
                (p - 10.0).abs() < 1e-8 * 10.0,
                "mu {mu:?}: {} = {p}",
                model.responses[r].name
            );
        }
    }
}

#[test]
fn hertz_half_width_and_peak_pressure() {
    let h = HertzSpec::default();
    let model = hertz(&h).build().unwrap();
    let res = solve(&model);
    let last = res.states.len() - 1;
    let pair = &model.contacts[0];
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    // half model, thickness t: force per unit length of the full model P = 2 F / t;
    // M2 = int p x^2 dx over the full width = 2 sum_i F_i x_i^2 / t
    let thickness = model.mesh.blocks[0].z.length;
    let fy = model
        .responses
        .iter()
        .position(|r| r.name == "cylinder-force-y")
        .unwrap();
    let total = 2.0 * res.response_value(&model, fy, last) / thickness;
    let c = &res.contact[last];
    let flat = res.contact_flat[0];
    let (mut force, mut m2) = (0.0, 0.0);
    for (i, &s) in pair.hitting.iter().enumerate() {
        let f = c.normal_force[flat + i];
        force += 2.0 * f / thickness;
        m2 += 2.0 * f * x[s][0].powi(2) / thickness;
    }
    let a_eff = 2.0 * (m2 / force).sqrt();
    let p0 = (0..model.responses.len())
        .filter(|r| model.responses[*r].name.starts_with("p["))
        .map(|r| res.response_value(&model, r, last))
        .fold(0.0f64, f64::max);
    let p = h.load();
    let a = (4.0 * p * h.radius / (std::f64::consts::PI * h.e_star())).sqrt();
    let p0_exact = 2.0 * p / (std::f64::consts::PI * a);
    println!("P {force:.4} (applied {p:.4}); a_eff {a_eff:.5} (Hertz {a:.5}); p0 {p0:.3} (Hertz {p0_exact:.3})");
    // the normal forces' vertical components carry the load (equilibrium to solver tolerance)
    assert!((total - p).abs() < 1e-7 * p, "equilibrium: {total} vs {p}");
    assert!((a_eff - a).abs() < 0.03 * a, "half-width {a_eff} vs {a}");
    assert!(
        (p0 - p0_exact).abs() < 0.03 * p0_exact,
        "peak {p0} vs {p0_exact}"
    );
}

#[test]
fn strip_pullout_end_displacement_and_mu_sensitivity_against_the_1d_oracle() {
    let s = StripSpec::default();
    let model = strip_pullout(&s).build().unwrap();
    let mu = Parameter::by_name(&model, "ground.mu").unwrap();
    let settings = Settings {
        method: Method::Ddm,
        ..Settings::default()
    };
    let (res, sens) = run_sensitivity(&model, &[mu], &settings).unwrap();
    let k = s.young * s.thickness * s.width * s.mu * s.n;
    let mut checked = 0;
    let mut checked_d = 0;
    let mut worst: f64 = 0.0;
    let mut worst_d: f64 = 0.0;
    for inc in &sens.increments {
        let t = inc.time;
        // slip length of the last change of direction (loading: F / (mu n); unloading: the
        // reverse-slip zone (F1 - F) / (2 mu n))
        let (u0, slip_length) = if t <= 1.0 {
            let f = s.force * t;
            (f * f / (2.0 * k), f / (s.mu * s.n))
        } else {
            let f = s.force * (2.0 - t);
            (
                s.force.powi(2) / (2.0 * k) - (s.force - f).powi(2) / (4.0 * k),
                (s.force - f) / (2.0 * s.mu * s.n),
            )
        };
        let got = inc.values[0];
        let dgot = inc.derivatives[0][0];
        // the 1D oracle holds for thickness / slip length < 0.05 (oracles.md section 7)
        let valid = s.thickness / slip_length < 0.05;
        // the derivative of the discrete problem holds the stick/slip pattern fixed, so it
        // misses the motion of the slip front, an O(h / l) error: it is compared where the slip
        // zone spans at least 20 elements
        let h = s.length / s.elements as f64;
        let resolved = slip_length >= 20.0 * h;
        println!(
            "t = {t:.2}: u0 {got:.6e} ({u0:.6e}), du0/dmu {dgot:.6e} ({:.6e}){}{}",
            -u0 / s.mu,
            if valid {
                ""
            } else {
                "  [outside the oracle's range]"
            },
            if resolved {
                "  [slip zone >= 20 elements]"
            } else {
                ""
            }
        );
        if valid {
            checked += 1;
            worst = worst.max((got - u0).abs() / u0);
            if resolved {
                worst_d = worst_d.max((dgot + u0 / s.mu).abs() / (u0 / s.mu));
                checked_d += 1;
            }
        }
    }
    let iters: Vec<usize> = res.records.iter().map(|r| r.iterations).collect();
    println!("Newton iterations per increment: {iters:?}");
    assert!(
        checked >= 3,
        "too few points inside the oracle's range ({checked})"
    );
    println!("largest relative error of u0 inside the oracle's range: {worst:.4}");
    println!("largest relative error of du0/dmu where resolved: {worst_d:.4} ({checked_d} points)");
    assert!(worst < 0.02, "u0: largest error {worst}");
    assert!(checked_d >= 3, "too few resolved points ({checked_d})");
    assert!(worst_d < 0.02, "du0/dmu: largest error {worst_d}");
}

#[test]
fn strip_pullout_ddm_matches_central_fdm_and_the_mu_scaling_along_loading_and_unloading() {
    // The 1D solution scales as u0 ~ 1/mu at every point of the path (K = EA mu n); the
    // discrete model keeps that scaling up to its discretisation, and DDM must equal a central
    // finite difference of reruns wherever no stick/slip state changes within the step.
    let s = StripSpec::default();
    let model = strip_pullout(&s).build().unwrap();
    let mu = [Parameter::by_name(&model, "ground.mu").unwrap()];
    let run = |method, beta| {
        let settings = Settings {
            method,
            beta,
            tangent: TangentChoice::Exact,
            ..Settings::default()
        };
        run_sensitivity(&model, &mu, &settings).unwrap().1
    };
    let ddm = run(Method::Ddm, 0.0);
    let fdm = run(Method::FdmCentral, 1e-7);
    let mut agree = 0;
    for (a, b) in ddm.increments.iter().zip(&fdm.increments) {
        let (d, f, u0) = (a.derivatives[0][0], b.derivatives[0][0], a.values[0]);
        // -u0/mu within 5 % where the slip zone spans at least 10 elements: the scaling of
        // the continuum, which a slip zone of a few nodes cannot resolve
        let t = a.time;
        let h = s.length / s.elements as f64;
        // (loading only: on unloading the discrete reverse-slip front jumps a node every
        // increment or two and the derivative of the discrete problem oscillates about the
        // continuum scaling; DDM = FDM below is the check there)
        let zone = s.force * t / (s.mu * s.n);
        if t <= 1.0 && zone >= 10.0 * h {
            assert!(
                (d + u0 / s.mu).abs() < 0.05 * u0 / s.mu,
                "t = {t}: {d} vs {}",
                -u0 / s.mu
            );
        }
        // DDM against central FDM of complete reruns (beta = 1e-7: truncation ~1e-14,
        // round-off ~1e-16 / 1e-7 amplified by the Newton tolerance 1e-9 / 1e-7 ~ 1e-2 of the
        // response's last digits, i.e. ~1e-6 relative here)
        assert!(
            (d - f).abs() < 1e-5 * d.abs(),
            "t = {t}: DDM {d} vs FDM {f}"
        );
        agree += 1;
        println!(
            "t = {:.1}: ddm {d:.6e} fdm {f:.6e} -u0/mu {:.6e}",
            a.time,
            -u0 / s.mu
        );
    }
    assert!(
        agree >= ddm.increments.len() / 2,
        "DDM and FDM agree at only {agree} increments"
    );
}

#[test]
fn strip_pullout_mu_sensitivity_on_a_fine_mesh_along_loading_and_unloading() {
    // 200 elements (h = 0.05): du0/dmu = -u0/mu (oracles.md section 7) within 2 % on the
    // whole unloading branch and wherever the loading slip zone spans >= 35 elements (measured:
    // 2.9 % at 24, 2.3 % at 30, 1.9 % at 36, 1.2 % at 60 elements; unloading <= 1.6 %); the
    // derivative of the discrete problem holds the slip front at a node, an O(h / l) error that
    // halves from 100 to 200 elements (the short slip zones of early loading are not resolved)
    let s = StripSpec {
        elements: 200,
        ..StripSpec::default()
    };
    let mut scene = strip_pullout(&s);
    // the slip front advances about one node per Newton iteration: allow for it
    scene.solver.max_iterations = 80;
    let model = scene.build().unwrap();
    let mu = [Parameter::by_name(&model, "ground.mu").unwrap()];
    let (_, sens) = run_sensitivity(&model, &mu, &Settings::default()).unwrap();
    let k = s.young * s.thickness * s.width * s.mu * s.n;
    let h = s.length / s.elements as f64;
    let mut checked = 0;
    for inc in &sens.increments {
        let t = inc.time;
        let (u0, l, loading) = if t <= 1.0 {
            let f = s.force * t;
            (f * f / (2.0 * k), f / (s.mu * s.n), true)
        } else {
            let f = s.force * (2.0 - t);
            (
                s.force.powi(2) / (2.0 * k) - (s.force - f).powi(2) / (4.0 * k),
                (s.force - f) / (2.0 * s.mu * s.n),
                false,
            )
        };
        let (got, d) = (inc.values[0], inc.derivatives[0][0]);
        if !loading || l >= 35.0 * h {
            checked += 1;
            assert!((got - u0).abs() < 0.01 * u0, "t = {t}: u0 {got} vs {u0}");
            assert!(
                (d + u0 / s.mu).abs() < 0.02 * u0 / s.mu,
                "t = {t}: du0/dmu {d} vs {}",
                -u0 / s.mu
            );
        }
    }
    assert!(checked >= 14, "only {checked} points checked");
}
