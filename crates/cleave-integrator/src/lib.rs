//! cleave-integrator: the corotated linearly implicit backward Euler step and the static solve,
//! for any [`cleave_core::Discretization`], with two solvers (faer sparse Cholesky with the
//! symbolic factorization cached per epoch, and block-Jacobi preconditioned CG, assembled or
//! matrix-free). Equations: `docs/math/corotated-integrator.md`. Contact is found by
//! `cleave-contact` and enters the step through `penalty.rs`.

mod cg;
mod constraints;
mod error;
mod integrator;
mod low_rank;
mod momentum;
mod penalty;
mod pieces;
mod statics;
mod system;
mod two_level;

// Contact is found by its own crate; its colliders and the structures of a topology are
// re-exported so that a program that steps a body needs this crate only.
pub use cleave_contact::{
    Colliders, ContactKind, ContactSet, ContactStats, FRICTION_SLIP_SPEED, MeshCollider, MeshColliderError,
    PlaneCollider, SurfaceContact,
};
pub use constraints::{Constraints, PenaltyPins};
pub use error::{StepError, StepErrorKind};
pub use integrator::{
    AUTO_COARSE_DOFS, Integrator, PhaseSeconds, Preconditioner, RECOMMENDED_ROTATION_REFRESH_ANGLE, Settings, Solver,
    StepReport,
};
pub use statics::{IterativeStaticSolution, IterativeStatics, StaticSolution, solve_inertia_relief, solve_static};
