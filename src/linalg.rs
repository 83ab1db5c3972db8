//! Global sparse system: fixed pattern, block assembly, LU reused across a run.
//!
//! (module docs written at the end)

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::sync::Mutex;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::ldlt::factor::{LdltError, LdltRegularization};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, NumericLu, SymbolicLu};
use faer::sparse::linalg::LuError;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, MatMut, Par, Side};

/// Index of a stored value of a [`SparsePattern`] (position in [`SparseMatrix::values`]).
///
/// `u32` rather than `usize`: the per-block slot tables are the largest arrays of the
/// module (one entry per element-matrix entry), and halving them speeds up assembly.
pub type Slot = u32;

/// Errors of the sparse linear algebra.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LinalgError {
    /// The matrix is (numerically or structurally) singular.
    #[error("singular matrix{}", match .index { Some(i) => format!(" (no pivot at elimination step {i})"), None => " (non-finite values in the factors)".to_string() })]
    Singular {
        /// Elimination step (in faer's permuted order) where no pivot was found, when
        /// faer reports one; `None` when singularity was detected by non-finite values.
        index: Option<usize>,
    },
    /// A Cholesky (LLT/LDLT) factorization met a non-positive or zero pivot.
    #[error("matrix not positive definite (bad pivot at elimination step {index})")]
    NotPositiveDefinite {
        /// Elimination step (in the fill-reducing order).
        index: usize,
    },
    /// Entry `(row, col)` is not in the sparsity pattern.
    #[error("entry ({row}, {col}) is not in the sparsity pattern")]
    NotInPattern {
        /// Row index.
        row: usize,
        /// Column index.
        col: usize,
    },
    /// An index (DOF or block) is out of range.
    #[error("index {index} out of range (size {n})")]
    IndexOutOfRange {
        /// The offending index.
        index: usize,
        /// The size it must be below.
        n: usize,
    },
    /// A slice has the wrong length.
    #[error("dimension mismatch: expected {expected}, found {found}")]
    DimensionMismatch {
        /// Expected length.
        expected: usize,
        /// Actual length.
        found: usize,
    },
    /// The matrix was built on another pattern than the solver.
    #[error("matrix pattern differs from the solver's pattern")]
    PatternMismatch,
    /// `solve` called before a successful `factor`.
    #[error("no numeric factorization available (call factor first)")]
    NotFactored,
    /// The pattern has more stored entries than a [`Slot`] can index.
    #[error("pattern too large: {nnz} stored entries")]
    PatternTooLarge {
        /// Number of stored entries.
        nnz: usize,
    },
    /// Any other error reported by faer.
    #[error("faer: {0}")]
    Faer(String),
}

/// Result alias of this module.
pub type Result<T, E = LinalgError> = std::result::Result<T, E>;

fn check_len(expected: usize, found: usize) -> Result<()> {
    if expected == found {
        Ok(())
    } else {
        Err(LinalgError::DimensionMismatch { expected, found })
    }
}

// ---------------------------------------------------------------------------------------
// Pattern
// ---------------------------------------------------------------------------------------

/// Target number of element-matrix entries per assembly chunk (2 MB of `f64`).
const CHUNK_ENTRIES: usize = 1 << 18;

/// Fixed, structurally symmetric CSC sparsity pattern built from element blocks.
#[derive(Debug)]
pub struct SparsePattern {
    n: usize,
    symbolic: SymbolicSparseColMat<usize>,
    /// `block_dofs[block_dof_ptr[b]..block_dof_ptr[b+1]]`: DOFs of block `b`.
    block_dof_ptr: Vec<usize>,
    block_dofs: Vec<usize>,
    /// `block_slot_data[block_slot_ptr[b]..block_slot_ptr[b+1]]`: slots of block `b`,
    /// row-major over its local indices.
    block_slot_ptr: Vec<usize>,
    block_slot_data: Vec<Slot>,
    /// Slot of each diagonal entry.
    diag: Vec<usize>,
    /// Block boundaries of the assembly chunks.
    chunk_ptr: Vec<usize>,
    /// Blocks grouped by colour (no two blocks of a colour share a DOF).
    colour_ptr: Vec<usize>,
    colour_blocks: Vec<usize>,
}

impl SparsePattern {
    /// Builds the pattern of an `n x n` matrix.
    ///
    /// Every pair `(i, j)` of DOFs within one block is coupled; `extra` adds single
    /// entries; the full diagonal is always present. The pattern is made structurally
    /// symmetric (`(j, i)` is added for every extra `(i, j)`). DOFs repeated within a
    /// block are allowed (their contributions are summed).
    pub fn new(n: usize, blocks: &[&[usize]], extra: &[(usize, usize)]) -> Result<Self> {
        // Blocks, flattened.
        let mut block_dof_ptr = Vec::with_capacity(blocks.len() + 1);
        let mut block_slot_ptr = Vec::with_capacity(blocks.len() + 1);
        block_dof_ptr.push(0);
        block_slot_ptr.push(0);
        let total_dofs: usize = blocks.iter().map(|b| b.len()).sum();
        let mut block_dofs = Vec::with_capacity(total_dofs);
        for blk in blocks {
            for &d in *blk {
                if d >= n {
                    return Err(LinalgError::IndexOutOfRange { index: d, n });
                }
            }
            block_dofs.extend_from_slice(blk);
            block_dof_ptr.push(block_dofs.len());
            block_slot_ptr.push(block_slot_ptr.last().unwrap() + blk.len() * blk.len());
        }
        for &(i, j) in extra {
            for d in [i, j] {
                if d >= n {
                    return Err(LinalgError::IndexOutOfRange { index: d, n });
                }
            }
        }

        // Incidence DOF -> (block, local index), CSR.
        let mut inc_ptr = vec![0usize; n + 1];
        for &d in &block_dofs {
            inc_ptr[d + 1] += 1;
        }
        for i in 0..n {
            inc_ptr[i + 1] += inc_ptr[i];
        }
        let mut inc = vec![(0usize, 0usize); block_dofs.len()];
        {
            let mut next = inc_ptr.clone();
            for b in 0..blocks.len() {
                for (l, &d) in block_dofs[block_dof_ptr[b]..block_dof_ptr[b + 1]]
                    .iter()
                    .enumerate()
                {
                    inc[next[d]] = (b, l);
                    next[d] += 1;
                }
            }
        }

        // Extra entries per column, symmetrised.
        let mut ext_ptr = vec![0usize; n + 1];
        for &(i, j) in extra {
            ext_ptr[j + 1] += 1;
            ext_ptr[i + 1] += 1;
        }
        for i in 0..n {
            ext_ptr[i + 1] += ext_ptr[i];
        }
        let mut ext = vec![0usize; ext_ptr[n]];
        {
            let mut next = ext_ptr.clone();
            for &(i, j) in extra {
                ext[next[j]] = i;
                next[j] += 1;
                ext[next[i]] = j;
                next[i] += 1;
            }
        }

        // Columns: union of the DOFs of the blocks touching j, extras, and j.
        let mut col_ptr = Vec::with_capacity(n + 1);
        col_ptr.push(0usize);
        let mut row_idx: Vec<usize> = Vec::new();
        let mut mark = vec![usize::MAX; n];
        let mut rows = Vec::new();
        for j in 0..n {
            rows.clear();
            mark[j] = j;
            rows.push(j);
            for &(b, _) in &inc[inc_ptr[j]..inc_ptr[j + 1]] {
                for &d in &block_dofs[block_dof_ptr[b]..block_dof_ptr[b + 1]] {
                    if mark[d] != j {
                        mark[d] = j;
                        rows.push(d);
                    }
                }
            }
            for &d in &ext[ext_ptr[j]..ext_ptr[j + 1]] {
                if mark[d] != j {
                    mark[d] = j;
                    rows.push(d);
                }
            }
            rows.sort_unstable();
            row_idx.extend_from_slice(&rows);
            col_ptr.push(row_idx.len());
        }
        let nnz = row_idx.len();
        if nnz > Slot::MAX as usize {
            return Err(LinalgError::PatternTooLarge { nnz });
        }

        // Slots of every block entry: position map per column, no search.
        let mut block_slot_data: Vec<Slot> = vec![0; *block_slot_ptr.last().unwrap()];
        let mut diag = vec![0usize; n];
        let mut pos: Vec<Slot> = vec![0; n];
        for j in 0..n {
            for (k, &r) in row_idx
                .iter()
                .enumerate()
                .take(col_ptr[j + 1])
                .skip(col_ptr[j])
            {
                pos[r] = k as Slot;
            }
            diag[j] = pos[j] as usize;
            for &(b, lb) in &inc[inc_ptr[j]..inc_ptr[j + 1]] {
                let dofs = &block_dofs[block_dof_ptr[b]..block_dof_ptr[b + 1]];
                let m = dofs.len();
                let out = &mut block_slot_data[block_slot_ptr[b]..block_slot_ptr[b + 1]];
                for (a, &d) in dofs.iter().enumerate() {
                    out[a * m + lb] = pos[d];
                }
            }
        }

        // Assembly chunks (block ranges of about CHUNK_ENTRIES entries).
        let nb = blocks.len();
        let mut chunk_ptr = vec![0usize];
        let mut start = 0usize;
        for b in 0..nb {
            if block_slot_ptr[b + 1] - block_slot_ptr[start] > CHUNK_ENTRIES && b > start {
                chunk_ptr.push(b);
                start = b;
            }
        }
        if nb > 0 {
            chunk_ptr.push(nb);
        }

        // Greedy colouring (blocks of one colour share no DOF).
        let mut colour = vec![usize::MAX; nb];
        let mut used = Vec::<usize>::new(); // used[c] == b  <=> colour c taken by a neighbour of b
        let mut ncolours = 0usize;
        for b in 0..nb {
            for &d in &block_dofs[block_dof_ptr[b]..block_dof_ptr[b + 1]] {
                for &(nbk, _) in &inc[inc_ptr[d]..inc_ptr[d + 1]] {
                    let c = colour[nbk];
                    if c != usize::MAX {
                        used[c] = b;
                    }
                }
            }
            let c = (0..ncolours).find(|&c| used[c] != b).unwrap_or(ncolours);
            if c == ncolours {
                ncolours += 1;
                used.push(usize::MAX);
            }
            colour[b] = c;
        }
        let mut colour_ptr = vec![0usize; ncolours + 1];
        for &c in &colour {
            colour_ptr[c + 1] += 1;
        }
        for c in 0..ncolours {
            colour_ptr[c + 1] += colour_ptr[c];
        }
        let mut colour_blocks = vec![0usize; nb];
        {
            let mut next = colour_ptr.clone();
            for (b, &c) in colour.iter().enumerate() {
                colour_blocks[next[c]] = b;
                next[c] += 1;
            }
        }

        let symbolic = SymbolicSparseColMat::<usize>::new_checked(n, n, col_ptr, None, row_idx);
        Ok(Self {
            n,
            symbolic,
            block_dof_ptr,
            block_dofs,
            block_slot_ptr,
            block_slot_data,
            diag,
            chunk_ptr,
            colour_ptr,
            colour_blocks,
        })
    }

    /// Matrix dimension.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.symbolic.row_idx().len()
    }

    /// Number of blocks.
    pub fn num_blocks(&self) -> usize {
        self.block_dof_ptr.len() - 1
    }

    /// Global DOFs of block `b`.
    ///
    /// # Panics
    /// If `b >= num_blocks()`.
    pub fn block_dofs(&self, b: usize) -> &[usize] {
        &self.block_dofs[self.block_dof_ptr[b]..self.block_dof_ptr[b + 1]]
    }

    /// Value slots of block `b`, row-major over its local indices: entry `(a, c)` of the
    /// local matrix goes to `values[block_slots(b)[a * m + c] as usize]`, `m` the block size.
    ///
    /// # Panics
    /// If `b >= num_blocks()`.
    pub fn block_slots(&self, b: usize) -> &[Slot] {
        &self.block_slot_data[self.block_slot_ptr[b]..self.block_slot_ptr[b + 1]]
    }

    /// Slot of entry `(i, j)` (binary search in column `j`), `None` if not stored.
    pub fn slot(&self, i: usize, j: usize) -> Option<usize> {
        if i >= self.n || j >= self.n {
            return None;
        }
        let cp = self.symbolic.col_ptr();
        let rows = &self.symbolic.row_idx()[cp[j]..cp[j + 1]];
        rows.binary_search(&i).ok().map(|k| cp[j] + k)
    }

    /// Slot of the diagonal entry `(i, i)`.
    ///
    /// # Panics
    /// If `i >= n()`.
    pub fn diag_slot(&self, i: usize) -> usize {
        self.diag[i]
    }

    /// CSC column pointers (`n + 1` entries).
    pub fn col_ptr(&self) -> &[usize] {
        self.symbolic.col_ptr()
    }

    /// CSC row indices, sorted within each column.
    pub fn row_idx(&self) -> &[usize] {
        self.symbolic.row_idx()
    }

    /// Number of colours of the block colouring used by parallel assembly.
    pub fn num_colours(&self) -> usize {
        self.colour_ptr.len() - 1
    }

    /// faer view of the pattern.
    pub fn faer_symbolic(&self) -> faer::sparse::SymbolicSparseColMatRef<'_, usize> {
        self.symbolic.as_ref()
    }
}

// ---------------------------------------------------------------------------------------
// Matrix
// ---------------------------------------------------------------------------------------

/// Values over a shared [`SparsePattern`] (CSC order).
#[derive(Debug, Clone)]
pub struct SparseMatrix {
    pattern: Arc<SparsePattern>,
    values: Vec<f64>,
    /// Reused assembly buffers (two chunks, double-buffered).
    buffer: Vec<f64>,
}

/// `*mut f64` that may cross threads; used only where writes are provably disjoint.
#[derive(Clone, Copy)]
struct SharedMut(*mut f64);
// SAFETY: only used for colour-disjoint scatter (see `assemble_coloured`).
unsafe impl Send for SharedMut {}
unsafe impl Sync for SharedMut {}

/// Per-thread cache of user scratch values for parallel assembly.
struct ScratchPool<S> {
    slots: Vec<Mutex<Option<S>>>,
}

impl<S> ScratchPool<S> {
    fn new() -> Self {
        let k = rayon::current_num_threads() + 1;
        Self {
            slots: (0..k).map(|_| Mutex::new(None)).collect(),
        }
    }

    /// Runs `body` with this thread's scratch (created by `init` on first use). Falls
    /// back to a fresh scratch when the slot is busy (re-entrant work stealing).
    fn with<R>(&self, init: &(impl Fn() -> S + Sync), body: impl FnOnce(&mut S) -> R) -> R {
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
        let n = self.pattern.n;
        check_len(n, x.len())?;
        check_len(n, y.len())?;
        let cp = self.pattern.symbolic.col_ptr();
        let ri = self.pattern.symbolic.row_idx();
        y.fill(0.0);
        for j in 0..n {
            let xj = x[j];
            if xj != 0.0 {
                for k in cp[j]..cp[j + 1] {
                    y[ri[k]] += self.values[k] * xj;
                }
            }
        }
        Ok(())
    }

    /// `y = A^T x`.
    pub fn mul_vec_transpose(&self, x: &[f64], y: &mut [f64]) -> Result<()> {
        let n = self.pattern.n;
        check_len(n, x.len())?;
        check_len(n, y.len())?;
        let cp = self.pattern.symbolic.col_ptr();
        let ri = self.pattern.symbolic.row_idx();
        for (j, yj) in y.iter_mut().enumerate() {
            let mut s = 0.0;
            for k in cp[j]..cp[j + 1] {
                s += self.values[k] * x[ri[k]];
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

    /// Coloured parallel assembly (blocks of one colour scatter concurrently, colours in
    /// sequence). Deterministic for any thread count, but the summation order differs
    /// from block order. Kept for comparison (see module docs).
    #[doc(hidden)]
    pub fn assemble_blocks_coloured<F>(&mut self, f: F)
    where
        F: Fn(usize, &mut [f64]) + Sync,
    {
        use rayon::prelude::*;
        let pat = &*self.pattern;
        let ptr = SharedMut(self.values.as_mut_ptr());
        for c in 0..pat.num_colours() {
            let blocks = &pat.colour_blocks[pat.colour_ptr[c]..pat.colour_ptr[c + 1]];
            blocks
                .par_iter()
                .for_each_init(Vec::new, |local: &mut Vec<f64>, &b| {
                    let slots = pat.block_slots(b);
                    local.clear();
                    local.resize(slots.len(), 0.0);
                    f(b, local);
                    let p = ptr;
                    for (&s, &v) in slots.iter().zip(local.iter()) {
                        // SAFETY: blocks of one colour share no DOF, hence no slot; slots are
                        // < nnz = values.len().
                        unsafe { *p.0.add(s as usize) += v };
                    }
                });
        }
    }
}

/// Evaluates blocks `b0..b1` into `buf` (laid out as their slots), recursively in parallel.
fn eval_range<S, E, I, F>(
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

// ---------------------------------------------------------------------------------------
// Solver
// ---------------------------------------------------------------------------------------

/// Factorization used by [`LinearSolver`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum FactorKind {
    /// Sparse LU with partial pivoting (COLAMD column ordering). Any nonsingular matrix.
    #[default]
    Lu,
    /// Sparse Cholesky `L L^T` (AMD ordering), symmetric positive definite matrices only;
    /// reads the lower triangle.
    Llt,
    /// Sparse `L D L^T` without pivoting (AMD ordering), symmetric matrices with
    /// nonzero pivots (e.g. quasi-definite); reads the lower triangle.
    Ldlt,
}

/// Options of [`LinearSolver`].
#[derive(Debug, Clone, Copy)]
pub struct SolverOptions {
    /// Factorization kind.
    pub kind: FactorKind,
    /// Parallelism of the numeric factorization.
    pub factor_par: Par,
    /// Parallelism of the triangular solves.
    pub solve_par: Par,
    /// After each factorization, solve once with a vector of ones and fail with
    /// [`LinalgError::Singular`] if the result is not finite (costs one solve).
    pub check_finite: bool,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self {
            kind: FactorKind::Lu,
            factor_par: Par::Seq,
            solve_par: Par::Seq,
            check_finite: true,
        }
    }
}

/// Cost counters of a [`LinearSolver`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SolverStats {
    /// Symbolic factorizations (1 per solver).
    pub symbolic: usize,
    /// Successful numeric factorizations.
    pub numeric: usize,
    /// Calls of the solve functions (a multi-column solve counts once).
    pub solve_calls: usize,
    /// Right-hand-side columns solved.
    pub solve_columns: usize,
}

enum SymbolicFactor {
    Lu(SymbolicLu<usize>),
    Cholesky(SymbolicCholesky<usize>),
}

enum NumericFactor {
    None,
    Lu(NumericLu<usize, f64>),
    Llt(Vec<f64>),
    Ldlt(Vec<f64>),
}

/// Sparse direct solver on a fixed pattern: symbolic analysis once, numeric
/// factorization per matrix, many right-hand sides per solve.
pub struct LinearSolver {
    pattern: Arc<SparsePattern>,
    options: SolverOptions,
    symbolic: SymbolicFactor,
    numeric: NumericFactor,
    /// Kept between factorizations (the numeric LU storage is reused too).
    factor_mem: Option<MemBuffer>,
    symbolic_count: usize,
    numeric_count: usize,
    solve_calls: AtomicUsize,
    solve_columns: AtomicUsize,
}

impl std::fmt::Debug for LinearSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LinearSolver")
            .field("n", &self.pattern.n)
            .field("options", &self.options)
            .field("stats", &self.stats())
            .finish_non_exhaustive()
    }
}

fn faer_err(e: impl std::fmt::Debug) -> LinalgError {
    LinalgError::Faer(format!("{e:?}"))
}

impl LinearSolver {
    /// LU solver with default options; runs the symbolic analysis.
    pub fn new(pattern: Arc<SparsePattern>) -> Result<Self> {
        Self::with_options(pattern, SolverOptions::default())
    }

    /// Solver with the given options; runs the symbolic analysis.
    pub fn with_options(pattern: Arc<SparsePattern>, options: SolverOptions) -> Result<Self> {
        let a = pattern.symbolic.as_ref();
        let symbolic = match options.kind {
            FactorKind::Lu => {
                SymbolicFactor::Lu(factorize_symbolic_lu(a, Default::default()).map_err(faer_err)?)
            }
            FactorKind::Llt | FactorKind::Ldlt => SymbolicFactor::Cholesky(
                factorize_symbolic_cholesky(
                    a,
                    Side::Lower,
                    SymmetricOrdering::Amd,
                    Default::default(),
                )
                .map_err(faer_err)?,
            ),
        };
        Ok(Self {
            pattern,
            options,
            symbolic,
            numeric: NumericFactor::None,
            factor_mem: None,
            symbolic_count: 1,
            numeric_count: 0,
            solve_calls: AtomicUsize::new(0),
            solve_columns: AtomicUsize::new(0),
        })
    }

    /// The pattern.
    pub fn pattern(&self) -> &Arc<SparsePattern> {
        &self.pattern
    }

    /// Options in use.
    pub fn options(&self) -> &SolverOptions {
        &self.options
    }

    /// Number of symbolic analyses run (always 1: done in the constructor).
    pub fn symbolic_count(&self) -> usize {
        self.symbolic_count
    }

    /// Number of successful numeric factorizations.
    pub fn factor_count(&self) -> usize {
        self.numeric_count
    }

    /// Number of right-hand-side columns solved.
    pub fn solve_count(&self) -> usize {
        self.solve_columns.load(Ordering::Relaxed)
    }

    /// All counters.
    pub fn stats(&self) -> SolverStats {
        SolverStats {
            symbolic: self.symbolic_count,
            numeric: self.numeric_count,
            solve_calls: self.solve_calls.load(Ordering::Relaxed),
            solve_columns: self.solve_columns.load(Ordering::Relaxed),
        }
    }

    /// Whether a numeric factorization is available.
    pub fn is_factored(&self) -> bool {
        !matches!(self.numeric, NumericFactor::None)
    }

    /// Numeric factorization of `a`, reusing the symbolic analysis. On error the
    /// previous factorization is discarded.
    pub fn factor(&mut self, a: &SparseMatrix) -> Result<()> {
        if !Arc::ptr_eq(&a.pattern, &self.pattern) {
            return Err(LinalgError::PatternMismatch);
        }
        let par = self.options.factor_par;
        let mat = a.as_faer();
        let numeric = std::mem::replace(&mut self.numeric, NumericFactor::None);
        let mem = self.factor_mem.take();
        let (numeric, mem) = match &self.symbolic {
            SymbolicFactor::Lu(sym) => {
                let mut lu = match numeric {
                    NumericFactor::Lu(lu) => lu,
                    _ => NumericLu::new(),
                };
                let req = sym.factorize_numeric_lu_scratch::<f64>(par, Default::default());
                let mut mem = reuse_mem(mem, req)?;
                sym.factorize_numeric_lu(
                    &mut lu,
                    mat,
                    par,
                    MemStack::new(&mut mem),
                    Default::default(),
                )
                .map_err(|e| match e {
                    LuError::SymbolicSingular { index } => {
                        LinalgError::Singular { index: Some(index) }
                    }
                    e => faer_err(e),
                })?;
                (NumericFactor::Lu(lu), mem)
            }
            SymbolicFactor::Cholesky(sym) => {
                let mut l = match numeric {
                    NumericFactor::Llt(v) | NumericFactor::Ldlt(v) => v,
                    _ => Vec::new(),
                };
                l.resize(sym.len_val(), 0.0);
                if self.options.kind == FactorKind::Llt {
                    let req = sym.factorize_numeric_llt_scratch::<f64>(par, Default::default());
                    let mut mem = reuse_mem(mem, req)?;
                    sym.factorize_numeric_llt(
                        &mut l,
                        mat,
                        Side::Lower,
                        LltRegularization::default(),
                        par,
                        MemStack::new(&mut mem),
                        Default::default(),
                    )
                    .map_err(|e| match e {
                        LltError::NonPositivePivot { index } => {
                            LinalgError::NotPositiveDefinite { index }
                        }
                    })?;
                    (NumericFactor::Llt(l), mem)
                } else {
                    let req = sym.factorize_numeric_ldlt_scratch::<f64>(par, Default::default());
                    let mut mem = reuse_mem(mem, req)?;
                    sym.factorize_numeric_ldlt(
                        &mut l,
                        mat,
                        Side::Lower,
                        LdltRegularization::default(),
                        par,
                        MemStack::new(&mut mem),
                        Default::default(),
                    )
                    .map_err(|e| match e {
                        LdltError::ZeroPivot { index } => {
                            LinalgError::NotPositiveDefinite { index }
                        }
                    })?;
                    (NumericFactor::Ldlt(l), mem)
                }
            }
        };
        self.numeric = numeric;
        self.factor_mem = Some(mem);
        if self.options.check_finite {
            let mut ones = vec![1.0; self.pattern.n];
            self.solve_raw(
                MatMut::from_column_major_slice_mut(&mut ones, self.pattern.n, 1),
                false,
            )?;
            if !ones.iter().all(|v| v.is_finite()) {
                self.numeric = NumericFactor::None;
                return Err(LinalgError::Singular { index: None });
            }
        }
        self.numeric_count += 1;
        Ok(())
    }

    fn solve_raw(&self, rhs: MatMut<'_, f64>, transpose: bool) -> Result<()> {
        let par = self.options.solve_par;
        let k = rhs.ncols();
        match (&self.symbolic, &self.numeric) {
            (_, NumericFactor::None) => return Err(LinalgError::NotFactored),
            (SymbolicFactor::Lu(sym), NumericFactor::Lu(lu)) => {
                let lu = faer::sparse::linalg::lu::LuRef::new_unchecked(sym, lu);
                let mut mem = MemBuffer::try_new(sym.solve_in_place_scratch::<f64>(k, par))
                    .map_err(faer_err)?;
                let stack = MemStack::new(&mut mem);
                if transpose {
                    lu.solve_transpose_in_place_with_conj(Conj::No, rhs, par, stack);
                } else {
                    lu.solve_in_place_with_conj(Conj::No, rhs, par, stack);
                }
            }
            (SymbolicFactor::Cholesky(sym), NumericFactor::Llt(l)) => {
                let mut mem = MemBuffer::try_new(sym.solve_in_place_scratch::<f64>(k, par))
                    .map_err(faer_err)?;
                faer::sparse::linalg::cholesky::LltRef::new(sym, l).solve_in_place_with_conj(
                    Conj::No,
                    rhs,
                    par,
                    MemStack::new(&mut mem),
                );
            }
            (SymbolicFactor::Cholesky(sym), NumericFactor::Ldlt(l)) => {
                let mut mem = MemBuffer::try_new(sym.solve_in_place_scratch::<f64>(k, par))
                    .map_err(faer_err)?;
                faer::sparse::linalg::cholesky::LdltRef::new(sym, l).solve_in_place_with_conj(
                    Conj::No,
                    rhs,
                    par,
                    MemStack::new(&mut mem),
                );
            }
            _ => unreachable!("numeric factor kind always matches the symbolic one"),
        }
        Ok(())
    }

    fn count(&self, cols: usize) {
        self.solve_calls.fetch_add(1, Ordering::Relaxed);
        self.solve_columns.fetch_add(cols, Ordering::Relaxed);
    }

    /// Solves `A x = rhs` in place (one column).
    pub fn solve_in_place(&self, rhs: &mut [f64]) -> Result<()> {
        self.solve_multi_in_place(rhs, 1)
    }

    /// Solves `A X = RHS` in place for `ncols` columns stored column-major in `rhs`
    /// (`rhs.len() == n * ncols`), in one call.
    pub fn solve_multi_in_place(&self, rhs: &mut [f64], ncols: usize) -> Result<()> {
        let n = self.pattern.n;
        check_len(n * ncols, rhs.len())?;
        self.solve_mat_in_place(MatMut::from_column_major_slice_mut(rhs, n, ncols))
    }

    /// Solves `A X = RHS` in place for all columns of a faer matrix, in one call.
    pub fn solve_mat_in_place(&self, rhs: MatMut<'_, f64>) -> Result<()> {
        check_len(self.pattern.n, rhs.nrows())?;
        let k = rhs.ncols();
        self.solve_raw(rhs, false)?;
        self.count(k);
        Ok(())
    }

    /// Solves `A^T X = RHS` in place (column-major, `ncols` columns), e.g. for adjoint
    /// sensitivities. Same cost as [`LinearSolver::solve_multi_in_place`].
    pub fn solve_transpose_multi_in_place(&self, rhs: &mut [f64], ncols: usize) -> Result<()> {
        let n = self.pattern.n;
        check_len(n * ncols, rhs.len())?;
        // Cholesky factors are of symmetric matrices: A^T = A.
        let transpose = matches!(self.symbolic, SymbolicFactor::Lu(_));
        self.solve_raw(
            MatMut::from_column_major_slice_mut(rhs, n, ncols),
            transpose,
        )?;
        self.count(ncols);
        Ok(())
    }

    /// Iterative refinement of `x` for `a x = b`, with the stored factorization (possibly
    /// of another matrix) as preconditioner: `steps` times `x += LU^{-1} (b - a x)`.
    /// Returns the final relative residual `|b - a x| / |b|` (absolute if `b = 0`).
    pub fn refine(&self, a: &SparseMatrix, b: &[f64], x: &mut [f64], steps: usize) -> Result<f64> {
        self.refine_multi(a, b, x, 1, steps)
    }

    /// [`LinearSolver::refine`] for `ncols` column-major columns, all columns solved in
    /// one call per step. Returns the largest relative residual over the columns.
    pub fn refine_multi(
        &self,
        a: &SparseMatrix,
        b: &[f64],
        x: &mut [f64],
        ncols: usize,
        steps: usize,
    ) -> Result<f64> {
        let n = self.pattern.n;
        check_len(a.n(), n)?;
        check_len(n * ncols, b.len())?;
        check_len(n * ncols, x.len())?;
        let mut r = vec![0.0; n * ncols];
        let residual = |x: &[f64], r: &mut [f64]| -> Result<f64> {
            let mut worst = 0.0f64;
            for c in 0..ncols {
                let (xc, bc) = (&x[c * n..(c + 1) * n], &b[c * n..(c + 1) * n]);
                let rc = &mut r[c * n..(c + 1) * n];
                a.mul_vec(xc, rc)?;
                let (mut rr, mut bb) = (0.0, 0.0);
                for (ri, &bi) in rc.iter_mut().zip(bc) {
                    *ri = bi - *ri;
                    rr += *ri * *ri;
                    bb += bi * bi;
                }
                let rel = if bb > 0.0 {
                    (rr / bb).sqrt()
                } else {
                    rr.sqrt()
                };
                worst = worst.max(rel);
            }
            Ok(worst)
        };
        let mut res = residual(x, &mut r)?;
        for _ in 0..steps {
            self.solve_multi_in_place(&mut r, ncols)?;
            for (xi, ri) in x.iter_mut().zip(&r) {
                *xi += ri;
            }
            res = residual(x, &mut r)?;
        }
        Ok(res)
    }
}

fn reuse_mem(mem: Option<MemBuffer>, req: faer::dyn_stack::StackReq) -> Result<MemBuffer> {
    // MemBuffer does not expose its size: reallocate when the requirement changes is
    // not detectable, so keep one buffer sized for this solver's (fixed) requirement.
    match mem {
        Some(m) => Ok(m),
        None => MemBuffer::try_new(req).map_err(faer_err),
    }
}
