//! The timeline: events turned into cuts ready to act (soups read and placed, blades checked)
//! and the surfaces due in each step.

use super::*;
use crate::schema::{CutSpec, EventSpec};
use cleave_core::{CutSurface, Point3, Real, Vector3};
use cleave_geometry::{Blade, Keyframe};
use nalgebra::UnitQuaternion;
use std::path::Path;

/// A timeline event ready to act: a fixed soup at a time, or a blade over a window.
pub(super) enum TimedCut {
    Once {
        time: Real,
        surface: Option<CutSurface>,
    },
    /// `begun`: whether a step has handed over the blade's first soup (its face included).
    Blade {
        start: Real,
        end: Real,
        blade: Blade,
        begun: bool,
    },
}

impl Simulation {
    /// The surfaces the timeline cuts at the start of the step from `t0` to `t1`: a `Cut` once,
    /// at the first step that starts at or after its time (a plane stays a plane: the backend
    /// cuts it exactly, without the slivers a huge two-triangle stand-in leaves along its
    /// diagonal); the blades' soups swept over their part of this step, as one soup (the first
    /// step of a blade with its incision, [`Blade::swept`]; later ones only what its cutting
    /// edges sweep, [`Blade::swept_after`]).
    /// A `Cut` comes with its index in the timeline.
    pub(super) fn due_cuts(&mut self, t0: Real, t1: Real) -> Vec<(Option<usize>, CutSurface)> {
        let mut due = Vec::new();
        let mut swept = Vec::new();
        for (k, event) in self.timeline.iter_mut().enumerate() {
            match event {
                TimedCut::Once { time, surface } => {
                    if *time <= t0 + 1e-9
                        && let Some(surface) = surface.take()
                    {
                        due.push((Some(k), surface));
                    }
                }
                TimedCut::Blade { start, end, blade, begun } => {
                    let (a, b) = (t0.max(*start), t1.min(*end));
                    // The first step the blade is due hands over its face there (even where the
                    // run starts after the blade did); later ones only what is new since the
                    // step before.
                    if !*begun && (a < b || (a == b && a == *start)) {
                        swept.extend(blade.swept(a, b));
                        *begun = true;
                    } else if *begun && a < b {
                        swept.extend(blade.swept_after(a, b));
                    }
                }
            }
        }
        if !swept.is_empty() {
            due.push((None, CutSurface::Triangles(swept)));
        }
        due
    }
}

/// Turns the scene's events into cuts ready to act: OBJ soups read and placed, blades checked.
pub(super) fn prepare_timeline(events: &[EventSpec], scene: &Path) -> Result<Vec<TimedCut>, SceneError> {
    let build_error = |message: String| SceneError::Build { path: scene.to_path_buf(), message };
    let mut timeline = Vec::with_capacity(events.len());
    for (index, event) in events.iter().enumerate() {
        timeline.push(match event {
            EventSpec::Cut { time, surface } => {
                if !time.is_finite() {
                    return Err(build_error(format!("timeline[{index}]: Cut time must be finite, got {time}")));
                }
                let surface = match surface {
                    CutSpec::Plane { point, normal } => {
                        CutSurface::Plane { point: Point3::from(*point), normal: Vector3::from(normal.0) }
                    }
                    CutSpec::Obj { path: obj, transform } => {
                        let mesh =
                            load_obj(scene, obj, transform, Some(&format!("timeline[{index}]")), Closed::NotRequired)?;
                        CutSurface::Triangles(
                            (0..mesh.triangles.len()).filter_map(|t| mesh.triangle_points(t)).collect(),
                        )
                    }
                };
                TimedCut::Once { time: *time, surface: Some(surface) }
            }
            EventSpec::Blade { start, end, polygon, path, cutting_edges } => {
                if !(start.is_finite() && end.is_finite() && start <= end) {
                    return Err(build_error(format!("timeline[{index}]: blade window {start}..{end} is empty")));
                }
                let keyframes = path
                    .iter()
                    .map(|k| {
                        let [rx, ry, rz] = k.rotation_degrees.map(Real::to_radians);
                        Keyframe {
                            time: k.time,
                            translation: Vector3::from(k.translation),
                            rotation: UnitQuaternion::from_euler_angles(rx, ry, rz),
                        }
                    })
                    .collect();
                let polygon = polygon.iter().map(|p| Point3::from(*p)).collect();
                let mut blade = Blade::new(polygon, keyframes);
                if let Some(edges) = cutting_edges {
                    blade = blade.and_then(|b| b.with_cutting_edges(edges.clone()));
                }
                let blade = blade.map_err(|e| build_error(format!("timeline[{index}]: {e}")))?;
                TimedCut::Blade { start: *start, end: *end, blade, begun: false }
            }
        });
    }
    Ok(timeline)
}
