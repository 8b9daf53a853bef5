//! The closest point of a triangle to a point, with its barycentric coordinates, and the
//! closest points of two lines.

use nalgebra::Point3;

/// The point of triangle `t` closest to `p` and its barycentric coordinates `(u, v, w)`
/// (`u a + v b + w c`), by Voronoi regions (Ericson, *Real-Time Collision Detection*, §5.1.5).
/// A degenerate triangle gives a point of its closure.
pub fn closest_point_on_triangle(p: &Point3<f64>, t: &[Point3<f64>; 3]) -> (Point3<f64>, [f64; 3]) {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, [1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, [1.0 - v, v, 0.0]);
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, [0.0, 1.0 - w, w]);
    }
    let denominator = va + vb + vc;
    if denominator == 0.0 || !denominator.is_finite() {
        return (a, [1.0, 0.0, 0.0]);
    }
    let (v, w) = (vb / denominator, vc / denominator);
    (a + ab * v + ac * w, [1.0 - v - w, v, w])
}

/// The parameters `(s, t)` of the closest points `p₀ + s (p₁ − p₀)` and `q₀ + t (q₁ − q₀)` of
/// the two lines through the segments, or `None` when the lines are parallel to within
/// `1e-12` of the product of their squared lengths (then no single pair is closest). Where
/// both lie in `[0, 1]` they are also the closest points of the segments, and the segment
/// between them is perpendicular to both (Ericson, *Real-Time Collision Detection*, §5.1.8).
pub fn closest_parameters_of_lines(p: &[Point3<f64>; 2], q: &[Point3<f64>; 2]) -> Option<(f64, f64)> {
    let (d1, d2, r) = (p[1] - p[0], q[1] - q[0], p[0] - q[0]);
    let (a, b, e) = (d1.norm_squared(), d1.dot(&d2), d2.norm_squared());
    let (c, f) = (d1.dot(&r), d2.dot(&r));
    let denominator = a * e - b * b;
    // Also rejects NaN input: the comparison is false.
    if denominator.partial_cmp(&(1e-12 * a * e)) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let s = (b * f - c * e) / denominator;
    Some((s, (b * s + f) / e))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the defining property: the segment between the two points is perpendicular to
    /// both lines; and against brute force where both parameters lie inside the segments.
    #[test]
    fn closest_points_of_lines_are_perpendicular_and_minimal() {
        let mut state = 987654321u64;
        let mut random = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut inside = 0;
        for _ in 0..400 {
            let mut point = || Point3::new(random(), random(), random());
            let (p, q) = ([point(), point()], [point(), point()]);
            let (s, t) = closest_parameters_of_lines(&p, &q).expect("random lines are not parallel");
            let (a, b) = (p[0] + (p[1] - p[0]) * s, q[0] + (q[1] - q[0]) * t);
            assert!((a - b).dot(&(p[1] - p[0])).abs() < 1e-10 && (a - b).dot(&(q[1] - q[0])).abs() < 1e-10);
            if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
                inside += 1;
                let n = 200;
                let best = (0..=n)
                    .flat_map(|i| (0..=n).map(move |j| (i as f64 / n as f64, j as f64 / n as f64)))
                    .map(|(u, v)| ((p[0] + (p[1] - p[0]) * u) - (q[0] + (q[1] - q[0]) * v)).norm())
                    .fold(f64::INFINITY, f64::min);
                assert!((a - b).norm() <= best + 1e-12);
            }
        }
        assert!(inside > 20, "the brute-force branch ran {inside} times");
        let parallel = [Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0)];
        let shifted = [Point3::new(0.0, 1.0, 0.0), Point3::new(2.0, 1.0, 0.0)];
        assert_eq!(closest_parameters_of_lines(&parallel, &shifted), None);
        // Two perpendicular skew lines: x-axis and the line x = 0.3, z = 1 along y.
        let skew = [Point3::new(0.3, -1.0, 1.0), Point3::new(0.3, 1.0, 1.0)];
        let (s, t) = closest_parameters_of_lines(&parallel, &skew).unwrap();
        assert!((s - 0.3).abs() < 1e-15 && (t - 0.5).abs() < 1e-15);
    }

    /// Against brute force: the minimum distance over a fine barycentric sampling of the
    /// triangle is never below the returned one, and the barycentric coordinates reproduce it.
    #[test]
    fn agrees_with_sampling() {
        let t = [Point3::new(0.1, -0.2, 0.3), Point3::new(1.3, 0.1, -0.2), Point3::new(0.4, 0.9, 0.5)];
        let mut state = 12345u64;
        let mut random = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 3.0 - 1.5
        };
        for _ in 0..200 {
            let p = Point3::new(random(), random(), random());
            let (c, w) = closest_point_on_triangle(&p, &t);
            let from_weights = Point3::from(t[0].coords * w[0] + t[1].coords * w[1] + t[2].coords * w[2]);
            assert!((from_weights - c).norm() < 1e-12);
            assert!(w.iter().all(|&x| x >= -1e-12) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let n = 60;
            let mut best = f64::INFINITY;
            for i in 0..=n {
                for j in 0..=n - i {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let q = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                    best = best.min((q - p).norm());
                }
            }
            let d = (c - p).norm();
            assert!(d <= best + 1e-12, "{d} > {best}");
            assert!(best - d < 0.05, "sampling is within 1/60 of the edge length of the closest point");
        }
    }
}
