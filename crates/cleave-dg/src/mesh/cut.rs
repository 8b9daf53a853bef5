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
    MeshSplit, MeshSplitError, PolyhedralMesh, UnionFind, cut_mesh_by_polygon, split_mesh_by_plane,
    triangulate_planar_polygon,
};
use std::collections::{BTreeMap, HashMap};

/// Distance under which a vertex counts as on a cutting plane, relative to the mesh's size: far
/// below any element, far above the rounding that moves a vertex exactly on the plane off it
/// (docs/math/polygon-split.md, "Tolerance").
const ON_PLANE: Real = 1e-12;

impl DgMesh {
    /// Per element, its piece (components joined through coupled faces), and the piece count.
    fn piece_of_elements(&self) -> (Vec<usize>, usize) {
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
    /// a body with weak Dirichlet data is refused (the rebuild would need the data again).
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
        if self.has_dirichlet {
            return Err(TopologyError::Invalid(
                "a DG body with weak Dirichlet data (pins) cannot be cut yet: the data is not kept for the rebuild"
                    .into(),
            ));
        }
        let (mut lo, mut hi) = (Point3::from([Real::MAX; 3]), Point3::from([Real::MIN; 3]));
        for p in &self.mesh.vertices {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let tolerance = ON_PLANE * (hi - lo).norm();
        let fail = |e: MeshSplitError| TopologyError::Invalid(format!("cutting the DG mesh: {e}"));
        // The mesh after each triangle, with each element's first parent and each face's cut mark.
        let mut mesh = self.mesh.clone();
        let mut parent: Vec<u32> = (0..mesh.num_elements as u32).collect();
        let mut cut_faces = self.cut_faces.clone();
        // Per face, the face before the cut it is a piece of (`None`: a piece of a section).
        let mut first_face: Vec<Option<u32>> = (0..mesh.faces.len() as u32).map(Some).collect();
        let mut changed = false;
        let mut apply = |split: MeshSplit, mesh: &mut PolyhedralMesh, parent: &mut Vec<u32>, cut: &mut Vec<bool>| {
            changed |= split.split_elements > 0 || split.uncoupled_faces > 0;
            first_face = split.face_source.iter().map(|s| s.and_then(|f| first_face[f as usize])).collect();
            // On a cut: a boundary piece of the section, a piece of a face already cut, or an
            // interior face the cut ran along (coupled before, boundary now).
            *cut = split
                .face_source
                .iter()
                .zip(&split.mesh.faces)
                .map(|(source, face)| match source {
                    None => face.outer.is_none(),
                    Some(f) => cut[*f as usize] || (mesh.faces[*f as usize].outer.is_some() && face.outer.is_none()),
                })
                .collect();
            *parent = split.parent.iter().map(|&p| parent[p as usize]).collect();
            *mesh = split.mesh;
        };
        match surface {
            CutSurface::Plane { point, normal } => {
                let n = normal / normal.norm();
                let helper = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
                let u = n.cross(&helper).normalize();
                // (u) × (n × u) = n: the plane's right-hand normal is n.
                let plane = [*point, point + u, point + n.cross(&u)];
                let split = split_mesh_by_plane(&mesh, &plane, tolerance).map_err(fail)?;
                apply(split, &mut mesh, &mut parent, &mut cut_faces);
            }
            CutSurface::Triangles(triangles) => {
                for triangle in triangles {
                    match cut_mesh_by_polygon(&mesh, triangle, tolerance) {
                        Ok(split) => apply(split, &mut mesh, &mut parent, &mut cut_faces),
                        // A triangle without area, or thinner than the tolerance, covers nothing.
                        Err(MeshSplitError::BadPolygon) if thinner_than(triangle, tolerance) => {}
                        Err(e) => return Err(fail(e)),
                    }
                }
            }
        }
        if !changed {
            return Ok(TopologyChange {
                epoch: self.epoch,
                remap: DofRemap::Identity,
                frames: FrameRemap::Identity,
                pattern_changed: false,
            });
        }
        // The penalty reached before (with its margin) is kept: the jumps already there keep
        // their energy. IP may still double it if a child makes the stiffness indefinite.
        let options = DgOptions { penalty: self.penalty, penalty_margin: 1.0, ..self.options };
        // A piece of a coupled face keeps the face's penalty weight, so its jump keeps its energy.
        let inherited: Vec<Option<Real>> =
            first_face.iter().map(|f| f.map(|f| self.face_weights[f as usize])).collect();
        let mut rebuilt = DgMesh::with_face_weights(mesh, self.material, options, None, Some(&inherited))
            .map_err(|e| TopologyError::Invalid(format!("rebuilding the DG discretization after a cut: {e}")))?;
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
        *self = rebuilt;
        Ok(TopologyChange {
            epoch: self.epoch,
            remap: DofRemap::Linear(rows),
            frames: FrameRemap::Gather(parent),
            pattern_changed: true,
        })
    }

    /// `None` before the first cut; then the boundary faces (the original surface's pieces and
    /// the cuts'), ear-clipped into
    /// triangles (a fan only if clipping fails); a vertex is one per mesh vertex and group of
    /// elements joined around it through coupled faces holding it (so the two sheets of a cut
    /// that ends inside the body share only the vertices along its end), evaluated as the mean
    /// of the group's elements that hold it on their boundary (each element's polynomial at the
    /// point), so every piece's surface is closed.
    fn surface(&self) -> Option<EmbeddedSurface> {
        // Uncut, the input surface (MLS-embedded, §8) still describes the body, finer than the
        // sliced cells' faces.
        if self.epoch == 0 {
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
