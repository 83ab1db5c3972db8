//! Cost of one load increment, primal alone and with each in-line sensitivity method, measured
//! as a whole short run divided by its number of converged increments:
//!
//! * `cantilever-small`: the large-deflection cantilever coarsened to 20 x 2 x 1 hex8 with
//!   incompatible modes (738 unknowns), alpha = 1 in 4 increments;
//! * `uniaxial-j2`: the built-in one-element J2 stress cycle (30 increments, plastic).
//!
//! Methods: `primal` (Newton only), `sdm` and `sdm-central` (1 parameter), `ddm` (1 parameter),
//! `ddm-4` and `sdm-4` (4 parameters; DDM: one `Dual64` pass per parameter, then one
//! 4-column solve). Parameters: cantilever E (then E, nu, tip load, beam length); J2 sigma_y
//! (then E, nu, sigma_y, H).
//!
//! `cargo bench --bench increment`

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use fricsens::model::Model;
use fricsens::scene::{builtin, cantilever, CantileverSpec};
use fricsens::sensitivity::{run_sensitivity, Method, Parameter, Settings};
use fricsens::solver::{NoObserver, RunOptions, Solver};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// One run: the primal alone (`None`) or with a sensitivity method.
fn run(model: &Model, method: Option<Method>, params: &[Parameter]) -> usize {
    match method {
        None => {
            let mut s = Solver::new(model).expect("solver");
            let r = s.run(&RunOptions::default(), &mut NoObserver).expect("run");
            r.records.len()
        }
        Some(method) => {
            let settings = Settings {
                method,
                ..Settings::default()
            };
            let (r, s) = run_sensitivity(model, params, &settings).expect("run");
            black_box(&s);
            r.records.len()
        }
    }
}

fn scene(c: &mut Criterion, name: &str, model: &Model, one: &str, four: [&str; 4]) {
    let p1 = vec![Parameter::by_name(model, one).expect("parameter")];
    let p4: Vec<Parameter> = four
        .iter()
        .map(|p| Parameter::by_name(model, p).expect("parameter"))
        .collect();
    let increments = run(model, None, &[]);
    println!(
        "{name}: {} unknowns, {increments} increments per run",
        model.dof_map().n_total
    );
    let cases: [(&str, Option<Method>, &[Parameter]); 6] = [
        ("primal", None, &[]),
        ("sdm", Some(Method::Sdm), &p1),
        ("sdm-central", Some(Method::SdmCentral), &p1),
        ("ddm", Some(Method::Ddm), &p1),
        ("sdm-4", Some(Method::Sdm), &p4),
        ("ddm-4", Some(Method::Ddm), &p4),
    ];
    let mut g = c.benchmark_group(format!("increment/{name}"));
    g.sampling_mode(SamplingMode::Flat);
    for (label, method, params) in cases {
        g.bench_function(label, |b| {
            b.iter_custom(|iters| {
                let start = Instant::now();
                let mut incs = 0;
                for _ in 0..iters {
                    incs += run(model, method, params);
                }
                // criterion divides by `iters`: report the time per increment
                start.elapsed().mul_f64(iters as f64 / incs as f64)
            })
        });
    }
    g.finish();
}

fn increments(c: &mut Criterion) {
    let cantilever = cantilever_small();
    scene(
        c,
        "cantilever-small",
        &cantilever,
        "E",
        ["E", "nu", "load.tip", "beam.length.x"],
    );
    let uniaxial = builtin("uniaxial-j2")
        .expect("built-in scene")
        .build()
        .expect("model");
    scene(
        c,
        "uniaxial-j2",
        &uniaxial,
        "sigma_y",
        ["E", "nu", "sigma_y", "H"],
    );
}

/// 20 x 2 x 1 elements, alpha = 1 in 4 increments.
fn cantilever_small() -> Model {
    let spec = CantileverSpec {
        nx: 20,
        alpha: 1.0,
        increments: 4,
        ..CantileverSpec::large_deflection()
    };
    cantilever(&spec).build().expect("cantilever")
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(2));
    targets = increments
}
criterion_main!(benches);
