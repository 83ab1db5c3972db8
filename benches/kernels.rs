//! One hex8 evaluation (large kinematics, 2x2x2 Gauss points), per scalar type, formulation
//! (full, incompatible modes, F-bar) and material:
//!
//! * `f64`, `dual64` (E seeded), `dsvec4`, `dsvec8` (all material parameters seeded): residual
//!   only — the primal, DDM single and DDM batched pseudo-load evaluations;
//! * `f64+tangent`: residual and the hand-coded consistent tangent (one Newton iteration);
//! * `rev/record+sweep`: one vector-Jacobian product in reverse mode (the unknowns and the
//!   history read as inputs, one recording and one sweep), the adjoint's local derivative;
//!   `rev/record` and `rev/sweep` its two halves (the adjoint sweeps each recording once per
//!   column and phase);
//! * `ad-tangent/dual64`: the tangent by forward AD, one `Dual64` pass per element unknown
//!   (24 or 33 passes); `ad-tangent/dsvec8`: 3 or 5 passes of `DualSVec64<8>`;
//!   `ad-tangent/dsvec24` (full, F-bar) and `ad-tangent/dsvec33` (incompatible modes): one pass.
//!
//! Materials: St Venant-Kirchhoff, and J2 (linear hardening) stretched to four times its yield
//! strain from a virgin history, so every Gauss point returns plastically.
//!
//! `cargo bench --bench kernels`

mod common;

use common::{ad_tangent, j2, relative_difference, svk, Element};
use criterion::{criterion_group, criterion_main, Criterion};
use fricsens::element::Formulation;
use fricsens::material::{Branch, MaterialLaw};
use fricsens::scalar::{tape, Rev, Scalar};
use num_dual::{Dual64, DualSVec64};
use std::hint::black_box;
use std::time::Duration;

fn residual<S: Scalar, M: MaterialLaw>(
    c: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    base: &Element<f64>,
    material: &M,
    seed_params: usize,
) {
    let mut el: Element<S> = base.lift(seed_params);
    c.bench_function(name, |b| {
        b.iter(|| {
            el.evaluate(black_box(material), false).expect("element");
            black_box(&el.force);
        })
    });
}

fn ad<S: Scalar, M: MaterialLaw>(
    c: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    base: &Element<f64>,
    material: &M,
    reference: &[f64],
) {
    let mut work: Element<S> = base.lift(0);
    let mut k = vec![0.0; reference.len()];
    ad_tangent(base, &mut work, material, &mut k).expect("element");
    let rel = relative_difference(reference, &k);
    assert!(
        rel < 1e-8,
        "{name}: AD tangent differs from the hand-coded one by {rel:.2e}"
    );
    c.bench_function(name, |b| {
        b.iter(|| {
            ad_tangent(base, &mut work, black_box(material), &mut k).expect("element");
            black_box(&k);
        })
    });
}

/// One vector-Jacobian product of the element in reverse mode, as the adjoint's sweep takes
/// it: the unknowns and the history read are the inputs, the tape recorded by one evaluation
/// and swept once with a weight on every force and history output. Checked against the
/// hand-coded tangent (with the history's weights zero, the unknowns' part is `w^T K`).
fn vjp<M: MaterialLaw>(
    c: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    base: &Element<f64>,
    material: &M,
    reference: &[f64],
) {
    let nd = base.ndof();
    let w: Vec<f64> = (0..nd).map(|i| 1.0 + 0.1 * i as f64).collect();
    let mut el: Element<Rev> = base.lift(0);
    let mut adjoint = Vec::new();
    let record = |el: &mut Element<Rev>| {
        tape::clear();
        for (d, x) in el.dofs.iter_mut().zip(&base.dofs) {
            *d = x.map(Rev::input);
        }
        for (h, x) in el.hist_old.iter_mut().zip(&base.hist_old) {
            *h = Rev::input(*x);
        }
        el.evaluate(material, false).expect("element");
    };
    let seeds = |el: &Element<Rev>, history: f64| -> Vec<(Rev, f64)> {
        (el.force.iter().zip(&w).map(|(f, w)| (*f, *w)))
            .chain(el.hist_new.iter().map(|h| (*h, history)))
            .collect()
    };
    let once = |el: &mut Element<Rev>, adjoint: &mut Vec<f64>, history: f64| {
        record(el);
        tape::sweep(seeds(el, history), adjoint);
    };
    // the history's weights zero for the check: w^T K from the sweep against the
    // hand-coded tangent
    once(&mut el, &mut adjoint, 0.0);
    let got: Vec<f64> = (el.dofs.iter())
        .flat_map(|d| (0..3).map(move |i| d[i]))
        .map(|d| d.adjoint(&adjoint))
        .collect();
    let want: Vec<f64> = (0..nd)
        .map(|k| (0..nd).map(|i| w[i] * reference[i * nd + k]).sum())
        .collect();
    let rel = relative_difference(&want, &got);
    assert!(
        rel < 1e-8,
        "rev: w^T K differs from the hand-coded one by {rel:.2e}"
    );
    // the halves: the recording left on the tape by the check above, swept again
    let weights = seeds(&el, 1.0);
    c.bench_function("rev/sweep", |b| {
        b.iter(|| {
            tape::sweep(weights.iter().copied(), &mut adjoint);
            black_box(&adjoint);
        })
    });
    c.bench_function("rev/record", |b| {
        b.iter(|| {
            record(&mut el);
            black_box(&el.force);
        })
    });
    c.bench_function("rev/record+sweep", |b| {
        b.iter(|| {
            once(&mut el, &mut adjoint, 1.0);
            black_box(&adjoint);
        })
    });
}

fn case<M: MaterialLaw>(c: &mut Criterion, mat_name: &str, material: &M, plastic: bool) {
    for (form_name, formulation) in [
        ("full", Formulation::Full),
        ("im", Formulation::IncompatibleModes),
        ("fbar", Formulation::FBar),
    ] {
        let np = material.params().len();
        let mut base = Element::new(
            formulation,
            material.params(),
            material.history_len(),
            plastic,
        );
        base.evaluate(material, true).expect("element");
        let want = if plastic {
            Branch::Plastic
        } else {
            Branch::Elastic
        };
        assert!(base.branches.iter().all(|b| *b == want), "branches");
        let reference = base.tangent.clone();

        let mut g = c.benchmark_group(format!("hex8/{mat_name}/{form_name}"));
        residual::<f64, M>(&mut g, "f64", &base, material, 0);
        residual::<Dual64, M>(&mut g, "dual64", &base, material, 1);
        residual::<DualSVec64<4>, M>(&mut g, "dsvec4", &base, material, np);
        residual::<DualSVec64<8>, M>(&mut g, "dsvec8", &base, material, np);
        {
            let mut el = base.lift::<f64>(0);
            g.bench_function("f64+tangent", |b| {
                b.iter(|| {
                    el.evaluate(black_box(material), true).expect("element");
                    black_box(&el.tangent);
                })
            });
        }
        vjp(&mut g, &base, material, &reference);
        ad::<Dual64, M>(&mut g, "ad-tangent/dual64", &base, material, &reference);
        ad::<DualSVec64<8>, M>(&mut g, "ad-tangent/dsvec8", &base, material, &reference);
        if formulation == Formulation::IncompatibleModes {
            ad::<DualSVec64<33>, M>(&mut g, "ad-tangent/dsvec33", &base, material, &reference)
        } else {
            ad::<DualSVec64<24>, M>(&mut g, "ad-tangent/dsvec24", &base, material, &reference)
        }
        g.finish();
    }
}

fn kernels(c: &mut Criterion) {
    case(c, "svk", &svk(), false);
    case(c, "j2", &j2(), true);
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    targets = kernels
}
criterion_main!(benches);
