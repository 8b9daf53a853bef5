//! The voxel backend (mueller2004): its scene settings and its comparison variant. Nodal, so
//! Dirichlet data and pins are imposed strongly by pinning the nodes in the region.

use crate::backend::{
    Backend, BackendError, BuiltSolid, Capabilities, RestSurface, Shape, SolidRequest, box_dims, cell_size_for,
    one_size, parse_settings,
};
use cleave_core::{Discretization, Material, Point3, Real};
use cleave_testkit::compare::{
    BoxGrid, BuildError, BuiltProblem, CompareBackend, DirichletSpec, ExtremeCase, NotApplicable, corner_pushed_in,
    nodal_problem, stretch_start,
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
        if variant != "trilinear" {
            return Err(BuildError(format!("voxel has no variant {variant:?} (only \"trilinear\")")));
        }
        let mesh =
            VoxelMesh::from_box(*material, grid.origin, grid.h, grid.dims).map_err(|e| BuildError(e.to_string()))?;
        let elements = mesh.num_cubes();
        Ok(nodal_problem(Box::new(mesh), elements, dirichlet))
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
    fn name(&self) -> &str {
        "voxel"
    }

    fn summary(&self) -> &str {
        "voxel cube FEM, closed-form 24×24 cube stiffness (Müller, Teschner, Gross 2004)"
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities::default()
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
                let grid = cleave_geometry::voxelize(surface, h).map_err(|e| build(&e))?;
                let mesh = VoxelMesh::new(request.material, grid.origin, grid.cell_size, &grid.cells)
                    .map_err(|e| build(&e))?;
                let rest = RestSurface { vertices: surface.vertices.clone(), triangles: surface.triangles.clone() };
                (mesh, rest)
            }
            Shape::Box { min, max } => {
                let h = settings
                    .cell_size
                    .ok_or_else(|| BackendError::Build("a Box object needs voxel settings with `cell_size`".into()))?;
                let dims = box_dims(&min, &max, h)?;
                let mesh = VoxelMesh::from_box(request.material, Point3::from(min), h, dims).map_err(|e| build(&e))?;
                let triangles = voxel_boundary(&mesh);
                let vertices = mesh.rest_dofs().chunks(3).map(|p| Point3::new(p[0], p[1], p[2])).collect();
                (mesh, RestSurface { vertices, triangles })
            }
        };
        let pins = self.resolve_pins(&mesh, request.pins)?;
        let (elements, element_size) = (mesh.num_cubes(), mesh.cell_size());
        Ok(BuiltSolid { discretization: Box::new(mesh), elements, element_size, pins, surface })
    }

    fn compare(&self) -> &dyn CompareBackend {
        self
    }
}

/// The boundary faces of a voxel mesh as triangles over its nodes, outward oriented.
fn voxel_boundary(mesh: &VoxelMesh) -> Vec<[u32; 3]> {
    // For each axis and side: the four corners of that face (bit `axis` fixed), in cyclic order.
    let mut triangles = Vec::new();
    for (cube, cell) in mesh.cells().iter().enumerate() {
        for axis in 0..3 {
            for side in [0, 1] {
                let mut neighbour = *cell;
                neighbour[axis] += if side == 1 { 1 } else { -1 };
                if mesh.cube_at(neighbour).is_some() {
                    continue;
                }
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let corner = |a: usize, b: usize| (side << axis) | (a << u) | (b << v);
                let quad = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                let nodes = quad.map(|c| mesh.cube_nodes()[cube][c]);
                // (u, v, axis) is right-handed, so the cyclic order above faces +axis; flip it on
                // the minus side.
                if side == 1 {
                    triangles.push([nodes[0], nodes[1], nodes[2]]);
                    triangles.push([nodes[0], nodes[2], nodes[3]]);
                } else {
                    triangles.push([nodes[0], nodes[2], nodes[1]]);
                    triangles.push([nodes[0], nodes[3], nodes[2]]);
                }
            }
        }
    }
    triangles
}
