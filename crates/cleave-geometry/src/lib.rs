//! Surface meshes for cleave: OBJ loading, closedness/orientation validation, inside tests,
//! triangle–box overlap and voxelization into simulation cells.
//!
//! - [`TriangleMesh`] (module `mesh`): an indexed triangle surface, read from Wavefront OBJ
//!   text, with volume, area, centroid and bounding box.
//! - [`TriangleMesh::validate_closed`] (module `validate`): closed, manifold, consistently
//!   and outward oriented, returning [`MeshStats`].
//! - [`TriangleMesh::winding_number`] / [`TriangleMesh::contains`] and the accelerated
//!   [`InsideTester`] (module `inside`).
//! - [`triangle_aabb_overlap`] (module `overlap`).
//! - [`voxelize`] producing a [`VoxelGrid`] (module `voxelize`), following Müller et al.
//!   2004, §2.1.
//! - [`PolyhedralMesh`] (module `polyhedral`): polyhedral elements with shared planar
//!   polygon faces, for the DG backend (Kaufmann et al. 2008).
//!
//! The library performs no file or terminal I/O and reports bad input as
//! [`GeometryError`] values naming the offending triangle, edge, vertex or OBJ line.

mod error;
mod inside;
mod mesh;
mod obj;
mod overlap;
mod polyhedral;
mod validate;
mod voxelize;

pub use error::GeometryError;
pub use inside::InsideTester;
pub use mesh::TriangleMesh;
pub use overlap::triangle_aabb_overlap;
pub use polyhedral::{ElementFace, PolyFace, PolyhedralMesh};
pub use validate::{DEGENERATE_RATIO, MeshStats};
pub use voxelize::{CELL_TOLERANCE, MAX_GRID_CELLS, VoxelGrid, voxelize};
