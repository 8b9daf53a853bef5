//! The indexed triangle surface mesh [`TriangleMesh`] and its integral quantities.

use nalgebra::{Point3, Vector3};

use crate::GeometryError;

/// An indexed triangle surface mesh.
///
/// Triangles are counter-clockwise seen from outside for an outward-oriented closed
/// surface (the convention checked by [`TriangleMesh::validate_closed`]). Nothing is
/// enforced at construction; the geometric methods skip triangles whose indices are out of
/// range instead of panicking.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles as three indices into `vertices`.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// Creates a mesh from vertices and triangles (no validation).
    pub fn new(vertices: Vec<Point3<f64>>, triangles: Vec<[u32; 3]>) -> Self {
        Self { vertices, triangles }
    }

    /// The closed, outward oriented surface of the box `[lo, hi]` (12 triangles; vertex `i`
    /// takes `hi` along axis `a` when bit `a` of `i` is set).
    pub fn cuboid(lo: Point3<f64>, hi: Point3<f64>) -> Self {
        let vertices = (0..8)
            .map(|i| {
                Point3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                )
            })
            .collect();
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
        Self { vertices, triangles }
    }

    /// Reads a Wavefront OBJ mesh from a reader (the caller opens files).
    ///
    /// Parsing is done by `tobj` (triangulating polygons as fans, ignoring points, lines,
    /// normals, texture coordinates and materials; `mtllib` is never opened). All objects
    /// and groups are merged into one mesh. Vertices keep their file order, with two
    /// exceptions: vertices referenced by no face are dropped, and vertices with exactly
    /// equal coordinates are merged into the first one. For an OBJ whose vertices are all
    /// used and distinct, mesh vertex `i` is OBJ vertex `i + 1`; triangles follow the face
    /// order of the file.
    ///
    /// Errors name the 1-based line for malformed vertices, faces referring to missing
    /// vertices, non-finite coordinates and invalid UTF-8; an OBJ without triangles is
    /// [`GeometryError::NoTriangles`].
    pub fn from_obj_reader(reader: &mut impl std::io::BufRead) -> Result<Self, GeometryError> {
        let mut bytes = Vec::new();
        reader.read_to_end(&mut bytes).map_err(|e| GeometryError::Read { message: e.to_string() })?;
        crate::obj::parse_obj_bytes(&bytes)
    }

    /// Parses a Wavefront OBJ mesh from a string; see [`TriangleMesh::from_obj_reader`].
    pub fn from_obj_str(text: &str) -> Result<Self, GeometryError> {
        crate::obj::parse_obj_bytes(text.as_bytes())
    }

    /// The corner positions of triangle `t`, or `None` if `t` or one of its indices is out
    /// of range.
    pub fn triangle_points(&self, t: usize) -> Option<[Point3<f64>; 3]> {
        let tri = self.triangles.get(t)?;
        Some([
            *self.vertices.get(tri[0] as usize)?,
            *self.vertices.get(tri[1] as usize)?,
            *self.vertices.get(tri[2] as usize)?,
        ])
    }

    /// Iterates over the corner positions of all triangles whose indices are in range.
    pub(crate) fn valid_triangle_points(&self) -> impl Iterator<Item = [Point3<f64>; 3]> + '_ {
        (0..self.triangles.len()).filter_map(|t| self.triangle_points(t))
    }

    /// Axis-aligned bounding box `(min, max)` of all vertices.
    ///
    /// For a mesh without vertices this is the empty box `(+∞, −∞)`.
    pub fn aabb(&self) -> (Point3<f64>, Point3<f64>) {
        let mut lo = Point3::from([f64::INFINITY; 3]);
        let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
        for v in &self.vertices {
            for d in 0..3 {
                lo[d] = lo[d].min(v[d]);
                hi[d] = hi[d].max(v[d]);
            }
        }
        (lo, hi)
    }

    /// A reference point used to reduce cancellation in volume integrals (the AABB center,
    /// or the origin for an empty mesh).
    fn reference_point(&self) -> Point3<f64> {
        let (lo, hi) = self.aabb();
        let c = nalgebra::center(&lo, &hi);
        if c.iter().all(|x| x.is_finite()) { c } else { Point3::origin() }
    }

    /// Signed enclosed volume by the divergence theorem: the sum of the signed volumes of
    /// the tetrahedra joining a reference point to every triangle.
    ///
    /// For a closed surface the result does not depend on the reference point and is
    /// positive for outward orientation. For an open surface it does (the AABB center is
    /// used). Triangles with out-of-range indices are skipped.
    pub fn signed_volume(&self) -> f64 {
        let r = self.reference_point();
        let six_v: f64 = self.valid_triangle_points().map(|[a, b, c]| (a - r).dot(&(b - r).cross(&(c - r)))).sum();
        six_v / 6.0
    }

    /// Total surface area (triangles with out-of-range indices are skipped).
    pub fn area(&self) -> f64 {
        self.valid_triangle_points().map(|[a, b, c]| 0.5 * (b - a).cross(&(c - a)).norm()).sum()
    }

    /// Applies `f` to every vertex, keeping the triangles.
    ///
    /// A map with negative Jacobian determinant (e.g. a mirror) turns an outward mesh
    /// inward; re-orienting the triangles is then the caller's business.
    pub fn transformed(&self, f: impl Fn(&Point3<f64>) -> Point3<f64>) -> Self {
        Self { vertices: self.vertices.iter().map(f).collect(), triangles: self.triangles.clone() }
    }

    /// Centroid of the enclosed solid (assuming uniform density), or `None` when the signed
    /// volume is zero or not finite.
    ///
    /// Meaningful for closed, consistently oriented surfaces.
    pub fn centroid_of_volume(&self) -> Option<Point3<f64>> {
        let r = self.reference_point();
        let mut six_v = 0.0;
        let mut moment = Vector3::zeros();
        for [a, b, c] in self.valid_triangle_points() {
            let (a, b, c) = (a - r, b - r, c - r);
            let w = a.dot(&b.cross(&c));
            six_v += w;
            // The tetrahedron (r, a, b, c) has centroid r + (a + b + c) / 4.
            moment += (a + b + c) * (w / 4.0);
        }
        if six_v == 0.0 || !six_v.is_finite() {
            return None;
        }
        let c = r + moment / six_v;
        c.iter().all(|x| x.is_finite()).then_some(c)
    }
}
