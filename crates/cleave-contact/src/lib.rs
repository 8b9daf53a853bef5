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
//! and one set of loops (`rows.rs`) turns that into the force, the matrix-free action, the
//! preconditioner's diagonal blocks and the energy, for every kind alike; the integrator adds
//! the blocks to its assembled matrix.
//!
//! The crate finds the contacts; it does not step. Its parts: the colliders and the
//! [`Colliders`] a detection reads (`colliders.rs`); the row and its penalty law (`rows.rs`);
//! the structures of one topology, [`ContactSet::new`], which anyone may build on any thread
//! (`set.rs`); the broad phase's motion bounds and trees (`motion.rs`); the narrow phase,
//! [`ContactSet::detect`] (`narrow.rs`).

mod colliders;
mod motion;
mod narrow;
mod rows;
mod set;
mod tests;

pub use colliders::{Colliders, MeshCollider, MeshColliderError, PlaneCollider, SurfaceContact};
pub use rows::{
    Contact, ContactKind, ContactStats, FRICTION_SLIP_SPEED, Row, add_action, add_diagonal_blocks, add_forces, energy,
    for_each_entry, row_value,
};
pub use set::ContactSet;
