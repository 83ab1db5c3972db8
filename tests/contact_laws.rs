//! The three normal laws on the contact patch test: Lagrange multipliers (exact, indefinite
//! system), penalty (cheap, interpenetrates by p_n / eps_N), augmented Lagrangian (penalty
//! stiffness, multiplier estimates updated until the penetration is within tolerance).

use fricsens::contact::NormalLaw;
use fricsens::scene::contact_patch;
use fricsens::solver::{NoObserver, Results, RunOptions, Solver};

fn run(normal: NormalLaw) -> (fricsens::model::Model, Results) {
    let mut scene = contact_patch(None);
    scene.contacts[0].normal = normal;
    let model = scene.build().unwrap();
    let res = Solver::new(&model)
        .unwrap()
        .run(&RunOptions::default(), &mut NoObserver)
        .unwrap();
    (model, res)
}

/// Largest penetration, and the pressures, at the end.
fn summary(model: &fricsens::model::Model, res: &Results) -> (f64, Vec<f64>) {
    let last = res.states.len() - 1;
    let c = &res.contact[last];
    let pen = c.gap.iter().fold(0.0f64, |m, g| m.max(-g));
    let p = (0..model.responses.len())
        .map(|r| res.response_value(model, r, last))
        .collect();
    (pen, p)
}

#[test]
fn lagrange_penalty_and_augmented_lagrangian_on_the_patch_test() {
    let eps = 1e5; // pressure per unit penetration; the applied pressure is 10
    let (m, r) = run(NormalLaw::Lagrange);
    let (pen_l, p_l) = summary(&m, &r);
    let (m, r2) = run(NormalLaw::Penalty { stiffness: eps });
    let (pen_p, p_p) = summary(&m, &r2);
    let tol = 1e-9;
    let (m, r3) = run(NormalLaw::Augmented {
        stiffness: eps,
        tolerance: tol,
    });
    let (pen_a, p_a) = summary(&m, &r3);
    let iters = |r: &Results| r.records.iter().map(|x| x.iterations).sum::<usize>();
    let augs = r3.records.iter().map(|x| x.augmentations).sum::<usize>();
    println!(
        "Lagrange: penetration {pen_l:.2e}, {} iterations",
        iters(&r)
    );
    println!(
        "penalty:  penetration {pen_p:.2e}, {} iterations",
        iters(&r2)
    );
    println!(
        "augmented: penetration {pen_a:.2e}, {} iterations in {} passes",
        iters(&r3),
        augs + r3.records.len()
    );
    // every law transmits the uniform pressure (equilibrium)
    for p in p_l.iter().chain(&p_p).chain(&p_a) {
        assert!((p - 10.0).abs() < 1e-8 * 10.0, "pressure {p}");
    }
    // Lagrange: no penetration
    assert!(pen_l < 1e-12, "Lagrange penetration {pen_l}");
    // penalty: the bodies interpenetrate by p / eps_N = 1e-4 everywhere
    assert!(
        (pen_p - 10.0 / eps).abs() < 1e-6 * pen_p,
        "penalty penetration {pen_p}"
    );
    // augmented Lagrangian: within its tolerance after a few passes
    assert!(pen_a <= tol, "augmented penetration {pen_a}");
    assert!(augs >= 1, "no augmentation pass");
}

#[test]
fn the_active_set_weight_changes_the_newton_path_not_the_solution() {
    // any weight c > 0 of the gap in `lambda - c k g >= 0` has the same solutions; on the coarse
    // leaf spring (frictional, elastoplastic, the block's nose sliding across faces) c = 1 and
    // c = 1e-3 converge through the same increments, so every response must agree at every
    // increment to Newton's tolerance (1e-9 of the reference force; 1e-6 relative leaves room
    // for the path-dependent friction and plastic history of two differently iterated but
    // equally converged runs). The sliding block served until the extrapolating predictor made
    // both weights take identical iterates there.
    let run = |c: Option<f64>| {
        let mut scene = fricsens::scene::builtin("leaf-spring-coarse").unwrap();
        for p in &mut scene.contacts {
            p.activation = c;
        }
        let model = scene.build().unwrap();
        let res = Solver::new(&model)
            .unwrap()
            .run(&RunOptions::default(), &mut NoObserver)
            .unwrap();
        let residuals: Vec<Vec<f64>> = res.records.iter().map(|r| r.residuals.clone()).collect();
        let values: Vec<Vec<f64>> = (0..model.responses.len())
            .map(|r| {
                (1..res.times.len())
                    .map(|k| res.response_value(&model, r, k))
                    .collect()
            })
            .collect();
        (res.times.clone(), values, residuals)
    };
    let (t1, v1, r1) = run(None);
    let (t3, v3, r3) = run(Some(1e-3));
    assert_eq!(t1, t3, "same increments");
    // not vacuous: the weight changes the iterates (the residual histories), whether or not
    // it changes the number of iterations
    assert_ne!(r1, r3, "the weight changes Newton's path");
    for (a, b) in v1.iter().zip(&v3) {
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-6 * scale, "{x} vs {y}");
        }
    }
}

#[test]
fn the_extrapolating_predictor_and_the_penetration_limiter_change_the_path_not_the_solution() {
    // The predictor only chooses where Newton starts, and the limiter only shortens steps on
    // the way: on the coarse leaf spring (frictional, elastoplastic, leaf-leaf first contact
    // that the limiter acts on) the runs with and without extrapolation must agree at every
    // time both converged at, to 1e-6 of each response's largest value (the tolerance of the
    // activation test above, for the same reason: path-dependent friction and plastic history
    // of two differently iterated, equally converged runs), and the extrapolated run must
    // take fewer Newton iterations.
    let run = |extrapolate: bool| {
        let mut scene = fricsens::scene::builtin("leaf-spring-coarse").unwrap();
        scene.solver.extrapolate = extrapolate;
        let model = scene.build().unwrap();
        let res = Solver::new(&model)
            .unwrap()
            .run(&RunOptions::default(), &mut NoObserver)
            .unwrap();
        let iterations: usize = res.records.iter().map(|r| r.iterations).sum();
        (model, res, iterations)
    };
    let (model, on, it_on) = run(true);
    let (_, off, it_off) = run(false);
    assert!(it_on < it_off, "{it_on} vs {it_off} iterations");
    let mut compared = 0;
    for r in 0..model.responses.len() {
        let values = |res: &Results| -> Vec<(f64, f64)> {
            (1..res.times.len())
                .map(|k| (res.times[k], res.response_value(&model, r, k)))
                .collect()
        };
        let (a, b) = (values(&on), values(&off));
        let scale = a.iter().fold(0.0f64, |m, (_, v)| m.max(v.abs()));
        for (t, x) in &a {
            if let Some((_, y)) = b.iter().find(|(s, _)| (s - t).abs() <= 1e-12) {
                assert!((x - y).abs() <= 1e-6 * scale, "t = {t}: {x} vs {y}");
                compared += 1;
            }
        }
    }
    assert!(
        compared >= 10 * model.responses.len(),
        "only {compared} values compared"
    );
}
