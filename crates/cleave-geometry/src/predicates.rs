//! Exact orientation predicates (Shewchuk's adaptive arithmetic via the `robust` crate) in the
//! conventions of this crate, and the small 2D polygon helpers built on projections.

use nalgebra::{Point2, Point3, Vector3};
use robust::{Coord, Coord3D};

/// Exact sign of the side of `d` relative to the plane through `a, b, c`: `+1` on the side the
/// right-hand normal `(b − a) × (c − a)` points to, `−1` on the other side, `0` exactly on it.
#[inline]
pub fn side3(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>, d: &Point3<f64>) -> i8 {
    let c3 = |p: &Point3<f64>| Coord3D { x: p.x, y: p.y, z: p.z };
    // robust::orient3d is positive when d lies *below* the counter-clockwise plane a, b, c.
    let o = robust::orient3d(c3(a), c3(b), c3(c), c3(d));
    if o < 0.0 {
        1
    } else if o > 0.0 {
        -1
    } else {
        0
    }
}

/// The side of `p` relative to the plane through `plane` (its right-hand normal points to
/// `+1`), with points within `tolerance` (a distance) of it counted as on it (`0`): exact
/// (`side3`) beyond the tolerance. A tolerance of zero is `side3` itself. Cutting uses a small
/// one so that a plane through a corner in exact arithmetic, which rounding moved by 1e-16, is
/// not split off a sliver a few ulps wide (docs/math/polygon-split.md, "Tolerance").
pub fn side_of_plane(plane: &[Point3<f64>; 3], p: &Point3<f64>, tolerance: f64) -> i8 {
    let [a, b, c] = plane;
    if tolerance > 0.0 {
        let n = (b - a).cross(&(c - a));
        if n.dot(&(p - a)).abs() <= tolerance * n.norm() {
            return 0;
        }
    }
    side3(a, b, c, p)
}

/// The two coordinates kept when projecting along `axis` (cyclic, so that projecting a plane whose
/// normal has a positive `axis` component keeps counter-clockwise order).
#[inline]
pub fn kept_axes(axis: usize) -> (usize, usize) {
    ((axis + 1) % 3, (axis + 2) % 3)
}

/// Projects `p` along `axis`.
#[inline]
pub fn project(p: &Point3<f64>, axis: usize) -> Point2<f64> {
    let (u, v) = kept_axes(axis);
    Point2::new(p[u], p[v])
}

/// Exact twice-signed area sign of the projected triangle `(a, b, c)` along `axis`.
#[inline]
pub fn orient2(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>, axis: usize) -> f64 {
    let (u, v) = kept_axes(axis);
    robust::orient2d(Coord { x: a[u], y: a[v] }, Coord { x: b[u], y: b[v] }, Coord { x: c[u], y: c[v] })
}

/// Whether the triangle is exactly degenerate (its three points collinear or coincident): all
/// three axis projections have exactly zero area.
pub fn triangle_is_degenerate(t: &[Point3<f64>; 3]) -> bool {
    (0..3).all(|axis| orient2(&t[0], &t[1], &t[2], axis) == 0.0)
}

/// The axis along which the triangle's projection has the largest area (so that its plane is
/// a graph over the other two coordinates). The projected area along it is exactly non-zero for
/// a non-degenerate triangle.
pub fn dominant_axis(t: &[Point3<f64>; 3]) -> usize {
    let mut best = (0, -1.0);
    for axis in 0..3 {
        let a = orient2(&t[0], &t[1], &t[2], axis).abs();
        if a > best.1 {
            best = (axis, a);
        }
    }
    best.0
}

/// Index of the largest absolute component.
pub fn largest_component(n: &Vector3<f64>) -> usize {
    let a = n.map(f64::abs);
    if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    }
}

/// Signed area of a 2D polygon (positive counter-clockwise).
pub fn polygon_area_2d(p: &[Point2<f64>]) -> f64 {
    let n = p.len();
    if n < 3 {
        return 0.0;
    }
    let mut s = 0.0;
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        s += (a.x - p[0].x) * (b.y - p[0].y) - (b.x - p[0].x) * (a.y - p[0].y);
    }
    0.5 * s
}

/// Area of the intersection of two convex 2D polygons (either orientation), by clipping `a` with
/// every edge of `b` (Sutherland–Hodgman). Floating point; used only to decide whether two
/// coplanar face pieces overlap with an area far above rounding.
pub fn convex_overlap_area(
    a: &[Point2<f64>],
    b: &[Point2<f64>],
    scratch: &mut (Vec<Point2<f64>>, Vec<Point2<f64>>),
) -> f64 {
    if a.len() < 3 || b.len() < 3 {
        return 0.0;
    }
    let orientation = polygon_area_2d(b).signum();
    if orientation == 0.0 {
        return 0.0;
    }
    let (cur, next) = scratch;
    cur.clear();
    cur.extend_from_slice(a);
    for i in 0..b.len() {
        let (p, q) = (b[i], b[(i + 1) % b.len()]);
        let e = q - p;
        let inside = |x: &Point2<f64>| orientation * (e.x * (x.y - p.y) - e.y * (x.x - p.x));
        next.clear();
        for j in 0..cur.len() {
            let (s, t) = (cur[j], cur[(j + 1) % cur.len()]);
            let (ds, dt) = (inside(&s), inside(&t));
            if ds >= 0.0 {
                next.push(s);
            }
            if (ds >= 0.0) != (dt >= 0.0) {
                let w = ds / (ds - dt);
                if w.is_finite() {
                    next.push(s + (t - s) * w);
                }
            }
        }
        std::mem::swap(cur, next);
        if cur.len() < 3 {
            return 0.0;
        }
    }
    polygon_area_2d(cur).abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn side_follows_the_right_hand_normal() {
        let (a, b, c) = (Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0));
        assert_eq!(side3(&a, &b, &c, &Point3::new(0.2, 0.2, 1.0)), 1);
        assert_eq!(side3(&a, &b, &c, &Point3::new(0.2, 0.2, -1e-300)), -1);
        assert_eq!(side3(&a, &b, &c, &Point3::new(5.0, -3.0, 0.0)), 0);
    }

    #[test]
    fn overlap_of_two_unit_squares_shifted_by_half() {
        let sq = |x: f64| {
            vec![Point2::new(x, 0.0), Point2::new(x + 1.0, 0.0), Point2::new(x + 1.0, 1.0), Point2::new(x, 1.0)]
        };
        let mut scratch = Default::default();
        let mut b = sq(0.5);
        assert!((convex_overlap_area(&sq(0.0), &b, &mut scratch) - 0.5).abs() < 1e-15);
        b.reverse();
        assert!((convex_overlap_area(&sq(0.0), &b, &mut scratch) - 0.5).abs() < 1e-15);
        assert_eq!(convex_overlap_area(&sq(0.0), &sq(1.0), &mut scratch), 0.0);
    }

    #[test]
    fn degenerate_triangles_are_found_exactly() {
        let p = |x: f64, y: f64, z: f64| Point3::new(x, y, z);
        assert!(triangle_is_degenerate(&[p(0.0, 0.0, 0.0), p(1.0, 1.0, 1.0), p(2.0, 2.0, 2.0)]));
        assert!(triangle_is_degenerate(&[p(0.1, 0.2, 0.3), p(0.1, 0.2, 0.3), p(0.4, 0.5, 0.6)]));
        assert!(!triangle_is_degenerate(&[p(0.0, 0.0, 0.0), p(1.0, 1.0, 1.0), p(2.0, 2.0, 2.0 + 1e-15)]));
    }
}
