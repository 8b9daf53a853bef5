//! Cutting a mesh of convex polyhedra by splitting elements (wicke2007 §5, docs/math/mean-value.md
//! §9): the topology of the elements as polygons of global nodes, split by the plane of each
//! convex cut polygon, the faces in that plane split by the polygon's edges, the faces inside it
//! covered, nodes duplicated per group of elements still joined around them, and a pocket node
//! where a covered region has no node to open with. Every new node's rest position and its row
//! over the old nodes (the old element's mean value coordinates there) are recorded for
//! `DofRemap::Linear`.
//!
//! Conformity is kept without subdividing neighbours: a node created on an edge is inserted into
//! every face holding that edge, and a face split in one element is split the same way in the
//! element across it (two coplanar faces there), so the two sides of every shared face stay the
//! same polygons.

use nalgebra::{Point2, Point3, Vector3};
use std::collections::{BTreeMap, HashMap, HashSet};

use crate::polyhedron::Real;

/// Distance from a cutting plane, relative to the largest element diameter, under which a node
/// counts as on it: nodes computed on earlier cuts, and the crossings of several planes through
/// one point, which round-off leaves about 1e-11 apart and would otherwise join by needle edges
/// (the element validation allows what this implies, `ConvexPolyhedron::with_position_tolerance`).
pub const ON_PLANE_TOLERANCE: Real = 1e-9;

/// One element of the topology being cut: faces as cycles of global nodes (counter-clockwise
/// from outside), which faces lie on a cut, and the element of the mesh before this cut that
/// holds it.
#[derive(Clone, Debug)]
pub(crate) struct CutElement {
    pub faces: Vec<Vec<u32>>,
    pub cut: Vec<Mark>,
    pub parent: u32,
}

/// Whether a face lies on a cut, and whether this cut covered it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Mark {
    /// Material continues across it (or it is on the original boundary).
    Open,
    /// Covered by an earlier cut.
    Cut,
    /// Covered by the cut being made.
    NewCut,
}

impl Mark {
    pub fn is_cut(self) -> bool {
        self != Mark::Open
    }
}

/// A node's value as weights over the nodes before the cut.
pub(crate) type Row = Vec<(u32, Real)>;

/// The topology a cut works on, with every new node's position and row.
pub(crate) struct Topology<'a> {
    pub positions: Vec<Point3<Real>>,
    /// Rows of nodes created by this cut (index − `old_nodes`).
    pub rows: Vec<Row>,
    /// Elements a plane crossed but whose section was degenerate (kept whole, faces split).
    pub degenerate: usize,
    pub old_nodes: usize,
    pub elements: Vec<CutElement>,
    boxes: Vec<(Point3<Real>, Point3<Real>)>,
    largest: Real,
    tolerance: Real,
    /// The row of a point of an old element (its coordinates there).
    interpolate: &'a dyn Fn(u32, &Point3<Real>) -> Row,
}

/// A plane `n·x = offset` (unit `n`).
#[derive(Clone, Copy, Debug)]
struct Plane {
    n: Vector3<Real>,
    offset: Real,
}

impl Plane {
    fn distance(&self, p: &Point3<Real>) -> Real {
        self.n.dot(&p.coords) - self.offset
    }
}

/// A convex cut polygon prepared: its plane, the inward planes through its edges (perpendicular
/// to it) and its corners.
struct CutPolygon {
    plane: Plane,
    sides: Vec<Plane>,
    corners: Vec<Point3<Real>>,
}

impl CutPolygon {
    /// `None` for a polygon of (nearly) no area.
    fn new(corners: &[Point3<Real>]) -> Option<Self> {
        let m = corners.len();
        let normal = (0..m).fold(Vector3::zeros(), |n, k| n + corners[k].coords.cross(&corners[(k + 1) % m].coords));
        let scale = (0..m).map(|k| (corners[(k + 1) % m] - corners[k]).norm()).fold(0.0, Real::max);
        // NaN-safe: a non-finite normal is no polygon either.
        if normal.norm().partial_cmp(&(1e-12 * scale * scale)) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let n = normal.normalize();
        let plane = Plane { n, offset: n.dot(&corners[0].coords) };
        let sides = (0..m)
            .filter_map(|i| {
                let (a, b) = (corners[i], corners[(i + 1) % m]);
                let m = n.cross(&(b - a));
                (m.norm() > 0.0).then(|| {
                    let m = m.normalize();
                    Plane { n: m, offset: m.dot(&a.coords) }
                })
            })
            .collect();
        Some(Self { plane, sides, corners: corners.to_vec() })
    }

    fn bounds(&self) -> (Point3<Real>, Point3<Real>) {
        self.corners.iter().fold((self.corners[0], self.corners[0]), |(lo, hi), p| (lo.inf(p), hi.sup(p)))
    }
}

/// The soup's triangles, with each pair that shares an edge, lies in one plane, faces the same
/// way and makes a convex quadrilateral merged into it (a blade's swept strips, a rectangle
/// given as two triangles): a diagonal inside the cut would otherwise split every face in the
/// plane it crosses, for nothing.
pub(crate) fn cut_polygons(triangles: &[[Point3<Real>; 3]]) -> Vec<Vec<Point3<Real>>> {
    let bits = |p: &Point3<Real>| p.coords.map(|c| c.to_bits());
    let mut by_edge: HashMap<([u64; 3], [u64; 3]), Vec<usize>> = HashMap::new();
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (bits(&tri[k]), bits(&tri[(k + 1) % 3]));
            by_edge.entry((a.into(), b.into())).or_default().push(t);
        }
    }
    let mut used = vec![false; triangles.len()];
    let mut polygons = Vec::with_capacity(triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        if used[t] {
            continue;
        }
        used[t] = true;
        let mut merged = None;
        'edges: for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let Some(others) = by_edge.get(&(bits(&b).into(), bits(&a).into())) else { continue };
            for &o in others {
                if used[o] {
                    continue;
                }
                let other = &triangles[o];
                let Some(q) = other.iter().find(|p| bits(p) != bits(&a) && bits(p) != bits(&b)) else { continue };
                let quad = [a, *q, b, tri[(k + 2) % 3]];
                let n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
                let scale = quad.iter().map(|p| (p - a).norm()).fold(0.0, Real::max);
                let planar = n.dot(&(q - a)).abs() <= 1e-12 * n.norm() * scale;
                let convex = (0..4).all(|i| {
                    let (p0, p1, p2) = (quad[i], quad[(i + 1) % 4], quad[(i + 2) % 4]);
                    n.dot(&(p1 - p0).cross(&(p2 - p1))) > 1e-9 * n.norm() * scale * scale
                });
                if planar && convex {
                    used[o] = true;
                    merged = Some(quad.to_vec());
                    break 'edges;
                }
            }
        }
        polygons.push(merged.unwrap_or_else(|| tri.to_vec()));
    }
    polygons
}

/// The sorted node set of a face: the same for both sides of a shared face.
fn key(face: &[u32]) -> Vec<u32> {
    let mut k = face.to_vec();
    k.sort_unstable();
    k
}

fn bounds_of(positions: &[Point3<Real>], element: &CutElement) -> (Point3<Real>, Point3<Real>) {
    let mut nodes = element.faces.iter().flatten();
    let first = positions[*nodes.next().expect("an element has nodes") as usize];
    element.faces.iter().flatten().fold((first, first), |(lo, hi), &v| {
        let p = positions[v as usize];
        (lo.inf(&p), hi.sup(&p))
    })
}

/// Area of the part of the convex polygon `points` (in a plane with unit normal `n`) inside the
/// half-spaces `sides`: Sutherland–Hodgman clipping of its projection.
fn area_inside(points: &[Point3<Real>], n: &Vector3<Real>, sides: &[Plane]) -> Real {
    let mut polygon: Vec<Point3<Real>> = points.to_vec();
    for side in sides {
        let mut clipped = Vec::with_capacity(polygon.len() + 2);
        for k in 0..polygon.len() {
            let (a, b) = (polygon[k], polygon[(k + 1) % polygon.len()]);
            let (da, db) = (side.distance(&a), side.distance(&b));
            if da >= 0.0 {
                clipped.push(a);
            }
            if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
                clipped.push(a + (b - a) * (da / (da - db)));
            }
        }
        polygon = clipped;
        if polygon.len() < 3 {
            return 0.0;
        }
    }
    let mut area = Vector3::zeros();
    for k in 0..polygon.len() {
        area += polygon[k].coords.cross(&polygon[(k + 1) % polygon.len()].coords);
    }
    (area.dot(n) / 2.0).abs()
}

/// The convex hull of points of a plane (unit normal `n`), counter-clockwise about `n`.
fn planar_hull(points: &[Point3<Real>], n: &Vector3<Real>) -> Vec<Point3<Real>> {
    let u = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let u = (u - n * n.dot(&u)).normalize();
    let w = n.cross(&u);
    let mut flat: Vec<(Point2<Real>, usize)> =
        points.iter().enumerate().map(|(i, p)| (Point2::new(p.coords.dot(&u), p.coords.dot(&w)), i)).collect();
    flat.sort_by(|a, b| a.0.x.total_cmp(&b.0.x).then(a.0.y.total_cmp(&b.0.y)));
    let cross = |o: Point2<Real>, a: Point2<Real>, b: Point2<Real>| (a - o).perp(&(b - o));
    let mut hull: Vec<(Point2<Real>, usize)> = Vec::with_capacity(flat.len() + 1);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &(Point2<Real>, usize)>> =
            if pass == 0 { Box::new(flat.iter()) } else { Box::new(flat.iter().rev()) };
        for &p in iter {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2].0, hull[hull.len() - 1].0, p.0) <= 0.0 {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull.into_iter().map(|(_, i)| points[i]).collect()
}

impl<'a> Topology<'a> {
    pub fn new(
        positions: Vec<Point3<Real>>,
        elements: Vec<CutElement>,
        interpolate: &'a dyn Fn(u32, &Point3<Real>) -> Row,
    ) -> Self {
        let boxes: Vec<_> = elements.iter().map(|e| bounds_of(&positions, e)).collect();
        let largest = boxes.iter().map(|(lo, hi)| (hi - lo).norm()).fold(0.0, Real::max);
        Self {
            old_nodes: positions.len(),
            positions,
            rows: Vec::new(),
            degenerate: 0,
            elements,
            boxes,
            largest,
            tolerance: ON_PLANE_TOLERANCE * largest,
            interpolate,
        }
    }

    /// Elements whose box comes within the largest element diameter of `[lo, hi]` (every element
    /// that shares a node or edge with one meeting the box), ascending.
    fn near(&self, lo: &Point3<Real>, hi: &Point3<Real>) -> Vec<usize> {
        let pad = self.largest;
        (0..self.elements.len())
            .filter(|&e| {
                let (a, b) = &self.boxes[e];
                (0..3).all(|k| a[k] <= hi[k] + pad && b[k] >= lo[k] - pad)
            })
            .collect()
    }

    fn add_node(&mut self, p: Point3<Real>, row: Row) -> u32 {
        self.positions.push(p);
        self.rows.push(row);
        (self.positions.len() - 1) as u32
    }

    /// The row of node `v` over the old nodes.
    fn row(&self, v: u32) -> Row {
        if (v as usize) < self.old_nodes { vec![(v, 1.0)] } else { self.rows[v as usize - self.old_nodes].clone() }
    }

    fn side(&self, plane: &Plane, v: u32) -> i8 {
        let d = plane.distance(&self.positions[v as usize]);
        if d > self.tolerance {
            1
        } else if d < -self.tolerance {
            -1
        } else {
            0
        }
    }

    /// Cuts along one convex polygon: splits the elements whose section by its plane meets it,
    /// splits the faces in its plane by its edges, and covers those inside it.
    pub fn cut_polygon(&mut self, polygon: &[Point3<Real>]) -> Result<(), String> {
        let Some(t) = CutPolygon::new(polygon) else { return Ok(()) };
        let (lo, hi) = t.bounds();
        let mut near = self.near(&lo, &hi);
        self.split_section(&t, &mut near)?;
        // The faces in the plane that the triangle overlaps, split by its edges' planes.
        for side in &t.sides {
            let faces: HashSet<Vec<u32>> = self
                .faces_in_plane(&near, &t.plane)
                .into_iter()
                .filter(|f| {
                    let points: Vec<Point3<Real>> = f.iter().map(|&v| self.positions[v as usize]).collect();
                    area_inside(&points, &t.plane.n, &t.sides) > self.tolerance * self.largest
                })
                .map(|f| key(&f))
                .collect();
            self.split(&mut near, side, &[], &faces)?;
        }
        // Cover the faces in the plane inside the triangle (both sides of each).
        let inside: HashSet<Vec<u32>> = self
            .faces_in_plane(&near, &t.plane)
            .into_iter()
            .filter(|f| {
                let c = f.iter().map(|&v| self.positions[v as usize].coords).sum::<Vector3<Real>>() / f.len() as Real;
                t.sides.iter().all(|s| s.distance(&Point3::from(c)) > self.tolerance)
            })
            .map(|f| key(&f))
            .collect();
        for &e in &near {
            let element = &mut self.elements[e];
            for (face, mark) in element.faces.iter().zip(element.cut.iter_mut()) {
                if *mark == Mark::Open && inside.contains(&key(face)) {
                    *mark = Mark::NewCut;
                }
            }
        }
        Ok(())
    }

    /// The section of element `e` by `plane`: the convex hull of its nodes on the plane and its
    /// edges' crossings, counter-clockwise about the plane's normal; `None` unless the plane
    /// crosses the element.
    fn section(&self, e: usize, plane: &Plane) -> Option<Vec<Point3<Real>>> {
        let element = &self.elements[e];
        let sides: Vec<i8> = element.faces.iter().flatten().map(|&v| self.side(plane, v)).collect();
        if !(sides.contains(&1) && sides.contains(&-1)) {
            return None;
        }
        let mut points: Vec<Point3<Real>> = Vec::new();
        for face in &element.faces {
            for k in 0..face.len() {
                let (a, b) = (face[k], face[(k + 1) % face.len()]);
                let (sa, sb) = (self.side(plane, a), self.side(plane, b));
                if sa == 0 {
                    points.push(self.positions[a as usize]);
                } else if sa * sb < 0 {
                    let (pa, pb) = (self.positions[a as usize], self.positions[b as usize]);
                    let (da, db) = (plane.distance(&pa), plane.distance(&pb));
                    points.push(pa + (pb - pa) * (da / (da - db)));
                }
            }
        }
        let hull = planar_hull(&points, &plane.n);
        (hull.len() >= 3).then_some(hull)
    }

    /// The elements of `near` whose section by the polygon's plane meets it (with area).
    fn meeting(&self, t: &CutPolygon, near: &[usize]) -> Vec<(usize, Vec<Point3<Real>>)> {
        near.iter()
            .filter_map(|&e| {
                let hull = self.section(e, &t.plane)?;
                (area_inside(&hull, &t.plane.n, &t.sides) > self.tolerance * self.largest).then_some((e, hull))
            })
            .collect()
    }

    /// Splits the elements of `near` whose section by the polygon's plane meets the polygon
    /// (wicke2007 §5.1); the parts are appended to `near`.
    fn split_section(&mut self, t: &CutPolygon, near: &mut Vec<usize>) -> Result<(), String> {
        let to_split: Vec<usize> = self.meeting(t, near).into_iter().map(|(e, _)| e).collect();
        self.split(near, &t.plane, &to_split, &HashSet::new())
    }

    /// The faces of `elements` with every node on `plane`.
    fn faces_in_plane(&self, elements: &[usize], plane: &Plane) -> Vec<Vec<u32>> {
        let mut faces = Vec::new();
        for &e in elements {
            for face in &self.elements[e].faces {
                if face.iter().all(|&v| self.side(plane, v) == 0) {
                    faces.push(face.clone());
                }
            }
        }
        faces
    }

    /// Splits the elements `to_split` (all crossed by `plane`) into their two convex parts, and
    /// the faces whose key is in `faces` (crossed by `plane`) into two; the same faces in every
    /// other element of `near` are split alike, and new edge nodes are inserted into every face
    /// of `near` holding the edge. New parts are appended to `near`.
    fn split(
        &mut self,
        near: &mut Vec<usize>,
        plane: &Plane,
        to_split: &[usize],
        faces: &HashSet<Vec<u32>>,
    ) -> Result<(), String> {
        let crossed = |this: &Self, face: &[u32]| {
            let s: Vec<i8> = face.iter().map(|&v| this.side(plane, v)).collect();
            s.contains(&1) && s.contains(&-1)
        };
        let mut split_faces: HashSet<Vec<u32>> = faces.iter().filter(|f| crossed(self, f)).cloned().collect();
        for &e in to_split {
            for face in &self.elements[e].faces {
                if crossed(self, face) {
                    split_faces.insert(key(face));
                }
            }
        }
        if split_faces.is_empty() && to_split.is_empty() {
            return Ok(());
        }
        // New nodes on crossed edges of the faces to split, in a deterministic order.
        let mut edge_nodes: BTreeMap<(u32, u32), u32> = BTreeMap::new();
        for &e in near.iter() {
            for fi in 0..self.elements[e].faces.len() {
                let face = self.elements[e].faces[fi].clone();
                if !split_faces.contains(&key(&face)) {
                    continue;
                }
                for k in 0..face.len() {
                    let (a, b) = (face[k], face[(k + 1) % face.len()]);
                    let (lo, hi) = (a.min(b), a.max(b));
                    if self.side(plane, lo) * self.side(plane, hi) < 0 && !edge_nodes.contains_key(&(lo, hi)) {
                        let (pa, pb) = (self.positions[lo as usize], self.positions[hi as usize]);
                        let (da, db) = (plane.distance(&pa), plane.distance(&pb));
                        let p = pa + (pb - pa) * (da / (da - db));
                        let row = (self.interpolate)(self.elements[e].parent, &p);
                        let v = self.add_node(p, row);
                        edge_nodes.insert((lo, hi), v);
                    }
                }
            }
        }
        let split_set: HashSet<usize> = to_split.iter().copied().collect();
        let mut appended = Vec::new();
        for &e in near.iter() {
            let element = &self.elements[e];
            // Insert the new edge nodes, remembering which faces were to split.
            let mut inserted: Vec<(Vec<u32>, Mark, bool)> = Vec::with_capacity(element.faces.len());
            for (face, &cut) in element.faces.iter().zip(&element.cut) {
                let to = split_faces.contains(&key(face));
                let mut out = Vec::with_capacity(face.len() + 2);
                for k in 0..face.len() {
                    let (a, b) = (face[k], face[(k + 1) % face.len()]);
                    out.push(a);
                    if let Some(&m) = edge_nodes.get(&(a.min(b), a.max(b))) {
                        out.push(m);
                    }
                }
                inserted.push((out, cut, to));
            }
            let parts = if split_set.contains(&e) { self.split_parts(plane, &inserted) } else { None };
            if split_set.contains(&e) && parts.is_none() {
                self.degenerate += 1;
            }
            if let Some([(below_faces, below_cut), (above_faces, above_cut)]) = parts {
                let parent = self.elements[e].parent;
                self.elements[e] = CutElement { faces: below_faces, cut: below_cut, parent };
                self.elements.push(CutElement { faces: above_faces, cut: above_cut, parent });
                appended.push(self.elements.len() - 1);
            } else {
                // Not split (or its section degenerate: kept whole): its faces crossed where a
                // neighbour's are split alike, as coplanar pairs.
                let (mut faces, mut cut) =
                    (Vec::with_capacity(inserted.len() + 1), Vec::with_capacity(inserted.len() + 1));
                for (face, c, to) in inserted {
                    if to {
                        for keep in [-1i8, 1] {
                            if let Some(p) = self.part(plane, &face, keep) {
                                faces.push(p);
                                cut.push(c);
                            }
                        }
                    } else {
                        faces.push(face);
                        cut.push(c);
                    }
                }
                self.elements[e].faces = faces;
                self.elements[e].cut = cut;
            }
        }
        for &e in near.iter().chain(&appended) {
            if e >= self.boxes.len() {
                self.boxes.push(bounds_of(&self.positions, &self.elements[e]));
            } else {
                self.boxes[e] = bounds_of(&self.positions, &self.elements[e]);
            }
        }
        near.extend(appended);
        Ok(())
    }

    /// The part of `face` on side `keep` of `plane` (with its nodes on the plane), if it has one.
    fn part(&self, plane: &Plane, face: &[u32], keep: i8) -> Option<Vec<u32>> {
        let out: Vec<u32> = face.iter().copied().filter(|&v| self.side(plane, v) != -keep).collect();
        (out.len() >= 3 && out.iter().any(|&v| self.side(plane, v) == keep)).then_some(out)
    }

    /// The two convex parts (below, above) of an element whose faces, with the plane's edge
    /// nodes inserted, are `inserted`: each part's clipped faces and the cap closing it. `None`
    /// when the section is not one polygon (a face of the element within the on-plane tolerance
    /// of the plane while the plane crosses it elsewhere: a degenerate touch the caller keeps
    /// whole).
    #[allow(clippy::type_complexity)]
    fn split_parts(
        &self,
        plane: &Plane,
        inserted: &[(Vec<u32>, Mark, bool)],
    ) -> Option<[(Vec<Vec<u32>>, Vec<Mark>); 2]> {
        let mut parts = Vec::with_capacity(2);
        for keep in [-1i8, 1] {
            let (mut faces, mut cut) = (Vec::new(), Vec::new());
            // The cap's directed edges: each face part's run along the plane, reversed.
            let mut runs: Vec<(u32, u32)> = Vec::new();
            for (face, c, _) in inserted {
                let Some(p) = self.part(plane, face, keep) else { continue };
                for k in 0..p.len() {
                    let (a, b) = (p[k], p[(k + 1) % p.len()]);
                    if self.side(plane, a) == 0 && self.side(plane, b) == 0 {
                        runs.push((b, a));
                    }
                }
                faces.push(p);
                cut.push(*c);
            }
            // An edge the part uses both ways lies on the plane between two of its faces: not
            // the cap's.
            let mut cap_edges: HashMap<u32, u32> = HashMap::new();
            for &(a, b) in &runs {
                if !runs.contains(&(b, a)) && cap_edges.insert(a, b).is_some() {
                    return None;
                }
            }
            let (&start, _) = cap_edges.iter().min_by_key(|(a, _)| **a)?;
            let mut cap = vec![start];
            let mut current = cap_edges[&start];
            while current != start {
                if cap.len() > cap_edges.len() {
                    return None;
                }
                cap.push(current);
                current = *cap_edges.get(&current)?;
            }
            if cap.len() != cap_edges.len() || cap.len() < 3 {
                return None;
            }
            faces.push(cap);
            cut.push(Mark::Open);
            parts.push((faces, cut));
        }
        let above = parts.pop()?;
        let below = parts.pop()?;
        Some([below, above])
    }

    /// Faces by key: `(element, face)` of each side.
    fn face_index(&self) -> HashMap<Vec<u32>, Vec<(usize, usize)>> {
        let mut index: HashMap<Vec<u32>, Vec<(usize, usize)>> = HashMap::new();
        for (e, element) in self.elements.iter().enumerate() {
            for (f, face) in element.faces.iter().enumerate() {
                index.entry(key(face)).or_default().push((e, f));
            }
        }
        index
    }

    /// For each node on a covered face, its incident elements grouped by what still joins them
    /// around it (shared faces through it that no cut covers); nodes with one group are left out.
    fn groups(&self) -> BTreeMap<u32, Vec<Vec<usize>>> {
        let index = self.face_index();
        let mut on_cut: Vec<u32> = Vec::new();
        for element in &self.elements {
            for (face, &cut) in element.faces.iter().zip(&element.cut) {
                if cut.is_cut() {
                    on_cut.extend(face);
                }
            }
        }
        on_cut.sort_unstable();
        on_cut.dedup();
        let wanted: HashSet<u32> = on_cut.iter().copied().collect();
        let mut incident: HashMap<u32, Vec<usize>> = HashMap::new();
        for (e, element) in self.elements.iter().enumerate() {
            let mut nodes: Vec<u32> = element.faces.iter().flatten().copied().filter(|v| wanted.contains(v)).collect();
            nodes.sort_unstable();
            nodes.dedup();
            for v in nodes {
                incident.entry(v).or_default().push(e);
            }
        }
        let mut result = BTreeMap::new();
        for v in on_cut {
            let elements = &incident[&v];
            let mut group: Vec<usize> = (0..elements.len()).collect();
            fn find(group: &mut [usize], i: usize) -> usize {
                let mut r = i;
                while group[r] != r {
                    r = group[r];
                }
                group[i] = r;
                r
            }
            for (i, &e) in elements.iter().enumerate() {
                for (face, &cut) in self.elements[e].faces.iter().zip(&self.elements[e].cut) {
                    if cut.is_cut() || !face.contains(&v) {
                        continue;
                    }
                    for &(other, of) in &index[&key(face)] {
                        if other != e && !self.elements[other].cut[of].is_cut() {
                            let j = elements.binary_search(&other).expect("incident");
                            let (a, b) = (find(&mut group, i), find(&mut group, j));
                            group[a.max(b)] = a.min(b);
                        }
                    }
                }
            }
            let mut by_root: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
            for i in 0..elements.len() {
                let r = find(&mut group, i);
                by_root.entry(r).or_default().push(elements[i]);
            }
            if by_root.len() > 1 {
                result.insert(v, by_root.into_values().collect());
            }
        }
        result
    }

    /// Inserts a pocket node (wicke2007 §5.2) into each region of faces covered by this cut that
    /// no node can open: at the centroid of its largest face, which becomes a fan of covered
    /// triangles around it on both sides.
    fn add_pockets(&mut self, opening: &HashSet<u32>) {
        let mut regions: Vec<Vec<Vec<u32>>> = Vec::new();
        // Faces this cut covered with material on both sides (a cut along the body's boundary
        // opens nothing).
        let index = self.face_index();
        let mut covered: Vec<Vec<u32>> = index
            .iter()
            .filter(|(_, sides)| {
                sides.len() == 2 && sides.iter().all(|&(e, f)| self.elements[e].cut[f] == Mark::NewCut)
            })
            .map(|(k, _)| k.clone())
            .collect();
        covered.sort_unstable();
        // Regions: covered faces joined through shared nodes.
        let mut node_region: HashMap<u32, usize> = HashMap::new();
        let mut parent: Vec<usize> = Vec::new();
        fn find(parent: &mut [usize], i: usize) -> usize {
            let mut r = i;
            while parent[r] != r {
                r = parent[r];
            }
            parent[i] = r;
            r
        }
        for (i, face) in covered.iter().enumerate() {
            parent.push(i);
            for &v in face {
                if let Some(&j) = node_region.get(&v) {
                    let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                    parent[a.max(b)] = a.min(b);
                } else {
                    node_region.insert(v, i);
                }
            }
        }
        let mut by_root: BTreeMap<usize, Vec<Vec<u32>>> = BTreeMap::new();
        for (i, face) in covered.iter().enumerate() {
            let r = find(&mut parent, i);
            by_root.entry(r).or_default().push(face.clone());
        }
        regions.extend(by_root.into_values());
        for region in regions {
            if region.iter().flatten().any(|v| opening.contains(v)) {
                continue;
            }
            // The largest face of the region (by the area of its key's polygon in any element).
            let area = |this: &Self, k: &[u32]| -> Real {
                let p: Vec<Point3<Real>> = k.iter().map(|&v| this.positions[v as usize]).collect();
                planar_hull_area(&p)
            };
            let Some(target) = region.iter().max_by(|a, b| area(self, a).total_cmp(&area(self, b))).cloned() else {
                continue;
            };
            let centroid = Point3::from(
                target.iter().map(|&v| self.positions[v as usize].coords).sum::<Vector3<Real>>() / target.len() as Real,
            );
            let mut pocket = None;
            for e in 0..self.elements.len() {
                let Some(f) = self.elements[e].faces.iter().position(|face| key(face) == target) else { continue };
                let node = *pocket.get_or_insert_with(|| {
                    let row = (self.interpolate)(self.elements[e].parent, &centroid);
                    self.add_node(centroid, row)
                });
                let face = self.elements[e].faces.remove(f);
                self.elements[e].cut.remove(f);
                for k in 0..face.len() {
                    self.elements[e].faces.push(vec![node, face[k], face[(k + 1) % face.len()]]);
                    self.elements[e].cut.push(Mark::NewCut);
                }
            }
        }
    }

    /// Duplicates nodes per group of elements around them (the first group keeps the node) after
    /// adding pockets where needed; returns, per new node, the node it copies.
    pub fn separate(&mut self) -> Vec<(u32, u32)> {
        let opening: HashSet<u32> = self.groups().into_keys().collect();
        self.add_pockets(&opening);
        let groups = self.groups();
        let mut copies = Vec::new();
        for (v, groups) in groups {
            for group in groups.into_iter().skip(1) {
                let p = self.positions[v as usize];
                let copy = self.add_node(p, self.row(v));
                copies.push((copy, v));
                for e in group {
                    for face in &mut self.elements[e].faces {
                        for w in face.iter_mut().filter(|w| **w == v) {
                            *w = copy;
                        }
                    }
                }
            }
        }
        copies
    }

    /// Distance from a plane under which a node counts as on it.
    pub fn tolerance(&self) -> Real {
        self.tolerance
    }

    /// Whether this cut covered any face; the marks become `Cut` for the next one.
    pub fn finish_marks(&mut self) -> bool {
        let mut any = false;
        for mark in self.elements.iter_mut().flat_map(|e| e.cut.iter_mut()) {
            if *mark == Mark::NewCut {
                *mark = Mark::Cut;
                any = true;
            }
        }
        any
    }
}

/// Area of a planar polygon given in order (Newell).
fn planar_hull_area(points: &[Point3<Real>]) -> Real {
    let mut n = Vector3::zeros();
    for k in 0..points.len() {
        n += points[k].coords.cross(&points[(k + 1) % points.len()].coords);
    }
    n.norm() / 2.0
}
