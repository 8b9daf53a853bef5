//! A convex polyhedral mesh of a closed surface, made without TetGen (docs/math/mean-value.md
//! §8): a grid of cubes of edge `h` over the solid; cubes well inside stay whole (8-node mean
//! value elements), the others are split into the six Kuhn tetrahedra around their main
//! diagonal (conforming across cubes, and with a cube's face split into two coplanar triangles
//! where a split cube meets a whole one). The signed distance to the surface is sampled at the
//! lattice nodes; a node closer to an edge's zero crossing than [`WARP_FRACTION`] of the edge is
//! moved onto that crossing (isosurface stuffing's warp, Labelle & Shewchuk 2007: tetrahedra stay
//! planar-faced whatever their nodes do, and no cut leaves a sliver); every tetrahedron the zero
//! set crosses is cut by the plane of its linear interpolant, which is the same line on a face
//! from both sides, so the cells are convex and conforming with no node inserted anywhere. The
//! boundary is the marching-tetrahedra surface of the sampled distance: within O(h²) of the
//! input, and the volume differs by that much (measured in the tests).

use crate::cuttable::element_of;
use crate::mesh::{DEFAULT_REFINEMENT, MeanValueError, MeanValueMesh};
use crate::polyhedron::Real;
use cleave_core::{Material, Point3, Vector3};
use cleave_geometry::{InsideTester, TriangleMesh};
use std::collections::HashMap;

/// A node closer to a zero crossing of one of its edges than this fraction of the edge is moved
/// onto it (the cut would otherwise leave a cell thinner than that).
pub const WARP_FRACTION: Real = 0.2;

/// Largest number of cubes of the grid's bounding box the mesher accepts.
pub const MAX_CUBES: usize = 20_000_000;

/// Local faces of a cuboid whose corner `c` has bit 0 = x, bit 1 = y, bit 2 = z (outward).
const CUBE_FACES: [[usize; 4]; 6] =
    [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];

/// What meshing a surface made, for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeshingReport {
    /// Whole cubes (well inside).
    pub cubes: usize,
    /// Whole tetrahedra.
    pub tetrahedra: usize,
    /// Cut tetrahedra (convex cells with a face on the surface).
    pub cut: usize,
    /// Nodes moved onto the surface.
    pub warped: usize,
}

/// The Kuhn tetrahedra of a cube: corner 0, one axis step, two, corner 7 (every permutation of
/// the axes), positively oriented.
fn kuhn_tetrahedra() -> [[usize; 4]; 6] {
    let mut tets = [[0; 4]; 6];
    let permutations = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    for (t, p) in permutations.iter().enumerate() {
        let a = 1 << p[0];
        let b = a | (1 << p[1]);
        // Even permutations are positive with this order; odd ones swap two corners.
        tets[t] = if t == 0 || t == 3 || t == 4 { [0, a, b, 7] } else { [0, b, a, 7] };
    }
    tets
}

/// Outward faces of a positively oriented tetrahedron `[a, b, c, d]`.
const TET_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// The mean value mesh of the solid `surface` bounds (closed, outward), on cubes of edge `h`.
pub fn mesh_closed_surface(
    surface: &TriangleMesh,
    h: Real,
    material: Material,
) -> Result<(MeanValueMesh, MeshingReport), MeanValueError> {
    let surface_error = |e: cleave_geometry::GeometryError| MeanValueError::Surface(e.to_string());
    if !(h.is_finite() && h > 0.0) {
        return Err(MeanValueError::Surface(format!("the cell size must be finite and positive, got {h}")));
    }
    let tester = InsideTester::new(surface).map_err(surface_error)?;
    let (lo, hi) = surface.aabb();
    // One cube of margin on every side, the grid centred on the surface's box.
    let dims: [usize; 3] = std::array::from_fn(|a| ((hi[a] - lo[a]) / h).ceil() as usize + 2);
    let count = dims.iter().map(|&d| d as u128).product::<u128>();
    if count > MAX_CUBES as u128 {
        return Err(MeanValueError::Surface(format!(
            "a cell size of {h} m makes {count} cubes over the surface's box, more than {MAX_CUBES}"
        )));
    }
    let origin = Point3::from((lo.coords + hi.coords) / 2.0 - Vector3::from(dims.map(|d| d as Real)) * (h / 2.0));
    let index = |i: usize, j: usize, k: usize| i + (dims[0] + 1) * (j + (dims[1] + 1) * k);
    let lattice = |n: usize| {
        let (i, j, k) = (n % (dims[0] + 1), (n / (dims[0] + 1)) % (dims[1] + 1), n / ((dims[0] + 1) * (dims[1] + 1)));
        origin + Vector3::new(i as Real, j as Real, k as Real) * h
    };
    let nodes = (dims[0] + 1) * (dims[1] + 1) * (dims[2] + 1);
    // The signed distance at every lattice node (in parallel would need rayon here; the tree
    // query is a few microseconds).
    let mut distance: Vec<Real> = (0..nodes).map(|n| tester.signed_distance(&lattice(n))).collect();
    let mut position: Vec<Point3<Real>> = (0..nodes).map(lattice).collect();
    let cube_nodes = |i: usize, j: usize, k: usize| -> [usize; 8] {
        std::array::from_fn(|c| index(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)))
    };
    // Whole cubes: every corner deeper than a warp could reach from a crossing on its longest
    // edge (the distance is 1-Lipschitz), so none of their nodes moves.
    let deep = -(WARP_FRACTION + 1e-9) * 3f64.sqrt() * h;
    let tets = kuhn_tetrahedra();
    let mut whole = Vec::new();
    let mut split = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let corners = cube_nodes(i, j, k);
                if corners.iter().all(|&n| distance[n] < deep) {
                    whole.push(corners);
                } else if corners.iter().any(|&n| distance[n] < 0.0) {
                    split.push(corners);
                }
            }
        }
    }
    // Warp: each node to the nearest zero crossing closer than the fraction of its edge.
    let mut target: HashMap<usize, (Real, Point3<Real>)> = HashMap::new();
    for corners in &split {
        for tet in &tets {
            for a in 0..4 {
                for b in a + 1..4 {
                    let (p, q) = (corners[tet[a]], corners[tet[b]]);
                    let (dp, dq) = (distance[p], distance[q]);
                    if !(dp < 0.0 && dq > 0.0 || dp > 0.0 && dq < 0.0) {
                        continue;
                    }
                    let t = dp / (dp - dq);
                    let crossing = position[p] + (position[q] - position[p]) * t;
                    let length = (position[q] - position[p]).norm();
                    for (node, fraction) in [(p, t), (q, 1.0 - t)] {
                        if fraction < WARP_FRACTION {
                            let gap = fraction * length;
                            let entry = target.entry(node).or_insert((Real::MAX, crossing));
                            if gap < entry.0
                                || (gap == entry.0
                                    && (crossing.x, crossing.y, crossing.z) < (entry.1.x, entry.1.y, entry.1.z))
                            {
                                *entry = (gap, crossing);
                            }
                        }
                    }
                }
            }
        }
    }
    let warped = target.len();
    for (&node, &(_, crossing)) in &target {
        position[node] = crossing;
        distance[node] = 0.0;
    }
    // The elements, on global node ids: lattice nodes, then crossing nodes.
    let mut crossing_of: HashMap<(usize, usize), usize> = HashMap::new();
    let mut extra: Vec<Point3<Real>> = Vec::new();
    let mut faces_of: Vec<Vec<Vec<usize>>> = Vec::with_capacity(whole.len() + 6 * split.len());
    // A whole cube's face that a split neighbour's tetrahedra meet is split along the Kuhn
    // diagonal (from its lowest-index corner to its highest), as two coplanar triangles.
    let split_cube: std::collections::HashSet<usize> = split.iter().map(|c| c[0]).collect();
    let (mut tetrahedra, mut cut) = (0, 0);
    for corners in &whole {
        let mut faces = Vec::with_capacity(8);
        for (f, face) in CUBE_FACES.iter().enumerate() {
            let nodes: Vec<usize> = face.iter().map(|&c| corners[c]).collect();
            // The neighbour across face f (z, y, x faces, low then high): its lowest corner.
            let step = if f % 2 == 0 { -1i64 } else { 1 };
            let stride = [1, dims[0] + 1, (dims[0] + 1) * (dims[1] + 1)][[2, 2, 1, 1, 0, 0][f]];
            let neighbour = corners[0] as i64 + step * stride as i64;
            if neighbour >= 0 && split_cube.contains(&(neighbour as usize)) {
                // The Kuhn diagonal of a face joins its lowest and highest corner (lattice ids
                // grow with x, y and z), which lie opposite each other.
                let (low, _) = nodes.iter().enumerate().min_by_key(|(_, n)| **n).expect("four");
                let high = (low + 2) % 4;
                faces.push(vec![nodes[low], nodes[(low + 1) % 4], nodes[high]]);
                faces.push(vec![nodes[high], nodes[(high + 1) % 4], nodes[low]]);
            } else {
                faces.push(nodes);
            }
        }
        faces_of.push(faces);
    }
    for corners in &split {
        for tet in &tets {
            let v = tet.map(|c| corners[c]);
            let d = v.map(|n| distance[n]);
            if d.iter().all(|&x| x >= 0.0) {
                continue;
            }
            if d.iter().all(|&x| x <= 0.0) {
                faces_of.push(TET_FACES.iter().map(|f| f.iter().map(|&c| v[c]).collect()).collect());
                tetrahedra += 1;
                continue;
            }
            // The part where the linear interpolant is ≤ 0: each face clipped, and the cap.
            let mut crossing = |a: usize, b: usize, extra: &mut Vec<Point3<Real>>| -> usize {
                let (lo, hi) = (a.min(b), a.max(b));
                *crossing_of.entry((lo, hi)).or_insert_with(|| {
                    let t = distance[lo] / (distance[lo] - distance[hi]);
                    extra.push(position[lo] + (position[hi] - position[lo]) * t);
                    nodes + extra.len() - 1
                })
            };
            let mut faces: Vec<Vec<usize>> = Vec::with_capacity(5);
            let mut runs: HashMap<usize, usize> = HashMap::new();
            for f in &TET_FACES {
                let mut polygon = Vec::with_capacity(4);
                let mut on = Vec::with_capacity(2);
                for e in 0..3 {
                    let (a, b) = (v[f[e]], v[f[(e + 1) % 3]]);
                    let (da, db) = (distance[a], distance[b]);
                    if da <= 0.0 {
                        polygon.push(a);
                        if da == 0.0 {
                            on.push(polygon.len() - 1);
                        }
                    }
                    if da < 0.0 && db > 0.0 || da > 0.0 && db < 0.0 {
                        polygon.push(crossing(a, b, &mut extra));
                        on.push(polygon.len() - 1);
                    }
                }
                let inside = f.iter().any(|&c| d[c] < 0.0);
                if polygon.len() < 3 || !inside {
                    continue;
                }
                // Edges of this face on the zero plane close the cap, reversed.
                let m = polygon.len();
                for k in 0..m {
                    if on.contains(&k) && on.contains(&((k + 1) % m)) {
                        runs.insert(polygon[(k + 1) % m], polygon[k]);
                    }
                }
                faces.push(polygon);
            }
            if let Some((&start, _)) = runs.iter().min_by_key(|(a, _)| **a) {
                let mut cap = vec![start];
                let mut current = runs[&start];
                while current != start && cap.len() <= runs.len() {
                    cap.push(current);
                    current = match runs.get(&current) {
                        Some(&next) => next,
                        None => break,
                    };
                }
                if cap.len() >= 3 {
                    faces.push(cap);
                }
            }
            faces_of.push(faces);
            cut += 1;
        }
    }
    // Renumber the nodes the elements use, and build them.
    let mut renumber: HashMap<usize, u32> = HashMap::new();
    let mut rest: Vec<Point3<Real>> = Vec::new();
    let mut built = Vec::with_capacity(faces_of.len());
    for (e, faces) in faces_of.iter().enumerate() {
        let faces: Vec<Vec<u32>> = faces
            .iter()
            .map(|f| {
                f.iter()
                    .map(|&n| {
                        *renumber.entry(n).or_insert_with(|| {
                            rest.push(if n < nodes { position[n] } else { extra[n - nodes] });
                            (rest.len() - 1) as u32
                        })
                    })
                    .collect()
            })
            .collect();
        let (shape, element_nodes) =
            element_of(&faces, &rest, 0.0).map_err(|source| MeanValueError::Element { element: e, source })?;
        built.push((shape, element_nodes, vec![false; faces.len()]));
    }
    let report = MeshingReport { cubes: whole.len(), tetrahedra, cut, warped };
    let mesh = MeanValueMesh::with_cut_faces(material, rest, built, DEFAULT_REFINEMENT, None)?;
    Ok((mesh, report))
}
