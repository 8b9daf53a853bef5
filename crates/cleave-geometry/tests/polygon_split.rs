//! `split_polygon` against areas computed by hand: a square cut straight and through two
//! corners, a U cut across its arms (three pieces) and along its notch's edge, a polygon the
//! plane only touches; the same U turned and moved in space with a tilted plane; and random
//! star-shaped polygons, whose pieces' areas must add up to the polygon's with every piece on
//! one side.

mod common;

use cleave_geometry::{PolygonSplit, PolygonSplitError, split_polygon};
use common::{Rng, plane};
use nalgebra::{Point3, Rotation3, Vector3};

/// The area of a planar polygon (Newell), signed along `normal`.
fn area(points: &[Point3<f64>], normal: &Vector3<f64>) -> f64 {
    let n = points.len();
    let twice: Vector3<f64> = (0..n).map(|i| points[i].coords.cross(&points[(i + 1) % n].coords)).sum();
    twice.dot(normal) / 2.0
}

/// Per piece: (side, area along `normal`), sorted.
fn pieces(split: &PolygonSplit, normal: &Vector3<f64>) -> Vec<(i8, f64)> {
    let mut out: Vec<(i8, f64)> = split
        .pieces
        .iter()
        .map(|p| {
            let points: Vec<Point3<f64>> = p.corners.iter().map(|&k| split.corners[k].1).collect();
            (p.side, area(&points, normal))
        })
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
    out
}

fn flat(xy: &[[f64; 2]]) -> Vec<Point3<f64>> {
    xy.iter().map(|p| Point3::new(p[0], p[1], 0.0)).collect()
}

fn close(found: &[(i8, f64)], expected: &[(i8, f64)]) {
    assert_eq!(found.len(), expected.len(), "{found:?} vs {expected:?}");
    for (f, e) in found.iter().zip(expected) {
        assert!(f.0 == e.0 && (f.1 - e.1).abs() < 1e-12, "{found:?} vs {expected:?}");
    }
}

/// The U: [0,3]² without the notch [1,2] × [1,3], counter-clockwise.
const U: [[f64; 2]; 8] =
    [[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [2.0, 3.0], [2.0, 1.0], [1.0, 1.0], [1.0, 3.0], [0.0, 3.0]];

#[test]
fn a_square_splits_into_one_piece_per_side() {
    let square = flat(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    let split = split_polygon(&square, &plane(Vector3::x(), 0.3), 0.0).unwrap();
    close(&pieces(&split, &Vector3::z()), &[(-1, 0.3), (1, 0.7)]);
    // Through two corners: the diagonal x + y = 1, no crossing inserted.
    let split = split_polygon(&square, &plane(Vector3::new(1.0, 1.0, 0.0), 0.5f64.sqrt()), 0.0).unwrap();
    assert_eq!(split.corners.len(), 4);
    close(&pieces(&split, &Vector3::z()), &[(-1, 0.5), (1, 0.5)]);
}

#[test]
fn a_u_cut_across_its_arms_leaves_three_pieces() {
    let u = flat(&U);
    // y = 2: below, the U's base with the notch's lower part (6 − 1); above, two arms.
    let split = split_polygon(&u, &plane(Vector3::y(), 2.0), 0.0).unwrap();
    close(&pieces(&split, &Vector3::z()), &[(-1, 5.0), (1, 1.0), (1, 1.0)]);
    // y = 1, along the notch's bottom edge: the base below, the two arms (2 each) above.
    let split = split_polygon(&u, &plane(Vector3::y(), 1.0), 0.0).unwrap();
    close(&pieces(&split, &Vector3::z()), &[(-1, 3.0), (1, 2.0), (1, 2.0)]);
    // x = 1.5, through the notch: two halves, each an L.
    let split = split_polygon(&u, &plane(Vector3::x(), 1.5), 0.0).unwrap();
    close(&pieces(&split, &Vector3::z()), &[(-1, 3.5), (1, 3.5)]);
}

#[test]
fn a_plane_that_only_touches_leaves_the_polygon_whole() {
    let u = flat(&U);
    for (normal, offset, side) in [(Vector3::y(), 3.0, -1), (Vector3::y(), 0.0, 1), (Vector3::z(), 0.0, 0)] {
        let split = split_polygon(&u, &plane(normal, offset), 0.0).unwrap();
        assert_eq!(split.pieces.len(), 1);
        assert_eq!(split.pieces[0].side, side);
        assert_eq!(split.pieces[0].corners, (0..8).collect::<Vec<_>>());
    }
    assert_eq!(split_polygon(&u[..2], &plane(Vector3::x(), 0.5), 0.0), Err(PolygonSplitError::TooFewCorners(2)));
    let line = flat(&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]);
    assert_eq!(split_polygon(&line, &plane(Vector3::x(), 0.5), 0.0), Err(PolygonSplitError::Degenerate));
}

/// The U turned about an oblique axis and moved, cut by the plane y = 2 carried along and then
/// tilted about the U's normal by 0.1 rad (still across both arms): the areas of the carried
/// cut are the flat ones, and the tilted cut's pieces add up to the U's 7.
#[test]
fn a_turned_and_moved_u_splits_as_the_flat_one() {
    let turn = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(Vector3::new(0.3, -0.8, 0.5)), 1.1);
    let shift = Vector3::new(0.7, -2.0, 5.0);
    let moved: Vec<Point3<f64>> = flat(&U).iter().map(|p| turn * p + shift).collect();
    let normal = turn * Vector3::z();
    let carried = plane(Vector3::y(), 2.0).map(|p| turn * p + shift);
    let split = split_polygon(&moved, &carried, 0.0).unwrap();
    close(&pieces(&split, &normal), &[(-1, 5.0), (1, 1.0), (1, 1.0)]);
    let tilt = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(normal), 0.1);
    let centre = turn * Point3::new(1.5, 2.0, 0.0) + shift;
    let tilted = carried.map(|p| centre + tilt * (p - centre));
    let split = split_polygon(&moved, &tilted, 0.0).unwrap();
    let found = pieces(&split, &normal);
    assert_eq!(found.iter().map(|p| p.0).collect::<Vec<_>>(), vec![-1, 1, 1], "{found:?}");
    assert!((found.iter().map(|p| p.1).sum::<f64>() - 7.0).abs() < 1e-12);
}

/// Random star-shaped polygons (12–40 corners, radii 0.2–1, so deeply non-convex) cut by
/// random planes and by planes through two of their corners: the pieces' areas are positive and add up to the polygon's to 1e-12; each
/// piece's corners lie on its side or on the plane; a plane with corners on both sides gives
/// pieces on both sides.
#[test]
fn random_stars_split_into_pieces_that_tile_them() {
    let mut rng = Rng(11);
    let mut many = 0;
    for trial in 0..500 {
        let n = 12 + (rng.next_u64() % 29) as usize;
        let star: Vec<Point3<f64>> = (0..n)
            .map(|k| {
                let angle = std::f64::consts::TAU * k as f64 / n as f64;
                let r = rng.range(0.2, 1.0);
                Point3::new(r * angle.cos(), r * angle.sin(), 0.0)
            })
            .collect();
        // Half the trials cut through two of the corners exactly (the plane through them and a
        // point above the first): corners on the plane are where tracing goes wrong.
        let cut = if trial % 2 == 0 {
            let normal = Vector3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-0.3, 0.3));
            plane(normal, rng.range(-0.5, 0.5))
        } else {
            let (i, j) = ((rng.next_u64() as usize) % n, (rng.next_u64() as usize) % n);
            let j = if i == j { (j + n / 2) % n } else { j };
            [star[i], star[i] + Vector3::z(), star[j]]
        };
        let split = split_polygon(&star, &cut, 0.0).unwrap_or_else(|e| panic!("trial {trial}: {e}"));
        let found = pieces(&split, &Vector3::z());
        let total = area(&star, &Vector3::z());
        let sum: f64 = found.iter().map(|p| p.1).sum();
        assert!((sum - total).abs() < 1e-12 * total, "trial {trial}: {sum} vs {total}");
        assert!(found.iter().all(|p| p.1 > 0.0), "trial {trial}: {found:?}");
        for piece in &split.pieces {
            assert!(piece.corners.iter().all(|&k| split.corners[k].2 == 0 || split.corners[k].2 == piece.side));
        }
        let sides: Vec<i8> = split.corners.iter().map(|c| c.2).collect();
        if sides.contains(&1) && sides.contains(&-1) {
            assert!(found.iter().any(|p| p.0 == 1) && found.iter().any(|p| p.0 == -1), "trial {trial}");
        }
        many += usize::from(found.len() > 2);
    }
    println!("{many} of 500 splits gave more than two pieces");
    // The stars are non-convex enough that many cuts leave several pieces on a side.
    assert!(many > 100, "{many}");
}
