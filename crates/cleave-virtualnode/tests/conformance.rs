//! The conformance suite on a carved block, before and after cuts (plane and triangle soup).

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Vector3};
use cleave_testkit::{assert_all_pass, conformance_suite};
use cleave_virtualnode::VirtualNodeMesh;

fn block() -> VirtualNodeMesh {
    let material = Material::new(3e5, 0.35, 1100.0).unwrap();
    // Box faces off the lattice planes, so the carving cuts tetrahedra.
    VirtualNodeMesh::from_box(Point3::new(0.03, -0.21, 0.11), Point3::new(0.83, 0.17, 0.52), 0.1, material).unwrap()
}

#[test]
fn carved_block_passes_the_conformance_suite() {
    let mesh = block();
    println!("{} duplicates, {} nodes", mesh.num_duplicates(), mesh.num_nodes());
    assert_all_pass(&conformance_suite(&mesh));
}

#[test]
fn cut_block_passes_the_conformance_suite() {
    let mut mesh = block();
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.4, 0.0, 0.0), normal: Vector3::new(1.0, 0.3, 0.1) }).unwrap();
    // A partial cut: a slanted triangle that ends inside the material.
    let tri = [Point3::new(0.6, -0.3, 0.2), Point3::new(0.7, 0.3, 0.35), Point3::new(0.65, -0.3, 0.6)];
    mesh.cut(&CutSurface::Triangles(vec![tri])).unwrap();
    assert_eq!(mesh.pieces().len(), 2);
    println!("{} duplicates, {} nodes", mesh.num_duplicates(), mesh.num_nodes());
    assert_all_pass(&conformance_suite(&mesh));
}
