//! The shared benchmark problems of `shared/notes/benchmarks.md` (copied into
//! `docs/math/benchmarks.md`): the manufactured solutions `sin111` and `cos123` on the unit cube,
//! the static cantilever, and its crack (§5). Backend-neutral: everything goes through the trait.

use cleave_core::{Discretization, Material, Matrix3, Point3, Real, Vector3};
use std::f64::consts::PI;

/// Amplitude `A` of the manufactured displacement.
pub const MMS_AMPLITUDE: Real = 0.01;

/// The two manufactured solutions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Manufactured {
    /// `g = s1 s2 s3`, `a = (1,1,1)`, zero on the boundary.
    Sin111,
    /// `g = c1 c2 c3`, `a = (1,2,3)`, inhomogeneous Dirichlet data.
    Cos123,
}

impl Manufactured {
    fn direction(self) -> Vector3<Real> {
        match self {
            Manufactured::Sin111 => Vector3::new(1.0, 1.0, 1.0),
            Manufactured::Cos123 => Vector3::new(1.0, 2.0, 3.0),
        }
    }

    /// `g`, `∇g` and `Hess g` at `p`.
    fn scalar(self, p: &Point3<Real>) -> (Real, Vector3<Real>, Matrix3<Real>) {
        let s = p.coords.map(|x| (PI * x).sin());
        let c = p.coords.map(|x| (PI * x).cos());
        // Write g = f0(x) f1(y) f2(z) with f = sin or cos; f' and f'' per axis.
        let (f, df, ddf) = match self {
            Manufactured::Sin111 => (s, c * PI, -s * PI * PI),
            Manufactured::Cos123 => (c, -s * PI, -c * PI * PI),
        };
        let g = f[0] * f[1] * f[2];
        let grad = Vector3::new(df[0] * f[1] * f[2], f[0] * df[1] * f[2], f[0] * f[1] * df[2]);
        let mut hess = Matrix3::zeros();
        for i in 0..3 {
            for j in 0..3 {
                hess[(i, j)] = (0..3)
                    .map(|k| {
                        let order = usize::from(k == i) + usize::from(k == j);
                        match order {
                            0 => f[k],
                            1 => df[k],
                            _ => ddf[k],
                        }
                    })
                    .product();
            }
        }
        (g, grad, hess)
    }

    /// Exact displacement `u = A g a`.
    pub fn displacement(self, p: &Point3<Real>) -> Vector3<Real> {
        self.direction() * (MMS_AMPLITUDE * self.scalar(p).0)
    }

    /// Exact gradient `∇u = A a ⊗ ∇g`.
    pub fn gradient(self, p: &Point3<Real>) -> Matrix3<Real> {
        self.direction() * self.scalar(p).1.transpose() * MMS_AMPLITUDE
    }

    /// Body force `f = A [3π² μ g a − (λ+μ) (Hess g) a]` that makes `u` an equilibrium.
    pub fn body_force(self, material: &Material, p: &Point3<Real>) -> Vector3<Real> {
        let (lambda, mu) = material.lame();
        let (g, _, hess) = self.scalar(p);
        let a = self.direction();
        (a * (3.0 * PI * PI * mu * g) - hess * a * (lambda + mu)) * MMS_AMPLITUDE
    }
}

/// An exact displacement field: `(u, ∇u)` at a rest position.
pub type ExactField<'a> = dyn Fn(&Point3<Real>) -> (Vector3<Real>, Matrix3<Real>) + 'a;

/// Relative errors of a discrete displacement against an exact field.
#[derive(Clone, Copy, Debug)]
pub struct FieldErrors {
    /// `‖u − u_h‖_L2 / ‖u‖_L2`.
    pub l2_relative: Real,
    /// `|u − u_h|_H1 / |u|_H1`.
    pub h1_relative: Real,
}

/// Errors of `displacement` (DOF vector of `u_h`) against `exact`, with a quadrature of degree
/// `degree` per element (higher than the element's).
pub fn field_errors(
    d: &dyn Discretization,
    displacement: &[Real],
    degree: usize,
    exact: &ExactField<'_>,
) -> FieldErrors {
    let (mut e0, mut n0, mut e1, mut n1) = (0.0, 0.0, 0.0, 0.0);
    d.visit_field(displacement, degree, &mut |s| {
        let (u, grad) = exact(&s.position);
        e0 += s.weight * (u - s.displacement).norm_squared();
        n0 += s.weight * u.norm_squared();
        e1 += s.weight * (grad - s.gradient).norm_squared();
        n1 += s.weight * grad.norm_squared();
    });
    FieldErrors { l2_relative: (e0 / n0).sqrt(), h1_relative: (e1 / n1).sqrt() }
}

/// Observed convergence rate between two refinements: `log(e1/e2) / log(h1/h2)`.
pub fn rate(error_coarse: Real, error_fine: Real, h_coarse: Real, h_fine: Real) -> Real {
    (error_coarse / error_fine).ln() / (h_coarse / h_fine).ln()
}

/// The observed L2 and H1 rates between consecutive levels of a refinement on the unit cube
/// (`sizes[k]` cells per edge, `errors[k]` its relative (L2, H1) errors), each printed under
/// `label`.
pub fn refinement_rates(label: &str, sizes: &[usize], errors: &[(Real, Real)]) -> Vec<(Real, Real)> {
    (0..sizes.len().saturating_sub(1))
        .map(|w| {
            let (h0, h1) = (1.0 / sizes[w] as Real, 1.0 / sizes[w + 1] as Real);
            let l2 = rate(errors[w].0, errors[w + 1].0, h0, h1);
            let h1_rate = rate(errors[w].1, errors[w + 1].1, h0, h1);
            println!(
                "{label} n = {} → {}: L2 {:.3e} → {:.3e} rate {l2:.3}, H1 {:.3e} → {:.3e} rate {h1_rate:.3}",
                sizes[w],
                sizes[w + 1],
                errors[w].0,
                errors[w + 1].0,
                errors[w].1,
                errors[w + 1].1
            );
            (l2, h1_rate)
        })
        .collect()
}

/// Strong Dirichlet data: the scalar DOFs of the nodes `Discretization::dirichlet_nodes` holds
/// for `on_boundary` (for nodal bases the nodes whose rest position lies on it; for carved ones
/// also the nodes of elements touching it), each given `value` at its rest position. Scene pins
/// resolve through the same `dirichlet_nodes`.
pub fn nodal_dirichlet(
    d: &dyn Discretization,
    on_boundary: impl Fn(&Point3<Real>) -> bool,
    value: impl Fn(&Point3<Real>) -> Vector3<Real>,
) -> Vec<(usize, Real)> {
    let rest = d.rest_dofs();
    let mut prescribed = Vec::new();
    for node in d.dirichlet_nodes(&on_boundary) {
        let k = 3 * node as usize;
        let u = value(&Point3::new(rest[k], rest[k + 1], rest[k + 2]));
        prescribed.extend((0..3).map(|c| (k + c, u[c])));
    }
    prescribed
}

/// True on the boundary of the unit cube (to rounding).
pub fn on_unit_cube_boundary(p: &Point3<Real>) -> bool {
    p.coords.iter().any(|&x| x.abs() < 1e-9 || (x - 1.0).abs() < 1e-9)
}

/// The static cantilever of benchmarks.md §2.
pub mod cantilever {
    use super::*;

    /// Beam length along x.
    pub const LENGTH: Real = 4.0;
    /// Gravity.
    pub const GRAVITY: Real = 9.81;

    /// Young's modulus of the static cantilever [Pa].
    pub const YOUNGS_MODULUS: Real = 1e6;

    /// E = 1e6, the given ν, ρ = 1000.
    pub fn material(poisson_ratio: Real) -> Material {
        Material::new(YOUNGS_MODULUS, poisson_ratio, 1000.0).expect("benchmark material is valid")
    }

    /// Body force density `(0, 0, −ρg)`.
    pub fn force_density(material: &Material) -> Vector3<Real> {
        Vector3::new(0.0, 0.0, -material.density * GRAVITY)
    }

    /// Clamped DOFs: every node on x = 0 (nodal backends).
    pub fn clamped_dofs(d: &dyn Discretization) -> Vec<(usize, Real)> {
        nodal_dirichlet(d, |p| p.x.abs() < 1e-9, |_| Vector3::zeros())
    }

    /// Gauss points (2×2 per cell of an `m × m` grid) and weights on the tip face x = 4.
    pub fn tip_face_quadrature(m: usize) -> Vec<(Point3<Real>, Real)> {
        let g = 0.5 / 3f64.sqrt();
        let h = 1.0 / m as Real;
        let mut points = Vec::with_capacity(4 * m * m);
        for j in 0..m {
            for k in 0..m {
                for (a, b) in [(-g, -g), (-g, g), (g, -g), (g, g)] {
                    let y = (j as Real + 0.5 + a) * h;
                    let z = (k as Real + 0.5 + b) * h;
                    points.push((Point3::new(LENGTH, y, z), h * h / 4.0));
                }
            }
        }
        points
    }
}

/// The crack of the cut cantilever (benchmarks.md §5), and the same crack on other beams.
pub mod crack {
    use super::*;
    use cleave_core::CutSurface;

    /// The crack plane of the §5 cantilever: x = 2.
    pub const PLANE_X: Real = 2.0;
    /// Its front: the crack runs from the top face z = 1 down to z = 0.5.
    pub const FRONT_Z: Real = 0.5;

    /// The half-plane `{x = x_plane, z ≥ front_z}` over the box `lo..hi` as a soup of two
    /// triangles in rest space that reach `overhang` past the box on the three open sides (y
    /// below and above, z above), so the crack goes through the whole width and out of the top
    /// face, and ends inside the material exactly at z = `front_z`.
    pub fn half_plane(
        lo: &Point3<Real>,
        hi: &Point3<Real>,
        x_plane: Real,
        front_z: Real,
        overhang: Real,
    ) -> CutSurface {
        let (y0, y1, z1) = (lo.y - overhang, hi.y + overhang, hi.z + overhang);
        let corners = [
            Point3::new(x_plane, y0, front_z),
            Point3::new(x_plane, y1, front_z),
            Point3::new(x_plane, y1, z1),
            Point3::new(x_plane, y0, z1),
        ];
        CutSurface::Triangles(vec![[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]])
    }

    /// The §5 crack of the 4 × 1 × 1 beam for cells of edge `h` (overhang h).
    pub fn cantilever(h: Real) -> CutSurface {
        half_plane(&Point3::origin(), &Point3::new(cantilever::LENGTH, 1.0, 1.0), PLANE_X, FRONT_Z, h)
    }

    /// The two points whose u_x difference is the crack opening u_x(2⁺, 0.5, 1) − u_x(2⁻, 0.5,
    /// 1): on the top face, `1e-4 h` on either side of the plane (embedding a point exactly on
    /// a cut picks one side; `1e-4 h` changes the difference by 2e-4 h |∂u_x/∂x|).
    pub fn opening_points(h: Real) -> [Point3<Real>; 2] {
        let e = 1e-4 * h;
        [Point3::new(PLANE_X + e, 0.5, 1.0), Point3::new(PLANE_X - e, 0.5, 1.0)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The body force must equal −div σ(u) computed by finite differences of σ.
    #[test]
    fn body_force_is_minus_divergence_of_stress_by_finite_differences() {
        let material = Material::new(1e6, 0.3, 1000.0).unwrap();
        let (lambda, mu) = material.lame();
        for case in [Manufactured::Sin111, Manufactured::Cos123] {
            let stress = |p: &Point3<Real>| {
                let g = case.gradient(p);
                let eps = (g + g.transpose()) * 0.5;
                Matrix3::identity() * (lambda * eps.trace()) + eps * (2.0 * mu)
            };
            for p in [Point3::new(0.3, 0.6, 0.2), Point3::new(0.81, 0.17, 0.55)] {
                let h = 1e-5;
                let mut div = Vector3::zeros();
                for j in 0..3 {
                    let mut e = Vector3::zeros();
                    e[j] = h;
                    let ds = (stress(&(p + e)) - stress(&(p - e))) / (2.0 * h);
                    div += ds.column(j);
                }
                let f = case.body_force(&material, &p);
                assert!((f + div).norm() < 1e-6 * f.norm(), "{case:?} at {p}: f = {f}, -div = {}", -div);
            }
            // the gradient is the derivative of the displacement
            let p = Point3::new(0.42, 0.31, 0.77);
            let h = 1e-6;
            for j in 0..3 {
                let mut e = Vector3::zeros();
                e[j] = h;
                let fd = (case.displacement(&(p + e)) - case.displacement(&(p - e))) / (2.0 * h);
                assert!((fd - case.gradient(&p).column(j)).norm() < 1e-8);
            }
        }
    }
}

#[cfg(test)]
mod crack_tests {
    use super::crack;
    use cleave_core::{CutSurface, Point3, Real, Vector3};

    /// Whether `p` lies in the closed triangle `t` (same plane assumed), by barycentric signs.
    fn in_triangle(t: &[Point3<Real>; 3], p: &Point3<Real>) -> bool {
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        (0..3).all(|i| (t[(i + 1) % 3] - t[i]).cross(&(p - t[i])).dot(&n) >= -1e-12)
    }

    #[test]
    fn the_crack_covers_the_plane_above_its_front_through_the_whole_width() {
        let h = 0.25;
        let CutSurface::Triangles(soup) = crack::cantilever(h) else { panic!("a soup") };
        assert_eq!(soup.len(), 2);
        // Both triangles lie in x = 2.
        assert!(soup.iter().flatten().all(|p| p.x == 2.0));
        let covered = |y: Real, z: Real| soup.iter().any(|t| in_triangle(t, &Point3::new(2.0, y, z)));
        // Every point of the beam's cross-section at x = 2 above z = 0.5 is covered, none below.
        for i in 0..=20 {
            for k in 0..=20 {
                let (y, z) = (i as Real / 20.0, k as Real / 20.0);
                assert_eq!(covered(y, z), z >= 0.5, "(2, {y}, {z})");
            }
        }
        // Its area inside the beam's cross-section is 1 × 0.5; the whole soup is (1 + 2h)(0.5 + h).
        let area: Real = soup.iter().map(|t| 0.5 * (t[1] - t[0]).cross(&(t[2] - t[0])).norm()).sum();
        assert!((area - (1.0 + 2.0 * h) * (0.5 + h)).abs() < 1e-14, "{area}");
        let normal = (soup[0][1] - soup[0][0]).cross(&(soup[0][2] - soup[0][0]));
        assert!(normal.normalize().dot(&Vector3::x()).abs() > 1.0 - 1e-15);
        let [plus, minus] = crack::opening_points(h);
        assert!(plus.x > 2.0 && minus.x < 2.0 && (plus.x - minus.x - 2e-4 * h).abs() < 1e-15);
    }
}
