//! Cutting a DG body by a plane (kaufmann2008 §8; docs/math/dg.md §13): the polyhedral mesh
//! split by `cleave_geometry::split_mesh_by_plane`, the discretization rebuilt on it with the
//! penalty kept, each child's coefficients its parent's polynomial restricted exactly
//! (`basis::restriction`), the pieces the components joined through coupled faces, and a render
//! surface made of the boundary faces, welded per piece.

use super::DgMesh;
use crate::basis::restriction;
use crate::mesh::DgOptions;
use cleave_core::{
    CutSurface, Cuttable, DofRemap, EmbeddedSurface, Embedding, FrameRemap, Piece, Point3, Real, TopologyChange,
    TopologyError, Vector3,
};
use cleave_geometry::{UnionFind, split_mesh_by_plane};
use std::collections::BTreeMap;

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

impl Cuttable for DgMesh {
    /// Cuts along a plane; triangle soups (and so blades) are refused for now (issue 38's next
    /// step), as is a body with weak Dirichlet data, which the rebuild would need again.
    fn cut(&mut self, surface: &CutSurface) -> Result<TopologyChange, TopologyError> {
        let CutSurface::Plane { point, normal } = surface else {
            return Err(TopologyError::Invalid(
                "the DG backend cuts planes only so far; triangle soups and blades are not built yet".into(),
            ));
        };
        let length = normal.norm();
        if !(length.is_finite() && length > 0.0 && point.coords.iter().all(|c| c.is_finite())) {
            return Err(TopologyError::Invalid(format!(
                "a cutting plane needs a finite point and a non-zero normal, got {point} and {normal}"
            )));
        }
        if self.has_dirichlet {
            return Err(TopologyError::Invalid(
                "a DG body with weak Dirichlet data (pins) cannot be cut yet: the data is not kept for the rebuild"
                    .into(),
            ));
        }
        let n = normal / length;
        let helper = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
        let u = n.cross(&helper).normalize();
        // (u) × (n × u) = n: the plane's right-hand normal is n.
        let plane = [*point, point + u, point + n.cross(&u)];
        let (mut lo, mut hi) = (Point3::from([Real::MAX; 3]), Point3::from([Real::MIN; 3]));
        for p in &self.mesh.vertices {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let tolerance = ON_PLANE * (hi - lo).norm();
        let split = split_mesh_by_plane(&self.mesh, &plane, tolerance)
            .map_err(|e| TopologyError::Invalid(format!("cutting the DG mesh: {e}")))?;
        if split.split_elements == 0 && split.uncoupled_faces == 0 {
            return Ok(TopologyChange {
                epoch: self.epoch,
                remap: DofRemap::Identity,
                frames: FrameRemap::Identity,
                pattern_changed: false,
            });
        }
        // On a cut: a piece of the section, a piece of a face already cut, or an interior face
        // the plane ran along (coupled before, boundary now).
        let cut_faces: Vec<bool> = split
            .face_source
            .iter()
            .zip(&split.mesh.faces)
            .map(|(source, face)| {
                source.is_none_or(|f| {
                    self.cut_faces[f as usize] || (self.mesh.faces[f as usize].outer.is_some() && face.outer.is_none())
                })
            })
            .collect();
        // The penalty reached before (with its margin) is kept: the jumps already there keep
        // their energy. IP may still double it if a child makes the stiffness indefinite.
        let options = DgOptions { penalty: self.penalty, penalty_margin: 1.0, ..self.options };
        let mut rebuilt = DgMesh::new(split.mesh, self.material, options, None)
            .map_err(|e| TopologyError::Invalid(format!("rebuilding the DG discretization after a cut: {e}")))?;
        let nb = self.exps.len();
        let mut rows = Embedding::new();
        let mut nodes = vec![0u32; nb];
        for (child, &parent) in split.parent.iter().enumerate() {
            let (p, c) = (parent as usize, child);
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
            frames: FrameRemap::Gather(split.parent),
            pattern_changed: true,
        })
    }

    /// The boundary faces (the original surface's pieces and the cuts'), fanned into triangles;
    /// a vertex is one per mesh vertex and piece, evaluated as the mean of the piece's elements
    /// that hold it on their boundary (each element's polynomial at the point), so every piece's
    /// surface is closed. Fans are exact for convex faces; a cut's face through a non-convex
    /// element may be non-convex, and its fan then overlaps itself (the signed area and the
    /// enclosed volume stay right).
    fn surface(&self) -> Option<EmbeddedSurface> {
        let (piece_of, _) = self.piece_of_elements();
        let nb = self.exps.len();
        // (mesh vertex, piece) ↦ (surface vertex, elements holding it).
        let mut welded: BTreeMap<(u32, usize), (u32, Vec<u32>)> = BTreeMap::new();
        let mut surface = EmbeddedSurface::default();
        for (f, face) in self.mesh.faces.iter().enumerate().filter(|(_, face)| face.outer.is_none()) {
            let element = face.inner;
            let piece = piece_of[element as usize];
            let corners: Vec<u32> = face
                .polygon
                .iter()
                .map(|&v| {
                    let next = welded.len() as u32;
                    let entry = welded.entry((v, piece)).or_insert_with(|| (next, Vec::new()));
                    if !entry.1.contains(&element) {
                        entry.1.push(element);
                    }
                    entry.0
                })
                .collect();
            for k in 1..corners.len().saturating_sub(1) {
                surface.triangles.push([corners[0], corners[k], corners[k + 1]]);
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
