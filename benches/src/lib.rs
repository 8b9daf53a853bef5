//! Shared set-up for the criterion benches: the bunny at a given cube count, the benchmark beam.

use cleave_core::{Material, Point3, Real};
use cleave_geometry::{TriangleMesh, voxelize};
use cleave_voxel::VoxelMesh;

/// The bunny of the scenes (0.2 m, z up), voxelized with about `target` cubes.
pub fn bunny_voxels(target: usize) -> (VoxelMesh, TriangleMesh) {
    let text = include_str!("../../scenes/meshes/bunny.obj");
    let mesh = TriangleMesh::from_obj_str(text).expect("bunny parses");
    // As scenes/bunny_drop_voxel.ron: scale 0.02, y up turned z up, lowest point at z = 0.3.
    let mesh = mesh.transformed(|p| Point3::new(0.02 * p.x, -0.02 * p.z, 0.02 * p.y));
    let lift = 0.3 - mesh.aabb().0.z;
    let mesh = mesh.transformed(|p| Point3::new(p.x, p.y, p.z + lift));
    let volume = mesh.signed_volume();
    let mut h = (volume / target as Real).cbrt();
    let mut grid = voxelize(&mesh, h).expect("bunny voxelizes");
    for _ in 0..4 {
        h *= (grid.cells.len() as Real / target as Real).cbrt();
        grid = voxelize(&mesh, h).expect("bunny voxelizes");
    }
    let material = Material::new(2e5, 0.3, 1000.0).expect("valid").with_damping(0.0, 0.01).expect("valid");
    (VoxelMesh::new(material, grid.origin, grid.cell_size, &grid.cells).expect("voxel mesh"), mesh)
}
