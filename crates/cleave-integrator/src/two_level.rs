//! The two-level CG preconditioner: block-Jacobi plus a coarse-space correction,
//!
//! ```text
//! z = D⁻¹ r + Z P A_c⁻¹ Pᵀ Z r,      A_c = Pᵀ Z A₀ Z P   (Galerkin)
//! ```
//!
//! where `P` is the backend's prolongation ([`cleave_core::CoarseSpace`]), `Z` zeroes pinned DOFs
//! and `A₀ = c_M M + c_K K + h² K_pins + K_contacts` is the step matrix with the rotations at
//! identity and the contacts of some recent step. `A₀` without contacts does not change within
//! an epoch, so its Galerkin values are assembled once per epoch; the contacts' terms are added
//! and `A_c` is factorized again (same pattern, symbolic analysis kept) only when the contacts that
//! joined or left since number more than [`CONTACT_REFRESH_FRACTION`] of them. Every
//! application costs one restriction, one pair of triangular solves and one prolongation. The
//! additive form is symmetric positive definite for any positive definite `A_c`, so CG stays valid
//! however far the rotations and contacts of a step drift from `A₀`; they only cost iterations.
//! Contact stiffness is why the contacts are in it: a resting body's penalty terms `h² k` are
//! thousands of times its nodes' masses, and a coarse operator without them proposes corrections
//! the contacts resist (the voxel bunny at rest: 16 CG iterations a step without, see
//! `docs/results/voxel-bench.md`).

use crate::constraints::PenaltyPins;
use crate::error::StepErrorKind;
use cleave_contact::{Contact, for_each_entry};
use cleave_core::{AssemblyPattern, CoarseSpace, Discretization, Embedding, Matrix3, Real, SparseCholesky};
use rayon::prelude::*;

/// The coarse operator, its factorization and the transfer operators of one epoch.
pub(crate) struct TwoLevel {
    prolongation: Embedding,
    /// `Pᵀ` by coarse node: (fine node, weight) lists, for a parallel gather.
    restriction: Embedding,
    /// Fine scalar DOFs that are pinned (`Z`).
    pinned: Vec<bool>,
    cholesky: SparseCholesky,
    coarse: Vec<Real>,
    /// The coarse pattern and `Pᵀ Z A₀ Z P` without contacts (the epoch's part).
    pattern: AssemblyPattern,
    base_values: Vec<Real>,
    /// Scratch for the values with contacts.
    values: Vec<Real>,
    /// The contacts `A_c` holds, as sorted (kind, slot) keys, and this step's.
    held: Vec<(u8, u32)>,
    current: Vec<(u8, u32)>,
    /// Times `A_c` was factorized again for contacts (for the step reports).
    refreshes: usize,
    /// Buffers of the Galerkin terms and of one contact's (node, weight) entries.
    scratch: GalerkinScratch,
    entries: (Vec<u32>, Vec<Real>),
}

/// How many contacts may have joined or left since `A_c` took its contacts (the symmetric
/// difference of the two sets, keyed by collider kind and point slot), as a fraction of the larger
/// set, before `A_c` takes the step's contacts and is factorized again. A point that moves to
/// another triangle keeps its slot and does not count. Any `A_c` keeps the preconditioner valid;
/// this trades factorizations against iterations.
pub(crate) const CONTACT_REFRESH_FRACTION: Real = 0.25;

/// Coarse nodes of the union of the prolongation rows of `nodes`, sorted.
fn coarse_union(prolongation: &Embedding, nodes: &[u32], out: &mut Vec<u32>) {
    out.clear();
    for &n in nodes {
        out.extend_from_slice(prolongation.row(n as usize).0);
    }
    out.sort_unstable();
    out.dedup();
}

/// Adds `Pᵀ Z K Z P` of one fine term (nodes, 3×3 blocks `k(i, j)`) to the coarse values.
struct Galerkin<'a> {
    prolongation: &'a Embedding,
    pinned: &'a [bool],
    pattern: &'a AssemblyPattern,
    scratch: &'a mut GalerkinScratch,
}

/// Buffers of [`Galerkin::add`], kept across calls (and across the refreshes of `A_c`).
#[derive(Default)]
struct GalerkinScratch {
    union: Vec<u32>,
    ranks: Vec<u32>,
    local: Vec<Matrix3<Real>>,
}

impl Galerkin<'_> {
    /// Adds the term, or returns `false` (adding nothing) when the coarse pattern does not
    /// couple every pair of its coarse nodes.
    fn add(&mut self, nodes: &[u32], k: impl Fn(usize, usize) -> Matrix3<Real>, values: &mut [Real]) -> bool {
        let GalerkinScratch { union, ranks, local } = &mut *self.scratch;
        coarse_union(self.prolongation, nodes, union);
        let m = union.len();
        ranks.clear();
        for &cj in union.iter() {
            for &ci in union.iter() {
                match self.pattern.rank(ci, cj) {
                    Some(rank) => ranks.push(rank),
                    None => return false,
                }
            }
        }
        local.clear();
        local.resize(m * m, Matrix3::zeros());
        let position = |union: &[u32], c: u32| union.binary_search(&c).expect("the union holds every row's nodes");
        for (i, &ni) in nodes.iter().enumerate() {
            for (j, &nj) in nodes.iter().enumerate() {
                let mut kij = k(i, j);
                for a in 0..3 {
                    if self.pinned[3 * ni as usize + a] {
                        kij.row_mut(a).fill(0.0);
                    }
                    if self.pinned[3 * nj as usize + a] {
                        kij.column_mut(a).fill(0.0);
                    }
                }
                let (ci, wi) = self.prolongation.row(ni as usize);
                let (cj, wj) = self.prolongation.row(nj as usize);
                for (&ci, &wi) in ci.iter().zip(wi) {
                    let row = position(union, ci);
                    for (&cj, &wj) in cj.iter().zip(wj) {
                        let col = position(union, cj);
                        local[row * m + col] += kij * (wi * wj);
                    }
                }
            }
        }
        for (col, &cj) in union.iter().enumerate() {
            for row in 0..m {
                self.pattern.add_block(values, ranks[col * m + row], cj, &local[row * m + col], 1.0);
            }
        }
        true
    }
}

impl TwoLevel {
    /// Assembles and factorizes `A_c` for an epoch.
    pub(crate) fn new(
        discretization: &dyn Discretization,
        space: CoarseSpace,
        pinned: &[bool],
        penalty_pins: Option<&PenaltyPins>,
        mass_scale: Real,
        stiffness_scale: Real,
        h: Real,
    ) -> Result<Self, StepErrorKind> {
        let CoarseSpace { num_nodes: num_coarse, prolongation } = space;
        let num_fine = discretization.num_nodes();
        if prolongation.len() != num_fine {
            return Err(StepErrorKind::Solver(format!(
                "the coarse space has {} prolongation rows for {num_fine} nodes",
                prolongation.len()
            )));
        }
        if let Some(&bad) = (0..num_fine).flat_map(|k| prolongation.row(k).0).find(|&&c| c as usize >= num_coarse) {
            return Err(StepErrorKind::Solver(format!("coarse node {bad} out of range (0..{num_coarse})")));
        }
        let blocks = discretization.blocks();
        let mut union = Vec::new();
        let mut groups: Vec<Vec<u32>> = Vec::with_capacity(blocks.len());
        for nodes in blocks.node_groups() {
            coarse_union(&prolongation, nodes, &mut union);
            groups.push(union.clone());
        }
        if let Some(pins) = penalty_pins {
            for nodes in pins.points.node_groups() {
                coarse_union(&prolongation, nodes, &mut union);
                groups.push(union.clone());
            }
        }
        let pattern = AssemblyPattern::from_groups(num_coarse, groups.iter().map(Vec::as_slice));
        drop(groups);
        let mut values = pattern.new_values();
        let mut scratch = GalerkinScratch { union, ..Default::default() };
        let mut galerkin = Galerkin { prolongation: &prolongation, pinned, pattern: &pattern, scratch: &mut scratch };
        for b in 0..blocks.len() {
            let block = blocks.block(b);
            // Rotations at identity: the rest matrix itself.
            let k = |i: usize, j: usize| -> Matrix3<Real> {
                block.rest.fixed_view::<3, 3>(3 * i, 3 * j).into_owned() * stiffness_scale
            };
            assert!(galerkin.add(block.nodes, k, &mut values), "the coarse pattern holds every block's union");
        }
        if let Some(pins) = penalty_pins {
            for i in 0..pins.points.len() {
                let (nodes, weights) = pins.points.row(i);
                let k = |a: usize, b: usize| Matrix3::identity() * (h * h * pins.stiffness * weights[a] * weights[b]);
                assert!(galerkin.add(nodes, k, &mut values), "the coarse pattern holds every pin's union");
            }
        }
        let mass = discretization.mass().diagonal();
        for k in 0..num_fine {
            let (nodes, weights) = prolongation.row(k);
            for (&cj, &wj) in nodes.iter().zip(weights) {
                for (&ci, &wi) in nodes.iter().zip(weights) {
                    let rank = pattern.rank(ci, cj).expect("a row's nodes share a term");
                    for a in 0..3 {
                        if !pinned[3 * k + a] {
                            values[pattern.position(rank, cj, a, a)] += mass_scale * mass[3 * k + a] * wi * wj;
                        }
                    }
                }
            }
        }
        // Coarse DOFs that no free fine DOF touches have an empty row: make it the identity (the
        // restriction is zero there, so their correction stays zero).
        for c in 0..num_coarse as u32 {
            let rank = pattern.rank(c, c).expect("diagonal is in the pattern");
            for a in 0..3 {
                let p = pattern.position(rank, c, a, a);
                if values[p] == 0.0 {
                    values[p] = 1.0;
                }
            }
        }

        let dim = pattern.dim();
        let mut cholesky = SparseCholesky::new(&pattern)?;
        cholesky.factorize(&values)?;

        let mut lists: Vec<Vec<(u32, Real)>> = vec![Vec::new(); num_coarse];
        for k in 0..num_fine {
            let (nodes, weights) = prolongation.row(k);
            for (&c, &w) in nodes.iter().zip(weights) {
                lists[c as usize].push((k as u32, w));
            }
        }
        let mut restriction = Embedding::new();
        let (mut nodes, mut weights) = (Vec::new(), Vec::new());
        for list in &lists {
            nodes.clear();
            weights.clear();
            nodes.extend(list.iter().map(|e| e.0));
            weights.extend(list.iter().map(|e| e.1));
            restriction.push_row(&nodes, &weights);
        }
        Ok(Self {
            prolongation,
            restriction,
            pinned: pinned.to_vec(),
            cholesky,
            coarse: vec![0.0; dim],
            base_values: values.clone(),
            values,
            pattern,
            held: Vec::new(),
            current: Vec::new(),
            refreshes: 0,
            scratch,
            entries: (Vec::new(), Vec::new()),
        })
    }

    /// Takes the step's active `contacts` into `A_c` when they differ from those it holds by more
    /// than [`CONTACT_REFRESH_FRACTION`]: `A_c = Pᵀ Z (A₀ + Σ_contacts w wᵀ ⊗ P_c) Z P`, refactorized
    /// on the kept symbolic analysis. A contact whose coarse nodes the coarse pattern does not
    /// couple (two pieces' cubes in different coarse cells) is left out: `A_c` only has to be
    /// positive definite. Returns whether it refactorized.
    pub(crate) fn take_contacts(&mut self, points: &Embedding, contacts: &[Contact]) -> Result<bool, StepErrorKind> {
        self.current.clear();
        self.current.extend(contacts.iter().map(|c| (c.kind as u8, c.slot)));
        self.current.sort_unstable();
        let (mut differ, mut i, mut j) = (0usize, 0usize, 0usize);
        while i < self.held.len() || j < self.current.len() {
            match (self.held.get(i), self.current.get(j)) {
                (Some(a), Some(b)) if a == b => (i, j) = (i + 1, j + 1),
                (Some(a), Some(b)) if a < b => (differ, i) = (differ + 1, i + 1),
                (Some(_), None) => (differ, i) = (differ + 1, i + 1),
                _ => (differ, j) = (differ + 1, j + 1),
            }
        }
        let size = self.held.len().max(self.current.len());
        if differ == 0 || (differ as Real) <= CONTACT_REFRESH_FRACTION * size as Real {
            return Ok(false);
        }
        // A contact whose matrix is not finite (a step gone to NaN) stays out: the step reports
        // it as not finite, and the coarse operator stays factorized.
        self.values.copy_from_slice(&self.base_values);
        let mut galerkin = Galerkin {
            prolongation: &self.prolongation,
            pinned: &self.pinned,
            pattern: &self.pattern,
            scratch: &mut self.scratch,
        };
        let (nodes, weights) = &mut self.entries;
        for c in contacts.iter().filter(|c| c.matrix.iter().all(|m| m.is_finite())) {
            nodes.clear();
            weights.clear();
            for_each_entry(points, c, |n, w| {
                nodes.push(n);
                weights.push(w);
            });
            // A term the coarse pattern does not couple is left out (`add` returns false).
            galerkin.add(nodes, |i, j| c.matrix * (weights[i] * weights[j]), &mut self.values);
        }
        if let Err(error) = self.cholesky.factorize(&self.values) {
            // Back to the operator without contacts, which factorized when the epoch began, so
            // that a later step never meets an unfactorized coarse solve.
            self.held.clear();
            self.cholesky.factorize(&self.base_values)?;
            return Err(error.into());
        }
        std::mem::swap(&mut self.held, &mut self.current);
        self.refreshes += 1;
        Ok(true)
    }

    /// Times `A_c` was factorized again for the step's contacts.
    pub(crate) fn refreshes(&self) -> usize {
        self.refreshes
    }

    /// Coarse DOFs and nonzeros of the coarse factor.
    pub(crate) fn size(&self) -> (usize, usize) {
        (self.coarse.len(), self.cholesky.factor_nnz())
    }

    /// `z += Z P A_c⁻¹ Pᵀ Z r`.
    pub(crate) fn add_correction(&mut self, r: &[Real], z: &mut [Real]) {
        let (restriction, pinned) = (&self.restriction, &self.pinned);
        self.coarse.par_chunks_mut(3).enumerate().for_each(|(c, out)| {
            let (nodes, weights) = restriction.row(c);
            out.fill(0.0);
            for (&k, &w) in nodes.iter().zip(weights) {
                for a in 0..3 {
                    let d = 3 * k as usize + a;
                    if !pinned[d] {
                        out[a] += w * r[d];
                    }
                }
            }
        });
        self.cholesky.solve_in_place_sequential(&mut self.coarse);
        let (prolongation, coarse) = (&self.prolongation, &self.coarse);
        z.par_chunks_mut(3).enumerate().for_each(|(k, out)| {
            let (nodes, weights) = prolongation.row(k);
            for a in 0..3 {
                if !pinned[3 * k + a] {
                    out[a] += nodes.iter().zip(weights).map(|(&c, &w)| w * coarse[3 * c as usize + a]).sum::<Real>();
                }
            }
        });
    }
}
