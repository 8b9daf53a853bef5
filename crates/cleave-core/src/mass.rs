//! Mass matrices a backend may provide: lumped (diagonal) now; DG's consistent block-diagonal mass
//! will join as a second variant.

use crate::Real;

/// The mass matrix `M` of a discretization.
#[derive(Clone, Debug)]
pub enum Mass {
    /// Diagonal mass, one entry per scalar DOF (the three entries of a node are equal for the
    /// lumped FEM masses, but need not be).
    Lumped(Vec<Real>),
}

impl Mass {
    /// `out = M v`.
    pub fn apply(&self, v: &[Real], out: &mut [Real]) {
        match self {
            Mass::Lumped(m) => {
                for ((o, m), v) in out.iter_mut().zip(m).zip(v) {
                    *o = m * v;
                }
            }
        }
    }

    /// `out += s · M v`.
    pub fn add_scaled(&self, v: &[Real], scale: Real, out: &mut [Real]) {
        match self {
            Mass::Lumped(m) => {
                for ((o, m), v) in out.iter_mut().zip(m).zip(v) {
                    *o += scale * m * v;
                }
            }
        }
    }

    /// The diagonal of `M` (for preconditioners and assembly).
    pub fn diagonal(&self) -> &[Real] {
        match self {
            Mass::Lumped(m) => m,
        }
    }

    /// `½ vᵀ M v`.
    pub fn kinetic_energy(&self, v: &[Real]) -> Real {
        match self {
            Mass::Lumped(m) => 0.5 * m.iter().zip(v).map(|(m, v)| m * v * v).sum::<Real>(),
        }
    }

    /// Sum of the x-component diagonal: the body's mass for nodal bases with lumped mass. Not a
    /// mass for non-nodal bases (DG's orthonormal coefficients carry ρ each); there the mass is
    /// the work of `add_gravity_load` on the translation `add_translation` gives.
    pub fn total(&self) -> Real {
        match self {
            Mass::Lumped(m) => m.iter().step_by(3).sum(),
        }
    }
}
