//! The material of one (duplicate of a) tetrahedron as a set of convex cells, split by cut
//! triangles with exact side-of-plane decisions, and its material regions (connected components
//! of the tetrahedron minus the union of the closed cut triangles).
//!
//! # How a triangle cuts
//!
//! A triangle `T` with supporting plane `P` separates material exactly on `T`. Let `k` be the axis
//! along which `T`'s projection has the largest area, and `S₀, S₁, S₂` the planes through the edges
//! of `T` parallel to axis `k` ("side planes"); the prism between them meets `P` in exactly `T`.
//! A cell that `P` splits is first split by the side planes its would-be cap straddles; the part
//! inside the prism is then split by `P`, and that cap, which lies inside `T`, is marked covered.
//! Side-plane faces are not covered: material stays connected through them. A cell face that lies
//! in `P` is marked covered where it lies inside the prism (it is split by the side planes first
//! when it straddles one). Degenerate (exactly collinear) triangles cut nothing.
//!
//! # What is exact
//!
//! Every plane is given by three `f64` points; the side of a cell vertex is decided by
//! `robust::orient3d` on its `f64` coordinates, except that a vertex created on a plane (the
//! intersection of an edge with it) is *on* that plane by construction, whatever its rounded
//! coordinates say. Planes that are exactly equal (all three points of one on the other) share
//! one identity, so a triangle in a tetrahedron face, in a previous cut, or coplanar with another
//! triangle is recognised as such. Intersection points are computed in floating point from the
//! edge's end points in a canonical order. Splits are therefore combinatorially consistent;
//! geometry is exact up to the rounding of constructed points.
//!
//! Connectivity of cells: two cells are connected when they have faces on the same plane, with
//! opposite outward sides, neither covered, whose projections overlap with an area above
//! [`OVERLAP_TOLERANCE`] times the tetrahedron's squared edge (floating point).

use crate::FastMap;
use crate::UnionFind;
use crate::predicates::{
    convex_overlap_area, dominant_axis, largest_component, polygon_area_2d, project, side3, triangle_is_degenerate,
};
use nalgebra::{Point2, Point3, Vector3};

/// Relative area (of the squared edge length of the tetrahedron) below which two coplanar face
/// pieces are not considered to overlap.
pub const OVERLAP_TOLERANCE: f64 = 1e-12;

const MAX_VERTEX_PLANES: usize = 8;

/// Distance, relative to the tetrahedron's longest edge, below which a rounded intersection
/// point is taken to coincide with a vertex.
pub const WELD_TOLERANCE: f64 = 1e-13;

/// Padding of bounding-box rejections, relative to the tetrahedron's longest edge.
pub const BOX_PADDING: f64 = 1e-9;

/// Number of splits refused (process-wide) because the rounded geometry gave no closed cap or
/// parts that are not closed: a diagnostic the tests read; each refusal keeps a cell whole.
pub static REFUSED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Who covers a face.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cover {
    /// Not covered: material continues across the face (or it is a tetrahedron face).
    Open,
    /// Covered by the original object surface (carving).
    Surface,
    /// Covered by a cut triangle.
    Cut,
}

/// A vertex of the arrangement with the planes it was constructed on.
#[derive(Clone, Copy, Debug)]
pub struct Vertex {
    /// Position (rounded).
    pub p: Point3<f64>,
    planes: [u32; MAX_VERTEX_PLANES],
    num_planes: u8,
}

impl Vertex {
    fn new(p: Point3<f64>) -> Self {
        Self { p, planes: [0; MAX_VERTEX_PLANES], num_planes: 0 }
    }

    #[inline]
    fn on(&self, plane: u32) -> bool {
        self.planes[..self.num_planes as usize].contains(&plane)
    }

    fn add_plane(&mut self, plane: u32) {
        if self.can_take(plane) && !self.on(plane) {
            self.planes[self.num_planes as usize] = plane;
            self.num_planes += 1;
        }
    }

    /// Whether `plane` is or can be recorded (a vertex holds at most [`MAX_VERTEX_PLANES`]).
    fn can_take(&self, plane: u32) -> bool {
        self.on(plane) || (self.num_planes as usize) < MAX_VERTEX_PLANES
    }
}

/// A plane through three exact points.
#[derive(Clone, Copy, Debug)]
pub struct Plane {
    /// The three points defining it.
    pub points: [Point3<f64>; 3],
    /// Its right-hand normal `(b − a) × (c − a)` in floating point.
    pub normal: Vector3<f64>,
    /// The axis of the largest normal component (projection axis for 2D work).
    pub axis: u8,
}

impl Plane {
    fn new(points: [Point3<f64>; 3]) -> Self {
        let normal = (points[1] - points[0]).cross(&(points[2] - points[0]));
        Self { points, normal, axis: largest_component(&normal) as u8 }
    }

    #[inline]
    fn side(&self, p: &Point3<f64>) -> i8 {
        side3(&self.points[0], &self.points[1], &self.points[2], p)
    }

    #[inline]
    fn distance(&self, p: &Point3<f64>) -> f64 {
        self.normal.dot(&(p - self.points[0]))
    }
}

/// A planar convex face of a cell: a vertex loop, counter-clockwise seen from outside the cell.
#[derive(Clone, Debug)]
pub struct Face {
    /// Vertex indices into the arrangement's vertices.
    pub verts: Vec<u32>,
    /// The plane it lies in (`0..4` are the tetrahedron's faces).
    pub plane: u32,
    /// Whether the cell's outward normal points along the plane's normal.
    pub positive: bool,
    /// Whether it is covered by a cut or the object surface.
    pub cover: Cover,
}

/// A convex polyhedral cell.
#[derive(Clone, Debug, Default)]
pub struct Cell {
    /// Its faces.
    pub faces: Vec<Face>,
}

impl Cell {
    /// Distinct vertex indices, sorted.
    pub fn vertex_ids(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self.faces.iter().flat_map(|f| f.verts.iter().copied()).collect();
        v.sort_unstable();
        v.dedup();
        v
    }
}

/// Outcome of splitting a cell by a plane.
enum Split {
    /// Entirely on the negative side (or on the plane).
    Neg,
    /// Entirely on the positive side.
    Pos,
    /// Both parts and the cap's vertices (counter-clockwise seen from the positive side).
    Both(Cell, Cell),
}

/// The convex cells of one tetrahedron's material.
#[derive(Clone, Debug)]
pub struct Arrangement {
    /// Vertices; `0..4` are the tetrahedron's corners.
    pub vertices: Vec<Vertex>,
    /// Planes; `i < 4` is the face opposite corner `i`.
    pub planes: Vec<Plane>,
    /// The cells.
    pub cells: Vec<Cell>,
    edge_points: FastMap<(u32, u32, u32), u32>,
    scale2: f64,
}

/// Outward face `i` of a positively oriented tetrahedron: the corners other than `i`,
/// counter-clockwise seen from outside.
pub const TET_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// A triangle prepared for cutting one arrangement: its supporting plane and three inward
/// oriented side planes.
struct PreparedTriangle {
    plane: u32,
    sides: [(u32, bool); 3],
}

/// A face projected for overlap tests: its cell, outward side, 2D loop and 2D bounds.
type FacePolygon = (usize, bool, Vec<Point2<f64>>, [f64; 4]);

/// Removes consecutive repeated vertices (cyclically).
fn dedup_cyclic(v: &mut Vec<u32>) {
    v.dedup();
    while v.len() > 1 && v.first() == v.last() {
        v.pop();
    }
}

/// Whether every directed edge of the cell's faces has its reverse exactly once.
fn is_closed(cell: &Cell) -> bool {
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(32);
    for face in &cell.faces {
        let n = face.verts.len();
        for i in 0..n {
            edges.push((face.verts[i], face.verts[(i + 1) % n]));
        }
    }
    edges.sort_unstable();
    if edges.windows(2).any(|w| w[0] == w[1]) {
        return false;
    }
    edges.iter().all(|&(a, b)| edges.binary_search(&(b, a)).is_ok())
}

fn lex_less(a: &Point3<f64>, b: &Point3<f64>) -> bool {
    (a.x, a.y, a.z) < (b.x, b.y, b.z)
}

impl Arrangement {
    /// The uncut tetrahedron `corners` (must be positively oriented) as one cell.
    pub fn tetrahedron(corners: [Point3<f64>; 4]) -> Self {
        let mut vertices: Vec<Vertex> = corners.iter().map(|&p| Vertex::new(p)).collect();
        let planes: Vec<Plane> = TET_FACES.iter().map(|f| Plane::new(f.map(|i| corners[i]))).collect();
        for (i, v) in vertices.iter_mut().enumerate() {
            for f in 0..4 {
                if f != i {
                    v.add_plane(f as u32);
                }
            }
        }
        let faces = TET_FACES
            .iter()
            .enumerate()
            .map(|(i, f)| Face {
                verts: f.iter().map(|&c| c as u32).collect(),
                plane: i as u32,
                positive: true,
                cover: Cover::Open,
            })
            .collect();
        let scale2 = (0..4)
            .flat_map(|i| (0..4).map(move |j| (i, j)))
            .map(|(i, j)| (corners[i] - corners[j]).norm_squared())
            .fold(0.0, f64::max);
        Self { vertices, planes, cells: vec![Cell { faces }], edge_points: FastMap::default(), scale2 }
    }

    /// The corners of the tetrahedron.
    pub fn corners(&self) -> [Point3<f64>; 4] {
        std::array::from_fn(|i| self.vertices[i].p)
    }

    /// Squared longest edge of the tetrahedron.
    pub fn scale2(&self) -> f64 {
        self.scale2
    }

    /// Position of vertex `v`.
    #[inline]
    pub fn point(&self, v: u32) -> Point3<f64> {
        self.vertices[v as usize].p
    }

    /// Exact side of vertex `v` relative to plane `q`.
    #[inline]
    fn side(&self, v: u32, q: u32) -> i8 {
        let vertex = &self.vertices[v as usize];
        if vertex.on(q) { 0 } else { self.planes[q as usize].side(&vertex.p) }
    }

    /// Registers a plane through three exact points, reusing an exactly equal one: returns its id
    /// and whether its normal is opposite to the given points' normal.
    fn register_plane(&mut self, points: [Point3<f64>; 3]) -> (u32, bool) {
        let new = Plane::new(points);
        for (j, q) in self.planes.iter().enumerate() {
            if points.iter().all(|p| q.side(p) == 0) {
                return (j as u32, new.normal.dot(&q.normal) < 0.0);
            }
        }
        self.planes.push(new);
        (self.planes.len() as u32 - 1, false)
    }

    /// The rounded intersection point of edge `(a, b)` with plane `q`, computed from the end
    /// points in lexicographic order (so both directions give the same bits).
    fn intersection(&self, a: u32, b: u32, q: u32) -> Point3<f64> {
        let (pa, pb) = (self.point(a), self.point(b));
        let (lo, hi) = if lex_less(&pb, &pa) { (pb, pa) } else { (pa, pb) };
        let plane = &self.planes[q as usize];
        let (dl, dh) = (plane.distance(&lo), plane.distance(&hi));
        let mut t = dl / (dl - dh);
        if !t.is_finite() {
            t = 0.5;
        }
        let t = t.clamp(0.0, 1.0);
        lo + (hi - lo) * t
    }

    /// The intersection of edge `(a, b)` with plane `q` (created once per edge and plane).
    fn edge_point(&mut self, a: u32, b: u32, q: u32) -> u32 {
        let key = (a.min(b), a.max(b), q);
        if let Some(&v) = self.edge_points.get(&key) {
            return v;
        }
        let mut vertex = Vertex::new(self.intersection(a, b, q));
        let (va, vb) = (self.vertices[a as usize], self.vertices[b as usize]);
        vertex.add_plane(q);
        for &pl in &va.planes[..va.num_planes as usize] {
            if vb.on(pl) {
                vertex.add_plane(pl);
            }
        }
        self.vertices.push(vertex);
        let id = self.vertices.len() as u32 - 1;
        self.edge_points.insert(key, id);
        id
    }

    /// Signs of the cell's distinct vertices relative to plane `q` (sorted by vertex id).
    fn classify(&self, cell: &Cell, q: u32) -> Vec<(u32, i8)> {
        cell.vertex_ids().into_iter().map(|v| (v, self.side(v, q))).collect()
    }

    fn lookup(signs: &[(u32, i8)], v: u32) -> i8 {
        match signs.binary_search_by_key(&v, |s| s.0) {
            Ok(i) => signs[i].1,
            Err(_) => 0, // constructed on the plane during this split
        }
    }

    /// Splits `cell` by plane `q` (its own orientation); the cap gets `cover`.
    ///
    /// Rounded intersection points closer than [`WELD_TOLERANCE`] (relative to the tetrahedron's
    /// size) to a vertex of the cell move that vertex onto the plane (it is recorded as lying on
    /// `q`), and new points that close to each other are merged, so that no edge of zero length
    /// and no sliver of zero thickness is created. Should the rounded geometry still give a cap
    /// that is not one closed loop, or parts that are not closed polyhedra, the cell is kept
    /// whole on the side of its larger part (counted in [`REFUSED`]).
    fn split(&mut self, cell: &Cell, q: u32, cover: Cover) -> Split {
        let signs = self.classify(cell, q);
        if !signs.iter().any(|s| s.1 > 0) {
            return Split::Neg;
        }
        if !signs.iter().any(|s| s.1 < 0) {
            return Split::Pos;
        }
        if let Some(split) = self.try_split(cell, q, cover, signs.clone(), true) {
            return split;
        }
        if let Some(split) = self.try_split(cell, q, cover, signs.clone(), false) {
            return split;
        }
        REFUSED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        // Keep the cell whole on the side of most of its vertices' distance.
        let plane = &self.planes[q as usize];
        let balance: f64 = signs.iter().map(|s| plane.distance(&self.point(s.0))).sum();
        if balance <= 0.0 { Split::Neg } else { Split::Pos }
    }

    /// One attempt at [`Arrangement::split`] for a straddling cell, with or without snapping;
    /// `None` if the rounded geometry gives no closed parts.
    fn try_split(&mut self, cell: &Cell, q: u32, cover: Cover, mut signs: Vec<(u32, i8)>, snap: bool) -> Option<Split> {
        let tolerance2 = if snap { (WELD_TOLERANCE * WELD_TOLERANCE) * self.scale2 } else { -1.0 };
        // Pass 1: vertices that a rounded intersection point lands on are on the plane.
        let mut snapped = snap;
        while snapped {
            snapped = false;
            for face in &cell.faces {
                let n = face.verts.len();
                for i in 0..n {
                    let (a, b) = (face.verts[i], face.verts[(i + 1) % n]);
                    if (Self::lookup(&signs, a) as i32) * (Self::lookup(&signs, b) as i32) >= 0 {
                        continue;
                    }
                    let p = self.intersection(a, b, q);
                    for s in signs.iter_mut() {
                        if s.1 != 0 && (self.point(s.0) - p).norm_squared() <= tolerance2 {
                            s.1 = 0;
                            snapped = true;
                        }
                    }
                }
            }
        }
        let commit = |this: &mut Self, signs: &[(u32, i8)]| {
            for s in signs {
                if s.1 == 0 {
                    this.vertices[s.0 as usize].add_plane(q);
                }
            }
        };
        if !signs.iter().any(|s| s.1 > 0) {
            commit(self, &signs);
            return Some(Split::Neg);
        }
        if !signs.iter().any(|s| s.1 < 0) {
            commit(self, &signs);
            return Some(Split::Pos);
        }
        // Pass 2: the two parts, new points merged when they coincide.
        let mut created: Vec<u32> = Vec::new();
        let mut neg_faces = Vec::with_capacity(cell.faces.len() + 1);
        let mut pos_faces = Vec::with_capacity(cell.faces.len() + 1);
        let mut cap_edges: Vec<(u32, u32)> = Vec::new();
        for face in &cell.faces {
            let n = face.verts.len();
            let face_signs: Vec<i8> = face.verts.iter().map(|&v| Self::lookup(&signs, v)).collect();
            if face.plane == q || face_signs.iter().all(|&s| s == 0) {
                // A face on the plane of a straddling cell: possible only through rounding of
                // constructed points; the cap replaces it.
                continue;
            }
            let mut neg: Vec<u32> = Vec::with_capacity(n + 2);
            let mut pos: Vec<u32> = Vec::with_capacity(n + 2);
            for i in 0..n {
                let (a, b) = (face.verts[i], face.verts[(i + 1) % n]);
                let (sa, sb) = (face_signs[i], face_signs[(i + 1) % n]);
                if sa <= 0 {
                    neg.push(a);
                }
                if sa >= 0 {
                    pos.push(a);
                }
                if (sa as i32) * (sb as i32) < 0 {
                    let mut m = self.edge_point(a, b, q);
                    // The edge lies in this face's plane (and, from the face on its other side,
                    // in that one's): so does the new point.
                    self.vertices[m as usize].add_plane(face.plane);
                    let p = self.point(m);
                    if let Some(&w) =
                        created.iter().find(|&&w| w != m && (self.point(w) - p).norm_squared() <= tolerance2)
                    {
                        m = w;
                    } else if !created.contains(&m) {
                        created.push(m);
                    }
                    neg.push(m);
                    pos.push(m);
                }
            }
            dedup_cyclic(&mut neg);
            dedup_cyclic(&mut pos);
            if neg.len() >= 3 {
                for i in 0..neg.len() {
                    let j = (i + 1) % neg.len();
                    if Self::lookup(&signs, neg[i]) == 0 && Self::lookup(&signs, neg[j]) == 0 {
                        cap_edges.push((neg[j], neg[i]));
                    }
                }
                neg_faces.push(Face { verts: neg, ..face.clone() });
            }
            if pos.len() >= 3 {
                pos_faces.push(Face { verts: pos, ..face.clone() });
            }
        }
        // A part without volume (all its faces collapsed): the cell lies on the other side.
        if neg_faces.len() < 3 {
            commit(self, &signs);
            return Some(Split::Pos);
        }
        if pos_faces.len() < 3 {
            commit(self, &signs);
            return Some(Split::Neg);
        }
        // An edge on the plane shared by two faces of the same part (it touches the plane from
        // that side, as after snapping) is not on the cap's boundary: drop both directions.
        let all_edges = cap_edges.clone();
        cap_edges.retain(|&(a, b)| !all_edges.contains(&(b, a)));
        let cap = self.chain_cap(&cap_edges)?;
        let mut reversed = cap.clone();
        reversed.reverse();
        neg_faces.push(Face { verts: cap.clone(), plane: q, positive: true, cover });
        pos_faces.push(Face { verts: reversed, plane: q, positive: false, cover });
        let (neg, pos) = (Cell { faces: neg_faces }, Cell { faces: pos_faces });
        if !is_closed(&neg) || !is_closed(&pos) {
            return None;
        }
        commit(self, &signs);
        for &v in &cap {
            self.vertices[v as usize].add_plane(q);
        }
        Some(Split::Both(neg, pos))
    }

    /// Chains directed cap edges into one loop; `None` if they do not form exactly one.
    fn chain_cap(&self, edges: &[(u32, u32)]) -> Option<Vec<u32>> {
        if edges.len() < 3 {
            return None;
        }
        let mut loop_ = Vec::with_capacity(edges.len());
        let start = edges[0].0;
        let mut current = start;
        for _ in 0..edges.len() {
            let mut next = edges.iter().filter(|e| e.0 == current);
            let e = next.next()?;
            if next.next().is_some() {
                return None;
            }
            loop_.push(current);
            current = e.1;
            if current == start {
                break;
            }
        }
        (current == start && loop_.len() == edges.len()).then_some(loop_)
    }

    /// Volume of a cell (divergence theorem on fan-triangulated faces).
    pub fn cell_volume(&self, cell: &Cell) -> f64 {
        let Some(r) = cell.faces.first().and_then(|f| f.verts.first()).map(|&v| self.point(v)) else {
            return 0.0;
        };
        let mut six = 0.0;
        for face in &cell.faces {
            let p0 = self.point(face.verts[0]) - r;
            for w in face.verts[1..].windows(2) {
                let (p1, p2) = (self.point(w[0]) - r, self.point(w[1]) - r);
                six += p0.dot(&p1.cross(&p2));
            }
        }
        six / 6.0
    }

    /// Vertex average of a cell (an interior point of a non-degenerate convex cell).
    pub fn cell_center(&self, cell: &Cell) -> Point3<f64> {
        let ids = cell.vertex_ids();
        let sum = ids.iter().fold(Vector3::zeros(), |s, &v| s + self.point(v).coords);
        Point3::from(sum / ids.len().max(1) as f64)
    }

    /// Bounding box of a cell.
    pub fn cell_bounds(&self, cell: &Cell) -> (Point3<f64>, Point3<f64>) {
        let mut lo = Point3::from([f64::INFINITY; 3]);
        let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
        for face in &cell.faces {
            for &v in &face.verts {
                let p = self.point(v);
                for a in 0..3 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
        }
        (lo, hi)
    }

    /// Bounding box of all cells.
    pub fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        let mut lo = Point3::from([f64::INFINITY; 3]);
        let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
        for cell in &self.cells {
            let (a, b) = self.cell_bounds(cell);
            for k in 0..3 {
                lo[k] = lo[k].min(a[k]);
                hi[k] = hi[k].max(b[k]);
            }
        }
        (lo, hi)
    }

    /// Total volume of the cells.
    pub fn volume(&self) -> f64 {
        self.cells.iter().map(|c| self.cell_volume(c)).sum()
    }

    /// Prepares triangle `t` (exactly degenerate ones give `None`).
    fn prepare(&mut self, t: &[Point3<f64>; 3]) -> Option<PreparedTriangle> {
        if triangle_is_degenerate(t) {
            return None;
        }
        let (plane, _) = self.register_plane(*t);
        let k = dominant_axis(t);
        let sides = std::array::from_fn(|i| {
            let (a, b, opposite) = (t[i], t[(i + 1) % 3], t[(i + 2) % 3]);
            let mut c = a;
            c[k] = if a[k] == 0.0 { 1.0 } else { 2.0 * a[k] };
            let (id, _) = self.register_plane([a, b, c]);
            // Inside (the triangle's side) is the stored plane's negative side when the opposite
            // corner is there (never on it: the projection along `k` has non-zero area).
            (id, self.planes[id as usize].side(&opposite) < 0)
        });
        Some(PreparedTriangle { plane, sides })
    }

    /// Inside-signs of vertices relative to side plane `(q, flip)`.
    fn inside_signs(&self, verts: &[u32], q: u32, flip: bool) -> (bool, bool) {
        let (mut any_in, mut any_out) = (false, false);
        for &v in verts {
            let s = self.side(v, q) * if flip { -1 } else { 1 };
            any_in |= s > 0;
            any_out |= s < 0;
        }
        (any_in, any_out)
    }

    /// Cuts every cell by the closed triangle `t`; covered faces get `cover`. Returns whether any
    /// cell changed. Exactly degenerate triangles and non-finite ones cut nothing.
    pub fn cut(&mut self, t: &[Point3<f64>; 3], cover: Cover) -> bool {
        if !t.iter().all(|p| p.iter().all(|x| x.is_finite())) {
            return false;
        }
        let (mut tlo, mut thi) = (t[0], t[0]);
        for p in &t[1..] {
            for a in 0..3 {
                tlo[a] = tlo[a].min(p[a]);
                thi[a] = thi[a].max(p[a]);
            }
        }
        let Some(tri) = self.prepare(t) else {
            return false;
        };
        let pad = BOX_PADDING * self.scale2.sqrt();
        let mut changed = false;
        let cells = std::mem::take(&mut self.cells);
        let mut out = Vec::with_capacity(cells.len() + 4);
        for cell in cells {
            let (lo, hi) = self.cell_bounds(&cell);
            // Padded: vertices constructed on a plane may be rounded to either side of it.
            if (0..3).any(|a| lo[a] > thi[a] + pad || hi[a] < tlo[a] - pad) {
                out.push(cell);
                continue;
            }
            // A cell in the closed outer half-space of a side plane meets the triangle at most
            // in a set of zero area.
            let outside = tri.sides.iter().any(|&(q, flip)| {
                cell.faces.iter().all(|f| f.verts.iter().all(|&v| self.side(v, q) * if flip { -1 } else { 1 } <= 0))
            });
            if outside {
                out.push(cell);
                continue;
            }
            changed |= self.cut_cell(cell, &tri, cover, &mut out);
        }
        self.cells = out;
        changed
    }

    /// Cuts every cell by the whole plane through the three exact points `plane` (an unbounded
    /// cut: no side planes); caps get `cover`. Returns whether any cell changed.
    pub fn cut_plane(&mut self, plane: &[Point3<f64>; 3], cover: Cover) -> bool {
        if !plane.iter().all(|p| p.iter().all(|x| x.is_finite())) || triangle_is_degenerate(plane) {
            return false;
        }
        let (p, _) = self.register_plane(*plane);
        let mut changed = false;
        let cells = std::mem::take(&mut self.cells);
        let mut out = Vec::with_capacity(cells.len() + 4);
        for cell in cells {
            self.snap_faces_onto(&cell, p);
            match self.split(&cell, p, cover) {
                Split::Both(neg, pos) => {
                    out.push(neg);
                    out.push(pos);
                    changed = true;
                }
                _ => {
                    let mut cell = cell;
                    changed |= self.cover_faces_on(&mut cell, p, cover);
                    out.push(cell);
                }
            }
        }
        self.cells = out;
        changed
    }

    fn cut_cell(&mut self, cell: Cell, tri: &PreparedTriangle, cover: Cover, out: &mut Vec<Cell>) -> bool {
        let p = tri.plane;
        self.snap_faces_onto(&cell, p);
        match self.split(&cell, p, cover) {
            Split::Both(neg, pos) => {
                let cap = &neg.faces.last().expect("a split cell has its cap").verts;
                let mut straddled = Vec::new();
                for &(q, flip) in &tri.sides {
                    match self.inside_signs(cap, q, flip) {
                        (_, false) => {}
                        (false, true) => {
                            out.push(cell);
                            return false;
                        }
                        (true, true) => straddled.push((q, flip)),
                    }
                }
                if straddled.is_empty() {
                    out.push(neg);
                    out.push(pos);
                    return true;
                }
                let Some(inner) = self.peel(cell, &straddled, out) else {
                    return true;
                };
                match self.split(&inner, p, cover) {
                    Split::Both(neg, pos) => {
                        out.push(neg);
                        out.push(pos);
                    }
                    _ => {
                        let mut inner = inner;
                        self.cover_faces_on(&mut inner, p, cover);
                        out.push(inner);
                    }
                }
                true
            }
            _ => {
                // Not split: a face may lie in the plane.
                let Some(fi) = cell.faces.iter().position(|f| self.face_on(f, p)) else {
                    out.push(cell);
                    return false;
                };

                if cell.faces[fi].cover != Cover::Open {
                    out.push(cell);
                    return false;
                }
                let verts = cell.faces[fi].verts.clone();
                let mut straddled = Vec::new();
                for &(q, flip) in &tri.sides {
                    match self.inside_signs(&verts, q, flip) {
                        (_, false) => {}
                        (false, true) => {
                            out.push(cell);
                            return false;
                        }
                        (true, true) => straddled.push((q, flip)),
                    }
                }
                let Some(mut inner) = self.peel(cell, &straddled, out) else {
                    return true;
                };
                self.cover_faces_on(&mut inner, p, cover);
                out.push(inner);
                true
            }
        }
    }

    /// Records the vertices of every face of `cell` that lies within the weld tolerance of plane
    /// `p` (all its vertices, not all exactly) as lying on `p`, so that the face is taken to lie
    /// in it ([`Self::face_on`]) and is covered by what cuts along `p`. Two planes of different
    /// cuts can nearly coincide: a wavy sheet's triangle at z = 0.045 and a blade strip's side
    /// plane 3e-17 m above it left the strip's face (on the side plane) uncovered by the
    /// sheet, joining the material above and below the sheet through it. Isolated vertices
    /// near the plane are left to the exact predicates: snapping them too let coverage slip
    /// between two triangles' prisms when carving the bunny.
    fn snap_faces_onto(&mut self, cell: &Cell, p: u32) {
        let plane = self.planes[p as usize];
        let tolerance = WELD_TOLERANCE * self.scale2.sqrt() * plane.normal.norm();
        for face in &cell.faces {
            if face.plane == p || face.verts.iter().all(|&v| self.vertices[v as usize].on(p)) {
                continue;
            }
            // Only whole faces: a face some of whose vertices could not record the plane (full)
            // would be half on it.
            if face.verts.iter().all(|&v| {
                let vertex = &self.vertices[v as usize];
                vertex.can_take(p) && plane.distance(&vertex.p).abs() <= tolerance
            }) {
                for &v in &face.verts {
                    self.vertices[v as usize].add_plane(p);
                }
            }
        }
    }

    /// Whether `face` lies in plane `p`: it was made on it, or all its vertices are on it.
    fn face_on(&self, face: &Face, p: u32) -> bool {
        face.plane == p || face.verts.iter().all(|&v| self.side(v, p) == 0)
    }

    /// Covers the open faces of `cell` lying in plane `p`; returns whether any was.
    fn cover_faces_on(&self, cell: &mut Cell, p: u32, cover: Cover) -> bool {
        let mut changed = false;
        for i in 0..cell.faces.len() {
            if cell.faces[i].cover == Cover::Open && self.face_on(&cell.faces[i], p) {
                cell.faces[i].cover = cover;
                changed = true;
            }
        }
        changed
    }

    /// Splits off the parts of `cell` outside the given side planes (pushed to `out`, their caps
    /// open) and returns the part inside all of them, if any.
    fn peel(&mut self, mut cell: Cell, sides: &[(u32, bool)], out: &mut Vec<Cell>) -> Option<Cell> {
        for &(q, flip) in sides {
            match self.split(&cell, q, Cover::Open) {
                Split::Both(neg, pos) => {
                    let (inside, outside) = if flip { (neg, pos) } else { (pos, neg) };
                    out.push(outside);
                    cell = inside;
                }
                Split::Neg if !flip => {
                    out.push(cell);
                    return None;
                }
                Split::Pos if flip => {
                    out.push(cell);
                    return None;
                }
                _ => {}
            }
        }
        Some(cell)
    }

    /// Covers every open interior face that lies within the covered faces of other cells on
    /// the same plane, facing it (its projected overlap with them is its whole area, up to
    /// rounding), with their cover; returns how many it covered.
    ///
    /// Coverage belongs to the surface between two cells, but each cell keeps its own flag, and
    /// the side-plane tests that set it run on each cell's own copies of the face's corners: a
    /// corner on a side plane rounded to either side leaves one copy covered and the other open.
    /// The cells are then two regions (`regions` joins only open pairs), and the open copy,
    /// drawn by neither, left a hole in a piece's surface (a wavy sheet's flat part on an
    /// interior lattice plane through the torus). [`Self::regions`] calls it first.
    pub fn close_coverage(&mut self) -> usize {
        let mut groups: FastMap<u32, Vec<(usize, usize)>> = FastMap::default();
        for (c, cell) in self.cells.iter().enumerate() {
            for (f, face) in cell.faces.iter().enumerate() {
                if face.plane >= 4 {
                    groups.entry(face.plane).or_default().push((c, f));
                }
            }
        }
        let threshold = OVERLAP_TOLERANCE * self.scale2;
        let mut scratch = (Vec::new(), Vec::new());
        let mut covers: Vec<(usize, usize, Cover)> = Vec::new();
        for (&plane, group) in &groups {
            if !group.iter().any(|&(c, f)| self.cells[c].faces[f].cover != Cover::Open)
                || !group.iter().any(|&(c, f)| self.cells[c].faces[f].cover == Cover::Open)
            {
                continue;
            }
            let axis = self.planes[plane as usize].axis as usize;
            let projected = |c: usize, f: usize| -> Vec<Point2<f64>> {
                self.cells[c].faces[f].verts.iter().map(|&v| project(&self.point(v), axis)).collect()
            };
            for &(c, f) in group {
                let open = &self.cells[c].faces[f];
                if open.cover != Cover::Open {
                    continue;
                }
                let polygon = projected(c, f);
                let area = polygon_area_2d(&polygon).abs();
                if area <= threshold {
                    continue;
                }
                // The covered faces facing it belong to disjoint cells on one side: their
                // overlaps with it add up. Any open face facing it beyond the threshold
                // `regions` joins through keeps it open.
                let (mut covered, mut cover, mut joined) = (0.0, Cover::Open, false);
                for &(d, g) in group {
                    let other = &self.cells[d].faces[g];
                    if d == c || other.positive == open.positive {
                        continue;
                    }
                    let overlap = convex_overlap_area(&polygon, &projected(d, g), &mut scratch);
                    if overlap <= threshold {
                        continue;
                    }
                    if other.cover == Cover::Open {
                        joined = true;
                        break;
                    }
                    covered += overlap;
                    if cover == Cover::Open {
                        cover = other.cover;
                    }
                }
                if !joined && covered >= area - threshold.max(1e-9 * area) {
                    covers.push((c, f, cover));
                }
            }
        }
        for &(c, f, cover) in &covers {
            self.cells[c].faces[f].cover = cover;
        }
        covers.len()
    }

    /// Material regions: groups of cells connected through open faces, with positive volume,
    /// after coverage is made the same on both sides of every face ([`Self::close_coverage`]:
    /// every caller after a cut needs it, so it is not left to them). Returns `(cells of the
    /// region, volume)` per region.
    pub fn regions(&mut self) -> Vec<(Vec<usize>, f64)> {
        self.close_coverage();
        self.connected_regions()
    }

    /// Groups of cells connected through open faces, as the flags stand.
    fn connected_regions(&self) -> Vec<(Vec<usize>, f64)> {
        let n = self.cells.len();
        let mut sets = UnionFind::new(n);
        // Open interior faces grouped by plane.
        let mut groups: FastMap<u32, Vec<(usize, usize)>> = FastMap::default();
        for (c, cell) in self.cells.iter().enumerate() {
            for (f, face) in cell.faces.iter().enumerate() {
                if face.plane >= 4 && face.cover == Cover::Open {
                    groups.entry(face.plane).or_default().push((c, f));
                }
            }
        }
        let threshold = OVERLAP_TOLERANCE * self.scale2;
        let mut scratch = (Vec::new(), Vec::new());
        let mut keys: Vec<u32> = groups.keys().copied().collect();
        keys.sort_unstable();
        for key in keys {
            let group = &groups[&key];
            let axis = self.planes[key as usize].axis as usize;
            let polys: Vec<FacePolygon> = group
                .iter()
                .map(|&(c, f)| {
                    let face = &self.cells[c].faces[f];
                    let pts: Vec<Point2<f64>> = face.verts.iter().map(|&v| project(&self.point(v), axis)).collect();
                    let mut b = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
                    for p in &pts {
                        b[0] = b[0].min(p.x);
                        b[1] = b[1].min(p.y);
                        b[2] = b[2].max(p.x);
                        b[3] = b[3].max(p.y);
                    }
                    (c, face.positive, pts, b)
                })
                .collect();
            for a in &polys {
                if !a.1 {
                    continue;
                }
                for b in &polys[..] {
                    if b.1 || sets.find(a.0) == sets.find(b.0) {
                        continue;
                    }
                    let (ba, bb) = (a.3, b.3);
                    if ba[0] > bb[2] || bb[0] > ba[2] || ba[1] > bb[3] || bb[1] > ba[3] {
                        continue;
                    }
                    if convex_overlap_area(&a.2, &b.2, &mut scratch) > threshold {
                        sets.union(a.0, b.0);
                    }
                }
            }
        }
        let mut index: FastMap<usize, usize> = FastMap::default();
        let mut regions: Vec<(Vec<usize>, f64)> = Vec::new();
        for c in 0..n {
            let r = sets.find(c);
            let k = *index.entry(r).or_insert_with(|| {
                regions.push((Vec::new(), 0.0));
                regions.len() - 1
            });
            regions[k].0.push(c);
            regions[k].1 += self.cell_volume(&self.cells[c]);
        }
        regions.retain(|r| r.1 > 0.0);
        regions
    }

    /// A new arrangement holding only `cells` (vertices compacted; the corners keep ids `0..4`).
    pub fn restricted(&self, cells: &[usize]) -> Self {
        let mut map: FastMap<u32, u32> = FastMap::default();
        let mut vertices: Vec<Vertex> = self.vertices[..4].to_vec();
        for i in 0..4u32 {
            map.insert(i, i);
        }
        let mut new_cells = Vec::with_capacity(cells.len());
        for &c in cells {
            let mut cell = self.cells[c].clone();
            for face in &mut cell.faces {
                for v in &mut face.verts {
                    *v = *map.entry(*v).or_insert_with(|| {
                        vertices.push(self.vertices[*v as usize]);
                        vertices.len() as u32 - 1
                    });
                }
            }
            new_cells.push(cell);
        }
        let edge_points = self
            .edge_points
            .iter()
            .filter_map(|(&(a, b, q), &m)| {
                let (a, b, m) = (map.get(&a)?, map.get(&b)?, map.get(&m)?);
                Some(((*a.min(b), *a.max(b), q), *m))
            })
            .collect();
        Self { vertices, planes: self.planes.clone(), cells: new_cells, edge_points, scale2: self.scale2 }
    }

    /// Whether the cells contain corner `i` of the tetrahedron (as a vertex).
    pub fn has_corner(&self, i: usize) -> bool {
        self.cells.iter().any(|c| c.faces.iter().any(|f| f.verts.contains(&(i as u32))))
    }

    /// The open (uncovered) pieces of tetrahedron face `i`, as point loops.
    pub fn open_face_pieces(&self, i: usize) -> Vec<Vec<Point3<f64>>> {
        self.cells
            .iter()
            .flat_map(|c| c.faces.iter())
            .filter(|f| f.plane == i as u32 && f.cover == Cover::Open)
            .map(|f| f.verts.iter().map(|&v| self.point(v)).collect())
            .collect()
    }

    /// Whether tetrahedron face `i` is one whole open face of a cell.
    pub fn face_is_whole(&self, i: usize) -> bool {
        let mut pieces = self.cells.iter().flat_map(|c| c.faces.iter()).filter(|f| f.plane == i as u32);
        match (pieces.next(), pieces.next()) {
            (Some(f), None) => f.cover == Cover::Open && f.verts.len() == 3 && f.verts.iter().all(|&v| v < 4),
            _ => false,
        }
    }

    /// Signed distance-like measure of how far `p` is outside cell `c` (≤ 0 inside), in length
    /// units.
    pub fn outside_distance(&self, c: usize, p: &Point3<f64>) -> f64 {
        let mut worst = f64::NEG_INFINITY;
        for face in &self.cells[c].faces {
            worst = worst.max(self.face_distance(face, p));
        }
        worst
    }

    /// Signed distance of `p` from the plane of `face`, positive outside the cell. Uses the
    /// plane's own normal, so faces degenerated by rounding do not matter.
    pub fn face_distance(&self, face: &Face, p: &Point3<f64>) -> f64 {
        let plane = &self.planes[face.plane as usize];
        let len = plane.normal.norm();
        let d = plane.normal.dot(&(p - plane.points[0])) / len;
        if face.positive { d } else { -d }
    }

    /// Checks cell `c`: every directed edge has its reverse exactly once (a closed, consistently
    /// oriented surface) and every vertex lies inside every face plane up to `1e-9` of the
    /// tetrahedron's size (convexity). Returns what is wrong.
    pub fn check_cell(&self, c: usize) -> Result<(), String> {
        let cell = &self.cells[c];
        let mut edges: FastMap<(u32, u32), i32> = FastMap::default();
        for face in &cell.faces {
            let n = face.verts.len();
            if n < 3 {
                return Err(format!("face with {n} vertices"));
            }
            for i in 0..n {
                *edges.entry((face.verts[i], face.verts[(i + 1) % n])).or_default() += 1;
            }
        }
        for (&(a, b), &k) in &edges {
            if k != 1 || edges.get(&(b, a)) != Some(&1) {
                return Err(format!("edge ({a}, {b}) used {k} times, reverse {:?}", edges.get(&(b, a))));
            }
        }
        let tolerance = 1e-9 * self.scale2.sqrt();
        for face in &cell.faces {
            for v in cell.vertex_ids() {
                let d = self.face_distance(face, &self.point(v));
                if d > tolerance {
                    return Err(format!("vertex {v} is {d:e} outside face on plane {}", face.plane));
                }
            }
        }
        Ok(())
    }

    /// Newell normal of a face (twice the vector area).
    pub fn face_normal(&self, face: &Face) -> Vector3<f64> {
        let n = face.verts.len();
        let mut normal = Vector3::zeros();
        let p0 = self.point(face.verts[0]);
        for i in 1..n.saturating_sub(1) {
            normal += (self.point(face.verts[i]) - p0).cross(&(self.point(face.verts[i + 1]) - p0));
        }
        normal
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_tet() -> Arrangement {
        Arrangement::tetrahedron([
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ])
    }

    #[test]
    fn uncut_tetrahedron_has_its_volume_and_one_region() {
        let mut a = unit_tet();
        assert!((a.volume() - 1.0 / 6.0).abs() < 1e-16);
        assert_eq!(a.regions().len(), 1);
    }

    #[test]
    fn a_through_cut_makes_two_regions_and_a_partial_cut_one() {
        let big = |z: f64| [[Point3::new(-1.0, -1.0, z), Point3::new(3.0, -1.0, z), Point3::new(-1.0, 3.0, z)]];
        let mut a = unit_tet();
        for t in big(0.3) {
            assert!(a.cut(&t, Cover::Cut));
        }
        let regions = a.regions();
        assert_eq!(regions.len(), 2);
        let lower = 1.0 / 6.0 * (1.0 - 0.7f64.powi(3));
        let mut v: Vec<f64> = regions.iter().map(|r| r.1).collect();
        v.sort_by(f64::total_cmp);
        assert!((v[1] - lower).abs() < 1e-15, "{v:?}");
        // A triangle that covers only part of the cross section leaves one region.
        let mut b = unit_tet();
        b.cut(&[Point3::new(-1.0, -1.0, 0.3), Point3::new(1.2, -1.0, 0.3), Point3::new(-1.0, 1.2, 0.3)], Cover::Cut);
        assert_eq!(b.regions().len(), 1);
        assert!(b.cells.len() >= 3);
        assert!((b.volume() - 1.0 / 6.0).abs() < 1e-15);
    }

    /// A square in the plane z = `z` larger than the unit tetrahedron's section, corners
    /// counter-clockwise seen from above.
    fn section_quad(z: f64) -> [Point3<f64>; 4] {
        [Point3::new(-1.0, -1.0, z), Point3::new(2.0, -1.0, z), Point3::new(2.0, 2.0, z), Point3::new(-1.0, 2.0, z)]
    }

    #[test]
    fn two_coplanar_triangles_that_together_cover_a_section_separate() {
        let mut a = unit_tet();
        let quad = section_quad(0.25);
        a.cut(&[quad[0], quad[1], quad[2]], Cover::Cut);
        assert_eq!(a.regions().len(), 1, "one triangle alone leaves a bridge");
        a.cut(&[quad[0], quad[2], quad[3]], Cover::Cut);
        assert_eq!(a.regions().len(), 2);
    }

    #[test]
    fn a_face_covered_on_one_side_only_is_covered_on_both() {
        // Two coplanar triangles cover the section z = 0.25; one cell's copy of a covered face
        // is opened, as a corner rounded to the other side of a side plane leaves it.
        let mut a = unit_tet();
        let quad = section_quad(0.25);
        a.cut(&[quad[0], quad[1], quad[2]], Cover::Cut);
        a.cut(&[quad[0], quad[2], quad[3]], Cover::Cut);
        assert_eq!(a.close_coverage(), 0, "both sides already covered");
        let (c, f) = (0..a.cells.len())
            .flat_map(|c| (0..a.cells[c].faces.len()).map(move |f| (c, f)))
            .find(|&(c, f)| a.cells[c].faces[f].cover == Cover::Cut && !a.cells[c].faces[f].positive)
            .expect("a covered face below the section");
        a.cells[c].faces[f].cover = Cover::Open;
        assert_eq!(a.close_coverage(), 1);
        assert_eq!(a.cells[c].faces[f].cover, Cover::Cut);
        assert_eq!(a.regions().len(), 2);
        // Of the four faces on a section split in two by x = 0.2, one beyond x = 0.2 stays
        // covered and the other three are opened: only the face facing the covered one is
        // covered again; the open pair facing each other stays open and joins its cells.
        let mut b = unit_tet();
        let section = |b: &Arrangement| -> Vec<(usize, usize)> {
            (0..b.cells.len())
                .flat_map(|c| (0..b.cells[c].faces.len()).map(move |f| (c, f)))
                .filter(|&(c, f)| b.face_on(&b.cells[c].faces[f], 4))
                .collect()
        };
        b.cut_plane(&[quad[0], quad[1], quad[2]], Cover::Cut);
        b.cut_plane(&[Point3::new(0.2, 0.0, 0.0), Point3::new(0.2, 1.0, 0.0), Point3::new(0.2, 0.0, 1.0)], Cover::Open);
        let faces = section(&b);
        assert_eq!(faces.len(), 4, "two faces below the section, two above");
        let centre_x = |b: &Arrangement, (c, f): (usize, usize)| {
            let verts = &b.cells[c].faces[f].verts;
            verts.iter().map(|&v| b.point(v).x).sum::<f64>() / verts.len() as f64
        };
        let kept = *faces
            .iter()
            .find(|&&(c, f)| b.cells[c].faces[f].positive && centre_x(&b, (c, f)) > 0.2)
            .expect("a face beyond x = 0.2");
        for &(c, f) in &faces {
            if (c, f) != kept {
                b.cells[c].faces[f].cover = Cover::Open;
            }
        }
        assert_eq!(b.close_coverage(), 1);
        let covered: Vec<(usize, usize)> =
            faces.iter().copied().filter(|&(c, f)| b.cells[c].faces[f].cover == Cover::Cut).collect();
        assert_eq!(covered.len(), 2);
        assert!(covered.iter().all(|&face| centre_x(&b, face) > 0.2), "only beyond x = 0.2");
        assert_eq!(b.regions().len(), 1, "joined through the open pair");
    }

    #[test]
    fn a_triangle_in_a_tet_face_covers_it() {
        let mut a = unit_tet();
        a.cut(&[Point3::new(-1.0, -1.0, 0.0), Point3::new(3.0, -1.0, 0.0), Point3::new(-1.0, 3.0, 0.0)], Cover::Cut);
        assert!(a.open_face_pieces(3).is_empty());
        assert_eq!(a.open_face_pieces(0).len(), 1);
        assert_eq!(a.regions().len(), 1);
    }
}
