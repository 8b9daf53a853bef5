//! The virtual node backend (sifakis2007): its scene settings and its comparison variant. A
//! closed surface (or box) is carved out of a BCC lattice by the same algorithm that cuts; the
//! backend is nodal, so pins hold every node copy whose rest position lies in a pin region, and
//! are resolved again after every cut.

use crate::backend::{
    Backend, BackendError, BuiltSolid, Capabilities, RestSurface, Shape, SolidRequest, cell_size_for, one_size,
    parse_settings,
};
use cleave_core::{Material, Point3, Real};
use cleave_testkit::compare::{
    BoxGrid, BuildError, BuiltProblem, CompareBackend, DirichletSpec, ExtremeCase, NotApplicable, corner_pushed_in,
    nodal_problem, stretch_start,
};
use cleave_virtualnode::{VirtualNodeMesh, box_surface};

/// Registration of `cleave-virtualnode`: one variant, corotated linear tetrahedra on a BCC lattice.
#[derive(Clone, Copy, Debug, Default)]
pub struct VirtualNodeBackend;

/// The scene settings of the virtual node backend.
#[derive(Clone, Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct VirtualNodeSettings {
    /// Edge of the lattice's cubes [m] (each cube holds 6 tetrahedra of the BCC lattice).
    #[serde(default)]
    cell_size: Option<Real>,
    /// Or: about this many tetrahedra (duplicates) after carving.
    #[serde(default)]
    target_tets: Option<usize>,
}

fn carve(surface: &cleave_geometry::TriangleMesh, h: Real, material: Material) -> Result<VirtualNodeMesh, String> {
    VirtualNodeMesh::carve(surface, h, material).map_err(|e| e.to_string())
}

impl Backend for VirtualNodeBackend {
    fn name(&self) -> &str {
        "virtualnode"
    }

    fn summary(&self) -> &str {
        "corotated linear tetrahedra with the generalized virtual node algorithm (Sifakis, Der, Fedkiw 2007)"
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities { cut: true, ..Default::default() }
    }

    fn build_solid(&self, settings: &str, request: &SolidRequest) -> Result<BuiltSolid, BackendError> {
        let settings: VirtualNodeSettings = parse_settings(settings)?;
        let surface = match request.shape {
            Shape::Surface(surface) => surface.clone(),
            Shape::Box { min, max } => box_surface(Point3::from(min), Point3::from(max)),
        };
        let h = one_size("virtualnode", settings.cell_size, settings.target_tets, "target_tets", |target| {
            cell_size_for(&surface, target, 0.1, |h| carve(&surface, h, request.material).map(|m| m.num_duplicates()))
        })?;
        let mesh = carve(&surface, h, request.material).map_err(BackendError::Build)?;
        let pins = self.resolve_pins(&mesh, request.pins)?;
        let elements = mesh.num_duplicates();
        // The scene renders the backend's own surface (`Cuttable::surface`); this one is only
        // the input's, for reports.
        let rest = RestSurface { vertices: surface.vertices.clone(), triangles: surface.triangles.clone() };
        Ok(BuiltSolid { discretization: Box::new(mesh), elements, element_size: h, pins, surface: rest })
    }

    fn compare(&self) -> &dyn CompareBackend {
        self
    }
}

impl CompareBackend for VirtualNodeBackend {
    fn name(&self) -> &str {
        "virtualnode"
    }

    fn variants(&self) -> Vec<String> {
        vec!["linear-tet".into()]
    }

    fn build_box(
        &self,
        variant: &str,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
    ) -> Result<BuiltProblem, BuildError> {
        if variant != "linear-tet" {
            return Err(BuildError(format!("virtualnode has no variant {variant:?} (only \"linear-tet\")")));
        }
        let mesh = VirtualNodeMesh::from_box(grid.origin, grid.max_corner(), grid.h, *material)
            .map_err(|e| BuildError(e.to_string()))?;
        let elements = mesh.num_duplicates();
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
            ExtremeCase::Sliver => Err(NotApplicable(
                "uncut lattice tetrahedra are congruent; slivers come from cuts (the cut-beam rows of issue 16)".into(),
            )),
            ExtremeCase::Stretch100 => Ok(stretch_start(built, grid)),
        }
    }
}
