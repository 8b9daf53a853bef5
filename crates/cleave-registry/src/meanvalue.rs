//! The mean value backend (wicke2007): FEM on convex polyhedra with 3D mean value shape
//! functions (`cleave-meanvalue`). Nodal, so Dirichlet data and pins are imposed strongly. Built
//! on boxes of cuboid cells (the comparison problems and box scenes), cut by splitting elements
//! (the cut cantilever, the cut cells of the stability grid, scenes), and on closed surfaces
//! (`mesh_closed_surface`: cubes inside, cut Kuhn tetrahedra at the boundary).

use crate::backend::{Backend, BackendError, BuiltSolid, Shape, SolidRequest, box_dims, parse_settings};
use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real};
use cleave_meanvalue::{MeanValueMesh, mesh_closed_surface};
use cleave_testkit::compare::{
    BoxGrid, BuildError, BuiltProblem, CompareBackend, CutError, CutProblem, DirichletSpec, ExtremeCase, NotApplicable,
    corner_pushed_in, nodal_problem, stretch_start,
};

/// Distance of the sliver beam's crack plane from the node plane it is next to, in units of the
/// cell edge `h`: the elements it crosses leave slabs 1e-5 h thick.
pub const SLIVER_OFFSET: Real = 1e-5;

/// The stability grid's sliver case for mean value elements, whose slivers come from cuts: the
/// box `mesh` of `grid` (cuboids, or split cuboids) cracked by the plane x = x₀ +
/// [`SLIVER_OFFSET`]·h (x₀ the node plane nearest the middle) from 40 % of its height up
/// through the top, as for virtual node tetrahedra. One piece; on cuboids, a column of cells
/// split into a slab 1e-5 h thick and the rest (what sliver merging leaves of it).
pub fn sliver_beam(mut mesh: MeanValueMesh, grid: &BoxGrid) -> Result<MeanValueMesh, String> {
    let (lo, hi) = (grid.origin, grid.max_corner());
    let x = lo.x + (grid.dims[0] / 2) as Real * grid.h + SLIVER_OFFSET * grid.h;
    let crack = cleave_testkit::problems::crack::half_plane(&lo, &hi, x, lo.z + 0.4 * (hi.z - lo.z), grid.h);
    mesh.cut(&crack).map_err(|e| format!("cracking the sliver beam: {e}"))?;
    Ok(mesh)
}

/// The box of `grid` in `variant`'s cells: cuboids (`polygon`) or cuboids split by the plane
/// families of `MeanValueMesh::from_split_box` (`split`).
fn box_mesh(variant: &str, material: &Material, grid: &BoxGrid) -> Result<MeanValueMesh, BuildError> {
    match variant {
        "split" => MeanValueMesh::from_split_box(*material, grid.origin, grid.h, grid.dims),
        _ => {
            crate::only_variant("meanvalue", variant, "polygon")?;
            MeanValueMesh::from_box(*material, grid.origin, grid.h, grid.dims)
        }
    }
    .map_err(|e| BuildError(e.to_string()))
}

/// Registration of `cleave-meanvalue`: mean value coordinates with the polygon face rule
/// (docs/math/mean-value.md §2.3) on boxes of cuboids (`polygon`, the variant that cuts and
/// that scenes use), and on boxes whose cuboids are split by three families of oblique planes
/// (`split`, §11: the convergence of the method on general convex polyhedra).
#[derive(Clone, Copy, Debug, Default)]
pub struct MeanValueBackend;

impl CompareBackend for MeanValueBackend {
    fn name(&self) -> &str {
        "meanvalue"
    }

    fn variants(&self) -> Vec<String> {
        vec!["polygon".into(), "split".into()]
    }

    fn build_box(
        &self,
        variant: &str,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
    ) -> Result<BuiltProblem, BuildError> {
        let mesh = box_mesh(variant, material, grid)?;
        let elements = mesh.num_elements();
        Ok(nodal_problem(Box::new(mesh), elements, dirichlet))
    }

    fn cuts(&self, _variant: &str) -> bool {
        true
    }

    /// The box cut by `surface` with `Cuttable::cut` (what scenes call), the Dirichlet data
    /// resolved on the cut mesh.
    fn build_cut_box(
        &self,
        variant: &str,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
        surface: &CutSurface,
    ) -> Result<CutProblem, CutError> {
        let mut mesh = box_mesh(variant, material, grid).map_err(|e| CutError::Build(e.0))?;
        let change = mesh.cut(surface).map_err(|e| CutError::Build(e.to_string()))?;
        let elements = mesh.num_elements();
        Ok(CutProblem { built: nodal_problem(Box::new(mesh), elements, dirichlet), change })
    }

    /// Uncut cells are all the same cube, so the sliver case cracks the beam first
    /// ([`sliver_beam`]).
    fn build_extreme(
        &self,
        variant: &str,
        case: ExtremeCase,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
    ) -> Result<Option<BuiltProblem>, BuildError> {
        if case != ExtremeCase::Sliver {
            return Ok(None);
        }
        let mesh = sliver_beam(box_mesh(variant, material, grid)?, grid).map_err(BuildError)?;
        let elements = mesh.num_elements();
        Ok(Some(nodal_problem(Box::new(mesh), elements, dirichlet)))
    }

    fn extreme_start(
        &self,
        _variant: &str,
        case: ExtremeCase,
        built: &BuiltProblem,
        grid: &BoxGrid,
    ) -> Result<Vec<Real>, NotApplicable> {
        match case {
            ExtremeCase::PreInverted => corner_pushed_in(built, grid),
            // The sliver beam of `build_extreme`, at rest.
            ExtremeCase::Sliver => Ok(built.discretization.rest_dofs().to_vec()),
            ExtremeCase::Stretch100 => Ok(stretch_start(built, grid)),
        }
    }
}

/// The scene settings of the mean value backend.
#[derive(Clone, Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct MeanValueSettings {
    /// Cell edge [m]: of a box's cuboids, or of the grid a closed surface is meshed on.
    #[serde(default)]
    cell_size: Option<Real>,
}

impl Backend for MeanValueBackend {
    fn summary(&self) -> &str {
        "FEM on convex polyhedra, 3D mean value shape functions, cut by splitting elements (Wicke, Botsch, Gross 2007)"
    }

    fn build_solid(&self, settings: &str, request: &SolidRequest) -> Result<BuiltSolid, BackendError> {
        let settings: MeanValueSettings = parse_settings(settings)?;
        let h = settings
            .cell_size
            .filter(|h| h.is_finite() && *h > 0.0)
            .ok_or_else(|| BackendError::Build("the meanvalue settings need a `cell_size` (> 0) [m]".into()))?;
        let mesh = match request.shape {
            Shape::Box { min, max } => {
                let dims = box_dims(&min, &max, h)?;
                MeanValueMesh::from_box(request.material, Point3::from(min), h, dims)
                    .map_err(|e| BackendError::Build(e.to_string()))?
            }
            Shape::Surface(surface) => {
                mesh_closed_surface(surface, h, request.material).map_err(|e| BackendError::Mesh(e.to_string()))?.0
            }
        };
        let vertices = mesh.rest_dofs().chunks(3).map(|p| Point3::new(p[0], p[1], p[2])).collect();
        let surface = cleave_geometry::TriangleMesh::new(vertices, mesh.boundary_triangles());
        let pins = self.resolve_pins(&mesh, request.pins)?;
        // The cell edge, as virtual node reports its lattice's (the mean element of a meshed
        // surface is a sixth of a cube, whose cube root would understate it).
        let (elements, element_size) = (mesh.num_elements(), h);
        Ok(BuiltSolid { discretization: Box::new(mesh), elements, element_size, pins, surface })
    }
}
