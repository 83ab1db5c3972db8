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
//!    Cholesky structure, [`crate::linalg::symlu`]; faer's LU: COLAMD column ordering + symbolic
//!    LU, built only if a matrix is declined; LLT/LDLT: AMD + symbolic Cholesky).
//!    [`LinearSolver::symbolic_count`] stays 1 ([`LinearSolver::sibling`] shares the
//!    analysis: 0). [`LinearSolver::with_fixed`] analyses and factors the free unknowns'
//!    system alone, for matrices whose prescribed rows and columns are the identity's
//!    (Newton's: a plane-strain model's factorizations take a third to a quarter of the
//!    time, the paper's indentation 3.7 times less).
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
//!
//! Measured costs and the parallelism choices behind the defaults: `benches/README.md`.
//!
//! # Notes
//! - The pattern is made structurally symmetric (an extra `(i, j)` also stores `(j, i)`),
//!   which Dirichlet elimination and the Cholesky path rely on.
//! - LU: pivoting within the diagonal blocks of the symmetric-pattern LU; a matrix it
//!   declines (a multiplier above [`crate::linalg::symlu::MAX_MULTIPLIER`], a zero pivot) goes to
//!   faer's supernodal/simplicial LU with partial pivoting. A numerically singular matrix
//!   gives non-finite factors there, caught by the finiteness check.
//! - LLT/LDLT read the lower triangle only; the values must be symmetric (not checked).

mod direct;
mod krylov;
mod matrix;
mod pattern;
pub mod symlu;

pub use direct::*;
pub(crate) use krylov::*;
pub use matrix::*;
pub use pattern::*;

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
    /// A solver that leaves out fixed unknowns ([`LinearSolver::with_fixed`]) was given a
    /// matrix whose row or column of one of them is not the identity's.
    #[error("entry ({row}, {col}) of the matrix is not the identity's, though unknown {unknown} is fixed")]
    FixedNotIdentity {
        /// The fixed unknown.
        unknown: usize,
        /// Row of the entry.
        row: usize,
        /// Column of the entry.
        col: usize,
    },
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

#[cfg(test)]
mod tests;
