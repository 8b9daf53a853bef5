//! cleave-registry: the one list of backends. Each backend registers once, in one file here,
//! with its scene settings and its comparison variants ([`Backend`] and its supertrait
//! `CompareBackend`); its capabilities are read off what it builds. The scene runner,
//! `cargo xtask run --backend`, `compare` and `stability` all read this list, so adding a
//! backend is one file and one line in [`registered`].

pub mod backend;
mod dg;
mod meanvalue;
mod virtualnode;
mod voxel;

pub use backend::{Backend, BackendError, BuiltSolid, Capabilities, Region, ResolvedPins, Shape, SolidRequest};
pub use dg::DgBackend;
pub use meanvalue::MeanValueBackend;
pub use virtualnode::{SLIVER_OFFSET, VirtualNodeBackend, sliver_beam};
pub use voxel::VoxelBackend;

/// Every registered backend, in report order.
pub fn registered() -> Vec<Box<dyn Backend>> {
    vec![Box::new(VoxelBackend), Box::new(DgBackend), Box::new(VirtualNodeBackend), Box::new(MeanValueBackend)]
}

/// The registered backend called `name`.
pub fn find(name: &str) -> Option<Box<dyn Backend>> {
    registered().into_iter().find(|b| b.name() == name)
}

/// Names of every registered backend (for error messages and `--backend` listings).
pub fn names() -> Vec<String> {
    registered().iter().map(|b| b.name().to_string()).collect()
}

/// The single compare variant `only` of `backend`, or the error naming what exists (every
/// `build_*` of a one-variant backend starts with it).
pub(crate) fn only_variant(
    backend: &str,
    variant: &str,
    only: &str,
) -> Result<(), cleave_testkit::compare::BuildError> {
    if variant == only {
        Ok(())
    } else {
        Err(cleave_testkit::compare::BuildError(format!("{backend} has no variant {variant:?} (only {only:?})")))
    }
}
