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
        let mut times = vec![t0];
        times.extend(self.keyframes.iter().map(|k| k.time).filter(|&t| t > t0 && t < t1));
        times.push(t1);
        let mut soup = Vec::new();
        let fan = |p: &[Point3<f64>], soup: &mut Vec<[Point3<f64>; 3]>| {
            for k in 1..p.len() - 1 {
                soup.push([p[0], p[k], p[k + 1]]);
            }
        };
        let mut previous = self.polygon_at(times[0]);
        fan(&previous, &mut soup);
        for &t in &times[1..] {
            let current = self.polygon_at(t);
            let n = current.len();
            for i in 0..n {
                let j = (i + 1) % n;
                soup.push([previous[i], previous[j], current[j]]);
                soup.push([previous[i], current[j], current[i]]);
            }
            fan(&current, &mut soup);
            previous = current;
        }
        soup
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
