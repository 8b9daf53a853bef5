//! Cutting a DG body by a plane or a triangle soup (kaufmann2008 §8; docs/math/dg.md §13): the
//! polyhedral mesh split by `cleave_geometry::split_mesh_by_plane` or, triangle by triangle,
//! `cut_mesh_by_polygon`, the discretization rebuilt on it with the penalty kept, each child's
//! coefficients its first parent's polynomial restricted exactly (`basis::restriction`), the
//! pieces the components joined through coupled faces, and a render surface made of the
//! boundary faces, welded per group of elements joined around each vertex.

use super::DgMesh;
use crate::basis::restriction;
use crate::mesh::DgOptions;
use cleave_core::{
    CutSurface, Cuttable, DofRemap, EmbeddedSurface, Embedding, FrameRemap, Piece, Point3, Real, TopologyChange,
    TopologyError, Vector3,
};
use cleave_geometry::{
    Frame, MeshSplit, MeshSplitError, PolyhedralMesh, UnionFind, cut_mesh_by_polygon, element_moments_from_faces,
    split_mesh_by_plane, triangulate_planar_polygon,
};
use std::collections::{BTreeMap, HashMap};

/// Distance under which a vertex counts as on a cutting plane, relative to the mesh's size: far
/// below any element, far above the rounding that moves a vertex exactly on the plane off it
/// (docs/math/polygon-split.md, "Tolerance").
const ON_PLANE: Real = 1e-12;

impl DgMesh {
    /// Per element, its piece (components joined through coupled faces), and the piece count.
    pub(super) fn piece_of_elements(&self) -> (Vec<usize>, usize) {
        let mut joined = UnionFind::new(self.mesh.num_elements);
        for face in &self.mesh.faces {
            if let Some(outer) = face.outer {
                joined.union(face.inner as usize, outer as usize);
            }
        }
        let mut index = BTreeMap::new();
        let piece: Vec<usize> = (0..self.mesh.num_elements)
            .map(|e| {
                let root = joined.find(e);
                let next = index.len();
                *index.entry(root).or_insert(next)
            })
            .collect();
        (piece, index.len())
    }

    /// Distance under which a vertex counts as on a splitting plane ([`ON_PLANE`] of the mesh's
    /// bounding box diagonal).
    pub(super) fn on_plane_tolerance(&self) -> Real {
        let (mut lo, mut hi) = (Point3::from([Real::MAX; 3]), Point3::from([Real::MIN; 3]));
        for p in &self.mesh.vertices {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        ON_PLANE * (hi - lo).norm()
    }

    /// Replaces the discretization by one on `edit`'s mesh (a cut's or a refinement's; `what`
    /// names it in errors): the penalty kept, pieces of old faces keeping their weights, each
    /// element's refinement depth its parent's plus its splits, and each child's coefficients
    /// its first parent's polynomial restricted exactly.
    pub(super) fn rebuild(&mut self, edit: MeshEdit, what: &str) -> Result<TopologyChange, TopologyError> {
        let MeshEdit { mesh, parent, cut_faces, first_face, depth, dirichlet_faces, .. } = edit;
        // The penalty reached before (with its margin) is kept: the jumps already there keep
        // their energy. IP may still double it if a child makes the stiffness indefinite.
        let options = DgOptions { penalty: self.penalty, penalty_margin: 1.0, ..self.options };
        // A piece of a coupled face keeps the face's penalty weight, so its jump keeps its energy.
        let inherited: Vec<Option<Real>> =
            first_face.iter().map(|f| f.map(|f| self.face_weights[f as usize])).collect();
        let clamp = self.has_dirichlet.then_some(dirichlet_faces.as_slice());
        let mut rebuilt = DgMesh::with_face_weights(mesh, self.material, options, None, Some(&inherited), clamp)
            .map_err(|e| TopologyError::Invalid(format!("rebuilding the DG discretization after {what}: {e}")))?;
        let nb = self.exps.len();
        let mut rows = Embedding::new();
        let mut nodes = vec![0u32; nb];
        for (child, &first) in parent.iter().enumerate() {
            let (p, c) = (first as usize, child);
            let r = restriction(&self.bases[p], &rebuilt.bases[c], self.options.degree).ok_or_else(|| {
                TopologyError::Invalid(format!("element {c} (of {p}): its basis cannot take its parent's polynomial"))
            })?;
            for (j, node) in nodes.iter_mut().enumerate() {
                *node = (p * nb + j) as u32;
            }
            for i in 0..nb {
                let weights: Vec<Real> = (0..nb).map(|j| r[(i, j)]).collect();
                rows.push_row(&nodes, &weights);
            }
        }
        rebuilt.epoch = self.epoch + 1;
        rebuilt.cut_faces = cut_faces;
        rebuilt.depth = depth;
        rebuilt.refinement = self.refinement;
        *self = rebuilt;
        Ok(TopologyChange {
            epoch: self.epoch,
            remap: DofRemap::Linear(rows),
            frames: FrameRemap::Gather(parent),
            pattern_changed: true,
        })
    }
}

/// The plane through `point` with right-hand normal `normal` as three points.
pub(super) fn plane_through(point: &Point3<Real>, normal: &Vector3<Real>) -> [Point3<Real>; 3] {
    let n = normal / normal.norm();
    let helper = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let u = n.cross(&helper).normalize();
    // (u) × (n × u) = n: the plane's right-hand normal is n.
    [*point, point + u, point + n.cross(&u)]
}

/// A mesh being changed by splits, with what the rebuild needs: each element's first parent and
/// refinement depth, each face's cut mark and the face before the change it is a piece of.
#[derive(Clone)]
pub(super) struct MeshEdit {
    pub(super) mesh: PolyhedralMesh,
    pub(super) parent: Vec<u32>,
    pub(super) cut_faces: Vec<bool>,
    /// Per face, the face before the change it is a piece of (`None`: a piece of a section).
    pub(super) first_face: Vec<Option<u32>>,
    pub(super) depth: Vec<u32>,
    /// Per face: whether it is clamped (a piece of a clamped face).
    pub(super) dirichlet_faces: Vec<bool>,
    /// Whether any split changed the mesh.
    pub(super) changed: bool,
}

impl MeshEdit {
    pub(super) fn new(dg: &DgMesh) -> Self {
        Self {
            mesh: dg.mesh.clone(),
            parent: (0..dg.mesh.num_elements as u32).collect(),
            cut_faces: dg.cut_faces.clone(),
            first_face: (0..dg.mesh.faces.len() as u32).map(Some).collect(),
            depth: dg.depth.clone(),
            dirichlet_faces: dg.dirichlet_faces.clone(),
            changed: false,
        }
    }

    /// Takes one split of the current mesh.
    pub(super) fn apply(&mut self, split: MeshSplit) {
        self.changed |= split.split_elements > 0 || split.uncoupled_faces > 0;
        let first_face = &self.first_face;
        self.first_face = split.face_source.iter().map(|s| s.and_then(|f| first_face[f as usize])).collect();
        // On a cut: a boundary piece of the section, a piece of a face already cut, or an
        // interior face the cut ran along (coupled before, boundary now).
        let (cut, mesh) = (&self.cut_faces, &self.mesh);
        self.cut_faces = split
            .face_source
            .iter()
            .zip(&split.mesh.faces)
            .map(|(source, face)| match source {
                None => face.outer.is_none(),
                Some(f) => cut[*f as usize] || (mesh.faces[*f as usize].outer.is_some() && face.outer.is_none()),
            })
            .collect();
        let clamped = &self.dirichlet_faces;
        self.dirichlet_faces = split
            .face_source
            .iter()
            .zip(&split.mesh.faces)
            .map(|(source, face)| face.outer.is_none() && source.is_some_and(|f| clamped[f as usize]))
            .collect();
        self.parent = split.parent.iter().map(|&p| self.parent[p as usize]).collect();
        self.depth = split.parent.iter().map(|&p| self.depth[p as usize]).collect();
        self.mesh = split.mesh;
    }

    /// Merges every element below `fraction` (`DgOptions::sliver_fraction`) of its first parent's volume (`parent_volume`)
    /// into the neighbour across coupled faces it shares the most area with (kaufmann2008 §10:
    /// DG elements need not be convex), the smallest first; a neighbour it also faces across a
    /// cut only when there is no other (the crack's faces between them go: it ends one element
    /// short). The merged element
    /// keeps the largest member's first parent, so it carries that parent's polynomial
    /// (docs/math/dg.md §13.6). Returns (merged, left below the threshold: no neighbour).
    pub(super) fn merge_slivers(&mut self, parent_volume: &[Real], fraction: Real) -> (usize, usize) {
        if fraction.is_nan() || fraction <= 0.0 {
            return (0, 0);
        }
        let n = self.mesh.num_elements;
        let element_faces = self.mesh.element_faces();
        let volumes: Vec<Real> = element_faces
            .iter()
            .map(|faces| {
                let points = faces.iter().flat_map(|f| f.polygon.iter()).map(|&v| self.mesh.vertices[v as usize]);
                let frame = Frame::bounding(points);
                let mut moments = Vec::new();
                element_moments_from_faces(&self.mesh, faces, &frame, 0, &mut moments);
                moments[0]
            })
            .collect();
        let threshold = |e: usize| fraction * parent_volume[self.parent[e] as usize];
        let mut slivers: Vec<usize> = (0..n).filter(|&e| volumes[e] < threshold(e)).collect();
        if slivers.is_empty() {
            return (0, 0);
        }
        slivers.sort_by(|&a, &b| volumes[a].total_cmp(&volumes[b]).then(a.cmp(&b)));
        // Boundary faces by corner set: the two sides of a cut face each other there.
        let mut boundary_by_corners: HashMap<Vec<u32>, Vec<u32>> = HashMap::new();
        for face in self.mesh.faces.iter().filter(|f| f.outer.is_none()) {
            let mut corners = face.polygon.clone();
            corners.sort_unstable();
            boundary_by_corners.entry(corners).or_default().push(face.inner);
        }
        let mut facing_across_cut: Vec<(u32, u32)> = Vec::new();
        for elements in boundary_by_corners.values().filter(|e| e.len() > 1) {
            for (k, &a) in elements.iter().enumerate() {
                for &b in &elements[k + 1..] {
                    facing_across_cut.push((a.min(b), a.max(b)));
                }
            }
        }
        let mut group = UnionFind::new(n);
        let mut group_volume = volumes.clone();
        // A group's threshold is its members' largest (so also that of its largest member's
        // parent, which the merged element answers to): conservative where parents differ.
        let mut group_threshold: Vec<Real> = (0..n).map(threshold).collect();
        let mut group_size = vec![1usize; n];
        let mut merged = 0;
        // A sliver's group grows until it passes its threshold or finds no neighbour.
        let mut pending: std::collections::VecDeque<usize> = slivers.into_iter().collect();
        let mut rounds = 0;
        while let Some(s) = pending.pop_front() {
            let root = group.find(s);
            if group_volume[root] >= group_threshold[root] {
                continue;
            }
            rounds += 1;
            if rounds > 4 * n {
                break;
            }
            // Shared coupled area per neighbouring group, and whether it faces the sliver
            // across a cut too.
            let mut shared: Vec<(usize, Real, bool)> = Vec::new();
            // The faces of every member of its group (a group of slivers looks past itself).
            let members: Vec<usize> =
                if group_size[root] > 1 { (0..n).filter(|&e| group.find(e) == root).collect() } else { vec![s] };
            for (member, face) in members.iter().flat_map(|&m| element_faces[m].iter().map(move |f| (m, f))) {
                let f = &self.mesh.faces[face.face];
                let Some(outer) = f.outer else { continue };
                let other = if f.inner as usize == member { outer } else { f.inner };
                let across_cut = facing_across_cut.contains(&(other.min(member as u32), other.max(member as u32)));
                let other_root = group.find(other as usize);
                if other_root == root {
                    continue;
                }
                let area = polygon_area(face.polygon.iter().map(|&v| self.mesh.vertices[v as usize]));
                match shared.iter_mut().find(|(r, _, _)| *r == other_root) {
                    Some((_, total, cut)) => {
                        *total += area;
                        *cut |= across_cut;
                    }
                    None => shared.push((other_root, area, across_cut)),
                }
            }
            // Across a cut: any element of the group faces any element of the other across one.
            for candidate in &mut shared {
                candidate.2 |= facing_across_cut.iter().any(|&(a, b)| {
                    let (ra, rb) = (group.find(a as usize), group.find(b as usize));
                    (ra == root && rb == candidate.0) || (ra == candidate.0 && rb == root)
                });
            }
            // A neighbour not across a cut first; else one across a cut that ends inside them
            // (the crack then ends one element short: its faces inside the merged element go).
            let best = |across: bool| {
                shared
                    .iter()
                    .filter(|c| c.2 == across)
                    .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
                    .map(|c| c.0)
            };
            let Some(target) = best(false).or_else(|| best(true)) else {
                continue;
            };
            let total = group_volume[root] + group_volume[target];
            let bar = group_threshold[root].max(group_threshold[target]);
            let size = group_size[root] + group_size[target];
            group.union(root, target);
            let joined = group.find(root);
            group_volume[joined] = total;
            group_threshold[joined] = bar;
            group_size[joined] = size;
            merged += 1;
            // Check it again: still below its (maybe raised) threshold, it merges once more.
            pending.push_back(s);
        }
        // Groups still below their threshold: no neighbour to merge into.
        let mut short: Vec<usize> = (0..n).map(|e| group.find(e)).collect();
        short.sort_unstable();
        short.dedup();
        let left = short
            .iter()
            .filter(|&&r| group_volume[r].partial_cmp(&group_threshold[r]).is_none_or(|o| o.is_lt()))
            .count();
        if merged == 0 {
            return (0, left);
        }
        // One element per group, numbered by first member; the largest member speaks for it.
        let mut new_id = vec![u32::MAX; n];
        let mut representative: Vec<usize> = Vec::new();
        let roots: Vec<usize> = (0..n).map(|e| group.find(e)).collect();
        for e in 0..n {
            let r = roots[e];
            if new_id[r] == u32::MAX {
                new_id[r] = representative.len() as u32;
                representative.push(e);
            }
            let id = new_id[r] as usize;
            if volumes[e] > volumes[representative[id]] {
                representative[id] = e;
            }
        }
        let mut faces = Vec::with_capacity(self.mesh.faces.len());
        let (mut first_face, mut cut_faces, mut dirichlet_faces) = (Vec::new(), Vec::new(), Vec::new());
        // Boundary faces facing a face of the same merged element (a crack's two sides inside it).
        let mut inside_crack = vec![false; self.mesh.faces.len()];
        let mut by_corners: HashMap<Vec<u32>, Vec<usize>> = HashMap::new();
        for (f, face) in self.mesh.faces.iter().enumerate().filter(|(_, f)| f.outer.is_none()) {
            let mut corners = face.polygon.clone();
            corners.sort_unstable();
            by_corners.entry(corners).or_default().push(f);
        }
        for faces in by_corners.values().filter(|f| f.len() == 2) {
            let (a, b) = (faces[0], faces[1]);
            if roots[self.mesh.faces[a].inner as usize] == roots[self.mesh.faces[b].inner as usize] {
                inside_crack[a] = true;
                inside_crack[b] = true;
            }
        }
        for (f, face) in self.mesh.faces.iter().enumerate() {
            let inner = new_id[roots[face.inner as usize]];
            let outer = face.outer.map(|o| new_id[roots[o as usize]]);
            if outer == Some(inner) || inside_crack[f] {
                continue;
            }
            faces.push(cleave_geometry::PolyFace { polygon: face.polygon.clone(), inner, outer });
            first_face.push(self.first_face[f]);
            cut_faces.push(self.cut_faces[f]);
            dirichlet_faces.push(self.dirichlet_faces[f]);
        }
        self.parent = representative.iter().map(|&e| self.parent[e]).collect();
        self.depth = representative.iter().map(|&e| self.depth[e]).collect();
        self.mesh = PolyhedralMesh {
            vertices: std::mem::take(&mut self.mesh.vertices),
            faces,
            num_elements: representative.len(),
        };
        self.first_face = first_face;
        self.cut_faces = cut_faces;
        self.dirichlet_faces = dirichlet_faces;
        self.changed = true;
        (merged, left)
    }
}

/// The area of a planar polygon (Newell's area vector about its mean).
fn polygon_area(points: impl Iterator<Item = Point3<Real>>) -> Real {
    let points: Vec<Point3<Real>> = points.collect();
    let mean = points.iter().map(|p| p.coords).sum::<Vector3<Real>>() / points.len().max(1) as Real;
    let twice: Vector3<Real> = (0..points.len())
        .map(|k| (points[k].coords - mean).cross(&(points[(k + 1) % points.len()].coords - mean)))
        .sum();
    twice.norm() / 2.0
}

/// Whether the triangle is degenerate or its smallest height is within `tolerance`.
fn thinner_than(triangle: &[Point3<Real>; 3], tolerance: Real) -> bool {
    let twice_area = (triangle[1] - triangle[0]).cross(&(triangle[2] - triangle[0])).norm();
    let longest = (0..3).map(|k| (triangle[(k + 1) % 3] - triangle[k]).norm()).fold(0.0, Real::max);
    cleave_geometry::predicates::triangle_is_degenerate(triangle) || twice_area <= tolerance * longest
}

impl Cuttable for DgMesh {
    /// Cuts along a plane or a triangle soup (each triangle in turn, `cut_mesh_by_polygon`: the
    /// section uncoupled where the triangle covers it, so a cut may end inside the material);
    /// a body with weak Dirichlet data other than a kept clamp (`DgMesh::clamped`) is refused
    /// (the rebuild would need the data again).
    fn cut(&mut self, surface: &CutSurface) -> Result<TopologyChange, TopologyError> {
        if let CutSurface::Plane { point, normal } = surface {
            let length = normal.norm();
            if !(length.is_finite() && length > 0.0 && point.coords.iter().all(|c| c.is_finite())) {
                return Err(TopologyError::Invalid(format!(
                    "a cutting plane needs a finite point and a non-zero normal, got {point} and {normal}"
                )));
            }
        }
        if let CutSurface::Triangles(triangles) = surface
            && let Some(bad) = triangles.iter().position(|t| t.iter().any(|p| p.coords.iter().any(|c| !c.is_finite())))
        {
            return Err(TopologyError::Invalid(format!(
                "cut triangle {bad} has a non-finite corner: {:?}",
                triangles[bad]
            )));
        }
        if self.has_dirichlet && !self.clamp_kept {
            return Err(TopologyError::Invalid(
                "a DG body with weak Dirichlet data other than a clamp (DgMesh::clamped) cannot be cut: the data is not kept for the rebuild"
                    .into(),
            ));
        }
        let tolerance = self.on_plane_tolerance();
        let fail = |e: MeshSplitError| TopologyError::Invalid(format!("cutting the DG mesh: {e}"));
        let mut edit = MeshEdit::new(self);
        match surface {
            CutSurface::Plane { point, normal } => {
                let split = split_mesh_by_plane(&edit.mesh, &plane_through(point, normal), tolerance).map_err(fail)?;
                edit.apply(split);
            }
            CutSurface::Triangles(triangles) => {
                for triangle in triangles {
                    match cut_mesh_by_polygon(&edit.mesh, triangle, tolerance) {
                        Ok(split) => edit.apply(split),
                        // A triangle without area, or thinner than the tolerance, covers nothing.
                        Err(MeshSplitError::BadPolygon) if thinner_than(triangle, tolerance) => {}
                        Err(e) => return Err(fail(e)),
                    }
                }
            }
        }
        if !edit.changed {
            return Ok(TopologyChange {
                epoch: self.epoch,
                remap: DofRemap::Identity,
                frames: FrameRemap::Identity,
                pattern_changed: false,
            });
        }
        let parent_volume: Vec<Real> = self.bases.iter().map(|b| b.volume).collect();
        let (merged, left) = edit.merge_slivers(&parent_volume, self.options.sliver_fraction);
        let change = self.rebuild(edit, "a cut")?;
        self.last_slivers = (merged, left);
        Ok(change)
    }

    /// `None` before the first cut (a refinement alone keeps the MLS surface); then the boundary
    /// faces (the original surface's pieces and the cuts'), ear-clipped into triangles (a fan
    /// only if clipping fails); a vertex is one per mesh vertex and group of
    /// elements joined around it through coupled faces holding it (so the two sheets of a cut
    /// that ends inside the body share only the vertices along its end), evaluated as the mean
    /// of the group's elements that hold it on their boundary (each element's polynomial at the
    /// point), so every piece's surface is closed.
    fn surface(&self) -> Option<EmbeddedSurface> {
        // Uncut, the input surface (MLS-embedded, §8) still describes the body, finer than the
        // sliced cells' faces.
        if !self.cut_faces.iter().any(|&c| c) {
            return None;
        }
        let (piece_of, _) = self.piece_of_elements();
        let nb = self.exps.len();
        // (vertex, element) incidences, joined through the coupled faces holding the vertex.
        let mut incidence: HashMap<(u32, u32), usize> = HashMap::new();
        let mut joins = Vec::new();
        for face in &self.mesh.faces {
            for &v in &face.polygon {
                let next = incidence.len();
                let a = *incidence.entry((v, face.inner)).or_insert(next);
                if let Some(outer) = face.outer {
                    let next = incidence.len();
                    joins.push((a, *incidence.entry((v, outer)).or_insert(next)));
                }
            }
        }
        let mut group = UnionFind::new(incidence.len());
        for (a, b) in joins {
            group.union(a, b);
        }
        // (mesh vertex, group) ↦ (surface vertex, elements holding it).
        let mut welded: BTreeMap<(u32, usize), (u32, Vec<u32>)> = BTreeMap::new();
        let mut surface = EmbeddedSurface::default();
        for (f, face) in self.mesh.faces.iter().enumerate().filter(|(_, face)| face.outer.is_none()) {
            let element = face.inner;
            let piece = piece_of[element as usize];
            let corners: Vec<u32> = face
                .polygon
                .iter()
                .map(|&v| {
                    let root = group.find(incidence[&(v, element)]);
                    let next = welded.len() as u32;
                    let entry = welded.entry((v, root)).or_insert_with(|| (next, Vec::new()));
                    if !entry.1.contains(&element) {
                        entry.1.push(element);
                    }
                    entry.0
                })
                .collect();
            // Ear clipping: cut faces carry collinear corners (vertices inserted on their edges)
            // and may be non-convex; a fan would make zero-area or overlapping triangles.
            let points: Vec<Point3<Real>> = face.polygon.iter().map(|&v| self.mesh.vertices[v as usize]).collect();
            let triangles = triangulate_planar_polygon(&points)
                .unwrap_or_else(|| (1..points.len() - 1).map(|k| [0, k, k + 1]).collect());
            for [a, b, c] in triangles {
                surface.triangles.push([corners[a], corners[b], corners[c]]);
                surface.on_cut.push(self.cut_faces[f]);
                surface.piece.push(piece as u32);
            }
        }
        let mut ordered: Vec<(u32, u32, &Vec<u32>)> = welded.iter().map(|(&(v, _), (s, e))| (*s, v, e)).collect();
        ordered.sort_unstable_by_key(|&(s, _, _)| s);
        let (mut values, mut gradients) = (vec![0.0; nb], vec![Vector3::zeros(); nb]);
        for (_, v, elements) in ordered {
            let p = self.mesh.vertices[v as usize];
            surface.rest_vertices.push(p);
            let (mut row_nodes, mut row_weights) = (Vec::new(), Vec::new());
            for &e in elements {
                self.evaluate_basis(e as usize, &p, &mut values, &mut gradients);
                for (i, value) in values.iter().enumerate() {
                    row_nodes.push(e * nb as u32 + i as u32);
                    row_weights.push(value / elements.len() as Real);
                }
            }
            surface.embedding.push_row(&row_nodes, &row_weights);
        }
        Some(surface)
    }

    fn pieces(&self) -> Vec<Piece> {
        let (piece_of, count) = self.piece_of_elements();
        let nb = self.exps.len() as u32;
        let mut pieces = vec![Piece::default(); count];
        for (e, &p) in piece_of.iter().enumerate() {
            let piece = &mut pieces[p];
            piece.elements.push(e as u32);
            piece.nodes.extend((0..nb).map(|i| e as u32 * nb + i));
            piece.volume += self.bases[e].volume;
        }
        for piece in &mut pieces {
            piece.mass = self.material.density * piece.volume;
        }
        pieces
    }
}
