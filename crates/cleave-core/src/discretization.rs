//! The `Discretization` trait: what the integrator, the scene runner and the conformance suite
//! know about a backend. Object safe; called a few times per time step on whole DOF vectors.

use crate::blocks::BlockSet;
use crate::embedding::{EmbedError, Embedding};
use crate::mass::Mass;
use crate::{Matrix3, Point3, Real, Vector3};

/// What `write_rotations` found about the current deformation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RotationStats {
    /// Frames whose fitted deformation gradient has `det F ≤ 0`.
    pub inverted: usize,
}

/// The displacement field and its gradient at one quadrature point of a backend's own rule.
#[derive(Clone, Copy, Debug)]
pub struct FieldSample {
    /// Rest position of the point.
    pub position: Point3<Real>,
    /// Quadrature weight (volume measure).
    pub weight: Real,
    /// Displacement `u_h` at the point.
    pub displacement: Vector3<Real>,
    /// Displacement gradient `∇u_h`, `[i][j] = ∂u_i/∂X_j`.
    pub gradient: Matrix3<Real>,
}

/// A coarse space for two-level preconditioners: every node of the discretization as a weighted
/// combination of coarse nodes (the prolongation `P`, acting on each of the three components
/// alike). Built once per epoch by backends that have a natural coarsening (voxels: cubes of 2h
/// with trilinear interpolation).
#[derive(Clone, Debug)]
pub struct CoarseSpace {
    /// Number of coarse 3-vector nodes.
    pub num_nodes: usize,
    /// Row `k` = fine node `k` as `Σ w_c · coarse_c`; the rows must span the rigid motions.
    pub prolongation: Embedding,
}

/// How state maps across a topology change.
#[derive(Clone, Debug, PartialEq)]
pub enum DofRemap {
    /// Same DOFs as before.
    Identity,
    /// New node `k` copies old node `src[k]` (duplicated nodes of a cut or fracture).
    Gather(Vec<u32>),
    /// New node `k` = `Σ w · old node` over row `k` (nodes interpolated on a cut, re-projected DG
    /// coefficients). A `Gather` is the special case of one weight 1 per row.
    Linear(Embedding),
}

impl DofRemap {
    /// Maps a DOF vector of the old epoch to the new one.
    pub fn apply(&self, old: &[Real]) -> Vec<Real> {
        let mut new = Vec::new();
        self.apply_into(old, &mut new);
        new
    }

    /// Maps a DOF vector of the old epoch into `new` (cleared and refilled; its allocation is
    /// reused).
    pub fn apply_into(&self, old: &[Real], new: &mut Vec<Real>) {
        new.clear();
        match self {
            DofRemap::Identity => new.extend_from_slice(old),
            DofRemap::Gather(src) => {
                for &s in src {
                    new.extend_from_slice(&old[3 * s as usize..3 * s as usize + 3]);
                }
            }
            DofRemap::Linear(rows) => {
                for k in 0..rows.len() {
                    let p = rows.point(old, k);
                    new.extend_from_slice(&[p.x, p.y, p.z]);
                }
            }
        }
    }

    /// Number of nodes after the change, given the number before.
    pub fn new_num_nodes(&self, old_num_nodes: usize) -> usize {
        match self {
            DofRemap::Identity => old_num_nodes,
            DofRemap::Gather(src) => src.len(),
            DofRemap::Linear(rows) => rows.len(),
        }
    }
}

/// How rotation frames map across a topology change (warm starts for `write_rotations`).
#[derive(Clone, Debug, PartialEq)]
pub enum FrameRemap {
    /// Same frames as before.
    Identity,
    /// New frame `k` starts from the rotation of old frame `src[k]` (the element it was cut from).
    Gather(Vec<u32>),
}

impl FrameRemap {
    /// Maps the rotations of the old epoch to the new one.
    pub fn apply(&self, old: &[Matrix3<Real>]) -> Vec<Matrix3<Real>> {
        match self {
            FrameRemap::Identity => old.to_vec(),
            FrameRemap::Gather(src) => src.iter().map(|&s| old[s as usize]).collect(),
        }
    }
}

/// The outcome of a topology change.
#[derive(Clone, Debug, PartialEq)]
pub struct TopologyChange {
    /// The new epoch.
    pub epoch: u64,
    /// How to carry `x`, `v` and any history across.
    pub remap: DofRemap,
    /// How to carry the rotation frames across.
    pub frames: FrameRemap,
    /// Whether the stiffness pattern changed (so symbolic factorizations must be redone).
    pub pattern_changed: bool,
}

/// A topology change that could not be carried out.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TopologyError {
    /// The request was malformed (e.g. a zero normal).
    #[error("invalid topology request: {0}")]
    Invalid(String),
}

/// A cutting surface in rest (material) coordinates.
#[derive(Clone, Debug, PartialEq)]
pub enum CutSurface {
    /// The plane through `point` with normal `normal` (need not be unit).
    Plane {
        /// a point on the plane
        point: Point3<Real>,
        /// its normal
        normal: Vector3<Real>,
    },
    /// A triangle soup: arbitrary triangles, possibly open, non-manifold, self-intersecting or
    /// degenerate (zero area). Material is separated exactly where a triangle covers it.
    Triangles(Vec<[Point3<Real>; 3]>),
}

/// The render surface of a cut (or cuttable) body in its current topology: the original surface
/// clipped to the material that owns it plus the faces cuts have opened, each vertex embedded in
/// the element that owns it. Every piece's surface is closed.
#[derive(Clone, Debug, Default)]
pub struct EmbeddedSurface {
    /// Vertex positions in rest space (vertices of different pieces may coincide).
    pub rest_vertices: Vec<Point3<Real>>,
    /// Outward triangles over the vertices.
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle: lies on a cut (`true`) or on the original surface.
    pub on_cut: Vec<bool>,
    /// Per triangle: the piece (index into `Cuttable::pieces`) it bounds.
    pub piece: Vec<u32>,
    /// Per vertex, the row that evaluates it from the DOFs.
    pub embedding: Embedding,
}

/// A connected component of a discretization: the one piece type of every backend.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Piece {
    /// Its elements (duplicates, polyhedra, cubes: frame indices), ascending.
    pub elements: Vec<u32>,
    /// Its nodes, ascending.
    pub nodes: Vec<u32>,
    /// Material volume [m³].
    pub volume: Real,
    /// Mass [kg].
    pub mass: Real,
}

/// Backends that can be cut by a surface.
pub trait Cuttable {
    /// Cuts the material along `surface` at the rest configuration. A cut that separates
    /// nothing returns a change with the current epoch and `DofRemap::Identity`, which the
    /// integrator skips.
    fn cut(&mut self, surface: &CutSurface) -> Result<TopologyChange, TopologyError>;

    /// The render surface of the current topology, if the backend makes its own (cut bodies
    /// must: the input surface no longer describes them).
    fn surface(&self) -> Option<EmbeddedSurface> {
        None
    }

    /// The connected components of the current topology with their volume and mass.
    fn pieces(&self) -> Vec<Piece> {
        Vec::new()
    }
}

/// Backends that fracture under tensile stress.
pub trait Fracturable {
    /// Separates elements whose largest principal stress at positions `x` exceeds `threshold`
    /// (Pa); `None` if nothing broke.
    fn fracture(
        &mut self,
        x: &[Real],
        rotations: &[Matrix3<Real>],
        threshold: Real,
    ) -> Result<Option<TopologyChange>, TopologyError>;
}

/// Backends that refine adaptively.
pub trait Refinable {
    /// Refines the elements whose largest absolute principal stress at positions `x` (element
    /// frames `rotations`, as for [`Fracturable::fracture`]) exceeds `threshold` (Pa); the field
    /// is carried across exactly. `None` if nothing was refined.
    fn refine(
        &mut self,
        x: &[Real],
        rotations: &[Matrix3<Real>],
        threshold: Real,
    ) -> Result<Option<TopologyChange>, TopologyError>;
}

/// A spatial discretization of an elastic solid, seen through its warped stiffness blocks.
///
/// DOFs are 3-vectors ("nodes"); every slice argument is flat of length `3 * num_nodes()`.
pub trait Discretization: Send + Sync {
    /// Short backend name for reports ("voxel", "dg-ip-2", …).
    fn name(&self) -> &str;

    /// Number of 3-vector DOFs.
    fn num_nodes(&self) -> usize;

    /// `X0`: the DOF vector whose field is the identity map `x ↦ x`.
    fn rest_dofs(&self) -> &[Real];

    /// `x += T(t)`, the DOFs of the constant field `t` (a translation). The default adds `t` to
    /// every node, right for nodal bases (which sum to one); non-nodal bases (DG) override it.
    fn add_translation(&self, t: &Vector3<Real>, x: &mut [Real]) {
        for p in x.chunks_exact_mut(3) {
            for a in 0..3 {
                p[a] += t[a];
            }
        }
    }

    /// Bumped at every topology change.
    fn epoch(&self) -> u64;

    /// The mass matrix.
    fn mass(&self) -> &Mass;

    /// Number of rotation frames (usually one per element).
    fn num_frames(&self) -> usize;

    /// Writes one proper rotation per frame for positions `x`. `rotations` holds the previous
    /// rotations on entry (a warm start; identity at the first call of an epoch).
    fn write_rotations(&self, x: &[Real], rotations: &mut [Matrix3<Real>]) -> RotationStats;

    /// The stiffness as warped blocks over a rest-matrix library.
    fn blocks(&self) -> &BlockSet;

    /// Whether an assembled stiffness pays off for this backend; `false` = matrix-free only.
    fn wants_assembly(&self) -> bool {
        true
    }

    /// `out += −Σ_b R K (Rᵀ x_b − X_b)`. Backends may override with a faster kernel; the
    /// conformance suite checks it against the shared one.
    fn add_internal_force(&self, rotations: &[Matrix3<Real>], x: &[Real], out: &mut [Real]) {
        self.blocks().add_internal_force(rotations, x, self.rest_dofs(), out);
    }

    /// `out += s · Σ_b R K Rᵀ dx_b`. Backends may override with a faster kernel.
    fn add_stiffness_action(&self, rotations: &[Matrix3<Real>], dx: &[Real], scale: Real, out: &mut [Real]) {
        self.blocks().add_stiffness_action(rotations, dx, scale, out);
    }

    /// Elastic energy of the warped linear model at `x`.
    fn elastic_energy(&self, rotations: &[Matrix3<Real>], x: &[Real]) -> Real {
        self.blocks().elastic_energy(rotations, x, self.rest_dofs())
    }

    /// `out += ∫ f(X) N_k dV` for a force density `f` [N/m³] given at rest positions (gravity is
    /// `ρ g`), integrated with a rule exact for the backend's shape functions times a quadratic.
    fn add_load(&self, force_density: &dyn Fn(&Point3<Real>) -> Vector3<Real>, out: &mut [Real]);

    /// `out += ∫ ρ g N_k dV`: the gravity load. The default, `M g` per node, is exact for nodal
    /// bases with a lumped mass whose rows sum to the consistent mass; backends whose DOFs are not
    /// nodal values (DG) override it.
    fn add_gravity_load(&self, gravity: &Vector3<Real>, out: &mut [Real]) {
        for (f, m) in out.chunks_exact_mut(3).zip(self.mass().diagonal().chunks_exact(3)) {
            for a in 0..3 {
                f[a] += m[a] * gravity[a];
            }
        }
    }

    /// Embeds rest-space points: one row of (node, weight) pairs per point. Exact evaluation of the
    /// discrete field (probes, pins).
    fn embed(&self, points: &[Point3<Real>]) -> Result<Embedding, EmbedError>;

    /// Embeds surface points for rendering and contact. Defaults to [`Discretization::embed`];
    /// a discontinuous backend returns a smooth (e.g. MLS) embedding instead.
    fn embed_surface(&self, points: &[Point3<Real>]) -> Result<Embedding, EmbedError> {
        self.embed(points)
    }

    /// Visits the displacement field `u = x − X0` and its gradient at the quadrature points of a
    /// rule of at least `min_degree` exactness per element (for error norms).
    fn visit_field(&self, displacement: &[Real], min_degree: usize, visit: &mut dyn FnMut(&FieldSample));

    /// A coarse space for the two-level CG preconditioner, if the backend has one.
    fn coarse_space(&self) -> Option<CoarseSpace> {
        None
    }

    /// Cutting, if supported.
    fn as_cuttable(&mut self) -> Option<&mut dyn Cuttable> {
        None
    }

    /// A copy of this body that a cut known ahead can be applied to off the step's thread and
    /// swapped in when it is due (the scene runner prepares a timeline `Cut` this way, copy
    /// included, while the steps before it run); `None` if the backend cannot copy itself or
    /// cannot cut: the cut is then made when due.
    fn copy_for_cutting(&self) -> Option<Box<dyn Discretization>> {
        None
    }

    /// Fracture, if supported.
    fn as_fracturable(&mut self) -> Option<&mut dyn Fracturable> {
        None
    }

    /// Adaptive refinement, if supported.
    fn as_refinable(&mut self) -> Option<&mut dyn Refinable> {
        None
    }

    /// The nodes whose values impose Dirichlet data strongly on the part of the boundary inside
    /// `region` (rest space), ascending. Scenes' pins and the comparisons' boundary data both
    /// resolve through it. The default, every node whose rest position lies in `region`, is
    /// right for nodal bases whose shape functions vanish on the boundary away from their node;
    /// backends whose elements reach past the boundary (virtual node's carved tetrahedra)
    /// override it. Weak backends (DG) impose data through their boundary terms instead.
    fn dirichlet_nodes(&self, region: &dyn Fn(&Point3<Real>) -> bool) -> Vec<u32> {
        let rest = self.rest_dofs();
        (0..rest.len() / 3)
            .filter(|&k| region(&Point3::new(rest[3 * k], rest[3 * k + 1], rest[3 * k + 2])))
            .map(|k| k as u32)
            .collect()
    }
}
