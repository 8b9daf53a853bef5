//! MCAP recording with Foxglove conventions: the deformed surface as `foxglove.SceneUpdate` JSON,
//! per-step statistics and timeline events as JSON on their own channels. Chunks are flushed to
//! disk every few frames so a killed run keeps what it computed; `finish` writes the summary.

use cleave_core::{Point3, Real, Vector3};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Topic of the deformed surface.
pub const SURFACE_TOPIC: &str = "/surface";
/// Topic of the static mesh colliders (one message at the start).
pub const COLLIDERS_TOPIC: &str = "/colliders";
/// Topic of the per-step statistics.
pub const STATS_TOPIC: &str = "/stats";
/// Topic of timeline and topology events.
pub const EVENTS_TOPIC: &str = "/events";

/// JSON schema of the subset of `foxglove.SceneUpdate` we write (entities of triangle lists).
const SCENE_UPDATE_SCHEMA: &str = r#"{
  "title": "foxglove.SceneUpdate",
  "description": "An update to the entities displayed in a 3D scene",
  "type": "object",
  "properties": {
    "deletions": { "type": "array", "items": { "type": "object" } },
    "entities": {
      "type": "array",
      "items": {
        "type": "object",
        "properties": {
          "timestamp": { "type": "object", "properties": { "sec": { "type": "integer" }, "nsec": { "type": "integer" } } },
          "frame_id": { "type": "string" },
          "id": { "type": "string" },
          "lifetime": { "type": "object", "properties": { "sec": { "type": "integer" }, "nsec": { "type": "integer" } } },
          "frame_locked": { "type": "boolean" },
          "metadata": { "type": "array", "items": { "type": "object" } },
          "arrows": { "type": "array" }, "cubes": { "type": "array" }, "spheres": { "type": "array" },
          "cylinders": { "type": "array" }, "lines": { "type": "array" }, "texts": { "type": "array" },
          "models": { "type": "array" },
          "triangles": {
            "type": "array",
            "items": {
              "type": "object",
              "properties": {
                "pose": { "type": "object" },
                "points": { "type": "array", "items": { "type": "object", "properties": { "x": { "type": "number" }, "y": { "type": "number" }, "z": { "type": "number" } } } },
                "color": { "type": "object", "properties": { "r": { "type": "number" }, "g": { "type": "number" }, "b": { "type": "number" }, "a": { "type": "number" } } },
                "colors": { "type": "array" },
                "indices": { "type": "array", "items": { "type": "integer", "minimum": 0 } }
              }
            }
          }
        }
      }
    }
  }
}"#;

const STATS_SCHEMA: &str = r#"{
  "title": "cleave.StepStats",
  "description": "One implicit step: solver effort, phase timings [s], energies [J], contact and probe data",
  "type": "object",
  "properties": {
    "step": { "type": "integer" }, "time": { "type": "number" },
    "iterations": { "type": "integer" }, "residual": { "type": "number" },
    "seconds": { "type": "object" }, "energy": { "type": "object" },
    "inverted_elements": { "type": "integer" }, "active_contacts": { "type": "integer" },
    "surface": { "type": "object" }, "probes": { "type": "object" }
  }
}"#;

const EVENT_SCHEMA: &str = r#"{
  "title": "cleave.Event",
  "description": "A timeline or topology event, or the end of the run",
  "type": "object",
  "properties": { "time": { "type": "number" }, "kind": { "type": "string" }, "message": { "type": "string" } }
}"#;

/// A failed recording operation.
#[derive(Debug, thiserror::Error)]
#[error("recording {path}: {message}")]
pub struct RecordError {
    /// The MCAP path.
    pub path: PathBuf,
    /// What failed.
    pub message: String,
}

/// Writes one run into one MCAP file.
pub struct Recorder {
    path: PathBuf,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    surface: u16,
    colliders: u16,
    stats: u16,
    events: u16,
    sequence: u32,
    frames_since_flush: u32,
    flush_every: u32,
}

/// A coordinate as JSON, rounded to `f32` (7 significant digits: a micrometre on a metre-sized
/// scene, far below what a frame shows, and half the bytes and formatting time of an `f64`;
/// coincident points stay coincident). Non-finite values (a diverged run's last frame) become 0
/// rather than invalid JSON.
fn finite(v: Real) -> f32 {
    if v.is_finite() { v as f32 } else { 0.0 }
}

/// Side of the square a plane collider is drawn as in `/colliders` [m].
pub const PLANE_SIDE: f32 = 2.0;

/// The unit quaternion `[x, y, z, w]` turning +z into the unit vector `n` (the shortest arc;
/// half a turn about x when `n` is −z).
fn rotation_from_z(n: &Vector3<Real>) -> [f32; 4] {
    let n = n.normalize();
    if n.z < -1.0 + 1e-9 {
        return [1.0, 0.0, 0.0, 0.0];
    }
    // (1 + z·n, z × n) normalized: half the angle between z and n about their common normal.
    let q = [-n.y, n.x, 0.0, 1.0 + n.z];
    let norm = q.iter().map(|c| c * c).sum::<Real>().sqrt();
    q.map(|c| (c / norm) as f32)
}

fn nanoseconds(time: Real) -> u64 {
    (time.max(0.0) * 1e9).round() as u64
}

impl Recorder {
    /// Creates the file and declares the channels; every channel's metadata names the scene and
    /// the backend (what `cargo xtask render` labels a picture with).
    pub fn create(path: &Path, scene_name: &str, backend: &str, flush_every: u32) -> Result<Self, RecordError> {
        let error = |message: String| RecordError { path: path.to_path_buf(), message };
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|e| error(format!("cannot create directory: {e}")))?;
        }
        let file = File::create(path).map_err(|e| error(format!("cannot create file: {e}")))?;
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            // The fastest level: surfaces of 10⁵ triangles per frame made level 3 a third of a run.
            .compression_level(1)
            .profile("")
            .library(concat!("cleave ", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::new(file))
            .map_err(|e| error(e.to_string()))?;
        let mut metadata = BTreeMap::new();
        metadata.insert("scene".to_string(), scene_name.to_string());
        metadata.insert("backend".to_string(), backend.to_string());
        let mut channel = |schema_name: &str, schema: &str, topic: &str| -> Result<u16, RecordError> {
            let schema_id =
                writer.add_schema(schema_name, "jsonschema", schema.as_bytes()).map_err(|e| error(e.to_string()))?;
            writer.add_channel(schema_id, topic, "json", &metadata).map_err(|e| error(e.to_string()))
        };
        let surface = channel("foxglove.SceneUpdate", SCENE_UPDATE_SCHEMA, SURFACE_TOPIC)?;
        let colliders = channel("foxglove.SceneUpdate", SCENE_UPDATE_SCHEMA, COLLIDERS_TOPIC)?;
        let stats = channel("cleave.StepStats", STATS_SCHEMA, STATS_TOPIC)?;
        let events = channel("cleave.Event", EVENT_SCHEMA, EVENTS_TOPIC)?;
        Ok(Self {
            path: path.to_path_buf(),
            writer: Some(writer),
            surface,
            colliders,
            stats,
            events,
            sequence: 0,
            frames_since_flush: 0,
            flush_every: flush_every.max(1),
        })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn write(&mut self, channel: u16, time: Real, value: &Value) -> Result<(), RecordError> {
        let bytes =
            serde_json::to_vec(value).map_err(|e| RecordError { path: self.path.clone(), message: e.to_string() })?;
        self.write_bytes(channel, time, &bytes)
    }

    fn write_bytes(&mut self, channel: u16, time: Real, bytes: &[u8]) -> Result<(), RecordError> {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time: nanoseconds(time),
            publish_time: nanoseconds(time),
        };
        self.sequence += 1;
        let writer = self
            .writer
            .as_mut()
            .ok_or_else(|| RecordError { path: self.path.clone(), message: "already finished".into() })?;
        writer
            .write_to_known_channel(&header, bytes)
            .map_err(|e| RecordError { path: self.path.clone(), message: e.to_string() })
    }

    /// Records the deformed surface as one entity with triangle lists per piece and kind: the
    /// original surface (tan) and the faces cuts opened (`on_cut[t]`, red), each list with only
    /// the points it uses, in piece order (`piece[t]`; empty = one piece), so a reader can check
    /// that every piece is closed. The JSON is written straight into one buffer (a surface of
    /// 10⁵ triangles as `serde_json::Value`s cost more than the step).
    pub fn surface(
        &mut self,
        time: Real,
        points: &[Point3<Real>],
        triangles: &[[u32; 3]],
        on_cut: &[bool],
        piece: &[u32],
    ) -> Result<(), RecordError> {
        use std::fmt::Write as _;
        let ns = nanoseconds(time);
        let (mut float, mut integer) = (zmij::Buffer::new(), itoa::Buffer::new());
        let mut json = String::with_capacity(64 * points.len() + 32 * triangles.len() + 512);
        let _ = write!(
            json,
            r#"{{"deletions":[],"entities":[{{"timestamp":{{"sec":{},"nsec":{}}},"frame_id":"world","id":"solid","lifetime":{{"sec":0,"nsec":0}},"frame_locked":false,"metadata":[],"arrows":[],"cubes":[],"spheres":[],"cylinders":[],"lines":[],"texts":[],"models":[],"triangles":["#,
            ns / 1_000_000_000,
            ns % 1_000_000_000
        );
        // The triangles of each list (piece k, cut or not: list 2k + cut), bucketed in one pass.
        let pieces = piece.iter().copied().max().map_or(1, |m| m as usize + 1);
        let list_of = |t: usize| {
            2 * piece.get(t).copied().unwrap_or(0) as usize + usize::from(on_cut.get(t).copied().unwrap_or(false))
        };
        let mut starts = vec![0usize; 2 * pieces + 1];
        for t in 0..triangles.len() {
            starts[list_of(t) + 1] += 1;
        }
        for l in 0..2 * pieces {
            starts[l + 1] += starts[l];
        }
        let mut order = vec![0u32; triangles.len()];
        let mut fill = starts.clone();
        for t in 0..triangles.len() {
            let l = list_of(t);
            order[fill[l]] = t as u32;
            fill[l] += 1;
        }
        let mut local = vec![u32::MAX; points.len()];
        let mut first_list = true;
        for list in 0..2 * pieces {
            let members = &order[starts[list]..starts[list + 1]];
            if members.is_empty() {
                continue;
            }
            let color = if list % 2 == 1 { "0.80,\"g\":0.15,\"b\":0.15" } else { "0.85,\"g\":0.62,\"b\":0.38" };
            if !first_list {
                json.push(',');
            }
            first_list = false;
            json.push_str(r#"{"pose":{"position":{"x":0.0,"y":0.0,"z":0.0},"orientation":{"x":0.0,"y":0.0,"z":0.0,"w":1.0}},"points":["#);
            let mut used = 0u32;
            for &t in members {
                for &v in &triangles[t as usize] {
                    if local[v as usize] == u32::MAX {
                        local[v as usize] = used;
                        let p = points[v as usize];
                        if used > 0 {
                            json.push(',');
                        }
                        json.push_str(r#"{"x":"#);
                        json.push_str(float.format_finite(finite(p.x)));
                        json.push_str(r#","y":"#);
                        json.push_str(float.format_finite(finite(p.y)));
                        json.push_str(r#","z":"#);
                        json.push_str(float.format_finite(finite(p.z)));
                        json.push('}');
                        used += 1;
                    }
                }
            }
            let _ = write!(json, r#"],"color":{{"r":{color},"a":1.0}},"colors":[],"indices":["#);
            let mut first = true;
            for &t in members {
                for &v in &triangles[t as usize] {
                    if !first {
                        json.push(',');
                    }
                    first = false;
                    json.push_str(integer.format(local[v as usize]));
                }
            }
            json.push_str("]}");
            // Only the points this list used get their slot back.
            for &t in members {
                for &v in &triangles[t as usize] {
                    local[v as usize] = u32::MAX;
                }
            }
        }
        json.push_str("]}]}");
        self.write_bytes(self.surface, time, json.as_bytes())
    }

    /// Records the static colliders once, as one entity that never expires, so that a viewer
    /// shows the ground, bowl or table the body meets: each mesh as a triangle list, each plane
    /// (`(point, unit normal)`) as a square of zero thickness, [`PLANE_SIDE`] wide, centred on
    /// its point with its local z along the normal (`cargo xtask render` reads the plane back
    /// from that pose).
    pub fn colliders(
        &mut self,
        meshes: &[cleave_geometry::TriangleMesh],
        planes: &[(Point3<Real>, Vector3<Real>)],
    ) -> Result<(), RecordError> {
        if meshes.is_empty() && planes.is_empty() {
            return Ok(());
        }
        let lists: Vec<Value> = meshes
            .iter()
            .map(|mesh| {
                let (points, triangles) = (&mesh.vertices, &mesh.triangles);
                json!({
                    "pose": { "position": { "x": 0.0, "y": 0.0, "z": 0.0 }, "orientation": { "x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0 } },
                    "points": points.iter().map(|p| json!({ "x": finite(p.x), "y": finite(p.y), "z": finite(p.z) })).collect::<Vec<_>>(),
                    "color": { "r": 0.6, "g": 0.65, "b": 0.7, "a": 1.0 },
                    "colors": [],
                    "indices": triangles.iter().flatten().copied().collect::<Vec<u32>>(),
                })
            })
            .collect();
        let cubes: Vec<Value> = planes
            .iter()
            .map(|(point, normal)| {
                let q = rotation_from_z(normal);
                json!({
                    "pose": {
                        "position": { "x": finite(point.x), "y": finite(point.y), "z": finite(point.z) },
                        "orientation": { "x": q[0], "y": q[1], "z": q[2], "w": q[3] },
                    },
                    "size": { "x": PLANE_SIDE, "y": PLANE_SIDE, "z": 0.0 },
                    "color": { "r": 0.78, "g": 0.78, "b": 0.78, "a": 1.0 },
                })
            })
            .collect();
        let update = json!({
            "deletions": [],
            "entities": [{
                "timestamp": { "sec": 0, "nsec": 0 }, "frame_id": "world", "id": "colliders",
                "lifetime": { "sec": 0, "nsec": 0 }, "frame_locked": false, "metadata": [],
                "arrows": [], "cubes": cubes, "spheres": [], "cylinders": [], "lines": [], "texts": [],
                "models": [], "triangles": lists,
            }],
        });
        self.write(self.colliders, 0.0, &update)
    }

    /// Records a step's statistics, flushing to disk every `flush_every` calls.
    pub fn stats(&mut self, time: Real, stats: &Value) -> Result<(), RecordError> {
        self.write(self.stats, time, stats)?;
        self.frames_since_flush += 1;
        if self.frames_since_flush >= self.flush_every {
            self.flush()?;
        }
        Ok(())
    }

    /// Records an event and flushes, so events survive a crash right after them.
    pub fn event(&mut self, time: Real, kind: &str, message: &str) -> Result<(), RecordError> {
        self.write(self.events, time, &json!({ "time": time, "kind": kind, "message": message }))?;
        self.flush()
    }

    /// Closes the current chunk and pushes it to the file.
    pub fn flush(&mut self) -> Result<(), RecordError> {
        self.frames_since_flush = 0;
        if let Some(writer) = self.writer.as_mut() {
            writer.flush().map_err(|e| RecordError { path: self.path.clone(), message: e.to_string() })?;
        }
        Ok(())
    }

    /// Writes the summary and closes the file.
    pub fn finish(&mut self) -> Result<(), RecordError> {
        if let Some(mut writer) = self.writer.take() {
            writer.finish().map_err(|e| RecordError { path: self.path.clone(), message: e.to_string() })?;
        }
        Ok(())
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        // A recorder dropped without `finish` (an unwinding panic, an early return) still closes
        // the file properly; errors here have nowhere to go.
        let _ = self.finish();
    }
}
