//! End-to-end: `xtask run` on the README scene records a bunny that falls, reaches the ground and
//! comes to rest; a run killed with SIGKILL keeps its flushed frames; a bad scene exits non-zero
//! with a one-line file:line:column message.

use mcap::read::Options;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

fn xtask() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_xtask"));
    command.current_dir(workspace());
    command
}

/// (min_z, kinetic energy) of every stats message readable from the file.
fn stats(bytes: &[u8], lenient: bool) -> Vec<(f64, f64)> {
    let stream = if lenient {
        mcap::MessageStream::new_with_options(bytes, Options::IgnoreEndMagic.into())
    } else {
        mcap::MessageStream::new(bytes)
    };
    let mut out = Vec::new();
    for message in stream.unwrap() {
        let Ok(message) = message else { break };
        let value: serde_json::Value = serde_json::from_slice(&message.data).unwrap();
        if message.channel.topic == "/stats" {
            out.push((value["surface"]["min_z"].as_f64().unwrap(), value["energy"]["kinetic"].as_f64().unwrap()));
        }
    }
    out
}

#[test]
fn bunny_falls_hits_the_ground_and_rests() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bunny.mcap");
    let status = xtask().args(["run", "scenes/bunny_drop_voxel.ron", "--quiet", "--out"]).arg(&out).status().unwrap();
    assert!(status.success());
    let stats = stats(&std::fs::read(&out).unwrap(), false);
    assert_eq!(stats.len(), 241, "initial state + 240 steps");
    let start = stats[0].0;
    let lowest = stats.iter().map(|s| s.0).fold(f64::MAX, f64::min);
    let peak_kinetic = stats.iter().map(|s| s.1).fold(0.0, f64::max);
    let (final_z, final_kinetic) = *stats.last().unwrap();
    println!(
        "min z start {start:.4}, lowest {lowest:.4}, final {final_z:.4}; kinetic peak {peak_kinetic:.3e}, final {final_kinetic:.3e}"
    );
    assert!((start - 0.3).abs() < 0.01, "starts 0.3 m up: {start}");
    // free fall from 0.3 m: v = sqrt(2 g 0.3) = 2.43 m/s at impact
    assert!(lowest.abs() < 0.01, "reaches the ground: {lowest}");
    assert!(final_z.abs() < 0.01, "ends on the ground: {final_z}");
    assert!(final_kinetic < 1e-4 * peak_kinetic, "comes to rest: {final_kinetic} vs peak {peak_kinetic}");
}

#[test]
fn dg_bunny_falls_hops_and_rests_with_its_mls_surface_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bunny_dg.mcap");
    let status = xtask().args(["run", "scenes/bunny_drop_dg.ron", "--quiet", "--out"]).arg(&out).status().unwrap();
    assert!(status.success());
    let bytes = std::fs::read(&out).unwrap();
    let stats = stats(&bytes, false);
    assert_eq!(stats.len(), 601, "initial state + 600 steps");
    let first_contact = stats.iter().position(|s| s.0 < 0.0).expect("reaches the ground");
    let lowest = stats.iter().map(|s| s.0).fold(f64::MAX, f64::min);
    let hop = stats[first_contact..].iter().map(|s| s.0).fold(f64::MIN, f64::max);
    let peak_kinetic = stats.iter().map(|s| s.1).fold(0.0, f64::max);
    let (final_z, final_kinetic) = *stats.last().unwrap();
    println!(
        "contact at step {first_contact}, lowest {lowest:.4}, hop {hop:.4}, final {final_z:.4}; kinetic peak {peak_kinetic:.3e}, final {final_kinetic:.3e}"
    );
    // free fall from 0.3 m takes sqrt(2·0.3/9.81) = 0.247 s = 59 steps of 1/240 s
    assert!((57..=62).contains(&first_contact), "contact at step {first_contact}");
    assert!(lowest.abs() < 0.01, "penetration {lowest}");
    assert!(hop > 1e-3, "the bunny must leave the ground after impact: {hop}");
    assert!(final_z.abs() < 0.002, "ends on the ground: {final_z}");
    assert!(final_kinetic < 1e-3 * peak_kinetic, "comes to rest: {final_kinetic} vs peak {peak_kinetic}");
    // The surface channel carries the MLS-embedded original surface: 1839 vertices per frame.
    let mut surface_frames = 0;
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        if message.channel.topic == "/surface" {
            let value: serde_json::Value = serde_json::from_slice(&message.data).unwrap();
            let points = value["entities"][0]["triangles"][0]["points"].as_array().unwrap().len();
            assert_eq!(points, 1839);
            surface_frames += 1;
        }
    }
    assert!(surface_frames >= 300, "{surface_frames} surface frames");
}

#[test]
fn a_killed_run_keeps_its_flushed_frames() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("killed.mcap");
    let mut child = xtask()
        .args(["run", "scenes/bunny_drop_voxel.ron", "--quiet", "--steps", "100000", "--out"])
        .arg(&out)
        .spawn()
        .unwrap();
    // Wait until at least a few flushes reached the disk, then SIGKILL.
    let clock = Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(200));
        let flushed = std::fs::read(&out).map(|b| stats(&b, true).len()).unwrap_or(0);
        if flushed >= 30 || clock.elapsed() > Duration::from_secs(120) {
            break;
        }
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let bytes = std::fs::read(&out).unwrap();
    assert!(!bytes.ends_with(mcap::MAGIC), "a killed run has no footer");
    let frames = stats(&bytes, true);
    assert!(frames.len() >= 30, "only {} frames survived", frames.len());
}

#[test]
fn a_bad_scene_fails_with_one_line_naming_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.ron");
    let text = std::fs::read_to_string(workspace().join("scenes/cantilever_voxel.ron")).unwrap();
    std::fs::write(&scene, text.replace("poisson_ratio: 0.3", "poisson_ratio: 0.5")).unwrap();
    let output = xtask().arg("run").arg(&scene).output().unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    let line = stderr.lines().last().unwrap();
    assert!(line.starts_with("error: ") && line.contains("bad.ron:") && line.contains("Poisson ratio"), "{stderr}");
}
