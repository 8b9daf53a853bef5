//! Sparse patterns of 3×3-blocked symmetric matrices, built once per epoch; kernels write values
//! through precomputed positions (no search, no allocation per step).
//!
//! Layout: node `J` has the sorted neighbour list `N_J` (nodes sharing a block or a coupling group
//! with it, itself included). Scalar column `3J + c` holds rows `3I + r` for `I ∈ N_J`, `r = 0..3`
//! in that order, so entry `(3I + r, 3J + c)` sits at `col_ptr[3J + c] + 3·rank_J(I) + r`. Both
//! triangles are stored: Cholesky reads the lower one, the matrix–vector product all of it.

use crate::Real;
use rayon::prelude::*;

/// Sparsity pattern of a symmetric matrix with 3×3 node blocks.
#[derive(Clone, Debug)]
pub struct AssemblyPattern {
    num_nodes: usize,
    neighbour_offsets: Vec<usize>,
    neighbours: Vec<u32>,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
}

impl AssemblyPattern {
    /// The pattern coupling every pair of nodes that appear together in one of `groups`.
    /// Node indices must be `< num_nodes` (checked; a violation is a backend bug, so it panics
    /// with the offending index).
    pub fn from_groups<'a>(num_nodes: usize, groups: impl Iterator<Item = &'a [u32]>) -> Self {
        let mut pairs: Vec<Vec<u32>> = vec![Vec::new(); num_nodes];
        for group in groups {
            for &j in group {
                assert!((j as usize) < num_nodes, "node {j} out of range 0..{num_nodes}");
                pairs[j as usize].extend_from_slice(group);
            }
        }
        pairs.par_iter_mut().enumerate().for_each(|(j, list)| {
            list.push(j as u32);
            list.sort_unstable();
            list.dedup();
        });
        Self::from_neighbour_lists(num_nodes, pairs.iter().map(Vec::as_slice))
    }

    /// This pattern with the couplings of `groups` added (pattern growth: only the nodes the
    /// groups name are sorted again, the rest is copied).
    pub fn with_groups<'a>(&self, groups: impl Iterator<Item = &'a [u32]>) -> Self {
        let num_nodes = self.num_nodes;
        let mut added: Vec<Vec<u32>> = vec![Vec::new(); num_nodes];
        for group in groups {
            for &j in group {
                assert!((j as usize) < num_nodes, "node {j} out of range 0..{num_nodes}");
                added[j as usize].extend_from_slice(group);
            }
        }
        added.par_iter_mut().enumerate().filter(|(_, list)| !list.is_empty()).for_each(|(j, list)| {
            list.extend_from_slice(self.neighbours(j as u32));
            list.sort_unstable();
            list.dedup();
        });
        let lists = (0..num_nodes).map(|j| match added[j].is_empty() {
            true => self.neighbours(j as u32),
            false => added[j].as_slice(),
        });
        Self::from_neighbour_lists(num_nodes, lists)
    }

    /// The pattern of sorted neighbour lists (each holding its own node), one per node.
    fn from_neighbour_lists<'a>(num_nodes: usize, lists: impl Iterator<Item = &'a [u32]>) -> Self {
        let mut neighbour_offsets = Vec::with_capacity(num_nodes + 1);
        neighbour_offsets.push(0);
        let mut neighbours = Vec::new();
        for list in lists {
            neighbours.extend_from_slice(list);
            neighbour_offsets.push(neighbours.len());
        }
        let nnz = 9 * neighbours.len();
        let mut col_ptr = Vec::with_capacity(3 * num_nodes + 1);
        let mut row_idx = Vec::with_capacity(nnz);
        col_ptr.push(0);
        for j in 0..num_nodes {
            let list = &neighbours[neighbour_offsets[j]..neighbour_offsets[j + 1]];
            for _c in 0..3 {
                for &i in list {
                    for r in 0..3 {
                        row_idx.push(3 * i as usize + r);
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        Self { num_nodes, neighbour_offsets, neighbours, col_ptr, row_idx }
    }

    /// A zeroed value array for this pattern whose memory is already resident (see
    /// [`resident_zeros`]), so the first assembly does not pay for the page faults.
    pub fn new_values(&self) -> Vec<Real> {
        resident_zeros(self.nnz())
    }

    /// Number of 3-vector nodes (the matrix is `3n × 3n`).
    pub fn num_nodes(&self) -> usize {
        self.num_nodes
    }

    /// Scalar dimension `3n`.
    pub fn dim(&self) -> usize {
        3 * self.num_nodes
    }

    /// Number of stored scalar entries (both triangles).
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// The nodes coupled to node `j` (sorted, `j` included): the node-level graph of the pattern.
    pub fn neighbours(&self, j: u32) -> &[u32] {
        &self.neighbours[self.neighbour_offsets[j as usize]..self.neighbour_offsets[j as usize + 1]]
    }

    /// CSC column pointers (length `3n + 1`).
    pub fn col_ptr(&self) -> &[usize] {
        &self.col_ptr
    }

    /// CSC row indices, sorted within each column.
    pub fn row_idx(&self) -> &[usize] {
        &self.row_idx
    }

    /// Rank of node `i` in the neighbour list of node `j`, if they are coupled.
    pub fn rank(&self, i: u32, j: u32) -> Option<u32> {
        let list = &self.neighbours[self.neighbour_offsets[j as usize]..self.neighbour_offsets[j as usize + 1]];
        list.binary_search(&i).ok().map(|r| r as u32)
    }

    /// Position of scalar entry `(3i + r, 3j + c)` given `rank = rank(i, j)`.
    #[inline]
    pub fn position(&self, rank: u32, j: u32, r: usize, c: usize) -> usize {
        self.col_ptr[3 * j as usize + c] + 3 * rank as usize + r
    }

    /// `out = A x` for the symmetric matrix with these `values`, stored in full: each output
    /// entry gathers its column (`(A x)_j = Σ_i A_ji x_i`), so outputs are independent and run in
    /// parallel.
    pub fn mul_vec(&self, values: &[Real], x: &[Real], out: &mut [Real]) {
        let (col_ptr, row_idx) = (&self.col_ptr, &self.row_idx);
        out.par_iter_mut().enumerate().for_each(|(j, o)| {
            let mut sum = 0.0;
            for p in col_ptr[j]..col_ptr[j + 1] {
                sum += values[p] * x[row_idx[p]];
            }
            *o = sum;
        });
    }

    /// Value at scalar `(row, col)`, zero outside the pattern (a binary search: for tests).
    pub fn get(&self, values: &[Real], row: usize, col: usize) -> Real {
        let range = self.col_ptr[col]..self.col_ptr[col + 1];
        match self.row_idx[range.clone()].binary_search(&row) {
            Ok(k) => values[range.start + k],
            Err(_) => 0.0,
        }
    }

    /// Calls `fill(nodes, slice, base)` for the column nodes between consecutive `bounds`
    /// (increasing), in parallel: `slice` holds the values of those nodes' columns, whose first
    /// entry is the pattern's entry `base`. Columns are contiguous in the storage, so each task
    /// owns its slice and no two write one entry (no atomics); the ranges are split at the middle
    /// bound with `rayon::join`, with no allocation.
    pub fn for_column_ranges<F>(&self, bounds: &[u32], values: &mut [Real], fill: &F)
    where
        F: Fn(std::ops::Range<u32>, &mut [Real], usize) + Sync,
    {
        let (Some(&first), Some(_)) = (bounds.first(), bounds.last()) else { return };
        let base = self.col_ptr[3 * first as usize];
        self.column_ranges(bounds, &mut values[base..], base, fill);
    }

    fn column_ranges<F>(&self, bounds: &[u32], values: &mut [Real], base: usize, fill: &F)
    where
        F: Fn(std::ops::Range<u32>, &mut [Real], usize) + Sync,
    {
        if bounds.len() > 2 {
            let mid = bounds.len() / 2;
            let split = self.col_ptr[3 * bounds[mid] as usize] - base;
            let (low, high) = values.split_at_mut(split);
            rayon::join(
                || self.column_ranges(&bounds[..=mid], low, base, fill),
                || self.column_ranges(&bounds[mid..], high, base + split, fill),
            );
        } else if let [start, end] = *bounds {
            let len = self.col_ptr[3 * end as usize] - base;
            fill(start..end, &mut values[..len], base);
        }
    }

    /// Adds the 3×3 block `m` (row-major `m[r][c]`) times `scale` at node pair `(i, j)` whose rank
    /// is known.
    #[inline]
    pub fn add_block(&self, values: &mut [Real], rank: u32, j: u32, m: &nalgebra::Matrix3<Real>, scale: Real) {
        for c in 0..3 {
            let base = self.col_ptr[3 * j as usize + c] + 3 * rank as usize;
            for r in 0..3 {
                values[base + r] += scale * m[(r, c)];
            }
        }
    }
}

/// `len` zeros written one by one into fresh memory. `vec![0.0; len]` gets zeroed pages from the
/// allocator lazily, so the first pass that writes them (the first assembly or factorization of
/// an epoch, often the only one of a static solve) would take the page faults: hundreds of
/// megabytes for a quadratic DG factor. Built once per epoch, it keeps that cost in the set-up.
pub fn resident_zeros(len: usize) -> Vec<Real> {
    let mut values = Vec::with_capacity(len);
    values.resize(len, 0.0);
    values
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pattern_couples_exactly_the_grouped_nodes() {
        // chain 0-1-2 and an isolated node 3
        let groups: Vec<Vec<u32>> = vec![vec![0, 1], vec![1, 2]];
        let p = AssemblyPattern::from_groups(4, groups.iter().map(|g| g.as_slice()));
        assert_eq!(p.nnz(), 9 * (2 + 3 + 2 + 1));
        assert_eq!(p.rank(2, 0), None);
        assert_eq!(p.rank(2, 1), Some(2));
        // the position formula lands on the right row
        let pos = p.position(p.rank(2, 1).unwrap(), 1, 1, 2);
        assert_eq!(p.row_idx()[pos], 3 * 2 + 1);
        assert!(pos >= p.col_ptr()[3 + 2] && pos < p.col_ptr()[3 + 3]);
    }

    #[test]
    fn a_grown_pattern_equals_the_pattern_built_with_all_groups() {
        let first: Vec<Vec<u32>> = vec![vec![0, 1], vec![1, 2], vec![4, 5, 6]];
        let later: Vec<Vec<u32>> = vec![vec![2, 5], vec![0, 6, 3], vec![1, 2]];
        let grown = AssemblyPattern::from_groups(8, first.iter().map(Vec::as_slice))
            .with_groups(later.iter().map(Vec::as_slice));
        let whole = AssemblyPattern::from_groups(8, first.iter().chain(&later).map(Vec::as_slice));
        assert_eq!(grown.col_ptr(), whole.col_ptr());
        assert_eq!(grown.row_idx(), whole.row_idx());
        assert_eq!(grown.rank(5, 2), Some(2));
        assert_eq!(grown.rank(7, 7), Some(0));
        assert_eq!(grown.rank(3, 1), None);
    }
}
