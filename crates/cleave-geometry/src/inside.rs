//! Inside/outside queries: the generalized winding number and a BVH-accelerated tester.

use nalgebra::Point3;
use parry3d_f64::math::Vector;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::{TriMesh, TriMeshFlags};

use crate::{GeometryError, TriangleMesh};

/// Signed solid angle of triangle `(a, b, c)` seen from the origin (Van Oosterom–Strackee
/// formula); positive when `a · (b × c) > 0`, i.e. when the origin is behind the triangle
/// with respect to its right-hand normal.
fn solid_angle(a: nalgebra::Vector3<f64>, b: nalgebra::Vector3<f64>, c: nalgebra::Vector3<f64>) -> f64 {
    let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
    let num = a.dot(&b.cross(&c));
    let den = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
    2.0 * num.atan2(den)
}

/// Generalized winding number of `p` with respect to closed, outward polygon loops (a
/// polyhedron's faces, each fanned from its first vertex): 1 inside, 0 outside (up to
/// rounding). On a face the solid angle of the fan triangle holding the point is ±2π by the sign
/// of a zero, so the number is 0 or 1 there; a point at a polygon's vertex counts as inside (1).
pub fn polygon_winding_number<'a>(faces: impl IntoIterator<Item = &'a [Point3<f64>]>, p: &Point3<f64>) -> f64 {
    let mut total = 0.0;
    for face in faces {
        for k in 1..face.len().saturating_sub(1) {
            let (a, b, c) = (face[0] - p, face[k] - p, face[k + 1] - p);
            if a.norm() < 1e-300 || b.norm() < 1e-300 || c.norm() < 1e-300 {
                return 1.0;
            }
            total += solid_angle(a, b, c);
        }
    }
    total / (4.0 * std::f64::consts::PI)
}

impl TriangleMesh {
    /// Generalized winding number of `p`: the sum of the signed solid angles of all
    /// triangles seen from `p`, divided by 4π.
    ///
    /// For a closed, outward-oriented surface it is 1 inside, 0 outside (exact up to
    /// rounding) and about 1/2 on a face; for open or non-manifold triangle soups it degrades
    /// gracefully. Cost is linear in the number of triangles. Triangles with out-of-range
    /// indices are skipped; a non-finite `p` gives NaN.
    pub fn winding_number(&self, p: &Point3<f64>) -> f64 {
        let sum: f64 = self.valid_triangle_points().map(|[a, b, c]| solid_angle(a - p, b - p, c - p)).sum();
        sum / (4.0 * std::f64::consts::PI)
    }

    /// Whether `p` is inside the surface: [`TriangleMesh::winding_number`] `> 0.5`.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        self.winding_number(p) > 0.5
    }
}

/// Fast point containment for a closed, outward-oriented mesh, using a `parry3d-f64`
/// [`TriMesh`] with a BVH and oriented pseudo-normals (`TriMeshFlags::ORIENTED`).
///
/// Agrees with [`TriangleMesh::contains`] except for points within rounding distance of the
/// surface, at logarithmic instead of linear cost per query.
pub struct InsideTester {
    trimesh: TriMesh,
}

impl std::fmt::Debug for InsideTester {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("InsideTester").field("triangles", &self.trimesh.indices().len()).finish()
    }
}

impl InsideTester {
    /// Builds the tester. The mesh must pass [`TriangleMesh::validate_closed`] (whose error
    /// is returned otherwise), since pseudo-normal containment is only correct for closed,
    /// consistently oriented surfaces.
    pub fn new(mesh: &TriangleMesh) -> Result<Self, GeometryError> {
        mesh.validate_closed()?;
        let vertices = mesh.vertices.iter().map(|v| Vector::new(v.x, v.y, v.z)).collect();
        let trimesh = TriMesh::with_flags(vertices, mesh.triangles.clone(), TriMeshFlags::ORIENTED)
            .map_err(|e| GeometryError::Accelerator { message: e.to_string() })?;
        Ok(Self { trimesh })
    }

    /// The signed distance from `p` to the surface: negative inside, positive outside (the
    /// nearest point by the tree; the side by pseudo-normals, as [`InsideTester::contains`]);
    /// NaN for non-finite `p`.
    pub fn signed_distance(&self, p: &Point3<f64>) -> f64 {
        if !p.iter().all(|x| x.is_finite()) {
            return f64::NAN;
        }
        let q = Vector::new(p.x, p.y, p.z);
        let projection = self.trimesh.project_local_point(q, false);
        let distance = (projection.point - q).length();
        if projection.is_inside { -distance } else { distance }
    }

    /// Whether `p` is inside (or on) the surface; `false` for non-finite `p`.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        if !p.iter().all(|x| x.is_finite()) {
            return false;
        }
        self.trimesh.contains_local_point(Vector::new(p.x, p.y, p.z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_polygon_winding_number_of_a_cube_is_one_inside_and_zero_outside() {
        // The unit cube's six outward quads; the solid angles sum to 4π seen from inside.
        let corner = |i: usize| Point3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64);
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let faces: Vec<Vec<Point3<f64>>> = quads.iter().map(|q| q.iter().map(|&i| corner(i)).collect()).collect();
        let w = |p: Point3<f64>| polygon_winding_number(faces.iter().map(Vec::as_slice), &p);
        assert!((w(Point3::new(0.3, 0.6, 0.2)) - 1.0).abs() < 1e-12);
        assert!(w(Point3::new(1.7, 0.5, 0.5)).abs() < 1e-12);
        let on_face = w(Point3::new(0.5, 0.4, 1.0));
        assert!(on_face.abs() < 1e-12 || (on_face - 1.0).abs() < 1e-12, "{on_face}");
        assert_eq!(w(corner(7)), 1.0, "a vertex counts as inside");
        // Reversed loops (inward) give −1 inside.
        let inward: Vec<Vec<Point3<f64>>> = faces.iter().map(|f| f.iter().rev().copied().collect()).collect();
        let inside = polygon_winding_number(inward.iter().map(Vec::as_slice), &Point3::new(0.5, 0.5, 0.5));
        assert!((inside + 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_signed_distance_to_a_cube_is_the_depth_below_its_nearest_face() {
        let corner = |i: usize| Point3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64);
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles =
            quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).map(|t| t.map(|i| i as u32));
        let mesh = TriangleMesh::new((0..8).map(corner).collect(), triangles.collect());
        let tester = InsideTester::new(&mesh).unwrap();
        assert!((tester.signed_distance(&Point3::new(0.3, 0.6, 0.2)) + 0.2).abs() < 1e-15);
        assert!((tester.signed_distance(&Point3::new(0.5, 0.5, 0.5)) + 0.5).abs() < 1e-15);
        // Outside: beyond a face, and beyond a corner (the distance to the corner).
        assert!((tester.signed_distance(&Point3::new(1.7, 0.5, 0.5)) - 0.7).abs() < 1e-15);
        assert!((tester.signed_distance(&Point3::new(2.0, 2.0, 2.0)) - 3f64.sqrt()).abs() < 1e-15);
        assert!(tester.signed_distance(&Point3::new(f64::NAN, 0.0, 0.0)).is_nan());
    }
}
