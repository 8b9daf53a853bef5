//! Surface meshes for cleave: OBJ loading, closedness/orientation validation, inside tests,
//! triangle–box overlap and voxelization into simulation cells.
//!
//! - [`TriangleMesh`] (module `mesh`): an indexed triangle surface, read from Wavefront OBJ
//!   text, with volume, area, centroid and bounding box.
//! - [`TriangleMesh::validate_closed`] (module `validate`): closed, manifold, consistently
//!   and outward oriented, returning [`MeshStats`].
//! - [`TriangleMesh::winding_number`] / [`TriangleMesh::contains`] and the accelerated
//!   [`InsideTester`] (module `inside`).
//! - [`triangle_aabb_overlap`] (module `overlap`); [`closest_point_on_triangle`] and
//!   [`closest_parameters_of_lines`] (module `closest`).
//! - [`voxelize`] producing a [`VoxelGrid`] (module `voxelize`), following Müller et al.
//!   2004, §2.1.
//! - [`hex_slice`] producing a [`HexSlicing`] (module `hex_slice`): a closed surface sliced by
//!   a cube grid into polyhedral elements (Kaufmann et al. 2008, §10).
//!   Pieces below a fraction of the cell volume are merged into neighbours by
//!   [`merge_small_elements`] (module `merge`, kaufmann2008 §10 "sliver merging");
//!   [`hex_slice_with`] takes [`HexSliceOptions`] to change or disable that.
//! - [`PolyhedralMesh`] (module `polyhedral`): polyhedral elements with shared planar
//!   polygon faces, for the DG backend (Kaufmann et al. 2008), checked by
//!   [`PolyhedralMesh::validate`] (module `poly_validate`) returning [`PolyMeshStats`].
//! - [`element_moments`] / [`face_moments`] (module `moments`): exact monomial integrals over
//!   (non-convex) polyhedra and polygons by the divergence theorem.
//! - [`arrangement::Arrangement`]: a convex region (a tetrahedron today) as convex cells split
//!   by cut triangles and planes with exact side-of-plane decisions ([`predicates`], on
//!   `robust`), and its material regions: the splitting every polyhedral backend cuts with
//!   (virtual node's duplicates; mean value's elements next).
//! - [`split_polygon`] (module `polygon_split`): a planar polygon, convex or not, split by a plane
//!   into its pieces on each side, sides exact: the face step of cutting general polyhedra (DG);
//!   [`split_element`] (module `element_split`): the element step, a closed polyhedron split
//!   into its connected children, capped by the section; [`split_mesh_by_plane`] (module
//!   `mesh_split`): the mesh step, every element a plane crosses split, the section uncoupled;
//!   [`split_mesh_element`]: one element split, its section coupled (refinement).
//!
//! The library performs no file or terminal I/O and reports bad input as
//! [`GeometryError`] values naming the offending triangle, edge, vertex or OBJ line.

pub mod arrangement;
mod blade;
mod closest;
mod ear_clip;
mod element_split;
mod error;
mod hex_slice;
mod inside;
mod merge;
mod mesh;
mod mesh_split;
mod moments;
mod obj;
mod overlap;
mod poly_validate;
mod polygon_split;
mod polyhedral;
pub mod predicates;
mod slivers;
mod union_find;
mod validate;
mod voxelize;

pub use blade::{Blade, BladeError, Keyframe};
pub use closest::{closest_parameters_of_lines, closest_point_on_triangle};
pub use ear_clip::triangulate_planar_polygon;
pub use element_split::{
    ChildFace, ElementChild, ElementSplit, ElementSplitError, FaceSource, SplitVertex, split_element,
};
pub use error::GeometryError;
pub use hex_slice::{
    DEFAULT_MERGE_BELOW, GRID_MARGIN, HexSliceOptions, HexSlicing, MAX_SLICE_CELLS, MIN_FACE_AREA, hex_slice,
    hex_slice_with,
};
pub use inside::{InsideTester, polygon_winding_number};
pub use merge::{MergeReport, merge_small_elements};
pub use mesh::TriangleMesh;
pub use mesh_split::{MeshSplit, MeshSplitError, cut_mesh_by_polygon, split_mesh_by_plane, split_mesh_element};
pub use moments::{
    Frame, MAX_MOMENT_DEGREE, element_frame, element_moments, element_moments_from_faces, element_volume_centroid,
    face_area_normal_centroid, face_moments, monomial_exponents, monomial_index, num_monomials, shift_moments,
    try_element_moments, try_element_moments_from_faces, try_face_moments,
};
pub use overlap::triangle_aabb_overlap;
pub use poly_validate::PolyMeshStats;
pub use polygon_split::{PolygonPiece, PolygonSplit, PolygonSplitError, SplitCorner, split_polygon};
pub use polyhedral::{ElementFace, PolyFace, PolyhedralMesh};
pub use slivers::{SliverRepair, repair_slivers};
pub use union_find::UnionFind;
pub use validate::{DEGENERATE_RATIO, MeshStats};
pub use voxelize::{CELL_TOLERANCE, MAX_GRID_CELLS, VoxelGrid, voxelize};

/// A hash map with a fast fixed-seed hasher, for integer and float-bit keys.
pub(crate) type FastMap<K, V> = std::collections::HashMap<K, V, foldhash::fast::FixedState>;
