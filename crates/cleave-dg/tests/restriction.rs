//! The exact restriction of a parent element's polynomial to its children (`basis::restriction`,
//! docs/math/dg.md §12): a cube split 1→8; at points inside each child, the child's field from
//! the restricted coefficients equals the parent's field to 1e-12 for random coefficients of
//! degrees 1 and 2. (The map is algebraic in the two frames, so the children's shapes do not
//! enter; the cube's children are the refinement of issue 38.)

use cleave_core::{Point3, Real, Vector3};
use cleave_dg::basis::{ElementBasis, basis_size, exponents, restriction};
use cleave_geometry::{PolyhedralMesh, element_frame, element_moments};

/// The basis of `element` of `mesh` (exact moments in its bounding frame).
fn basis(mesh: &PolyhedralMesh, element: usize, degree: usize) -> ElementBasis {
    let frame = element_frame(mesh, element);
    let mut moments = Vec::new();
    element_moments(mesh, element, &frame, 2 * degree, &mut moments);
    ElementBasis::new(frame, degree, &moments).unwrap()
}

/// `Σ d_i ψ_i(p)`.
fn field(basis: &ElementBasis, degree: usize, d: &[Real], p: &Point3<Real>) -> Real {
    let exps = exponents(degree);
    let n = exps.len();
    let (mut values, mut gradients) = (vec![0.0; n], vec![Vector3::zeros(); n]);
    basis.evaluate(&exps, p, &mut values, &mut gradients);
    values.iter().zip(d).map(|(v, c)| v * c).sum()
}

#[test]
fn children_carry_the_parents_polynomial_exactly() {
    let mut random = cleave_testkit::Lcg::new(17);
    let origin = Point3::new(0.3, -0.2, 0.5);
    let parent_mesh = PolyhedralMesh::grid(origin, 0.8, [1, 1, 1]);
    let children = PolyhedralMesh::grid(origin, 0.4, [2, 2, 2]);
    for degree in [1, 2] {
        let n = basis_size(degree);
        let parent = basis(&parent_mesh, 0, degree);
        let d: Vec<Real> = (0..n).map(|_| random.next()).collect();
        for c in 0..children.num_elements {
            let child = basis(&children, c, degree);
            let r = restriction(&parent, &child, degree).unwrap();
            let dc: Vec<Real> = (0..n).map(|i| (0..n).map(|j| r[(i, j)] * d[j]).sum()).collect();
            let frame = element_frame(&children, c);
            for _ in 0..20 {
                // A point inside the child (its bounding box is the child cube).
                let p = frame.center + Vector3::new(random.next(), random.next(), random.next()) * 0.5 * frame.scale;
                let (a, b) = (field(&parent, degree, &d, &p), field(&child, degree, &dc, &p));
                assert!((a - b).abs() < 1e-12 * (1.0 + a.abs()), "degree {degree}, child {c}: {a} against {b}");
            }
            // A child field off by 1e-6 in its constant is told apart (the test can fail).
            let other: Vec<Real> = dc.iter().enumerate().map(|(i, x)| if i == 0 { x + 1e-6 } else { *x }).collect();
            let p = frame.center;
            assert!((field(&parent, degree, &d, &p) - field(&child, degree, &other, &p)).abs() > 1e-12);
        }
    }
}
