//! The cost figures of the closing note of issue 2, as plain tables. Every figure is the
//! fastest of several repetitions (the machine is shared: the fastest run is the least
//! disturbed one); read them to two digits.
//!
//! 1. Per element (hex8, large kinematics): f64 vs dual residual, hand-coded vs AD tangent.
//! 2. One Newton iteration on the ~10^4-unknown cantilever: assembly with tangent,
//!    factorization and solve, from a real increment (the solver's own timers) and from
//!    repeated calls at the converged state.
//! 3. Rayon-parallel assembly on 1 vs 2 threads (local thread pools, the same as
//!    `RAYON_NUM_THREADS=1` / `2` for this code), with the cores the process really had.
//! 4. Where an increment of the `benches/increment.rs` scenes goes: primal parts and the
//!    in-line sensitivity work per method.
//!
//! `cargo bench --bench figures` (about a minute); `cargo bench --bench figures -- 3` runs
//! section 3 only. Under `cargo test --benches` it only prints how to run it.

mod common;

use common::{
    ad_tangent, bending_state, cantilever_model, fastest_time, j2, relative_difference, svk,
    Element, NX_10K,
};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuSymbolicParams, NumericLu};
use faer::sparse::linalg::SupernodalThreshold;
use faer::Par;
use fricsens::assembly::{Assembler, Evaluation};
use fricsens::element::Formulation;
use fricsens::linalg::{LinearSolver, SolverOptions, SparseMatrix};
use fricsens::material::MaterialLaw;
use fricsens::model::DesignParam;
use fricsens::model::Model;
use fricsens::scalar::Scalar;
use fricsens::scene::{builtin, cantilever, CantileverSpec};
use fricsens::sensitivity::{run_sensitivity, Method, Parameter, Settings};
use fricsens::solver::{NoObserver, RunOptions, Solver};
use num_dual::{Dual64, DualSVec64};
use std::hint::black_box;
use std::time::{Duration, Instant};

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Time of one call of `f`: the fastest of 9 batches of about 20 ms.
fn per_call(mut f: impl FnMut()) -> Duration {
    let start = Instant::now();
    let mut calls = 0u32;
    while start.elapsed() < Duration::from_millis(20) {
        f();
        calls += 1;
    }
    fastest_time(9, || {
        for _ in 0..calls {
            f();
        }
    }) / calls
}

fn residual_time<S: Scalar, M: MaterialLaw>(base: &Element<f64>, m: &M, seed: usize) -> Duration {
    let mut el: Element<S> = base.lift(seed);
    per_call(|| {
        el.evaluate(m, false).expect("element");
        black_box(&el.force);
    })
}

fn ad_time<S: Scalar, M: MaterialLaw>(base: &Element<f64>, m: &M) -> (Duration, f64) {
    let mut work: Element<S> = base.lift(0);
    let mut k = vec![0.0; base.tangent.len()];
    let t = per_call(|| {
        ad_tangent(base, &mut work, m, &mut k).expect("element");
        black_box(&k);
    });
    (t, relative_difference(&base.tangent, &k))
}

fn element_table<M: MaterialLaw>(name: &str, m: &M, plastic: bool) {
    for (fname, form) in [
        ("full", Formulation::Full),
        ("im", Formulation::IncompatibleModes),
    ] {
        let np = m.params().len();
        let mut base = Element::new(form, m.params(), m.history_len(), plastic);
        base.evaluate(m, true).expect("element");
        let f64_r = residual_time::<f64, M>(&base, m, 0);
        let d1 = residual_time::<Dual64, M>(&base, m, 1);
        let d4 = residual_time::<DualSVec64<4>, M>(&base, m, np);
        let d8 = residual_time::<DualSVec64<8>, M>(&base, m, np);
        let hand = {
            let mut el = base.lift::<f64>(0);
            per_call(|| {
                el.evaluate(m, true).expect("element");
                black_box(&el.tangent);
            })
        };
        let (ad1, e1) = ad_time::<Dual64, M>(&base, m);
        let (ad8, e8) = ad_time::<DualSVec64<8>, M>(&base, m);
        let (adw, ew, wname) = if form == Formulation::IncompatibleModes {
            let (t, e) = ad_time::<DualSVec64<33>, M>(&base, m);
            (t, e, "dsvec33")
        } else {
            let (t, e) = ad_time::<DualSVec64<24>, M>(&base, m);
            (t, e, "dsvec24")
        };
        let r = |d: Duration| us(d) / us(f64_r);
        let h = |d: Duration| us(d) / us(hand);
        println!(
            "{:<4} {:<4} | {:>6.2} | {:>6.2} {:>4.1}x | {:>6.2} {:>4.1}x | {:>6.2} {:>4.1}x | {:>6.2} | {:>7.1} {:>4.1}x | {:>7.1} {:>4.1}x | {:>7.1} {:>4.1}x ({wname}) | {:.0e}",
            name,
            fname,
            us(f64_r),
            us(d1),
            r(d1),
            us(d4),
            r(d4),
            us(d8),
            r(d8),
            us(hand),
            us(ad1),
            h(ad1),
            us(ad8),
            h(ad8),
            us(adw),
            h(adw),
            e1.max(e8).max(ew),
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if !args.iter().any(|a| a == "--bench") {
        println!("figures: run with `cargo bench --bench figures [-- SECTION...]`");
        return;
    }
    // sections to run: `cargo bench --bench figures -- 3` runs section 3 only
    let chosen: Vec<&str> = args
        .iter()
        .map(|a| a.as_str())
        .filter(|a| !a.starts_with('-'))
        .collect();
    let run = |k: &str| chosen.is_empty() || chosen.contains(&k);
    println!(
        "rayon threads: {} (RAYON_NUM_THREADS={:?}); load average at start: {}",
        rayon::current_num_threads(),
        std::env::var("RAYON_NUM_THREADS").ok(),
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );

    if run("1") {
        element_section();
    }
    if run("2") {
        newton_section();
    }
    if run("3") {
        rayon_section();
    }
    if run("4") {
        increment_section();
    }
    println!(
        "\nload average at the end: {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
}

/// Section 1: one element.
fn element_section() {
    println!("## 1. One hex8 evaluation (large kinematics, 8 Gauss points), microseconds");
    println!("residual: f64, then dual types with the ratio to f64 (Dual64: E seeded; DualSVec64<N>: every material parameter seeded)");
    println!("tangent: f64 residual + hand-coded tangent, then forward AD of the residual over the element unknowns, with the ratio to the hand-coded one");
    println!("J2 is at a plastic state (every Gauss point returns); last column: largest |K_AD - K_hand| / max |K_hand|\n");
    println!("mat  form | f64    | Dual64       | DSVec<4>     | DSVec<8>     | f64+K  | AD Dual64 x ndof | AD DSVec<8>     | AD one pass               | AD err");
    element_table("svk", &svk(), false);
    element_table("j2", &j2(), true);
}

/// Section 2: one Newton iteration on the ~10^4-unknown cantilever.
fn newton_section() {
    let model = cantilever_model(NX_10K, 1.0, 1);
    let mut solver = Solver::new(&model).expect("solver");
    let n = solver.assembler.dofs.n_total;
    let n_nodal = solver.assembler.dofs.n_nodal;
    let ne = model.mesh.n_elements();
    let nnz = solver.assembler.pattern.nnz();
    println!(
        "\n## 2. Newton iteration, cantilever {NX_10K} x 4 x 2 hex8 (incompatible modes, SVK, large kinematics): {ne} elements, {n} unknowns ({n_nodal} nodal + {} modes), {nnz} stored entries",
        n - n_nodal
    );
    let t = Instant::now();
    let res = solver
        .run(&RunOptions::default(), &mut NoObserver)
        .expect("run");
    let wall = t.elapsed();
    let c = &res.cost;
    let iters: usize = res.records.iter().map(|r| r.iterations).sum();
    println!(
        "\n### a. one increment to alpha = 1 (the solver's timers): {} increment(s), {} Newton iterations, {} assemblies, {} factorizations, {} solves, wall {:.2} s",
        res.records.len(),
        iters,
        c.assemblies,
        c.factorizations,
        c.solves,
        wall.as_secs_f64()
    );
    let a = c.assembly_seconds / c.assemblies as f64;
    let f = c.factor_seconds / c.factorizations as f64;
    let s = c.solve_seconds / c.solves as f64;
    let it = a + f + s;
    println!("per iteration: assembly+tangent {:.1} ms ({:.0} %), factorization {:.1} ms ({:.0} %, includes faer's numeric LU and a check solve), solve {:.1} ms ({:.0} %), total {:.1} ms",
        a * 1e3, 100.0 * a / it, f * 1e3, 100.0 * f / it, s * 1e3, 100.0 * s / it, it * 1e3);
    let other = wall.as_secs_f64() - c.assembly_seconds - c.factor_seconds - c.solve_seconds;
    println!(
        "outside those timers (set-up, symbolic analysis, identity rows, residual norms, results): {:.0} ms in the run",
        other * 1e3
    );

    // components at the converged state
    let asm = &solver.assembler;
    let lifted = model.lifted::<f64>(&[]);
    let z = res
        .states
        .last()
        .cloned()
        .unwrap_or_else(|| bending_state(&model, n));
    let hist = vec![0.0; asm.dofs.n_history];
    let mut ev_r = Evaluation::<f64>::new(asm, ne);
    let mut ev_k = Evaluation::<f64>::new(asm, ne);
    let mut k = SparseMatrix::new(asm.pattern.clone());
    let e = DesignParam::Material { body: 0, index: 0 };
    let young = model.param_value(e).expect("E");
    let lifted_d = model.lifted::<Dual64>(&[(e, Dual64::new(young, 1.0))]);
    let z_d: Vec<Dual64> = z.iter().map(|v| Dual64::from_re(*v)).collect();
    let hist_d = vec![Dual64::from_re(0.0); asm.dofs.n_history];
    let mut ev_d = Evaluation::<Dual64>::new(asm, ne);

    let mut assemble_r = || {
        asm.evaluate(&model, &lifted, &z, &hist, 1.0, None, None, &mut ev_r)
            .expect("assembly")
    };
    let t_r = fastest_time(5, &mut assemble_r);
    let mut assemble_k = |k: &mut SparseMatrix| {
        asm.evaluate(&model, &lifted, &z, &hist, 1.0, None, Some(k), &mut ev_k)
            .expect("assembly")
    };
    let t_k = fastest_time(5, || assemble_k(&mut k));
    let mut assemble_d = || {
        asm.evaluate(&model, &lifted_d, &z_d, &hist_d, 1.0, None, None, &mut ev_d)
            .expect("assembly")
    };
    let t_d = fastest_time(5, &mut assemble_d);

    let constrained = solver.constrained().to_vec();
    let k_raw = k.clone();
    let mut kk = k.clone();
    let t_id = fastest_time(5, || {
        kk.values_mut().copy_from_slice(k_raw.values());
        for (d, c) in constrained.iter().enumerate() {
            if *c {
                kk.set_identity_row_col(d).expect("in range");
            }
        }
    });
    let mut lu = LinearSolver::new(asm.pattern.clone()).expect("symbolic");
    let t_sym = fastest_time(3, || {
        black_box(LinearSolver::new(asm.pattern.clone()).expect("symbolic"));
    });
    let t_f = fastest_time(5, || lu.factor(&kk).expect("factor"));
    let mut lu_nocheck = LinearSolver::with_options(
        asm.pattern.clone(),
        SolverOptions {
            check_finite: false,
            ..SolverOptions::default()
        },
    )
    .expect("symbolic");
    let t_f_nocheck = fastest_time(5, || lu_nocheck.factor(&kk).expect("factor"));
    let mut lu_par = LinearSolver::with_options(
        asm.pattern.clone(),
        SolverOptions {
            check_finite: false,
            factor_par: Some(Par::rayon(2)),
            solve_par: Par::rayon(2),
            ..SolverOptions::default()
        },
    )
    .expect("symbolic");
    let t_f_par = fastest_time(5, || lu_par.factor(&kk).expect("factor"));
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
    let t_s1 = fastest_time(9, || {
        x[..n].copy_from_slice(&rhs[..n]);
        lu.solve_in_place(&mut x[..n]).expect("solve");
    });
    let t_s10 = fastest_time(9, || {
        x.copy_from_slice(&rhs);
        lu.solve_multi_in_place(&mut x, 10).expect("solve");
    });
    let t_s10_single = fastest_time(5, || {
        x.copy_from_slice(&rhs);
        for col in x.chunks_mut(n) {
            lu.solve_in_place(col).expect("solve");
        }
    });
    let t_s10_par = fastest_time(5, || {
        x.copy_from_slice(&rhs);
        lu_par.solve_multi_in_place(&mut x, 10).expect("solve");
    });
    let t_it = t_k + t_id + t_f + t_s1;
    let pct = |d: Duration| 100.0 * d.as_secs_f64() / t_it.as_secs_f64();
    println!("\n### b. the parts, repeated at the converged state (fastest of 5-9), ms");
    println!("| part | ms | share of an iteration |");
    println!("|---|---:|---:|");
    println!(
        "| assembly, residual + tangent (f64) | {:.1} | {:.0} % |",
        ms(t_k),
        pct(t_k)
    );
    println!(
        "| identity rows at the clamped unknowns | {:.2} | {:.1} % |",
        ms(t_id),
        pct(t_id)
    );
    println!(
        "| numeric LU (`factor`, default options: with check solve) | {:.1} | {:.0} % |",
        ms(t_f),
        pct(t_f)
    );
    println!("| solve, 1 column | {:.2} | {:.1} % |", ms(t_s1), pct(t_s1));
    println!("| **one Newton iteration** | **{:.1}** | 100 % |", ms(t_it));
    println!("| (symbolic LU, once per run) | {:.1} | |", ms(t_sym));
    println!(
        "| numeric LU without the check solve | {:.1} | |",
        ms(t_f_nocheck)
    );
    println!(
        "| numeric LU, faer's simplicial kernel forced (default picks supernodal here) | {:.1} | |",
        ms(lu_time(&kk, SupernodalThreshold::FORCE_SIMPLICIAL))
    );
    println!(
        "| numeric LU, `factor_par: Some(Par::rayon(2))` | {:.1} | |",
        ms(t_f_par)
    );
    println!("| assembly, residual only (f64) | {:.1} | |", ms(t_r));
    println!(
        "| assembly, residual only (Dual64, E seeded) | {:.1} | |",
        ms(t_d)
    );
    println!("| solve, 10 columns in one call | {:.2} | |", ms(t_s10));
    println!(
        "| solve, 10 columns one by one | {:.2} | |",
        ms(t_s10_single)
    );
    println!(
        "| solve, 10 columns, `solve_par: Par::rayon(2)` | {:.2} | |",
        ms(t_s10_par)
    );
    println!(
        "per element inside the assembly (2 threads): residual f64 {:.2} us, Dual64 {:.2} us ({:.1}x), residual + tangent {:.1} us",
        us(t_r) / ne as f64,
        us(t_d) / ne as f64,
        t_d.as_secs_f64() / t_r.as_secs_f64(),
        us(t_k) / ne as f64
    );
}

/// CPU time of every thread of this process so far (from `/proc/self/task/*/schedstat`, ns).
fn cpu_seconds() -> f64 {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return f64::NAN;
    };
    dir.filter_map(|t| t.ok())
        .filter_map(|t| std::fs::read_to_string(t.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .sum::<f64>()
        * 1e-9
}

/// Section 3: the assembly on local rayon pools of 1 and 2 threads.
fn rayon_section() {
    let model = cantilever_model(NX_10K, 1.0, 1);
    let asm = Assembler::new(&model, &[]).expect("pattern");
    let n = asm.dofs.n_total;
    let ne = model.mesh.n_elements();
    let lifted = model.lifted::<f64>(&[]);
    let z = bending_state(&model, n);
    let hist = vec![0.0; asm.dofs.n_history];
    let mut ev_r = Evaluation::<f64>::new(&asm, ne);
    let mut ev_k = Evaluation::<f64>::new(&asm, ne);
    let mut k = SparseMatrix::new(asm.pattern.clone());
    let e = DesignParam::Material { body: 0, index: 0 };
    let young = model.param_value(e).expect("E");
    let lifted_d = model.lifted::<Dual64>(&[(e, Dual64::new(young, 1.0))]);
    let z_d: Vec<Dual64> = z.iter().map(|v| Dual64::from_re(*v)).collect();
    let hist_d = vec![Dual64::from_re(0.0); asm.dofs.n_history];
    let mut ev_d = Evaluation::<Dual64>::new(&asm, ne);
    let mut assemble_r = || {
        asm.evaluate(&model, &lifted, &z, &hist, 1.0, None, None, &mut ev_r)
            .expect("assembly")
    };
    let mut assemble_k = || {
        asm.evaluate(
            &model,
            &lifted,
            &z,
            &hist,
            1.0,
            None,
            Some(&mut k),
            &mut ev_k,
        )
        .expect("assembly")
    };
    let mut assemble_d = || {
        asm.evaluate(&model, &lifted_d, &z_d, &hist_d, 1.0, None, None, &mut ev_d)
            .expect("assembly")
    };
    println!("\n## 3. Rayon-parallel assembly: 1 vs 2 threads (same cantilever), ms");
    println!("| assembly | 1 thread | 2 threads | speed-up | cores busy with 2 threads |");
    println!("|---|---:|---:|---:|---:|");
    let pool = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool")
    };
    let (p1, p2) = (pool(1), pool(2));
    // 1 and 2 threads alternate, so that both see the same background load; the CPU time of
    // all threads of the process over the wall time tells whether two cores were really had.
    // With `pause`, each timed call follows that much single-threaded work (as an assembly
    // follows a factorization in Newton), long enough for idle rayon workers to fall asleep.
    let row = |label: &str, pause: Duration, f: &mut (dyn FnMut() + Send)| {
        let (mut t1, mut t2) = (Duration::MAX, Duration::MAX);
        let (mut cpu2, mut wall2) = (0.0, 0.0);
        let timed = |f: &mut (dyn FnMut() + Send)| {
            let s = Instant::now();
            while s.elapsed() < pause {
                std::hint::spin_loop();
            }
            let s = Instant::now();
            f();
            s.elapsed()
        };
        p1.install(&mut *f);
        p2.install(&mut *f);
        for _ in 0..11 {
            t1 = t1.min(p1.install(|| timed(&mut *f)));
            let c0 = cpu_seconds();
            let t = p2.install(|| timed(&mut *f));
            cpu2 += cpu_seconds() - c0 - pause.as_secs_f64();
            wall2 += t.as_secs_f64();
            t2 = t2.min(t);
        }
        println!(
            "| {label} | {:.2} | {:.2} | {:.2}x | {:.2} |",
            ms(t1),
            ms(t2),
            t1.as_secs_f64() / t2.as_secs_f64(),
            cpu2 / wall2
        );
    };
    let none = Duration::ZERO;
    row("residual (f64)", none, &mut assemble_r);
    row("residual + tangent (f64)", none, &mut assemble_k);
    row("residual (Dual64)", none, &mut assemble_d);
    row(
        "residual + tangent (f64), after 20 ms of serial work",
        Duration::from_millis(20),
        &mut assemble_k,
    );
    {
        // the cantilever of `benches/increment.rs`: 40 elements, one small parallel chunk
        let small = cantilever(&CantileverSpec {
            nx: 20,
            alpha: 1.0,
            increments: 4,
            ..CantileverSpec::large_deflection()
        })
        .build()
        .expect("cantilever");
        let asm_s = Assembler::new(&small, &[]).expect("pattern");
        let n_s = asm_s.dofs.n_total;
        let ne_s = small.mesh.n_elements();
        let lifted_s = small.lifted::<f64>(&[]);
        let z_s = bending_state(&small, n_s);
        let hist_s = vec![0.0; asm_s.dofs.n_history];
        let mut ev_s = Evaluation::<f64>::new(&asm_s, ne_s);
        let mut k_s = SparseMatrix::new(asm_s.pattern.clone());
        let mut f = || {
            asm_s
                .evaluate(
                    &small,
                    &lifted_s,
                    &z_s,
                    &hist_s,
                    1.0,
                    None,
                    Some(&mut k_s),
                    &mut ev_s,
                )
                .expect("assembly")
        };
        row(
            &format!(
                "residual + tangent (f64), small cantilever ({ne_s} elements, {n_s} unknowns)"
            ),
            none,
            &mut f,
        );
        row(
            "the same, after 2 ms of serial work (one LU of that model)",
            Duration::from_millis(2),
            &mut f,
        );
    }
}

/// Section 4: increments of the small scenes.
fn increment_section() {
    println!("\n## 4. Where an increment goes (the scenes of `benches/increment.rs`; solver and engine timers, fastest of 5 runs)");
    let small = cantilever(&CantileverSpec {
        nx: 20,
        alpha: 1.0,
        increments: 4,
        ..CantileverSpec::large_deflection()
    })
    .build()
    .expect("cantilever");
    increment_table(
        "cantilever-small",
        &small,
        "E",
        &["E", "nu", "load.tip", "beam.length.x"],
    );
    let uniaxial = builtin("uniaxial-j2")
        .expect("scene")
        .build()
        .expect("model");
    increment_table(
        "uniaxial-j2",
        &uniaxial,
        "sigma_y",
        &["E", "nu", "sigma_y", "H"],
    );
}

/// Fastest numeric LU of `k` with faer's simplicial or supernodal kernel forced (the
/// library's `LinearSolver` lets faer choose).
fn lu_time(k: &SparseMatrix, threshold: SupernodalThreshold) -> Duration {
    let a = k.as_faer();
    let sym = factorize_symbolic_lu(
        a.symbolic(),
        LuSymbolicParams {
            supernodal_flop_ratio_threshold: threshold,
            ..Default::default()
        },
    )
    .expect("symbolic LU");
    let mut lu = NumericLu::<usize, f64>::new();
    let mut mem =
        MemBuffer::new(sym.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default()));
    fastest_time(9, || {
        sym.factorize_numeric_lu(
            &mut lu,
            a,
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .expect("numeric LU");
    })
}

/// The tangent of `model` at a bending state, identity rows at the constrained unknowns.
fn newton_matrix(model: &Model) -> SparseMatrix {
    let solver = Solver::new(model).expect("solver");
    let asm = &solver.assembler;
    let n = asm.dofs.n_total;
    let mut k = SparseMatrix::new(asm.pattern.clone());
    let mut ev = Evaluation::<f64>::new(asm, model.mesh.n_elements());
    let z = bending_state(model, n);
    let hist = vec![0.0; asm.dofs.n_history];
    asm.evaluate(
        model,
        &model.lifted::<f64>(&[]),
        &z,
        &hist,
        1.0,
        None,
        Some(&mut k),
        &mut ev,
    )
    .expect("assembly");
    for (d, c) in solver.constrained().iter().enumerate() {
        if *c {
            k.set_identity_row_col(d).expect("in range");
        }
    }
    k
}

/// Per-increment figures of a run, each the smallest over 5 runs.
fn increment_table(name: &str, model: &Model, one: &str, four: &[&str]) {
    let p1 = vec![Parameter::by_name(model, one).expect("parameter")];
    let p4: Vec<Parameter> = four
        .iter()
        .map(|p| Parameter::by_name(model, p).expect("parameter"))
        .collect();
    let fastest = |v: Vec<f64>| v.into_iter().fold(f64::INFINITY, f64::min);
    // primal: the solver's timers
    let mut rows = Vec::new();
    for _ in 0..5 {
        let mut solver = Solver::new(model).expect("solver");
        let t = Instant::now();
        let r = solver
            .run(&RunOptions::default(), &mut NoObserver)
            .expect("run");
        let wall = t.elapsed().as_secs_f64();
        let inc = r.records.len() as f64;
        let iters: usize = r.records.iter().map(|x| x.iterations).sum();
        let c = r.cost;
        rows.push([
            wall / inc,
            c.assembly_seconds / inc,
            c.factor_seconds / inc,
            c.solve_seconds / inc,
            iters as f64 / inc,
            c.factor_seconds / c.factorizations.max(1) as f64,
        ]);
    }
    let col = |k: usize| fastest(rows.iter().map(|r| r[k]).collect());
    println!(
        "\n{name}: {} unknowns, {:.1} Newton iterations per increment; primal per increment {:.3} ms = assembly {:.3} + LU {:.3} ({:.3} per factorization) + solve {:.3} + rest",
        model.dof_map().n_total,
        col(4),
        col(0) * 1e3,
        col(1) * 1e3,
        col(2) * 1e3,
        col(5) * 1e3,
        col(3) * 1e3
    );
    if model.dof_map().n_total > 100 {
        let k = newton_matrix(model);
        println!(
            "numeric LU of its tangent, faer kernel forced: simplicial {:.3} ms, supernodal {:.3} ms",
            ms(lu_time(&k, SupernodalThreshold::FORCE_SIMPLICIAL)),
            ms(lu_time(&k, SupernodalThreshold::FORCE_SUPERNODAL))
        );
    }
    println!("| method | sensitivity work per increment, ms | residual evaluations / increment | solve columns / increment | extra factorizations |");
    println!("|---|---:|---:|---:|---:|");
    for (label, method, params) in [
        ("sdm", Method::Sdm, &p1),
        ("sdm-central", Method::SdmCentral, &p1),
        ("ddm", Method::Ddm, &p1),
        ("sdm-4", Method::Sdm, &p4),
        ("ddm-4", Method::Ddm, &p4),
    ] {
        let settings = Settings {
            method,
            ..Settings::default()
        };
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..5 {
            let (r, s) = run_sensitivity(model, params, &settings).expect("run");
            let inc = r.records.len() as f64;
            times.push(s.cost.wall_seconds / inc);
            last = Some((s.cost, inc));
        }
        let (c, inc) = last.expect("five runs");
        println!(
            "| {label} | {:.3} | {:.1} | {:.1} | {} |",
            fastest(times) * 1e3,
            c.residual_evaluations as f64 / inc,
            c.solve_columns as f64 / inc,
            c.factorizations
        );
    }
}
