//! Rigid fragments in a scene (mueller2004 §2.4): which free pieces are handed to the rigid
//! world (`cleave-rigid`, on rapier) and when they come back; the rules are derived in
//! docs/math/rigid-fragments.md §2. The runner calls [`RigidHybrid::before_step`] and
//! [`RigidHybrid::after_step`] around each integrator step; a cut or fracture returns every
//! fragment first ([`RigidHybrid::return_all`]), since it renumbers the nodes.

use cleave_core::{Discretization, Embedding, Piece, Point3, Real};
use cleave_integrator::{Integrator, StepError};
use cleave_rigid::{FragmentShape, RigidFit, RigidWorld};
use nalgebra::Matrix3;
use std::collections::{HashMap, HashSet};

/// The thresholds of the switching rules.
#[derive(Clone, Debug)]
pub(crate) struct RigidRules {
    pub check_every: u64,
    /// [J/kg]
    pub max_strain_energy: Real,
    /// [m/s]
    pub max_vibration_speed: Real,
    /// [m]
    pub margin: Real,
    /// Impacts are kept in the rigid world and analysed statically (`impact: Static`): no
    /// fragment returns ahead of an obstacle, and a piece about to hit one may go rigid.
    pub static_impacts: bool,
}

/// The static load of an impact on one fragment (`impact: Static`, docs/math/rigid-fragments.md
/// §5): its contact impulses as forces at the nearest nodes, in the rest frame, of a size to be
/// scaled (by the energy of the impact), and the free bodies they act on (its pieces that
/// received some).
pub(crate) struct ImpactLoad {
    pub load: Vec<Real>,
    pub bodies: Vec<Vec<u32>>,
    /// The kinetic energy of the approach, `½ M v_n²` with `v_n` the speed at which the
    /// fragment's centre approached along the net impulse before the step [J]: what the static
    /// load's strain energy is scaled to.
    pub approach_energy: Real,
    /// `|J| / M` [m/s].
    pub velocity_change: Real,
}

/// Hand-offs over a run.
#[derive(Clone, Copy, Debug, Default)]
pub struct RigidCounts {
    /// Pieces that became rigid bodies.
    pub to_rigid: usize,
    /// Fragments returned by an impact.
    pub by_impact: usize,
    /// Fragments returned because a deformable piece came near.
    pub by_proximity: usize,
    /// Fragments returned by a cut or a fracture.
    pub by_change: usize,
    /// Fragments rigid now.
    pub rigid: usize,
    /// Impacts kept in the rigid world and analysed statically (`impact: Static`).
    pub static_impacts: usize,
}

pub(crate) struct RigidHybrid {
    world: RigidWorld,
    rules: RigidRules,
    /// The DOFs the scene's pins hold (the rigid fragments' nodes are pinned besides these).
    scene_pinned: Vec<usize>,
    /// Per node: which fragment moves it (`u32::MAX`: none).
    fragment_of: Vec<u32>,
    /// Scratch for one piece's elastic energy.
    alone: Vec<Real>,
    alone_rotations: Vec<Matrix3<Real>>,
    /// Scratch: the deformable nodes' grid of the proximity rule (run every step).
    near_grid: NearGrid,
    /// Scratch for the surface points a fragment's collider is made of.
    surface_points: Vec<Point3<Real>>,
    pub(crate) counts: RigidCounts,
}

/// The cells of a grid (edge `gap`) that hold deformable nodes: a point is near them when a
/// cell next to its own holds one (always when one is within `gap`, never when none is within
/// `2√3 gap`). Entering uses `4 · margin` cells and returning `margin` cells, so a piece that
/// just went rigid (nothing within 4 margins) is not returned at once (that needs something
/// within 2√3 ≈ 3.5 margins).
struct NearGrid {
    gap: Real,
    cells: HashSet<[i64; 3]>,
}

impl NearGrid {
    fn new(gap: Real) -> Self {
        Self { gap, cells: HashSet::default() }
    }

    /// Empties the grid and sets its cell size, keeping its allocation.
    fn reset(&mut self, gap: Real) {
        self.gap = gap;
        self.cells.clear();
    }

    fn cell(&self, x: &[Real], node: u32) -> [i64; 3] {
        let k = 3 * node as usize;
        [0, 1, 2].map(|a| (x[k + a] / self.gap).floor() as i64)
    }

    fn insert(&mut self, nodes: &[u32], x: &[Real]) {
        for &n in nodes {
            let cell = self.cell(x, n);
            self.cells.insert(cell);
        }
    }

    fn near(&self, nodes: &[u32], x: &[Real]) -> bool {
        nodes.iter().any(|&n| {
            let [i, j, k] = self.cell(x, n);
            (-1..=1).any(|a| (-1..=1).any(|b| (-1..=1).any(|c| self.cells.contains(&[i + a, j + b, k + c]))))
        })
    }
}

impl RigidHybrid {
    pub(crate) fn new(world: RigidWorld, rules: RigidRules, scene_pinned: Vec<usize>) -> Self {
        Self {
            world,
            rules,
            scene_pinned,
            fragment_of: Vec::new(),
            alone: Vec::new(),
            alone_rotations: Vec::new(),
            surface_points: Vec::new(),
            near_grid: NearGrid::new(1.0),
            counts: RigidCounts::default(),
        }
    }

    /// The pinned DOFs the integrator needs: the scene's and every rigid fragment's.
    fn pinned_dofs(&self) -> Vec<usize> {
        let mut dofs = self.scene_pinned.clone();
        for f in self.world.fragments() {
            dofs.extend(f.nodes.iter().flat_map(|&n| (0..3).map(move |a| 3 * n as usize + a)));
        }
        dofs.sort_unstable();
        dofs.dedup();
        dofs
    }

    fn refresh_fragment_of(&mut self, num_nodes: usize) {
        self.fragment_of.clear();
        self.fragment_of.resize(num_nodes, u32::MAX);
        for (i, f) in self.world.fragments().iter().enumerate() {
            for &n in &f.nodes {
                self.fragment_of[n as usize] = i as u32;
            }
        }
        self.counts.rigid = self.world.fragments().len();
    }

    /// Before a topology change: every fragment returns (its nodes already carry its motion);
    /// the change's rebuild unpins them. `scene_pinned`: the scene's pins after the change.
    /// Returns how many fragments returned.
    pub(crate) fn return_all(&mut self, scene_pinned: Vec<usize>) -> usize {
        let returned = self.world.fragments().len();
        self.counts.by_change += returned;
        self.world.clear();
        self.scene_pinned = scene_pinned;
        self.fragment_of.clear();
        self.counts.rigid = 0;
        returned
    }

    /// Before the integrator's step: fragments about to hit an obstacle and fragments near a
    /// deformable piece return (before the rigid world steps, so that nothing they would have
    /// touched in that step keeps an impulse from them); then the rigid world steps, and
    /// fragments hit hard enough return, rolled back to before the step.
    pub(crate) fn before_step(
        &mut self,
        body: &dyn Discretization,
        integrator: &mut Integrator,
        pieces: &[Piece],
    ) -> Result<(), StepError> {
        if self.world.is_empty() {
            return Ok(());
        }
        // Fragments about to hit an obstacle return two steps ahead (docs §2), unless the
        // rigid world keeps its impacts.
        let (x, v) = (integrator.positions(), integrator.velocities());
        let ahead =
            if self.rules.static_impacts { Vec::new() } else { self.world.about_to_hit(x, v, self.rules.margin, 2.0) };
        for &i in ahead.iter().rev() {
            self.world.remove(i);
        }
        let mut changed = !ahead.is_empty();
        // Proximity, until no returned fragment brings another near.
        loop {
            self.refresh_fragment_of(body.num_nodes());
            let deformable = &mut self.near_grid;
            deformable.reset(self.rules.margin);
            for p in
                pieces.iter().filter(|p| p.nodes.first().is_some_and(|&n| self.fragment_of[n as usize] == u32::MAX))
            {
                deformable.insert(&p.nodes, x);
            }
            let near: Vec<usize> = (0..self.world.fragments().len())
                .filter(|&i| self.near_grid.near(&self.world.fragments()[i].nodes, x))
                .collect();
            if near.is_empty() {
                break;
            }
            for &i in near.iter().rev() {
                self.world.remove(i);
            }
            self.counts.by_proximity += near.len();
            changed = true;
        }
        let hit = self.world.step().len();
        self.counts.by_impact += ahead.len() + hit;
        self.counts.static_impacts += self.world.impacts().len();
        changed |= hit > 0;
        if changed {
            self.refresh_fragment_of(body.num_nodes());
            integrator.set_pinned_dofs(body, self.pinned_dofs())?;
        }
        Ok(())
    }

    /// After the integrator's step: the fragments' motion (already stepped) is written into
    /// their nodes; every `check_every` steps, quiet free pieces far from deformable ones are
    /// handed to the rigid world. Returns whether the state was edited (its energies are then
    /// to be evaluated again).
    pub(crate) fn after_step(
        &mut self,
        body: &dyn Discretization,
        integrator: &mut Integrator,
        pieces: &[Piece],
        surface: (&Embedding, &[[u32; 3]], &[u32]),
    ) -> Result<bool, StepError> {
        let edited = !self.world.is_empty();
        if edited {
            let world = &self.world;
            integrator.edit_state(body, |x, v| world.write_motion(x, v));
        }
        if !integrator.steps_taken().is_multiple_of(self.rules.check_every) {
            return Ok(edited);
        }
        self.refresh_fragment_of(body.num_nodes());
        let mass = body.mass().diagonal();
        let (x, v) = (integrator.positions(), integrator.velocities());
        let pinned: Vec<bool> = {
            let mut pinned = vec![false; body.num_nodes()];
            self.scene_pinned.iter().for_each(|&d| pinned[d / 3] = true);
            pinned
        };
        // Candidates: free, quiet and nearly unstrained; the others stay deformable.
        let vibration_limit = 0.5 * self.rules.max_vibration_speed.powi(2);
        let mut candidates = Vec::new();
        let mut deformable = NearGrid::new(4.0 * self.rules.margin);
        for (index, piece) in pieces.iter().enumerate() {
            let Some(&first) = piece.nodes.first() else { continue };
            if self.fragment_of[first as usize] != u32::MAX {
                continue;
            }
            let quiet = !piece.nodes.iter().any(|&n| pinned[n as usize])
                && RigidFit::of(&piece.nodes, mass, x, v).is_some_and(|fit| {
                    fit.vibration_energy_per_mass() <= vibration_limit
                        && self.strain_energy(body, piece, x, integrator.rotations())
                            <= self.rules.max_strain_energy * fit.mass
                });
            if quiet { candidates.push(index) } else { deformable.insert(&piece.nodes, x) }
        }
        // A candidate near a deformable piece or a rigid fragment, or about to hit an obstacle,
        // stays deformable itself, which may bring others near: until none changes. (Rigid
        // fragments resting on each other in the rigid world chatter: touching candidates go
        // rigid as one body below, and none goes rigid next to a fragment.)
        for f in self.world.fragments() {
            deformable.insert(&f.nodes, x);
        }
        loop {
            let (keep, stay): (Vec<usize>, Vec<usize>) = candidates.iter().partition(|&&i| {
                !deformable.near(&pieces[i].nodes, x)
                    && (self.rules.static_impacts
                        || !self.world.approaching(&pieces[i].nodes, x, v, self.rules.margin, 2.0))
            });
            if stay.is_empty() {
                break;
            }
            stay.iter().for_each(|&i| deformable.insert(&pieces[i].nodes, x));
            candidates = keep;
        }
        // Candidates within 4 margins of each other: one rigid body (a resting pile moves as one).
        let mut cluster_of = cleave_geometry::UnionFind::new(candidates.len());
        let mut grid = NearGrid::new(4.0 * self.rules.margin);
        for i in 0..candidates.len() {
            grid.reset(4.0 * self.rules.margin);
            grid.insert(&pieces[candidates[i]].nodes, x);
            for j in i + 1..candidates.len() {
                if grid.near(&pieces[candidates[j]].nodes, x) {
                    cluster_of.union(i, j);
                }
            }
        }
        let mut clusters: Vec<Vec<usize>> = Vec::new();
        let mut cluster_index: HashMap<usize, usize> = HashMap::new();
        // Per piece, its cluster (u32::MAX: none).
        let mut piece_cluster = vec![u32::MAX; pieces.len()];
        for i in 0..candidates.len() {
            let r = cluster_of.find(i);
            let c = *cluster_index.entry(r).or_insert_with(|| {
                clusters.push(Vec::new());
                clusters.len() - 1
            });
            clusters[c].push(candidates[i]);
            piece_cluster[candidates[i]] = c as u32;
        }
        let (embedding, triangles, piece_of) = surface;
        let mut points = std::mem::take(&mut self.surface_points);
        if !clusters.is_empty() {
            embedding.evaluate(x, &mut points);
        }
        let mut added = false;
        let mut local_vertex = HashMap::new();
        for (c, cluster) in clusters.iter().enumerate() {
            // The pieces' own surface triangles, over their own vertices.
            local_vertex.clear();
            let (mut vertices, mut own) = (Vec::new(), Vec::new());
            for (t, _) in triangles.iter().zip(piece_of).filter(|&(_, &p)| piece_cluster[p as usize] == c as u32) {
                own.push(t.map(|i| {
                    *local_vertex.entry(i).or_insert_with(|| {
                        vertices.push(points[i as usize]);
                        (vertices.len() - 1) as u32
                    })
                }));
            }
            let mut nodes: Vec<u32> = cluster.iter().flat_map(|&i| pieces[i].nodes.iter().copied()).collect();
            nodes.sort_unstable();
            nodes.dedup();
            let shape = FragmentShape::Surface { vertices: &vertices, triangles: &own };
            if self.world.add(nodes, mass, x, v, shape).is_ok() {
                self.counts.to_rigid += cluster.len();
                added = true;
            }
        }
        self.surface_points = points;
        if added {
            self.refresh_fragment_of(body.num_nodes());
            integrator.set_pinned_dofs(body, self.pinned_dofs())?;
        }
        Ok(edited)
    }

    /// The static loads of this step's impacts (`impact: Static`), one per fragment hit: each
    /// contact impulse `J` acts as a force at the fragment's node nearest its point, all in the
    /// rest frame (its size is the energy method's, applied by the caller). A fragment's own frame (its hand-off
    /// shape about its centre) is turned to the rest frame by the rotation that best carries the
    /// rest shape onto it (the polar factor of `Σ m r_handoff (X − C)ᵀ`); its pieces that
    /// receive a load are the free bodies (docs §5).
    pub(crate) fn impact_loads(&self, body: &dyn Discretization, pieces: &[Piece]) -> Vec<ImpactLoad> {
        let impacts = self.world.impacts();
        let rest = body.rest_dofs();
        let mass = body.mass().diagonal();
        let at = |n: u32| {
            let k = 3 * n as usize;
            nalgebra::Vector3::new(rest[k], rest[k + 1], rest[k + 2])
        };
        let mut loads = Vec::new();
        for impact in impacts {
            let mut load = vec![0.0; rest.len()];
            let fragment = &self.world.fragments()[impact.fragment];
            let total: Real = fragment.nodes.iter().map(|&n| mass[3 * n as usize]).sum();
            let centre =
                fragment.nodes.iter().map(|&n| mass[3 * n as usize] * at(n)).sum::<nalgebra::Vector3<Real>>() / total;
            let mut covariance = Matrix3::zeros();
            for (&n, offset) in fragment.nodes.iter().zip(fragment.offsets()) {
                covariance += mass[3 * n as usize] * offset * (at(n) - centre).transpose();
            }
            let to_rest = nearest_rotation(&covariance).transpose();
            let mut net = nalgebra::Vector3::zeros();
            for (point, impulse) in &impact.contacts {
                let p = centre + to_rest * point.coords;
                let nearest = fragment
                    .nodes
                    .iter()
                    .copied()
                    .min_by(|&a, &b| (at(a) - p).norm_squared().total_cmp(&(at(b) - p).norm_squared()))
                    .expect("a fragment has nodes");
                let force = to_rest * impulse;
                let k = 3 * nearest as usize;
                (0..3).for_each(|a| load[k + a] += force[a]);
                net += impulse;
            }
            let bodies: Vec<Vec<u32>> = pieces
                .iter()
                .filter(|p| p.nodes.iter().any(|&n| (0..3).any(|a| load[3 * n as usize + a] != 0.0)))
                .map(|p| p.nodes.clone())
                .collect();
            let velocity_change = net.norm() / fragment.mass;
            let approach_energy = 0.5 * fragment.mass * impact.approach_speed.powi(2);
            loads.push(ImpactLoad { load, bodies, approach_energy, velocity_change });
        }
        loads
    }

    /// The elastic energy of one piece: the body's with every other node at its rest position
    /// and every other frame unrotated (an element at rest stores none, and each element lies
    /// in one piece); the piece's frames keep the step's rotations.
    fn strain_energy(
        &mut self,
        body: &dyn Discretization,
        piece: &Piece,
        x: &[Real],
        rotations: &[Matrix3<Real>],
    ) -> Real {
        self.alone.clear();
        self.alone.extend_from_slice(body.rest_dofs());
        for &n in &piece.nodes {
            let k = 3 * n as usize;
            self.alone[k..k + 3].copy_from_slice(&x[k..k + 3]);
        }
        self.alone_rotations.clear();
        self.alone_rotations.resize(body.num_frames(), Matrix3::identity());
        for &e in &piece.elements {
            self.alone_rotations[e as usize] = rotations[e as usize];
        }
        body.elastic_energy(&self.alone_rotations, &self.alone)
    }
}

/// The rotation nearest `a` (the polar factor of its singular value decomposition, a reflection
/// turned into a rotation by flipping the least singular direction).
fn nearest_rotation(a: &Matrix3<Real>) -> Matrix3<Real> {
    let svd = a.svd(true, true);
    let (u, v_t) = (svd.u.expect("asked for u"), svd.v_t.expect("asked for vᵀ"));
    let mut flip = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        // nalgebra sorts the singular values in descending order: the last is the least.
        flip[(2, 2)] = -1.0;
    }
    u * flip * v_t
}
