//! A polyhedral mesh cut by a plane, or by a bounded convex polygon in it: every element whose
//! section meets the cut split into its children (`split_element`), the crossings shared
//! between neighbours through their edges, the section uncoupled where the polygon covers it and
//! coupled where it does not (so a cut may end inside an element and material stays joined
//! around its end), and each new element's parent: the mesh step of cutting DG's general
//! polyhedra (kaufmann2008 §8; docs/math/polygon-split.md, "The mesh step").

use crate::element_split::{ElementSplitError, FaceSource, SplitVertex, split_element};
use crate::polygon_split::{newell_normal, split_polygon};
use crate::polyhedral::{PolyFace, PolyhedralMesh};
use crate::predicates::side_of_plane;
use nalgebra::{Point3, Vector3};
use std::collections::HashMap;

/// A mesh cut by a plane or a polygon.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshSplit {
    /// The cut mesh: the old vertices first (same indices), then the new ones.
    pub mesh: PolyhedralMesh,
    /// Per new element, the old element it lies in.
    pub parent: Vec<u32>,
    /// Per new face, the old face it is (a piece of), `None` for a piece of the section.
    pub face_source: Vec<Option<u32>>,
    /// Old elements split into more than one child.
    pub split_elements: usize,
    /// Old interior faces lying in the plane that the cut uncoupled (wholly or in part).
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
        /// the old face (`u32::MAX`: a piece of an element's section)
        face: u32,
    },
    /// The cutting polygon is degenerate, not planar, not convex, or not finite.
    #[error("the cutting polygon must be finite, planar, convex and enclose an area")]
    BadPolygon,
    /// A piece of the section or of a face could not be split by the polygon's sides.
    #[error("splitting a face by the cutting polygon's sides: {0}")]
    Cover(crate::PolygonSplitError),
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
    cut_mesh(mesh, plane, None, None, tolerance)
}

/// Splits element `element` of `mesh` by the plane through `plane` into children joined through
/// their section (a coupled face): refinement (kaufmann2008 §10; docs/math/dg.md §14). The faces
/// the plane crosses are split as by a cut, their pieces coupled to the neighbour, which keeps
/// its element whole (its face now has more corners: DG elements may be any polyhedron); no face
/// is uncoupled. An element the plane does not cross, or an index past the last element, leaves
/// the mesh as it is (`split_elements` 0).
pub fn split_mesh_element(
    mesh: &PolyhedralMesh,
    element: usize,
    plane: &[Point3<f64>; 3],
    tolerance: f64,
) -> Result<MeshSplit, MeshSplitError> {
    cut_mesh(mesh, plane, None, Some(element), tolerance)
}

/// Cuts `mesh` by the planar convex polygon `polygon` (corners in order, either orientation),
/// vertices within `tolerance` of its plane or of the planes through its sides (normal to it)
/// counting as on them.
///
/// An element is split by the polygon's plane when its section meets the polygon in an area;
/// on the section, the part the polygon covers uncouples the two sides and the rest couples them
/// (the section cut along the polygon's sides): a polygon ending inside an element leaves its
/// children joined around the end. A face the plane crosses between a split element and a
/// whole one is split too (pieces coupled to the whole element), an interior face lying in the
/// plane is uncoupled where the polygon covers it, and every vertex created on an edge is
/// inserted into every face holding that edge, so the new mesh is conforming.
pub fn cut_mesh_by_polygon(
    mesh: &PolyhedralMesh,
    polygon: &[Point3<f64>],
    tolerance: f64,
) -> Result<MeshSplit, MeshSplitError> {
    let cover = Cover::new(polygon, tolerance).ok_or(MeshSplitError::BadPolygon)?;
    let plane = cover.plane;
    cut_mesh(mesh, &plane, Some(&cover), None, tolerance)
}

/// The convex polygon a cut covers: its plane and the planes through its sides, normal to it,
/// each with the side its interior lies on.
struct Cover {
    plane: [Point3<f64>; 3],
    sides: Vec<([Point3<f64>; 3], i8)>,
    lo: Point3<f64>,
    hi: Point3<f64>,
}

impl Cover {
    fn new(polygon: &[Point3<f64>], tolerance: f64) -> Option<Self> {
        if polygon.len() < 3 || polygon.iter().any(|p| p.coords.iter().any(|c| !c.is_finite())) {
            return None;
        }
        let centroid = Point3::from(polygon.iter().map(|p| p.coords).sum::<Vector3<f64>>() / polygon.len() as f64);
        // About the centroid: a thin polygon far from the origin keeps its normal's precision.
        let relative: Vec<Point3<f64>> = polygon.iter().map(|p| Point3::from(p - centroid)).collect();
        let normal = newell_normal(&relative);
        let length = normal.norm();
        if length.is_nan() || length <= 0.0 {
            return None;
        }
        let n = normal / length;
        let diameter = polygon.iter().map(|p| (p - centroid).norm()).fold(0.0, f64::max);
        let plane = if let [a, b, c] = polygon {
            // A triangle is its own plane, exactly.
            [*a, *b, *c]
        } else {
            let helper = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
            let u = n.cross(&helper).normalize() * diameter;
            let plane = [centroid, centroid + u, centroid + n.cross(&u)];
            if polygon.iter().any(|p| side_of_plane(&plane, p, tolerance) != 0) {
                return None;
            }
            plane
        };
        let mut sides = Vec::new();
        for (k, a) in polygon.iter().enumerate() {
            let b = polygon[(k + 1) % polygon.len()];
            if (b - a).norm() <= tolerance {
                continue;
            }
            let side_plane = [*a, b, a + n * diameter];
            // The interior is on the side of the corner farthest from this side: none beyond the
            // tolerance means the polygon is thinner than it (it covers nothing).
            let away = (b - a).cross(&n);
            let farthest =
                polygon.iter().max_by(|p, q| away.dot(&(*p - a)).abs().total_cmp(&away.dot(&(*q - a)).abs()))?;
            let inside = side_of_plane(&side_plane, farthest, tolerance);
            // Convex: no corner beyond a side.
            if inside == 0 || polygon.iter().any(|p| side_of_plane(&side_plane, p, tolerance) == -inside) {
                return None;
            }
            sides.push((side_plane, inside));
        }
        let (mut lo, mut hi) = (polygon[0], polygon[0]);
        for p in polygon {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let margin = Vector3::repeat(tolerance);
        Some(Self { plane, sides, lo: lo - margin, hi: hi + margin })
    }

    /// Whether the box `[lo, hi]` may meet the polygon.
    fn may_meet(&self, lo: &Point3<f64>, hi: &Point3<f64>) -> bool {
        (0..3).all(|i| lo[i] <= self.hi[i] && hi[i] >= self.lo[i])
    }

    /// Whether the cover meets the planar polygon `points` in an area: more than `tolerance`
    /// times its perimeter (a line or a point within the tolerance is not an area).
    fn covers(&self, points: &[Point3<f64>], tolerance: f64) -> Result<bool, MeshSplitError> {
        let perimeter: f64 = (0..points.len()).map(|k| (points[(k + 1) % points.len()] - points[k]).norm()).sum();
        Ok(self.covered_area(points, tolerance)? > tolerance * perimeter)
    }

    /// The area of the planar polygon `points` inside the cover.
    fn covered_area(&self, points: &[Point3<f64>], tolerance: f64) -> Result<f64, MeshSplitError> {
        let mut inside = vec![points.to_vec()];
        for (side_plane, side) in &self.sides {
            let mut next = Vec::new();
            for piece in &inside {
                let split = split_polygon(piece, side_plane, tolerance).map_err(MeshSplitError::Cover)?;
                for p in split.pieces.iter().filter(|p| p.side == *side) {
                    next.push(p.corners.iter().map(|&k| split.corners[k].1).collect());
                }
            }
            inside = next;
        }
        Ok(inside.iter().map(|p| newell_normal(p).norm() / 2.0).sum())
    }
}

/// The vertices a cut creates, each once: crossings of old edges with the plane, and points
/// where the cover's sides cross edges of the section; each is recorded on the segment it
/// splits so that every face holding that segment takes it.
struct NewVertices {
    vertices: Vec<Point3<f64>>,
    /// Segment (smaller id first) ↦ the vertex inside it.
    inside: HashMap<(u32, u32), u32>,
}

impl NewVertices {
    /// The vertex on segment `(a, b)` at `position`, made if the segment has none yet.
    fn on_segment(&mut self, a: u32, b: u32, position: impl FnOnce() -> Point3<f64>) -> u32 {
        *self.inside.entry((a.min(b), a.max(b))).or_insert_with(|| {
            self.vertices.push(position());
            (self.vertices.len() - 1) as u32
        })
    }

    /// `polygon` with every vertex made inside one of its edges inserted, in order.
    fn refine(&self, polygon: &[u32]) -> Vec<u32> {
        if self.inside.is_empty() {
            return polygon.to_vec();
        }
        let mut out = Vec::with_capacity(polygon.len());
        for (k, &a) in polygon.iter().enumerate() {
            out.push(a);
            self.between(a, polygon[(k + 1) % polygon.len()], &mut out);
        }
        out
    }

    fn between(&self, a: u32, b: u32, out: &mut Vec<u32>) {
        // Vertices are made after the segment's ends, so the recursion ends.
        if let Some(&v) = self.inside.get(&(a.min(b), a.max(b))) {
            self.between(a, v, out);
            out.push(v);
            self.between(v, b, out);
        }
    }

    /// Splits the section polygon `polygon` (over vertex ids) by the cover's sides: its pieces,
    /// each with whether the cover covers it. Every piece is split by every side, so a segment
    /// two pieces share is split at one vertex.
    fn split_by_cover(
        &mut self,
        polygon: Vec<u32>,
        cover: &Cover,
        tolerance: f64,
    ) -> Result<Vec<(Vec<u32>, bool)>, MeshSplitError> {
        let mut pieces = vec![(polygon, true)];
        for (side_plane, side) in &cover.sides {
            let mut next = Vec::with_capacity(pieces.len() + 1);
            for (piece, covered) in pieces {
                let points: Vec<Point3<f64>> = piece.iter().map(|&v| self.vertices[v as usize]).collect();
                let split = split_polygon(&points, side_plane, tolerance).map_err(MeshSplitError::Cover)?;
                let ids: Vec<u32> = split
                    .corners
                    .iter()
                    .map(|&(corner, position, _)| match corner {
                        crate::SplitCorner::Vertex(j) => piece[j],
                        crate::SplitCorner::Crossing(j) => {
                            self.on_segment(piece[j], piece[(j + 1) % piece.len()], || position)
                        }
                    })
                    .collect();
                for p in &split.pieces {
                    next.push((p.corners.iter().map(|&k| ids[k]).collect(), covered && p.side == *side));
                }
            }
            pieces = next;
        }
        Ok(pieces)
    }
}

/// Per old element: its new elements, each with its outward faces (polygon over vertex ids,
/// old face or `None` for a cap) and, for a split element, its caps on the `+1` side paired with
/// the child across.
struct Parted {
    /// New element ids of the children, in order.
    first: u32,
    children: Vec<Vec<(Vec<u32>, Option<u32>)>>,
    /// (+ child, − child, cap polygon outward from the + child).
    caps: Vec<(u32, u32, Vec<u32>)>,
}

/// The mesh step of a cut (`refine_only: None`: every element the section of `plane` ∩ `cover`
/// meets is split and the section uncoupled) or of a refinement (`Some(e)`: element `e` alone,
/// its section coupled).
fn cut_mesh(
    mesh: &PolyhedralMesh,
    plane: &[Point3<f64>; 3],
    cover: Option<&Cover>,
    refine_only: Option<usize>,
    tolerance: f64,
) -> Result<MeshSplit, MeshSplitError> {
    if let Some((face, vertex)) = mesh
        .faces
        .iter()
        .enumerate()
        .find_map(|(f, face)| face.polygon.iter().find(|&&v| v as usize >= mesh.vertices.len()).map(|&v| (f, v)))
    {
        let source = ElementSplitError::VertexOutOfRange { face, vertex, vertices: mesh.vertices.len() };
        return Err(MeshSplitError::Element { element: mesh.faces[face].inner as usize, source });
    }
    let mut made = NewVertices { vertices: mesh.vertices.clone(), inside: HashMap::new() };
    let element_faces = mesh.element_faces();
    let mut parted: Vec<Parted> = Vec::with_capacity(mesh.num_elements);
    let mut next_id = 0u32;
    let mut split_elements = 0;
    for (e, faces) in element_faces.iter().enumerate() {
        let outward: Vec<Vec<u32>> = faces
            .iter()
            .map(|f| if f.reversed { f.polygon.iter().rev().copied().collect() } else { f.polygon.to_vec() })
            .collect();
        let whole = |next_id: &mut u32, outward: Vec<Vec<u32>>| {
            let first = *next_id;
            *next_id += 1;
            Parted {
                first,
                children: vec![outward.into_iter().zip(faces).map(|(p, f)| (p, Some(f.face as u32))).collect()],
                caps: Vec::new(),
            }
        };
        if refine_only.is_some_and(|only| only != e) {
            parted.push(whole(&mut next_id, outward));
            continue;
        }
        if let Some(cover) = cover {
            let (mut lo, mut hi) = (Point3::from([f64::MAX; 3]), Point3::from([f64::MIN; 3]));
            for &v in outward.iter().flatten() {
                lo = lo.inf(&mesh.vertices[v as usize]);
                hi = hi.sup(&mesh.vertices[v as usize]);
            }
            if !cover.may_meet(&lo, &hi) {
                parted.push(whole(&mut next_id, outward));
                continue;
            }
        }
        let split = split_element(&mesh.vertices, &outward, plane, tolerance)
            .map_err(|source| MeshSplitError::Element { element: e, source })?;
        if split.children.len() < 2 {
            parted.push(whole(&mut next_id, outward));
            continue;
        }
        let position = |v: &SplitVertex| match *v {
            SplitVertex::Old(i) => mesh.vertices[i as usize],
            SplitVertex::Crossing(a, b) => split.crossings[&(a, b)],
        };
        if let Some(cover) = cover {
            let mut meets = false;
            for child in split.children.iter().filter(|c| c.side > 0) {
                for face in child.faces.iter().filter(|f| f.source == FaceSource::Cap) {
                    let points: Vec<Point3<f64>> = face.polygon.iter().map(position).collect();
                    meets |= cover.covers(&points, tolerance)?;
                }
            }
            if !meets {
                parted.push(whole(&mut next_id, outward));
                continue;
            }
        }
        split_elements += 1;
        let first = next_id;
        let mut children = Vec::with_capacity(split.children.len());
        // − side caps by corner set: (child, polygon).
        let mut minus_caps: HashMap<Vec<u32>, u32> = HashMap::new();
        let mut plus_caps = Vec::new();
        for (c, child) in split.children.iter().enumerate() {
            let id = first + c as u32;
            let mut polygons = Vec::with_capacity(child.faces.len());
            for face in &child.faces {
                let polygon: Vec<u32> = face
                    .polygon
                    .iter()
                    .map(|v| match *v {
                        SplitVertex::Old(i) => i,
                        SplitVertex::Crossing(a, b) => made.on_segment(a, b, || split.crossings[&(a, b)]),
                    })
                    .collect();
                match face.source {
                    FaceSource::Face(i) => polygons.push((polygon, Some(faces[i].face as u32))),
                    FaceSource::Cap if child.side > 0 => plus_caps.push((id, polygon)),
                    FaceSource::Cap => {
                        let mut corners = polygon;
                        corners.sort_unstable();
                        minus_caps.insert(corners, id);
                    }
                }
            }
            children.push(polygons);
        }
        let mut caps = Vec::with_capacity(plus_caps.len());
        for (plus, polygon) in plus_caps {
            let mut corners = polygon.clone();
            corners.sort_unstable();
            let minus = minus_caps.remove(&corners).ok_or(MeshSplitError::UnmatchedFace { face: u32::MAX })?;
            caps.push((plus, minus, polygon));
        }
        if !minus_caps.is_empty() {
            return Err(MeshSplitError::UnmatchedFace { face: u32::MAX });
        }
        next_id += children.len() as u32;
        parted.push(Parted { first, children, caps });
    }

    // A refinement uncouples nothing: a face in the plane stays as it is.
    let in_plane = |f: &PolyFace| {
        refine_only.is_none()
            && f.outer.is_some()
            && f.polygon.iter().all(|&v| side_of_plane(plane, &mesh.vertices[v as usize], tolerance) == 0)
    };
    let mut faces: Vec<PolyFace> = Vec::new();
    let mut face_source: Vec<Option<u32>> = Vec::new();
    let mut uncoupled_faces = 0;
    // Pieces of old faces from each element's side: old face ↦ [(new element, outward polygon)].
    let mut from_inner: HashMap<u32, Vec<(u32, Vec<u32>)>> = HashMap::new();
    let mut from_outer: HashMap<u32, Vec<(u32, Vec<u32>)>> = HashMap::new();
    for (e, part) in parted.iter_mut().enumerate() {
        for (c, child) in part.children.iter_mut().enumerate() {
            for (polygon, source) in child.drain(..) {
                let f = source.expect("children's listed faces come from old faces");
                let side = if mesh.faces[f as usize].inner as usize == e { &mut from_inner } else { &mut from_outer };
                side.entry(f).or_default().push((part.first + c as u32, polygon));
            }
        }
    }
    let mut push = |faces: &mut Vec<PolyFace>, polygon: Vec<u32>, inner: u32, outer: Option<u32>, source| {
        faces.push(PolyFace { polygon, inner, outer });
        face_source.push(source);
    };
    for (f, old) in mesh.faces.iter().enumerate() {
        let f32 = f as u32;
        let inner_pieces = from_inner.remove(&f32).unwrap_or_default();
        if old.outer.is_none() {
            for (element, polygon) in inner_pieces {
                push(&mut faces, polygon, element, None, Some(f32));
            }
            continue;
        }
        let mut outer_pieces = from_outer.remove(&f32).unwrap_or_default();
        if in_plane(old) {
            // Whole on each side (a polygon in the plane is not split by it).
            let (Some((inner_element, polygon)), Some((outer_element, _))) =
                (inner_pieces.first().cloned(), outer_pieces.first())
            else {
                return Err(MeshSplitError::UnmatchedFace { face: f32 });
            };
            let outer_element = *outer_element;
            let pieces = match cover {
                None => vec![(polygon, true)],
                Some(cover) => {
                    let points: Vec<Point3<f64>> = polygon.iter().map(|&v| mesh.vertices[v as usize]).collect();
                    if cover.covers(&points, tolerance)? {
                        made.split_by_cover(polygon, cover, tolerance)?
                    } else {
                        vec![(polygon, false)]
                    }
                }
            };
            if pieces.iter().any(|(_, covered)| *covered) {
                uncoupled_faces += 1;
            }
            for (polygon, covered) in pieces {
                if covered {
                    let reversed = polygon.iter().rev().copied().collect();
                    push(&mut faces, polygon, inner_element, None, Some(f32));
                    push(&mut faces, reversed, outer_element, None, Some(f32));
                } else {
                    push(&mut faces, polygon, inner_element, Some(outer_element), Some(f32));
                }
            }
            continue;
        }
        match (inner_pieces.len(), outer_pieces.len()) {
            (1, 1)
                if outer_pieces[0].1.len() == inner_pieces[0].1.len()
                    && is_reversed_cycle(&inner_pieces[0].1, &outer_pieces[0].1) =>
            {
                let (element, polygon) = inner_pieces.into_iter().next().expect("one piece");
                push(&mut faces, polygon, element, Some(outer_pieces[0].0), Some(f32));
            }
            (1.., 1) if is_reversed_cycle(&old.polygon, &outer_pieces[0].1) => {
                // The outer element holds the whole face; the inner one's pieces couple to it.
                for (element, polygon) in inner_pieces {
                    push(&mut faces, polygon, element, Some(outer_pieces[0].0), Some(f32));
                }
            }
            (1, 1..)
                if is_reversed_cycle(&inner_pieces[0].1, &old.polygon.iter().rev().copied().collect::<Vec<_>>()) =>
            {
                for (element, polygon) in outer_pieces {
                    push(&mut faces, polygon, element, Some(inner_pieces[0].0), Some(f32));
                }
            }
            _ => {
                for (element, polygon) in inner_pieces {
                    let mut corners = polygon.clone();
                    corners.sort_unstable();
                    let twin = outer_pieces.iter().position(|(_, other)| {
                        let mut theirs = other.clone();
                        theirs.sort_unstable();
                        theirs == corners && is_reversed_cycle(&polygon, other)
                    });
                    let Some(twin) = twin else {
                        return Err(MeshSplitError::UnmatchedFace { face: f32 });
                    };
                    let (across, _) = outer_pieces.swap_remove(twin);
                    push(&mut faces, polygon, element, Some(across), Some(f32));
                }
                if !outer_pieces.is_empty() {
                    return Err(MeshSplitError::UnmatchedFace { face: f32 });
                }
            }
        }
    }
    for part in &parted {
        for (plus, minus, polygon) in &part.caps {
            let pieces = match cover {
                None => vec![(polygon.clone(), refine_only.is_none())],
                Some(cover) => made.split_by_cover(polygon.clone(), cover, tolerance)?,
            };
            for (polygon, covered) in pieces {
                if covered {
                    let reversed = polygon.iter().rev().copied().collect();
                    push(&mut faces, polygon, *plus, None, None);
                    push(&mut faces, reversed, *minus, None, None);
                } else {
                    push(&mut faces, polygon, *plus, Some(*minus), None);
                }
            }
        }
    }
    for face in &mut faces {
        face.polygon = made.refine(&face.polygon);
    }
    let parent = parted
        .iter()
        .enumerate()
        .flat_map(|(e, part)| std::iter::repeat_n(e as u32, part.children.len().max(1)))
        .collect::<Vec<u32>>();
    debug_assert_eq!(parent.len(), next_id as usize);
    Ok(MeshSplit {
        mesh: PolyhedralMesh { vertices: made.vertices, faces, num_elements: next_id as usize },
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
