//! cleave-integrator: the corotated linearly implicit backward Euler step and the static solve,
//! for any [`cleave_core::Discretization`], with two solvers (faer sparse Cholesky with the
//! symbolic factorization cached per epoch, and block-Jacobi preconditioned CG, assembled or
//! matrix-free). Equations: `docs/math/corotated-integrator.md`.

mod cg;
mod constraints;
mod error;
mod integrator;
mod statics;
mod system;

pub use constraints::{Constraints, PenaltyPins, PlaneCollider};
pub use error::{StepError, StepErrorKind};
pub use integrator::{Integrator, PhaseSeconds, Settings, Solver, StepReport};
pub use statics::{solve_static, StaticSolution};
