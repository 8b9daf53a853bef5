//! What splitting elements costs against element size (issue 36): a unit cube of n³ cuboid
//! cells cut by an oblique plane, one `Cuttable::cut` per size, with the number of elements it
//! split and the time per split element (the whole change: splitting, separation, validation,
//! the new elements' integrals and the mesh rebuilt around them).
//!
//! Run: `cargo run --release -p cleave-meanvalue --example split_cost`

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Vector3};
use cleave_meanvalue::MeanValueMesh;
use std::time::Instant;

fn main() {
    let material = Material::new(1e6, 0.3, 1000.0).expect("a valid material");
    println!("| n | h [m] | elements before | split | nodes before → after | cut [ms] | ms per split element |");
    println!("|---|---|---|---|---|---|---|");
    for n in [4, 8, 16, 24] {
        let h = 1.0 / n as f64;
        let mut best = f64::MAX;
        let mut row = String::new();
        for _ in 0..3 {
            let mut mesh = MeanValueMesh::from_box(material, Point3::origin(), h, [n, n, n]).expect("a box");
            let (elements, nodes) = (mesh.num_elements(), mesh.num_nodes());
            let plane = CutSurface::Plane { point: Point3::new(0.5, 0.5, 0.5), normal: Vector3::new(1.0, 0.7, 0.4) };
            let clock = Instant::now();
            mesh.cut(&plane).expect("the plane cuts");
            let ms = clock.elapsed().as_secs_f64() * 1e3;
            // Each split element becomes two (merged slivers aside).
            let split = mesh.num_elements() - elements + mesh.last_cut().merged;
            if ms < best {
                best = ms;
                row = format!(
                    "| {n} | {h:.4} | {elements} | {split} | {nodes} → {} | {ms:.1} | {:.3} |",
                    mesh.num_nodes(),
                    ms / split as f64
                );
            }
        }
        println!("{row}");
    }
}
