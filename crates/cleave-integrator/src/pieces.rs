//! The piecewise CG preconditioner for bodies cut into many pieces: the Cholesky factor of the
//! step matrix without the couplings that contacts make between nodes, plus a coarse space of
//! the pieces' affine motions that carries the contacts between pieces,
//!
//! ```text
//! z = L⁻ᵀ L⁻¹ r + Φ A_c⁻¹ Φᵀ r,      L Lᵀ = A_elastic + Σ_contacts Σ_points s² (e eᵀ ⊗ P),
//!                                   A_c = Φᵀ A Φ   (Galerkin, contacts included)
//! ```
//!
//! (docs/math/corotated-integrator.md, "Piecewise preconditioner"). `A_elastic` is the step
//! matrix of the elements, masses and pins: its pattern couples no two pieces, so the ordering
//! keeps them apart and the factor is block diagonal by piece, as cheap as the pieces are small,
//! however many there are. A contact row `Σ_k s_k e_k` (surface points `k` with weights `s_k`,
//! each embedded by the row `e_k` of one element's nodes) enters `L` lumped by surface point,
//! `Σ_k s_k² e_k e_kᵀ`: positive semidefinite and within one element, so no fill. The couplings
//! it leaves out (a point pressed against another piece's triangle) are what moves pieces
//! against each other, and `Φ` (twelve columns per piece: a translation and a linear map about
//! its centroid, so rigid motions and uniform strains) holds those motions, with the contacts'
//! terms assembled exactly into the small sparse `A_c`. Pieces with a hard-pinned DOF take no coarse columns (their
//! pins hold them in `L`). Both terms are symmetric positive (semi)definite and their sum is
//! positive definite, so CG stays valid for any contacts; inexactness costs iterations only.

use crate::constraints::Constraints;
use crate::error::StepErrorKind;
use crate::system::AssembledSystem;
use cleave_contact::{Contact, for_each_entry};
use cleave_core::{AssemblyPattern, Discretization, Embedding, Matrix3, Real, SparseCholesky, Vector3};
use rayon::prelude::*;

/// No coarse columns (a piece with a hard pin, or one too small to turn).
const NO_MODES: u32 = u32::MAX;

/// Coarse 3-DOF nodes per piece: the translation and the three columns of the affine map.
const MODE_NODES: usize = 4;
/// Coarse columns per piece.
const MODES: usize = 3 * MODE_NODES;

type Phi = nalgebra::SMatrix<Real, 3, MODES>;
type CoarseBlock = nalgebra::SMatrix<Real, MODES, MODES>;
type CoarseVector = nalgebra::SVector<Real, MODES>;

/// The piecewise preconditioner of one epoch.
pub(crate) struct PiecePreconditioner {
    /// Elements, masses and pins on the pattern of the blocks (no contact couplings); its
    /// values are gathered into the pieces' own factorizations.
    system: AssembledSystem,
    /// One factorization per piece (every piece, held or not), factorized and solved side by
    /// side.
    factors: Vec<PieceFactor>,
    /// The system's values without the lumped contacts, pins applied: with the contacts'
    /// action, the step matrix CG multiplies with ([`multiply`](Self::multiply)).
    operator_values: Vec<Real>,
    /// Coarse index of each node's piece, or [`NO_MODES`].
    coarse_of_node: Vec<u32>,
    /// Nodes of each coarse piece.
    piece_offsets: Vec<usize>,
    piece_nodes: Vec<u32>,
    /// Centroid of each coarse piece at the prepared state.
    centroids: Vec<Vector3<Real>>,
    /// Coarse pattern (two 3-DOF nodes per piece: translation `2p`, rotation `2p + 1`), the
    /// piece pairs it couples (sorted), its values and factorization.
    coarse_pattern: AssemblyPattern,
    coupled_pairs: Vec<(u32, u32)>,
    coarse_values: Vec<Real>,
    coarse_cholesky: Option<SparseCholesky>,
    /// Whether the last coarse factorization succeeded (else the correction is skipped).
    coarse_ready: bool,
    /// Scratch, kept across steps: the step's pairs, one contact's pieces and sides, the
    /// restricted vector, per-piece coarse blocks.
    pairs: Vec<(u32, u32)>,
    contact_pieces: Vec<u32>,
    sides: Vec<(u32, Phi)>,
    restricted: Vec<Real>,
    diagonal: Vec<CoarseBlock>,
    /// Times the coarse pattern grew for new piece pairs in contact.
    pub growths: usize,
}

/// `Φ_n = [I | d_x I | d_y I | d_z I]` (3×12) of a node at offset `d` from its piece's
/// centroid: the velocity of the node under the piece's translation `t` and linear map `G`
/// (columns `g_x, g_y, g_z`) is `Φ_n (t, g_x, g_y, g_z) = t + G d`.
#[inline]
fn phi(d: &Vector3<Real>) -> Phi {
    let mut m = Phi::zeros();
    for a in 0..3 {
        m[(a, a)] = 1.0;
        for b in 0..3 {
            m[(a, 3 * (b + 1) + a)] = d[b];
        }
    }
    m
}

impl PiecePreconditioner {
    /// The pieces of `discretization` (nodes coupled by some block), the pattern of its blocks
    /// and pins and its symbolic factorization (computed by the first [`prepare`](Self::prepare)).
    pub(crate) fn new(
        discretization: &dyn Discretization,
        constraints: &Constraints,
        pinned: &[bool],
    ) -> Result<Self, StepErrorKind> {
        let system = AssembledSystem::new(discretization, constraints, false)?;
        let nodes = discretization.num_nodes();
        let mut sets = cleave_geometry::UnionFind::new(nodes);
        let mut members = vec![0u32; nodes];
        for group in discretization.blocks().node_groups() {
            let Some((&first, rest)) = group.split_first() else { continue };
            for &b in rest {
                sets.union(first as usize, b as usize);
            }
        }
        let mut held = vec![false; nodes];
        for node in 0..nodes {
            let root = sets.find(node);
            members[root] += 1;
            if (0..3).any(|a| pinned[3 * node + a]) {
                held[root] = true;
            }
        }
        // Coarse pieces: at least four nodes (so that the affine columns are independent for
        // any nondegenerate element) and no hard pin.
        let mut coarse_of_root = vec![NO_MODES; nodes];
        let mut count = 0u32;
        let mut coarse_of_node = vec![NO_MODES; nodes];
        for node in 0..nodes {
            let root = sets.find(node);
            if held[root] || members[root] < 4 {
                continue;
            }
            if coarse_of_root[root] == NO_MODES {
                coarse_of_root[root] = count;
                count += 1;
            }
            coarse_of_node[node] = coarse_of_root[root];
        }
        let pieces = count as usize;
        let mut piece_offsets = vec![0usize; pieces + 1];
        for &c in &coarse_of_node {
            if c != NO_MODES {
                piece_offsets[c as usize + 1] += 1;
            }
        }
        for p in 0..pieces {
            piece_offsets[p + 1] += piece_offsets[p];
        }
        let mut fill = piece_offsets.clone();
        let mut piece_nodes = vec![0u32; piece_offsets[pieces]];
        for (node, &c) in coarse_of_node.iter().enumerate() {
            if c != NO_MODES {
                piece_nodes[fill[c as usize]] = node as u32;
                fill[c as usize] += 1;
            }
        }
        let mut index_of_root = vec![u32::MAX; nodes];
        let mut members_of: Vec<Vec<u32>> = Vec::new();
        for node in 0..nodes {
            let root = sets.find(node);
            if index_of_root[root] == u32::MAX {
                index_of_root[root] = members_of.len() as u32;
                members_of.push(Vec::new());
            }
            members_of[index_of_root[root] as usize].push(node as u32);
        }
        let factors = members_of
            .into_par_iter()
            .map(|members| PieceFactor::new(members, &system.pattern))
            .collect::<Result<Vec<_>, _>>()?;
        let coarse_pattern = Self::coarse_pattern(pieces, &[]);
        let coarse_values = coarse_pattern.new_values();
        Ok(Self {
            system,
            factors,
            operator_values: Vec::new(),
            coarse_of_node,
            piece_offsets,
            piece_nodes,
            centroids: vec![Vector3::zeros(); pieces],
            coarse_pattern,
            coupled_pairs: Vec::new(),
            coarse_values,
            coarse_cholesky: None,
            coarse_ready: false,
            pairs: Vec::new(),
            contact_pieces: Vec::with_capacity(16),
            sides: Vec::with_capacity(4),
            restricted: vec![0.0; MODES * pieces],
            diagonal: vec![CoarseBlock::zeros(); pieces],
            growths: 0,
        })
    }

    fn coarse_pattern(pieces: usize, pairs: &[(u32, u32)]) -> AssemblyPattern {
        let nodes = |p: u32| (0..MODE_NODES as u32).map(move |k| MODE_NODES as u32 * p + k);
        let own = (0..pieces as u32).map(|p| nodes(p).collect::<Vec<u32>>());
        let coupled = pairs.iter().map(|&(p, q)| nodes(p).chain(nodes(q)).collect::<Vec<u32>>());
        let groups: Vec<Vec<u32>> = own.chain(coupled).collect();
        AssemblyPattern::from_groups(MODE_NODES * pieces, groups.iter().map(Vec::as_slice))
    }

    /// Fills and factorizes `L` and `A_c` for the step matrix at `x` with `rotations` and the
    /// step's `contacts`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn prepare(
        &mut self,
        discretization: &dyn Discretization,
        constraints: &Constraints,
        rotations: &[Matrix3<Real>],
        x: &[Real],
        contacts: &[Contact],
        mass_scale: Real,
        stiffness_scale: Real,
        h: Real,
    ) -> Result<(), StepErrorKind> {
        let points = constraints.contact_points.as_ref();
        // L: elements, masses and pins.
        self.system.fill(discretization, rotations, mass_scale, stiffness_scale);
        if let Some(pins) = &constraints.penalty_pins {
            let k = Matrix3::identity() * (h * h * pins.stiffness);
            let system = &mut self.system;
            for i in 0..pins.points.len() {
                system.pin_ranks.add_row(&pins.points, i, &k, &system.pattern, &mut system.values);
            }
        }
        // The coarse operator from these values (before the lumped contacts and the pins'
        // identity rows: coarse pieces have no hard pins), then the contacts' terms exactly.
        self.update_centroids(x);
        if let Some(points) = points {
            self.grow_coarse_pattern(points, contacts)?;
        } else if self.coarse_cholesky.is_none() {
            self.grow_coarse_pattern(&Embedding::default(), &[])?;
        }
        self.assemble_coarse_elastic(x);
        self.system.apply_pins();
        self.operator_values.clone_from(&self.system.values);
        if let Some(points) = points {
            self.add_coarse_contacts(points, contacts, x);
            add_lumped_contacts(points, contacts, &self.system.pattern, &mut self.system.values);
            // Lumped terms in pinned rows and columns are replaced by the identity again.
            self.system.apply_pins();
        }
        let values = &self.system.values;
        self.factors.par_iter_mut().try_for_each(|factor| factor.factorize(values))?;
        self.coarse_ready = match &mut self.coarse_cholesky {
            Some(cholesky) => cholesky.factorize(&self.coarse_values).is_ok(),
            None => false,
        };
        Ok(())
    }

    fn update_centroids(&mut self, x: &[Real]) {
        let (offsets, nodes) = (&self.piece_offsets, &self.piece_nodes);
        self.centroids.par_iter_mut().enumerate().for_each(|(p, c)| {
            let members = &nodes[offsets[p]..offsets[p + 1]];
            let mut sum = Vector3::zeros();
            for &n in members {
                sum += position(x, n);
            }
            *c = sum / members.len() as Real;
        });
    }

    /// The coarse piece of `node` and its offset from that piece's centroid.
    #[inline]
    fn offset(&self, node: u32, x: &[Real]) -> Option<(u32, Vector3<Real>)> {
        let c = self.coarse_of_node[node as usize];
        (c != NO_MODES).then(|| (c, position(x, node) - self.centroids[c as usize]))
    }

    /// Pieces of the step's contacts that the coarse pattern does not couple yet join it (a new
    /// symbolic factorization; pairs seen before in this epoch are kept).
    fn grow_coarse_pattern(&mut self, points: &Embedding, contacts: &[Contact]) -> Result<(), StepErrorKind> {
        self.pairs.clear();
        let mut pieces = std::mem::take(&mut self.contact_pieces);
        for c in contacts {
            pieces.clear();
            for_each_entry(points, c, |n, _| {
                let p = self.coarse_of_node[n as usize];
                if p != NO_MODES {
                    pieces.push(p);
                }
            });
            pieces.sort_unstable();
            pieces.dedup();
            for (k, &p) in pieces.iter().enumerate() {
                for &q in &pieces[k + 1..] {
                    self.pairs.push((p, q));
                }
            }
        }
        self.contact_pieces = pieces;
        self.pairs.sort_unstable();
        self.pairs.dedup();
        let known = |pair: &(u32, u32)| self.coupled_pairs.binary_search(pair).is_ok();
        if self.coarse_cholesky.is_some() && self.pairs.iter().all(known) {
            return Ok(());
        }
        let mut merged = std::mem::take(&mut self.coupled_pairs);
        merged.extend_from_slice(&self.pairs);
        merged.sort_unstable();
        merged.dedup();
        self.coupled_pairs = merged;
        self.coarse_pattern = Self::coarse_pattern(self.centroids.len(), &self.coupled_pairs);
        self.coarse_values = self.coarse_pattern.new_values();
        self.coarse_cholesky = Some(SparseCholesky::new(&self.coarse_pattern)?);
        self.growths += 1;
        Ok(())
    }

    /// `Φᵀ A Φ` of the values written so far (elements, masses, penalty pins), piece by piece
    /// (their pattern couples no two pieces), into the coarse values, which it resets. Per
    /// column node `j`: `u = Σ_i Φ_iᵀ a_ij = [Σ a_ij ; Σ [d_i]× a_ij]`, then `u Φ_j`.
    fn assemble_coarse_elastic(&mut self, x: &[Real]) {
        let mut diagonal = std::mem::take(&mut self.diagonal);
        let pattern = &self.system.pattern;
        let values = &self.system.values;
        let this = &*self;
        diagonal.par_iter_mut().enumerate().for_each(|(p, block)| {
            let mut acc = CoarseBlock::zeros();
            for &j in &this.piece_nodes[this.piece_offsets[p]..this.piece_offsets[p + 1]] {
                let mut u = nalgebra::SMatrix::<Real, MODES, 3>::zeros();
                let col_ptr = pattern.col_ptr();
                for (rank, &i) in pattern.neighbours(j).iter().enumerate() {
                    let mut a = Matrix3::zeros();
                    for col in 0..3 {
                        let at = col_ptr[3 * j as usize + col] + 3 * rank;
                        for row in 0..3 {
                            a[(row, col)] = values[at + row];
                        }
                    }
                    let d = position(x, i) - this.centroids[p];
                    u += phi(&d).transpose() * a;
                }
                let d = position(x, j) - this.centroids[p];
                acc += u * phi(&d);
            }
            *block = acc;
        });
        self.coarse_values.iter_mut().for_each(|v| *v = 0.0);
        for (p, block) in diagonal.iter().enumerate() {
            add_coarse_block(&self.coarse_pattern, &mut self.coarse_values, p as u32, p as u32, block);
        }
        self.diagonal = diagonal;
    }

    /// `Σ_contacts G_pᵀ P G_q` over the pieces `p, q` of each contact row, `G_p = Σ_{n ∈ p} w_n Φ_n`.
    fn add_coarse_contacts(&mut self, points: &Embedding, contacts: &[Contact], x: &[Real]) {
        let mut sides = std::mem::take(&mut self.sides);
        for c in contacts {
            sides.clear();
            for_each_entry(points, c, |n, w| {
                if let Some((p, d)) = self.offset(n, x) {
                    let g = phi(&d) * w;
                    match sides.iter_mut().find(|s| s.0 == p) {
                        Some(side) => side.1 += g,
                        None => sides.push((p, g)),
                    }
                }
            });
            for (p, gp) in &sides {
                for (q, gq) in &sides {
                    let m = gp.transpose() * c.matrix * gq;
                    add_coarse_block(&self.coarse_pattern, &mut self.coarse_values, *p, *q, &m);
                }
            }
        }
        self.sides = sides;
    }

    /// The step matrix and the preconditioner of the prepared step, borrowed apart for CG.
    pub(crate) fn split(&mut self) -> (PieceOperator<'_>, PieceCorrection<'_>) {
        let operator = PieceOperator { pattern: &self.system.pattern, values: &self.operator_values };
        let coarse = self.coarse_cholesky.as_mut().filter(|_| self.coarse_ready);
        let correction = PieceCorrection {
            factors: &mut self.factors,
            coarse,
            coarse_of_node: &self.coarse_of_node,
            piece_offsets: &self.piece_offsets,
            piece_nodes: &self.piece_nodes,
            centroids: &self.centroids,
            restricted: &mut self.restricted,
        };
        (operator, correction)
    }
}

/// `A` of a prepared step: [`PiecePreconditioner::split`].
pub(crate) struct PieceOperator<'a> {
    pattern: &'a AssemblyPattern,
    values: &'a [Real],
}

impl PieceOperator<'_> {
    /// `out = A p`: the prepared elements, masses and pins (identity rows where pinned) plus
    /// the contacts' action (`contacts` of the prepared step).
    pub(crate) fn multiply(
        &self,
        points: Option<&Embedding>,
        contacts: &[Contact],
        pinned: &[bool],
        p: &[Real],
        out: &mut [Real],
    ) {
        self.pattern.mul_vec(self.values, p, out);
        if let Some(points) = points {
            cleave_contact::add_action(points, contacts, p, out);
            for (d, (o, &pin)) in out.iter_mut().zip(pinned).enumerate() {
                if pin {
                    *o = p[d];
                }
            }
        }
    }
}

/// The preconditioner of a prepared step: [`PiecePreconditioner::split`].
pub(crate) struct PieceCorrection<'a> {
    factors: &'a mut [PieceFactor],
    coarse: Option<&'a mut SparseCholesky>,
    coarse_of_node: &'a [u32],
    piece_offsets: &'a [usize],
    piece_nodes: &'a [u32],
    centroids: &'a [Vector3<Real>],
    restricted: &'a mut Vec<Real>,
}

impl PieceCorrection<'_> {
    /// `z = L⁻ᵀ L⁻¹ r + Φ A_c⁻¹ Φᵀ r` with the centroids of the prepared state `x`.
    pub(crate) fn apply(&mut self, x: &[Real], r: &[Real], z: &mut [Real]) {
        self.factors.par_iter_mut().for_each(|factor| factor.solve(r));
        for factor in self.factors.iter() {
            factor.scatter(z);
        }
        let Some(coarse) = self.coarse.as_deref_mut() else { return };
        let (offsets, nodes, centroids) = (self.piece_offsets, self.piece_nodes, self.centroids);
        self.restricted.par_chunks_mut(MODES).enumerate().for_each(|(p, y)| {
            let mut sum = CoarseVector::zeros();
            for &n in &nodes[offsets[p]..offsets[p + 1]] {
                sum += phi(&(position(x, n) - centroids[p])).transpose() * position(r, n);
            }
            y.copy_from_slice(sum.as_slice());
        });
        coarse.solve_in_place(self.restricted);
        let restricted = &*self.restricted;
        let coarse_of_node = self.coarse_of_node;
        z.par_chunks_mut(3).enumerate().for_each(|(n, z)| {
            let p = coarse_of_node[n];
            if p == NO_MODES {
                return;
            }
            let y = CoarseVector::from_column_slice(&restricted[MODES * p as usize..MODES * (p as usize + 1)]);
            let add = phi(&(position(x, n as u32) - centroids[p as usize])) * y;
            for a in 0..3 {
                z[a] += add[a];
            }
        });
    }
}

/// Node `n`'s 3-vector of `v`.
#[inline]
fn position(v: &[Real], n: u32) -> Vector3<Real> {
    let i = 3 * n as usize;
    Vector3::new(v[i], v[i + 1], v[i + 2])
}

/// Adds the 6×6 block `m` at pieces `(p, q)` of the coarse values (rows `p`, columns `q`).
fn add_coarse_block(pattern: &AssemblyPattern, values: &mut [Real], p: u32, q: u32, m: &CoarseBlock) {
    for bj in 0..MODE_NODES {
        let cj = (MODE_NODES * q as usize + bj) as u32;
        for bi in 0..MODE_NODES {
            let ci = (MODE_NODES * p as usize + bi) as u32;
            let rank = pattern.rank(ci, cj).expect("the coarse pattern couples every contact's pieces");
            let block = m.fixed_view::<3, 3>(3 * bi, 3 * bj).into_owned();
            pattern.add_block(values, rank, cj, &block, 1.0);
        }
    }
}

/// `L += Σ_contacts Σ_points s² (e eᵀ ⊗ P)`: each contact row lumped by surface point (one
/// element's nodes, in the pattern). A point whose embedding row the pattern does not couple
/// (an embedding across elements) is lumped further onto its nodes' diagonals,
/// `s² |w_i| Σ_j |w_j| P`, which bounds `s² e eᵀ ⊗ P` from above.
fn add_lumped_contacts(points: &Embedding, contacts: &[Contact], pattern: &AssemblyPattern, values: &mut [Real]) {
    for c in contacts {
        for (point, s) in c.row.entries() {
            let (nodes, weights) = points.row(point as usize);
            let coupled = nodes.iter().all(|&j| nodes.iter().all(|&i| pattern.rank(i, j).is_some()));
            if coupled {
                for (&j, &wj) in nodes.iter().zip(weights) {
                    for (&i, &wi) in nodes.iter().zip(weights) {
                        let rank = pattern.rank(i, j).expect("checked above");
                        pattern.add_block(values, rank, j, &c.matrix, s * s * wi * wj);
                    }
                }
            } else {
                let total: Real = weights.iter().map(|w| w.abs()).sum();
                for (&j, &wj) in nodes.iter().zip(weights) {
                    let rank = pattern.rank(j, j).expect("diagonal is in the pattern");
                    pattern.add_block(values, rank, j, &c.matrix, s * s * wj.abs() * total);
                }
            }
        }
    }
}

/// The Cholesky factorization of one piece's rows and columns of the step matrix.
struct PieceFactor {
    /// The piece's nodes, ascending (local node `k` is `nodes[k]`).
    nodes: Vec<u32>,
    /// For each local value, its position in the whole system's values.
    gather: Vec<usize>,
    values: Vec<Real>,
    cholesky: SparseCholesky,
    /// The piece's part of the right-hand side, solved in place.
    rhs: Vec<Real>,
}

impl PieceFactor {
    /// The local pattern of `nodes` (a union of connected components of `pattern`) and its
    /// symbolic factorization.
    fn new(nodes: Vec<u32>, pattern: &AssemblyPattern) -> Result<Self, StepErrorKind> {
        let local = |global: u32| nodes.binary_search(&global).expect("a piece holds its neighbours") as u32;
        let pairs: Vec<[u32; 2]> = nodes
            .iter()
            .enumerate()
            .flat_map(|(k, &j)| pattern.neighbours(j).iter().map(move |&i| (k, i)))
            .map(|(k, i)| [local(i), k as u32])
            .collect();
        let own = AssemblyPattern::from_groups(nodes.len(), pairs.iter().map(|p| &p[..]));
        let mut gather = vec![0usize; own.nnz()];
        for (k, &j) in nodes.iter().enumerate() {
            for (local_rank, &i_local) in own.neighbours(k as u32).iter().enumerate() {
                let rank = pattern.rank(nodes[i_local as usize], j).expect("the local pattern is the global one's");
                for c in 0..3 {
                    for r in 0..3 {
                        gather[own.position(local_rank as u32, k as u32, r, c)] = pattern.position(rank, j, r, c);
                    }
                }
            }
        }
        let cholesky = SparseCholesky::new(&own)?;
        let dim = own.dim();
        Ok(Self { nodes, values: vec![0.0; gather.len()], gather, cholesky, rhs: vec![0.0; dim] })
    }

    fn factorize(&mut self, values: &[Real]) -> Result<(), StepErrorKind> {
        for (v, &g) in self.values.iter_mut().zip(&self.gather) {
            *v = values[g];
        }
        Ok(self.cholesky.factorize(&self.values)?)
    }

    /// Solves for the piece's part of `r` (kept in `rhs`).
    fn solve(&mut self, r: &[Real]) {
        for (k, &n) in self.nodes.iter().enumerate() {
            self.rhs[3 * k..3 * k + 3].copy_from_slice(&r[3 * n as usize..3 * n as usize + 3]);
        }
        self.cholesky.solve_in_place_sequential(&mut self.rhs);
    }

    /// Writes the last solution into the piece's rows of `z`.
    fn scatter(&self, z: &mut [Real]) {
        for (k, &n) in self.nodes.iter().enumerate() {
            z[3 * n as usize..3 * n as usize + 3].copy_from_slice(&self.rhs[3 * k..3 * k + 3]);
        }
    }
}
