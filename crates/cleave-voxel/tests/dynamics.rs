//! The corotated implicit integrator driving voxel meshes: exact free fall, conservation of
//! momentum, bounded energy, agreement of the three solver paths, contact, and step errors.

use cleave_core::{Discretization, Material, Point3, Real, Vector3};
use cleave_integrator::{Constraints, Integrator, PlaneCollider, Preconditioner, Settings, Solver, StepErrorKind};
use cleave_voxel::VoxelMesh;

fn block(material: Material) -> VoxelMesh {
    VoxelMesh::from_box(material, Point3::new(0.0, 0.0, 1.0), 0.1, [4, 3, 2]).unwrap()
}

const SOLVERS: [Solver; 3] = [
    Solver::Cholesky,
    Solver::ConjugateGradient { tolerance: 1e-10, max_iterations: 500, assembled: false },
    Solver::ConjugateGradient { tolerance: 1e-10, max_iterations: 500, assembled: true },
];

#[test]
fn free_fall_follows_the_discrete_backward_euler_trajectory() {
    let mesh = block(Material::new(1e5, 0.3, 1000.0).unwrap());
    for solver in SOLVERS {
        let mut settings = Settings::new(0.01);
        settings.solver = solver;
        let mut integrator = Integrator::new(&mesh, settings, Constraints::default()).unwrap();
        let steps = 50;
        for _ in 0..steps {
            integrator.step(&mesh).unwrap();
        }
        // v_n = n h g, x_n = x_0 + h² g n(n+1)/2: translation is in K's null space.
        let drop = 9.81 * 0.01 * 0.01 * (steps * (steps + 1)) as Real / 2.0;
        for (x, x0) in integrator.positions().chunks(3).zip(mesh.rest_dofs().chunks(3)) {
            assert!((x[2] - (x0[2] - drop)).abs() < 1e-9, "{solver:?}: {} vs {}", x[2], x0[2] - drop);
            assert!((x[0] - x0[0]).abs() < 1e-9);
        }
    }
}

fn stretched_state(mesh: &VoxelMesh) -> (Vec<Real>, Vec<Real>) {
    let x: Vec<Real> = mesh.rest_dofs().chunks(3).flat_map(|p| [1.3 * p[0], p[1], 0.9 * p[2] + 0.2 * p[0]]).collect();
    let v: Vec<Real> = mesh.rest_dofs().chunks(3).flat_map(|p| [0.1, -p[2], p[1]]).collect();
    (x, v)
}

#[test]
fn momentum_is_conserved_and_energy_stays_bounded_without_gravity() {
    let mesh = block(Material::new(1e5, 0.3, 1000.0).unwrap());
    for solver in SOLVERS {
        let mut settings = Settings::new(1.0 / 60.0);
        settings.gravity = Vector3::zeros();
        settings.solver = solver;
        let mut integrator = Integrator::new(&mesh, settings, Constraints::default()).unwrap();
        let (x, v) = stretched_state(&mesh);
        integrator.set_state(&mesh, x, v);
        let momentum = |v: &[Real]| {
            let m = mesh.mass().diagonal();
            Vector3::<Real>::from_fn(|a, _| (0..v.len() / 3).map(|n| m[3 * n + a] * v[3 * n + a]).sum::<Real>())
        };
        let p0 = momentum(integrator.velocities());
        let e0 = integrator.energies(&mesh).total_energy();
        let mut last = e0;
        for _ in 0..120 {
            let report = integrator.step(&mesh).unwrap();
            last = report.total_energy();
            assert!(last <= 1.01 * e0, "{solver:?}: energy grew from {e0} to {last} at step {}", report.step);
        }
        let p = momentum(integrator.velocities());
        assert!((p - p0).norm() < 1e-8 * (p0.norm() + 1.0), "{solver:?}: momentum {p0} -> {p}");
        // Backward Euler dissipates: two seconds of vibration lose a good part of the energy.
        assert!(last < 0.9 * e0, "{solver:?}: {e0} -> {last}");
    }
}

#[test]
fn cholesky_and_both_cg_paths_agree_on_a_deformed_step() {
    let mesh = block(Material::new(1e6, 0.45, 1000.0).unwrap().with_damping(0.1, 0.01).unwrap());
    let pinned: Vec<usize> =
        (0..mesh.num_nodes()).filter(|&n| mesh.node_coords()[n][0] == 0).flat_map(|n| 3 * n..3 * n + 3).collect();
    let mut results = Vec::new();
    for solver in SOLVERS {
        let mut settings = Settings::new(1.0 / 30.0);
        settings.solver = solver;
        settings.rayleigh_alpha = 0.1;
        settings.rayleigh_beta = 0.01;
        let constraints = Constraints { pinned_dofs: pinned.clone(), ..Default::default() };
        let mut integrator = Integrator::new(&mesh, settings, constraints).unwrap();
        let (x, v) = stretched_state(&mesh);
        integrator.set_state(&mesh, x, v);
        for _ in 0..3 {
            integrator.step(&mesh).unwrap();
        }
        results.push(integrator.velocities().to_vec());
    }
    let scale = results[0].iter().map(|v| v * v).sum::<Real>().sqrt();
    for other in &results[1..] {
        let difference = results[0].iter().zip(other).map(|(a, b)| (a - b).powi(2)).sum::<Real>().sqrt();
        assert!(difference < 1e-7 * scale, "solver paths differ by {difference} (scale {scale})");
    }
    // and pinned DOFs never moved
    assert!(pinned.iter().all(|&d| results[0][d] == 0.0));
}

#[test]
fn a_block_dropped_on_a_plane_comes_to_rest_on_it() {
    let material = Material::new(1e5, 0.3, 1000.0).unwrap();
    let mesh = block(material);
    // contact points: every node (their rows are single weights)
    let points: Vec<Point3<Real>> = mesh.rest_dofs().chunks(3).map(|p| Point3::new(p[0], p[1], p[2])).collect();
    let contact_points = mesh.embed(&points).unwrap();
    let stiffness = 1e5;
    let constraints = Constraints {
        contact_points: Some(contact_points),
        planes: vec![PlaneCollider {
            point: Point3::new(0.0, 0.0, 0.5),
            normal: Vector3::z(),
            stiffness,
            damping: 50.0,
            friction: 0.0,
        }],
        ..Default::default()
    };
    let mut settings = Settings::new(1.0 / 60.0);
    settings.rayleigh_beta = 0.01;
    let mut integrator = Integrator::new(&mesh, settings, constraints).unwrap();
    let mut touched = false;
    for _ in 0..300 {
        let report = integrator.step(&mesh).unwrap();
        touched |= report.active_contacts > 0;
    }
    assert!(touched);
    // At rest on the plane (k = 1e5 N/m per contact point, every node a contact point).
    let speed = integrator.velocities().iter().map(|v| v.abs()).fold(0.0, Real::max);
    assert!(speed < 1e-6, "still moving at {speed} m/s");
    let weight = mesh.mass().total() * 9.81;
    let bottom: Vec<usize> = (0..mesh.num_nodes()).filter(|&n| mesh.node_coords()[n][2] == 0).collect();
    assert_eq!(integrator.energies(&mesh).active_contacts, bottom.len(), "exactly the bottom nodes touch");
    let x = integrator.positions();
    let depth = |n: usize| 0.5 - x[3 * n + 2];
    // Equilibrium: the springs carry the weight, k Σ depth = M g, so the mean sag of the 20
    // bottom nodes is M g / (20 k) = 1.18e-4 m (zero sag carries nothing).
    let carried = stiffness * bottom.iter().map(|&n| depth(n)).sum::<Real>();
    println!("weight {weight:.6} N, carried by the contacts {carried:.6} N");
    assert!((carried / weight - 1.0).abs() < 1e-6, "contacts carry {carried} N of {weight} N");
    // How it is shared: a contact spring (1e5 N/m) is ten times stiffer than a cube (E h = 1e4
    // N/m), so the block presses on the plane with its uniform weight per area M g / A and each
    // bottom node takes its tributary area (corner ¼, edge ½, interior 1 cell face of the 4 × 3
    // faces): depth = share · M g / (12 k), 1.96e-4 m for an interior node. Measured: corners
    // −7.6 %, edges −2.7 … +0.4 %, interior +1.9 … +4.3 % from that.
    let cells = [4, 3];
    let per_face = weight / (cells[0] * cells[1]) as Real / stiffness;
    for &n in &bottom {
        let c = mesh.node_coords()[n];
        let on_edges = (0..2).filter(|&a| c[a] == 0 || c[a] == cells[a]).count();
        let share = [1.0, 0.5, 0.25][on_edges];
        let expected = share * per_face;
        println!("node {c:?}: depth {:.4e} m, tributary estimate {expected:.4e} m", depth(n));
        assert!(
            (depth(n) / expected - 1.0).abs() < 0.15,
            "node {c:?} sags {:.4e} m, its tributary share predicts {expected:.4e} m",
            depth(n)
        );
    }
}

#[test]
fn failures_are_step_errors_not_panics() {
    let mesh = block(Material::new(1e5, 0.3, 1000.0).unwrap());
    let mut settings = Settings::new(1.0 / 60.0);
    settings.solver = Solver::ConjugateGradient { tolerance: 1e-12, max_iterations: 1, assembled: false };
    let mut integrator = Integrator::new(&mesh, settings.clone(), Constraints::default()).unwrap();
    let (x, v) = stretched_state(&mesh);
    integrator.set_state(&mesh, x.clone(), v.clone());
    let error = integrator.step(&mesh).unwrap_err();
    assert_eq!(error.step, 0);
    assert!(matches!(error.kind, StepErrorKind::CgNotConverged { iterations: 1, .. }), "{error}");

    settings.solver = Solver::Cholesky;
    let mut integrator = Integrator::new(&mesh, settings, Constraints::default()).unwrap();
    integrator.step(&mesh).unwrap();
    let mut bad = v;
    bad[7] = Real::NAN;
    integrator.set_state(&mesh, x, bad);
    let error = integrator.step(&mesh).unwrap_err();
    assert_eq!(error.step, 1);
    assert!(matches!(error.kind, StepErrorKind::NotFinite { .. }), "{error}");
    assert!(error.to_string().starts_with("step 1:"));
}

/// Mean CG iterations a step of a block settling on the ground and resting there (two-level
/// preconditioner, the bunny scene's tolerance), and how often the coarse operator was
/// factorized again for the contacts.
fn resting_iterations() -> (Real, usize, Real) {
    // 12 × 12 × 4 cubes of 2.5 cm, E and the ground as in scenes/bunny_drop_voxel.ron, placed
    // 1 mm above the ground.
    let mesh =
        VoxelMesh::from_box(Material::new(2e5, 0.3, 1000.0).unwrap(), Point3::new(0.0, 0.0, 0.001), 0.025, [12, 12, 4])
            .unwrap();
    let points: Vec<Point3<Real>> = mesh.rest_dofs().chunks(3).map(|p| Point3::new(p[0], p[1], p[2])).collect();
    let constraints = Constraints {
        contact_points: Some(mesh.embed(&points).unwrap()),
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
    settings.solver = Solver::ConjugateGradient { tolerance: 1e-3, max_iterations: 1000, assembled: false };
    settings.preconditioner = Preconditioner::TwoLevel;
    settings.rayleigh_beta = 0.01;
    let mut integrator = Integrator::new(&mesh, settings, constraints).unwrap();
    let mut at_rest = 0;
    for step in 0..120 {
        let report = integrator.step(&mesh).unwrap();
        if step >= 60 {
            at_rest += report.iterations;
        }
    }
    let lowest = integrator.positions().chunks(3).map(|p| p[2]).fold(Real::INFINITY, Real::min);
    (at_rest as Real / 60.0, integrator.coarse_refreshes().unwrap(), lowest)
}

#[test]
fn a_block_resting_on_the_ground_needs_few_cg_iterations_with_its_contacts_in_the_coarse_operator() {
    // The penalty terms h²k (5.6 kg) of the 169 contacts under the block are about 700 times
    // the mass of a node on its bottom;
    // a coarse operator without them needed 16 iterations a step at rest on the voxel bunny
    // (docs/results/voxel-bench.md) and 4.8 on this block; with them 1.2.
    let (iterations, refreshes, lowest) = resting_iterations();
    println!(
        "{iterations:.2} CG iterations a step at rest, coarse operator factorized again {refreshes} times, lowest z {lowest:.2e} m"
    );
    // Resting on the ground: the penalty sag m g / (n k) = 88 N / (169 · 2e4 N/m) is 0.026 mm.
    assert!(lowest < 0.0 && lowest > -1e-4, "lowest point {lowest}");
    assert!((1..=10).contains(&refreshes), "{refreshes} refactorizations");
    assert!(iterations <= 2.5, "{iterations} iterations a step at rest");
}
