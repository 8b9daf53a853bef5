//! Separating cubes across faces (`VoxelMesh::separate_faces`): node counts against counts made
//! by hand, the rigid modes of the assembled stiffness (eigenvalues of a dense K built column by
//! column from the stiffness action), pieces found from shared nodes, and the state carried
//! across the change.

use cleave_core::{Discretization, DofRemap, Material, Matrix3, Point3, Real};
use cleave_voxel::{CubeFace, VoxelMesh};
use nalgebra::DMatrix;

fn material() -> Material {
    Material::new(1e6, 0.3, 1000.0).unwrap()
}

fn beam(n: usize) -> VoxelMesh {
    VoxelMesh::from_box(material(), Point3::origin(), 1.0 / n as Real, [4 * n, n, n]).unwrap()
}

/// Faces of the plane x = `plane` (in cubes) whose cube's z index is at least `z_from`.
fn plane_faces(mesh: &VoxelMesh, plane: i32, z_from: i32) -> Vec<CubeFace> {
    mesh.cells()
        .iter()
        .filter(|c| c[0] == plane - 1 && c[2] >= z_from)
        .map(|&cell| CubeFace { cell, axis: 0 })
        .collect()
}

/// The dense stiffness (identity rotations) from the stiffness action on unit vectors.
fn dense_stiffness(mesh: &VoxelMesh) -> DMatrix<Real> {
    let n = 3 * mesh.num_nodes();
    let rotations = vec![Matrix3::identity(); mesh.num_frames()];
    let mut k = DMatrix::zeros(n, n);
    let mut unit = vec![0.0; n];
    for j in 0..n {
        unit[j] = 1.0;
        let mut column = vec![0.0; n];
        mesh.add_stiffness_action(&rotations, &unit, 1.0, &mut column);
        unit[j] = 0.0;
        for i in 0..n {
            k[(i, j)] = column[i];
        }
    }
    k
}

/// Eigenvalues below 1e-10 of the largest: the zero-energy modes.
fn zero_modes(k: &DMatrix<Real>) -> usize {
    let eigen = k.clone().symmetric_eigenvalues();
    let largest = eigen.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
    eigen.iter().filter(|v| v.abs() < 1e-10 * largest).count()
}

/// Connected components of cubes that share a node.
fn pieces(mesh: &VoxelMesh) -> usize {
    let cubes = mesh.cube_nodes();
    let mut label: Vec<Option<usize>> = vec![None; cubes.len()];
    let mut count = 0;
    for start in 0..cubes.len() {
        if label[start].is_some() {
            continue;
        }
        let mut stack = vec![start];
        label[start] = Some(count);
        while let Some(c) = stack.pop() {
            for (other, nodes) in cubes.iter().enumerate() {
                if label[other].is_none() && nodes.iter().any(|n| cubes[c].contains(n)) {
                    label[other] = Some(count);
                    stack.push(other);
                }
            }
        }
        count += 1;
    }
    count
}

#[test]
fn a_full_plane_splits_the_beam_into_two_pieces_with_two_more_rigid_modes() {
    let mesh = beam(1);
    // 4 × 1 × 1 cubes: 5 · 2 · 2 = 20 nodes; the plane x = 2 has 4 of them, each duplicated.
    assert_eq!(mesh.num_nodes(), 20);
    let (split, change) = mesh.separate_faces(&plane_faces(&mesh, 2, 0)).unwrap();
    assert_eq!(split.num_nodes(), 24);
    assert_eq!(pieces(&mesh), 1);
    assert_eq!(pieces(&split), 2);
    // Free faces: no node is shared by a cube left of x = 2 and one right of it.
    for (a, left) in split.cells().iter().zip(split.cube_nodes()) {
        for (b, right) in split.cells().iter().zip(split.cube_nodes()) {
            if a[0] < 2 && b[0] >= 2 {
                assert!(left.iter().all(|n| !right.contains(n)), "cubes {a:?} and {b:?} share a node");
            }
        }
    }
    assert_eq!(zero_modes(&dense_stiffness(&mesh)), 6);
    assert_eq!(zero_modes(&dense_stiffness(&split)), 12);
    assert_eq!(change.epoch, mesh.epoch() + 1);
    // Every new node copies the old node at its rest position.
    let DofRemap::Gather(source) = &change.remap else { panic!("expected a gather, got {:?}", change.remap) };
    for (new, &old) in source.iter().enumerate() {
        assert_eq!(split.rest_dofs()[3 * new..3 * new + 3], mesh.rest_dofs()[3 * old as usize..3 * old as usize + 3]);
    }
    // The mass is redistributed, not changed.
    let total = |m: &VoxelMesh| m.mass().diagonal().iter().sum::<Real>();
    assert!((total(&split) - total(&mesh)).abs() < 1e-12 * total(&mesh));
}

#[test]
fn a_half_depth_crack_duplicates_the_nodes_above_its_front_only() {
    for n in [2usize, 4, 6] {
        let mesh = beam(n);
        // Faces x = 2 with z > 0.5: the cubes of z index ≥ n/2 left of the plane, n · n/2 faces.
        let faces = plane_faces(&mesh, 2 * n as i32, n as i32 / 2);
        assert_eq!(faces.len(), n * n / 2);
        let (cracked, _) = mesh.separate_faces(&faces).unwrap();
        // By hand: the nodes on x = 2 strictly above z = 0.5 (the front z = 0.5 stays one node):
        // (n + 1) along y times n/2 along z.
        assert_eq!(cracked.num_nodes() - mesh.num_nodes(), (n + 1) * n / 2, "n = {n}");
        assert_eq!(pieces(&cracked), 1);
        if n == 2 {
            // Still connected below the crack: the six rigid modes only.
            assert_eq!(zero_modes(&dense_stiffness(&cracked)), 6);
        }
    }
}

#[test]
fn no_faces_leave_the_mesh_as_it_was_and_a_boundary_face_is_an_error() {
    let mesh = beam(2);
    let (same, change) = mesh.separate_faces(&[]).unwrap();
    assert_eq!(change.remap, DofRemap::Identity);
    assert_eq!(same.epoch(), mesh.epoch());
    assert_eq!(same.rest_dofs(), mesh.rest_dofs());
    assert_eq!(same.cube_nodes(), mesh.cube_nodes());
    // The tip face x = 4 has no cube beyond it.
    let error = mesh.separate_faces(&[CubeFace { cell: [7, 0, 0], axis: 0 }]).unwrap_err();
    assert!(error.to_string().contains("(7, 0, 0) towards +x"), "{error}");
}
