//! Blades for progressive cutting: a planar polygon (the knife, in its own frame) moved along a
//! keyframed rigid path in rest space. A blade separates material along the surface its cutting
//! edges sweep, and along its polygon only at its first pose (an incision where it starts inside
//! the material); its face pushing material aside is not modelled. Each step hands the backend
//! what the cutting edges swept since the previous step, as a triangle soup, so a tilted blade
//! leaves one swept surface and a turning blade a ruled surface, not a fan of poses
//! (docs/math/blades.md, docs/architecture.md "The cut path").

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
    /// A named cutting edge that the polygon does not have.
    #[error(
        "blade cutting edge {edge} does not exist: the polygon has {edges} edges (edge i joins points i and i + 1)"
    )]
    Edge {
        /// The edge named.
        edge: usize,
        /// How many edges the polygon has.
        edges: usize,
    },
    /// A polygon of zero area has no plane, so no edge can be said to lead.
    #[error("a blade polygon needs a non-zero area to have a plane")]
    Flat,
}

/// Which edges of the polygon cut.
#[derive(Clone, Debug, PartialEq)]
enum CuttingEdges {
    /// Those that lead the motion: moving into material within the polygon's plane.
    Leading,
    /// The edges named (edge `i` joins points `i` and `i + 1`), whatever their motion.
    Named(Vec<usize>),
}

/// A planar polygon moved along keyframes.
#[derive(Clone, Debug, PartialEq)]
pub struct Blade {
    polygon: Vec<Point3<f64>>,
    keyframes: Vec<Keyframe>,
    /// Unit normal of the polygon in the blade's frame (Newell's method).
    normal: Vector3<f64>,
    edges: CuttingEdges,
    /// Per edge, how many segments each swept strip is split into along the edge, so that the
    /// strip follows the ruled surface where the edge's points move in turning directions
    /// (one for a path that does not turn).
    segments: Vec<usize>,
}

impl Blade {
    /// A blade from its polygon (blade frame; closed implicitly, planar by intent, of non-zero
    /// area, convex where its incision matters: the incision is its fan) and its keyframes
    /// (times strictly increasing). Its cutting edges are the ones leading the motion;
    /// [`Blade::with_cutting_edges`] names them instead.
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
        let normal = newell_normal(&polygon).ok_or(BladeError::Flat)?;
        let mut blade =
            Self { segments: vec![1; polygon.len()], polygon, keyframes, normal, edges: CuttingEdges::Leading };
        blade.segments = blade.edge_segments();
        Ok(blade)
    }

    /// Per edge, the segments a strip needs so that the directions in which neighbouring segment
    /// ends move (across the edge) differ by at most [`MAX_TWIST`] anywhere on the path. For a
    /// rigid motion over a short time those directions depend on the ratio of turn to
    /// translation, not on the time, so the path's sub-intervals of [`Blade::sweep`] are sampled;
    /// one count per edge for the whole path keeps the strips of consecutive steps sharing their
    /// vertices exactly.
    fn edge_segments(&self) -> Vec<usize> {
        let n = self.polygon.len();
        let mut segments = vec![1usize; n];
        let (first, last) = (self.keyframes[0].time, self.keyframes[self.keyframes.len() - 1].time);
        let times = self.sub_intervals(first, last);
        for w in times.windows(2) {
            let (before, after) = (self.polygon_at(w[0]), self.polygon_at(w[1]));
            for i in 0..n {
                let j = (i + 1) % n;
                let along = (before[j] - before[i]).normalize();
                let across = |k: usize| {
                    let moved = after[k] - before[k];
                    moved - along * along.dot(&moved)
                };
                let (a, b) = (across(i), across(j));
                if a.norm() > 0.0 && b.norm() > 0.0 {
                    let twist = a.angle(&b);
                    let needed = (twist / MAX_TWIST).ceil() as usize;
                    segments[i] = segments[i].max(needed.min(MAX_SEGMENTS));
                }
            }
        }
        segments
    }

    /// The times from `t0` to `t1` at which a sweep places the blade: the keyframes between and
    /// enough more that the blade turns by at most [`MAX_TURN`] from one to the next.
    fn sub_intervals(&self, t0: f64, t1: f64) -> Vec<f64> {
        let mut times = vec![t0];
        let mut knots: Vec<f64> = self.keyframes.iter().map(|k| k.time).filter(|&t| t > t0 && t < t1).collect();
        knots.push(t1);
        for &t in &knots {
            let from = *times.last().expect("starts with t0");
            let turn = self.pose(from).1.angle_to(&self.pose(t).1);
            let pieces = (turn / MAX_TURN).ceil().max(1.0) as usize;
            for k in 1..pieces {
                times.push(from + (t - from) * k as f64 / pieces as f64);
            }
            times.push(t);
        }
        times
    }

    /// The same blade cutting with the edges named (edge `i` joins points `i` and `i + 1`,
    /// the last joins the last point and the first), whatever their motion.
    pub fn with_cutting_edges(mut self, edges: Vec<usize>) -> Result<Self, BladeError> {
        let n = self.polygon.len();
        if let Some(&edge) = edges.iter().find(|&&e| e >= n) {
            return Err(BladeError::Edge { edge, edges: n });
        }
        self.edges = CuttingEdges::Named(edges);
        Ok(self)
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

    /// What the blade cuts from `t0` to `t1` when it starts cutting at `t0`: the incision (its
    /// polygon at `t0`, where it starts inside the material) and what its cutting edges sweep.
    pub fn swept(&self, t0: f64, t1: f64) -> Vec<[Point3<f64>; 3]> {
        let mut soup = Vec::new();
        fan(&self.polygon_at(t0), &mut soup);
        self.sweep(t0, t1, &mut soup);
        soup
    }

    /// What the blade newly cuts from `t0` to `t1` when [`Blade::swept`] or this method already
    /// handed over everything up to `t0`: the surface its cutting edges sweep, nothing of its
    /// face. Over a run of steps the strips of consecutive steps share their edges exactly (the
    /// edge at `t0` is computed from the same time as the step before's edge at its end).
    pub fn swept_after(&self, t0: f64, t1: f64) -> Vec<[Point3<f64>; 3]> {
        let mut soup = Vec::new();
        self.sweep(t0, t1, &mut soup);
        soup
    }

    /// Appends the strips the cutting edges sweep from `t0` to `t1`: per cutting edge and
    /// sub-interval ([`Blade::sub_intervals`]) a strip of quads (two triangles each) between the
    /// edge's two poses, split along the edge into its [`Blade::edge_segments`], so a turning
    /// edge is followed along its ruled surface (two triangles across a twisted quad would
    /// measure its area by the trapezoidal rule at the quad's two ends). An edge cuts in a
    /// sub-interval when it leads there (an endpoint moves outward across it within the
    /// polygon's plane at the sub-interval's start), or when the scene names it.
    fn sweep(&self, t0: f64, t1: f64, soup: &mut Vec<[Point3<f64>; 3]>) {
        if t1 <= t0 {
            return;
        }
        let times = self.sub_intervals(t0, t1);
        let n = self.polygon.len();
        let mut previous = self.polygon_at(t0);
        let mut previous_rotation = self.pose(t0).1;
        for &t in &times[1..] {
            let current = self.polygon_at(t);
            for i in 0..n {
                let j = (i + 1) % n;
                let cuts = match &self.edges {
                    CuttingEdges::Named(edges) => edges.contains(&i),
                    CuttingEdges::Leading => {
                        // Outward normal of edge i within the plane: edge × normal for a
                        // polygon wound counter-clockwise about its normal.
                        let outward = previous_rotation * (self.polygon[j] - self.polygon[i]).cross(&self.normal);
                        [i, j].iter().any(|&k| {
                            let moved = current[k] - previous[k];
                            outward.dot(&moved) > LEAD_TOLERANCE * outward.norm() * moved.norm()
                        })
                    }
                };
                if cuts {
                    let m = self.segments[i];
                    let at = |p: &[Point3<f64>], k: usize| {
                        if k == 0 {
                            p[i]
                        } else if k == m {
                            p[j]
                        } else {
                            p[i] + (p[j] - p[i]) * (k as f64 / m as f64)
                        }
                    };
                    for k in 0..m {
                        let (a, b, c, d) =
                            (at(&previous, k), at(&previous, k + 1), at(&current, k + 1), at(&current, k));
                        soup.push([a, b, c]);
                        soup.push([a, c, d]);
                    }
                }
            }
            previous = current;
            previous_rotation = self.pose(t).1;
        }
    }
}

/// The largest turn of the blade [rad] between two poses of a sweep: the chord between them
/// stands in for the arc its points follow (relative area error about turn² / 24, 2e-4).
pub const MAX_TURN: f64 = 4.0 * std::f64::consts::PI / 180.0;

/// The largest angle [rad] between the directions in which the two ends of one swept quad move
/// across its edge: two triangles over a quad twisted by α measure its area too large by about
/// α² / 12 (8e-4 at 5°; docs/math/blades.md).
pub const MAX_TWIST: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// At most this many segments per edge and strip (a path turning about a point on the edge
/// twists its strips by up to 180°).
const MAX_SEGMENTS: usize = 64;

/// Cosine of the angle between an endpoint's motion and its edge's outward normal below which
/// the edge does not lead: rounding of the poses, not a motion into the material.
const LEAD_TOLERANCE: f64 = 1e-9;

/// Unit normal of a polygon by Newell's method (`None` for zero area).
fn newell_normal(polygon: &[Point3<f64>]) -> Option<Vector3<f64>> {
    let n = polygon.len();
    let origin = polygon[0].coords;
    let mut normal = Vector3::zeros();
    for i in 0..n {
        let (a, b) = (polygon[i].coords - origin, polygon[(i + 1) % n].coords - origin);
        normal += a.cross(&b);
    }
    let scale = polygon.iter().map(|p| (p.coords - origin).norm_squared()).fold(0.0, f64::max);
    if normal.norm() <= 1e-12 * scale { None } else { Some(normal.normalize()) }
}

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
    fn a_sliding_blade_hands_over_the_leading_strip_and_covers_the_same_rectangle() {
        // The square of the test above, first step with its face, later steps only what is new:
        // per step the leading edge (x = 1 at the start) sweeps 1 × 2.5/7; the trailing edge
        // moves into what is cut already and the edges along the motion sweep nothing. The union
        // is still exactly [0, 3.5] × [0, 1].
        let blade = Blade::new(unit_square(), moving(Vector3::new(2.5, 0.0, 0.0))).unwrap();
        let times: Vec<f64> = (0..=7).map(|k| k as f64 / 7.0).collect();
        let mut soup = blade.swept(times[0], times[1]);
        for w in times[1..].windows(2) {
            let step = blade.swept_after(w[0], w[1]);
            assert!((area(&step) - 2.5 / 7.0).abs() < 1e-12, "area {}", area(&step));
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

    /// A knife 0.4 wide and 0.15 tall in its frame's plane x = 0, cutting edge along y at z = 0.
    fn knife() -> Vec<Point3<f64>> {
        vec![
            Point3::new(0.0, -0.2, 0.0),
            Point3::new(0.0, 0.2, 0.0),
            Point3::new(0.0, 0.2, 0.15),
            Point3::new(0.0, -0.2, 0.15),
        ]
    }

    #[test]
    fn a_tilted_blade_coming_down_cuts_the_vertical_plane_its_edge_sweeps() {
        // The knife tilted 20° about its edge (y) and pushed straight down 0.3 in 9 steps: only
        // the edge leads (within the tilted plane it moves outward by cos 20° of the motion;
        // the side edges move along their own line and outward by nothing), so every step hands
        // over a strip of the plane x = 0.01 and nothing else: 0.4 × 0.3 in all.
        let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 20f64.to_radians());
        let keys = vec![
            Keyframe { time: 0.0, translation: Vector3::new(0.01, 0.0, 0.2), rotation: tilt },
            Keyframe { time: 1.0, translation: Vector3::new(0.01, 0.0, -0.1), rotation: tilt },
        ];
        let blade = Blade::new(knife(), keys).unwrap();
        let mut total = 0.0;
        for k in 0..9 {
            let step = blade.swept_after(k as f64 / 9.0, (k + 1) as f64 / 9.0);
            assert_eq!(step.len(), 2, "step {k}: one quad");
            assert!(step.iter().flatten().all(|p| (p.x - 0.01).abs() < 1e-15), "off the plane x = 0.01");
            total += area(&step);
        }
        assert!((total - 0.4 * 0.3).abs() < 1e-12, "area {total}");
        // Pushed along its own normal instead, no edge leads: it cuts nothing.
        let normal = tilt * Vector3::x();
        let flat = vec![
            Keyframe { time: 0.0, translation: Vector3::zeros(), rotation: tilt },
            Keyframe { time: 1.0, translation: 0.3 * normal, rotation: tilt },
        ];
        assert!(Blade::new(knife(), flat).unwrap().swept_after(0.0, 1.0).is_empty());
    }

    #[test]
    fn a_turning_blade_sweeps_a_helicoid_of_the_analytic_area() {
        // The knife's edge (half length a = 0.2) turning 35° about the vertical through its
        // middle while it descends H = 0.15: a helicoid (s cos φ, s sin φ, -c φ), c = H / θ, of
        // area θ (a √(a² + c²) + c² asinh(a / c)). Steps of 1/6 of the motion turn 5.8°
        // each, so the sweep is followed in sub-intervals of at most MAX_TURN.
        let (a, theta, drop) = (0.2f64, 35f64.to_radians(), 0.15);
        let c = drop / theta;
        let exact = theta * (a * (a * a + c * c).sqrt() + c * c * (a / c).asinh());
        let keys = vec![
            Keyframe { time: 0.0, translation: Vector3::zeros(), rotation: UnitQuaternion::identity() },
            Keyframe {
                time: 1.0,
                translation: Vector3::new(0.0, 0.0, -drop),
                rotation: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), theta),
            },
        ];
        let blade = Blade::new(knife(), keys).unwrap();
        let soup: Vec<_> = (0..6).flat_map(|k| blade.swept_after(k as f64 / 6.0, (k + 1) as f64 / 6.0)).collect();
        let quads = soup.len() / 2;
        assert!(quads >= 9 * 16, "{quads} quads for 35° and a 78° twist along the edge");
        let relative = (area(&soup) - exact).abs() / exact;
        assert!(relative < 1e-3, "area {} against {exact}: {relative:e}", area(&soup));
        // Every swept point lies on the helicoid: at height z the ruling is turned by -z / c.
        for p in soup.iter().flatten() {
            let phi = -p.z / c;
            let off = Vector3::new(phi.cos(), phi.sin(), 0.0).dot(&p.coords);
            assert!(off.abs() < 1e-15, "{p} off the helicoid by {off}");
        }
        // One quad per step and edge (no segments, no sub-intervals) is off by far more.
        let coarse: f64 = (0..6)
            .map(|k| {
                let (p, q) = (blade.polygon_at(k as f64 / 6.0), blade.polygon_at((k + 1) as f64 / 6.0));
                area(&[[p[0], p[1], q[1]], [p[0], q[1], q[0]]])
            })
            .sum();
        assert!((coarse - exact).abs() / exact > 3e-3, "coarse {coarse} against {exact}");
    }

    #[test]
    fn named_edges_cut_whatever_their_motion_and_bad_names_are_refused() {
        // The knife pushed along its own normal, its top edge (2) named: that edge's strip only.
        let keys = moving(Vector3::new(0.3, 0.0, 0.0));
        let blade = Blade::new(knife(), keys.clone()).unwrap().with_cutting_edges(vec![2]).unwrap();
        let soup = blade.swept_after(0.0, 1.0);
        assert_eq!(soup.len(), 2);
        assert!(soup.iter().flatten().all(|p| p.z == 0.15));
        assert!((area(&soup) - 0.4 * 0.3).abs() < 1e-12);
        let refused = Blade::new(knife(), keys.clone()).unwrap().with_cutting_edges(vec![4]);
        assert_eq!(refused, Err(BladeError::Edge { edge: 4, edges: 4 }));
        let line = vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(2.0, 0.0, 0.0)];
        assert_eq!(Blade::new(line, keys), Err(BladeError::Flat));
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
