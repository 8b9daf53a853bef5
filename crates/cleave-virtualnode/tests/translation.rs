//! Virtual node tets, carved and cut, do not know where the world origin is: the same block built
//! 1000 m away and cut by the same (translated) soup gives the same force, stiffness action and
//! energy at a bent state, and a bent state rotated rigidly gives rotated forces.

use cleave_core::{Cuttable, Discretization, Material, Point3, Vector3};
use cleave_testkit::{assert_all_pass, rotation_covariance, translation_invariance};
use cleave_virtualnode::VirtualNodeMesh;

#[test]
fn a_cut_block_moved_1000_m_keeps_force_action_and_energy() {
    let material = Material::new(3e5, 0.35, 1100.0).unwrap();
    // Dyadic coordinates throughout, so the moved box, lattice and soup are the same numbers
    // plus the shift, exactly: carving decides by exact predicates, and inputs rounded
    // differently would carve slivers of 1e-13 m differently (a different mesh, not a test of
    // the physics). |shift| = 1173 m.
    let shift = Vector3::new(512.0, -256.0, 1024.0);
    // Faces off the lattice planes (a generic carving, not one decided by ties).
    let (lo, hi) = (Point3::new(0.3125, -1.0, 2.0), Point3::new(1.140625, -0.6328125, 2.2890625));
    let mut near = VirtualNodeMesh::from_box(lo, hi, 0.125, material).unwrap();
    let mut far = VirtualNodeMesh::from_box(lo + shift, hi + shift, 0.125, material).unwrap();
    // A slanted triangle that cuts part way into the block (an unfinished cut).
    let soup =
        [[Point3::new(0.625, -1.25, 1.875), Point3::new(0.75, -0.375, 1.875), Point3::new(0.6875, -0.8125, 2.1875)]];
    let moved: Vec<[Point3<f64>; 3]> = soup.iter().map(|t| t.map(|p| p + shift)).collect();
    println!("before the cut: {} and {}", near.num_duplicates(), far.num_duplicates());
    near.cut(&cleave_core::CutSurface::Triangles(soup.to_vec())).unwrap();
    far.cut(&cleave_core::CutSurface::Triangles(moved)).unwrap();
    println!(
        "duplicates {} and {}, nodes {} and {}",
        near.num_duplicates(),
        far.num_duplicates(),
        near.num_nodes(),
        far.num_nodes()
    );
    assert!(near.num_duplicates() > 0 && near.num_duplicates() == far.num_duplicates());
    assert_all_pass(&[translation_invariance(&near, &far), rotation_covariance(&near)]);
}
