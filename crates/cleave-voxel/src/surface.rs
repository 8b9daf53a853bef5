//! A surface mesh embedded in the cubes, separated along its triangles' edges where the cubes
//! under them come apart (mueller2004 §3.1), and closed again (docs/math/voxel-cutting.md §4):
//! large triangles are split at load so no edge exceeds the cube edge (§3.3), each triangle
//! belongs to the cube its centroid lies in, two triangles sharing an edge stay joined while
//! their cubes share a node (after a cut, cubes across it share none), each vertex is copied per
//! group of joined triangles around it and embedded trilinearly in a cube of its group; each side
//! of every separated face is closed by the paper's polygons (`closing.rs`), and every loop of
//! edges still open is capped by a polygon through its own vertices.

use crate::closing::{Closer, ClosingRefusal, ClosingReport, ClosingVertex};
use crate::mesh::VoxelMesh;
use crate::stiffness::corner_offset;
use cleave_core::{Discretization, EmbeddedSurface, Point3, Real, Vector3};
use cleave_geometry::{InsideTester, TriangleMesh, UnionFind};
use std::collections::{HashMap, HashSet};

/// The input surface as the voxel mesh keeps it: rest vertices, triangles (no edge longer than
/// the cube edge), the cube under each triangle's centroid, and the pairs of triangles that
/// share an edge.
#[derive(Clone, Debug)]
pub struct EmbeddedInput {
    pub(crate) vertices: Vec<Point3<Real>>,
    pub(crate) triangles: Vec<[u32; 3]>,
    owner: Vec<[i32; 3]>,
    /// (triangle, triangle, the shared edge's two vertices).
    neighbours: Vec<(u32, u32, [u32; 2])>,
    /// Per vertex, the triangles around it and its corner in each (CSR by `around_offsets`).
    around: Vec<(u32, u8)>,
    around_offsets: Vec<u32>,
    /// The triangles whose bounding box touches each cell (closed cells).
    by_cell: HashMap<[i32; 3], Vec<u32>>,
    /// Point containment for the faces no triangle crosses.
    inside: std::sync::Arc<InsideTester>,
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
/// clipped at any ear whose new edge is free, ignoring the plane. What is left when no ear has a
/// free new edge is returned second, to be fanned from a new vertex (every edge of that fan is
/// new, so none ends up in more than two triangles).
pub fn cap_loop(
    points: &[Point3<Real>],
    loop_: &[u32],
    taken: &mut HashSet<(u32, u32)>,
) -> (Vec<[u32; 3]>, Option<Vec<u32>>) {
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
            return (out, Some(polygon));
        };
        let (a, b, c) = corners(ear);
        taken.insert(key(a, c));
        out.push([a, b, c]);
        polygon.remove(ear);
    }
    out.push([polygon[0], polygon[1], polygon[2]]);
    (out, None)
}

impl EmbeddedInput {
    /// The surface `mesh` (closed, every edge in two triangles) for cubes of edge `h`: split so
    /// no edge exceeds `h`, each triangle under the cube `cell_of` gives its centroid (`None`:
    /// no cube there, an error naming the triangle).
    pub fn new(
        mesh: &TriangleMesh,
        origin: Point3<Real>,
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
        let mut around_offsets = vec![0u32; mesh.vertices.len() + 1];
        for t in &mesh.triangles {
            for &v in t {
                around_offsets[v as usize + 1] += 1;
            }
        }
        for v in 0..mesh.vertices.len() {
            around_offsets[v + 1] += around_offsets[v];
        }
        let mut around = vec![(0u32, 0u8); around_offsets[mesh.vertices.len()] as usize];
        let mut fill = around_offsets.clone();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for (k, &v) in tri.iter().enumerate() {
                around[fill[v as usize] as usize] = (t as u32, k as u8);
                fill[v as usize] += 1;
            }
        }
        let mut by_cell: HashMap<[i32; 3], Vec<u32>> = HashMap::new();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let cell = |p: &Point3<Real>, grow: Real| -> [i32; 3] {
                std::array::from_fn(|a| ((p[a] - origin[a]) / h + grow).floor() as i32)
            };
            let (mut lo, mut hi) = ([i32::MAX; 3], [i32::MIN; 3]);
            for &v in tri {
                let (l, u) = (cell(&mesh.vertices[v as usize], -1e-9), cell(&mesh.vertices[v as usize], 1e-9));
                for a in 0..3 {
                    lo[a] = lo[a].min(l[a]);
                    hi[a] = hi[a].max(u[a]);
                }
            }
            // Cells are closed (the ±1e-9 above): a triangle on a face belongs to both cubes.
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        by_cell.entry([x, y, z]).or_default().push(t as u32);
                    }
                }
            }
        }
        let inside = InsideTester::new(&mesh).map_err(|e| format!("the carried surface: {e}"))?;
        Ok(Self {
            vertices: mesh.vertices,
            triangles: mesh.triangles,
            owner,
            neighbours,
            around,
            around_offsets,
            by_cell,
            inside: std::sync::Arc::new(inside),
        })
    }

    /// The triangles around input vertex `vertex`, each with the vertex's corner in it.
    pub(crate) fn triangles_around(&self, vertex: u32) -> &[(u32, u8)] {
        let v = vertex as usize;
        &self.around[self.around_offsets[v] as usize..self.around_offsets[v + 1] as usize]
    }

    /// The triangles whose bounding box touches the closed cell `cell`.
    pub(crate) fn triangles_in_cell(&self, cell: [i32; 3]) -> &[u32] {
        self.by_cell.get(&cell).map_or(&[], Vec::as_slice)
    }

    /// Whether `p` is inside the surface.
    pub(crate) fn contains(&self, p: &Point3<Real>) -> bool {
        self.inside.contains(p)
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

    /// How the carried surface of the current topology was closed (`None` without one): face
    /// sides closed by the paper's polygons, refused ones by reason, loops capped after.
    pub fn closing_report(&self) -> Option<ClosingReport> {
        let input = self.embedded_input()?;
        let (piece_of, _) = self.piece_of_cubes();
        Some(self.separated_surface(input, &piece_of).1)
    }

    /// The embedded input surface of the current topology: separated where the cubes under two
    /// triangles sharing an edge no longer share a node, every open loop capped (`on_cut`).
    pub(crate) fn separated_surface(
        &self,
        input: &EmbeddedInput,
        piece_of: &[u32],
    ) -> (EmbeddedSurface, ClosingReport) {
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
        // Each class embedded in a cube of its own triangles: one that contains the vertex if any.
        let h = self.cell_size();
        let mut host: HashMap<usize, (usize, bool)> = HashMap::new();
        for (t, tri) in input.triangles.iter().enumerate() {
            let cell = self.cells()[cube[t]];
            for (k, &v) in tri.iter().enumerate() {
                let p = input.vertices[v as usize];
                let inside = (0..3).all(|a| {
                    let s = (p[a] - self.origin()[a]) / h - cell[a] as Real;
                    (-1e-9..=1.0 + 1e-9).contains(&s)
                });
                let entry = host.entry(slots.find(3 * t + k)).or_insert((cube[t], inside));
                if inside && !entry.1 {
                    *entry = (cube[t], inside);
                }
            }
        }
        // One copy per vertex and set of nodes it moves with: two classes of a vertex embedded on
        // the same nodes (a fan split by a crack that passes through it twice) coincide in every
        // motion, so they are one vertex, not two at one place.
        let mut surface = EmbeddedSurface::default();
        let mut copy_of_class: HashMap<usize, u32> = HashMap::new();
        let mut copy_of_key: HashMap<(u32, Vec<u32>), u32> = HashMap::new();
        for (t, tri) in input.triangles.iter().enumerate() {
            let mut ids = [0u32; 3];
            for (k, &v) in tri.iter().enumerate() {
                let class = slots.find(3 * t + k);
                ids[k] = *copy_of_class.entry(class).or_insert_with(|| {
                    let p = input.vertices[v as usize];
                    let (nodes, weights) = self.trilinear_row(host[&class].0, &p);
                    let mut support: Vec<u32> =
                        nodes.iter().zip(&weights).filter(|(_, w)| w.abs() > 1e-9).map(|(&n, _)| n).collect();
                    support.sort_unstable();
                    *copy_of_key.entry((v, support)).or_insert_with(|| {
                        surface.rest_vertices.push(p);
                        surface.embedding.push_row(&nodes, &weights);
                        (surface.rest_vertices.len() - 1) as u32
                    })
                });
            }
            surface.triangles.push(ids);
            surface.on_cut.push(false);
            surface.piece.push(piece_of[cube[t]]);
        }
        let report = self.close_faces(input, &cube, piece_of, &mut surface);
        (surface, report)
    }

    /// Closes `surface` (the separated input triangles, in input order): each side of every
    /// separated face by the paper's polygons (`closing.rs`), kept where it leaves every edge in
    /// at most two triangles, once each way; then every loop of edges still open is capped.
    fn close_faces(
        &self,
        input: &EmbeddedInput,
        cube: &[usize],
        piece_of: &[u32],
        surface: &mut EmbeddedSurface,
    ) -> ClosingReport {
        let copies: Vec<[u32; 3]> = surface.triangles.clone();
        let closer = Closer { mesh: self, input, triangle_cube: cube, triangle_copies: &copies };
        let mut report = ClosingReport::default();
        let mut refused: HashMap<ClosingRefusal, usize> = HashMap::new();
        let mut directed: HashSet<(u32, u32)> = HashSet::new();
        let mut uses: HashMap<(u32, u32), u8> = HashMap::new();
        for ids in &surface.triangles {
            for k in 0..3 {
                let (a, b) = (ids[k], ids[(k + 1) % 3]);
                directed.insert((a, b));
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        let input_uses = uses.clone();
        let mut node_vertex: HashMap<u32, u32> = HashMap::new();
        let rest = self.rest_dofs();
        for &face in self.cut_faces() {
            for near_is_lower in [true, false] {
                let closing = match closer.close(face, near_is_lower) {
                    Ok(closing) => closing,
                    Err(why) => {
                        *refused.entry(why).or_default() += 1;
                        continue;
                    }
                };
                if closing.is_empty() {
                    continue;
                }
                let mut upper = face.cell;
                upper[face.axis] += 1;
                let near =
                    self.cube_at(if near_is_lower { face.cell } else { upper }).expect("closed faces have cubes");
                // Ids: new vertices for nodes get the next free indices, made only if kept.
                let mut fresh: Vec<u32> = Vec::new();
                let id = |w: ClosingVertex, fresh: &mut Vec<u32>| match w {
                    ClosingVertex::Surface(x) => x,
                    ClosingVertex::Node(n) => node_vertex.get(&n).copied().unwrap_or_else(|| {
                        let at = fresh.iter().position(|&m| m == n).unwrap_or_else(|| {
                            fresh.push(n);
                            fresh.len() - 1
                        });
                        (surface.rest_vertices.len() + at) as u32
                    }),
                };
                let triangles: Vec<[u32; 3]> = closing
                    .iter()
                    .map(|t| t.map(|w| id(w, &mut fresh)))
                    .filter(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0])
                    .collect();
                let mut batch_directed: HashSet<(u32, u32)> = HashSet::new();
                let mut batch_uses: HashMap<(u32, u32), u8> = HashMap::new();
                let mut conflicts: Vec<(u32, u32)> = Vec::new();
                for t in &triangles {
                    for k in 0..3 {
                        let (a, b) = (t[k], t[(k + 1) % 3]);
                        if directed.contains(&(a, b)) || !batch_directed.insert((a, b)) {
                            conflicts.push((a.min(b), a.max(b)));
                        }
                        *batch_uses.entry((a.min(b), a.max(b))).or_default() += 1;
                    }
                }
                conflicts.extend(
                    batch_uses.iter().filter(|(e, n)| uses.get(*e).copied().unwrap_or(0) + **n > 2).map(|(e, _)| *e),
                );
                if !conflicts.is_empty() {
                    // Only edges the surface closes already (input triangles on both sides): the
                    // crack has not opened the surface here, and there is nothing to close.
                    let closed_surface = |e: &(u32, u32)| input_uses.get(e) == Some(&2);
                    if conflicts.iter().all(closed_surface) {
                        report.face_sides_not_open += 1;
                    } else {
                        *refused.entry(ClosingRefusal::Manifold).or_default() += 1;
                    }
                    continue;
                }
                for &n in &fresh {
                    let i = 3 * n as usize;
                    node_vertex.insert(n, surface.rest_vertices.len() as u32);
                    surface.rest_vertices.push(Point3::new(rest[i], rest[i + 1], rest[i + 2]));
                    surface.embedding.push_row(&[n], &[1.0]);
                }
                for (e, n) in batch_uses {
                    *uses.entry(e).or_default() += n;
                }
                directed.extend(batch_directed);
                for t in triangles {
                    surface.triangles.push(t);
                    surface.on_cut.push(true);
                    surface.piece.push(piece_of[near]);
                }
                report.face_sides_closed += 1;
            }
        }
        report.refused = refused.into_iter().collect();
        report.refused.sort_unstable();
        (report.loops_capped, report.walks_left_open) = cap_open_loops(surface);
        report
    }
}

/// Adds a vertex at the mean of `polygon`'s vertices, embedded by the mean of their rows.
fn add_centre(surface: &mut EmbeddedSurface, polygon: &[u32]) -> u32 {
    let share = 1.0 / polygon.len() as Real;
    let mut row: Vec<(u32, Real)> = Vec::new();
    let mut point = Vector3::zeros();
    for &v in polygon {
        point += surface.rest_vertices[v as usize].coords * share;
        let (nodes, weights) = surface.embedding.row(v as usize);
        for (&n, &w) in nodes.iter().zip(weights) {
            match row.iter_mut().find(|(m, _)| *m == n) {
                Some(entry) => entry.1 += w * share,
                None => row.push((n, w * share)),
            }
        }
    }
    let (nodes, weights): (Vec<u32>, Vec<Real>) = row.into_iter().unzip();
    surface.embedding.push_row(&nodes, &weights);
    surface.rest_vertices.push(Point3::from(point));
    (surface.rest_vertices.len() - 1) as u32
}

/// Caps every loop of open edges of `surface` (directed edges whose reverse no triangle has) by
/// a polygon through its own vertices (`cap_loop`); returns the number of loops capped and of
/// walks that found no way back (none, as every vertex has as many open edges out as in).
fn cap_open_loops(surface: &mut EmbeddedSurface) -> (usize, usize) {
    let (mut capped, mut stuck) = (0, 0);
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
        // Walk the open edges from a → b back to a; where the walk meets a vertex it has passed,
        // the part since then is a simple loop of its own and is capped at once.
        let mut walk = vec![a, b];
        while walk.len() > 1 {
            let at = *walk.last().expect("not empty");
            if let Some(i) = walk[..walk.len() - 1].iter().position(|&w| w == at) {
                let mut simple = walk.split_off(i);
                simple.pop();
                walk.push(at);
                if simple.len() >= 3 {
                    // The cap runs the loop backwards: each open edge a → b gets its b → a.
                    simple.reverse();
                    let (mut triangles, rest) = cap_loop(&surface.rest_vertices, &simple, &mut taken);
                    if let Some(polygon) = rest {
                        let centre = add_centre(surface, &polygon);
                        let n = polygon.len();
                        triangles.extend((0..n).map(|k| [centre, polygon[k], polygon[(k + 1) % n]]));
                    }
                    for t in triangles {
                        surface.triangles.push(t);
                        surface.on_cut.push(true);
                        surface.piece.push(piece);
                    }
                    capped += 1;
                }
                if walk.len() == 1 {
                    break;
                }
                continue;
            }
            let Some(next) = outgoing.get_mut(&at).and_then(|l| l.pop()) else {
                stuck += 1;
                break;
            };
            walk.push(next);
        }
    }
    (capped, stuck)
}
