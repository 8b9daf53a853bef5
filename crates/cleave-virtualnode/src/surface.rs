//! The render surface of a virtual node mesh: every cell face covered by the object surface or a
//! cut, triangulated, each vertex embedded (barycentric weights) in the duplicate that owns it.
//!
//! Faces keep the orientation of their cell (outward), so the two sides of a cut get their own,
//! opposite copies. The coplanar faces of one duplicate that together cover one convex polygon
//! (fragments of a cut or surface polygon split by the duplicate's cells) are merged into it. Where a vertex of one face lies on an edge of another face of the same piece
//! (cells split by different planes meet along that edge), it is inserted into that edge, so
//! that welding the vertices of a piece by rest position leaves no T-junction: the surface of
//! every piece is then closed (every directed edge is matched by its reverse).
//!
//! After a cut only the polygons the cut can reach are made again; the others, with their loops,
//! come from the last render (`RenderCache`), and the result is the one made from scratch.

use crate::FastMap;
use crate::mesh::VirtualNodeMesh;
use cleave_core::{Discretization, Embedding, Point3, Real, Vector3};
use cleave_geometry::arrangement::{Arrangement, Cover, Face};
use cleave_geometry::closest_point_on_triangle;
use rayon::prelude::*;

/// Whether a render triangle lies on the original object surface or on a cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SurfaceKind {
    /// A piece of the carved object's surface.
    Original,
    /// A piece of a cut.
    Cut,
}

/// Triangles over embedded vertices.
#[derive(Clone, Debug, Default)]
pub struct RenderSurface {
    /// Rest position of every vertex.
    pub positions: Vec<Point3<Real>>,
    /// One row per vertex: the four nodes of its duplicate and its barycentric weights there.
    pub embedding: Embedding,
    /// Counter-clockwise seen from outside the material.
    pub triangles: Vec<[u32; 3]>,
    /// Original surface or cut, per triangle.
    pub kinds: Vec<SurfaceKind>,
    /// Duplicate (element) owning each triangle.
    pub duplicates: Vec<u32>,
}

/// Relative tolerance (of the lattice spacing) within which a vertex lies on another face's
/// edge.
pub const T_JUNCTION_TOLERANCE: Real = 1e-10;

/// Relative tolerance (of the lattice spacing) below which an edge of a piece's surface is
/// collapsed and a corner nearer its opposite edge is flipped away ([`remove_slivers`]):
/// 1.5e-7 m at 15 mm cells, ten times what an f32 recording of a 0.2 m body resolves.
pub const SLIVER_TOLERANCE: Real = 1e-5;

/// Relative tolerance (of the lattice spacing) within which an open edge of a piece's surface is
/// split at the corners of other open edges after the render ([`remove_slivers`]): the cut
/// faces and the clipped object surface are two computations of the curve where they meet,
/// and near-coplanar source triangles put them up to ~1e-6 m apart at 15 mm cells.
pub const JUNCTION_TOLERANCE: Real = 1e-3;

/// Relative distance (of the lattice spacing) within which two consecutive points of a merged
/// cut or surface polygon are copies of one point made in two cells (`merged_loop`): rounding
/// puts such copies ~1e-9 h apart, far inside the sliver repair's [`SLIVER_TOLERANCE`].
const NEAR_COPY: Real = 1e-8;

/// Weights at or below this do not make a node one of a vertex's own when deciding whether two
/// vertices nearer than the sliver tolerance may be merged (a point computed in two
/// tetrahedra lands up to ~1e-7 outside the face they share).
const SLIVER_WEIGHT: Real = 1e-6;

/// Repairs the slivers of one piece's surface (`cleave_geometry::repair_slivers`): two near
/// vertices are merged only when their nodes of weight above [`SLIVER_WEIGHT`] are the same,
/// the two ends of a short edge when those nodes fit in one tetrahedron (never the two sides
/// of a crack, whose nodes are different copies); the vertices merged away are dropped with
/// their embedding rows.
fn remove_slivers(surface: &mut RenderSurface, tolerance: Real) {
    let own_nodes = |v: u32| {
        let (nodes, weights) = surface.embedding.row(v as usize);
        let mut own = [u32::MAX; 4];
        for (slot, (n, w)) in own.iter_mut().zip(nodes.iter().zip(weights)) {
            if w.abs() > SLIVER_WEIGHT {
                *slot = *n;
            }
        }
        own.sort_unstable();
        own
    };
    // Near vertices are one point when their own nodes agree; the two ends of a triangle's
    // edge lie in one duplicate's polygon, on one side of any crack, so their own nodes need
    // only fit in one tetrahedron.
    let same_point = |u: u32, v: u32, joined: bool| {
        let (a, b) = (own_nodes(u), own_nodes(v));
        if !joined {
            return a == b;
        }
        let mut union: Vec<u32> = a.iter().chain(&b).copied().filter(|&n| n != u32::MAX).collect();
        union.sort_unstable();
        union.dedup();
        union.len() <= 4
    };
    let mut tags: Vec<(SurfaceKind, u32)> =
        surface.kinds.iter().copied().zip(surface.duplicates.iter().copied()).collect();
    let repair = cleave_geometry::repair_slivers(
        &surface.positions,
        &mut surface.triangles,
        &mut tags,
        tolerance,
        JUNCTION_TOLERANCE / SLIVER_TOLERANCE * tolerance,
        same_point,
    );
    if repair == cleave_geometry::SliverRepair::default() {
        return;
    }
    (surface.kinds, surface.duplicates) = tags.into_iter().unzip();
    if repair.collapsed > 0 {
        // Vertices merged away are used by no triangle now: keep the used ones, in order.
        let mut used = vec![false; surface.positions.len()];
        surface.triangles.iter().flatten().for_each(|&v| used[v as usize] = true);
        let mut new_index = vec![u32::MAX; used.len()];
        let (mut positions, mut embedding) = (Vec::with_capacity(used.len()), Embedding::new());
        for v in (0..used.len()).filter(|&v| used[v]) {
            new_index[v] = positions.len() as u32;
            positions.push(surface.positions[v]);
            let (nodes, weights) = surface.embedding.row(v);
            embedding.push_row(nodes, weights);
        }
        for t in &mut surface.triangles {
            *t = t.map(|v| new_index[v as usize]);
        }
        (surface.positions, surface.embedding) = (positions, embedding);
    }
}

/// A point of a polygon's loop: rest position, barycentric weights, and for a whole source
/// triangle the lattice tetrahedron whose (only) duplicate embeds it. Node numbers are not
/// kept: a cut renumbers them, and the welder reads them from the duplicate at each render.
#[derive(Clone, Copy, Debug)]
struct CachedPoint {
    p: Point3<Real>,
    weights: [Real; 4],
    tet: u32,
}

/// A polygon's loop (its corners and the points of other faces on its edges, then its vertex
/// average where no corner can be the fan's apex) and the apex.
type Ring = (Vec<CachedPoint>, Option<usize>);

/// One polygon of the render surface, with its loop once made.
#[derive(Clone, Debug)]
struct Entry {
    kind: SurfaceKind,
    points: Vec<Point3<Real>>,
    ring: Option<Ring>,
}

/// Where a polygon of a piece is kept: a whole source triangle, or face `e` of duplicate `d`.
#[derive(Clone, Copy, Debug)]
enum EntryRef {
    Whole(u32),
    Duplicate(u32, u32),
}

impl EntryRef {
    fn get<'a>(self, entries: &'a [Vec<Entry>], whole: &'a [Option<Entry>]) -> &'a Entry {
        match self {
            EntryRef::Whole(i) => whole[i as usize].as_ref().expect("whole triangles have entries"),
            EntryRef::Duplicate(d, e) => &entries[d as usize][e as usize],
        }
    }
}

/// The last render's polygons and loops, per duplicate and per whole source triangle, for the
/// epoch they were made in. The next render after one cut takes them for every duplicate (and
/// whole triangle) whose lattice tetrahedra share no edge with a tetrahedron the cut changed
/// or with a tetrahedron of a source triangle that such a tetrahedron meets, or with a
/// tetrahedron of a piece that split: a loop depends on its own tetrahedron's cells, on the
/// polygons of the tetrahedra sharing an edge with it and on which of them share its piece.
#[derive(Clone, Debug, Default)]
pub(crate) struct RenderCache {
    epoch: Option<u64>,
    /// Polygons the render that made this cache took from the one before.
    reused: usize,
    piece_of_duplicate: Vec<u32>,
    duplicates: Vec<Vec<Entry>>,
    whole: Vec<Option<Entry>>,
}

/// Covered faces of one duplicate on one plane, side and kind.
type FaceGroup<'a> = ((u32, bool, SurfaceKind), Vec<&'a Face>);

/// Weights below this do not count when deciding whether two embedded vertices at one rest
/// position are the same material point (barycentric rounding on a shared face is ~1e-16).
const ZERO_WEIGHT: Real = 1e-12;

/// Finds the vertex already made for a material point: one on the same nodes (weights above
/// [`ZERO_WEIGHT`]) within `tolerance` of the same rest position. Positions of one point
/// computed in two arrangements (or as a source triangle's corner) differ by rounding, so an
/// exact key alone would leave hairline cracks; the exact key is the fast path.
/// A vertex made by the welder: rest position, its nodes (see [`ZERO_WEIGHT`]), its index.
type WeldedVertex = (Point3<Real>, [u32; 4], u32);

struct Welder {
    tolerance: Real,
    cell: Real,
    exact: FastMap<([u64; 3], [u32; 4]), u32>,
    /// Per grid cell the last vertex made in it; `next` chains each vertex to the one made in
    /// its cell before it (no list per cell: cells are tiny, most hold one vertex).
    grid: FastMap<[i64; 3], u32>,
    vertices: Vec<WeldedVertex>,
    next: Vec<u32>,
}

impl Welder {
    fn new(tolerance: Real) -> Self {
        Self {
            tolerance,
            cell: 1e3 * tolerance,
            exact: FastMap::default(),
            grid: FastMap::default(),
            vertices: Vec::new(),
            next: Vec::new(),
        }
    }

    fn find_or_insert(&mut self, p: Point3<Real>, nodes: [u32; 4], make: impl FnOnce() -> u32) -> u32 {
        let exact_key = ([p.x.to_bits(), p.y.to_bits(), p.z.to_bits()], nodes);
        if let Some(&id) = self.exact.get(&exact_key) {
            return id;
        }
        let key: [i64; 3] = std::array::from_fn(|a| (p[a] / self.cell).floor() as i64);
        // Neighbouring cells only along axes where `p` lies within the tolerance of the border.
        let range: [(i64, i64); 3] = std::array::from_fn(|a| {
            let local = p[a] - key[a] as Real * self.cell;
            (-i64::from(local < self.tolerance), i64::from(local > self.cell - self.tolerance))
        });
        for i in range[0].0..=range[0].1 {
            for j in range[1].0..=range[1].1 {
                for k in range[2].0..=range[2].1 {
                    let mut slot = self.grid.get(&[key[0] + i, key[1] + j, key[2] + k]).copied();
                    while let Some(v) = slot.filter(|&v| v != u32::MAX) {
                        let (q, n, id) = &self.vertices[v as usize];
                        if *n == nodes && (q - p).norm() <= self.tolerance {
                            let id = *id;
                            self.exact.insert(exact_key, id);
                            return id;
                        }
                        slot = Some(self.next[v as usize]);
                    }
                }
            }
        }
        let id = make();
        self.exact.insert(exact_key, id);
        let slot = self.vertices.len() as u32;
        self.next.push(self.grid.insert(key, slot).unwrap_or(u32::MAX));
        self.vertices.push((p, nodes, id));
        id
    }
}

/// The one convex polygon that coplanar, equally oriented `faces` of one arrangement cover
/// together, if they do: edges split where another face's vertex lies on them, interior edges
/// (met once in each direction) cancelled, the rest chained into a single loop, collinear
/// vertices dropped; `tolerance` is the render welder's ([`T_JUNCTION_TOLERANCE`] times the
/// lattice spacing). `None` (draw the faces as they are) for a single face, several loops, a
/// vertex with two ways on, or a loop that is not convex.
///
/// A cut through a tetrahedron that the object surface or earlier cuts had split into cells
/// leaves one fragment of the cut per cell; drawn separately they multiply the triangles that
/// contact searches and the recording writes (merged: 29k instead of 48k triangles at the end
/// of `bunny_slice.ron`).
fn merged_loop(cells: &Arrangement, faces: &[&Face], tolerance: Real) -> Option<Vec<u32>> {
    if faces.len() < 2 {
        return None;
    }
    // Cells split apart make their own copies of a vertex on a shared edge: one id per position
    // (the first in x order of those within the tolerance, the render welder's).
    let mut ids: Vec<u32> = faces.iter().flat_map(|f| f.verts.iter().copied()).collect();
    ids.sort_unstable();
    ids.dedup();
    let mut by_x = ids.clone();
    by_x.sort_by(|&u, &v| cells.point(u).x.total_cmp(&cells.point(v).x));
    let mut canonical: Vec<(u32, u32)> = ids.iter().map(|&v| (v, v)).collect();
    let slot = |v: u32| ids.binary_search(&v).expect("a face vertex");
    for (i, &u) in by_x.iter().enumerate() {
        let pu = cells.point(u);
        for &w in &by_x[i + 1..] {
            let pw = cells.point(w);
            if pw.x - pu.x > tolerance {
                break;
            }
            let (su, sw) = (slot(u), slot(w));
            if canonical[sw].1 == w && (pw - pu).norm() <= tolerance {
                canonical[sw].1 = canonical[su].1;
            }
        }
    }
    let weld = |v: u32| canonical[slot(v)].1;
    let mut edges: Vec<(u32, u32)> = Vec::new();
    for face in faces {
        let n = face.verts.len();
        edges.extend((0..n).map(|i| (weld(face.verts[i]), weld(face.verts[(i + 1) % n]))).filter(|e| e.0 != e.1));
    }
    let chain = match single_loop(&mut edges) {
        Some(chain) => chain,
        None => {
            // Where one fragment's edge passes through another's vertex, split it there and
            // try again.
            let kept: Vec<u32> = ids.iter().copied().filter(|&v| weld(v) == v).collect();
            let mut split = Vec::with_capacity(edges.len());
            let mut on_edge: Vec<(Real, u32)> = Vec::new();
            for &(a, b) in &edges {
                let (pa, pb) = (cells.point(a), cells.point(b));
                let d = pb - pa;
                let len2 = d.norm_squared();
                on_edge.clear();
                for &w in kept.iter().filter(|&&w| w != a && w != b) {
                    let pw = cells.point(w);
                    let t = (pw - pa).dot(&d) / len2;
                    if t > 1e-9 && t < 1.0 - 1e-9 && (pw - (pa + d * t)).norm_squared() <= 1e-20 * len2 {
                        on_edge.push((t, w));
                    }
                }
                on_edge.sort_by(|x, y| x.0.total_cmp(&y.0));
                let mut from = a;
                for &(_, w) in &on_edge {
                    split.push((from, w));
                    from = w;
                }
                split.push((from, b));
            }
            single_loop(&mut split)?
        }
    };
    // Convex, with the normal of the faces (Newell's normal of the loop). A vertex is dropped
    // only where it lies within the welding tolerance of the chord from the last corner kept to
    // the next vertex, and between them: anywhere else a neighbouring polygon's copy of it would
    // be neither welded nor inserted into the merged edge, and the piece's surface would open
    // there. Judged against the last corner kept, not the previous vertex: two copies of one
    // point from two cells (1e-11 m apart, beyond the welding tolerance) each lie on the chord
    // through the other, and judged against each other both were dropped, cutting the corner
    // between them off the polygon (a hole between the cut face and the surface it meets).
    let points: Vec<Point3<Real>> = chain.iter().map(|&v| cells.point(v)).collect();
    let m = points.len();
    // Relative to the first point: a small polygon far from the origin keeps its digits.
    let normal =
        (1..m - 1).fold(Vector3::zeros(), |s, i| s + (points[i] - points[0]).cross(&(points[i + 1] - points[0])));
    // The scan starts at the point farthest from the vertex average, a corner of any convex
    // polygon (a point inside an edge is never farthest, whatever the rounding: the
    // lexicographic least point can be, on an edge along an axis). Copies nearer than
    // `NEAR_COPY` lattice spacings to the corner kept before them are the same point (dropped;
    // the sliver repair joins the neighbours' copies to the one kept), and a corner's turn is
    // taken towards the next point that is not its copy.
    let near = NEAR_COPY / T_JUNCTION_TOLERANCE * tolerance;
    let average = points.iter().fold(Vector3::zeros(), |s, p| s + (p - points[0])) / m as Real;
    let start = (0..m)
        .max_by(|&i, &j| {
            ((points[i] - points[0]) - average)
                .norm_squared()
                .total_cmp(&((points[j] - points[0]) - average).norm_squared())
        })
        .expect("a loop has points");
    let mut corners = Vec::with_capacity(m);
    corners.push(start);
    for step in 1..m {
        let i = (start + step) % m;
        let (a, b) = (points[*corners.last().expect("the start is kept")], points[i]);
        if (b - a).norm() <= near {
            continue;
        }
        // Every point from here to the start a copy of this one: it is a copy of the start.
        let Some(c) = (1..=m - step).map(|k| points[(i + k) % m]).find(|c| (c - b).norm() > near) else {
            continue;
        };
        let (e1, e2, chord) = (b - a, c - b, c - a);
        let turn = e1.cross(&e2);
        let off_chord = turn.norm() / chord.norm().max(Real::MIN_POSITIVE);
        if off_chord <= tolerance && e1.dot(&e2) > 0.0 {
            continue;
        }
        if turn.dot(&normal) <= 1e-9 * e1.norm() * e2.norm() * normal.norm() {
            return None;
        }
        corners.push(i);
    }
    // The start's own turn, between the last corner kept and the first after it.
    while corners.len() > 1 && (points[*corners.last().expect("non-empty")] - points[start]).norm() <= near {
        corners.pop();
    }
    if corners.len() < 3 {
        return None;
    }
    let (a, b, c) = (points[corners[corners.len() - 1]], points[start], points[corners[1]]);
    let (e1, e2) = (b - a, c - b);
    if e1.cross(&e2).dot(&normal) <= 1e-9 * e1.norm() * e2.norm() * normal.norm() {
        return None;
    }
    // In the loop's own order from its first point: the fan (and so the contact surface) does
    // not depend on where the scan started.
    corners.sort_unstable();
    Some(corners.into_iter().map(|i| chain[i]).collect())
}

/// The directed `edges` (sorted in place) without those met once in each direction, if what
/// remains is one closed loop: its vertices in order.
fn single_loop(edges: &mut [(u32, u32)]) -> Option<Vec<u32>> {
    edges.sort_unstable();
    let boundary: Vec<(u32, u32)> =
        edges.iter().copied().filter(|&(a, b)| edges.binary_search(&(b, a)).is_err()).collect();
    if boundary.len() < 3 || boundary.windows(2).any(|w| w[0].0 == w[1].0) {
        return None;
    }
    let next = |v: u32| boundary.binary_search_by_key(&v, |e| e.0).ok().map(|k| boundary[k].1);
    let mut chain = vec![boundary[0].0];
    let mut v = boundary[0].1;
    while v != chain[0] {
        if chain.len() >= boundary.len() {
            return None;
        }
        chain.push(v);
        v = next(v)?;
    }
    (chain.len() == boundary.len()).then_some(chain)
}

/// A uniform grid of points for "which vertices lie near this segment" queries.
struct PointGrid {
    cell: Real,
    buckets: FastMap<[i64; 3], Vec<Point3<Real>>>,
}

impl PointGrid {
    fn key(&self, p: &Point3<Real>) -> [i64; 3] {
        std::array::from_fn(|a| (p[a] / self.cell).floor() as i64)
    }

    /// Points strictly inside segment `(a, b)` within `tolerance` of it, with their parameter.
    fn on_segment(&self, a: &Point3<Real>, b: &Point3<Real>, tolerance: Real, out: &mut Vec<(Real, Point3<Real>)>) {
        out.clear();
        let d = b - a;
        let len2 = d.norm_squared();
        if len2 <= tolerance * tolerance {
            return;
        }
        let lo = self.key(&(a.inf(b) - Vector3::repeat(tolerance)));
        let hi = self.key(&(a.sup(b) + Vector3::repeat(tolerance)));
        // Long edges over many empty cells are rare (a cell is a quarter of the lattice spacing).
        for i in lo[0]..=hi[0] {
            for j in lo[1]..=hi[1] {
                for k in lo[2]..=hi[2] {
                    let Some(points) = self.buckets.get(&[i, j, k]) else { continue };
                    for p in points {
                        let t = (p - a).dot(&d) / len2;
                        let closest = a + d * t;
                        let margin = tolerance / len2.sqrt();
                        if t > margin && t < 1.0 - margin && (p - closest).norm() <= tolerance {
                            out.push((t, *p));
                        }
                    }
                }
            }
        }
        out.sort_by(|x, y| x.0.total_cmp(&y.0));
        out.dedup_by(|x, y| (x.1 - y.1).norm() <= tolerance);
    }
}

impl VirtualNodeMesh {
    /// The render surface: covered cell faces (object surface and both sides of every cut),
    /// coplanar fragments of one duplicate merged (see `merged_loop`), T-junctions resolved
    /// within each piece, each polygon fanned into triangles from a corner whose edges carry no
    /// inserted point, else from its vertex average.
    ///
    /// A triangle of the carved surface no longer than the lattice spacing whose lattice
    /// tetrahedra no cut has touched (each holds one duplicate without cut faces) is drawn whole, each vertex embedded in the tetrahedron
    /// containing it, instead of as its clipped pieces: the field is continuous across those
    /// tetrahedra, and clipping every triangle to every tetrahedron multiplies the triangle
    /// count by 20 on the bunny. Vertices are shared where they are the same material point: the
    /// same rest position on the same nodes (weights above `ZERO_WEIGHT`), so two sides of a
    /// cut never share a vertex and two tetrahedra meeting at a shared face always do.
    ///
    /// After a cut, polygons and loops the cut cannot have changed are taken from the last
    /// render (see `RenderCache` in the source); the result is the same as [`Self::render_surface_from_scratch`].
    pub fn render_surface(&self) -> RenderSurface {
        let mut guard = self.render_cache.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let cache = std::mem::take(&mut *guard);
        let (surface, cache) = self.render_surface_with(cache);
        *guard = cache;
        surface
    }

    /// The render surface built without the last render's polygons (what
    /// [`Self::render_surface`] must equal).
    pub fn render_surface_from_scratch(&self) -> RenderSurface {
        self.render_surface_with(RenderCache::default()).0
    }

    /// Polygons (with their loops) the last [`Self::render_surface`] took from the render
    /// before it instead of making them again.
    pub fn render_polygons_reused(&self) -> usize {
        self.render_cache.lock().unwrap_or_else(std::sync::PoisonError::into_inner).reused
    }

    /// Per lattice tetrahedron, whether `cache` (the last render's polygons) may not be reused
    /// there: `None` when nothing may be (another epoch than the one before the last change, or
    /// a piece that split among duplicates the change kept). See [`RenderCache`].
    fn dirty_tets(&self, cache: &RenderCache, piece_of_duplicate: &[u32]) -> Option<(Vec<bool>, Vec<Option<u32>>)> {
        let num_tets = self.source().triangles_of_tet.len();
        let old_of_new: Vec<Option<u32>>;
        let changed: Vec<bool>;
        // (`changed` grows below by the pieces that split.)
        match (cache.epoch, self.last_change()) {
            (Some(e), _) if e == self.epoch() => {
                old_of_new = (0..self.num_duplicates() as u32).map(Some).collect();
                changed = vec![false; num_tets];
            }
            (Some(e), Some(change)) if e == change.epoch_before && e + 1 == self.epoch() => {
                let mut inverse = vec![None; self.num_duplicates()];
                for (old, new) in change.new_of_old.iter().enumerate() {
                    if let Some(new) = *new {
                        inverse[new as usize] = Some(old as u32);
                    }
                }
                old_of_new = inverse;
                changed = change.changed_tet.clone();
            }
            _ => return None,
        }
        // A piece split among kept duplicates drops T-junction points between polygons that did
        // not move (two sides of an earlier cut joined elsewhere, now in two pieces): every
        // tetrahedron of a piece that split is redone. Two old pieces in one new piece (which
        // a cut cannot make) would add points: then nothing is kept.
        let mut new_of_old_piece: FastMap<u32, (u32, bool)> = FastMap::default();
        let mut old_of_new_piece: FastMap<u32, u32> = FastMap::default();
        for (d, old) in old_of_new.iter().enumerate() {
            let Some(old) = *old else { continue };
            let (new_piece, old_piece) = (piece_of_duplicate[d], *cache.piece_of_duplicate.get(old as usize)?);
            if *old_of_new_piece.entry(new_piece).or_insert(old_piece) != old_piece {
                return None;
            }
            let entry = new_of_old_piece.entry(old_piece).or_insert((new_piece, false));
            entry.1 |= entry.0 != new_piece;
        }
        let mut changed = changed;
        for (d, old) in old_of_new.iter().enumerate() {
            let Some(old) = *old else { continue };
            if new_of_old_piece.get(&cache.piece_of_duplicate[old as usize]).is_some_and(|e| e.1) {
                changed[self.tet_of_duplicate(d)] = true;
            }
        }
        // Changed tetrahedra, and every tetrahedron of a source triangle one of them meets (that
        // triangle is no longer drawn whole: its clipped parts appear in all its tetrahedra).
        let source = self.source();
        let mut grown = changed.clone();
        for t in (0..num_tets).filter(|&t| changed[t]) {
            for &i in &source.triangles_of_tet[t] {
                for &u in &source.tets_of_triangle[i as usize] {
                    grown[u as usize] = true;
                }
            }
        }
        // A polygon's loop holds the points of other polygons on its edges: of its own
        // tetrahedron's, or, on a face or edge of it, of the tetrahedra sharing that edge (two
        // tetrahedra of the lattice meet in a face, an edge, a vertex or not at all, and an
        // edge point inside a tetrahedron's closure is a vertex of it only at an edge's end,
        // which no loop inserts). So everything sharing an edge with a grown one is redone.
        let edges_of = |t: usize| {
            let n = self.tet_lattice_nodes(t);
            [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)].map(|(a, b)| (n[a].min(n[b]), n[a].max(n[b])))
        };
        let mut grown_edges: FastMap<(u32, u32), ()> = FastMap::default();
        for t in (0..num_tets).filter(|&t| grown[t]) {
            grown_edges.extend(edges_of(t).map(|e| (e, ())));
        }
        let dirty = (0..num_tets)
            .into_par_iter()
            .map(|t| grown[t] || edges_of(t).iter().any(|e| grown_edges.contains_key(e)))
            .collect();
        Some((dirty, old_of_new))
    }

    fn render_surface_with(&self, cache: RenderCache) -> (RenderSurface, RenderCache) {
        let h = self.lattice().h;
        let tolerance = T_JUNCTION_TOLERANCE * h;
        let pieces = self.pieces();
        let mut piece_of_duplicate = vec![0u32; self.num_duplicates()];
        for (k, piece) in pieces.iter().enumerate() {
            for &d in &piece.elements {
                piece_of_duplicate[d as usize] = k as u32;
            }
        }
        let source = self.source();
        let num_tets = source.triangles_of_tet.len();
        let untouched: Vec<bool> = (0..num_tets)
            .into_par_iter()
            .map(|t| match self.duplicates_of_tet(t) {
                [d] => !self
                    .duplicate_cells(*d as usize)
                    .cells
                    .iter()
                    .any(|c| c.faces.iter().any(|f| f.cover == Cover::Cut)),
                _ => false,
            })
            .collect();
        // The lattice tetrahedron and weights of point `p` of whole triangle `i`: the one in
        // which its smallest barycentric coordinate is largest.
        let locate = |i: u32, p: &Point3<Real>| -> (u32, [Real; 4]) {
            let mut best = (Real::NEG_INFINITY, 0, [0.0; 4]);
            for &t in &source.tets_of_triangle[i as usize] {
                let w = self.tet_shape(t as usize).barycentric(p);
                let smallest = w.iter().copied().fold(Real::INFINITY, Real::min);
                if smallest > best.0 {
                    best = (smallest, t, w);
                }
            }
            (best.1, best.2)
        };
        // Whole triangles: all their tetrahedra untouched, all three corners in one piece.
        let whole: Vec<Option<u32>> = (0..source.triangles.len())
            .into_par_iter()
            .map(|i| {
                let tets = &source.tets_of_triangle[i];
                if tets.is_empty() || !tets.iter().all(|&t| untouched[t as usize]) {
                    return None;
                }
                // A triangle larger than the lattice is clipped anyway: its vertices are the
                // contact points, and a box's face drawn as two triangles would touch the ground
                // at its corners only.
                let [a, b, c] = source.triangles[i];
                if (b - a).norm().max((c - b).norm()).max((a - c).norm()) > h {
                    return None;
                }
                let corners = source.triangles[i].map(|p| self.duplicates_of_tet(locate(i as u32, &p).0 as usize)[0]);
                let piece = piece_of_duplicate[corners[0] as usize];
                corners.iter().all(|&d| piece_of_duplicate[d as usize] == piece).then_some(corners[0])
            })
            .collect();
        // What the last render may lend: per new duplicate its old entries, per whole triangle
        // its old entry, where nothing the change reached can have altered them.
        let reuse = self.dirty_tets(&cache, &piece_of_duplicate);
        let RenderCache { duplicates: mut old_duplicates, whole: mut old_whole, .. } = cache;
        let mut entries: Vec<Option<Vec<Entry>>> = (0..self.num_duplicates()).map(|_| None).collect();
        let mut whole_entries: Vec<Option<Entry>> = (0..source.triangles.len()).map(|_| None).collect();
        if let Some((dirty, old_of_new)) = &reuse {
            for (d, slot) in entries.iter_mut().enumerate() {
                if let Some(old) = old_of_new[d].filter(|_| !dirty[self.tet_of_duplicate(d)]) {
                    *slot = old_duplicates.get_mut(old as usize).map(std::mem::take);
                }
            }
            for (i, slot) in whole_entries.iter_mut().enumerate() {
                if whole[i].is_some() && !source.tets_of_triangle[i].iter().any(|&t| dirty[t as usize]) {
                    *slot = old_whole.get_mut(i).and_then(Option::take);
                }
            }
        }
        for (i, slot) in whole_entries.iter_mut().enumerate() {
            if whole[i].is_some() && slot.is_none() {
                *slot = Some(Entry { kind: SurfaceKind::Original, points: source.triangles[i].to_vec(), ring: None });
            }
        }
        // The covered faces of every other duplicate (in parallel).
        let fresh: Vec<(usize, Vec<Entry>)> = (0..self.num_duplicates())
            .filter(|&d| entries[d].is_none())
            .collect::<Vec<_>>()
            .into_par_iter()
            .map_init(Vec::new, |groups: &mut Vec<FaceGroup>, d| {
                let cells = self.duplicate_cells(d);
                let tet = self.tet_of_duplicate(d);
                // Object-surface faces of an untouched tetrahedron are still the carved ones, in
                // the carved order, with their source triangles known.
                let sources = &source.face_sources[tet];
                let mut surface_face = 0;
                // Covered faces grouped by plane, side and kind: the cells of a duplicate split
                // one cut or surface polygon into fragments, merged again below.
                groups.clear();
                for cell in &cells.cells {
                    for face in &cell.faces {
                        let kind = match face.cover {
                            Cover::Open => continue,
                            Cover::Cut => SurfaceKind::Cut,
                            Cover::Surface => {
                                surface_face += 1;
                                if untouched[tet]
                                    && sources
                                        .get(surface_face - 1)
                                        .is_some_and(|&i| whole.get(i as usize).is_some_and(Option::is_some))
                                {
                                    continue;
                                }
                                SurfaceKind::Original
                            }
                        };
                        let key = (face.plane, face.positive, kind);
                        match groups.iter_mut().find(|g| g.0 == key) {
                            Some(group) => group.1.push(face),
                            None => groups.push((key, vec![face])),
                        }
                    }
                }
                let mut polygons = Vec::new();
                for ((_, _, kind), faces) in groups.iter() {
                    let entry = |verts: &[u32]| Entry {
                        kind: *kind,
                        points: verts.iter().map(|&v| cells.point(v)).collect(),
                        ring: None,
                    };
                    match merged_loop(cells, faces, tolerance) {
                        Some(merged) => polygons.push(entry(&merged)),
                        None => polygons.extend(faces.iter().map(|f| entry(&f.verts))),
                    }
                }
                (d, polygons)
            })
            .collect();
        for (d, polygons) in fresh {
            entries[d] = Some(polygons);
        }
        let mut entries: Vec<Vec<Entry>> = entries.into_iter().map(Option::unwrap_or_default).collect();
        // Per piece its polygons in order: whole triangles, then each duplicate's faces.
        let mut refs_of_piece: Vec<Vec<EntryRef>> = (0..pieces.len()).map(|_| Vec::new()).collect();
        for (i, corner) in whole.iter().enumerate() {
            if let Some(d) = *corner {
                refs_of_piece[piece_of_duplicate[d as usize] as usize].push(EntryRef::Whole(i as u32));
            }
        }
        for (k, piece) in pieces.iter().enumerate() {
            for &d in &piece.elements {
                refs_of_piece[k].extend((0..entries[d as usize].len() as u32).map(|e| EntryRef::Duplicate(d, e)));
            }
        }
        // The loop of every polygon without one (its corners and the points of the piece's other
        // faces on its edges, each with its embedding), in parallel.
        let grids: Vec<PointGrid> = refs_of_piece
            .par_iter()
            .map(|refs| {
                let mut grid = PointGrid { cell: 0.25 * h, buckets: FastMap::default() };
                for &r in refs {
                    for p in &r.get(&entries, &whole_entries).points {
                        grid.buckets.entry(grid.key(p)).or_default().push(*p);
                    }
                }
                for bucket in grid.buckets.values_mut() {
                    bucket.sort_by(|a, b| {
                        (a.x, a.y, a.z).partial_cmp(&(b.x, b.y, b.z)).unwrap_or(std::cmp::Ordering::Equal)
                    });
                    bucket.dedup();
                }
                grid
            })
            .collect();
        let missing: Vec<(usize, EntryRef)> = refs_of_piece
            .iter()
            .enumerate()
            .flat_map(|(k, refs)| refs.iter().map(move |&r| (k, r)))
            .filter(|&(_, r)| r.get(&entries, &whole_entries).ring.is_none())
            .collect();
        let rings: Vec<Ring> = missing
            .par_iter()
            .map_init(Vec::new, |found, &(k, r)| {
                let polygon = r.get(&entries, &whole_entries);
                let embedded = |p: Point3<Real>| -> CachedPoint {
                    match r {
                        EntryRef::Duplicate(d, _) => {
                            CachedPoint { p, weights: self.duplicate_shape(d as usize).barycentric(&p), tet: u32::MAX }
                        }
                        EntryRef::Whole(i) => {
                            let (tet, weights) = locate(i, &p);
                            CachedPoint { p, weights, tet }
                        }
                    }
                };
                let mut points = Vec::with_capacity(polygon.points.len() + 2);
                let mut corner = Vec::with_capacity(polygon.points.len() + 2);
                let n = polygon.points.len();
                for i in 0..n {
                    let (a, b) = (polygon.points[i], polygon.points[(i + 1) % n]);
                    points.push(embedded(a));
                    corner.push(true);
                    grids[k].on_segment(&a, &b, tolerance, found);
                    points.extend(found.iter().map(|f| embedded(f.1)));
                    corner.extend(found.iter().map(|_| false));
                }
                // Faces are convex: fanned from a corner whose two edges carry no inserted
                // point (any other fan triangle has positive area), else from the vertex
                // average (inserted points lie on the edges), appended last.
                let m = points.len();
                let apex = (0..m).find(|&a| corner[a] && corner[(a + 1) % m] && corner[(a + m - 1) % m]);
                if apex.is_none() {
                    let centre = points.iter().fold(Vector3::zeros(), |s, q| s + q.p.coords) / m as Real;
                    points.push(embedded(Point3::from(centre)));
                }
                (points, apex)
            })
            .collect();
        for (&(_, r), ring) in missing.iter().zip(rings) {
            let slot = match r {
                EntryRef::Whole(i) => whole_entries[i as usize].as_mut().expect("whole triangles have entries"),
                EntryRef::Duplicate(d, e) => &mut entries[d as usize][e as usize],
            };
            slot.ring = Some(ring);
        }
        // Welding in polygon order, per piece (pieces share no vertex: a vertex's nodes belong
        // to one piece), in parallel.
        let parts: Vec<RenderSurface> = refs_of_piece
            .par_iter()
            .map(|refs| {
                let mut surface = RenderSurface { embedding: Embedding::new(), ..Default::default() };
                let mut welder = Welder::new(tolerance);
                let mut ids: Vec<u32> = Vec::new();
                for &r in refs {
                    let polygon = r.get(&entries, &whole_entries);
                    let (points, apex) = polygon.ring.as_ref().expect("every polygon has its loop now");
                    let duplicate = match r {
                        EntryRef::Duplicate(d, _) => d,
                        EntryRef::Whole(i) => whole[i as usize].expect("a whole triangle has its corner's duplicate"),
                    };
                    ids.clear();
                    for q in points {
                        let d = match r {
                            EntryRef::Duplicate(d, _) => d,
                            EntryRef::Whole(_) => self.duplicates_of_tet(q.tet as usize)[0],
                        };
                        let nodes = self.duplicate_nodes_of(d as usize);
                        let mut key = [u32::MAX; 4];
                        for c in 0..4 {
                            if q.weights[c].abs() > ZERO_WEIGHT {
                                key[c] = nodes[c];
                            }
                        }
                        key.sort_unstable();
                        ids.push(welder.find_or_insert(q.p, key, || {
                            surface.positions.push(q.p);
                            surface.embedding.push_row(&nodes, &q.weights);
                            surface.positions.len() as u32 - 1
                        }));
                    }
                    let mut push = |triangle: [u32; 3]| {
                        if triangle[0] != triangle[1] && triangle[1] != triangle[2] && triangle[2] != triangle[0] {
                            surface.triangles.push(triangle);
                            surface.kinds.push(polygon.kind);
                            surface.duplicates.push(duplicate);
                        }
                    };
                    match *apex {
                        Some(a) => {
                            let m = ids.len();
                            (1..m - 1).for_each(|i| push([ids[a], ids[(a + i) % m], ids[(a + i + 1) % m]]));
                        }
                        None => {
                            let (c, ring) = ids.split_last().expect("a polygon has corners");
                            let m = ring.len();
                            (0..m).for_each(|i| push([*c, ring[i], ring[(i + 1) % m]]));
                        }
                    }
                }
                remove_slivers(&mut surface, SLIVER_TOLERANCE * h);
                surface
            })
            .collect();
        let mut surface = RenderSurface { embedding: Embedding::new(), ..Default::default() };
        for part in parts {
            let offset = surface.positions.len() as u32;
            surface.positions.extend_from_slice(&part.positions);
            for row in 0..part.positions.len() {
                let (nodes, weights) = part.embedding.row(row);
                surface.embedding.push_row(nodes, weights);
            }
            surface.triangles.extend(part.triangles.iter().map(|t| t.map(|v| v + offset)));
            surface.kinds.extend_from_slice(&part.kinds);
            surface.duplicates.extend_from_slice(&part.duplicates);
        }
        let reused = refs_of_piece.iter().map(Vec::len).sum::<usize>() - missing.len();
        let cache = RenderCache {
            epoch: Some(self.epoch()),
            reused,
            piece_of_duplicate,
            duplicates: entries,
            whole: whole_entries,
        };
        (surface, cache)
    }

    /// The source triangle of every object-surface face of the carved duplicates of lattice
    /// tetrahedron `tet`, in cell and face order: the triangle of the tetrahedron nearest the
    /// face's centroid (a covered face lies inside the triangle that covered it).
    pub(crate) fn carved_face_sources(&self, tet: usize) -> Vec<u32> {
        let source = self.source();
        let mut sources = Vec::new();
        for &d in self.duplicates_of_tet(tet) {
            let cells = self.duplicate_cells(d as usize);
            for face in cells.cells.iter().flat_map(|c| &c.faces).filter(|f| f.cover == Cover::Surface) {
                let centroid = Point3::from(
                    face.verts.iter().fold(Vector3::zeros(), |s, &v| s + cells.point(v).coords)
                        / face.verts.len() as Real,
                );
                let nearest = source.triangles_of_tet[tet]
                    .iter()
                    .map(|&i| {
                        ((closest_point_on_triangle(&centroid, &source.triangles[i as usize]).0 - centroid).norm(), i)
                    })
                    .min_by(|a, b| a.0.total_cmp(&b.0));
                sources.push(nearest.map_or(u32::MAX, |n| n.1));
            }
        }
        sources
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    /// Area of a planar polygon.
    fn area(points: &[Point3<Real>]) -> Real {
        let n = points.len();
        0.5 * (1..n - 1)
            .fold(Vector3::zeros(), |s, i| s + (points[i] - points[0]).cross(&(points[i + 1] - points[0])))
            .norm()
    }

    /// Poses of the unit tetrahedron: as it is, and turned about a skew axis and moved 1 km away
    /// (where a formula on absolute coordinates loses the digits of a small polygon).
    fn poses() -> [Isometry3<Real>; 2] {
        let turned = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -0.7, 0.5));
        [Isometry3::identity(), Isometry3::from_parts(Translation3::new(1000.0, -400.0, 250.0), turned)]
    }

    /// The unit tetrahedron placed by `pose`, cut by the plane z = 0.3 and by `x = c` for `c` in
    /// `xs` and `y = c` for `c` in `ys` (its own frame), and the faces on z = 0.3 seen from below
    /// (outward +z of the cells under it) with their centroids in its own frame.
    fn section_fragments(pose: &Isometry3<Real>, xs: &[Real], ys: &[Real]) -> (Arrangement, Vec<(usize, usize)>) {
        let corners =
            [Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0), Point3::new(0.0, 0.0, 1.0)];
        let mut cells = Arrangement::tetrahedron(corners.map(|p| pose * p));
        let big = 10.0;
        let mut planes = vec![[Point3::new(-big, -big, 0.3), Point3::new(big, -big, 0.3), Point3::new(0.0, big, 0.3)]];
        planes.extend(
            xs.iter().map(|&c| [Point3::new(c, -big, -big), Point3::new(c, big, -big), Point3::new(c, 0.0, big)]),
        );
        planes.extend(
            ys.iter().map(|&c| [Point3::new(-big, c, -big), Point3::new(big, c, -big), Point3::new(0.0, c, big)]),
        );
        for t in planes {
            assert!(cells.cut(&t.map(|p| pose * p), Cover::Cut));
        }
        let local = |v: u32| pose.inverse_transform_point(&cells.point(v));
        let below = (0..cells.cells.len())
            .flat_map(|c| (0..cells.cells[c].faces.len()).map(move |f| (c, f)))
            .filter(|&(c, f)| {
                let face = &cells.cells[c].faces[f];
                let p: Vec<Point3<Real>> = face.verts.iter().map(|&v| local(v)).collect();
                face.cover == Cover::Cut
                    && p.iter().all(|q| (q.z - 0.3).abs() < 1e-9)
                    && (p[1] - p[0]).cross(&(p[2] - p[0])).z > 0.0
            })
            .collect();
        (cells, below)
    }

    fn faces<'a>(cells: &'a Arrangement, which: &[(usize, usize)]) -> Vec<&'a Face> {
        which.iter().map(|&(c, f)| &cells.cells[c].faces[f]).collect()
    }

    /// The merged loop's points in the tetrahedron's own frame.
    fn merged_points(cells: &Arrangement, faces: &[&Face], pose: &Isometry3<Real>) -> Option<Vec<Point3<Real>>> {
        merged_loop(cells, faces, 1e-10)
            .map(|ids| ids.iter().map(|&v| pose.inverse_transform_point(&cells.point(v))).collect())
    }

    #[test]
    fn fragments_of_a_cut_split_by_a_second_cut_merge_into_the_section() {
        for pose in poses() {
            let (cells, below) = section_fragments(&pose, &[0.2], &[]);
            let below = faces(&cells, &below);
            assert_eq!(below.len(), 2, "the second cut splits the section in two");
            let points = merged_points(&cells, &below, &pose).expect("two halves of a triangle merge");
            // The section of the tet at z = 0.3 is the triangle with legs 0.7: area 0.245; the
            // split points on its edges are collinear and dropped, so three corners remain.
            assert_eq!(points.len(), 3);
            assert!((area(&points) - 0.5 * 0.7 * 0.7).abs() < 1e-9, "area {}", area(&points));
            let fragments: Real =
                below.iter().map(|f| area(&f.verts.iter().map(|&v| cells.point(v)).collect::<Vec<_>>())).sum();
            assert!((fragments - 0.245).abs() < 1e-9);
            // Same orientation as the fragments (counter-clockwise seen from +z).
            assert!((points[1] - points[0]).cross(&(points[2] - points[0])).z > 0.0);
        }
    }

    #[test]
    fn fragments_around_a_reflex_corner_stay_apart() {
        for pose in poses() {
            let (cells, below) = section_fragments(&pose, &[0.2], &[0.2]);
            let below = faces(&cells, &below);
            assert_eq!(below.len(), 4, "two cuts split the section in four");
            let centroid = |f: &Face| {
                let sum = f.verts.iter().fold(Vector3::zeros(), |s, &v| s + cells.point(v).coords);
                pose.inverse_transform_point(&Point3::from(sum / f.verts.len() as Real))
            };
            // All four: the whole section again.
            let all = merged_points(&cells, &below, &pose).expect("the four quarters merge");
            assert_eq!(all.len(), 3);
            assert!((area(&all) - 0.245).abs() < 1e-9);
            // Three of them, the corner at the origin left out: an L with a reflex corner at
            // (0.2, 0.2), which is not one convex polygon.
            let without_corner: Vec<&Face> =
                below.iter().copied().filter(|f| centroid(f).x > 0.2 || centroid(f).y > 0.2).collect();
            assert_eq!(without_corner.len(), 3);
            assert!(merged_loop(&cells, &without_corner, 1e-10).is_none());
            // The two beyond x = 0.2 (split by y = 0.2): the part of the section with x > 0.2, a
            // triangle with legs 0.5 and area 0.125.
            let beyond: Vec<&Face> = below.iter().copied().filter(|f| centroid(f).x > 0.2).collect();
            let points = merged_points(&cells, &beyond, &pose).expect("the two parts beyond x = 0.2 merge");
            assert_eq!(points.len(), 3);
            assert!((area(&points) - 0.125).abs() < 1e-9, "area {}", area(&points));
            // A single face is left as it is.
            assert!(merged_loop(&cells, &below[..1], 1e-10).is_none());
        }
    }
}
