// Index loops mirror the matrix formulas in the test oracles.
#![allow(clippy::needless_range_loop)]

use super::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use faer::Par;

use approx::assert_relative_eq;
use faer::prelude::*;
use faer::Mat;
use proptest::prelude::*;

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// Dense copy of a sparse matrix.
fn to_dense(a: &SparseMatrix) -> Mat<f64> {
    let n = a.n();
    let mut d = Mat::<f64>::zeros(n, n);
    let (cp, ri) = (a.pattern().col_ptr(), a.pattern().row_idx());
    for j in 0..n {
        for k in cp[j]..cp[j + 1] {
            d[(ri[k], j)] += a.values()[k];
        }
    }
    d
}

/// Dense LU solve (the independent oracle).
fn dense_solve(d: &Mat<f64>, b: &[f64]) -> Vec<f64> {
    let n = b.len();
    let rhs = Mat::<f64>::from_fn(n, 1, |i, _| b[i]);
    let x = d.partial_piv_lu().solve(&rhs);
    (0..n).map(|i| x[(i, 0)]).collect()
}

fn rel_err(x: &[f64], y: &[f64]) -> f64 {
    let num: f64 = x.iter().zip(y).map(|(a, b)| (a - b) * (a - b)).sum();
    let den: f64 = y.iter().map(|a| a * a).sum();
    (num / den).sqrt()
}

fn residual(a: &SparseMatrix, x: &[f64], b: &[f64]) -> f64 {
    let mut ax = vec![0.0; b.len()];
    a.mul_vec(x, &mut ax).unwrap();
    rel_err(&ax, b)
}

/// 2D grid of bilinear quads (nx x ny elements), blocks of the 4 corner nodes.
fn quad_grid(nx: usize, ny: usize) -> (usize, Vec<Vec<usize>>) {
    let node = |i: usize, j: usize| j * (nx + 1) + i;
    let mut blocks = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            blocks.push(vec![
                node(i, j),
                node(i + 1, j),
                node(i + 1, j + 1),
                node(i, j + 1),
            ]);
        }
    }
    ((nx + 1) * (ny + 1), blocks)
}

/// Q1 Laplacian element matrix on a square (row-major 4x4), plus an optional
/// unsymmetric convection-like part `c`.
fn q1_laplace(c: f64) -> Vec<f64> {
    let k = [
        [4.0, -1.0, -2.0, -1.0],
        [-1.0, 4.0, -1.0, -2.0],
        [-2.0, -1.0, 4.0, -1.0],
        [-1.0, -2.0, -1.0, 4.0],
    ];
    let mut out = Vec::with_capacity(16);
    for a in 0..4 {
        for b in 0..4 {
            let skew = if a == b {
                0.0
            } else if (a + 1) % 4 == b {
                c
            } else if (b + 1) % 4 == a {
                -c
            } else {
                0.0
            };
            out.push(k[a][b] / 6.0 + skew);
        }
    }
    out
}

fn refs(blocks: &[Vec<usize>]) -> Vec<&[usize]> {
    blocks.iter().map(|b| b.as_slice()).collect()
}

/// 2D Poisson (optionally with convection) with Dirichlet boundary; matrix and rhs.
fn poisson_2d(nx: usize, c: f64) -> (SparseMatrix, Vec<f64>) {
    let (n, blocks) = quad_grid(nx, nx);
    let pat = Arc::new(SparsePattern::new(n, &refs(&blocks), &[]).unwrap());
    let mut a = SparseMatrix::new(pat);
    let ke = q1_laplace(c);
    for b in 0..blocks.len() {
        a.add_block(b, &ke).unwrap();
    }
    let mut rhs: Vec<f64> = (0..n).map(|i| 1.0 + 0.01 * i as f64).collect();
    let boundary: Vec<(usize, f64)> = (0..n)
        .filter(|&p| {
            let (i, j) = (p % (nx + 1), p / (nx + 1));
            i == 0 || j == 0 || i == nx || j == nx
        })
        .map(|p| (p, 0.1 * (p % 7) as f64))
        .collect();
    a.apply_dirichlet(&boundary, &mut rhs).unwrap();
    (a, rhs)
}

/// Residuals of `A X = B` and `A^T X = B` solved by `solver` for three columns.
fn residuals(solver: &LinearSolver, a: &SparseMatrix) -> (f64, f64) {
    let n = a.pattern().n();
    let b: Vec<f64> = (0..3 * n)
        .map(|i| ((i * 7 % 13) as f64 - 6.0) * 0.1)
        .collect();
    let mut worst = (0.0f64, 0.0f64);
    for transpose in [false, true] {
        let mut x = b.clone();
        if transpose {
            solver.solve_transpose_multi_in_place(&mut x, 3).unwrap();
        } else {
            solver.solve_multi_in_place(&mut x, 3).unwrap();
        }
        for c in 0..3 {
            let mut ax = vec![0.0; n];
            let xc = &x[c * n..(c + 1) * n];
            if transpose {
                a.mul_vec_transpose(xc, &mut ax).unwrap();
            } else {
                a.mul_vec(xc, &mut ax).unwrap();
            }
            let r = rel_err(&ax, &b[c * n..(c + 1) * n]);
            if transpose {
                worst.1 = worst.1.max(r);
            } else {
                worst.0 = worst.0.max(r);
            }
        }
    }
    worst
}

/// A grid of `nx x nx` bilinear quads whose node pairs `ties` are tied by one Lagrange
/// multiplier each (unknowns `n..n + ties.len()`): the unknown count `n` of the grid and the
/// blocks, the quads' first, then one per tie.
fn tied_grid(nx: usize, ties: &[(usize, usize)]) -> (usize, Vec<Vec<usize>>) {
    let (n, mut blocks) = quad_grid(nx, nx);
    for (j, &(p, q)) in ties.iter().enumerate() {
        blocks.push(vec![p, q, n + j]);
    }
    (n, blocks)
}

/// The matrix of [`tied_grid`] on `pattern`: the quads' Laplacian with convection `c` and
/// the ties' rows and columns (`u_p - u_q`).
fn tied_matrix(
    pattern: Arc<SparsePattern>,
    nx: usize,
    n: usize,
    ties: &[(usize, usize)],
    c: f64,
) -> SparseMatrix {
    let mut a = SparseMatrix::new(pattern);
    let ke = q1_laplace(c);
    for b in 0..nx * nx {
        a.add_block(b, &ke).unwrap();
    }
    for (j, &(p, q)) in ties.iter().enumerate() {
        for (i, v) in [(p, 1.0), (q, -1.0)] {
            a.add(i, n + j, v).unwrap();
            a.add(n + j, i, v).unwrap();
        }
    }
    a
}

/// The symmetric-pattern LU (the default) against faer's LU with partial pivoting on
/// an unsymmetric convection-diffusion matrix: both solve it, plain and transposed, to
/// round-off, and agree.
#[test]
fn symmetric_pattern_lu_solves_like_faers_lu() {
    let (a, _) = poisson_2d(24, 0.3);
    let mut ours = LinearSolver::new(a.pattern().clone()).unwrap();
    let opts = SolverOptions {
        kind: FactorKind::LuColamd,
        ..Default::default()
    };
    let mut faers = LinearSolver::with_options(a.pattern().clone(), opts).unwrap();
    ours.factor(&a).unwrap();
    faers.factor(&a).unwrap();
    assert_eq!(ours.stats().declined, 0);
    let (r, rt) = residuals(&ours, &a);
    assert!(r < 1e-13 && rt < 1e-13, "residuals {r:e} {rt:e}");
    let n = a.pattern().n();
    let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).cos()).collect();
    let (mut x1, mut x2) = (b.clone(), b.clone());
    ours.solve_in_place(&mut x1).unwrap();
    faers.solve_in_place(&mut x2).unwrap();
    assert!(rel_err(&x1, &x2) < 1e-12, "{:e}", rel_err(&x1, &x2));
}

/// A saddle-point system (a 2D Laplacian with tie constraints `u_a - u_b = 0` by
/// Lagrange multipliers, zero diagonals): with the multipliers marked, each is
/// eliminated after the unknowns it ties and the symmetric-pattern LU factors it; left
/// unmarked, the fill-reducing order eliminates a multiplier first, its zero pivot is
/// declined and faer's LU factors the matrix instead. Both solve to round-off.
#[test]
fn saddle_point_multipliers_are_eliminated_after_their_neighbours() {
    let nx = 12;
    let ties: Vec<(usize, usize)> = (0..6).map(|j| (20 + 17 * j, 30 + 13 * j)).collect();
    let (n, blocks) = tied_grid(nx, &ties);
    let m = ties.len();
    let build = |pattern: SparsePattern| {
        let mut a = tied_matrix(Arc::new(pattern), nx, n, &ties, 0.2);
        for i in 0..=nx {
            a.set_identity_row_col(i).unwrap();
        }
        a
    };
    let marked = build(
        SparsePattern::new(n + m, &refs(&blocks), &[])
            .unwrap()
            .with_multipliers_from(n),
    );
    let unmarked = build(SparsePattern::new(n + m, &refs(&blocks), &[]).unwrap());
    for (a, declined) in [(&marked, 0), (&unmarked, 1)] {
        let mut solver = LinearSolver::new(a.pattern().clone()).unwrap();
        solver.factor(a).unwrap();
        assert_eq!(solver.stats().declined, declined);
        let (r, rt) = residuals(&solver, a);
        assert!(r < 1e-12 && rt < 1e-12, "residuals {r:e} {rt:e}");
    }
}

#[test]
fn poisson_1d_two_node_blocks_matches_dense_lu() {
    let ne = 40;
    let n = ne + 1;
    let blocks: Vec<Vec<usize>> = (0..ne).map(|e| vec![e, e + 1]).collect();
    let pat = Arc::new(SparsePattern::new(n, &refs(&blocks), &[]).unwrap());
    assert_eq!(pat.nnz(), n + 2 * ne);
    let mut a = SparseMatrix::new(pat.clone());
    for e in 0..ne {
        let k = 1.0 + e as f64 * 0.1;
        a.add_block(e, &[k, -k, -k, k]).unwrap();
    }
    let mut b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
    a.set_identity_row_col(0).unwrap();
    b[0] = 0.0;
    let x_ref = dense_solve(&to_dense(&a), &b);
    let mut solver = LinearSolver::new(pat).unwrap();
    solver.factor(&a).unwrap();
    let mut x = b.clone();
    solver.solve_in_place(&mut x).unwrap();
    assert!(rel_err(&x, &x_ref) < 1e-12);
    assert!(residual(&a, &x, &b) < 1e-13);
}

#[test]
fn poisson_2d_q1_blocks_match_dense_lu() {
    for c in [0.0, 0.3] {
        let (a, b) = poisson_2d(12, c);
        let x_ref = dense_solve(&to_dense(&a), &b);
        let mut solver = LinearSolver::new(a.pattern().clone()).unwrap();
        solver.factor(&a).unwrap();
        let mut x = b.clone();
        solver.solve_in_place(&mut x).unwrap();
        assert!(rel_err(&x, &x_ref) < 1e-12, "c = {c}");
    }
}

#[test]
fn part_of_a_block_adds_like_the_zero_padded_block() {
    let blocks: Vec<Vec<usize>> = vec![vec![0, 3, 1, 5], vec![2, 4]];
    let pat = Arc::new(SparsePattern::new(6, &refs(&blocks), &[]).unwrap());
    // rows and columns 3 and 1 of block 0 (DOFs 5 and 3), in that order
    let index = [3, 1];
    let part = [1.0, 2.0, 3.0, 4.0];
    let mut padded = vec![0.0; 16];
    for (a, &r) in index.iter().enumerate() {
        for (c, &k) in index.iter().enumerate() {
            padded[r * 4 + k] = part[a * 2 + c];
        }
    }
    let mut a = SparseMatrix::new(pat.clone());
    let mut b = SparseMatrix::new(pat.clone());
    a.add_block_part(0, &index, &part).unwrap();
    b.add_block(0, &padded).unwrap();
    assert_eq!(a.values(), b.values());
    assert_eq!((a.get(5, 5), a.get(5, 3), a.get(3, 5)), (1.0, 2.0, 3.0));
    // a position outside the block, a wrong length: typed errors
    assert!(a.add_block_part(0, &[4], &[1.0]).is_err());
    assert!(a.add_block_part(0, &[0, 1], &[1.0]).is_err());
    assert!(a.add_block_part(2, &[0], &[1.0]).is_err());
}

#[test]
fn block_slots_agree_with_binary_search_and_duplicates_sum() {
    // Block 1 repeats DOF 2.
    let blocks: Vec<Vec<usize>> = vec![vec![0, 3, 1], vec![2, 4, 2], vec![4, 0]];
    let pat = Arc::new(SparsePattern::new(6, &refs(&blocks), &[(5, 1)]).unwrap());
    for b in 0..pat.num_blocks() {
        let dofs = pat.block_dofs(b);
        let m = dofs.len();
        for (a, &i) in dofs.iter().enumerate() {
            for (c, &j) in dofs.iter().enumerate() {
                assert_eq!(
                    pat.block_slots(b)[a * m + c] as usize,
                    pat.slot(i, j).unwrap()
                );
            }
        }
    }
    // structurally symmetric extra, full diagonal
    assert!(pat.slot(5, 1).is_some() && pat.slot(1, 5).is_some());
    assert!((0..6).all(|i| pat.slot(i, i) == Some(pat.diag_slot(i))));
    assert_eq!(pat.slot(5, 0), None);
    let mut a = SparseMatrix::new(pat.clone());
    a.add_block(1, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
        .unwrap();
    assert_eq!(a.get(2, 2), 1.0 + 3.0 + 7.0 + 9.0);
    assert_eq!(a.get(2, 4), 2.0 + 8.0);
    assert_eq!(a.get(4, 2), 4.0 + 6.0);
    assert_eq!(a.get(4, 4), 5.0);
}

#[test]
fn errors_carry_context() {
    let blocks: Vec<Vec<usize>> = vec![vec![0, 1], vec![2, 3]];
    assert!(matches!(
        SparsePattern::new(3, &refs(&blocks), &[]),
        Err(LinalgError::IndexOutOfRange { index: 3, n: 3 })
    ));
    let pat = Arc::new(SparsePattern::new(4, &refs(&blocks), &[]).unwrap());
    let mut a = SparseMatrix::new(pat.clone());
    assert!(matches!(
        a.add(0, 2, 1.0),
        Err(LinalgError::NotInPattern { row: 0, col: 2 })
    ));
    assert!(matches!(
        a.add(0, 9, 1.0),
        Err(LinalgError::IndexOutOfRange { index: 9, n: 4 })
    ));
    assert!(matches!(
        a.add_block(0, &[1.0]),
        Err(LinalgError::DimensionMismatch { .. })
    ));
    let mut solver = LinearSolver::new(pat.clone()).unwrap();
    assert!(matches!(solver.factor_par(), Par::Seq)); // small system
    let mut x = vec![1.0; 4];
    assert!(matches!(
        solver.solve_in_place(&mut x),
        Err(LinalgError::NotFactored)
    ));
    // Block 1 is [[1, 1], [1, 1]]: numerically singular.
    a.add_block(0, &[2.0, 1.0, 1.0, 2.0]).unwrap();
    a.add_block(1, &[1.0, 1.0, 1.0, 1.0]).unwrap();
    assert!(matches!(
        solver.factor(&a),
        Err(LinalgError::Singular { .. })
    ));
    assert!(!solver.is_factored());
    let other = Arc::new(SparsePattern::new(4, &refs(&blocks), &[]).unwrap());
    assert!(matches!(
        solver.factor(&SparseMatrix::new(other)),
        Err(LinalgError::PatternMismatch)
    ));
    let e = LinalgError::NotInPattern { row: 1, col: 2 };
    assert_eq!(e.to_string(), "entry (1, 2) is not in the sparsity pattern");
}

#[test]
fn multi_column_solve_equals_column_by_column() {
    let (a, b) = poisson_2d(10, 0.2);
    let n = a.n();
    let mut solver = LinearSolver::new(a.pattern().clone()).unwrap();
    solver.factor(&a).unwrap();
    let ncols = 7;
    let rhs: Vec<f64> = (0..n * ncols)
        .map(|k| b[k % n] * (1.0 + (k / n) as f64) + (k as f64 * 0.37).cos())
        .collect();
    let mut multi = rhs.clone();
    solver.solve_multi_in_place(&mut multi, ncols).unwrap();
    for c in 0..ncols {
        let mut col = rhs[c * n..(c + 1) * n].to_vec();
        solver.solve_in_place(&mut col).unwrap();
        for (u, v) in col.iter().zip(&multi[c * n..(c + 1) * n]) {
            assert_relative_eq!(*u, *v, epsilon = 1e-14, max_relative = 1e-14);
        }
    }
    let s = solver.stats();
    // the column of the finiteness check in `factor` is not counted
    assert_eq!(
        (s.symbolic, s.numeric, s.solve_calls, s.solve_columns),
        (1, 1, 8, 14)
    );
}

#[test]
fn transpose_solve_matches_dense() {
    let (a, b) = poisson_2d(8, 0.4);
    let mut solver = LinearSolver::new(a.pattern().clone()).unwrap();
    solver.factor(&a).unwrap();
    let mut x = b.clone();
    solver.solve_transpose_multi_in_place(&mut x, 1).unwrap();
    let x_ref = dense_solve(&to_dense(&a).transpose().to_owned(), &b);
    assert!(rel_err(&x, &x_ref) < 1e-12);
    let mut atx = vec![0.0; b.len()];
    a.mul_vec_transpose(&x, &mut atx).unwrap();
    assert!(rel_err(&atx, &b) < 1e-13);
}

#[test]
fn refactor_with_new_values_reuses_symbolic() {
    let (a, b) = poisson_2d(10, 0.1);
    let mut solver = LinearSolver::new(a.pattern().clone()).unwrap();
    solver.factor(&a).unwrap();
    let mut a2 = a.clone();
    for (k, v) in a2.values_mut().iter_mut().enumerate() {
        *v *= 1.0 + 0.3 * ((k as f64) * 0.71).sin();
    }
    for i in 0..a2.n() {
        a2.add(i, i, 0.5).unwrap();
    }
    for m in [&a2, &a, &a2] {
        solver.factor(m).unwrap();
        let mut x = b.clone();
        solver.solve_in_place(&mut x).unwrap();
        assert!(rel_err(&x, &dense_solve(&to_dense(m), &b)) < 1e-12);
    }
    assert_eq!(solver.symbolic_count(), 1);
    assert_eq!(solver.factor_count(), 4);
}

#[test]
fn dirichlet_elimination_reproduces_prescribed_values_and_free_equations() {
    let (n, blocks) = quad_grid(6, 6);
    let pat = Arc::new(SparsePattern::new(n, &refs(&blocks), &[]).unwrap());
    let mut a = SparseMatrix::new(pat.clone());
    let ke = q1_laplace(0.25);
    for b in 0..blocks.len() {
        a.add_block(b, &ke).unwrap();
    }
    let original = a.clone();
    let f: Vec<f64> = (0..n).map(|i| (i as f64).sqrt()).collect();
    let fixed: Vec<(usize, f64)> = (0..=6)
        .map(|i| (i, 1.0 + i as f64))
        .chain([(20, -2.0)])
        .collect();
    let mut rhs = f.clone();
    a.apply_dirichlet(&fixed, &mut rhs).unwrap();
    for &(i, _) in &fixed {
        for j in 0..n {
            let expect = if i == j { 1.0 } else { 0.0 };
            assert_eq!(a.get(i, j), expect);
            assert_eq!(a.get(j, i), expect);
        }
    }
    let mut solver = LinearSolver::new(pat).unwrap();
    solver.factor(&a).unwrap();
    let mut x = rhs.clone();
    solver.solve_in_place(&mut x).unwrap();
    let mut r = vec![0.0; n];
    original.mul_vec(&x, &mut r).unwrap();
    for i in 0..n {
        match fixed.iter().find(|p| p.0 == i) {
            Some(&(_, u)) => assert_relative_eq!(x[i], u, epsilon = 1e-13),
            None => {
                assert_relative_eq!(r[i], f[i], epsilon = 1e-11, max_relative = 1e-12)
            }
        }
    }
}

/// Deterministic, irregular local matrix of block `b` (size m x m).
fn local_values(b: usize, out: &mut [f64]) {
    for (k, v) in out.iter_mut().enumerate() {
        *v = ((b * 31 + k * 7) as f64 * 0.123).sin() * 10f64.powi((k % 5) as i32 - 2);
    }
}

fn irregular_pattern(n: usize, nb: usize) -> Arc<SparsePattern> {
    let blocks: Vec<Vec<usize>> = (0..nb)
        .map(|b| {
            let m = 2 + b % 6;
            (0..m)
                .map(|l| (b * 13 + l * l * 7 + (l % 2) * b) % n)
                .collect()
        })
        .collect();
    Arc::new(SparsePattern::new(n, &refs(&blocks), &[(0, n - 1)]).unwrap())
}

#[test]
fn parallel_assembly_is_bit_identical_to_sequential() {
    // Several assembly chunks; blocks have repeated DOFs.
    let pat = irregular_pattern(500, 30_000);
    assert!(pat.chunk_ptr.len() > 2);
    let mut seq = SparseMatrix::new(pat.clone());
    let mut buf = Vec::new();
    for b in 0..pat.num_blocks() {
        buf.resize(pat.block_slots(b).len(), 0.0);
        local_values(b, &mut buf);
        seq.add_block(b, &buf).unwrap();
    }
    for threads in [1, 2, 3] {
        let mut par = SparseMatrix::new(pat.clone());
        pool(threads).install(|| par.assemble_blocks_par(local_values));
        assert!(
            seq.values()
                .iter()
                .zip(par.values())
                .all(|(x, y)| x.to_bits() == y.to_bits()),
            "threads = {threads}"
        );
    }
}

#[test]
fn parallel_assembly_reports_lowest_failing_block_and_reuses_scratch() {
    let pat = irregular_pattern(300, 20_000);
    let inits = AtomicUsize::new(0);
    for threads in [1, 2] {
        let mut m = SparseMatrix::new(pat.clone());
        let r = pool(threads).install(|| {
            m.try_assemble_blocks_par_with(
                || {
                    inits.fetch_add(1, Ordering::Relaxed);
                    vec![0.0; 64]
                },
                |scratch, b, out| {
                    if b == 7_001 || b == 15_000 {
                        return Err(b);
                    }
                    scratch[0] += 1.0;
                    local_values(b, out);
                    Ok(())
                },
            )
        });
        assert_eq!(r, Err(7_001));
    }
    // a handful of scratch values per thread and call, not one per block
    assert!(inits.load(Ordering::Relaxed) < 50);
}

#[test]
fn refine_improves_solution_from_perturbed_factorization() {
    let (a, b) = poisson_2d(12, 0.2);
    let mut perturbed = a.clone();
    for (k, v) in perturbed.values_mut().iter_mut().enumerate() {
        *v *= 1.0 + 1e-3 * ((k as f64) * 1.3).sin();
    }
    let mut solver = LinearSolver::new(a.pattern().clone()).unwrap();
    solver.factor(&perturbed).unwrap();
    let mut x = b.clone();
    solver.solve_in_place(&mut x).unwrap();
    let r0 = solver.refine(&a, &b, &mut x, 0).unwrap();
    assert!(r0 > 1e-6, "perturbation too small to test: {r0}");
    let r1 = solver.refine(&a, &b, &mut x, 1).unwrap();
    // contraction ~ |A'^-1 (A' - A)| ~ 4e-3 per step here
    let r8 = solver.refine(&a, &b, &mut x, 7).unwrap();
    assert!(r1 < 1e-2 * r0 && r8 < 1e-13, "{r0} {r1} {r8}");
    assert!(rel_err(&x, &dense_solve(&to_dense(&a), &b)) < 1e-12);
    // multi-column refine
    let n = a.n();
    let bb: Vec<f64> = b.iter().copied().chain((0..n).map(|i| i as f64)).collect();
    let mut xx = bb.clone();
    solver.solve_multi_in_place(&mut xx, 2).unwrap();
    let r = solver.refine_multi(&a, &bb, &mut xx, 2, 8).unwrap();
    assert!(r < 1e-13 && xx.len() == 2 * n);
}

#[test]
fn gmres_accepts_a_direct_solves_backward_error_where_the_relative_residual_is_out_of_reach() {
    // a penalty P (i - j)^2 between two interior neighbours: |K||x| ~ P |x| at their rows,
    // far above |b|, so no solve reaches a relative residual of 1e-11 (a factorization of
    // K itself included); GMRES preconditioned with the penalty-free factor is accepted
    // because its backward error is that of the factorization
    let (a, b) = poisson_2d(12, 0.2);
    let (i, j) = (40, 41);
    let penalty = 1e9;
    let mut stiff = a.clone();
    for (p, q, v) in [(i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)] {
        stiff.add(p, q, penalty * v).unwrap();
    }
    let mut direct = LinearSolver::new(a.pattern().clone()).unwrap();
    direct.factor(&stiff).unwrap();
    let mut x_direct = b.clone();
    direct.solve_in_place(&mut x_direct).unwrap();
    let r_direct = residual(&stiff, &x_direct, &b);
    assert!(r_direct > 1e-11, "reachable after all: {r_direct:e}");
    let mut neighbour = LinearSolver::new(a.pattern().clone()).unwrap();
    neighbour.factor(&a).unwrap();
    let mut x = b.clone();
    let report = neighbour.gmres_multi(&stiff, &mut x, 1, 1e-11, 30).unwrap();
    println!("{report:?}, direct solve's relative residual {r_direct:e}");
    assert!(report.converged, "{report:?}");
    assert!(report.relative_residual > 1e-11, "{report:?}");
    assert!(report.backward_error <= BACKWARD_STABLE_ULPS * f64::EPSILON);
    // no worse than the factorization it replaces (with a factor 2 for the round-off of
    // two different computations at the same scale)
    assert!(
        report.relative_residual <= 2.0 * r_direct,
        "{report:?} vs {r_direct:e}"
    );
    // and the same solution: both are backward stable, so they differ by about
    // cond(K) eps ~ (P / smallest eigenvalue) eps ~ 1e9 / 1e-2 * 2e-16 = 2e-5 at most
    assert!(rel_err(&x, &x_direct) < 2e-5, "{}", rel_err(&x, &x_direct));
}

/// The unsymmetric `a` with three columns changed by more than its own entries, `a`'s
/// factorization, and two right-hand sides: `b` and a second one.
fn changed_columns(a: &SparseMatrix, b: &[f64]) -> (SparseMatrix, LinearSolver, Vec<f64>) {
    let n = a.n();
    let mut changed = a.clone();
    let cp = a.pattern().col_ptr().to_vec();
    for j in [17, 60, 100] {
        for k in cp[j]..cp[j + 1] {
            changed.values_mut()[k] += 2.0 * (1.0 + (k % 3) as f64);
        }
    }
    let mut solver = LinearSolver::new(a.pattern().clone()).unwrap();
    solver.factor(a).unwrap();
    let bb: Vec<f64> = b
        .iter()
        .copied()
        .chain((0..n).map(|i| (i % 5) as f64))
        .collect();
    (changed, solver, bb)
}

#[test]
fn block_gmres_with_the_factor_of_a_neighbour_solves_a_low_rank_change_in_rank_over_columns_plus_one_steps(
) {
    let (a, b) = poisson_2d(12, 0.2);
    let n = a.n();
    // three columns changed by more than the matrix's own entries (not a mere scaling of
    // a column, which would make the start residual an eigenvector): a change E of rank 3.
    // From x0 = M^-1 b the residual lies in range(E), invariant under a M^-1 = I + E M^-1.
    // Two columns start the shared space with 2 of its 3 dimensions and the first
    // iteration spans the third, so block GMRES preconditioned with a's factor needs at
    // most 2 iterations in exact arithmetic (separate spaces: 3 each); the bound asserted
    // leaves one iteration for the tolerance's round-off
    let (changed, solver, bb) = changed_columns(&a, &b);
    let col = |v: &[f64], c: usize| v[c * n..(c + 1) * n].to_vec();
    let mut plain = bb.clone();
    solver.solve_multi_in_place(&mut plain, 2).unwrap();
    let start: Vec<f64> = (0..2)
        .map(|c| residual(&changed, &col(&plain, c), &col(&bb, c)))
        .collect();
    assert!(
        start.iter().all(|s| *s > 1e-2),
        "change too small: {start:?}"
    );
    let mut x = bb.clone();
    let report = solver.gmres_multi(&changed, &mut x, 2, 1e-12, 30).unwrap();
    assert!(report.converged, "{report:?}");
    assert!(report.iterations <= 3, "{report:?}");
    let dense = to_dense(&changed);
    for c in 0..2 {
        assert!(residual(&changed, &col(&x, c), &col(&bb, c)) < 1e-12);
        assert!(rel_err(&col(&x, c), &dense_solve(&dense, &col(&bb, c))) < 1e-10);
    }
    // too few steps: reported as not converged, each column's iterate better than its start
    let mut y = bb.clone();
    let short = solver.gmres_multi(&changed, &mut y, 2, 1e-12, 1).unwrap();
    assert!(!short.converged && short.iterations == 1, "{short:?}");
    for c in 0..2 {
        let r = residual(&changed, &col(&y, c), &col(&bb, c));
        assert!(r < start[c], "column {c}: {r} vs {}", start[c]);
    }
    // ten columns share one Krylov space: their start residuals all lie in range(E), of
    // dimension 3, so the start block deflates to 3 vectors, which span an invariant
    // subspace: one iteration with 3 columns solved (separate Krylov spaces: 3 or 4
    // iterations of 10 columns each)
    let ten: Vec<f64> = (0..10 * n)
        .map(|i| ((i * 7 + i / n) % 11) as f64 - 5.0)
        .collect();
    let mut x = ten.clone();
    let report = solver.gmres_multi(&changed, &mut x, 10, 1e-12, 30).unwrap();
    assert!(report.converged, "{report:?}");
    assert!(
        report.iterations == 1 && report.solve_columns == 2 * 10 + 3,
        "{report:?}"
    );
    for c in 0..10 {
        assert!(rel_err(&col(&x, c), &dense_solve(&dense, &col(&ten, c))) < 1e-10);
    }
    // a zero column stays zero
    let mut z = vec![0.0; n];
    let zero = solver.gmres_multi(&changed, &mut z, 1, 1e-12, 30).unwrap();
    assert!(zero.converged && zero.iterations == 0 && z.iter().all(|v| *v == 0.0));
    // without an iteration there is nothing to combine: the start's solve is the only one
    assert_eq!(zero.solve_columns, 1, "{zero:?}");
}

/// The adjoint's solve: `a^T X = B` by block GMRES preconditioned with the transpose of a
/// neighbour's factor, on the unsymmetric matrix with three changed columns above (three
/// changed rows of `a^T`: again a change of rank 3, so two iterations in exact arithmetic,
/// one more for round-off), against a dense solve of the transpose.
#[test]
fn transposed_block_gmres_solves_the_transposed_system() {
    let (a, b) = poisson_2d(12, 0.2);
    let n = a.n();
    let (changed, solver, bb) = changed_columns(&a, &b);
    let col = |v: &[f64], c: usize| v[c * n..(c + 1) * n].to_vec();
    let dense_t = to_dense(&changed).transpose().to_owned();
    let mut x = bb.clone();
    let report = solver
        .gmres_transpose_multi(&changed, &mut x, 2, 1e-12, 30)
        .unwrap();
    assert!(report.converged, "{report:?}");
    assert!(report.iterations <= 3, "{report:?}");
    for c in 0..2 {
        let reference = dense_solve(&dense_t, &col(&bb, c));
        assert!(rel_err(&col(&x, c), &reference) < 1e-10);
        // not the untransposed system's solution (the matrix is unsymmetric)
        let untransposed = dense_solve(&to_dense(&changed), &col(&bb, c));
        assert!(rel_err(&untransposed, &reference) > 1e-3);
    }
}

#[test]
fn cholesky_paths_match_lu_on_spd_poisson() {
    let (a, b) = poisson_2d(12, 0.0);
    let mut lu = LinearSolver::new(a.pattern().clone()).unwrap();
    lu.factor(&a).unwrap();
    let mut x_lu = b.clone();
    lu.solve_in_place(&mut x_lu).unwrap();
    for kind in [FactorKind::Llt, FactorKind::Ldlt] {
        let opts = SolverOptions {
            kind,
            ..Default::default()
        };
        let mut s = LinearSolver::with_options(a.pattern().clone(), opts).unwrap();
        for _ in 0..2 {
            s.factor(&a).unwrap();
        }
        let mut x = b.clone();
        s.solve_in_place(&mut x).unwrap();
        assert!(rel_err(&x, &x_lu) < 1e-12, "{kind:?}");
        let mut xt = b.clone();
        s.solve_transpose_multi_in_place(&mut xt, 1).unwrap();
        assert_eq!(x, xt);
        assert_eq!(s.symbolic_count(), 1);
    }
    // LLT rejects an indefinite matrix
    let mut neg = a.clone();
    neg.values_mut().iter_mut().for_each(|v| *v = -*v);
    let opts = SolverOptions {
        kind: FactorKind::Llt,
        ..Default::default()
    };
    let mut s = LinearSolver::with_options(a.pattern().clone(), opts).unwrap();
    assert!(matches!(
        s.factor(&neg),
        Err(LinalgError::NotPositiveDefinite { .. })
    ));
}

#[test]
fn solver_is_send_and_sync() {
    fn check<T: Send + Sync>() {}
    check::<LinearSolver>();
    check::<SparseMatrix>();
    check::<SparsePattern>();
}

/// Structured hex8 mesh of `ne^3` elements, 3 DOFs per node: blocks of 24 DOFs.
fn hex8_blocks(ne: usize) -> (usize, Vec<Vec<usize>>) {
    let nn = ne + 1;
    let node = |i: usize, j: usize, k: usize| (k * nn + j) * nn + i;
    let mut blocks = Vec::with_capacity(ne * ne * ne);
    for k in 0..ne {
        for j in 0..ne {
            for i in 0..ne {
                let corners = [
                    node(i, j, k),
                    node(i + 1, j, k),
                    node(i + 1, j + 1, k),
                    node(i, j + 1, k),
                    node(i, j, k + 1),
                    node(i + 1, j, k + 1),
                    node(i + 1, j + 1, k + 1),
                    node(i, j + 1, k + 1),
                ];
                blocks.push(
                    corners
                        .iter()
                        .flat_map(|&c| crate::model::node_dofs(c))
                        .collect(),
                );
            }
        }
    }
    (3 * nn * nn * nn, blocks)
}

/// Nonsingular 24x24 local matrix (graph Laplacian + shift + optional skew part).
fn hex8_local(b: usize, out: &mut [f64], skew: f64) {
    for a in 0..24 {
        for c in 0..24 {
            out[a * 24 + c] = if a == c {
                23.1
            } else {
                -1.0 + skew * (((a * 5 + c * 3 + b) % 17) as f64 / 17.0 - 0.5)
            };
        }
    }
}

/// A realistic element cost: K = sum over 8 points of B^T D B, B 6x24.
fn hex8_btdb(b: usize, out: &mut [f64]) {
    let mut d = [[0.0; 6]; 6];
    for (i, row) in d.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = if i == j {
                2.0
            } else if i < 3 && j < 3 {
                1.0
            } else {
                0.0
            };
        }
    }
    let mut bm = [[0.0; 24]; 6];
    let mut db = [[0.0; 24]; 6];
    for gp in 0..8 {
        for (i, row) in bm.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (((i * 24 + j + gp * 7 + b) % 13) as f64 - 6.0) * 0.1;
            }
        }
        for i in 0..6 {
            for j in 0..24 {
                db[i][j] = (0..6).map(|k| d[i][k] * bm[k][j]).sum();
            }
        }
        for a in 0..24 {
            for c in 0..24 {
                let mut s = 0.0;
                for k in 0..6 {
                    s += bm[k][a] * db[k][c];
                }
                out[a * 24 + c] += s;
            }
        }
    }
}

fn best_of<R>(reps: usize, mut f: impl FnMut() -> R) -> (f64, R) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..reps {
        let t = std::time::Instant::now();
        let r = f();
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(r);
    }
    (best, last.unwrap())
}

#[test]
#[ignore = "timing printout; run with --release -- --ignored --nocapture"]
fn timing_hex8_pattern() {
    let ms = |t: f64| format!("{:9.2} ms", t * 1e3);
    // ---- assembly: 31^3 = 29791 blocks of 24x24
    let (n, blocks) = hex8_blocks(31);
    let (t, pat) = best_of(1, || {
        Arc::new(SparsePattern::new(n, &refs(&blocks), &[]).unwrap())
    });
    println!(
        "assembly mesh: n = {n}, blocks = {}, nnz = {}, pattern build {}",
        blocks.len(),
        pat.nnz(),
        ms(t)
    );
    type Kernel = fn(usize, &mut [f64]);
    let kernels: [(&str, Kernel); 2] = [
        ("cheap local (fill only)", |b, out| hex8_local(b, out, 0.2)),
        ("B^T D B, 8 points", hex8_btdb),
    ];
    for (name, f) in kernels {
        let mut m = SparseMatrix::new(pat.clone());
        let mut buf = vec![0.0; 576];
        let (t_seq, _) = best_of(5, || {
            m.zero();
            for b in 0..pat.num_blocks() {
                buf.fill(0.0);
                f(b, &mut buf);
                m.add_block(b, &buf).unwrap();
            }
        });
        let reference = m.values().to_vec();
        print!("  {name:24}: sequential add_block {}", ms(t_seq));
        for threads in [1, 2] {
            let p = pool(threads);
            let (t_buf, _) = best_of(5, || {
                m.zero();
                p.install(|| m.assemble_blocks_par(f));
            });
            assert_eq!(m.values(), &reference[..]);
            print!(" | {threads} thr: assemble_blocks_par {}", ms(t_buf));
        }
        println!();
    }

    // ---- solver: ~30k DOF (and smaller systems, where parallel overhead shows)
    for ne in [8, 13, 21] {
        let (n, blocks) = hex8_blocks(ne);
        let (t_pat, pat) = best_of(1, || {
            Arc::new(SparsePattern::new(n, &refs(&blocks), &[]).unwrap())
        });
        let mut a = SparseMatrix::new(pat.clone());
        a.assemble_blocks_par(|b, out| hex8_local(b, out, 0.2));
        let mut spd = SparseMatrix::new(pat.clone());
        spd.assemble_blocks_par(|b, out| hex8_local(b, out, 0.0));
        println!(
            "solver mesh: n = {n}, nnz = {} ({:.0}/row), pattern build {}",
            pat.nnz(),
            pat.nnz() as f64 / n as f64,
            ms(t_pat)
        );
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.1).sin()).collect();
        let b10: Vec<f64> = (0..10 * n).map(|i| (i as f64 * 0.1).sin()).collect();
        // Seq and rayon(2) interleaved, best of several runs (the machine is shared).
        let pars = [("Seq", Par::Seq), ("rayon(2)", Par::rayon(2))];
        for kind in [FactorKind::Lu, FactorKind::Llt] {
            let m = if kind == FactorKind::Lu { &a } else { &spd };
            let mut solvers = Vec::new();
            let mut t = [[f64::INFINITY; 5]; 2];
            for (p, &(_, par)) in pars.iter().enumerate() {
                let opts = SolverOptions {
                    kind,
                    factor_par: Some(par),
                    solve_par: par,
                    check_finite: false,
                };
                let (t_sym, s) =
                    best_of(1, || LinearSolver::with_options(pat.clone(), opts).unwrap());
                t[p][0] = t_sym;
                solvers.push(s);
            }
            for _ in 0..3 {
                for (p, s) in solvers.iter_mut().enumerate() {
                    t[p][1] = t[p][1].min(best_of(1, || s.factor(m).unwrap()).0);
                }
            }
            for _ in 0..7 {
                for (p, s) in solvers.iter().enumerate() {
                    let (t1, x) = best_of(1, || {
                        let mut x = b.clone();
                        s.solve_in_place(&mut x).unwrap();
                        x
                    });
                    let (t10, x10) = best_of(1, || {
                        let mut x = b10.clone();
                        s.solve_multi_in_place(&mut x, 10).unwrap();
                        x
                    });
                    let (tr, _) = best_of(1, || {
                        let mut y = x.clone();
                        s.refine(m, &b, &mut y, 1).unwrap()
                    });
                    assert!(residual(m, &x, &b) < 1e-10);
                    assert!(residual(m, &x10[9 * n..], &b10[9 * n..]) < 1e-10);
                    t[p][2] = t[p][2].min(t1);
                    t[p][3] = t[p][3].min(t10);
                    t[p][4] = t[p][4].min(tr);
                }
            }
            let (t_mv, _) = best_of(5, || {
                let mut y = vec![0.0; n];
                m.mul_vec(&b, &mut y).unwrap();
                y
            });
            println!("  mul_vec {}", ms(t_mv));
            for (p, (pname, _)) in pars.iter().enumerate() {
                println!(
                    "  {kind:?} {pname:9}: symbolic {} numeric {} solve(1) {} solve(10) {} refine(1 step) {}",
                    ms(t[p][0]),
                    ms(t[p][1]),
                    ms(t[p][2]),
                    ms(t[p][3]),
                    ms(t[p][4])
                );
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn random_diagonally_dominant_unsymmetric_systems_solve(
        n in 1usize..40,
        raw_blocks in proptest::collection::vec(proptest::collection::vec(0usize..1000, 1..6), 0..30),
        extra in proptest::collection::vec((0usize..1000, 0usize..1000), 0..10),
        seed in 0u64..1000,
    ) {
        let blocks: Vec<Vec<usize>> = raw_blocks.iter().map(|b| b.iter().map(|d| d % n).collect()).collect();
        let extra: Vec<(usize, usize)> = extra.iter().map(|&(i, j)| (i % n, j % n)).collect();
        let pat = Arc::new(SparsePattern::new(n, &refs(&blocks), &extra).unwrap());
        let mut a = SparseMatrix::new(pat.clone());
        let val = |k: usize| (((k as u64 + 1) * (seed + 7)) as f64 * 0.6180339887).fract() * 2.0 - 1.0;
        for b in 0..pat.num_blocks() {
            let m = pat.block_dofs(b).len();
            let local: Vec<f64> = (0..m * m).map(|k| val(k + 100 * b)).collect();
            a.add_block(b, &local).unwrap();
        }
        for (e, &(i, j)) in extra.iter().enumerate() {
            a.add(i, j, val(e + 7777)).unwrap();
        }
        // make strictly diagonally dominant by rows
        let mut rowsum = vec![0.0; n];
        let (cp, ri) = (pat.col_ptr(), pat.row_idx());
        for j in 0..n {
            for k in cp[j]..cp[j + 1] {
                if ri[k] != j {
                    rowsum[ri[k]] += a.values()[k].abs();
                }
            }
        }
        for i in 0..n {
            let s = pat.diag_slot(i);
            a.values_mut()[s] = rowsum[i] + 0.5 + val(i + 999).abs();
        }
        let b: Vec<f64> = (0..n).map(|i| val(i + 5000)).collect();
        let mut solver = LinearSolver::new(pat).unwrap();
        solver.factor(&a).unwrap();
        let mut x = b.clone();
        solver.solve_in_place(&mut x).unwrap();
        let mut ax = vec![0.0; n];
        a.mul_vec(&x, &mut ax).unwrap();
        let res = rel_err(&ax, &b);
        prop_assert!(res < 1e-10, "residual {}", res);
    }
}

/// The double-double residuals `b - A x` and `b - A^T x` against exact integer arithmetic:
/// entries and unknowns are positive integers times powers of two whose products are exact in
/// `f64` and whose sums are exact in `i128`, and `b` is the sum rounded to `f64`, so that the
/// residual is that rounding error alone, a few units against terms of 2^51 and more. Every
/// term and every rounding error is then a multiple of the unit, 2^-15, below 2^53 units, so
/// the double-double sums are exact and the residual must be the exact one (rounded once, to
/// itself); the `f64` product misses it. Columns of 11 entries take the transposed
/// residual's four interleaved sums and its tail.
#[test]
fn double_double_residuals_match_exact_integer_arithmetic() {
    let n = 11;
    let all: Vec<usize> = (0..n).collect();
    let pat = Arc::new(SparsePattern::new(n, &[all.as_slice()], &[]).unwrap());
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    // an integer in [2^(bits - 1), 2^bits)
    let mut int = |bits: u32| -> i64 {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        ((seed >> (65 - bits)) | (1 << (bits - 1))) as i64
    };
    // a = ia 2^-10, x = ix 2^-5: ia ix in [2^51, 2^53), exact products, in units of 2^-15
    let ia: Vec<i64> = (0..n * n).map(|_| int(26)).collect();
    let ix: Vec<i64> = (0..n).map(|_| int(27)).collect();
    let mut a = SparseMatrix::new(pat);
    let local: Vec<f64> = ia.iter().map(|&v| v as f64 / 1024.0).collect();
    a.add_block(0, &local).unwrap();
    let x: Vec<f64> = ix.iter().map(|&v| v as f64 / 32.0).collect();
    let unit = 2f64.powi(-15);
    for transpose in [false, true] {
        // row i of A (of A^T): local[i n + j] (local[j n + i])
        let entry = |i: usize, j: usize| {
            if transpose {
                ia[j * n + i]
            } else {
                ia[i * n + j]
            }
        };
        let sums: Vec<i128> = (0..n)
            .map(|i| (0..n).map(|j| entry(i, j) as i128 * ix[j] as i128).sum())
            .collect();
        let b: Vec<f64> = sums.iter().map(|&s| s as f64 * unit).collect();
        let exact: Vec<f64> = (sums.iter().zip(&b))
            .map(|(&s, &bi)| ((bi / unit) as i128 - s) as f64 * unit)
            .collect();
        let mut r = vec![0.0; n];
        let mut ax = vec![0.0; n];
        if transpose {
            a.residual_extended_transpose(&x, &b, &mut r).unwrap();
            a.mul_vec_transpose(&x, &mut ax).unwrap();
        } else {
            a.residual_extended(&x, &b, &mut r).unwrap();
            a.mul_vec(&x, &mut ax).unwrap();
        }
        assert_eq!(r, exact, "transpose {transpose}");
        let plain_misses = (0..n).filter(|&i| b[i] - ax[i] != exact[i]).count();
        let nonzero = exact.iter().filter(|r| **r != 0.0).count();
        assert!(
            plain_misses > n / 2 && nonzero > n / 2,
            "the test needs residuals that plain f64 misses: {plain_misses} missed, {nonzero} nonzero"
        );
    }
}

/// The one-pass identity rows and columns of a mask give the matrix the one-at-a-time calls
/// give, entry for entry: an entry in a fixed row or column 0, a fixed diagonal 1, every
/// other entry untouched (its bits included).
#[test]
fn identity_rows_of_a_mask_match_one_at_a_time() {
    let (n, blocks) = quad_grid(7, 5);
    let pat = Arc::new(SparsePattern::new(n, &refs(&blocks), &[]).unwrap());
    let mut a = SparseMatrix::new(pat);
    for (b, block) in blocks.iter().enumerate() {
        let m = block.len();
        // unsymmetric values of no special form, so that a misplaced entry shows
        let local: Vec<f64> = (0..m * m)
            .map(|k| {
                ((b * 31 + k * 7) as f64 * 0.37).sin() + if k % (m + 1) == 0 { 4.0 } else { 0.0 }
            })
            .collect();
        a.add_block(b, &local).unwrap();
    }
    let fixed: Vec<bool> = (0..n).map(|i| i % 3 == 0 || i % 7 == 2).collect();
    let mut one_by_one = a.clone();
    for (i, f) in fixed.iter().enumerate() {
        if *f {
            one_by_one.set_identity_row_col(i).unwrap();
        }
    }
    let mut at_once = a.clone();
    at_once.set_identity_rows_cols(&fixed).unwrap();
    let bits = |m: &SparseMatrix| m.values().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&at_once), bits(&one_by_one));
    // and it is what it says on the dense matrix
    let (d, d0) = (to_dense(&at_once), to_dense(&a));
    for i in 0..n {
        for j in 0..n {
            let expected = if fixed[i] || fixed[j] {
                if i == j {
                    1.0
                } else {
                    0.0
                }
            } else {
                d0[(i, j)]
            };
            assert_eq!(d[(i, j)].to_bits(), expected.to_bits(), "({i}, {j})");
        }
    }
    assert!(at_once.set_identity_rows_cols(&fixed[1..]).is_err());
}

/// A sibling shares its solver's symbolic analysis and factors and solves exactly as a solver
/// with an analysis of its own does, while the first keeps its own factorization.
#[test]
fn a_sibling_factors_as_a_solver_of_its_own() {
    let (n, blocks) = quad_grid(6, 6);
    let pat = Arc::new(SparsePattern::new(n, &refs(&blocks), &[]).unwrap());
    let matrix = |shift: f64| {
        let mut a = SparseMatrix::new(pat.clone());
        for b in 0..blocks.len() {
            a.add_block(b, &q1_laplace(0.2 + shift * b as f64)).unwrap();
        }
        a.set_identity_row_col(0).unwrap();
        a
    };
    let (a, b) = (matrix(0.0), matrix(0.01));
    let mut first = LinearSolver::new(pat.clone()).unwrap();
    first.factor(&a).unwrap();
    let mut sibling = first.sibling();
    assert_eq!(sibling.symbolic_count(), 0);
    sibling.factor(&b).unwrap();
    let mut own = LinearSolver::new(pat.clone()).unwrap();
    own.factor(&b).unwrap();
    let rhs: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).cos()).collect();
    let solve = |s: &LinearSolver| {
        let mut x = rhs.clone();
        s.solve_in_place(&mut x).unwrap();
        x.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    };
    assert_eq!(solve(&sibling), solve(&own));
    // the first still holds the factorization of `a`, and factors again beside the sibling's
    let mut x = rhs.clone();
    first.solve_in_place(&mut x).unwrap();
    assert!(residual(&a, &x, &rhs) < 1e-13);
    first.factor(&b).unwrap();
    assert_eq!(solve(&first), solve(&own));
    // a factorization kept from the first is solved with by the sibling (the adjoint's
    // `--tangent last`): the sibling's own factorization is back after it
    let mut kept = first.keep().expect("a symmetric-pattern LU is kept");
    first.factor(&a).unwrap();
    let with_kept = sibling.with_kept(&mut kept, |s| Ok(solve(s))).unwrap();
    assert_eq!(with_kept, solve(&own));
    assert_eq!(solve(&sibling), solve(&own));
    // the kept factors are shared, not copied: the first factored `a` into memory of its own,
    // and does so again each time it is kept
    let solve_a = |s: &LinearSolver| {
        let mut x = rhs.clone();
        s.solve_in_place(&mut x).unwrap();
        x
    };
    assert!(residual(&a, &solve_a(&first), &rhs) < 1e-13);
    let mut kept_a = Vec::new();
    for _ in 0..3 {
        kept_a.push(first.keep().unwrap());
        first.factor(&b).unwrap();
        assert_eq!(solve(&first), solve(&own));
        kept_a.push(first.keep().unwrap());
        first.factor(&a).unwrap();
    }
    for (i, k) in kept_a.iter_mut().enumerate() {
        let x = sibling.with_kept(k, |s| Ok(solve_a(s))).unwrap();
        let m = if i % 2 == 0 { &a } else { &b };
        assert!(residual(m, &x, &rhs) < 1e-13, "kept factorization {i}");
    }
}

/// A solver that leaves the fixed unknowns out of its factorizations
/// ([`LinearSolver::with_fixed`]) against the dense LU of the whole matrix (its fixed rows
/// and columns the identity's), on an unsymmetric saddle-point system with multipliers, the
/// fixed unknowns on the boundary and inside: plain, transposed and multi-column solves agree
/// to round-off, the fixed unknowns' solution is the right-hand side to the bit, a sibling and
/// a kept factorization solve alike, and a matrix whose fixed row is not the identity's is
/// refused, naming the unknown.
#[test]
fn a_solver_without_its_fixed_unknowns_solves_the_whole_system() {
    let nx = 10;
    let ties: Vec<(usize, usize)> = (0..4).map(|j| (24 + 17 * j, 35 + 13 * j)).collect();
    let (n, blocks) = tied_grid(nx, &ties);
    let m = ties.len();
    let pattern = Arc::new(
        SparsePattern::new(n + m, &refs(&blocks), &[])
            .unwrap()
            .with_multipliers_from(n),
    );
    let mut a = tied_matrix(pattern.clone(), nx, n, &ties, 0.3);
    // the bottom edge and two interior unknowns
    let mut fixed = vec![false; n + m];
    for i in (0..=nx).chain([57, 58]) {
        fixed[i] = true;
    }
    a.set_identity_rows_cols(&fixed).unwrap();
    let dense = to_dense(&a);
    let nt = n + m;
    let ncols = 3;
    let b: Vec<f64> = (0..ncols * nt)
        .map(|i| ((i * 7 % 13) as f64 - 6.0) * 0.1 + 1e-3 * i as f64)
        .collect();
    let mut reduced =
        LinearSolver::with_fixed(pattern.clone(), SolverOptions::default(), &fixed).unwrap();
    reduced.factor(&a).unwrap();
    // the multipliers stay last among the free unknowns: no decline to faer's LU
    assert_eq!(reduced.stats().declined, 0);
    assert_eq!(
        reduced.factored_n(),
        nt - fixed.iter().filter(|f| **f).count()
    );
    let mut whole = LinearSolver::new(pattern.clone()).unwrap();
    whole.factor(&a).unwrap();
    for transpose in [false, true] {
        let mut x = b.clone();
        if transpose {
            reduced
                .solve_transpose_multi_in_place(&mut x, ncols)
                .unwrap();
        } else {
            reduced.solve_multi_in_place(&mut x, ncols).unwrap();
        }
        let mut y = b.clone();
        if transpose {
            whole.solve_transpose_multi_in_place(&mut y, ncols).unwrap();
        } else {
            whole.solve_multi_in_place(&mut y, ncols).unwrap();
        }
        let d = if transpose {
            dense.transpose().to_owned()
        } else {
            dense.clone()
        };
        for c in 0..ncols {
            let col = c * nt..(c + 1) * nt;
            let oracle = dense_solve(&d, &b[col.clone()]);
            assert!(rel_err(&x[col.clone()], &oracle) < 1e-12);
            assert!(rel_err(&x[col.clone()], &y[col.clone()]) < 1e-12);
            for i in (0..nt).filter(|&i| fixed[i]) {
                assert_eq!(x[c * nt + i].to_bits(), b[c * nt + i].to_bits());
            }
        }
    }
    // a sibling factors on the same reduction; a kept factorization solves in its place
    let mut sibling = reduced.sibling();
    sibling.factor(&a).unwrap();
    let mut kept = reduced.keep().unwrap();
    let mut x = b[..nt].to_vec();
    sibling.solve_in_place(&mut x).unwrap();
    let mut other = LinearSolver::with_fixed(pattern.clone(), SolverOptions::default(), &fixed)
        .unwrap()
        .sibling();
    let mut y = b[..nt].to_vec();
    other
        .with_kept(&mut kept, |s| s.solve_in_place(&mut y))
        .unwrap();
    assert_eq!(x, y);
    assert!(residual(&a, &x, &b[..nt]) < 1e-12);
    // refinement reads the whole matrix
    let mut z = vec![0.0; nt];
    let r = reduced.refine(&a, &b[..nt], &mut z, 2).unwrap();
    assert!(r < 1e-13, "refined residual {r:e}");
    // a fixed unknown's row that is not the identity's
    let mut bad = a.clone();
    bad.add(57, 68, 0.5).unwrap();
    match reduced.factor(&bad) {
        Err(LinalgError::FixedNotIdentity { unknown, row, col }) => {
            assert_eq!((unknown, row, col), (57, 57, 68));
        }
        other => panic!("expected FixedNotIdentity, got {other:?}"),
    }
    // the refused matrix leaves no factorization behind
    assert!(!reduced.is_factored());
    // a kept factorization of the whole system does not fit the reduced solver
    let mut whole_kept = whole.keep().unwrap();
    assert!(sibling
        .with_kept(&mut whole_kept, |s| s.solve_in_place(&mut y))
        .is_err());
    // without the multipliers marked, the reduced system's zero diagonal is declined by the
    // symmetric-pattern LU and factored by faer's LU on the reduced pattern: the same solution
    let unmarked = Arc::new(SparsePattern::new(n + m, &refs(&blocks), &[]).unwrap());
    let mut b2 = SparseMatrix::new(unmarked.clone());
    for (k, v) in b2.values_mut().iter_mut().enumerate() {
        let (cp, ri) = (unmarked.col_ptr(), unmarked.row_idx());
        let col = cp.partition_point(|&p| p <= k) - 1;
        *v = a.get(ri[k], col);
    }
    let mut unmarked_solver =
        LinearSolver::with_fixed(unmarked, SolverOptions::default(), &fixed).unwrap();
    unmarked_solver.factor(&b2).unwrap();
    assert_eq!(unmarked_solver.stats().declined, 1);
    let mut z2 = b[..nt].to_vec();
    unmarked_solver.solve_in_place(&mut z2).unwrap();
    assert!(rel_err(&z2, &dense_solve(&dense, &b[..nt])) < 1e-12);
}

/// A solve of no column is a no-op for every factorization (an empty list of design
/// parameters asked DDM and SDM for one, and the supernodal LU's panels sliced past an empty
/// buffer: a panic found by an audit of bad input).
#[test]
fn a_solve_of_no_column_does_nothing() {
    let (a, _) = poisson_2d(6, 0.0);
    for kind in [
        FactorKind::Lu,
        FactorKind::LuColamd,
        FactorKind::Llt,
        FactorKind::Ldlt,
    ] {
        let opts = SolverOptions {
            kind,
            ..SolverOptions::default()
        };
        let mut solver = LinearSolver::with_options(a.pattern().clone(), opts).unwrap();
        solver.factor(&a).unwrap();
        let mut none: Vec<f64> = Vec::new();
        solver.solve_multi_in_place(&mut none, 0).unwrap();
        solver.solve_transpose_multi_in_place(&mut none, 0).unwrap();
        assert!(none.is_empty(), "{kind:?}");
    }
}
