//! A polyhedral element, convex or not, split by a plane into its connected children on each
//! side, closed by the section's cap faces, sides exact: the element step of cutting DG's
//! general polyhedra (kaufmann2008 §8; docs/math/polygon-split.md, "The element step").

use crate::UnionFind;
use crate::polygon_split::{SplitCorner, clockwise_turn, newell_normal, split_polygon};
use crate::predicates::{kept_axes, side_of_plane};
use nalgebra::{Point2, Point3, Vector3};
use std::collections::{BTreeMap, HashMap};

/// A corner of a child's face: a vertex of the mesh, or the crossing of the plane with the
/// mesh edge between two vertices (the smaller index first), shared by every face holding it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SplitVertex {
    /// A vertex of the mesh.
    Old(u32),
    /// The crossing on the edge `(a, b)`, `a < b`.
    Crossing(u32, u32),
}

/// Where a child's face comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaceSource {
    /// A piece of (or the whole) face `i` of the element, in the order the faces were given.
    Face(usize),
    /// A piece of the plane's section of the element.
    Cap,
}

/// One face of a child, outward for the child.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChildFace {
    /// Corners, counter-clockwise seen from outside the child.
    pub polygon: Vec<SplitVertex>,
    /// Its origin.
    pub source: FaceSource,
}

/// One connected child of a split element.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ElementChild {
    /// `+1` or `−1`: the side of the plane it lies on (`0`: the element was not split).
    pub side: i8,
    /// Its faces.
    pub faces: Vec<ChildFace>,
}

/// An element split by a plane.
#[derive(Clone, Debug, PartialEq)]
pub struct ElementSplit {
    /// The children; one (the element, `side` of its corners or 0) when the plane does not
    /// cross its interior.
    pub children: Vec<ElementChild>,
    /// The crossings the children use, with their positions (interpolated from the two
    /// vertices' float distances to the plane, the smaller index first, so that every element
    /// holding the edge places it at the same point).
    pub crossings: BTreeMap<(u32, u32), Point3<f64>>,
}

/// Why an element could not be split.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ElementSplitError {
    /// A face could not be split.
    #[error("face {face}: {source}")]
    Face {
        /// the face's index in the list given
        face: usize,
        /// why
        source: crate::PolygonSplitError,
    },
    /// A face names a vertex the mesh does not have.
    #[error("face {face} names vertex {vertex}, but there are {vertices}")]
    VertexOutOfRange {
        /// the face's index
        face: usize,
        /// the vertex
        vertex: u32,
        /// vertices given
        vertices: usize,
    },
    /// The section's edges do not close into loops (the element is not closed).
    #[error("the section of the element does not close into loops: is the element closed?")]
    OpenSection,
    /// The section has a hole (a loop inside another): a face with a hole is not built yet.
    #[error("the section of the element has a hole, which a face cannot hold yet")]
    SectionWithHole,
}

/// Splits the closed element bounded by `faces` (outward polygons over `vertices`) by the plane
/// through `plane` (its right-hand normal points to side `+1`), vertices within `tolerance` (a
/// distance) of it counting as on it ([`side_of_plane`](crate::predicates::side_of_plane)).
///
/// Each face is split by [`split_polygon`]; a face lying in the plane goes to the side its
/// element lies on. On each side, the faces' edges along the plane that no other face of that
/// side holds the other way round bound the section: reversed and chained into loops (at a
/// corner with several ways on, the first clockwise), they are the side's cap faces. Each side's
/// faces joined through shared edges are one child.
pub fn split_element(
    vertices: &[Point3<f64>],
    faces: &[Vec<u32>],
    plane: &[Point3<f64>; 3],
    tolerance: f64,
) -> Result<ElementSplit, ElementSplitError> {
    for (face, polygon) in faces.iter().enumerate() {
        if let Some(&vertex) = polygon.iter().find(|&&v| v as usize >= vertices.len()) {
            return Err(ElementSplitError::VertexOutOfRange { face, vertex, vertices: vertices.len() });
        }
    }
    let [a, b, c] = plane;
    let sides: HashMap<u32, i8> =
        faces.iter().flatten().map(|&v| (v, side_of_plane(plane, &vertices[v as usize], tolerance))).collect();
    let (plus, minus) = (sides.values().any(|&s| s > 0), sides.values().any(|&s| s < 0));
    if !(plus && minus) {
        let side = if plus {
            1
        } else if minus {
            -1
        } else {
            0
        };
        let faces = faces
            .iter()
            .enumerate()
            .map(|(i, f)| ChildFace {
                polygon: f.iter().map(|&v| SplitVertex::Old(v)).collect(),
                source: FaceSource::Face(i),
            })
            .collect();
        return Ok(ElementSplit { children: vec![ElementChild { side, faces }], crossings: BTreeMap::new() });
    }
    let plane_normal = (b - a).cross(&(c - a));
    let distance = |v: u32| plane_normal.dot(&(vertices[v as usize] - a));
    let mut crossings = BTreeMap::new();
    // Per side (index 0: −1, 1: +1): its faces.
    let mut by_side: [Vec<ChildFace>; 2] = [Vec::new(), Vec::new()];
    for (i, polygon) in faces.iter().enumerate() {
        let points: Vec<Point3<f64>> = polygon.iter().map(|&v| vertices[v as usize]).collect();
        let split =
            split_polygon(&points, plane, tolerance).map_err(|source| ElementSplitError::Face { face: i, source })?;
        let corner = |k: usize| match split.corners[k].0 {
            SplitCorner::Vertex(j) => SplitVertex::Old(polygon[j]),
            SplitCorner::Crossing(j) => {
                let (p, q) = (polygon[j], polygon[(j + 1) % polygon.len()]);
                SplitVertex::Crossing(p.min(q), p.max(q))
            }
        };
        for piece in &split.pieces {
            let corners: Vec<SplitVertex> = piece.corners.iter().map(|&k| corner(k)).collect();
            for v in &corners {
                if let &SplitVertex::Crossing(p, q) = v {
                    crossings.entry((p, q)).or_insert_with(|| {
                        let (dp, dq) = (distance(p), distance(q));
                        let t = if dp != dq { (dp / (dp - dq)).clamp(0.0, 1.0) } else { 0.5 };
                        vertices[p as usize] + t * (vertices[q as usize] - vertices[p as usize])
                    });
                }
            }
            // A face in the plane goes to the side its element lies on: against its normal.
            let side = if piece.side != 0 {
                piece.side
            } else {
                if newell_normal(&points).dot(&plane_normal) > 0.0 { -1 } else { 1 }
            };
            by_side[usize::from(side > 0)].push(ChildFace { polygon: corners, source: FaceSource::Face(i) });
        }
    }
    let position = |v: &SplitVertex| match *v {
        SplitVertex::Old(i) => vertices[i as usize],
        SplitVertex::Crossing(p, q) => crossings[&(p, q)],
    };
    let on_plane = |v: &SplitVertex| match *v {
        SplitVertex::Old(i) => sides[&i] == 0,
        SplitVertex::Crossing(..) => true,
    };
    let mut children = Vec::new();
    for (index, side_faces) in by_side.iter_mut().enumerate() {
        let side: i8 = if index == 1 { 1 } else { -1 };
        // Directed edges held by this side's faces; the unmatched ones along the plane bound
        // its cap.
        let mut held: HashMap<(SplitVertex, SplitVertex), usize> = HashMap::new();
        for face in side_faces.iter() {
            for k in 0..face.polygon.len() {
                let edge = (face.polygon[k], face.polygon[(k + 1) % face.polygon.len()]);
                *held.entry(edge).or_default() += 1;
            }
        }
        let mut cap_edges: BTreeMap<SplitVertex, Vec<SplitVertex>> = BTreeMap::new();
        for (&(u, v), &count) in &held {
            let back = held.get(&(v, u)).copied().unwrap_or(0);
            if count > back && on_plane(&u) && on_plane(&v) {
                for _ in 0..count - back {
                    cap_edges.entry(v).or_default().push(u);
                }
            }
        }
        // The cap's outward normal points to the other side.
        let cap_normal = -f64::from(side) * plane_normal;
        for cap in chain_loops(&mut cap_edges, &position, &cap_normal)? {
            side_faces.push(ChildFace { polygon: cap, source: FaceSource::Cap });
        }
        // Children: faces joined through shared edges.
        let mut joined = UnionFind::new(side_faces.len());
        let mut first_holder: HashMap<(SplitVertex, SplitVertex), usize> = HashMap::new();
        for (f, face) in side_faces.iter().enumerate() {
            for k in 0..face.polygon.len() {
                let (u, v) = (face.polygon[k], face.polygon[(k + 1) % face.polygon.len()]);
                let key = (u.min(v), u.max(v));
                match first_holder.get(&key) {
                    Some(&g) => {
                        joined.union(f, g);
                    }
                    None => {
                        first_holder.insert(key, f);
                    }
                }
            }
        }
        let mut child_of: HashMap<usize, usize> = HashMap::new();
        let first_child = children.len();
        for (f, face) in std::mem::take(side_faces).into_iter().enumerate() {
            let root = joined.find(f);
            let child = *child_of.entry(root).or_insert_with(|| {
                children.push(ElementChild { side, faces: Vec::new() });
                children.len() - 1 - first_child
            });
            children[first_child + child].faces.push(face);
        }
    }
    Ok(ElementSplit { children, crossings })
}

/// Chains the cap's directed edges (`from → [to]`) into loops, counter-clockwise about
/// `normal`; at a corner with several ways on, the first turning clockwise from the way back.
/// A loop turning the other way is a hole: refused for now.
fn chain_loops(
    edges: &mut BTreeMap<SplitVertex, Vec<SplitVertex>>,
    position: &dyn Fn(&SplitVertex) -> Point3<f64>,
    normal: &Vector3<f64>,
) -> Result<Vec<Vec<SplitVertex>>, ElementSplitError> {
    let axis = normal.iamax();
    let (u, v) = kept_axes(axis);
    let flip = if normal[axis] < 0.0 { -1.0 } else { 1.0 };
    let flat = |p: &SplitVertex| {
        let q = position(p);
        Point2::new(q[u], flip * q[v])
    };
    let total: usize = edges.values().map(Vec::len).sum();
    let mut loops = Vec::new();
    while let Some((&start, _)) = edges.iter().find(|(_, to)| !to.is_empty()) {
        let mut cycle = vec![start];
        let mut from = start;
        let mut at = edges.get_mut(&start).and_then(Vec::pop).ok_or(ElementSplitError::OpenSection)?;
        while at != start {
            if cycle.len() > total {
                return Err(ElementSplitError::OpenSection);
            }
            cycle.push(at);
            let ways = edges.get_mut(&at).filter(|w| !w.is_empty()).ok_or(ElementSplitError::OpenSection)?;
            let (here, back) = (flat(&at), flat(&from));
            let turn = |w: &SplitVertex| clockwise_turn(&here, &back, &flat(w));
            let pick =
                (0..ways.len()).min_by(|&i, &j| turn(&ways[i]).total_cmp(&turn(&ways[j]))).expect("ways is not empty");
            let next = ways.swap_remove(pick);
            from = at;
            at = next;
        }
        let points: Vec<Point3<f64>> = cycle.iter().map(position).collect();
        if newell_normal(&points).dot(normal) < 0.0 {
            return Err(ElementSplitError::SectionWithHole);
        }
        loops.push(cycle);
    }
    Ok(loops)
}
