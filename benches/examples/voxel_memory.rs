//! Peak memory per voxel at about a million cubes, everything included: builds a box of
//! `n × n × n` cubes (default 100), resting on a ground plane through its bottom nodes, takes a
//! few matrix-free block-Jacobi CG steps, and reads the peak resident set (`VmHWM`) from
//! `/proc/self/status` (Linux).
//!
//! ```text
//! cargo run --release -p cleave-benches --example voxel_memory -- 100 3
//! ```

use cleave_core::{Discretization, Material, Point3, Real, Vector3};
use cleave_integrator::{Constraints, Integrator, PlaneCollider, Preconditioner, Settings, Solver};
use cleave_voxel::VoxelMesh;

fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().map_or(Ok(100), |a| a.parse())?;
    let steps: usize = args.next().map_or(Ok(3), |a| a.parse())?;
    let before = peak_rss_kib().unwrap_or(0);
    let material = Material::new(2e5, 0.3, 1000.0)?.with_damping(0.0, 0.01)?;
    let h = 0.2 / n as Real;
    let mesh = VoxelMesh::from_box(material, Point3::new(0.0, 0.0, 0.01), h, [n, n, n])?;
    // Contact points: the bottom nodes (one embedding row each), as a surface would give.
    let bottom: Vec<Point3<Real>> =
        mesh.rest_dofs().chunks(3).filter(|p| p[2] < 0.01 + 0.5 * h).map(|p| Point3::new(p[0], p[1], p[2])).collect();
    let contact = mesh.embed(&bottom)?;
    let mut settings = Settings::new(1.0 / 60.0);
    settings.rayleigh_beta = 0.01;
    settings.solver = Solver::ConjugateGradient { tolerance: 1e-3, max_iterations: 2000, assembled: false };
    settings.preconditioner = Preconditioner::BlockJacobi;
    let constraints = Constraints {
        contact_points: Some(contact),
        planes: vec![PlaneCollider {
            point: Point3::origin(),
            normal: Vector3::z(),
            stiffness: 2e4,
            damping: 20.0,
            friction: 0.0,
        }],
        ..Default::default()
    };
    let mut integrator = Integrator::new(&mesh, settings, constraints)?;
    for _ in 0..steps {
        let report = integrator.step(&mesh)?;
        println!("step {}: {} CG iterations, {:.2} s", report.step, report.iterations, report.seconds.total());
    }
    let peak = peak_rss_kib().ok_or("no VmHWM in /proc/self/status")?;
    let cubes = mesh.num_cubes();
    println!(
        "{cubes} cubes, {} nodes: peak RSS {:.1} MiB (before building {:.1} MiB) = {:.3} KB per voxel",
        mesh.num_nodes(),
        peak as Real / 1024.0,
        before as Real / 1024.0,
        peak as Real * 1024.0 / 1000.0 / cubes as Real
    );
    Ok(())
}
