//! Per-element polynomial bases: monomials in the element's scaled frame, orthonormalized against
//! the element's exact Gram matrix so the consistent mass matrix is `ρ I` (docs/math/dg.md §2).
//!
//! `m_α(x) = ξ^α`, `ξ = (x − c) / s` with `c` the centroid and `s` the largest centroid–vertex
//! distance; `G = ∫_K m mᵀ = L Lᵀ` (Cholesky); `ψ = A m` with `A = L⁻¹`, so `∫_K ψ ψᵀ = I`.

use cleave_core::{Point3, Real, Vector3};
use cleave_geometry::{Frame, monomial_exponents, monomial_index};
use nalgebra::DMatrix;

/// Number of monomials of degree ≤ `degree` in three variables.
pub fn basis_size(degree: usize) -> usize {
    (degree + 1) * (degree + 2) * (degree + 3) / 6
}

/// The orthonormal basis of one element.
#[derive(Clone, Debug)]
pub struct ElementBasis {
    /// The scaled frame of the monomials.
    pub frame: Frame,
    /// `A = L⁻¹`: row `i` holds the monomial coefficients of `ψ_i`.
    pub a: DMatrix<Real>,
    /// Element volume.
    pub volume: Real,
}

/// Monomial exponents of degree ≤ `degree` (cached by callers).
pub fn exponents(degree: usize) -> Vec<[u32; 3]> {
    monomial_exponents(degree)
}

/// Index of the monomial `e` (graded order).
pub fn index(e: [u32; 3]) -> usize {
    monomial_index(e)
}

/// Values of all monomials of degree ≤ `degree` at `xi`.
pub fn monomials(exps: &[[u32; 3]], xi: &Vector3<Real>, out: &mut [Real]) {
    for (o, e) in out.iter_mut().zip(exps) {
        *o = xi.x.powi(e[0] as i32) * xi.y.powi(e[1] as i32) * xi.z.powi(e[2] as i32);
    }
}

/// `∂/∂ξ_d` of all monomials at `xi`.
pub fn monomial_gradients(exps: &[[u32; 3]], xi: &Vector3<Real>, out: &mut [Vector3<Real>]) {
    let pw = |x: Real, n: u32| if n == 0 { 1.0 } else { x.powi(n as i32) };
    for (o, e) in out.iter_mut().zip(exps) {
        let [a, b, c] = *e;
        let (x, y, z) = (xi.x, xi.y, xi.z);
        *o = Vector3::new(
            if a == 0 { 0.0 } else { a as Real * pw(x, a - 1) * pw(y, b) * pw(z, c) },
            if b == 0 { 0.0 } else { b as Real * pw(x, a) * pw(y, b - 1) * pw(z, c) },
            if c == 0 { 0.0 } else { c as Real * pw(x, a) * pw(y, b) * pw(z, c - 1) },
        );
    }
}

impl ElementBasis {
    /// Orthonormalizes the monomials of degree ≤ `degree` against the Gram matrix built from the
    /// element's exact moments `moments` (degree ≤ 2·degree, in `frame`). `None` when the Gram
    /// matrix is not positive definite (a degenerate element).
    pub fn new(frame: Frame, degree: usize, moments: &[Real]) -> Option<Self> {
        let exps = exponents(degree);
        let n = exps.len();
        let gram = DMatrix::from_fn(n, n, |i, j| moments[index(add(exps[i], exps[j]))]);
        let l = gram.cholesky()?.l();
        let a = l.try_inverse()?;
        Some(Self { frame, a, volume: moments[0] })
    }

    /// `ξ` of a point.
    #[inline]
    pub fn xi(&self, p: &Point3<Real>) -> Vector3<Real> {
        (p - self.frame.center) / self.frame.scale
    }

    /// Values `ψ_i(p)` and gradients `∇ψ_i(p)` (physical), written into the given buffers.
    pub fn evaluate(&self, exps: &[[u32; 3]], p: &Point3<Real>, values: &mut [Real], gradients: &mut [Vector3<Real>]) {
        let n = exps.len();
        let xi = self.xi(p);
        let mut m = [0.0; 10];
        let mut dm = [Vector3::zeros(); 10];
        monomials(exps, &xi, &mut m[..n]);
        monomial_gradients(exps, &xi, &mut dm[..n]);
        for i in 0..n {
            let mut v = 0.0;
            let mut g = Vector3::zeros();
            for k in 0..=i {
                // A is lower triangular.
                let a = self.a[(i, k)];
                v += a * m[k];
                g += dm[k] * a;
            }
            values[i] = v;
            gradients[i] = g / self.frame.scale;
        }
    }
}

/// The exact restriction of a parent element's polynomial to a child's basis (a child of a split or
/// refinement, lying inside the parent): `R` with `d_child = R d_parent` for each displacement
/// component, so that `Σ d_child,i ψ^child_i = Σ d_parent,i ψ^parent_i` everywhere
/// (docs/math/dg.md §12). With `ξ_parent = o + r ξ_child` the parent's monomials are `E` times the
/// child's (`shifted_monomial`), and `R = (A_parent E A_child⁻¹)ᵀ`. No integration; `None` if the
/// child's coefficient matrix is singular (it never is for a basis `ElementBasis::new` made).
pub fn restriction(parent: &ElementBasis, child: &ElementBasis, degree: usize) -> Option<DMatrix<Real>> {
    let exps = exponents(degree);
    let n = exps.len();
    let o = (child.frame.center - parent.frame.center) / parent.frame.scale;
    let r = child.frame.scale / parent.frame.scale;
    let mut e = DMatrix::zeros(n, n);
    let mut row = vec![0.0; n];
    for (beta_index, beta) in exps.iter().enumerate() {
        shifted_monomial(*beta, &o, r, degree, &mut row);
        for (k, value) in row.iter().enumerate() {
            e[(beta_index, k)] = *value;
        }
    }
    // A_child is lower triangular: its inverse is the Cholesky factor, recovered by a solve.
    let child_inverse = child.a.clone().try_inverse()?;
    Some((&parent.a * e * child_inverse).transpose())
}

/// Sum of exponents.
#[inline]
pub fn add(a: [u32; 3], b: [u32; 3]) -> [u32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// Coefficients of `m_β((o + r ξ))` as a polynomial in `ξ` over the monomials of degree ≤ `degree`
/// (per-axis binomial expansion; the substitution is a scaling and shift per axis).
pub fn shifted_monomial(beta: [u32; 3], o: &Vector3<Real>, r: Real, degree: usize, out: &mut [Real]) {
    out.iter_mut().for_each(|x| *x = 0.0);
    let binom = |n: u32, k: u32| -> Real { (0..k).map(|i| (n - i) as Real / (i + 1) as Real).product() };
    for kx in 0..=beta[0] {
        let cx = binom(beta[0], kx) * o.x.powi((beta[0] - kx) as i32) * r.powi(kx as i32);
        for ky in 0..=beta[1] {
            let cy = binom(beta[1], ky) * o.y.powi((beta[1] - ky) as i32) * r.powi(ky as i32);
            for kz in 0..=beta[2] {
                let cz = binom(beta[2], kz) * o.z.powi((beta[2] - kz) as i32) * r.powi(kz as i32);
                if (kx + ky + kz) as usize <= degree {
                    out[index([kx, ky, kz])] += cx * cy * cz;
                }
            }
        }
    }
}
