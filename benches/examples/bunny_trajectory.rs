//! The bunny drop without the scene crate, for solver studies: steps it with a chosen solver,
//! CG tolerance and ground stiffness, prints the summary (lowest and final height, bounce, rest,
//! iterations, solve time) and optionally writes the per-step trajectory as CSV so two runs can be
//! compared (`--csv FILE`, `--compare FILE`).
//!
//! ```text
//! cargo run --release -p cleave-benches --example bunny_trajectory -- \
//!     --solver two-level --tolerance 1e-3 --stiffness 2e5 --steps 240 --cubes 10000
//! ```

use cleave_benches::bunny_voxels;
use cleave_core::{Discretization, Point3, Real, Vector3};
use cleave_integrator::{Constraints, Integrator, PlaneCollider, Preconditioner, Settings, Solver};
use std::time::Instant;

struct Args {
    solver: String,
    tolerance: Real,
    stiffness: Real,
    damping: Real,
    steps: usize,
    cubes: usize,
    csv: Option<String>,
    compare: Option<String>,
    coarsening: i32,
}

fn parse() -> Result<Args, String> {
    let mut args = Args {
        solver: "two-level".into(),
        tolerance: 1e-3,
        stiffness: 2e5,
        damping: 20.0,
        steps: 240,
        cubes: 10_000,
        csv: None,
        compare: None,
        coarsening: 2,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let value = it.next().ok_or_else(|| format!("{flag} needs a value"))?;
        let number = || value.parse::<Real>().map_err(|e| format!("{flag} {value}: {e}"));
        match flag.as_str() {
            "--solver" => args.solver = value.clone(),
            "--tolerance" => args.tolerance = number()?,
            "--stiffness" => args.stiffness = number()?,
            "--damping" => args.damping = number()?,
            "--steps" => args.steps = number()? as usize,
            "--cubes" => args.cubes = number()? as usize,
            "--csv" => args.csv = Some(value.clone()),
            "--compare" => args.compare = Some(value.clone()),
            "--coarsening" => args.coarsening = number()? as i32,
            _ => return Err(format!("unknown flag {flag}")),
        }
    }
    Ok(args)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse()?;
    let (mut mesh, surface) = bunny_voxels(args.cubes);
    mesh.set_coarsening(args.coarsening);
    let contact = mesh.embed(&surface.vertices)?;
    let mut settings = Settings::new(1.0 / 60.0);
    settings.rayleigh_beta = 0.01;
    let cg = |assembled| Solver::ConjugateGradient { tolerance: args.tolerance, max_iterations: 5000, assembled };
    match args.solver.as_str() {
        "cholesky" => settings.solver = Solver::Cholesky,
        "jacobi" | "jacobi-assembled" => {
            settings.solver = cg(args.solver == "jacobi-assembled");
            settings.preconditioner = Preconditioner::BlockJacobi;
        }
        "two-level" => {
            settings.solver = cg(false);
            settings.preconditioner = Preconditioner::TwoLevel;
        }
        other => return Err(format!("unknown solver {other} (cholesky, jacobi, jacobi-assembled, two-level)").into()),
    }
    let constraints = Constraints {
        contact_points: Some(contact.clone()),
        planes: vec![PlaneCollider {
            point: Point3::origin(),
            normal: Vector3::z(),
            stiffness: args.stiffness,
            damping: args.damping,
            friction: 0.0,
        }],
        ..Default::default()
    };
    let clock = Instant::now();
    let mut integrator = Integrator::new(&mesh, settings, constraints)?;
    let setup = clock.elapsed().as_secs_f64();
    {
        let mut out = vec![0.0; 3 * mesh.num_nodes()];
        let clock = Instant::now();
        for _ in 0..50 {
            mesh.add_stiffness_action(integrator.rotations(), mesh.rest_dofs(), 1.0, &mut out);
        }
        println!("stiffness action: {:.3} ms per call", clock.elapsed().as_secs_f64() * 1e3 / 50.0);
    }
    if let Some((dofs, nnz)) = integrator.coarse_stats() {
        println!("coarse space: {dofs} DOFs, factor {nnz} nonzeros");
    }
    let lowest_z = |x: &[Real]| (0..contact.len()).map(|i| contact.point(x, i).z).fold(Real::MAX, Real::min);
    let mut rows = vec![(lowest_z(integrator.positions()), integrator.energies(&mesh).total_energy(), 0.0)];
    let (mut iterations, mut max_iterations, mut solve, mut total) = (0, 0, 0.0, 0.0);
    let mut phases = [0.0; 6];
    for _ in 0..args.steps {
        let report = integrator.step(&mesh)?;
        iterations += report.iterations;
        max_iterations = max_iterations.max(report.iterations);
        solve += report.seconds.solve;
        total += report.seconds.total();
        let p = &report.seconds;
        for (sum, value) in
            phases.iter_mut().zip([p.rotations, p.assembly, p.solve, p.contact, p.contact_forces, p.rest])
        {
            *sum += value;
        }
        rows.push((lowest_z(integrator.positions()), report.total_energy(), report.kinetic_energy));
        if std::env::var_os("VERBOSE").is_some() {
            println!(
                "step {} iterations {} active contacts {} lowest z {:.5} kinetic {:.3e} residual {:.2e} mean v {:?}",
                report.step,
                report.iterations,
                report.active_contacts,
                rows.last().map_or(0.0, |r| r.0),
                report.kinetic_energy,
                report.residual,
                {
                    let v = integrator.velocities();
                    let n = (v.len() / 3) as Real;
                    [0, 1, 2].map(|a| format!("{:.2e}", v.iter().skip(a).step_by(3).sum::<Real>() / n))
                }
            );
        }
    }
    let lowest = rows.iter().map(|r| r.0).fold(Real::MAX, Real::min);
    let impact = rows.iter().position(|r| r.0 <= lowest + 1e-12).unwrap_or(0);
    let bounce = rows[impact..].iter().map(|r| r.0).fold(Real::MIN, Real::max);
    let peak_kinetic = rows.iter().map(|r| r.2).fold(0.0, Real::max);
    let last = rows.last().copied().unwrap_or_default();
    let steps = args.steps.max(1) as Real;
    println!(
        "{} cubes, {} DOFs, solver {} tol {:e}, ground k {:e} c {}: setup {:.3} s",
        mesh.num_cubes(),
        3 * mesh.num_nodes(),
        args.solver,
        args.tolerance,
        args.stiffness,
        args.damping,
        setup
    );
    println!(
        "lowest z {:.4} m at step {impact}, bounce to {:.4} m, final z {:.4} m, kinetic peak {:.3e} final {:.3e} J, energy {:.4} -> {:.4} J",
        lowest, bounce, last.0, peak_kinetic, last.2, rows[0].1, last.1
    );
    println!(
        "iterations/step {:.1} (max {max_iterations}), solve {:.2} ms/step, step {:.2} ms ({:.1} steps/s)",
        iterations as Real / steps,
        1e3 * solve / steps,
        1e3 * total / steps,
        steps / total
    );
    println!(
        "per step [ms]: rotations {:.2}, assembly {:.2}, solve {:.2}, contact {:.2}, contact forces {:.2}, rest {:.2}",
        1e3 * phases[0] / steps,
        1e3 * phases[1] / steps,
        1e3 * phases[2] / steps,
        1e3 * phases[3] / steps,
        1e3 * phases[4] / steps,
        1e3 * phases[5] / steps
    );
    if let Some(path) = &args.csv {
        let text: String = rows.iter().map(|r| format!("{:.9e},{:.9e},{:.9e}\n", r.0, r.1, r.2)).collect();
        std::fs::write(path, text)?;
    }
    if let Some(path) = &args.compare {
        let text = std::fs::read_to_string(path)?;
        let (mut dz, mut de) = (0.0 as Real, 0.0 as Real);
        for (line, r) in text.lines().zip(&rows) {
            let values: Vec<Real> = line.split(',').filter_map(|v| v.parse().ok()).collect();
            if values.len() == 3 {
                dz = dz.max((values[0] - r.0).abs());
                de = de.max((values[1] - r.1).abs());
            }
        }
        println!("vs {path}: max |Δ lowest z| {dz:.3e} m, max |Δ total energy| {de:.3e} J");
    }
    Ok(())
}
