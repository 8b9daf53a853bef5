//! Blades for progressive cutting: a planar polygon (the knife's face, in its own frame) moved
//! along a keyframed rigid path in rest space. Each step hands the backend only what the blade
//! covered since the previous step, as a triangle soup: the polygon at both poses and the strips
//! its edges swept. For a blade moving in its own plane the union over steps is exactly the
//! region it passed through, so a blade stopped inside the material leaves it connected beyond
//! its edge (docs/architecture.md, "The cut path").

use nalgebra::{Point3, UnitQuaternion, Vector3};

/// One pose of the blade at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe {
    /// Time [s].
    pub time: f64,
    /// Translation of the blade's frame.
    pub translation: Vector3<f64>,
    /// Rotation of the blade's frame.
    pub rotation: UnitQuaternion<f64>,
}

/// Why a blade is malformed (reported with the offending value, never a panic).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BladeError {
    /// Fewer than three polygon points.
    #[error("a blade polygon needs at least 3 points, got {0}")]
    Polygon(usize),
    /// A point or keyframe value that is not finite.
    #[error("blade value {0} is not finite")]
    NotFinite(f64),
    /// No keyframe, or keyframe times not strictly increasing.
    #[error("blade keyframe times must be strictly increasing, got {0:?}")]
    Times(Vec<f64>),
}

/// A planar polygon moved along keyframes.
#[derive(Clone, Debug, PartialEq)]
pub struct Blade {
    polygon: Vec<Point3<f64>>,
    keyframes: Vec<Keyframe>,
}

impl Blade {
    /// A blade from its polygon (blade frame; closed implicitly, convex or not, planar by intent)
    /// and its keyframes (times strictly increasing).
    pub fn new(polygon: Vec<Point3<f64>>, keyframes: Vec<Keyframe>) -> Result<Self, BladeError> {
        if polygon.len() < 3 {
            return Err(BladeError::Polygon(polygon.len()));
        }
        let values = polygon.iter().flat_map(|p| p.coords.iter().copied()).chain(keyframes.iter().flat_map(|k| {
            [k.time].into_iter().chain(k.translation.iter().copied()).chain(k.rotation.coords.iter().copied())
        }));
        for v in values {
            if !v.is_finite() {
                return Err(BladeError::NotFinite(v));
            }
        }
        if keyframes.is_empty() || keyframes.windows(2).any(|w| w[1].time <= w[0].time) {
            return Err(BladeError::Times(keyframes.iter().map(|k| k.time).collect()));
        }
        Ok(Self { polygon, keyframes })
    }

    /// The pose at time `t`: linear in translation, spherical-linear in rotation between
    /// keyframes, held before the first and after the last.
    pub fn pose(&self, t: f64) -> (Vector3<f64>, UnitQuaternion<f64>) {
        let first = self.keyframes[0];
        let last = self.keyframes[self.keyframes.len() - 1];
        if t <= first.time {
            return (first.translation, first.rotation);
        }
        if t >= last.time {
            return (last.translation, last.rotation);
        }
        let k = self.keyframes.partition_point(|k| k.time <= t) - 1;
        let (a, b) = (self.keyframes[k], self.keyframes[k + 1]);
        let s = (t - a.time) / (b.time - a.time);
        let rotation =
            a.rotation.try_slerp(&b.rotation, s, 1e-12).unwrap_or(if s < 0.5 { a.rotation } else { b.rotation });
        (a.translation.lerp(&b.translation, s), rotation)
    }

    /// The polygon placed at time `t`.
    pub fn polygon_at(&self, t: f64) -> Vec<Point3<f64>> {
        let (translation, rotation) = self.pose(t);
        self.polygon.iter().map(|p| rotation * p + translation).collect()
    }

    /// What the blade covers from `t0` to `t1`: the polygon at both poses (fans) and, per edge,
    /// the quad its endpoints swept (two triangles), with intermediate poses wherever a keyframe
    /// lies inside the interval so a turning blade is followed piecewise.
    pub fn swept(&self, t0: f64, t1: f64) -> Vec<[Point3<f64>; 3]> {
        let mut soup = Vec::new();
        fan(&self.polygon_at(t0), &mut soup);
        self.sweep(t0, t1, true, &mut soup);
        soup
    }

    /// What the blade newly covers from `t0` to `t1` when [`Blade::swept`] or this method
    /// already handed over everything up to `t0`: the quads the edges swept and the polygon at
    /// each later pose, except that the polygon at `t0` is left out (it was handed over last) and
    /// so is the polygon after a piece of motion that keeps it in its own plane (a translation
    /// along the plane, rotation unchanged): that polygon lies inside the polygon before the
    /// motion and the quads its edges swept. The union over a run of steps is the same region
    /// as with [`Blade::swept`], but a blade sliding through the material hands over a strip per
    /// step instead of its whole face again, and its face's fan diagonal does not split material
    /// anew at every step.
    pub fn swept_after(&self, t0: f64, t1: f64) -> Vec<[Point3<f64>; 3]> {
        let mut soup = Vec::new();
        self.sweep(t0, t1, false, &mut soup);
        soup
    }

    /// Appends the quads the edges sweep from `t0` to `t1` (piecewise between the keyframes
    /// inside) and the polygon at each later pose: always with `every_face`, else only after
    /// motion that leaves the polygon's plane.
    fn sweep(&self, t0: f64, t1: f64, every_face: bool, soup: &mut Vec<[Point3<f64>; 3]>) {
        let mut times = vec![t0];
        times.extend(self.keyframes.iter().map(|k| k.time).filter(|&t| t > t0 && t < t1));
        times.push(t1);
        let normal = self.normal();
        let (mut previous_pose, mut previous) = (self.pose(t0), self.polygon_at(t0));
        for &t in &times[1..] {
            let pose = self.pose(t);
            let current = self.polygon_at(t);
            let n = current.len();
            for i in 0..n {
                let j = (i + 1) % n;
                soup.push([previous[i], previous[j], current[j]]);
                soup.push([previous[i], current[j], current[i]]);
            }
            let moved = pose.0 - previous_pose.0;
            let in_plane =
                pose.1 == previous_pose.1 && (pose.1 * normal).dot(&moved).abs() <= IN_PLANE_TOLERANCE * moved.norm();
            if every_face || !in_plane {
                fan(&current, soup);
            }
            (previous_pose, previous) = (pose, current);
        }
    }

    /// Unit normal of the polygon in the blade's frame (Newell's method; zero for a polygon of
    /// zero area, whose face then counts as in its plane whenever the rotation holds: it covers
    /// nothing anyway).
    fn normal(&self) -> Vector3<f64> {
        let n = self.polygon.len();
        let origin = self.polygon[0].coords;
        let mut normal = Vector3::zeros();
        for i in 0..n {
            let (a, b) = (self.polygon[i].coords - origin, self.polygon[(i + 1) % n].coords - origin);
            normal += a.cross(&b);
        }
        normal.try_normalize(0.0).unwrap_or_else(Vector3::zeros)
    }
}

/// Relative size of the out-of-plane part of a motion below which the polygon after it is taken
/// to lie in the plane before it (rounding of the poses' translations).
const IN_PLANE_TOLERANCE: f64 = 1e-12;

/// Appends the fan of convex polygon `p` from its first corner.
fn fan(p: &[Point3<f64>], soup: &mut Vec<[Point3<f64>; 3]>) {
    for k in 1..p.len() - 1 {
        soup.push([p[0], p[k], p[k + 1]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inside_triangle_2d(p: (f64, f64), t: &[Point3<f64>; 3]) -> bool {
        let cross = |a: &Point3<f64>, b: &Point3<f64>| (b.x - a.x) * (p.1 - a.y) - (b.y - a.y) * (p.0 - a.x);
        let (c0, c1, c2) = (cross(&t[0], &t[1]), cross(&t[1], &t[2]), cross(&t[2], &t[0]));
        (c0 >= 0.0 && c1 >= 0.0 && c2 >= 0.0) || (c0 <= 0.0 && c1 <= 0.0 && c2 <= 0.0)
    }

    #[test]
    fn a_square_sliding_in_its_plane_covers_exactly_the_rectangle_it_swept() {
        // A unit square in z = 0 moved 2.5 along x from t = 0 to 1 in 7 steps: the union of the
        // step soups is [0, 3.5] × [0, 1] (the Minkowski sum), and nothing outside it.
        let square = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        let keys = vec![
            Keyframe { time: 0.0, translation: Vector3::zeros(), rotation: UnitQuaternion::identity() },
            Keyframe { time: 1.0, translation: Vector3::new(2.5, 0.0, 0.0), rotation: UnitQuaternion::identity() },
        ];
        let blade = Blade::new(square, keys).unwrap();
        let times: Vec<f64> = (0..=7).map(|k| k as f64 / 7.0).collect();
        let soup: Vec<[Point3<f64>; 3]> = times.windows(2).flat_map(|w| blade.swept(w[0], w[1])).collect();
        assert!(soup.iter().all(|t| t.iter().all(|p| p.z == 0.0)));
        for i in 0..80 {
            for j in 0..30 {
                let p = (-0.3 + 4.2 * (i as f64 + 0.5) / 80.0, -0.25 + 1.5 * (j as f64 + 0.5) / 30.0);
                let expected = p.0 > 0.0 && p.0 < 3.5 && p.1 > 0.0 && p.1 < 1.0;
                let covered = soup.iter().any(|t| inside_triangle_2d(p, t));
                assert_eq!(covered, expected, "point {p:?}");
            }
        }
    }

    fn area(soup: &[[Point3<f64>; 3]]) -> f64 {
        soup.iter().map(|t| 0.5 * (t[1] - t[0]).cross(&(t[2] - t[0])).norm()).sum()
    }

    fn unit_square() -> Vec<Point3<f64>> {
        vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ]
    }

    fn moving(by: Vector3<f64>) -> Vec<Keyframe> {
        vec![
            Keyframe { time: 0.0, translation: Vector3::zeros(), rotation: UnitQuaternion::identity() },
            Keyframe { time: 1.0, translation: by, rotation: UnitQuaternion::identity() },
        ]
    }

    #[test]
    fn a_sliding_blade_hands_over_strips_that_cover_the_same_rectangle() {
        // The square of the test above, first step with its face, later steps only what is new:
        // per step the two edges across the motion sweep 1 × 2.5/7 each (the faces, area 1 each,
        // are left out), and the union is still exactly [0, 3.5] × [0, 1].
        let blade = Blade::new(unit_square(), moving(Vector3::new(2.5, 0.0, 0.0))).unwrap();
        let times: Vec<f64> = (0..=7).map(|k| k as f64 / 7.0).collect();
        let mut soup = blade.swept(times[0], times[1]);
        for w in times[1..].windows(2) {
            let step = blade.swept_after(w[0], w[1]);
            assert!((area(&step) - 2.0 * 2.5 / 7.0).abs() < 1e-12, "area {}", area(&step));
            soup.extend(step);
        }
        for i in 0..80 {
            for j in 0..30 {
                let p = (-0.3 + 4.2 * (i as f64 + 0.5) / 80.0, -0.25 + 1.5 * (j as f64 + 0.5) / 30.0);
                let expected = p.0 > 0.0 && p.0 < 3.5 && p.1 > 0.0 && p.1 < 1.0;
                assert_eq!(soup.iter().any(|t| inside_triangle_2d(p, t)), expected, "point {p:?}");
            }
        }
    }

    #[test]
    fn a_blade_leaving_its_plane_hands_over_its_face_at_each_later_pose() {
        // Moved 0.7 along its normal in one step: four side quads of 1 × 0.7 and the face at the
        // end (area 1), not the face at the start. Tilted by 30° instead: the face comes too.
        let blade = Blade::new(unit_square(), moving(Vector3::new(0.0, 0.0, 0.7))).unwrap();
        let step = blade.swept_after(0.0, 1.0);
        assert!((area(&step) - (4.0 * 0.7 + 1.0)).abs() < 1e-12, "area {}", area(&step));
        assert!(step.iter().flatten().any(|p| p.z == 0.7));
        let turning = vec![
            Keyframe { time: 0.0, translation: Vector3::zeros(), rotation: UnitQuaternion::identity() },
            Keyframe {
                time: 1.0,
                translation: Vector3::zeros(),
                rotation: UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 30f64.to_radians()),
            },
        ];
        let blade = Blade::new(unit_square(), turning).unwrap();
        let face = blade.polygon_at(1.0);
        let step = blade.swept_after(0.0, 1.0);
        assert!(step.iter().any(|t| t == &[face[0], face[1], face[2]]));
    }

    #[test]
    fn poses_interpolate_and_hold_and_bad_blades_are_refused() {
        let keys = vec![
            Keyframe { time: 1.0, translation: Vector3::zeros(), rotation: UnitQuaternion::identity() },
            Keyframe {
                time: 3.0,
                translation: Vector3::new(0.0, 4.0, 0.0),
                rotation: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 1.0),
            },
        ];
        let tri = vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)];
        let blade = Blade::new(tri.clone(), keys.clone()).unwrap();
        let (t, r) = blade.pose(2.0);
        assert!((t - Vector3::new(0.0, 2.0, 0.0)).norm() < 1e-15);
        assert!((r.angle() - 0.5).abs() < 1e-12);
        assert_eq!(blade.pose(0.0).0, Vector3::zeros());
        assert_eq!(blade.pose(9.0).0, Vector3::new(0.0, 4.0, 0.0));
        assert_eq!(Blade::new(tri[..2].to_vec(), keys.clone()), Err(BladeError::Polygon(2)));
        let mut backwards = keys.clone();
        backwards.reverse();
        assert!(matches!(Blade::new(tri.clone(), backwards), Err(BladeError::Times(_))));
        let nan = vec![Point3::new(f64::NAN, 0.0, 0.0), Point3::origin(), Point3::new(0.0, 1.0, 0.0)];
        assert!(matches!(Blade::new(nan, keys), Err(BladeError::NotFinite(_))));
    }
}
