//! Contact in the integrator's step on boxes of corotated tetrahedra whose nodes are the contact
//! points (plain embedding rows, no backend; `common/mod.rs`): a block on a slope sticks or
//! slides as Coulomb says, a mesh collider of two triangles is the plane collider, and boxes
//! thrown at each other conserve linear and angular momentum and bounce apart. The tests of
//! contact on cut bodies (halves of a cut block, an unfinished cut, a crack ending inside the
//! material) need a cutting backend and live in `crates/cleave-virtualnode/tests/contact.rs`.

mod common;

use cleave_contact::{Colliders, MeshCollider, PlaneCollider, SurfaceContact};
use cleave_core::{Discretization, Material, Point3, Real, Vector3};
use cleave_integrator::{Constraints, Integrator, Settings, Solver};
use common::{TetBoxes, momentum};

const H: Real = 1.0 / 60.0;

fn settings(gravity: Vector3<Real>) -> Settings {
    let mut s = Settings::new(H);
    s.solver = Solver::Cholesky;
    s.gravity = gravity;
    s.rayleigh_beta = 0.01;
    s
}

fn ground(stiffness: Real, friction: Real) -> PlaneCollider {
    PlaneCollider { point: Point3::origin(), normal: Vector3::z(), stiffness, damping: 0.0, friction }
}

/// Slides a 0.1 m cube on the ground under gravity tilted by 30° (the same as a 30° slope) and
/// returns the x positions of its centre of mass over time.
fn slide(friction: Real) -> Vec<(Real, Real)> {
    let material = Material::new(1e6, 0.3, 1000.0).unwrap();
    let body = TetBoxes::new(&[(Point3::origin(), Point3::new(0.1, 0.1, 0.1))], &material);
    let theta = 30.0_f64.to_radians();
    let gravity = Vector3::new(theta.sin(), 0.0, -theta.cos()) * 9.81;
    let constraints = Constraints {
        contact_points: Some(body.node_points()),
        planes: vec![ground(2e6, friction)],
        ..Default::default()
    };
    let mut integrator = Integrator::new(&body, settings(gravity), constraints).unwrap();
    let m = body.mass().diagonal().to_vec();
    let mut track = Vec::new();
    for _ in 0..90 {
        integrator.step(&body).unwrap();
        let x = integrator.positions();
        let cx = (0..m.len() / 3).map(|k| m[3 * k] * x[3 * k]).sum::<Real>() / body.mass().total();
        track.push((integrator.time(), cx));
    }
    track
}

/// μ = 0.7 holds a block on a 30° slope (tan 30° = 0.577); μ = 0.3 lets it slide with the
/// acceleration g (sin 30° − μ cos 30°) within 5 %.
#[test]
fn a_block_on_a_slope_sticks_or_slides_as_coulomb_says() {
    let g = 9.81;
    let theta = 30.0_f64.to_radians();
    // Placed on the slope at rest, the block first sinks into the penalty layer while friction
    // builds up with the normal force; from 0.5 s on it must not move.
    let stuck = slide(0.7);
    let moved = stuck.last().unwrap().1 - stuck[29].1;
    let sliding = slide(0.3);
    assert!(sliding.last().unwrap().1 - sliding[0].1 > 0.5, "mu = 0.3 must let the block slide");
    // Acceleration by a least-squares parabola through the positions after 0.25 s.
    let samples: Vec<(Real, Real)> = sliding.iter().copied().filter(|s| s.0 >= 0.25).collect();
    let (mut normal, mut rhs) = (nalgebra::Matrix3::<Real>::zeros(), nalgebra::Vector3::<Real>::zeros());
    for &(t, x) in &samples {
        let basis = nalgebra::Vector3::new(1.0, t, t * t);
        normal += basis * basis.transpose();
        rhs += basis * x;
    }
    let fit = normal.try_inverse().unwrap() * rhs;
    let acceleration = 2.0 * fit[2];
    let expected = g * (theta.sin() - 0.3 * theta.cos());
    println!(
        "mu = 0.7: the block moves {moved:.2e} m from 0.5 s to 1.5 s; mu = 0.3: acceleration {acceleration:.4} m/s^2 vs {expected:.4} ({:+.2} %)",
        100.0 * (acceleration / expected - 1.0)
    );
    assert!(moved.abs() < 1e-3, "mu = 0.7 must hold the block: it moved {moved} m");
    assert!((acceleration / expected - 1.0).abs() < 0.05, "sliding acceleration {acceleration} vs {expected}");
}

/// A box thrown sideways onto the ground lands and is slowed by friction, and every node ends
/// where it ends against the plane collider (1e-9 m) when the ground is a mesh collider of two
/// triangles: the mesh's nearest-triangle search, normals and friction are the plane's there.
#[test]
fn a_two_triangle_mesh_collider_is_the_plane_collider() {
    let material = Material::new(5e5, 0.3, 1000.0).unwrap();
    let body = TetBoxes::new(&[(Point3::new(0.0, 0.0, 0.03), Point3::new(0.1, 0.1, 0.13))], &material);
    let run = |mesh_collider: bool| -> Vec<Real> {
        let mut constraints = Constraints { contact_points: Some(body.node_points()), ..Default::default() };
        if mesh_collider {
            let l = 10.0;
            let vertices = vec![
                Point3::new(-l, -l, 0.0),
                Point3::new(l, -l, 0.0),
                Point3::new(l, l, 0.0),
                Point3::new(-l, l, 0.0),
            ];
            constraints
                .meshes
                .push(MeshCollider::new(vertices, vec![[0, 1, 2], [0, 2, 3]], 2e6, 0.0, 0.5, 0.01).unwrap());
        } else {
            constraints.planes.push(ground(2e6, 0.5));
        }
        let mut integrator = Integrator::new(&body, settings(Vector3::new(0.0, 0.0, -9.81)), constraints).unwrap();
        let v: Vec<Real> = body.rest_dofs().chunks_exact(3).flat_map(|_| [0.8, 0.3, 0.0]).collect();
        integrator.set_state(&body, body.rest_dofs().to_vec(), v);
        let mut ground_contacts = 0;
        for _ in 0..60 {
            let r = integrator.step(&body).unwrap();
            ground_contacts += r.contacts.planes + r.contacts.meshes;
        }
        let vx = integrator.velocities().iter().step_by(3).sum::<Real>() / (body.num_nodes() as Real);
        assert!(
            ground_contacts > 0 && vx < 0.7,
            "the box must land and be slowed by friction: {ground_contacts}, {vx}"
        );
        integrator.positions().to_vec()
    };
    let (plane, mesh) = (run(false), run(true));
    let difference = plane.iter().zip(&mesh).map(|(a, b)| (a - b).abs()).fold(0.0, Real::max);
    println!("largest difference of node positions after 1 s: {difference:.2e} m");
    assert!(difference < 1e-9, "{difference}");
}

/// Two 0.2 m boxes 2 cm apart and offset sideways, closing at 2 m/s with no gravity or ground
/// (an oblique impact that sets them spinning), with and without friction: surface contact
/// forces are equal, opposite and on one line, so linear momentum is conserved to rounding;
/// with the step's angular momentum correction (docs/math/corotated-integrator.md, "Angular
/// momentum") so is angular momentum; frictionless, the boxes bounce apart.
#[test]
fn boxes_thrown_at_each_other_conserve_momentum() {
    let material = Material::new(1e7, 0.3, 1000.0).unwrap();
    let body = TetBoxes::new(
        &[(Point3::origin(), Point3::new(0.2, 0.2, 0.2)), (Point3::new(0.22, 0.08, 0.0), Point3::new(0.42, 0.28, 0.2))],
        &material,
    );
    let (x, mut v) = (body.rest_dofs().to_vec(), vec![0.0; body.rest_dofs().len()]);
    for n in body.box_nodes(0) {
        v[3 * n] = 1.0;
        v[3 * n + 2] = 0.1;
    }
    for n in body.box_nodes(1) {
        v[3 * n] = -1.0;
    }
    let box_mass = 1000.0 * 0.2 * 0.2 * 0.2;
    for (friction, conserve) in [(0.0, true), (0.5, true), (0.0, false), (0.5, false)] {
        let surface = SurfaceContact {
            triangles: body.triangles.clone(),
            on_cut: Vec::new(),
            piece: body.piece.clone(),
            stiffness: 1e6,
            damping: 0.0,
            friction,
            thickness: 0.0,
            reach: 0.005,
            edge_contact: true,
        };
        let constraints = Constraints {
            contact_points: Some(body.node_points()),
            surface_contact: Some(surface),
            ..Default::default()
        };
        assert!(constraints.colliders().surface.is_some());
        let mut step_settings = settings(Vector3::zeros());
        step_settings.conserve_angular_momentum = conserve;
        let mut integrator = Integrator::new(&body, step_settings, constraints).unwrap();
        integrator.set_state(&body, x.clone(), v.clone());
        let (p0, l0) = momentum(&body, &x, &v);
        let (mut contacts, mut worst_p, mut worst_l): (usize, Real, Real) = (0, 0.0, 0.0);
        for _ in 0..30 {
            let report = integrator.step(&body).unwrap();
            contacts = contacts.max(report.contacts.surface + report.contacts.edges);
            let (p, l) = momentum(&body, integrator.positions(), integrator.velocities());
            worst_p = worst_p.max((p - p0).norm() / p0.norm().max(box_mass));
            worst_l = worst_l.max((l - l0).norm() / l0.norm());
        }
        let (x_end, v_end) = (integrator.positions(), integrator.velocities());
        let mean = |b: usize, of: &[Real]| body.box_nodes(b).map(|n| of[3 * n]).sum::<Real>() / 8.0;
        let (left_x, right_x, left_vx, right_vx) = (mean(0, x_end), mean(1, x_end), mean(0, v_end), mean(1, v_end));
        println!(
            "mu = {friction}, correction {conserve}: up to {contacts} contacts; centres at x = {left_x:.3} and {right_x:.3} m moving at {left_vx:+.3} and {right_vx:+.3} m/s; linear momentum changed by {worst_p:.1e}, angular by {worst_l:.1e}"
        );
        assert!(contacts > 0, "the boxes must meet");
        assert!(worst_p < 1e-9, "linear momentum changed by {worst_p}");
        if friction == 0.0 {
            assert!(left_x < right_x && left_vx < right_vx, "the boxes must bounce apart, not pass through");
        }
        // The plain linearly implicit step changes the angular momentum (the elastic forces are
        // linearized with the start-of-step rotations of spinning boxes; friction pairs act on
        // two points the penalty holds apart); the correction removes both.
        if conserve {
            assert!(worst_l < 1e-9, "angular momentum changed by {worst_l}");
        } else {
            assert!(worst_l > 1e-5, "the plain step should change the angular momentum: {worst_l}");
        }
    }
}

/// The borrowed view a detection reads names what the constraints hold.
#[test]
fn constraints_lend_their_colliders() {
    let material = Material::new(1e6, 0.3, 1000.0).unwrap();
    let body = TetBoxes::new(&[(Point3::origin(), Point3::new(0.1, 0.1, 0.1))], &material);
    let constraints =
        Constraints { contact_points: Some(body.node_points()), planes: vec![ground(1.0, 0.0)], ..Default::default() };
    let colliders: Colliders<'_> = constraints.colliders();
    assert_eq!(colliders.points.map(|p| p.len()), Some(8));
    assert_eq!(colliders.planes.len(), 1);
    assert!(colliders.meshes.is_empty() && colliders.surface.is_none());
    assert_eq!(body.triangles.len(), 12, "two triangles per box face");
}
