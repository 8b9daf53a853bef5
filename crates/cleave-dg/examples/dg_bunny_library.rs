//! Library use of the DG backend without the scene crate: load the bunny, cut it into polyhedral
//! elements by hexahedral slicing, build the DG discretization, embed the original surface by MLS,
//! and step it onto a ground plane with the integrator. The path to copy into your own program.

use cleave_core::{Discretization, Material, Point3, Real, Vector3};
use cleave_dg::{DgMesh, DgOptions, Flux};
use cleave_geometry::{TriangleMesh, hex_slice};
use cleave_integrator::{Constraints, Integrator, PlaneCollider, Settings, Solver};
use std::io::BufReader;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // 1. A closed surface: the bunny, scaled to 0.2 m, turned z up, 0.3 m above the ground.
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/meshes/bunny.obj");
    let mesh = TriangleMesh::from_obj_reader(&mut BufReader::new(std::fs::File::open(path)?))?;
    mesh.validate_closed()?;
    let mesh = mesh.transformed(|p| Point3::new(0.02 * p.x, -0.02 * p.z, 0.02 * p.y));
    let lift = 0.3 - mesh.aabb().0.z;
    let mesh = mesh.transformed(|p| p + Vector3::new(0.0, 0.0, lift));

    // 2. Hexahedral slicing: cubes inside, arbitrary polyhedra where the surface cuts a cell.
    let slicing = hex_slice(&mesh, 0.022)?;
    let material = Material::new(2e5, 0.3, 1000.0)?.with_damping(0.0, 0.002)?;
    let dg = DgMesh::new(slicing.mesh, material, DgOptions::new(1, Flux::InteriorPenalty), None)?;
    println!("{} elements, {} DOFs, penalty η = {}", dg.num_elements(), 3 * dg.num_nodes(), dg.penalty());

    // 3. The original surface, embedded by MLS: smooth across the discontinuous elements. It
    //    renders the result and collides with the ground.
    let surface = dg.embed_surface(&mesh.vertices)?;
    let constraints = Constraints {
        contact_points: Some(surface.clone()),
        planes: vec![PlaneCollider {
            point: Point3::origin(),
            normal: Vector3::z(),
            stiffness: 2e5,
            damping: 0.0,
            friction: 0.0,
        }],
        ..Default::default()
    };
    let mut settings = Settings::new(1.0 / 240.0);
    settings.rayleigh_beta = material.rayleigh_beta;
    settings.solver = Solver::Cholesky;
    let mut integrator = Integrator::new(&dg, settings, constraints)?;

    // 4. Step and watch the lowest surface point.
    for step in 0..480 {
        let report = integrator.step(&dg)?;
        if step % 40 == 0 {
            let lowest =
                (0..surface.len()).map(|i| surface.point(integrator.positions(), i).z).fold(Real::MAX, Real::min);
            println!("t = {:.3} s  lowest z = {:.4} m  energy = {:.4} J", report.time, lowest, report.total_energy());
        }
    }
    Ok(())
}
