//! Block GMRES preconditioned with a factorization at hand: the sensitivity solve with the
//! converged tangent when Newton's last factor is of a neighbouring matrix.

use super::*;

impl LinearSolver {
    /// Solves `a X = B` by block GMRES right-preconditioned with the stored factorization `M`
    /// (`a M^-1 Y = B`, `X = M^-1 Y`), for `a` close to the factored matrix or differing from
    /// it in a few rows and columns. The start is the plain solve `X0 = M^-1 B`; the columns
    /// share one Krylov space, grown by all of them at once: each iteration is one
    /// multi-column solve with the factor over the newest basis vectors (one per column) and
    /// their products with `a`. A change of rank `k` lies in one invariant subspace of
    /// dimension `k` that every column's residual lives in, so `p` columns converge in about
    /// `k / p + 1` iterations in exact arithmetic, where separate Krylov spaces would take
    /// `k + 1` each. A column's start residual in the span of the others' is left out
    /// (deflation, see [`DEFLATION`]).
    ///
    /// `rhs` holds `B` (`ncols` column-major columns) on entry and the last iterate on
    /// return, converged or not (a caller that falls back to a factorization keeps `B`).
    /// The iteration stops when every column's residual estimate reaches a tenth of
    /// `tol |b|` (the residual recomputed from the iterate sits above the estimate by the
    /// round-off of the solves); the returned residual is recomputed, and `converged` requires
    /// it below `tol` too, or else a normwise backward error `|b - a x| / | |a||x| + |b| |` of
    /// at most [`BACKWARD_STABLE_ULPS`] eps: where `|a||x|` is far above `|b|`, a relative
    /// residual of `tol` is out of reach of any solve, a factorization's included (and
    /// finite).
    pub(crate) fn gmres_multi(
        &self,
        a: &SparseMatrix,
        rhs: &mut [f64],
        ncols: usize,
        tol: f64,
        max_iter: usize,
    ) -> Result<KrylovReport> {
        self.gmres_oriented(a, false, rhs, ncols, tol, max_iter)
    }

    /// [`LinearSolver::gmres_multi`] on `a^T X = B`, right-preconditioned with the stored
    /// factorization's transpose (`a^T M^-T Y = B`): the adjoint's transposed solve with the
    /// converged tangent, Newton's last factor at hand.
    pub(crate) fn gmres_transpose_multi(
        &self,
        a: &SparseMatrix,
        rhs: &mut [f64],
        ncols: usize,
        tol: f64,
        max_iter: usize,
    ) -> Result<KrylovReport> {
        self.gmres_oriented(a, true, rhs, ncols, tol, max_iter)
    }

    /// [`LinearSolver::gmres_multi`] with `a` and the factor transposed where `transpose`.
    fn gmres_oriented(
        &self,
        a: &SparseMatrix,
        transpose: bool,
        rhs: &mut [f64],
        ncols: usize,
        tol: f64,
        max_iter: usize,
    ) -> Result<KrylovReport> {
        let precondition = |x: &mut [f64], ncols: usize| {
            if transpose {
                self.solve_transpose_multi_in_place(x, ncols)
            } else {
                self.solve_multi_in_place(x, ncols)
            }
        };
        let n = self.pattern.n;
        check_len(a.n(), n)?;
        check_len(n * ncols, rhs.len())?;
        let b = rhs.to_vec();
        let norm = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>().sqrt();
        let b_norm: Vec<f64> = b.chunks(n.max(1)).map(norm).collect();
        // X0 = M^-1 B, R0 = B - a X0
        precondition(rhs, ncols)?;
        // the first solve; each iteration adds its block, the final combination its columns
        let mut solve_columns = ncols;
        let mut r = vec![0.0; n * ncols];
        let start_relative = residuals_of(a, transpose, &b, rhs, &mut r, ncols)?;
        let target: Vec<f64> = b_norm.iter().map(|bn| tol * bn).collect();
        let active: Vec<bool> = (0..ncols)
            .map(|c| norm(&r[c * n..(c + 1) * n]) > target[c])
            .collect();
        let mut arnoldi = BlockArnoldi::new(n, ncols);
        for c in (0..ncols).filter(|&c| active[c]) {
            arnoldi.start(c, &r[c * n..(c + 1) * n]);
        }
        let estimate_ok = |arnoldi: &BlockArnoldi| {
            (0..ncols).all(|c| !active[c] || arnoldi.estimate(c) <= ESTIMATE_MARGIN * target[c])
        };
        let mut iterations = 0;
        let mut z = Vec::new();
        let mut w = vec![0.0; n];
        while iterations < max_iter && !arnoldi.exhausted() && !estimate_ok(&arnoldi) {
            iterations += 1;
            // Z = M^-1 V_j for the newest basis vectors, in one solve
            let block = arnoldi.unprocessed();
            z.clear();
            for j in block.clone() {
                z.extend_from_slice(&arnoldi.basis[j]);
            }
            precondition(&mut z, block.len())?;
            solve_columns += block.len();
            for (k, _) in block.enumerate() {
                if transpose {
                    a.mul_vec_transpose(&z[k * n..(k + 1) * n], &mut w)?;
                } else {
                    a.mul_vec(&z[k * n..(k + 1) * n], &mut w)?;
                }
                arnoldi.step(&mut w);
            }
        }
        let converged_estimate = arnoldi.exhausted() || estimate_ok(&arnoldi);
        // a NaN column shows and fails `converged`
        let relative = if iterations == 0 {
            // the start solved every column: the iterate and its residual are the start's
            start_relative
        } else {
            // X += M^-1 (V Y), all columns in one solve
            let mut u = vec![0.0; n * ncols];
            arnoldi.combine(&mut u);
            precondition(&mut u, ncols)?;
            solve_columns += ncols;
            for (xi, ui) in rhs.iter_mut().zip(&u) {
                *xi += ui;
            }
            residuals_of(a, transpose, &b, rhs, &mut r, ncols)?
        };
        // a column whose relative residual is above `tol` is still solved when its backward
        // error is that of a stable direct solve (`|K||x|` far above `|b|`: the relative
        // residual a factorization of `a` would reach is no better)
        let mut backward_error = 0.0f64;
        let mut each_ok = true;
        let mut scale = vec![0.0; n];
        for c in 0..ncols {
            let (bc, xc) = (&b[c * n..(c + 1) * n], &rhs[c * n..(c + 1) * n]);
            if transpose {
                a.abs_mul_vec_transpose(xc, &mut scale)?;
            } else {
                a.abs_mul_vec(xc, &mut scale)?;
            }
            let den = scale
                .iter()
                .zip(bc)
                .map(|(s, b)| (s + b.abs()).powi(2))
                .sum::<f64>()
                .sqrt();
            // |b - a x|, from the relative residual `residuals_of` measured
            let rn = relative[c] * if b_norm[c] > 0.0 { b_norm[c] } else { 1.0 };
            let omega = if rn == 0.0 { 0.0 } else { rn / den };
            if omega.is_nan() || omega > backward_error {
                backward_error = omega;
            }
            // (NaN fails both)
            each_ok &= relative[c] <= tol || omega <= BACKWARD_STABLE_ULPS * f64::EPSILON;
        }
        Ok(KrylovReport {
            iterations,
            solve_columns,
            relative_residual: worst(&relative),
            backward_error,
            converged: converged_estimate && each_ok,
        })
    }
}

/// The fraction of the tolerance [`LinearSolver::gmres_multi`] asks of its residual estimate.
pub(super) const ESTIMATE_MARGIN: f64 = 0.1;

/// A column's start residual whose part outside the basis falls below this fraction of its
/// norm lies in the span of the other columns' (to the round-off of two Gram-Schmidt passes,
/// 1e-16) and is left out of the block Arnoldi basis: the residual left behind is below any
/// tolerance asked. Products are left out only when exactly in the span: with a penalty of
/// 1e9 in a Poisson matrix, leaving out a product's part of 1e-14 of its norm doubled the
/// residual GMRES reached (9.7e-8 against the factorization's 4.5e-8).
pub(crate) const DEFLATION: f64 = 1e-14;

/// Normwise backward error `|b - a x| / | |a||x| + |b| |`, in ulps, that
/// [`LinearSolver::gmres_multi`] accepts in place of its relative-residual tolerance: that of
/// a backward-stable direct solve. faer's LU measured 0.39 to 0.46 eps on the stacked leaves'
/// and the cantilever's converged tangents with the pseudo-load in `E` (relative residuals
/// 5e-10 and 2.5e-9, where GMRES preconditioned with Newton's factor reached 0.27 to 0.32 eps).
pub(crate) const BACKWARD_STABLE_ULPS: f64 = 1.0;

/// Outcome of [`LinearSolver::gmres_multi`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct KrylovReport {
    /// Iterations (each one multi-column solve with the factor and a product per column).
    pub iterations: usize,
    /// Columns solved with the factor: the start of every column, the basis vectors of every
    /// iteration, and the final combination of every column (none without an iteration).
    pub solve_columns: usize,
    /// Largest relative residual `|b - a x| / |b|` over the columns, from the returned iterate.
    pub relative_residual: f64,
    /// Largest normwise backward error `|b - a x| / | |a||x| + |b| |` over the columns.
    pub backward_error: f64,
    /// Every column reached the tolerance by its estimate, and by the recomputed residual or
    /// else by a backward error of at most that of a backward-stable direct solve.
    pub converged: bool,
}

/// The block Arnoldi process of [`LinearSolver::gmres_multi`]: one orthonormal basis `V` for
/// all columns, started from their residuals; each processed basis vector `v_j` adds the
/// column `h` of `a M^-1 v_j = V h`, reduced to upper triangular form by Givens rotations as
/// it comes, which rotate the right-hand sides `G` (the residuals' coordinates in `V`) too.
/// With `m` vectors processed, column `c`'s least-squares residual is the norm of
/// `G[m.., c]`.
pub(super) struct BlockArnoldi {
    pub(super) n: usize,
    pub(super) ncols: usize,
    pub(super) basis: Vec<Vec<f64>>,
    /// Basis vectors whose product has been taken (the columns of `H` so far).
    pub(super) processed: usize,
    /// Upper triangular columns of the rotated `H`.
    pub(super) r: Vec<Vec<f64>>,
    /// Rotations `(i, cs, sn)` of rows `i` and `i + 1`, in the order applied.
    pub(super) rotations: Vec<(usize, f64, f64)>,
    /// Rotated right-hand sides, row-major: `g[i * ncols + c]`.
    pub(super) g: Vec<f64>,
}

impl BlockArnoldi {
    pub(super) fn new(n: usize, ncols: usize) -> Self {
        BlockArnoldi {
            n,
            ncols,
            basis: Vec::new(),
            processed: 0,
            r: Vec::new(),
            rotations: Vec::new(),
            g: Vec::new(),
        }
    }

    /// Orthogonalize `w` against the basis (modified Gram-Schmidt, twice), its coordinates
    /// added to `h`; append it normalized (its norm to `h`) unless what is left of it is at
    /// most `deflation` times its norm.
    pub(super) fn orthogonalize(&mut self, w: &mut [f64], h: &mut Vec<f64>, deflation: f64) {
        h.resize(self.basis.len(), 0.0);
        let before = w.iter().map(|v| v * v).sum::<f64>().sqrt();
        for _pass in 0..2 {
            for (i, v) in self.basis.iter().enumerate() {
                let d: f64 = w.iter().zip(v).map(|(a, b)| a * b).sum();
                h[i] += d;
                for (wk, vk) in w.iter_mut().zip(v) {
                    *wk -= d * vk;
                }
            }
        }
        let norm = w.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm > deflation * before && norm > 0.0 {
            self.basis.push(w.iter().map(|v| v / norm).collect());
            self.g.extend(std::iter::repeat_n(0.0, self.ncols));
            h.push(norm);
        }
    }

    /// Add column `c`'s start residual to the space.
    pub(super) fn start(&mut self, c: usize, residual: &[f64]) {
        let mut w = residual.to_vec();
        let mut h = Vec::new();
        self.orthogonalize(&mut w, &mut h, DEFLATION);
        for (i, hi) in h.iter().enumerate() {
            self.g[i * self.ncols + c] = *hi;
        }
    }

    /// The basis vectors whose product is still to be taken.
    pub(super) fn unprocessed(&self) -> std::ops::Range<usize> {
        self.processed..self.basis.len()
    }

    /// Every basis vector processed: the space is invariant and holds every solution.
    pub(super) fn exhausted(&self) -> bool {
        self.processed == self.basis.len()
    }

    /// Column `c`'s least-squares residual over the processed vectors.
    pub(super) fn estimate(&self, c: usize) -> f64 {
        (self.processed..self.basis.len())
            .map(|i| self.g[i * self.ncols + c].powi(2))
            .sum::<f64>()
            .sqrt()
    }

    /// Take `w = a M^-1 v_j` for the next unprocessed `v_j`: orthogonalize, rotate the new
    /// column of `H` to upper triangular form and the right-hand sides with it.
    pub(super) fn step(&mut self, w: &mut [f64]) {
        let j = self.processed;
        let mut h = Vec::new();
        self.orthogonalize(w, &mut h, 0.0);
        for &(i, cs, sn) in &self.rotations {
            let (a, b) = (h[i], h[i + 1]);
            h[i] = cs * a + sn * b;
            h[i + 1] = -sn * a + cs * b;
        }
        // zero the entries below the diagonal, from the bottom up
        for i in (j..h.len() - 1).rev() {
            let d = h[i].hypot(h[i + 1]);
            let (cs, sn) = if d > 0.0 {
                (h[i] / d, h[i + 1] / d)
            } else {
                (1.0, 0.0)
            };
            h[i] = d;
            h[i + 1] = 0.0;
            self.rotations.push((i, cs, sn));
            for c in 0..self.ncols {
                let (a, b) = (self.g[i * self.ncols + c], self.g[(i + 1) * self.ncols + c]);
                self.g[i * self.ncols + c] = cs * a + sn * b;
                self.g[(i + 1) * self.ncols + c] = -sn * a + cs * b;
            }
        }
        h.truncate(j + 1);
        self.r.push(h);
        self.processed += 1;
    }

    /// `U += V Y` with `R Y = G` over the processed vectors (back substitution), each column
    /// of `U` (column-major) one right-hand side.
    pub(super) fn combine(&self, u: &mut [f64]) {
        let m = self.processed;
        let n = self.n;
        for c in 0..self.ncols {
            let mut y = vec![0.0; m];
            for i in (0..m).rev() {
                let mut s = self.g[i * self.ncols + c];
                for (k, yk) in y.iter().enumerate().skip(i + 1) {
                    s -= self.r[k][i] * yk;
                }
                y[i] = if self.r[i][i] != 0.0 {
                    s / self.r[i][i]
                } else {
                    0.0
                };
            }
            let uc = &mut u[c * n..(c + 1) * n];
            for (v, yi) in self.basis.iter().zip(&y) {
                for (uk, vk) in uc.iter_mut().zip(v) {
                    *uk += yi * vk;
                }
            }
        }
    }
}

/// `r = b - a x` (or `b - a^T x` where `transpose`) for `ncols` column-major columns, and
/// each column's relative residual `|r| / |b|` (`|r|` where `b = 0`; NaN for a NaN column).
pub(super) fn residuals_of(
    a: &SparseMatrix,
    transpose: bool,
    b: &[f64],
    x: &[f64],
    r: &mut [f64],
    ncols: usize,
) -> Result<Vec<f64>> {
    let n = a.n();
    (0..ncols)
        .map(|c| {
            let (xc, bc) = (&x[c * n..(c + 1) * n], &b[c * n..(c + 1) * n]);
            let rc = &mut r[c * n..(c + 1) * n];
            if transpose {
                a.mul_vec_transpose(xc, rc)?;
            } else {
                a.mul_vec(xc, rc)?;
            }
            let (mut rr, mut bb) = (0.0, 0.0);
            for (ri, &bi) in rc.iter_mut().zip(bc) {
                *ri = bi - *ri;
                rr += *ri * *ri;
                bb += bi * bi;
            }
            Ok(if bb > 0.0 {
                (rr / bb).sqrt()
            } else {
                rr.sqrt()
            })
        })
        .collect()
}

/// The largest of `v` (0 when empty), a NaN showing (`f64::max` would drop it).
pub(super) fn worst(v: &[f64]) -> f64 {
    v.iter()
        .fold(0.0f64, |w, &x| if x.is_nan() || x > w { x } else { w })
}
