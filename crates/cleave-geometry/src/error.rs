//! The error type of `cleave-geometry`: every failure names the offending value.

/// Errors from loading, validating, querying and voxelizing triangle meshes.
///
/// Triangle indices are positions in [`TriangleMesh::triangles`](crate::TriangleMesh::triangles),
/// vertex indices are 0-based positions in
/// [`TriangleMesh::vertices`](crate::TriangleMesh::vertices).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GeometryError {
    /// Reading from the supplied reader failed.
    #[error("failed to read OBJ input: {message}")]
    Read {
        /// The I/O error message.
        message: String,
    },
    /// An OBJ line is malformed or refers to something that does not exist.
    #[error("OBJ line {line}: {message}")]
    ObjLine {
        /// 1-based line number in the OBJ text.
        line: usize,
        /// What is wrong with the line, quoting the offending value.
        message: String,
    },
    /// `tobj` rejected the OBJ text for a reason that could not be traced to a line.
    #[error("OBJ parse error: {message}")]
    Obj {
        /// The message reported by `tobj`.
        message: String,
    },
    /// The mesh (or OBJ file) contains no triangles.
    #[error("the mesh has no triangles")]
    NoTriangles,
    /// A vertex has a NaN or infinite coordinate.
    #[error("vertex {vertex} has a non-finite position {position:?}")]
    NonFiniteVertex {
        /// Index of the vertex.
        vertex: usize,
        /// Its coordinates.
        position: [f64; 3],
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "triangle {triangle} (vertices {vertices:?}) refers to vertex {index}, \
         but the mesh has only {vertex_count} vertices"
    )]
    IndexOutOfRange {
        /// Index of the triangle.
        triangle: usize,
        /// The triangle's three vertex indices.
        vertices: [u32; 3],
        /// The first out-of-range index in it.
        index: u32,
        /// Number of vertices of the mesh.
        vertex_count: usize,
    },
    /// A triangle repeats a vertex index or has (numerically) zero area.
    #[error("triangle {triangle} (vertices {vertices:?}) is degenerate: area {area:e}")]
    DegenerateTriangle {
        /// Index of the triangle.
        triangle: usize,
        /// The triangle's three vertex indices.
        vertices: [u32; 3],
        /// Its area (0 when an index is repeated).
        area: f64,
    },
    /// A boundary edge: the undirected edge (a, b) is used by a single triangle, so the
    /// surface is not closed.
    #[error("open edge ({a}, {b}): used only by triangle {triangle}")]
    OpenEdge {
        /// First vertex of the edge, in the triangle's orientation.
        a: u32,
        /// Second vertex of the edge, in the triangle's orientation.
        b: u32,
        /// The only triangle using the edge.
        triangle: usize,
    },
    /// The undirected edge (a, b), a < b, is shared by more than two triangles.
    #[error("non-manifold edge ({a}, {b}): used by {count} triangles (first: triangle {triangle})")]
    NonManifoldEdge {
        /// Smaller vertex index of the edge.
        a: u32,
        /// Larger vertex index of the edge.
        b: u32,
        /// Number of triangles using the edge.
        count: usize,
        /// The lowest-index triangle using the edge.
        triangle: usize,
    },
    /// Two triangles traverse the edge a → b in the same direction, so their orientations
    /// disagree.
    #[error(
        "inconsistent orientation: directed edge ({a}, {b}) is used by both \
         triangle {} and triangle {}",
        triangles.0,
        triangles.1
    )]
    InconsistentOrientation {
        /// Start vertex of the directed edge.
        a: u32,
        /// End vertex of the directed edge.
        b: u32,
        /// The two triangles, lower index first.
        triangles: (usize, usize),
    },
    /// The closed, consistently oriented surface has non-positive signed volume, i.e. its
    /// normals point inward.
    #[error("inward orientation: signed volume {volume:e} is not positive (flip every triangle)")]
    InwardOrientation {
        /// The signed volume.
        volume: f64,
    },
    /// `parry3d-f64` refused to build its acceleration structure for the mesh.
    #[error("parry3d-f64 rejected the mesh: {message}")]
    Accelerator {
        /// The message reported by parry.
        message: String,
    },
    /// The voxel cell size is not a positive finite number.
    #[error("invalid cell size {cell_size}: must be positive and finite")]
    InvalidCellSize {
        /// The rejected cell size.
        cell_size: f64,
    },
    /// The voxel grid for this cell size would be too large.
    #[error(
        "voxel grid of {} x {} x {} = {cells:e} cells exceeds the limit of {limit} cells; \
         use a larger cell size",
        dims[0],
        dims[1],
        dims[2]
    )]
    GridTooLarge {
        /// Cells along x, y and z (may be astronomically large or infinite).
        dims: [f64; 3],
        /// Total number of cells.
        cells: f64,
        /// The maximum allowed number of cells.
        limit: u64,
    },
}
