//! Timeline cuts applied ahead to a copy of the body, off the step's thread, give the run that
//! cutting each one when due gives, bit for bit; a blade acting before a cut keeps it from
//! being prepared on a body the blade will still change, and a copy another cut made stale is
//! not used.

use cleave_scene::Simulation;
use cleave_scene::run::parse_scene;
use std::path::Path;

/// A block on the ground, with gravity and contact between the pieces (so the state at each
/// cut is not the rest state), `steps` of 0.01 s and the timeline `events`.
fn scene(steps: u32, events: &str) -> String {
    format!(
        r#"Scene(
    name: "cut ahead",
    object: Box(min: (-0.1, -0.1, 0.0), max: (0.1, 0.1, 0.2)),
    material: (youngs_modulus: 1.0e6, poisson_ratio: 0.3, density: 1000.0, rayleigh_alpha: 0.0, rayleigh_beta: 0.01),
    backend: "virtualnode",
    settings: {{ "virtualnode": (cell_size: 0.05) }},
    time_step: 0.01,
    steps: {steps},
    gravity: (0.0, 0.0, -9.81),
    solver: Cholesky,
    colliders: [Plane(point: (0.0, 0.0, 0.0), normal: (0.0, 0.0, 1.0), stiffness: 1.0e5, damping: 20.0, friction: 0.5)],
    contact: Some((stiffness: 1.0e5, damping: 20.0, friction: 0.5)),
    timeline: [{events}],
)"#
    )
}

/// A plane, then a blade, then a plane crossing both.
const PLANE_BLADE_PLANE: &str = "
        Cut(time: 0.05, surface: Plane(point: (0.0, 0.0, 0.11), normal: (0.0, 0.0, 1.0))),
        Blade(start: 0.08, end: 0.12, polygon: [(0.03, -0.3, 0.3), (0.03, 0.3, 0.3), (0.03, 0.3, 0.25), (0.03, -0.3, 0.25)], path: [(time: 0.08), (time: 0.12, translation: (0.0, 0.0, -0.12))]),
        Cut(time: 0.17, surface: Plane(point: (0.0, 0.013, 0.0), normal: (0.2, 1.0, 0.1))),";

/// Two planes due in the same step, the one listed first a hair later than the other: the
/// later-listed one is prepared (it is the earliest) but the first-listed one changes the body
/// before it, so its copy is stale and must not be used; then a third plane, prepared and used.
const SAME_STEP: &str = "
        Cut(time: 0.0500000001, surface: Plane(point: (0.0, 0.0, 0.11), normal: (0.0, 0.0, 1.0))),
        Cut(time: 0.05, surface: Plane(point: (0.013, 0.0, 0.0), normal: (1.0, 0.1, 0.0))),
        Cut(time: 0.1, surface: Plane(point: (0.0, 0.013, 0.0), normal: (0.2, 1.0, 0.1))),";

/// Surface points after every step, the pieces and how many changes were prepared ahead.
fn run(cut_ahead: bool) -> (Vec<Vec<[u64; 3]>>, usize, usize, usize) {
    run_scene(&scene(24, PLANE_BLADE_PLANE), cut_ahead)
}

fn run_scene(scene: &str, cut_ahead: bool) -> (Vec<Vec<[u64; 3]>>, usize, usize, usize) {
    let loaded = parse_scene(Path::new("cut_ahead.ron"), scene).unwrap();
    let mut simulation = Simulation::build(&loaded, None).unwrap();
    simulation.set_cut_ahead(cut_ahead);
    let mut frames = Vec::new();
    while simulation.steps_done() < simulation.total_steps() {
        simulation.step().unwrap();
        frames.push(simulation.surface().iter().map(|p| [p.x, p.y, p.z].map(f64::to_bits)).collect());
    }
    let summary = simulation.cut_summary();
    (frames, summary.pieces.len(), summary.changes, summary.prepared)
}

#[test]
fn cuts_made_ahead_give_the_same_run_bit_for_bit() {
    let (inline, pieces, changes, prepared) = run(false);
    assert_eq!(prepared, 0);
    assert!(pieces >= 4, "two planes and a blade leave at least four pieces, got {pieces}");
    let (ahead, pieces_ahead, changes_ahead, prepared_ahead) = run(true);
    assert_eq!((pieces_ahead, changes_ahead), (pieces, changes));
    // Both planes are prepared ahead: the first from the first step on, the second once the
    // blade has ended (the blade's own strips are cut when due).
    assert_eq!(prepared_ahead, 2, "{changes} changes");
    for (step, (a, b)) in ahead.iter().zip(&inline).enumerate() {
        assert!(a == b, "surfaces differ after step {step}");
    }
}

#[test]
fn a_copy_another_cut_made_stale_is_not_used() {
    let text = scene(16, SAME_STEP);
    let (inline, pieces, changes, _) = run_scene(&text, false);
    assert_eq!(changes, 3, "three planes cut");
    let (ahead, pieces_ahead, changes_ahead, prepared) = run_scene(&text, true);
    assert_eq!((pieces_ahead, changes_ahead), (pieces, changes));
    assert_eq!(prepared, 1, "only the third plane's copy is used");
    for (step, (a, b)) in ahead.iter().zip(&inline).enumerate() {
        assert!(a == b, "surfaces differ after step {step}");
    }
}
