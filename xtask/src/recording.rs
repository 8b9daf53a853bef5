//! Reading a cleave MCAP recording back for `cargo xtask render`: the `/surface` frames
//! (triangle lists with their colours), the static colliders of `/colliders` (meshes, and
//! planes recorded as flat cubes) and the scene and backend names of the channel metadata.

use anyhow::{Context, Result, anyhow, bail};
use mcap::read::Options;
use serde::Deserialize;
use std::path::Path;

/// A point or vector in world coordinates [m].
pub type Vec3 = [f32; 3];

pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn dot(a: Vec3, b: Vec3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

pub fn normalized(a: Vec3) -> Vec3 {
    let length = dot(a, a).sqrt();
    a.map(|c| c / length)
}

/// Triangles of one colour: `indices[3k..3k + 3]` index `points`.
#[derive(Debug, Clone)]
pub struct TriangleList {
    pub points: Vec<Vec3>,
    pub indices: Vec<u32>,
    /// Linear RGB in [0, 1].
    pub color: Vec3,
}

/// One recorded surface at one simulated time.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Simulated time [s] (the message's log time).
    pub time: f64,
    pub lists: Vec<TriangleList>,
}

/// A collider plane: a point on it, its unit normal and its recorded colour.
#[derive(Debug, Clone, Copy)]
pub struct Plane {
    pub point: Vec3,
    pub normal: Vec3,
    pub color: Vec3,
}

/// Everything `render` needs from one recording.
#[derive(Debug)]
pub struct Recording {
    /// The scene's name (channel metadata `scene`), or the file stem.
    pub scene: String,
    /// The backend that ran it (channel metadata `backend`), if recorded.
    pub backend: Option<String>,
    /// The surface frames, in time order.
    pub frames: Vec<Frame>,
    /// Static mesh colliders.
    pub meshes: Vec<TriangleList>,
    pub planes: Vec<Plane>,
}

// The subset of `foxglove.SceneUpdate` JSON that the recorder writes and `render` draws.
#[derive(Deserialize)]
struct SceneUpdate {
    #[serde(default)]
    entities: Vec<Entity>,
}

#[derive(Deserialize)]
struct Entity {
    #[serde(default)]
    triangles: Vec<TrianglesJson>,
    #[serde(default)]
    cubes: Vec<CubeJson>,
}

#[derive(Deserialize)]
struct TrianglesJson {
    #[serde(default)]
    pose: Pose,
    points: Vec<Xyz>,
    color: Rgba,
    #[serde(default)]
    indices: Vec<u32>,
}

#[derive(Deserialize)]
struct CubeJson {
    #[serde(default)]
    pose: Pose,
    color: Rgba,
}

#[derive(Deserialize, Default)]
struct Pose {
    #[serde(default)]
    position: Xyz,
    #[serde(default)]
    orientation: Quaternion,
}

#[derive(Deserialize, Default, Clone, Copy)]
struct Xyz {
    x: f32,
    y: f32,
    z: f32,
}

#[derive(Deserialize, Clone, Copy)]
struct Quaternion {
    x: f32,
    y: f32,
    z: f32,
    w: f32,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self { x: 0.0, y: 0.0, z: 0.0, w: 1.0 }
    }
}

#[derive(Deserialize)]
struct Rgba {
    r: f32,
    g: f32,
    b: f32,
}

impl Pose {
    /// The pose applied to a local point: rotation by the unit quaternion, then translation.
    fn apply(&self, p: Vec3) -> Vec3 {
        let q = self.orientation;
        let u = [q.x, q.y, q.z];
        // v' = v + 2w (u × v) + 2 u × (u × v)
        let t = cross(u, p).map(|c| 2.0 * c);
        let r = cross(u, t);
        let o = self.position;
        [p[0] + q.w * t[0] + r[0] + o.x, p[1] + q.w * t[1] + r[1] + o.y, p[2] + q.w * t[2] + r[2] + o.z]
    }
}

impl TrianglesJson {
    fn into_list(self) -> Result<TriangleList> {
        if !self.indices.len().is_multiple_of(3) {
            bail!("a triangle list has {} indices, not a multiple of 3", self.indices.len());
        }
        if let Some(&bad) = self.indices.iter().find(|&&i| i as usize >= self.points.len()) {
            bail!("a triangle list indexes point {bad} of {}", self.points.len());
        }
        let pose = self.pose;
        let points = self.points.iter().map(|p| pose.apply([p.x, p.y, p.z])).collect();
        Ok(TriangleList { points, indices: self.indices, color: [self.color.r, self.color.g, self.color.b] })
    }
}

fn triangle_lists(update: SceneUpdate) -> Result<Vec<TriangleList>> {
    update.entities.into_iter().flat_map(|e| e.triangles).map(TrianglesJson::into_list).collect()
}

/// Reads `path`. A run killed before it finished is read up to its last complete chunk (with a
/// warning on stderr).
pub fn read(path: &Path) -> Result<Recording> {
    let name = path.display();
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {name}"))?;
    if !bytes.starts_with(mcap::MAGIC) {
        bail!("{name} is not an MCAP file (it does not start with the MCAP magic bytes)");
    }
    let stream = mcap::MessageStream::new_with_options(&bytes, Options::IgnoreEndMagic.into())
        .map_err(|e| anyhow!("{name} is not a readable MCAP file: {e}"))?;
    let stem = path.file_stem().map_or_else(|| "recording".into(), |s| s.to_string_lossy().into_owned());
    let mut recording =
        Recording { scene: stem, backend: None, frames: Vec::new(), meshes: Vec::new(), planes: Vec::new() };
    for message in stream {
        let message = match message {
            Ok(message) => message,
            Err(error) if recording.frames.is_empty() => {
                bail!("{name} is damaged before its first /surface frame: {error}")
            }
            Err(error) => {
                eprintln!("warning: {name}: stopped reading at a damaged record ({error}); rendering what came before");
                break;
            }
        };
        let topic = message.channel.topic.as_str();
        let context = || format!("{name}: a {topic} message at t = {} s", message.log_time as f64 * 1e-9);
        match topic {
            "/surface" => {
                if recording.frames.is_empty() {
                    let metadata = &message.channel.metadata;
                    if let Some(scene) = metadata.get("scene") {
                        recording.scene = scene.clone();
                    }
                    recording.backend = metadata.get("backend").cloned();
                }
                let update: SceneUpdate = serde_json::from_slice(&message.data).with_context(context)?;
                let lists = triangle_lists(update).with_context(context)?;
                recording.frames.push(Frame { time: message.log_time as f64 * 1e-9, lists });
            }
            "/colliders" => {
                let update: SceneUpdate = serde_json::from_slice(&message.data).with_context(context)?;
                for entity in &update.entities {
                    for cube in &entity.cubes {
                        let o = cube.pose.position;
                        let local_z =
                            Pose { orientation: cube.pose.orientation, ..Default::default() }.apply([0.0, 0.0, 1.0]);
                        recording.planes.push(Plane {
                            point: [o.x, o.y, o.z],
                            normal: local_z,
                            color: [cube.color.r, cube.color.g, cube.color.b],
                        });
                    }
                }
                recording.meshes.extend(triangle_lists(update).with_context(context)?);
            }
            _ => {}
        }
    }
    if recording.frames.is_empty() {
        bail!("{name} has no /surface frames (is it a cleave recording? `cargo xtask run` writes one)");
    }
    recording.frames.sort_by(|a, b| a.time.total_cmp(&b.time));
    Ok(recording)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pose_turns_then_moves() {
        // A quarter turn about z (w = z = 1/√2) takes x to y; then the position adds 1 in z.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let pose =
            Pose { position: Xyz { x: 0.0, y: 0.0, z: 1.0 }, orientation: Quaternion { x: 0.0, y: 0.0, z: h, w: h } };
        let p = pose.apply([2.0, 0.0, 0.0]);
        for (got, want) in p.iter().zip([0.0, 2.0, 1.0]) {
            assert!((got - want).abs() < 1e-6, "{p:?}");
        }
    }

    #[test]
    fn missing_and_foreign_files_are_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.mcap");
        let error = format!("{:#}", read(&missing).unwrap_err());
        assert!(error.contains("cannot read") && error.contains("missing.mcap"), "{error}");
        let text = dir.path().join("text.mcap");
        std::fs::write(&text, "not an mcap").unwrap();
        let error = format!("{:#}", read(&text).unwrap_err());
        assert!(error.contains("is not an MCAP file") && error.contains("text.mcap"), "{error}");
    }

    #[test]
    fn a_recording_without_surface_frames_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("stats_only.mcap");
        let mut recorder = cleave_scene::Recorder::create(&path, "empty", "voxel", 1).unwrap();
        recorder.stats(0.0, &serde_json::json!({ "step": 0 })).unwrap();
        recorder.finish().unwrap();
        let error = format!("{:#}", read(&path).unwrap_err());
        assert!(error.contains("stats_only.mcap has no /surface frames"), "{error}");
    }

    #[test]
    fn planes_scene_and_backend_come_back_as_recorded() {
        use cleave_core::{Point3, Vector3};
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("planes.mcap");
        let tilted = Vector3::new(0.3, -0.4, 0.5).normalize();
        let planes = [
            (Point3::new(0.0, 0.0, -0.25), Vector3::z()),
            (Point3::new(1.0, 2.0, 3.0), tilted),
            (Point3::new(0.0, 0.0, 1.0), -Vector3::z()),
        ];
        let mut recorder = cleave_scene::Recorder::create(&path, "three planes", "dg-ip-1", 1).unwrap();
        recorder.colliders(&[], &planes).unwrap();
        let points = [Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)];
        recorder.surface(0.25, &points, &[[0, 1, 2]], &[true], &[]).unwrap();
        recorder.finish().unwrap();
        let recording = read(&path).unwrap();
        assert_eq!((recording.scene.as_str(), recording.backend.as_deref()), ("three planes", Some("dg-ip-1")));
        assert_eq!(recording.planes.len(), 3);
        for (got, (point, normal)) in recording.planes.iter().zip(&planes) {
            for k in 0..3 {
                assert!((got.point[k] as f64 - point[k]).abs() < 1e-6, "{:?} vs {point}", got.point);
                assert!((got.normal[k] as f64 - normal[k]).abs() < 1e-6, "{:?} vs {normal}", got.normal);
            }
        }
        let frame = &recording.frames[0];
        assert_eq!((frame.time, frame.lists.len(), frame.lists[0].indices.as_slice()), (0.25, 1, &[0, 1, 2][..]));
        assert_eq!(frame.lists[0].color, [0.8, 0.15, 0.15], "cut faces are recorded red");
    }
}
