//! Every shipped material through the one `MaterialLaw` interface, on a small frictional scene
//! under large deformation: a strip held by friction on a rigid ground, pulled into the plastic
//! range and released (the release unloads the plastic zone and turns the friction round). For each law: the
//! consistent tangent against the dual-number derivative of the residual, and DDM against
//! central finite differences of complete reruns for each of its parameters along the whole
//! path (which exercises the history sensitivities of J2 and of the stick anchors).

use crate::common;

use fricsens::element::Kinematics;
use fricsens::material::{J2Plasticity, Material, NeoHookean, StVenantKirchhoff};
use fricsens::model::Model;
use fricsens::scene::{strip_pullout, StripSpec};

fn materials() -> Vec<(&'static str, Material, Vec<&'static str>)> {
    // the pull force over the strip's section peaks at 1.5 / (0.02 x 0.1) = 750: a yield stress
    // of 500 makes the pulled half yield, and the friction holds the rest elastic
    let j2 = |saturation: Option<(f64, f64)>| {
        Material::J2(match saturation {
            Some((sigma_inf, delta)) => {
                J2Plasticity::saturation(1e5, 0.3, 500.0, 1e4, sigma_inf, delta)
            }
            None => J2Plasticity::linear(1e5, 0.3, 500.0, 1e4),
        })
    };
    vec![
        (
            "svk",
            Material::Svk(StVenantKirchhoff::new(1e5, 0.3)),
            vec!["E", "nu"],
        ),
        ("j2 linear", j2(None), vec!["E", "sigma_y", "H"]),
        (
            "j2 saturation",
            j2(Some((700.0, 50.0))),
            vec!["sigma_y", "H", "sigma_inf", "delta"],
        ),
        (
            "neo-hookean",
            Material::NeoHookean(NeoHookean::new(1e5, 0.3)),
            vec!["E", "nu"],
        ),
    ]
}

/// The frictional strip pull-out (`shared/oracles.md` section 7, 20 elements) under large
/// deformation: pulled to 1.5 and released, so the plastic zone unloads and the friction turns
/// round.
fn model(material: &Material) -> Model {
    let spec = StripSpec {
        elements: 20,
        ..StripSpec::default()
    };
    let mut scene = strip_pullout(&spec);
    for b in &mut scene.bodies {
        b.material = material.clone();
        b.kinematics = Kinematics::Large;
    }
    scene.build().unwrap()
}

#[test]
fn each_material_has_a_tangent_equal_to_the_dual_derivative_of_its_residual() {
    for (name, material, _) in materials() {
        let mut m = model(&material);
        m.times.retain(|t| *t <= 0.9 + 1e-12); // loading, partly plastic
        let c = common::tangent_check(&m, 1e-4);
        if name.starts_with("j2") {
            assert!(c.plastic > 0, "{name}: the J2 check needs plastic points");
        }
        assert!(c.mismatch <= 1e-8, "{name}: {}", c.mismatch);
        println!(
            "{name}: tangent matches to {:.1e}, {} plastic points",
            c.mismatch, c.plastic
        );
    }
}

#[test]
fn each_material_ddm_equals_central_fdm_along_loading_and_release() {
    for (name, material, params) in materials() {
        let m = model(&material);
        let (ps, ddm, fdm) = common::ddm_and_central_fdm(&m, &params);
        println!(
            "{name}: {} increments, primal {:.1} s, FDM {:.1} s",
            ddm.increments.len(),
            ddm.primal_seconds,
            fdm.cost.wall_seconds
        );
        assert_eq!(ddm.increments.len(), fdm.increments.len());
        for (r, response) in ddm.responses.iter().enumerate() {
            for (p, param) in ps.iter().enumerate() {
                // relative to the largest sensitivity over the path, or, where the response
                // hardly depends on the parameter, to max|R| / |b| (a unit logarithmic
                // sensitivity): differences of a response that is flat in b are round-off of
                // the reruns, at ~1e-11 of |R| / |b| here
                let largest = ddm
                    .increments
                    .iter()
                    .fold(0.0f64, |m, i| m.max(i.derivatives[r][p].abs()));
                let magnitude = ddm
                    .increments
                    .iter()
                    .fold(0.0f64, |m, i| m.max(i.values[r].abs()));
                let floor = largest.max(magnitude / param.value.abs());
                let mut worst: f64 = 0.0;
                for (a, b) in ddm.increments.iter().zip(&fdm.increments) {
                    // an increment whose rerun needed sub-steps the nominal run did not take
                    // followed another discrete path: no derivative to compare
                    if b.rerun_substeps.get(p).copied().unwrap_or(false) {
                        continue;
                    }
                    worst = worst.max((a.derivatives[r][p] - b.derivatives[r][p]).abs() / floor);
                }
                println!(
                    "{name} d{response}/d{}: DDM vs central FDM {worst:.2e} (largest |dR/db| {largest:.2e})",
                    param.name
                );
                assert!(worst < 1e-6, "{name} d{response}/d{}: {worst}", param.name);
            }
        }
    }
}

/// Observer of the skip check: at every converged increment, evaluates the history update
/// with and without skipping the elements frozen elastic and compares.
struct SkipCheck {
    skipped: usize,
    evaluated: usize,
}

impl fricsens::solver::Observer for SkipCheck {
    fn converged(
        &mut self,
        c: &fricsens::solver::Converged<'_>,
    ) -> Result<(), fricsens::solver::AnalysisError> {
        use fricsens::assembly::{Evaluation, Frozen};
        use num_dual::Dual64;
        let ne = c.model.mesh.n_elements();
        let frozen = Frozen {
            gauss: Some(&c.eval.branches),
            contact: &c.eval.contact.choice,
            skip: None,
            ..Frozen::default()
        };
        let skip =
            fricsens::sensitivity::history_unchanged(c.model, &c.assembler.dofs, &c.eval.branches);
        let update = Frozen {
            skip: Some(&skip),
            ..frozen
        };
        self.skipped += skip.iter().filter(|s| **s).count();
        self.evaluated += skip.iter().filter(|s| !**s).count();
        // derivative parts on every unknown and history scalar, as in DDM's update
        let lifted = c.model.lifted::<Dual64>(&[]);
        let z: Vec<Dual64> =
            c.z.iter()
                .enumerate()
                .map(|(i, v)| Dual64::new(*v, 1e-3 * ((i % 7) as f64 - 3.0)))
                .collect();
        let hist: Vec<Dual64> = c
            .hist_prev
            .iter()
            .enumerate()
            .map(|(i, v)| Dual64::new(*v, 1.0 + (i % 5) as f64))
            .collect();
        let mut full = Evaluation::<Dual64>::new(c.assembler, ne);
        let mut part = Evaluation::<Dual64>::new(c.assembler, ne);
        for (fr, ev) in [(&frozen, &mut full), (&update, &mut part)] {
            c.assembler
                .evaluate(c.model, &lifted, &z, &hist, c.time, Some(fr), None, ev)
                .map_err(fricsens::solver::AnalysisError::from)?;
        }
        for (i, (a, b)) in full.hist_new.iter().zip(&part.hist_new).enumerate() {
            assert_eq!(
                (a.re, a.eps),
                (b.re, b.eps),
                "increment {}: history scalar {i}",
                c.index
            );
        }
        for r in &c.model.responses {
            let (a, b) = (
                r.value(&full.response_input(&z, c.assembler)),
                r.value(&part.response_input(&z, c.assembler)),
            );
            assert_eq!((a.re, a.eps), (b.re, b.eps), "response {}", r.name);
        }
        Ok(())
    }
}

#[test]
fn skipping_elements_frozen_elastic_leaves_the_history_update_and_the_responses_unchanged() {
    // the coarse leaf spring: J2 leaves whose clamp region yields, contact responses; the
    // history update with the elastic elements skipped must equal the full one bit for bit,
    // value and derivative parts (Branch::Elastic: history unchanged)
    let model = fricsens::scene::builtin("leaf-spring-coarse")
        .unwrap()
        .build()
        .unwrap();
    let mut solver = fricsens::solver::Solver::new(&model).unwrap();
    let mut check = SkipCheck {
        skipped: 0,
        evaluated: 0,
    };
    solver
        .run(&fricsens::solver::RunOptions::default(), &mut check)
        .unwrap();
    // both kinds occur: the check compares something
    assert!(
        check.skipped > 0 && check.evaluated > 0,
        "{}/{}",
        check.skipped,
        check.evaluated
    );
}

/// The coarse leaf spring (yielding clamp, friction, load reversal) and the named parameters.
fn coarse_leaf_spring(
    names: &[&str],
) -> (
    fricsens::model::Model,
    Vec<fricsens::sensitivity::Parameter>,
) {
    let model = fricsens::scene::builtin("leaf-spring-coarse")
        .unwrap()
        .build()
        .unwrap();
    let params = common::params(&model, names);
    (model, params)
}

/// Assert that the derivatives of `a` agree with `reference`'s, response by response and
/// parameter by parameter, to `tol` of the largest value the reference takes over the run;
/// `pairs(a_inc, reference_inc, r, p)` gives the values compared at one increment (none skips
/// it). Returns the number of comparisons and the largest difference over the scale.
fn assert_derivatives_agree(
    model: &fricsens::model::Model,
    names: &[&str],
    a: &fricsens::sensitivity::SensitivityResults,
    reference: &fricsens::sensitivity::SensitivityResults,
    tol: f64,
    label: &str,
    pairs: impl Fn(
        &fricsens::sensitivity::IncrementSensitivity,
        &fricsens::sensitivity::IncrementSensitivity,
        usize,
        usize,
    ) -> Vec<(f64, f64)>,
) -> (usize, f64) {
    assert_eq!(a.increments.len(), reference.increments.len(), "{label}");
    let mut compared = 0;
    let mut worst = 0.0f64;
    for r in 0..model.responses.len() {
        for (p, name) in names.iter().enumerate() {
            let scale = reference
                .increments
                .iter()
                .fold(0.0f64, |m, i| m.max(i.derivatives[r][p].abs()));
            if scale == 0.0 {
                continue;
            }
            for (x_inc, y_inc) in a.increments.iter().zip(&reference.increments) {
                for (x, y) in pairs(x_inc, y_inc, r, p) {
                    worst = worst.max((x - y).abs() / scale);
                    assert!(
                        (x - y).abs() <= tol * scale,
                        "{label}: {} / {name} at t = {}: {x} vs {y}",
                        model.responses[r].name,
                        x_inc.time
                    );
                    compared += 1;
                }
            }
        }
    }
    (compared, worst)
}

#[test]
fn pseudo_loads_over_only_the_elements_a_parameter_reaches_match_ddm_over_all() {
    // SDM and DDM leave out of their pseudo-loads the elements a parameter does not reach: for
    // mu the elements without a history derivative, for sigma_y and H those frozen elastic too
    // (J2: both act on the plastic branch only). On the coarse leaf spring (yielding clamp,
    // friction, load reversal) the reference is DDM over all elements (`restrict: false`).
    // * Restricted DDM: the left-out elements' derivative parts are zero, so only the order
    //   of the sums may change: 1e-12 of the largest derivative of each response and parameter.
    // * Restricted central SDM, wherever no branch is flagged: 1e-5 of that scale; measured
    //   1.5e-7 (truncation beta^2 and round-off eps / beta, amplified by the tangent). Leaving
    //   out the elements with a history derivative as well errs by 1.8e-4 (checked by mutation).
    use fricsens::sensitivity::{run_sensitivity, Method, Settings, TangentChoice};
    let names = ["mu", "sigma_y", "H"];
    let (model, params) = coarse_leaf_spring(&names);
    let sdm = common::sensitivities(&model, &params, Method::SdmCentral, 1e-5);
    let ddm = common::sensitivities(&model, &params, Method::Ddm, 0.0);
    let full = Settings {
        method: Method::Ddm,
        tangent: TangentChoice::Exact,
        restrict: false,
        ..Settings::default()
    };
    let reference = run_sensitivity(&model, &params, &full).unwrap().1;
    for (name, s) in [("SDM", &sdm), ("DDM", &ddm)] {
        assert!(
            s.cost.partial_evaluations > 0,
            "{name}: no partial evaluation: the restriction was not exercised"
        );
    }
    assert_eq!(reference.cost.partial_evaluations, 0);
    for (method, s, tol) in [("DDM", &ddm, 1e-12), ("SDM central", &sdm, 1e-5)] {
        let label = format!("{method} vs DDM over all elements");
        let (compared, worst) =
            assert_derivatives_agree(&model, &names, s, &reference, tol, &label, |a, b, r, p| {
                if !a.kinks.is_empty() || !b.kinks.is_empty() {
                    return Vec::new();
                }
                vec![(a.derivatives[r][p], b.derivatives[r][p])]
            });
        println!("{method}: {compared} comparisons, largest error {worst:.2e} of the scale");
        assert!(compared >= 20, "only {compared} comparisons");
    }
    // DDM's one-sided derivatives at flagged increments: restricted, the forced tangent and
    // pseudo-loads are the converged ones changed over the elements whose points are forced
    // to another branch; the reference assembles them over all elements. Both sides solve
    // with GMRES to a relative residual of 1e-11 (different preconditioners: Newton's last
    // factor, the converged tangent's), so they agree to that times the conditioning:
    // measured 1.2e-10 of the scale
    let (compared, worst) = assert_derivatives_agree(
        &model,
        &names,
        &ddm,
        &reference,
        1e-9,
        "DDM one-sided vs over all elements",
        |a, b, r, p| match (&a.one_sided, &b.one_sided) {
            (Some(x), Some(y)) => {
                let ((xl, xu), (yl, yu)) = (x.both().expect("sides"), y.both().expect("sides"));
                vec![(xl[r][p], yl[r][p]), (xu[r][p], yu[r][p])]
            }
            (None, None) => Vec::new(),
            _ => panic!("flagged in one run only at t = {}", a.time),
        },
    );
    println!("DDM one-sided: {compared} comparisons, largest error {worst:.2e} of the scale");
    assert!(compared > 0, "no flagged increment");
}

#[test]
fn gmres_with_newtons_factor_solves_the_converged_and_forced_tangents_as_their_factorizations_do() {
    // With `Settings::krylov` the engine solves with the converged tangent (and DDM's forced
    // tangents at flagged points) by GMRES preconditioned with Newton's last factor, instead of
    // factoring them. The reference is the same run with every such tangent factored. On the
    // coarse leaf spring (yielding clamp, friction, load reversal, flagged increments) DDM
    // with the converged tangent must agree, derivatives and one-sided derivatives, at every
    // increment: both solve to a relative residual of 1e-11 or better (GMRES by its
    // tolerance, the LU to its round-off), and the difference of two such solves is carried
    // through the history derivatives of later increments; 1e-8 of each derivative's largest
    // value over the run is that residual amplified a thousandfold (measured: 1.0e-10).
    use fricsens::sensitivity::{run_sensitivity, Method, Settings, TangentChoice};
    let names = ["mu", "E", "sigma_y"];
    let (model, params) = coarse_leaf_spring(&names);
    let settings = |krylov| Settings {
        method: Method::Ddm,
        tangent: TangentChoice::Exact,
        krylov,
        ..Settings::default()
    };
    let gmres = run_sensitivity(&model, &params, &settings(true)).unwrap().1;
    let factored = run_sensitivity(&model, &params, &settings(false))
        .unwrap()
        .1;
    assert!(gmres.cost.krylov_solves > 0 && factored.cost.krylov_solves == 0);
    assert!(
        gmres.cost.factorizations < factored.cost.factorizations,
        "{} vs {}",
        gmres.cost.factorizations,
        factored.cost.factorizations
    );
    assert_eq!(gmres.increments.len(), factored.increments.len());
    let mut flagged = 0;
    for (a, b) in gmres.increments.iter().zip(&factored.increments) {
        assert_eq!(
            a.one_sided.is_some(),
            b.one_sided.is_some(),
            "t = {}",
            a.time
        );
        flagged += usize::from(a.one_sided.is_some());
    }
    let (compared, worst) = assert_derivatives_agree(
        &model,
        &names,
        &gmres,
        &factored,
        1e-8,
        "GMRES vs factored",
        |a, b, r, p| {
            let mut pairs = vec![(a.derivatives[r][p], b.derivatives[r][p])];
            if let (Some(sa), Some(sb)) = (&a.one_sided, &b.one_sided) {
                let ((al, au), (bl, bu)) = (sa.both().expect("sides"), sb.both().expect("sides"));
                pairs.push((al[r][p], bl[r][p]));
                pairs.push((au[r][p], bu[r][p]));
            }
            pairs
        },
    );
    println!(
        "{compared} comparisons ({flagged} flagged increments), largest difference {worst:.2e} of the scale; factorizations {} vs {}, {} GMRES solves in {} steps",
        gmres.cost.factorizations,
        factored.cost.factorizations,
        gmres.cost.krylov_solves,
        gmres.cost.krylov_iterations
    );
    assert!(compared >= 100 && flagged > 0, "{compared} / {flagged}");
}
