//! Triangle–box overlap by the separating axis theorem (Akenine-Möller 2001).

use nalgebra::{Point3, Vector3};

/// Whether the closed triangle `tri` and the closed axis-aligned box `[box_min, box_max]`
/// intersect (touching counts).
///
/// Tests the 13 candidate separating axes of Akenine-Möller: the three box axes, the
/// triangle normal and the nine cross products of box axes with triangle edges. Exact up to
/// rounding, i.e. configurations within a few ulps of touching may go either way.
/// Degenerate triangles (segments, points) are handled correctly. Returns `false` for an
/// empty box (`box_min > box_max` on some axis) and for non-finite input.
pub fn triangle_aabb_overlap(tri: &[Point3<f64>; 3], box_min: &Point3<f64>, box_max: &Point3<f64>) -> bool {
    let finite = |p: &Point3<f64>| p.iter().all(|x| x.is_finite());
    if !(tri.iter().all(finite) && finite(box_min) && finite(box_max)) {
        return false;
    }
    let center = nalgebra::center(box_min, box_max);
    let half: Vector3<f64> = (box_max - box_min) / 2.0;
    if half.iter().any(|&x| x < 0.0) {
        return false;
    }
    let v = tri.map(|p| p - center);

    // Separated along `axis` if the triangle's projection interval misses the box's.
    let separated = |axis: Vector3<f64>| {
        let p0 = axis.dot(&v[0]);
        let p1 = axis.dot(&v[1]);
        let p2 = axis.dot(&v[2]);
        let r = half.x * axis.x.abs() + half.y * axis.y.abs() + half.z * axis.z.abs();
        p0.min(p1).min(p2) > r || p0.max(p1).max(p2) < -r
    };

    // Box face normals.
    for d in 0..3 {
        if separated(Vector3::ith(d, 1.0)) {
            return false;
        }
    }
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    // Edge–edge axes: box axis × triangle edge.
    for e in &edges {
        for axis in [Vector3::new(0.0, -e.z, e.y), Vector3::new(e.z, 0.0, -e.x), Vector3::new(-e.y, e.x, 0.0)] {
            if separated(axis) {
                return false;
            }
        }
    }
    // Triangle plane.
    !separated(edges[0].cross(&edges[1]))
}
