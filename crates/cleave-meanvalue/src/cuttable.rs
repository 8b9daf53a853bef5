//! `Cuttable` for the mean value mesh (wicke2007 §5, docs/math/mean-value.md §9): a cut made on
//! the element topology (`cut.rs`), the mesh rebuilt from it with rest matrices shared per shape,
//! the new nodes carried by `DofRemap::Linear` (each the old element's coordinates at its rest
//! position, so affine fields are carried exactly), pieces as elements joined through uncut
//! faces, and the render surface as the faces that are boundary or cut.

use crate::coordinates::{Workspace, mean_value_coordinates};
use crate::cut::{CutElement, Mark, Row, Topology, cut_polygons};
use crate::mesh::{CutReport, MeanValueMesh};
use crate::polyhedron::{ConvexPolyhedron, Real};
use cleave_core::{
    CutSurface, Cuttable, Discretization, DofRemap, EmbeddedSurface, Embedding, FrameRemap, Piece, Point3,
    TopologyChange, TopologyError, Vector3,
};
use std::collections::HashMap;

/// Weights below this are dropped from a new node's row (coordinates that vanish on a face).
const ROW_EPSILON: Real = 1e-15;

/// The quality floor of an element made by a cut (see [`quality`]). An element below it is
/// merged into the neighbour across an uncut shared face with which it makes the best convex
/// element (mean-value.md §9, "Slivers").
pub const QUALITY_FLOOR: Real = 1e-2;

/// An element's quality: its width (the least, over its faces, of the distance from the face's
/// plane to the farthest vertex behind it) over its diameter, times √3 so that a cube has 1 (a
/// regular tetrahedron 1.41). Its stiffness per unit mass grows like 1/width², so this ratio,
/// squared, bounds how much stiffer than its neighbours' an element's stiffest mode is: a flat
/// sliver (thickness t) and a needle (cross-section w × w) both score t/diam or w/diam
/// (mean-value.md §9, "Slivers"; volume over diameter cubed scored a needle (w/diam)², far
/// below what its stiffness says).
pub fn quality(shape: &ConvexPolyhedron) -> Real {
    let vertices = shape.vertices();
    let width = (0..shape.faces().len())
        .map(|f| vertices.iter().map(|v| shape.depth(f, v)).fold(0.0, Real::max))
        .fold(Real::INFINITY, Real::min);
    width * 3f64.sqrt() / shape.diameter()
}

/// An element being rebuilt: its shape, global nodes, cut faces and parent.
pub(crate) type Rebuilt = (ConvexPolyhedron, Vec<u32>, Vec<bool>, u32);

/// The element of global faces `faces` (with their cut marks) over `positions`.
pub(crate) fn element_of(
    faces: &[Vec<u32>],
    positions: &[Point3<Real>],
    tolerance: Real,
) -> Result<(ConvexPolyhedron, Vec<u32>), crate::PolyhedronError> {
    let mut nodes: Vec<u32> = Vec::new();
    let mut local: HashMap<u32, usize> = HashMap::new();
    let local_faces: Vec<Vec<usize>> = faces
        .iter()
        .map(|face| {
            face.iter()
                .map(|&v| {
                    *local.entry(v).or_insert_with(|| {
                        nodes.push(v);
                        nodes.len() - 1
                    })
                })
                .collect()
        })
        .collect();
    let points = nodes.iter().map(|&v| positions[v as usize]).collect();
    Ok((ConvexPolyhedron::with_position_tolerance(points, local_faces, tolerance)?, nodes))
}

/// Global faces of a rebuilt element.
fn global_faces(element: &Rebuilt) -> Vec<Vec<u32>> {
    element.0.faces().iter().map(|f| f.iter().map(|&i| element.1[i]).collect()).collect()
}

/// The area of a planar polygon.
fn newell_area(points: &[Point3<Real>]) -> Real {
    let mut n = Vector3::zeros();
    for k in 0..points.len() {
        n += points[k].coords.cross(&points[(k + 1) % points.len()].coords);
    }
    0.5 * n.norm()
}

/// The union of the elements `group` (joined through uncut faces) as one element, if it is a
/// valid convex polyhedron that keeps every node of its members as a vertex (a node only on the
/// faces between them would be left without an element); its parent is the second member's.
fn union_of(elements: &[Rebuilt], group: &[usize], positions: &[Point3<Real>], tolerance: Real) -> Option<Rebuilt> {
    let key = |f: &[u32]| {
        let mut k = f.to_vec();
        k.sort_unstable();
        k
    };
    let mut count: HashMap<Vec<u32>, usize> = HashMap::new();
    for &m in group {
        for face in global_faces(&elements[m]) {
            *count.entry(key(&face)).or_default() += 1;
        }
    }
    let mut faces = Vec::new();
    let mut cut = Vec::new();
    for &m in group {
        for (face, &c) in global_faces(&elements[m]).into_iter().zip(&elements[m].2) {
            match count[&key(&face)] {
                1 => {
                    faces.push(face);
                    cut.push(c);
                }
                // A face between two members: inside the union, unless a cut separates them
                // there (then no union).
                2 if !c => {}
                _ => return None,
            }
        }
    }
    let (shape, nodes) = element_of(&faces, positions, tolerance).ok()?;
    let members: std::collections::HashSet<u32> = group.iter().flat_map(|&m| elements[m].1.iter().copied()).collect();
    (nodes.len() == members.len()).then(|| (shape, nodes, cut, elements[group[1]].3))
}

/// Merges each element below [`QUALITY_FLOOR`], worst first, into the neighbour across an
/// uncut shared face that makes the best convex union with it. Returns how many were merged and
/// how many stay below the floor (no convex union).
pub(crate) fn merge_slivers(
    elements: &mut Vec<Rebuilt>,
    positions: &[Point3<Real>],
    tolerance: Real,
) -> (usize, usize) {
    let mut merged = 0;
    // Passes until none merges: a union may itself be below the floor and merge again.
    loop {
        let pass = merge_pass(elements, positions, tolerance);
        merged += pass;
        if pass == 0 {
            break;
        }
    }
    (merged, elements.iter().filter(|e| quality(&e.0) < QUALITY_FLOOR).count())
}

/// One pass of [`merge_slivers`]: returns how many merged.
fn merge_pass(elements: &mut Vec<Rebuilt>, positions: &[Point3<Real>], tolerance: Real) -> usize {
    let key = |f: &[u32]| {
        let mut k = f.to_vec();
        k.sort_unstable();
        k
    };
    let mut slivers: Vec<(Real, usize)> =
        elements.iter().enumerate().map(|(e, el)| (quality(&el.0), e)).filter(|(q, _)| *q < QUALITY_FLOOR).collect();
    if slivers.is_empty() {
        return 0;
    }
    slivers.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut sides: HashMap<Vec<u32>, Vec<usize>> = HashMap::new();
    for (e, element) in elements.iter().enumerate() {
        for face in global_faces(element) {
            sides.entry(key(&face)).or_default().push(e);
        }
    }
    let mut dead = vec![false; elements.len()];
    let mut merged = 0;
    for &(_, s) in &slivers {
        if dead[s] || quality(&elements[s].0) >= QUALITY_FLOOR {
            continue;
        }
        let faces_s = global_faces(&elements[s]);
        // Neighbours across uncut faces, and those across the faces parallel to the sliver's
        // largest uncut face (across its thin direction).
        let (mut neighbours, mut across): (Vec<usize>, Vec<usize>) = (Vec::new(), Vec::new());
        let shape_s = &elements[s].0;
        let area =
            |f: usize| newell_area(&shape_s.faces()[f].iter().map(|&i| shape_s.vertices()[i]).collect::<Vec<_>>());
        let largest = (0..faces_s.len()).filter(|&f| !elements[s].2[f]).max_by(|&a, &b| area(a).total_cmp(&area(b)));
        for (f, face) in faces_s.iter().enumerate() {
            if elements[s].2[f] {
                continue;
            }
            let parallel = largest.is_some_and(|l| shape_s.normals()[f].dot(&shape_s.normals()[l]) > 1.0 - 1e-9);
            for &n in sides.get(&key(face)).into_iter().flatten() {
                if n != s && !dead[n] {
                    if !neighbours.contains(&n) {
                        neighbours.push(n);
                    }
                    if parallel && !across.contains(&n) {
                        across.push(n);
                    }
                }
            }
        }
        // Candidates, in order of preference: one sound neighbour (the best union), the
        // neighbours across the thin direction together (a slab along several cells, or a
        // neighbour split by an earlier cut), all neighbours together, one sliver neighbour.
        let sound: Vec<Vec<usize>> =
            neighbours.iter().filter(|&&n| quality(&elements[n].0) >= QUALITY_FLOOR).map(|&n| vec![s, n]).collect();
        let weak: Vec<Vec<usize>> =
            neighbours.iter().filter(|&&n| quality(&elements[n].0) < QUALITY_FLOOR).map(|&n| vec![s, n]).collect();
        let mut best: Option<(Real, Vec<usize>, Rebuilt)> = None;
        for tier in [sound, vec![[&[s][..], &across].concat()], vec![[&[s][..], &neighbours].concat()], weak] {
            for group in tier {
                if group.len() < 2 {
                    continue;
                }
                let Some(union) = union_of(elements, &group, positions, tolerance) else { continue };
                let q = quality(&union.0);
                if best.as_ref().is_none_or(|(b, ..)| q > *b) {
                    best = Some((q, group, union));
                }
            }
            if best.is_some() {
                break;
            }
        }
        if let Some((_, group, union)) = best {
            for &m in &group {
                for face in global_faces(&elements[m]) {
                    if let Some(list) = sides.get_mut(&key(&face)) {
                        list.retain(|&e| e != m);
                    }
                }
            }
            let keeper = group[1];
            for face in global_faces(&union) {
                sides.entry(key(&face)).or_default().push(keeper);
            }
            elements[keeper] = union;
            for &m in &group {
                if m != keeper {
                    dead[m] = true;
                }
            }
            merged += 1;
        }
    }
    let mut index = 0;
    elements.retain(|_| {
        index += 1;
        !dead[index - 1]
    });
    merged
}

impl MeanValueMesh {
    fn rest_point(&self, v: u32) -> Point3<Real> {
        let i = 3 * v as usize;
        Point3::new(self.rest[i], self.rest[i + 1], self.rest[i + 2])
    }

    /// The convex polygons of a cut surface: a plane as one square reaching well past the body, a
    /// soup's triangles with coplanar convex pairs merged (`cut_polygons`).
    fn cut_polygons(&self, surface: &CutSurface) -> Result<Vec<Vec<Point3<Real>>>, TopologyError> {
        let finite = |p: &Point3<Real>| p.coords.iter().all(|c| c.is_finite());
        match surface {
            CutSurface::Plane { point, normal } => {
                let length = normal.norm();
                if !(length.is_finite() && length > 0.0 && finite(point)) {
                    return Err(TopologyError::Invalid(format!(
                        "a cutting plane needs a finite point and a nonzero normal, got {point:?} and {normal:?}"
                    )));
                }
                let n = normal / length;
                let (mut lo, mut hi) = (Vector3::repeat(Real::MAX), Vector3::repeat(Real::MIN));
                for p in self.rest.chunks_exact(3) {
                    let p = Vector3::new(p[0], p[1], p[2]);
                    lo = lo.inf(&p);
                    hi = hi.sup(&p);
                }
                let centre = (lo + hi) / 2.0;
                let reach = 4.0 * (hi - lo).norm().max(Real::MIN_POSITIVE);
                let o = Point3::from(centre - n * n.dot(&(centre - point.coords)));
                let u = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
                let u = (u - n * n.dot(&u)).normalize() * reach;
                let w = n.cross(&u);
                Ok(vec![vec![o - u - w, o + u - w, o + u + w, o - u + w]])
            }
            CutSurface::Triangles(triangles) => {
                if let Some(t) = triangles.iter().find(|t| !t.iter().all(finite)) {
                    return Err(TopologyError::Invalid(format!("a cut triangle has a non-finite vertex: {t:?}")));
                }
                Ok(cut_polygons(triangles))
            }
        }
    }

    /// The row of rest point `p` of element `e`: its mean value coordinates there.
    fn row_at(&self, e: u32, p: &Point3<Real>) -> Row {
        let element = &self.elements[e as usize];
        let mut values = vec![0.0; element.nodes.len()];
        mean_value_coordinates(&element.shape, p, &mut values, None, &mut Workspace::default());
        element.nodes.iter().zip(&values).filter(|(_, w)| w.abs() > ROW_EPSILON).map(|(&n, &w)| (n, w)).collect()
    }

    /// Faces by their node sets: `(element, local face)` of each side.
    fn face_sides(&self) -> HashMap<Vec<u32>, Vec<(usize, usize)>> {
        let mut sides: HashMap<Vec<u32>, Vec<(usize, usize)>> = HashMap::new();
        for (e, element) in self.elements.iter().enumerate() {
            for (f, face) in element.shape.faces().iter().enumerate() {
                let mut key: Vec<u32> = face.iter().map(|&i| element.nodes[i]).collect();
                key.sort_unstable();
                sides.entry(key).or_default().push((e, f));
            }
        }
        sides
    }

    /// Piece index per element: elements joined through faces both share and no cut covers.
    fn piece_of_elements(&self) -> (Vec<u32>, usize) {
        let mut parent: Vec<usize> = (0..self.elements.len()).collect();
        fn find(parent: &mut [usize], i: usize) -> usize {
            let mut r = i;
            while parent[r] != r {
                r = parent[r];
            }
            parent[i] = r;
            r
        }
        for sides in self.face_sides().values() {
            if let [(a, fa), (b, fb)] = sides[..]
                && !self.elements[a].cut[fa]
                && !self.elements[b].cut[fb]
            {
                let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
                parent[ra.max(rb)] = ra.min(rb);
            }
        }
        let mut index: HashMap<usize, u32> = HashMap::new();
        let mut piece = Vec::with_capacity(self.elements.len());
        for e in 0..self.elements.len() {
            let r = find(&mut parent, e);
            let next = index.len() as u32;
            piece.push(*index.entry(r).or_insert(next));
        }
        (piece, index.len())
    }
}

/// Whether the polygon has a vertex on the straight line between its neighbours.
fn has_straight_vertex(points: &[Point3<Real>]) -> bool {
    let m = points.len();
    let n = (0..m).fold(Vector3::zeros(), |n, k| n + points[k].coords.cross(&points[(k + 1) % m].coords));
    let scale = n.norm();
    (0..m).any(|k| {
        let (a, b, c) = (points[(k + m - 1) % m], points[k], points[(k + 1) % m]);
        (b - a).cross(&(c - b)).norm() <= 1e-9 * scale
    })
}

impl Cuttable for MeanValueMesh {
    fn cut(&mut self, surface: &CutSurface) -> Result<TopologyChange, TopologyError> {
        let polygons = self.cut_polygons(surface)?;
        let old_nodes = self.num_nodes();
        let positions: Vec<Point3<Real>> = (0..old_nodes as u32).map(|v| self.rest_point(v)).collect();
        let elements: Vec<CutElement> = self
            .elements
            .iter()
            .enumerate()
            .map(|(e, element)| CutElement {
                faces: element.shape.faces().iter().map(|f| f.iter().map(|&i| element.nodes[i]).collect()).collect(),
                cut: element.cut.iter().map(|&c| if c { Mark::Cut } else { Mark::Open }).collect(),
                parent: e as u32,
            })
            .collect();
        let interpolate = |e: u32, p: &Point3<Real>| self.row_at(e, p);
        let mut topology = Topology::new(positions, elements, &interpolate);
        for polygon in &polygons {
            topology.cut_polygon(polygon).map_err(TopologyError::Invalid)?;
        }
        topology.separate();
        let covered = topology.finish_marks();
        if !covered && topology.positions.len() == old_nodes && topology.elements.len() == self.elements.len() {
            return Ok(TopologyChange {
                epoch: self.epoch,
                remap: DofRemap::Identity,
                frames: FrameRemap::Identity,
                pattern_changed: false,
            });
        }
        // The new elements, each on its nodes in order of first appearance, slivers merged.
        let mut built: Vec<Rebuilt> = Vec::with_capacity(topology.elements.len());
        for (e, element) in topology.elements.iter().enumerate() {
            let (shape, nodes) = element_of(&element.faces, &topology.positions, topology.tolerance())
                .map_err(|err| TopologyError::Invalid(format!("element {e} after the cut: {err}")))?;
            built.push((shape, nodes, element.cut.iter().map(|m| m.is_cut()).collect(), element.parent));
        }
        let (merged, left) = merge_slivers(&mut built, &topology.positions, topology.tolerance());
        let report = CutReport { merged, below_floor: left, degenerate: topology.degenerate };
        let mut remap = Embedding::new();
        for v in 0..topology.positions.len() {
            if v < old_nodes {
                remap.push_row(&[v as u32], &[1.0]);
            } else {
                let row = &topology.rows[v - old_nodes];
                let (nodes, weights): (Vec<u32>, Vec<Real>) = row.iter().copied().unzip();
                remap.push_row(&nodes, &weights);
            }
        }
        let frames = FrameRemap::Gather(built.iter().map(|e| e.3).collect());
        let built = built.into_iter().map(|(shape, nodes, cut, _)| (shape, nodes, cut)).collect();
        let (material, refinement, epoch) = (self.material, self.refinement, self.epoch + 1);
        let mut mesh = MeanValueMesh::with_cut_faces(material, topology.positions, built, refinement, Some(self))
            .map_err(|err| TopologyError::Invalid(format!("the cut mesh: {err}")))?;
        mesh.epoch = epoch;
        mesh.last_cut = report;

        *self = mesh;
        Ok(TopologyChange { epoch, remap: DofRemap::Linear(remap), frames, pattern_changed: true })
    }

    fn surface(&self) -> Option<EmbeddedSurface> {
        let sides = self.face_sides();
        let (piece_of, _) = self.piece_of_elements();
        let mut surface = EmbeddedSurface::default();
        let mut vertex_of: HashMap<u32, u32> = HashMap::new();
        for (e, element) in self.elements.iter().enumerate() {
            for (f, face) in element.shape.faces().iter().enumerate() {
                let nodes: Vec<u32> = face.iter().map(|&i| element.nodes[i]).collect();
                let mut key = nodes.clone();
                key.sort_unstable();
                if !element.cut[f] && sides[&key].len() == 2 {
                    continue;
                }
                let mut vertex = |v: u32, surface: &mut EmbeddedSurface| {
                    *vertex_of.entry(v).or_insert_with(|| {
                        surface.rest_vertices.push(self.rest_point(v));
                        surface.embedding.push_row(&[v], &[1.0]);
                        (surface.rest_vertices.len() - 1) as u32
                    })
                };
                let ids: Vec<u32> = nodes.iter().map(|&v| vertex(v, &mut surface)).collect();
                let points: Vec<Point3<Real>> = nodes.iter().map(|&v| self.rest_point(v)).collect();
                let push = |t: [u32; 3], surface: &mut EmbeddedSurface| {
                    surface.triangles.push(t);
                    surface.on_cut.push(element.cut[f]);
                    surface.piece.push(piece_of[e]);
                };
                if ids.len() > 3 && has_straight_vertex(&points) {
                    // A fan from the vertex average: no triangle of zero area at a straight vertex.
                    let weight = 1.0 / nodes.len() as Real;
                    let centre = points.iter().map(|p| p.coords).sum::<Vector3<Real>>() * weight;
                    surface.rest_vertices.push(Point3::from(centre));
                    surface.embedding.push_row(&nodes, &vec![weight; nodes.len()]);
                    let c = (surface.rest_vertices.len() - 1) as u32;
                    for k in 0..ids.len() {
                        push([c, ids[k], ids[(k + 1) % ids.len()]], &mut surface);
                    }
                } else {
                    for k in 1..ids.len() - 1 {
                        push([ids[0], ids[k], ids[k + 1]], &mut surface);
                    }
                }
            }
        }
        Some(surface)
    }

    fn pieces(&self) -> Vec<Piece> {
        let (piece_of, count) = self.piece_of_elements();
        let mut pieces = vec![Piece::default(); count];
        for (e, element) in self.elements.iter().enumerate() {
            let piece = &mut pieces[piece_of[e] as usize];
            piece.elements.push(e as u32);
            piece.nodes.extend(&element.nodes);
            piece.volume += element.volume;
        }
        for piece in &mut pieces {
            piece.nodes.sort_unstable();
            piece.nodes.dedup();
            piece.mass = piece.volume * self.material.density;
        }
        pieces
    }
}
