//! The static linear solve `K u = f` (no warping) with prescribed displacements, for convergence
//! studies: assemble, eliminate the prescribed DOFs into the right-hand side, factorize, solve.

use crate::constraints::Constraints;
use crate::error::StepErrorKind;
use crate::system::AssembledSystem;
use cleave_core::{Discretization, Matrix3, Real};
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

/// Solves `K u = f` with `u_d = value` for every `(d, value)` in `prescribed`.
pub fn solve_static(
    discretization: &dyn Discretization,
    load: &[Real],
    prescribed: &[(usize, Real)],
) -> Result<StaticSolution, StepErrorKind> {
    let n = 3 * discretization.num_nodes();
    if load.len() != n {
        return Err(StepErrorKind::LoadLength { what: "load", len: load.len(), dofs: n });
    }
    if let Some(&(d, _)) = prescribed.iter().find(|(d, _)| *d >= n) {
        return Err(StepErrorKind::DofOutOfRange { what: "prescribed", dof: d, dofs: n });
    }
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
