//! temporary profiling
use cleave_core::{CutSurface, Cuttable, Material, Point3, Vector3};
use cleave_geometry::TriangleMesh;
use cleave_virtualnode::VirtualNodeMesh;
use std::io::BufReader;
use std::time::Instant;
fn main() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/meshes/bunny.obj");
    let mesh = TriangleMesh::from_obj_reader(&mut BufReader::new(std::fs::File::open(path).unwrap())).unwrap();
    let mesh = mesh.transformed(|p| Point3::new(0.02 * p.x, -0.02 * p.z, 0.02 * p.y));
    let lift = -mesh.aabb().0.z;
    let mesh = mesh.transformed(|p| p + Vector3::new(0.0, 0.0, lift));
    let material = Material::new(2e5, 0.3, 1000.0).unwrap();
    let mut body = VirtualNodeMesh::carve(&mesh, 0.02, material).unwrap();
    let reps: usize = std::env::args().nth(1).map(|a| a.parse().unwrap()).unwrap_or(10);
    let mode = std::env::args().nth(2).unwrap_or("surface".into());
    let planes = [
        ((0.0, 0.0, 0.125), (0.0, 0.0, 1.0)),
        ((0.035, 0.0, 0.0), (1.0, 0.0, 0.0)),
        ((-0.05, 0.0, 0.0), (1.0, 0.0, 0.0)),
        ((0.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ];
    if mode == "cut" {
        let mut total = 0.0;
        for _ in 0..reps {
            let mut b = VirtualNodeMesh::carve(&mesh, 0.02, material).unwrap();
            let t = Instant::now();
            for (p, n) in planes {
                b.cut(&CutSurface::Plane { point: Point3::new(p.0, p.1, p.2), normal: Vector3::new(n.0, n.1, n.2) })
                    .unwrap();
            }
            total += t.elapsed().as_secs_f64();
        }
        println!("4 cuts {:.1} ms", total * 1e3 / reps as f64);
        return;
    }
    for (p, n) in planes {
        body.cut(&CutSurface::Plane { point: Point3::new(p.0, p.1, p.2), normal: Vector3::new(n.0, n.1, n.2) })
            .unwrap();
    }
    let t = Instant::now();
    let mut n = 0;
    for _ in 0..reps {
        n += body.render_surface().triangles.len();
    }
    println!("render_surface {:.1} ms, {} triangles", t.elapsed().as_secs_f64() * 1e3 / reps as f64, n / reps);
}
