//! Library use of the virtual node backend without the scene crate: load the bunny, carve it out
//! of a BCC lattice, drop it on the ground, cut it with a plane while it moves, and keep
//! stepping. Prints pieces, volume drift and milliseconds per cut.
//!
//! `cargo run -p cleave-virtualnode --release --example bunny_cut [h]` (lattice spacing in m,
//! default 0.008).

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real, Vector3};
use cleave_geometry::TriangleMesh;
use cleave_integrator::{Constraints, Integrator, PlaneCollider, Settings, Solver};
use cleave_virtualnode::VirtualNodeMesh;
use std::io::BufReader;
use std::time::Instant;

fn constraints(mesh: &VirtualNodeMesh, surface: &TriangleMesh) -> Result<Constraints, Box<dyn std::error::Error>> {
    // The bunny's own vertices collide with the ground (re-embedded after every cut: each lies in
    // exactly one region).
    Ok(Constraints {
        contact_points: Some(mesh.embed(&surface.vertices)?),
        planes: vec![PlaneCollider {
            point: Point3::origin(),
            normal: Vector3::z(),
            stiffness: 2e4,
            damping: 20.0,
            friction: 0.0,
        }],
        ..Default::default()
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let h: Real = std::env::args().nth(1).map(|a| a.parse()).transpose()?.unwrap_or(0.008);
    // 1. The bunny, scaled to 0.2 m, turned z up, 0.05 m above the ground.
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/meshes/bunny.obj");
    let mesh = TriangleMesh::from_obj_reader(&mut BufReader::new(std::fs::File::open(path)?))?;
    let mesh = mesh.transformed(|p| Point3::new(0.02 * p.x, -0.02 * p.z, 0.02 * p.y));
    let lift = 0.05 - mesh.aabb().0.z;
    let mesh = mesh.transformed(|p| p + Vector3::new(0.0, 0.0, lift));
    let exact_volume = mesh.signed_volume();

    // 2. Carve it out of the lattice: the surface is the first cut.
    let material = Material::new(2e5, 0.3, 1000.0)?.with_damping(0.0, 0.01)?;
    let start = Instant::now();
    let mut body = VirtualNodeMesh::carve(&mesh, h, material)?;
    if std::env::var("UNIFORM").is_ok() {
        body.set_mass_lumping(cleave_virtualnode::MassLumping::Uniform);
    }
    println!(
        "carved {} surface triangles at h = {h} m in {:.0} ms: {} lattice tets, {} duplicates, {} nodes, volume {:.6e} m³ (surface encloses {:.6e}, relative difference {:.1e})",
        mesh.triangles.len(),
        start.elapsed().as_secs_f64() * 1e3,
        body.num_lattice_tets(),
        body.num_duplicates(),
        body.num_nodes(),
        body.volume(),
        exact_volume,
        (body.volume() - exact_volume).abs() / exact_volume
    );

    // A blade swept in ten increments (each a two-triangle strip in rest space), as a scene
    // runner hands them over frame by frame; measured on a copy, the run below uses planes.
    {
        let mut sweep = VirtualNodeMesh::carve(&mesh, h, material)?;
        let (lo, hi) = mesh.aabb();
        let (x, z0, z1) = (0.5 * (lo.x + hi.x), lo.z - 0.01, hi.z + 0.01);
        let mut times = Vec::new();
        for i in 0..10 {
            let y0 = lo.y - 0.01 + (hi.y - lo.y + 0.02) * i as Real / 10.0;
            let y1 = lo.y - 0.01 + (hi.y - lo.y + 0.02) * (i + 1) as Real / 10.0;
            let (a, b, c, d) = (
                Point3::new(x, y0, z0),
                Point3::new(x, y1, z0),
                Point3::new(x, y1, z1),
                Point3::new(x + 0.002, y0, z1),
            );
            let start = Instant::now();
            sweep.cut(&CutSurface::Triangles(vec![[a, b, c], [a, c, d]]))?;
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(|a, b| a.total_cmp(b));
        println!(
            "blade sweep in 10 strips: median {:.1} ms, max {:.1} ms per cut; {} pieces",
            times[5],
            times[9],
            sweep.pieces().len()
        );
    }

    // 3. Step it with the integrator.
    let mut settings = Settings::new(1.0 / 60.0);
    settings.rayleigh_beta = material.rayleigh_beta;
    settings.solver = Solver::ConjugateGradient { tolerance: 1e-6, max_iterations: 2000, assembled: true };
    let mut integrator = Integrator::new(&body, settings, constraints(&body, &mesh)?)?;
    let volume0 = body.volume();
    let (lo, hi) = mesh.aabb();
    let centre = nalgebra::center(&lo, &hi);
    for step in 0..90 {
        // 4. Cut in rest space: a vertical plane at step 30, a slanted one at step 60.
        let cut = match step {
            30 => Some(CutSurface::Plane { point: centre, normal: Vector3::new(1.0, 0.2, 0.0) }),
            60 => Some(CutSurface::Plane {
                point: centre + Vector3::new(0.0, 0.02, 0.0),
                normal: Vector3::new(0.1, 1.0, 0.3),
            }),
            _ => None,
        };
        if let Some(cut) = cut {
            let start = Instant::now();
            let change = body.cut(&cut)?;
            let cut_ms = start.elapsed().as_secs_f64() * 1e3;
            let start = Instant::now();
            integrator.apply_topology_change(&body, &change, constraints(&body, &mesh)?)?;
            let rebuild_ms = start.elapsed().as_secs_f64() * 1e3;
            let pieces = body.pieces();
            println!(
                "cut at step {step}: {:.1} ms (touched {} duplicates) + {:.1} ms integrator rebuild → {} duplicates, {} nodes, {} pieces (volumes {:?} cm³), volume drift {:.1e}",
                cut_ms,
                body.last_cut().touched,
                rebuild_ms,
                body.num_duplicates(),
                body.num_nodes(),
                pieces.len(),
                pieces.iter().map(|p| (p.volume * 1e6 * 10.0).round() / 10.0).collect::<Vec<_>>(),
                (body.volume() - volume0).abs() / volume0
            );
        }
        let report = integrator.step(&body)?;
        if step % 15 == 0 {
            println!(
                "t = {:.3} s  CG {:3}  step {:.1} ms (rotations {:.1}, assembly {:.1}, solve {:.1}, rest {:.1})  energy = {:.4} J  inverted = {}",
                report.time,
                report.iterations,
                report.seconds.total() * 1e3,
                report.seconds.rotations * 1e3,
                report.seconds.assembly * 1e3,
                report.seconds.solve * 1e3,
                report.seconds.rest * 1e3,
                report.total_energy(),
                report.inverted_elements
            );
        }
    }
    Ok(())
}
