//! Quadrature for non-polynomial integrands (loads, Dirichlet data, error norms) on polygons and
//! polyhedra by signed simplex decompositions with collapsed Gauss rules. Polynomial integrands
//! (mass, stiffness, face terms) never come here: they use the exact divergence-theorem moments of
//! `cleave_geometry` (docs/math/dg.md §3).
//!
//! A polygon is fanned into triangles from its first vertex and a polyhedron into tetrahedra from
//! an apex to those triangles. For non-convex shapes some simplices have negative orientation; their
//! weights are negative and the sum is still the integral over the shape of any function defined on
//! the simplices' union (the polynomial extension of a DG field, a smooth load), because the signed
//! simplices cover every point of the shape once more than they cover points outside it.

use cleave_core::quadrature::gauss_legendre;
use cleave_core::{Point3, Real, Vector3};

/// Gauss–Legendre points per direction of the collapsed rules: exact for degree 2·5 − 3 = 7 on
/// simplices (the Duffy Jacobian uses up two degrees).
const POINTS_PER_DIRECTION: usize = 5;

fn unit_interval_rule() -> Vec<(Real, Real)> {
    let (p, w) = gauss_legendre(POINTS_PER_DIRECTION).expect("5-point Gauss rule exists");
    p.iter().zip(w).map(|(p, w)| (0.5 * (p + 1.0), 0.5 * w)).collect()
}

/// Calls `visit(point, weight)` for a rule on the triangle `a, b, c` whose weights sum to the signed
/// area relative to `normal` (positive when `a, b, c` is counter-clockwise about `normal`).
pub fn triangle_rule(
    a: &Point3<Real>,
    b: &Point3<Real>,
    c: &Point3<Real>,
    normal: &Vector3<Real>,
    visit: &mut dyn FnMut(Point3<Real>, Real),
) {
    let double_area = (b - a).cross(&(c - a)).dot(normal);
    let rule = unit_interval_rule();
    for &(u, wu) in &rule {
        for &(v, wv) in &rule {
            // Duffy: (u, v) ∈ [0,1]² ↦ (s, t) = (u, (1 − u) v), Jacobian (1 − u).
            let s = u;
            let t = (1.0 - u) * v;
            let p = a + (b - a) * s + (c - a) * t;
            visit(p, wu * wv * (1.0 - u) * double_area);
        }
    }
}

/// Calls `visit(point, weight)` for a rule on the tetrahedron `a, b, c, d` whose weights sum to its
/// signed volume `((b − a) × (c − a)) · (d − a) / 6`.
pub fn tetrahedron_rule(
    a: &Point3<Real>,
    b: &Point3<Real>,
    c: &Point3<Real>,
    d: &Point3<Real>,
    visit: &mut dyn FnMut(Point3<Real>, Real),
) {
    let six_volume = (b - a).cross(&(c - a)).dot(&(d - a));
    let rule = unit_interval_rule();
    for &(u, wu) in &rule {
        for &(v, wv) in &rule {
            for &(w, ww) in &rule {
                // Collapsed cube: s = u, t = (1−u) v, r = (1−u)(1−v) w; Jacobian (1−u)²(1−v).
                let s = u;
                let t = (1.0 - u) * v;
                let r = (1.0 - u) * (1.0 - v) * w;
                let p = a + (b - a) * s + (c - a) * t + (d - a) * r;
                visit(p, wu * wv * ww * (1.0 - u) * (1.0 - u) * (1.0 - v) * six_volume);
            }
        }
    }
}

/// A rule over a planar polygon (vertices in order, counter-clockwise about `normal`).
pub fn polygon_rule(vertices: &[Point3<Real>], normal: &Vector3<Real>, visit: &mut dyn FnMut(Point3<Real>, Real)) {
    for k in 1..vertices.len().saturating_sub(1) {
        triangle_rule(&vertices[0], &vertices[k], &vertices[k + 1], normal, visit);
    }
}

/// A rule over a polyhedron given by its outward faces (each a vertex loop), cones from `apex`.
pub fn polyhedron_rule<'a>(
    faces: impl Iterator<Item = Vec<Point3<Real>>> + 'a,
    apex: &Point3<Real>,
    visit: &mut dyn FnMut(Point3<Real>, Real),
) {
    for face in faces {
        for k in 1..face.len().saturating_sub(1) {
            // Outward face (a, b, c) seen from inside: the tetrahedron (apex, a, b, c) is positive.
            tetrahedron_rule(apex, &face[0], &face[k], &face[k + 1], visit);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ over the unit simplex of x^a y^b z^c = a! b! c! / (a+b+c+3)!.
    fn simplex_moment(a: i32, b: i32, c: i32) -> Real {
        let f = |n: i32| (1..=n).map(Real::from).product::<Real>();
        f(a) * f(b) * f(c) / f(a + b + c + 3)
    }

    #[test]
    fn tetrahedron_rule_is_exact_to_degree_seven() {
        let o = Point3::origin();
        for (a, b, c) in [(0, 0, 0), (1, 2, 0), (3, 2, 2), (7, 0, 0), (2, 2, 3), (1, 1, 5)] {
            let mut sum = 0.0;
            tetrahedron_rule(
                &o,
                &Point3::new(1.0, 0.0, 0.0),
                &Point3::new(0.0, 1.0, 0.0),
                &Point3::new(0.0, 0.0, 1.0),
                &mut |p, w| sum += w * p.x.powi(a) * p.y.powi(b) * p.z.powi(c),
            );
            let exact = simplex_moment(a, b, c);
            assert!((sum - exact).abs() < 1e-13 * exact.abs().max(1e-3), "{a}{b}{c}: {sum} vs {exact}");
        }
    }

    #[test]
    fn non_convex_polygon_weights_integrate_exactly() {
        // An L-shaped hexagon (area 3) fanned from a reflex-free corner: ∫ x dA = 3.5 (by boxes).
        let l = [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)]
            .map(|(x, y)| Point3::new(x, y, 0.0));
        let (mut area, mut first) = (0.0, 0.0);
        polygon_rule(&l, &Vector3::z(), &mut |p, w| {
            area += w;
            first += w * p.x;
        });
        assert!((area - 3.0).abs() < 1e-13 && (first - (2.0 * 1.0 + 0.5 * 1.0)).abs() < 1e-13, "{area} {first}");
        // Rotated start vertex (the fan then crosses outside): the signed sum stays exact.
        let mut rotated = l.to_vec();
        rotated.rotate_left(3);
        let mut area2 = 0.0;
        polygon_rule(&rotated, &Vector3::z(), &mut |_, w| area2 += w);
        assert!((area2 - 3.0).abs() < 1e-13, "{area2}");
    }
}
