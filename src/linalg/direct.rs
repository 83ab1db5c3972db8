//! The direct solver: the symbolic analysis done once per run, numeric factorizations (the
//! symmetric-pattern LU of [`super::symlu`], faer's LU, LLT, LDLT), multi-column solves and
//! iterative refinement.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

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

use super::*;
use crate::linalg::symlu::{NumericSymLu, SymbolicSymLu};

/// Factorization used by [`LinearSolver`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum FactorKind {
    /// Supernodal LU on the symmetric pattern (AMD ordering, pivoting within the diagonal
    /// blocks; [`crate::linalg::symlu`]). A matrix it declines (a multiplier above
    /// [`crate::linalg::symlu::MAX_MULTIPLIER`], a zero pivot) is factored by faer's LU with
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
    /// threads of the current rayon pool) when the factored unknowns
    /// ([`LinearSolver::factored_n`]) are at least `PAR_FACTOR_MIN_N` and the pool has
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
    /// Symbolic factorizations (1 per solver, 0 for a [`LinearSolver::sibling`]).
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

/// Shared by a solver's siblings ([`LinearSolver::sibling`]).
#[derive(Clone)]
pub(super) enum SymbolicFactor {
    /// The symmetric-pattern LU, and faer's (built on the first declined matrix).
    SymLu(Arc<SymbolicSymLu>, Option<Arc<SymbolicLu<usize>>>),
    Lu(Arc<SymbolicLu<usize>>),
    Cholesky(Arc<SymbolicCholesky<usize>>),
}

#[derive(Clone)]
pub(super) enum NumericFactor {
    None,
    SymLu(Box<NumericSymLu>),
    Lu(Box<NumericLu<usize, f64>>),
    Llt(Vec<f64>),
    Ldlt(Vec<f64>),
}

/// Sparse direct solver on a fixed pattern: symbolic analysis once, numeric
/// factorization per matrix, many right-hand sides per solve.
pub struct LinearSolver {
    pub(super) pattern: Arc<SparsePattern>,
    pub(super) options: SolverOptions,
    pub(super) factor_par: Par,
    pub(super) symbolic: SymbolicFactor,
    pub(super) numeric: NumericFactor,
    /// Kept between factorizations (the numeric LU storage is reused too).
    pub(super) factor_mem: Option<MemBuffer>,
    pub(super) symbolic_count: usize,
    pub(super) numeric_count: usize,
    pub(super) declined: usize,
    pub(super) solve_calls: AtomicUsize,
    pub(super) solve_columns: AtomicUsize,
    /// The unknowns left out of the factorizations ([`LinearSolver::with_fixed`]), shared
    /// with the siblings.
    pub(super) reduction: Option<Arc<Reduction>>,
    /// The free unknowns' matrix values, gathered at each factorization.
    pub(super) reduced_values: Vec<f64>,
}

/// The unknowns a solver leaves out of its factorizations ([`LinearSolver::with_fixed`]): in
/// every matrix it factors their rows and columns are the identity's (checked), so there the
/// solution is the right-hand side, and elsewhere it solves the free unknowns' system alone.
/// The full LU would eliminate them too, each a pivot of 1 with zero multipliers, on a
/// pattern that still holds their couplings: a plane-strain model's out-of-plane
/// unknowns, a third of all, in every supernode.
pub(super) struct Reduction {
    /// Full index of each free unknown, ascending.
    free: Vec<usize>,
    /// The pattern among the free unknowns: the full one's entries in a free row and a free
    /// column, renumbered.
    symbolic: SymbolicSparseColMat<usize>,
    /// Full value slot of each of its entries, in its column-major order.
    slots: Vec<usize>,
    /// Full value slots in a fixed row or column, off the diagonal (zero in every matrix).
    off: Vec<usize>,
    /// Full value slots of the fixed unknowns' diagonal entries (one in every matrix).
    diag: Vec<usize>,
    /// [`SparsePattern::multipliers_from`] and [`SparsePattern::last_from`] among the free
    /// unknowns.
    multipliers_from: usize,
    last_from: usize,
}

impl Reduction {
    /// The reduction of `pattern` by `fixed`; `None` when nothing is fixed or nothing free.
    fn new(pattern: &SparsePattern, fixed: &[bool]) -> Result<Option<Self>> {
        let n = pattern.n;
        check_len(n, fixed.len())?;
        let free: Vec<usize> = (0..n).filter(|&i| !fixed[i]).collect();
        if free.is_empty() || free.len() == n {
            return Ok(None);
        }
        let mut index = vec![usize::MAX; n];
        for (r, &i) in free.iter().enumerate() {
            index[i] = r;
        }
        let cp = pattern.symbolic.col_ptr();
        let ri = pattern.symbolic.row_idx();
        let (mut col_ptr, mut row_idx, mut slots) = (vec![0], Vec::new(), Vec::new());
        let (mut off, mut diag) = (Vec::new(), Vec::new());
        for c in 0..n {
            for (k, &r) in ri.iter().enumerate().take(cp[c + 1]).skip(cp[c]) {
                if !fixed[c] && !fixed[r] {
                    row_idx.push(index[r]);
                    slots.push(k);
                } else if r == c {
                    diag.push(k);
                } else {
                    off.push(k);
                }
            }
            if !fixed[c] {
                col_ptr.push(row_idx.len());
            }
        }
        let nf = free.len();
        let symbolic = SymbolicSparseColMat::new_checked(nf, nf, col_ptr, None, row_idx);
        let below = |b: usize| free.partition_point(|&i| i < b);
        Ok(Some(Self {
            multipliers_from: below(pattern.multipliers_from),
            last_from: below(pattern.last_from),
            free,
            symbolic,
            slots,
            off,
            diag,
        }))
    }

    /// The free unknowns' values of `a` into `into`, after checking that the fixed rows and
    /// columns are the identity's.
    fn gather(&self, a: &SparseMatrix, into: &mut Vec<f64>) -> Result<()> {
        let v = &a.values;
        let bad = (self.off.iter().find(|&&k| v[k] != 0.0))
            .or_else(|| self.diag.iter().find(|&&k| v[k] != 1.0));
        if let Some(&k) = bad {
            let cp = a.pattern.symbolic.col_ptr();
            let col = cp.partition_point(|&p| p <= k) - 1;
            let row = a.pattern.symbolic.row_idx()[k];
            let fixed = if self.free.binary_search(&col).is_err() {
                col
            } else {
                row
            };
            return Err(LinalgError::FixedNotIdentity {
                unknown: fixed,
                row,
                col,
            });
        }
        into.clear();
        into.extend(self.slots.iter().map(|&k| v[k]));
        Ok(())
    }
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

pub(super) fn faer_err(e: impl std::fmt::Debug) -> LinalgError {
    LinalgError::Faer(format!("{e:?}"))
}

impl LinearSolver {
    /// LU solver with default options; runs the symbolic analysis.
    pub fn new(pattern: Arc<SparsePattern>) -> Result<Self> {
        Self::with_options(pattern, SolverOptions::default())
    }

    /// Solver with the given options; runs the symbolic analysis.
    pub fn with_options(pattern: Arc<SparsePattern>, options: SolverOptions) -> Result<Self> {
        Self::build(pattern, options, None)
    }

    /// Solver for matrices whose rows and columns of the unknowns `fixed` are the
    /// identity's (a [`SparseMatrix::set_identity_rows_cols`] by `fixed` or more), which
    /// factors the other unknowns' system alone: the same solutions, to rounding, for less.
    /// [`LinearSolver::factor`] fails with [`LinalgError::FixedNotIdentity`] on a matrix
    /// that is not the identity's there.
    pub fn with_fixed(
        pattern: Arc<SparsePattern>,
        options: SolverOptions,
        fixed: &[bool],
    ) -> Result<Self> {
        let reduction = Reduction::new(&pattern, fixed)?.map(Arc::new);
        Self::build(pattern, options, reduction)
    }

    fn build(
        pattern: Arc<SparsePattern>,
        options: SolverOptions,
        reduction: Option<Arc<Reduction>>,
    ) -> Result<Self> {
        let (a, multipliers_from, last_from) = match &reduction {
            Some(r) => (r.symbolic.as_ref(), r.multipliers_from, r.last_from),
            None => (
                pattern.symbolic.as_ref(),
                pattern.multipliers_from,
                pattern.last_from,
            ),
        };
        let symbolic = match options.kind {
            FactorKind::Lu => SymbolicFactor::SymLu(
                Arc::new(
                    SymbolicSymLu::new(a, multipliers_from, last_from)
                        .map_err(LinalgError::Faer)?,
                ),
                None,
            ),
            FactorKind::LuColamd => SymbolicFactor::Lu(Arc::new(
                factorize_symbolic_lu(a, Default::default()).map_err(faer_err)?,
            )),
            FactorKind::Llt | FactorKind::Ldlt => SymbolicFactor::Cholesky(Arc::new(
                factorize_symbolic_cholesky(
                    a,
                    Side::Lower,
                    SymmetricOrdering::Amd,
                    Default::default(),
                )
                .map_err(faer_err)?,
            )),
        };
        let factored_n = a.nrows();
        let factor_par = options.factor_par.unwrap_or_else(|| {
            if factored_n >= PAR_FACTOR_MIN_N && rayon::current_num_threads() > 1 {
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
            reduction,
            reduced_values: Vec::new(),
        })
    }

    /// A solver on this one's pattern and options that shares its symbolic analysis (its
    /// [`LinearSolver::symbolic_count`] is 0; faer's LU analysis after a declined matrix is
    /// shared if this one had made it, else made by the sibling at its own first decline) and
    /// holds no factorization yet: the adjoint's sweep factors its tangents on the forward
    /// run's analysis.
    pub fn sibling(&self) -> Self {
        Self {
            pattern: self.pattern.clone(),
            options: self.options,
            factor_par: self.factor_par,
            symbolic: self.symbolic.clone(),
            numeric: NumericFactor::None,
            factor_mem: None,
            symbolic_count: 0,
            numeric_count: 0,
            declined: 0,
            solve_calls: AtomicUsize::new(0),
            solve_columns: AtomicUsize::new(0),
            reduction: self.reduction.clone(),
            reduced_values: Vec::new(),
        }
    }

    /// Unknowns in the factored system: the pattern's, less the fixed ones
    /// ([`LinearSolver::with_fixed`]).
    pub fn factored_n(&self) -> usize {
        self.reduction
            .as_ref()
            .map_or(self.pattern.n, |r| r.free.len())
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

    /// Number of symbolic analyses run (1: done in the constructor; 0 for a
    /// [`LinearSolver::sibling`]).
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
        let mut reduced = std::mem::take(&mut self.reduced_values);
        let out = match self.reduction.clone() {
            Some(r) => match r.gather(a, &mut reduced) {
                Ok(()) => {
                    self.factor_faer(SparseColMatRef::new(r.symbolic.as_ref(), &reduced), par)
                }
                Err(e) => {
                    self.numeric = NumericFactor::None;
                    Err(e)
                }
            },
            None => self.factor_faer(a.as_faer(), par),
        };
        self.reduced_values = reduced;
        out
    }

    /// [`LinearSolver::factor`] of the matrix the symbolic analysis is of (the free
    /// unknowns' where the solver has a [`Reduction`]).
    fn factor_faer(&mut self, mat: SparseColMatRef<'_, usize, f64>, par: Par) -> Result<()> {
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
                *colamd = Some(Arc::new(
                    factorize_symbolic_lu(mat.symbolic(), Default::default()).map_err(faer_err)?,
                ));
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
    pub(super) fn finish_factor(&mut self) -> Result<()> {
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

    pub(super) fn solve_raw(&self, mut rhs: MatMut<'_, f64>, transpose: bool) -> Result<()> {
        let Some(r) = &self.reduction else {
            return self.solve_factored(rhs, transpose);
        };
        let (nf, k) = (r.free.len(), rhs.ncols());
        let mut free = vec![0.0; nf * k];
        for (c, col) in free.chunks_exact_mut(nf).enumerate() {
            for (x, &i) in col.iter_mut().zip(&r.free) {
                *x = rhs[(i, c)];
            }
        }
        self.solve_factored(
            MatMut::from_column_major_slice_mut(&mut free, nf, k),
            transpose,
        )?;
        for (c, col) in free.chunks_exact(nf).enumerate() {
            for (x, &i) in col.iter().zip(&r.free) {
                rhs[(i, c)] = *x;
            }
        }
        Ok(())
    }

    /// [`LinearSolver::solve_raw`] on the factored system (the free unknowns' where the
    /// solver has a [`Reduction`]).
    fn solve_factored(&self, rhs: MatMut<'_, f64>, transpose: bool) -> Result<()> {
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

    pub(super) fn count(&self, cols: usize) {
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
        self.refine_oriented(a, false, b, x, ncols, steps)
    }

    /// [`LinearSolver::refine_multi`] for `a x = b`, or for `a^T x = b` with the transposed
    /// solves where `transpose`.
    fn refine_oriented(
        &self,
        a: &SparseMatrix,
        transpose: bool,
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
        let mut res = worst(&residuals_of(a, transpose, b, x, &mut r, ncols)?);
        for _ in 0..steps {
            if transpose {
                self.solve_transpose_multi_in_place(&mut r, ncols)?;
            } else {
                self.solve_multi_in_place(&mut r, ncols)?;
            }
            for (xi, ri) in x.iter_mut().zip(&r) {
                *xi += ri;
            }
            res = worst(&residuals_of(a, transpose, b, x, &mut r, ncols)?);
        }
        Ok(res)
    }
}

/// A numeric factorization kept apart from the solver that made it ([`LinearSolver::keep`]):
/// the adjoint keeps Newton's last factorization of every increment to solve with it on its
/// way back ([`LinearSolver::with_kept`]).
pub struct KeptFactor(NumericFactor, usize);

/// `f`, its symmetric-pattern LU factors shared ([`LinearSolver::keep`]), other kinds copied.
fn shared(f: &NumericFactor) -> NumericFactor {
    match f {
        NumericFactor::SymLu(f) => NumericFactor::SymLu(Box::new(f.share_factors())),
        f => f.clone(),
    }
}

impl Clone for KeptFactor {
    /// Another handle on the same factors (shared, as [`LinearSolver::keep`] shares them).
    fn clone(&self) -> Self {
        KeptFactor(shared(&self.0), self.1)
    }
}

impl KeptFactor {
    /// Bytes of its factors, in full however many others share them (the adjoint keeps an
    /// earlier increment's factorization again for an increment converged without one: its
    /// ledger counts it twice).
    pub fn bytes(&self) -> usize {
        match &self.0 {
            NumericFactor::None => 0,
            NumericFactor::SymLu(f) => f.bytes(),
            NumericFactor::Lu(_) => 0,
            NumericFactor::Llt(v) | NumericFactor::Ldlt(v) => 8 * v.len(),
        }
    }
}

impl std::fmt::Debug for KeptFactor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "KeptFactor({} bytes)", self.bytes())
    }
}

impl LinearSolver {
    /// The current numeric factorization, to solve with later by a solver on the same
    /// pattern ([`LinearSolver::with_kept`]). `None` when not factored, or factored by
    /// faer's LU after the symmetric-pattern LU declined the matrix (whose symbolic analysis
    /// another solver may not hold). The symmetric-pattern LU's factors are shared, not
    /// copied: this solver's next factorization writes into new memory instead of over
    /// them (the adjoint's forward run keeps every increment's: copied, the leaf spring's
    /// 75 MiB took its observer 0.06 s, shared 0.007 s with the rest it keeps). Cholesky
    /// factors are copied.
    pub fn keep(&self) -> Option<KeptFactor> {
        match &self.numeric {
            NumericFactor::None | NumericFactor::Lu(_) => None,
            f => Some(KeptFactor(shared(f), self.factored_n())),
        }
    }

    /// Take `kept` (or no factorization, for `None`) as this solver's own last
    /// factorization, shared as [`LinearSolver::keep`] shares it: a run resumed where
    /// another kept it goes on with that run's factorization, and this solver's next one
    /// writes into new memory. Fails as [`LinearSolver::with_kept`] does when `kept` is not
    /// of this solver's kind or size, leaving this solver unfactored.
    pub fn restore(&mut self, kept: Option<&KeptFactor>) -> Result<()> {
        let Some(kept) = kept else {
            self.numeric = NumericFactor::None;
            return Ok(());
        };
        if let Err(e) = self.fits(kept) {
            self.numeric = NumericFactor::None;
            return Err(e);
        }
        match (&mut self.numeric, &kept.0) {
            // the scratch of this solver's own factorization kept for its next
            (NumericFactor::SymLu(own), NumericFactor::SymLu(f)) => own.adopt_factors(f),
            (own, f) => *own = shared(f),
        }
        Ok(())
    }

    /// Whether `kept` is a factorization of this solver's kind and size.
    fn fits(&self, kept: &KeptFactor) -> Result<()> {
        let fits = matches!(
            (&self.symbolic, &kept.0),
            (SymbolicFactor::SymLu(..), NumericFactor::SymLu(_))
                | (
                    SymbolicFactor::Cholesky(_),
                    NumericFactor::Llt(_) | NumericFactor::Ldlt(_)
                )
        );
        if !fits {
            return Err(LinalgError::NotFactored);
        }
        // a factorization of the free unknowns' system fits only a solver that leaves out
        // the same unknowns
        check_len(self.factored_n(), kept.1)
    }

    /// Run `f` with `kept` in place of this solver's own factorization (this solver's
    /// symbolic analysis; the pattern must be the one `kept` was factored on), and put both
    /// back. Fails with [`LinalgError::NotFactored`] when the factor's kind is not this
    /// solver's, and with [`LinalgError::DimensionMismatch`] when it leaves out other
    /// unknowns.
    pub fn with_kept<R>(
        &mut self,
        kept: &mut KeptFactor,
        f: impl FnOnce(&LinearSolver) -> Result<R>,
    ) -> Result<R> {
        self.fits(kept)?;
        std::mem::swap(&mut self.numeric, &mut kept.0);
        let out = f(self);
        std::mem::swap(&mut self.numeric, &mut kept.0);
        out
    }

    /// [`LinearSolver::refine_multi`] for `a^T x = b`: `steps` times
    /// `x += LU^{-T} (b - a^T x)`. Returns the largest relative residual over the columns.
    pub fn refine_transpose_multi(
        &self,
        a: &SparseMatrix,
        b: &[f64],
        x: &mut [f64],
        ncols: usize,
        steps: usize,
    ) -> Result<f64> {
        self.refine_oriented(a, true, b, x, ncols, steps)
    }
}

pub(super) fn reuse_mem(
    mem: Option<MemBuffer>,
    req: faer::dyn_stack::StackReq,
) -> Result<MemBuffer> {
    // The requirement depends only on the pattern, the kind and the parallelism, all
    // fixed for a solver: the first buffer fits every later factorization.
    match mem {
        Some(m) => Ok(m),
        None => MemBuffer::try_new(req).map_err(faer_err),
    }
}
