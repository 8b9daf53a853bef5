//! The error type of `cleave-geometry`: every failure names the offending value.

/// Errors from loading, validating, querying and voxelizing triangle meshes, and from
/// validating and integrating over polyhedral meshes.
///
/// Triangle indices are positions in [`TriangleMesh::triangles`](crate::TriangleMesh::triangles),
/// vertex indices are 0-based positions in
/// [`TriangleMesh::vertices`](crate::TriangleMesh::vertices) (or
/// [`PolyhedralMesh::vertices`](crate::PolyhedralMesh::vertices)); face indices are positions
/// in [`PolyhedralMesh::faces`](crate::PolyhedralMesh::faces).
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
    /// The polyhedral mesh has no elements.
    #[error("the polyhedral mesh has no elements")]
    NoElements,
    /// A face index passed to a query does not exist.
    #[error("face {face} does not exist: the mesh has {num_faces} faces")]
    FaceOutOfRange {
        /// The requested face.
        face: usize,
        /// Number of faces of the mesh.
        num_faces: usize,
    },
    /// An element index passed to a query does not exist.
    #[error("element {element} does not exist: the mesh has {num_elements} elements")]
    ElementOutOfRange {
        /// The requested element.
        element: usize,
        /// Number of elements of the mesh.
        num_elements: usize,
    },
    /// A face polygon refers to a vertex that does not exist.
    #[error("face {face} refers to vertex {index}, but the mesh has only {vertex_count} vertices")]
    FaceVertexOutOfRange {
        /// Index of the face.
        face: usize,
        /// The first out-of-range vertex index in its polygon.
        index: u32,
        /// Number of vertices of the mesh.
        vertex_count: usize,
    },
    /// A face's `inner` or `outer` element index is not below `num_elements`.
    #[error("face {face} refers to element {element}, but the mesh has only {num_elements} elements")]
    FaceElementOutOfRange {
        /// Index of the face.
        face: usize,
        /// The out-of-range element index (`inner` if it is bad, else `outer`).
        element: u32,
        /// Number of elements of the mesh.
        num_elements: usize,
    },
    /// A face has the same element on both sides.
    #[error("face {face} has element {element} on both sides")]
    SelfAdjacentFace {
        /// Index of the face.
        face: usize,
        /// The element named as both `inner` and `outer`.
        element: u32,
    },
    /// A face has fewer than three distinct vertices, repeats a vertex, or has (numerically)
    /// zero area.
    #[error("face {face} (polygon {polygon:?}) is degenerate: {distinct_vertices} distinct vertices, area {area:e}")]
    DegenerateFace {
        /// Index of the face.
        face: usize,
        /// Its vertex indices.
        polygon: Vec<u32>,
        /// Number of distinct vertex indices in it.
        distinct_vertices: usize,
        /// Its area (Newell), 0 when it has fewer than three distinct vertices.
        area: f64,
    },
    /// A face is not planar: some vertex lies farther from the Newell plane (through the
    /// vertex mean) than `tolerance` times the face diameter.
    #[error(
        "face {face} is not planar: vertex {vertex} deviates from its Newell plane by {deviation:e} \
         face diameters (tolerance {tolerance:e})"
    )]
    NonPlanarFace {
        /// Index of the face.
        face: usize,
        /// The vertex (mesh index) farthest from the plane.
        vertex: u32,
        /// Its distance from the plane divided by the face diameter.
        deviation: f64,
        /// The tolerance it exceeds.
        tolerance: f64,
    },
    /// An element boundary is open: the directed edge (a, b) of one of its outward faces is
    /// not matched by the reverse edge (b, a) of another.
    #[error("element {element} is not closed: edge ({a}, {b}) of face {face} has no reverse edge ({b}, {a})")]
    OpenElementBoundary {
        /// Index of the element.
        element: usize,
        /// Start vertex of the directed edge, in the element's outward orientation.
        a: u32,
        /// End vertex of the directed edge.
        b: u32,
        /// The face (mesh index) containing the edge.
        face: usize,
    },
    /// Two outward faces of an element traverse the edge a → b in the same direction, so
    /// the element boundary is inconsistently oriented.
    #[error(
        "element {element} is inconsistently oriented: directed edge ({a}, {b}) is used by both \
         face {} and face {}",
        faces.0,
        faces.1
    )]
    InconsistentElementOrientation {
        /// Index of the element.
        element: usize,
        /// Start vertex of the directed edge.
        a: u32,
        /// End vertex of the directed edge.
        b: u32,
        /// The two faces (mesh indices), in the element's face order.
        faces: (usize, usize),
    },
    /// An element has zero, negative or NaN volume (e.g. all its faces point inward).
    #[error("element {element} has non-positive volume {volume:e}")]
    NonPositiveVolume {
        /// Index of the element.
        element: usize,
        /// Its signed volume.
        volume: f64,
    },
    /// A tolerance is negative or not a number.
    #[error("invalid tolerance {tolerance}: must be non-negative")]
    InvalidTolerance {
        /// The rejected tolerance.
        tolerance: f64,
    },
    /// A sliver-merging volume threshold is negative, infinite or NaN.
    #[error("invalid merge threshold {threshold}: must be non-negative and finite")]
    InvalidMergeThreshold {
        /// The rejected threshold (a volume, or a fraction of the cell volume for slicing).
        threshold: f64,
    },
    /// A moment frame has a non-finite centre or a scale that is not positive and finite.
    #[error("invalid frame: center {center:?}, scale {scale} (the scale must be positive and finite)")]
    InvalidFrame {
        /// The frame centre.
        center: [f64; 3],
        /// The frame scale.
        scale: f64,
    },
    /// A moment vector does not have one entry per monomial of its degree.
    #[error("{got} moments given where degree {degree} has {expected}")]
    MomentCount {
        /// The degree the moments are said to have.
        degree: usize,
        /// Monomials of that degree, `(d+1)(d+2)(d+3)/6`.
        expected: usize,
        /// Moments given.
        got: usize,
    },
    /// The requested moment degree exceeds the supported maximum.
    #[error("moment degree {degree} exceeds the supported maximum {limit}")]
    MomentDegreeTooHigh {
        /// The requested degree.
        degree: usize,
        /// The maximum, [`MAX_MOMENT_DEGREE`](crate::MAX_MOMENT_DEGREE).
        limit: usize,
    },
    /// Hexahedral slicing found no grid shift that keeps every surface vertex, edge crossing
    /// and triangle–grid-line crossing away from the grid planes and leaves no sliver face
    /// (see [`GRID_MARGIN`](crate::GRID_MARGIN) and [`MIN_FACE_AREA`](crate::MIN_FACE_AREA)).
    #[error("hexahedral slicing at cell size {cell_size}: no generic grid shift in {attempts} attempts")]
    NoGenericGridShift {
        /// The requested cell size.
        cell_size: f64,
        /// Number of shifts tried.
        attempts: usize,
    },
    /// Hexahedral slicing produced an inconsistent arrangement in a grid cell (e.g. for a
    /// self-intersecting surface).
    #[error("hexahedral slicing failed in grid cell {cell:?}: {message}")]
    SliceInconsistent {
        /// The grid cell `[i, j, k]` (for a face: the cell above it).
        cell: [i32; 3],
        /// What did not fit together.
        message: String,
    },
}
