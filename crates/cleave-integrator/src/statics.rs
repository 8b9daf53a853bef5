//! The static linear solve `K u = f` (no warping) with prescribed displacements, for convergence
//! studies: assemble, eliminate the prescribed DOFs into the right-hand side, factorize, solve;
//! and the same solve matrix-free by two-level preconditioned CG (`IterativeStatics`); the
//! static analysis of a free body under an impact by inertia relief (`solve_inertia_relief`).

use crate::cg::CgWorkspace;
use crate::constraints::Constraints;
use crate::error::StepErrorKind;
use crate::integrator::invert_blocks_with_pins;
use crate::system::AssembledSystem;
use crate::two_level::TwoLevel;
use cleave_core::{Discretization, Matrix3, Real, Vector3};
use rayon::prelude::*;
use std::time::Instant;

/// A static solution and what it cost.
#[derive(Clone, Debug)]
pub struct StaticSolution {
    /// Displacement DOFs `u` (so positions are `X0 + u`).
    pub displacement: Vec<Real>,
    /// Strain energy `½ uᵀ K u` [J].
    pub strain_energy: Real,
    /// Stored nonzeros of `K`.
    pub nnz: usize,
    /// Nonzeros of the Cholesky factor.
    pub factor_nnz: usize,
    /// Seconds spent building the pattern and symbolic factorization.
    pub seconds_setup: Real,
    /// Seconds spent assembling values.
    pub seconds_assemble: Real,
    /// Seconds spent in the numeric factorization and solve.
    pub seconds_solve: Real,
}

/// The DOF count of `discretization`, once the load has that length and every prescribed DOF
/// exists.
fn check_static_input(
    discretization: &dyn Discretization,
    load: &[Real],
    prescribed: &[(usize, Real)],
) -> Result<usize, StepErrorKind> {
    let n = 3 * discretization.num_nodes();
    if load.len() != n {
        return Err(StepErrorKind::LoadLength { what: "load", len: load.len(), dofs: n });
    }
    if let Some(&(d, _)) = prescribed.iter().find(|(d, _)| *d >= n) {
        return Err(StepErrorKind::DofOutOfRange { what: "prescribed", dof: d, dofs: n });
    }
    Ok(n)
}

/// Solves `K u = f` with `u_d = value` for every `(d, value)` in `prescribed`.
pub fn solve_static(
    discretization: &dyn Discretization,
    load: &[Real],
    prescribed: &[(usize, Real)],
) -> Result<StaticSolution, StepErrorKind> {
    let n = check_static_input(discretization, load, prescribed)?;
    let clock = Instant::now();
    let constraints = Constraints { pinned_dofs: prescribed.iter().map(|&(d, _)| d).collect(), ..Default::default() };
    let mut system = AssembledSystem::new(discretization, &constraints, true)?;
    let seconds_setup = clock.elapsed().as_secs_f64();

    let clock = Instant::now();
    let identity = vec![Matrix3::identity(); discretization.num_frames()];
    system.fill(discretization, &identity, 0.0, 1.0);
    // rhs = f − K g for the prescribed field g, then rhs_d = g_d on prescribed rows.
    let mut g = vec![0.0; n];
    for &(d, value) in prescribed {
        g[d] = value;
    }
    let mut kg = vec![0.0; n];
    if prescribed.iter().any(|&(_, value)| value != 0.0) {
        system.pattern.mul_vec(&system.values, &g, &mut kg);
    }
    let mut rhs: Vec<Real> = load.iter().zip(&kg).map(|(f, kg)| f - kg).collect();
    for &(d, value) in prescribed {
        rhs[d] = value;
    }
    // The strain energy needs K without the pinned rows replaced; keep a copy only when there
    // are pins to replace (DG imposes its Dirichlet data weakly and has none).
    let unpinned = (!prescribed.is_empty()).then(|| system.values.clone());
    system.apply_pins();
    let seconds_assemble = clock.elapsed().as_secs_f64();

    let clock = Instant::now();
    system.factorize()?;
    system.solve_in_place(&mut rhs);
    let seconds_solve = clock.elapsed().as_secs_f64();
    if let Some(dof) = rhs.iter().position(|u| !u.is_finite()) {
        return Err(StepErrorKind::NotFinite { dof });
    }
    let mut ku = vec![0.0; n];
    system.pattern.mul_vec(unpinned.as_deref().unwrap_or(&system.values), &rhs, &mut ku);
    let strain_energy = 0.5 * ku.iter().zip(&rhs).map(|(a, b)| a * b).sum::<Real>();
    Ok(StaticSolution {
        nnz: system.pattern.nnz(),
        factor_nnz: system.factor_nnz().unwrap_or(0),
        displacement: rhs,
        strain_energy,
        seconds_setup,
        seconds_assemble,
        seconds_solve,
    })
}

/// The static deformation of free bodies under loads that accelerate them (an impact on a
/// rigid fragment, mueller2004 §2.4), by *inertia relief* (docs/math/rigid-fragments.md §5):
/// each body's load `f` is balanced by the D'Alembert force of the rigid acceleration it
/// gives the body, `f_i − m_i (a + α × r_i)` with `a = Σ f / M`, `α = I⁻¹ Σ r × f` and
/// `r_i = X_i − C` about its rest centre of mass `C`, so that the load left is in equilibrium;
/// the body is then held by a statically determinate 3-2-1 support, whose reactions vanish.
/// Every node in no body is held at rest. For nodal bases (`m_i`: the lumped mass diagonal,
/// `X_i`: the rest DOFs); the displacement is relative to the support (its rigid part is
/// arbitrary, its strain is not).
///
/// `bodies`: disjoint node lists, each a connected body with an invertible inertia.
pub fn solve_inertia_relief(
    discretization: &dyn Discretization,
    load: &[Real],
    bodies: &[Vec<u32>],
) -> Result<StaticSolution, StepErrorKind> {
    let n = check_static_input(discretization, load, &[])?;
    let mass = discretization.mass().diagonal();
    let rest = discretization.rest_dofs();
    let at = |values: &[Real], i: u32| {
        let k = 3 * i as usize;
        Vector3::new(values[k], values[k + 1], values[k + 2])
    };
    let mut relieved = load.to_vec();
    let mut held = vec![true; n / 3];
    let mut prescribed = Vec::new();
    for (index, nodes) in bodies.iter().enumerate() {
        if let Some(&node) = nodes.iter().find(|&&i| 3 * i as usize >= n) {
            return Err(StepErrorKind::DofOutOfRange { what: "inertia relief body", dof: 3 * node as usize, dofs: n });
        }
        let body_mass: Real = nodes.iter().map(|&i| mass[3 * i as usize]).sum();
        let centre = nodes.iter().map(|&i| mass[3 * i as usize] * at(rest, i)).sum::<Vector3<Real>>() / body_mass;
        let (mut force, mut moment, mut inertia) = (Vector3::zeros(), Vector3::zeros(), Matrix3::zeros());
        for &i in nodes {
            let (r, f, m) = (at(rest, i) - centre, at(load, i), mass[3 * i as usize]);
            force += f;
            moment += r.cross(&f);
            inertia += m * (Matrix3::identity() * r.norm_squared() - r * r.transpose());
        }
        let Some(spin) = inertia.cholesky().filter(|_| body_mass > 0.0 && !nodes.is_empty()) else {
            return Err(StepErrorKind::SingularBody { body: index, nodes: nodes.len() });
        };
        let (acceleration, angular) = (force / body_mass, spin.solve(&moment));
        if let Some(&node) = nodes.iter().find(|&&i| !held[i as usize]) {
            return Err(StepErrorKind::OverlappingBodies { node });
        }
        for &i in nodes {
            let k = 3 * i as usize;
            let r = at(rest, i) - centre;
            let inertial = mass[k] * (acceleration + angular.cross(&r));
            for a in 0..3 {
                relieved[k + a] -= inertial[a];
            }
            held[i as usize] = false;
        }
        prescribed.extend(three_two_one(nodes, rest, &centre));
    }
    for (i, _) in held.iter().enumerate().filter(|(_, h)| **h) {
        prescribed.extend((0..3).map(|a| (3 * i + a, 0.0)));
    }
    solve_static(discretization, &relieved, &prescribed)
}

/// A statically determinate support of one body (six DOFs held at zero): the node `A` nearest
/// its centre in all three directions; the node `B` farthest from `A` across the two directions
/// in which `d = X_B − X_A` is smallest (the turns about the axes across `d`); a node `C` in the
/// direction in which the turn about `d` moves it most, the node chosen to maximise that
/// motion.
fn three_two_one(nodes: &[u32], rest: &[Real], centre: &Vector3<Real>) -> Vec<(usize, Real)> {
    let at = |i: u32| {
        let k = 3 * i as usize;
        Vector3::new(rest[k], rest[k + 1], rest[k + 2])
    };
    let least_by = |key: &dyn Fn(u32) -> Real| {
        nodes.iter().copied().min_by(|&a, &b| key(a).total_cmp(&key(b))).expect("a body has nodes")
    };
    let a = least_by(&|i| (at(i) - centre).norm_squared());
    let b = least_by(&|i| -(at(i) - at(a)).norm_squared());
    let d = at(b) - at(a);
    let along = d.iamax();
    let c = least_by(&|i| -d.cross(&(at(i) - at(a))).amax());
    let turn = d.cross(&(at(c) - at(a)));
    let mut held: Vec<(usize, Real)> = (0..3).map(|k| (3 * a as usize + k, 0.0)).collect();
    held.extend((0..3).filter(|&k| k != along).map(|k| (3 * b as usize + k, 0.0)));
    held.push((3 * c as usize + turn.iamax(), 0.0));
    held
}

/// A static solution by preconditioned CG on the backend's matrix-free stiffness action.
#[derive(Clone, Debug)]
pub struct IterativeStaticSolution {
    /// Displacement DOFs `u`.
    pub displacement: Vec<Real>,
    /// CG iterations.
    pub iterations: usize,
    /// The relative residual reached.
    pub relative_residual: Real,
    /// Whether it reached the tolerance within the iteration limit.
    pub converged: bool,
    /// Seconds of this tolerance's CG iterations (the set-up not included).
    pub seconds_solve: Real,
}

/// The matrix-free static path: the preconditioner, built once, and the solves of a tolerance
/// sweep (`compare`'s time-to-accuracy column, docs/results/voxel-bench.md, statics).
pub struct IterativeStatics<'a> {
    discretization: &'a dyn Discretization,
    pinned: Vec<bool>,
    /// `g` on prescribed DOFs, zero elsewhere.
    prescribed_field: Vec<Real>,
    /// `Z (f − K g)`.
    rhs: Vec<Real>,
    block_inverses: Vec<Matrix3<Real>>,
    two_level: Option<TwoLevel>,
    cg: CgWorkspace,
    identity: Vec<Matrix3<Real>>,
    /// Seconds spent building the preconditioner (block-Jacobi inverses, coarse operator and its
    /// factorization).
    pub seconds_setup: Real,
}

impl<'a> IterativeStatics<'a> {
    /// The block-Jacobi inverses of `K` and, when the backend offers a coarse space, the
    /// factorized Galerkin coarse operator `Pᵀ Z K Z P` (the integrator's two-level
    /// preconditioner with no mass term).
    pub fn new(
        discretization: &'a dyn Discretization,
        load: &[Real],
        prescribed: &[(usize, Real)],
    ) -> Result<Self, StepErrorKind> {
        let n = check_static_input(discretization, load, prescribed)?;
        let clock = Instant::now();
        let mut pinned = vec![false; n];
        let mut prescribed_field = vec![0.0; n];
        for &(d, value) in prescribed {
            pinned[d] = true;
            prescribed_field[d] = value;
        }
        let identity = vec![Matrix3::identity(); discretization.num_frames()];
        let mut rhs = load.to_vec();
        if prescribed.iter().any(|&(_, value)| value != 0.0) {
            let mut kg = vec![0.0; n];
            discretization.add_stiffness_action(&identity, &prescribed_field, 1.0, &mut kg);
            rhs.iter_mut().zip(&kg).for_each(|(r, kg)| *r -= kg);
        }
        rhs.iter_mut().zip(&pinned).filter(|(_, p)| **p).for_each(|(r, _)| *r = 0.0);
        let mut block_inverses = vec![Matrix3::zeros(); discretization.num_nodes()];
        discretization.blocks().add_diagonal_blocks(&identity, 1.0, &mut block_inverses);
        invert_blocks_with_pins(&mut block_inverses, &pinned);
        let two_level = match discretization.coarse_space() {
            Some(space) => Some(TwoLevel::new(discretization, space, &pinned, None, 0.0, 1.0, 0.0)?),
            None => None,
        };
        Ok(Self {
            discretization,
            pinned,
            prescribed_field,
            rhs,
            block_inverses,
            two_level,
            cg: CgWorkspace::default(),
            identity,
            seconds_setup: clock.elapsed().as_secs_f64(),
        })
    }

    /// Whether the backend's coarse space is in the preconditioner.
    pub fn is_two_level(&self) -> bool {
        self.two_level.is_some()
    }

    /// Solves from zero to relative residual `tolerance` (at most `max_iterations`).
    pub fn solve(&mut self, tolerance: Real, max_iterations: usize) -> IterativeStaticSolution {
        let clock = Instant::now();
        let Self { discretization, pinned, rhs, block_inverses, two_level, cg, identity, .. } = self;
        let mut x = vec![0.0; rhs.len()];
        let outcome = cg.solve(
            |p, out| {
                out.fill(0.0);
                discretization.add_stiffness_action(identity, p, 1.0, out);
                for ((o, &pin), &p) in out.iter_mut().zip(pinned.iter()).zip(p) {
                    if pin {
                        *o = p;
                    }
                }
            },
            |r, z| {
                z.par_chunks_mut(3).zip(r.par_chunks(3)).zip(&*block_inverses).for_each(|((z, r), m)| {
                    let y = m * Vector3::new(r[0], r[1], r[2]);
                    z.copy_from_slice(y.as_slice());
                });
                if let Some(two_level) = two_level.as_mut() {
                    two_level.add_correction(r, z);
                }
            },
            rhs,
            0.0,
            &mut x,
            tolerance,
            max_iterations,
        );
        x.iter_mut().zip(&self.prescribed_field).for_each(|(x, g)| *x += g);
        IterativeStaticSolution {
            displacement: x,
            iterations: outcome.iterations,
            relative_residual: outcome.relative_residual,
            converged: outcome.converged,
            seconds_solve: clock.elapsed().as_secs_f64(),
        }
    }
}
