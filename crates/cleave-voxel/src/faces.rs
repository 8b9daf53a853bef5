//! Which cube faces a cut surface covers, for separating cubes along whole faces
//! ([`VoxelMesh::separate_faces`]): what the comparison's cut cantilever cuts with.

use crate::mesh::{CubeFace, VoxelError, VoxelMesh};
use cleave_core::{CutSurface, Real};

/// The interior cube faces `surface` covers, for cutting along whole faces. A face is covered
/// when it lies in the plane of a triangle (every corner within 1e-9 h of it) and its centre and
/// its four quarter points (halfway between centre and corners) lie in the union of such
/// triangles; a face with some but not all of those five points covered is only partly cut,
/// which cubes cannot express ([`VoxelError::PartlyCoveredFace`]), and so is a surface that covers
/// no face ([`VoxelError::NoFaceCovered`], e.g. a plane off the cube faces).
pub fn covered_faces(mesh: &VoxelMesh, surface: &CutSurface) -> Result<Vec<CubeFace>, VoxelError> {
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
                _ => return Err(VoxelError::PartlyCoveredFace(cell[0], cell[1], cell[2], ['x', 'y', 'z'][axis])),
            }
        }
    }
    if faces.is_empty() {
        return Err(VoxelError::NoFaceCovered);
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
