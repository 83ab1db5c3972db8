//! Global assembly and the sparse LU on the ~10^4-unknown cantilever (85 x 4 x 2 hex8 with
//! incompatible modes, St Venant-Kirchhoff, large kinematics), at a bending state:
//!
//! * `Assembler::evaluate`: residual only (f64), residual + tangent (f64), residual in `Dual64`
//!   with E seeded (DDM's pseudo-load);
//! * `LinearSolver`: identity rows at the clamped unknowns (as the Newton solver does before
//!   factoring), numeric LU `factor` (on the symbolic analysis done once), `solve_in_place` with
//!   one column, `solve_multi_in_place` with 10 columns, and 10 separate one-column solves.
//!
//! `cargo bench --bench assembly`

mod common;

use common::{bending_state, cantilever_model, NX_10K};
use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use fricsens::assembly::{Assembler, Evaluation};
use fricsens::linalg::{LinearSolver, SparseMatrix};
use fricsens::model::DesignParam;
use fricsens::solver::Solver;
use num_dual::Dual64;
use std::hint::black_box;
use std::time::Duration;

fn assembly(c: &mut Criterion) {
    let model = cantilever_model(NX_10K, 1.0, 1);
    let asm = Assembler::new(&model, &[]).expect("pattern");
    let dofs = &asm.dofs;
    let ne = model.mesh.n_elements();
    let n = dofs.n_total;
    println!(
        "cantilever {NX_10K} x 4 x 2: {ne} elements, {n} unknowns ({} nodal + {} incompatible-mode), {} stored tangent entries, {} rayon threads",
        dofs.n_nodal,
        n - dofs.n_nodal,
        asm.pattern.nnz(),
        rayon::current_num_threads()
    );
    let lifted = model.lifted::<f64>(&[]);
    let z = bending_state(&model, n);
    let hist = vec![0.0; dofs.n_history];
    let mut ev = Evaluation::<f64>::new(&asm, ne);
    let mut k = SparseMatrix::new(asm.pattern.clone());

    let mut g = c.benchmark_group(format!("assembly/cantilever-{n}"));
    g.sampling_mode(SamplingMode::Flat);
    g.bench_function("residual/f64", |b| {
        b.iter(|| {
            asm.evaluate(&model, &lifted, &z, &hist, 1.0, None, None, &mut ev)
                .expect("assembly");
            black_box(&ev.residual);
        })
    });
    g.bench_function("residual+tangent/f64", |b| {
        b.iter(|| {
            asm.evaluate(&model, &lifted, &z, &hist, 1.0, None, Some(&mut k), &mut ev)
                .expect("assembly");
            black_box(k.values());
        })
    });
    {
        let e = DesignParam::Material { body: 0, index: 0 };
        let young = model.param_value(e).expect("E");
        let lifted_d = model.lifted::<Dual64>(&[(e, Dual64::new(young, 1.0))]);
        let z_d: Vec<Dual64> = z.iter().map(|v| Dual64::from_re(*v)).collect();
        let hist_d: Vec<Dual64> = vec![Dual64::from_re(0.0); dofs.n_history];
        let mut ev_d = Evaluation::<Dual64>::new(&asm, ne);
        g.bench_function("residual/dual64", |b| {
            b.iter(|| {
                asm.evaluate(&model, &lifted_d, &z_d, &hist_d, 1.0, None, None, &mut ev_d)
                    .expect("assembly");
                black_box(&ev_d.residual);
            })
        });
    }
    g.finish();

    // the tangent as the Newton solver factors it
    let constrained = Solver::new(&model).expect("solver").constrained().to_vec();
    asm.evaluate(&model, &lifted, &z, &hist, 1.0, None, Some(&mut k), &mut ev)
        .expect("assembly");
    let set_identity = |k: &mut SparseMatrix| {
        for (d, c) in constrained.iter().enumerate() {
            if *c {
                k.set_identity_row_col(d).expect("in range");
            }
        }
    };
    let mut g = c.benchmark_group(format!("linear/cantilever-{n}"));
    g.sampling_mode(SamplingMode::Flat);
    {
        let k0 = k.clone();
        let mut kk = k.clone();
        g.bench_function("identity-rows", |b| {
            b.iter(|| {
                kk.values_mut().copy_from_slice(k0.values());
                set_identity(&mut kk);
                black_box(kk.values());
            })
        });
    }
    set_identity(&mut k);
    let mut lu = LinearSolver::new(asm.pattern.clone()).expect("symbolic LU");
    g.bench_function("factor", |b| {
        b.iter(|| lu.factor(black_box(&k)).expect("factor"))
    });
    lu.factor(&k).expect("factor");
    let rhs: Vec<f64> = (0..10 * n)
        .map(|i| {
            if constrained[i % n] {
                0.0
            } else {
                ((i % 7) as f64 - 3.0) * 1e-3
            }
        })
        .collect();
    let mut x = rhs.clone();
    g.bench_function("solve/1-column", |b| {
        b.iter(|| {
            x[..n].copy_from_slice(&rhs[..n]);
            lu.solve_in_place(&mut x[..n]).expect("solve");
            black_box(&x);
        })
    });
    g.bench_function("solve/10-columns-multi", |b| {
        b.iter(|| {
            x.copy_from_slice(&rhs);
            lu.solve_multi_in_place(&mut x, 10).expect("solve");
            black_box(&x);
        })
    });
    g.bench_function("solve/10-columns-one-by-one", |b| {
        b.iter(|| {
            x.copy_from_slice(&rhs);
            for col in x.chunks_mut(n) {
                lu.solve_in_place(col).expect("solve");
            }
            black_box(&x);
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    targets = assembly
}
criterion_main!(benches);
