//! A blade in a scene hands over its face the first step it is due, also where it started
//! before the run did: a blade standing across a box separates it at once.

use cleave_scene::Simulation;
use cleave_scene::run::parse_scene;
use std::path::Path;

fn scene(start: f64) -> String {
    format!(
        r#"Scene(
    name: "standing blade",
    object: Box(min: (0.0, 0.0, 0.0), max: (1.0, 0.5, 0.5)),
    material: (youngs_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000.0),
    backend: "virtualnode",
    settings: {{ "virtualnode": (cell_size: 0.25) }},
    time_step: 0.01,
    steps: 2,
    timeline: [Blade(start: {start:?}, end: 1.0, polygon: [(0.55, -1.0, -1.0), (0.55, 2.0, -1.0), (0.55, 2.0, 2.0), (0.55, -1.0, 2.0)], path: [(time: 0.0)])],
)"#
    )
}

#[test]
fn a_standing_blade_separates_what_its_face_covers_at_its_first_step() {
    // The face covers the whole section x = 0.55 and never moves: the strips its edges sweep
    // are empty, so only the face handed over on the first due step can cut.
    for start in [0.0, -1.0] {
        let loaded = parse_scene(Path::new("blade.ron"), &scene(start)).unwrap();
        let mut simulation = Simulation::build(&loaded, None).unwrap();
        assert_eq!(simulation.cut_summary().pieces.len(), 1);
        simulation.step().unwrap();
        assert_eq!(simulation.cut_summary().pieces.len(), 2, "blade starting at t = {start}");
        simulation.step().unwrap();
        assert_eq!(simulation.cut_summary().pieces.len(), 2, "blade starting at t = {start}");
    }
}
