//! Momentum through free flight: runs a free body from a given state and measures how far its
//! linear and angular momentum drift, with `∫ ρ v` and `∫ ρ x × v` as sums over DOFs (exact for
//! a diagonal mass of a nodal basis or of an orthogonal modal one).

use cleave_core::{Discretization, Real, Vector3};
use cleave_integrator::{Constraints, Integrator, Settings, Solver};

/// Linear and angular momentum (about the origin) of the state `(x, v)`.
pub fn momenta(discretization: &dyn Discretization, x: &[Real], v: &[Real]) -> (Vector3<Real>, Vector3<Real>) {
    let m = discretization.mass().diagonal();
    // The coefficient of every DOF in the constant field 1: 1 for nodal bases.
    let mut unit = vec![0.0; x.len()];
    discretization.add_translation(&Vector3::x(), &mut unit);
    let (mut p, mut l) = (Vector3::zeros(), Vector3::zeros());
    for k in 0..x.len() / 3 {
        let mv = Vector3::new(v[3 * k], v[3 * k + 1], v[3 * k + 2]) * m[3 * k];
        p += mv * unit[3 * k];
        l += Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]).cross(&mv);
    }
    (p, l)
}

/// What [`free_flight`] measured.
#[derive(Clone, Copy, Debug)]
pub struct Drift {
    /// Largest `|L − L₀| / |L₀|` over the steps.
    pub angular: Real,
    /// Largest `|P − P₀| / |P₀|` over the steps.
    pub linear: Real,
    /// Total energy before the first step and after the last [J].
    pub energy: (Real, Real),
    /// Largest rise of the total energy in one step [J].
    pub largest_rise: Real,
}

/// Steps a free body (no pins, no contact, no gravity) from `(x, v)` at h = 1/60 s with the
/// direct solver, stiffness damping `beta` and the angular momentum correction on or off, and
/// measures the drift of its momenta.
pub fn free_flight(
    discretization: &dyn Discretization,
    (beta, conserve_angular_momentum): (Real, bool),
    x: &[Real],
    v: &[Real],
    steps: usize,
) -> Drift {
    let mut settings = Settings::new(1.0 / 60.0);
    settings.gravity = Vector3::zeros();
    settings.rayleigh_beta = beta;
    settings.solver = Solver::Cholesky;
    settings.conserve_angular_momentum = conserve_angular_momentum;
    let (p0, l0) = momenta(discretization, x, v);
    let mut integrator = Integrator::new(discretization, settings, Constraints::default()).expect("integrator");
    integrator.set_state(discretization, x.to_vec(), v.to_vec());
    let first = integrator.energies(discretization).total_energy();
    let mut drift = Drift { angular: 0.0, linear: 0.0, energy: (first, first), largest_rise: 0.0 };
    for _ in 0..steps {
        let energy = integrator.step(discretization).expect("step").total_energy();
        drift.largest_rise = drift.largest_rise.max(energy - drift.energy.1);
        drift.energy.1 = energy;
        let (p, l) = momenta(discretization, integrator.positions(), integrator.velocities());
        drift.angular = drift.angular.max((l - l0).norm() / l0.norm());
        drift.linear = drift.linear.max((p - p0).norm() / p0.norm());
    }
    drift
}
