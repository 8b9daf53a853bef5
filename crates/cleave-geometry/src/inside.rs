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

    /// Whether `p` is inside (or on) the surface; `false` for non-finite `p`.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        if !p.iter().all(|x| x.is_finite()) {
            return false;
        }
        self.trimesh.contains_local_point(Vector::new(p.x, p.y, p.z))
    }
}
