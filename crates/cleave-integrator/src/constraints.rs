//! Boundary conditions the integrator applies through `embed` rows and DOF masks: pinned DOFs
//! (eliminated), penalty pins and plane colliders (implicit penalty stiffness).

use cleave_core::{Embedding, Point3, Real, Vector3};

/// Material points held at targets by springs (for rows that are not a single node).
#[derive(Clone, Debug)]
pub struct PenaltyPins {
    /// The embedded points.
    pub points: Embedding,
    /// Target position of each point.
    pub targets: Vec<Point3<Real>>,
    /// Spring stiffness per point [N/m].
    pub stiffness: Real,
}

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
}

/// All boundary conditions of a run.
#[derive(Clone, Debug, Default)]
pub struct Constraints {
    /// Scalar DOFs held fixed at their current value (velocity zero).
    pub pinned_dofs: Vec<usize>,
    /// Penalty pins.
    pub penalty_pins: Option<PenaltyPins>,
    /// Points tested against the colliders (e.g. the embedded surface vertices).
    pub contact_points: Option<Embedding>,
    /// Plane colliders.
    pub planes: Vec<PlaneCollider>,
    /// A constant load added to gravity, one entry per scalar DOF (empty = none): the boundary
    /// terms of weakly imposed Dirichlet data (DG), which backends hand over as a vector.
    pub extra_load: Vec<Real>,
}

impl Constraints {
    /// Node groups that penalty terms couple (for the sparsity pattern).
    pub(crate) fn coupling_groups(&self) -> impl Iterator<Item = &[u32]> {
        let pins = self.penalty_pins.iter().flat_map(|p| p.points.node_groups());
        let contacts = self.contact_points.iter().filter(|_| !self.planes.is_empty()).flat_map(|c| c.node_groups());
        pins.chain(contacts)
    }
}
