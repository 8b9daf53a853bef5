//! The voxel backend (mueller2004): its scene settings and its comparison variant. Nodal, so
//! Dirichlet data and pins are imposed strongly by pinning the nodes in the region. It cuts as
//! scenes do (`Cuttable::cut`: the cubes on both sides of every face whose dual edge the cut
//! crosses get their own nodes), which for the crack of benchmarks.md §5 on cube faces is the
//! conforming cracked hexahedral grid. A body voxelized from a surface mesh carries that mesh
//! (`VoxelMesh::carry_surface`), separated along triangle edges and capped as it is cut.

use crate::backend::{
    Backend, BackendError, BuiltSolid, Shape, SolidRequest, box_dims, cell_size_for, one_size, parse_settings,
};
use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real};
use cleave_testkit::compare::{
    BoxGrid, BuildError, BuiltProblem, CompareBackend, CutError, CutProblem, DirichletSpec, ExtremeCase, NotApplicable,
    corner_pushed_in, nodal_problem, stretch_start,
};
use cleave_voxel::VoxelMesh;

/// Registration of `cleave-voxel`: one variant, trilinear cubes with the closed-form stiffness.
#[derive(Clone, Copy, Debug, Default)]
pub struct VoxelBackend;

impl CompareBackend for VoxelBackend {
    fn name(&self) -> &str {
        "voxel"
    }

    fn variants(&self) -> Vec<String> {
        vec!["trilinear".into()]
    }

    fn build_box(
        &self,
        variant: &str,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
    ) -> Result<BuiltProblem, BuildError> {
        crate::only_variant("voxel", variant, "trilinear")?;
        let mesh =
            VoxelMesh::from_box(*material, grid.origin, grid.h, grid.dims).map_err(|e| BuildError(e.to_string()))?;
        let elements = mesh.num_cubes();
        Ok(nodal_problem(Box::new(mesh), elements, dirichlet))
    }

    fn cuts(&self, variant: &str) -> bool {
        variant == "trilinear"
    }

    fn build_cut_box(
        &self,
        variant: &str,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
        surface: &CutSurface,
    ) -> Result<CutProblem, CutError> {
        crate::only_variant("voxel", variant, "trilinear").map_err(|e| CutError::Build(e.0))?;
        let mut mesh = VoxelMesh::from_box(*material, grid.origin, grid.h, grid.dims)
            .map_err(|e| CutError::Build(e.to_string()))?;
        let change = mesh.cut(surface).map_err(|e| CutError::CannotCut(e.to_string()))?;
        if mesh.cut_faces().is_empty() {
            return Err(CutError::CannotCut("the cut crosses no dual edge between two cubes".into()));
        }
        let elements = mesh.num_cubes();
        Ok(CutProblem { built: nodal_problem(Box::new(mesh), elements, dirichlet), change })
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
            ExtremeCase::Sliver => Err(NotApplicable("equal cubes (a voxel mesh has no slivers)".into())),
            ExtremeCase::Stretch100 => Ok(stretch_start(built, grid)),
        }
    }
}

/// The scene settings of the voxel backend.
#[derive(Clone, Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct VoxelSettings {
    /// Cube edge [m].
    #[serde(default)]
    cell_size: Option<Real>,
    /// Or: about this many cubes.
    #[serde(default)]
    target_cubes: Option<usize>,
}

impl Backend for VoxelBackend {
    fn summary(&self) -> &str {
        "voxel cube FEM, closed-form 24×24 cube stiffness (Müller, Teschner, Gross 2004)"
    }

    fn build_solid(&self, settings: &str, request: &SolidRequest) -> Result<BuiltSolid, BackendError> {
        let settings: VoxelSettings = parse_settings(settings)?;
        let build = |e: &dyn std::fmt::Display| BackendError::Build(e.to_string());
        let (mesh, surface) = match request.shape {
            Shape::Surface(surface) => {
                let h = one_size("voxel", settings.cell_size, settings.target_cubes, "target_cubes", |target| {
                    cell_size_for(surface, target, 0.05, |h| {
                        cleave_geometry::voxelize(surface, h).map(|g| g.cells.len()).map_err(|e| e.to_string())
                    })
                })?;
                let mesh_error = |e: &dyn std::fmt::Display| BackendError::Mesh(e.to_string());
                let grid = cleave_geometry::voxelize(surface, h).map_err(|e| mesh_error(&e))?;
                let mut mesh = VoxelMesh::new(request.material, grid.origin, grid.cell_size, &grid.cells)
                    .map_err(|e| mesh_error(&e))?;
                mesh.carry_surface(surface).map_err(|e| mesh_error(&e))?;
                let rest = surface.clone();
                (mesh, rest)
            }
            Shape::Box { min, max } => {
                let h = settings
                    .cell_size
                    .ok_or_else(|| BackendError::Build("a Box object needs voxel settings with `cell_size`".into()))?;
                let dims = box_dims(&min, &max, h)?;
                let mesh = VoxelMesh::from_box(request.material, Point3::from(min), h, dims).map_err(|e| build(&e))?;
                let triangles = mesh.boundary_triangles();
                let vertices = mesh.rest_dofs().chunks(3).map(|p| Point3::new(p[0], p[1], p[2])).collect();
                (mesh, cleave_geometry::TriangleMesh::new(vertices, triangles))
            }
        };
        let pins = self.resolve_pins(&mesh, request.pins)?;
        let (elements, element_size) = (mesh.num_cubes(), mesh.cell_size());
        Ok(BuiltSolid { discretization: Box::new(mesh), elements, element_size, pins, surface })
    }
}
