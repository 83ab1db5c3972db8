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
