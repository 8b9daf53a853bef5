//! Tests of `TriangleMesh::validate_closed`: each error names the expected offender.

mod common;

use cleave_geometry::{GeometryError, TriangleMesh};
use common::{BUNNY_AREA, BUNNY_VOLUME, box_mesh, bunny, unit_cube};
use nalgebra::Point3;

#[test]
fn cube_statistics() {
    let s = unit_cube().validate_closed().unwrap();
    assert_eq!((s.vertices, s.triangles, s.edges, s.components), (8, 12, 18, 1));
    assert!((s.volume - 1.0).abs() < 1e-14);
    assert!((s.area - 6.0).abs() < 1e-14);
}

#[test]
fn removed_triangle_gives_open_edge() {
    // Triangle 5 = [0, 5, 4]; the first remaining triangle using one of its edges is
    // triangle 2 = [4, 5, 6], whose first edge (4, 5) is now open.
    let mut m = unit_cube();
    m.triangles.remove(5);
    assert_eq!(m.validate_closed(), Err(GeometryError::OpenEdge { a: 4, b: 5, triangle: 2 }));
    // Removing triangle 1 = [0, 2, 1] opens the diagonal of triangle 0 = [0, 3, 2] at its
    // third edge (2, 0).
    let mut m = unit_cube();
    m.triangles.remove(1);
    assert_eq!(m.validate_closed(), Err(GeometryError::OpenEdge { a: 2, b: 0, triangle: 0 }));
}

#[test]
fn flipped_triangle_gives_inconsistent_orientation() {
    // Flip triangle 3 = [4, 6, 7] to [4, 7, 6]: its edge 6 -> 4 now runs the same way as
    // the third edge of triangle 2 = [4, 5, 6].
    let mut m = unit_cube();
    m.triangles[3] = [4, 7, 6];
    assert_eq!(m.validate_closed(), Err(GeometryError::InconsistentOrientation { a: 6, b: 4, triangles: (2, 3) }));
}

#[test]
fn flipped_mesh_gives_inward_orientation() {
    let mut m = box_mesh([1.0, 2.0, 3.0], [1.0, 2.0, 3.0]);
    for t in &mut m.triangles {
        t.swap(1, 2);
    }
    match m.validate_closed() {
        Err(GeometryError::InwardOrientation { volume }) => {
            assert!((volume + 6.0).abs() < 1e-12, "{volume}")
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn degenerate_triangles() {
    let mut m = unit_cube();
    m.triangles.push([0, 0, 1]);
    assert_eq!(
        m.validate_closed(),
        Err(GeometryError::DegenerateTriangle { triangle: 12, vertices: [0, 0, 1], area: 0.0 })
    );
    // Collinear corners: vertex 8 is the midpoint of edge (0, 1).
    let mut m = unit_cube();
    m.vertices.push(Point3::new(0.5, 0.0, 0.0));
    m.triangles.insert(4, [0, 8, 1]);
    match m.validate_closed() {
        Err(GeometryError::DegenerateTriangle { triangle: 4, vertices: [0, 8, 1], area }) => assert!(area < 1e-15),
        other => panic!("{other:?}"),
    }
    // A tiny but well-shaped cube is not degenerate.
    let tiny = unit_cube().transformed(|p| Point3::from(p.coords * 1e-7));
    assert_eq!(tiny.validate_closed().unwrap().edges, 18);
}

#[test]
fn non_manifold_edge_and_bad_indices() {
    let mut m = unit_cube();
    m.vertices.push(Point3::new(2.0, 2.0, -1.0));
    m.triangles.push([0, 2, 8]);
    assert_eq!(m.validate_closed(), Err(GeometryError::NonManifoldEdge { a: 0, b: 2, count: 3, triangle: 0 }));

    let mut m = unit_cube();
    m.triangles[7] = [3, 6, 99];
    assert_eq!(
        m.validate_closed(),
        Err(GeometryError::IndexOutOfRange { triangle: 7, vertices: [3, 6, 99], index: 99, vertex_count: 8 })
    );

    let mut m = unit_cube();
    m.vertices[6].y = f64::NAN;
    assert!(matches!(m.validate_closed(), Err(GeometryError::NonFiniteVertex { vertex: 6, .. })));

    assert_eq!(TriangleMesh::default().validate_closed(), Err(GeometryError::NoTriangles));
}

#[test]
fn error_messages_name_the_offender() {
    let mut m = unit_cube();
    m.triangles.remove(5);
    let msg = m.validate_closed().unwrap_err().to_string();
    assert!(msg.contains("(4, 5)") && msg.contains("triangle 2"), "{msg}");
}

fn merged(a: &TriangleMesh, b: &TriangleMesh) -> TriangleMesh {
    let off = a.vertices.len() as u32;
    let mut m = a.clone();
    m.vertices.extend(&b.vertices);
    m.triangles.extend(b.triangles.iter().map(|t| t.map(|i| i + off)));
    m
}

#[test]
fn components_and_cavities() {
    let two = merged(&unit_cube(), &box_mesh([3.0, 0.0, 0.0], [1.0, 1.0, 2.0]));
    let s = two.validate_closed().unwrap();
    assert_eq!(s.components, 2);
    assert_eq!(s.vertices as i64 - s.edges as i64 + s.triangles as i64, 4);
    assert!((s.volume - 3.0).abs() < 1e-12);

    // A 2x2x2 box with an inward-facing 1x1x1 cavity: 8 - 1 = 7.
    let mut cavity = box_mesh([0.5, 0.5, 0.5], [1.0, 1.0, 1.0]);
    for t in &mut cavity.triangles {
        t.swap(1, 2);
    }
    let hollow = merged(&box_mesh([0.0, 0.0, 0.0], [2.0, 2.0, 2.0]), &cavity);
    let s = hollow.validate_closed().unwrap();
    assert!((s.volume - 7.0).abs() < 1e-12);
    assert_eq!(s.components, 2);
}

#[test]
fn bunny_is_closed_genus_zero() {
    let s = bunny().validate_closed().unwrap();
    assert_eq!(s.vertices, 1839);
    assert_eq!(s.triangles, 3674);
    assert_eq!(s.edges, 5511);
    assert_eq!(s.components, 1);
    assert_eq!(s.vertices as i64 - s.edges as i64 + s.triangles as i64, 2);
    assert!((s.volume - BUNNY_VOLUME).abs() < 1e-9 * BUNNY_VOLUME);
    assert!((s.area - BUNNY_AREA).abs() < 1e-9 * BUNNY_AREA);
}
