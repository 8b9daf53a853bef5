//! Sparse Cholesky of a matrix on an [`AssemblyPattern`]: a fill-reducing order computed on the
//! node graph, the symbolic factorization built once per pattern, then any number of numeric
//! factorizations and solves on it (faer's supernodal LLᵀ).
//!
//! The order is computed on the pattern's node graph, not on the scalar matrix: nodes with
//! identical neighbour sets (the basis functions of one DG element couple to exactly the same
//! nodes) are merged into one vertex first, AMD orders that quotient graph, and the order is
//! expanded to scalar DOFs with each node's three components consecutive. faer's default orders
//! the `3n × 3n` scalar pattern, which holds 9 entries per node coupling and, for DG, `nb²` copies
//! of every element coupling; AMD's supervariable detection finds the same elimination order
//! (the factor has exactly the same nonzeros) but only after reading the whole scalar graph, which
//! on the 10×10×10 quadratic DG grid of kaufmann2008 Table 1 took 2–3× longer than the whole
//! symbolic factorization does now.
//!
//! The permuted matrix is built here too, at the node level, and faer analyses and factorizes it
//! in the identity order: the upper triangle of `P A Pᵀ` for the symbolic analysis, the lower for
//! the numeric factorizations, and the solves apply `P` themselves. faer's own permutation of the
//! scalar pattern cost as much as its elimination tree and column counts together (about a
//! third of every symbolic factorization, one per contact pattern growth on `bunny_slice.ron`);
//! the factor is the same bit for bit (a test compares the two).

use crate::Real;
use crate::assembly::AssemblyPattern;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering, factorize_symbolic_cholesky, supernodal,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use std::collections::HashMap;

/// Why a sparse Cholesky could not be set up or factorized.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CholeskyError {
    /// A pivot was not positive: the matrix is not positive definite (scalar DOF `pivot` in the
    /// elimination order).
    #[error("the matrix is not positive definite (non-positive pivot at elimination step {pivot})")]
    NotPositiveDefinite {
        /// Elimination step of the failing pivot.
        pivot: usize,
    },
    /// The ordering or symbolic factorization failed (index overflow, out of memory).
    #[error("sparse Cholesky set-up: {0}")]
    Setup(String),
}

/// The symbolic factorization of one pattern and the storage for its numeric factor.
pub struct SparseCholesky {
    /// Symbolic factorization of `P A Pᵀ` in the identity order.
    symbolic: SymbolicCholesky<usize>,
    /// The scalar order (`perm[new] = old`).
    perm: Vec<usize>,
    /// Right-hand sides in elimination order (grown on demand to the columns solved).
    permuted_rhs: Vec<Real>,
    factor_values: Vec<Real>,
    scratch: MemBuffer,
    /// Workspace of multi-column solves and how many columns it holds (grown on demand).
    column_scratch: (usize, MemBuffer),
    factored: bool,
    order_groups: usize,
    /// The matrix's lower triangle in elimination order (once per pattern).
    permuted: PermutedLower,
    /// Floating-point operations of one numeric factorization, from the symbolic structure.
    flops: f64,
    /// faer's parallelism for this factor's factorizations and solves ([`parallelism`]).
    par: Par,
    /// The fill-reducing ordering chosen.
    ordering: FillOrdering,
}

/// The lower triangle of `P A Pᵀ` as the supernodal factorization reads it, and for each of its
/// entries the position of its value in the pattern's values. faer's `factorize_numeric_llt`
/// builds this matrix again at every factorization (`permute_self_adjoint_to_unsorted`, 3–4 ms
/// a step on `bunny_slice.ron`: counting, prefix sums and scatter over both triangles); with the
/// structure kept per pattern a factorization only gathers the values.
struct PermutedLower {
    matrix: SymbolicSparseColMat<usize>,
    source: Vec<usize>,
    values: Vec<Real>,
}

impl PermutedLower {
    /// The entries `A[i][j]` with `i ≥ j` (the lower triangle faer reads with `Side::Lower`),
    /// each at row `max(p(i), p(j))`, column `min(p(i), p(j))` of the permuted matrix, `p` the
    /// new index of an old one: the same entries faer's permutation keeps, so the factor is the
    /// same bit for bit. Built column by column of the new order at the node level (`new_node`
    /// and its inverse `old_node`: the order keeps a node's three components consecutive).
    fn new(pattern: &AssemblyPattern, new_node: &[usize], old_node: &[u32]) -> Self {
        let nodes = pattern.num_nodes();
        // Rank of node j in the list of each of its neighbours i (the lists are sorted and
        // symmetric: visiting j in increasing order meets each list's entries in order).
        let mut offsets = Vec::with_capacity(nodes + 1);
        offsets.push(0);
        for j in 0..nodes as u32 {
            offsets.push(offsets[j as usize] + pattern.neighbours(j).len());
        }
        let mut cursor = vec![0u32; nodes];
        let mut transposed_rank = vec![0u32; offsets[nodes]];
        for j in 0..nodes as u32 {
            for (r, &i) in pattern.neighbours(j).iter().enumerate() {
                transposed_rank[offsets[j as usize] + r] = cursor[i as usize];
                cursor[i as usize] += 1;
            }
        }
        let dim = 3 * nodes;
        let mut col_ptr = Vec::with_capacity(dim + 1);
        let mut row_idx = Vec::with_capacity(pattern.nnz() / 2 + dim);
        let mut source = Vec::with_capacity(pattern.nnz() / 2 + dim);
        col_ptr.push(0);
        for (p, &j) in old_node.iter().enumerate() {
            let neighbours = pattern.neighbours(j);
            let ranks_in_theirs = &transposed_rank[offsets[j as usize]..offsets[j as usize + 1]];
            for b in 0..3 {
                for ((rank, &i), &rank_in_theirs) in neighbours.iter().enumerate().zip(ranks_in_theirs) {
                    let q = new_node[i as usize];
                    if q < p {
                        continue;
                    }
                    for a in 0..3 {
                        let k = if i == j {
                            if a < b {
                                continue;
                            }
                            pattern.position(rank as u32, j, a, b)
                        } else if i > j {
                            pattern.position(rank as u32, j, a, b)
                        } else {
                            // Old row 3j + b below old column 3i + a: stored in column i.
                            pattern.position(rank_in_theirs, i, b, a)
                        };
                        row_idx.push(3 * q + a);
                        source.push(k);
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        let values = vec![0.0; source.len()];
        let matrix = SymbolicSparseColMat::new_unsorted_checked(dim, dim, col_ptr, None, row_idx);
        Self { matrix, source, values }
    }
}

/// The structure of the upper triangle of `P A Pᵀ` (diagonal included), built at the node level
/// (`new_node[old]`, the order keeps a node's three components consecutive): column `3p + b`
/// holds the rows `3q + a` of the neighbours `q < p` and `3p + a`, `a ≤ b`; rows unsorted, as
/// faer's own permutation leaves them.
fn permuted_upper(pattern: &AssemblyPattern, new_node: &[usize], old_node: &[u32]) -> SymbolicSparseColMat<usize> {
    let dim = 3 * pattern.num_nodes();
    let mut col_ptr = Vec::with_capacity(dim + 1);
    let mut row_idx = Vec::with_capacity(pattern.nnz() / 2 + dim);
    col_ptr.push(0);
    for (p, &j) in old_node.iter().enumerate() {
        for b in 0..3 {
            for &i in pattern.neighbours(j) {
                let q = new_node[i as usize];
                if q < p {
                    row_idx.extend([3 * q, 3 * q + 1, 3 * q + 2]);
                }
            }
            row_idx.extend((0..=b).map(|a| 3 * p + a));
            col_ptr.push(row_idx.len());
        }
    }
    SymbolicSparseColMat::new_unsorted_checked(dim, dim, col_ptr, None, row_idx)
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("dim", &self.perm.len())
            .field("factor_nnz", &self.factor_nnz())
            .field("order_groups", &self.order_groups)
            .finish()
    }
}

/// Factorization work (floating-point operations) from which faer's parallel kernels pay.
/// faer's parallel supernodal kernels spin-wait for work; on small factors the threads of a
/// two-core machine cannot give it them (bunny_slice's systems, 5k DOFs, 1.4M factor nonzeros:
/// 25–26 ms a step sequential, 41–49 ms parallel, when every pool of at most two threads was
/// sequential). Measured on 2 idle cores with `cargo run --release -p cleave-core --example
/// cholesky_threads` (3D grids of 8-node cells, one factorization and solve, best of three):
///
/// | DOFs | flops | sequential [ms] | parallel [ms] |
/// |---|---|---|---|
/// | 3,000 | 2.4e8 | 17.1 | 18.8 |
/// | 5,184 | 8.1e8 | 47.1 | 50.5 |
/// | 6,591 | 1.5e9 | 77.8 | 69.8 |
/// | 17,496 | 1.4e10 | 636 | 419 |
/// | 52,728 | 1.5e11 | 5,912 | 3,277 |
///
/// Below the crossover the difference is a few percent; above it parallel approaches 2×.
pub const PARALLEL_FACTOR_FLOPS: f64 = 1e9;

/// faer's parallelism for a factor of `flops` operations: sequential below
/// [`PARALLEL_FACTOR_FLOPS`] or on one thread, every thread of the pool above.
fn parallelism(flops: f64) -> Par {
    if rayon::current_num_threads() <= 1 || flops < PARALLEL_FACTOR_FLOPS { Par::Seq } else { Par::rayon(0) }
}

/// Floating-point operations of a numeric Cholesky factorization with this structure: Σ_j c_j²
/// over the factor's columns, `c_j` the nonzeros of column j (the multiply–adds of its updates
/// to later columns, up to lower-order terms).
fn factor_flops(symbolic: &SymbolicCholesky<usize>) -> f64 {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Supernodal(raw) => {
            let rows = raw.col_ptr_for_row_idx();
            (0..raw.n_supernodes())
                .map(|s| {
                    let width = raw.supernode_end()[s] - raw.supernode_begin()[s];
                    let below = (rows[s + 1] - rows[s]) as f64;
                    // Column k of the supernode holds (width − k) rows of the diagonal block.
                    (1..=width).map(|k| (k as f64 + below).powi(2)).sum::<f64>()
                })
                .sum()
        }
        SymbolicCholeskyRaw::Simplicial(raw) => raw.col_ptr().windows(2).map(|w| ((w[1] - w[0]) as f64).powi(2)).sum(),
    }
}

/// Parts of at most this many nodes are ordered by AMD instead of dissected further.
const DISSECTION_LEAF: usize = 256;

/// Factor work above which [`FillOrdering::Auto`] also tries nested dissection (about 0.5 s of
/// factorization here, so the second ordering and symbolic analysis cost a few percent of one
/// factorization). Below it every measured system (bunny_slice's 5k DOFs, the voxel bunny's
/// coarse space) factors with less work under AMD (docs/results/voxel-bench.md, orderings).
pub const AUTO_DISSECTION_FLOPS: f64 = 1e10;

/// Nodes per quotient-graph group below which [`FillOrdering::Auto`] tries nested dissection.
/// DG's basis functions of one element form one group (4 or 10 nodes); on its grids AMD needed
/// 0.6× the operations of nested dissection in every measured case, so the second ordering
/// (0.3–0.7 s on Table 1's quadratic grids) would only be paid for. Nodal meshes have about one
/// node per group.
pub const AUTO_DISSECTION_GROUP_SIZE: f64 = 2.0;

/// The fill-reducing ordering of a [`SparseCholesky`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FillOrdering {
    /// Approximate minimum degree (faer's AMD) of the node graph.
    Amd,
    /// Nested dissection of the node graph by METIS bisections, AMD on small parts.
    NestedDissection,
    /// AMD, and for factors above [`AUTO_DISSECTION_FLOPS`] of nodal meshes (fewer than
    /// [`AUTO_DISSECTION_GROUP_SIZE`] nodes per group) also nested dissection, keeping the
    /// ordering whose factor takes fewer operations.
    #[default]
    Auto,
}

/// The scalar ordering of `fill_ordering` (`Amd` or `NestedDissection`) with its node maps
/// (`new_node[old]`, `old_node[new]`).
fn node_ordering(
    pattern: &AssemblyPattern,
    graph: &QuotientGraph,
    fill_ordering: FillOrdering,
) -> Result<(ScalarOrdering, Vec<usize>, Vec<u32>), CholeskyError> {
    let order = match fill_ordering {
        FillOrdering::NestedDissection => graph.nested_dissection()?,
        FillOrdering::Amd | FillOrdering::Auto => graph.amd()?,
    };
    let ordering = graph.expand(&order);
    let nodes = pattern.num_nodes();
    let new_node: Vec<usize> = (0..nodes).map(|n| ordering.perm_inv[3 * n] / 3).collect();
    let mut old_node = vec![0u32; nodes];
    for (n, &p) in new_node.iter().enumerate() {
        old_node[p] = n as u32;
    }
    Ok((ordering, new_node, old_node))
}

/// faer's symbolic Cholesky of the permuted upper triangle.
fn symbolic_of(
    pattern: &AssemblyPattern,
    new_node: &[usize],
    old_node: &[u32],
) -> Result<SymbolicCholesky<usize>, CholeskyError> {
    let upper = permuted_upper(pattern, new_node, old_node);
    factorize_symbolic_cholesky(upper.as_ref(), Side::Upper, SymmetricOrdering::Identity, Default::default())
        .map_err(|e| CholeskyError::Setup(format!("symbolic factorization: {e:?}")))
}

impl SparseCholesky {
    /// Orders the node graph of `pattern` ([`FillOrdering::Auto`]) and builds the symbolic
    /// factorization (once per pattern).
    pub fn new(pattern: &AssemblyPattern) -> Result<Self, CholeskyError> {
        Self::with_ordering(pattern, FillOrdering::Auto)
    }

    /// [`SparseCholesky::new`] with a chosen fill-reducing ordering.
    pub fn with_ordering(pattern: &AssemblyPattern, fill_ordering: FillOrdering) -> Result<Self, CholeskyError> {
        let dim = pattern.dim();
        let graph = QuotientGraph::new(pattern);
        let first = match fill_ordering {
            FillOrdering::NestedDissection => FillOrdering::NestedDissection,
            FillOrdering::Amd | FillOrdering::Auto => FillOrdering::Amd,
        };
        let (mut ordering, new_node, old_node) = node_ordering(pattern, &graph, first)?;
        let mut chosen = first;
        // The permuted lower triangle beside the symbolic analysis of the upper (both
        // sequential; on a busy pool the second waits for a free thread).
        let (symbolic, mut permuted) = rayon::join(
            || symbolic_of(pattern, &new_node, &old_node),
            || PermutedLower::new(pattern, &new_node, &old_node),
        );
        let mut symbolic = symbolic?;
        let nodes_per_group = pattern.num_nodes() as f64 / graph.groups().max(1) as f64;
        if fill_ordering == FillOrdering::Auto
            && factor_flops(&symbolic) > AUTO_DISSECTION_FLOPS
            && nodes_per_group < AUTO_DISSECTION_GROUP_SIZE
        {
            // A large factor of a nodal mesh: nested dissection may need far less work (the
            // voxel cantilever at n = 16: half); keep the ordering with fewer operations.
            let (nd_ordering, nd_new, nd_old) = node_ordering(pattern, &graph, FillOrdering::NestedDissection)?;
            let nd_symbolic = symbolic_of(pattern, &nd_new, &nd_old)?;
            if factor_flops(&nd_symbolic) < factor_flops(&symbolic) {
                permuted = PermutedLower::new(pattern, &nd_new, &nd_old);
                (ordering, symbolic) = (nd_ordering, nd_symbolic);
                chosen = FillOrdering::NestedDissection;
            }
        }
        let order_groups = ordering.groups;
        let flops = factor_flops(&symbolic);
        let par = parallelism(flops);
        // Sized for both parallelisms, so that `set_parallel` may switch.
        let requirement = |par: Par| {
            let supernodal = match symbolic.raw() {
                SymbolicCholeskyRaw::Supernodal(raw) => {
                    supernodal::factorize_supernodal_numeric_llt_scratch::<usize, Real>(raw, par, Default::default())
                }
                SymbolicCholeskyRaw::Simplicial(_) => StackReq::empty(),
            };
            StackReq::any_of(&[
                symbolic.factorize_numeric_llt_scratch::<Real>(par, Default::default()),
                supernodal,
                symbolic.solve_in_place_scratch::<Real>(1, par),
            ])
        };
        let scratch = MemBuffer::try_new(StackReq::any_of(&[requirement(Par::Seq), requirement(Par::rayon(0))]))
            .map_err(|_| CholeskyError::Setup("out of memory for the Cholesky workspace".into()))?;
        let factor_values = crate::assembly::resident_zeros(symbolic.len_val());
        let column_scratch = (0, MemBuffer::new(StackReq::empty()));
        Ok(Self {
            symbolic,
            perm: ordering.perm,
            permuted_rhs: vec![0.0; dim],
            factor_values,
            scratch,
            column_scratch,
            factored: false,
            order_groups,
            permuted,
            flops,
            par,
            ordering: chosen,
        })
    }

    /// The fill-reducing ordering the factor uses (`Amd` or `NestedDissection`).
    pub fn ordering(&self) -> FillOrdering {
        self.ordering
    }

    /// Nonzeros of the factor `L`.
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Floating-point operations of one numeric factorization (Σ_j c_j² over the factor's
    /// columns), from which faer's parallel kernels are used ([`PARALLEL_FACTOR_FLOPS`]).
    pub fn factor_flops(&self) -> f64 {
        self.flops
    }

    /// Whether this factor's factorizations and solves use faer's parallel kernels.
    pub fn is_parallel(&self) -> bool {
        !matches!(self.par, Par::Seq)
    }

    /// Overrides the choice of [`PARALLEL_FACTOR_FLOPS`] (to measure it): faer's parallel
    /// kernels on every thread of the pool, or none. The workspace is sized for either.
    pub fn set_parallel(&mut self, parallel: bool) {
        self.par = if parallel && rayon::current_num_threads() > 1 { Par::rayon(0) } else { Par::Seq };
    }

    /// Vertices of the quotient graph the ordering was computed on.
    pub fn order_groups(&self) -> usize {
        self.order_groups
    }

    /// Numeric factorization of the matrix with `values` on the pattern (both triangles stored;
    /// the lower one is read).
    pub fn factorize(&mut self, values: &[Real]) -> Result<(), CholeskyError> {
        let permuted = &mut self.permuted;
        for (value, &k) in permuted.values.iter_mut().zip(&permuted.source) {
            *value = values[k];
        }
        let result = match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(raw) => supernodal::factorize_supernodal_numeric_llt::<usize, Real>(
                &mut self.factor_values,
                SparseColMatRef::new(permuted.matrix.as_ref(), &permuted.values),
                LltRegularization::default(),
                raw,
                self.par,
                MemStack::new(&mut self.scratch),
                Default::default(),
            )
            .map(|_| ()),
            SymbolicCholeskyRaw::Simplicial(_) => self
                .symbolic
                .factorize_numeric_llt::<Real>(
                    &mut self.factor_values,
                    SparseColMatRef::new(permuted.matrix.as_ref(), &permuted.values),
                    Side::Lower,
                    LltRegularization::default(),
                    self.par,
                    MemStack::new(&mut self.scratch),
                    Default::default(),
                )
                .map(|_| ()),
        };
        self.factored = result.is_ok();
        result.map_err(|LltError::NonPositivePivot { index }| CholeskyError::NotPositiveDefinite { pivot: index })
    }

    /// Solves `A x = rhs` in place with the last successful factorization, with this factor's
    /// parallelism ([`PARALLEL_FACTOR_FLOPS`]).
    ///
    /// # Panics
    /// Before a successful [`factorize`](Self::factorize): a caller bug, not a user-input error.
    pub fn solve_in_place(&mut self, rhs: &mut [Real]) {
        self.solve_with(rhs, self.par);
    }

    /// As [`solve_in_place`](Self::solve_in_place) on one thread (for small systems solved often,
    /// such as a coarse-grid correction inside CG, where threading costs more than it saves).
    pub fn solve_in_place_sequential(&mut self, rhs: &mut [Real]) {
        self.solve_with(rhs, Par::Seq);
    }

    /// Solves `A X = B` in place for the `columns` columns of `rhs` (column-major, each of the
    /// matrix's dimension) with the last successful factorization: one pass over the factor
    /// for all of them, cheaper than as many single solves.
    ///
    /// # Panics
    /// Before a successful [`factorize`](Self::factorize), or when `rhs` does not hold
    /// `columns` columns: caller bugs.
    pub fn solve_columns_in_place(&mut self, rhs: &mut [Real], columns: usize) {
        assert!(self.factored, "SparseCholesky::solve before a successful factorize");
        let n = self.perm.len();
        assert_eq!(rhs.len(), n * columns, "solve_columns_in_place: rhs holds {columns} columns of {n}");
        if columns == 0 {
            return;
        }
        let par = self.par;
        if self.column_scratch.0 < columns {
            // Sized for both parallelisms, as the main workspace, so `set_parallel` may switch.
            let requirement = StackReq::any_of(&[
                self.symbolic.solve_in_place_scratch::<Real>(columns, Par::Seq),
                self.symbolic.solve_in_place_scratch::<Real>(columns, Par::rayon(0)),
            ]);
            self.column_scratch = (columns, MemBuffer::new(requirement));
        }
        self.solve_permuted(rhs, par, true);
    }

    fn solve_with(&mut self, rhs: &mut [Real], par: Par) {
        assert!(self.factored, "SparseCholesky::solve before a successful factorize");
        self.solve_permuted(rhs, par, false);
    }

    /// `rhs ← A⁻¹ rhs` for the columns of `rhs`: each permuted into `P rhs`, solved with the
    /// factor of `P A Pᵀ`, and permuted back (what faer does with an order of its own), in the
    /// multi-column workspace or the single-column one.
    fn solve_permuted(&mut self, rhs: &mut [Real], par: Par, in_column_scratch: bool) {
        let perm = &self.perm;
        let n = perm.len();
        let columns = rhs.len() / n.max(1);
        if self.permuted_rhs.len() < rhs.len() {
            self.permuted_rhs.resize(rhs.len(), 0.0);
        }
        let permuted = &mut self.permuted_rhs[..rhs.len()];
        for (to, from) in permuted.chunks_mut(n).zip(rhs.chunks(n)) {
            for (x, &old) in to.iter_mut().zip(perm) {
                *x = from[old];
            }
        }
        let scratch = MemStack::new(if in_column_scratch { &mut self.column_scratch.1 } else { &mut self.scratch });
        let llt = LltRef::<'_, usize, Real>::new(&self.symbolic, &self.factor_values);
        llt.solve_in_place_with_conj(Conj::No, MatMut::from_column_major_slice_mut(permuted, n, columns), par, scratch);
        for (from, to) in permuted.chunks(n).zip(rhs.chunks_mut(n)) {
            for (&x, &old) in from.iter().zip(perm) {
                to[old] = x;
            }
        }
    }
}

/// A scalar permutation (`perm[new] = old`), its inverse, and the size of the ordered graph.
struct ScalarOrdering {
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    groups: usize,
}

/// The pattern's node graph with indistinguishable nodes (identical closed neighbourhoods)
/// merged: CSC adjacency of the groups (rows sorted, diagonal included) and each group's nodes.
struct QuotientGraph {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    members_offsets: Vec<usize>,
    members: Vec<u32>,
}

impl QuotientGraph {
    fn new(pattern: &AssemblyPattern) -> Self {
        let n = pattern.num_nodes();
        let mut group_of = vec![0u32; n];
        let mut representatives: Vec<u32> = Vec::new();
        {
            let mut ids: HashMap<&[u32], u32> = HashMap::with_capacity(n);
            for j in 0..n as u32 {
                let next = representatives.len() as u32;
                let id = *ids.entry(pattern.neighbours(j)).or_insert_with(|| {
                    representatives.push(j);
                    next
                });
                group_of[j as usize] = id;
            }
        }
        let groups = representatives.len();
        // Members of each group in node order (a counting sort by group).
        let mut members_offsets = vec![0usize; groups + 1];
        for &g in &group_of {
            members_offsets[g as usize + 1] += 1;
        }
        for g in 0..groups {
            members_offsets[g + 1] += members_offsets[g];
        }
        let mut members = vec![0u32; n];
        let mut next_slot = members_offsets.clone();
        for (j, &g) in group_of.iter().enumerate() {
            members[next_slot[g as usize]] = j as u32;
            next_slot[g as usize] += 1;
        }
        let mut col_ptr = Vec::with_capacity(groups + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0usize);
        let mut column: Vec<usize> = Vec::new();
        for &r in &representatives {
            column.clear();
            column.extend(pattern.neighbours(r).iter().map(|&k| group_of[k as usize] as usize));
            column.sort_unstable();
            column.dedup();
            row_idx.extend_from_slice(&column);
            col_ptr.push(row_idx.len());
        }
        Self { col_ptr, row_idx, members_offsets, members }
    }

    fn groups(&self) -> usize {
        self.col_ptr.len() - 1
    }

    /// Expands a group order (`order[new] = old group`) to scalar DOFs.
    fn expand(&self, order: &[usize]) -> ScalarOrdering {
        let n = self.members.len();
        let mut perm = Vec::with_capacity(3 * n);
        for &g in order {
            for &node in &self.members[self.members_offsets[g]..self.members_offsets[g + 1]] {
                perm.extend((0..3).map(|c| 3 * node as usize + c));
            }
        }
        let mut perm_inv = vec![0usize; 3 * n];
        for (new, &old) in perm.iter().enumerate() {
            perm_inv[old] = new;
        }
        ScalarOrdering { perm, perm_inv, groups: self.groups() }
    }

    /// Nested-dissection order of the groups: the graph is bisected by METIS (its multilevel
    /// recursive bisection; the safe binding has no `NodeND`, and the workspace forbids the FFI),
    /// each edge separator becomes a vertex separator (the cut's end points on the side that has
    /// fewer of them), the two halves are ordered recursively before their separator, and parts
    /// of at most [`DISSECTION_LEAF`] nodes take AMD. Groups weigh their member nodes. On a 3D grid this is the ordering with
    /// O(n²) factor work against AMD's larger constant (docs/results/voxel-bench.md, orderings).
    fn nested_dissection(&self) -> Result<Vec<usize>, CholeskyError> {
        let groups = self.groups();
        let mut order = Vec::with_capacity(groups);
        let mut local = vec![usize::MAX; groups];
        // A part is split into two parts to order and a separator to emit after both.
        enum Task {
            Part(Vec<usize>),
            Emit(Vec<usize>),
        }
        let mut tasks = vec![Task::Part((0..groups).collect())];
        while let Some(task) = tasks.pop() {
            let vertices = match task {
                Task::Emit(separator) => {
                    order.extend(separator);
                    continue;
                }
                Task::Part(vertices) => vertices,
            };
            let weight: usize = vertices.iter().map(|&g| self.members_offsets[g + 1] - self.members_offsets[g]).sum();
            if weight <= DISSECTION_LEAF {
                order.extend(self.amd_of(&vertices, &mut local)?);
                continue;
            }
            let (left, right, separator) = self.bisect(&vertices, &mut local)?;
            if left.is_empty() || right.is_empty() {
                // No useful cut (a clique or a tiny component): minimum degree for the rest.
                order.extend(self.amd_of(&vertices, &mut local)?);
                continue;
            }
            // Popped in reverse: left, then right, then the separator.
            tasks.push(Task::Emit(separator));
            tasks.push(Task::Part(right));
            tasks.push(Task::Part(left));
        }
        debug_assert_eq!(order.len(), groups);
        Ok(order)
    }

    /// The subgraph on `vertices` in METIS's CSR form (no self loops), with `local` mapping
    /// group → index in `vertices` (reset by the caller).
    fn subgraph(&self, vertices: &[usize], local: &mut [usize]) -> (Vec<metis::Idx>, Vec<metis::Idx>) {
        for (i, &v) in vertices.iter().enumerate() {
            local[v] = i;
        }
        let mut xadj = Vec::with_capacity(vertices.len() + 1);
        let mut adjncy = Vec::new();
        xadj.push(0);
        for &v in vertices {
            for &w in &self.row_idx[self.col_ptr[v]..self.col_ptr[v + 1]] {
                if w != v && local[w] != usize::MAX {
                    adjncy.push(local[w] as metis::Idx);
                }
            }
            xadj.push(adjncy.len() as metis::Idx);
        }
        (xadj, adjncy)
    }

    /// METIS bisection of `vertices` into (left, right, vertex separator).
    #[allow(clippy::type_complexity)]
    fn bisect(
        &self,
        vertices: &[usize],
        local: &mut [usize],
    ) -> Result<(Vec<usize>, Vec<usize>, Vec<usize>), CholeskyError> {
        let (xadj, adjncy) = self.subgraph(vertices, local);
        // Groups stand for their member nodes: balance nodes, not groups (a DG element's
        // basis functions are one group).
        let weights: Vec<metis::Idx> =
            vertices.iter().map(|&g| (self.members_offsets[g + 1] - self.members_offsets[g]) as metis::Idx).collect();
        let mut part = vec![0 as metis::Idx; vertices.len()];
        if adjncy.is_empty() {
            // No edges: any split is a dissection with an empty separator.
            let half = vertices.len() / 2;
            part[half..].fill(1);
        } else {
            metis::Graph::new(1, 2, &xadj, &adjncy)
                .map_err(|e| CholeskyError::Setup(format!("METIS graph: {e:?}")))?
                .set_vwgt(&weights)
                .part_recursive(&mut part)
                .map_err(|e| CholeskyError::Setup(format!("METIS bisection: {e:?}")))?;
        }
        // End points of cut edges on each side; the smaller set is the separator.
        let mut boundary = [Vec::new(), Vec::new()];
        for i in 0..vertices.len() {
            let side = part[i] as usize;
            let cut = adjncy[xadj[i] as usize..xadj[i + 1] as usize].iter().any(|&j| part[j as usize] as usize != side);
            if cut {
                boundary[side].push(i);
            }
        }
        let separator_side = if boundary[0].len() <= boundary[1].len() { 0 } else { 1 };
        let mut in_separator = vec![false; vertices.len()];
        for &i in &boundary[separator_side] {
            in_separator[i] = true;
        }
        let (mut left, mut right, mut separator) = (Vec::new(), Vec::new(), Vec::new());
        for (i, &v) in vertices.iter().enumerate() {
            if in_separator[i] {
                separator.push(v);
            } else if part[i] == 0 {
                left.push(v);
            } else {
                right.push(v);
            }
        }
        for &v in vertices {
            local[v] = usize::MAX;
        }
        Ok((left, right, separator))
    }

    /// AMD order of the subgraph on `vertices`, as groups.
    fn amd_of(&self, vertices: &[usize], local: &mut [usize]) -> Result<Vec<usize>, CholeskyError> {
        let (xadj, adjncy) = self.subgraph(vertices, local);
        for &v in vertices {
            local[v] = usize::MAX;
        }
        let n = vertices.len();
        let col_ptr: Vec<usize> = xadj.iter().map(|&x| x as usize).collect();
        let row_idx: Vec<usize> = adjncy.iter().map(|&x| x as usize).collect();
        let graph = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let (mut order, mut inverse) = (vec![0usize; n], vec![0usize; n]);
        let mut memory = MemBuffer::try_new(amd::order_scratch::<usize>(n, row_idx.len()))
            .map_err(|_| CholeskyError::Setup("out of memory for the AMD workspace".into()))?;
        amd::order(&mut order, &mut inverse, graph, amd::Control::default(), MemStack::new(&mut memory))
            .map_err(|e| CholeskyError::Setup(format!("AMD ordering: {e:?}")))?;
        Ok(order.into_iter().map(|i| vertices[i]).collect())
    }

    /// Approximate minimum degree order of the groups.
    fn amd(&self) -> Result<Vec<usize>, CholeskyError> {
        let groups = self.groups();
        let graph = SymbolicSparseColMatRef::new_checked(groups, groups, &self.col_ptr, None, &self.row_idx);
        let mut order = vec![0usize; groups];
        let mut inverse = vec![0usize; groups];
        let mut memory = MemBuffer::try_new(amd::order_scratch::<usize>(groups, self.row_idx.len()))
            .map_err(|_| CholeskyError::Setup("out of memory for the AMD workspace".into()))?;
        amd::order(&mut order, &mut inverse, graph, amd::Control::default(), MemStack::new(&mut memory))
            .map_err(|e| CholeskyError::Setup(format!("AMD ordering: {e:?}")))?;
        Ok(order)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    fn assert_is_scalar_permutation(ordering: &ScalarOrdering, dim: usize) {
        let mut seen = ordering.perm.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..dim).collect::<Vec<_>>());
        for (new, &old) in ordering.perm.iter().enumerate() {
            assert_eq!(ordering.perm_inv[old], new);
        }
        for chunk in ordering.perm.chunks(3) {
            assert!(chunk[0] % 3 == 0 && chunk[1] == chunk[0] + 1 && chunk[2] == chunk[0] + 2);
        }
    }

    #[test]
    fn nodes_with_identical_neighbourhoods_are_ordered_together() {
        // Two "elements" of 3 nodes coupled through the group {2, 3}: nodes 0, 1 see {0,1,2};
        // 2 sees {0,1,2,3} and 3 sees {2,3,4,5}, so only 0 ~ 1 and 4 ~ 5 merge.
        let groups: [&[u32]; 3] = [&[0, 1, 2], &[3, 4, 5], &[2, 3]];
        let pattern = AssemblyPattern::from_groups(6, groups.into_iter());
        let graph = QuotientGraph::new(&pattern);
        assert_eq!(graph.groups(), 4, "{{0,1}}, {{2}}, {{3}}, {{4,5}}");
        for order in [graph.amd().unwrap(), (0..graph.groups()).collect()] {
            let ordering = graph.expand(&order);
            assert_is_scalar_permutation(&ordering, 18);
            let position = |node: usize| ordering.perm_inv[3 * node] / 3;
            assert_eq!(position(0).abs_diff(position(1)), 1);
            assert_eq!(position(4).abs_diff(position(5)), 1);
        }
    }

    /// The matrix `Σ_groups (L_g ⊗ B)` plus `shift · I`, with `L_g` the complete graph
    /// Laplacian of a group (`|g| − 1` on the diagonal, −1 off it) and `B` a fixed SPD 3×3
    /// block: positive semidefinite, SPD for a positive shift.
    fn group_laplacian_system<const N: usize>(
        nodes: usize,
        groups: &[[u32; N]],
        shift: Real,
    ) -> (AssemblyPattern, Vec<Real>) {
        let pattern = AssemblyPattern::from_groups(nodes, groups.iter().map(|g| &g[..]));
        let mut values = vec![0.0; pattern.nnz()];
        let b = Matrix3::new(2.0, 0.5, 0.0, 0.5, 3.0, 0.25, 0.0, 0.25, 1.5);
        for g in groups {
            for &i in g {
                for &j in g {
                    let weight = if i == j { (N - 1) as Real } else { -1.0 };
                    pattern.add_block(&mut values, pattern.rank(i, j).unwrap(), j, &b, weight);
                }
            }
        }
        for j in 0..nodes as u32 {
            pattern.add_block(&mut values, pattern.rank(j, j).unwrap(), j, &Matrix3::identity(), shift);
        }
        (pattern, values)
    }

    /// A chain of 10 nodes coupled in pairs.
    fn chain_system(shift: Real) -> (AssemblyPattern, Vec<Real>) {
        let groups: Vec<[u32; 2]> = (0..9).map(|i| [i, i + 1]).collect();
        group_laplacian_system(10, &groups, shift)
    }

    #[test]
    fn solves_a_spd_system_to_round_off_and_rejects_an_indefinite_one() {
        let (pattern, values) = chain_system(0.1);
        let mut cholesky = SparseCholesky::new(&pattern).unwrap();
        cholesky.factorize(&values).unwrap();
        let x_true: Vec<Real> = (0..30).map(|i| (i as Real * 0.37).sin()).collect();
        let mut b = vec![0.0; 30];
        pattern.mul_vec(&values, &x_true, &mut b);
        cholesky.solve_in_place(&mut b);
        let error = b.iter().zip(&x_true).map(|(a, t)| (a - t).abs()).fold(0.0, Real::max);
        assert!(error < 1e-10, "max error {error}");
        // A negative shift larger than the smallest Laplacian eigenvalue (0) makes it indefinite.
        let (_, indefinite) = chain_system(-0.1);
        assert!(matches!(cholesky.factorize(&indefinite), Err(CholeskyError::NotPositiveDefinite { .. })));
    }

    #[test]
    fn a_multi_column_solve_solves_every_column() {
        // The grid's symmetric values (no nudge), so `mul_vec` is the matrix solved; large
        // enough that faer takes a supernodal factor (as on the bodies the integrator solves).
        let (pattern, values) = symmetric_grid_system();
        let mut cholesky = supernodal_factor(&pattern, &values);
        let dim = pattern.dim();
        for columns in [1, 3, 7, 2] {
            let truth: Vec<Real> = (0..dim * columns).map(|i| (i as Real * 0.37).sin() + (i / dim) as Real).collect();
            let mut rhs = vec![0.0; dim * columns];
            for (x, b) in truth.chunks(dim).zip(rhs.chunks_mut(dim)) {
                pattern.mul_vec(&values, x, b);
            }
            cholesky.solve_columns_in_place(&mut rhs, columns);
            let error = rhs.iter().zip(&truth).map(|(a, t)| (a - t).abs()).fold(0.0, Real::max);
            assert!(error < 1e-10, "{columns} columns: max error {error}");
        }
    }

    /// The factorization of `values` on `pattern`, asserted supernodal (keeping the permuted
    /// triangle), as on the bodies the integrator solves.
    fn supernodal_factor(pattern: &AssemblyPattern, values: &[Real]) -> SparseCholesky {
        let mut cholesky = SparseCholesky::new(pattern).unwrap();
        assert!(matches!(cholesky.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)), "a supernodal factor");
        cholesky.factorize(values).unwrap();
        cholesky
    }

    /// A 7×7×7 grid of nodes coupled by its 6³ cubes (8 nodes each), values `Laplacian ⊗ B`
    /// plus a shift: large enough that faer chooses a supernodal factor.
    fn symmetric_grid_system() -> (AssemblyPattern, Vec<Real>) {
        box_grid_system(7, 7, 7)
    }

    /// A box grid of `nx × ny × nz` nodes coupled by its cubes, values as in
    /// [`symmetric_grid_system`].
    fn box_grid_system(nx: u32, ny: u32, nz: u32) -> (AssemblyPattern, Vec<Real>) {
        let node = |x: u32, y: u32, z: u32| x + nx * (y + ny * z);
        let cubes: Vec<[u32; 8]> = (0..nz - 1)
            .flat_map(|z| (0..ny - 1).flat_map(move |y| (0..nx - 1).map(move |x| (x, y, z))))
            .map(|(x, y, z)| {
                [0, 1, 2, 3, 4, 5, 6, 7].map(|c| node(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1)))
            })
            .collect();
        group_laplacian_system((nx * ny * nz) as usize, &cubes, 0.5)
    }

    /// Nested dissection is a valid order that solves to round-off; on an elongated box grid
    /// (the cantilever's shape, 4:1:1) its factor needs fewer operations than AMD's, as the
    /// theory of separators says for 3D grids; `Auto` keeps AMD below its threshold.
    #[test]
    fn nested_dissection_solves_and_beats_amd_on_a_box_grid() {
        let (pattern, values) = box_grid_system(41, 11, 11);
        let graph = QuotientGraph::new(&pattern);
        let order = graph.nested_dissection().unwrap();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..graph.groups()).collect::<Vec<_>>(), "a permutation of the groups");
        let mut flops = Vec::new();
        for ordering in [FillOrdering::Amd, FillOrdering::NestedDissection] {
            let mut cholesky = SparseCholesky::with_ordering(&pattern, ordering).unwrap();
            assert_eq!(cholesky.ordering(), ordering);
            cholesky.factorize(&values).unwrap();
            let truth: Vec<Real> = (0..pattern.dim()).map(|i| (i as Real * 0.37).sin()).collect();
            let mut b = vec![0.0; pattern.dim()];
            pattern.mul_vec(&values, &truth, &mut b);
            cholesky.solve_in_place(&mut b);
            let error = b.iter().zip(&truth).map(|(a, t)| (a - t).abs()).fold(0.0, Real::max);
            assert!(error < 1e-9, "{ordering:?}: max error {error}");
            flops.push(cholesky.factor_flops());
        }
        println!("factor flops: AMD {:.3e}, nested dissection {:.3e}", flops[0], flops[1]);
        assert!(flops[1] < 0.9 * flops[0], "nested dissection {:.3e} against AMD {:.3e}", flops[1], flops[0]);
        assert!(flops[0] < AUTO_DISSECTION_FLOPS);
        assert_eq!(SparseCholesky::new(&pattern).unwrap().ordering(), FillOrdering::Amd, "below the threshold");
    }

    /// Above the threshold `Auto` compares both and keeps nested dissection on the cantilever's
    /// grid (64 × 16 × 16 cubes), whose factor it halves (docs/results/voxel-bench.md, orderings).
    #[test]
    fn auto_keeps_nested_dissection_where_it_needs_fewer_operations() {
        let (pattern, _) = box_grid_system(65, 17, 17);
        let auto = SparseCholesky::new(&pattern).unwrap();
        let amd = SparseCholesky::with_ordering(&pattern, FillOrdering::Amd).unwrap();
        assert!(amd.factor_flops() > AUTO_DISSECTION_FLOPS);
        assert_eq!(auto.ordering(), FillOrdering::NestedDissection);
        assert!(
            auto.factor_flops() < 0.7 * amd.factor_flops(),
            "{:.3e} against {:.3e}",
            auto.factor_flops(),
            amd.factor_flops()
        );
    }

    /// [`symmetric_grid_system`] with every entry above the diagonal then nudged: no longer
    /// symmetric bit for bit, so reading the wrong triangle would show.
    fn grid_system() -> (AssemblyPattern, Vec<Real>) {
        let (pattern, mut values) = symmetric_grid_system();
        for col in 0..pattern.dim() {
            for k in pattern.col_ptr()[col]..pattern.col_ptr()[col + 1] {
                if pattern.row_idx()[k] < col {
                    values[k] *= 1.0 + 1e-9;
                }
            }
        }
        (pattern, values)
    }

    /// The permuted triangles built at the node level (the upper analysed, the lower factorized,
    /// both in the identity order) give the factor faer computes from the pattern and the same
    /// order with its own permutation, bit for bit, and the solves agree with faer's.
    #[test]
    fn the_node_level_permuted_triangles_give_faers_own_factor_bit_for_bit() {
        let (pattern, values) = grid_system();
        let mut cholesky = supernodal_factor(&pattern, &values);
        let dim = pattern.dim();
        let matrix =
            SymbolicSparseColMat::new_checked(dim, dim, pattern.col_ptr().to_vec(), None, pattern.row_idx().to_vec());
        let perm_inv = {
            let mut inverse = vec![0; dim];
            for (new, &old) in cholesky.perm.iter().enumerate() {
                inverse[old] = new;
            }
            inverse
        };
        let faers_symbolic = factorize_symbolic_cholesky(
            matrix.as_ref(),
            Side::Lower,
            SymmetricOrdering::Custom(faer::perm::PermRef::new_checked(&cholesky.perm, &perm_inv, dim)),
            Default::default(),
        )
        .unwrap();
        assert_eq!(faers_symbolic.len_val(), cholesky.factor_nnz());
        let mut faers = vec![0.0; cholesky.factor_values.len()];
        faers_symbolic
            .factorize_numeric_llt::<Real>(
                &mut faers,
                SparseColMatRef::new(matrix.as_ref(), &values),
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut MemBuffer::new(
                    faers_symbolic.factorize_numeric_llt_scratch::<Real>(Par::Seq, Default::default()),
                )),
                Default::default(),
            )
            .unwrap();
        assert!(cholesky.factor_values.iter().zip(&faers).all(|(a, b)| a.to_bits() == b.to_bits()));
        // And it solves the lower triangle's system (the one both read) to round-off.
        let dim = pattern.dim();
        let x_true: Vec<Real> = (0..dim).map(|i| (i as Real * 0.37).sin()).collect();
        let mut rhs = vec![0.0; dim];
        for col in 0..dim {
            for k in pattern.col_ptr()[col]..pattern.col_ptr()[col + 1] {
                let row = pattern.row_idx()[k];
                if row >= col {
                    rhs[row] += values[k] * x_true[col];
                    if row > col {
                        rhs[col] += values[k] * x_true[row];
                    }
                }
            }
        }
        let mut faers_solution = rhs.clone();
        let mut solve_scratch = MemBuffer::new(faers_symbolic.solve_in_place_scratch::<Real>(1, Par::Seq));
        LltRef::<'_, usize, Real>::new(&faers_symbolic, &faers).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut faers_solution, dim, 1),
            Par::Seq,
            MemStack::new(&mut solve_scratch),
        );
        cholesky.solve_in_place(&mut rhs);
        assert!(rhs.iter().zip(&faers_solution).all(|(a, b)| a.to_bits() == b.to_bits()));
        let error = rhs.iter().zip(&x_true).map(|(a, t)| (a - t).abs()).fold(0.0, Real::max);
        assert!(error < 1e-10, "max error {error}");
    }

    /// Σ_j c_j² by elimination on bit sets: the structure of `P A Pᵀ`, then for each column k
    /// every row of it below k gains k's structure below the diagonal (the elimination graph).
    fn flops_by_elimination(pattern: &AssemblyPattern, perm: &[usize]) -> f64 {
        let n = pattern.dim();
        let words = n.div_ceil(64);
        let mut new_of_old = vec![0; n];
        for (new, &old) in perm.iter().enumerate() {
            new_of_old[old] = new;
        }
        // Column j's rows (a symmetric structure: rows of column j = columns of row j).
        let mut structure = vec![0u64; n * words];
        for old_col in 0..n {
            for &old_row in &pattern.row_idx()[pattern.col_ptr()[old_col]..pattern.col_ptr()[old_col + 1]] {
                let (r, c) = (new_of_old[old_row], new_of_old[old_col]);
                structure[c * words + r / 64] |= 1 << (r % 64);
            }
        }
        let mut flops = 0.0;
        for k in 0..n {
            let below: Vec<usize> = (k..n).filter(|&r| structure[k * words + r / 64] >> (r % 64) & 1 == 1).collect();
            flops += (below.len() as f64).powi(2);
            for &i in below.iter().filter(|&&i| i > k) {
                for &r in &below {
                    if r >= i {
                        structure[i * words + r / 64] |= 1 << (r % 64);
                    }
                }
            }
        }
        flops
    }

    #[test]
    fn the_flop_count_is_that_of_the_elimination() {
        // Simplicial (a chain) and supernodal (the grid) structures against the elimination on
        // bit sets in the same order: equal for the simplicial factor; the supernodal one may
        // hold explicit zeros where faer merged columns into supernodes, so it counts at least
        // as much, and not much more.
        let (chain, _) = chain_system(0.1);
        let cholesky = SparseCholesky::new(&chain).unwrap();
        assert!(matches!(cholesky.symbolic.raw(), SymbolicCholeskyRaw::Simplicial(_)));
        assert_eq!(cholesky.factor_flops(), flops_by_elimination(&chain, &cholesky.perm));
        let (grid, values) = symmetric_grid_system();
        let cholesky = supernodal_factor(&grid, &values);
        let exact = flops_by_elimination(&grid, &cholesky.perm);
        let counted = cholesky.factor_flops();
        println!("grid: {counted:.4e} flops counted, {exact:.4e} by elimination");
        assert!(counted >= exact && counted <= 1.3 * exact, "{counted} against {exact}");
        assert!(!cholesky.is_parallel(), "{counted} flops are below the parallel threshold");
    }
}
