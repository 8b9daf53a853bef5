//! `split_element` against volumes computed by hand: a cube cut straight and obliquely (turned
//! and moved), a U-shaped prism cut across its arms (three children) and along its notch's
//! floor, a plane that only touches; every child closed (each directed edge met once the other
//! way round), the children's volumes adding up to the element's.

mod common;

use common::plane;

use cleave_geometry::{ElementSplit, FaceSource, SplitVertex, split_element};
use nalgebra::{Point3, Rotation3, Unit, Vector3};
use std::collections::HashMap;

/// A prism: the counter-clockwise polygon `xy` extruded from z = 0 to 1; vertex k at the
/// bottom, n + k at the top.
fn prism(xy: &[[f64; 2]]) -> (Vec<Point3<f64>>, Vec<Vec<u32>>) {
    let n = xy.len() as u32;
    let mut vertices: Vec<Point3<f64>> = xy.iter().map(|p| Point3::new(p[0], p[1], 0.0)).collect();
    vertices.extend(xy.iter().map(|p| Point3::new(p[0], p[1], 1.0)));
    let mut faces = vec![(0..n).rev().collect::<Vec<u32>>(), (n..2 * n).collect()];
    for k in 0..n {
        let j = (k + 1) % n;
        faces.push(vec![k, j, n + j, n + k]);
    }
    (vertices, faces)
}

const U: [[f64; 2]; 8] =
    [[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [2.0, 3.0], [2.0, 1.0], [1.0, 1.0], [1.0, 3.0], [0.0, 3.0]];

/// Per child: (side, volume), sorted; asserting each child is closed.
fn children(split: &ElementSplit, vertices: &[Point3<f64>]) -> Vec<(i8, f64)> {
    let position = |v: &SplitVertex| match *v {
        SplitVertex::Old(i) => vertices[i as usize],
        SplitVertex::Crossing(p, q) => split.crossings[&(p, q)],
    };
    let mut out: Vec<(i8, f64)> = split
        .children
        .iter()
        .map(|child| {
            let mut edges: HashMap<(SplitVertex, SplitVertex), i32> = HashMap::new();
            let mut volume = 0.0;
            for face in &child.faces {
                let p: Vec<Point3<f64>> = face.polygon.iter().map(position).collect();
                for k in 1..p.len() - 1 {
                    volume += p[0].coords.dot(&p[k].coords.cross(&p[k + 1].coords)) / 6.0;
                }
                for k in 0..face.polygon.len() {
                    let (u, v) = (face.polygon[k], face.polygon[(k + 1) % face.polygon.len()]);
                    *edges.entry((u, v)).or_default() += 1;
                }
            }
            for (&(u, v), &count) in &edges {
                assert_eq!(edges.get(&(v, u)).copied(), Some(count), "child not closed at {u:?} → {v:?}");
            }
            (child.side, volume)
        })
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
    out
}

fn close(found: &[(i8, f64)], expected: &[(i8, f64)], tolerance: f64) {
    assert_eq!(found.len(), expected.len(), "{found:?} vs {expected:?}");
    for (f, e) in found.iter().zip(expected) {
        assert!(f.0 == e.0 && (f.1 - e.1).abs() < tolerance, "{found:?} vs {expected:?}");
    }
}

#[test]
fn a_cube_splits_into_two_closed_children() {
    let (vertices, faces) = prism(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    let split = split_element(&vertices, &faces, &plane(Vector3::x(), 0.3), 1e-12).unwrap();
    close(&children(&split, &vertices), &[(-1, 0.3), (1, 0.7)], 1e-12);
    let caps = split.children.iter().map(|c| c.faces.iter().filter(|f| f.source == FaceSource::Cap).count());
    assert!(caps.into_iter().all(|n| n == 1));
}

/// The cube turned about an oblique axis and moved, cut by a plane through its centre along
/// (1, 2, 3) carried with it: the halves are equal (the cube's central symmetry maps one onto
/// the other), each ½. That plane passes through the corners (0, 0, 1) and (1, 1, 0), which
/// rounding moves off it by about 1e-16: the tolerance keeps them on it (with none, a crossing
/// lands on the corner and the face cannot be traced).
#[test]
fn a_turned_cube_cut_through_its_centre_splits_in_halves() {
    let (vertices, faces) = prism(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    let turn = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(-0.4, 0.9, 0.2)), 0.8);
    let shift = Vector3::new(3.0, -1.0, 0.5);
    let moved: Vec<Point3<f64>> = vertices.iter().map(|p| turn * p + shift).collect();
    let normal = Vector3::new(1.0, 2.0, 3.0);
    let cut = plane(normal, normal.normalize().dot(&Vector3::repeat(0.5))).map(|p| turn * p + shift);
    let split = split_element(&moved, &faces, &cut, 1e-12).unwrap();
    close(&children(&split, &moved), &[(-1, 0.5), (1, 0.5)], 1e-12);
}

#[test]
fn a_u_prism_cut_across_its_arms_leaves_three_children() {
    let (vertices, faces) = prism(&U);
    let split = split_element(&vertices, &faces, &plane(Vector3::y(), 2.0), 1e-12).unwrap();
    close(&children(&split, &vertices), &[(-1, 5.0), (1, 1.0), (1, 1.0)], 1e-12);
    // Along the notch's floor (a face in the plane, which stays with the base).
    let split = split_element(&vertices, &faces, &plane(Vector3::y(), 1.0), 1e-12).unwrap();
    close(&children(&split, &vertices), &[(-1, 3.0), (1, 2.0), (1, 2.0)], 1e-12);
    // Obliquely across both arms and the base: volumes add up to the U's 7.
    let split = split_element(&vertices, &faces, &plane(Vector3::new(0.3, 1.0, 0.2), 1.5), 1e-12).unwrap();
    let found = children(&split, &vertices);
    assert_eq!(found.len(), 3, "{found:?}");
    assert!((found.iter().map(|c| c.1).sum::<f64>() - 7.0).abs() < 1e-12);
}

#[test]
fn a_plane_that_only_touches_leaves_the_element_whole() {
    let (vertices, faces) = prism(&U);
    for (normal, offset, side) in [(Vector3::y(), 3.0, -1), (Vector3::z(), 0.0, 1), (Vector3::x(), -1.0, 1)] {
        let split = split_element(&vertices, &faces, &plane(normal, offset), 1e-12).unwrap();
        assert_eq!(split.children.len(), 1);
        assert_eq!(split.children[0].side, side);
        assert_eq!(split.children[0].faces.len(), faces.len());
    }
}

/// Random star-shaped prisms (10–30 corners, radii 0.2–1: non-convex), turned and moved, cut
/// by random planes and by planes through two of their vertices: every child closed, the
/// children's volumes positive and adding up to the prism's (its base's area × 1) to 1e-12,
/// and many cuts leave more than two children (46 of 300).
#[test]
fn random_star_prisms_split_into_closed_children_that_fill_them() {
    let mut state = 7u64;
    let mut next = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut many = 0;
    for trial in 0..300 {
        let n = 10 + (next() * 21.0) as usize;
        let star: Vec<[f64; 2]> = (0..n)
            .map(|k| {
                let angle = std::f64::consts::TAU * k as f64 / n as f64;
                let r = 0.2 + 0.8 * next();
                [r * angle.cos(), r * angle.sin()]
            })
            .collect();
        let base: f64 =
            (0..n).map(|k| star[k][0] * star[(k + 1) % n][1] - star[(k + 1) % n][0] * star[k][1]).sum::<f64>() / 2.0;
        let (vertices, faces) = prism(&star);
        let turn = Rotation3::from_axis_angle(
            &Unit::new_normalize(Vector3::new(next() - 0.5, next() - 0.5, next())),
            3.0 * next(),
        );
        let shift = Vector3::new(next(), next(), next()) * 4.0;
        let moved: Vec<Point3<f64>> = vertices.iter().map(|p| turn * p + shift).collect();
        let cut = if trial % 2 == 0 {
            let normal = Vector3::new(next() - 0.5, next() - 0.5, 0.6 * (next() - 0.5));
            plane(normal, normal.normalize().dot(&Vector3::new(0.0, 0.0, 0.5)) + 0.6 * (next() - 0.5))
                .map(|p| turn * p + shift)
        } else {
            let (i, j) = ((next() * 2.0 * n as f64) as usize % (2 * n), (next() * n as f64) as usize % n);
            let j = if i % n == j { (j + n / 2) % n } else { j };
            [moved[i], moved[j], moved[(j + 1) % n] + turn * Vector3::new(0.0, 0.0, 0.37)]
        };
        let split = split_element(&moved, &faces, &cut, 1e-12).unwrap_or_else(|e| panic!("trial {trial}: {e}"));
        let found = children(&split, &moved);
        let sum: f64 = found.iter().map(|c| c.1).sum();
        assert!((sum - base).abs() < 1e-12 * base, "trial {trial}: {sum} vs {base}");
        assert!(found.iter().all(|c| c.1 > 0.0), "trial {trial}: {found:?}");
        many += usize::from(found.len() > 2);
    }
    println!("{many} of 300 cuts left more than two children");
    assert!(many > 30, "{many}");
}
