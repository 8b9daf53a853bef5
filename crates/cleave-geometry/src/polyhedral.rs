//! Polyhedral meshes: elements bounded by planar polygon faces (convex or not), shared faces
//! between elements stored once. The element data of the DG backend (kaufmann2008 §6, §10).

use nalgebra::{Point3, Vector3};

/// One planar polygon face of a [`PolyhedralMesh`], stored once for the two elements it
/// separates.
///
/// `polygon` lists vertex indices counter-clockwise seen from outside `inner`, i.e. its
/// normal (right-hand rule) points out of `inner` and into `outer`. For `outer`, the face is
/// the same polygon reversed. The polygon may be non-convex but must be simple and planar.
#[derive(Debug, Clone, PartialEq)]
pub struct PolyFace {
    /// Vertex indices into [`PolyhedralMesh::vertices`].
    pub polygon: Vec<u32>,
    /// The element the face normal points out of.
    pub inner: u32,
    /// The element on the other side, or `None` on the boundary of the solid.
    pub outer: Option<u32>,
}

/// A set of polyhedral elements sharing vertices and faces.
///
/// The boundary of element `e` is the union of the faces with `inner == e` (as stored) and
/// the faces with `outer == Some(e)` (reversed); it is closed and outward oriented.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PolyhedralMesh {
    /// Vertex positions.
    pub vertices: Vec<Point3<f64>>,
    /// All faces; interior faces appear once.
    pub faces: Vec<PolyFace>,
    /// Number of elements; element indices are `0..num_elements`.
    pub num_elements: usize,
}

/// A face of one element, oriented outward from that element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElementFace<'a> {
    /// Index of the face in [`PolyhedralMesh::faces`].
    pub face: usize,
    /// The polygon's vertex indices as stored.
    pub polygon: &'a [u32],
    /// Whether the stored polygon must be read backwards to be outward for this element.
    pub reversed: bool,
}

impl PolyhedralMesh {
    /// The boundary faces (those without an outer element) fanned into triangles over the
    /// vertices, oriented as the faces are (outward).
    pub fn boundary_triangles(&self) -> Vec<[u32; 3]> {
        let mut triangles = Vec::new();
        for face in self.faces.iter().filter(|f| f.outer.is_none()) {
            for k in 1..face.polygon.len().saturating_sub(1) {
                triangles.push([face.polygon[0], face.polygon[k], face.polygon[k + 1]]);
            }
        }
        triangles
    }

    /// Area of a planar polygon of this mesh's vertices (Newell's formula about its first vertex,
    /// so small faces far from the origin keep their precision).
    pub fn polygon_area(&self, polygon: &[u32]) -> f64 {
        let p = |k: usize| self.vertices[polygon[k] as usize] - self.vertices[polygon[0] as usize];
        let twice: Vector3<f64> = (1..polygon.len().saturating_sub(1)).map(|k| p(k).cross(&p(k + 1))).sum();
        twice.norm() / 2.0
    }

    /// The box `[origin, origin + h·dims]` cut into `dims[0]·dims[1]·dims[2]` cubes of edge
    /// `h`; element `(i, j, k)` has index `i + dims[0]·(j + dims[1]·k)`.
    pub fn grid(origin: Point3<f64>, h: f64, dims: [usize; 3]) -> Self {
        let [nx, ny, nz] = dims;
        let vid = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
        let eid = |i: usize, j: usize, k: usize| (i + nx * (j + ny * k)) as u32;
        let mut vertices = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    vertices.push(origin + h * Vector3::new(i as f64, j as f64, k as f64));
                }
            }
        }
        let mut faces = Vec::new();
        // Faces normal to x at i (between cells i−1 and i), counter-clockwise seen from −x
        // side's outside, i.e. normal +x: (j,k) → (j+1,k) → (j+1,k+1) → (j,k+1) in the y–z plane.
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..=nx {
                    let polygon = vec![vid(i, j, k), vid(i, j + 1, k), vid(i, j + 1, k + 1), vid(i, j, k + 1)];
                    faces.push(oriented_face(polygon, i, nx, |c| eid(c, j, k)));
                }
            }
        }
        for k in 0..nz {
            for j in 0..=ny {
                for i in 0..nx {
                    // normal +y: z–x plane order
                    let polygon = vec![vid(i, j, k), vid(i, j, k + 1), vid(i + 1, j, k + 1), vid(i + 1, j, k)];
                    faces.push(oriented_face(polygon, j, ny, |c| eid(i, c, k)));
                }
            }
        }
        for k in 0..=nz {
            for j in 0..ny {
                for i in 0..nx {
                    // normal +z: x–y plane order
                    let polygon = vec![vid(i, j, k), vid(i + 1, j, k), vid(i + 1, j + 1, k), vid(i, j + 1, k)];
                    faces.push(oriented_face(polygon, k, nz, |c| eid(i, j, c)));
                }
            }
        }
        Self { vertices, faces, num_elements: nx * ny * nz }
    }

    /// The faces of one element, outward for it (a scan over all faces; for every element at
    /// once use [`PolyhedralMesh::element_faces`]).
    pub fn faces_of(&self, element: usize) -> Vec<ElementFace<'_>> {
        let e = element as u64;
        let mut out = Vec::new();
        for (f, face) in self.faces.iter().enumerate() {
            if u64::from(face.inner) == e {
                out.push(ElementFace { face: f, polygon: &face.polygon, reversed: false });
            }
            if face.outer.map(u64::from) == Some(e) {
                out.push(ElementFace { face: f, polygon: &face.polygon, reversed: true });
            }
        }
        out
    }

    /// The faces of every element, outward for that element: `result[e]` lists element `e`'s
    /// faces.
    pub fn element_faces(&self) -> Vec<Vec<ElementFace<'_>>> {
        let mut out: Vec<Vec<ElementFace<'_>>> = vec![Vec::new(); self.num_elements];
        for (f, face) in self.faces.iter().enumerate() {
            if let Some(list) = out.get_mut(face.inner as usize) {
                list.push(ElementFace { face: f, polygon: &face.polygon, reversed: false });
            }
            if let Some(list) = face.outer.and_then(|o| out.get_mut(o as usize)) {
                list.push(ElementFace { face: f, polygon: &face.polygon, reversed: true });
            }
        }
        out
    }
}

/// A face with normal `+axis` at grid plane `plane` (of `0..=n`): the cell below (`plane − 1`)
/// is inner; on the lower boundary the cell above is inner and the polygon is reversed.
fn oriented_face(mut polygon: Vec<u32>, plane: usize, n: usize, cell: impl Fn(usize) -> u32) -> PolyFace {
    if plane == 0 {
        polygon.reverse();
        PolyFace { polygon, inner: cell(0), outer: None }
    } else if plane == n {
        PolyFace { polygon, inner: cell(n - 1), outer: None }
    } else {
        PolyFace { polygon, inner: cell(plane - 1), outer: Some(cell(plane)) }
    }
}

#[cfg(test)]
mod boundary_tests {
    use super::*;

    #[test]
    fn the_boundary_of_a_polyhedral_grid_is_closed_outward_and_encloses_it() {
        let grid = PolyhedralMesh::grid(Point3::new(-1.0, 0.5, 2.0), 0.25, [3, 2, 1]);
        let surface = crate::TriangleMesh::new(grid.vertices.clone(), grid.boundary_triangles());
        // 2·(3·2 + 3·1 + 2·1) = 22 boundary quads, two triangles each.
        assert_eq!(surface.triangles.len(), 44);
        surface.validate_closed().unwrap();
        assert!((surface.signed_volume() - 6.0 * 0.25f64.powi(3)).abs() < 1e-12);
    }
}
