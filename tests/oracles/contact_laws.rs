//! The three normal laws on the contact patch test: Lagrange multipliers (exact, indefinite
//! system), penalty (cheap, interpenetrates by p_n / eps_N), augmented Lagrangian (penalty
//! stiffness, multiplier estimates updated until no loaded node is off the target, either way,
//! by more than a tolerance).

use crate::common::solve_scene;

use fricsens::contact::NormalLaw;
use fricsens::scene::contact_patch;
use fricsens::solver::Results;

fn run(normal: NormalLaw) -> (fricsens::model::Model, Results) {
    let mut scene = contact_patch(None);
    scene.contacts[0].normal = normal;
    solve_scene(scene)
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
    solve_scene(scene)
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

/// The built-in leaf spring cut to its first loading increment (the block 2 mm down) taken in
/// `n` increments, its solver settings changed by `change`.
fn leaf_spring_first_increment(
    n: usize,
    change: impl FnOnce(&mut fricsens::model::SolverSettings),
) -> (fricsens::model::Model, Results) {
    let mut scene = fricsens::scene::builtin("leaf-spring").unwrap();
    let end = scene.steps[0].end / scene.steps[0].increments as f64;
    scene.steps = vec![fricsens::scene::StepSpec { end, increments: n }];
    change(&mut scene.solver);
    solve_scene(scene)
}

#[test]
fn the_active_set_predictor_settles_the_leaf_springs_first_contacts_where_beam_theory_puts_them() {
    // Beam theory for the first 2 mm of the block's stroke (rotations below 2 degrees): the
    // upper leaf, pushed down at x = 90 mm, rests on the lower one. Wherever the leaves touch,
    // both carry point loads only, so the difference of their bending moments is linear in x
    // and positive at the lower leaf's tip (it is P (90 - 71.5) there); the difference of the
    // deflections, zero with zero slope at the clamp, is then below its tip value along the
    // whole lower leaf. The leaves touch at the lower leaf's tip only. The block's
    // cylindrical nose (r = 5 mm) touches the upper leaf's top at the node row under its axis
    // (x = 90 mm): the rows 2.5 mm either side lie 0.67 mm below the nose's surface.
    let (model, res) = leaf_spring_first_increment(1, |_| {});
    let rec = &res.records[0];
    assert_eq!(
        rec.cutbacks, 0,
        "the 2 mm increment converged without cutback"
    );
    assert!(rec.active_set_solves > 0, "the predictor acted");
    let coords = model.lifted::<f64>(&[]).coords;
    let last = res.contact.len() - 1;
    for (p, pair) in model.contacts.iter().enumerate() {
        let closed: Vec<f64> = pair
            .hitting
            .iter()
            .enumerate()
            .filter(|(i, _)| {
                res.contact[last].choice[res.contact_flat[p] + i].state
                    != fricsens::contact::ContactState::Open
            })
            .map(|(_, &n)| coords[n].x)
            .collect();
        let at = match pair.name.as_str() {
            "leaves" => 71.5,
            "block" => 90.0,
            other => panic!("unexpected pair {other}"),
        };
        // one node row: both nodes across the one-element width, at x = `at`
        assert_eq!(
            closed.len(),
            2,
            "pair {}: closed at x = {closed:?}",
            pair.name
        );
        for xc in closed {
            assert!(
                (xc - at).abs() < 1e-9,
                "pair {}: closed at x = {xc}",
                pair.name
            );
        }
    }
}

#[test]
fn the_active_set_predictor_changes_the_path_not_the_solution() {
    // Friction and plasticity make the solution depend on the increments taken, so the runs
    // compared must converge through the same ones: the leaf spring's first 2 mm in four
    // increments (each run without cutback), and the coarse leaf spring's whole load history
    // (loading, unloading, reloading). With and without the predictor they must agree at
    // every increment.
    for (model, on, off) in [
        {
            let (model, on) = leaf_spring_first_increment(4, |_| {});
            let (_, off) = leaf_spring_first_increment(4, |s| s.active_set_solves = 0);
            (model, on, off)
        },
        {
            let (model, on) = coarse_leaf_spring(|_| {});
            let (_, off) = coarse_leaf_spring(|scene| scene.solver.active_set_solves = 0);
            (model, on, off)
        },
    ] {
        let solves: usize = on.records.iter().map(|r| r.active_set_solves).sum();
        assert!(solves > 0, "the predictor acted");
        assert_eq!(on.times, off.times, "same increments");
        let compared = assert_same_responses(&model, &on, &off);
        assert_eq!(compared, model.responses.len() * (on.times.len() - 1));
    }
}

/// The augmented Lagrangian on unloading: the patch test's pressure taken from 10 down to 5 in
/// one increment. The multiplier estimates carried from the loaded increment (10) alone would
/// hold the upper block off the lower one at a gap of `(10 - 5) / eps_N = 5e-5`, with the
/// pressure of 5 still transmitted across it; the passes go on until no loaded node is off the
/// target by more than the tolerance either way, and the pressure is the applied one.
#[test]
fn the_augmented_lagrangian_closes_the_gap_its_estimates_open_on_unloading() {
    let eps = 1e5;
    let tol = 1e-9;
    let mut scene = contact_patch(None);
    scene.contacts[0].normal = NormalLaw::Augmented {
        stiffness: eps,
        tolerance: tol,
    };
    scene.loads[0].amplitude = vec![(0.0, 0.0), (1.0, 1.0), (2.0, 0.5)];
    scene.steps.push(fricsens::scene::StepSpec {
        end: 2.0,
        increments: 1,
    });
    let (model, res) = solve_scene(scene);
    let last = res.states.len() - 1;
    let record = res.records.last().unwrap();
    assert_eq!(record.time, 2.0);
    let c = &res.contact[last];
    let mut loaded = 0;
    for (f, g) in c.normal_force.iter().zip(&c.gap) {
        if *f > 0.0 {
            loaded += 1;
            assert!(g.abs() <= tol, "a loaded node off the target by {g:e}");
        }
    }
    assert!(loaded > 0);
    for r in 0..model.responses.len() {
        let p = res.response_value(&model, r, last);
        assert!((p - 5.0).abs() < 1e-8 * 5.0, "pressure {p}");
    }
    assert!(
        record.augmentations >= 1,
        "the unloading increment was accepted without a pass"
    );
}
