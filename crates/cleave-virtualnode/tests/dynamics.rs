//! End to end with the integrator: a hanging column, pinned at its top, is cut through while it
//! swings; afterwards the lower piece is free, so its momentum grows by exactly m·g per unit time
//! (internal forces of a free piece sum to zero), while the upper piece stays attached; and a
//! bent bar, turned and moved away from the origin, spinning freely, keeps its angular momentum.

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real, Vector3};
use cleave_integrator::{Constraints, Integrator, Settings, Solver};
use cleave_testkit::momentum::free_flight;
use cleave_virtualnode::VirtualNodeMesh;

fn pins(mesh: &VirtualNodeMesh) -> Constraints {
    let pinned_dofs = mesh
        .rest_dofs()
        .chunks_exact(3)
        .enumerate()
        .filter(|(_, p)| p[2] >= 0.95)
        .flat_map(|(n, _)| [3 * n, 3 * n + 1, 3 * n + 2])
        .collect();
    Constraints { pinned_dofs, ..Default::default() }
}

fn piece_momentum(mesh: &VirtualNodeMesh, nodes: &[u32], v: &[Real]) -> (Vector3<Real>, Real) {
    let m = mesh.mass().diagonal();
    let mut p = Vector3::zeros();
    let mut mass = 0.0;
    for &n in nodes {
        let i = 3 * n as usize;
        p += Vector3::new(m[i] * v[i], m[i + 1] * v[i + 1], m[i + 2] * v[i + 2]);
        mass += m[i];
    }
    (p, mass)
}

#[test]
fn the_cut_off_end_of_a_hanging_column_falls_freely() {
    let material = Material::new(5e4, 0.3, 1000.0).unwrap().with_damping(0.0, 0.02).unwrap();
    let mut mesh =
        VirtualNodeMesh::from_box(Point3::new(0.0, 0.0, 0.0), Point3::new(0.2, 0.2, 1.0), 0.1, material).unwrap();
    let mut settings = Settings::new(1.0 / 100.0);
    settings.rayleigh_beta = material.rayleigh_beta;
    settings.gravity = Vector3::new(1.0, 0.0, -9.81);
    settings.solver = Solver::Cholesky;
    let mut integrator = Integrator::new(&mesh, settings.clone(), pins(&mesh)).unwrap();
    for _ in 0..20 {
        integrator.step(&mesh).unwrap();
    }
    let change = mesh
        .cut(&CutSurface::Plane { point: Point3::new(0.0, 0.0, 0.43), normal: Vector3::new(0.1, 0.0, 1.0) })
        .unwrap();
    integrator.apply_topology_change(&mesh, &change, pins(&mesh)).unwrap();
    let pieces = mesh.pieces();
    assert_eq!(pieces.len(), 2);
    // The lower piece: the one without pinned nodes.
    let pinned = pins(&mesh).pinned_dofs;
    let lower =
        pieces.iter().find(|p| p.nodes.iter().all(|&n| !pinned.contains(&(3 * n as usize)))).expect("a free piece");
    let (p0, mass) = piece_momentum(&mesh, &lower.nodes, integrator.velocities());
    println!("lower piece: {} nodes, mass {mass:.6} kg (ρV = {:.6})", lower.nodes.len(), lower.mass);
    assert!((mass - lower.mass).abs() < 1e-12 * mass);
    let steps = 15;
    for _ in 0..steps {
        integrator.step(&mesh).unwrap();
    }
    let (p1, _) = piece_momentum(&mesh, &lower.nodes, integrator.velocities());
    let expected = settings.gravity * (mass * steps as Real * settings.time_step);
    let error = (p1 - p0 - expected).norm() / expected.norm();
    println!("momentum change {:?} vs m g t {:?}: relative error {error:.2e}", p1 - p0, expected);
    assert!(error < 1e-8, "{error}");
}

#[test]
fn a_bent_spinning_bar_keeps_its_angular_momentum() {
    // A soft bar bent into an arc, turned about an oblique axis, moved 3 m from the origin,
    // spinning about another oblique axis while it unbends: a stressed body whose element
    // rotations change by 0.1 rad per step, so the rotations frozen at the start of a step
    // differ from those at its end.
    let material = Material::new(2e5, 0.3, 1000.0).unwrap().with_damping(0.0, 0.01).unwrap();
    let mesh = VirtualNodeMesh::from_box(Point3::origin(), Point3::new(0.6, 0.1, 0.1), 0.05, material).unwrap();
    let axis = nalgebra::Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8));
    let turn = nalgebra::Rotation3::from_axis_angle(&axis, 0.9);
    let offset = Vector3::new(2.0, -1.5, 1.8);
    let spin = Vector3::new(-2.0, 4.0, 3.0);
    let rest = mesh.rest_dofs().to_vec();
    let (mut x, mut v) = (rest.clone(), vec![0.0; rest.len()]);
    for k in 0..rest.len() / 3 {
        let r = Vector3::new(rest[3 * k] - 0.3, rest[3 * k + 1] - 0.05, rest[3 * k + 2] - 0.05);
        let bent = r + Vector3::new(0.0, 0.0, 0.4 * r.x * r.x);
        let p = turn * bent + offset;
        let u = spin.cross(&(turn * bent)) + turn * Vector3::new(0.0, 0.3 * r.x, 0.0);
        for a in 0..3 {
            x[3 * k + a] = p[a];
            v[3 * k + a] = u[a];
        }
    }
    for conserve in [true, false] {
        let drift = free_flight(&mesh, (material.rayleigh_beta, conserve), &x, &v, 60);
        println!("conserve {conserve}: {drift:?}");
        // Backward Euler dissipates: the correction must not feed energy in.
        assert!(drift.largest_rise <= 1e-12 * drift.energy.0, "energy rose by {} J in a step", drift.largest_rise);
        assert!(drift.linear < 1e-11, "linear momentum changed by {}", drift.linear);
        if conserve {
            assert!(drift.angular < 1e-11, "angular momentum changed by {}", drift.angular);
        } else {
            // The plain step's frozen rotations lose angular momentum: the test can fail.
            assert!(drift.angular > 1e-6, "the plain step kept the angular momentum: {}", drift.angular);
        }
    }
}
