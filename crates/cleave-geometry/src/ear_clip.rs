//! Ear clipping of a simple planar polygon in space, convex or not, whose corners may include
//! collinear ones (vertices a cut inserted on its edges): triangles of positive area only,
//! which a fan from one corner does not give.

use crate::polygon_split::newell_normal;
use crate::predicates::kept_axes;
use nalgebra::{Point2, Point3};

/// Triangles (corner indices, counter-clockwise about the polygon's own normal) covering the
/// simple planar polygon `points`; `None` if the polygon is degenerate or some step finds no
/// ear (it is not simple). Only strictly convex corners (twice the area above 1e-10 of the
/// squared diameter) are clipped, so collinear corners never make zero-area triangles: corners
/// computed on a line carry rounding of their coordinates' size (1e-17 m at 0.5 m), which on a
/// face 1 cm across is 1e-14 of its squared diameter.
pub fn triangulate_planar_polygon(points: &[Point3<f64>]) -> Option<Vec<[usize; 3]>> {
    let n = points.len();
    if n < 3 {
        return None;
    }
    if n == 3 {
        return Some(vec![[0, 1, 2]]);
    }
    let normal = newell_normal(points);
    let axis = normal.iamax();
    if normal[axis].is_nan() || normal[axis] == 0.0 {
        return None;
    }
    let (u, v) = kept_axes(axis);
    let flip = if normal[axis] < 0.0 { -1.0 } else { 1.0 };
    let flat: Vec<Point2<f64>> = points.iter().map(|p| Point2::new(p[u], flip * p[v])).collect();
    let diameter = points.iter().map(|p| (p - points[0]).norm()).fold(0.0, f64::max);
    let tiny = 1e-10 * diameter * diameter;
    let cross = |o: usize, p: usize, q: usize| {
        let (o, p, q) = (flat[o], flat[p], flat[q]);
        (p.x - o.x) * (q.y - o.y) - (p.y - o.y) * (q.x - o.x)
    };
    let mut polygon: Vec<usize> = (0..n).collect();
    let mut out = Vec::with_capacity(n - 2);
    while polygon.len() > 3 {
        let m = polygon.len();
        let ear = (0..m).find(|&i| {
            let (a, b, c) = (polygon[(i + m - 1) % m], polygon[i], polygon[(i + 1) % m]);
            cross(a, b, c) > tiny
                && !polygon.iter().any(|&q| {
                    q != a
                        && q != b
                        && q != c
                        && flat[q] != flat[a]
                        && flat[q] != flat[c]
                        && cross(a, b, q) >= 0.0
                        && cross(b, c, q) >= 0.0
                        && cross(c, a, q) >= 0.0
                })
        })?;
        out.push([polygon[(ear + m - 1) % m], polygon[ear], polygon[(ear + 1) % m]]);
        polygon.remove(ear);
    }
    out.push([polygon[0], polygon[1], polygon[2]]);
    Some(out)
}
