//! A surface mesh embedded in the cubes, separated along its triangles' edges where the cubes
//! under them come apart (mueller2004 §3.1), and closed again (docs/math/voxel-cutting.md §4):
//! large triangles are split at load so no edge exceeds the cube edge (§3.3), each triangle
//! belongs to the cube its centroid lies in, two triangles sharing an edge stay joined while
//! their cubes share a node (after a cut, cubes across it share none), each vertex is copied per
//! group of joined triangles around it and embedded trilinearly in a cube of its group, and every
//! loop of edges left open is capped by a polygon through its own vertices.

use crate::mesh::VoxelMesh;
use crate::stiffness::corner_offset;
use cleave_core::{EmbeddedSurface, Point3, Real, Vector3};
use cleave_geometry::{TriangleMesh, UnionFind};
use std::collections::{HashMap, HashSet};

/// The input surface as the voxel mesh keeps it: rest vertices, triangles (no edge longer than
/// the cube edge), the cube under each triangle's centroid, and the pairs of triangles that
/// share an edge.
#[derive(Clone, Debug)]
pub struct EmbeddedInput {
    vertices: Vec<Point3<Real>>,
    triangles: Vec<[u32; 3]>,
    owner: Vec<[i32; 3]>,
    /// (triangle, triangle, the shared edge's two vertices).
    neighbours: Vec<(u32, u32, [u32; 2])>,
}

/// Splits every edge longer than `h` at its midpoint, in passes, each triangle by the number of
/// its edges split (2, 3 or 4 triangles), until none is longer (mueller2004 §3.3). Midpoints are
/// shared by the triangles on both sides, so a closed surface stays closed.
pub fn subdivide_to(mesh: &TriangleMesh, h: Real) -> TriangleMesh {
    let mut vertices = mesh.vertices.clone();
    let mut triangles = mesh.triangles.clone();
    loop {
        let mut midpoint: HashMap<(u32, u32), u32> = HashMap::new();
        let long = |a: u32, b: u32, vertices: &[Point3<Real>]| (vertices[a as usize] - vertices[b as usize]).norm() > h;
        let mut any = false;
        let mut next = Vec::with_capacity(triangles.len());
        for t in &triangles {
            let mid: [Option<u32>; 3] = std::array::from_fn(|k| {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                long(a, b, &vertices).then(|| {
                    *midpoint.entry((a.min(b), a.max(b))).or_insert_with(|| {
                        vertices.push(Point3::from((vertices[a as usize].coords + vertices[b as usize].coords) / 2.0));
                        (vertices.len() - 1) as u32
                    })
                })
            });
            match mid {
                [None, None, None] => next.push(*t),
                [Some(m), None, None] => next.extend([[t[0], m, t[2]], [m, t[1], t[2]]]),
                [None, Some(m), None] => next.extend([[t[1], m, t[0]], [m, t[2], t[0]]]),
                [None, None, Some(m)] => next.extend([[t[2], m, t[1]], [m, t[0], t[1]]]),
                [Some(a), Some(b), None] => next.extend([[t[0], a, t[2]], [a, t[1], b], [a, b, t[2]]]),
                [None, Some(b), Some(c)] => next.extend([[t[1], b, t[0]], [b, t[2], c], [b, c, t[0]]]),
                [Some(a), None, Some(c)] => next.extend([[t[2], c, t[1]], [c, t[0], a], [c, a, t[1]]]),
                [Some(a), Some(b), Some(c)] => next.extend([[t[0], a, c], [a, t[1], b], [c, b, t[2]], [a, b, c]]),
            }
            any |= mid.iter().any(Option::is_some);
        }
        triangles = next;
        if !any {
            return TriangleMesh::new(vertices, triangles);
        }
    }
}

/// Triangulates the closed polygon `loop_` (indices into `points`, in order) by ear clipping in
/// the plane of its Newell normal, keeping its orientation: every edge `loop_[k] → loop_[k+1]`
/// is an edge of a triangle in that direction. An ear whose new edge is already an edge of the
/// surface (`taken`, undirected, smaller index first) is not cut, so no edge ends up in more
/// than two triangles; the edges it makes are added to `taken`. A polygon whose projection has
/// no such ear (a slit whose two sides coincide, a loop that crosses itself in projection) is
/// clipped at any ear whose new edge is free, ignoring the plane, and fanned as a last resort.
pub fn cap_loop(points: &[Point3<Real>], loop_: &[u32], taken: &mut HashSet<(u32, u32)>) -> Vec<[u32; 3]> {
    let p = |v: u32| points[v as usize];
    let mut normal = Vector3::zeros();
    for k in 0..loop_.len() {
        normal += p(loop_[k]).coords.cross(&p(loop_[(k + 1) % loop_.len()]).coords);
    }
    let scale: Real = loop_.iter().map(|&v| (p(v) - p(loop_[0])).norm_squared()).fold(0.0, Real::max);
    let flat = normal.norm() <= 1e-12 * scale;
    let normal = if flat { Vector3::zeros() } else { normal.normalize() };
    let twice_area = |a: u32, b: u32, c: u32| (p(b) - p(a)).cross(&(p(c) - p(a))).dot(&normal);
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let mut polygon: Vec<u32> = loop_.to_vec();
    let mut out = Vec::with_capacity(loop_.len());
    while polygon.len() > 3 {
        let n = polygon.len();
        let corners = |i: usize| (polygon[(i + n - 1) % n], polygon[i], polygon[(i + 1) % n]);
        let free = |i: usize| {
            let (a, _, c) = corners(i);
            a != c && !taken.contains(&key(a, c))
        };
        let geometric = |i: usize| {
            let (a, b, c) = corners(i);
            !flat
                && twice_area(a, b, c) > 1e-12 * scale
                && !polygon.iter().any(|&q| {
                    q != a
                        && q != b
                        && q != c
                        && twice_area(a, b, q) >= 0.0
                        && twice_area(b, c, q) >= 0.0
                        && twice_area(c, a, q) >= 0.0
                })
        };
        let ear = (0..n).find(|&i| free(i) && geometric(i)).or_else(|| (0..n).find(|&i| free(i)));
        let Some(ear) = ear else {
            // No ear with a free new edge: fan what is left from its first vertex.
            out.extend((1..n - 1).map(|k| [polygon[0], polygon[k], polygon[k + 1]]));
            return out;
        };
        let (a, b, c) = corners(ear);
        taken.insert(key(a, c));
        out.push([a, b, c]);
        polygon.remove(ear);
    }
    out.push([polygon[0], polygon[1], polygon[2]]);
    out
}

impl EmbeddedInput {
    /// The surface `mesh` (closed, every edge in two triangles) for cubes of edge `h`: split so
    /// no edge exceeds `h`, each triangle under the cube `cell_of` gives its centroid (`None`:
    /// no cube there, an error naming the triangle).
    pub fn new(
        mesh: &TriangleMesh,
        h: Real,
        cell_of: impl Fn(&Point3<Real>) -> Option<[i32; 3]>,
    ) -> Result<Self, String> {
        let mesh = subdivide_to(mesh, h);
        let mut owner = Vec::with_capacity(mesh.triangles.len());
        for (i, t) in mesh.triangles.iter().enumerate() {
            let centroid =
                Point3::from(t.iter().map(|&v| mesh.vertices[v as usize].coords).sum::<Vector3<Real>>() / 3.0);
            let cell = cell_of(&centroid)
                .or_else(|| t.iter().find_map(|&v| cell_of(&mesh.vertices[v as usize])))
                .ok_or_else(|| format!("surface triangle {i} (centroid {centroid:?}) lies in no cube"))?;
            owner.push(cell);
        }
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        let mut neighbours = Vec::new();
        for (i, t) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                match edges.remove(&(b, a)) {
                    Some(j) => neighbours.push((j, i as u32, [a, b])),
                    None => {
                        edges.insert((a, b), i as u32);
                    }
                }
            }
        }
        if let Some((&(a, b), &t)) = edges.iter().next() {
            return Err(format!("the surface is not closed: edge {a} → {b} of triangle {t} has no opposite edge"));
        }
        Ok(Self { vertices: mesh.vertices, triangles: mesh.triangles, owner, neighbours })
    }

    /// Triangles after subdivision.
    pub fn num_triangles(&self) -> usize {
        self.triangles.len()
    }
}

impl VoxelMesh {
    /// Trilinear weights of `p` in `cube` over its nodes (extrapolated outside it).
    fn trilinear_row(&self, cube: usize, p: &Point3<Real>) -> ([u32; 8], [Real; 8]) {
        let cell = self.cells()[cube];
        let h = self.cell_size();
        let t: [Real; 3] = std::array::from_fn(|a| (p[a] - self.origin()[a]) / h - cell[a] as Real);
        let weights = std::array::from_fn(|c| {
            let o = corner_offset(c);
            (0..3).map(|a| if o[a] == 1 { t[a] } else { 1.0 - t[a] }).product()
        });
        (self.cube_nodes()[cube], weights)
    }

    /// The embedded input surface of the current topology: separated where the cubes under two
    /// triangles sharing an edge no longer share a node, every open loop capped (`on_cut`).
    pub(crate) fn separated_surface(&self, input: &EmbeddedInput, piece_of: &[u32]) -> EmbeddedSurface {
        let cube: Vec<usize> =
            input.owner.iter().map(|c| self.cube_at(*c).expect("the owner cubes are the mesh's")).collect();
        let shares_node = |a: usize, b: usize| {
            a == b || {
                let (na, nb) = (&self.cube_nodes()[a], &self.cube_nodes()[b]);
                na.iter().any(|n| nb.contains(n))
            }
        };
        // Corner slots 3t + k, united across every joined edge.
        let mut slots = UnionFind::new(3 * input.triangles.len());
        let slot = |t: u32, v: u32| 3 * t as usize + input.triangles[t as usize].iter().position(|&w| w == v).unwrap();
        for &(t, u, [a, b]) in &input.neighbours {
            if shares_node(cube[t as usize], cube[u as usize]) {
                slots.union(slot(t, a), slot(u, a));
                slots.union(slot(t, b), slot(u, b));
            }
        }
        // Slots around one vertex are united only through its fan; slots of different vertices
        // are never united, so a class is one copy of one vertex.
        let mut surface = EmbeddedSurface::default();
        let mut copy_of_class: HashMap<usize, u32> = HashMap::new();
        for (t, tri) in input.triangles.iter().enumerate() {
            let mut ids = [0u32; 3];
            for (k, &v) in tri.iter().enumerate() {
                let class = slots.find(3 * t + k);
                ids[k] = *copy_of_class.entry(class).or_insert_with(|| {
                    let p = input.vertices[v as usize];
                    surface.rest_vertices.push(p);
                    (surface.rest_vertices.len() - 1) as u32
                });
            }
            surface.triangles.push(ids);
            surface.on_cut.push(false);
            surface.piece.push(piece_of[cube[t]]);
        }
        // Each copy embedded in a cube of its own triangles: one that contains it if any.
        let mut host: Vec<Option<(usize, bool)>> = vec![None; surface.rest_vertices.len()];
        let h = self.cell_size();
        for (t, ids) in surface.triangles.iter().enumerate() {
            for &id in ids {
                let p = surface.rest_vertices[id as usize];
                let cell = self.cells()[cube[t]];
                let inside = (0..3).all(|a| {
                    let s = (p[a] - self.origin()[a]) / h - cell[a] as Real;
                    (-1e-9..=1.0 + 1e-9).contains(&s)
                });
                match host[id as usize] {
                    Some((_, true)) => {}
                    Some((_, false)) if !inside => {}
                    _ => host[id as usize] = Some((cube[t], inside)),
                }
            }
        }
        for (id, p) in surface.rest_vertices.iter().enumerate() {
            let (c, _) = host[id].expect("every copy has a triangle");
            let (nodes, weights) = self.trilinear_row(c, p);
            surface.embedding.push_row(&nodes, &weights);
        }
        // Open edges: a directed edge whose reverse no triangle has.
        let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
        for (t, ids) in surface.triangles.iter().enumerate() {
            for k in 0..3 {
                directed.insert((ids[k], ids[(k + 1) % 3]), t);
            }
        }
        let mut open: Vec<(u32, u32)> =
            directed.keys().filter(|(a, b)| !directed.contains_key(&(*b, *a))).copied().collect();
        open.sort_unstable();
        let mut taken: HashSet<(u32, u32)> = directed.keys().map(|&(a, b)| (a.min(b), a.max(b))).collect();
        let mut outgoing: HashMap<u32, Vec<u32>> = HashMap::new();
        for &(a, b) in &open {
            outgoing.entry(a).or_default().push(b);
        }
        for &(a, b) in &open {
            let Some(list) = outgoing.get_mut(&a) else { continue };
            let Some(k) = list.iter().position(|&w| w == b) else { continue };
            list.swap_remove(k);
            let piece = surface.piece[directed[&(a, b)]];
            // Walk the open edges from a → b back to a.
            let mut walk = vec![a];
            let mut at = b;
            while at != a {
                walk.push(at);
                let Some(next) = outgoing.get_mut(&at).and_then(|l| l.pop()) else { break };
                at = next;
            }
            if at != a || walk.len() < 3 {
                continue;
            }
            // The cap runs the loop backwards: each open edge a → b gets its b → a.
            walk.reverse();
            for t in cap_loop(&surface.rest_vertices, &walk, &mut taken) {
                surface.triangles.push(t);
                surface.on_cut.push(true);
                surface.piece.push(piece);
            }
        }
        surface
    }
}
