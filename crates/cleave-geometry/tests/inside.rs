//! Tests of the winding number, `contains` and the parry-accelerated `InsideTester`.

mod common;

use cleave_geometry::{GeometryError, InsideTester, TriangleMesh};
use common::{BUNNY_VOLUME, Rng, box_mesh, bunny, icosphere, unit_cube};
use nalgebra::{Point3, Vector3};

#[test]
fn winding_number_of_box_inside_outside_and_near_faces() {
    let m = box_mesh([-1.0, 2.0, 0.5], [1.0, 2.0, 3.0]);
    let mut rng = Rng(1);
    for _ in 0..200 {
        let p = rng.point(&Point3::new(-0.99, 2.01, 0.51), &Point3::new(-0.01, 3.99, 3.49));
        assert!((m.winding_number(&p) - 1.0).abs() < 1e-12, "{p}");
        assert!(m.contains(&p));
    }
    for _ in 0..200 {
        let p = rng.point(&Point3::new(-5.0, -5.0, -5.0), &Point3::new(5.0, 5.0, 5.0));
        let inside = (-1.0..=0.0).contains(&p.x) && (2.0..=4.0).contains(&p.y) && (0.5..=3.5).contains(&p.z);
        let w = m.winding_number(&p);
        let expected = if inside { 1.0 } else { 0.0 };
        assert!((w - expected).abs() < 1e-12, "{p}: {w}");
    }
    // Just inside / outside the face x = 0.
    let inner = Point3::new(-1e-9, 3.3, 1.7);
    let outer = Point3::new(1e-9, 3.3, 1.7);
    assert!((m.winding_number(&inner) - 1.0).abs() < 1e-6);
    assert!(m.winding_number(&outer).abs() < 1e-6);
    // At a vertex the value stays finite.
    assert!(m.winding_number(&Point3::new(-1.0, 2.0, 0.5)).is_finite());
    assert!(m.winding_number(&Point3::new(f64::NAN, 0.0, 0.0)).is_nan());
    assert!(!m.contains(&Point3::new(f64::NAN, 0.0, 0.0)));
}

#[test]
fn winding_number_counts_nesting_and_orientation() {
    // Two nested outward spheres: winding 2 in the inner one.
    let outer = icosphere(2, 2.0, Point3::origin());
    let inner = icosphere(2, 1.0, Point3::origin());
    let off = outer.vertices.len() as u32;
    let mut both = outer.clone();
    both.vertices.extend(&inner.vertices);
    both.triangles.extend(inner.triangles.iter().map(|t| t.map(|i| i + off)));
    assert!((both.winding_number(&Point3::new(0.1, 0.2, 0.0)) - 2.0).abs() < 1e-12);
    assert!((both.winding_number(&Point3::new(1.5, 0.0, 0.0)) - 1.0).abs() < 1e-12);
    // Inward orientation gives -1.
    let flipped = unit_cube().transformed(|p| Point3::new(-p.x, p.y, p.z));
    assert!((flipped.winding_number(&Point3::new(-0.5, 0.5, 0.5)) + 1.0).abs() < 1e-12);
}

#[test]
fn winding_number_of_an_open_hemisphere_soup_is_fractional() {
    // Half of a closed sphere, seen from its center, subtends half of the full solid angle.
    let s = icosphere(3, 1.0, Point3::origin());
    let upper: Vec<[u32; 3]> = s
        .triangles
        .iter()
        .copied()
        .filter(|t| t.iter().map(|&i| s.vertices[i as usize].z).sum::<f64>() > 0.0)
        .collect();
    let half = TriangleMesh::new(s.vertices.clone(), upper);
    let w = half.winding_number(&Point3::origin());
    assert!((w - 0.5).abs() < 0.05, "{w}");
    assert!(half.validate_closed().is_err());
}

#[test]
fn bunny_inside_tester_agrees_with_winding_number_and_volume() {
    let m = bunny();
    let fast = InsideTester::new(&m).unwrap();
    let (lo, hi) = m.aabb();
    let pad = Vector3::repeat(0.5);
    let (lo, hi) = (lo - pad, hi + pad);
    let mut rng = Rng(42);

    // Agreement with the exact winding number, which must be near an integer.
    let mut inside = 0;
    for _ in 0..2000 {
        let p = rng.point(&lo, &hi);
        let w = m.winding_number(&p);
        let nearest = w.round();
        assert!((w - nearest).abs() < 1e-6 && (nearest == 0.0 || nearest == 1.0), "{p}: {w}");
        assert_eq!(fast.contains(&p), m.contains(&p), "{p}: winding {w}");
        inside += usize::from(m.contains(&p));
    }
    assert!(inside > 200, "{inside}");

    // Monte Carlo volume with the fast tester: within 5 standard deviations.
    let n = 40_000;
    let hits = (0..n).filter(|_| fast.contains(&rng.point(&lo, &hi))).count();
    let box_volume = (hi - lo).product();
    let frac = hits as f64 / n as f64;
    let estimate = frac * box_volume;
    let sigma = box_volume * (frac * (1.0 - frac) / n as f64).sqrt();
    assert!((estimate - BUNNY_VOLUME).abs() < 5.0 * sigma, "{estimate} ± {sigma}");
}

#[test]
fn inside_tester_requires_a_closed_mesh() {
    let mut m = unit_cube();
    m.triangles.remove(5);
    assert!(matches!(InsideTester::new(&m), Err(GeometryError::OpenEdge { .. })));
    let t = InsideTester::new(&unit_cube()).unwrap();
    assert!(t.contains(&Point3::new(0.5, 0.5, 0.5)));
    assert!(!t.contains(&Point3::new(1.5, 0.5, 0.5)));
    assert!(!t.contains(&Point3::new(f64::NAN, 0.5, 0.5)));
}
