//! Supernodal sparse LU on the symmetric pattern: the default factorization of
//! [`crate::linalg::LinearSolver`] for unsymmetric matrices.
//!
//! Finite element tangents are structurally symmetric (a stored `(i, j)` also stores
//! `(j, i)`), and their values are unsymmetric only through friction and the consistent
//! tangents of some laws. A fill-reducing *symmetric* ordering (AMD on the pattern) with the
//! pivots kept on the block diagonal then gives `L` the pattern of the Cholesky factor and
//! `U` its transpose. faer's sparse LU instead orders columns with COLAMD and bounds the fill
//! of row pivoting by the pattern of `A^T A`; on the leaf spring's tangent (2,662 unknowns)
//! that stores 3.2 times the entries of `L + U` here and costs 16 ms per factorization
//! against 1 to 2 ms.
//!
//! # Method
//! Left-looking supernodal LU on the symbolic structure of faer's supernodal Cholesky
//! (AMD ordering, relaxed supernodes). Supernode `s` owns the columns `S` and the rows `P`
//! below its diagonal block. Its values are two dense column-major panels: `L_s`, the rows
//! `S ∪ P` of its columns (the whole diagonal block `A_SS`, then `A_PS`), and `Ut_s`, the
//! transpose of the rows `S` of `U` in the columns `P` (`A_SP^T`). Factoring `s`:
//! 1. subtract the updates of every descendant `d` whose pattern reaches `S`
//!    (`L_d U_d` restricted to the rows and columns of `s`; CHOLMOD's linked lists of
//!    descendants by their next target);
//! 2. dense LU with partial pivoting of the diagonal block, `Π A_SS = L_D U_D`: rows are
//!    exchanged only within `S`;
//! 3. `L_P = A_PS U_D^-1` and `U_P = L_D^-1 Π A_SP`.
//!
//! The Schur complement `A_PP - L_P U_P` is then exactly that of block elimination, so the
//! solve is the block recursion (forward: `y_S = L_D^-1 Π b_S`, `b_P -= L_P y_S`; backward:
//! `x_S = U_D^-1 (y_S - U_P x_P)`), and the transposed solve its transpose.
//!
//! # When it declines
//! Pivoting confined to diagonal blocks can meet a zero or tiny pivot that a row exchange
//! across supernodes would avoid (saddle-point systems, zero diagonals). The factorization
//! then returns [`Declined`], and [`crate::linalg::LinearSolver`] factors that matrix with
//! faer's LU instead (partial pivoting over all rows). The test is on the multipliers:
//! every entry of `L_P` must be at most [`MAX_MULTIPLIER`] in magnitude, so each
//! elimination step grows the entries by at most that factor. Entries of `L_D` are at most
//! one (partial pivoting within the block).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::factor::{lu_in_place, lu_in_place_scratch};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_unit_lower_triangular_in_place,
    solve_unit_upper_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Accum, MatMut, MatRef, Par, Side};
use std::sync::Arc;

/// Largest magnitude accepted for an entry of `L` below a diagonal block (a multiplier
/// relative to its pivot). Threshold partial pivoting with `u = 1e-4`: each elimination
/// step can grow the entries by at most this factor, against 2 for full partial pivoting.
/// Finite element tangents stay near 1 (the pivots are the diagonal stiffnesses); a
/// matrix that needs a row exchange across supernodes exceeds it and is factored by faer's
/// LU instead.
pub const MAX_MULTIPLIER: f64 = 1e4;

const NONE: usize = usize::MAX;

/// Why a numeric factorization was declined (the matrix needs pivoting across supernodes,
/// or is singular).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Declined {
    /// Column (in the fill-reducing order) where the factorization stopped.
    pub column: usize,
    /// The largest multiplier or the pivot magnitude that failed.
    pub value: f64,
}

/// Symbolic analysis: ordering, supernodes, panel layout and where each stored entry of
/// the matrix goes. Computed once per pattern.
#[derive(Debug, Clone)]
pub(crate) struct SymbolicSymLu {
    n: usize,
    /// `perm[new] = old`.
    perm: Vec<usize>,
    /// Columns of supernode `s`: `begin[s]..begin[s + 1]`.
    begin: Vec<usize>,
    /// Rows of supernode `s` below its diagonal block: `pat[pat_ptr[s]..pat_ptr[s + 1]]`,
    /// ascending.
    pat_ptr: Vec<usize>,
    pat: Vec<usize>,
    /// Start of supernode `s`'s panels in the values: `L_s` (`(w + p) x w`, then `Ut_s`
    /// (`p x w`), both column-major.
    off: Vec<usize>,
    len: usize,
    /// Supernode of each column (new order).
    sn_of: Vec<usize>,
    /// Position in the values of each stored entry of the matrix (CSC order).
    dest: Vec<usize>,
    /// Largest `p * w` over the supernodes (update scratch).
    max_pw: usize,
    max_w: usize,
    max_p: usize,
}

/// The factors and pivots of one numeric factorization: what a solve reads. Shared, not
/// copied, by the solver that made them and the ones that keep them
/// ([`crate::linalg::LinearSolver::keep`]); a factorization writes into memory of its own
/// when they are shared.
#[derive(Clone, Debug, Default)]
pub(crate) struct LuFactors {
    values: Vec<f64>,
    /// Row exchanges within each diagonal block: for the columns `begin[s]..begin[s + 1]`,
    /// `piv[begin[s] + i]` is the local row moved to position `i` (`(Π y)[i] = y[piv[i]]`).
    piv: Vec<usize>,
    piv_inv: Vec<usize>,
    factored: bool,
}

/// Numeric factors and the scratch reused between factorizations.
#[derive(Clone, Debug, Default)]
pub(crate) struct NumericSymLu {
    lu: Arc<LuFactors>,
    head: Vec<usize>,
    next: Vec<usize>,
    cursor: Vec<usize>,
    map: Vec<usize>,
    tmp: Vec<f64>,
    tmp_t: Vec<f64>,
}

impl NumericSymLu {
    /// Bytes of the factors and pivots (the scratch left out).
    pub(crate) fn bytes(&self) -> usize {
        let lu = &self.lu;
        8 * (lu.values.len() + lu.piv.len() + lu.piv_inv.len())
    }

    /// The factors alone, shared with `self` (no copy: `self`'s next factorization writes
    /// into new memory), to solve with.
    pub(crate) fn share_factors(&self) -> Self {
        NumericSymLu {
            lu: Arc::clone(&self.lu),
            ..NumericSymLu::default()
        }
    }

    /// Take `other`'s factors as its own, shared, keeping its scratch.
    pub(crate) fn adopt_factors(&mut self, other: &NumericSymLu) {
        self.lu = Arc::clone(&other.lu);
    }
}

fn mat(values: &[f64], nrows: usize, ncols: usize, stride: usize) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice_with_stride(values, nrows, ncols, stride.max(1))
}

fn mat_mut(values: &mut [f64], nrows: usize, ncols: usize, stride: usize) -> MatMut<'_, f64> {
    MatMut::from_column_major_slice_with_stride_mut(values, nrows, ncols, stride.max(1))
}

/// The fill-reducing order `order` (`order[new] = old`) with each Lagrange multiplier
/// (unknowns `first..last`) moved to just after the last of the other unknowns it couples to,
/// and the unknowns `last..n` at the end.
/// A multiplier's diagonal is zero in a saddle-point system; eliminated after its
/// neighbours, its pivot is the Schur complement `-b^T K_E^-1 b` of the unknowns `E`
/// eliminated before it, nonzero when `K_E` is definite. The multipliers stay local, so the
/// fill stays close to the fill-reducing order's.
pub(crate) fn multiplier_order(
    a: SymbolicSparseColMatRef<'_, usize>,
    order: &[usize],
    first: usize,
    last: usize,
) -> Vec<usize> {
    let n = order.len();
    let pos = inverse(order);
    let key: Vec<(usize, usize, usize)> = (0..n)
        .map(|old| {
            if old < first {
                (pos[old], 0, 0)
            } else if old >= last {
                (n, 2, pos[old])
            } else {
                let last = a
                    .row_idx_of_col(old)
                    .filter(|&i| i < first)
                    .map(|i| pos[i])
                    .max()
                    .unwrap_or(pos[old]);
                (last, 1, pos[old])
            }
        })
        .collect();
    let mut perm: Vec<usize> = (0..n).collect();
    perm.sort_unstable_by_key(|&old| key[old]);
    perm
}

/// `inv[perm[i]] = i`.
fn inverse(perm: &[usize]) -> Vec<usize> {
    let mut inv = vec![0; perm.len()];
    for (new, &old) in perm.iter().enumerate() {
        inv[old] = new;
    }
    inv
}

impl SymbolicSymLu {
    /// Analysis of a structurally symmetric pattern with a full diagonal whose unknowns
    /// `multipliers_from..last_from` are Lagrange multipliers and `last_from..n` go last (see
    /// [`multiplier_order`]).
    pub fn new(
        a: SymbolicSparseColMatRef<'_, usize>,
        multipliers_from: usize,
        last_from: usize,
    ) -> Result<Self, String> {
        let n = a.nrows();
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        };
        let amd = factorize_symbolic_cholesky(a, Side::Lower, SymmetricOrdering::Amd, params)
            .map_err(|e| format!("{e:?}"))?;
        let amd_perm: Vec<usize> = match amd.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..n).collect(),
        };
        let (chol, perm) = if multipliers_from < n {
            let perm = multiplier_order(
                a,
                &amd_perm,
                multipliers_from,
                last_from.max(multipliers_from),
            );
            let inv = inverse(&perm);
            let custom = faer::perm::PermRef::new_checked(&perm, &inv, n);
            let chol = factorize_symbolic_cholesky(
                a,
                Side::Lower,
                SymmetricOrdering::Custom(custom),
                params,
            )
            .map_err(|e| format!("{e:?}"))?;
            (chol, perm)
        } else {
            (amd, amd_perm)
        };
        let perm_inv = inverse(&perm);
        let mut begin = Vec::new();
        let mut pat_ptr = vec![0];
        let mut pat = Vec::new();
        let mut push = |start: usize, rows: &mut Vec<usize>| {
            rows.sort_unstable();
            begin.push(start);
            pat.extend_from_slice(rows);
            pat_ptr.push(pat.len());
        };
        match chol.raw() {
            SymbolicCholeskyRaw::Supernodal(sup) => {
                for s in 0..sup.n_supernodes() {
                    let mut rows = sup.supernode(s).pattern().to_vec();
                    push(sup.supernode_begin()[s], &mut rows);
                }
            }
            // faer keeps a structure without any elimination work (a diagonal, a
            // 1 x 1 matrix) simplicial even when asked otherwise: one column per supernode
            SymbolicCholeskyRaw::Simplicial(simp) => {
                let l = simp.factor();
                for j in 0..n {
                    let mut rows: Vec<usize> = l.row_idx_of_col(j).filter(|&i| i > j).collect();
                    push(j, &mut rows);
                }
            }
        }
        begin.push(n);
        let ns = begin.len() - 1;
        let mut sn_of = vec![0; n];
        let mut off = Vec::with_capacity(ns + 1);
        let mut len = 0;
        let (mut max_pw, mut max_w, mut max_p) = (0, 0, 0);
        for s in 0..ns {
            sn_of[begin[s]..begin[s + 1]].fill(s);
            let w = begin[s + 1] - begin[s];
            let p = pat_ptr[s + 1] - pat_ptr[s];
            off.push(len);
            len += (w + p) * w + p * w;
            max_pw = max_pw.max(p * w);
            max_w = max_w.max(w);
            max_p = max_p.max(p);
        }
        off.push(len);
        let mut sym = Self {
            n,
            perm,
            begin,
            pat_ptr,
            pat,
            off,
            len,
            sn_of,
            dest: Vec::new(),
            max_pw,
            max_w,
            max_p,
        };
        // where each stored entry goes
        let mut dest = Vec::with_capacity(a.compute_nnz());
        for j in 0..n {
            for i in a.row_idx_of_col(j) {
                let (r, c) = (perm_inv[i], perm_inv[j]);
                dest.push(
                    sym.position(r, c).ok_or_else(|| {
                        format!("entry ({i}, {j}) outside the symbolic structure")
                    })?,
                );
            }
        }
        sym.dest = dest;
        Ok(sym)
    }

    fn pattern(&self, s: usize) -> &[usize] {
        &self.pat[self.pat_ptr[s]..self.pat_ptr[s + 1]]
    }

    /// Position of entry `(r, c)` (new order) in the values.
    fn position(&self, r: usize, c: usize) -> Option<usize> {
        let (sr, sc) = (self.sn_of[r], self.sn_of[c]);
        if sr == sc {
            let s = sc;
            let (st, w) = (self.begin[s], self.begin[s + 1] - self.begin[s]);
            let ld = w + self.pattern(s).len();
            Some(self.off[s] + (c - st) * ld + (r - st))
        } else if r > c {
            let s = sc;
            let (st, w) = (self.begin[s], self.begin[s + 1] - self.begin[s]);
            let pat = self.pattern(s);
            let k = pat.binary_search(&r).ok()?;
            Some(self.off[s] + (c - st) * (w + pat.len()) + w + k)
        } else {
            let s = sr;
            let (st, w) = (self.begin[s], self.begin[s + 1] - self.begin[s]);
            let pat = self.pattern(s);
            let k = pat.binary_search(&c).ok()?;
            Some(self.off[s] + (w + pat.len()) * w + (r - st) * pat.len() + k)
        }
    }

    /// Numeric factorization of `a` (the pattern analysed). On [`Declined`] the factors
    /// are unusable.
    pub fn factor(
        &self,
        a: SparseColMatRef<'_, usize, f64>,
        num: &mut NumericSymLu,
        par: Par,
    ) -> Result<(), Declined> {
        let n = self.n;
        let ns = self.begin.len() - 1;
        if Arc::get_mut(&mut num.lu).is_none() {
            // kept by another solver: the factors go to new memory, the old ones stay theirs
            // (its pages faulted in by the zeroing below: on the leaf spring's forward run
            // keeping all 35 increments' factors, 0.013 s more over its 174 factorizations)
            num.lu = Arc::default();
        }
        let lu = Arc::make_mut(&mut num.lu);
        lu.factored = false;
        lu.values.clear();
        lu.values.resize(self.len, 0.0);
        for (k, &v) in a.val().iter().enumerate() {
            lu.values[self.dest[k]] = v;
        }
        lu.piv.resize(n, 0);
        lu.piv_inv.resize(n, 0);
        num.head.clear();
        num.head.resize(ns, NONE);
        num.next.resize(ns, NONE);
        num.cursor.resize(ns, 0);
        num.map.resize(n, 0);
        // update scratch: a descendant's rows T and columns Q in the target satisfy
        // q <= t <= max_p and q <= max_w; its upper rows T \ Q lie in the target's pattern,
        // so (t - q) q <= p_a w_a <= max_pw, which also holds the p x w permuted Ut
        num.tmp
            .resize(self.max_p * self.max_w.min(self.max_p).max(1), 0.0);
        num.tmp_t.resize(self.max_pw, 0.0);
        let mut lu_mem = MemBuffer::new(lu_in_place_scratch::<usize, f64>(
            self.max_w,
            self.max_w,
            par,
            Default::default(),
        ));
        for s in 0..ns {
            let (st, en) = (self.begin[s], self.begin[s + 1]);
            let w = en - st;
            let pat = self.pattern(s);
            let p = pat.len();
            let ld = w + p;
            for (i, r) in (st..en).enumerate() {
                num.map[r] = i;
            }
            for (i, &r) in pat.iter().enumerate() {
                num.map[r] = w + i;
            }
            let (done, rest) = lu.values.split_at_mut(self.off[s]);
            let (lpanel, upanel) = rest[..ld * w + p * w].split_at_mut(ld * w);
            // 1. updates of the descendants
            let mut d = std::mem::replace(&mut num.head[s], NONE);
            while d != NONE {
                let next_d = num.next[d];
                let wd = self.begin[d + 1] - self.begin[d];
                let pd_pat = self.pattern(d);
                let pd = pd_pat.len();
                let ldd = wd + pd;
                let cd = num.cursor[d];
                let rows = &pd_pat[cd..];
                let q = rows.iter().take_while(|&&r| r < en).count();
                let t = rows.len();
                let base = self.off[d];
                let ld_panel = &done[base..base + ldd * wd];
                let ud_panel = &done[base + ldd * wd..base + ldd * wd + pd * wd];
                // L_d rows T (t x wd) and Ut_d rows Q (q x wd)
                let l_t = mat(&ld_panel[wd + cd..], t, wd, ldd);
                let u_q = mat(&ud_panel[cd..], q, wd, pd);
                let mut c1 = mat_mut(&mut num.tmp[..t * q], t, q, t);
                matmul(c1.rb_mut(), Accum::Replace, l_t, u_q.transpose(), 1.0, par);
                for j in 0..q {
                    let col = rows[j] - st;
                    let dst = &mut lpanel[col * ld..(col + 1) * ld];
                    let src = &num.tmp[j * t..(j + 1) * t];
                    for (i, &r) in rows.iter().enumerate() {
                        dst[num.map[r]] -= src[i];
                    }
                }
                let tq = t - q;
                if tq > 0 && q > 0 {
                    let u_t = mat(&ud_panel[cd + q..], tq, wd, pd);
                    let l_q = mat(&ld_panel[wd + cd..], q, wd, ldd);
                    let mut c2 = mat_mut(&mut num.tmp_t[..tq * q], tq, q, tq);
                    matmul(c2.rb_mut(), Accum::Replace, u_t, l_q.transpose(), 1.0, par);
                    for j in 0..q {
                        let col = rows[j] - st;
                        let dst = &mut upanel[col * p..(col + 1) * p];
                        let src = &num.tmp_t[j * tq..(j + 1) * tq];
                        for (i, &r) in rows[q..].iter().enumerate() {
                            dst[num.map[r] - w] -= src[i];
                        }
                    }
                }
                num.cursor[d] = cd + q;
                if cd + q < pd {
                    let target = self.sn_of[pd_pat[cd + q]];
                    num.next[d] = num.head[target];
                    num.head[target] = d;
                }
                d = next_d;
            }
            // 2. the diagonal block
            let mut lmat = mat_mut(lpanel, ld, w, ld);
            let (mut diag, mut below) = lmat.rb_mut().split_at_row_mut(w);
            {
                let (fwd, inv) = (&mut lu.piv[st..en], &mut lu.piv_inv[st..en]);
                lu_in_place(
                    diag.rb_mut(),
                    fwd,
                    inv,
                    par,
                    MemStack::new(&mut lu_mem),
                    Default::default(),
                );
            }
            for i in 0..w {
                let u = diag[(i, i)];
                if u == 0.0 || !u.is_finite() {
                    return Err(Declined {
                        column: st + i,
                        value: u,
                    });
                }
            }
            // 3. L_P = A_PS U_D^-1, U_P = L_D^-1 Π A_SP
            if p > 0 {
                solve_lower_triangular_in_place(
                    diag.rb().transpose(),
                    below.rb_mut().transpose_mut(),
                    par,
                );
                for j in 0..w {
                    for i in 0..p {
                        let v = below[(i, j)];
                        // NaN fails too
                        if v.is_nan() || v.abs() > MAX_MULTIPLIER {
                            return Err(Declined {
                                column: st + j,
                                value: v,
                            });
                        }
                    }
                }
                let mut ut = mat_mut(upanel, p, w, p);
                let scratch = &mut num.tmp_t[..p * w];
                for j in 0..w {
                    let from = lu.piv[st + j];
                    for i in 0..p {
                        scratch[j * p + i] = ut[(i, from)];
                    }
                }
                for j in 0..w {
                    for i in 0..p {
                        ut[(i, j)] = scratch[j * p + i];
                    }
                }
                solve_unit_lower_triangular_in_place(diag.rb(), ut.rb_mut().transpose_mut(), par);
                num.cursor[s] = 0;
                let target = self.sn_of[pat[0]];
                num.next[s] = num.head[target];
                num.head[target] = s;
            }
        }
        lu.factored = true;
        Ok(())
    }

    /// Solves `A X = B` (or `A^T X = B` when `transpose`) in place for every column of
    /// `rhs`, with the factors of the last successful [`SymbolicSymLu::factor`].
    pub fn solve_in_place(&self, num: &NumericSymLu, mut rhs: MatMut<'_, f64>, transpose: bool) {
        let lu = &num.lu;
        assert!(lu.factored, "solve before a successful factorization");
        let n = self.n;
        let k = rhs.ncols();
        // no column, nothing to solve (the panels below slice a buffer of n k values)
        if k == 0 {
            return;
        }
        let ns = self.begin.len() - 1;
        let mut y = vec![0.0; n * k];
        for c in 0..k {
            for i in 0..n {
                y[c * n + i] = rhs[(self.perm[i], c)];
            }
        }
        let mut g = vec![0.0; self.max_p.max(self.max_w) * k];
        let vals = &lu.values;
        let panels = |s: usize| {
            let w = self.begin[s + 1] - self.begin[s];
            let p = self.pat_ptr[s + 1] - self.pat_ptr[s];
            let ld = w + p;
            let o = self.off[s];
            let l = mat(&vals[o..o + ld * w], ld, w, ld);
            let ut = mat(&vals[o + ld * w..o + ld * w + p * w], p, w, p);
            (w, p, l, ut)
        };
        // forward
        for s in 0..ns {
            let st = self.begin[s];
            let pat = self.pattern(s);
            let (w, p, l, ut) = panels(s);
            let (diag, below) = l.split_at_row(w);
            if !transpose {
                for c in 0..k {
                    let col = &mut y[c * n + st..c * n + st + w];
                    for i in 0..w {
                        g[i] = col[lu.piv[st + i]];
                    }
                    col.copy_from_slice(&g[..w]);
                }
            }
            let mut ys = mat_mut(&mut y[st..], w, k, n);
            if transpose {
                solve_lower_triangular_in_place(diag.transpose(), ys.rb_mut(), Par::Seq);
            } else {
                solve_unit_lower_triangular_in_place(diag, ys.rb_mut(), Par::Seq);
            }
            if p > 0 {
                let ys = mat(&y[st..], w, k, n);
                let mut gm = mat_mut(&mut g[..p * k], p, k, p);
                let lhs = if transpose { ut } else { below };
                matmul(gm.rb_mut(), Accum::Replace, lhs, ys, 1.0, Par::Seq);
                for c in 0..k {
                    for (i, &r) in pat.iter().enumerate() {
                        y[c * n + r] -= g[c * p + i];
                    }
                }
            }
        }
        // backward
        for s in (0..ns).rev() {
            let st = self.begin[s];
            let pat = self.pattern(s);
            let (w, p, l, ut) = panels(s);
            let (diag, below) = l.split_at_row(w);
            if p > 0 {
                for c in 0..k {
                    for (i, &r) in pat.iter().enumerate() {
                        g[c * p + i] = y[c * n + r];
                    }
                }
                let gm = mat(&g[..p * k], p, k, p);
                let ys = mat_mut(&mut y[st..], w, k, n);
                let lhs = if transpose { below } else { ut };
                matmul(ys, Accum::Add, lhs.transpose(), gm, -1.0, Par::Seq);
            }
            let mut ys = mat_mut(&mut y[st..], w, k, n);
            if transpose {
                solve_unit_upper_triangular_in_place(diag.transpose(), ys.rb_mut(), Par::Seq);
            } else {
                solve_upper_triangular_in_place(diag, ys.rb_mut(), Par::Seq);
            }
            if transpose {
                for c in 0..k {
                    let col = &mut y[c * n + st..c * n + st + w];
                    for i in 0..w {
                        g[lu.piv[st + i]] = col[i];
                    }
                    col.copy_from_slice(&g[..w]);
                }
            }
        }
        for c in 0..k {
            for i in 0..n {
                rhs[(self.perm[i], c)] = y[c * n + i];
            }
        }
    }
}
