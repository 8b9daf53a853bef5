//! Contact: embedded surface points against planes, static triangle meshes and the triangles of
//! the body's own embedded surface (between pieces and within one), with regularized Coulomb
//! friction. Equations and what is guaranteed: docs/math/contact.md.
//!
//! Every contact is one *row*, a combination of at most four surface points' embedding rows
//! ([`Row`]): a point alone against a collider; a point minus the barycentric combination of a
//! triangle's vertices (vertex–triangle); the closest point of one surface edge minus that of
//! another (edge–edge). With the row's weights `w` over nodes, a normal `n` and a gap `d`, a
//! contact contributes
//!
//! ```text
//! force    w ⊗ f,             f = −k min(d, 0) n
//! matrix   (w wᵀ) ⊗ P,        P = (h² k + h c) n nᵀ + h c_t (I − n nᵀ)
//! energy   ½ k min(d, 0)²
//! ```
//!
//! and one set of loops below turns that into the force, the assembled matrix, the matrix-free
//! action, the preconditioner's diagonal blocks and the energy, for every kind alike.

use crate::constraints::{Constraints, MeshCollider};
use cleave_core::{AssemblyPattern, Embedding, Matrix3, Point3, Real, Vector3};
use cleave_geometry::{closest_parameters_of_lines, closest_point_on_triangle};
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::math::Vector as ParryVector;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, BvhLeafUpdateStatus, BvhWorkspace};
use rayon::prelude::*;

/// Tangential slip speed below which friction is a viscous stick, `c_t = μ λ (2/ε − |v_t|/ε²)`
/// (the IPC mollifier), above which it is Coulomb's `μ λ / |v_t|` [m/s].
pub const FRICTION_SLIP_SPEED: Real = 1e-3;

/// What a contact pushes against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactKind {
    /// A plane collider.
    Plane,
    /// A static triangle mesh collider.
    Mesh,
    /// A triangle of the body's own embedded surface (another piece, or the same piece).
    Surface,
    /// An edge of the body's surface against an edge of another piece.
    Edge,
}

/// The surface points of a contact row and their weights: `Σ weights[k] · point(points[k])`
/// over the first `len` entries is the row's position (and velocity) difference.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Row {
    pub points: [u32; 4],
    pub weights: [Real; 4],
    pub len: u8,
}

impl Row {
    /// One point against a collider.
    fn point(i: u32) -> Self {
        Row { points: [i, 0, 0, 0], weights: [1.0, 0.0, 0.0, 0.0], len: 1 }
    }

    /// Point `i` minus the point of triangle `tri` at barycentric `beta`.
    fn vertex_triangle(i: u32, tri: [u32; 3], beta: [Real; 3]) -> Self {
        Row { points: [i, tri[0], tri[1], tri[2]], weights: [1.0, -beta[0], -beta[1], -beta[2]], len: 4 }
    }

    /// The point at `s` of edge `a` minus the point at `t` of edge `b`.
    fn edge_edge(a: [u32; 2], s: Real, b: [u32; 2], t: Real) -> Self {
        Row { points: [a[0], a[1], b[0], b[1]], weights: [1.0 - s, s, t - 1.0, -t], len: 4 }
    }

    pub(crate) fn entries(&self) -> impl Iterator<Item = (u32, Real)> + '_ {
        self.points.iter().copied().zip(self.weights.iter().copied()).take(self.len as usize)
    }
}

/// One active contact of a step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Contact {
    /// The surface points of the row.
    pub row: Row,
    /// `P` of the module docs.
    pub matrix: Matrix3<Real>,
    /// `f` of the module docs.
    pub force: Vector3<Real>,
    /// Gap at the start of the step (negative: penetrating) [m].
    pub depth: Real,
    /// Stiffness, for the energy.
    pub stiffness: Real,
    /// Normal damping.
    pub damping: Real,
    /// Unit normal, towards the point's allowed side.
    pub normal: Vector3<Real>,
    /// Index of the lagged normal force of this point and this collider.
    pub slot: u32,
    /// `d(x) = n · row(x) + offset` (for a plane `−n·p₀`, a mesh `−n·c`, the surface `−thickness`):
    /// the gap of this pair at any state, for the energy after the step.
    pub offset: Real,
    pub kind: ContactKind,
}

/// A surface pair within the reach that the start-of-step velocities did not predict to close:
/// what [`make_contact`] needs to activate it later.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NearPair {
    row: Row,
    which: (ContactKind, u32, Real),
    normal: Vector3<Real>,
    gap: (Real, Real, Real),
    params: (Real, Real, Real),
    /// Penetration the solution may predict before the pair joins: half the reach, so that
    /// pairs closing by a little do not cost a second solve (the next step's prediction sees
    /// them).
    slack: Real,
}

/// Counts and depth of the active contacts of a step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ContactStats {
    /// Active contacts against planes.
    pub planes: usize,
    /// Active contacts against mesh colliders.
    pub meshes: usize,
    /// Active contacts between surface points and surface triangles (between or within pieces).
    pub surface: usize,
    /// Active contacts between surface edges of different pieces.
    pub edges: usize,
    /// Largest penetration `max(−d)` over active contacts (0 when none penetrates) [m].
    pub max_penetration: Real,
    /// Seconds spent finding contacts.
    pub seconds: Real,
}

/// Where on a surface a triangle's nearest point lies ([`ContactSet::feature`]).
enum Feature {
    Face,
    /// A surface edge (index into `ContactSet::edges`).
    Edge(u32),
    /// A surface point.
    Corner(u32),
}

/// Per contact, its (node, weight) entries with one entry per node: offsets and entries (CSR).
type MergedEntries = (Vec<usize>, Vec<(u32, Real)>);

/// Per-epoch contact structures and per-step scratch.
#[derive(Default)]
pub(crate) struct ContactSet {
    pub contacts: Vec<Contact>,
    positions: Vec<Point3<Real>>,
    velocities: Vec<Vector3<Real>>,
    vertex_normals: Vec<Vector3<Real>>,
    triangle_normals: Vec<Vector3<Real>>,
    /// This step's `(b − a) × (c − a)` of every surface triangle.
    triangle_area_normals: Vec<Vector3<Real>>,
    /// One-ring of every surface point (CSR), itself included: pairs excluded by adjacency.
    ring_offsets: Vec<usize>,
    ring: Vec<u32>,
    /// Triangles around every surface point (CSR): the corner pseudonormals.
    vertex_triangle_offsets: Vec<usize>,
    vertex_triangles: Vec<u32>,
    /// Rest position of every surface point, and the connected component of the surface it
    /// belongs to (triangles sharing vertices).
    rest: Vec<Point3<Real>>,
    component: Vec<u32>,
    /// Points per component.
    component_points: Vec<u32>,
    /// This step's largest difference of two corners' velocities in each triangle.
    triangle_spread: Vec<Real>,
    /// This step's motion of each component, what the search is bounded by.
    motion: PieceMotion,
    /// Per point its position when its piece's whole-surface tree was last refit, and per
    /// piece the largest move of a point since (its tree's boxes loosened by it hold the
    /// triangles); which trees this step refits, and the per-range scratch.
    refit_positions: Vec<Point3<Real>>,
    staleness: Vec<Real>,
    refit_now: Vec<bool>,
    staleness_ranges: Vec<Real>,
    /// Per piece this step, `reach + h(|w_b| + s_b + τ_b)` (rounded up): with `h|u|` added, at
    /// least any point's search radius for the piece.
    loose_reach: Vec<Real>,
    /// Per piece this step (CSR), the other pieces near enough that one of its points or
    /// feature edges may reach them: what each point and edge searches.
    piece_candidate_offsets: Vec<usize>,
    piece_candidates: Vec<u32>,
    /// Bound the search by the mean velocities alone (ω = 0 for every piece): the bounds before
    /// the rigid fit, which find the same pairs (a test compares the two).
    ignore_turning: bool,
    /// Search every other piece from every point and edge (no pair filter): what the filter
    /// keeps, it must find the same pairs with (a test compares the two).
    search_every_piece: bool,
    /// Per surface component: its triangles, and those on a cut (indices into the surface's
    /// triangles), with a bounding volume hierarchy over each list (built at the first step of
    /// an epoch, refit every step).
    component_triangles: Vec<Vec<u32>>,
    component_cut_triangles: Vec<Vec<u32>>,
    bvh_all: Vec<Bvh>,
    bvh_cut: Vec<Bvh>,
    /// Per surface component: its triangle count and a hash of its triangles' rest corners in
    /// list order. A component of the next epoch with the same fingerprint is the same surface
    /// (a piece the cut did not touch) and takes this epoch's tree instead of building one.
    component_fingerprint: Vec<(usize, u64)>,
    /// Trees taken from the previous epoch for the components that match one of its own
    /// ([`ContactSet::reuse_trees`]), until the first detection refits them.
    reused_trees: Vec<Option<Bvh>>,
    /// This step's root box of every `bvh_all` tree: a query misses a piece
    /// whose root it misses, without setting up a traversal (most pieces are far from most
    /// points).
    roots_all: Vec<Aabb>,
    refit: RefitScratch,
    per_point: Vec<Option<Contact>>,
    /// Per surface point, the pair it found this step but did not activate (not predicted to
    /// close): [`ContactSet::activate_driven`] activates it when the step's solution closes it.
    near: Vec<Option<NearPair>>,
    /// Surface edges (point pairs), the triangles on either side, and the *feature* edges among
    /// them (where the faces meet at more than [`FEATURE_DIHEDRAL_COS`] at rest, or fewer or
    /// more than two faces meet): edge–edge contact searches from feature edges only.
    edges: Vec<[u32; 2]>,
    edge_faces: Vec<[u32; 2]>,
    /// Per triangle, the edge from its vertex `k` to vertex `k + 1` (for the edge pseudonormals).
    triangle_edges: Vec<[u32; 3]>,
    feature_edges: Vec<u32>,
    /// Per surface component its feature edges (indices into `edges`), with a bounding volume
    /// hierarchy over each list (built at the first step of an epoch, refit every step).
    component_feature_edges: Vec<Vec<u32>>,
    bvh_edges: Vec<Bvh>,
    per_edge: Vec<Option<Contact>>,
    /// Normal force of the last step per (collider, point): planes, then meshes, then the
    /// surface; what friction is proportional to.
    lagged: Vec<Real>,
    /// [`add_matrix`]'s scratch: per contact its merged (node, weight) entries (CSR).
    matrix_entries: std::sync::Mutex<MergedEntries>,
}

impl std::fmt::Debug for ContactSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ContactSet").field("contacts", &self.contacts.len()).finish()
    }
}

/// A rigid velocity field fit to a piece's points, `w + ω × (x − center)` with `w` its mean
/// velocity, and the largest deviation of a point's velocity from it.
#[derive(Clone, Copy, Debug)]
struct RigidMotion {
    center: Point3<Real>,
    angular: Vector3<Real>,
    deviation: Real,
}

/// The motion of every piece in a step, each measured over its points in parallel ranges whose
/// partial results are combined in range order (the same numbers whatever the threads do).
#[derive(Debug, Default)]
struct PieceMotion {
    /// Mean velocity of each piece's points.
    velocity: Vec<Vector3<Real>>,
    /// Largest speed of a piece's point relative to its mean velocity.
    spread: Vec<Real>,
    /// Largest difference of two corners' velocities in one of a piece's triangles (τ_b).
    triangle_spread: Vec<Real>,
    /// Rigid motion fit to each piece's points.
    rigid: Vec<RigidMotion>,
    /// Per point, how far its velocity deviates from its piece's rigid motion.
    point_deviation: Vec<Real>,
    /// Per range and piece partial results, and their totals per piece (no allocation after
    /// the first step).
    sums: Vec<(Vector3<Real>, Vector3<Real>)>,
    moments: Vec<(Real, Matrix3<Real>, Vector3<Real>)>,
    maxima: Vec<Real>,
    sum_totals: Vec<(Vector3<Real>, Vector3<Real>)>,
    moment_totals: Vec<(Real, Matrix3<Real>, Vector3<Real>)>,
}

/// Ranges the per-piece measures split their points (or triangles) into.
const MOTION_RANGES: usize = 16;

/// Runs `fold(row, range)` for [`MOTION_RANGES`] consecutive ranges of `0..items` in parallel,
/// each into its own `pieces`-long row of `scratch` (set to `zero` first).
fn fold_ranges<A: Copy + Send>(
    scratch: &mut Vec<A>,
    pieces: usize,
    items: usize,
    zero: A,
    fold: impl Fn(&mut [A], std::ops::Range<usize>) + Sync,
) {
    let length = items.div_ceil(MOTION_RANGES).max(1);
    scratch.clear();
    scratch.resize(MOTION_RANGES * pieces.max(1), zero);
    scratch.par_chunks_mut(pieces.max(1)).enumerate().for_each(|(k, row)| {
        fold(row, (k * length).min(items)..((k + 1) * length).min(items));
    });
}

/// Combines the rows [`fold_ranges`] left in `scratch` into `out`, one entry per piece set to
/// `zero` first, in range order.
fn combine_rows<A, B: Clone>(scratch: &[A], pieces: usize, out: &mut Vec<B>, zero: B, combine: impl Fn(&mut B, &A)) {
    out.clear();
    out.resize(pieces, zero);
    for row in scratch.chunks(pieces.max(1)) {
        for (total, part) in out.iter_mut().zip(row) {
            combine(total, part);
        }
    }
}

impl PieceMotion {
    /// Measures the pieces' motions: mean velocities, spreads about them, the least-squares
    /// angular velocity of each about its mean position (`J ω = Σ r × (v − w)`,
    /// `J = Σ |r|² I − r rᵀ`; none where `J` is singular or the piece turns more than half a
    /// radian in a step `h`, or for `h = 0`), each point's deviation from its piece's rigid
    /// motion and each piece's largest, and the largest triangle spread. Any `ω` gives valid
    /// bounds with its own deviations; the fit makes them small.
    fn measure(
        &mut self,
        h: Real,
        (positions, velocities): (&[Point3<Real>], &[Vector3<Real>]),
        (component, points): (&[u32], &[u32]),
        (triangles, triangle_spread): (&[[u32; 3]], &[Real]),
    ) {
        let pieces = points.len();
        let n = positions.len();
        // Mean positions and velocities.
        let zero = (Vector3::zeros(), Vector3::zeros());
        fold_ranges(&mut self.sums, pieces, n, zero, |row, range| {
            for i in range {
                let sum = &mut row[component[i] as usize];
                sum.0 += positions[i].coords;
                sum.1 += velocities[i];
            }
        });
        combine_rows(&self.sums, pieces, &mut self.sum_totals, zero, |total, part| {
            total.0 += part.0;
            total.1 += part.1;
        });
        self.rigid.clear();
        self.velocity.clear();
        for (total, &count) in self.sum_totals.iter().zip(points) {
            let count = count.max(1) as Real;
            let center = Point3::from(total.0 / count);
            self.rigid.push(RigidMotion { center, angular: Vector3::zeros(), deviation: 0.0 });
            self.velocity.push(total.1 / count);
        }
        // Spreads about the mean velocities, and the fit's moments.
        let (mean, rigid) = (&self.velocity, &self.rigid);
        let zero = (0.0, Matrix3::zeros(), Vector3::zeros());
        fold_ranges(&mut self.moments, pieces, n, zero, |row, range| {
            for i in range {
                let c = component[i] as usize;
                let (r, relative) = (positions[i] - rigid[c].center, velocities[i] - mean[c]);
                let moment = &mut row[c];
                moment.0 = moment.0.max(relative.norm());
                moment.1 += Matrix3::identity() * r.norm_squared() - r * r.transpose();
                moment.2 += r.cross(&relative);
            }
        });
        combine_rows(&self.moments, pieces, &mut self.moment_totals, zero, |total, part| {
            total.0 = total.0.max(part.0);
            total.1 += part.1;
            total.2 += part.2;
        });
        self.spread.clear();
        self.spread.extend(self.moment_totals.iter().map(|total| total.0));
        for (rigid, (_, j, l)) in self.rigid.iter_mut().zip(&self.moment_totals) {
            rigid.angular = j
                .try_inverse()
                .map(|inverse| inverse * l)
                .filter(|w| h > 0.0 && w.iter().all(|x| x.is_finite()) && h * w.norm() <= 0.5)
                .unwrap_or_else(Vector3::zeros);
        }
        // Each point's deviation from its piece's rigid motion (in the ranges of `fold_ranges`,
        // written per point as well), and each piece's largest.
        self.point_deviation.resize(n, 0.0);
        let (mean, rigid) = (&self.velocity, &self.rigid);
        let length = n.div_ceil(MOTION_RANGES).max(1);
        self.maxima.clear();
        self.maxima.resize(MOTION_RANGES * pieces.max(1), 0.0);
        self.point_deviation
            .par_chunks_mut(length)
            .zip(self.maxima.par_chunks_mut(pieces.max(1)))
            .enumerate()
            .for_each(|(k, (deviations, row))| {
                for (offset, deviation) in deviations.iter_mut().enumerate() {
                    let i = k * length + offset;
                    let c = component[i] as usize;
                    let field = mean[c] + rigid[c].angular.cross(&(positions[i] - rigid[c].center));
                    *deviation = (velocities[i] - field).norm();
                    row[c] = row[c].max(*deviation);
                }
            });
        for row in self.maxima.chunks(pieces.max(1)) {
            for (rigid, &deviation) in self.rigid.iter_mut().zip(row) {
                rigid.deviation = rigid.deviation.max(deviation);
            }
        }
        // The largest triangle spread of each piece.
        fold_ranges(&mut self.maxima, pieces, triangles.len(), 0.0, |row, range| {
            for t in range {
                let c = component[triangles[t][0] as usize] as usize;
                row[c] = row[c].max(triangle_spread[t]);
            }
        });
        combine_rows(&self.maxima, pieces, &mut self.triangle_spread, 0.0, |total, &part| *total = total.max(part));
    }
}

impl RigidMotion {
    /// `1 − h|ω|`, at least a half ([`PieceMotion::measure`] keeps no faster turn).
    fn shrink(&self, h: Real) -> Real {
        1.0 - h * self.angular.norm()
    }
}

/// A tree over `leaves` (leaf `k` is the `k`-th box).
fn build_tree(leaves: impl Iterator<Item = Aabb>) -> Bvh {
    let leaves: Vec<Aabb> = leaves.collect();
    Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves)
}

/// Sets every leaf's box of `bvh` (leaf `k` the `k`-th of `leaves`, as many as it has) and
/// refits the inner boxes, in place on one thread.
fn refit_in_place(bvh: &mut Bvh, leaves: impl Iterator<Item = Aabb>) {
    for (k, aabb) in leaves.enumerate() {
        bvh.insert_or_update_partially(aabb, k as u32, 0.0);
    }
    bvh.refit_without_opt();
}

/// Squared distance between two boxes (zero where they overlap).
fn squared_distance_between_boxes(a: &Aabb, b: &Aabb) -> Real {
    (b.mins - a.maxs).max(a.mins - b.maxs).max(ParryVector::ZERO).length_squared()
}

/// Squared distance from `q` to the box from `lo` to `hi` (zero inside it).
fn squared_distance_to_box(q: ParryVector, lo: ParryVector, hi: ParryVector) -> Real {
    (lo - q).max(q - hi).max(ParryVector::ZERO).length_squared()
}

fn to_parry(p: &Point3<Real>) -> ParryVector {
    ParryVector::new(p.x, p.y, p.z)
}

/// The contact normal of point `q` against the triangle point `c` closest to it (at
/// `distance`), the triangle having unit normal `n`: `n` when `q` projects into the triangle
/// or lies within `lateral` of it sideways (a vertex on a vertex of a coinciding face, where
/// the deformed faces around it leave gaps between their projections), none when farther
/// beyond its edges (it is the neighbouring triangle's; where no triangle's, an edge meets an
/// edge, which vertex–triangle contact does not see: docs/math/contact.md §5). The force pair
/// then acts on one line up to that sideways offset, which bounds its torque.
fn contact_normal(
    q: &Point3<Real>,
    c: &Point3<Real>,
    n: &Vector3<Real>,
    distance: Real,
    lateral: Real,
) -> Option<Vector3<Real>> {
    let offset = q - c;
    (distance == 0.0 || (offset - n * n.dot(&offset)).norm() <= lateral.max(1e-9 * distance)).then_some(*n)
}

/// A point's pair with one triangle: gap along `normal`, distance to the triangle, and the
/// barycentrics of the triangle point it meets.
struct Candidate {
    gap: Real,
    distance: Real,
    triangle: usize,
    beta: [Real; 3],
    normal: Vector3<Real>,
}

/// Edges whose faces meet at an angle with cosine below this at rest (about 26°) are feature
/// edges, searched for edge–edge contact: where faces meet flatter, the vertex–triangle
/// contacts of the faces around them keep surfaces apart.
const FEATURE_DIHEDRAL_COS: Real = 0.9;

/// Sideways tolerance of [`contact_normal`], as a fraction of the reach.
const LATERAL_FRACTION: Real = 0.05;

/// `c_t / (μ λ)`: the lagged tangential damping per unit friction force.
fn slip_coefficient(speed: Real) -> Real {
    let eps = FRICTION_SLIP_SPEED;
    if speed < eps { 2.0 / eps - speed / (eps * eps) } else { 1.0 / speed }
}

/// Builds the contact of a point at gap `d` along unit normal `n` with relative velocity `u`.
/// Active when `d` or the prediction `d + h n·(u + h g)` is below `touching` (0 for colliders,
/// rounding level for the body's own surface; gravity only for points not moving away, see
/// `Integrator::add_penalty_forces`).
#[allow(clippy::too_many_arguments)]
fn make_contact(
    row: Row,
    (kind, slot, lagged_force): (ContactKind, u32, Real),
    n: Vector3<Real>,
    (d, offset, touching): (Real, Real, Real),
    u: &Vector3<Real>,
    gravity_along: Real,
    h: Real,
    (stiffness, damping, friction): (Real, Real, Real),
) -> Option<Contact> {
    let approach = n.dot(u);
    let pulled = approach + h * gravity_along;
    let predicted = d + h * if approach <= 0.0 { pulled } else { approach };
    if d.min(predicted) >= touching {
        return None;
    }
    // The normal force the last step's solution carried (a resting point sits at d ≈ 0, held
    // by the implicit term, not by its penetration), at least the penetration's.
    let normal_force = lagged_force.max(stiffness * (-d).max(0.0));
    let tangential = u - n * approach;
    let c_t = friction * normal_force * slip_coefficient(tangential.norm());
    let nn = n * n.transpose();
    let matrix = nn * (h * h * stiffness + h * damping) + (Matrix3::identity() - nn) * (h * c_t);
    let force = n * (-stiffness * d.min(0.0));
    Some(Contact { row, matrix, force, depth: d, stiffness, damping, normal: n, slot, offset, kind })
}

impl ContactSet {
    /// Per-epoch structures: the one-ring, rest position and surface component of every point.
    pub fn new(constraints: &Constraints, rest_dofs: &[Real]) -> Self {
        let mut set = ContactSet::default();
        if let (Some(points), Some(surface)) = (&constraints.contact_points, &constraints.surface_contact) {
            set.rest = (0..points.len()).map(|i| points.point(rest_dofs, i)).collect();
            let mut sets = cleave_geometry::UnionFind::new(points.len());
            for t in &surface.triangles {
                sets.union(t[0] as usize, t[1] as usize);
                sets.union(t[0] as usize, t[2] as usize);
            }
            // The parts of one piece's surface are one component: a sheet a crack left inside a
            // piece lies inside the rest of its surface, which is not a contact (`SurfaceContact::piece`).
            // (The integrator refuses a piece list of another length than the triangles'.)
            if surface.piece.len() == surface.triangles.len() {
                let pieces = surface.piece.iter().max().map_or(0, |&p| p as usize + 1);
                let mut first_of_piece = vec![u32::MAX; pieces];
                for (t, &piece) in surface.triangles.iter().zip(&surface.piece) {
                    let first = &mut first_of_piece[piece as usize];
                    if *first == u32::MAX {
                        *first = t[0];
                    }
                    sets.union(*first as usize, t[0] as usize);
                }
            }
            let roots: Vec<u32> = (0..points.len()).map(|i| sets.find(i) as u32).collect();
            let mut compact = vec![u32::MAX; points.len()];
            let mut count = 0;
            set.component = roots
                .iter()
                .map(|&r| {
                    if compact[r as usize] == u32::MAX {
                        compact[r as usize] = count;
                        count += 1;
                    }
                    compact[r as usize]
                })
                .collect();
            set.component_points = vec![0; count as usize];
            for &c in &set.component {
                set.component_points[c as usize] += 1;
            }
            set.component_triangles = vec![Vec::new(); count as usize];
            set.component_cut_triangles = vec![Vec::new(); count as usize];
            for (t, tri) in surface.triangles.iter().enumerate() {
                let c = set.component[tri[0] as usize] as usize;
                set.component_triangles[c].push(t as u32);
                if surface.on_cut.get(t).copied().unwrap_or(false) {
                    set.component_cut_triangles[c].push(t as u32);
                }
            }
            set.component_fingerprint = set
                .component_triangles
                .par_iter()
                .map(|list| {
                    let hash = list.iter().flat_map(|&t| surface.triangles[t as usize]).fold(0u64, |hash, k| {
                        set.rest[k as usize]
                            .iter()
                            .fold(hash, |h, x| (h.rotate_left(5) ^ x.to_bits()).wrapping_mul(0x517c_c1b7_2722_0a95))
                    });
                    (list.len(), hash)
                })
                .collect();
            let both: Vec<bool> = (0..set.component_cut_triangles.len())
                .into_par_iter()
                .map(|c| set.holds_both_faces_of_a_cut(c, &surface.triangles))
                .collect();
            for (list, both) in set.component_cut_triangles.iter_mut().zip(both) {
                if !both {
                    list.clear();
                }
            }
            let mut counts = vec![0usize; points.len() + 1];
            for t in &surface.triangles {
                for &k in t {
                    counts[k as usize + 1] += 1;
                }
            }
            for k in 0..points.len() {
                counts[k + 1] += counts[k];
            }
            let mut fill = counts.clone();
            set.vertex_triangles = vec![0; counts[points.len()]];
            for (u, t) in surface.triangles.iter().enumerate() {
                for &k in t {
                    set.vertex_triangles[fill[k as usize]] = u as u32;
                    fill[k as usize] += 1;
                }
            }
            set.vertex_triangle_offsets = counts;
            // The one-ring from the triangles around each point, in parallel over blocks of
            // points (one list per block, not per point), then concatenated.
            let (offsets, around) = (&set.vertex_triangle_offsets, &set.vertex_triangles);
            let blocks: Vec<(Vec<u32>, Vec<usize>)> = (0..points.len())
                .collect::<Vec<_>>()
                .par_chunks(1024)
                .map(|block| {
                    let (mut rings, mut lengths) = (Vec::new(), Vec::with_capacity(block.len()));
                    let mut ring: Vec<u32> = Vec::with_capacity(32);
                    for &i in block {
                        ring.clear();
                        ring.push(i as u32);
                        ring.extend(
                            around[offsets[i]..offsets[i + 1]].iter().flat_map(|&t| surface.triangles[t as usize]),
                        );
                        ring.sort_unstable();
                        ring.dedup();
                        rings.extend_from_slice(&ring);
                        lengths.push(ring.len());
                    }
                    (rings, lengths)
                })
                .collect();
            set.ring_offsets.push(0);
            for (rings, lengths) in blocks {
                set.ring.extend_from_slice(&rings);
                for length in lengths {
                    let last = *set.ring_offsets.last().unwrap_or(&0);
                    set.ring_offsets.push(last + length);
                }
            }
            set.find_edges(&surface.triangles);
        }
        set
    }

    /// Takes the triangle trees of `previous` (the last epoch's set) for the components whose
    /// fingerprint matches one of its own: a cut leaves most pieces as they were, and building
    /// their trees again cost most of a cut step's contact search. A matching tree is correct
    /// whatever the match (the first detection refits every box from the new surface; a tree
    /// over as many leaves is valid for any of them), and as good as a new one when the
    /// triangles are the same.
    pub fn reuse_trees(&mut self, previous: ContactSet) {
        if previous.bvh_all.len() != previous.component_fingerprint.len() {
            return;
        }
        let mut trees: std::collections::HashMap<(usize, u64), Bvh> =
            previous.component_fingerprint.into_iter().zip(previous.bvh_all).collect();
        self.reused_trees = self.component_fingerprint.iter().map(|key| trees.remove(key)).collect();
    }

    /// Whether component `c` holds both faces of some cut: two of its cut triangles coincide in
    /// the rest shape with opposite normals (an unfinished cut, or a flap still attached). Only
    /// then can a point of the component meet the component's own cut faces; a component
    /// whose cuts went through has the other face in another component, and searching its
    /// own cut faces only visits coplanar neighbours (55 % of all candidates on bunny_slice).
    fn holds_both_faces_of_a_cut(&self, c: usize, triangles: &[[u32; 3]]) -> bool {
        let list = &self.component_cut_triangles[c];
        if list.len() < 2 {
            return false;
        }
        let corners = |t: u32| triangles[t as usize].map(|k| self.rest[k as usize]);
        let size = |[a, b, c]: [Point3<Real>; 3]| (b - a).norm().max((c - a).norm()).max((c - b).norm());
        let leaves: Vec<Aabb> = list
            .iter()
            .map(|&t| {
                let [a, b, c] = corners(t);
                let margin = Vector3::repeat(1e-9 * size([a, b, c]));
                Aabb::new(to_parry(&(a.inf(&b).inf(&c) - margin)), to_parry(&(a.sup(&b).sup(&c) + margin)))
            })
            .collect();
        let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves);
        list.iter().any(|&t| {
            let [a, b, c] = corners(t);
            let normal = (b - a).cross(&(c - a));
            let centroid = Point3::from((a.coords + b.coords + c.coords) / 3.0);
            let tolerance = 1e-9 * size([a, b, c]);
            let query = Aabb::new(
                to_parry(&(centroid - Vector3::repeat(tolerance))),
                to_parry(&(centroid + Vector3::repeat(tolerance))),
            );
            bvh.intersect_aabb(&query).any(|leaf| {
                let u = list[leaf as usize];
                let other = corners(u);
                let other_normal = (other[1] - other[0]).cross(&(other[2] - other[0]));
                u != t
                    && normal.dot(&other_normal) < 0.0
                    && (closest_point_on_triangle(&centroid, &other).0 - centroid).norm() <= tolerance
            })
        })
    }

    /// The other pieces this step's points and feature edges of `piece` search.
    fn candidate_pieces(&self, piece: usize) -> impl Iterator<Item = usize> + '_ {
        let range = self.piece_candidate_offsets[piece]..self.piece_candidate_offsets[piece + 1];
        self.piece_candidates[range].iter().map(|&b| b as usize)
    }

    /// The surface's edges, their faces, each triangle's edges and the feature edges.
    fn find_edges(&mut self, triangles: &[[u32; 3]]) {
        // Every side of every triangle as (lower point, higher point, triangle, side), sorted:
        // the sides of one edge are consecutive.
        let mut sides: Vec<(u32, u32, u32, u8)> = triangles
            .par_iter()
            .enumerate()
            .flat_map_iter(|(t, tri)| {
                (0..3).map(move |k| (tri[k].min(tri[(k + 1) % 3]), tri[k].max(tri[(k + 1) % 3]), t as u32, k as u8))
            })
            .collect();
        sides.par_sort_unstable();
        let mut starts: Vec<usize> = (0..sides.len())
            .filter(|&i| i == 0 || (sides[i - 1].0, sides[i - 1].1) != (sides[i].0, sides[i].1))
            .collect();
        starts.push(sides.len());
        let rest_normal = |t: u32| {
            let [a, b, c] = triangles[t as usize].map(|k| self.rest[k as usize]);
            (b - a).cross(&(c - a)).try_normalize(0.0)
        };
        let feature: Vec<bool> = starts
            .par_windows(2)
            .map(|w| {
                let group = &sides[w[0]..w[1]];
                group.len() != 2
                    || match (rest_normal(group[0].2), rest_normal(group[1].2)) {
                        (Some(n0), Some(n1)) => n0.dot(&n1) < FEATURE_DIHEDRAL_COS,
                        _ => false,
                    }
            })
            .collect();
        self.triangle_edges = vec![[0; 3]; triangles.len()];
        for (w, feature) in starts.windows(2).zip(feature) {
            let group = &sides[w[0]..w[1]];
            let e = self.edges.len() as u32;
            for &(_, _, t, k) in group {
                self.triangle_edges[t as usize][k as usize] = e;
            }
            if feature {
                self.feature_edges.push(e);
            }
            self.edges.push([group[0].0, group[0].1]);
            self.edge_faces.push([group[0].2, group.get(1).map_or(group[0].2, |g| g.2)]);
        }
        self.component_feature_edges = vec![Vec::new(); self.component_points.len()];
        for &e in &self.feature_edges {
            self.component_feature_edges[self.component[self.edges[e as usize][0] as usize] as usize].push(e);
        }
    }

    /// Whether point `i` lies behind triangle `tri` (at barycentric `beta`) in the rest shape.
    /// Nothing overlaps at rest, so such a pair of one surface is not a contact but a point
    /// beside an obtuse convex edge seen from the face across it; the two faces of a cut
    /// coincide at rest (gap 0) and stay candidates.
    fn behind_at_rest(&self, i: usize, tri: &[u32; 3], beta: &[Real; 3]) -> bool {
        let [a, b, c] = tri.map(|k| self.rest[k as usize]);
        let normal = (b - a).cross(&(c - a));
        let scale = normal.norm();
        if scale == 0.0 {
            return false;
        }
        let on = Point3::from(a.coords * beta[0] + b.coords * beta[1] + c.coords * beta[2]);
        normal.dot(&(self.rest[i] - on)) / scale < -1e-9 * (b - a).norm().max((c - a).norm())
    }

    /// The angle-weighted pseudonormal (not normalized) of the feature of triangle `t` that
    /// holds its point at barycentrics `beta`: the triangle's normal inside it, the sum of the
    /// two faces' normals on an edge, the angle-weighted vertex normal at a corner. Its sign
    /// against `q − c`, with `c` the nearest surface point, tells whether `q` lies inside a
    /// closed surface (Bærentzen & Aanæs 2005).
    fn pseudonormal(&self, triangles: &[[u32; 3]], t: usize, beta: &[Real; 3]) -> Vector3<Real> {
        match self.feature(triangles, t, beta) {
            Feature::Face => self.triangle_normals[t],
            Feature::Edge(e) => {
                let [f0, f1] = self.edge_faces[e as usize];
                self.triangle_normals[f0 as usize] + self.triangle_normals[f1 as usize]
            }
            // Weighted by each triangle's angle at the corner (area weights are not exact here);
            // computed only for the rare point whose nearest feature is a corner.
            Feature::Corner(corner) => self.triangles_around(corner).iter().fold(Vector3::zeros(), |sum, &u| {
                let around = &triangles[u as usize];
                let k = (0..3).find(|&k| around[k] == corner).unwrap_or(0);
                let p = around.map(|i| self.positions[i as usize]);
                let (e1, e2) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                sum + self.triangle_normals[u as usize] * e1.cross(&e2).norm().atan2(e1.dot(&e2))
            }),
        }
    }

    /// The feature of triangle `t` that holds its point at barycentrics `beta`: the triangle
    /// itself (no zero weight), the surface edge opposite the one zero weight, or the corner
    /// of the largest weight (two zero weights).
    fn feature(&self, triangles: &[[u32; 3]], t: usize, beta: &[Real; 3]) -> Feature {
        match beta.iter().filter(|&&b| b == 0.0).count() {
            0 => Feature::Face,
            // On the edge from vertex k to k + 1, opposite the zero weight.
            1 => Feature::Edge(self.triangle_edges[t][(0..3).find(|&k| beta[(k + 2) % 3] == 0.0).unwrap_or(0)]),
            _ => Feature::Corner(triangles[t][(0..3).max_by(|&a, &b| beta[a].total_cmp(&beta[b])).unwrap_or(0)]),
        }
    }

    /// The triangles around surface point `corner`.
    fn triangles_around(&self, corner: u32) -> &[u32] {
        &self.vertex_triangles
            [self.vertex_triangle_offsets[corner as usize]..self.vertex_triangle_offsets[corner as usize + 1]]
    }

    /// The triangles at the feature of triangle `t` that holds its point at barycentrics
    /// `beta` ([`Self::feature`]), in index order: `t` inside it, the faces of an edge, every
    /// triangle around a corner.
    fn feature_triangles(&self, triangles: &[[u32; 3]], t: usize, beta: &[Real; 3], out: &mut Vec<u32>) {
        out.clear();
        match self.feature(triangles, t, beta) {
            Feature::Face => {}
            Feature::Edge(e) => out.extend(self.edge_faces[e as usize]),
            Feature::Corner(corner) => out.extend_from_slice(self.triangles_around(corner)),
        }
        // (At an edge of more than two faces `edge_faces` holds two of them: `t` is always one.)
        out.push(t as u32);
        out.sort_unstable();
        out.dedup();
    }

    fn excluded(&self, point: u32, triangle: &[u32; 3]) -> bool {
        let ring = &self.ring[self.ring_offsets[point as usize]..self.ring_offsets[point as usize + 1]];
        // The triangle contains the point or a neighbour of it: a neighbouring triangle's vertex.
        triangle.iter().any(|v| ring.binary_search(v).is_ok())
    }

    /// Finds this step's contacts at `x` with velocities `v`.
    pub fn detect(&mut self, constraints: &Constraints, x: &[Real], v: &[Real], h: Real, gravity: &Vector3<Real>) {
        self.contacts.clear();
        let Some(points) = &constraints.contact_points else { return };
        let n = points.len();
        self.positions.resize(n, Point3::origin());
        self.velocities.resize(n, Vector3::zeros());
        self.positions.par_iter_mut().zip(self.velocities.par_iter_mut()).enumerate().for_each(|(i, (p, u))| {
            *p = points.point(x, i);
            *u = points.point(v, i).coords;
        });
        let colliders = constraints.planes.len() + constraints.meshes.len() + 1;
        if self.lagged.len() != colliders * n + self.feature_edges.len() {
            self.lagged = vec![0.0; colliders * n + self.feature_edges.len()];
        }
        // One slot per point, reused by every collider: no allocation after the first step.
        let mut per_point = std::mem::take(&mut self.per_point);
        per_point.resize(n, None);
        let (positions, velocities, lagged) = (&self.positions, &self.velocities, &self.lagged);
        // Planes in one sequential pass per plane: a dot product per point, and the few points
        // at the plane become contacts (a parallel pass through a slot per point cost more in
        // writing and scanning the slots than the test itself).
        for (k, plane) in constraints.planes.iter().enumerate() {
            let params = (plane.stiffness, plane.damping, plane.friction);
            let g = plane.normal.dot(gravity);
            let offset = -plane.normal.dot(&plane.point.coords);
            for (i, (q, u)) in positions.iter().zip(velocities).enumerate() {
                let d = plane.normal.dot(&q.coords) + offset;
                let slot = k * n + i;
                let which = (ContactKind::Plane, slot as u32, lagged[slot]);
                if let Some(contact) =
                    make_contact(Row::point(i as u32), which, plane.normal, (d, offset, 0.0), u, g, h, params)
                {
                    self.contacts.push(contact);
                }
            }
        }
        for (k, mesh) in constraints.meshes.iter().enumerate() {
            let k = constraints.planes.len() + k;
            per_point.par_iter_mut().enumerate().for_each(|(i, slot_of_point)| {
                *slot_of_point = (|| {
                    let (q, u) = (&positions[i], &velocities[i]);
                    let radius = mesh.reach + h * u.norm();
                    let (c, normal) = mesh.closest(q, radius)?;
                    let d = normal.dot(&(q - c));
                    // Deeper than `reach` behind a triangle is the far side of a thin wall.
                    if d < -mesh.reach {
                        return None;
                    }
                    let params = (mesh.stiffness, mesh.damping, mesh.friction);
                    let slot = k * n + i;
                    let which = (ContactKind::Mesh, slot as u32, lagged[slot]);
                    make_contact(
                        Row::point(i as u32),
                        which,
                        normal,
                        (d, -normal.dot(&c.coords), 0.0),
                        u,
                        normal.dot(gravity),
                        h,
                        params,
                    )
                })();
            });
            self.contacts.extend(per_point.iter().flatten().copied());
        }
        self.per_point = per_point;
        if let Some(surface) = &constraints.surface_contact {
            self.detect_surface(surface, h, gravity, (colliders - 1) * n);
            if surface.edge_contact {
                self.detect_edges(surface, h, colliders * n);
            }
        }
    }

    fn detect_surface(
        &mut self,
        surface: &crate::constraints::SurfaceContact,
        h: Real,
        gravity: &Vector3<Real>,
        first_slot: usize,
    ) {
        let (positions, velocities) = (&self.positions, &self.velocities);
        let triangles = &surface.triangles;
        // Deformed vertex normals (area weighted): a contact needs opposing surfaces, so points
        // of one smooth surface never push on its own nearby triangles.
        self.vertex_normals.clear();
        self.vertex_normals.resize(positions.len(), Vector3::zeros());
        // Each triangle's area normal once (the vertex normals sum them), then its unit normal.
        self.triangle_area_normals.resize(triangles.len(), Vector3::zeros());
        self.triangle_normals.resize(triangles.len(), Vector3::zeros());
        // And the largest difference of its corners' velocities, which bounds how much faster any
        // corner moves than any point of the triangle.
        self.triangle_spread.resize(triangles.len(), 0.0);
        self.triangle_area_normals
            .par_iter_mut()
            .zip(self.triangle_normals.par_iter_mut())
            .zip(self.triangle_spread.par_iter_mut())
            .zip(triangles)
            .for_each(|(((area_normal, normal), spread), triangle)| {
                let [a, b, c] = triangle.map(|i| positions[i as usize]);
                *area_normal = (b - a).cross(&(c - a));
                *normal = area_normal.try_normalize(0.0).unwrap_or_else(Vector3::zeros);
                let [va, vb, vc] = triangle.map(|i| velocities[i as usize]);
                *spread = (va - vb).norm().max((vb - vc).norm()).max((vc - va).norm());
            });
        let (offsets, around, area_normals) =
            (&self.vertex_triangle_offsets, &self.vertex_triangles, &self.triangle_area_normals);
        self.vertex_normals.par_iter_mut().enumerate().for_each(|(i, normal)| {
            *normal =
                around[offsets[i]..offsets[i + 1]].iter().fold(Vector3::zeros(), |s, &t| s + area_normals[t as usize]);
        });
        // Motion is bounded relative to the mean velocity `w_b` of the piece searched:
        // |u_q − u_t| ≤ |u_q − w_b| + |u_t − w_b|, the second in the leaf boxes, the first in
        // the query. So a piece moving as a whole (falling, sliding) does not inflate its boxes
        // by its motion, and a point is searched with only its speed relative to each piece;
        // tighter still relative to its rigid motion (`RigidMotion`).
        self.motion.measure(
            if self.ignore_turning { 0.0 } else { h },
            (positions, velocities),
            (&self.component, &self.component_points),
            (triangles, &self.triangle_spread),
        );
        let motion = &self.motion;
        let component = &self.component;
        // A leaf box of a piece's whole surface is the triangle's own (the nearest-triangle
        // search below bounds its radius by the motion); a leaf box of its cut faces holds the
        // reach, the triangle's motion relative to the piece and the spread of its corners'
        // velocities (the own-cut query is a box).
        let num_whole = self.component_triangles.len();
        let triangle_spread = &self.triangle_spread;
        let leaf = |triangle: u32, tree: usize| -> Aabb {
            let t = &triangles[triangle as usize];
            let mut lo = positions[t[0] as usize];
            let mut hi = lo;
            for &i in t {
                lo = lo.inf(&positions[i as usize]);
                hi = hi.sup(&positions[i as usize]);
            }
            if tree < num_whole {
                return Aabb::new(to_parry(&lo), to_parry(&hi));
            }
            // With the piece's rigid motion `f(x) = w + ω × (x − c)` and a point q of the same
            // piece at distance d from the point p of the triangle it meets, |u − v_p| ≤ |ω| d
            // + |u − f(q)| + max_k |v_k − f(x_k)|, so `consider`'s reach
            // reach + h(|u − v_p| + max_k |v_k − v_p|) is at least d only if
            // d (1 − h|ω|) ≤ reach + h(|u − f(q)| + max_k |v_k − f(x_k)| + τ_t): the leaf box
            // holds all of it but the query's |u − f(q)| (`own_query`), each over 1 − h|ω|.
            let rigid = &motion.rigid[component[t[0] as usize] as usize];
            let deviation = t.iter().map(|&i| motion.point_deviation[i as usize]).fold(0.0, Real::max);
            let margin = Vector3::repeat(
                (surface.reach + h * (deviation + triangle_spread[triangle as usize])) / rigid.shrink(h)
                    * (1.0 + 1e-12),
            );
            Aabb::new(to_parry(&(lo - margin)), to_parry(&(hi + margin)))
        };
        let lists = self.component_triangles.iter().chain(&self.component_cut_triangles);
        if self.bvh_all.is_empty() {
            // Built at the first step of an epoch, one tree per task; a tree taken from the
            // last epoch is refit instead.
            let mut reused = std::mem::take(&mut self.reused_trees);
            reused.resize_with(self.component_triangles.len(), || None);
            let mut all: Vec<Bvh> = reused
                .into_par_iter()
                .map(Some)
                .chain(self.component_cut_triangles.par_iter().map(|_| None))
                .zip(self.component_triangles.par_iter().chain(self.component_cut_triangles.par_iter()))
                .enumerate()
                .map(|(tree, (reused, list))| {
                    let leaves = list.iter().map(|&t| leaf(t, tree));
                    match reused.flatten() {
                        Some(mut bvh) => {
                            refit_in_place(&mut bvh, leaves);
                            bvh
                        }
                        None => build_tree(leaves),
                    }
                })
                .collect();
            self.bvh_cut = all.split_off(self.component_triangles.len());
            self.bvh_all = all;
            self.refit_positions.clear();
            self.refit_positions.extend_from_slice(positions);
            self.staleness.clear();
            self.staleness.resize(num_whole, 0.0);
        } else {
            // A piece's whole-surface tree is refit only once a point moved more than
            // STALE_REACH reaches since its last refit: until then each of its boxes, loosened
            // by `staleness` (the largest such move), holds the triangles it was fit to, and
            // the searches loosen them so (a piece at rest is refit every few dozen steps).
            let refit_positions = &self.refit_positions;
            fold_ranges(&mut self.staleness_ranges, num_whole, positions.len(), 0.0, |row, range| {
                for i in range {
                    let c = component[i] as usize;
                    row[c] = row[c].max((positions[i] - refit_positions[i]).norm());
                }
            });
            combine_rows(&self.staleness_ranges, num_whole, &mut self.staleness, 0.0, |stale, &moved| {
                *stale = stale.max(moved)
            });
            let limit = STALE_REACH * surface.reach;
            self.refit_now.clear();
            self.refit_now.extend(self.staleness.iter().map(|&s| s > limit || s.is_nan()));
            self.refit_now.resize(num_whole + self.bvh_cut.len(), true);
            let refit_now = &self.refit_now;
            // Trees side by side, one task each (a piece's tree is refit sequentially in place:
            // on bunny_slice's 22 trees 1.45 against 2.7 ms/step for each tree in turn spread
            // over the pool); a tree too large to be one task uses parry's parallel update.
            let lists_par = self.component_triangles.par_iter().chain(self.component_cut_triangles.par_iter());
            self.bvh_all.par_iter_mut().chain(self.bvh_cut.par_iter_mut()).zip(lists_par).enumerate().for_each(
                |(tree, (bvh, list))| {
                    if list.len() < PARALLEL_REFIT_LEAVES && refit_now[tree] {
                        refit_in_place(bvh, list.iter().map(|&t| leaf(t, tree)));
                    }
                },
            );
            for (tree, (bvh, list)) in self.bvh_all.iter_mut().chain(self.bvh_cut.iter_mut()).zip(lists).enumerate() {
                if list.len() >= PARALLEL_REFIT_LEAVES && refit_now[tree] {
                    self.refit.refit(bvh, list.len(), |k| leaf(list[k], tree));
                }
            }
            for (stale, &refit) in self.staleness.iter_mut().zip(refit_now) {
                if refit {
                    *stale = 0.0;
                }
            }
            self.refit_positions.par_iter_mut().zip(positions).zip(component).for_each(|((last, p), &c)| {
                if refit_now[c as usize] {
                    *last = *p;
                }
            });
        }
        self.roots_all.clear();
        self.roots_all
            .extend(self.bvh_all.iter().zip(&self.staleness).map(|(bvh, &stale)| bvh.root_aabb().loosened(stale)));
        // Per piece the search radius (below) less the point's own speed term, bounded from
        // above: reach + h(|w_b| + s_b + τ_b).
        self.loose_reach.clear();
        self.loose_reach.extend((0..self.bvh_all.len()).map(|b| {
            (surface.reach
                + h * (self.motion.velocity[b].norm() + self.motion.spread[b] + self.motion.triangle_spread[b]))
                * (1.0 + 1e-9)
        }));
        // Every point of piece a lies in a's root box and moves at most |w_a| + s_a, so a
        // piece b farther from that box than loose_reach[b] + h(|w_a| + s_a) is beyond every
        // point's loose bound below, and beyond every edge query of `detect_edges` (which is
        // within reach + h(|w_a| + s_a + |w_b| + s_b), smaller). Tested once per pair of
        // pieces instead of once per point and piece (22 pieces on bunny_slice).
        self.piece_candidate_offsets.clear();
        self.piece_candidates.clear();
        self.piece_candidate_offsets.push(0);
        for (a, root_a) in self.roots_all.iter().enumerate() {
            let own_speed = h * (self.motion.velocity[a].norm() + self.motion.spread[a]) * (1.0 + 1e-6);
            for (b, root_b) in self.roots_all.iter().enumerate() {
                let bound = self.loose_reach[b] + own_speed + 1e-12 * surface.reach;
                if b != a && (self.search_every_piece || squared_distance_between_boxes(root_a, root_b) < bound * bound)
                {
                    self.piece_candidates.push(b as u32);
                }
            }
            self.piece_candidate_offsets.push(self.piece_candidates.len());
        }

        let mut per_point = std::mem::take(&mut self.per_point);
        let mut near = std::mem::take(&mut self.near);
        // Every slot is written below (an empty one by its tag alone): clearing both lists
        // first wrote 5 MB a step on bunny_slice.
        near.resize(self.positions.len(), None);
        per_point.resize(positions.len(), None);
        let this = &*self;
        let params = (surface.stiffness, surface.damping, surface.friction);
        let lateral = LATERAL_FRACTION * surface.reach;
        per_point.par_iter_mut().zip(near.par_iter_mut()).enumerate().for_each_init(
            Vec::new,
            |at_feature: &mut Vec<u32>, (i, (slot, near))| {
                let q = positions[i];
                let u = velocities[i];
                let vertex_normal = this.vertex_normals[i];
                *slot = None;
                *near = None;
                if vertex_normal == Vector3::zeros() {
                    return;
                }
                let own = this.component[i] as usize;
                // The point's own part of its own piece's cut-face leaf boxes (see `leaf`).
                let own_query = || {
                    let rigid = &this.motion.rigid[own];
                    let deviation = u - this.motion.velocity[own] - rigid.angular.cross(&(q - rigid.center));
                    let motion = Vector3::repeat(h * deviation.norm() / rigid.shrink(h) * (1.0 + 1e-12));
                    Aabb::new(to_parry(&(q - motion)), to_parry(&(q + motion)))
                };
                // Whether a pair is within reach: farther than the reach is no contact yet; deeper
                // than it behind the surface is beyond what the search sees (the boxes hold the
                // reach).
                let within_reach = |candidate: &Candidate| {
                    let tri = triangles[candidate.triangle];
                    let other_velocity = tri
                        .iter()
                        .zip(&candidate.beta)
                        .fold(Vector3::zeros(), |s, (&k, &b)| s + velocities[k as usize] * b);
                    let reach = surface.reach
                        + h * ((u - other_velocity).norm()
                            + tri
                                .iter()
                                .map(|&k| (velocities[k as usize] - other_velocity).norm())
                                .fold(0.0, Real::max));
                    candidate.distance <= reach && candidate.gap >= -surface.reach
                };
                // Per searched surface its pair for this point, within reach; the smallest gap wins.
                let mut best: Option<Candidate> = None;
                let mut keep = |candidate: Candidate| {
                    if best.as_ref().is_none_or(|b| candidate.gap < b.gap) {
                        best = Some(candidate);
                    }
                };
                // The point's own piece only through its cut faces (the two faces of an unfinished
                // cut, a flap): its own smooth surface around the point is never visited. A pair
                // needs opposing faces, no adjacency and to be within reach, and the closest such
                // triangle is taken (so neither what the box search visits beyond the reach nor the
                // order it visits in changes which).
                {
                    let query = own_query();
                    let list = &this.component_cut_triangles[own];
                    let mut nearest: Option<Candidate> = None;
                    for t in this.bvh_cut[own].intersect_aabb(&query).map(|leaf| list[leaf as usize]) {
                        let tri = &triangles[t as usize];
                        if vertex_normal.dot(&this.triangle_normals[t as usize]) >= 0.0 || this.excluded(i as u32, tri)
                        {
                            continue;
                        }
                        let corners = tri.map(|k| positions[k as usize]);
                        let (c, beta) = closest_point_on_triangle(&q, &corners);
                        let distance = (q - c).norm();
                        if contact_normal(&q, &c, &this.triangle_normals[t as usize], distance, lateral).is_none()
                            || this.behind_at_rest(i, tri, &beta)
                        {
                            continue;
                        }
                        let normal = this.triangle_normals[t as usize];
                        let candidate =
                            Candidate { gap: normal.dot(&(q - c)), distance, triangle: t as usize, beta, normal };
                        // Equally near (a point on a vertex or edge of the coinciding face): the
                        // lowest-numbered triangle, whatever order the tree visits them in.
                        let nearer = |b: &Candidate| {
                            distance < b.distance || (distance == b.distance && candidate.triangle < b.triangle)
                        };
                        if nearest.as_ref().is_none_or(nearer) && within_reach(&candidate) {
                            nearest = Some(candidate);
                        }
                    }
                    if let Some(candidate) = nearest {
                        keep(candidate);
                    }
                }
                // Every other piece by its signed distance: the nearest triangle of its closed
                // surface, inside or outside by the pseudonormal of the nearest feature (face, edge
                // or vertex); inside, the normal along q − c. Taking a farther triangle because a nearer one
                // faces the wrong way, as a facing filter does, made points on or beside another
                // piece's rim "penetrate" a face beyond the rim by up to the reach (most of the
                // deep contacts after a cut through touching pieces: docs/math/contact.md §5).
                // Another piece's nearest triangle counts within reach.
                let mut consider = |candidate: Candidate| {
                    if within_reach(&candidate) {
                        keep(candidate);
                    }
                };
                let q_parry = to_parry(&q);
                let speed = h * u.norm();
                for b in this.candidate_pieces(own) {
                    // Most pieces are far from most points: a bound on the radius below that
                    // needs no square root (|u − w_b| ≤ |u| + |w_b|) rules them out first.
                    let root = &this.roots_all[b];
                    let loose = this.loose_reach[b] + speed * (1.0 + 1e-9);
                    if squared_distance_to_box(q_parry, root.mins, root.maxs) >= loose * loose {
                        continue;
                    }
                    // The nearest triangle within the largest reach any triangle of the piece can
                    // have (`consider` below), by branch and bound on the triangles' own boxes:
                    // what is found depends on the triangles only, not on boxes, so not on how the
                    // scene is turned. Per triangle the reach is the surface's plus the step's
                    // approach, h(|u − v_t| + max_k |v_k − v_t|) with v_t the velocity of its point
                    // (a convex combination of its corners'), which is at most
                    // h(|u − w_b| + s_b + τ_b) with w_b the piece's mean velocity, s_b its points'
                    // largest speed relative to it and τ_b the largest difference of two corners'
                    // velocities in one of its triangles (a rotating piece: its points' speeds
                    // relative to w_b grow with its size, τ_b only with its triangles'). The
                    // factor keeps rounding from putting a triangle `consider` takes outside.
                    let radius = (surface.reach
                        + h * ((u - this.motion.velocity[b]).norm()
                            + this.motion.spread[b]
                            + this.motion.triangle_spread[b]))
                        * (1.0 + 1e-12);
                    if squared_distance_to_box(q_parry, root.mins, root.maxs) >= radius * radius {
                        continue;
                    }
                    // A piece that turns moves its points relative to its mean velocity by up to
                    // its angular speed times its size, but a triangle near q relative to q by
                    // little more than what the piece's rigid motion does at q: with v = w + ω ×
                    // (x − c) + δ, |u − v_t| ≤ |u − w − ω × (q − c)| + |ω| d + δ_b at distance d,
                    // so d ≤ reach_t needs d (1 − h|ω|) ≤ reach + h(|u − w − ω × (q − c)| + δ_b
                    // + τ_b).
                    let rigid = &this.motion.rigid[b];
                    let relative = u - this.motion.velocity[b] - rigid.angular.cross(&(q - rigid.center));
                    let rigid_radius = (surface.reach
                        + h * (relative.norm() + rigid.deviation + this.motion.triangle_spread[b]))
                        / rigid.shrink(h)
                        * (1.0 + 1e-12);
                    let radius = radius.min(rigid_radius);
                    let list = &this.component_triangles[b];
                    // A box of a tree not refit since its piece moved by up to `stale` holds its
                    // triangles once loosened by that on every side.
                    let stale = ParryVector::splat(this.staleness[b]);
                    let nearest = this.bvh_all[b].find_best(
                        radius * radius,
                        |node, _| squared_distance_to_box(q_parry, node.mins() - stale, node.maxs() + stale),
                        |leaf, _| {
                            let t = list[leaf as usize] as usize;
                            let corners = triangles[t].map(|k| positions[k as usize]);
                            let (c, beta) = closest_point_on_triangle(&q, &corners);
                            Some(((q - c).norm_squared(), (t, c, beta)))
                        },
                    );
                    let Some((_, (distance_squared, (t, c, beta)))) = nearest else { continue };
                    let distance = distance_squared.sqrt();
                    // Every triangle at the nearest feature is nearest (a corner's, an edge's faces):
                    // the pair is decided over all of them, so it does not depend on which one the
                    // search met first (its order, or rounding between the faces of an edge).
                    this.feature_triangles(triangles, t, &beta, at_feature);
                    // The pair is held by the feature's first triangle, whichever the search found.
                    let (t, c, beta, distance) = match at_feature[0] as usize {
                        first if first != t => {
                            let (c, beta) =
                                closest_point_on_triangle(&q, &triangles[first].map(|k| positions[k as usize]));
                            (first, c, beta, (q - c).norm())
                        }
                        _ => (t, c, beta, distance),
                    };
                    let offset = q - c;
                    // The feature's triangles with their own closest points (the same point up to
                    // rounding), in index order.
                    let on_triangle = |o: u32| {
                        if o as usize == t {
                            return (c, beta);
                        }
                        closest_point_on_triangle(&q, &triangles[o as usize].map(|k| positions[k as usize]))
                    };
                    // Inside by the pseudonormal, and behind every face at the nearest feature: where
                    // an edge or corner of a piece is not manifold (two regions of one piece meeting
                    // there), its pseudonormal can say inside for a point beside it, and a point
                    // inside near a reflex edge or corner, the only inside points whose nearest
                    // feature is not a face, is behind every face there.
                    let behind = at_feature.iter().all(|&o| this.triangle_normals[o as usize].dot(&offset) < 0.0);
                    if distance > 1e-9 * surface.reach
                        && behind
                        && offset.dot(&this.pseudonormal(triangles, t, &beta)) < 0.0
                    {
                        // Inside: pushed out along the shortest way, whatever feature is nearest.
                        let normal = -offset / distance;
                        consider(Candidate { gap: -distance, distance, triangle: t, beta, normal });
                    } else {
                        // Outside or touching: only a face it projects into and that faces it, the
                        // smallest gap among the feature's faces. An edge or corner nearest from
                        // outside is no contact yet (its direction q − c says little about where the
                        // point will meet the surface: a point 2 cm beside an edge, closing along x,
                        // would get a sideways push), and no farther triangle stands in for it.
                        let mut facing: Option<Candidate> = None;
                        for &o in at_feature.iter() {
                            let normal = this.triangle_normals[o as usize];
                            let (c, beta) = on_triangle(o);
                            let gap = normal.dot(&(q - c));
                            if vertex_normal.dot(&normal) < 0.0
                                && contact_normal(&q, &c, &normal, distance, lateral).is_some()
                                && facing.as_ref().is_none_or(|f| gap < f.gap)
                            {
                                facing = Some(Candidate { gap, distance, triangle: o as usize, beta, normal });
                            }
                        }
                        if let Some(candidate) = facing {
                            consider(candidate);
                        }
                    }
                }
                let Some(Candidate { gap, triangle, beta, normal, .. }) = best else { return };
                let tri = triangles[triangle];
                let other_velocity =
                    tri.iter().zip(&beta).fold(Vector3::zeros(), |s, (&k, &b)| s + velocities[k as usize] * b);
                let relative = u - other_velocity;
                let d = gap - surface.thickness;
                let which = (ContactKind::Surface, (first_slot + i) as u32, this.lagged[first_slot + i]);
                // Touching counts (faces a cut has just separated coincide, and nothing else would
                // hold the upper one up in the step after the cut), up to rounding of the gap.
                let gap = (d, -surface.thickness, 1e-9 * surface.reach);
                let row = Row::vertex_triangle(i as u32, tri, beta);
                // Gravity enters the prediction where the triangle's side is at rest (slower than a
                // step of free fall, g h): a piece lying on another falls onto it as onto the
                // ground. Where both sides move, they may be falling together, and it does not.
                let resting = other_velocity.norm() < h * gravity.norm();
                let gravity_along = if resting { normal.dot(gravity) } else { 0.0 };
                *slot = make_contact(row, which, normal, gap, &relative, gravity_along, h, params);
                if slot.is_none() {
                    *near = Some(NearPair { row, which, normal, gap, params, slack: 0.5 * surface.reach });
                }
            },
        );
        self.contacts.extend(per_point.iter().flatten().copied());
        self.near = near;
        self.per_point = per_point;
    }

    /// Edge–edge contacts: each feature edge against the feature edges of the other pieces, where
    /// the closest points of the two lines lie inside both edges and the two pieces' faces at the
    /// edges oppose along the common normal `e_a × e_b` (docs/math/contact.md §2). The closest
    /// active pair per feature edge; a pair is taken from its lower-numbered edge.
    fn detect_edges(&mut self, surface: &crate::constraints::SurfaceContact, h: Real, first_slot: usize) {
        let (positions, velocities) = (&self.positions, &self.velocities);
        // Leaf box of a feature edge: its ends, the reach, and their motion relative to their
        // piece's mean velocity in one step (as the cut triangles' boxes, `detect_surface`).
        let (component, component_velocity) = (&self.component, &self.motion.velocity);
        let leaf = |g: u32| -> Aabb {
            let [p, q] = self.edges[g as usize];
            let w = component_velocity[component[p as usize] as usize];
            let speed = (velocities[p as usize] - w).norm().max((velocities[q as usize] - w).norm());
            let margin = Vector3::repeat(surface.reach + h * speed);
            let (p, q) = (positions[p as usize], positions[q as usize]);
            Aabb::new(to_parry(&(p.inf(&q) - margin)), to_parry(&(p.sup(&q) + margin)))
        };
        if self.bvh_edges.is_empty() {
            self.bvh_edges =
                self.component_feature_edges.par_iter().map(|list| build_tree(list.iter().map(|&g| leaf(g)))).collect();
        } else {
            self.bvh_edges
                .par_iter_mut()
                .zip(self.component_feature_edges.par_iter())
                .for_each(|(bvh, list)| refit_in_place(bvh, list.iter().map(|&g| leaf(g))));
        }
        // Every slot is written below.
        let mut per_edge = std::mem::take(&mut self.per_edge);
        per_edge.resize(self.feature_edges.len(), None);
        let this = &*self;
        let params = (surface.stiffness, surface.damping, surface.friction);
        // Outward normal of the faces at an edge (their sum, deformed).
        let edge_normal = |e: usize| {
            let [f0, f1] = this.edge_faces[e];
            this.triangle_normals[f0 as usize] + this.triangle_normals[f1 as usize]
        };
        per_edge.par_iter_mut().enumerate().for_each(|(k, slot)| {
            let e = this.feature_edges[k] as usize;
            let a = this.edges[e];
            let ends = a.map(|i| positions[i as usize]);
            let speeds = a.map(|i| velocities[i as usize]);
            let own = this.component[a[0] as usize] as usize;
            let outward_a = edge_normal(e);
            // The closest active pair.
            let mut best: Option<(Real, Contact)> = None;
            let which = (ContactKind::Edge, (first_slot + k) as u32, this.lagged[first_slot + k]);
            for b in this.candidate_pieces(own) {
                // A pair is taken from its lower-numbered edge, and a piece's list is in
                // increasing order: a piece whose edges all come before this one has none.
                let (bvh, list) = (&this.bvh_edges[b], &this.component_feature_edges[b]);
                if list.last().is_none_or(|&last| (last as usize) < e) {
                    continue;
                }
                let w = this.motion.velocity[b];
                let motion = Vector3::repeat(h * (speeds[0] - w).norm().max((speeds[1] - w).norm()));
                let query =
                    Aabb::new(to_parry(&(ends[0].inf(&ends[1]) - motion)), to_parry(&(ends[0].sup(&ends[1]) + motion)));
                // (The root box is the piece's triangles' own; the leaves of its edge tree lie
                // within it loosened by the reach and the piece's spread of speeds.)
                if !this.roots_all[b].loosened(surface.reach + h * this.motion.spread[b]).intersects(&query) {
                    continue;
                }
                for g in bvh.intersect_aabb(&query).map(|leaf| list[leaf as usize] as usize) {
                    if g < e {
                        continue;
                    }
                    let other = this.edges[g].map(|i| positions[i as usize]);
                    let Some((s, t)) = closest_parameters_of_lines(&ends, &other) else { continue };
                    // Within the reach of an end the pair is that end's: the vertex–triangle
                    // contacts of the faces around it see it, and the two edges' common normal
                    // turns arbitrarily as they come to share a corner.
                    let (length_a, length_b) = ((ends[1] - ends[0]).norm(), (other[1] - other[0]).norm());
                    let (margin_s, margin_t) = (surface.reach / length_a, surface.reach / length_b);
                    if !(margin_s..=1.0 - margin_s).contains(&s) || !(margin_t..=1.0 - margin_t).contains(&t) {
                        continue;
                    }
                    // The common normal, towards this edge's side of the other piece.
                    let Some(mut normal) = (ends[1] - ends[0]).cross(&(other[1] - other[0])).try_normalize(0.0) else {
                        continue;
                    };
                    let outward_b = edge_normal(g);
                    if normal.dot(&outward_b) < 0.0 {
                        normal = -normal;
                    }
                    if normal.dot(&outward_a) >= 0.0 || normal.dot(&outward_b) <= 0.0 {
                        continue;
                    }
                    let p = ends[0] + (ends[1] - ends[0]) * s;
                    let q = other[0] + (other[1] - other[0]) * t;
                    let d = normal.dot(&(p - q)) - surface.thickness;
                    let row = Row::edge_edge(a, s, this.edges[g], t);
                    let relative = row.entries().fold(Vector3::zeros(), |sum, (i, w)| sum + velocities[i as usize] * w);
                    // Farther than the reach (with this step's approach) is no contact yet;
                    // deeper than the reach is the far side of a thin part.
                    if d > surface.reach + h * relative.norm() || d < -surface.reach {
                        continue;
                    }
                    let distance = (p - q).norm();
                    if best.as_ref().is_some_and(|best| distance >= best.0) {
                        continue;
                    }
                    let gap = (d, -surface.thickness, 1e-9 * surface.reach);
                    if let Some(contact) = make_contact(row, which, normal, gap, &relative, 0.0, h, params) {
                        best = Some((distance, contact));
                    }
                }
            }
            *slot = best.map(|(_, contact)| contact);
        });
        self.contacts.extend(per_edge.iter().flatten().copied());
        self.per_edge = per_edge;
    }

    /// Stores the normal force every active contact carried in the step just solved (new
    /// velocities `v`): `max(0, −k (min(d, 0) + h n·u⁺) − c n·u⁺)` with `u⁺` the row's
    /// velocity; friction of the next step is proportional to it.
    pub fn store_normal_forces(&mut self, points: &Embedding, v: &[Real], h: Real) {
        self.lagged.iter_mut().for_each(|l| *l = 0.0);
        for c in &self.contacts {
            let approach = c.normal.dot(&row_value(points, c, v));
            let force = -c.stiffness * (c.depth.min(0.0) + h * approach) - c.damping * approach;
            self.lagged[c.slot as usize] = force.max(0.0);
        }
    }

    /// Activates the near pairs of this step's detection that velocities `v` (the step's
    /// solution) drive more than their slack into each other, `d + h n·u⁺ < −slack` (half the
    /// reach), and returns how many: the
    /// caller solves again with them. Their gap is not negative, so they add no force, only
    /// the implicit term that stops the approach (docs/math/contact.md §3).
    pub fn activate_driven(&mut self, points: &Embedding, v: &[Real], h: Real) -> usize {
        let mut added = 0;
        for slot in self.near.iter_mut() {
            let Some(pair) = slot else { continue };
            let u = pair
                .row
                .entries()
                .fold(Vector3::zeros(), |sum, (point, w)| sum + points.point(v, point as usize).coords * w);
            if pair.gap.0 + h * pair.normal.dot(&u) < -pair.slack
                && let Some(contact) =
                    make_contact(pair.row, pair.which, pair.normal, pair.gap, &u, 0.0, h, pair.params)
            {
                self.contacts.push(contact);
                added += 1;
                *slot = None;
            }
        }
        added
    }

    /// Visits the couple of every pair between two sides of the body's surface in the step just
    /// solved (velocities `v`, not yet applied to `x`), with a node of each side: a penalty pair
    /// acts on two points that the penetration (or, for a pair the prediction activated, the
    /// approach) holds apart along the normal, so its tangential (friction) part is a couple
    /// `r × f` with `r = p − c` the row's value at `x`, which changes the angular momentum by
    /// `h r × f` where the continuum's touching surfaces have none. `visit(a, b, h r × f)`;
    /// docs/math/contact.md §5.
    pub fn visit_pair_couples(
        &self,
        points: &Embedding,
        x: &[Real],
        v: &[Real],
        h: Real,
        mut visit: impl FnMut(u32, u32, Vector3<Real>),
    ) {
        for c in self.contacts.iter().filter(|c| c.row.len > 1) {
            let force = c.force - c.matrix * row_value(points, c, v) / h;
            let couple = row_value(points, c, x).cross(&force) * h;
            let side = |entry: usize| points.row(c.row.points[entry] as usize).0.first().copied();
            if let (Some(a), Some(b)) = (side(0), side(c.row.len as usize - 1)) {
                visit(a, b, couple);
            }
        }
    }

    /// Counts per kind and the deepest penetration.
    pub fn stats(&self) -> ContactStats {
        let mut stats = ContactStats::default();
        for c in &self.contacts {
            match c.kind {
                ContactKind::Plane => stats.planes += 1,
                ContactKind::Mesh => stats.meshes += 1,
                ContactKind::Surface => stats.surface += 1,
                ContactKind::Edge => stats.edges += 1,
            }
            stats.max_penetration = stats.max_penetration.max(-c.depth);
        }
        stats
    }
}

/// Visits the entries `(node, weight)` of a contact's row: each surface point's embedding row
/// scaled by the point's weight in the row. A node may occur more than once (point and
/// triangle in one element); every sum below treats the entries as a sum, which is exact.
#[inline]
pub(crate) fn for_each_entry(points: &Embedding, contact: &Contact, mut visit: impl FnMut(u32, Real)) {
    for (point, scale) in contact.row.entries() {
        let (nodes, weights) = points.row(point as usize);
        for (&n, &w) in nodes.iter().zip(weights) {
            visit(n, scale * w);
        }
    }
}

/// `Σ_entries w v_node` over a contact's row.
#[inline]
fn row_value(points: &Embedding, contact: &Contact, v: &[Real]) -> Vector3<Real> {
    let mut sum = Vector3::zeros();
    for_each_entry(points, contact, |n, w| {
        let i = 3 * n as usize;
        sum += Vector3::new(v[i], v[i + 1], v[i + 2]) * w;
    });
    sum
}

/// `force += Σ w ⊗ f` over the contacts.
pub(crate) fn add_forces(points: &Embedding, contacts: &[Contact], force: &mut [Real]) {
    for c in contacts {
        for_each_entry(points, c, |n, w| {
            for a in 0..3 {
                force[3 * n as usize + a] += w * c.force[a];
            }
        });
    }
}

/// `Σ ½ k min(d(x), 0)²` over the pairs of `contacts` at state `x`, and how many penetrate.
/// A pair found at the start of a step keeps its normal and barycentric point through it, so
/// this is the penalty energy at the end of the step of the pairs the step acted on.
pub(crate) fn energy(points: &Embedding, contacts: &[Contact], x: &[Real]) -> (Real, usize) {
    let mut energy = 0.0;
    let mut penetrating = 0;
    for c in contacts {
        let d = c.normal.dot(&row_value(points, c, x)) + c.offset;
        if d < 0.0 {
            energy += 0.5 * c.stiffness * d * d;
            penetrating += 1;
        }
    }
    (energy, penetrating)
}

/// The node groups of this step's contact rows whose couplings the pattern lacks (a point and
/// a triangle, or two edges, of the body's surface that were never in contact before in this
/// epoch). Each group is the nodes of the row's points *and of the points around them*, so
/// that a point sliding on to a neighbouring triangle needs no new pattern.
pub(crate) fn missing_couplings(points: &Embedding, set: &ContactSet, pattern: &AssemblyPattern) -> Vec<Vec<u32>> {
    // Checked in parallel over the contacts, each row's nodes once (the corners of a triangle
    // mostly share a duplicate's nodes); the groups in contact order.
    set.contacts
        .par_iter()
        .filter(|c| c.row.len > 1)
        .map_init(
            || Vec::with_capacity(16),
            |nodes: &mut Vec<u32>, c| {
                nodes.clear();
                for_each_entry(points, c, |n, _| nodes.push(n));
                nodes.sort_unstable();
                nodes.dedup();
                if !nodes.iter().any(|&j| nodes.iter().any(|&i| pattern.rank(i, j).is_none())) {
                    return None;
                }
                let mut group = Vec::new();
                for (v, _) in c.row.entries() {
                    for &around in &set.ring[set.ring_offsets[v as usize]..set.ring_offsets[v as usize + 1]] {
                        group.extend_from_slice(points.row(around as usize).0);
                    }
                }
                group.sort_unstable();
                group.dedup();
                Some(group)
            },
        )
        .flatten()
        .collect()
}

/// How far, in reaches, a piece's points may move before its whole-surface tree is refit.
const STALE_REACH: Real = 0.1;

/// Trees with fewer leaves are refit one per task, side by side; larger ones with parry's
/// parallel batch update and refit (a single large piece would otherwise refit on one core).
const PARALLEL_REFIT_LEAVES: usize = 16384;

/// Scratch of the per-step hierarchy refits, reused across steps.
#[derive(Default)]
struct RefitScratch {
    updates: Vec<(Aabb, u32, Real)>,
    statuses: Vec<BvhLeafUpdateStatus>,
    workspace: BvhWorkspace,
}

impl RefitScratch {
    /// Moves leaf `k` of `bvh` to `leaf(k)` for every one of its `count` leaves and refits it:
    /// the boxes computed, written and merged upwards on the rayon pool.
    fn refit(&mut self, bvh: &mut Bvh, count: usize, leaf: impl Fn(usize) -> Aabb + Sync) {
        (0..count).into_par_iter().map(|k| (leaf(k), k as u32, 0.0)).collect_into_vec(&mut self.updates);
        bvh.insert_or_update_batch_partially_parallel(&self.updates, &mut self.statuses);
        bvh.refit_parallel(&mut self.workspace);
    }
}

/// Adds `(w wᵀ) ⊗ P` of every contact to the assembled matrix, whose pattern holds every
/// contact row's couplings (see [`missing_couplings`]). In parallel over [`COLUMN_RANGES`]
/// ranges of column nodes ([`AssemblyPattern::for_column_ranges`]): each task writes the blocks
/// of every contact whose column node is its own.
pub(crate) fn add_matrix(points: &Embedding, set: &ContactSet, pattern: &AssemblyPattern, values: &mut [Real]) {
    let nodes = pattern.num_nodes();
    if set.contacts.is_empty() || nodes == 0 {
        return;
    }
    let bounds: [u32; COLUMN_RANGES + 1] = std::array::from_fn(|k| (k * nodes / COLUMN_RANGES) as u32);
    let col_ptr = pattern.col_ptr();
    // Every contact's entries once, for all column ranges: one entry per node, weights summed
    // (the corners of a triangle mostly lie in one duplicate, so 16 entries are often 4 to 8
    // nodes; `w wᵀ` is the same matrix).
    let mut scratch = set.matrix_entries.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let (offsets, all) = &mut *scratch;
    offsets.clear();
    all.clear();
    offsets.push(0);
    for c in &set.contacts {
        let start = all.len();
        for_each_entry(points, c, |n, w| all.push((n, w)));
        let entries = &mut all[start..];
        entries.sort_unstable_by_key(|e| e.0);
        let mut kept = 0;
        for k in 0..entries.len() {
            if k > 0 && entries[k].0 == entries[kept].0 {
                entries[kept].1 += entries[k].1;
            } else {
                if k > 0 {
                    kept += 1;
                }
                entries[kept] = entries[k];
            }
        }
        all.truncate(start + kept + 1);
        offsets.push(all.len());
    }
    let (offsets, all) = (&*offsets, &*all);
    pattern.for_column_ranges(&bounds, values, &|columns, values, base| {
        for (c, range) in set.contacts.iter().zip(offsets.windows(2)) {
            let entries = &all[range[0]..range[1]];
            // The entries are sorted by node: those of this range's columns are consecutive,
            // and for each column its rows' ranks increase, found in one walk along its list.
            let first = entries.partition_point(|e| e.0 < columns.start);
            let last = first + entries[first..].partition_point(|e| e.0 < columns.end);
            for &(j, wj) in &entries[first..last] {
                let neighbours = pattern.neighbours(j);
                let mut rank = 0;
                for &(i, wi) in entries {
                    rank += neighbours[rank..].partition_point(|&k| k < i);
                    assert!(neighbours.get(rank) == Some(&i), "the pattern holds every contact row's couplings");
                    for col in 0..3 {
                        let at = col_ptr[3 * j as usize + col] + 3 * rank - base;
                        for row in 0..3 {
                            values[at + row] += wi * wj * c.matrix[(row, col)];
                        }
                    }
                }
            }
        }
    });
}

/// Column ranges the contact blocks are assembled over (a few per core of a small machine).
const COLUMN_RANGES: usize = 8;

/// `out += Σ (w wᵀ ⊗ P) p` over the contacts (the full rows: matrix-free path).
pub(crate) fn add_action(points: &Embedding, contacts: &[Contact], p: &[Real], out: &mut [Real]) {
    for c in contacts {
        let y = c.matrix * row_value(points, c, p);
        for_each_entry(points, c, |n, w| {
            for a in 0..3 {
                out[3 * n as usize + a] += w * y[a];
            }
        });
    }
}

/// `blocks[node] += w² P` (block-Jacobi).
pub(crate) fn add_diagonal_blocks(points: &Embedding, contacts: &[Contact], blocks: &mut [Matrix3<Real>]) {
    for c in contacts {
        for_each_entry(points, c, |n, w| blocks[n as usize] += c.matrix * (w * w));
    }
}

impl MeshCollider {
    /// The closest point of the mesh to `q` within `radius` and the unit normal of its
    /// triangle (pointing to the allowed side).
    fn closest(&self, q: &Point3<Real>, radius: Real) -> Option<(Point3<Real>, Vector3<Real>)> {
        let r = Vector3::repeat(radius);
        let query = Aabb::new(to_parry(&(q - r)), to_parry(&(q + r)));
        let mut best: Option<(Real, Point3<Real>, usize)> = None;
        for t in self.bvh.intersect_aabb(&query) {
            let corners = self.triangles[t as usize].map(|k| self.vertices[k as usize]);
            let (c, _) = closest_point_on_triangle(q, &corners);
            let distance = (q - c).norm();
            if contact_normal(q, &c, &self.normals[t as usize], distance, LATERAL_FRACTION * self.reach).is_none() {
                continue;
            }
            if distance <= radius && best.is_none_or(|b| distance < b.0) {
                best = Some((distance, c, t as usize));
            }
        }
        best.and_then(|(distance, c, t)| {
            Some((c, contact_normal(q, &c, &self.normals[t], distance, LATERAL_FRACTION * self.reach)?))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraints::{PlaneCollider, SurfaceContact};

    /// Two triangles of two pieces (points 0–2 and 3–5, every point its own node) at `lower`
    /// and `upper`; at rest the upper one floats 1 m higher, so nothing touches there.
    fn two_triangles(
        lower: [[Real; 3]; 3],
        upper: [[Real; 3]; 3],
        planes: Vec<PlaneCollider>,
    ) -> (Constraints, Vec<Real>, Vec<Real>) {
        let mut points = Embedding::new();
        for i in 0..6u32 {
            points.push_row(&[i], &[1.0]);
        }
        let x: Vec<Real> = lower.iter().chain(&upper).flatten().copied().collect();
        let rest: Vec<Real> =
            x.iter().enumerate().map(|(i, &c)| if i >= 9 && i % 3 == 2 { c + 1.0 } else { c }).collect();
        let constraints = Constraints {
            contact_points: Some(points),
            planes,
            surface_contact: Some(SurfaceContact {
                triangles: vec![[0, 1, 2], [3, 4, 5]],
                on_cut: Vec::new(),
                piece: Vec::new(),
                stiffness: 1e4,
                damping: 0.0,
                friction: 0.0,
                thickness: 0.0,
                reach: 0.05,
                edge_contact: true,
            }),
            ..Default::default()
        };
        (constraints, x, rest)
    }

    /// The upper triangle sunk into the lower one (lower faces up, upper faces down: opposing),
    /// with a tilted ground plane under a corner.
    fn setup() -> (Constraints, Vec<Real>, Vec<Real>) {
        let ground = PlaneCollider {
            point: Point3::new(0.0, 0.0, 0.01),
            normal: Vector3::new(0.1, -0.2, 1.0).normalize(),
            stiffness: 3e3,
            damping: 0.0,
            friction: 0.0,
        };
        two_triangles(
            [[0.0, 0.0, 0.0], [1.0, 0.1, 0.02], [0.2, 1.0, -0.03]],
            [[0.3, 0.3, -0.004], [0.35, 0.5, -0.002], [0.55, 0.3, 0.05]],
            vec![ground],
        )
    }

    /// Two triangles whose edges cross 3.7 mm into each other (an edge along x whose triangle
    /// faces up, one along y whose triangle faces down), slightly skewed so that nothing is
    /// axis aligned, with no point near the other's face: an edge–edge contact.
    fn crossing_edges() -> (Constraints, Vec<Real>, Vec<Real>) {
        two_triangles(
            [[0.5, 0.02, 0.01], [-0.5, -0.01, -0.01], [0.03, -0.5, -0.5]],
            [[0.1, -0.5, -0.002], [0.12, 0.5, -0.001], [0.6, 0.02, 0.5]],
            Vec::new(),
        )
    }

    #[test]
    fn crossing_edges_make_an_edge_contact() {
        let (constraints, x, rest) = crossing_edges();
        let mut set = ContactSet::new(&constraints, &rest);
        set.detect(&constraints, &x, &vec![0.0; x.len()], 0.01, &Vector3::zeros());
        let stats = set.stats();
        // The crossing's depth along the common normal, computed here from the four points.
        let at = |k: usize| Point3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]);
        let (a, b) = ([at(0), at(1)], [at(3), at(4)]);
        let (s, t) = closest_parameters_of_lines(&a, &b).unwrap();
        let gap = ((a[0] + (a[1] - a[0]) * s) - (b[0] + (b[1] - b[0]) * t)).norm();
        println!("{stats:?}; the edges cross {gap:.3e} m deep");
        assert_eq!(stats.edges, 1, "{stats:?}");
        assert!((stats.max_penetration - gap).abs() < 1e-12 * gap.max(1.0), "{} vs {gap}", stats.max_penetration);
    }

    /// Two points 1 mm above a flat triangle of another piece, at rest: not active, but kept as
    /// near pairs; a solution that moves them towards it joins them exactly when it carries them
    /// more than half the reach (0.025 m) through, `d + h n·u⁺ < −reach/2`, each with the
    /// implicit block `h² k n nᵀ` (1.0 along `n`). The same in a turned and moved copy of the
    /// scene, where the normal is not an axis.
    #[test]
    fn pairs_the_solution_drives_together_join_the_step() {
        let turns = [
            (nalgebra::Rotation3::identity(), Vector3::zeros()),
            (nalgebra::Rotation3::new(Vector3::new(0.4, -0.9, 0.3)), Vector3::new(2.0, -1.0, 0.5)),
        ];
        for (turn, shift) in turns {
            let place = |p: [Real; 3]| (turn * Vector3::from(p) + shift).into();
            let (constraints, x, rest) = two_triangles(
                [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]].map(place),
                [[0.3, 0.3, 0.001], [0.35, 0.5, 0.001], [0.55, 0.3, 0.2]].map(place),
                Vec::new(),
            );
            let normal = turn * Vector3::z();
            let points = constraints.contact_points.clone().unwrap();
            let h = 0.01;
            for (speed, expected) in [(2.5, 0), (3.1, 2)] {
                let mut set = ContactSet::new(&constraints, &rest);
                set.detect(&constraints, &x, &vec![0.0; x.len()], h, &Vector3::zeros());
                assert_eq!(set.stats().surface, 0, "nothing closes at rest");
                let mut v = vec![0.0; x.len()];
                for k in [3, 4] {
                    v[3 * k..3 * k + 3].copy_from_slice((-speed * normal).as_slice());
                }
                let added = set.activate_driven(&points, &v, h);
                println!("towards it at {speed} m/s: predicted gap {:.4} m, {added} pairs join", 0.001 - h * speed);
                assert_eq!(added, expected);
                for c in &set.contacts {
                    assert_eq!(c.kind, ContactKind::Surface);
                    assert!((c.normal - normal).norm() < 1e-12 && (c.depth - 0.001).abs() < 1e-12, "{c:?}");
                    assert!((c.matrix - normal * normal.transpose() * (h * h * 1e4)).norm() < 1e-9);
                }
            }
        }
    }

    /// The upper triangle's two low points 8 cm above the lower one, farther than the reach
    /// (5 cm), at 10 m/s (10 cm in the step of 0.01 s): moving towards it they are found and
    /// active; moving away they are near pairs only (within the reach plus their step's motion),
    /// and the same in the scene turned and moved. A search box along each point's path found
    /// none when moving away in the scene as given and two in the turned one (a tilted
    /// triangle's box reaches behind the point): it made contacts depend on the scene's
    /// orientation, and was reverted.
    #[test]
    fn what_a_point_finds_does_not_depend_on_the_scene_orientation() {
        let turns = [
            (nalgebra::Rotation3::identity(), Vector3::zeros()),
            (nalgebra::Rotation3::new(Vector3::new(0.4, -0.9, 0.3)), Vector3::new(2.0, -1.0, 0.5)),
        ];
        for (turn, shift) in turns {
            let place = |p: [Real; 3]| (turn * Vector3::from(p) + shift).into();
            let (constraints, x, rest) = two_triangles(
                [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]].map(place),
                [[0.3, 0.3, 0.08], [0.35, 0.5, 0.08], [0.55, 0.3, 0.3]].map(place),
                Vec::new(),
            );
            let normal = turn * Vector3::z();
            let h = 0.01;
            for (speed, active, near) in [(10.0, 2, 0), (-10.0, 0, 2)] {
                let mut v = vec![0.0; x.len()];
                for k in 3..6 {
                    v[3 * k..3 * k + 3].copy_from_slice((-speed * normal).as_slice());
                }
                let mut set = ContactSet::new(&constraints, &rest);
                set.detect(&constraints, &x, &v, h, &Vector3::zeros());
                let found_near = set.near.iter().flatten().count();
                println!("at {speed} m/s towards the lower triangle: {:?}, {found_near} near pairs", set.stats());
                assert_eq!(set.stats().surface, active, "{speed} m/s");
                assert_eq!(found_near, near, "{speed} m/s");
                for c in &set.contacts {
                    assert!((c.normal - normal).norm() < 1e-12 && (c.depth - 0.08).abs() < 1e-12, "{c:?}");
                }
            }
        }
    }

    /// A set built for the next epoch takes the trees of the components it shares with the last
    /// one, and its first detection refits them: the upper triangle, 1 m above at the last
    /// detection, now sunk into the lower one, gives exactly the contacts a set with trees
    /// built afresh gives (a kept tree that were not refit would still hold it 1 m up).
    #[test]
    fn kept_trees_are_refit_and_find_what_new_ones_find() {
        let (constraints, x, rest) = setup();
        let zero = vec![0.0; x.len()];
        let mut last = ContactSet::new(&constraints, &rest);
        last.detect(&constraints, &rest, &zero, 0.01, &Vector3::zeros());
        assert_eq!(last.stats().surface, 0, "nothing touches at rest");
        let mut kept = ContactSet::new(&constraints, &rest);
        kept.reuse_trees(last);
        assert_eq!(kept.reused_trees.iter().flatten().count(), 2, "both pieces keep their trees");
        kept.detect(&constraints, &x, &zero, 0.01, &Vector3::zeros());
        let mut fresh = ContactSet::new(&constraints, &rest);
        fresh.detect(&constraints, &x, &zero, 0.01, &Vector3::zeros());
        assert!(fresh.stats().surface > 0, "{:?}", fresh.stats());
        assert_eq!(kept.stats(), fresh.stats());
        assert_eq!(format!("{:?}", kept.contacts), format!("{:?}", fresh.contacts));
    }

    /// The box [0, size]² × [0, thick] (corner k at the bits of k) and its 12 triangles,
    /// outward, counter-clockwise seen from outside.
    fn slab(size: Real, thick: Real) -> (Vec<[Real; 3]>, Vec<[u32; 3]>) {
        let corners =
            (0..8).map(|k| [size * (k & 1) as Real, size * ((k >> 1) & 1) as Real, thick * (k >> 2) as Real]).collect();
        let triangles = vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        (corners, triangles)
    }

    /// The corners of a regular tetrahedron of half-size `half` turned by `turn` about `centre`
    /// (points 8–11 after a slab's 8; [`TETRAHEDRON_TRIANGLES`] its outward faces).
    fn tetrahedron(turn: nalgebra::Rotation3<Real>, centre: Vector3<Real>, half: Real) -> [Vector3<Real>; 4] {
        [[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]]
            .map(|c| turn * Vector3::from(c) * half + centre)
    }
    /// The outward faces of [`tetrahedron`]'s corners as points 8–11.
    const TETRAHEDRON_TRIANGLES: [[u32; 3]; 4] = [[8, 9, 10], [8, 11, 9], [8, 10, 11], [9, 11, 10]];

    /// The DOFs of a slab's corners followed by a tetrahedron's.
    fn slab_then_tetrahedron_dofs(slab: &[[Real; 3]], corners: &[Vector3<Real>; 4]) -> Vec<Real> {
        slab.iter().flatten().copied().chain(corners.iter().flat_map(|c| [c.x, c.y, c.z])).collect()
    }

    /// A reproducible sequence of numbers in [0, 1) (a 64-bit linear congruential generator).
    fn uniform(seed: u64) -> impl FnMut() -> Real {
        let mut state = seed;
        move || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as Real / (1u64 << 53) as Real
        }
    }

    /// Surface contact between a slab (points 0–7) and a tetrahedron (points 8–11) at `x`, each
    /// point its own node, with `triangles` as the surface; the rest shape holds the tetrahedron
    /// 10 m away, so nothing is behind anything at rest.
    fn slab_and_tetrahedron(triangles: Vec<[u32; 3]>, x: &[Real]) -> (Constraints, Vec<Real>) {
        let mut points = Embedding::new();
        for i in 0..12u32 {
            points.push_row(&[i], &[1.0]);
        }
        let rest = x.iter().enumerate().map(|(i, &c)| if i >= 24 { c + 10.0 } else { c }).collect();
        let constraints = Constraints {
            contact_points: Some(points),
            surface_contact: Some(SurfaceContact {
                triangles,
                on_cut: Vec::new(),
                piece: Vec::new(),
                stiffness: 1e4,
                damping: 0.0,
                friction: 0.0,
                thickness: 0.0,
                reach: 0.01,
                edge_contact: false,
            }),
            ..Default::default()
        };
        (constraints, rest)
    }

    /// A pair's points, weights, normal and depth, the numbers as bits.
    type PairBits = ([u32; 4], [u64; 4], Vector3<u64>, u64);

    /// The contacts and near pairs of a set's last detection, each as its bits.
    fn pairs_bit_for_bit(set: &ContactSet) -> (Vec<PairBits>, Vec<PairBits>) {
        let bits = |row: &Row, normal: &Vector3<Real>, depth: Real| -> PairBits {
            (row.points, row.weights.map(Real::to_bits), normal.map(Real::to_bits), depth.to_bits())
        };
        let contacts = set.contacts.iter().map(|c| bits(&c.row, &c.normal, c.depth)).collect();
        let near = set.near.iter().flatten().map(|p| bits(&p.row, &p.normal, p.gap.0)).collect();
        (contacts, near)
    }

    /// The pairs (contacts and near pairs) that detection finds at `x`, `v`, with the search
    /// bounded by the pieces' rigid motions, by their mean velocities alone, and with every
    /// other piece searched (no filter of the pairs of pieces), asserted equal bit for bit;
    /// returns how many.
    fn pairs_found_alike(constraints: &Constraints, rest: &[Real], x: &[Real], v: &[Real], h: Real) -> usize {
        let found = |ignore_turning: bool, search_every_piece: bool| {
            let mut set = ContactSet::new(constraints, rest);
            set.ignore_turning = ignore_turning;
            set.search_every_piece = search_every_piece;
            set.detect(constraints, x, v, h, &Vector3::zeros());
            pairs_bit_for_bit(&set)
        };
        let turning = found(false, false);
        assert_eq!(turning, found(true, false), "mean velocities: x = {x:?}, v = {v:?}");
        assert_eq!(turning, found(false, true), "every piece: x = {x:?}, v = {v:?}");
        turning.0.len() + turning.1.len()
    }

    /// One piece whose two halves meet along an unfinished cut (two coinciding faces of opposite
    /// orientation, joined by a bridge triangle), turning fast as a whole (up to 45 rad/s, h|ω|
    /// up to 0.45) while the halves fold into each other: its points' searches of its own cut faces find the same pairs with the
    /// boxes bounded by its rigid motion as with those bounded by its mean velocity, in 3000
    /// random states. Leaf boxes that left out the spread of a triangle's corners' velocities
    /// (τ_t, which the search's reach holds) lost pairs here.
    #[test]
    fn own_cut_boxes_by_the_rigid_motion_find_what_boxes_by_the_mean_velocity_find() {
        let mut random = uniform(0x6a09_e667_f3bc_c909);
        let mut spin = || Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
        // A 4 × 4 grid of points per half (3 cm square), lower half 0–15, upper 16–31, and the
        // bridge's apex 32 beside the corner both halves share in the rest shape.
        let grid = |k: usize| Vector3::new(0.01 * (k % 4) as Real, 0.01 * (k / 4) as Real, 0.0);
        let mut triangles = Vec::new();
        for (half, up) in [(0u32, true), (16, false)] {
            for j in 0..3u32 {
                for i in 0..3u32 {
                    let [a, b, c, d] =
                        [i + 4 * j, i + 1 + 4 * j, i + 4 * (j + 1), i + 1 + 4 * (j + 1)].map(|k| k + half);
                    if up {
                        triangles.extend([[a, b, d], [a, d, c]]);
                    } else {
                        triangles.extend([[a, d, b], [a, c, d]]);
                    }
                }
            }
        }
        triangles.push([15, 31, 32]);
        let on_cut = (0..triangles.len()).map(|t| t < 36).collect();
        let rest: Vec<Real> = (0..33)
            .flat_map(|k| {
                let p = if k == 32 { Vector3::new(0.04, 0.04, 0.0) } else { grid(k % 16) };
                [p.x, p.y, p.z]
            })
            .collect();
        let mut points = Embedding::new();
        for i in 0..33u32 {
            points.push_row(&[i], &[1.0]);
        }
        let constraints = Constraints {
            contact_points: Some(points),
            surface_contact: Some(SurfaceContact {
                triangles,
                on_cut,
                piece: Vec::new(),
                stiffness: 1e4,
                damping: 0.0,
                friction: 0.0,
                thickness: 0.0,
                reach: 0.002,
                edge_contact: false,
            }),
            ..Default::default()
        };
        let (mut pairs, h) = (0, 0.01);
        for _ in 0..3000 {
            // The upper half folded about the shared corner's edge by a small angle, the whole
            // placed at random; velocities: a turn of up to 45 rad/s of the whole, a
            // folding of up to 2 rad/s, and up to 5 cm/s per point.
            let fold = nalgebra::Rotation3::new(Vector3::new(1.0, -1.0, 0.0).normalize() * 0.2 * spin().x);
            // Half the states unturned (the cut faces across z, where a box's gap is the
            // distance itself, not a fraction of it).
            let turn = match spin().x > 0.0 {
                true => nalgebra::Rotation3::new(spin() * 6.0),
                false => nalgebra::Rotation3::identity(),
            };
            let shift = spin() * 0.1;
            let (w, omega, folding) = (spin() * 2.0, spin() * 90.0, spin() * 4.0);
            let corner = grid(15);
            let (mut x, mut v) = (Vec::new(), Vec::new());
            for k in 0..33 {
                let r = Vector3::new(rest[3 * k], rest[3 * k + 1], rest[3 * k + 2]);
                let (p, own) = if (16..32).contains(&k) {
                    (corner + fold * (r - corner), folding.cross(&(r - corner)))
                } else {
                    (r, Vector3::zeros())
                };
                let placed = turn * p + shift;
                let u = w + omega.cross(&placed) + turn * own + spin() * 0.1;
                x.extend_from_slice(placed.as_slice());
                v.extend_from_slice(u.as_slice());
            }
            pairs += pairs_found_alike(&constraints, &rest, &x, &v, h);
        }
        println!("{pairs} pairs found alike");
        assert!(pairs > 1000, "too few pairs ({pairs}) for the comparison to mean anything");
    }

    /// A tetrahedron and a slab creeping about in 400 steps of at most a twentieth of the reach,
    /// turning and shaking, the tetrahedron hovering at the edge of the search (its lowest
    /// corners about a reach above the slab, which moves up and down): the set kept from step to step (whose whole-surface
    /// trees are refit only after a tenth of the reach of motion, their boxes loosened until
    /// then) finds the same pairs, bit for bit, as a set built afresh at every state. Searching
    /// the stale boxes without loosening them lost pairs here.
    #[test]
    fn trees_not_refit_yet_find_what_fresh_ones_find() {
        let (size, thick, reach) = (0.05, 0.004, 0.01);
        let (slab, slab_triangles) = slab(size, thick);
        let mut random = uniform(0xbb67_ae85_84ca_a73b);
        let mut spin = || Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
        let mut triangles = slab_triangles.clone();
        triangles.extend(TETRAHEDRON_TRIANGLES);
        let (mut centre, mut drift) = (Vector3::new(0.5 * size, 0.5 * size, thick + reach), Vector3::zeros());
        let mut turn = nalgebra::Rotation3::identity();
        let x_of = |centre: Vector3<Real>, turn: nalgebra::Rotation3<Real>, drift: Vector3<Real>| -> Vec<Real> {
            let corners = tetrahedron(turn, centre, 0.003);
            let slab = slab.iter().map(|p| Vector3::from(*p) + drift);
            slab.chain(corners).flat_map(|c| [c.x, c.y, c.z]).collect()
        };
        let (constraints, rest) = slab_and_tetrahedron(triangles, &x_of(centre, turn, drift));
        let mut kept = ContactSet::new(&constraints, &rest);
        let (h, mut pairs, mut stale_steps) = (0.01, 0, 0);
        for _ in 0..400 {
            // Each step moves every point by at most 0.5 mm (a twentieth of the reach).
            centre += spin() * 0.0004;
            centre.z = centre.z.clamp(thick + reach, thick + reach + 0.0025);
            drift.z = (drift.z + 0.0004 * spin().z).clamp(-0.002, 0.002);
            turn = nalgebra::Rotation3::new(spin() * 0.05) * turn;
            let x = x_of(centre, turn, drift);
            let v: Vec<Real> = (0..x.len()).map(|_| 0.2 * (spin().x)).collect();
            kept.detect(&constraints, &x, &v, h, &Vector3::zeros());
            let mut fresh = ContactSet::new(&constraints, &rest);
            fresh.detect(&constraints, &x, &v, h, &Vector3::zeros());
            assert_eq!(pairs_bit_for_bit(&kept), pairs_bit_for_bit(&fresh), "centre {centre:?}");
            pairs += kept.contacts.len() + kept.near.iter().flatten().count();
            stale_steps += usize::from(kept.staleness.iter().any(|&s| s > 0.0));
        }
        println!("{pairs} pairs alike, {stale_steps} of 400 steps searched trees not refit");
        assert!(pairs > 400 && stale_steps > 100, "{pairs} pairs, {stale_steps} steps with loosened trees");
    }

    /// Pieces that turn fast (up to a quarter radian per step) and deform a little: the search
    /// bounded by each piece's fitted rigid motion finds exactly the pairs, contacts and near
    /// pairs alike, that the search bounded by the mean velocities alone finds, in 3000 random
    /// poses of a small tetrahedron at a 5 cm slab whose faces are cut faces (so its points also
    /// search its own cut faces). A rigid bound that left out the turn of the searched piece
    /// between the point and the triangle (|ω| d) lost pairs here.
    #[test]
    fn bounds_by_the_rigid_motion_find_what_bounds_by_the_mean_velocity_find() {
        let (size, thick) = (0.05, 0.004);
        let (slab, slab_triangles) = slab(size, thick);
        let mut random = uniform(0x2545_f491_4f6c_dd1d);
        let mut spin = || Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
        let (mut pairs, h) = (0, 0.01);
        for _ in 0..3000 {
            let turn = nalgebra::Rotation3::new(spin() * 6.0);
            let offset = spin();
            let centre =
                Vector3::new(size * (1.0 + 0.3 * offset.x), size * (0.5 + offset.y), thick * (0.5 + 3.0 * offset.z));
            let corners = tetrahedron(turn, centre, 0.004);
            let x = slab_then_tetrahedron_dofs(&slab, &corners);
            // Each piece: a mean velocity, a turn of up to 25 rad/s about its centre, and a
            // deformation of up to 5 cm/s per point.
            let mut v = vec![0.0; x.len()];
            for points in [0..8, 8..12] {
                let count = points.len() as Real;
                let centre =
                    points.clone().map(|k| Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2])).sum::<Vector3<Real>>()
                        / count;
                let (w, omega) = (spin() * 2.0, spin() * 50.0);
                for k in points {
                    let r = Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]) - centre;
                    let u = w + omega.cross(&r) + spin() * 0.1;
                    v[3 * k..3 * k + 3].copy_from_slice(u.as_slice());
                }
            }
            let mut triangles = slab_triangles.clone();
            triangles.extend(TETRAHEDRON_TRIANGLES);
            let (mut constraints, rest) = slab_and_tetrahedron(triangles, &x);
            if let Some(surface) = constraints.surface_contact.as_mut() {
                surface.on_cut = (0..16).map(|t| t < 12).collect();
            }
            pairs += pairs_found_alike(&constraints, &rest, &x, &v, h);
        }
        println!("{pairs} pairs found alike");
        assert!(pairs > 1000, "too few pairs ({pairs}) for the comparison to mean anything");
    }

    /// A small tetrahedron above a 5 cm slab, farther from it than the reach (1–4 cm against
    /// 1 cm) but closing fast (up to 3 m/s, h = 0.01 s, turning), the slab moving too: the pairs
    /// of pieces ruled in once per step (their root boxes against the loosest radius of any
    /// point) keep every pair that searching every other piece from every point finds, in 3000
    /// random states. A filter that left out the searching piece's own motion lost pairs here.
    #[test]
    fn the_pair_filter_keeps_every_pair_searching_every_piece_finds() {
        let (size, thick) = (0.05, 0.004);
        let (slab, slab_triangles) = slab(size, thick);
        let mut random = uniform(0x9e37_79b9_7f4a_7c15);
        let mut spin = || Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
        let (mut pairs, h) = (0, 0.01);
        for _ in 0..3000 {
            let turn = nalgebra::Rotation3::new(spin() * 6.0);
            let offset = spin();
            let centre = Vector3::new(
                size * (0.5 + 0.6 * offset.x),
                size * (0.5 + 0.6 * offset.y),
                thick + 0.025 + 0.06 * offset.z,
            );
            let corners = tetrahedron(turn, centre, 0.004);
            let x = slab_then_tetrahedron_dofs(&slab, &corners);
            let mut v = vec![0.0; x.len()];
            let slab_velocity = spin() * 2.0;
            for k in 0..8 {
                v[3 * k..3 * k + 3].copy_from_slice(slab_velocity.as_slice());
            }
            let (closing, omega) = (Vector3::new(0.0, 0.0, -3.0 * (spin().z + 0.5)) + spin(), spin() * 20.0);
            for (k, corner) in corners.iter().enumerate() {
                let u = closing + omega.cross(&(corner - centre));
                v[24 + 3 * k..27 + 3 * k].copy_from_slice(u.as_slice());
            }
            let mut triangles = slab_triangles.clone();
            triangles.extend(TETRAHEDRON_TRIANGLES);
            let (constraints, rest) = slab_and_tetrahedron(triangles, &x);
            pairs += pairs_found_alike(&constraints, &rest, &x, &v, h);
        }
        println!("{pairs} pairs found alike");
        assert!(pairs > 500, "too few pairs ({pairs}) for the comparison to mean anything");
    }

    /// Surface points of a small tetrahedron tossed around the rim of a thin slab (4 mm, thinner
    /// than twice the reach) in 3000 random poses: every point–triangle contact of a tetrahedron
    /// point is exactly the slab's analytic signed distance where the point is inside the slab,
    /// and there is none where it is outside. A facing filter that skipped the nearest face and
    /// took a farther one gave points on or beside the rim depths of up to the slab's thickness
    /// (docs/math/contact.md §5).
    #[test]
    fn surface_contact_depth_is_the_signed_distance_of_the_other_piece() {
        let (size, thick) = (1.0, 0.004);
        let (slab, slab_triangles) = slab(size, thick);
        let inside_depth = |p: &Point3<Real>| {
            let d = [p.x, size - p.x, p.y, size - p.y, p.z, thick - p.z];
            d.iter().all(|&d| d > 0.0).then(|| d.iter().copied().fold(Real::MAX, Real::min))
        };
        let mut random = uniform(0x9e37_79b9_7f4a_7c15);
        let (mut inside_points, mut checked) = (0, 0);
        for _ in 0..3000 {
            // A regular tetrahedron of edge ~6 mm, randomly turned, centred within 6 mm of the
            // slab's edge x = 1 at a random height around the slab.
            let axis = Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
            let turn = nalgebra::Rotation3::new(axis * 6.0);
            let centre = Vector3::new(size + 0.012 * (random() - 0.5), 0.5, thick * (3.0 * random() - 1.0));
            let corners = tetrahedron(turn, centre, 0.002);
            let x = slab_then_tetrahedron_dofs(&slab, &corners);
            let mut triangles = slab_triangles.clone();
            triangles.extend(TETRAHEDRON_TRIANGLES);
            let (constraints, rest) = slab_and_tetrahedron(triangles, &x);
            let mut set = ContactSet::new(&constraints, &rest);
            set.detect(&constraints, &x, &vec![0.0; x.len()], 0.01, &Vector3::zeros());
            for k in 8..12u32 {
                let p = Point3::from(corners[k as usize - 8]);
                let contact = set.contacts.iter().find(|c| c.kind == ContactKind::Surface && c.row.points[0] == k);
                match (inside_depth(&p), contact) {
                    (Some(depth), Some(c)) => {
                        inside_points += 1;
                        assert!(
                            (c.depth + depth).abs() < 1e-12,
                            "point {p} is {depth} m inside, contact depth {}",
                            c.depth
                        );
                    }
                    (Some(depth), None) => panic!("point {p} is {depth} m inside the slab and has no contact"),
                    (None, Some(c)) => {
                        assert!(c.depth >= -1e-12, "point {p} is outside the slab and has contact depth {}", c.depth)
                    }
                    (None, None) => {}
                }
                checked += 1;
            }
        }
        println!("{checked} points, {inside_points} inside the slab");
        assert!(inside_points > 300, "the poses must put many points inside the slab");
    }

    /// A point closing on a slab's rim from just beyond its top edge (0.05–0.3 mm past the
    /// side, 0.5–3 mm above the top, falling at 1 m/s): its nearest feature is the edge, equally
    /// near the top face (which it projects into within the sideways tolerance, and faces) and
    /// the side face (which it does not face). It must meet the top face whatever the order of
    /// the slab's triangles and of their corners, in a randomly turned and moved scene. Taking
    /// whichever face the search met first gave no contact in some of these (a rounding-level
    /// tie between the two faces).
    #[test]
    fn a_pair_at_an_edge_does_not_depend_on_the_order_of_the_triangles() {
        let (size, thick) = (1.0, 0.004);
        let (slab, slab_triangles) = slab(size, thick);
        let mut random = uniform(0x2545_f491_4f6c_dd1d);
        let mut met = 0;
        for trial in 0..200 {
            // A tetrahedron with its apex (point 8) down: the apex's vertex normal points down.
            let apex = Vector3::new(
                size + 1e-4 * (0.5 + 2.5 * random()),
                0.2 + 0.6 * random(),
                thick + 1e-3 * (0.5 + 2.5 * random()),
            );
            let top: Vec<Vector3<Real>> = (0..3)
                .map(|k| {
                    let angle = 2.0 * std::f64::consts::PI * k as Real / 3.0 + random();
                    apex + Vector3::new(0.002 * angle.cos(), 0.002 * angle.sin(), 0.003)
                })
                .collect();
            let axis = Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
            let turn = nalgebra::Rotation3::new(axis * 6.0);
            let shift = Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
            let place = |c: Vector3<Real>| turn * c + shift;
            let x: Vec<Real> = slab
                .iter()
                .map(|&c| Vector3::from(c))
                .chain(std::iter::once(apex).chain(top))
                .flat_map(|c| place(c).data.0[0])
                .collect();
            let down = turn * -Vector3::z();
            let v: Vec<Real> = (0..x.len()).map(|i| if i >= 24 { down[i % 3] } else { 0.0 }).collect();
            // The three side faces seen from outside, counter-clockwise, and the top.
            let tetrahedron = [[8, 10, 9], [8, 11, 10], [8, 9, 11], [9, 10, 11]];
            for order in 0..4 {
                let mut triangles = slab_triangles.clone();
                if order & 1 == 1 {
                    triangles.reverse();
                }
                if order & 2 == 2 {
                    triangles.iter_mut().for_each(|t| t.rotate_left(1));
                }
                triangles.extend(tetrahedron);
                let (constraints, rest) = slab_and_tetrahedron(triangles, &x);
                let mut set = ContactSet::new(&constraints, &rest);
                set.detect(&constraints, &x, &v, 0.01, &Vector3::zeros());
                let contact = set.contacts.iter().find(|c| c.kind == ContactKind::Surface && c.row.points[0] == 8);
                let Some(contact) = contact else {
                    panic!("trial {trial}, order {order}: the apex {apex:?} closing on the top face has no contact")
                };
                assert!(
                    (contact.normal + down).norm() < 1e-12,
                    "trial {trial}, order {order}: normal {:?}",
                    contact.normal
                );
                assert!(
                    (contact.depth - (apex.z - thick)).abs() < 1e-12,
                    "trial {trial}, order {order}: gap {}",
                    contact.depth
                );
                met += 1;
            }
        }
        assert_eq!(met, 800);
    }

    #[test]
    fn contact_forces_are_the_negative_gradient_of_the_contact_energy() {
        for (constraints, x, rest) in [setup(), crossing_edges()] {
            forces_are_the_negative_gradient(constraints, x, rest);
        }
    }

    fn forces_are_the_negative_gradient(constraints: Constraints, x: Vec<Real>, rest: Vec<Real>) {
        let points = constraints.contact_points.as_ref().unwrap();
        let mut set = ContactSet::new(&constraints, &rest);
        set.detect(&constraints, &x, &vec![0.0; x.len()], 0.01, &Vector3::zeros());
        let kinds = set.stats();
        assert!((kinds.surface > 0 && kinds.planes > 0) || kinds.edges > 0, "{kinds:?}");
        let mut force = vec![0.0; x.len()];
        add_forces(points, &set.contacts, &mut force);
        let mut worst: Real = 0.0;
        let scale = force.iter().map(|f| f.abs()).fold(0.0, Real::max);
        for i in 0..x.len() {
            let eps = 1e-7;
            let (mut plus, mut minus) = (x.clone(), x.clone());
            plus[i] += eps;
            minus[i] -= eps;
            let derivative =
                (energy(points, &set.contacts, &plus).0 - energy(points, &set.contacts, &minus).0) / (2.0 * eps);
            worst = worst.max((derivative + force[i]).abs());
        }
        println!("{kinds:?}; largest |dE/dx + f| = {worst:.2e} of |f| up to {scale:.2e}");
        assert!(worst < 1e-6 * scale);
    }

    #[test]
    fn surface_contact_forces_have_no_net_force_or_torque() {
        for (mut constraints, x, rest) in [setup(), crossing_edges()] {
            constraints.planes.clear();
            no_net_force_or_torque(constraints, x, rest);
        }
    }

    fn no_net_force_or_torque(constraints: Constraints, x: Vec<Real>, rest: Vec<Real>) {
        let points = constraints.contact_points.as_ref().unwrap().clone();
        let mut set = ContactSet::new(&constraints, &rest);
        set.detect(&constraints, &x, &vec![0.0; x.len()], 0.01, &Vector3::zeros());
        let stats = set.stats();
        assert!(stats.surface + stats.edges >= 1);
        let mut force = vec![0.0; x.len()];
        add_forces(&points, &set.contacts, &mut force);
        // The implicit part as well: the action of the contact matrix on any velocity.
        let v: Vec<Real> = (0..x.len()).map(|i| ((i * 7 % 5) as Real - 2.0) * 0.3).collect();
        let mut action = vec![0.0; x.len()];
        add_action(&points, &set.contacts, &v, &mut action);
        for (what, f) in [("force", &force), ("matrix action", &action)] {
            let (mut total, mut torque) = (Vector3::zeros(), Vector3::zeros());
            let mut size: Real = 0.0;
            for k in 0..6 {
                let fk = Vector3::new(f[3 * k], f[3 * k + 1], f[3 * k + 2]);
                total += fk;
                torque += Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]).cross(&fk);
                size = size.max(fk.norm());
            }
            println!(
                "{what}: net force {:.1e}, net torque {:.1e}, largest nodal force {size:.2e}",
                total.norm(),
                torque.norm()
            );
            assert!(size > 0.0 && total.norm() < 1e-12 * size && torque.norm() < 1e-12 * size, "{what}");
        }
    }
}
