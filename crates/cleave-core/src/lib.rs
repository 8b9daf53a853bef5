//! cleave-core: the `Discretization` trait every backend implements, the warped-block kernels the
//! integrator drives, materials, rotation extraction and sparse assembly patterns.
//!
//! Conventions (see `docs/math/corotated-integrator.md`): SI units, `f64` everywhere, DOF vectors
//! are flat slices of length `3 * num_nodes` with node `k` at `3k..3k+3`, forces are positive in
//! the direction they push (internal force `f = -∇E`).

pub mod assembly;
pub mod blocks;
pub mod cholesky;
pub mod discretization;
pub mod embedding;
pub mod mass;
pub mod material;
pub mod quadrature;
pub mod reduce;
pub mod rotation;
pub mod scatter;

pub use assembly::AssemblyPattern;
pub use blocks::{BlockRanks, BlockRef, BlockSet, BlockSetBuilder, BlockSetError, MAX_BLOCK_NODES};
pub use cholesky::{AUTO_DISSECTION_FLOPS, CholeskyError, FillOrdering, SparseCholesky};
pub use discretization::{
    CoarseSpace, CutSurface, Cuttable, Discretization, DofRemap, EmbeddedSurface, FieldSample, Fracturable, FrameRemap,
    Piece, Refinable, RotationStats, TopologyChange, TopologyError,
};
pub use embedding::{EmbedError, Embedding};
pub use mass::Mass;
pub use material::{Material, MaterialError};
pub use scatter::ScatterPlan;

/// The one scalar type of cleave.
pub type Real = f64;
pub use nalgebra::{Matrix3, Point3, Vector3};
