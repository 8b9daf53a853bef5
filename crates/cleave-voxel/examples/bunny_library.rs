//! Library use of one backend without the scene crate: load the bunny, voxelize it, step it with
//! the integrator onto a ground plane, print its height. The path to copy into your own program.

use cleave_core::{Discretization, Material, Point3, Real, Vector3};
use cleave_geometry::{TriangleMesh, voxelize};
use cleave_integrator::{Constraints, Integrator, PlaneCollider, Settings, Solver};
use cleave_voxel::VoxelMesh;
use std::io::BufReader;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // 1. A closed surface: the bunny, scaled to 0.2 m, turned z up, 0.3 m above the ground.
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/meshes/bunny.obj");
    let mesh = TriangleMesh::from_obj_reader(&mut BufReader::new(std::fs::File::open(path)?))?;
    mesh.validate_closed()?;
    let mesh = mesh.transformed(|p| Point3::new(0.02 * p.x, -0.02 * p.z, 0.02 * p.y));
    let lift = 0.3 - mesh.aabb().0.z;
    let mesh = mesh.transformed(|p| p + Vector3::new(0.0, 0.0, lift));

    // 2. Voxelize and build the cube mesh: one 24×24 stiffness for all cubes.
    let material = Material::new(2e5, 0.3, 1000.0)?.with_damping(0.0, 0.01)?;
    let grid = voxelize(&mesh, 0.008)?;
    let cubes = VoxelMesh::new(material, grid.origin, grid.cell_size, &grid.cells)?;
    println!("{} cubes, {} nodes", cubes.num_cubes(), cubes.num_nodes());

    // 3. Embed the surface vertices; they render the result and collide with the ground.
    let surface = cubes.embed(&mesh.vertices)?;
    let constraints = Constraints {
        contact_points: Some(surface.clone()),
        planes: vec![PlaneCollider {
            point: Point3::origin(),
            normal: Vector3::z(),
            stiffness: 2e4,
            damping: 20.0,
            friction: 0.0,
        }],
        ..Default::default()
    };
    let mut settings = Settings::new(1.0 / 60.0);
    settings.rayleigh_beta = material.rayleigh_beta;
    settings.solver = Solver::ConjugateGradient { tolerance: 1e-6, max_iterations: 1000, assembled: false };
    let mut integrator = Integrator::new(&cubes, settings, constraints)?;

    // 4. Step and watch the lowest surface point.
    for step in 0..120 {
        let report = integrator.step(&cubes)?;
        if step % 10 == 0 {
            let lowest =
                (0..surface.len()).map(|i| surface.point(integrator.positions(), i).z).fold(Real::MAX, Real::min);
            println!(
                "t = {:.3} s  lowest z = {:.4} m  CG iterations = {:3}  energy = {:.4} J",
                report.time,
                lowest,
                report.iterations,
                report.total_energy()
            );
        }
    }
    Ok(())
}
