//! A damped scene with nothing doing work gains no energy after its cuts, whatever they leave:
//! a stack of slices 1 % of a cell thick, a chip of 1e-6 of a cell's volume cut off a corner
//! (a piece of one element whose nodes all lie outside its material), and random soups. The
//! total energy (kinetic + elastic + gravitational + penalty) after the last cut may never rise
//! above its value then by more than 1 % (the stability criterion of the benchmarks).

use cleave_scene::Simulation;
use cleave_scene::run::parse_scene;
use std::path::Path;

/// A block 0.2 × 0.2 × 0.1 m on the ground, cells of 0.05 m, contact between pieces, the
/// timeline `events` (all at t = 0), 1.2 s of 1/100 s steps.
fn scene(events: &str) -> String {
    format!(
        r#"Scene(
    name: "energy after cuts",
    object: Box(min: (-0.1, -0.1, 0.0), max: (0.1, 0.1, 0.1)),
    material: (youngs_modulus: 5.0e5, poisson_ratio: 0.3, density: 1000.0, rayleigh_alpha: 0.0, rayleigh_beta: 0.01),
    backend: "virtualnode",
    settings: {{ "virtualnode": (cell_size: 0.05) }},
    time_step: 0.01,
    steps: 120,
    gravity: (0.0, 0.0, -9.81),
    solver: Cholesky,
    colliders: [Plane(point: (0.0, 0.0, 0.0), normal: (0.0, 0.0, 1.0), stiffness: 2.0e4, damping: 20.0, friction: 0.5)],
    timeline: [{events}],
)"#
    )
}

/// Runs the scene; returns the pieces, the energy at the first step after the last cut and the
/// largest energy after it, with its step.
fn run(events: &str) -> (usize, f64, f64, u64) {
    let loaded = parse_scene(Path::new("energy.ron"), &scene(events)).unwrap();
    let mut simulation = Simulation::build(&loaded, None).unwrap();
    let mut after = None;
    let mut peak = (f64::NEG_INFINITY, 0);
    while simulation.steps_done() < simulation.total_steps() {
        let report = simulation.step().unwrap();
        if std::env::var("ENERGY_TRACE").is_ok() {
            println!(
                "step {} kinetic {:.5} elastic {:.5} gravity {:.5} penalty {:.5} total {:.5} deepest {:.2e} {:?}",
                report.step,
                report.kinetic_energy,
                report.elastic_energy,
                report.gravitational_energy,
                report.penalty_energy,
                report.total_energy(),
                report.contacts.max_penetration,
                (report.contacts.planes, report.contacts.surface, report.contacts.edges)
            );
        }
        // The cuts are due at the first step; energy is measured from the second on.
        if simulation.steps_done() < 2 {
            continue;
        }
        let e = report.total_energy();
        after.get_or_insert(e);
        if e > peak.0 {
            peak = (e, report.step);
        }
    }
    (simulation.cut_summary().pieces.len(), after.unwrap(), peak.0, peak.1)
}

fn check(name: &str, events: &str, min_pieces: usize) {
    let (pieces, start, peak, step) = run(events);
    let rise = (peak - start) / start.abs();
    println!(
        "{name}: {pieces} pieces, energy after the cuts {start:.6} J, peak {peak:.6} J at step {step} ({:+.3} %)",
        100.0 * rise
    );
    assert!(pieces >= min_pieces, "{name}: {pieces} pieces");
    assert!(rise <= 0.01, "{name}: energy rose by {:.2} % after the cuts", 100.0 * rise);
}

#[test]
fn a_stack_of_slices_one_percent_of_a_cell_thick_gains_no_energy() {
    // Six horizontal planes 0.5 mm apart (1 % of the cell) through the middle of the block.
    let events: String = (0..6)
        .map(|k| {
            format!(
                "Cut(time: 0.0, surface: Plane(point: (0.0, 0.0, {}), normal: (0.0, 0.0, 1.0))),",
                0.0473 + 0.0005 * k as f64
            )
        })
        .collect();
    check("thin stack", &events, 7);
}

#[test]
fn a_chip_of_a_millionth_of_a_cell_gains_no_energy() {
    // The plane x + y + z = ε through the corner (-0.1, -0.1, 0) cuts off a tetrahedron of
    // ε³/6 = 1e-6 h³: one element, all of whose nodes lie outside its material.
    let eps = (6e-6f64).cbrt() * 0.05;
    let point = [-0.1 + eps, -0.1, 0.0];
    let events = format!(
        "Cut(time: 0.0, surface: Plane(point: ({}, {}, {}), normal: (1.0, 1.0, 1.0))),",
        point[0], point[1], point[2]
    );
    check("corner chip", &events, 2);
}

#[test]
fn random_soups_leaving_small_fragments_gain_no_energy() {
    // Twelve random triangles about a cell across (an OBJ soup), then three random planes:
    // fragments of every size, pieces of one element among them. A fixed linear congruential
    // sequence.
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut obj = String::new();
    for t in 0..12 {
        let centre = [-0.1 + 0.2 * next(), -0.1 + 0.2 * next(), 0.1 * next()];
        for _ in 0..3 {
            let p: Vec<f64> = centre.iter().map(|c| c + 0.08 * (next() - 0.5)).collect();
            obj.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
        }
        obj.push_str(&format!("f {} {} {}\n", 3 * t + 1, 3 * t + 2, 3 * t + 3));
    }
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("energy_random_soup.obj");
    std::fs::write(&path, obj).unwrap();
    let mut events = format!("Cut(time: 0.0, surface: Obj(path: {:?})),", path.to_str().unwrap());
    for _ in 0..3 {
        let point = [-0.1 + 0.2 * next(), -0.1 + 0.2 * next(), 0.1 * next()];
        let normal = [next() - 0.5, next() - 0.5, next() - 0.5];
        events.push_str(&format!(
            "Cut(time: 0.0, surface: Plane(point: ({}, {}, {}), normal: ({}, {}, {}))),",
            point[0], point[1], point[2], normal[0], normal[1], normal[2]
        ));
    }
    check("random soup and planes", &events, 4);
}
