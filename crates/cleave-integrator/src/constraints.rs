//! Boundary conditions the integrator applies through `embed` rows and DOF masks: pinned DOFs
//! (eliminated), penalty pins, and contact (implicit penalty stiffness, friction) against plane
//! colliders, static mesh colliders and the body's own surface (found by `cleave-contact`,
//! entered into the step by `penalty.rs`).

use cleave_contact::{Colliders, MeshCollider, PlaneCollider, SurfaceContact};
use cleave_core::{Embedding, Point3, Real};

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
    /// Static triangle mesh colliders.
    pub meshes: Vec<MeshCollider>,
    /// Contact of the body's surface with itself (between and within pieces).
    pub surface_contact: Option<SurfaceContact>,
    /// A constant load added to gravity, one entry per scalar DOF (empty = none): the boundary
    /// terms of weakly imposed Dirichlet data (DG), which backends hand over as a vector.
    pub extra_load: Vec<Real>,
}

impl Constraints {
    /// Whether there is anything for contact points to touch.
    pub fn has_any_contact(&self) -> bool {
        !self.planes.is_empty() || !self.meshes.is_empty() || self.surface_contact.is_some()
    }

    /// What contact detection reads: the contact points and the colliders.
    pub fn colliders(&self) -> Colliders<'_> {
        Colliders {
            points: self.contact_points.as_ref(),
            planes: &self.planes,
            meshes: &self.meshes,
            surface: self.surface_contact.as_ref(),
        }
    }

    /// Whether contact points are tested against anything.
    pub(crate) fn has_contact(&self) -> bool {
        self.contact_points.is_some() && self.has_any_contact()
    }

    /// Node groups that penalty terms couple (for the sparsity pattern): every pin row and every
    /// contact point row (a point against a plane or a static mesh). The rows of surface and
    /// edge contacts (a point and a triangle, two edges) join the pattern when they first occur
    /// (`penalty::missing_couplings`); so do the couplings among a triangle's vertex rows, which
    /// a group per surface triangle here would add to the pattern of every epoch whether the
    /// triangle ever touches anything or not (on `bunny_slice.ron` that fill made the
    /// factorization 40 % slower: docs/math/contact.md §3).
    ///
    /// Flat, a row equal to the one before it skipped (points of one element come together).
    pub(crate) fn coupling_groups(&self) -> NodeGroups {
        let mut groups = NodeGroups::default();
        for rows in self.penalty_pins.iter().map(|p| &p.points) {
            groups.extend_rows(rows);
        }
        if let Some(points) = self.contact_points.as_ref().filter(|_| self.has_contact()) {
            groups.extend_rows(points);
        }
        groups
    }
}

/// Node groups stored flat (one allocation for all of them).
#[derive(Debug, Default)]
pub(crate) struct NodeGroups {
    nodes: Vec<u32>,
    offsets: Vec<usize>,
}

impl NodeGroups {
    fn push(&mut self, group: &[u32]) {
        if self.offsets.is_empty() {
            self.offsets.push(0);
        }
        self.nodes.extend_from_slice(group);
        self.offsets.push(self.nodes.len());
    }

    /// Every row's nodes, a row equal to the last group skipped.
    fn extend_rows(&mut self, rows: &Embedding) {
        for group in rows.node_groups() {
            if self.iter().next_back() != Some(group) {
                self.push(group);
            }
        }
    }

    /// The groups in order.
    pub(crate) fn iter(&self) -> impl DoubleEndedIterator<Item = &[u32]> {
        self.offsets.windows(2).map(|w| &self.nodes[w[0]..w[1]])
    }
}
