//! The DG backend (kaufmann2008) registered with the comparison harness: Dirichlet data is
//! imposed weakly (Nitsche/interior-penalty boundary terms on the faces whose centroid lies in the
//! Dirichlet region), handed over as a load vector; no DOF is pinned.

use cleave_core::{Material, Matrix3, Real, Vector3};
use cleave_dg::{DgMesh, DgOptions, Flux, WeakDirichlet};
use cleave_geometry::PolyhedralMesh;
use cleave_testkit::compare::{
    BoxGrid, BuildError, BuiltProblem, CompareBackend, DirichletSpec, ExtremeCase, NotApplicable, stretch_start,
};

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
        let weak = WeakDirichlet { on_boundary: dirichlet.region, data: dirichlet.value };
        let dg = DgMesh::new(mesh, *material, options, Some(&weak)).map_err(|e| BuildError(e.to_string()))?;
        let elements = dg.num_elements();
        let search_seconds = dg.penalty_search_seconds();
        let dirichlet_load = dg.dirichlet_load().to_vec();
        Ok(BuiltProblem {
            discretization: Box::new(dg),
            prescribed: Vec::new(),
            dirichlet_load,
            elements,
            search_seconds,
        })
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
