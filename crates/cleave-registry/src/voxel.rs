//! The voxel backend (mueller2004) registered with the comparison harness: nodal, so Dirichlet
//! data is imposed strongly by pinning the nodes in the Dirichlet region.

use cleave_core::{Material, Real};
use cleave_testkit::compare::{
    BoxGrid, BuildError, BuiltProblem, CompareBackend, DirichletSpec, ExtremeCase, NotApplicable, stretch_start,
};
use cleave_testkit::problems::nodal_dirichlet;
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
        let prescribed = nodal_dirichlet(&mesh, dirichlet.region, dirichlet.value);
        let elements = mesh.num_cubes();
        Ok(BuiltProblem {
            discretization: Box::new(mesh),
            prescribed,
            dirichlet_load: Vec::new(),
            elements,
            search_seconds: 0.0,
        })
    }

    fn extreme_start(
        &self,
        _variant: &str,
        case: ExtremeCase,
        built: &BuiltProblem,
        grid: &BoxGrid,
    ) -> Result<Vec<Real>, NotApplicable> {
        let rest = built.discretization.rest_dofs();
        match case {
            ExtremeCase::PreInverted => {
                // The outer corner of the free-end cube (it belongs to that cube only) moves to
                // (−½, −½, −½) in the cube's coordinates, through the three faces opposite it:
                // the centre gradient is F = I − (9/8)·(1,1,1)⊗(1,1,1)/3 with det F = −1/8.
                let corner = grid.max_corner();
                let node = rest
                    .chunks_exact(3)
                    .position(|p| (0..3).all(|a| (p[a] - corner[a]).abs() < 1e-9 * grid.h.max(1.0)))
                    .ok_or_else(|| NotApplicable("no node at the outer corner of the box".into()))?;
                let mut x = rest.to_vec();
                for a in 0..3 {
                    x[3 * node + a] -= 1.5 * grid.h;
                }
                Ok(x)
            }
            ExtremeCase::Sliver => Err(NotApplicable("equal cubes (a voxel mesh has no slivers)".into())),
            ExtremeCase::Stretch100 => Ok(stretch_start(built, grid)),
        }
    }
}
