//! The conformance suite on a carved block, before and after cuts (plane and triangle soup),
//! and the cut contract (`cleave_testkit::cut_conformance`).

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real, Vector3};
use cleave_testkit::cut_conformance::{CutBody, CutSubject, Transfer, contract_cuts, cut_conformance};
use cleave_testkit::{assert_all_pass, conformance_suite};
use cleave_virtualnode::{VirtualNodeMesh, box_surface};
use nalgebra::Isometry3;

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

#[test]
fn cuts_keep_the_cut_contract() {
    // A block off the lattice planes, cut by an oblique plane, a partial slanted triangle that
    // ends inside the material, a curved soup (a bent strip of triangles) and a plane through
    // lattice nodes; moved by a turn about a skew axis and a translation off the lattice.
    let material = Material::new(3e5, 0.35, 1100.0).unwrap();
    let surface = box_surface(Point3::new(0.03, -0.21, 0.11), Point3::new(0.83, 0.17, 0.52));
    let make = |motion: &Isometry3<Real>| -> Box<dyn CutBody> {
        let moved = surface.transformed(|p| motion * p);
        Box::new(VirtualNodeMesh::carve(&moved, 0.1, material).unwrap())
    };
    let subject = CutSubject {
        make: &make,
        cuts: contract_cuts(0.3),
        placement: Isometry3::new(Vector3::new(0.37, -1.21, 2.53), Vector3::new(0.3, -0.5, 0.8)),
        transfer: Transfer::Exact,
    };
    assert_all_pass(&cut_conformance(&subject));
}
