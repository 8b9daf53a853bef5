//! Tests of `voxelize`: exact cell sets for a box, bounds for a sphere, and consistency
//! checks (winding numbers, parry overlap tests) for the bunny.

mod common;

use std::collections::HashSet;

use cleave_geometry::{GeometryError, MAX_GRID_CELLS, TriangleMesh, VoxelGrid, voxelize};
use common::{BUNNY_VOLUME, Rng, box_mesh, bunny, icosphere, unit_cube};
use nalgebra::{Point3, Vector3};
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector;
use parry3d_f64::query::details::intersection_test_aabb_triangle;
use parry3d_f64::shape::Triangle;

/// Structural invariants of any grid.
fn check_structure(g: &VoxelGrid, triangle_count: usize) {
    assert_eq!(g.cell_triangles_offsets.len(), g.cells.len() + 1);
    assert_eq!(g.cell_triangles_offsets[0], 0);
    assert_eq!(*g.cell_triangles_offsets.last().unwrap() as usize, g.cell_triangles.len());
    let key = |c: &[i32; 3]| (c[2], c[1], c[0]);
    for w in g.cells.windows(2) {
        assert!(key(&w[0]) < key(&w[1]), "cells not sorted by (k, j, i): {w:?}");
    }
    for (c, cell) in g.cells.iter().enumerate() {
        assert!((0..3).all(|d| cell[d] >= 0 && cell[d] < g.dims[d]), "{cell:?}");
        assert_eq!(g.find(*cell), Some(c));
        let tris = g.triangles_of(c);
        assert!(tris.windows(2).all(|w| w[0] < w[1]));
        assert!(tris.iter().all(|&t| (t as usize) < triangle_count));
    }
}

/// Cells (i, j, k) of the grid whose closed cube intersects the closed box [lo, hi],
/// computed per axis from the grid origin.
fn expected_box_cells(g: &VoxelGrid, lo: [f64; 3], hi: [f64; 3]) -> HashSet<[i32; 3]> {
    let axis = |d: usize| -> Vec<i32> {
        (-5..g.dims[d] + 5)
            .filter(|&i| {
                let a = g.origin[d] + f64::from(i) * g.cell_size;
                let b = a + g.cell_size;
                a <= hi[d] && b >= lo[d]
            })
            .collect()
    };
    let (xs, ys, zs) = (axis(0), axis(1), axis(2));
    let mut set = HashSet::new();
    for &i in &xs {
        for &j in &ys {
            for &k in &zs {
                set.insert([i, j, k]);
            }
        }
    }
    set
}

fn check_box(h: f64, expected_dims: [i32; 3]) {
    let lo = [0.3, -1.7, 2.1];
    let size = [1.0, 2.0, 3.0];
    let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
    let m = box_mesh(lo, size);
    let g = voxelize(&m, h).unwrap();
    check_structure(&g, 12);
    assert_eq!(g.dims, expected_dims);
    assert!((g.origin - Point3::new(lo[0] - h / 2.0, lo[1] - h / 2.0, lo[2] - h / 2.0)).norm() < 1e-15);
    let n: i32 = expected_dims.iter().product();
    assert_eq!(g.len(), n as usize);
    let listed: HashSet<[i32; 3]> = g.cells.iter().copied().collect();
    assert_eq!(listed, expected_box_cells(&g, lo, hi));

    // Box faces pass through the centers of the outermost cell layers: exactly the shell
    // intersects the surface, the rest is inside.
    let interior: i32 = expected_dims.iter().map(|n| n - 2).product();
    let surface = (0..g.len()).filter(|&c| g.is_surface(c)).count();
    assert_eq!(surface as i32, n - interior);
    for (c, cell) in g.cells.iter().enumerate() {
        let on_shell = (0..3).any(|d| cell[d] == 0 || cell[d] == g.dims[d] - 1);
        assert_eq!(g.is_surface(c), on_shell, "{cell:?}");
        // Every listed triangle lies in a box face that passes through this cell.
        let cmin = g.cell_min(*cell);
        for &t in g.triangles_of(c) {
            let [a, b, c3] = m.triangle_points(t as usize).unwrap();
            let d = (0..3).find(|&d| a[d] == b[d] && b[d] == c3[d]).unwrap();
            assert!(cmin[d] <= a[d] && a[d] <= cmin[d] + h, "cell {cell:?} triangle {t}");
        }
    }
}

#[test]
fn box_cells_are_exactly_those_touching_the_box() {
    // Per axis floor(L / h + 1/2) + 1 cells.
    check_box(0.25, [5, 9, 13]);
    check_box(0.1, [11, 21, 31]);
}

#[test]
fn icosphere_cells_bound_the_volume() {
    let center = Point3::new(0.1, 0.2, -0.3);
    let radius = 1.0;
    let m = icosphere(3, radius, center);
    assert_eq!(m.triangles.len(), 1280);
    m.validate_closed().unwrap();
    // Inscribed radius: smallest distance from the center to a face plane.
    let r_in = (0..m.triangles.len())
        .map(|t| {
            let [a, b, c] = m.triangle_points(t).unwrap();
            let n = (b - a).cross(&(c - a)).normalize();
            n.dot(&(a - center)).abs()
        })
        .fold(f64::INFINITY, f64::min);
    assert!(r_in > 0.98 && r_in < radius);
    for h in [0.1, 0.07] {
        let g = voxelize(&m, h).unwrap();
        check_structure(&g, m.triangles.len());
        let covered = g.len() as f64 * h.powi(3);
        let solid = 4.0 / 3.0 * std::f64::consts::PI * r_in.powi(3);
        let dilated = 4.0 / 3.0 * std::f64::consts::PI * (radius + h * 3f64.sqrt()).powi(3);
        assert!(covered >= m.signed_volume() && covered >= solid, "{covered}");
        assert!(covered <= dilated, "{covered} > {dilated}");

        // Cell by cell: cubes inside the inscribed sphere must be listed, cubes outside
        // the circumscribed sphere must not.
        let listed: HashSet<[i32; 3]> = g.cells.iter().copied().collect();
        let (mut must, mut must_not) = (0, 0);
        for k in -1..=g.dims[2] {
            for j in -1..=g.dims[1] {
                for i in -1..=g.dims[0] {
                    let lo = g.cell_min([i, j, k]) - center;
                    let hi = lo + Vector3::repeat(h);
                    let far = Vector3::from_fn(|d, _| lo[d].abs().max(hi[d].abs())).norm();
                    let near = Vector3::from_fn(|d, _| {
                        if lo[d] > 0.0 {
                            lo[d]
                        } else if hi[d] < 0.0 {
                            -hi[d]
                        } else {
                            0.0
                        }
                    })
                    .norm();
                    if far < r_in {
                        must += 1;
                        assert!(listed.contains(&[i, j, k]), "inner cell {i} {j} {k} missing");
                    }
                    if near > radius {
                        must_not += 1;
                        assert!(!listed.contains(&[i, j, k]), "outer cell {i} {j} {k} listed");
                    }
                }
            }
        }
        assert!(must > 1000 && must_not > 1000);
        // Inside cells lie inside: their centers have winding number 1.
        for (c, cell) in g.cells.iter().enumerate() {
            if !g.is_surface(c) {
                let w = m.winding_number(&g.cell_center(*cell));
                assert!((w - 1.0).abs() < 1e-9, "{cell:?}: {w}");
            }
        }
    }
}

fn parry_overlap(m: &TriangleMesh, t: usize, lo: Point3<f64>, hi: Point3<f64>) -> bool {
    let v = |q: &Point3<f64>| Vector::new(q.x, q.y, q.z);
    let [a, b, c] = m.triangle_points(t).unwrap();
    intersection_test_aabb_triangle(&Aabb::new(v(&lo), v(&hi)), &Triangle::new(v(&a), v(&b), v(&c)))
}

#[test]
fn bunny_voxels_are_consistent() {
    let m = bunny();
    let h = 0.29;
    let g = voxelize(&m, h).unwrap();
    check_structure(&g, m.triangles.len());
    assert!((9_000..12_000).contains(&g.len()), "{}", g.len());
    assert!(g.len() as f64 * h.powi(3) >= BUNNY_VOLUME);

    // Each vertex lies in a listed cell that lists every triangle using the vertex.
    let mut incident = vec![Vec::new(); m.vertices.len()];
    for (t, tri) in m.triangles.iter().enumerate() {
        for &i in tri {
            incident[i as usize].push(t as u32);
        }
    }
    for (v, p) in m.vertices.iter().enumerate() {
        let cell = g.cell_of(p).unwrap();
        let c = g.find(cell).unwrap_or_else(|| panic!("vertex {v} in unlisted cell {cell:?}"));
        for t in &incident[v] {
            assert!(g.triangles_of(c).contains(t), "vertex {v}: triangle {t} missing in {cell:?}");
        }
    }

    // Triangle lists agree with parry's overlap test on every cell near a sample of
    // triangles (disagreement allowed only within 1e-8 h of touching).
    let mut listed_pairs = HashSet::new();
    for c in 0..g.len() {
        for &t in g.triangles_of(c) {
            listed_pairs.insert((g.cells[c], t));
        }
    }
    let eps = Vector3::repeat(1e-8 * h);
    let mut checked = 0;
    for t in (0..m.triangles.len()).step_by(5) {
        let [a, b, c] = m.triangle_points(t).unwrap();
        let lo = g.cell_of(&a.inf(&b).inf(&c)).unwrap();
        let hi = g.cell_of(&a.sup(&b).sup(&c)).unwrap();
        for k in lo[2] - 1..=hi[2] + 1 {
            for j in lo[1] - 1..=hi[1] + 1 {
                for i in lo[0] - 1..=hi[0] + 1 {
                    let cmin = g.cell_min([i, j, k]);
                    let cmax = cmin + Vector3::repeat(h);
                    let listed = listed_pairs.contains(&([i, j, k], t as u32));
                    if listed != parry_overlap(&m, t, cmin, cmax) {
                        assert!(
                            !parry_overlap(&m, t, cmin + eps, cmax - eps)
                                && parry_overlap(&m, t, cmin - eps, cmax + eps),
                            "triangle {t} cell {:?}: listed {listed}",
                            [i, j, k]
                        );
                    }
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 10_000);

    // Every triangle is listed somewhere.
    let used: HashSet<u32> = g.cell_triangles.iter().copied().collect();
    assert_eq!(used.len(), m.triangles.len());

    // Inside cells have winding number 1 at their centers; cells of the padded grid that
    // are not listed have winding number 0.
    let mut rng = Rng(11);
    let inside: Vec<usize> = (0..g.len()).filter(|&c| !g.is_surface(c)).collect();
    assert!(inside.len() > 3000);
    for _ in 0..400 {
        let c = inside[(rng.next_u64() % inside.len() as u64) as usize];
        let w = m.winding_number(&g.cell_center(g.cells[c]));
        assert!((w - 1.0).abs() < 1e-6, "inside cell {:?}: {w}", g.cells[c]);
    }
    let listed: HashSet<[i32; 3]> = g.cells.iter().copied().collect();
    let mut outside_checked = 0;
    while outside_checked < 400 {
        let cell: [i32; 3] = std::array::from_fn(|d| (rng.next_u64() % (g.dims[d] as u64 + 2)) as i32 - 1);
        if listed.contains(&cell) {
            continue;
        }
        let w = m.winding_number(&g.cell_center(cell));
        assert!(w.abs() < 1e-6, "unlisted cell {cell:?}: {w}");
        outside_checked += 1;
    }
}

#[test]
fn bunny_at_80k_cells_fills_its_volume_and_follows_translation() {
    // Its speed is measured by the criterion bench `voxelize` (benches/), not asserted here.
    let m = bunny();
    let h = 0.14;
    let g = voxelize(&m, h).unwrap();
    check_structure(&g, m.triangles.len());
    assert!((70_000..95_000).contains(&g.len()), "{}", g.len());
    // Inside cells lie within the volume and every listed cell touches it: the inside cells'
    // volume is below the bunny's, the listed cells' above.
    let inside = (0..g.len()).filter(|&c| !g.is_surface(c)).count() as f64;
    let (inner, outer) = (inside * h.powi(3), g.len() as f64 * h.powi(3));
    println!("inside cells {inner:.2}, listed cells {outer:.2}, bunny {BUNNY_VOLUME:.2}");
    assert!(inner < BUNNY_VOLUME && outer > BUNNY_VOLUME, "{inner} < {BUNNY_VOLUME} < {outer} fails");
    // Voxelizing a translated copy gives the same cells (the grid follows the mesh).
    let moved = m.transformed(|p| p + Vector3::new(3.0, -2.0, 1.0));
    let g2 = voxelize(&moved, 0.14).unwrap();
    assert_eq!(g2.cells, g.cells);
}

#[test]
fn open_mesh_has_no_inside_cells() {
    // The flood fill leaks through the hole: only intersected cells remain.
    let mut m = box_mesh([0.0, 0.0, 0.0], [2.0, 2.0, 2.0]);
    m.triangles.remove(2);
    let g = voxelize(&m, 0.25).unwrap();
    check_structure(&g, m.triangles.len());
    assert!(!g.is_empty());
    assert!((0..g.len()).all(|c| g.is_surface(c)));
    let closed = voxelize(&box_mesh([0.0, 0.0, 0.0], [2.0, 2.0, 2.0]), 0.25).unwrap();
    assert_eq!(closed.len(), 9 * 9 * 9);
    assert!(g.len() < 9 * 9 * 9 - 7 * 7 * 7);
}

#[test]
fn invalid_input_is_an_error_not_a_panic() {
    let m = unit_cube();
    for h in [0.0, -1.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        match voxelize(&m, h) {
            Err(GeometryError::InvalidCellSize { cell_size }) => {
                assert!(cell_size.is_nan() && h.is_nan() || cell_size == h)
            }
            other => panic!("{h}: {other:?}"),
        }
    }
    match voxelize(&m, 1e-3) {
        Err(GeometryError::GridTooLarge { cells, limit, .. }) => {
            assert_eq!(limit, MAX_GRID_CELLS);
            assert_eq!(cells, 1001.0f64.powi(3));
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(voxelize(&m, f64::MIN_POSITIVE), Err(GeometryError::GridTooLarge { .. })));
    // A flat, very long triangle.
    let needle = TriangleMesh::new(
        vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1e12, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)],
        vec![[0, 1, 2]],
    );
    assert!(matches!(voxelize(&needle, 1.0), Err(GeometryError::GridTooLarge { .. })));
    let huge = unit_cube().transformed(|p| Point3::from(p.coords * 1e308));
    assert!(matches!(voxelize(&huge, 1.0), Err(GeometryError::GridTooLarge { .. })));

    let mut nan = unit_cube();
    nan.vertices[3].z = f64::NAN;
    assert!(matches!(voxelize(&nan, 0.5), Err(GeometryError::NonFiniteVertex { vertex: 3, .. })));
    let mut bad = unit_cube();
    bad.triangles[4] = [0, 8, 1];
    assert!(matches!(voxelize(&bad, 0.5), Err(GeometryError::IndexOutOfRange { triangle: 4, index: 8, .. })));
    assert_eq!(voxelize(&TriangleMesh::default(), 0.5), Err(GeometryError::NoTriangles));
    // Degenerate geometry is fine: a point-like mesh gives one cell.
    let point = TriangleMesh::new(vec![Point3::new(1.0, 2.0, 3.0)], vec![[0, 0, 0]]);
    let g = voxelize(&point, 0.5).unwrap();
    assert_eq!(g.cells, vec![[0, 0, 0]]);
    assert_eq!(g.triangles_of(0), &[0]);
    assert_eq!(g.triangles_of(5), &[] as &[u32]);
}
