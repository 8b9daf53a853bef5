//! Tests of `hex_slice`: element volumes against the surface's enclosed volume, closed and
//! consistently oriented element boundaries, separate elements for separate pieces of one cell,
//! boundary faces tiling the surface, input errors, and the default sliver merging of the bunny
//! slicings (volume kept, no small element left, pieces accounted for).

mod common;

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use cleave_geometry::{
    DEFAULT_MERGE_BELOW, GeometryError, HexSliceOptions, HexSlicing, MIN_FACE_AREA, PolyhedralMesh, TriangleMesh,
    hex_slice, hex_slice_with, triangle_aabb_overlap,
};
use common::{BUNNY_VOLUME, box_mesh, bunny, icosphere};
use nalgebra::{Point3, Vector3};

/// Outward polygons of every element: `(face, vertex indices in outward order)`.
fn element_polygons(mesh: &PolyhedralMesh) -> Vec<Vec<(usize, Vec<u32>)>> {
    let mut out = vec![Vec::new(); mesh.num_elements];
    for (f, face) in mesh.faces.iter().enumerate() {
        out[face.inner as usize].push((f, face.polygon.clone()));
        if let Some(o) = face.outer {
            out[o as usize].push((f, face.polygon.iter().rev().copied().collect()));
        }
    }
    out
}

/// Six times the signed volume of the cone from the origin over an outward polygon (fan
/// triangles from its first vertex).
fn six_cone_volume(vertices: &[Point3<f64>], polygon: &[u32]) -> f64 {
    let p = |k: usize| vertices[polygon[k] as usize].coords;
    (1..polygon.len() - 1).map(|k| p(0).dot(&p(k).cross(&p(k + 1)))).sum()
}

/// Element volumes by the divergence theorem, independent of the crate's integration code.
fn element_volumes(mesh: &PolyhedralMesh) -> Vec<f64> {
    element_polygons(mesh)
        .iter()
        .map(|faces| faces.iter().map(|(_, poly)| six_cone_volume(&mesh.vertices, poly)).sum::<f64>() / 6.0)
        .collect()
}

/// Newell area vector of a polygon (about its first vertex, so small faces far from the
/// origin keep their precision).
fn area_vector(vertices: &[Point3<f64>], polygon: &[u32]) -> Vector3<f64> {
    let p = |k: usize| vertices[polygon[k] as usize] - vertices[polygon[0] as usize];
    (1..polygon.len() - 1).map(|k| p(k).cross(&p(k + 1))).sum::<Vector3<f64>>() / 2.0
}

/// Asserts every element boundary is closed and consistently oriented: each directed edge of
/// its outward faces appears once, and so does its reverse.
fn assert_closed_oriented(mesh: &PolyhedralMesh) {
    for (e, faces) in element_polygons(mesh).iter().enumerate() {
        let mut edges = HashSet::new();
        for (f, poly) in faces {
            for k in 0..poly.len() {
                let edge = (poly[k], poly[(k + 1) % poly.len()]);
                assert!(edges.insert(edge), "element {e}: directed edge {edge:?} used twice (face {f})");
            }
        }
        for &(a, b) in &edges {
            assert!(edges.contains(&(b, a)), "element {e}: edge ({a}, {b}) has no reverse");
        }
    }
}

/// Asserts a face is planar (within 1e-12 h of its Newell plane) and simple (no two
/// non-adjacent edges meet, in the projection along the normal's largest component).
fn assert_planar_simple(name: &str, vertices: &[Point3<f64>], polygon: &[u32], normal: Vector3<f64>, h: f64) {
    let n = polygon.len();
    let unit = normal.normalize();
    let p = |k: usize| vertices[polygon[k % n] as usize];
    for k in 0..n {
        assert!((p(k) - p(0)).dot(&unit).abs() < 1e-12 * h, "{name}: face {polygon:?} is not planar");
    }
    let c = normal.iamax();
    let (a, b) = ((c + 1) % 3, (c + 2) % 3);
    let q = |k: usize| [p(k)[a], p(k)[b]];
    let orient = |o: [f64; 2], x: [f64; 2], y: [f64; 2]| (x[0] - o[0]) * (y[1] - o[1]) - (x[1] - o[1]) * (y[0] - o[0]);
    for i in 0..n {
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue;
            }
            let (s0, s1, t0, t1) = (q(i), q(i + 1), q(j), q(j + 1));
            let (o1, o2) = (orient(s0, s1, t0), orient(s0, s1, t1));
            let (o3, o4) = (orient(t0, t1, s0), orient(t0, t1, s1));
            // Collinear within rounding: compare the intervals along the line instead.
            let scale = 1e-12 * h * h;
            let collinear = [o1, o2, o3, o4].iter().all(|o| o.abs() <= scale);
            let crosses = if collinear {
                let k = if (s1[0] - s0[0]).abs() > (s1[1] - s0[1]).abs() { 0 } else { 1 };
                let (a0, a1) = (s0[k].min(s1[k]), s0[k].max(s1[k]));
                let (b0, b1) = (t0[k].min(t1[k]), t0[k].max(t1[k]));
                a0 <= b1 && b0 <= a1
            } else {
                o1 * o2 < 0.0 && o3 * o4 < 0.0
            };
            assert!(!crosses, "{name}: face {polygon:?} is not simple (edges {i} and {j} meet)");
        }
    }
}

/// Structural checks shared by all inputs; returns (sum of element volumes, boundary area).
fn check_slicing(name: &str, surface: &TriangleMesh, s: &HexSlicing) -> (f64, f64) {
    let mesh = &s.mesh;
    let h = s.cell_size;
    assert_eq!(s.element_cells.len(), mesh.num_elements);
    assert_closed_oriented(mesh);
    // The crate's own check too (the DG backend runs it with this tolerance).
    mesh.validate(1e-8).unwrap_or_else(|e| panic!("{name}: validate rejects the slicing: {e}"));
    let volumes = element_volumes(mesh);
    let min_volume = volumes.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(min_volume > 0.0, "{name}: an element has volume {min_volume:e}");
    let total: f64 = volumes.iter().sum();
    let expected = surface.signed_volume();
    let mut boundary_area = 0.0;
    let mut min_area = f64::INFINITY;
    for face in &mesh.faces {
        let n = face.polygon.len();
        assert!(n >= 3);
        let distinct: HashSet<u32> = face.polygon.iter().copied().collect();
        assert_eq!(distinct.len(), n, "{name}: face repeats a vertex: {:?}", face.polygon);
        let normal = area_vector(&mesh.vertices, &face.polygon);
        let area = normal.norm();
        min_area = min_area.min(area);
        assert_planar_simple(name, &mesh.vertices, &face.polygon, normal, h);
        match face.outer {
            None => boundary_area += area,
            Some(o) => {
                assert_ne!(o, face.inner);
                // Interior faces lie on one grid plane.
                let on_plane = (0..3).any(|d| {
                    let c = mesh.vertices[face.polygon[0] as usize][d];
                    let p = ((c - s.origin[d]) / h).round();
                    face.polygon
                        .iter()
                        .all(|&v| (mesh.vertices[v as usize][d] - (s.origin[d] + p * h)).abs() < 1e-12 * h)
                });
                assert!(on_plane, "{name}: interior face off the grid planes");
            }
        }
    }
    println!(
        "{name}: h = {h}, {} elements, {} faces, {} vertices; volume {total:.12} vs {expected:.12} (rel {:.1e}); \
         boundary area rel err {:.1e}; min face area {:.1e} h², min element volume {:.1e} h³",
        mesh.num_elements,
        mesh.faces.len(),
        mesh.vertices.len(),
        (total - expected).abs() / expected,
        (boundary_area - surface.area()).abs() / surface.area(),
        min_area / (h * h),
        min_volume / (h * h * h),
    );
    assert!(min_area >= MIN_FACE_AREA * h * h, "{name}: sliver face of area {min_area:e}");
    (total, boundary_area)
}

fn assert_rel(name: &str, what: &str, got: f64, expected: f64, tol: f64) {
    let rel = (got - expected).abs() / expected.abs();
    assert!(rel <= tol, "{name}: {what} {got} vs {expected}: relative error {rel:e} > {tol:e}");
}

/// The raw slicing, one element per connected piece of a cell: the structural tests below
/// count and measure pieces per cell.
const RAW: HexSliceOptions = HexSliceOptions { merge_below: 0.0 };

fn check_volume_and_area(name: &str, surface: &TriangleMesh, cell_size: f64) -> HexSlicing {
    let start = Instant::now();
    let s = hex_slice_with(surface, cell_size, RAW).expect("slicing succeeds");
    assert_eq!(s.merge.merges, 0, "{name}: merge_below = 0 merged something");
    println!("{name}: sliced in {:.1} ms", start.elapsed().as_secs_f64() * 1e3);
    let (volume, area) = check_slicing(name, surface, &s);
    assert_rel(name, "sum of element volumes", volume, surface.signed_volume(), 1e-10);
    assert_rel(name, "boundary face area", area, surface.area(), 1e-10);
    s
}

/// Cells whose cube lies inside the solid and meets no triangle (checked with the crate's
/// triangle–box test and the winding number of the centre).
fn fully_inside_cells(surface: &TriangleMesh, s: &HexSlicing) -> HashSet<[i32; 3]> {
    let h = s.cell_size;
    let cells: HashSet<[i32; 3]> = s.element_cells.iter().copied().collect();
    cells
        .into_iter()
        .filter(|c| {
            let lo = s.origin + Vector3::from(c.map(f64::from)) * h;
            let hi = lo + Vector3::repeat(h);
            let touched = (0..surface.triangles.len())
                .any(|t| triangle_aabb_overlap(&surface.triangle_points(t).expect("valid triangle"), &lo, &hi));
            !touched && surface.contains(&nalgebra::center(&lo, &hi))
        })
        .collect()
}

#[test]
fn bunny_volumes_areas_and_cubes() {
    let surface = bunny();
    for (name, cell_size) in [("bunny ~41", 3.0), ("bunny ~300", 1.1), ("bunny ~5000", 0.375)] {
        let s = check_volume_and_area(name, &surface, cell_size);
        let inside = fully_inside_cells(&surface, &s);
        let mut cubes = 0;
        let faces = element_polygons(&s.mesh);
        for (e, cell) in s.element_cells.iter().enumerate() {
            if inside.contains(cell) {
                cubes += 1;
                assert_eq!(faces[e].len(), 6, "{name}: inside cell {cell:?} element has {} faces", faces[e].len());
                for (f, poly) in &faces[e] {
                    assert_eq!(poly.len(), 4);
                    assert!(s.mesh.faces[*f].outer.is_some(), "{name}: cube face without outer element");
                    let a = area_vector(&s.mesh.vertices, poly).norm();
                    assert_rel(name, "cube face area", a, cell_size * cell_size, 1e-12);
                }
            }
        }
        let cut_cells: HashSet<[i32; 3]> = s.element_cells.iter().copied().filter(|c| !inside.contains(c)).collect();
        println!("{name}: {cubes} interior cubes, {} cut cells", cut_cells.len());
    }
}

#[test]
fn icosphere_volume_and_area() {
    let surface = icosphere(3, 1.0, Point3::new(0.1, -0.2, 0.3));
    let s = check_volume_and_area("icosphere", &surface, 0.3);
    // Every cell meeting the sphere holds one piece: the sphere is convex.
    let mut per_cell: HashMap<[i32; 3], usize> = HashMap::new();
    for c in &s.element_cells {
        *per_cell.entry(*c).or_default() += 1;
    }
    assert!(per_cell.values().all(|&n| n == 1), "a convex solid split within a cell");
}

#[test]
fn box_on_lattice_planes() {
    // Faces at multiples of the cell size: the unshifted lattice would have every face on a
    // grid plane and every corner on a grid corner.
    let surface = box_mesh([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    let h = 0.25;
    let s = check_volume_and_area("box", &surface, h);
    assert_rel("box", "sum of element volumes", element_volumes(&s.mesh).iter().sum(), 1.0, 1e-12);
    // Each cell meeting the box holds one box-shaped piece; count the cells per axis.
    let cells_per_axis = |d: usize| {
        let first = ((0.0 - s.origin[d]) / h).floor();
        let last = ((1.0 - s.origin[d]) / h).floor();
        (last - first + 1.0) as usize
    };
    let expected: usize = (0..3).map(cells_per_axis).product();
    assert_eq!(s.mesh.num_elements, expected);
    for d in 0..3 {
        let shift = ((0.0 - s.origin[d]) / h).fract();
        assert!(shift > 1e-3 && shift < 1.0 - 1e-3, "axis {d}: grid not shifted off the box faces");
    }
}

/// A U extruded along y: prongs x ∈ [0, 1] and [1.1, 2.1], z ∈ [1, 5], base z ∈ [0, 1],
/// y ∈ [0, 1].
fn u_shape() -> TriangleMesh {
    let outline: [[f64; 2]; 10] = [
        [0.0, 0.0],
        [1.0, 0.0],
        [1.1, 0.0],
        [2.1, 0.0],
        [2.1, 5.0],
        [1.1, 5.0],
        [1.1, 1.0],
        [1.0, 1.0],
        [1.0, 5.0],
        [0.0, 5.0],
    ];
    // Cap triangles, counter-clockwise in (x, z).
    let cap: [[u32; 3]; 8] = [[0, 1, 7], [0, 7, 8], [0, 8, 9], [1, 2, 6], [1, 6, 7], [2, 3, 6], [6, 3, 4], [6, 4, 5]];
    let n = outline.len() as u32;
    let mut vertices = Vec::new();
    for y in [0.0, 1.0] {
        vertices.extend(outline.iter().map(|&[x, z]| Point3::new(x, y, z)));
    }
    let mut triangles = Vec::new();
    // Counter-clockwise in (x, z) has normal e_x × e_z = −y: the y = 0 cap as is.
    for &[a, b, c] in &cap {
        triangles.push([a, b, c]);
        triangles.push([a + n, c + n, b + n]);
    }
    for k in 0..n {
        let (p, q) = (k, (k + 1) % n);
        triangles.push([p, p + n, q + n]);
        triangles.push([p, q + n, q]);
    }
    TriangleMesh::new(vertices, triangles)
}

#[test]
fn u_prongs_in_one_cell_are_separate_elements() {
    let surface = u_shape();
    surface.validate_closed().expect("the U is closed and outward");
    let h = 2.0;
    let s = check_volume_and_area("U", &surface, h);
    let cell_of = |p: Point3<f64>| -> [i32; 3] { std::array::from_fn(|d| ((p[d] - s.origin[d]) / h).floor() as i32) };
    let left = cell_of(Point3::new(0.99, 0.5, 4.5));
    let right = cell_of(Point3::new(1.11, 0.5, 4.5));
    assert_eq!(left, right, "test setup: the grid should put both prong tips in one cell");
    let cell = left;
    let elements: Vec<usize> = (0..s.mesh.num_elements).filter(|&e| s.element_cells[e] == cell).collect();
    assert_eq!(elements.len(), 2, "cell {cell:?} should hold one element per prong");
    let shared = s.mesh.faces.iter().any(|f| {
        let sides = [Some(f.inner), f.outer];
        elements.iter().all(|&e| sides.contains(&Some(e as u32)))
    });
    assert!(!shared, "the two prong elements share a face");
    // Their volumes are the prongs clipped to the cell, computed from the box bounds.
    let clip = |a: f64, b: f64, d: usize| {
        let lo = s.origin[d] + f64::from(cell[d]) * h;
        (b.min(lo + h) - a.max(lo)).max(0.0)
    };
    let y_z = clip(0.0, 1.0, 1) * clip(1.0, 5.0, 2);
    let mut expected = [clip(0.0, 1.0, 0) * y_z, clip(1.1, 2.1, 0) * y_z];
    let volumes = element_volumes(&s.mesh);
    let mut got = [volumes[elements[0]], volumes[elements[1]]];
    expected.sort_by(f64::total_cmp);
    got.sort_by(f64::total_cmp);
    println!("U: cell {cell:?}: prong volumes {got:?}, expected {expected:?}");
    for k in 0..2 {
        assert_rel("U", "prong volume", got[k], expected[k], 1e-12);
    }
}

#[test]
fn errors_for_bad_input() {
    let surface = box_mesh([0.0; 3], [1.0; 3]);
    for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(hex_slice(&surface, h), Err(GeometryError::InvalidCellSize { .. })), "cell size {h}");
    }
    assert!(matches!(hex_slice(&surface, 1e-4), Err(GeometryError::GridTooLarge { .. })));
    let mut open = surface.clone();
    open.triangles.pop();
    assert_eq!(hex_slice(&open, 0.3).unwrap_err(), open.validate_closed().unwrap_err());
}

/// The block [0, 5] × [0, 5] × [0, 3] with the square tunnel [2.5, 3] × [1.8, 2.5] along z.
fn tunnel_block() -> TriangleMesh {
    let outer = [[0.0, 0.0], [5.0, 0.0], [5.0, 5.0], [0.0, 5.0]];
    let inner = [[2.5, 1.8], [3.0, 1.8], [3.0, 2.5], [2.5, 2.5]];
    let mut vertices = Vec::new();
    for z in [0.0, 3.0] {
        vertices.extend(outer.iter().chain(&inner).map(|&[x, y]| Point3::new(x, y, z)));
    }
    let (o, i, top) = (|k: u32| k % 4, |k: u32| 4 + k % 4, 8);
    let mut triangles = Vec::new();
    for k in 0..4 {
        // Top cap counter-clockwise in (x, y) (normal +z), bottom reversed.
        for [a, b, c] in [[o(k), o(k + 1), i(k + 1)], [o(k), i(k + 1), i(k)]] {
            triangles.push([a + top, b + top, c + top]);
            triangles.push([a, c, b]);
        }
        // Outer walls face away from the block's axis, tunnel walls into the tunnel.
        let (p, q) = (o(k), o(k + 1));
        triangles.extend([[p, q, q + top], [p, q + top, p + top]]);
        let (p, q) = (i(k), i(k + 1));
        triangles.extend([[p, q + top, q], [p, p + top, q + top]]);
    }
    TriangleMesh::new(vertices, triangles)
}

#[test]
fn tunnel_through_a_face_square_splits_the_region() {
    let surface = tunnel_block();
    surface.validate_closed().expect("the tunnel block is closed and outward");
    let h = 2.5;
    let s = check_volume_and_area("tunnel", &surface, h);
    // Setup: some grid face square contains the tunnel's cross-section strictly, on a plane
    // crossing the block, so that face's region has a hole.
    let cell_lo = |d: usize, x: f64| s.origin[d] + ((x - s.origin[d]) / h).floor() * h;
    assert!(cell_lo(0, 2.5) < 2.5 && cell_lo(0, 2.5) + h > 3.0 && cell_lo(1, 1.8) < 1.8 && cell_lo(1, 1.8) + h > 2.5);
    assert!(cell_lo(2, 3.0) > 0.0, "a z grid plane crosses the block");
    // Every element is its cell's piece of the block minus the tunnel: boxes, exactly.
    let volumes = element_volumes(&s.mesh);
    let overlap = |cell: [i32; 3], lo: [f64; 3], hi: [f64; 3]| -> f64 {
        (0..3)
            .map(|d| {
                let a = s.origin[d] + f64::from(cell[d]) * h;
                (hi[d].min(a + h) - lo[d].max(a)).max(0.0)
            })
            .product()
    };
    for (e, &cell) in s.element_cells.iter().enumerate() {
        let expected = overlap(cell, [0.0; 3], [5.0, 5.0, 3.0]) - overlap(cell, [2.5, 1.8, 0.0], [3.0, 2.5, 3.0]);
        assert_rel("tunnel", "element volume", volumes[e], expected, 1e-12);
    }
    let triangles_on_planes = s.mesh.faces.iter().filter(|f| f.outer.is_some() && f.polygon.len() == 3).count();
    println!("tunnel: {} elements, {triangles_on_planes} triangular interior faces", s.mesh.num_elements);
    assert!(triangles_on_planes > 0, "the holed region was not cut into triangles");
}

#[test]
fn degenerate_first_shift_is_replaced() {
    // A box whose far x face lies exactly on a plane of the first shifted grid (attempt 1
    // shifts x by frac(φ − 1) cells), so slicing must move on to the next shift.
    let h = 0.25;
    let first_origin_x = h * ((0.0f64 / h).floor() - 1.0 + 0.618_033_988_749_894_9);
    let far_x = first_origin_x + 5.0 * h;
    let surface = box_mesh([0.0; 3], [far_x, 1.0, 1.0]);
    let s = check_volume_and_area("box on shifted plane", &surface, h);
    assert!((s.origin.x - first_origin_x).abs() > 1e-3 * h, "the degenerate first shift was kept");
    for v in &surface.vertices {
        for d in 0..3 {
            let t = (v[d] - s.origin[d]) / h;
            assert!((t - t.round()).abs() >= 1e-9, "vertex {v:?} within 1e-9 h of a grid plane");
        }
    }
}

#[test]
fn bunny_sweep_of_cell_sizes() {
    // Many grids, many chances for near-coincidences: every slicing, raw and merged, must pass
    // the structural checks and conserve the volume.
    let surface = bunny();
    let mut h = 0.45;
    while h < 4.0 {
        for (name, options) in [("bunny sweep raw", RAW), ("bunny sweep merged", HexSliceOptions::default())] {
            let s = hex_slice_with(&surface, h, options).expect("slicing succeeds");
            let (volume, area) = check_slicing(name, &surface, &s);
            assert_rel(name, "sum of element volumes", volume, surface.signed_volume(), 1e-10);
            assert_rel(name, "boundary face area", area, surface.area(), 1e-10);
            if options.merge_below > 0.0 {
                assert_merged(name, &s);
            }
        }
        h *= 1.17;
    }
}

/// The largest interior-face penalty factor `area · (1/vol⁻ + 1/vol⁺)` in units of `1/h` (2 for
/// two cubes): the scale of the penalty term η_f of `docs/math/dg.md` §4.
fn max_penalty_factor(mesh: &PolyhedralMesh, h: f64) -> f64 {
    let volumes = element_volumes(mesh);
    mesh.faces
        .iter()
        .filter_map(|f| {
            let o = f.outer? as usize;
            let area = area_vector(&mesh.vertices, &f.polygon).norm();
            Some(area * (1.0 / volumes[f.inner as usize] + 1.0 / volumes[o]) * h)
        })
        .fold(0.0, f64::max)
}

/// Checks of a merged slicing against numbers computed here: no element below the threshold
/// except isolated ones (no interior face) as many as reported, and the report's bookkeeping.
fn assert_merged(name: &str, s: &HexSlicing) {
    let h = s.cell_size;
    let threshold = DEFAULT_MERGE_BELOW * h * h * h;
    let volumes = element_volumes(&s.mesh);
    let mut has_neighbour = vec![false; s.mesh.num_elements];
    for f in &s.mesh.faces {
        if let Some(o) = f.outer {
            has_neighbour[f.inner as usize] = true;
            has_neighbour[o as usize] = true;
        }
    }
    let small: Vec<usize> = (0..volumes.len()).filter(|&e| volumes[e] < threshold).collect();
    for &e in &small {
        assert!(!has_neighbour[e], "{name}: element {e} of volume {:e} h³ has a neighbour", volumes[e] / h.powi(3));
    }
    let r = &s.merge;
    assert_eq!(small.len(), r.isolated_small, "{name}: isolated small elements");
    assert_eq!(r.elements_after, s.mesh.num_elements);
    assert_eq!(r.elements_before - r.merges, r.elements_after);
    let min = volumes.iter().copied().fold(f64::INFINITY, f64::min);
    let diff = (r.min_volume_after - min).abs() / (h * h * h);
    assert!(diff < 1e-12, "{name}: reported smallest volume after merging off by {diff:e} h³");
}

#[test]
fn bunny_sliver_merging() {
    let surface = bunny();
    for (name, cell_size) in [("bunny ~41", 3.0), ("bunny ~300", 1.1), ("bunny ~5000", 0.375)] {
        let h3 = cell_size * cell_size * cell_size;
        let raw = hex_slice_with(&surface, cell_size, RAW).expect("raw slicing succeeds");
        let start = Instant::now();
        let s = hex_slice(&surface, cell_size).expect("slicing succeeds");
        let seconds = start.elapsed().as_secs_f64();
        let (volume, area) = check_slicing(name, &surface, &s);
        // The enclosed volume from the bunny's triangles (independent node script) and from the
        // crate's surface volume.
        assert_rel(name, "merged volumes vs independent bunny volume", volume, BUNNY_VOLUME, 1e-10);
        assert_rel(name, "merged volumes vs surface volume", volume, surface.signed_volume(), 1e-10);
        assert_rel(name, "boundary face area", area, surface.area(), 1e-10);
        assert_merged(name, &s);
        // Same grid, and every merged element is the union of the raw pieces mapped to it.
        assert_eq!(s.origin, raw.origin);
        assert_eq!(s.merge.elements_before, raw.mesh.num_elements);
        let raw_volumes = element_volumes(&raw.mesh);
        let mut summed = vec![0.0; s.mesh.num_elements];
        for (piece, &e) in s.merge.element_map.iter().enumerate() {
            summed[e as usize] += raw_volumes[piece];
        }
        for (e, (&got, &expected)) in element_volumes(&s.mesh).iter().zip(&summed).enumerate() {
            assert_rel(name, &format!("element {e} volume vs its raw pieces"), got, expected, 1e-9);
        }
        // The cell of a merged element is its surviving piece's cell.
        for (e, &piece) in s.merge.survivors.iter().enumerate() {
            assert_eq!(s.merge.element_map[piece as usize] as usize, e);
            assert_eq!(s.element_cells[e], raw.element_cells[piece as usize]);
        }
        let raw_min = raw_volumes.iter().copied().fold(f64::INFINITY, f64::min);
        println!(
            "{name}: h = {cell_size}: {} → {} elements ({} merges, {} isolated small kept); smallest volume \
             {:.2e} h³ → {:.2e} h³; max penalty factor area·(1/v⁻+1/v⁺)·h {:.3e} → {:.3e}; merged slicing {:.1} ms",
            raw.mesh.num_elements,
            s.mesh.num_elements,
            s.merge.merges,
            s.merge.isolated_small,
            raw_min / h3,
            s.merge.min_volume_after / h3,
            max_penalty_factor(&raw.mesh, cell_size),
            max_penalty_factor(&s.mesh, cell_size),
            seconds * 1e3,
        );
        // Absolute in h³: the cone sums here lose digits on pieces far smaller than the cell.
        let diff = (s.merge.min_volume_before - raw_min).abs() / h3;
        assert!(diff < 1e-12, "{name}: reported smallest raw volume off by {diff:e} h³");
        assert!(s.mesh.num_elements < raw.mesh.num_elements, "{name}: nothing merged");
    }
}

#[test]
fn invalid_merge_threshold() {
    let surface = box_mesh([0.0; 3], [1.0; 3]);
    for merge_below in [-0.1, f64::NAN, f64::INFINITY] {
        let result = hex_slice_with(&surface, 0.3, HexSliceOptions { merge_below });
        assert!(
            matches!(result, Err(GeometryError::InvalidMergeThreshold { threshold }) if threshold.to_bits() == merge_below.to_bits()),
            "merge_below {merge_below}: {result:?}"
        );
    }
}
