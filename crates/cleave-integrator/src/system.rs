//! The assembled system path: the sparsity pattern, block and pin-row ranks, pinned-entry
//! positions and the Cholesky symbolic factorization, all built once per pattern; per step only
//! values are written and refactorized. The symbolic factorization of a new pattern is computed
//! beside the first fill of its values ([`AssembledSystem::fill_beside_symbolic`]): both need
//! only the pattern, and the ordering and symbolic analysis run on one thread.

use crate::constraints::Constraints;
use crate::error::StepErrorKind;
use cleave_core::{AssemblyPattern, BlockRanks, Discretization, Embedding, Matrix3, Real, SparseCholesky};

/// Ranks of every (row, column) node pair of a list of embedding rows in the pattern.
#[derive(Debug, Default)]
pub(crate) struct RowRanks {
    offsets: Vec<usize>,
    ranks: Vec<u32>,
}

impl RowRanks {
    pub(crate) fn new(rows: &Embedding, pattern: &AssemblyPattern) -> Self {
        let mut offsets = vec![0];
        let mut ranks = Vec::new();
        for i in 0..rows.len() {
            let nodes = rows.row(i).0;
            for &j in nodes {
                for &k in nodes {
                    ranks.push(pattern.rank(k, j).expect("pattern holds every coupling row"));
                }
            }
            offsets.push(ranks.len());
        }
        Self { offsets, ranks }
    }

    /// Adds `w wᵀ ⊗ P` for row `i` of `rows`.
    pub(crate) fn add_row(
        &self,
        rows: &Embedding,
        i: usize,
        p: &Matrix3<Real>,
        pattern: &AssemblyPattern,
        values: &mut [Real],
    ) {
        let (nodes, weights) = rows.row(i);
        let ranks = &self.ranks[self.offsets[i]..self.offsets[i + 1]];
        let n = nodes.len();
        for (b, (&j, &wj)) in nodes.iter().zip(weights).enumerate() {
            for (a, &wi) in weights.iter().enumerate() {
                pattern.add_block(values, ranks[b * n + a], j, p, wi * wj);
            }
        }
    }
}

/// Everything the assembled path keeps for one epoch.
pub(crate) struct AssembledSystem {
    pub pattern: AssemblyPattern,
    pub block_ranks: BlockRanks,
    pub pin_ranks: RowRanks,
    pub values: Vec<Real>,
    /// Positions of entries in a pinned row or column (zeroed) and of pinned diagonals (set to 1).
    pinned_off_diagonal: Vec<usize>,
    pinned_diagonal: Vec<usize>,
    cholesky: Option<SparseCholesky>,
    /// The Cholesky path's symbolic factorization of this pattern is still to be computed.
    symbolic_pending: bool,
}

impl AssembledSystem {
    pub(crate) fn new(
        discretization: &dyn Discretization,
        constraints: &Constraints,
        with_cholesky: bool,
    ) -> Result<Self, StepErrorKind> {
        Self::on_pattern(Self::base_pattern(discretization, constraints), discretization, constraints, with_cholesky)
    }

    /// The pattern of the blocks and the constraints' coupling groups (each epoch's start).
    pub(crate) fn base_pattern(discretization: &dyn Discretization, constraints: &Constraints) -> AssemblyPattern {
        let coupling = constraints.coupling_groups();
        AssemblyPattern::from_groups(
            discretization.num_nodes(),
            discretization.blocks().node_groups().chain(coupling.iter()),
        )
    }

    /// The system of the same epoch on this pattern grown by `couplings` (surface contacts
    /// between nodes it did not couple): a new symbolic factorization, but the pattern is only
    /// merged, not built again from every element and surface triangle.
    pub(crate) fn grown(
        &self,
        couplings: &[Vec<u32>],
        discretization: &dyn Discretization,
        constraints: &Constraints,
    ) -> Result<Self, StepErrorKind> {
        let pattern = self.pattern.with_groups(couplings.iter().map(Vec::as_slice));
        Self::on_pattern(pattern, discretization, constraints, self.cholesky.is_some() || self.symbolic_pending)
    }

    /// Ranks, pinned positions and values on `pattern`; with `with_cholesky` its symbolic
    /// factorization is pending (computed beside the first fill, or by the first factorization).
    pub(crate) fn on_pattern(
        pattern: AssemblyPattern,
        discretization: &dyn Discretization,
        constraints: &Constraints,
        with_cholesky: bool,
    ) -> Result<Self, StepErrorKind> {
        let block_ranks = BlockRanks::new(discretization.blocks(), &pattern);
        let pin_ranks =
            constraints.penalty_pins.as_ref().map_or_else(RowRanks::default, |p| RowRanks::new(&p.points, &pattern));
        let dim = pattern.dim();
        let mut pinned = vec![false; dim];
        for &d in &constraints.pinned_dofs {
            pinned[d] = true;
        }
        let (mut pinned_off_diagonal, mut pinned_diagonal) = (Vec::new(), Vec::new());
        // The scan reads every stored entry: skip it when nothing is pinned (DG, free bodies).
        let columns = if constraints.pinned_dofs.is_empty() { 0..0 } else { 0..dim };
        for col in columns {
            for p in pattern.col_ptr()[col]..pattern.col_ptr()[col + 1] {
                let row = pattern.row_idx()[p];
                if pinned[row] || pinned[col] {
                    if row == col {
                        pinned_diagonal.push(p);
                    } else {
                        pinned_off_diagonal.push(p);
                    }
                }
            }
        }
        let values = pattern.new_values();
        Ok(Self {
            pattern,
            block_ranks,
            pin_ranks,
            values,
            pinned_off_diagonal,
            pinned_diagonal,
            cholesky: None,
            symbolic_pending: with_cholesky,
        })
    }

    /// Whether the next [`fill_beside_symbolic`](Self::fill_beside_symbolic) also computes the
    /// symbolic factorization of a new pattern.
    pub(crate) fn symbolic_pending(&self) -> bool {
        self.symbolic_pending
    }

    /// Writes the values with `fill` (given the system and its values) and, where this pattern's
    /// symbolic factorization is pending, computes it at the same time on the other thread.
    pub(crate) fn fill_beside_symbolic<T: Send>(
        &mut self,
        fill: impl FnOnce(&Self, &mut [Real]) -> T + Send,
    ) -> Result<T, StepErrorKind> {
        let mut values = std::mem::take(&mut self.values);
        let this = &*self;
        let (symbolic, out) = if self.symbolic_pending {
            let (symbolic, out) = rayon::join(|| SparseCholesky::new(&this.pattern), || fill(this, &mut values));
            (Some(symbolic), out)
        } else {
            (None, fill(this, &mut values))
        };
        self.values = values;
        if let Some(symbolic) = symbolic {
            self.cholesky = Some(symbolic?);
            self.symbolic_pending = false;
        }
        Ok(out)
    }

    /// Number of nonzeros of the factor, if factorized.
    pub(crate) fn factor_nnz(&self) -> Option<usize> {
        self.cholesky.as_ref().map(SparseCholesky::factor_nnz)
    }

    /// `values = c_m M + c_k K_R` (penalty rows are added by the caller afterwards).
    pub(crate) fn fill(
        &mut self,
        discretization: &dyn Discretization,
        rotations: &[Matrix3<Real>],
        mass_scale: Real,
        stiffness_scale: Real,
    ) {
        let mut values = std::mem::take(&mut self.values);
        self.fill_values(&mut values, discretization, rotations, mass_scale, stiffness_scale);
        self.values = values;
    }

    /// [`fill`](Self::fill) into `values` (this pattern's).
    pub(crate) fn fill_values(
        &self,
        values: &mut [Real],
        discretization: &dyn Discretization,
        rotations: &[Matrix3<Real>],
        mass_scale: Real,
        stiffness_scale: Real,
    ) {
        values.fill(0.0);
        discretization.blocks().add_to_matrix(rotations, stiffness_scale, &self.pattern, &self.block_ranks, values);
        let mass = discretization.mass().diagonal();
        for node in 0..self.pattern.num_nodes() as u32 {
            let rank = self.pattern.rank(node, node).expect("diagonal is in the pattern");
            for c in 0..3 {
                let d = 3 * node as usize + c;
                values[self.pattern.position(rank, node, c, c)] += mass_scale * mass[d];
            }
        }
    }

    /// Replaces pinned rows and columns by those of the identity.
    pub(crate) fn apply_pins(&mut self) {
        let mut values = std::mem::take(&mut self.values);
        self.apply_pins_to(&mut values);
        self.values = values;
    }

    /// [`apply_pins`](Self::apply_pins) on `values` (this pattern's).
    pub(crate) fn apply_pins_to(&self, values: &mut [Real]) {
        for &p in &self.pinned_off_diagonal {
            values[p] = 0.0;
        }
        for &p in &self.pinned_diagonal {
            values[p] = 1.0;
        }
    }

    /// Numeric factorization on the cached symbolic one (computed first if still pending).
    pub(crate) fn factorize(&mut self) -> Result<(), StepErrorKind> {
        if self.symbolic_pending {
            self.cholesky = Some(SparseCholesky::new(&self.pattern)?);
            self.symbolic_pending = false;
        }
        let cholesky = self.cholesky.as_mut().expect("factorize needs the Cholesky storage");
        Ok(cholesky.factorize(&self.values)?)
    }

    /// Solves in place with the last factorization.
    pub(crate) fn solve_in_place(&mut self, rhs: &mut [Real]) {
        self.cholesky.as_mut().expect("solve needs the Cholesky storage").solve_in_place(rhs);
    }

    /// Solves the `columns` columns of `rhs` (column-major) in place with the last factorization.
    pub(crate) fn solve_columns_in_place(&mut self, rhs: &mut [Real], columns: usize) {
        self.cholesky.as_mut().expect("solve needs the Cholesky storage").solve_columns_in_place(rhs, columns);
    }
}
