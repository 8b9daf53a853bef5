//! Tests of `triangle_aabb_overlap`: hand-made cases and a cross-check against parry3d-f64.

mod common;

use cleave_geometry::triangle_aabb_overlap;
use common::Rng;
use nalgebra::Point3;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector;
use parry3d_f64::query::details::intersection_test_aabb_triangle;
use parry3d_f64::shape::Triangle;

fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
    Point3::new(x, y, z)
}

fn unit_box(tri: [Point3<f64>; 3]) -> bool {
    triangle_aabb_overlap(&tri, &p(0.0, 0.0, 0.0), &p(1.0, 1.0, 1.0))
}

#[test]
fn hand_made_cases() {
    // Inside.
    assert!(unit_box([p(0.2, 0.2, 0.2), p(0.8, 0.2, 0.2), p(0.2, 0.8, 0.2)]));
    // Huge triangle slicing through the box with all vertices outside.
    assert!(unit_box([p(-10.0, -10.0, 0.5), p(10.0, -10.0, 0.5), p(0.0, 10.0, 0.5)]));
    // Same plane shifted above the box.
    assert!(!unit_box([p(-10.0, -10.0, 1.5), p(10.0, -10.0, 1.5), p(0.0, 10.0, 1.5)]));
    // Touching a face, and just off it.
    assert!(unit_box([p(1.0, 0.2, 0.2), p(1.0, 0.8, 0.2), p(1.0, 0.2, 0.8)]));
    assert!(!unit_box([p(1.0 + 1e-9, 0.2, 0.2), p(1.0 + 1e-9, 0.8, 0.2), p(1.0 + 1e-9, 0.2, 0.8)]));
    // Touching only at a box corner with a vertex.
    assert!(unit_box([p(1.0, 1.0, 1.0), p(2.0, 1.0, 1.0), p(1.0, 2.0, 3.0)]));
    // Tilted plane x + y + z = 3.1 misses the corner (1,1,1); the box axes do not separate.
    assert!(!unit_box([p(3.1, 0.0, 0.0), p(0.0, 3.1, 0.0), p(0.0, 0.0, 3.1)]));
    assert!(unit_box([p(2.9, 0.0, 0.0), p(0.0, 2.9, 0.0), p(0.0, 0.0, 2.9)]));
    // Only an edge cross product separates: the bounding boxes overlap and the plane cuts
    // the box, yet the triangle misses it (parry agrees).
    let edge_case = [p(-1.0, 0.5, 1.5), p(-0.25, -0.5, 0.25), p(0.5, -1.0, -0.75)];
    assert!(!unit_box(edge_case));
    assert!(without_edge_axes(&edge_case, &p(0.0, 0.0, 0.0), &p(1.0, 1.0, 1.0)));
    assert!(!parry(&edge_case, &p(0.0, 0.0, 0.0), &p(1.0, 1.0, 1.0)));
    // Degenerate triangles: a segment crossing the box, a segment missing it diagonally,
    // a point inside.
    assert!(unit_box([p(-1.0, 0.5, 0.5), p(2.0, 0.5, 0.5), p(2.0, 0.5, 0.5)]));
    assert!(!unit_box([p(2.05, 0.0, 0.5), p(0.0, 2.05, 0.5), p(0.0, 2.05, 0.5)]));
    assert!(unit_box([p(0.5, 0.5, 0.5); 3]));
    // Empty box and non-finite input.
    assert!(!triangle_aabb_overlap(&[p(0.5, 0.5, 0.5); 3], &p(1.0, 0.0, 0.0), &p(0.0, 1.0, 1.0)));
    assert!(!unit_box([p(f64::NAN, 0.5, 0.5), p(0.5, 0.5, 0.5), p(0.5, 0.6, 0.5)]));
}

fn parry(tri: &[Point3<f64>; 3], lo: &Point3<f64>, hi: &Point3<f64>) -> bool {
    let v = |q: &Point3<f64>| Vector::new(q.x, q.y, q.z);
    intersection_test_aabb_triangle(&Aabb::new(v(lo), v(hi)), &Triangle::new(v(&tri[0]), v(&tri[1]), v(&tri[2])))
}

/// Only the box axes and the normal (the incomplete test a naive implementation uses).
fn without_edge_axes(tri: &[Point3<f64>; 3], lo: &Point3<f64>, hi: &Point3<f64>) -> bool {
    for d in 0..3 {
        let a = tri.iter().map(|q| q[d]).fold(f64::INFINITY, f64::min);
        let b = tri.iter().map(|q| q[d]).fold(f64::NEG_INFINITY, f64::max);
        if a > hi[d] || b < lo[d] {
            return false;
        }
    }
    let n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
    let c = nalgebra::center(lo, hi);
    let h = (hi - lo) / 2.0;
    let r = h.x * n.x.abs() + h.y * n.y.abs() + h.z * n.z.abs();
    n.dot(&(tri[0] - c)).abs() <= r
}

/// Cross-checks against parry on random configurations; a disagreement is allowed only if
/// the configuration is within `delta` of touching.
fn cross_check(rng: &mut Rng, lattice: bool, n: usize) -> (usize, usize, usize) {
    let delta = 1e-12;
    let (mut overlapping, mut edge_axis_cases, mut borderline) = (0, 0, 0);
    let coord = |rng: &mut Rng| {
        if lattice { (rng.range(-2.0, 3.0) * 4.0).round() / 4.0 } else { rng.range(-1.5, 2.5) }
    };
    for _ in 0..n {
        let tri: [Point3<f64>; 3] = std::array::from_fn(|_| p(coord(rng), coord(rng), coord(rng)));
        let a = p(coord(rng), coord(rng), coord(rng));
        let b = p(coord(rng), coord(rng), coord(rng));
        let lo = a.inf(&b);
        let hi = a.sup(&b);
        let mine = triangle_aabb_overlap(&tri, &lo, &hi);
        let theirs = parry(&tri, &lo, &hi);
        if mine != theirs {
            let d = nalgebra::Vector3::repeat(delta);
            let shrunk = triangle_aabb_overlap(&tri, &(lo + d), &(hi - d));
            let grown = triangle_aabb_overlap(&tri, &(lo - d), &(hi + d));
            assert!(
                !shrunk && grown,
                "disagreement away from touching: {tri:?} box {lo} {hi}: mine {mine}, parry {theirs}"
            );
            borderline += 1;
        }
        overlapping += usize::from(mine);
        if !mine && without_edge_axes(&tri, &lo, &hi) {
            edge_axis_cases += 1;
        }
    }
    (overlapping, edge_axis_cases, borderline)
}

#[test]
fn agrees_with_parry_on_random_triangles_and_boxes() {
    let mut rng = Rng(7);
    let n = 20_000;
    let (overlapping, edge_axis_cases, borderline) = cross_check(&mut rng, false, n);
    // Both outcomes are well represented, and the edge axes matter in some cases.
    assert!(overlapping > n / 5 && overlapping < 4 * n / 5, "{overlapping}");
    assert!(edge_axis_cases > 20, "{edge_axis_cases}");
    assert!(borderline < 5, "{borderline}");
}

#[test]
fn agrees_with_parry_on_lattice_configurations_with_exact_contacts() {
    // Coordinates on a 1/4 lattice create many exactly touching configurations.
    let mut rng = Rng(8);
    let n = 20_000;
    let (overlapping, _, _) = cross_check(&mut rng, true, n);
    assert!(overlapping > n / 10 && overlapping < 9 * n / 10, "{overlapping}");
}
