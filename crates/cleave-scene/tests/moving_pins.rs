//! Moving pins: the held nodes move at the region's velocity (exactly `X + v t` for the held
//! component, free in the others when `components` says so), and a slowly pulled bar stretches
//! uniformly, as the quasi-static solution `u(x) = x / L · u_end` says.

use cleave_core::Real;
use cleave_scene::Simulation;
use cleave_scene::run::parse_scene;
use std::path::Path;

const SCENE: &str = r#"Scene(
    name: "pulled bar",
    object: Box(min: (-0.1, 0.0, 0.0), max: (0.1, 0.04, 0.04)),
    material: (youngs_modulus: 1.0e6, poisson_ratio: 0.3, density: 1000.0, rayleigh_alpha: 0.0, rayleigh_beta: 0.001),
    backend: "voxel",
    settings: { "voxel": (cell_size: 0.02) },
    time_step: 0.005,
    steps: 100,
    gravity: (0.0, 0.0, 0.0),
    solver: Cholesky,
    pins: [
        Region(min: (-0.2, -1.0, -1.0), max: (-0.099, 1.0, 1.0), velocity: (-0.01, 0.0, 0.0), components: (true, false, false)),
        Region(min: (0.099, -1.0, -1.0), max: (0.2, 1.0, 1.0), velocity: (0.01, 0.0, 0.0), components: (true, false, false)),
    ],
)"#;

#[test]
fn pulled_ends_move_at_their_velocity_and_the_bar_stretches_uniformly() {
    let loaded = parse_scene(Path::new("pull.ron"), SCENE).unwrap();
    let mut simulation = Simulation::build(&loaded, None).unwrap();
    while simulation.steps_done() < simulation.total_steps() {
        simulation.step().unwrap();
    }
    let t = 100.0 * 0.005;
    let rest = simulation.body().rest_dofs().to_vec();
    let (x, v) = simulation.state();
    let mut lateral_moved = 0.0_f64;
    let mut quarter = Vec::new();
    for k in (0..x.len()).step_by(3) {
        let (rx, ux) = (rest[k], x[k] - rest[k]);
        if rx.abs() > 0.099 {
            // Held in x: exactly X + v t; free sideways (the ends contract).
            let expected = 0.01 * t * rx.signum();
            assert!((ux - expected).abs() < 1e-12, "end node at {rx}: {ux} vs {expected}");
            assert!((v[k] - 0.01 * rx.signum()).abs() < 1e-12);
            lateral_moved = lateral_moved.max((x[k + 1] - rest[k + 1]).abs().max((x[k + 2] - rest[k + 2]).abs()));
        }
        if (rx.abs() - 0.06).abs() < 1e-9 {
            quarter.push(ux / rx.signum());
        }
    }
    assert!(lateral_moved > 1e-6, "the ends contract sideways: {lateral_moved}");
    // u(0.06) = 0.06 / 0.1 · 5 mm = 3 mm; the moving pins lead the body by one step (0.05 mm).
    let mean: Real = quarter.iter().sum::<Real>() / quarter.len() as Real;
    assert!((mean - 3e-3).abs() < 0.05 * 3e-3, "u(0.06) = {mean}");
}
