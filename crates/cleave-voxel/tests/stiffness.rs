//! The closed-form 24×24 cube stiffness against 2×2×2 Gauss quadrature of the trilinear hexahedron
//! (an independent B-matrix path), against entries of mueller2004's appendix, and against the
//! six rigid-body modes it must annihilate.

use cleave_core::quadrature::gauss_legendre;
use cleave_core::{Material, Real};
use cleave_voxel::stiffness::{corner_signs, cube_stiffness};
use nalgebra::{SMatrix, SVector};

/// `K = Σ_q w_q Bᵀ D B |J|` with Voigt order (xx, yy, zz, yz, xz, xy), engineering shears.
fn quadrature_stiffness(material: &Material, h: Real) -> SMatrix<Real, 24, 24> {
    let (lambda, mu) = material.lame();
    let mut d = SMatrix::<Real, 6, 6>::zeros();
    for i in 0..3 {
        for j in 0..3 {
            d[(i, j)] = lambda;
        }
        d[(i, i)] = lambda + 2.0 * mu;
        d[(i + 3, i + 3)] = mu;
    }
    let (points, weights) = gauss_legendre(2).unwrap();
    let mut k = SMatrix::<Real, 24, 24>::zeros();
    let r = h / 2.0;
    for (xi, wx) in points.iter().zip(weights) {
        for (eta, wy) in points.iter().zip(weights) {
            for (zeta, wz) in points.iter().zip(weights) {
                let xi3 = [*xi, *eta, *zeta];
                let mut b = SMatrix::<Real, 6, 24>::zeros();
                for c in 0..8 {
                    let s = corner_signs(c);
                    // φ_c = Π (1 + s_a ξ_a) / 8, ∂φ/∂x_a = s_a/(8r) Π_{b≠a} (1 + s_b ξ_b)
                    let grad: [Real; 3] = std::array::from_fn(|a| {
                        s[a] / (8.0 * r) * (0..3).filter(|&b| b != a).map(|b| 1.0 + s[b] * xi3[b]).product::<Real>()
                    });
                    for a in 0..3 {
                        b[(a, 3 * c + a)] = grad[a];
                    }
                    b[(3, 3 * c + 1)] = grad[2];
                    b[(3, 3 * c + 2)] = grad[1];
                    b[(4, 3 * c)] = grad[2];
                    b[(4, 3 * c + 2)] = grad[0];
                    b[(5, 3 * c)] = grad[1];
                    b[(5, 3 * c + 1)] = grad[0];
                }
                k += b.transpose() * d * b * (wx * wy * wz * r * r * r);
            }
        }
    }
    k
}

#[test]
fn closed_form_equals_gauss_quadrature() {
    for (e, nu, h) in [(1e6, 0.3, 0.1), (2.1e11, 0.0, 1.0), (5e3, 0.49, 0.013), (7.7e7, -0.4, 2.5)] {
        let material = Material::new(e, nu, 1000.0).unwrap();
        let closed = cube_stiffness(&material, h);
        let quadrature = quadrature_stiffness(&material, h);
        let scale = quadrature.amax();
        for row in 0..24 {
            for col in 0..24 {
                let difference = (closed[row * 24 + col] - quadrature[(row, col)]).abs();
                assert!(
                    difference <= 1e-12 * scale,
                    "E={e} nu={nu} h={h} entry ({row},{col}): {} vs {}",
                    closed[row * 24 + col],
                    quadrature[(row, col)]
                );
            }
        }
    }
}

#[test]
fn matches_entries_of_the_paper_appendix() {
    // mueller2004 appendix A: a = hE(1−ν)/((1+ν)(1−2ν)), b = hEν/(…), c = hE/(2(1+ν)).
    let (e, nu, h) = (3e6, 0.27, 0.2);
    let material = Material::new(e, nu, 1.0).unwrap();
    let k = cube_stiffness(&material, h);
    let a = h * e * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let b = h * e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let c = h * e / (2.0 * (1.0 + nu));
    let entry = |i: usize, ai: usize, j: usize, bj: usize| k[(3 * i + ai) * 24 + 3 * j + bj];
    let close = |x: Real, y: Real| (x - y).abs() <= 1e-12 * x.abs().max(y.abs());
    // Diagonal blocks: d = (a + 2c)/9 on the diagonal, |o| = (b + c)/12 off it.
    for i in 0..8 {
        for ai in 0..3 {
            assert!(close(entry(i, ai, i, ai), (a + 2.0 * c) / 9.0));
        }
        assert!(close(entry(i, 0, i, 1).abs(), (b + c) / 12.0));
    }
    // Body diagonal (our corners 0 and 7, the paper's 0 and 6): d = (−a − 2c)/36, |o| = (b + c)/24.
    assert!(close(entry(0, 0, 7, 0), (-a - 2.0 * c) / 36.0));
    assert!(close(entry(0, 0, 7, 1).abs(), (b + c) / 24.0));
    // Edge along x (corners 0 and 1 in both numberings): d1 = (−a + c)/9, d2 = (a − c)/18,
    // |o1| = |b − c|/12.
    assert!(close(entry(0, 0, 1, 0), (-a + c) / 9.0));
    assert!(close(entry(0, 1, 1, 1), (a - c) / 18.0));
    assert!(close(entry(0, 2, 1, 2), (a - c) / 18.0));
    assert!(close(entry(0, 0, 1, 1).abs(), (b - c).abs() / 12.0));
}

#[test]
fn annihilates_rigid_body_modes_and_nothing_else() {
    let material = Material::new(1e6, 0.3, 1.0).unwrap();
    let k = SMatrix::<Real, 24, 24>::from_row_slice(&cube_stiffness(&material, 0.5));
    let mut modes = Vec::new();
    for t in 0..3 {
        modes.push(SVector::<Real, 24>::from_fn(|i, _| if i % 3 == t { 1.0 } else { 0.0 }));
    }
    for axis in 0..3 {
        let mut m = SVector::<Real, 24>::zeros();
        for c in 0..8 {
            let p = nalgebra::Vector3::from(corner_signs(c));
            let mut w = nalgebra::Vector3::zeros();
            w[axis] = 1.0;
            let v = w.cross(&p);
            for a in 0..3 {
                m[3 * c + a] = v[a];
            }
        }
        modes.push(m);
    }
    for m in &modes {
        assert!((k * m).norm() < 1e-9 * k.amax());
    }
    // exactly six zero eigenvalues: the 18 others are clearly positive
    let eigen = k.symmetric_eigenvalues();
    let zeros = eigen.iter().filter(|&&l| l.abs() < 1e-9 * k.amax()).count();
    assert_eq!(zeros, 6);
    assert!(eigen.iter().all(|&l| l > -1e-9 * k.amax()));
}
