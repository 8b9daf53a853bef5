//! The contact row and its penalty law: which surface points a contact combines, the force and
//! the linearized matrix `P` it contributes (normal penalty, damping and regularized Coulomb
//! friction), and the loops that visit a row's nodes (docs/math/contact.md §1, §4).

use cleave_core::{Embedding, Matrix3, Real, Vector3};

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
pub struct Row {
    /// Surface points (indices into the contact points).
    pub points: [u32; 4],
    /// Their weights in the row.
    pub weights: [Real; 4],
    /// How many entries are used.
    pub len: u8,
}

impl Row {
    /// One point against a collider.
    pub(crate) fn point(i: u32) -> Self {
        Row { points: [i, 0, 0, 0], weights: [1.0, 0.0, 0.0, 0.0], len: 1 }
    }

    /// Point `i` minus the point of triangle `tri` at barycentric `beta`.
    pub(crate) fn vertex_triangle(i: u32, tri: [u32; 3], beta: [Real; 3]) -> Self {
        Row { points: [i, tri[0], tri[1], tri[2]], weights: [1.0, -beta[0], -beta[1], -beta[2]], len: 4 }
    }

    /// The point at `s` of edge `a` minus the point at `t` of edge `b`.
    pub(crate) fn edge_edge(a: [u32; 2], s: Real, b: [u32; 2], t: Real) -> Self {
        Row { points: [a[0], a[1], b[0], b[1]], weights: [1.0 - s, s, t - 1.0, -t], len: 4 }
    }

    /// The used `(point, weight)` entries.
    pub fn entries(&self) -> impl Iterator<Item = (u32, Real)> + '_ {
        self.points.iter().copied().zip(self.weights.iter().copied()).take(self.len as usize)
    }
}

/// One active contact of a step.
#[derive(Clone, Copy, Debug)]
pub struct Contact {
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
    /// What the row pushes against.
    pub kind: ContactKind,
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
pub(crate) fn make_contact(
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

/// Visits the entries `(node, weight)` of a contact's row: each surface point's embedding row
/// scaled by the point's weight in the row. A node may occur more than once (point and
/// triangle in one element); every sum below treats the entries as a sum, which is exact.
#[inline]
pub fn for_each_entry(points: &Embedding, contact: &Contact, mut visit: impl FnMut(u32, Real)) {
    for (point, scale) in contact.row.entries() {
        let (nodes, weights) = points.row(point as usize);
        for (&n, &w) in nodes.iter().zip(weights) {
            visit(n, scale * w);
        }
    }
}

/// `Σ_entries w v_node` over a contact's row.
#[inline]
pub fn row_value(points: &Embedding, contact: &Contact, v: &[Real]) -> Vector3<Real> {
    let mut sum = Vector3::zeros();
    for_each_entry(points, contact, |n, w| {
        let i = 3 * n as usize;
        sum += Vector3::new(v[i], v[i + 1], v[i + 2]) * w;
    });
    sum
}

/// `force += Σ w ⊗ f` over the contacts.
pub fn add_forces(points: &Embedding, contacts: &[Contact], force: &mut [Real]) {
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
pub fn energy(points: &Embedding, contacts: &[Contact], x: &[Real]) -> (Real, usize) {
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

/// `out += Σ (w wᵀ ⊗ P) p` over the contacts (the full rows: matrix-free path).
pub fn add_action(points: &Embedding, contacts: &[Contact], p: &[Real], out: &mut [Real]) {
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
pub fn add_diagonal_blocks(points: &Embedding, contacts: &[Contact], blocks: &mut [Matrix3<Real>]) {
    for c in contacts {
        for_each_entry(points, c, |n, w| blocks[n as usize] += c.matrix * (w * w));
    }
}
