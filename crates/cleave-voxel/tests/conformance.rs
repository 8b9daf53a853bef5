//! The conformance suite and the patch test on voxel meshes.

use cleave_core::{Discretization, Material, Point3};
use cleave_testkit::{assert_all_pass, conformance_suite, patch_test};
use cleave_voxel::VoxelMesh;

/// An irregular set of cubes: an L-shaped slab with a tower, 0.2 m cubes, off the origin.
fn irregular_mesh() -> VoxelMesh {
    let mut cells = Vec::new();
    for i in 0..4 {
        for j in 0..3 {
            if i < 2 || j < 1 {
                cells.push([i, j, 0]);
            }
        }
    }
    for k in 1..4 {
        cells.push([0, 0, k]);
        cells.push([1, 0, k]);
    }
    let material = Material::new(3e5, 0.35, 1100.0).unwrap();
    VoxelMesh::new(material, Point3::new(0.3, -1.0, 2.0), 0.2, &cells).unwrap()
}

#[test]
fn voxel_backend_passes_the_conformance_suite() {
    let mesh = irregular_mesh();
    assert_all_pass(&conformance_suite(&mesh));
}

#[test]
fn patch_test_reproduces_affine_fields_on_a_box_with_interior_nodes() {
    let material = Material::new(1e6, 0.3, 1000.0).unwrap();
    let mesh = VoxelMesh::from_box(material, Point3::new(-0.5, 0.25, 1.0), 0.25, [4, 3, 3]).unwrap();
    let coords = mesh.node_coords();
    let boundary: Vec<usize> = (0..mesh.num_nodes())
        .filter(|&n| {
            let c = coords[n];
            c[0] == 0 || c[0] == 4 || c[1] == 0 || c[1] == 3 || c[2] == 0 || c[2] == 3
        })
        .collect();
    assert!(boundary.len() < mesh.num_nodes(), "the patch must have interior nodes");
    assert_all_pass(&[patch_test(&mesh, &boundary)]);
}

#[test]
fn translating_the_whole_problem_changes_no_force_action_or_energy() {
    // The same cubes built 1000 m away, at a bent state whose cube rotations differ by more than
    // 0.2 rad: a force that depended on where the origin is would differ by the lever arm.
    let material = Material::new(3e5, 0.35, 1100.0).unwrap();
    let cells = irregular_mesh().cells().to_vec();
    let shift = cleave_core::Vector3::new(600.0, -480.0, 640.0);
    let origin = Point3::new(0.3, -1.0, 2.0);
    let near = VoxelMesh::new(material, origin, 0.2, &cells).unwrap();
    let far = VoxelMesh::new(material, origin + shift, 0.2, &cells).unwrap();
    assert!((shift.norm() - 1e3).abs() < 1e-9);
    assert_all_pass(&[cleave_testkit::translation_invariance(&near, &far)]);
}
