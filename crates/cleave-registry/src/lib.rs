//! cleave-registry: the one list of backends. Each backend registers once, in one file here,
//! with its scene settings, its capabilities and its comparison variants ([`Backend`]); the scene
//! runner, `cargo xtask run --backend`, `compare` and `stability` all read this list, so adding a
//! backend is one file and one line in [`backends`].

pub mod backend;
mod dg;
mod virtualnode;
mod voxel;

pub use backend::{
    Backend, BackendError, BuiltSolid, Capabilities, Region, ResolvedPins, RestSurface, Shape, SolidRequest,
};
pub use dg::DgBackend;
pub use virtualnode::{SLIVER_OFFSET, VirtualNodeBackend, sliver_beam};
pub use voxel::{VoxelBackend, covered_faces};

use cleave_testkit::compare::CompareBackend;

/// Every registered backend, in report order.
pub fn registered() -> Vec<Box<dyn Backend>> {
    vec![Box::new(VoxelBackend), Box::new(DgBackend), Box::new(VirtualNodeBackend)]
}

/// The registered backend called `name`.
pub fn find(name: &str) -> Option<Box<dyn Backend>> {
    registered().into_iter().find(|b| b.name() == name)
}

/// Names of every registered backend (for error messages and `--backend` listings).
pub fn names() -> Vec<String> {
    registered().iter().map(|b| b.name().to_string()).collect()
}

/// Every registered backend's comparison registration, in report order.
pub fn backends() -> Vec<Box<dyn CompareBackend>> {
    registered().into_iter().map(|b| Box::new(CompareOf(b)) as Box<dyn CompareBackend>).collect()
}

/// The comparison registration of the backend called `name`.
pub fn backend(name: &str) -> Option<Box<dyn CompareBackend>> {
    backends().into_iter().find(|b| b.name() == name)
}

/// A registration seen through its comparison half (owning the box).
struct CompareOf(Box<dyn Backend>);

impl CompareBackend for CompareOf {
    fn name(&self) -> &str {
        self.0.compare().name()
    }
    fn variants(&self) -> Vec<String> {
        self.0.compare().variants()
    }
    fn build_box(
        &self,
        variant: &str,
        material: &cleave_core::Material,
        grid: &cleave_testkit::compare::BoxGrid,
        dirichlet: &cleave_testkit::compare::DirichletSpec,
    ) -> Result<cleave_testkit::compare::BuiltProblem, cleave_testkit::compare::BuildError> {
        self.0.compare().build_box(variant, material, grid, dirichlet)
    }
    fn is_consistent(&self, variant: &str) -> bool {
        self.0.compare().is_consistent(variant)
    }
    fn dynamic_solver(&self, variant: &str) -> cleave_integrator::Solver {
        self.0.compare().dynamic_solver(variant)
    }
    fn build_extreme(
        &self,
        variant: &str,
        case: cleave_testkit::compare::ExtremeCase,
        material: &cleave_core::Material,
        grid: &cleave_testkit::compare::BoxGrid,
        dirichlet: &cleave_testkit::compare::DirichletSpec,
    ) -> Result<Option<cleave_testkit::compare::BuiltProblem>, cleave_testkit::compare::BuildError> {
        self.0.compare().build_extreme(variant, case, material, grid, dirichlet)
    }
    fn cuts(&self, variant: &str) -> bool {
        self.0.compare().cuts(variant)
    }
    fn build_cut_box(
        &self,
        variant: &str,
        material: &cleave_core::Material,
        grid: &cleave_testkit::compare::BoxGrid,
        dirichlet: &cleave_testkit::compare::DirichletSpec,
        surface: &cleave_core::CutSurface,
    ) -> Result<cleave_testkit::compare::CutProblem, cleave_testkit::compare::CutError> {
        self.0.compare().build_cut_box(variant, material, grid, dirichlet, surface)
    }
    fn extreme_start(
        &self,
        variant: &str,
        case: cleave_testkit::compare::ExtremeCase,
        built: &cleave_testkit::compare::BuiltProblem,
        grid: &cleave_testkit::compare::BoxGrid,
    ) -> Result<Vec<cleave_core::Real>, cleave_testkit::compare::NotApplicable> {
        self.0.compare().extreme_start(variant, case, built, grid)
    }
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
