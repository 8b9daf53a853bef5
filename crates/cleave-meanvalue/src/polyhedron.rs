//! A convex polyhedron with planar convex polygonal faces: validation (a bad element is named by
//! what is wrong with it), plane normals, volume and centroid, and splitting by a plane into the
//! two convex parts (cut nodes on the crossed edges).

use nalgebra::{Point3, Vector3};
use thiserror::Error;

/// Real type of the crate.
pub type Real = f64;

/// Relative tolerance of the validation's planarity and convexity tests, in units of the
/// element's diameter.
pub const GEOMETRY_TOLERANCE: Real = 1e-9;

/// What makes a polyhedron unusable as a mean value element.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum PolyhedronError {
    /// Fewer than 4 vertices or 4 faces.
    #[error("a polyhedron needs at least 4 vertices and 4 faces, got {vertices} and {faces}")]
    TooSmall {
        /// Vertices given.
        vertices: usize,
        /// Faces given.
        faces: usize,
    },
    /// A face with fewer than 3 vertices or an index out of range.
    #[error("face {face} is not a polygon over the {vertices} vertices: {indices:?}")]
    BadFace {
        /// The face.
        face: usize,
        /// Its vertex indices.
        indices: Vec<usize>,
        /// Vertices of the polyhedron.
        vertices: usize,
    },
    /// A face whose vertices do not lie in one plane.
    #[error("face {face} is not planar: vertex {vertex} lies {distance:.3e} m off its plane")]
    NotPlanar {
        /// The face.
        face: usize,
        /// The vertex off its plane.
        vertex: usize,
        /// Its distance from the plane [m].
        distance: Real,
    },
    /// A vertex of the element outside a face's plane (the element is not convex, or the face's
    /// normal points inwards: inverted).
    #[error("not convex or inverted: vertex {vertex} lies {distance:.3e} m outside the plane of face {face}")]
    NotConvex {
        /// The face.
        face: usize,
        /// The vertex outside its plane.
        vertex: usize,
        /// How far outside [m].
        distance: Real,
    },
    /// A face polygon that turns the wrong way or folds at a vertex.
    #[error("face {face} is not a convex polygon counter-clockwise from outside (at vertex {vertex})")]
    FaceNotConvex {
        /// The face.
        face: usize,
        /// The vertex where it turns the wrong way.
        vertex: usize,
    },
    /// No volume.
    #[error("the polyhedron has no volume ({volume:.3e} m³)")]
    Degenerate {
        /// Its volume [m³].
        volume: Real,
    },
    /// An edge that is not shared by exactly two faces in opposite directions.
    #[error("edge ({0}, {1}) is not shared by exactly two faces in opposite directions")]
    NotClosed(usize, usize),
}

/// A convex polyhedron: vertices and faces, each face a polygon of vertex indices counter-
/// clockwise seen from outside. A face may hold vertices on the straight line between two others
/// (a neighbour's node inserted into it, which keeps the mesh conforming).
#[derive(Clone, Debug, PartialEq)]
pub struct ConvexPolyhedron {
    vertices: Vec<Point3<Real>>,
    faces: Vec<Vec<usize>>,
    normals: Vec<Vector3<Real>>,
    diameter: Real,
    /// The largest distance of a vertex from its face's plane (round-off of cut points).
    planarity: Real,
}

/// Newell's normal of a polygon (length twice its area).
fn newell(points: impl Iterator<Item = Point3<Real>> + Clone) -> Vector3<Real> {
    let next = points.clone().cycle().skip(1);
    points.zip(next).fold(Vector3::zeros(), |n, (a, b)| n + a.coords.cross(&b.coords))
}

impl ConvexPolyhedron {
    /// Validates and builds the element.
    pub fn new(vertices: Vec<Point3<Real>>, faces: Vec<Vec<usize>>) -> Result<Self, PolyhedronError> {
        Self::with_position_tolerance(vertices, faces, 0.0)
    }

    /// [`ConvexPolyhedron::new`] for vertices known only to `position` (a cut takes a node within
    /// its on-plane tolerance as on the plane): a face's plane is then uncertain by `position`
    /// over its width (twice its area over its longest edge), and the convexity test allows a
    /// vertex that much farther out, in proportion to its distance (a thin face's plane tilts).
    pub fn with_position_tolerance(
        vertices: Vec<Point3<Real>>,
        faces: Vec<Vec<usize>>,
        position: Real,
    ) -> Result<Self, PolyhedronError> {
        if vertices.len() < 4 || faces.len() < 4 {
            return Err(PolyhedronError::TooSmall { vertices: vertices.len(), faces: faces.len() });
        }
        for (f, face) in faces.iter().enumerate() {
            if face.len() < 3 || face.iter().any(|&v| v >= vertices.len()) {
                return Err(PolyhedronError::BadFace { face: f, indices: face.clone(), vertices: vertices.len() });
            }
        }
        let mut diameter: Real = 0.0;
        for a in &vertices {
            for b in &vertices {
                diameter = diameter.max((a - b).norm());
            }
        }
        let tolerance = GEOMETRY_TOLERANCE * diameter;
        let mut normals = Vec::with_capacity(faces.len());
        // Per face: how far its plane may tilt (radians) when its vertices are off by `position`.
        let mut tilts: Vec<Real> = Vec::with_capacity(faces.len());
        let mut planarity: Real = 0.0;
        for (f, face) in faces.iter().enumerate() {
            let n = newell(face.iter().map(|&v| vertices[v]));
            let length = n.norm();
            // No area for its size (a small face of sound shape is fine: its normal is as
            // accurate as its vertices are relative to its size).
            let longest = (0..face.len())
                .map(|k| (vertices[face[(k + 1) % face.len()]] - vertices[face[k]]).norm())
                .fold(0.0, Real::max);
            if length <= GEOMETRY_TOLERANCE * longest * longest {
                return Err(PolyhedronError::FaceNotConvex { face: f, vertex: face[0] });
            }
            let n = n / length;
            let origin = vertices[face[0]];
            for &v in face {
                let distance = n.dot(&(vertices[v] - origin));
                planarity = planarity.max(distance.abs());
                if distance.abs() > tolerance + position {
                    return Err(PolyhedronError::NotPlanar { face: f, vertex: v, distance });
                }
            }
            for k in 0..face.len() {
                let (a, b, c) =
                    (vertices[face[k]], vertices[face[(k + 1) % face.len()]], vertices[face[(k + 2) % face.len()]]);
                let turn = n.dot(&(b - a).cross(&(c - b)));
                // Straight (an inserted node) is allowed; a turn to the right is not, beyond a
                // vertex `position` off the line of its neighbours.
                if turn < -(tolerance * diameter + 2.0 * position * (c - a).norm()) {
                    return Err(PolyhedronError::FaceNotConvex { face: f, vertex: face[(k + 1) % face.len()] });
                }
            }
            normals.push(n);
            tilts.push(2.0 * position * longest / length.max(Real::MIN_POSITIVE));
        }
        for (f, face) in faces.iter().enumerate() {
            let origin = vertices[face[0]];
            for (v, p) in vertices.iter().enumerate() {
                let distance = normals[f].dot(&(p - origin));
                if distance > tolerance + position + tilts[f] * (p - origin).norm() {
                    return Err(PolyhedronError::NotConvex { face: f, vertex: v, distance });
                }
            }
        }
        // Each undirected edge once in each direction (a straight run of inserted nodes on one
        // side must be matched by the same nodes on the other): (direction balance, uses).
        let mut edges: std::collections::HashMap<(usize, usize), (i32, usize)> = std::collections::HashMap::new();
        for face in &faces {
            for k in 0..face.len() {
                let (a, b) = (face[k], face[(k + 1) % face.len()]);
                let entry = edges.entry((a.min(b), a.max(b))).or_insert((0, 0));
                entry.0 += if a < b { 1 } else { -1 };
                entry.1 += 1;
            }
        }
        if let Some((&(a, b), _)) = edges.iter().find(|(_, (balance, uses))| *balance != 0 || *uses != 2) {
            return Err(PolyhedronError::NotClosed(a, b));
        }
        let element = Self { vertices, faces, normals, diameter, planarity };
        let volume = element.volume();
        if volume <= GEOMETRY_TOLERANCE * diameter.powi(3) {
            return Err(PolyhedronError::Degenerate { volume });
        }
        Ok(element)
    }

    /// The axis-aligned box `[lo, hi]`.
    pub fn cuboid(lo: Point3<Real>, hi: Point3<Real>) -> Result<Self, PolyhedronError> {
        let corner = |c: usize| {
            Point3::new(
                if c & 1 == 0 { lo.x } else { hi.x },
                if c & 2 == 0 { lo.y } else { hi.y },
                if c & 4 == 0 { lo.z } else { hi.z },
            )
        };
        let faces = vec![
            vec![0, 2, 3, 1], // z = lo
            vec![4, 5, 7, 6], // z = hi
            vec![0, 1, 5, 4], // y = lo
            vec![2, 6, 7, 3], // y = hi
            vec![0, 4, 6, 2], // x = lo
            vec![1, 3, 7, 5], // x = hi
        ];
        Self::new((0..8).map(corner).collect(), faces)
    }

    /// The tetrahedron `(a, b, c, d)` (either orientation).
    pub fn tetrahedron(points: [Point3<Real>; 4]) -> Result<Self, PolyhedronError> {
        let [a, b, c, d] = points;
        let positive = (b - a).cross(&(c - a)).dot(&(d - a)) > 0.0;
        let faces = if positive {
            vec![vec![0, 2, 1], vec![0, 1, 3], vec![1, 2, 3], vec![0, 3, 2]]
        } else {
            vec![vec![0, 1, 2], vec![0, 3, 1], vec![1, 3, 2], vec![0, 2, 3]]
        };
        Self::new(points.to_vec(), faces)
    }

    /// The vertices (the element's nodes, in local order).
    pub fn vertices(&self) -> &[Point3<Real>] {
        &self.vertices
    }

    /// The faces, counter-clockwise from outside.
    pub fn faces(&self) -> &[Vec<usize>] {
        &self.faces
    }

    /// Outward unit normal of each face.
    pub fn normals(&self) -> &[Vector3<Real>] {
        &self.normals
    }

    /// The largest distance between two vertices.
    pub fn diameter(&self) -> Real {
        self.diameter
    }

    /// The largest distance of a vertex from the plane of a face it belongs to (the plane through
    /// the face's first vertex): zero up to the round-off of computed cut points.
    pub fn planarity_defect(&self) -> Real {
        self.planarity
    }

    /// The vertex average.
    pub fn vertex_average(&self) -> Point3<Real> {
        Point3::from(self.vertices.iter().map(|p| p.coords).sum::<Vector3<Real>>() / self.vertices.len() as Real)
    }

    /// Signed distance of `x` inside face `f`'s plane (positive inside the element).
    pub fn depth(&self, f: usize, x: &Point3<Real>) -> Real {
        self.normals[f].dot(&(self.vertices[self.faces[f][0]] - x))
    }

    /// The volume, by the divergence theorem over the faces fanned from their first vertex.
    pub fn volume(&self) -> Real {
        let o = self.vertex_average();
        self.faces
            .iter()
            .map(|face| {
                let a = self.vertices[face[0]] - o;
                (1..face.len() - 1)
                    .map(|k| a.dot(&(self.vertices[face[k]] - o).cross(&(self.vertices[face[k + 1]] - o))))
                    .sum::<Real>()
            })
            .sum::<Real>()
            / 6.0
    }

    /// The two parts on either side of the plane `{x : n·x = offset}`: `(below, above)` where
    /// below is `n·x < offset`. Vertices within `snap · diameter` of the plane are taken as on it
    /// (no sliver of that thickness is created); a part is `None` when the plane does not cross.
    /// The new vertices on crossed edges come after the old ones, in both parts with the same
    /// positions, so the cut face is shared.
    pub fn split(&self, n: &Vector3<Real>, offset: Real, snap: Real) -> (Option<Self>, Option<Self>) {
        let tolerance = snap * self.diameter;
        let side: Vec<Real> = self.vertices.iter().map(|p| n.dot(&p.coords) - offset).collect();
        let class: Vec<i8> = side
            .iter()
            .map(|&s| {
                if s < -tolerance {
                    -1
                } else if s > tolerance {
                    1
                } else {
                    0
                }
            })
            .collect();
        if class.iter().all(|&c| c >= 0) {
            return (None, Some(self.clone()));
        }
        if class.iter().all(|&c| c <= 0) {
            return (Some(self.clone()), None);
        }
        // Cut points on crossed edges, keyed by the edge.
        let mut points = self.vertices.clone();
        let mut cut_of: std::collections::HashMap<(usize, usize), usize> = std::collections::HashMap::new();
        for face in &self.faces {
            for k in 0..face.len() {
                let (a, b) = (face[k], face[(k + 1) % face.len()]);
                if class[a] * class[b] < 0 {
                    let key = (a.min(b), a.max(b));
                    cut_of.entry(key).or_insert_with(|| {
                        let t = side[a] / (side[a] - side[b]);
                        points.push(self.vertices[a] + (self.vertices[b] - self.vertices[a]) * t);
                        points.len() - 1
                    });
                }
            }
        }
        let part = |keep: i8| -> Option<Self> {
            let mut faces: Vec<Vec<usize>> = Vec::new();
            // Directed edges of the cut polygon: each clipped face contributes the segment
            // between its exit and entry points on the plane.
            let mut cap_edges: Vec<(usize, usize)> = Vec::new();
            for face in &self.faces {
                let mut clipped = Vec::new();
                for k in 0..face.len() {
                    let (a, b) = (face[k], face[(k + 1) % face.len()]);
                    if class[a] == keep || class[a] == 0 {
                        clipped.push(a);
                    }
                    if class[a] * class[b] < 0 {
                        clipped.push(cut_of[&(a.min(b), a.max(b))]);
                    }
                }
                if clipped.len() < 3 || !clipped.iter().any(|&v| v < class.len() && class[v] == keep) {
                    continue;
                }
                // The points of this face on the plane, in face order: the cap gets the reverse.
                let on: Vec<usize> = clipped.iter().copied().filter(|&v| v >= class.len() || class[v] == 0).collect();
                if on.len() >= 2 {
                    let m = clipped.len();
                    for k in 0..m {
                        let (a, b) = (clipped[k], clipped[(k + 1) % m]);
                        let a_on = a >= class.len() || class[a] == 0;
                        let b_on = b >= class.len() || class[b] == 0;
                        if a_on && b_on {
                            cap_edges.push((b, a));
                        }
                    }
                }
                faces.push(clipped);
            }
            // Chain the cap's directed edges into a polygon.
            if cap_edges.len() >= 3 {
                let mut cap = vec![cap_edges[0].0];
                let mut current = cap_edges[0].1;
                while current != cap[0] && cap.len() <= cap_edges.len() {
                    cap.push(current);
                    current = cap_edges.iter().find(|e| e.0 == current)?.1;
                }
                faces.push(cap);
            }
            // Renumber the used points.
            let mut used: Vec<usize> = faces.iter().flatten().copied().collect();
            used.sort_unstable();
            used.dedup();
            let index = |v: usize| used.binary_search(&v).expect("a used point");
            let faces = faces.into_iter().map(|f| f.into_iter().map(index).collect()).collect();
            Self::new(used.iter().map(|&v| points[v]).collect(), faces).ok()
        };
        (part(-1), part(1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cube_split_by_an_oblique_plane_keeps_its_volume_and_both_parts_are_valid() {
        let cube = ConvexPolyhedron::cuboid(Point3::origin(), Point3::new(1.0, 1.0, 1.0)).unwrap();
        assert!((cube.volume() - 1.0).abs() < 1e-15);
        let n = Vector3::new(1.0, 1.0, 1.0) / 3f64.sqrt();
        // x + y + z = 2.4 cuts off a corner whose volume is (3 − 2.4)³/6.
        let (below, above) = cube.split(&n, 2.4 / 3f64.sqrt(), 1e-12);
        let (below, above) = (below.unwrap(), above.unwrap());
        assert!((above.volume() - 0.6f64.powi(3) / 6.0).abs() < 1e-14, "{}", above.volume());
        assert!((below.volume() + above.volume() - 1.0).abs() < 1e-14);
        assert_eq!(above.vertices().len(), 4, "a corner tetrahedron");
        assert_eq!(below.vertices().len(), 10, "three pentagons, three squares, one triangle");
        assert_eq!(below.faces().len(), 7);
        // A plane through vertices only: nothing new, both halves prisms.
        let n = Vector3::new(1.0, -1.0, 0.0) / 2f64.sqrt();
        let (a, b) = cube.split(&n, 0.0, 1e-12);
        assert_eq!((a.unwrap().vertices().len(), b.unwrap().vertices().len()), (6, 6));
    }

    #[test]
    fn validation_names_what_is_wrong() {
        let p = |x: Real, y: Real, z: Real| Point3::new(x, y, z);
        let square = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(1.0, 1.0, 0.0), p(0.0, 1.0, 0.0)];
        // A pyramid with its base listed clockwise from outside: inverted.
        let mut points = square.to_vec();
        points.push(p(0.5, 0.5, 1.0));
        let inverted = vec![vec![0, 1, 2, 3], vec![0, 1, 4], vec![1, 2, 4], vec![2, 3, 4], vec![3, 0, 4]];
        assert!(matches!(
            ConvexPolyhedron::new(points.clone(), inverted),
            Err(PolyhedronError::NotConvex { .. } | PolyhedronError::NotClosed(..))
        ));
        let good = vec![vec![0, 3, 2, 1], vec![0, 1, 4], vec![1, 2, 4], vec![2, 3, 4], vec![3, 0, 4]];
        assert!(ConvexPolyhedron::new(points.clone(), good.clone()).is_ok());
        // The apex pushed below the base plane's far side: a base vertex lifted out of plane.
        let mut bent = points.clone();
        bent[2].z = 0.1;
        assert!(matches!(ConvexPolyhedron::new(bent, good.clone()), Err(PolyhedronError::NotPlanar { face: 0, .. })));
        // A dent: the apex inside the base makes the side faces non-convex.
        let mut dented = points;
        dented[4].z = -0.5;
        assert!(ConvexPolyhedron::new(dented, good).is_err());
    }
}
