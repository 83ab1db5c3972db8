//! Global sparse system of the Newton solver: fixed pattern, block assembly, sparse LU
//! (or Cholesky) whose symbolic analysis is reused over a whole run, multi-column solves.
//!
//! # Terms
//! - *block*: the list of global DOFs of one element (or any group of coupled DOFs);
//!   all pairs `(i, j)` within a block are stored. Repeated DOFs within a block are summed.
//! - *slot*: position of a stored entry in [`SparseMatrix::values`] (CSC order).
//!   [`SparsePattern::block_slots`] gives, for block `b` with `m` DOFs, the `m * m` slots
//!   of its local matrix, row-major: assembling is `values[slots[k]] += local[k]`.
//!
//! # Once per run (pattern fixed: include every candidate contact pair)
//! 1. [`SparsePattern::new`]: CSC pattern (structurally symmetric, full diagonal), the
//!    per-block slot tables (4 bytes per element-matrix entry: 30k hex8 blocks = 69 MB)
//!    and the assembly chunks.
//! 2. [`LinearSolver::new`] / [`LinearSolver::with_options`]: symbolic analysis (LU:
//!    AMD on the pattern, Lagrange multipliers after their neighbours, supernodes of the
//!    Cholesky structure, [`crate::symlu`]; faer's LU: COLAMD column ordering + symbolic
//!    LU, built only if a matrix is declined; LLT/LDLT: AMD + symbolic Cholesky).
//!    [`LinearSolver::symbolic_count`] stays 1.
//!
//! # Per Newton iteration
//! 1. [`SparseMatrix::zero`], then [`SparseMatrix::assemble_blocks_par`] (or
//!    [`SparseMatrix::try_assemble_blocks_par_with`] with per-thread scratch and
//!    fallible kernels), [`SparseMatrix::add`] for single entries.
//! 2. [`SparseMatrix::apply_dirichlet`] (or [`SparseMatrix::set_identity_row_col`]).
//! 3. [`LinearSolver::factor`]: numeric factorization only (storage reused).
//! 4. [`LinearSolver::solve_in_place`] for the Newton step; design sensitivities:
//!    [`LinearSolver::solve_multi_in_place`], all pseudo-loads in one call;
//!    [`LinearSolver::refine`] / [`LinearSolver::refine_multi`] for iterative
//!    refinement against another matrix (the "refined" tangent option);
//!    [`LinearSolver::solve_transpose_multi_in_place`] for adjoints.
//! 5. [`LinearSolver::stats`]: symbolic / numeric / solve counters for the cost ledger.
//!
//! # Measured costs (release, this 2-core machine, best of several interleaved runs)
//! The table below is faer's LU ([`FactorKind::LuColamd`], the default until the
//! symmetric-pattern LU). On the leaf spring's tangent (2,662 unknowns, 164,032 entries,
//! multipliers of closed contacts included) the default [`FactorKind::Lu`] factors in
//! 2.0 ms against 14.2 ms and solves one column in 0.16 ms against 0.25 ms, with
//! residuals of 1e-12 for both.
//! Structured hex8 meshes, 3 DOFs per node, blocks of 24 DOFs (27-node stencil).
//! Times from `timing_hex8_pattern` (`cargo test --release -- --ignored --nocapture`);
//! the machine was shared, spreads are over three runs.
//!
//! | n (DOF) | nnz/row | symbolic LU | numeric LU Seq | numeric LU rayon(2) | solve 1 col | solve 10 cols |
//! |--------:|--------:|------------:|---------------:|--------------------:|------------:|--------------:|
//! |   2 187 |      64 |       14 ms |          26 ms |               35 ms |      1.0 ms | 1.8 (Seq) / 3.6-4.9 (rayon) ms |
//! |   8 232 |      70 |      100 ms |         193 ms |              228 ms |      5.2 ms | 10 (Seq) / 14.5 (rayon) ms |
//! |  31 944 |      74 |   0.67-1.0 s |     2.7-3.2 s |          2.4-2.8 s |  37-39 ms | 79-86 (Seq and rayon) ms |
//!
//! Cholesky LLT (symmetric values), n = 31 944: symbolic 105 ms, numeric 1.31-1.41 s Seq,
//! 0.83 s rayon(2); n = 8 232: 68 ms Seq, 74 ms rayon; solves cost the same as with LU.
//! One refinement step (mat-vec + solve) ~ one solve; `mul_vec` 2 ms at n = 31 944.
//! Factor/solve ratio ~70 (LU, 32k DOF): ten right-hand sides in one call cost ~2 single
//! solves. [`SolverOptions::check_finite`] (on by default) adds one solve per factorization.
//!
//! # Parallelism choice
//! - Triangular solves: `Par::Seq` (default). rayon(2) was never faster and up to 2.7x
//!   slower for multi-column solves on small systems.
//! - Numeric factorization: rayon pays only on large systems (LU -5..-15 %, LLT -40 % at
//!   32k DOF) and costs +20..+75 % below ~10k DOF, so `factor_par: None` picks
//!   `Par::rayon(0)` for `n >= PAR_FACTOR_MIN_N` (20 000) and `Par::Seq` below.
//!   faer's `Par::Rayon` runs in the current rayon pool. Caveat: in two runs where other
//!   builds shared the cores, rayon(2) was 15-25 % *slower* at 32k DOF (LU and LLT) and
//!   parallel assembly gained nothing; pass `factor_par: Some(Par::Seq)` when the cores
//!   are shared or the caller already runs solvers in parallel.
//! - Assembly (29 791 blocks of 24x24, n = 98 304, nnz 7.5 M; pattern build ~0.2 s):
//!
//!   | kernel                   | sequential `add_block` | buffered, 1 thr | buffered, 2 thr | coloured, 1 thr | coloured, 2 thr |
//!   |--------------------------|-----------------------:|----------------:|----------------:|----------------:|----------------:|
//!   | fill only                |               61-71 ms |        57-84 ms |           36 ms |          115 ms |        49-57 ms |
//!   | B^T D B, 8 points        |             200-215 ms |      208-225 ms |      137-145 ms |      239-254 ms |      126-147 ms |
//!
//!   "Buffered" (kept): local matrices of a chunk of blocks (~2 MB) are evaluated in
//!   parallel into a buffer laid out like the slot tables, then added sequentially in
//!   block order while the next chunk is evaluated. "Coloured" (removed): greedy colouring
//!   (8 colours), blocks of one colour scattered concurrently. Equal at 2 threads within
//!   noise, buffered better at 1 thread, needs no `unsafe`, and is bit-identical to the
//!   sequential `add_block` loop for any thread count (coloured is only deterministic).
//!
//! # Notes
//! - The pattern is made structurally symmetric (an extra `(i, j)` also stores `(j, i)`),
//!   which Dirichlet elimination and the Cholesky path rely on.
//! - LU: pivoting within the diagonal blocks of the symmetric-pattern LU; a matrix it
//!   declines (a multiplier above [`crate::symlu::MAX_MULTIPLIER`], a zero pivot) goes to
//!   faer's supernodal/simplicial LU with partial pivoting. A numerically singular matrix
//!   gives non-finite factors there, caught by the finiteness check.
//! - LLT/LDLT read the lower triangle only; the values must be symmetric (not checked).

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

use crate::symlu::{NumericSymLu, SymbolicSymLu};

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
    /// The LLT factorization met a non-positive pivot (LDLT zero pivots give
    /// [`LinalgError::Singular`]).
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
    /// Unknowns from here on are Lagrange multipliers: their diagonal can be zero, so
    /// [`FactorKind::Lu`] eliminates each after the other unknowns it couples to.
    multipliers_from: usize,
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
            multipliers_from: n,
        })
    }

    /// Marks the unknowns `first..n` as Lagrange multipliers (zero diagonals in
    /// saddle-point systems). [`FactorKind::Lu`] orders each after every other unknown it
    /// is coupled to, so that its pivot is the Schur complement `-B K^-1 B^T` rather than
    /// its zero diagonal.
    pub fn with_multipliers_from(mut self, first: usize) -> Self {
        self.multipliers_from = first.min(self.n);
        self
    }

    /// First Lagrange multiplier (`n` when there are none).
    pub fn multipliers_from(&self) -> usize {
        self.multipliers_from
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
                // -a x = p + e exactly
                let p = -a * xj;
                let e = (-a).mul_add(xj, -p);
                // hi + p = s + t exactly
                let s = r[i] + p;
                let bp = s - r[i];
                let t = (r[i] - (s - bp)) + (p - bp);
                r[i] = s;
                lo[i] += t + e;
            }
        }
        for (ri, l) in r.iter_mut().zip(&lo) {
            *ri += l;
        }
        Ok(())
    }

    /// `y = |A| |x|`, entrywise absolute values (round-off bounds such as `eps |A| |x|`).
    pub fn abs_mul_vec(&self, x: &[f64], y: &mut [f64]) -> Result<()> {
        self.mul_vec_mapped(x, y, f64::abs)
    }

    /// `y = f(A) f(x)`, `f` applied to every entry of both.
    fn mul_vec_mapped(&self, x: &[f64], y: &mut [f64], f: impl Fn(f64) -> f64) -> Result<()> {
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
    /// Supernodal LU on the symmetric pattern (AMD ordering, pivoting within the diagonal
    /// blocks; [`crate::symlu`]). A matrix it declines (a multiplier above
    /// [`crate::symlu::MAX_MULTIPLIER`], a zero pivot) is factored by faer's LU with
    /// partial pivoting instead, counted in [`SolverStats::declined`]. Any nonsingular
    /// matrix with a structurally symmetric pattern.
    #[default]
    Lu,
    /// faer's sparse LU with partial pivoting over all rows (COLAMD column ordering), for
    /// every matrix: the reference of [`FactorKind::Lu`], and 3 to 10 times its cost on
    /// finite element tangents.
    LuColamd,
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
    /// Parallelism of the numeric factorization; `None` chooses: `Par::rayon(0)` (all
    /// threads of the current rayon pool) when `n >= PAR_FACTOR_MIN_N` and the pool has
    /// more than one thread, `Par::Seq` otherwise (see the module docs for the numbers).
    pub factor_par: Option<Par>,
    /// Parallelism of the triangular solves (`Par::Seq` measured never slower).
    pub solve_par: Par,
    /// After each factorization, solve once with a vector of ones and fail with
    /// [`LinalgError::Singular`] if the result is not finite (costs one solve).
    pub check_finite: bool,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self {
            kind: FactorKind::Lu,
            factor_par: None,
            solve_par: Par::Seq,
            check_finite: true,
        }
    }
}

/// Smallest dimension for which [`SolverOptions::factor_par`]` = None` factors in parallel.
pub const PAR_FACTOR_MIN_N: usize = 20_000;

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
    /// Factorizations [`FactorKind::Lu`] declined and left to faer's LU.
    pub declined: usize,
}

enum SymbolicFactor {
    /// The symmetric-pattern LU, and faer's (built on the first declined matrix).
    SymLu(Box<SymbolicSymLu>, Option<SymbolicLu<usize>>),
    Lu(SymbolicLu<usize>),
    Cholesky(SymbolicCholesky<usize>),
}

enum NumericFactor {
    None,
    SymLu(Box<NumericSymLu>),
    Lu(Box<NumericLu<usize, f64>>),
    Llt(Vec<f64>),
    Ldlt(Vec<f64>),
}

/// Sparse direct solver on a fixed pattern: symbolic analysis once, numeric
/// factorization per matrix, many right-hand sides per solve.
pub struct LinearSolver {
    pattern: Arc<SparsePattern>,
    options: SolverOptions,
    factor_par: Par,
    symbolic: SymbolicFactor,
    numeric: NumericFactor,
    /// Kept between factorizations (the numeric LU storage is reused too).
    factor_mem: Option<MemBuffer>,
    symbolic_count: usize,
    numeric_count: usize,
    declined: usize,
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
            FactorKind::Lu => SymbolicFactor::SymLu(
                Box::new(
                    SymbolicSymLu::new(a, pattern.multipliers_from).map_err(LinalgError::Faer)?,
                ),
                None,
            ),
            FactorKind::LuColamd => {
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
        let factor_par = options.factor_par.unwrap_or_else(|| {
            if pattern.n >= PAR_FACTOR_MIN_N && rayon::current_num_threads() > 1 {
                Par::rayon(0)
            } else {
                Par::Seq
            }
        });
        Ok(Self {
            pattern,
            options,
            factor_par,
            symbolic,
            numeric: NumericFactor::None,
            factor_mem: None,
            symbolic_count: 1,
            numeric_count: 0,
            declined: 0,
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

    /// Parallelism used by [`LinearSolver::factor`] (resolved from the options).
    pub fn factor_par(&self) -> Par {
        self.factor_par
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
            declined: self.declined,
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
        let par = self.factor_par;
        let mat = a.as_faer();
        let numeric = std::mem::replace(&mut self.numeric, NumericFactor::None);
        let mem = self.factor_mem.take();
        let numeric = if let SymbolicFactor::SymLu(sym, colamd) = &mut self.symbolic {
            let mut num = match numeric {
                NumericFactor::SymLu(num) => num,
                _ => Box::default(),
            };
            if sym.factor(mat, &mut num, par).is_ok() {
                self.numeric = NumericFactor::SymLu(num);
                self.factor_mem = mem;
                return self.finish_factor();
            }
            self.declined += 1;
            if colamd.is_none() {
                *colamd = Some(
                    factorize_symbolic_lu(self.pattern.symbolic.as_ref(), Default::default())
                        .map_err(faer_err)?,
                );
            }
            NumericFactor::None
        } else {
            numeric
        };
        let (numeric, mem) = match &self.symbolic {
            SymbolicFactor::SymLu(_, Some(sym)) | SymbolicFactor::Lu(sym) => {
                let mut lu = match numeric {
                    NumericFactor::Lu(lu) => lu,
                    _ => Box::new(NumericLu::new()),
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
                            LinalgError::Singular { index: Some(index) }
                        }
                    })?;
                    (NumericFactor::Ldlt(l), mem)
                }
            }
            SymbolicFactor::SymLu(_, None) => unreachable!("faer's LU analysed on a decline"),
        };
        self.numeric = numeric;
        self.factor_mem = Some(mem);
        self.finish_factor()
    }

    /// The finiteness check and the count, after a numeric factorization.
    fn finish_factor(&mut self) -> Result<()> {
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
            (SymbolicFactor::SymLu(sym, _), NumericFactor::SymLu(num)) => {
                sym.solve_in_place(num, rhs, transpose);
            }
            (SymbolicFactor::SymLu(_, Some(sym)), NumericFactor::Lu(lu))
            | (SymbolicFactor::Lu(sym), NumericFactor::Lu(lu)) => {
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
        let transpose = matches!(
            self.symbolic,
            SymbolicFactor::Lu(_) | SymbolicFactor::SymLu(..)
        );
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
        let mut res = worst(&residuals(a, b, x, &mut r, ncols)?);
        for _ in 0..steps {
            self.solve_multi_in_place(&mut r, ncols)?;
            for (xi, ri) in x.iter_mut().zip(&r) {
                *xi += ri;
            }
            res = worst(&residuals(a, b, x, &mut r, ncols)?);
        }
        Ok(res)
    }

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
    pub fn gmres_multi(
        &self,
        a: &SparseMatrix,
        rhs: &mut [f64],
        ncols: usize,
        tol: f64,
        max_iter: usize,
    ) -> Result<KrylovReport> {
        let n = self.pattern.n;
        check_len(a.n(), n)?;
        check_len(n * ncols, rhs.len())?;
        let b = rhs.to_vec();
        let norm = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>().sqrt();
        let b_norm: Vec<f64> = b.chunks(n.max(1)).map(norm).collect();
        // X0 = M^-1 B, R0 = B - a X0
        self.solve_multi_in_place(rhs, ncols)?;
        // the first solve; each iteration adds its block, the final combination its columns
        let mut solve_columns = ncols;
        let mut r = vec![0.0; n * ncols];
        let start_relative = residuals(a, &b, rhs, &mut r, ncols)?;
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
            self.solve_multi_in_place(&mut z, block.len())?;
            solve_columns += block.len();
            for (k, _) in block.enumerate() {
                a.mul_vec(&z[k * n..(k + 1) * n], &mut w)?;
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
            self.solve_multi_in_place(&mut u, ncols)?;
            solve_columns += ncols;
            for (xi, ui) in rhs.iter_mut().zip(&u) {
                *xi += ui;
            }
            residuals(a, &b, rhs, &mut r, ncols)?
        };
        // a column whose relative residual is above `tol` is still solved when its backward
        // error is that of a stable direct solve (`|K||x|` far above `|b|`: the relative
        // residual a factorization of `a` would reach is no better)
        let mut backward_error = 0.0f64;
        let mut each_ok = true;
        let mut scale = vec![0.0; n];
        for c in 0..ncols {
            let (bc, xc) = (&b[c * n..(c + 1) * n], &rhs[c * n..(c + 1) * n]);
            a.abs_mul_vec(xc, &mut scale)?;
            let den = scale
                .iter()
                .zip(bc)
                .map(|(s, b)| (s + b.abs()).powi(2))
                .sum::<f64>()
                .sqrt();
            // |b - a x|, from the relative residual `residuals` measured
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
const ESTIMATE_MARGIN: f64 = 0.1;

/// A column's start residual whose part outside the basis falls below this fraction of its
/// norm lies in the span of the other columns' (to the round-off of two Gram-Schmidt passes,
/// 1e-16) and is left out of the block Arnoldi basis: the residual left behind is below any
/// tolerance asked. Products are left out only when exactly in the span: with a penalty of
/// 1e9 in a Poisson matrix, leaving out a product's part of 1e-14 of its norm doubled the
/// residual GMRES reached (9.7e-8 against the factorization's 4.5e-8).
pub const DEFLATION: f64 = 1e-14;

/// Normwise backward error `|b - a x| / | |a||x| + |b| |`, in ulps, that
/// [`LinearSolver::gmres_multi`] accepts in place of its relative-residual tolerance: that of
/// a backward-stable direct solve. faer's LU measured 0.39 to 0.46 eps on the stacked leaves'
/// and the cantilever's converged tangents with the pseudo-load in `E` (relative residuals
/// 5e-10 and 2.5e-9, where GMRES preconditioned with Newton's factor reached 0.27 to 0.32 eps).
pub const BACKWARD_STABLE_ULPS: f64 = 1.0;

/// Outcome of [`LinearSolver::gmres_multi`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KrylovReport {
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
struct BlockArnoldi {
    n: usize,
    ncols: usize,
    basis: Vec<Vec<f64>>,
    /// Basis vectors whose product has been taken (the columns of `H` so far).
    processed: usize,
    /// Upper triangular columns of the rotated `H`.
    r: Vec<Vec<f64>>,
    /// Rotations `(i, cs, sn)` of rows `i` and `i + 1`, in the order applied.
    rotations: Vec<(usize, f64, f64)>,
    /// Rotated right-hand sides, row-major: `g[i * ncols + c]`.
    g: Vec<f64>,
}

impl BlockArnoldi {
    fn new(n: usize, ncols: usize) -> Self {
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
    fn orthogonalize(&mut self, w: &mut [f64], h: &mut Vec<f64>, deflation: f64) {
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
    fn start(&mut self, c: usize, residual: &[f64]) {
        let mut w = residual.to_vec();
        let mut h = Vec::new();
        self.orthogonalize(&mut w, &mut h, DEFLATION);
        for (i, hi) in h.iter().enumerate() {
            self.g[i * self.ncols + c] = *hi;
        }
    }

    /// The basis vectors whose product is still to be taken.
    fn unprocessed(&self) -> std::ops::Range<usize> {
        self.processed..self.basis.len()
    }

    /// Every basis vector processed: the space is invariant and holds every solution.
    fn exhausted(&self) -> bool {
        self.processed == self.basis.len()
    }

    /// Column `c`'s least-squares residual over the processed vectors.
    fn estimate(&self, c: usize) -> f64 {
        (self.processed..self.basis.len())
            .map(|i| self.g[i * self.ncols + c].powi(2))
            .sum::<f64>()
            .sqrt()
    }

    /// Take `w = a M^-1 v_j` for the next unprocessed `v_j`: orthogonalize, rotate the new
    /// column of `H` to upper triangular form and the right-hand sides with it.
    fn step(&mut self, w: &mut [f64]) {
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
    fn combine(&self, u: &mut [f64]) {
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

/// `r = b - a x` for `ncols` column-major columns, and each column's relative residual
/// `|r| / |b|` (`|r|` where `b = 0`; NaN for a NaN column).
fn residuals(
    a: &SparseMatrix,
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
            a.mul_vec(xc, rc)?;
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
fn worst(v: &[f64]) -> f64 {
    v.iter()
        .fold(0.0f64, |w, &x| if x.is_nan() || x > w { x } else { w })
}

fn reuse_mem(mem: Option<MemBuffer>, req: faer::dyn_stack::StackReq) -> Result<MemBuffer> {
    // The requirement depends only on the pattern, the kind and the parallelism, all
    // fixed for a solver: the first buffer fits every later factorization.
    match mem {
        Some(m) => Ok(m),
        None => MemBuffer::try_new(req).map_err(faer_err),
    }
}

#[cfg(test)]
// Index loops mirror the matrix formulas in the test oracles.
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;
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
        let (n, mut blocks) = quad_grid(nx, nx);
        let ties: Vec<(usize, usize)> = (0..6).map(|j| (20 + 17 * j, 30 + 13 * j)).collect();
        let m = ties.len();
        for (j, &(p, q)) in ties.iter().enumerate() {
            blocks.push(vec![p, q, n + j]);
        }
        let ke = q1_laplace(0.2);
        let build = |pattern: SparsePattern| {
            let mut a = SparseMatrix::new(Arc::new(pattern));
            for b in 0..nx * nx {
                a.add_block(b, &ke).unwrap();
            }
            for (j, &(p, q)) in ties.iter().enumerate() {
                for (i, v) in [(p, 1.0), (q, -1.0)] {
                    a.add(i, n + j, v).unwrap();
                    a.add(n + j, i, v).unwrap();
                }
            }
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
        let mut changed = a.clone();
        let cp = a.pattern().col_ptr().to_vec();
        for j in [17, 60, 100] {
            for k in cp[j]..cp[j + 1] {
                changed.values_mut()[k] += 2.0 * (1.0 + (k % 3) as f64);
            }
        }
        let mut solver = LinearSolver::new(a.pattern().clone()).unwrap();
        solver.factor(&a).unwrap();
        let bb: Vec<f64> = b
            .iter()
            .copied()
            .chain((0..n).map(|i| (i % 5) as f64))
            .collect();
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
                            .flat_map(|&c| (0..3).map(move |d| 3 * c + d))
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
}
