//! The voxel backend (mueller2004): its scene settings and its comparison variant. Nodal, so
//! Dirichlet data and pins are imposed strongly by pinning the nodes in the region. In the
//! comparison it cuts along whole cube faces ([`covered_faces`]: the cubes on both sides of every
//! face a cut covers get their own nodes), which for a cut on cube faces is the conforming
//! cracked hexahedral grid of benchmarks.md §5; scenes cannot cut it yet.

use crate::backend::{
    Backend, BackendError, BuiltSolid, Shape, SolidRequest, box_dims, cell_size_for, one_size, parse_settings,
};
use cleave_core::{CutSurface, Discretization, Material, Point3, Real};
use cleave_testkit::compare::{
    BoxGrid, BuildError, BuiltProblem, CompareBackend, CutError, CutProblem, DirichletSpec, ExtremeCase, NotApplicable,
    corner_pushed_in, nodal_problem, stretch_start,
};
use cleave_voxel::{CubeFace, VoxelMesh};

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
        let mesh = VoxelMesh::from_box(*material, grid.origin, grid.h, grid.dims)
            .map_err(|e| CutError::Build(e.to_string()))?;
        let faces = covered_faces(&mesh, surface)?;
        let (cut, change) = mesh.separate_faces(&faces).map_err(|e| CutError::Build(e.to_string()))?;
        let elements = cut.num_cubes();
        Ok(CutProblem { built: nodal_problem(Box::new(cut), elements, dirichlet), change })
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

/// The interior cube faces `surface` covers, for cutting along whole faces. A face is covered
/// when it lies in the plane of a triangle (every corner within 1e-9 h of it) and its centre and
/// its four quarter points (halfway between centre and corners) lie in the union of such
/// triangles; a face with some but not all of those five points covered is only partly cut,
/// which cubes cannot express ([`CutError::CannotCut`]), and so is a surface that covers no face
/// (e.g. a plane off the cube faces).
pub fn covered_faces(mesh: &VoxelMesh, surface: &CutSurface) -> Result<Vec<CubeFace>, CutError> {
    let h = mesh.cell_size();
    let origin = mesh.origin();
    let tolerance = 1e-9 * h;
    let mut faces = Vec::new();
    for cell in mesh.cells() {
        for axis in 0..3 {
            let mut next = *cell;
            next[axis] += 1;
            if mesh.cube_at(next).is_none() {
                continue;
            }
            let face = CubeFace { cell: *cell, axis };
            let coordinate = origin[axis] + h * next[axis] as Real;
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let centre = [origin[u] + h * (cell[u] as Real + 0.5), origin[v] + h * (cell[v] as Real + 0.5)];
            let samples: [[Real; 2]; 5] = std::array::from_fn(|k| match k {
                0 => centre,
                _ => {
                    let (su, sv) = (if k & 1 == 1 { 0.25 } else { -0.25 }, if k >= 3 { 0.25 } else { -0.25 });
                    [centre[0] + su * h, centre[1] + sv * h]
                }
            });
            let covered = match surface {
                CutSurface::Plane { point, normal } => {
                    let on_plane = (0..3).all(|a| a == axis || normal[a] == 0.0)
                        && normal[axis] != 0.0
                        && (point[axis] - coordinate).abs() <= tolerance;
                    if on_plane { 5 } else { 0 }
                }
                CutSurface::Triangles(triangles) => {
                    let coplanar: Vec<[[Real; 2]; 3]> = triangles
                        .iter()
                        .filter(|t| t.iter().all(|p| (p[axis] - coordinate).abs() <= tolerance))
                        .map(|t| t.map(|p| [p[u], p[v]]))
                        .collect();
                    samples.iter().filter(|s| coplanar.iter().any(|t| in_triangle(t, s, tolerance))).count()
                }
            };
            match covered {
                0 => {}
                5 => faces.push(face),
                _ => {
                    let c = cell;
                    return Err(CutError::CannotCut(format!(
                        "the cut covers the face of cube ({}, {}, {}) towards +{} in part; voxel cubes separate \
                         along whole faces only",
                        c[0],
                        c[1],
                        c[2],
                        ['x', 'y', 'z'][axis]
                    )));
                }
            }
        }
    }
    if faces.is_empty() {
        return Err(CutError::CannotCut("the cut covers no cube face (voxel cubes separate along faces only)".into()));
    }
    Ok(faces)
}

/// Whether the 2D point `p` lies in the closed triangle `t` (either orientation), with `tolerance`
/// as a distance.
fn in_triangle(t: &[[Real; 2]; 3], p: &[Real; 2], tolerance: Real) -> bool {
    let cross =
        |a: &[Real; 2], b: &[Real; 2], c: &[Real; 2]| (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    let area = cross(&t[0], &t[1], &t[2]);
    if area == 0.0 {
        return false;
    }
    (0..3).all(|i| {
        let (a, b) = (&t[i], &t[(i + 1) % 3]);
        let edge = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        cross(a, b, p) * area.signum() >= -tolerance * edge
    })
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
                let mesh = VoxelMesh::new(request.material, grid.origin, grid.cell_size, &grid.cells)
                    .map_err(|e| mesh_error(&e))?;
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
