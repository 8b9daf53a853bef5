//! cleave-integrator: the corotated linearly implicit backward Euler step and the static solve,
//! for any [`cleave_core::Discretization`], with two solvers (faer sparse Cholesky with the
//! symbolic factorization cached per epoch, and block-Jacobi preconditioned CG, assembled or
//! matrix-free). Equations: `docs/math/corotated-integrator.md`.

mod cg;
mod constraints;
mod contact;
mod error;
mod integrator;
mod low_rank;
mod momentum;
mod pieces;
mod statics;
mod system;
mod two_level;

pub use constraints::{Constraints, MeshCollider, MeshColliderError, PenaltyPins, PlaneCollider, SurfaceContact};
pub use contact::{ContactKind, ContactStats, FRICTION_SLIP_SPEED};
pub use error::{StepError, StepErrorKind};
pub use integrator::{
    AUTO_COARSE_DOFS, Integrator, PhaseSeconds, Preconditioner, PreparedContact, RECOMMENDED_ROTATION_REFRESH_ANGLE,
    Settings, Solver, StepReport,
};
pub use statics::{StaticSolution, solve_static};
