//! Recordings: a finished run is a valid MCAP with the three channels; a run that dies without
//! finishing still yields every flushed frame to a lenient reader.

use cleave_scene::Simulation;
use cleave_scene::run::parse_scene;
use mcap::read::Options;
use std::path::Path;

const SCENE: &str = r#"Scene(
    name: "box",
    object: Box(min: (0.0, 0.0, 0.0), max: (1.0, 0.5, 0.5)),
    material: (youngs_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000.0),
    backend: "voxel",
    settings: { "voxel": (cell_size: 0.25) },
    time_step: 0.01,
    steps: 23,
    pins: [Region(min: (-0.01, -1.0, -1.0), max: (0.01, 1.0, 1.0))],
    probes: [(name: "tip", position: (1.0, 0.25, 0.25))],
    output: (flush_every: 5),
)"#;

fn count_messages(bytes: &[u8], lenient: bool) -> (usize, usize, usize) {
    let stream = if lenient {
        mcap::MessageStream::new_with_options(bytes, Options::IgnoreEndMagic.into())
    } else {
        mcap::MessageStream::new(bytes)
    };
    let (mut surface, mut stats, mut events) = (0, 0, 0);
    for message in stream.unwrap() {
        let Ok(message) = message else { break };
        let _: serde_json::Value = serde_json::from_slice(&message.data).expect("every message is JSON");
        match message.channel.topic.as_str() {
            "/surface" => {
                assert_eq!(message.channel.schema.as_ref().unwrap().name, "foxglove.SceneUpdate");
                surface += 1
            }
            "/stats" => stats += 1,
            "/events" => events += 1,
            other => panic!("unexpected topic {other}"),
        }
    }
    (surface, stats, events)
}

#[test]
fn a_finished_run_has_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run.mcap");
    let loaded = parse_scene(Path::new("box.ron"), SCENE).unwrap();
    let mut simulation = Simulation::build(&loaded, Some(&out)).unwrap();
    for _ in 0..23 {
        simulation.step().unwrap();
    }
    simulation.finish(None).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    // initial frame + one per step; start and end events
    assert_eq!(count_messages(&bytes, false), (24, 24, 2));
}

#[test]
fn a_run_that_dies_keeps_its_flushed_frames() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("killed.mcap");
    let loaded = parse_scene(Path::new("box.ron"), SCENE).unwrap();
    let mut simulation = Simulation::build(&loaded, Some(&out)).unwrap();
    for _ in 0..13 {
        simulation.step().unwrap();
    }
    // Die like SIGKILL: no finish, no destructor, the unflushed buffer is lost.
    std::mem::forget(simulation);
    let bytes = std::fs::read(&out).unwrap();
    assert!(!bytes.ends_with(mcap::MAGIC), "a killed run has no footer");
    let (surface, stats, events) = count_messages(&bytes, true);
    // stats are flushed every 5: the initial record plus steps 1..=9 (two flushes) at least
    assert!(stats >= 10, "only {stats} stats frames survived");
    assert!(surface >= 10 && events >= 1, "surface {surface}, events {events}");
}
