//! Which cube faces the cut cantilever's crack covers (benchmarks.md §5), against counts made by
//! hand: the faces above the crack front and nothing else, a front through the middle of a row
//! of faces and a crack off the node planes declined.

use cleave_core::Point3;
use cleave_testkit::compare::Problem;
use cleave_testkit::problems::{cantilever, crack};
use cleave_voxel::{VoxelError, VoxelMesh, covered_faces};

#[test]
fn the_voxel_crack_is_the_cube_faces_above_the_front_and_nothing_else() {
    for n in [2usize, 4] {
        let grid = Problem::CutCantilever.grid(n);
        let mesh = VoxelMesh::from_box(cantilever::material(0.3), grid.origin, grid.h, grid.dims).unwrap();
        let faces = covered_faces(&mesh, &crack::cantilever(grid.h)).unwrap();
        // n cubes across the width, n/2 above z = 0.5, all with their +x face on x = 2.
        assert_eq!(faces.len(), n * n / 2, "n = {n}");
        assert!(faces.iter().all(|f| f.axis == 0 && f.cell[0] == 2 * n as i32 - 1 && f.cell[2] >= n as i32 / 2));
    }
    // n = 3: the front z = 0.5 crosses the middle of a row of faces.
    let grid = Problem::CutCantilever.grid(3);
    let mesh = VoxelMesh::from_box(cantilever::material(0.3), grid.origin, grid.h, grid.dims).unwrap();
    assert!(matches!(covered_faces(&mesh, &crack::cantilever(grid.h)), Err(VoxelError::PartlyCoveredFace(..))));
    // A crack 1e-6 h off the node plane lies on no face.
    let grid = Problem::CutCantilever.grid(2);
    let mesh = VoxelMesh::from_box(cantilever::material(0.3), grid.origin, grid.h, grid.dims).unwrap();
    let off = crack::half_plane(&Point3::origin(), &Point3::new(4.0, 1.0, 1.0), 2.0 + 1e-6 * grid.h, 0.5, grid.h);
    assert!(matches!(covered_faces(&mesh, &off), Err(VoxelError::NoFaceCovered)));
}
