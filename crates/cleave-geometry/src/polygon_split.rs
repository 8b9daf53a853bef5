//! A planar polygon, convex or not, split by a plane into the pieces on each side, with the
//! sides decided exactly (`side3`): the first brick of cutting general polyhedra (the DG
//! backend's elements, kaufmann2008 §8; docs/math/polygon-split.md).

use crate::predicates::{kept_axes, side_of_plane};
use nalgebra::{Point2, Point3, Vector3};

/// A corner of a split polygon: one of the input corners, or the crossing of the plane with
/// the input edge from corner `i` to corner `i + 1` (cyclically).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitCorner {
    /// Input corner `i`.
    Vertex(usize),
    /// The crossing on the input edge `(i, i + 1 mod n)`.
    Crossing(usize),
}

/// One piece of a split polygon: the side it lies on (`+1`: where the plane's right-hand normal
/// points, `−1`: the other, `0`: the whole polygon lies in the plane) and its corners, indices
/// into [`PolygonSplit::corners`], in the input polygon's orientation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PolygonPiece {
    /// `+1`, `−1`, or `0` for a polygon in the plane.
    pub side: i8,
    /// Indices into [`PolygonSplit::corners`].
    pub corners: Vec<usize>,
}

/// A planar polygon split by a plane.
#[derive(Clone, Debug, PartialEq)]
pub struct PolygonSplit {
    /// The input corners with the crossings inserted, in order; with their positions and exact
    /// sides (crossings are on the plane: side `0`).
    pub corners: Vec<(SplitCorner, Point3<f64>, i8)>,
    /// The pieces; one when the plane does not cross the polygon's interior.
    pub pieces: Vec<PolygonPiece>,
}

/// Why a polygon could not be split.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PolygonSplitError {
    /// Fewer than three corners.
    #[error("a polygon needs three corners, got {0}")]
    TooFewCorners(usize),
    /// The corners enclose no area (their normal vanishes) or are not finite.
    #[error("the polygon is degenerate (no area or a non-finite corner)")]
    Degenerate,
    /// The pieces could not be traced (a polygon that is not simple).
    #[error("the polygon's pieces could not be traced: is it simple?")]
    NotSimple,
}

/// Splits the simple planar polygon `points` (in order, convex or not) by the plane through
/// `plane` (three points; its right-hand normal `(b − a) × (c − a)` points to side `+1`),
/// corners within `tolerance` (a distance) of it counting as on it.
///
/// Each corner's side is exact beyond the tolerance ([`side_of_plane`]); a crossing lies on an edge whose corners are on opposite sides,
/// at the float interpolation of their distances. The pieces are the faces of the polygon's
/// boundary joined with the chords of the plane's line inside it (between consecutive on-plane
/// corners along the line), traced with the interior on the left: a convex polygon gives at
/// most one piece per side, a non-convex one as many as the line leaves (docs/math/polygon-split.md).
pub fn split_polygon(
    points: &[Point3<f64>],
    plane: &[Point3<f64>; 3],
    tolerance: f64,
) -> Result<PolygonSplit, PolygonSplitError> {
    let n = points.len();
    if n < 3 {
        return Err(PolygonSplitError::TooFewCorners(n));
    }
    let normal = newell_normal(points);
    let finite = points.iter().all(|p| p.coords.iter().all(|c| c.is_finite()));
    // A NaN norm (a non-finite corner) fails the comparison too.
    if !finite || normal.norm().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(PolygonSplitError::Degenerate);
    }
    let [a, b, c] = plane;
    let signs: Vec<i8> = points.iter().map(|p| side_of_plane(plane, p, tolerance)).collect();
    let whole = |side: i8| PolygonSplit {
        corners: (0..n).map(|i| (SplitCorner::Vertex(i), points[i], signs[i])).collect(),
        pieces: vec![PolygonPiece { side, corners: (0..n).collect() }],
    };
    let (plus, minus) = (signs.contains(&1), signs.contains(&-1));
    if !(plus && minus) {
        return Ok(whole(if plus {
            1
        } else if minus {
            -1
        } else {
            0
        }));
    }
    // Corners with the crossings inserted.
    let plane_normal = (b - a).cross(&(c - a));
    let distance = |p: &Point3<f64>| plane_normal.dot(&(p - a));
    let mut corners = Vec::with_capacity(n + 4);
    for i in 0..n {
        let j = (i + 1) % n;
        corners.push((SplitCorner::Vertex(i), points[i], signs[i]));
        if signs[i] * signs[j] < 0 {
            let (di, dj) = (distance(&points[i]), distance(&points[j]));
            let t = if di != dj { (di / (di - dj)).clamp(0.0, 1.0) } else { 0.5 };
            corners.push((SplitCorner::Crossing(i), points[i] + t * (points[j] - points[i]), 0));
        }
    }
    let m = corners.len();
    // The polygon in 2D, counter-clockwise.
    let axis = normal.iamax();
    let (u, v) = kept_axes(axis);
    let flip = if normal[axis] < 0.0 { -1.0 } else { 1.0 };
    let flat: Vec<Point2<f64>> = corners.iter().map(|(_, p, _)| Point2::new(p[u], flip * p[v])).collect();
    // On-plane corners in order along the line.
    let line = normal.cross(&plane_normal);
    let mut on_line: Vec<usize> = (0..m).filter(|&k| corners[k].2 == 0).collect();
    on_line.sort_by(|&p, &q| line.dot(&corners[p].1.coords).total_cmp(&line.dot(&corners[q].1.coords)));
    // Outgoing edges of each corner: the boundary's, then chords.
    let mut outgoing: Vec<Vec<usize>> = (0..m).map(|k| vec![(k + 1) % m]).collect();
    for pair in on_line.windows(2) {
        let (p, q) = (pair[0], pair[1]);
        let adjacent = (p + 1) % m == q || (q + 1) % m == p;
        if adjacent || flat[p] == flat[q] {
            continue;
        }
        let middle = Point2::from((flat[p].coords + flat[q].coords) / 2.0);
        if contains(&flat, &middle) {
            outgoing[p].push(q);
            outgoing[q].push(p);
        }
    }
    // Trace every directed edge's face (interior on the left): at each corner, the outgoing edge
    // met first turning clockwise from the way back.
    let edges: usize = outgoing.iter().map(Vec::len).sum();
    let mut used: Vec<Vec<bool>> = outgoing.iter().map(|out| vec![false; out.len()]).collect();
    let mut pieces = Vec::new();
    for start in 0..m {
        for first in 0..outgoing[start].len() {
            if used[start][first] {
                continue;
            }
            let mut cycle = vec![start];
            let (mut from, mut slot) = (start, first);
            loop {
                used[from][slot] = true;
                let to = outgoing[from][slot];
                if to == start && cycle.len() > 1 && next_slot(&flat, &outgoing, from, to) == first {
                    break;
                }
                if cycle.len() > edges {
                    return Err(PolygonSplitError::NotSimple);
                }
                slot = next_slot(&flat, &outgoing, from, to);
                if used[to][slot] {
                    return Err(PolygonSplitError::NotSimple);
                }
                cycle.push(to);
                from = to;
            }
            let side = cycle.iter().map(|&k| corners[k].2).find(|&s| s != 0).unwrap_or(0);
            pieces.push(PolygonPiece { side, corners: cycle });
        }
    }
    Ok(PolygonSplit { corners, pieces })
}

/// At corner `at`, entered from `from`: the index into `outgoing[at]` of the edge met first
/// turning clockwise from the direction back to `from`.
fn next_slot(flat: &[Point2<f64>], outgoing: &[Vec<usize>], from: usize, at: usize) -> usize {
    let mut best = (0, f64::INFINITY);
    for (slot, &to) in outgoing[at].iter().enumerate() {
        let turn = clockwise_turn(&flat[at], &flat[from], &flat[to]);
        if turn < best.1 {
            best = (slot, turn);
        }
    }
    best.0
}

/// The clockwise angle at `at` from the direction to `back` to the direction to `to`, in
/// (0, 2π]: the way back itself comes last. Walking a planar graph by the least such turn keeps
/// the face on the left (the tracing here and the cap loops of `split_element`).
pub(crate) fn clockwise_turn(at: &Point2<f64>, back: &Point2<f64>, to: &Point2<f64>) -> f64 {
    let (b, d) = (back - at, to - at);
    let turn = (b.y.atan2(b.x) - d.y.atan2(d.x)).rem_euclid(std::f64::consts::TAU);
    if turn <= 0.0 { std::f64::consts::TAU } else { turn }
}

/// The normal of a planar polygon by Newell's formula, `Σ p_i × p_{i+1}` (twice its area
/// along the unit normal).
pub(crate) fn newell_normal(points: &[Point3<f64>]) -> Vector3<f64> {
    let n = points.len();
    (0..n).map(|i| points[i].coords.cross(&points[(i + 1) % n].coords)).sum()
}

/// Whether `p` lies inside the simple counter-clockwise polygon `polygon` (crossing number).
fn contains(polygon: &[Point2<f64>], p: &Point2<f64>) -> bool {
    let mut inside = false;
    for i in 0..polygon.len() {
        let (a, b) = (polygon[i], polygon[(i + 1) % polygon.len()]);
        if (a.y > p.y) != (b.y > p.y) {
            let x = a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x);
            if p.x < x {
                inside = !inside;
            }
        }
    }
    inside
}
