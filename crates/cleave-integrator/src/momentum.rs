//! Angular momentum of free pieces: the linearly implicit step's elastic forces exert a
//! spurious torque on their own piece, which is removed after the solve
//! (docs/math/corotated-integrator.md, "Angular momentum").

use cleave_core::{Discretization, Matrix3, Real, Vector3};

/// Connected components of the mesh (pieces) and, per piece, whether it is free (no pinned DOF,
/// no penalty pin), with the scratch the per-step correction accumulates into.
#[derive(Debug, Default)]
pub(crate) struct FreePieces {
    /// Piece of every node; `u32::MAX` for nodes of pieces that are not free.
    piece_of_node: Vec<u32>,
    /// Number of free pieces.
    count: usize,
    /// Per free piece, one of its nodes: moments are taken about its position, which keeps
    /// them accurate for a small piece far from the origin.
    reference: Vec<u32>,
    /// Per node, its coefficient in the constant field 1 (`Discretization::add_translation`):
    /// 1 for nodal bases, which sum to one; for DG's modal bases only the constant mode's.
    translation: Vec<Real>,
    /// Per free piece: torque of the elastic force at the start of the step about `x_n`.
    start_torque: Vec<Vector3<Real>>,
    /// Angular momentum the couples of contact pairs between (or within) pieces added in the
    /// step, with the piece of either side (`u32::MAX` when held).
    couples: Vec<(u32, u32, Vector3<Real>)>,
    /// Per free piece: mass, first and second moments of `x_n`, torque of `K_R v⁺`.
    sums: Vec<PieceSums>,
}

/// Largest change of a piece's angular momentum about its centre of mass, relative to it, that
/// one step's correction makes.
const CORRECTION_LIMIT: Real = 1e-2;

/// Smallest ratio of a piece's smallest to largest principal moment of inertia that the
/// correction turns.
const INERTIA_CONDITION: Real = 1e-6;

#[derive(Clone, Copy, Debug, Default)]
struct PieceSums {
    mass: Real,
    first: Vector3<Real>,
    second: Matrix3<Real>,
    stiffness_torque: Vector3<Real>,
    /// Centre of mass (relative to the reference node), inertia about it, whether the piece
    /// can be turned, and the angular momentum to cancel.
    centre: Vector3<Real>,
    inertia: Matrix3<Real>,
    turns: bool,
    added: Vector3<Real>,
    /// Angular momentum about the origin and linear momentum of the solved `v⁺`.
    momentum: Vector3<Real>,
    linear: Vector3<Real>,
    /// Centre of mass and the change of angular velocity, once computed.
    turn: Option<(Vector3<Real>, Vector3<Real>)>,
}

impl FreePieces {
    /// Pieces of `discretization` from its blocks (two nodes are in one piece when some block
    /// couples them); `fixed_nodes` names nodes whose piece is held from outside, and the nodes
    /// of anchored blocks (DG's weak Dirichlet faces, forces from the world) are held too.
    pub(crate) fn new(discretization: &dyn Discretization, fixed_nodes: impl Iterator<Item = usize>) -> Self {
        let nodes = discretization.num_nodes();
        let mut sets = cleave_geometry::UnionFind::new(nodes);
        for group in discretization.blocks().node_groups() {
            let Some((&first, rest)) = group.split_first() else { continue };
            for &b in rest {
                sets.union(first as usize, b as usize);
            }
        }
        let mut fixed_root = vec![false; nodes];
        let blocks = discretization.blocks();
        let anchored = (0..blocks.len()).map(|b| blocks.block(b)).filter(|b| b.anchor.is_some());
        let anchored_nodes: Vec<usize> = anchored.flat_map(|b| b.nodes.iter().map(|&n| n as usize)).collect();
        for node in fixed_nodes.chain(anchored_nodes) {
            fixed_root[sets.find(node)] = true;
        }
        let mut index_of_root = vec![u32::MAX; nodes];
        let mut count = 0;
        let mut piece_of_node = vec![u32::MAX; nodes];
        let mut reference = Vec::new();
        for node in 0..nodes {
            let r = sets.find(node);
            if fixed_root[r] {
                continue;
            }
            if index_of_root[r] == u32::MAX {
                index_of_root[r] = count as u32;
                reference.push(node as u32);
                count += 1;
            }
            piece_of_node[node] = index_of_root[r];
        }
        let mut unit = vec![0.0; 3 * nodes];
        discretization.add_translation(&Vector3::x(), &mut unit);
        let translation = unit.iter().step_by(3).copied().collect();
        Self {
            piece_of_node,
            count,
            reference,
            translation,
            start_torque: vec![Vector3::zeros(); count],
            couples: Vec::new(),
            sums: vec![PieceSums::default(); count],
        }
    }

    /// Position of DOF `node` relative to its piece's reference node, `x_k − t_k x_ref` (a shift
    /// of the field by `−x_ref`; for nodal bases `x_k − x_ref`).
    fn relative(&self, x: &[Real], node: usize, piece: u32) -> Vector3<Real> {
        let r = self.reference[piece as usize] as usize;
        let t = self.translation[node];
        Vector3::from_fn(|a, _| x[3 * node + a] - t * x[3 * r + a])
    }

    /// Whether there is any free piece to correct.
    pub(crate) fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Records the torque of the elastic force `f_el(x)` of every free piece (about its
    /// reference node; internal forces sum to zero, so the point does not matter).
    pub(crate) fn record_start_torque(&mut self, x: &[Real], elastic_force: impl Fn(usize) -> Vector3<Real>) {
        self.start_torque.iter_mut().for_each(|t| *t = Vector3::zeros());
        self.couples.clear();
        for (node, &piece) in self.piece_of_node.iter().enumerate() {
            if piece != u32::MAX {
                let p = self.relative(x, node, piece);
                self.start_torque[piece as usize] += p.cross(&elastic_force(node));
            }
        }
    }

    /// Books the angular momentum `couple` that a contact pair between the pieces of nodes `a`
    /// and `b` added in the step; [`Self::cancel_elastic_torque`] shares it between the two.
    pub(crate) fn add_pair_couple(&mut self, a: u32, b: u32, couple: Vector3<Real>) {
        let piece = |n: u32| self.piece_of_node.get(n as usize).copied().unwrap_or(u32::MAX);
        let (pa, pb) = (piece(a), piece(b));
        if pa != u32::MAX || pb != u32::MAX {
            self.couples.push((pa, pb, couple));
        }
    }

    /// Changes `v` (the step's solution `v⁺`, not yet applied to `x`) by a rigid rotation about
    /// each free piece's centre of mass that cancels the angular momentum its own linearized
    /// elastic and stiffness-damping force `f_el(x) − (h + β) K_R v⁺` added in the step:
    /// `h Σ x × (f_el(x) − (h + β) K_R v⁺)`. `stiffness_times_v` is `K_R v⁺`; `mass` the lumped
    /// diagonal. The couples booked by [`Self::add_pair_couple`] are cancelled with it, each
    /// shared between its two pieces as `τ_a = I_a (I_a + I_b)⁻¹ τ` (the share with the smallest
    /// rigid-rotation energy `½ Σ δωᵀ I δω`: a sliver touching a large piece gets almost none),
    /// all of it to the one that can turn when the other is held or cannot. Linear momentum is unchanged (the rotations are about
    /// the centres of mass).
    pub(crate) fn cancel_elastic_torque(
        &mut self,
        x: &[Real],
        mass: &[Real],
        stiffness_times_v: &[Real],
        h: Real,
        beta: Real,
        v: &mut [Real],
    ) {
        self.sums.iter_mut().for_each(|s| *s = PieceSums::default());
        for (node, &piece) in self.piece_of_node.iter().enumerate() {
            if piece == u32::MAX {
                continue;
            }
            let p = self.relative(x, node, piece);
            let s = &mut self.sums[piece as usize];
            let m = mass[3 * node];
            let t = self.translation[node];
            s.mass += m * t * t;
            s.first += m * t * p;
            s.second += m * p * p.transpose();
            let kv = Vector3::new(
                stiffness_times_v[3 * node],
                stiffness_times_v[3 * node + 1],
                stiffness_times_v[3 * node + 2],
            );
            s.stiffness_torque += p.cross(&kv);
            s.momentum += p.cross(&Vector3::new(v[3 * node], v[3 * node + 1], v[3 * node + 2])) * m;
            s.linear += Vector3::new(v[3 * node], v[3 * node + 1], v[3 * node + 2]) * (m * t);
        }
        for (s, start_torque) in self.sums.iter_mut().zip(&self.start_torque) {
            s.turn = None;
            s.added = h * (start_torque - (h + beta) * s.stiffness_torque);
            s.turns = false;
            if s.mass > 0.0 {
                // The inertia about the centre of mass, `Σ m (|x|² I − x xᵀ) − m (|c|² I − c cᵀ)`
                // (over coefficients for modal bases: `∫ ρ x × v = Σ m_k x_k × v_k` for
                // orthogonal ones).
                let centre = s.first / s.mass;
                let about_origin = Matrix3::identity() * s.second.trace() - s.second;
                s.inertia =
                    about_origin - (Matrix3::identity() * centre.norm_squared() - centre * centre.transpose()) * s.mass;
                s.centre = centre;
                // A piece of one point, of collinear points or a needle cannot (or should not)
                // be turned about its weak axis: the spin for a given change of angular
                // momentum grows without bound.
                let eigen = s.inertia.symmetric_eigenvalues();
                s.turns = eigen.min() > INERTIA_CONDITION * eigen.max() && eigen.min().is_finite();
            }
        }
        for &(a, b, couple) in &self.couples {
            let inertia = |p: u32| self.sums.get(p as usize).filter(|s| s.turns).map(|s| s.inertia);
            match (inertia(a), inertia(b)) {
                (Some(ia), Some(ib)) if a != b => {
                    let share = (ia + ib).try_inverse().map_or(couple * 0.5, |inverse| ia * (inverse * couple));
                    self.sums[a as usize].added += share;
                    self.sums[b as usize].added += couple - share;
                }
                (Some(_), _) => self.sums[a as usize].added += couple,
                (None, Some(_)) => self.sums[b as usize].added += couple,
                (None, None) => {}
            }
        }
        for s in self.sums.iter_mut().filter(|s| s.turns) {
            let Some(spin) = s.inertia.try_inverse().map(|inverse| inverse * -s.added) else { continue };
            if !spin.iter().all(|c| c.is_finite()) {
                continue;
            }
            // The correction is explicit: it gives back as rigid rotation what the step's
            // implicit stiffness took. Where that is more than a small part of the piece's own
            // angular momentum about its centre of mass, the step does not resolve the piece's
            // rotation (a sliver of stiff elements, a piece turning by a large angle per step),
            // and giving it all back adds energy (docs/math/corotated-integrator.md): only
            // `CORRECTION_LIMIT` of the piece's own angular momentum is given back.
            let own = (s.momentum - s.centre.cross(&s.linear)).norm();
            let wanted = s.added.norm();
            let fraction = if wanted > CORRECTION_LIMIT * own { CORRECTION_LIMIT * own / wanted } else { 1.0 };
            s.turn = Some((s.centre, spin * fraction));
        }
        for (node, &piece) in self.piece_of_node.iter().enumerate() {
            if piece == u32::MAX {
                continue;
            }
            if let Some((centre, spin)) = self.sums[piece as usize].turn {
                let p = self.relative(x, node, piece);
                // The field `δω × (x − c)`: `δω × x` minus the constant `δω × c` (both relative
                // to the reference node).
                let dv = spin.cross(&p) - spin.cross(&centre) * self.translation[node];
                for a in 0..3 {
                    v[3 * node + a] += dv[a];
                }
            }
        }
    }
}
