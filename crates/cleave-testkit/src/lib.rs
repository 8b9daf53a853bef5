//! cleave-testkit: the conformance suite every backend must pass (design notes, "Verification
//! every backend owes"). Each check compares the backend against an independent number — finite
//! differences, the transposed product, the shared block kernel, an exact linear field — and
//! returns what it measured, so a failing test says by how much.

pub mod compare;
pub mod cut_conformance;
pub mod momentum;
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

/// Rotations extracted to convergence: warm-started rounds until no frame moves by more than
/// 1e-14 (large bends take more than one round from the identity).
fn converged_rotations(d: &dyn Discretization, x: &[Real], start: Vec<Matrix3<Real>>) -> Vec<Matrix3<Real>> {
    let mut r = start;
    for _ in 0..50 {
        let before = r.clone();
        d.write_rotations(x, &mut r);
        if r.iter().zip(&before).all(|(a, b)| (a - b).amax() < 1e-14) {
            break;
        }
    }
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

/// The backend's (possibly overridden) stiffness action and internal force against matrices
/// assembled from its blocks (`BlockSet::add_to_matrix`, a kernel neither method calls):
///
/// - action: `add_stiffness_action(R, d) = K_R d`;
/// - force, warped: with rotations frozen the force is affine in `x`, so
///   `f(x + s d) − f(x) = −s K_R d` at a deformed state whose rotations differ per frame;
/// - force, unwarped: at `R = I`, `f(x) = −K_I (x − X)`, which also pins the constant part.
///
/// For a backend that keeps the default `add_internal_force`, the force halves check the shared
/// force kernel against the assembly, not a method against itself.
pub fn matrix_free_equals_assembled(d: &dyn Discretization) -> Check {
    let mut rng = Lcg::new(4);
    let x = deformed(d, &mut rng);
    let r = rotations_at(d, &x);
    let blocks = d.blocks();
    let pattern = AssemblyPattern::from_groups(d.num_nodes(), blocks.node_groups());
    let ranks = BlockRanks::new(blocks, &pattern);
    let assemble = |rotations: &[Matrix3<Real>]| {
        let mut values = vec![0.0; pattern.nnz()];
        blocks.add_to_matrix(rotations, 1.0, &pattern, &ranks, &mut values);
        values
    };
    let relative = |a: &[Real], b: &[Real]| norm(&a.iter().zip(b).map(|(a, b)| a - b).collect::<Vec<_>>()) / norm(a);
    let warped = assemble(&r);
    let dir = rng.vector(x.len());
    let mut assembled = vec![0.0; x.len()];
    pattern.mul_vec(&warped, &dir, &mut assembled);
    let mut free = vec![0.0; x.len()];
    d.add_stiffness_action(&r, &dir, 1.0, &mut free);
    let action_error = relative(&assembled, &free);

    let s = 0.1 * rest_scale(d);
    let moved: Vec<Real> = x.iter().zip(&dir).map(|(x, d)| x + s * d).collect();
    let difference: Vec<Real> = force(d, &r, &moved).iter().zip(&force(d, &r, &x)).map(|(a, b)| a - b).collect();
    let expected: Vec<Real> = assembled.iter().map(|k| -s * k).collect();
    let warped_force_error = relative(&expected, &difference);

    let identity = vec![Matrix3::identity(); d.num_frames()];
    let displacement: Vec<Real> = x.iter().zip(d.rest_dofs()).map(|(x, rest)| x - rest).collect();
    let mut expected = vec![0.0; x.len()];
    pattern.mul_vec(&assemble(&identity), &displacement, &mut expected);
    expected.iter_mut().for_each(|e| *e = -*e);
    let unwarped_force_error = relative(&expected, &force(d, &identity, &x));
    Check {
        name: "matrix-free = assembled",
        error: action_error.max(warped_force_error).max(unwarped_force_error),
        tolerance: 1e-12,
    }
}

/// The DOFs of the affine field `x = A X + b`: `A` applied to every coefficient of the rest
/// DOFs, then `b` added as a translation (right for nodal and modal bases alike).
pub fn affine_dofs(d: &dyn Discretization, a: &Matrix3<Real>, b: &Vector3<Real>) -> Vec<Real> {
    let mut x: Vec<Real> = d
        .rest_dofs()
        .chunks_exact(3)
        .flat_map(|p| {
            let y = a * Vector3::new(p[0], p[1], p[2]);
            [y.x, y.y, y.z]
        })
        .collect();
    d.add_translation(b, &mut x);
    x
}

/// A rigid motion `x = Q X + t` of the rest state gives zero force once the backend extracts its
/// rotations (measured against the force of the non-rigid deformation of the same size).
pub fn rigid_motion_is_force_free(d: &dyn Discretization) -> Check {
    let mut rng = Lcg::new(5);
    let q = Rotation3::from_euler_angles(2.0, -1.0, 0.4).into_inner();
    let t = Vector3::new(3.0, -2.0, 1.0) * rest_scale(d);
    let x = affine_dofs(d, &q, &t);
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

/// Density of the body, from the gravity load against the plain load of the same constant field
/// (both through the trait, so it works for nodal and non-nodal bases alike).
fn density(d: &dyn Discretization) -> Real {
    let n = d.rest_dofs().len();
    let mut unit_z = vec![0.0; n];
    d.add_translation(&Vector3::z(), &mut unit_z);
    let (mut weight, mut volume) = (vec![0.0; n], vec![0.0; n]);
    d.add_gravity_load(&Vector3::z(), &mut weight);
    d.add_load(&|_| Vector3::z(), &mut volume);
    dot(&weight, &unit_z) / dot(&volume, &unit_z)
}

/// A bent state: the body bent about an axis through its centroid by an angle that grows along
/// its longest extent (about 1.2 rad end to end), twisted, then rotated as a whole, so that
/// neighbouring frames get visibly different rotations on every backend. Its DOFs: for a nodal
/// basis (a partition of unity, `Σ_k ∫ N_k` = the body's volume) the weighted average
/// `x_k = ∫ bend(X) N_k / ∫ N_k` over each node's support, whatever the mass lumping (a lumping
/// that moves mass between a duplicate's nodes would pull a node with more mass than `ρ ∫ N_k`
/// towards the origin); otherwise the mass-weighted projection `x_k = ρ ∫ bend(X) N_k / m_k`
/// (the exact L2 projection for an orthonormal consistent basis).
pub fn bent_state(d: &dyn Discretization) -> Vec<Real> {
    let mut lo = Vector3::repeat(Real::MAX);
    let mut hi = Vector3::repeat(Real::MIN);
    let (mut centroid, mut volume) = (Vector3::zeros(), 0.0);
    let zero = vec![0.0; d.rest_dofs().len()];
    d.visit_field(&zero, 2, &mut |s| {
        lo = lo.inf(&s.position.coords);
        hi = hi.sup(&s.position.coords);
        centroid += s.weight * s.position.coords;
        volume += s.weight;
    });
    let centroid = centroid / volume;
    let extent = hi - lo;
    let axis = extent.imax();
    let (across, other) = ((axis + 2) % 3, (axis + 1) % 3);
    let curvature = 1.2 / extent[axis];
    let whole = Rotation3::from_euler_angles(0.4, -0.3, 0.9);
    let bend = move |p: &Point3<Real>| -> Vector3<Real> {
        let s = p.coords - centroid;
        let bent = Rotation3::from_axis_angle(&Vector3::ith_axis(across), curvature * s[axis]);
        let twist = Rotation3::from_axis_angle(&Vector3::ith_axis(axis), 0.3 * s[axis] / extent[axis]);
        let stretch = 1.0 + 0.05 * s[other] / extent[other].max(Real::MIN_POSITIVE);
        centroid + whole * (bent * (twist * s * stretch))
    };
    let mut projected = vec![0.0; d.rest_dofs().len()];
    d.add_load(&bend, &mut projected);
    let mut support = vec![0.0; projected.len()];
    d.add_load(&|_: &Point3<Real>| Vector3::repeat(1.0), &mut support);
    let nodal =
        (support.iter().step_by(3).sum::<Real>() / volume - 1.0).abs() < 1e-9 && support.iter().all(|&s| s > 0.0);
    if nodal {
        projected.iter_mut().zip(&support).for_each(|(x, s)| *x /= s);
    } else {
        let rho = density(d);
        for (x, m) in projected.iter_mut().zip(d.mass().diagonal()) {
            *x *= rho / m;
        }
    }
    projected
}

/// The largest angle [rad] between the rotation of frame 0 and any other frame.
fn rotation_spread(rotations: &[Matrix3<Real>]) -> Real {
    let first = rotations.first().copied().unwrap_or_else(Matrix3::identity);
    rotations
        .iter()
        .map(|r| {
            let relative = first.transpose() * r;
            ((relative.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
        })
        .fold(0.0, Real::max)
}

fn relative_difference(a: &[Real], b: &[Real]) -> Real {
    let diff: Vec<Real> = a.iter().zip(b).map(|(a, b)| a - b).collect();
    norm(&diff) / norm(a).max(Real::MIN_POSITIVE)
}

/// Translation invariance: `moved` is the same discretization built with every rest position
/// (and any anchored boundary region) translated. At the bent state of `origin` translated the
/// same way, the internal force, the stiffness action and the elastic energy must be those of
/// `origin` (1e-10 relative). The bent state must give frames whose rotations differ by more
/// than 0.2 rad, or the check fails: a uniform rotation would hide the lever arm of a
/// translation.
pub fn translation_invariance(origin: &dyn Discretization, moved: &dyn Discretization) -> Check {
    let name = "translated problem -> same force, action, energy";
    let x0 = bent_state(origin);
    let x1: Vec<Real> = x0.iter().zip(moved.rest_dofs()).zip(origin.rest_dofs()).map(|((x, b), a)| x + b - a).collect();
    let identity = vec![Matrix3::identity(); origin.num_frames()];
    let (r0, r1) = (converged_rotations(origin, &x0, identity.clone()), converged_rotations(moved, &x1, identity));
    if rotation_spread(&r0) < 0.2 || x0.len() != moved.rest_dofs().len() {
        return Check { name, error: Real::INFINITY, tolerance: 1e-10 };
    }
    let force_error = relative_difference(&force(origin, &r0, &x0), &force(moved, &r1, &x1));
    let dir = Lcg::new(8).vector(x0.len());
    let (mut k0, mut k1) = (vec![0.0; x0.len()], vec![0.0; x0.len()]);
    origin.add_stiffness_action(&r0, &dir, 1.0, &mut k0);
    moved.add_stiffness_action(&r1, &dir, 1.0, &mut k1);
    let action_error = relative_difference(&k0, &k1);
    let (e0, e1) = (origin.elastic_energy(&r0, &x0), moved.elastic_energy(&r1, &x1));
    let energy_error = (e0 - e1).abs() / e0.abs().max(Real::MIN_POSITIVE);
    Check { name, error: force_error.max(action_error).max(energy_error), tolerance: 1e-10 }
}

/// Rotation covariance of a free body: rotating a bent state rigidly by `Q` rotates every
/// frame's rotation and every nodal force by `Q` and leaves the energy unchanged.
pub fn rotation_covariance(d: &dyn Discretization) -> Check {
    let name = "rotated bent state -> rotated force";
    let x = bent_state(d);
    let r = converged_rotations(d, &x, vec![Matrix3::identity(); d.num_frames()]);
    if rotation_spread(&r) < 0.2 {
        return Check { name, error: Real::INFINITY, tolerance: 1e-10 };
    }
    let q = Rotation3::from_euler_angles(-1.1, 0.6, 2.3).into_inner();
    let rotate = |v: &[Real]| -> Vec<Real> {
        v.chunks_exact(3)
            .flat_map(|p| {
                let y = q * Vector3::new(p[0], p[1], p[2]);
                [y.x, y.y, y.z]
            })
            .collect()
    };
    let xq = rotate(&x);
    // Warm start at Q R, as a simulation rotating slowly into this state would have.
    let rq = converged_rotations(d, &xq, r.iter().map(|r| q * r).collect());
    let frame_error = r.iter().zip(&rq).map(|(r, rq)| (q * r - rq).norm()).fold(0.0, Real::max);
    let force_error = relative_difference(&rotate(&force(d, &r, &x)), &force(d, &rq, &xq));
    let (e, eq) = (d.elastic_energy(&r, &x), d.elastic_energy(&rq, &xq));
    let energy_error = (e - eq).abs() / e.abs().max(Real::MIN_POSITIVE);
    Check { name, error: frame_error.max(force_error).max(energy_error), tolerance: 1e-10 }
}

/// Embedded points reproduce an affine field `x = A X + b` exactly.
pub fn embedding_reproduces_linear_fields(d: &dyn Discretization) -> Check {
    let mut rng = Lcg::new(6);
    let a = Matrix3::from_fn(|_, _| rng.next());
    let b = Vector3::new(rng.next(), rng.next(), rng.next());
    let x = affine_dofs(d, &a, &b);
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
        rotation_covariance(d),
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
