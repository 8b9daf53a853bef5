//! Pairs that join a step after its factorization, solved as a low-rank update of that
//! factorization (Sherman–Morrison–Woodbury) instead of a grown pattern and a new factorization:
//! docs/math/contact.md §3, "Pairs that join after the factorization".
//!
//! A contact adds `(w wᵀ) ⊗ P` to the matrix `A`, with `P = Σ λ_k e_k e_kᵀ` symmetric positive
//! semi-definite (its eigen-decomposition), so it adds `Σ u_k u_kᵀ` with the columns
//! `u_k = w ⊗ (√λ_k e_k)`. With `V` the matrix of all such columns of the pairs that joined,
//!
//! ```text
//! (A + V Vᵀ)⁻¹ b = y − Z (I + Vᵀ Z)⁻¹ Vᵀ y,     y = A⁻¹ b,  Z = A⁻¹ V
//! ```
//!
//! which needs one multi-column solve with the factorization already computed and an `r × r`
//! Cholesky (`r` the number of columns), not the pattern those pairs couple.

use cleave_contact::{Contact, for_each_entry};
use cleave_core::{Embedding, Real};
use nalgebra::{DMatrix, DVector};

/// Most columns a step takes as a low-rank update; beyond, the pattern grows and the matrix is
/// factorized again. A column costs about what a twentieth of a factorization does on
/// `bunny_slice.ron` (a multi-column solve against a refactorization), so the limit sits where
/// the two cost about the same (docs/math/contact.md §3).
pub(crate) const MAX_COLUMNS: usize = 64;

/// Eigenvalues of a contact's `P` below this fraction of its largest are dropped (round-off of a
/// rank-one or rank-zero part).
const DROPPED_EIGENVALUE: Real = 1e-13;

/// The columns of the pairs that joined a step, their solves and the solution they started from.
#[derive(Debug, Default)]
pub(crate) struct LowRankUpdate {
    /// `y = A⁻¹ b`: the step's solution before any pair joined.
    base: Vec<Real>,
    /// Column `k` of `V` holds `entries[offsets[k]..offsets[k + 1]]` as (DOF, value), a DOF
    /// possibly more than once (the values add).
    offsets: Vec<usize>,
    entries: Vec<(u32, Real)>,
    /// `Z = A⁻¹ V`, column-major, each column of the system's dimension.
    solved: Vec<Real>,
}

impl LowRankUpdate {
    /// Starts from the solution `y = A⁻¹ b` of the factorized matrix.
    pub(crate) fn begin(&mut self, solution: &[Real]) {
        self.base.clear();
        self.base.extend_from_slice(solution);
        self.offsets.clear();
        self.offsets.push(0);
        self.entries.clear();
        self.solved.clear();
    }

    /// Number of columns so far.
    pub(crate) fn rank(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Appends the columns of `contacts`; `pinned` DOFs are left out (the matrix's pinned rows
    /// and columns are the identity's, whatever the contacts add).
    pub(crate) fn push_contacts(&mut self, points: &Embedding, contacts: &[Contact], pinned: &[bool]) {
        for c in contacts {
            if !c.matrix.iter().all(|m| m.is_finite()) {
                // A column that `solve` refuses, without running the eigensolver on values it
                // may not finish on (a diverged state: the step then takes the path without the
                // update, which reports the divergence).
                self.entries.push((0, Real::NAN));
                self.offsets.push(self.entries.len());
                continue;
            }
            let eigen = c.matrix.symmetric_eigen();
            let largest = eigen.eigenvalues.max();
            for (k, &lambda) in eigen.eigenvalues.iter().enumerate() {
                if lambda <= DROPPED_EIGENVALUE * largest {
                    continue;
                }
                let direction = eigen.eigenvectors.column(k) * lambda.sqrt();
                for_each_entry(points, c, |node, w| {
                    for a in 0..3 {
                        let dof = 3 * node as usize + a;
                        if !pinned[dof] {
                            self.entries.push((dof as u32, w * direction[a]));
                        }
                    }
                });
                self.offsets.push(self.entries.len());
            }
        }
    }

    /// Solves the columns not solved yet with the factorization (`solve_columns(rhs, count)`
    /// solves `count` column-major columns in place), then writes
    /// `(A + V Vᵀ)⁻¹ b` to `v`. `false` (and `v` untouched) if a column is not finite or the capacitance matrix
    /// `I + Vᵀ Z` is not numerically positive definite.
    pub(crate) fn solve(&mut self, solve_columns: impl FnOnce(&mut [Real], usize), v: &mut [Real]) -> bool {
        if !self.entries.iter().all(|(_, value)| value.is_finite()) {
            return false;
        }
        let dim = self.base.len();
        let rank = self.rank();
        let done = self.solved.len() / dim;
        self.solved.resize(dim * rank, 0.0);
        for k in done..rank {
            let column = &mut self.solved[k * dim..(k + 1) * dim];
            for &(dof, value) in &self.entries[self.offsets[k]..self.offsets[k + 1]] {
                column[dof as usize] += value;
            }
        }
        solve_columns(&mut self.solved[done * dim..], rank - done);
        let column = |k: usize| &self.entries[self.offsets[k]..self.offsets[k + 1]];
        let dot = |k: usize, x: &[Real]| column(k).iter().map(|&(dof, value)| value * x[dof as usize]).sum::<Real>();
        let capacitance = DMatrix::from_fn(rank, rank, |i, j| {
            let vz = dot(i, &self.solved[j * dim..(j + 1) * dim]);
            if i == j { 1.0 + vz } else { vz }
        });
        // Vᵀ Z is symmetric in exact arithmetic; its mean is what the Cholesky reads.
        let capacitance = (&capacitance + capacitance.transpose()) * 0.5;
        let Some(cholesky) = capacitance.cholesky() else { return false };
        let projected = DVector::from_fn(rank, |k, _| dot(k, &self.base));
        let t = cholesky.solve(&projected);
        v.copy_from_slice(&self.base);
        for (k, &tk) in t.iter().enumerate() {
            for (v, z) in v.iter_mut().zip(&self.solved[k * dim..(k + 1) * dim]) {
                *v -= tk * z;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cleave_contact::{ContactKind, Row};
    use cleave_core::{AssemblyPattern, Matrix3, SparseCholesky, Vector3};

    /// A contact row over `points` with `weights`, `P = a n nᵀ + b (I − n nᵀ)`.
    fn contact(points: &[u32], weights: &[Real], n: Vector3<Real>, a: Real, b: Real) -> Contact {
        let mut row = Row { points: [0; 4], weights: [0.0; 4], len: points.len() as u8 };
        row.points[..points.len()].copy_from_slice(points);
        row.weights[..points.len()].copy_from_slice(weights);
        let n = n.normalize();
        let nn = n * n.transpose();
        Contact {
            row,
            matrix: nn * a + (Matrix3::identity() - nn) * b,
            force: Vector3::zeros(),
            depth: 0.0,
            stiffness: 0.0,
            damping: 0.0,
            normal: n,
            slot: 0,
            offset: 0.0,
            kind: ContactKind::Surface,
        }
    }

    /// Against a dense solve of the matrix with the contacts' blocks added and the pinned rows
    /// and columns replaced by the identity's: a chain of 8 nodes (a sparse SPD matrix), surface
    /// points embedded in one or two nodes, contacts of rank one and three (stiffness 10⁴ times
    /// the matrix's diagonal, as a penalty against a nodal mass), a DOF pinned, added in two
    /// passes as a step adds them.
    #[test]
    fn the_update_solves_the_matrix_with_the_pairs_added() {
        let nodes = 8;
        let groups: Vec<[u32; 2]> = (0..nodes as u32 - 1).map(|i| [i, i + 1]).collect();
        let pattern = AssemblyPattern::from_groups(nodes, groups.iter().map(|g| &g[..]));
        let mut values = pattern.new_values();
        let block = Matrix3::new(2.0, 0.5, 0.0, 0.5, 3.0, 0.25, 0.0, 0.25, 1.5);
        for g in &groups {
            for &i in g {
                for &j in g {
                    pattern.add_block(
                        &mut values,
                        pattern.rank(i, j).unwrap(),
                        j,
                        &block,
                        if i == j { 1.0 } else { -1.0 },
                    );
                }
            }
        }
        for j in 0..nodes as u32 {
            pattern.add_block(&mut values, pattern.rank(j, j).unwrap(), j, &Matrix3::identity(), 0.3);
        }
        let dim = 3 * nodes;
        let pinned_dof = 4;
        let mut pinned = vec![false; dim];
        pinned[pinned_dof] = true;
        let mut dense = DMatrix::zeros(dim, dim);
        let mut e = vec![0.0; dim];
        let mut column = vec![0.0; dim];
        for j in 0..dim {
            e.iter_mut().for_each(|x| *x = 0.0);
            e[j] = 1.0;
            pattern.mul_vec(&values, &e, &mut column);
            dense.column_mut(j).copy_from_slice(&column);
        }
        let pin = |m: &mut DMatrix<Real>| {
            m.row_mut(pinned_dof).fill(0.0);
            m.column_mut(pinned_dof).fill(0.0);
            m[(pinned_dof, pinned_dof)] = 1.0;
        };
        pin(&mut dense);
        // The factorized matrix has the pin applied as the integrator's does.
        let mut factor_values = values.clone();
        for col in 0..dim {
            for k in pattern.col_ptr()[col]..pattern.col_ptr()[col + 1] {
                let row = pattern.row_idx()[k];
                if row == pinned_dof || col == pinned_dof {
                    factor_values[k] = if row == col { 1.0 } else { 0.0 };
                }
            }
        }
        let mut cholesky = SparseCholesky::new(&pattern).unwrap();
        cholesky.factorize(&factor_values).unwrap();

        let mut points = Embedding::new();
        for n in 0..nodes as u32 {
            points.push_row(&[n], &[1.0]);
        }
        points.push_row(&[2, 3], &[0.25, 0.75]);
        points.push_row(&[6, 7], &[0.6, 0.4]);
        let k = 1e4 * block.norm();
        let first = [
            contact(&[0, 5, 6, 7], &[1.0, -0.2, -0.3, -0.5], Vector3::new(0.3, -1.0, 0.2), k, 0.0),
            contact(&[8, 1], &[1.0, -1.0], Vector3::new(1.0, 0.4, 0.1), k, 0.05 * k),
        ];
        let second = [contact(&[9, 1, 4, 8], &[1.0, -0.5, -0.25, -0.25], Vector3::new(-0.2, 0.1, 1.0), k, 0.01 * k)];

        let b: Vec<Real> = (0..dim).map(|i| if i == pinned_dof { 0.0 } else { (i as Real * 0.61).cos() }).collect();
        let mut y = b.clone();
        cholesky.solve_in_place(&mut y);
        let mut update = LowRankUpdate::default();
        update.begin(&y);
        let mut v = vec![0.0; dim];
        for pass in [&first[..], &second[..]] {
            update.push_contacts(&points, pass, &pinned);
            assert!(update.solve(|rhs, count| cholesky.solve_columns_in_place(rhs, count), &mut v));
            // The dense matrix with every contact so far.
            for c in pass {
                let mut w = Vec::new();
                for_each_entry(&points, c, |node, weight| w.push((node as usize, weight)));
                for &(i, wi) in &w {
                    for &(j, wj) in &w {
                        for a in 0..3 {
                            for bb in 0..3 {
                                dense[(3 * i + a, 3 * j + bb)] += wi * wj * c.matrix[(a, bb)];
                            }
                        }
                    }
                }
            }
            let mut pinned_dense = dense.clone();
            pin(&mut pinned_dense);
            let truth = pinned_dense.lu().solve(&DVector::from_column_slice(&b)).unwrap();
            let scale = truth.amax();
            let error = v.iter().zip(truth.iter()).map(|(a, t)| (a - t).abs()).fold(0.0, Real::max);
            assert!(error < 1e-9 * scale, "rank {}: max error {error} of {scale}", update.rank());
            assert_eq!(v[pinned_dof], 0.0);
        }
        assert_eq!(update.rank(), 1 + 3 + 3, "rank-one, then two rank-three contacts");
    }
}
