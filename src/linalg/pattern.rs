//! The sparsity pattern: CSC structure fixed over a run, per-block slot tables, assembly chunks.

use faer::sparse::SymbolicSparseColMat;

use super::*;

/// Target number of element-matrix entries per assembly chunk (2 MB of `f64`).
pub(super) const CHUNK_ENTRIES: usize = 1 << 18;

/// Fixed, structurally symmetric CSC sparsity pattern built from element blocks.
#[derive(Debug)]
pub struct SparsePattern {
    pub(super) n: usize,
    pub(super) symbolic: SymbolicSparseColMat<usize>,
    /// `block_dofs[block_dof_ptr[b]..block_dof_ptr[b+1]]`: DOFs of block `b`.
    pub(super) block_dof_ptr: Vec<usize>,
    pub(super) block_dofs: Vec<usize>,
    /// `block_slot_data[block_slot_ptr[b]..block_slot_ptr[b+1]]`: slots of block `b`,
    /// row-major over its local indices.
    pub(super) block_slot_ptr: Vec<usize>,
    pub(super) block_slot_data: Vec<Slot>,
    /// Slot of each diagonal entry.
    pub(super) diag: Vec<usize>,
    /// Block boundaries of the assembly chunks.
    pub(super) chunk_ptr: Vec<usize>,
    /// Unknowns from here on are Lagrange multipliers: their diagonal can be zero, so
    /// [`FactorKind::Lu`] eliminates each after the other unknowns it couples to.
    pub(super) multipliers_from: usize,
    /// Unknowns from here on (after the multipliers) are eliminated last: a few unknowns that
    /// couple to many others through multipliers (the translation of a rigid target pushed by
    /// a force), whose pivot is the stiffness of everything before them.
    pub(super) last_from: usize,
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
            last_from: n,
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

    /// Marks the unknowns `first..n` to be eliminated after all others by [`FactorKind::Lu`]
    /// (they may lie among the multipliers: those from `first` on are not multipliers). Their
    /// pivot is then the Schur complement of the whole rest: for the translation of a rigid
    /// target pushed by a force, the stiffness of the contact that holds it, where eliminated
    /// among the multipliers it would meet a zero diagonal.
    pub fn with_last_from(mut self, first: usize) -> Self {
        self.last_from = first.min(self.n);
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
