//! Step failures: every way a step can go wrong, named with the step it happened in.

use cleave_core::{CholeskyError, Real};

/// A failed step: what happened and in which step (0-based).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("step {step}: {kind}")]
pub struct StepError {
    /// Index of the step that failed.
    pub step: u64,
    /// What went wrong.
    pub kind: StepErrorKind,
}

/// What went wrong in a step.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StepErrorKind {
    /// NaN or infinity in the new state.
    #[error("the state became non-finite (NaN or infinity) at DOF {dof}")]
    NotFinite {
        /// first offending scalar DOF
        dof: usize,
    },
    /// Positions ran away.
    #[error("the solution diverged: a node moved {distance:.3e} m from the rest shape (limit {limit:.3e} m)")]
    Diverged {
        /// the largest displacement found
        distance: Real,
        /// the limit it crossed
        limit: Real,
    },
    /// CG hit its iteration limit.
    #[error(
        "CG did not converge: relative residual {residual:.3e} after {iterations} iterations (tolerance {tolerance:.1e})"
    )]
    CgNotConverged {
        /// iterations taken
        iterations: usize,
        /// final relative residual
        residual: Real,
        /// requested tolerance
        tolerance: Real,
    },
    /// Cholesky met a non-positive pivot.
    #[error("the system matrix is not positive definite (Cholesky pivot {pivot} in the permuted order)")]
    NotPositiveDefinite {
        /// 1-based pivot in faer's permuted order
        pivot: usize,
    },
    /// A body of an inertia relief solve without mass or with a singular inertia (its nodes on
    /// one line): no rigid acceleration balances its load.
    #[error("inertia relief body {body} ({nodes} nodes) has no mass or a singular inertia")]
    SingularBody {
        /// index of the body in the list given
        body: usize,
        /// its node count
        nodes: usize,
    },
    /// A node listed in two bodies of an inertia relief solve (the bodies must be disjoint).
    #[error("node {node} is in two inertia relief bodies")]
    OverlappingBodies {
        /// the node
        node: u32,
    },
    /// A load vector (the static load, the constant extra load of the constraints) whose length
    /// is not the system's number of scalar DOFs.
    #[error("{what} has length {len} but the system has {dofs} DOFs")]
    LoadLength {
        /// which load ("load", "extra load")
        what: &'static str,
        /// its length
        len: usize,
        /// scalar DOFs of the system
        dofs: usize,
    },
    /// A pinned or prescribed scalar DOF beyond the system.
    #[error("{what} DOF {dof} is out of range (0..{dofs})")]
    DofOutOfRange {
        /// which list ("pinned", "prescribed")
        what: &'static str,
        /// the offending DOF index
        dof: usize,
        /// scalar DOFs of the system
        dofs: usize,
    },
    /// A row of an embedding in the constraints (contact points, penalty pins) names a node the
    /// discretization does not have.
    #[error("{what} {row} names node {node}, but there are only {nodes} nodes")]
    NodeOutOfRange {
        /// which embedding ("contact point", "penalty pin")
        what: &'static str,
        /// the row (point) index
        row: usize,
        /// the offending node
        node: u32,
        /// nodes of the discretization
        nodes: usize,
    },
    /// Penalty pins with a different number of targets than embedded points.
    #[error("penalty pins have {targets} targets for {points} points")]
    PinTargets {
        /// targets given
        targets: usize,
        /// embedded points
        points: usize,
    },
    /// Surface contact with a piece list that does not give one piece per triangle.
    #[error("surface contact has {pieces} piece entries for {triangles} triangles")]
    SurfacePieces {
        /// piece entries given
        pieces: usize,
        /// surface triangles
        triangles: usize,
    },
    /// Something else from the sparse solver.
    #[error("sparse solver failure: {0}")]
    Solver(String),
}

impl From<CholeskyError> for StepErrorKind {
    fn from(error: CholeskyError) -> Self {
        match error {
            CholeskyError::NotPositiveDefinite { pivot } => StepErrorKind::NotPositiveDefinite { pivot },
            CholeskyError::Setup(message) => StepErrorKind::Solver(message),
        }
    }
}
