//! The linear tetrahedron: shape function gradients, barycentric weights, the 12×12 rest
//! stiffness of linear elasticity, and quadrature rules on tetrahedra of any degree.

use cleave_core::quadrature::gauss_legendre;
use cleave_core::{Material, Matrix3, Point3, Real, Vector3};
use nalgebra::DMatrix;

/// Rest data of one tetrahedron.
#[derive(Clone, Copy, Debug)]
pub struct TetShape {
    /// Rest corners.
    pub corners: [Point3<Real>; 4],
    /// `Dm⁻¹` with `Dm = [X₁−X₀, X₂−X₀, X₃−X₀]`.
    pub dm_inv: Matrix3<Real>,
    /// Gradients of the four shape functions.
    pub gradients: [Vector3<Real>; 4],
    /// Volume.
    pub volume: Real,
}

impl TetShape {
    /// Shape data of the tetrahedron with these corners (`None` if it is degenerate).
    pub fn new(corners: [Point3<Real>; 4]) -> Option<Self> {
        let dm = Matrix3::from_columns(&[corners[1] - corners[0], corners[2] - corners[0], corners[3] - corners[0]]);
        let volume = dm.determinant() / 6.0;
        if volume.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let dm_inv = dm.try_inverse()?;
        let g1 = dm_inv.row(0).transpose();
        let g2 = dm_inv.row(1).transpose();
        let g3 = dm_inv.row(2).transpose();
        Some(Self { corners, dm_inv, gradients: [-(g1 + g2 + g3), g1, g2, g3], volume })
    }

    /// Barycentric weights (shape function values) at `p`.
    #[inline]
    pub fn barycentric(&self, p: &Point3<Real>) -> [Real; 4] {
        let l = self.dm_inv * (p - self.corners[0]);
        [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]
    }

    /// The 12×12 rest stiffness of linear elasticity, `K_ab = V (λ g_a g_bᵀ + μ g_b g_aᵀ +
    /// μ (g_a·g_b) I)`, scaled by `fraction`, exactly symmetric.
    pub fn stiffness(&self, material: &Material, fraction: Real) -> DMatrix<Real> {
        let (lambda, mu) = material.lame();
        let v = self.volume * fraction;
        let mut k = DMatrix::zeros(12, 12);
        for a in 0..4 {
            for b in 0..4 {
                let (ga, gb) = (self.gradients[a], self.gradients[b]);
                let block = (ga * gb.transpose() * lambda
                    + gb * ga.transpose() * mu
                    + Matrix3::identity() * (mu * ga.dot(&gb)))
                    * v;
                for i in 0..3 {
                    for j in 0..3 {
                        k[(3 * a + i, 3 * b + j)] = block[(i, j)];
                    }
                }
            }
        }
        let kt = k.transpose();
        (k + kt) * 0.5
    }
}

/// A rule on the reference tetrahedron `{(u,v,w) ≥ 0, u+v+w ≤ 1}`: barycentric-free reference
/// coordinates and weights summing to 1 (multiply by the volume).
#[derive(Clone, Debug)]
pub struct TetRule {
    /// Points in reference coordinates `(u, v, w)`: `X = X₀ + u(X₁−X₀) + v(X₂−X₀) + w(X₃−X₀)`.
    pub points: Vec<[Real; 3]>,
    /// Weights, summing to 1.
    pub weights: Vec<Real>,
}

impl TetRule {
    /// A rule exact for polynomials of degree `degree`: the symmetric 4-point rule for degree
    /// ≤ 2, otherwise the collapsed (Duffy) tensor product of Gauss–Legendre rules with
    /// `n = ⌈(degree + 3) / 2⌉` points per axis (at most 6, degree 9).
    pub fn of_degree(degree: usize) -> Self {
        if degree <= 1 {
            return Self { points: vec![[0.25; 3]], weights: vec![1.0] };
        }
        if degree == 2 {
            let a = 0.585_410_196_624_968_5;
            let b = 0.138_196_601_125_010_5;
            return Self { points: vec![[b, b, b], [a, b, b], [b, a, b], [b, b, a]], weights: vec![0.25; 4] };
        }
        let n = (degree + 3).div_ceil(2).min(6);
        let (x, w) = gauss_legendre(n).expect("1..=6 point rules exist");
        let mut points = Vec::with_capacity(n * n * n);
        let mut weights = Vec::with_capacity(n * n * n);
        for (xa, wa) in x.iter().zip(w) {
            let s = 0.5 * (xa + 1.0);
            for (xb, wb) in x.iter().zip(w) {
                let t = 0.5 * (xb + 1.0);
                for (xc, wc) in x.iter().zip(w) {
                    let r = 0.5 * (xc + 1.0);
                    // (s, t, r) in the unit cube → u = s, v = t(1−s), w = r(1−s)(1−t).
                    let jacobian = (1.0 - s) * (1.0 - s) * (1.0 - t);
                    points.push([s, t * (1.0 - s), r * (1.0 - s) * (1.0 - t)]);
                    // Gauss weights on [0, 1] are half those on [−1, 1]; reference volume 1/6.
                    weights.push(wa * wb * wc * 0.125 * jacobian * 6.0);
                }
            }
        }
        Self { points, weights }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_integrate_monomials_exactly() {
        // ∫_T u^a v^b w^c = a! b! c! / (a+b+c+3)!, and the rules are normalized by 1/6.
        let fact = |n: u32| (1..=n).map(|k| k as Real).product::<Real>();
        for degree in 1..=6 {
            let rule = TetRule::of_degree(degree);
            for a in 0..=degree as u32 {
                for b in 0..=(degree as u32 - a) {
                    for c in 0..=(degree as u32 - a - b) {
                        let exact = fact(a) * fact(b) * fact(c) / fact(a + b + c + 3) * 6.0;
                        let q: Real = rule
                            .points
                            .iter()
                            .zip(&rule.weights)
                            .map(|(p, w)| w * p[0].powi(a as i32) * p[1].powi(b as i32) * p[2].powi(c as i32))
                            .sum();
                        assert!((q - exact).abs() < 1e-14, "degree {degree}: {a} {b} {c}: {q} vs {exact}");
                    }
                }
            }
        }
    }

    #[test]
    fn stiffness_annihilates_rigid_motions() {
        let shape = TetShape::new([
            Point3::new(0.1, 0.0, 0.0),
            Point3::new(1.0, 0.2, 0.0),
            Point3::new(0.0, 1.0, 0.3),
            Point3::new(0.2, 0.1, 1.0),
        ])
        .unwrap();
        let material = Material::new(1e6, 0.3, 1000.0).unwrap();
        let k = shape.stiffness(&material, 1.0);
        let omega = Vector3::new(0.3, -0.2, 0.5);
        let u = nalgebra::DVector::from_iterator(
            12,
            shape.corners.iter().flat_map(|p| {
                let v = omega.cross(&p.coords) + Vector3::new(1.0, 2.0, 3.0);
                [v.x, v.y, v.z]
            }),
        );
        assert!((&k * u).norm() < 1e-9 * k.norm());
    }
}
