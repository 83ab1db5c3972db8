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

/// The coarse leaf spring (frictional, elastoplastic, the block's nose sliding across faces,
/// leaf-leaf first contact), its scene changed by `change`, run to the end.
fn coarse_leaf_spring(
    change: impl FnOnce(&mut fricsens::scene::Scene),
) -> (fricsens::model::Model, Results) {
    let mut scene = fricsens::scene::builtin("leaf-spring-coarse").unwrap();
    change(&mut scene);
    let model = scene.build().unwrap();
    let res = Solver::new(&model)
        .unwrap()
        .run(&RunOptions::default(), &mut NoObserver)
        .unwrap();
    (model, res)
}

/// Assert that two runs of `model` agree, response by response, at every time both converged
/// at, to 1e-6 of the response's largest value: Newton's tolerance is 1e-9 of the reference
/// force, and 1e-6 leaves room for the path-dependent friction and plastic history of two
/// differently iterated but equally converged runs. Returns the number of values compared.
fn assert_same_responses(model: &fricsens::model::Model, a: &Results, b: &Results) -> usize {
    let mut compared = 0;
    for r in 0..model.responses.len() {
        let values = |res: &Results| -> Vec<(f64, f64)> {
            (1..res.times.len())
                .map(|k| (res.times[k], res.response_value(model, r, k)))
                .collect()
        };
        let (a, b) = (values(a), values(b));
        let scale = a.iter().fold(0.0f64, |m, (_, v)| m.max(v.abs()));
        for (t, x) in &a {
            if let Some((_, y)) = b.iter().find(|(s, _)| (s - t).abs() <= 1e-12) {
                assert!((x - y).abs() <= 1e-6 * scale, "t = {t}: {x} vs {y}");
                compared += 1;
            }
        }
    }
    compared
}

#[test]
fn the_active_set_weight_changes_the_newton_path_not_the_solution() {
    // any weight c > 0 of the gap in `lambda - c k g >= 0` has the same solutions; on the coarse
    // leaf spring c = 1 and c = 1e-3 converge through the same increments, so every response
    // must agree at every increment. The sliding block served until the extrapolating
    // predictor made both weights take identical iterates there.
    let with = |c: Option<f64>| {
        coarse_leaf_spring(|scene| {
            for p in &mut scene.contacts {
                p.activation = c;
            }
        })
    };
    let (model, a) = with(None);
    let (_, b) = with(Some(1e-3));
    assert_eq!(a.times, b.times, "same increments");
    // not vacuous: the weight changes the iterates (the residual histories), whether or not
    // it changes the number of iterations
    let residuals = |res: &Results| -> Vec<Vec<f64>> {
        res.records.iter().map(|r| r.residuals.clone()).collect()
    };
    assert_ne!(
        residuals(&a),
        residuals(&b),
        "the weight changes Newton's path"
    );
    let compared = assert_same_responses(&model, &a, &b);
    assert_eq!(compared, model.responses.len() * (a.times.len() - 1));
}

#[test]
fn the_extrapolating_predictor_and_the_penetration_limiter_change_the_path_not_the_solution() {
    // The predictor only chooses where Newton starts, and the limiter only shortens steps on
    // the way: on the coarse leaf spring (whose leaf-leaf first contact the limiter acts on)
    // the runs with and without extrapolation must agree at every time both converged at, and
    // the extrapolated run must take fewer Newton iterations.
    let (model, on) = coarse_leaf_spring(|scene| scene.solver.extrapolate = true);
    let (_, off) = coarse_leaf_spring(|scene| scene.solver.extrapolate = false);
    let iterations = |res: &Results| -> usize { res.records.iter().map(|r| r.iterations).sum() };
    let (it_on, it_off) = (iterations(&on), iterations(&off));
    assert!(it_on < it_off, "{it_on} vs {it_off} iterations");
    let compared = assert_same_responses(&model, &on, &off);
    assert!(
        compared >= 10 * model.responses.len(),
        "only {compared} values compared"
    );
}
