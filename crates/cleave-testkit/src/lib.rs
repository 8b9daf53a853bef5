//! cleave-testkit: the conformance suite every backend must pass (design notes, "Verification
//! every backend owes"). Each check compares the backend against an independent number — finite
//! differences, the transposed product, the shared block kernel, an exact linear field — and
//! returns what it measured, so a failing test says by how much.

pub mod compare;
pub mod problems;
pub mod stability;

use cleave_core::{AssemblyPattern, BlockRanks, Discretization, Matrix3, Point3, Real, Vector3};
use nalgebra::Rotation3;

/// A measured discrepancy and the tolerance it was held to.
#[derive(Clone, Debug)]
pub struct Check {
    /// What was checked.
    pub name: &'static str,
    /// The relative discrepancy found.
    pub error: Real,
    /// The largest acceptable one.
    pub tolerance: Real,
}

impl Check {
    /// Whether the discrepancy is within tolerance (NaN fails).
    pub fn passed(&self) -> bool {
        self.error <= self.tolerance
    }
}

/// Deterministic pseudo-random numbers in [−1, 1] (no dependency, reproducible across runs).
#[derive(Clone, Debug)]
pub struct Lcg(u64);

impl Lcg {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(1))
    }

    /// Next number in [−1, 1].
    #[allow(clippy::should_implement_trait)] // an infinite generator, not an Iterator: no Option
    pub fn next(&mut self) -> Real {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as Real / (1u64 << 53) as Real) * 2.0 - 1.0
    }

    /// A vector of `n` numbers in [−1, 1].
    pub fn vector(&mut self, n: usize) -> Vec<Real> {
        (0..n).map(|_| self.next()).collect()
    }
}

fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

fn norm(a: &[Real]) -> Real {
    dot(a, a).sqrt()
}

fn rest_scale(d: &dyn Discretization) -> Real {
    let rest = d.rest_dofs();
    let mut lo = [Real::MAX; 3];
    let mut hi = [Real::MIN; 3];
    for p in rest.chunks_exact(3) {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<Real>().sqrt()
}

/// A large smooth deformation of the rest state: rotation, stretch and noise of 5% of the size.
fn deformed(d: &dyn Discretization, rng: &mut Lcg) -> Vec<Real> {
    let scale = rest_scale(d);
    let rotation = Rotation3::from_euler_angles(0.3, -0.7, 1.1).into_inner();
    let stretch = Matrix3::new(1.2, 0.1, 0.0, 0.0, 0.9, 0.05, 0.0, 0.0, 1.1);
    let mut x = Vec::with_capacity(d.rest_dofs().len());
    for p in d.rest_dofs().chunks_exact(3) {
        let q = rotation * stretch * Vector3::new(p[0], p[1], p[2]);
        x.extend((0..3).map(|a| q[a] + 0.05 * scale * rng.next()));
    }
    x
}

fn rotations_at(d: &dyn Discretization, x: &[Real]) -> Vec<Matrix3<Real>> {
    let mut r = vec![Matrix3::identity(); d.num_frames()];
    d.write_rotations(x, &mut r);
    r
}

fn force(d: &dyn Discretization, r: &[Matrix3<Real>], x: &[Real]) -> Vec<Real> {
    let mut f = vec![0.0; x.len()];
    d.add_internal_force(r, x, &mut f);
    f
}

/// Force = −∇(elastic energy) with rotations frozen, by central differences along random
/// directions (the energy is quadratic then, so the difference quotient is exact to rounding).
pub fn force_is_energy_gradient(d: &dyn Discretization) -> Check {
    let mut rng = Lcg::new(1);
    let x = deformed(d, &mut rng);
    let r = rotations_at(d, &x);
    let f = force(d, &r, &x);
    let eps = 1e-4 * rest_scale(d);
    let mut worst: Real = 0.0;
    for _ in 0..5 {
        let dir = rng.vector(x.len());
        let plus: Vec<Real> = x.iter().zip(&dir).map(|(x, d)| x + eps * d).collect();
        let minus: Vec<Real> = x.iter().zip(&dir).map(|(x, d)| x - eps * d).collect();
        let fd = (d.elastic_energy(&r, &plus) - d.elastic_energy(&r, &minus)) / (2.0 * eps);
        let analytic = -dot(&f, &dir);
        worst = worst.max((fd - analytic).abs() / (norm(&f) * norm(&dir)));
    }
    Check { name: "force = -grad energy", error: worst, tolerance: 1e-7 }
}

/// Stiffness action = −Jacobian of the force (rotations frozen), by central differences.
pub fn stiffness_is_force_jacobian(d: &dyn Discretization) -> Check {
    let mut rng = Lcg::new(2);
    let x = deformed(d, &mut rng);
    let r = rotations_at(d, &x);
    let eps = 1e-4 * rest_scale(d);
    let dir = rng.vector(x.len());
    let plus: Vec<Real> = x.iter().zip(&dir).map(|(x, d)| x + eps * d).collect();
    let minus: Vec<Real> = x.iter().zip(&dir).map(|(x, d)| x - eps * d).collect();
    let (fp, fm) = (force(d, &r, &plus), force(d, &r, &minus));
    let mut kd = vec![0.0; x.len()];
    d.add_stiffness_action(&r, &dir, 1.0, &mut kd);
    let diff: Vec<Real> = fp.iter().zip(&fm).zip(&kd).map(|((p, m), k)| (p - m) / (2.0 * eps) + k).collect();
    Check { name: "stiffness = -d force/dx", error: norm(&diff) / norm(&kd), tolerance: 1e-7 }
}

/// `uᵀ (K w) = wᵀ (K u)` for random `u`, `w` and warped `K`.
pub fn stiffness_is_symmetric(d: &dyn Discretization) -> Check {
    let mut rng = Lcg::new(3);
    let x = deformed(d, &mut rng);
    let r = rotations_at(d, &x);
    let (u, w) = (rng.vector(x.len()), rng.vector(x.len()));
    let (mut ku, mut kw) = (vec![0.0; x.len()], vec![0.0; x.len()]);
    d.add_stiffness_action(&r, &u, 1.0, &mut ku);
    d.add_stiffness_action(&r, &w, 1.0, &mut kw);
    let error = (dot(&u, &kw) - dot(&w, &ku)).abs() / (norm(&u) * norm(&kw));
    Check { name: "stiffness symmetric", error, tolerance: 1e-12 }
}

/// The backend's (possibly overridden) stiffness action equals the assembled shared-kernel matrix
/// times the vector, and its force equals the shared block kernel's.
pub fn matrix_free_equals_assembled(d: &dyn Discretization) -> Check {
    let mut rng = Lcg::new(4);
    let x = deformed(d, &mut rng);
    let r = rotations_at(d, &x);
    let blocks = d.blocks();
    let pattern = AssemblyPattern::from_groups(d.num_nodes(), blocks.node_groups());
    let ranks = BlockRanks::new(blocks, &pattern);
    let mut values = vec![0.0; pattern.nnz()];
    blocks.add_to_matrix(&r, 1.0, &pattern, &ranks, &mut values);
    let dir = rng.vector(x.len());
    let mut assembled = vec![0.0; x.len()];
    pattern.mul_vec(&values, &dir, &mut assembled);
    let mut free = vec![0.0; x.len()];
    d.add_stiffness_action(&r, &dir, 1.0, &mut free);
    let action_error = norm(&assembled.iter().zip(&free).map(|(a, b)| a - b).collect::<Vec<_>>()) / norm(&assembled);
    let mut shared = vec![0.0; x.len()];
    blocks.add_internal_force(&r, &x, d.rest_dofs(), &mut shared);
    let own = force(d, &r, &x);
    let force_error = norm(&shared.iter().zip(&own).map(|(a, b)| a - b).collect::<Vec<_>>()) / norm(&shared);
    Check { name: "matrix-free = assembled", error: action_error.max(force_error), tolerance: 1e-12 }
}

/// A rigid motion `x = Q X + t` of the rest state gives zero force once the backend extracts its
/// rotations (measured against the force of the non-rigid deformation of the same size).
pub fn rigid_motion_is_force_free(d: &dyn Discretization) -> Check {
    let mut rng = Lcg::new(5);
    let q = Rotation3::from_euler_angles(2.0, -1.0, 0.4).into_inner();
    let t = Vector3::new(3.0, -2.0, 1.0) * rest_scale(d);
    let mut x: Vec<Real> = d
        .rest_dofs()
        .chunks_exact(3)
        .flat_map(|p| {
            let y = q * Vector3::new(p[0], p[1], p[2]);
            [y.x, y.y, y.z]
        })
        .collect();
    d.add_translation(&t, &mut x);
    // Several warm-started extractions: a rotation of 2 rad from the identity takes a few rounds.
    let mut r = vec![Matrix3::identity(); d.num_frames()];
    for _ in 0..10 {
        d.write_rotations(&x, &mut r);
    }
    let rigid = force(d, &r, &x);
    let bent = deformed(d, &mut rng);
    let reference = force(d, &rotations_at(d, &bent), &bent);
    Check { name: "rigid motion -> zero force", error: norm(&rigid) / norm(&reference), tolerance: 1e-9 }
}

/// Embedded points reproduce an affine field `x = A X + b` exactly.
pub fn embedding_reproduces_linear_fields(d: &dyn Discretization) -> Check {
    let mut rng = Lcg::new(6);
    let a = Matrix3::from_fn(|_, _| rng.next());
    let b = Vector3::new(rng.next(), rng.next(), rng.next());
    let mut x: Vec<Real> = d
        .rest_dofs()
        .chunks_exact(3)
        .flat_map(|p| {
            let y = a * Vector3::new(p[0], p[1], p[2]);
            [y.x, y.y, y.z]
        })
        .collect();
    d.add_translation(&b, &mut x);
    // Points inside the solid: the backend's own quadrature points.
    let mut points = Vec::new();
    let zero = vec![0.0; x.len()];
    d.visit_field(&zero, 2, &mut |s| points.push(s.position));
    let points: Vec<Point3<Real>> = points.into_iter().step_by(7).collect();
    let Ok(embedding) = d.embed(&points) else {
        return Check { name: "embedding reproduces linear fields", error: Real::INFINITY, tolerance: 1e-12 };
    };
    let scale = rest_scale(d) + b.norm();
    let error = points
        .iter()
        .enumerate()
        .map(|(i, p)| (embedding.point(&x, i).coords - (a * p.coords + b)).norm() / scale)
        .fold(0.0, Real::max);
    Check { name: "embedding reproduces linear fields", error, tolerance: 1e-12 }
}

/// Patch test: prescribe an affine displacement on `boundary_nodes`, solve `K u = 0` for the
/// rest, and compare every DOF and every quadrature-point gradient with the affine field.
pub fn patch_test(d: &dyn Discretization, boundary_nodes: &[usize]) -> Check {
    let mut rng = Lcg::new(7);
    let a = Matrix3::from_fn(|_, _| 1e-3 * rng.next());
    let b = Vector3::new(rng.next(), rng.next(), rng.next()) * 1e-3;
    let exact = |p: &[Real]| a * Vector3::new(p[0], p[1], p[2]) + b;
    let rest = d.rest_dofs();
    let prescribed: Vec<(usize, Real)> = boundary_nodes
        .iter()
        .flat_map(|&n| {
            let u = exact(&rest[3 * n..3 * n + 3]);
            (0..3).map(move |c| (3 * n + c, u[c]))
        })
        .collect();
    let load = vec![0.0; rest.len()];
    let Ok(solution) = cleave_integrator::solve_static(d, &load, &prescribed) else {
        return Check { name: "patch test", error: Real::INFINITY, tolerance: 1e-10 };
    };
    let mut error: Real = 0.0;
    for (n, p) in rest.chunks_exact(3).enumerate() {
        let u = exact(p);
        for c in 0..3 {
            error = error.max((solution.displacement[3 * n + c] - u[c]).abs() / a.norm());
        }
    }
    d.visit_field(&solution.displacement, 2, &mut |s| {
        error = error.max((s.gradient - a).norm() / a.norm());
    });
    Check { name: "patch test", error, tolerance: 1e-9 }
}

/// Every check of the suite that needs no backend-specific input.
pub fn conformance_suite(d: &dyn Discretization) -> Vec<Check> {
    vec![
        force_is_energy_gradient(d),
        stiffness_is_force_jacobian(d),
        stiffness_is_symmetric(d),
        matrix_free_equals_assembled(d),
        rigid_motion_is_force_free(d),
        embedding_reproduces_linear_fields(d),
    ]
}

/// Panics with a table of every failed check (for use in tests).
pub fn assert_all_pass(checks: &[Check]) {
    let failed: Vec<String> = checks
        .iter()
        .filter(|c| !c.passed())
        .map(|c| format!("{}: error {:.3e} > tolerance {:.1e}", c.name, c.error, c.tolerance))
        .collect();
    for c in checks {
        println!("{:<40} error {:.3e} (tolerance {:.1e})", c.name, c.error, c.tolerance);
    }
    assert!(failed.is_empty(), "conformance failures:\n{}", failed.join("\n"));
}
