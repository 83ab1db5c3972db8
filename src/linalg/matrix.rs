//! The sparse matrix on a fixed pattern: zeroing, block assembly (buffered, deterministic),
//! Dirichlet rows, products, residuals (also in double-double).

use std::sync::Arc;
use std::sync::Mutex;

use faer::sparse::SparseColMatRef;

use super::*;

/// Values over a shared [`SparsePattern`] (CSC order).
#[derive(Debug, Clone)]
pub struct SparseMatrix {
    pub(super) pattern: Arc<SparsePattern>,
    pub(super) values: Vec<f64>,
    /// Reused assembly buffers (two chunks, double-buffered).
    pub(super) buffer: Vec<f64>,
}

/// Per-thread cache of user scratch values for parallel assembly.
pub(super) struct ScratchPool<S> {
    pub(super) slots: Vec<Mutex<Option<S>>>,
}

impl<S> ScratchPool<S> {
    pub(super) fn new() -> Self {
        let k = rayon::current_num_threads() + 1;
        Self {
            slots: (0..k).map(|_| Mutex::new(None)).collect(),
        }
    }

    /// Runs `body` with this thread's scratch (created by `init` on first use). Falls
    /// back to a fresh scratch when the slot is busy (re-entrant work stealing).
    pub(super) fn with<R>(
        &self,
        init: &(impl Fn() -> S + Sync),
        body: impl FnOnce(&mut S) -> R,
    ) -> R {
        let k = rayon::current_thread_index()
            .map(|i| i.min(self.slots.len() - 2))
            .unwrap_or(self.slots.len() - 1);
        match self.slots[k].try_lock() {
            Ok(mut guard) => {
                let s = guard.get_or_insert_with(init);
                body(s)
            }
            Err(_) => body(&mut init()),
        }
    }
}

impl SparseMatrix {
    /// Zero matrix on `pattern`.
    pub fn new(pattern: Arc<SparsePattern>) -> Self {
        let nnz = pattern.nnz();
        Self {
            pattern,
            values: vec![0.0; nnz],
            buffer: Vec::new(),
        }
    }

    /// The pattern.
    pub fn pattern(&self) -> &Arc<SparsePattern> {
        &self.pattern
    }

    /// Dimension.
    pub fn n(&self) -> usize {
        self.pattern.n
    }

    /// Stored values (CSC order).
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Stored values, mutable (CSC order; index with [`SparsePattern::block_slots`] or
    /// [`SparsePattern::slot`]).
    pub fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }

    /// Sets all values to zero.
    pub fn zero(&mut self) {
        self.values.fill(0.0);
    }

    /// faer view.
    pub fn as_faer(&self) -> SparseColMatRef<'_, usize, f64> {
        SparseColMatRef::new(self.pattern.symbolic.as_ref(), &self.values)
    }

    /// Value of entry `(i, j)` (0 if not stored).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.pattern.slot(i, j).map_or(0.0, |s| self.values[s])
    }

    /// Adds the row-major dense `m x m` matrix `local` of block `b`.
    pub fn add_block(&mut self, b: usize, local: &[f64]) -> Result<()> {
        let nb = self.pattern.num_blocks();
        if b >= nb {
            return Err(LinalgError::IndexOutOfRange { index: b, n: nb });
        }
        let slots = self.pattern.block_slots(b);
        check_len(slots.len(), local.len())?;
        for (&s, &v) in slots.iter().zip(local) {
            self.values[s as usize] += v;
        }
        Ok(())
    }

    /// Adds the row-major dense `k x k` matrix `local` at rows and columns `index` (positions
    /// in block `b`, each below the block's size) of block `b`: a block whose other entries
    /// are all zero, without touching them.
    pub fn add_block_part(&mut self, b: usize, index: &[usize], local: &[f64]) -> Result<()> {
        let nb = self.pattern.num_blocks();
        if b >= nb {
            return Err(LinalgError::IndexOutOfRange { index: b, n: nb });
        }
        let m = self.pattern.block_dofs(b).len();
        let k = index.len();
        check_len(k * k, local.len())?;
        if let Some(&i) = index.iter().find(|&&i| i >= m) {
            return Err(LinalgError::IndexOutOfRange { index: i, n: m });
        }
        let slots = self.pattern.block_slots(b);
        for (a, &r) in index.iter().enumerate() {
            let row = &slots[r * m..(r + 1) * m];
            for (&c, &v) in index.iter().zip(&local[a * k..(a + 1) * k]) {
                self.values[row[c] as usize] += v;
            }
        }
        Ok(())
    }

    /// Adds `v` to entry `(i, j)`.
    pub fn add(&mut self, i: usize, j: usize, v: f64) -> Result<()> {
        let n = self.pattern.n;
        for d in [i, j] {
            if d >= n {
                return Err(LinalgError::IndexOutOfRange { index: d, n });
            }
        }
        let s = self
            .pattern
            .slot(i, j)
            .ok_or(LinalgError::NotInPattern { row: i, col: j })?;
        self.values[s] += v;
        Ok(())
    }

    /// Zeroes row `i` and column `i` and puts 1 on the diagonal (Dirichlet DOF).
    pub fn set_identity_row_col(&mut self, i: usize) -> Result<()> {
        let n = self.pattern.n;
        if i >= n {
            return Err(LinalgError::IndexOutOfRange { index: i, n });
        }
        let cp = self.pattern.symbolic.col_ptr();
        let ri = self.pattern.symbolic.row_idx();
        for k in cp[i]..cp[i + 1] {
            self.values[k] = 0.0;
            // The pattern is structurally symmetric: (i, r) exists for every r in column i.
            let r = ri[k];
            let col = &ri[cp[r]..cp[r + 1]];
            if let Ok(p) = col.binary_search(&i) {
                self.values[cp[r] + p] = 0.0;
            }
        }
        self.values[self.pattern.diag[i]] = 1.0;
        Ok(())
    }

    /// [`SparseMatrix::set_identity_row_col`] for every unknown `i` with `fixed[i]`, in one
    /// pass over the stored entries (no search per entry: an entry in a fixed row or column
    /// becomes 0, or 1 on the diagonal). The same matrix as the one-at-a-time calls.
    pub fn set_identity_rows_cols(&mut self, fixed: &[bool]) -> Result<()> {
        let n = self.pattern.n;
        check_len(n, fixed.len())?;
        let cp = self.pattern.symbolic.col_ptr();
        let ri = self.pattern.symbolic.row_idx();
        for c in 0..n {
            let col = cp[c]..cp[c + 1];
            if fixed[c] {
                for k in col {
                    self.values[k] = if ri[k] == c { 1.0 } else { 0.0 };
                }
            } else {
                for k in col {
                    if fixed[ri[k]] {
                        self.values[k] = 0.0;
                    }
                }
            }
        }
        // the pattern stores every diagonal entry: a fixed one was set to 1 above
        Ok(())
    }

    /// Symmetric elimination of prescribed DOFs: `rhs -= A[:, i] * u_i` for every
    /// `(i, u_i)` in `prescribed`, then rows/columns `i` become identity rows and
    /// `rhs[i] = u_i`. The solution of the modified system satisfies the original
    /// equations at the free DOFs and `x_i = u_i`.
    pub fn apply_dirichlet(&mut self, prescribed: &[(usize, f64)], rhs: &mut [f64]) -> Result<()> {
        let n = self.pattern.n;
        check_len(n, rhs.len())?;
        for &(i, _) in prescribed {
            if i >= n {
                return Err(LinalgError::IndexOutOfRange { index: i, n });
            }
        }
        let cp = self.pattern.symbolic.col_ptr();
        let ri = self.pattern.symbolic.row_idx();
        for &(i, u) in prescribed {
            if u != 0.0 {
                for k in cp[i]..cp[i + 1] {
                    rhs[ri[k]] -= self.values[k] * u;
                }
            }
        }
        for &(i, _) in prescribed {
            self.set_identity_row_col(i)?;
        }
        for &(i, u) in prescribed {
            rhs[i] = u;
        }
        Ok(())
    }

    /// `y = A x`.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) -> Result<()> {
        self.mul_vec_mapped(x, y, |v| v)
    }

    /// `r = b - A x` with every product and sum carried in double-double arithmetic (each
    /// product split exactly by a fused multiply-add, each sum by Knuth's two-sum), rounded to
    /// `f64` once at the end: the residual of `x` to about `eps |r| + eps^2 |A| |x|`, where the
    /// plain product loses everything below `eps |A| |x|`. Iterative refinement with it
    /// converges to the solution rounded to working precision whatever the cancellation in
    /// `A x` (the residual of a slender beam's tangent at its pseudo-load in `E` is a 1e-9
    /// fraction of `|A| |x|`).
    pub fn residual_extended(&self, x: &[f64], b: &[f64], r: &mut [f64]) -> Result<()> {
        let n = self.pattern.n;
        check_len(n, x.len())?;
        check_len(n, b.len())?;
        check_len(n, r.len())?;
        let cp = self.pattern.symbolic.col_ptr();
        let ri = self.pattern.symbolic.row_idx();
        // r = hi + lo per row, starting from b
        let mut lo = vec![0.0; n];
        r.copy_from_slice(b);
        for j in 0..n {
            let xj = x[j];
            if xj == 0.0 {
                continue;
            }
            let rows = cp[j]..cp[j + 1];
            for (&i, &a) in ri[rows.clone()].iter().zip(&self.values[rows]) {
                let (s, err) = sub_product(r[i], a, xj);
                r[i] = s;
                lo[i] += err;
            }
        }
        for (ri, l) in r.iter_mut().zip(&lo) {
            *ri += l;
        }
        Ok(())
    }

    /// `r = b - A^T x` in double-double arithmetic, as [`SparseMatrix::residual_extended`]
    /// (the refinement of a transposed solve: an adjoint).
    pub fn residual_extended_transpose(&self, x: &[f64], b: &[f64], r: &mut [f64]) -> Result<()> {
        let n = self.pattern.n;
        check_len(n, x.len())?;
        check_len(n, b.len())?;
        check_len(n, r.len())?;
        let cp = self.pattern.symbolic.col_ptr();
        let ri = self.pattern.symbolic.row_idx();
        // a column's terms go to LANES double-double sums in turn, added exactly at the end:
        // one sum is two chains of dependent additions, LANES sums overlap theirs
        const LANES: usize = 4;
        for (j, rj) in r.iter_mut().enumerate() {
            let (mut hi, mut lo) = ([0.0; LANES], [0.0; LANES]);
            hi[0] = b[j];
            let col = cp[j]..cp[j + 1];
            let (vals, rows) = (&self.values[col.clone()], &ri[col]);
            let (quads, rows_quads) = (vals.chunks_exact(LANES), rows.chunks_exact(LANES));
            let (tail, rows_tail) = (quads.remainder(), rows_quads.remainder());
            for (v, i) in quads.zip(rows_quads) {
                for l in 0..LANES {
                    let (s, err) = sub_product(hi[l], v[l], x[i[l]]);
                    hi[l] = s;
                    lo[l] += err;
                }
            }
            for (v, i) in tail.iter().zip(rows_tail) {
                let (s, err) = sub_product(hi[0], *v, x[*i]);
                hi[0] = s;
                lo[0] += err;
            }
            // the lanes' leading parts added exactly, their errors to the trailing parts
            let (mut sum, mut low) = (hi[0], lo[0]);
            for (h, l) in hi[1..].iter().zip(&lo[1..]) {
                let (s, err) = sub_product(sum, -1.0, *h);
                sum = s;
                low += err + l;
            }
            *rj = sum + low;
        }
        Ok(())
    }

    /// `y = |A| |x|`, entrywise absolute values (round-off bounds such as `eps |A| |x|`).
    pub fn abs_mul_vec(&self, x: &[f64], y: &mut [f64]) -> Result<()> {
        self.mul_vec_mapped(x, y, f64::abs)
    }

    /// `y = f(A) f(x)`, `f` applied to every entry of both.
    pub(super) fn mul_vec_mapped(
        &self,
        x: &[f64],
        y: &mut [f64],
        f: impl Fn(f64) -> f64,
    ) -> Result<()> {
        let n = self.pattern.n;
        check_len(n, x.len())?;
        check_len(n, y.len())?;
        let cp = self.pattern.symbolic.col_ptr();
        let ri = self.pattern.symbolic.row_idx();
        y.fill(0.0);
        for j in 0..n {
            let xj = f(x[j]);
            if xj != 0.0 {
                for k in cp[j]..cp[j + 1] {
                    y[ri[k]] += f(self.values[k]) * xj;
                }
            }
        }
        Ok(())
    }

    /// `y = A^T x`.
    pub fn mul_vec_transpose(&self, x: &[f64], y: &mut [f64]) -> Result<()> {
        self.mul_vec_transpose_mapped(x, y, |v| v)
    }

    /// `y = |A|^T |x|`, entrywise absolute values.
    pub fn abs_mul_vec_transpose(&self, x: &[f64], y: &mut [f64]) -> Result<()> {
        self.mul_vec_transpose_mapped(x, y, f64::abs)
    }

    /// `y = f(A)^T f(x)`, `f` applied to every entry of both.
    fn mul_vec_transpose_mapped(
        &self,
        x: &[f64],
        y: &mut [f64],
        f: impl Fn(f64) -> f64,
    ) -> Result<()> {
        let n = self.pattern.n;
        check_len(n, x.len())?;
        check_len(n, y.len())?;
        let cp = self.pattern.symbolic.col_ptr();
        let ri = self.pattern.symbolic.row_idx();
        for (j, yj) in y.iter_mut().enumerate() {
            let mut s = 0.0;
            for k in cp[j]..cp[j + 1] {
                s += f(self.values[k]) * f(x[ri[k]]);
            }
            *yj = s;
        }
        Ok(())
    }

    /// Adds the local matrix of every block, evaluated in parallel; see
    /// [`SparseMatrix::try_assemble_blocks_par_with`].
    pub fn assemble_blocks_par<F>(&mut self, f: F)
    where
        F: Fn(usize, &mut [f64]) + Sync,
    {
        let r: std::result::Result<(), std::convert::Infallible> = self
            .try_assemble_blocks_par_with(
                || (),
                |_, b, out| {
                    f(b, out);
                    Ok(())
                },
            );
        match r {
            Ok(()) => {}
            Err(e) => match e {},
        }
    }

    /// Adds the local matrix of every block: `f(scratch, b, out)` fills the zeroed,
    /// row-major `m x m` slice `out` for block `b`; `init` creates a per-thread scratch
    /// value (created once per worker thread and call, reused for all its blocks).
    ///
    /// Local matrices are evaluated in parallel (rayon, current pool) into a chunk
    /// buffer and added sequentially in block order, overlapped with the evaluation of
    /// the next chunk: the result is bit-identical to calling [`SparseMatrix::add_block`]
    /// for `b = 0, 1, ...`, whatever the number of threads.
    ///
    /// On error, the error of the lowest failing block is returned; the values are then
    /// partially assembled (zero and reassemble).
    pub fn try_assemble_blocks_par_with<S, E, I, F>(&mut self, init: I, f: F) -> Result<(), E>
    where
        S: Send,
        I: Fn() -> S + Sync,
        F: Fn(&mut S, usize, &mut [f64]) -> Result<(), E> + Sync,
        E: Send,
    {
        let pat = &*self.pattern;
        let nchunks = pat.chunk_ptr.len().saturating_sub(1);
        if nchunks == 0 {
            return Ok(());
        }
        let maxlen = (0..nchunks)
            .map(|c| {
                pat.block_slot_ptr[pat.chunk_ptr[c + 1]] - pat.block_slot_ptr[pat.chunk_ptr[c]]
            })
            .max()
            .unwrap_or(0);
        let mut buffer = std::mem::take(&mut self.buffer);
        buffer.resize(2 * maxlen, 0.0);
        let pool = ScratchPool::new();
        let (mut cur, mut next) = buffer.split_at_mut(maxlen);
        let values = &mut self.values;

        let eval = |c: usize, buf: &mut [f64]| -> Result<(), E> {
            let (b0, b1) = (pat.chunk_ptr[c], pat.chunk_ptr[c + 1]);
            let len = pat.block_slot_ptr[b1] - pat.block_slot_ptr[b0];
            eval_range(pat, b0, b1, &mut buf[..len], &pool, &init, &f)
        };
        let scatter = |c: usize, buf: &[f64], values: &mut [f64]| {
            let (b0, b1) = (pat.chunk_ptr[c], pat.chunk_ptr[c + 1]);
            let slots = &pat.block_slot_data[pat.block_slot_ptr[b0]..pat.block_slot_ptr[b1]];
            for (&s, &v) in slots.iter().zip(buf) {
                values[s as usize] += v;
            }
        };

        let mut result = eval(0, cur);
        if result.is_ok() {
            for c in 0..nchunks {
                let (_, r) = rayon::join(
                    || scatter(c, cur, values),
                    || {
                        if c + 1 < nchunks {
                            eval(c + 1, next)
                        } else {
                            Ok(())
                        }
                    },
                );
                if r.is_err() {
                    result = r;
                    break;
                }
                std::mem::swap(&mut cur, &mut next);
            }
        }
        self.buffer = buffer;
        result
    }
}

/// Evaluates blocks `b0..b1` into `buf` (laid out as their slots), recursively in parallel.
pub(super) fn eval_range<S, E, I, F>(
    pat: &SparsePattern,
    b0: usize,
    b1: usize,
    buf: &mut [f64],
    pool: &ScratchPool<S>,
    init: &I,
    f: &F,
) -> Result<(), E>
where
    S: Send,
    I: Fn() -> S + Sync,
    F: Fn(&mut S, usize, &mut [f64]) -> Result<(), E> + Sync,
    E: Send,
{
    const GRAIN: usize = 16;
    if b1 - b0 <= GRAIN {
        pool.with(init, |s| {
            let base = pat.block_slot_ptr[b0];
            for b in b0..b1 {
                let out = &mut buf[pat.block_slot_ptr[b] - base..pat.block_slot_ptr[b + 1] - base];
                out.fill(0.0);
                f(s, b, out)?;
            }
            Ok(())
        })
    } else {
        let mid = b0 + (b1 - b0) / 2;
        let (l, r) = buf.split_at_mut(pat.block_slot_ptr[mid] - pat.block_slot_ptr[b0]);
        let (rl, rr) = rayon::join(
            || eval_range(pat, b0, mid, l, pool, init, f),
            || eval_range(pat, mid, b1, r, pool, init, f),
        );
        rl.and(rr)
    }
}

/// `hi - a x = s + err` with `s` the rounded sum and `err` its exact error (to the rounding of
/// `err` itself): the product split exactly by a fused multiply-add, the sum by Knuth's
/// two-sum. The step of the double-double residuals.
#[inline]
fn sub_product(hi: f64, a: f64, x: f64) -> (f64, f64) {
    // -a x = p + e exactly
    let p = -a * x;
    let e = (-a).mul_add(x, -p);
    // hi + p = s + t exactly
    let s = hi + p;
    let bp = s - hi;
    let t = (hi - (s - bp)) + (p - bp);
    (s, t + e)
}
