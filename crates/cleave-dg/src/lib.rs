//! cleave-dg: discontinuous Galerkin FEM on arbitrary polyhedra after Kaufmann, Martin, Botsch and
//! Gross, "Flexible Simulation of Deformable Models Using Discontinuous Galerkin FEM" (SCA 2008).
//!
//! - Elements are the polyhedra of a [`cleave_geometry::PolyhedralMesh`] (hex grids, or hexahedral
//!   slicing of a surface), convex or not; one DOF ("node") is the 3-vector coefficient of one basis
//!   function of one element.
//! - Bases are the monomials of degree 1 or 2 in each element's scaled frame, orthonormalized with
//!   the element's exact Gram matrix (module `basis`), so the consistent mass is `ρ I`.
//! - Every polynomial integral is exact, by the divergence theorem (`cleave_geometry::element_moments`
//!   and `face_moments`); loads and Dirichlet data use signed simplex rules (module `quadrature`).
//! - Fluxes: Babuška–Zlámal or symmetric interior penalty, η doubled until the stiffness is positive
//!   definite; corotation warps each face's consistency part by the rotation of the element whose
//!   strain it uses, the penalty part not at all (module `mesh`).
//! - Surfaces are embedded by MLS over the stitched vertex field (module `mls`).
//! - Cutting (`Cuttable`, §13) and stress-driven refinement 1→8 or 1→2 (`Refinable`, §14) split
//!   elements into polyhedra and carry each parent's polynomial to its children exactly.
//!
//! Derivations: `docs/math/dg.md`.

pub mod basis;
mod mesh;
pub mod mls;
pub mod quadrature;

pub use mesh::{DgError, DgMesh, DgOptions, Flux, RefineSplit, Refinement, WeakDirichlet};
