//! A polyhedral mesh cut through by a plane: every element it crosses split into its children
//! (`split_element`), the crossings shared between neighbours through their edges, the section
//! uncoupled (each side's cap a boundary face), and each new element's parent: the mesh step of
//! cutting DG's general polyhedra (kaufmann2008 §8; docs/math/polygon-split.md).

use crate::element_split::{ElementSplitError, FaceSource, SplitVertex, split_element};
use crate::polyhedral::{PolyFace, PolyhedralMesh};
use crate::predicates::side_of_plane;
use nalgebra::Point3;
use std::collections::{BTreeMap, HashMap};

/// A mesh cut by a plane.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshSplit {
    /// The cut mesh: the old vertices first (same indices), then the crossings.
    pub mesh: PolyhedralMesh,
    /// Per new element, the old element it lies in.
    pub parent: Vec<u32>,
    /// Per new face, the old face it is (a piece of), `None` for a piece of the cut.
    pub face_source: Vec<Option<u32>>,
    /// Old elements split into more than one child.
    pub split_elements: usize,
    /// Old interior faces lying in the plane, uncoupled by the cut.
    pub uncoupled_faces: usize,
}

/// Why a mesh could not be cut.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MeshSplitError {
    /// An element could not be split.
    #[error("element {element}: {source}")]
    Element {
        /// the old element
        element: usize,
        /// why
        source: ElementSplitError,
    },
    /// A piece of an interior face found no twin in the element across (the two elements split
    /// it differently: a mesh that is not conforming there).
    #[error("a piece of interior face {face} has no twin across it: is the mesh conforming there?")]
    UnmatchedFace {
        /// the old face
        face: u32,
    },
}

/// Splits every element of `mesh` that the plane through `plane` crosses, vertices within
/// `tolerance` of it counting as on it. The cut's faces are boundary faces of both sides (the
/// two sides are no longer coupled there); an interior face lying in the plane is uncoupled the
/// same way. Faces the plane does not cross keep their polygons; faces it crosses are split the
/// same way from both their elements, so the new mesh is conforming.
pub fn split_mesh_by_plane(
    mesh: &PolyhedralMesh,
    plane: &[Point3<f64>; 3],
    tolerance: f64,
) -> Result<MeshSplit, MeshSplitError> {
    let mut vertices = mesh.vertices.clone();
    let mut crossing_ids: BTreeMap<(u32, u32), u32> = BTreeMap::new();
    let mut parent = Vec::new();
    // Per new element, its outward faces: (polygon over new vertex ids, old face or None).
    let mut element_faces: Vec<Vec<(Vec<u32>, Option<u32>)>> = Vec::new();
    let mut split_elements = 0;
    for (e, faces) in mesh.element_faces().into_iter().enumerate() {
        let outward: Vec<Vec<u32>> = faces
            .iter()
            .map(|f| if f.reversed { f.polygon.iter().rev().copied().collect() } else { f.polygon.to_vec() })
            .collect();
        let split = split_element(&mesh.vertices, &outward, plane, tolerance)
            .map_err(|source| MeshSplitError::Element { element: e, source })?;
        if split.children.len() > 1 {
            split_elements += 1;
        }
        for child in split.children {
            let polygons = child
                .faces
                .iter()
                .map(|face| {
                    let polygon = face
                        .polygon
                        .iter()
                        .map(|v| match *v {
                            SplitVertex::Old(i) => i,
                            SplitVertex::Crossing(a, b) => *crossing_ids.entry((a, b)).or_insert_with(|| {
                                vertices.push(split.crossings[&(a, b)]);
                                (vertices.len() - 1) as u32
                            }),
                        })
                        .collect();
                    let source = match face.source {
                        FaceSource::Face(i) => Some(faces[i].face as u32),
                        FaceSource::Cap => None,
                    };
                    (polygon, source)
                })
                .collect();
            parent.push(e as u32);
            element_faces.push(polygons);
        }
    }
    // An old interior face in the plane is cut along: both its sides become boundary.
    let in_plane: Vec<bool> = mesh
        .faces
        .iter()
        .map(|f| {
            f.outer.is_some()
                && f.polygon.iter().all(|&v| side_of_plane(plane, &mesh.vertices[v as usize], tolerance) == 0)
        })
        .collect();
    // Faces: a piece of an old interior face not in the plane meets its twin from the element
    // across (the same corners the other way round); everything else is boundary.
    let mut faces: Vec<PolyFace> = Vec::new();
    let mut face_source = Vec::new();
    // Keyed by the old face and the corner set; the twin must be the same cycle reversed.
    let mut waiting: HashMap<(u32, Vec<u32>), usize> = HashMap::new();
    for (element, polygons) in element_faces.into_iter().enumerate() {
        for (polygon, source) in polygons {
            let coupled = source.is_some_and(|f| mesh.faces[f as usize].outer.is_some() && !in_plane[f as usize]);
            if let (true, Some(f)) = (coupled, source) {
                let mut corners = polygon.clone();
                corners.sort_unstable();
                if let Some(index) = waiting.remove(&(f, corners.clone())) {
                    if !is_reversed_cycle(&faces[index].polygon, &polygon) {
                        return Err(MeshSplitError::UnmatchedFace { face: f });
                    }
                    faces[index].outer = Some(element as u32);
                    continue;
                }
                waiting.insert((f, corners), faces.len());
            }
            faces.push(PolyFace { polygon, inner: element as u32, outer: None });
            face_source.push(source);
        }
    }
    if let Some(&index) = waiting.values().min() {
        return Err(MeshSplitError::UnmatchedFace { face: face_source[index].unwrap_or(u32::MAX) });
    }
    let uncoupled_faces = in_plane.iter().filter(|&&p| p).count();
    let num_elements = parent.len();
    Ok(MeshSplit {
        mesh: PolyhedralMesh { vertices, faces, num_elements },
        parent,
        face_source,
        split_elements,
        uncoupled_faces,
    })
}

/// Whether `b` is the cycle `a` walked the other way round (from any corner).
fn is_reversed_cycle(a: &[u32], b: &[u32]) -> bool {
    let n = a.len();
    n == b.len()
        && b.first()
            .and_then(|first| a.iter().position(|v| v == first))
            .is_some_and(|start| (0..n).all(|k| b[k] == a[(start + n - k) % n]))
}
