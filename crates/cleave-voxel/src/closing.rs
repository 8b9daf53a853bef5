//! The closing surface of one side of an exposed cube face (mueller2004 §3.2;
//! docs/math/voxel-cutting.md §4): the part of the face inside the input surface, bounded by
//! oriented polygons made of the surface's intersection with the face and pieces of the face's
//! edges, triangulated in the face's plane and spanned between the surface vertices assigned to
//! the polygons' nodes and the mesh nodes at the face's corners.

use crate::mesh::{CubeFace, VoxelMesh};
use crate::stiffness::corner_offset;
use crate::surface::EmbeddedInput;
use cleave_core::{Point3, Real, Vector3};
use std::collections::HashMap;

/// A vertex of a closing triangle: a copy of a surface vertex (its index in the separated
/// surface) or a mesh node (a corner of the face, which the closing vertex sits on exactly).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum ClosingVertex {
    Surface(u32),
    Node(u32),
}

/// Why one side of an exposed face got no closing of its own; its opening is then capped by
/// the loop of open edges around it (`cap_loop`), so the surface stays closed either way.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ClosingRefusal {
    /// A surface edge crossing the face did not give exactly one entering and one leaving node
    /// (a triangle that only touches the face, or lies in its plane).
    Pairing,
    /// The walk along the face's edges met a node twice or a leaving node after a leaving node.
    Walk,
    /// The region inside the surface has a hole (the surface pierces the face as a tube).
    Hole,
    /// A node's assigned vertex has no copy on the side's cubes.
    Side,
    /// Two nodes of one polygon that are not neighbours were assigned the same vertex.
    Pinch,
    /// Ear clipping found no ear (a polygon that crosses itself after the nodes were moved).
    Ears,
    /// The closing would put an edge in more than two triangles or run an edge twice one way.
    Manifold,
}

/// What the surface's closing did: face sides closed by their own polygons, those refused (by
/// reason), and the loops of open edges capped afterwards.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ClosingReport {
    /// Face sides closed by the paper's polygons.
    pub face_sides_closed: usize,
    /// Face sides whose polygons would only run along edges the surface has closed (the crack
    /// has not opened the surface there), left without closing.
    pub face_sides_not_open: usize,
    /// Face sides refused, per reason.
    pub refused: Vec<(ClosingRefusal, usize)>,
    /// Loops of open edges capped after the face sides were closed.
    pub loops_capped: usize,
    /// Walks along open edges that did not come back to their start (none: every vertex has as
    /// many open edges out as in), left open.
    pub walks_left_open: usize,
}

/// The square's corners counter-clockwise in `(u, v)`, in units of the cube edge: perimeter
/// positions 0, 1, 2, 3.
const SQUARE_CORNERS: [(i32, i32); 4] = [(0, 0), (1, 0), (1, 1), (0, 1)];

#[derive(Clone, Copy, Debug)]
enum NodeKind {
    /// Where the surface edge `edge` (vertex ids, smaller first) crosses the face's plane.
    OnEdge([u32; 2]),
    /// Where a triangle's segment leaves the square through one of its edges, at perimeter
    /// position `s` (0..4, counter-clockwise from the first corner).
    OnBoundary(Real),
    /// The face corner at perimeter position `k` (0..4).
    Corner(usize),
}

#[derive(Clone, Copy, Debug)]
struct Node {
    /// In the face's plane, relative to the square's first corner.
    uv: [Real; 2],
    point: Point3<Real>,
    kind: NodeKind,
    /// The segment it ends or starts, if it is not a corner.
    segment: Option<usize>,
    next: Option<usize>,
}

/// One triangle's intersection with the face, clipped to the square: its nodes, and the
/// vertices rule (1) of the paper assigns to the ends of the unclipped segment.
#[derive(Clone, Copy, Debug)]
struct Segment {
    start: usize,
    end: usize,
    assigned: [u32; 2],
}

/// Closes the sides of exposed faces for one topology of `mesh` and its carried surface.
pub(crate) struct Closer<'a> {
    pub mesh: &'a VoxelMesh,
    pub input: &'a EmbeddedInput,
    /// The cube that owns each input triangle.
    pub triangle_cube: &'a [usize],
    /// The surface copies of each input triangle's vertices.
    pub triangle_copies: &'a [[u32; 3]],
}

impl Closer<'_> {
    /// Nodes the cubes `a` and `b` share (8 for a cube with itself).
    fn shared_nodes(&self, a: usize, b: usize) -> usize {
        let (na, nb) = (&self.mesh.cube_nodes()[a], &self.mesh.cube_nodes()[b]);
        na.iter().filter(|n| nb.contains(n)).count()
    }

    /// The copy of input vertex `vertex` on the side of cube `near` (not `far`): the copy of a
    /// triangle around it whose cube shares the most nodes with `near`, then the fewest with
    /// `far`.
    fn copy_near(&self, vertex: u32, near: usize, far: usize) -> Result<ClosingVertex, ClosingRefusal> {
        let mut best: Option<((usize, std::cmp::Reverse<usize>), u32)> = None;
        for &(t, k) in self.input.triangles_around(vertex) {
            let cube = self.triangle_cube[t as usize];
            let score = (self.shared_nodes(cube, near), std::cmp::Reverse(self.shared_nodes(cube, far)));
            if best.is_none_or(|(b, _)| score > b) {
                best = Some((score, self.triangle_copies[t as usize][k as usize]));
            }
        }
        match best {
            Some(((shared, _), copy)) if shared > 0 => Ok(ClosingVertex::Surface(copy)),
            _ => Err(ClosingRefusal::Side),
        }
    }

    /// The closing triangles of `face` on the side of the cube below it (`near_is_lower`) or
    /// above it, outward for that cube (docs/math/voxel-cutting.md §4, steps 3a–3e; 3f is the caller's).
    pub fn close(&self, face: CubeFace, near_is_lower: bool) -> Result<Vec<[ClosingVertex; 3]>, ClosingRefusal> {
        let (mesh, input) = (self.mesh, self.input);
        let (h, origin, a) = (mesh.cell_size(), mesh.origin(), face.axis);
        let mut upper = face.cell;
        upper[a] += 1;
        let (Some(lower_cube), Some(upper_cube)) = (mesh.cube_at(face.cell), mesh.cube_at(upper)) else {
            return Ok(Vec::new());
        };
        let (near, far) = if near_is_lower { (lower_cube, upper_cube) } else { (upper_cube, lower_cube) };
        let plane = origin[a] + (face.cell[a] + 1) as Real * h;
        let mut outward = Vector3::zeros();
        outward[a] = if near_is_lower { 1.0 } else { -1.0 };
        // (u, v) with e_u × e_v = outward, so counter-clockwise is positive about the outward normal.
        let (u, v) = if near_is_lower { ((a + 1) % 3, (a + 2) % 3) } else { ((a + 2) % 3, (a + 1) % 3) };
        let (u0, v0) = (origin[u] + face.cell[u] as Real * h, origin[v] + face.cell[v] as Real * h);
        // A point on the plane counts as above it, for every triangle alike.
        let above = |p: &Point3<Real>| p[a] >= plane;
        let near_above = !near_is_lower;

        // 3a. One directed segment per triangle crossing the plane inside the square.
        let mut nodes: Vec<Node> = Vec::new();
        let mut segments: Vec<Segment> = Vec::new();
        let mut candidates: Vec<u32> =
            input.triangles_in_cell(face.cell).iter().chain(input.triangles_in_cell(upper)).copied().collect();
        candidates.sort_unstable();
        candidates.dedup();
        for &t in &candidates {
            let ids = input.triangles[t as usize];
            let p = ids.map(|i| input.vertices[i as usize]);
            let side = p.map(|q| above(&q));
            if side[0] == side[1] && side[1] == side[2] {
                continue;
            }
            let cube = self.triangle_cube[t as usize];
            let near_group = match self.shared_nodes(cube, near).cmp(&self.shared_nodes(cube, far)) {
                std::cmp::Ordering::Greater => true,
                std::cmp::Ordering::Less => false,
                std::cmp::Ordering::Equal => {
                    above(&Point3::from((p[0].coords + p[1].coords + p[2].coords) / 3.0)) == near_above
                }
            };
            // Exactly two edges change side (the sides are booleans, not all equal).
            let mut crossings = [(Point3::origin(), [0u32; 2], 0u32); 2];
            let mut found = 0;
            for k in 0..3 {
                let (i, j) = (k, (k + 1) % 3);
                if side[i] == side[j] {
                    continue;
                }
                // Computed from the smaller vertex id, so both triangles on an edge get one point.
                let (lo, hi) = if ids[i] < ids[j] { (i, j) } else { (j, i) };
                let (pl, ph) = (p[lo], p[hi]);
                let mut q = pl + (ph - pl) * ((plane - pl[a]) / (ph[a] - pl[a]));
                q[a] = plane;
                // Rule (1): a triangle of the near side ends at the edge's vertex beyond the plane,
                // one of the far side at the vertex before it.
                let on_near = |x: usize| side[x] == near_above;
                let assigned = if near_group != on_near(lo) { ids[lo] } else { ids[hi] };
                crossings[found] = (q, [ids[lo], ids[hi]], assigned);
                found += 1;
            }
            let normal = (p[1] - p[0]).cross(&(p[2] - p[0]));
            debug_assert_eq!(found, 2);
            let (mut s, mut e) = (crossings[0], crossings[1]);
            if normal.cross(&(e.0 - s.0)).dot(&outward) < 0.0 {
                std::mem::swap(&mut s, &mut e);
            }
            // Liang–Barsky clipping of s → e to the square.
            let d = [e.0[u] - s.0[u], e.0[v] - s.0[v]];
            let limits = [
                (-d[0], s.0[u] - u0, 3usize),
                (d[0], u0 + h - s.0[u], 1),
                (-d[1], s.0[v] - v0, 0),
                (d[1], v0 + h - s.0[v], 2),
            ];
            let (mut t0, mut t1, mut enter, mut leave) = (0.0, 1.0, None, None);
            let mut empty = false;
            for (p_k, q_k, edge) in limits {
                if p_k == 0.0 {
                    empty |= q_k < 0.0;
                } else if p_k < 0.0 {
                    let r = q_k / p_k;
                    if r > t0 {
                        (t0, enter) = (r, Some(edge));
                    }
                } else {
                    let r = q_k / p_k;
                    if r < t1 {
                        (t1, leave) = (r, Some(edge));
                    }
                }
            }
            if empty || t0 >= t1 {
                continue;
            }
            let perimeter = |x: Real, y: Real, edge: usize| match edge {
                0 => (x - u0) / h,
                1 => 1.0 + (y - v0) / h,
                2 => 2.0 + (u0 + h - x) / h,
                _ => 3.0 + (v0 + h - y) / h,
            };
            let segment = segments.len();
            let mut end_node = |at: Real, crossing: &(Point3<Real>, [u32; 2], u32), edge: Option<usize>| {
                let point = s.0 + (e.0 - s.0) * at;
                let (point, kind) = match edge {
                    None => (crossing.0, NodeKind::OnEdge(crossing.1)),
                    Some(k) => (point, NodeKind::OnBoundary(perimeter(point[u], point[v], k))),
                };
                nodes.push(Node {
                    uv: [point[u] - u0, point[v] - v0],
                    point,
                    kind,
                    segment: Some(segment),
                    next: None,
                });
                nodes.len() - 1
            };
            let start = end_node(t0, &s, enter);
            let end = end_node(t1, &e, leave);
            nodes[start].next = Some(end);
            segments.push(Segment { start, end, assigned: [s.2, e.2] });
        }

        // 3b. The two nodes on one surface edge: the one that ends a segment leads to the one that
        // starts the next.
        let mut on_edge: HashMap<[u32; 2], Vec<usize>> = HashMap::new();
        for (i, n) in nodes.iter().enumerate() {
            if let NodeKind::OnEdge(edge) = n.kind {
                on_edge.entry(edge).or_default().push(i);
            }
        }
        for pair in on_edge.values() {
            let &[x, y] = pair.as_slice() else { return Err(ClosingRefusal::Pairing) };
            match (nodes[x].next.is_some(), nodes[y].next.is_some()) {
                (true, false) => nodes[y].next = Some(x),
                (false, true) => nodes[x].next = Some(y),
                _ => return Err(ClosingRefusal::Pairing),
            }
        }

        // 3c. Along the square's edges, counter-clockwise: from each node where a segment leaves,
        // through the corners passed, to the next node where one enters.
        let corner_node = |k: usize, nodes: &mut Vec<Node>| {
            let (cu, cv) = SQUARE_CORNERS[k];
            let mut point = Point3::origin();
            point[a] = plane;
            point[u] = u0 + cu as Real * h;
            point[v] = v0 + cv as Real * h;
            nodes.push(Node {
                uv: [point[u] - u0, point[v] - v0],
                point,
                kind: NodeKind::Corner(k),
                segment: None,
                next: None,
            });
            nodes.len() - 1
        };
        let mut boundary: Vec<(Real, usize)> = nodes
            .iter()
            .enumerate()
            .filter_map(|(i, n)| match n.kind {
                NodeKind::OnBoundary(s) => Some((s, i)),
                _ => None,
            })
            .collect();
        boundary.sort_by(|x, y| x.0.total_cmp(&y.0));
        if boundary.is_empty() {
            // No segment reaches the square's edges: the corners are all inside or all outside.
            let mut probe = Point3::origin();
            probe[a] = plane;
            probe[u] = u0 + 1e-6 * h;
            probe[v] = v0 + 1.3e-6 * h;
            if input.contains(&probe) {
                let corners: Vec<usize> = (0..4).map(|k| corner_node(k, &mut nodes)).collect();
                for k in 0..4 {
                    nodes[corners[k]].next = Some(corners[(k + 1) % 4]);
                }
            }
        }
        for b in 0..boundary.len() {
            let (s, leaving) = boundary[b];
            if nodes[leaving].next.is_some() {
                continue;
            }
            let (s_next, entering) = boundary[(b + 1) % boundary.len()];
            if nodes[entering].next.is_none() {
                return Err(ClosingRefusal::Walk);
            }
            let end = if s_next > s { s_next } else { s_next + 4.0 };
            let mut at = leaving;
            let mut k = s.floor() as usize + 1;
            while (k as Real) < end {
                let corner = corner_node(k % 4, &mut nodes);
                nodes[at].next = Some(corner);
                at = corner;
                k += 1;
            }
            nodes[at].next = Some(entering);
        }
        let mut incoming = vec![0u8; nodes.len()];
        for n in &nodes {
            match n.next {
                Some(x) => incoming[x] += 1,
                None => return Err(ClosingRefusal::Walk),
            }
        }
        if incoming.iter().any(|&c| c != 1) {
            return Err(ClosingRefusal::Walk);
        }

        // 3d. Cycles; the positive ones surround the closing surface, a negative one is a hole.
        let mut seen = vec![false; nodes.len()];
        let mut polygons: Vec<Vec<usize>> = Vec::new();
        for start in 0..nodes.len() {
            if seen[start] {
                continue;
            }
            let mut cycle = Vec::new();
            let mut at = start;
            while !seen[at] {
                seen[at] = true;
                cycle.push(at);
                at = nodes[at].next.expect("checked above");
            }
            let area: Real = (0..cycle.len())
                .map(|k| {
                    let (p, q) = (nodes[cycle[k]].uv, nodes[cycle[(k + 1) % cycle.len()]].uv);
                    p[0] * q[1] - p[1] * q[0]
                })
                .sum();
            if area < 0.0 {
                return Err(ClosingRefusal::Hole);
            }
            polygons.push(cycle);
        }

        // 3e. Each node assigned a vertex; consecutive repeats dropped; ear clipping in the plane
        // with each segment's surface-edge nodes moved a third of the way to its other end.
        let mut triangles = Vec::new();
        for cycle in polygons {
            let mut ring: Vec<(ClosingVertex, [Real; 2])> = Vec::with_capacity(cycle.len());
            for &i in &cycle {
                let node = &nodes[i];
                let vertex = match node.kind {
                    NodeKind::Corner(k) => {
                        let (cu, cv) = SQUARE_CORNERS[k];
                        let mut offset = [0i32; 3];
                        offset[a] = i32::from(near_is_lower);
                        offset[u] = cu;
                        offset[v] = cv;
                        let corner = (0..8).find(|&c| corner_offset(c) == offset).expect("a cube corner");
                        ClosingVertex::Node(mesh.cube_nodes()[near][corner])
                    }
                    // When the vertex assigned has no copy on this side (the fracture line passes
                    // on this side of it), the edge's other vertex, which then lies on the line.
                    NodeKind::OnEdge([a, b]) => {
                        let segment = &segments[node.segment.expect("a segment's node")];
                        let assigned = segment.assigned[usize::from(segment.end == i)];
                        let other = if assigned == a { b } else { a };
                        self.copy_near(assigned, near, far).or_else(|_| self.copy_near(other, near, far))?
                    }
                    NodeKind::OnBoundary(_) => {
                        let segment = &segments[node.segment.expect("a segment's node")];
                        let [x, y] = segment.assigned;
                        let distance = |w: u32| (input.vertices[w as usize] - node.point).norm();
                        let (first, second) = if distance(y) < distance(x) { (y, x) } else { (x, y) };
                        self.copy_near(first, near, far).or_else(|_| self.copy_near(second, near, far))?
                    }
                };
                let uv = match (node.kind, node.segment) {
                    (NodeKind::OnEdge(_), Some(s)) => {
                        let segment = &segments[s];
                        let other = nodes[if segment.start == i { segment.end } else { segment.start }].uv;
                        [node.uv[0] + (other[0] - node.uv[0]) / 3.0, node.uv[1] + (other[1] - node.uv[1]) / 3.0]
                    }
                    _ => node.uv,
                };
                if ring.last().is_none_or(|(last, _)| *last != vertex) {
                    ring.push((vertex, uv));
                }
            }
            while ring.len() > 1 && ring[0].0 == ring[ring.len() - 1].0 {
                ring.pop();
            }
            if ring.len() < 3 {
                continue;
            }
            let mut distinct: Vec<ClosingVertex> = ring.iter().map(|r| r.0).collect();
            distinct.sort_unstable_by_key(|w| match w {
                ClosingVertex::Surface(x) => (0, *x),
                ClosingVertex::Node(x) => (1, *x),
            });
            if distinct.windows(2).any(|w| w[0] == w[1]) {
                return Err(ClosingRefusal::Pinch);
            }
            triangles.extend(ear_clip(&ring, h).ok_or(ClosingRefusal::Ears)?);
        }
        Ok(triangles)
    }
}

/// Ear clipping of a counter-clockwise simple polygon in the plane of a face of edge `h` (points
/// relative to its corner); `None` if some step finds no ear (the polygon crosses itself).
fn ear_clip(ring: &[(ClosingVertex, [Real; 2])], h: Real) -> Option<Vec<[ClosingVertex; 3]>> {
    let cross =
        |o: [Real; 2], p: [Real; 2], q: [Real; 2]| (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0]);
    // The points are relative to the square's corner, so the tolerance is the face's.
    let tiny = 1e-14 * h * h;
    let mut polygon: Vec<usize> = (0..ring.len()).collect();
    let mut out = Vec::with_capacity(ring.len());
    while polygon.len() > 3 {
        let n = polygon.len();
        let ear = (0..n).find(|&i| {
            let (a, b, c) = (polygon[(i + n - 1) % n], polygon[i], polygon[(i + 1) % n]);
            let (pa, pb, pc) = (ring[a].1, ring[b].1, ring[c].1);
            cross(pa, pb, pc) > tiny
                && !polygon.iter().any(|&q| {
                    q != a
                        && q != b
                        && q != c
                        && cross(pa, pb, ring[q].1) >= 0.0
                        && cross(pb, pc, ring[q].1) >= 0.0
                        && cross(pc, pa, ring[q].1) >= 0.0
                })
        })?;
        let (a, b, c) = (polygon[(ear + n - 1) % n], polygon[ear], polygon[(ear + 1) % n]);
        out.push([ring[a].0, ring[b].0, ring[c].0]);
        polygon.remove(ear);
    }
    out.push([ring[polygon[0]].0, ring[polygon[1]].0, ring[polygon[2]].0]);
    Some(out)
}
