//! The stiffness as a list of warped blocks over a library of rest matrices, and the shared
//! kernels on it (derivation: `docs/math/corotated-integrator.md`):
//!
//! - internal force   `f_b = −R K (Rᵀ x_b − X_b)`
//! - elastic energy   `E_b = ½ (Rᵀ x_b − X_b)ᵀ K (Rᵀ x_b − X_b)`
//! - stiffness action `y_b = s · R K Rᵀ dx_b`
//! - assembly         `A += s · Σ_b R K Rᵀ`
//!
//! `R` is block-diagonal with the block's frame rotation on every node (identity for blocks
//! without a frame, such as DG penalty terms).
//!
//! An *anchored* block couples an element's strain to a world-anchored quantity (DG's weak
//! Dirichlet faces, `docs/math/dg.md` §6). It stores the non-symmetric `H` with `K = H + Hᵀ`;
//! `H`'s column argument is the corotated displacement `b = Rᵀx − X`, its row argument the world
//! displacement rotated into the frame, `a = Rᵀ(x − X)`:
//!
//! - internal force   `f_b = −R (H b + Hᵀ a)`
//! - elastic energy   `E_b = aᵀ H b`
//!
//! with the same stiffness `R K Rᵀ`. With `R = I` both forms agree; unlike the plain form, the
//! anchored one is unchanged when `x` and `X` are translated together, because `H` annihilates
//! constant fields in its column (strain) argument.

use crate::assembly::AssemblyPattern;
use crate::scatter::ScatterPlan;
use crate::{Matrix3, Real};
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Largest number of nodes one block may couple (a DG face block of two quadratic elements has
/// 20; a mean value element a blade has cut many times, 40 and more: wicke2007 reports 27 on its
/// cut sequence); bounds the stack scratch of the kernels.
pub const MAX_BLOCK_NODES: usize = 64;

/// Blocks of up to this many nodes (cubes, tetrahedra, DG faces, most mean value cells) take
/// their kernels' scratch from an array of this size, so they do not pay for zeroing the
/// largest block's.
const SMALL_BLOCK_NODES: usize = 32;

/// Runs `f` on `n` zeroed reals of stack scratch (`n ≤ 3 · MAX_BLOCK_NODES`).
#[inline(always)]
fn with_scratch<R>(n: usize, f: impl FnOnce(&mut [Real]) -> R) -> R {
    if n <= 3 * SMALL_BLOCK_NODES {
        let mut scratch = [0.0; 3 * SMALL_BLOCK_NODES];
        f(&mut scratch[..n])
    } else {
        let mut scratch = [0.0; 3 * MAX_BLOCK_NODES];
        f(&mut scratch[..n])
    }
}

const NO_FRAME: u32 = u32::MAX;
const NO_ANCHOR: u32 = u32::MAX;

/// A malformed block (a backend bug, reported rather than panicking inside a kernel).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BlockSetError {
    /// Rest matrix of the wrong shape or not symmetric.
    #[error(
        "rest matrix {index} is {rows}x{cols}, must be square, a multiple of 3, at most 3 × MAX_BLOCK_NODES (192) and symmetric"
    )]
    BadRestMatrix {
        /// index it would get
        index: usize,
        /// its rows
        rows: usize,
        /// its columns
        cols: usize,
    },
    /// Block whose node count does not match its rest matrix, or too many nodes.
    #[error("block {block} has {nodes} nodes but rest matrix {rest} is for {expected}")]
    NodeCount {
        /// block index
        block: usize,
        /// nodes given
        nodes: usize,
        /// rest matrix id
        rest: u32,
        /// nodes the rest matrix expects
        expected: usize,
    },
    /// Node index out of range.
    #[error("block {block} names node {node}, but there are only {num_nodes}")]
    NodeOutOfRange {
        /// block index
        block: usize,
        /// the node
        node: u32,
        /// node count
        num_nodes: usize,
    },
}

/// One block as seen by a kernel.
#[derive(Clone, Copy, Debug)]
pub struct BlockRef<'a> {
    /// Global node indices, in the rest matrix's order.
    pub nodes: &'a [u32],
    /// The rest stiffness (`3·nodes × 3·nodes`).
    pub rest: &'a DMatrix<Real>,
    /// Index of the rotation frame warping this block, if any.
    pub frame: Option<u32>,
    /// For an anchored block, `H` with `rest = H + Hᵀ` (module docs).
    pub anchor: Option<&'a DMatrix<Real>>,
}

/// A per-block list of indices, stored as `first + stride · b` when it is one: a voxel mesh's
/// blocks all have rest matrix 0, frame b, no anchor and offset 8b, and the four lists would
/// take 16 B a cube (16 MB at a million voxels, docs/results/voxel-bench.md).
#[derive(Clone, Debug)]
enum PerBlock {
    Affine { first: u32, stride: u32 },
    Each(Vec<u32>),
}

impl PerBlock {
    fn new(mut list: Vec<u32>) -> Self {
        let first = list.first().copied().unwrap_or(0);
        let stride = list.get(1).map_or(0, |&second| second.wrapping_sub(first));
        let affine = list.iter().enumerate().all(|(b, &v)| v == first.wrapping_add(stride.wrapping_mul(b as u32)));
        if affine {
            Self::Affine { first, stride }
        } else {
            list.shrink_to_fit();
            Self::Each(list)
        }
    }

    #[inline]
    fn get(&self, b: usize) -> u32 {
        match self {
            Self::Affine { first, stride } => first.wrapping_add(stride.wrapping_mul(b as u32)),
            Self::Each(list) => list[b],
        }
    }
}

/// Blocks `{nodes, rest matrix id, frame}` over a library of rest matrices.
#[derive(Clone, Debug)]
pub struct BlockSet {
    num_nodes: usize,
    num_blocks: usize,
    rest_matrices: Vec<DMatrix<Real>>,
    offsets: PerBlock,
    nodes: Vec<u32>,
    rest_ids: PerBlock,
    frames: PerBlock,
    /// Per block, the index into `anchors` or `NO_ANCHOR`.
    anchor_ids: PerBlock,
    anchors: Vec<DMatrix<Real>>,
    translation_invariant: bool,
    plan: ScatterPlan,
}

/// Builder for a [`BlockSet`]; `finish` checks everything once.
#[derive(Debug, Default)]
pub struct BlockSetBuilder {
    rest_matrices: Vec<DMatrix<Real>>,
    offsets: Vec<u32>,
    nodes: Vec<u32>,
    rest_ids: Vec<u32>,
    frames: Vec<u32>,
    anchor_ids: Vec<u32>,
    anchors: Vec<DMatrix<Real>>,
    translation_invariant: bool,
}

impl BlockSetBuilder {
    /// An empty builder.
    pub fn new() -> Self {
        Self { offsets: vec![0], ..Default::default() }
    }

    /// Adds a rest matrix to the library and returns its id.
    pub fn add_rest_matrix(&mut self, k: DMatrix<Real>) -> Result<u32, BlockSetError> {
        let index = self.rest_matrices.len();
        let bad = k.nrows() != k.ncols()
            || !k.nrows().is_multiple_of(3)
            || k.nrows() / 3 > MAX_BLOCK_NODES
            || (&k - k.transpose()).amax() > 1e-12 * k.amax().max(Real::MIN_POSITIVE);
        if bad {
            return Err(BlockSetError::BadRestMatrix { index, rows: k.nrows(), cols: k.ncols() });
        }
        self.rest_matrices.push(k);
        Ok(index as u32)
    }

    /// Declares that every block annihilates a common translation of its nodes (true of the
    /// elastic blocks of nodal bases: cubes, tetrahedra). The force and energy kernels then take
    /// positions relative to each block's first node, which gives the same value without
    /// rounding that grows with the distance to the world origin. Not for DG, whose translation
    /// lives on the constant basis function only.
    pub fn translation_invariant(mut self) -> Self {
        self.translation_invariant = true;
        self
    }

    /// Appends a block.
    pub fn push(&mut self, nodes: &[u32], rest: u32, frame: Option<u32>) {
        self.nodes.extend_from_slice(nodes);
        self.offsets.push(self.nodes.len() as u32);
        self.rest_ids.push(rest);
        self.frames.push(frame.unwrap_or(NO_FRAME));
        self.anchor_ids.push(NO_ANCHOR);
    }

    /// Appends an anchored block with the non-symmetric `h` (module docs): its rest matrix is
    /// `h + hᵀ`, added to the library here.
    pub fn push_anchored(&mut self, nodes: &[u32], h: DMatrix<Real>, frame: u32) -> Result<(), BlockSetError> {
        if h.nrows() != h.ncols() {
            let index = self.rest_matrices.len();
            return Err(BlockSetError::BadRestMatrix { index, rows: h.nrows(), cols: h.ncols() });
        }
        let rest = self.add_rest_matrix(&h + h.transpose())?;
        self.push(nodes, rest, Some(frame));
        if let Some(last) = self.anchor_ids.last_mut() {
            *last = self.anchors.len() as u32;
        }
        self.anchors.push(h);
        Ok(())
    }

    /// Validates and plans the parallel scatter for a mesh of `num_nodes` nodes.
    pub fn finish(mut self, num_nodes: usize) -> Result<BlockSet, BlockSetError> {
        // The node list grew by doubling; a million cubes would keep up to twice its size.
        self.nodes.shrink_to_fit();
        let num_blocks = self.rest_ids.len();
        for b in 0..num_blocks {
            let nodes = &self.nodes[self.offsets[b] as usize..self.offsets[b + 1] as usize];
            let rest = self.rest_ids[b];
            let expected = self.rest_matrices.get(rest as usize).map_or(0, |k| k.nrows() / 3);
            if nodes.len() != expected {
                return Err(BlockSetError::NodeCount { block: b, nodes: nodes.len(), rest, expected });
            }
            if let Some(&node) = nodes.iter().find(|&&n| n as usize >= num_nodes) {
                return Err(BlockSetError::NodeOutOfRange { block: b, node, num_nodes });
            }
        }
        let offsets = &self.offsets;
        let all_nodes = &self.nodes;
        let plan = ScatterPlan::new(num_blocks, 3 * num_nodes, |b| {
            let nodes = &all_nodes[offsets[b] as usize..offsets[b + 1] as usize];
            let lo = nodes.iter().min().map_or(0, |&n| 3 * n as usize);
            let hi = nodes.iter().max().map_or(0, |&n| 3 * n as usize + 3);
            lo..hi
        });
        Ok(BlockSet {
            num_nodes,
            num_blocks,
            rest_matrices: self.rest_matrices,
            offsets: PerBlock::new(self.offsets),
            nodes: self.nodes,
            rest_ids: PerBlock::new(self.rest_ids),
            frames: PerBlock::new(self.frames),
            anchor_ids: PerBlock::new(self.anchor_ids),
            anchors: self.anchors,
            translation_invariant: self.translation_invariant,
            plan,
        })
    }
}

impl BlockSet {
    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.num_blocks
    }

    /// True when there are no blocks.
    pub fn is_empty(&self) -> bool {
        self.num_blocks == 0
    }

    /// Number of nodes of the mesh the blocks live on.
    pub fn num_nodes(&self) -> usize {
        self.num_nodes
    }

    /// The rest-matrix library.
    pub fn rest_matrices(&self) -> &[DMatrix<Real>] {
        &self.rest_matrices
    }

    /// Block `b`.
    #[inline]
    pub fn block(&self, b: usize) -> BlockRef<'_> {
        let frame = self.frames.get(b);
        let anchor = self.anchor_ids.get(b);
        BlockRef {
            nodes: &self.nodes[self.offsets.get(b) as usize..self.offsets.get(b + 1) as usize],
            rest: &self.rest_matrices[self.rest_ids.get(b) as usize],
            frame: (frame != NO_FRAME).then_some(frame),
            anchor: (anchor != NO_ANCHOR).then(|| &self.anchors[anchor as usize]),
        }
    }

    /// Every block's nodes, one list after the other in block order.
    pub fn all_nodes(&self) -> &[u32] {
        &self.nodes
    }

    /// Node lists of all blocks (for building an [`AssemblyPattern`]).
    pub fn node_groups(&self) -> impl Iterator<Item = &[u32]> {
        (0..self.len()).map(|b| &self.nodes[self.offsets.get(b) as usize..self.offsets.get(b + 1) as usize])
    }

    /// The plan the parallel kernels scatter with.
    pub fn scatter_plan(&self) -> &ScatterPlan {
        &self.plan
    }

    fn rotation(rotations: &[Matrix3<Real>], frame: Option<u32>) -> Matrix3<Real> {
        frame.map_or_else(Matrix3::identity, |f| rotations[f as usize])
    }

    /// `out += −Σ_b R K (Rᵀ x_b − X_b)`: the internal elastic force at positions `x` (anchored
    /// blocks: `−R (H b + Hᵀ a)`, module docs).
    pub fn add_internal_force(&self, rotations: &[Matrix3<Real>], x: &[Real], rest: &[Real], out: &mut [Real]) {
        self.plan.scatter_add(out, |b, buf, base| {
            let block = self.block(b);
            let r = Self::rotation(rotations, block.frame);
            let n = 3 * block.nodes.len();
            with_scratch(n, |local| {
                corotated_displacement(&r, block.nodes, x, rest, self.translation_invariant, local);
                match block.anchor {
                    None => apply_warped(block.rest, &r, local, block.nodes, -1.0, buf, base),
                    Some(h) => {
                        let mut anchored = [0.0; 3 * MAX_BLOCK_NODES];
                        rotated_displacement(&r, block.nodes, x, rest, &mut anchored[..n]);
                        let mut y = [0.0; 3 * MAX_BLOCK_NODES];
                        for row in 0..n {
                            let mut sum = 0.0;
                            for col in 0..n {
                                sum += h[(row, col)] * local[col] + h[(col, row)] * anchored[col];
                            }
                            y[row] = sum;
                        }
                        scatter_rotated(&r, &y[..n], block.nodes, -1.0, buf, base);
                    }
                }
            });
        });
    }

    /// `out += s · Σ_b R K Rᵀ dx_b`.
    pub fn add_stiffness_action(&self, rotations: &[Matrix3<Real>], dx: &[Real], scale: Real, out: &mut [Real]) {
        self.plan.scatter_add(out, |b, buf, base| {
            let block = self.block(b);
            let r = Self::rotation(rotations, block.frame);
            with_scratch(3 * block.nodes.len(), |local| {
                for (a, &node) in block.nodes.iter().enumerate() {
                    let i = 3 * node as usize;
                    let p = r.tr_mul(&nalgebra::Vector3::new(dx[i], dx[i + 1], dx[i + 2]));
                    local[3 * a..3 * a + 3].copy_from_slice(p.as_slice());
                }
                apply_warped(block.rest, &r, local, block.nodes, scale, buf, base);
            });
        });
    }

    /// `½ Σ_b (Rᵀ x_b − X_b)ᵀ K (Rᵀ x_b − X_b)` (anchored blocks: `aᵀ H b`, module docs).
    /// Summed with the same bits on any thread count ([`crate::reduce::deterministic_sum`]).
    pub fn elastic_energy(&self, rotations: &[Matrix3<Real>], x: &[Real], rest: &[Real]) -> Real {
        crate::reduce::deterministic_sum(self.len(), |b| {
            let block = self.block(b);
            let r = Self::rotation(rotations, block.frame);
            let n = 3 * block.nodes.len();
            let mut local = [0.0; 3 * MAX_BLOCK_NODES];
            corotated_displacement(&r, block.nodes, x, rest, self.translation_invariant, &mut local[..n]);
            let (k, left, scale) = match block.anchor {
                None => (block.rest, local, 0.5),
                Some(h) => {
                    let mut anchored = [0.0; 3 * MAX_BLOCK_NODES];
                    rotated_displacement(&r, block.nodes, x, rest, &mut anchored[..n]);
                    (h, anchored, 1.0)
                }
            };
            let mut e = 0.0;
            for col in 0..n {
                let mut kv = 0.0;
                for row in 0..n {
                    kv += left[row] * k[(row, col)];
                }
                e += kv * local[col];
            }
            scale * e
        })
    }

    /// `diag[node] += s · Σ_b (R K Rᵀ)_{node,node}`: the 3×3 diagonal blocks (block Jacobi).
    pub fn add_diagonal_blocks(&self, rotations: &[Matrix3<Real>], scale: Real, diag: &mut [Matrix3<Real>]) {
        for b in 0..self.len() {
            let block = self.block(b);
            let r = Self::rotation(rotations, block.frame);
            for (a, &node) in block.nodes.iter().enumerate() {
                let kaa: Matrix3<Real> = block.rest.fixed_view::<3, 3>(3 * a, 3 * a).into_owned();
                diag[node as usize] += (r * kaa * r.transpose()) * scale;
            }
        }
    }

    /// `values += scale · Σ_b R K Rᵀ` on the pattern, in parallel over column nodes: each task
    /// owns a contiguous range of columns of `values` (`ranks` lists which blocks touch each
    /// column node and cuts the nodes into ranges of similar work), so no two tasks write the
    /// same entry and no atomics are needed. Blocks without a frame skip the warp.
    pub fn add_to_matrix(
        &self,
        rotations: &[Matrix3<Real>],
        scale: Real,
        pattern: &AssemblyPattern,
        ranks: &BlockRanks,
        values: &mut [Real],
    ) {
        let col_ptr = pattern.col_ptr();
        pattern.for_column_ranges(&ranks.chunk_bounds, values, &|nodes, values, base| {
            for j in nodes {
                let columns = [0, 1, 2].map(|c| col_ptr[3 * j as usize + c] - base);
                for &(b, bj) in ranks.column(j) {
                    let block = self.block(b as usize);
                    let n = block.nodes.len();
                    let bj = bj as usize;
                    let block_ranks = &ranks.block(b as usize)[bj * n..(bj + 1) * n];
                    let r = block.frame.map(|f| rotations[f as usize]);
                    for (bi, &rank) in block_ranks.iter().enumerate() {
                        let kij: Matrix3<Real> = block.rest.fixed_view::<3, 3>(3 * bi, 3 * bj).into_owned();
                        let m = match r {
                            Some(r) => r * kij * r.transpose(),
                            None => kij,
                        };
                        for (c, &column) in columns.iter().enumerate() {
                            let at = column + 3 * rank as usize;
                            for row in 0..3 {
                                values[at + row] += scale * m[(row, c)];
                            }
                        }
                    }
                }
            }
        });
    }
}

/// Per block, the rank of every (row node, column node) pair in the pattern: computed once per
/// epoch so assembly never searches.
#[derive(Clone, Debug)]
pub struct BlockRanks {
    offsets: Vec<usize>,
    ranks: Vec<u32>,
    /// For each column node, the (block, local index) pairs of the blocks that hold it.
    column_offsets: Vec<usize>,
    column_entries: Vec<(u32, u32)>,
    /// Node ranges of similar assembly work, the parallel tasks of `add_to_matrix`.
    chunk_bounds: Vec<u32>,
}

impl BlockRanks {
    /// Looks up every block's node pairs in `pattern`.
    pub fn new(blocks: &BlockSet, pattern: &AssemblyPattern) -> Self {
        let mut offsets = Vec::with_capacity(blocks.len() + 1);
        offsets.push(0);
        for b in 0..blocks.len() {
            offsets.push(offsets[b] + blocks.block(b).nodes.len().pow(2));
        }
        // The lookups in parallel (once per pattern, but a contact pattern growth waits for
        // them: 0.4–0.8 ms on one thread on bunny_slice.ron).
        let ranks: Vec<u32> = (0..blocks.len())
            .into_par_iter()
            .flat_map_iter(|b| {
                let nodes = blocks.block(b).nodes;
                nodes.iter().flat_map(move |&j| {
                    nodes.iter().map(move |&i| {
                        pattern.rank(i, j).expect("assembly pattern must contain every block's node pairs")
                    })
                })
            })
            .collect();
        // Column lists by a counting sort over the blocks' nodes.
        let num_nodes = pattern.num_nodes();
        let mut column_offsets = vec![0usize; num_nodes + 1];
        for b in 0..blocks.len() {
            for &j in blocks.block(b).nodes {
                column_offsets[j as usize + 1] += 1;
            }
        }
        for j in 0..num_nodes {
            column_offsets[j + 1] += column_offsets[j];
        }
        let mut next = column_offsets.clone();
        let mut column_entries = vec![(0u32, 0u32); column_offsets[num_nodes]];
        for b in 0..blocks.len() {
            for (bj, &j) in blocks.block(b).nodes.iter().enumerate() {
                column_entries[next[j as usize]] = (b as u32, bj as u32);
                next[j as usize] += 1;
            }
        }
        // Ranges of about equal work (3×3 blocks written), several per thread for balance.
        let work = |j: usize| -> usize {
            column_entries[column_offsets[j]..column_offsets[j + 1]]
                .iter()
                .map(|&(b, _)| blocks.block(b as usize).nodes.len())
                .sum()
        };
        let total: usize = (0..num_nodes).map(work).sum();
        let chunks = (8 * rayon::current_num_threads()).max(1);
        let target = total.div_ceil(chunks).max(1);
        let mut chunk_bounds = vec![0u32];
        let mut acc = 0;
        for j in 0..num_nodes {
            acc += work(j);
            if acc >= target && j + 1 < num_nodes {
                chunk_bounds.push(j as u32 + 1);
                acc = 0;
            }
        }
        chunk_bounds.push(num_nodes as u32);
        Self { offsets, ranks, column_offsets, column_entries, chunk_bounds }
    }

    /// The (block, local index) pairs of the blocks holding column node `j`.
    #[inline]
    fn column(&self, j: u32) -> &[(u32, u32)] {
        &self.column_entries[self.column_offsets[j as usize]..self.column_offsets[j as usize + 1]]
    }

    /// Ranks of block `b`, column-node-major: `[j * n + i]`.
    #[inline]
    pub fn block(&self, b: usize) -> &[u32] {
        &self.ranks[self.offsets[b]..self.offsets[b + 1]]
    }
}

/// `local = Rᵀ x_b − X_b`, the corotated displacement of the block's nodes; with `relative`
/// (a translation-invariant block) `Rᵀ (x_b − x_0) − (X_b − X_0)` relative to its first node.
#[inline]
fn corotated_displacement(
    r: &Matrix3<Real>,
    nodes: &[u32],
    x: &[Real],
    rest: &[Real],
    relative: bool,
    local: &mut [Real],
) {
    let (o, o_rest) = match (relative, nodes.first()) {
        (true, Some(&first)) => {
            let f = 3 * first as usize;
            ([x[f], x[f + 1], x[f + 2]], [rest[f], rest[f + 1], rest[f + 2]])
        }
        _ => ([0.0; 3], [0.0; 3]),
    };
    for (a, &node) in nodes.iter().enumerate() {
        let i = 3 * node as usize;
        let p = r.tr_mul(&nalgebra::Vector3::new(x[i] - o[0], x[i + 1] - o[1], x[i + 2] - o[2]));
        for c in 0..3 {
            local[3 * a + c] = p[c] - (rest[i + c] - o_rest[c]);
        }
    }
}

/// `local = Rᵀ (x_b − X_b)`, the world displacement rotated into the block's frame.
#[inline]
fn rotated_displacement(r: &Matrix3<Real>, nodes: &[u32], x: &[Real], rest: &[Real], local: &mut [Real]) {
    for (a, &node) in nodes.iter().enumerate() {
        let i = 3 * node as usize;
        let u = nalgebra::Vector3::new(x[i] - rest[i], x[i + 1] - rest[i + 1], x[i + 2] - rest[i + 2]);
        local[3 * a..3 * a + 3].copy_from_slice(r.tr_mul(&u).as_slice());
    }
}

/// `buf[node] += s · R (K local)` for every node of the block.
#[inline]
fn apply_warped(
    k: &DMatrix<Real>,
    r: &Matrix3<Real>,
    local: &[Real],
    nodes: &[u32],
    scale: Real,
    buf: &mut [Real],
    base: usize,
) {
    let n = local.len();
    let mut y = [0.0; 3 * MAX_BLOCK_NODES];
    // K is symmetric and stored column-major: (K v)_row = Σ_col K[col, row] v_col reads columns
    // contiguously.
    for (row, y_row) in y[..n].iter_mut().enumerate() {
        let column = k.column(row);
        let mut sum = 0.0;
        for (kc, v) in column.iter().zip(local) {
            sum += kc * v;
        }
        *y_row = sum;
    }
    scatter_rotated(r, &y[..n], nodes, scale, buf, base);
}

/// `buf[node] += s · R y_node` for every node of the block.
#[inline]
fn scatter_rotated(r: &Matrix3<Real>, y: &[Real], nodes: &[u32], scale: Real, buf: &mut [Real], base: usize) {
    for (a, &node) in nodes.iter().enumerate() {
        let v = r * nalgebra::Vector3::new(y[3 * a], y[3 * a + 1], y[3 * a + 2]);
        let i = 3 * node as usize - base;
        buf[i] += scale * v[0];
        buf[i + 1] += scale * v[1];
        buf[i + 2] += scale * v[2];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_block_lists_are_compact_only_when_affine_and_read_back_the_same() {
        let cases: [(Vec<u32>, bool); 6] = [
            ((0..1000).map(|b| 8 * b).collect(), true),
            (vec![0; 1000], true),
            (vec![NO_ANCHOR; 7], true),
            (vec![5], true),
            (vec![0, 1, 3, 4], false),
            ((0..1000).map(|b| if b == 999 { 0 } else { b }).collect(), false),
        ];
        for (list, affine) in cases {
            let compact = PerBlock::new(list.clone());
            assert_eq!(matches!(compact, PerBlock::Affine { .. }), affine, "{:?}", &list[..list.len().min(5)]);
            for (b, &v) in list.iter().enumerate() {
                assert_eq!(compact.get(b), v, "entry {b}");
            }
        }
    }

    /// A symmetric `3n × 3n` rest matrix with entries from a fixed pseudo-random sequence.
    fn rest_matrix(n: usize, seed: u64) -> DMatrix<Real> {
        let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as Real / (1u64 << 53) as Real - 0.5
        };
        let a = DMatrix::from_fn(3 * n, 3 * n, |_, _| next());
        &a + a.transpose()
    }

    #[test]
    fn parallel_assembly_matches_a_dense_sum_of_warped_blocks() {
        // 400 nodes in overlapping 4-node blocks, every other block with a frame: enough column
        // ranges that the recursive split runs several levels deep.
        let num_nodes = 400u32;
        let mut builder = BlockSetBuilder::new();
        let mut blocks_nodes = Vec::new();
        for b in 0..num_nodes - 3 {
            let nodes = [b, b + 1, b + 3, (b * 7) % num_nodes];
            let mut unique = nodes.to_vec();
            unique.sort_unstable();
            unique.dedup();
            let id = builder.add_rest_matrix(rest_matrix(unique.len(), b as u64)).unwrap();
            let frame = (b % 2 == 0).then_some(b / 2);
            builder.push(&unique, id, frame);
            blocks_nodes.push((unique, id, frame));
        }
        let blocks = builder.finish(num_nodes as usize).unwrap();
        let rotations: Vec<Matrix3<Real>> = (0..num_nodes)
            .map(|f| {
                let t = f as Real * 0.37;
                nalgebra::Rotation3::from_euler_angles(t, 0.5 * t, -t).into_inner()
            })
            .collect();
        let pattern = AssemblyPattern::from_groups(num_nodes as usize, blocks.node_groups());
        let ranks = BlockRanks::new(&blocks, &pattern);
        assert!(ranks.chunk_bounds.len() > 3, "the test must exercise the split: {:?}", ranks.chunk_bounds.len());
        let mut values = vec![0.0; pattern.nnz()];
        blocks.add_to_matrix(&rotations, 0.5, &pattern, &ranks, &mut values);

        let dim = 3 * num_nodes as usize;
        let mut dense = DMatrix::<Real>::zeros(dim, dim);
        for (nodes, id, frame) in &blocks_nodes {
            let k = &blocks.rest_matrices()[*id as usize];
            let r = frame.map_or_else(Matrix3::identity, |f| rotations[f as usize]);
            for (bi, &i) in nodes.iter().enumerate() {
                for (bj, &j) in nodes.iter().enumerate() {
                    let m = r * k.fixed_view::<3, 3>(3 * bi, 3 * bj) * r.transpose();
                    for a in 0..3 {
                        for c in 0..3 {
                            dense[(3 * i as usize + a, 3 * j as usize + c)] += 0.5 * m[(a, c)];
                        }
                    }
                }
            }
        }
        let mut largest: Real = 0.0;
        for col in 0..dim {
            for row in 0..dim {
                largest = largest.max((pattern.get(&values, row, col) - dense[(row, col)]).abs());
            }
        }
        assert!(largest < 1e-13, "largest difference {largest}");
    }
}
