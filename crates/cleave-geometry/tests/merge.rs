//! Tests of `merge_small_elements` on hand-built meshes whose merges are known in advance: which
//! element absorbs which, the merged volume and face count, re-evaluation after a merge, the
//! largest-shared-area rule, isolated pieces, a non-convex result and input errors.

use std::collections::HashMap;

use cleave_geometry::{GeometryError, MergeReport, PolyFace, PolyhedralMesh, merge_small_elements};
use nalgebra::Point3;

type Polygon = Vec<[f64; 3]>;

/// A mesh from elements given as outward polygons by coordinates. Equal coordinates are one
/// vertex; a polygon of one element whose reverse is a polygon of another becomes one interior
/// face (`inner` the element listed first), every other polygon a boundary face. Independent of
/// the crate's constructors.
fn mesh_from_polygons(elements: &[Vec<Polygon>]) -> PolyhedralMesh {
    let mut ids: HashMap<[u64; 3], u32> = HashMap::new();
    let mut vertices = Vec::new();
    let mut open: HashMap<Vec<u32>, usize> = HashMap::new();
    let mut faces: Vec<PolyFace> = Vec::new();
    for (e, polygons) in elements.iter().enumerate() {
        for polygon in polygons {
            let indices: Vec<u32> = polygon
                .iter()
                .map(|p| {
                    *ids.entry(p.map(f64::to_bits)).or_insert_with(|| {
                        vertices.push(Point3::from(*p));
                        (vertices.len() - 1) as u32
                    })
                })
                .collect();
            // Canonical cyclic form of the reversed polygon, to find the twin.
            let canonical = |poly: &[u32]| -> Vec<u32> {
                let k = (0..poly.len()).min_by_key(|&i| poly[i]).expect("non-empty polygon");
                (0..poly.len()).map(|i| poly[(k + i) % poly.len()]).collect()
            };
            let reversed: Vec<u32> = indices.iter().rev().copied().collect();
            if let Some(f) = open.remove(&canonical(&reversed)) {
                faces[f].outer = Some(e as u32);
            } else {
                open.insert(canonical(&indices), faces.len());
                faces.push(PolyFace { polygon: indices, inner: e as u32, outer: None });
            }
        }
    }
    PolyhedralMesh { vertices, faces, num_elements: elements.len() }
}

/// The six outward quads of the box `[lo, hi]`.
fn box_faces(lo: [f64; 3], hi: [f64; 3]) -> Vec<Polygon> {
    let [x0, y0, z0] = lo;
    let [x1, y1, z1] = hi;
    vec![
        vec![[x0, y0, z0], [x0, y0, z1], [x0, y1, z1], [x0, y1, z0]],
        vec![[x1, y0, z0], [x1, y1, z0], [x1, y1, z1], [x1, y0, z1]],
        vec![[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]],
        vec![[x0, y1, z0], [x0, y1, z1], [x1, y1, z1], [x1, y1, z0]],
        vec![[x0, y0, z0], [x0, y1, z0], [x1, y1, z0], [x1, y0, z0]],
        vec![[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],
    ]
}

/// Boxes `[xs[i], xs[i+1]] × [0, 1]²` in a row along x.
fn row_of_boxes(xs: &[f64]) -> PolyhedralMesh {
    let elements: Vec<Vec<Polygon>> = xs.windows(2).map(|w| box_faces([w[0], 0.0, 0.0], [w[1], 1.0, 1.0])).collect();
    mesh_from_polygons(&elements)
}

/// Validates (as the DG backend does) and returns the element volumes.
fn validated_volumes(name: &str, mesh: &PolyhedralMesh) -> Vec<f64> {
    mesh.validate(1e-8).unwrap_or_else(|e| panic!("{name}: validate rejects the mesh: {e}"));
    (0..mesh.num_elements).map(|e| cleave_geometry::element_volume_centroid(mesh, e).0).collect()
}

fn faces_of(mesh: &PolyhedralMesh, e: u32) -> usize {
    mesh.faces.iter().filter(|f| f.inner == e || f.outer == Some(e)).count()
}

fn faces_between(mesh: &PolyhedralMesh, a: u32, b: u32) -> usize {
    mesh.faces.iter().filter(|f| (f.inner == a && f.outer == Some(b)) || (f.inner == b && f.outer == Some(a))).count()
}

fn assert_close(name: &str, got: f64, expected: f64) {
    assert!((got - expected).abs() <= 1e-12 * expected.abs().max(1.0), "{name}: {got} vs {expected}");
}

fn report(name: &str, r: &MergeReport) {
    println!(
        "{name}: {} → {} elements, {} merges, smallest volume {:.3e} → {:.3e}, {} isolated small kept",
        r.elements_before, r.elements_after, r.merges, r.min_volume_before, r.min_volume_after, r.isolated_small
    );
}

#[test]
fn thin_slab_merges_into_the_cube_next_to_it() {
    // A unit cube and a slab of thickness 0.01 on its +x side.
    let t = 0.01;
    let mut mesh = row_of_boxes(&[0.0, 1.0, 1.0 + t]);
    validated_volumes("cube + slab", &mesh);
    let r = merge_small_elements(&mut mesh, 0.05).expect("merge succeeds");
    report("cube + slab", &r);
    assert_eq!((r.elements_before, r.elements_after, r.merges, r.isolated_small), (2, 1, 1, 0));
    assert_eq!(r.element_map, [0, 0]);
    assert_eq!(r.survivors, [0]);
    assert_close("smallest volume before", r.min_volume_before, t);
    assert_close("smallest volume after", r.min_volume_after, 1.0 + t);
    let volumes = validated_volumes("cube + slab merged", &mesh);
    assert_close("merged volume", volumes[0], 1.0 + t);
    // 6 + 6 faces minus the shared square: the box [0, 1.01] × [0, 1]² with its four sides
    // each in two coplanar pieces.
    assert_eq!(mesh.faces.len(), 10);
    assert!(mesh.faces.iter().all(|f| f.inner == 0 && f.outer.is_none()));
}

#[test]
fn small_element_picks_the_neighbour_with_the_largest_shared_area() {
    // Four boxes of height 1 on the 2 × 2 grid with lines x = 0.1 and y = 0.3: the corner box
    // [0, 0.1] × [0, 0.3] (volume 0.03) shares 0.3 with its +x neighbour and 0.1 with its +y
    // neighbour, so it joins the +x one; the +y one (volume 0.07) stays.
    let (a, b) = (0.1, 0.3);
    let cell = |x: [f64; 2], y: [f64; 2]| box_faces([x[0], y[0], 0.0], [x[1], y[1], 1.0]);
    let mut mesh = mesh_from_polygons(&[
        cell([0.0, a], [0.0, b]),
        cell([a, 1.0], [0.0, b]),
        cell([0.0, a], [b, 1.0]),
        cell([a, 1.0], [b, 1.0]),
    ]);
    validated_volumes("2 × 2", &mesh);
    let r = merge_small_elements(&mut mesh, 0.05).expect("merge succeeds");
    report("2 × 2", &r);
    assert_eq!((r.elements_after, r.merges), (3, 1));
    assert_eq!(r.element_map, [0, 0, 1, 2]);
    assert_eq!(r.survivors, [1, 2, 3]);
    let volumes = validated_volumes("2 × 2 merged", &mesh);
    for (got, expected) in volumes.iter().zip([b, a * (1.0 - b), (1.0 - a) * (1.0 - b)]) {
        assert_close("volume", *got, expected);
    }
    // The strip y ∈ [0, 0.3]: 6 + 6 − 2 faces, one to each remaining neighbour (the old corner
    // box's face to the +y box, the old +x box's face to the far box).
    assert_eq!(faces_of(&mesh, 0), 10);
    assert_eq!(faces_between(&mesh, 0, 1), 1);
    assert_eq!(faces_between(&mesh, 0, 2), 1);
    assert_eq!(faces_between(&mesh, 1, 2), 1);
}

#[test]
fn a_merged_small_element_is_reevaluated() {
    // Slabs of volume 0.01 and 0.02, then a unit cube. Smallest first: the 0.01 slab's only
    // neighbour is the other small slab, so it joins it anyway; the 0.03 result is still small
    // and joins the cube.
    let mut mesh = row_of_boxes(&[0.0, 0.01, 0.03, 1.03]);
    let r = merge_small_elements(&mut mesh, 0.05).expect("merge succeeds");
    report("two slabs + cube", &r);
    assert_eq!((r.elements_after, r.merges), (1, 2));
    assert_eq!(r.element_map, [0, 0, 0]);
    assert_eq!(r.survivors, [2]);
    let volumes = validated_volumes("two slabs + cube merged", &mesh);
    assert_close("merged volume", volumes[0], 1.03);
    // 18 polygons, two shared pairs: 16 faces, of which the two shared ones are gone.
    assert_eq!(mesh.faces.len(), 3 * 6 - 2 * 2);

    // Slabs of 0.03 and 0.03: the first joins the second (its only neighbour), which then has
    // 0.06, above the threshold, and stays.
    let mut mesh = row_of_boxes(&[0.0, 0.03, 0.06, 1.06]);
    let r = merge_small_elements(&mut mesh, 0.05).expect("merge succeeds");
    report("slab pair grows above the threshold", &r);
    assert_eq!((r.elements_after, r.merges), (2, 1));
    assert_eq!(r.element_map, [0, 0, 1]);
    let volumes = validated_volumes("slab pair merged", &mesh);
    assert_close("merged slab volume", volumes[0], 0.06);
    assert_close("cube volume", volumes[1], 1.0);
    assert_close("smallest volume after", r.min_volume_after, 0.06);
    assert_eq!(faces_of(&mesh, 0), 10);
    assert_eq!(faces_between(&mesh, 0, 1), 1);
}

#[test]
fn merged_element_keeps_several_faces_to_one_neighbour() {
    // A = [0, 1]² × [0, 0.02] under B = [0, 1]² × [0.02, 2], both against C = [1, 2] × [0, 1] ×
    // [0, 2], whose −x side is two faces (one to A, one to B). A shares 1 with B and 0.02 with
    // C: it joins B, and the union has two coplanar faces to C.
    let t = 0.02;
    let a = box_faces([0.0, 0.0, 0.0], [1.0, 1.0, t]);
    let b = box_faces([0.0, 0.0, t], [1.0, 1.0, 2.0]);
    let mut c = box_faces([1.0, 0.0, 0.0], [2.0, 1.0, 2.0]);
    c[0] = vec![[1.0, 0.0, 0.0], [1.0, 0.0, t], [1.0, 1.0, t], [1.0, 1.0, 0.0]];
    c.push(vec![[1.0, 0.0, t], [1.0, 0.0, 2.0], [1.0, 1.0, 2.0], [1.0, 1.0, t]]);
    // C's y = 0, y = 1 faces get the vertex at z = t on their x = 1 edge (the edges are split
    // there by its two −x faces).
    c[2] = vec![[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 0.0, 2.0], [1.0, 0.0, 2.0], [1.0, 0.0, t]];
    c[3] = vec![[1.0, 1.0, 0.0], [1.0, 1.0, t], [1.0, 1.0, 2.0], [2.0, 1.0, 2.0], [2.0, 1.0, 0.0]];
    let mut mesh = mesh_from_polygons(&[a, b, c]);
    let before = validated_volumes("slab under a box, beside a box", &mesh);
    assert_eq!(faces_between(&mesh, 0, 2), 1);
    assert_eq!(faces_between(&mesh, 1, 2), 1);
    let r = merge_small_elements(&mut mesh, 0.05).expect("merge succeeds");
    report("slab under a box, beside a box", &r);
    assert_eq!(r.element_map, [0, 0, 1]);
    let volumes = validated_volumes("slab under a box merged", &mesh);
    assert_close("merged volume", volumes[0], 2.0);
    assert_close("untouched volume", volumes[1], before[2]);
    assert_eq!(faces_between(&mesh, 0, 1), 2);
    assert_eq!(faces_of(&mesh, 0), 10);
    // The face normals still point out of `inner`: C's x = 1 faces point −x out of C.
    for (index, f) in mesh.faces.iter().enumerate().filter(|(_, f)| f.outer.is_some()) {
        let (_, n, _) = cleave_geometry::face_area_normal_centroid(&mesh, index);
        let expected = if f.inner == 1 { -1.0 } else { 1.0 };
        assert_close("interior face normal x", n.x, expected);
    }
}

#[test]
fn small_box_glued_on_a_big_one_gives_a_non_convex_element() {
    // The unit cube with the box [0, 0.2]² × [1, 1.1] (volume 0.004) standing on the corner of
    // its top. The cube's top is the shared square plus an L-shaped hexagon; its x = 0 and
    // y = 0 sides carry the square's corners on their top edges.
    let (s, z) = (0.2, 1.1);
    let big = vec![
        vec![[0.0, 0.0, 1.0], [s, 0.0, 1.0], [s, s, 1.0], [0.0, s, 1.0]],
        vec![[s, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0], [0.0, s, 1.0], [s, s, 1.0]],
        vec![[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, s, 1.0], [0.0, 1.0, 1.0], [0.0, 1.0, 0.0]],
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [s, 0.0, 1.0], [0.0, 0.0, 1.0]],
        vec![[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 1.0, 1.0], [1.0, 0.0, 1.0]],
        vec![[0.0, 1.0, 0.0], [0.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, 1.0, 0.0]],
        vec![[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 0.0]],
    ];
    let small = box_faces([0.0, 0.0, 1.0], [s, s, z]);
    let mut mesh = mesh_from_polygons(&[small, big]);
    let before = validated_volumes("glued boxes", &mesh);
    assert_close("small box volume", before[0], s * s * (z - 1.0));
    assert_eq!(faces_between(&mesh, 0, 1), 1);
    let r = merge_small_elements(&mut mesh, 0.05).expect("merge succeeds");
    report("glued boxes", &r);
    assert_eq!((r.elements_after, r.element_map.as_slice(), r.survivors.as_slice()), (1, &[0, 0][..], &[1][..]));
    let volumes = validated_volumes("glued boxes merged", &mesh);
    assert_close("merged volume", volumes[0], 1.0 + s * s * (z - 1.0));
    // 7 + 6 polygons, the shared square one face of each: 12 faces, 11 once it is gone.
    assert_eq!(mesh.faces.len(), 11);
    // Non-convex: some vertex of the element lies strictly outside the plane of one of its
    // faces (the small box's top corners above the L-shaped remainder of the cube's top).
    let outside = mesh.faces.iter().any(|f| {
        let p = |k: usize| mesh.vertices[f.polygon[k] as usize];
        let normal =
            (1..f.polygon.len() - 1).map(|k| (p(k) - p(0)).cross(&(p(k + 1) - p(0)))).sum::<nalgebra::Vector3<f64>>();
        mesh.vertices.iter().any(|v| (v - p(0)).dot(&normal) > 1e-9 * normal.norm())
    });
    assert!(outside, "the merged element is convex");
}

#[test]
fn isolated_small_element_is_kept_and_reported() {
    // A unit cube and, apart from it, a box of volume 0.001: a piece with no neighbour.
    let mut mesh = mesh_from_polygons(&[box_faces([0.0; 3], [1.0; 3]), box_faces([2.0, 0.0, 0.0], [2.1, 0.1, 0.1])]);
    let r = merge_small_elements(&mut mesh, 0.05).expect("merge succeeds");
    report("isolated box", &r);
    assert_eq!((r.elements_after, r.merges, r.isolated_small), (2, 0, 1));
    assert_close("smallest volume kept", r.min_volume_after, 0.001);
    validated_volumes("isolated box", &mesh);
}

#[test]
fn zero_threshold_keeps_the_mesh_and_bad_thresholds_are_errors() {
    let original = row_of_boxes(&[0.0, 1.0, 1.001]);
    let mut mesh = original.clone();
    let r = merge_small_elements(&mut mesh, 0.0).expect("merge succeeds");
    assert_eq!(mesh, original);
    assert_eq!((r.merges, r.element_map.as_slice()), (0, &[0, 1][..]));
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let result = merge_small_elements(&mut mesh, bad);
        assert!(matches!(result, Err(GeometryError::InvalidMergeThreshold { .. })), "{bad}: {result:?}");
    }
    mesh.faces[0].inner = 7;
    assert!(matches!(
        merge_small_elements(&mut mesh, 0.05),
        Err(GeometryError::FaceElementOutOfRange { face: 0, element: 7, num_elements: 2 })
    ));
}
