//! cleave-registry: the list of backends `cargo xtask compare` and `cargo xtask stability` run.
//! A backend joins with one file here implementing `cleave_testkit::compare::CompareBackend` and
//! one line in [`backends`]; the problems, timing, tables and plots are shared.

mod dg;
mod voxel;

pub use dg::DgBackend;
pub use voxel::VoxelBackend;

use cleave_testkit::compare::CompareBackend;

/// Every registered backend, in report order.
pub fn backends() -> Vec<Box<dyn CompareBackend>> {
    vec![Box::new(VoxelBackend), Box::new(DgBackend)]
}

/// The registered backend called `name`.
pub fn backend(name: &str) -> Option<Box<dyn CompareBackend>> {
    backends().into_iter().find(|b| b.name() == name)
}
