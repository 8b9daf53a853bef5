//! What contact points are tested against: plane colliders, static triangle mesh colliders, the
//! body's own surface, and [`Colliders`], the borrowed set of them that a detection reads.

use cleave_core::{Embedding, Point3, Real, Vector3};
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector as ParryVector;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy};

/// A half-space `n · (p − point) ≥ 0` that embedded contact points may not leave.
#[derive(Clone, Debug)]
pub struct PlaneCollider {
    /// A point on the plane.
    pub point: Point3<Real>,
    /// Unit outward normal (into the allowed side).
    pub normal: Vector3<Real>,
    /// Penalty stiffness per contact point [N/m].
    pub stiffness: Real,
    /// Normal damping per contact point [N·s/m].
    pub damping: Real,
    /// Coulomb friction coefficient μ (0: frictionless).
    pub friction: Real,
}

/// A static triangle mesh that embedded contact points may not pass (a table, a bowl): the
/// allowed side is the one its triangles' right-hand normals point to.
#[derive(Clone)]
pub struct MeshCollider {
    pub(crate) vertices: Vec<Point3<Real>>,
    pub(crate) triangles: Vec<[u32; 3]>,
    pub(crate) normals: Vec<Vector3<Real>>,
    pub(crate) bvh: Bvh,
    /// Penalty stiffness per contact point [N/m].
    pub stiffness: Real,
    /// Normal damping per contact point [N·s/m].
    pub damping: Real,
    /// Coulomb friction coefficient μ.
    pub friction: Real,
    /// How far from the mesh (either side) a point is still tested [m]: deeper penetration is
    /// lost (a thin wall is passed), so it should exceed the deepest expected penetration.
    pub reach: Real,
}

impl std::fmt::Debug for MeshCollider {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshCollider")
            .field("triangles", &self.triangles.len())
            .field("stiffness", &self.stiffness)
            .field("friction", &self.friction)
            .finish()
    }
}

/// Why a mesh collider cannot be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshColliderError {
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} names vertex {vertex}, but the mesh has {vertices} vertices")]
    VertexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// The vertex it names.
        vertex: u32,
        /// Vertices in the mesh.
        vertices: usize,
    },
    /// A vertex coordinate is not finite.
    #[error("vertex {0} has a non-finite coordinate")]
    NotFinite(usize),
    /// No triangle has a positive area.
    #[error("the mesh has no triangle of positive area")]
    Empty,
}

impl MeshCollider {
    /// Builds the collider and its bounding volume hierarchy; zero-area triangles are dropped.
    pub fn new(
        vertices: Vec<Point3<Real>>,
        triangles: Vec<[u32; 3]>,
        stiffness: Real,
        damping: Real,
        friction: Real,
        reach: Real,
    ) -> Result<Self, MeshColliderError> {
        if let Some(i) = vertices.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
            return Err(MeshColliderError::NotFinite(i));
        }
        let mut kept = Vec::with_capacity(triangles.len());
        let mut normals = Vec::with_capacity(triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            if let Some(&vertex) = tri.iter().find(|&&v| v as usize >= vertices.len()) {
                return Err(MeshColliderError::VertexOutOfRange { triangle: t, vertex, vertices: vertices.len() });
            }
            let [a, b, c] = tri.map(|v| vertices[v as usize]);
            if let Some(n) = (b - a).cross(&(c - a)).try_normalize(0.0) {
                kept.push(*tri);
                normals.push(n);
            }
        }
        if kept.is_empty() {
            return Err(MeshColliderError::Empty);
        }
        let leaves: Vec<Aabb> = kept
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| vertices[v as usize]);
                let (lo, hi) = (a.inf(&b).inf(&c), a.sup(&b).sup(&c));
                Aabb::new(ParryVector::new(lo.x, lo.y, lo.z), ParryVector::new(hi.x, hi.y, hi.z))
            })
            .collect();
        let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves);
        Ok(Self { vertices, triangles: kept, normals, bvh, stiffness, damping, friction, reach })
    }

    /// Number of (non-degenerate) triangles.
    pub fn num_triangles(&self) -> usize {
        self.triangles.len()
    }
}

/// Contact between the body's surface points and its own surface triangles: between the
/// pieces of a cut body and within one piece (the two faces of an unfinished cut, a flap).
/// The points are [`Colliders::points`]; the triangles index them.
#[derive(Clone, Debug)]
pub struct SurfaceContact {
    /// Triangles over the contact points, counter-clockwise seen from outside the material.
    pub triangles: Vec<[u32; 3]>,
    /// Whether each triangle lies on a cut (empty: none does). Within one piece only cut
    /// triangles are searched: the two faces of an unfinished cut meet there, while a point's
    /// own smooth surface around it is never a contact.
    pub on_cut: Vec<bool>,
    /// The piece each triangle bounds (empty: each connected part of the surface is a piece).
    /// A piece's surface need not be connected: a crack that ends inside the material leaves
    /// a closed two-sided sheet within it, not joined to the piece's outer surface, whose
    /// points lie inside that surface. Taken as a body of its own, the sheet would penetrate its
    /// own piece by up to the reach at rest (docs/math/contact.md §5).
    pub piece: Vec<u32>,
    /// Penalty stiffness per contact point [N/m].
    pub stiffness: Real,
    /// Normal damping per contact point [N·s/m].
    pub damping: Real,
    /// Coulomb friction coefficient μ.
    pub friction: Real,
    /// Distance the surfaces are held apart [m] (0: touching; faces of one cut coincide at
    /// rest, and any positive thickness would push them apart at the instant of the cut).
    pub thickness: Real,
    /// How far from a triangle a point is still tested, beyond its motion in the step [m].
    pub reach: Real,
    /// Whether the sharp (feature) edges of each piece are also tested against the sharp edges of the
    /// other pieces (edge–edge contact; docs/math/contact.md §2). Without it, two edges that
    /// cross between the surface points of both pass into each other until points meet faces.
    pub edge_contact: bool,
}

/// Everything a detection reads: the contact points (embedded surface points, e.g. the render
/// surface's vertices) and what they are tested against. Borrowed, so a caller keeps its
/// colliders wherever it likes (the integrator's `Constraints`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Colliders<'a> {
    /// Points tested against the colliders (`None`: nothing is tested).
    pub points: Option<&'a Embedding>,
    /// Plane colliders.
    pub planes: &'a [PlaneCollider],
    /// Static triangle mesh colliders.
    pub meshes: &'a [MeshCollider],
    /// Contact of the body's surface with itself (its triangles index `points`).
    pub surface: Option<&'a SurfaceContact>,
}
