//! Validation of [`PolyhedralMesh`]: indices, finite vertices, non-degenerate planar faces,
//! closed and consistently outward-oriented elements of positive volume, with [`PolyMeshStats`].

use std::collections::HashMap;

use nalgebra::Vector3;

use crate::moments::{Frame, try_element_moments_from_faces};
use crate::{DEGENERATE_RATIO, GeometryError, PolyhedralMesh};

/// Summary of a mesh that passed [`PolyhedralMesh::validate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolyMeshStats {
    /// Number of vertices referenced by at least one face.
    pub vertices: usize,
    /// Number of faces.
    pub faces: usize,
    /// Faces with an `outer` element.
    pub interior_faces: usize,
    /// Faces on the boundary of the solid (`outer == None`).
    pub boundary_faces: usize,
    /// Number of elements.
    pub elements: usize,
    /// Sum of the element volumes.
    pub volume: f64,
    /// Smallest element volume (positive).
    pub min_element_volume: f64,
    /// Largest relative planarity deviation of any face (distance from the Newell plane over
    /// the face diameter), at most the tolerance.
    pub max_planarity_deviation: f64,
}

impl PolyhedralMesh {
    /// Checks the mesh and returns its statistics. Never panics.
    ///
    /// Checks run in this order, each reporting its lowest-index offender:
    /// 1. `planarity_tolerance` is non-negative ([`GeometryError::InvalidTolerance`]);
    /// 2. at least one element ([`GeometryError::NoElements`]);
    /// 3. finite vertex coordinates ([`GeometryError::NonFiniteVertex`]);
    /// 4. per face: vertex indices in range ([`GeometryError::FaceVertexOutOfRange`]), `inner`
    ///    and `outer` below `num_elements` ([`GeometryError::FaceElementOutOfRange`]) and
    ///    different ([`GeometryError::SelfAdjacentFace`]);
    /// 5. per face: at least three vertices, none repeated, and area above
    ///    [`DEGENERATE_RATIO`] times the squared diameter ([`GeometryError::DegenerateFace`]);
    /// 6. per face: every vertex within `planarity_tolerance` face diameters of the Newell
    ///    plane through the vertex mean ([`GeometryError::NonPlanarFace`]);
    /// 7. per element: every directed edge of its outward faces matched by exactly one reverse
    ///    edge and by no other edge in the same direction
    ///    ([`GeometryError::InconsistentElementOrientation`],
    ///    [`GeometryError::OpenElementBoundary`]); the reported edge is the first bad one met
    ///    walking the element's faces in mesh order (see [`PolyhedralMesh::element_faces`]) and
    ///    each outward polygon from its first vertex;
    /// 8. per element: positive volume ([`GeometryError::NonPositiveVolume`]).
    ///
    /// Self-intersecting polygons and intersecting faces are not detected.
    pub fn validate(&self, planarity_tolerance: f64) -> Result<PolyMeshStats, GeometryError> {
        if planarity_tolerance.is_nan() || planarity_tolerance < 0.0 {
            return Err(GeometryError::InvalidTolerance { tolerance: planarity_tolerance });
        }
        if self.num_elements == 0 {
            return Err(GeometryError::NoElements);
        }
        if let Some((vertex, p)) = self.vertices.iter().enumerate().find(|(_, p)| !p.iter().all(|x| x.is_finite())) {
            return Err(GeometryError::NonFiniteVertex { vertex, position: [p.x, p.y, p.z] });
        }
        self.check_face_indices()?;
        let max_planarity_deviation = self.check_face_shapes(planarity_tolerance)?;

        let element_faces = self.element_faces();
        let mut edges: HashMap<(u32, u32), (usize, usize, usize)> = HashMap::new();
        for (element, faces) in element_faces.iter().enumerate() {
            // (count, first face, second face) of each directed edge.
            edges.clear();
            let directed = || {
                faces.iter().flat_map(|f| {
                    let k = f.polygon.len();
                    (0..k).map(move |i| {
                        let (a, b) = (f.polygon[i], f.polygon[(i + 1) % k]);
                        if f.reversed { (b, a, f.face) } else { (a, b, f.face) }
                    })
                })
            };
            for (a, b, face) in directed() {
                let entry = edges.entry((a, b)).or_insert((0, face, face));
                entry.0 += 1;
                if entry.0 == 2 {
                    entry.2 = face;
                }
            }
            for (a, b, face) in directed() {
                let (count, first, second) = edges[&(a, b)];
                if count > 1 {
                    return Err(GeometryError::InconsistentElementOrientation {
                        element,
                        a,
                        b,
                        faces: (first, second),
                    });
                }
                if !edges.contains_key(&(b, a)) {
                    return Err(GeometryError::OpenElementBoundary { element, a, b, face });
                }
            }
        }

        let mut volume = 0.0;
        let mut min_element_volume = f64::INFINITY;
        let mut moments = Vec::with_capacity(1);
        for (element, faces) in element_faces.iter().enumerate() {
            let frame =
                Frame::bounding(faces.iter().flat_map(|f| f.polygon.iter()).map(|&v| self.vertices[v as usize]));
            try_element_moments_from_faces(self, faces, &frame, 0, &mut moments)?;
            let v = moments[0];
            if v.is_nan() || v <= 0.0 {
                return Err(GeometryError::NonPositiveVolume { element, volume: v });
            }
            volume += v;
            min_element_volume = min_element_volume.min(v);
        }

        let mut used = vec![false; self.vertices.len()];
        for f in &self.faces {
            for &v in &f.polygon {
                used[v as usize] = true;
            }
        }
        let interior_faces = self.faces.iter().filter(|f| f.outer.is_some()).count();
        Ok(PolyMeshStats {
            vertices: used.iter().filter(|&&u| u).count(),
            faces: self.faces.len(),
            interior_faces,
            boundary_faces: self.faces.len() - interior_faces,
            elements: self.num_elements,
            volume,
            min_element_volume,
            max_planarity_deviation,
        })
    }

    fn check_face_indices(&self) -> Result<(), GeometryError> {
        let n = self.vertices.len();
        for (face, f) in self.faces.iter().enumerate() {
            if let Some(&index) = f.polygon.iter().find(|&&v| v as usize >= n) {
                return Err(GeometryError::FaceVertexOutOfRange { face, index, vertex_count: n });
            }
            let bad = |e: u32| e as usize >= self.num_elements;
            if let Some(element) = Some(f.inner).filter(|&e| bad(e)).or(f.outer.filter(|&e| bad(e))) {
                return Err(GeometryError::FaceElementOutOfRange { face, element, num_elements: self.num_elements });
            }
            if f.outer == Some(f.inner) {
                return Err(GeometryError::SelfAdjacentFace { face, element: f.inner });
            }
        }
        Ok(())
    }

    /// Degeneracy and planarity of every face; returns the largest planarity deviation.
    fn check_face_shapes(&self, tolerance: f64) -> Result<f64, GeometryError> {
        let mut max_deviation = 0.0f64;
        let mut sorted = Vec::new();
        for (face, f) in self.faces.iter().enumerate() {
            sorted.clear();
            sorted.extend_from_slice(&f.polygon);
            sorted.sort_unstable();
            sorted.dedup();
            let distinct_vertices = sorted.len();
            let degenerate =
                |area: f64| GeometryError::DegenerateFace { face, polygon: f.polygon.clone(), distinct_vertices, area };
            if distinct_vertices < 3 {
                return Err(degenerate(0.0));
            }
            let points: Vec<Vector3<f64>> = f.polygon.iter().map(|&v| self.vertices[v as usize].coords).collect();
            let p0 = points[0];
            let mut newell = Vector3::zeros();
            for i in 1..points.len() - 1 {
                newell += (points[i] - p0).cross(&(points[i + 1] - p0));
            }
            let area = 0.5 * newell.norm();
            let mut diameter2 = 0.0f64;
            for (i, p) in points.iter().enumerate() {
                for q in &points[i + 1..] {
                    diameter2 = diameter2.max((p - q).norm_squared());
                }
            }
            if distinct_vertices < f.polygon.len() || area <= DEGENERATE_RATIO * diameter2 {
                return Err(degenerate(area));
            }
            let n = newell / newell.norm();
            let mean = points.iter().fold(Vector3::zeros(), |s, p| s + (p - p0)) / points.len() as f64 + p0;
            let diameter = diameter2.sqrt();
            let (vertex, deviation) = f
                .polygon
                .iter()
                .zip(&points)
                .map(|(&v, p)| (v, (p - mean).dot(&n).abs() / diameter))
                .fold((f.polygon[0], 0.0f64), |best, cur| if cur.1 > best.1 { cur } else { best });
            if deviation > tolerance {
                return Err(GeometryError::NonPlanarFace { face, vertex, deviation, tolerance });
            }
            max_deviation = max_deviation.max(deviation);
        }
        Ok(max_deviation)
    }
}
