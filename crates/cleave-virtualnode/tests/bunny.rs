//! Carving the Stanford bunny (3674 triangles, many meeting at shallow angles inside one lattice
//! tetrahedron): the carved volume equals the volume the surface encloses.

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real, Vector3};
use cleave_geometry::TriangleMesh;
use cleave_virtualnode::VirtualNodeMesh;
use std::io::BufReader;

fn bunny() -> TriangleMesh {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/meshes/bunny.obj");
    let mesh = TriangleMesh::from_obj_reader(&mut BufReader::new(std::fs::File::open(path).unwrap())).unwrap();
    mesh.transformed(|p| Point3::new(0.02 * p.x, -0.02 * p.z, 0.02 * p.y + 0.05))
}

#[test]
fn carved_bunny_has_the_volume_its_surface_encloses() {
    let surface = bunny();
    let exact = surface.signed_volume();
    for h in [0.02, 0.013] {
        let start = std::time::Instant::now();
        let mut body = VirtualNodeMesh::carve(&surface, h, Material::new(1e5, 0.3, 1000.0).unwrap()).unwrap();
        let carve_ms = start.elapsed().as_secs_f64() * 1e3;
        let v = body.volume();
        println!(
            "h = {h}: {} duplicates, {} nodes, carved in {carve_ms:.0} ms, volume {v:.15e} vs {exact:.15e} (rel {:.1e})",
            body.num_duplicates(),
            body.num_nodes(),
            (v - exact).abs() / exact
        );
        assert!((v - exact).abs() < 1e-12 * exact);
        assert_eq!(body.pieces().len(), 1);
        let (lo, hi) = surface.aabb();
        let centre = nalgebra::center(&lo, &hi);
        let start = std::time::Instant::now();
        body.cut(&CutSurface::Plane { point: centre, normal: Vector3::new(1.0, 0.2, 0.1) }).unwrap();
        let pieces = body.pieces();
        let total: Real = pieces.iter().map(|p| p.volume).sum();
        println!("   plane cut in {:.1} ms: {} pieces", start.elapsed().as_secs_f64() * 1e3, pieces.len());
        assert!(pieces.len() >= 2);
        assert!((total - exact).abs() < 1e-12 * exact);
    }
}
