//! The virtual node backend (sifakis2007): its scene settings and its comparison variant. A
//! closed surface (or box) is carved out of a BCC lattice by the same algorithm that cuts. Scene
//! pins (resolved again after every cut) and the comparison's Dirichlet data (`nodal_dirichlet`)
//! both hold what `Discretization::dirichlet_nodes` names: every node of every duplicate whose
//! region has a face on the Dirichlet boundary, virtual nodes outside the box included.

use crate::backend::{Backend, BackendError, BuiltSolid, Shape, SolidRequest, cell_size_for, one_size, parse_settings};
use cleave_core::{CutSurface, Cuttable, Material, Point3, Real};
use cleave_testkit::compare::{
    BoxGrid, BuildError, BuiltProblem, CompareBackend, CutError, CutProblem, DirichletSpec, ExtremeCase, NotApplicable,
    corner_pushed_in, nodal_problem, stretch_start,
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
    fn summary(&self) -> &str {
        "corotated linear tetrahedra with the generalized virtual node algorithm (Sifakis, Der, Fedkiw 2007)"
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
        let mesh = carve(&surface, h, request.material).map_err(match request.shape {
            Shape::Surface(_) => BackendError::Mesh,
            Shape::Box { .. } => BackendError::Build,
        })?;
        let pins = self.resolve_pins(&mesh, request.pins)?;
        let elements = mesh.num_duplicates();
        // The scene renders the backend's own surface (`Cuttable::surface`); this one is only
        // the input's, for reports.
        let rest = surface.clone();
        Ok(BuiltSolid { discretization: Box::new(mesh), elements, element_size: h, pins, surface: rest })
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
        crate::only_variant("virtualnode", variant, "linear-tet")?;
        let mesh = VirtualNodeMesh::from_box(grid.origin, grid.max_corner(), grid.h, *material)
            .map_err(|e| BuildError(e.to_string()))?;
        let elements = mesh.num_duplicates();
        Ok(nodal_problem(Box::new(mesh), elements, dirichlet))
    }

    fn cuts(&self, variant: &str) -> bool {
        variant == "linear-tet"
    }

    /// The carved box cut by `surface` with `Cuttable::cut` (what scenes call), the Dirichlet data
    /// resolved on the cut mesh by `Discretization::dirichlet_nodes`, through `nodal_problem`.
    fn build_cut_box(
        &self,
        variant: &str,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
        surface: &CutSurface,
    ) -> Result<CutProblem, CutError> {
        crate::only_variant("virtualnode", variant, "linear-tet").map_err(|e| CutError::Build(e.0))?;
        let mut mesh = VirtualNodeMesh::from_box(grid.origin, grid.max_corner(), grid.h, *material)
            .map_err(|e| CutError::Build(e.to_string()))?;
        let change = mesh.cut(surface).map_err(|e| CutError::Build(e.to_string()))?;
        let elements = mesh.num_duplicates();
        Ok(CutProblem { built: nodal_problem(Box::new(mesh), elements, dirichlet), change })
    }

    /// Uncut lattice tetrahedra are congruent, so the sliver case cuts the beam first
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
        crate::only_variant("virtualnode", variant, "linear-tet")?;
        let mesh = sliver_beam(material, grid).map_err(BuildError)?;
        let elements = mesh.num_duplicates();
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

/// Distance of the sliver beam's crack plane from the lattice node plane it is next to, in units
/// of the lattice's cube edge `h`. Closer than about 3e-6 h, the caps the crack leaves around
/// lattice nodes meet their neighbours in faces below the arrangement's overlap tolerance
/// (1e-12 of the squared edge) and come apart as separate specks (measured on the stability
/// beam: 20 specks of 1.3e-19 of a tetrahedron at 1e-6 h, 3 at 2e-6 h, none from 3e-6 h on).
pub const SLIVER_OFFSET: Real = 1e-5;

/// The sliver case of the stability suite for virtual node tetrahedra, whose slivers come from
/// cuts: the box `grid` carved out of a lattice of cube edge `grid.h`, then cracked by the plane
/// x = x₀ + [`SLIVER_OFFSET`]·h, with x₀ the lattice node plane nearest the middle of the box,
/// across its whole width from 40 % of its height up through the top (two triangles reaching
/// past the box). The material stays connected below the crack, so the body is one piece; the
/// lattice tetrahedra the crack passes through leave regions 1e-5 h thick next to the node
/// plane: wedges along lattice edges in it and caps at lattice nodes on it, the smallest
/// 2e-15 of a tetrahedron's volume on the stability beam (`tests/virtualnode_sliver.rs`).
pub fn sliver_beam(material: &Material, grid: &BoxGrid) -> Result<VirtualNodeMesh, String> {
    cracked_beam(material, grid, SLIVER_OFFSET)
}

/// [`sliver_beam`] with the crack `offset · h` from the node plane.
fn cracked_beam(material: &Material, grid: &BoxGrid, offset: Real) -> Result<VirtualNodeMesh, String> {
    let (lo, hi) = (grid.origin, grid.max_corner());
    // Lattice nodes lie at the box's corner planes and every h from them.
    let x = lo.x + (grid.dims[0] / 2) as Real * grid.h + offset * grid.h;
    let mut mesh = VirtualNodeMesh::from_box(lo, hi, grid.h, *material).map_err(|e| e.to_string())?;
    let crack = cleave_testkit::problems::crack::half_plane(&lo, &hi, x, lo.z + 0.4 * (hi.z - lo.z), grid.h);
    mesh.cut(&crack).map_err(|e| format!("cracking the sliver beam: {e}"))?;
    Ok(mesh)
}
