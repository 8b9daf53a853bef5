//! Tests of `TriangleMesh`: integral quantities against analytic values, and OBJ parsing.

mod common;

use cleave_geometry::{GeometryError, TriangleMesh};
use common::{BUNNY_VOLUME, box_mesh, bunny, unit_cube};
use nalgebra::{Point3, Vector3};

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1.0)
}

#[test]
fn box_volume_area_centroid_aabb() {
    let m = box_mesh([10.3, -5.1, 3.7], [1.0, 2.0, 3.0]);
    assert!(close(m.signed_volume(), 6.0, 1e-12), "{}", m.signed_volume());
    assert!(close(m.area(), 2.0 * (2.0 + 3.0 + 6.0), 1e-12), "{}", m.area());
    let c = m.centroid_of_volume().unwrap();
    assert!((c - Point3::new(10.8, -4.1, 5.2)).norm() < 1e-12, "{c}");
    let (lo, hi) = m.aabb();
    assert_eq!(lo, Point3::new(10.3, -5.1, 3.7));
    assert!((hi - Point3::new(11.3, -3.1, 6.7)).norm() < 1e-12);
}

#[test]
fn tetrahedron_volume_area_centroid() {
    let (a, b, c) = (2.0, 3.0, 5.0);
    let m = TriangleMesh::new(
        vec![
            Point3::new(1.0, 1.0, 1.0),
            Point3::new(1.0 + a, 1.0, 1.0),
            Point3::new(1.0, 1.0 + b, 1.0),
            Point3::new(1.0, 1.0, 1.0 + c),
        ],
        vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    );
    assert!(close(m.signed_volume(), a * b * c / 6.0, 1e-12));
    let slanted = 0.5 * ((a * b).powi(2) + (b * c).powi(2) + (c * a).powi(2)).sqrt();
    let area = 0.5 * (a * b + b * c + c * a) + slanted;
    assert!(close(m.area(), area, 1e-12), "{} vs {area}", m.area());
    let centroid = m.centroid_of_volume().unwrap();
    let expected = Point3::new(1.0 + a / 4.0, 1.0 + b / 4.0, 1.0 + c / 4.0);
    assert!((centroid - expected).norm() < 1e-12, "{centroid}");
    assert_eq!(m.validate_closed().unwrap().edges, 6);
}

#[test]
fn transformed_scales_volume_and_mirror_flips_sign() {
    let m = unit_cube();
    let scaled = m.transformed(|p| Point3::new(2.0 * p.x, 3.0 * p.y, 4.0 * p.z + 1.0));
    assert!(close(scaled.signed_volume(), 24.0, 1e-12));
    let mirrored = m.transformed(|p| Point3::new(-p.x, p.y, p.z));
    assert!(close(mirrored.signed_volume(), -1.0, 1e-12));
    assert_eq!(mirrored.triangles, m.triangles);
}

#[test]
fn out_of_range_triangles_are_skipped_not_panicking() {
    let mut m = unit_cube();
    m.triangles.push([0, 1, 100]);
    assert!(close(m.signed_volume(), 1.0, 1e-12));
    assert!(close(m.area(), 6.0, 1e-12));
    assert!(m.triangle_points(12).is_none());
    let empty = TriangleMesh::default();
    assert_eq!(empty.centroid_of_volume(), None);
    assert_eq!(empty.signed_volume(), 0.0);
}

const CUBE_OBJ: &str = "\
# unit cube as quads, split into two groups, with normals and texcoords
mtllib missing.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
vt 0 0
vn 0 0 1
o bottom_and_sides
usemtl red
f 1 4 3 2
f 1/1/1 2/1/1 6/1/1 5/1/1
f 4 8 7 3
g rest
f 5 6 7 8
f 1 5 8 4
f -7 -6 -2 -3
";

#[test]
fn obj_quads_groups_merge_into_one_closed_mesh() {
    let m = TriangleMesh::from_obj_str(CUBE_OBJ).unwrap();
    // Vertices keep file order although the first face uses them as 1 4 3 2.
    assert_eq!(m.vertices, unit_cube().vertices);
    assert_eq!(m.triangles.len(), 12);
    // Fan triangulation of the first quad, in file order.
    assert_eq!(m.triangles[0], [0, 3, 2]);
    assert_eq!(m.triangles[1], [0, 2, 1]);
    let stats = m.validate_closed().unwrap();
    assert_eq!((stats.vertices, stats.edges, stats.components), (8, 18, 1));
    assert!(close(stats.volume, 1.0, 1e-12));
    // Reader and string entry points agree.
    let mut reader = std::io::BufReader::new(CUBE_OBJ.as_bytes());
    assert_eq!(TriangleMesh::from_obj_reader(&mut reader).unwrap(), m);
}

#[test]
fn obj_drops_unused_vertices_and_merges_duplicates() {
    let text = "v 0 0 0\nv 5 5 5\nv 1 0 0\nv 0 1 0\nv 1 0 0\nf 1 3 4\nf 1 4 5\n";
    let m = TriangleMesh::from_obj_str(text).unwrap();
    assert_eq!(m.vertices, vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)]);
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 1]]);
}

#[test]
fn obj_keeps_double_precision_and_weights() {
    let text = "v 0.1000000000000001 0 0\nv 2 0 0 2\nv 0 1 0\nf 1 2 3\n";
    let m = TriangleMesh::from_obj_str(text).unwrap();
    assert_eq!(m.vertices[0].x, 0.1000000000000001);
    assert_eq!(m.vertices[1], Point3::new(1.0, 0.0, 0.0));
}

fn line_of(result: Result<TriangleMesh, GeometryError>) -> (usize, String) {
    match result {
        Err(GeometryError::ObjLine { line, message }) => (line, message),
        other => panic!("expected ObjLine error, got {other:?}"),
    }
}

#[test]
fn obj_errors_name_the_line_and_value() {
    let (line, msg) = line_of(TriangleMesh::from_obj_str("v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n"));
    assert_eq!(line, 2);
    assert!(msg.contains("'x'"), "{msg}");

    let (line, msg) = line_of(TriangleMesh::from_obj_str("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 9\n"));
    assert_eq!(line, 5);
    assert!(msg.contains("vertex 9") && msg.contains('3'), "{msg}");

    let (line, msg) = line_of(TriangleMesh::from_obj_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"));
    assert_eq!(line, 4);
    assert!(msg.contains("vertex 0"), "{msg}");

    // Relative index reaching before the first vertex.
    let (line, msg) = line_of(TriangleMesh::from_obj_str("v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n"));
    assert_eq!(line, 3);
    assert!(msg.contains("-3"), "{msg}");

    let (line, _) = line_of(TriangleMesh::from_obj_str("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n"));
    assert_eq!(line, 2);
    let (line, _) = line_of(TriangleMesh::from_obj_str("v 0 0 0\nv 1 0 0 0\nv 0 1 0\nf 1 2 3\n"));
    assert_eq!(line, 2);
    let (line, _) = line_of(TriangleMesh::from_obj_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3a\n"));
    assert_eq!(line, 4);

    // Invalid UTF-8 on line 3 (through the reader).
    let bytes: &[u8] = b"v 0 0 0\nv 1 0 0\nv 0 \xff 1 0\nf 1 2 3\n";
    let (line, _) = line_of(TriangleMesh::from_obj_reader(&mut &bytes[..]));
    assert_eq!(line, 3);
}

#[test]
fn obj_index_components_that_would_overflow_tobj_are_rejected() {
    // Texture index 0 and a huge normal index make tobj overflow; they must be errors.
    let base = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n";
    let (line, msg) = line_of(TriangleMesh::from_obj_str(&format!("{base}f 1/0 2/1 3/1\n")));
    assert_eq!(line, 6);
    assert!(msg.contains("texture coordinate 0"), "{msg}");
    let huge = format!("{base}f 1//9223372036854775807 2//1 3//1\n");
    let (line, msg) = line_of(TriangleMesh::from_obj_str(&huge));
    assert_eq!(line, 6);
    assert!(msg.contains("normal 9223372036854775807"), "{msg}");
}

#[test]
fn obj_without_triangles_is_an_error() {
    assert_eq!(TriangleMesh::from_obj_str("# nothing\nv 0 0 0\n"), Err(GeometryError::NoTriangles));
    assert_eq!(TriangleMesh::from_obj_str("v 0 0 0\nv 1 0 0\nl 1 2\nf 1 2\n"), Err(GeometryError::NoTriangles));
    assert_eq!(TriangleMesh::from_obj_str(""), Err(GeometryError::NoTriangles));
}

#[test]
fn bunny_obj_counts_bbox_and_volume() {
    let m = bunny();
    assert_eq!(m.vertices.len(), 1839);
    assert_eq!(m.triangles.len(), 3674);
    let (lo, hi) = m.aabb();
    // Extremes of the package's positions.
    assert_eq!(lo, Point3::new(-4.958475, -0.003149, -3.729833));
    assert_eq!(hi, Point3::new(4.94885, 9.654748, 3.810639));
    assert!(close(m.signed_volume(), BUNNY_VOLUME, 1e-10));
    // First vertex and first face as in the package (`cells[0] = [2, 1661, 3]`).
    assert_eq!(m.vertices[0], Point3::new(1.301895, 0.122622, 2.550061));
    assert_eq!(m.triangles[0], [2, 1661, 3]);
    let c = m.centroid_of_volume().unwrap();
    assert!(c.iter().all(|x| x.is_finite()));
    let (lo, hi) = m.aabb();
    assert!((0..3).all(|d| c[d] > lo[d] && c[d] < hi[d]));
    // Translating moves the centroid by the same vector.
    let shift = Vector3::new(100.0, -50.0, 7.0);
    let moved = m.transformed(|p| p + shift).centroid_of_volume().unwrap();
    assert!((moved - (c + shift)).norm() < 1e-9);
}
