//! The mean value backend (wicke2007): FEM on convex polyhedra with 3D mean value shape
//! functions (`cleave-meanvalue`). Nodal, so Dirichlet data and pins are imposed strongly. Built
//! so far on boxes of cuboid cells (the comparison problems and box scenes); it does not yet
//! mesh closed surfaces or cut (issue 36).

use crate::backend::{Backend, BackendError, BuiltSolid, Shape, SolidRequest, box_dims, parse_settings};
use cleave_core::{Discretization, Material, Point3, Real};
use cleave_meanvalue::MeanValueMesh;
use cleave_testkit::compare::{
    BoxGrid, BuildError, BuiltProblem, CompareBackend, DirichletSpec, ExtremeCase, NotApplicable, corner_pushed_in,
    nodal_problem, stretch_start,
};

/// Registration of `cleave-meanvalue`: one variant, mean value coordinates with the polygon face
/// rule (docs/math/mean-value.md §2.3).
#[derive(Clone, Copy, Debug, Default)]
pub struct MeanValueBackend;

impl CompareBackend for MeanValueBackend {
    fn name(&self) -> &str {
        "meanvalue"
    }

    fn variants(&self) -> Vec<String> {
        vec!["polygon".into()]
    }

    fn build_box(
        &self,
        variant: &str,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
    ) -> Result<BuiltProblem, BuildError> {
        crate::only_variant("meanvalue", variant, "polygon")?;
        let mesh = MeanValueMesh::from_box(*material, grid.origin, grid.h, grid.dims)
            .map_err(|e| BuildError(e.to_string()))?;
        let elements = mesh.num_elements();
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
            ExtremeCase::Sliver => Err(NotApplicable("slivers come from cutting, which is not built yet".into())),
            ExtremeCase::Stretch100 => Ok(stretch_start(built, grid)),
        }
    }
}

/// The scene settings of the mean value backend.
#[derive(Clone, Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct MeanValueSettings {
    /// Cell edge of a box [m].
    #[serde(default)]
    cell_size: Option<Real>,
}

impl Backend for MeanValueBackend {
    fn summary(&self) -> &str {
        "FEM on convex polyhedra, 3D mean value shape functions (Wicke, Botsch, Gross 2007); boxes only so far"
    }

    fn build_solid(&self, settings: &str, request: &SolidRequest) -> Result<BuiltSolid, BackendError> {
        let settings: MeanValueSettings = parse_settings(settings)?;
        let (min, max) = match request.shape {
            Shape::Box { min, max } => (min, max),
            Shape::Surface(_) => {
                return Err(BackendError::Mesh(
                    "the mean value backend cannot mesh a closed surface yet (issue 36); use a Box object".into(),
                ));
            }
        };
        let h = settings.cell_size.filter(|h| h.is_finite() && *h > 0.0).ok_or_else(|| {
            BackendError::Build("a Box object needs meanvalue settings with `cell_size` (> 0)".into())
        })?;
        let dims = box_dims(&min, &max, h)?;
        let mesh = MeanValueMesh::from_box(request.material, Point3::from(min), h, dims)
            .map_err(|e| BackendError::Build(e.to_string()))?;
        let vertices = mesh.rest_dofs().chunks(3).map(|p| Point3::new(p[0], p[1], p[2])).collect();
        let surface = cleave_geometry::TriangleMesh::new(vertices, mesh.boundary_triangles());
        let pins = self.resolve_pins(&mesh, request.pins)?;
        let (elements, element_size) = (mesh.num_elements(), mesh.element_size());
        Ok(BuiltSolid { discretization: Box::new(mesh), elements, element_size, pins, surface })
    }
}
