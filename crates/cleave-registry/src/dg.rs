//! The DG backend (kaufmann2008): its scene settings and its comparison variants. Dirichlet data is
//! imposed weakly (Nitsche/interior-penalty boundary terms on the faces whose centroid lies in the
//! Dirichlet region), handed over as a load vector; no DOF is pinned.

use crate::backend::{
    Backend, BackendError, BuiltSolid, Region, ResolvedPins, Shape, SolidRequest, box_dims, cell_size_for, one_size,
    parse_settings,
};
use cleave_core::{CutSurface, Cuttable};
use cleave_core::{Discretization, Material, Matrix3, Point3, Real, Vector3};
use cleave_dg::{DgMesh, DgOptions, Flux, RefineSplit, Refinement, WeakDirichlet};
use cleave_geometry::PolyhedralMesh;
use cleave_testkit::compare::{
    BoxGrid, BuildError, BuiltProblem, CompareBackend, CutError, CutProblem, DirichletSpec, ExtremeCase, NotApplicable,
    stretch_start,
};

/// The DG discretization of `mesh` with the Dirichlet data imposed weakly, as a comparison problem
/// (its load vector handed over, no DOF pinned).
fn weakly_clamped(
    mesh: PolyhedralMesh,
    material: &Material,
    options: DgOptions,
    dirichlet: &DirichletSpec,
) -> Result<BuiltProblem, String> {
    let weak = WeakDirichlet { on_boundary: dirichlet.region, data: dirichlet.value };
    let dg = DgMesh::new(mesh, *material, options, Some(&weak)).map_err(|e| e.to_string())?;
    let (elements, search_seconds) = (dg.num_elements(), dg.penalty_search_seconds());
    let dirichlet_load = dg.dirichlet_load().to_vec();
    Ok(BuiltProblem { discretization: Box::new(dg), prescribed: Vec::new(), dirichlet_load, elements, search_seconds })
}

/// Registration of `cleave-dg`: variants `bz-1`, `ip-1`, `bz-2`, `ip-2` (flux, degree).
#[derive(Clone, Copy, Debug, Default)]
pub struct DgBackend;

fn parse_variant(variant: &str) -> Result<DgOptions, BuildError> {
    let (flux, degree) = match variant {
        "bz-1" => (Flux::BabuskaZlamal, 1),
        "ip-1" => (Flux::InteriorPenalty, 1),
        "bz-2" => (Flux::BabuskaZlamal, 2),
        "ip-2" => (Flux::InteriorPenalty, 2),
        _ => return Err(BuildError(format!("dg has no variant {variant:?} (bz-1, ip-1, bz-2, ip-2)"))),
    };
    Ok(DgOptions::new(degree, flux))
}

impl CompareBackend for DgBackend {
    fn name(&self) -> &str {
        "dg"
    }

    fn variants(&self) -> Vec<String> {
        ["bz-1", "ip-1", "bz-2", "ip-2"].map(String::from).to_vec()
    }

    fn is_consistent(&self, variant: &str) -> bool {
        // Babuška–Zlámal drops the consistency terms (kaufmann2008 §4, docs/math/dg.md §4).
        !variant.starts_with("bz")
    }

    fn build_box(
        &self,
        variant: &str,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
    ) -> Result<BuiltProblem, BuildError> {
        let options = parse_variant(variant)?;
        let mesh = PolyhedralMesh::grid(grid.origin, grid.h, grid.dims);
        weakly_clamped(mesh, material, options, dirichlet).map_err(BuildError)
    }

    fn cuts(&self, _variant: &str) -> bool {
        true
    }

    /// The box cut by `surface` with `Cuttable::cut` (what scenes call). A clamp (zero data) is
    /// kept by the cut (`DgMesh::clamped`, docs/math/dg.md §13.1): the box is built clamped and
    /// cut, as a running body is. Other data is not kept: the box is cut while free and the
    /// discretization rebuilt on the cut mesh with the data (same elements and DOFs, so
    /// `change` maps onto it, but a fresh epoch and the geometric face weights).
    fn build_cut_box(
        &self,
        variant: &str,
        material: &Material,
        grid: &BoxGrid,
        dirichlet: &DirichletSpec,
        surface: &CutSurface,
    ) -> Result<CutProblem, CutError> {
        let options = parse_variant(variant).map_err(|e| CutError::Build(e.0))?;
        let mesh = PolyhedralMesh::grid(grid.origin, grid.h, grid.dims);
        // A clamp (zero data at the corners and centroid of every face it holds) is kept by the cut: the box
        // is built clamped and cut as a running body would be (same epoch, weights and η).
        let clamp = mesh.faces.iter().enumerate().filter(|(_, f)| f.outer.is_none()).all(|(f, face)| {
            let centroid = cleave_geometry::face_area_normal_centroid(&mesh, f).2;
            !(dirichlet.region)(&centroid)
                || (face.polygon.iter().map(|&v| mesh.vertices[v as usize]))
                    .chain(std::iter::once(centroid))
                    .all(|p| (dirichlet.value)(&p) == Vector3::zeros())
        });
        if clamp {
            let mut dg = DgMesh::clamped(mesh, *material, options, dirichlet.region)
                .map_err(|e| CutError::Build(e.to_string()))?;
            let change = dg.cut(surface).map_err(|e| CutError::CannotCut(e.to_string()))?;
            if change.remap == cleave_core::DofRemap::Identity {
                return Err(CutError::CannotCut("the cut changes nothing: it misses the material".into()));
            }
            let (elements, search_seconds) = (dg.num_elements(), dg.penalty_search_seconds());
            let dirichlet_load = dg.dirichlet_load().to_vec();
            let built = BuiltProblem {
                discretization: Box::new(dg),
                prescribed: Vec::new(),
                dirichlet_load,
                elements,
                search_seconds,
            };
            return Ok(CutProblem { built, change });
        }
        // Other data cannot be kept: cut the free box, then impose it on the cut mesh.
        let mut free = DgMesh::new(mesh, *material, options, None).map_err(|e| CutError::Build(e.to_string()))?;
        let change = free.cut(surface).map_err(|e| CutError::CannotCut(e.to_string()))?;
        if change.remap == cleave_core::DofRemap::Identity {
            return Err(CutError::CannotCut("the cut changes nothing: it misses the material".into()));
        }
        let built =
            weakly_clamped(free.polyhedral_mesh().clone(), material, options, dirichlet).map_err(CutError::Build)?;
        Ok(CutProblem { built, change })
    }

    fn extreme_start(
        &self,
        _variant: &str,
        case: ExtremeCase,
        built: &BuiltProblem,
        grid: &BoxGrid,
    ) -> Result<Vec<Real>, NotApplicable> {
        let d = built.discretization.as_ref();
        let rest = d.rest_dofs();
        match case {
            ExtremeCase::PreInverted => {
                // The free-end corner element's field is mirrored through its centre along x
                // (F = diag(−1, 1, 1) there, det F = −1): coefficients d_i ↦ M d_i, plus the
                // translation that keeps the centre in place, on that element only.
                let nb = d.num_nodes() / built.elements;
                let [nx, ny, nz] = grid.dims;
                let element = (nx - 1) + nx * ((ny - 1) + ny * (nz - 1));
                let centre = grid.max_corner() - Vector3::repeat(0.5 * grid.h);
                let mirror = Matrix3::from_diagonal(&Vector3::new(-1.0, 1.0, 1.0));
                let mut shift = vec![0.0; rest.len()];
                d.add_translation(&(centre.coords - mirror * centre.coords), &mut shift);
                let mut x = rest.to_vec();
                for node in element * nb..(element + 1) * nb {
                    let p = Vector3::new(rest[3 * node], rest[3 * node + 1], rest[3 * node + 2]);
                    let q = mirror * p;
                    for a in 0..3 {
                        x[3 * node + a] = q[a] + shift[3 * node + a];
                    }
                }
                Ok(x)
            }
            ExtremeCase::Sliver => {
                Err(NotApplicable("equal cubes on the hex grid (slivers arise from cutting, a later issue)".into()))
            }
            ExtremeCase::Stretch100 => Ok(stretch_start(built, grid)),
        }
    }
}

/// The numerical flux in scene settings.
#[derive(Clone, Copy, Debug, Default, serde::Deserialize, PartialEq, Eq)]
enum FluxSetting {
    #[default]
    InteriorPenalty,
    BabuskaZlamal,
}

/// The scene settings of the DG backend.
#[derive(Clone, Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct DgSettings {
    /// Slicing cell edge [m].
    #[serde(default)]
    cell_size: Option<Real>,
    /// Or: about this many elements.
    #[serde(default)]
    target_elements: Option<usize>,
    /// Polynomial degree, 1 or 2.
    #[serde(default = "one")]
    degree: usize,
    #[serde(default)]
    flux: FluxSetting,
    /// Start of the penalty doubling.
    #[serde(default)]
    penalty: Option<Real>,
    /// Factor on the first positive definite penalty (docs/math/dg.md §9).
    #[serde(default)]
    penalty_margin: Option<Real>,
    /// How the scene's `refinement` splits an element (docs/math/dg.md §14).
    #[serde(default)]
    refine: RefineSetting,
}

/// How DG refines, in scene settings: `refine: (split: Halves, max_depth: 3)`.
#[derive(Clone, Copy, Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RefineSetting {
    /// `Octants` (1→8) or `Halves` (1→2).
    #[serde(default)]
    split: SplitSetting,
    /// Refinements an element may come from.
    #[serde(default = "three")]
    max_depth: u32,
}

impl Default for RefineSetting {
    fn default() -> Self {
        Self { split: SplitSetting::Octants, max_depth: 3 }
    }
}

/// 1→8 or 1→2.
#[derive(Clone, Copy, Debug, Default, serde::Deserialize, PartialEq, Eq)]
enum SplitSetting {
    #[default]
    Octants,
    Halves,
}

fn three() -> u32 {
    3
}

fn one() -> usize {
    1
}

impl Backend for DgBackend {
    fn summary(&self) -> &str {
        "discontinuous Galerkin FEM on polyhedra, BZ/IP fluxes, degree 1-2 (Kaufmann et al. 2008)"
    }

    fn build_solid(&self, settings: &str, request: &SolidRequest) -> Result<BuiltSolid, BackendError> {
        let settings: DgSettings = parse_settings(settings)?;
        let (poly, h, surface) = match request.shape {
            Shape::Surface(surface) => {
                let h = one_size("dg", settings.cell_size, settings.target_elements, "target_elements", |target| {
                    cell_size_for(surface, target, 0.1, |h| {
                        cleave_geometry::hex_slice(surface, h).map(|s| s.mesh.num_elements).map_err(|e| e.to_string())
                    })
                })?;
                let slicing = cleave_geometry::hex_slice(surface, h).map_err(|e| BackendError::Mesh(e.to_string()))?;
                let rest = surface.clone();
                (slicing.mesh, h, rest)
            }
            Shape::Box { min, max } => {
                let h = settings
                    .cell_size
                    .ok_or_else(|| BackendError::Build("a Box object needs dg settings with `cell_size`".into()))?;
                let dims = box_dims(&min, &max, h)?;
                let grid = PolyhedralMesh::grid(Point3::from(min), h, dims);
                let triangles = grid.boundary_triangles();
                let rest = cleave_geometry::TriangleMesh::new(grid.vertices.clone(), triangles);
                (grid, h, rest)
            }
        };
        let flux = match settings.flux {
            FluxSetting::InteriorPenalty => Flux::InteriorPenalty,
            FluxSetting::BabuskaZlamal => Flux::BabuskaZlamal,
        };
        let mut options = DgOptions::new(settings.degree, flux);
        if let Some(margin) = settings.penalty_margin {
            options.penalty_margin = margin;
        }
        if let Some(eta) = settings.penalty {
            options.penalty = eta;
        }
        // Pins clamp the boundary faces whose centroid lies in a pin region (weak Dirichlet
        // data u = 0: DG has no nodal values to hold).
        for (index, region) in request.pins.iter().enumerate() {
            let clamps_a_face = poly.faces.iter().enumerate().any(|(f, face)| {
                face.outer.is_none()
                    && region.contains(cleave_geometry::face_area_normal_centroid(&poly, f).2.coords.as_slice())
            });
            if !clamps_a_face {
                return Err(BackendError::Build(format!(
                    "pins[{index}]: the region {:?}..{:?} contains no boundary face centroid",
                    region.min, region.max
                )));
            }
        }
        let on_boundary = |p: &Point3<Real>| request.pins.iter().any(|region| region.contains(p.coords.as_slice()));
        let dg = if request.pins.is_empty() {
            DgMesh::new(poly, request.material, options, None)
        } else {
            // A clamp the mesh keeps through cuts and refinements.
            DgMesh::clamped(poly, request.material, options, &on_boundary)
        }
        .map_err(|e| BackendError::Build(format!("discretization: {e}")))?;
        let mut dg = dg;
        dg.set_refinement(Refinement {
            split: match settings.refine.split {
                SplitSetting::Octants => RefineSplit::Octants,
                SplitSetting::Halves => RefineSplit::Halves,
            },
            max_depth: settings.refine.max_depth,
        });
        let pins = ResolvedPins { pinned_dofs: Vec::new(), extra_load: dg.dirichlet_load().to_vec() };
        let elements = dg.num_elements();
        Ok(BuiltSolid { discretization: Box::new(dg), elements, element_size: h, pins, surface })
    }

    fn resolve_pins(
        &self,
        _discretization: &dyn Discretization,
        _pins: &[Region],
    ) -> Result<ResolvedPins, BackendError> {
        // The weak clamp is built into the DG mesh with its faces (`DgMesh::clamped`) and kept
        // by cuts and refinements; its data is u = 0, so it has no load.
        Ok(ResolvedPins::default())
    }
}
