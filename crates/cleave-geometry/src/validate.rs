//! Closedness, manifoldness and orientation checks for [`TriangleMesh`], with [`MeshStats`].

use crate::{GeometryError, TriangleMesh};

/// Summary of a mesh that passed [`TriangleMesh::validate_closed`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshStats {
    /// Number of vertices referenced by at least one triangle.
    pub vertices: usize,
    /// Number of triangles.
    pub triangles: usize,
    /// Number of undirected edges.
    pub edges: usize,
    /// Enclosed volume (positive).
    pub volume: f64,
    /// Surface area.
    pub area: f64,
    /// Number of connected components (triangles sharing a vertex are connected).
    pub components: usize,
}

/// A triangle counts as degenerate when `area <= DEGENERATE_RATIO * longest_edge²`, i.e.
/// its height over the longest edge is below `2 * DEGENERATE_RATIO` times that edge.
pub const DEGENERATE_RATIO: f64 = 1e-12;

impl TriangleMesh {
    /// Checks that the mesh is a closed, edge-manifold, consistently and outward oriented
    /// surface, and returns its statistics.
    ///
    /// Checks run in this order, each reporting its lowest-index offender:
    /// 1. at least one triangle ([`GeometryError::NoTriangles`]);
    /// 2. finite vertex coordinates ([`GeometryError::NonFiniteVertex`]);
    /// 3. indices in range ([`GeometryError::IndexOutOfRange`]);
    /// 4. no repeated index and non-zero area ([`GeometryError::DegenerateTriangle`], see
    ///    [`DEGENERATE_RATIO`]);
    /// 5. every undirected edge used by exactly two triangles, traversed in opposite
    ///    directions ([`GeometryError::OpenEdge`], [`GeometryError::NonManifoldEdge`],
    ///    [`GeometryError::InconsistentOrientation`]); the reported edge is the first bad one
    ///    met walking the triangles in order and, within a triangle, its edges
    ///    `(v0, v1), (v1, v2), (v2, v0)`;
    /// 6. positive total signed volume ([`GeometryError::InwardOrientation`]). Only the
    ///    total is checked, so correctly inward-facing cavity surfaces are accepted.
    ///
    /// Vertices where several sheets touch (non-manifold vertices) are not detected.
    pub fn validate_closed(&self) -> Result<MeshStats, GeometryError> {
        if self.triangles.is_empty() {
            return Err(GeometryError::NoTriangles);
        }
        if let Some((vertex, p)) = self.vertices.iter().enumerate().find(|(_, p)| !p.iter().all(|x| x.is_finite())) {
            return Err(GeometryError::NonFiniteVertex { vertex, position: [p.x, p.y, p.z] });
        }
        let n = self.vertices.len();
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&index) = tri.iter().find(|&&i| i as usize >= n) {
                return Err(GeometryError::IndexOutOfRange { triangle: t, vertices: *tri, index, vertex_count: n });
            }
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            let [a, b, c] = tri.map(|i| self.vertices[i as usize]);
            let area = 0.5 * (b - a).cross(&(c - a)).norm();
            let longest2 = (b - a).norm_squared().max((c - b).norm_squared()).max((a - c).norm_squared());
            let repeated = tri[0] == tri[1] || tri[1] == tri[2] || tri[2] == tri[0];
            if repeated || area <= DEGENERATE_RATIO * longest2 {
                return Err(GeometryError::DegenerateTriangle {
                    triangle: t,
                    vertices: *tri,
                    area: if repeated { 0.0 } else { area },
                });
            }
        }

        let edges = self.check_edges()?;

        let volume = self.signed_volume();
        if volume.is_nan() || volume <= 0.0 {
            return Err(GeometryError::InwardOrientation { volume });
        }

        // Connected components by union-find over vertices.
        let mut sets = crate::UnionFind::new(n);
        let mut referenced = vec![false; n];
        for tri in &self.triangles {
            for &i in tri {
                referenced[i as usize] = true;
            }
            sets.union(tri[0] as usize, tri[1] as usize);
            sets.union(tri[1] as usize, tri[2] as usize);
        }
        let vertices = referenced.iter().filter(|&&r| r).count();
        let components = (0..n).filter(|&i| referenced[i] && sets.find(i) == i).count();

        Ok(MeshStats { vertices, triangles: self.triangles.len(), edges, volume, area: self.area(), components })
    }

    /// Edge checks (indices already known to be in range, triangles non-degenerate).
    /// Returns the number of undirected edges.
    fn check_edges(&self) -> Result<usize, GeometryError> {
        // (min vertex, max vertex, triangle, corner); corner c is the edge tri[c] -> tri[c+1].
        let mut half_edges: Vec<(u32, u32, u32, u8)> = Vec::with_capacity(3 * self.triangles.len());
        for (t, tri) in self.triangles.iter().enumerate() {
            for c in 0..3u8 {
                let (a, b) = (tri[c as usize], tri[(c as usize + 1) % 3]);
                half_edges.push((a.min(b), a.max(b), t as u32, c));
            }
        }
        half_edges.sort_unstable();
        let directed = |t: u32, c: u8| {
            let tri = self.triangles[t as usize];
            (tri[c as usize], tri[(c as usize + 1) % 3])
        };

        let mut edge_count = 0;
        // Bad edge met first in (triangle, corner) order.
        let mut worst: Option<((u32, u8), GeometryError)> = None;
        for group in half_edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
            edge_count += 1;
            let (lo, hi, t0, c0) = group[0];
            let error = match group.len() {
                1 => {
                    let (a, b) = directed(t0, c0);
                    Some(GeometryError::OpenEdge { a, b, triangle: t0 as usize })
                }
                2 => {
                    let (t1, c1) = (group[1].2, group[1].3);
                    let (a, b) = directed(t0, c0);
                    (directed(t1, c1) == (a, b)).then_some(GeometryError::InconsistentOrientation {
                        a,
                        b,
                        triangles: (t0 as usize, t1 as usize),
                    })
                }
                count => Some(GeometryError::NonManifoldEdge { a: lo, b: hi, count, triangle: t0 as usize }),
            };
            if let Some(error) = error
                && worst.as_ref().is_none_or(|(pos, _)| (t0, c0) < *pos)
            {
                worst = Some(((t0, c0), error));
            }
        }
        match worst {
            Some((_, error)) => Err(error),
            None => Ok(edge_count),
        }
    }
}
