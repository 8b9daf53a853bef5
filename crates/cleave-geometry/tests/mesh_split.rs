//! `split_mesh_by_plane` on grids and on a sliced sphere and bunny (non-convex boundary cells,
//! merged slivers): the cut mesh validates (closed, outward, planar faces), keeps the volume to
//! 1e-12, and falls into exactly the pieces the plane leaves (components through coupled faces),
//! each child inside its parent (children's volumes add up to the parent's).

mod common;

use common::plane;

use cleave_geometry::{PolyhedralMesh, UnionFind, cut_mesh_by_polygon, hex_slice, split_mesh_by_plane};
use nalgebra::{Point3, Rotation3, Unit, Vector3};

/// Elements joined through coupled faces: the number of pieces.
fn pieces(mesh: &PolyhedralMesh) -> usize {
    let mut joined = UnionFind::new(mesh.num_elements);
    for f in &mesh.faces {
        if let Some(outer) = f.outer {
            joined.union(f.inner as usize, outer as usize);
        }
    }
    (0..mesh.num_elements).filter(|&e| joined.find(e) == e).count()
}

/// Per element, its volume (the element's outward faces fanned about their first corner).
fn volumes(mesh: &PolyhedralMesh) -> Vec<f64> {
    mesh.element_faces()
        .iter()
        .map(|faces| {
            // About a corner of the element, so a mesh far from the origin keeps its digits.
            let anchor = faces.first().map_or(Point3::origin(), |f| mesh.vertices[f.polygon[0] as usize]);
            faces
                .iter()
                .map(|f| {
                    let p: Vec<Point3<f64>> =
                        f.polygon.iter().map(|&v| Point3::from(mesh.vertices[v as usize] - anchor)).collect();
                    let sign = if f.reversed { -1.0 } else { 1.0 };
                    (1..p.len() - 1)
                        .map(|k| sign * p[0].coords.dot(&p[k].coords.cross(&p[k + 1].coords)) / 6.0)
                        .sum::<f64>()
                })
                .sum()
        })
        .collect()
}

/// Checks a cut: validation, volume kept, each parent's children filling it; returns the pieces.
fn check(before: &PolyhedralMesh, cut: &[Point3<f64>; 3], tolerance: f64) -> usize {
    let split = split_mesh_by_plane(before, cut, tolerance).unwrap();
    check_split(before, &split);
    pieces(&split.mesh)
}

/// The split mesh validates (closed, outward, planar), keeps the volume to 1e-12, and each old
/// element's children fill it to 1e-12.
fn check_split(before: &PolyhedralMesh, split: &cleave_geometry::MeshSplit) {
    let stats = split.mesh.validate(1e-8).unwrap_or_else(|e| panic!("{e}"));
    let old = volumes(before);
    let total: f64 = old.iter().sum();
    assert!((stats.volume - total).abs() < 1e-12 * total, "{} vs {total}", stats.volume);
    let mut filled = vec![0.0; old.len()];
    for (v, &p) in volumes(&split.mesh).iter().zip(&split.parent) {
        filled[p as usize] += v;
    }
    for (e, (f, o)) in filled.iter().zip(&old).enumerate() {
        assert!((f - o).abs() < 1e-12 * o.abs().max(1e-300) + 1e-15, "element {e}: {f} vs {o}");
    }
}

#[test]
fn a_grid_cut_obliquely_or_along_its_faces_falls_in_two() {
    let grid = PolyhedralMesh::grid(Point3::origin(), 1.0, [3, 3, 3]);
    assert_eq!(check(&grid, &plane(Vector3::new(0.3, 1.0, -0.4), 1.1), 1e-12), 2);
    // Along the grid faces x = 1: nothing split, nine faces uncoupled.
    let split = split_mesh_by_plane(&grid, &plane(Vector3::x(), 1.0), 1e-12).unwrap();
    assert_eq!((split.split_elements, split.uncoupled_faces, split.mesh.num_elements), (0, 9, 27));
    assert_eq!(check(&grid, &plane(Vector3::x(), 1.0), 1e-12), 2);
    // Turned and moved, cut through grid vertices (1, 0, 0), (0, 1, 0), (0, 0, 1) carried along.
    let turn = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.2, -0.7, 0.6)), 2.1);
    let shift = Vector3::new(-3.0, 1.5, 0.25);
    let moved = PolyhedralMesh { vertices: grid.vertices.iter().map(|p| turn * p + shift).collect(), ..grid.clone() };
    let through =
        [Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0), Point3::new(0.0, 0.0, 1.0)].map(|p| turn * p + shift);
    assert_eq!(check(&moved, &through, 1e-12), 2);
}

/// A sphere sliced into a grid (boundary cells non-convex where the grid is coarse against its
/// curvature, slivers merged), cut through its middle, off centre and through its cap.
#[test]
fn a_sliced_sphere_cut_anywhere_falls_in_two() {
    let sphere = common::icosphere(2, 1.0, Point3::new(0.1, -0.2, 0.05));
    let sliced = hex_slice(&sphere, 0.37).unwrap().mesh;
    for (normal, offset) in
        [(Vector3::new(1.0, 0.3, 0.2), 0.0), (Vector3::new(-0.2, 1.0, 0.7), 0.45), (Vector3::z(), 0.8)]
    {
        assert_eq!(check(&sliced, &plane(normal, offset), 1e-12), 2, "normal {normal}, offset {offset}");
    }
}

/// The bunny as the DG backend slices it, cut by three planes in turn (each cutting the last
/// cut's mesh): every cut validates and keeps the volume; the pieces only grow.
#[test]
fn the_sliced_bunny_cut_three_times_stays_valid() {
    let bunny = common::bunny();
    let (lo, hi) = bunny.aabb();
    let size = (hi - lo).norm();
    let mut mesh = hex_slice(&bunny, size / 12.0).unwrap().mesh;
    let centre = Point3::from((lo.coords + hi.coords) / 2.0);
    let mut last = 1;
    for normal in [Vector3::new(1.0, 0.2, 0.1), Vector3::new(0.1, 1.0, -0.3), Vector3::new(0.4, -0.3, 1.0)] {
        let n = normal.normalize();
        let cut = plane(n, n.dot(&centre.coords));
        let found = check(&mesh, &cut, 1e-12 * size);
        println!("{} elements, {found} pieces", mesh.num_elements);
        assert!(found > last, "{found} pieces after {last}");
        last = found;
        mesh = split_mesh_by_plane(&mesh, &cut, 1e-12 * size).unwrap().mesh;
    }
}

/// The area of the faces a cut opened (a piece of the section left uncoupled, or a piece of an
/// interior face in the plane), over both sides.
fn opened_area(before: &PolyhedralMesh, split: &cleave_geometry::MeshSplit) -> f64 {
    split
        .mesh
        .faces
        .iter()
        .zip(&split.face_source)
        .filter(|(face, source)| {
            face.outer.is_none() && source.is_none_or(|f| before.faces[f as usize].outer.is_some())
        })
        .map(|(face, _)| split.mesh.polygon_area(&face.polygon))
        .sum()
}

/// Cuts by a polygon and checks it like `check`; returns the split.
fn check_polygon(before: &PolyhedralMesh, polygon: &[Point3<f64>], tolerance: f64) -> cleave_geometry::MeshSplit {
    let split = cut_mesh_by_polygon(before, polygon, tolerance).unwrap();
    check_split(before, &split);
    split
}

/// A triangle covering part of a grid's section, through the middle of its cells: the covered
/// part (by hand, 2.25) is opened on both sides, the body stays one piece (the cut ends inside
/// it); the same on the grid turned and moved; a second, coplanar triangle sharing the first's
/// long side (as a blade's swept quads do) covers the rest of the section and separates the body.
#[test]
fn a_triangle_opens_what_it_covers_and_a_second_one_completes_the_cut() {
    let grid = PolyhedralMesh::grid(Point3::origin(), 1.0, [3, 3, 3]);
    let turn = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.2, -0.7, 0.6)), 2.1);
    let shift = Vector3::new(-3.0, 1.5, 0.25);
    let moved = PolyhedralMesh { vertices: grid.vertices.iter().map(|p| turn * p + shift).collect(), ..grid.clone() };
    let place = |p: Point3<f64>, turned: bool| if turned { turn * p + shift } else { p };
    for (mesh, turned) in [(&grid, false), (&moved, true)] {
        // In x = 1.5, (y, z) ∈ {(−1, −1), (5, −1), (−1, 2)}: covers z ≤ 1.5 − y/2 of [0, 3]².
        let first = [(-1.0, -1.0), (5.0, -1.0), (-1.0, 2.0)].map(|(y, z)| place(Point3::new(1.5, y, z), turned));
        let split = check_polygon(mesh, &first, 1e-12);
        assert!((opened_area(mesh, &split) - 2.0 * 2.25).abs() < 1e-12, "{}", opened_area(mesh, &split));
        assert_eq!(pieces(&split.mesh), 1, "a cut ending inside leaves one piece");
        // Beyond the first triangle's long side, sharing it: the rest of the section.
        let second = [(5.0, -1.0), (-1.0, 20.0), (-1.0, 2.0)].map(|(y, z)| place(Point3::new(1.5, y, z), turned));
        let again = check_polygon(&split.mesh, &second, 1e-12);
        assert_eq!(pieces(&again.mesh), 2);
        let split_area = opened_area(mesh, &split) + opened_area(&split.mesh, &again);
        assert!((split_area - 2.0 * 9.0).abs() < 1e-11, "{split_area}");
    }
}

/// A triangle lying in grid faces (x = 1) opens only what it covers of them: z ≤ 2 − y of the
/// 3 × 3 square, area 2 (by hand), on both sides, and the body stays one piece.
#[test]
fn a_triangle_in_the_grid_faces_uncouples_what_it_covers() {
    let grid = PolyhedralMesh::grid(Point3::origin(), 1.0, [3, 3, 3]);
    let triangle = [Point3::new(1.0, -1.0, -1.0), Point3::new(1.0, 3.0, -1.0), Point3::new(1.0, -1.0, 3.0)];
    let split = check_polygon(&grid, &triangle, 1e-12);
    assert_eq!(split.split_elements, 0);
    assert!((opened_area(&grid, &split) - 2.0 * 2.0).abs() < 1e-12, "{}", opened_area(&grid, &split));
    assert_eq!(pieces(&split.mesh), 1);
}

/// Random triangles on the sliced bunny, each cutting the last cut's mesh: every cut validates,
/// keeps the volume and fills its parents, whatever the triangle meets.
#[test]
fn random_triangles_cut_the_sliced_bunny_validly() {
    let bunny = common::bunny();
    let (lo, hi) = bunny.aabb();
    let size = (hi - lo).norm();
    let mut mesh = hex_slice(&bunny, size / 10.0).unwrap().mesh;
    let mut random = common::Rng(17);
    let mut opened = 0;
    for _ in 0..12 {
        let a = random.point(&lo, &hi);
        let triangle = [a, a + (random.point(&lo, &hi) - a) * 0.8, a + (random.point(&lo, &hi) - a) * 0.8];
        let split = check_polygon(&mesh, &triangle, 1e-12 * size);
        opened += split.split_elements + split.uncoupled_faces;
        mesh = split.mesh;
    }
    assert!(opened > 12, "the triangles met the bunny: {opened} elements split or faces opened");
}

/// A thin triangle far from the origin (height 1e-4 of its length, at 1e3 m) still cuts what it
/// covers (its plane is its own corners, its normal taken about its centroid); a triangle
/// thinner than the tolerance, or a mesh naming a vertex it does not have, is refused with an
/// error, not a panic.
#[test]
fn thin_and_far_triangles_cut_and_bad_input_is_refused() {
    let shift = Vector3::new(1000.0, -700.0, 300.0);
    let grid = PolyhedralMesh::grid(Point3::origin(), 1.0, [3, 3, 3]);
    let far = PolyhedralMesh { vertices: grid.vertices.iter().map(|p| p + shift).collect(), ..grid.clone() };
    // In x = 1.5: a sliver from (y, z) = (−1, 1.5) to (5, 1.5), 6e-4 high at its far corner.
    let thin = [(-1.0, 1.5), (5.0, 1.5), (-1.0, 1.5006)].map(|(y, z)| Point3::new(1.5, y, z) + shift);
    let split = check_polygon(&far, &thin, 1e-12 * 3.0 * 3f64.sqrt());
    assert!(split.split_elements > 0, "the thin triangle split what it crosses");
    let hair = [(-1.0, 1.5), (5.0, 1.5), (-1.0, 1.5 + 1e-13)].map(|(y, z)| Point3::new(1.5, y, z));
    assert_eq!(cut_mesh_by_polygon(&grid, &hair, 1e-12), Err(cleave_geometry::MeshSplitError::BadPolygon));
    let mut broken = grid.clone();
    broken.faces[5].polygon[0] = 10_000;
    let error = cut_mesh_by_polygon(&broken, &thin.map(|p| p - shift), 1e-12).unwrap_err();
    assert!(error.to_string().contains("10000"), "{error}");
}
