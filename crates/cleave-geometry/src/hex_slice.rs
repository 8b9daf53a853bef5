//! Hexahedral slicing (kaufmann2008 §10): a closed surface cut by a regular grid of cubes into
//! polyhedral elements, one per connected component of (cell ∩ solid), with small pieces merged
//! into neighbours by default. See `docs/math/hex-slicing.md`.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::voxelize::voxelize_on_grid;
use crate::{GeometryError, MergeReport, PolyFace, PolyhedralMesh, TriangleMesh, UnionFind, merge_small_elements};

/// Largest number of grid cells (of the bounding grid) [`hex_slice`] accepts.
pub const MAX_SLICE_CELLS: u64 = 20_000_000;

/// Genericity margin, in cell sizes: the grid is shifted until every surface vertex, every
/// crossing of a surface edge with a grid plane and every crossing of a surface triangle with
/// a grid line is at least this far (per coordinate) from the grid planes it does not lie on.
///
/// All combinatorial decisions (which side of a plane, which cell a crossing falls in, the
/// order of crossings along a cell edge) compare such a coordinate with a grid plane, so with
/// this margin rounding (≈1e-15 cell sizes) cannot flip them, and every decision taken twice
/// (once per neighbouring cell) comes out the same. It also bounds slivers: a clipped face
/// never has a vertex closer than this to a cell edge or corner it does not contain.
pub const GRID_MARGIN: f64 = 1e-9;

/// Smallest face area, in cell sizes squared, [`hex_slice`] emits: a slicing with a smaller
/// face (a sliver from a near-coincidence the genericity margin let through) is redone with
/// the next grid shift. It is [`GRID_MARGIN`] squared.
pub const MIN_FACE_AREA: f64 = GRID_MARGIN * GRID_MARGIN;

/// Number of grid shifts tried before giving up with [`GeometryError::NoGenericGridShift`].
const SHIFT_ATTEMPTS: usize = 16;

/// Attempt `n` (from 1) shifts axis `d` by `frac(n · SHIFT_STEPS[d])` cell sizes: multiples
/// of the golden ratio and of √2, √3 keep the shifts distinct and far from simple fractions,
/// so meshes aligned with the lattice `h·ℤ³` (boxes, voxel models) are never degenerate.
const SHIFT_STEPS: [f64; 3] = [0.618_033_988_749_894_9, 0.414_213_562_373_095_1, 0.732_050_807_568_877_2];

/// Default [`HexSliceOptions::merge_below`]: pieces smaller than 5% of a cell are merged into a
/// neighbour. Below it the penalty and basis conditioning of a corner, edge or face nick grows
/// quickly; the reasoning and the measured effect are in `docs/math/hex-slicing.md` §6.
pub const DEFAULT_MERGE_BELOW: f64 = 0.05;

/// Options of [`hex_slice_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HexSliceOptions {
    /// Sliver merging threshold as a fraction of the cell volume `h³`: every element of volume
    /// below `merge_below·h³` is merged into a face-adjacent neighbour by
    /// [`merge_small_elements`]. `0.0` keeps the raw slicing (one element per piece of a cell).
    pub merge_below: f64,
}

impl Default for HexSliceOptions {
    fn default() -> Self {
        Self { merge_below: DEFAULT_MERGE_BELOW }
    }
}

/// The result of [`hex_slice`]: polyhedral elements and the grid cell each came from.
#[derive(Debug, Clone, PartialEq)]
pub struct HexSlicing {
    /// The elements. Boundary faces (`outer: None`) are pieces of the surface triangles,
    /// interior faces are planar regions of grid faces.
    pub mesh: PolyhedralMesh,
    /// Grid cell `[i, j, k]` of each element; cell `[i, j, k]` is the cube from
    /// `origin + cell_size·(i, j, k)` to `origin + cell_size·(i + 1, j + 1, k + 1)`.
    ///
    /// After sliver merging an element is a union of raw pieces (see
    /// [`MergeReport::element_map`]) joined through shared faces, so from a connected set of
    /// cells. Its cell is the cell of its survivor ([`MergeReport::survivors`]), the piece the
    /// others were merged into, directly or through a chain. Small pieces join the neighbour
    /// they share the most area with, so the survivor is typically the element's main piece,
    /// but the element extends beyond that cell.
    pub element_cells: Vec<[i32; 3]>,
    /// Minimum corner of grid cell `[0, 0, 0]`, including the genericity shift.
    pub origin: Point3<f64>,
    /// Edge length of the cells.
    pub cell_size: f64,
    /// The sliver merge applied to the raw slicing (no merges when
    /// [`HexSliceOptions::merge_below`] is 0); its `element_map` maps the raw pieces, one per
    /// connected component of (cell ∩ solid), to the elements of `mesh`.
    pub merge: MergeReport,
}

/// Slices the solid bounded by the closed, outward-oriented triangle mesh `surface` with a
/// regular grid of cubes of edge `cell_size`: every connected component of (cell ∩ solid)
/// becomes one element (kaufmann2008 §10, "hexagonal slicing"), and elements smaller than
/// [`DEFAULT_MERGE_BELOW`]` · h³` are then merged into neighbours (last paragraph).
///
/// Cells entirely inside become cubes; cells the surface crosses become arbitrary (possibly
/// non-convex) polyhedra bounded by (a) the pieces of the surface triangles clipped to the
/// cell (boundary faces, `outer: None`, oriented like the triangles) and (b) the regions of
/// the cell's faces that lie inside the solid, shared by the two elements on either side
/// (interior faces, stored once with `inner` the cell below along the face normal's axis).
/// Two pieces of solid in one cell that touch only through the cell's interior are two
/// elements. Every element boundary is closed and outward oriented.
///
/// The grid is the lattice `h·ℤ³` shifted by `frac(n·(φ−1, √2−1, √3−1))·h` for attempt
/// `n = 1, 2, …` until the configuration is generic with margin [`GRID_MARGIN`]; the shift is
/// in [`HexSlicing::origin`]. The grid covers the bounding box with a margin of at least
/// `(1 − shift)·h` below and a positive one above, so its outer corners are outside.
///
/// Faces are simple planar polygons of area at least [`MIN_FACE_AREA`]`·h²`. A cell-face
/// region with holes (a tube of outside passing through a face square without touching its
/// edges) is bridged and cut into triangles.
///
/// Errors: the error of [`TriangleMesh::validate_closed`];
/// [`GeometryError::InvalidCellSize`]; [`GeometryError::GridTooLarge`] beyond
/// [`MAX_SLICE_CELLS`]; [`GeometryError::NoGenericGridShift`] if every shift is degenerate or
/// leaves a sliver; [`GeometryError::SliceInconsistent`] if the pieces do not fit together,
/// which happens for self-intersecting surfaces.
///
/// Pieces smaller than [`DEFAULT_MERGE_BELOW`]` · h³` are then merged into neighbours (see
/// [`hex_slice_with`]); this is [`hex_slice_with`] with [`HexSliceOptions::default`].
pub fn hex_slice(surface: &TriangleMesh, cell_size: f64) -> Result<HexSlicing, GeometryError> {
    hex_slice_with(surface, cell_size, HexSliceOptions::default())
}

/// [`hex_slice`] with explicit options.
///
/// After slicing, every element of volume below `options.merge_below · h³` is merged into the
/// face-adjacent neighbour it shares the most face area with ([`merge_small_elements`],
/// kaufmann2008 §10 "sliver merging"); the report is [`HexSlicing::merge`]. Merged elements are
/// non-convex in general, may have several faces to one neighbour, and interior faces stay
/// planar regions of grid faces. `merge_below = 0` returns the raw slicing.
///
/// Errors: those of [`hex_slice`], and [`GeometryError::InvalidMergeThreshold`] for a negative,
/// infinite or NaN `merge_below`.
pub fn hex_slice_with(
    surface: &TriangleMesh,
    cell_size: f64,
    options: HexSliceOptions,
) -> Result<HexSlicing, GeometryError> {
    surface.validate_closed()?;
    let h = cell_size;
    if !(h.is_finite() && h > 0.0) {
        return Err(GeometryError::InvalidCellSize { cell_size });
    }
    let merge_below = options.merge_below;
    if !(merge_below.is_finite() && merge_below >= 0.0) {
        return Err(GeometryError::InvalidMergeThreshold { threshold: merge_below });
    }
    let (lo, hi) = surface.aabb();
    for attempt in 1..=SHIFT_ATTEMPTS {
        let shift: [f64; 3] = std::array::from_fn(|d| (SHIFT_STEPS[d] * attempt as f64).fract());
        let origin = Point3::from(std::array::from_fn(|d| h * ((lo[d] / h).floor() - 1.0 + shift[d])));
        let dims_f: [f64; 3] = std::array::from_fn(|d| ((hi[d] - origin[d]) / h).floor() + 1.0);
        let cells: f64 = dims_f.iter().product();
        if cells.is_nan() || cells > MAX_SLICE_CELLS as f64 {
            return Err(GeometryError::GridTooLarge { dims: dims_f, cells, limit: MAX_SLICE_CELLS });
        }
        let Some(slicer) = Slicer::new(surface, origin, h) else { continue };
        let grid = voxelize_on_grid(surface, origin, h, dims_f)?;
        let mut slicing = slicer.slice(&grid)?;
        if smallest_face_area(&slicing.mesh) >= MIN_FACE_AREA * h * h {
            let merge = merge_small_elements(&mut slicing.mesh, merge_below * h * h * h)?;
            slicing.element_cells = merge.survivors.iter().map(|&p| slicing.element_cells[p as usize]).collect();
            slicing.merge = merge;
            return Ok(slicing);
        }
    }
    Err(GeometryError::NoGenericGridShift { cell_size, attempts: SHIFT_ATTEMPTS })
}

/// Area of the smallest face.
fn smallest_face_area(mesh: &PolyhedralMesh) -> f64 {
    mesh.faces.iter().map(|f| mesh.polygon_area(&f.polygon)).fold(f64::INFINITY, f64::min)
}

/// A vertex of the sliced mesh, named by the features whose intersection it is. Every vertex
/// is computed from its key alone, so the cells and faces that share it agree bit for bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Key {
    /// A surface vertex (inside a cell).
    Vertex(u32),
    /// Surface edge `a < b` crossing grid plane `x[axis] = plane`.
    EdgePlane { a: u32, b: u32, axis: u8, plane: i32 },
    /// Triangle `tri` crossing the grid line along `axis` with `x[(axis+1)%3] = fixed[0]`,
    /// `x[(axis+2)%3] = fixed[1]`.
    TriLine { tri: u32, axis: u8, fixed: [i32; 2] },
    /// A grid corner.
    Corner([i32; 3]),
}

impl Key {
    /// Whether the vertex lies on grid plane `x[d] = p`.
    fn on_plane(self, d: usize, p: i32) -> bool {
        match self {
            Key::EdgePlane { axis, plane, .. } => axis as usize == d && plane == p,
            Key::TriLine { axis, fixed, .. } => {
                let a = axis as usize;
                (d == (a + 1) % 3 && fixed[0] == p) || (d == (a + 2) % 3 && fixed[1] == p)
            }
            Key::Corner(c) => c[d] == p,
            Key::Vertex(_) => false,
        }
    }
}

/// A vertex of a polygon being clipped: its key, local position, the triangle edges
/// (bits 0..3) and the grid planes it lies on.
#[derive(Debug, Clone, Copy)]
struct ClipVertex {
    key: Key,
    x: Vector3<f64>,
    edges: u8,
    planes: [(u8, i32); 2],
    num_planes: u8,
}

/// The surface in grid coordinates (`(v − origin)/h`, grid planes at integers) with the
/// crossings of the surface with the x-parallel grid lines, for inside tests of grid corners.
struct Slicer<'a> {
    surface: &'a TriangleMesh,
    origin: Point3<f64>,
    h: f64,
    local: Vec<Vector3<f64>>,
    normals: Vec<Vector3<f64>>,
    /// Sorted x-coordinates where the surface crosses the grid line `(y, z) = key`.
    x_lines: HashMap<[i32; 2], Vec<f64>>,
}

fn near_integer(x: f64) -> bool {
    (x - x.round()).abs() < GRID_MARGIN
}

/// Surface edge `(xa, xb)` at grid plane `x[d] = p`, computed from the lower vertex index so
/// both triangles of the edge get the same bits.
fn edge_plane_point(xa: Vector3<f64>, xb: Vector3<f64>, d: usize, p: i32) -> Vector3<f64> {
    let s = (f64::from(p) - xa[d]) / (xb[d] - xa[d]);
    let mut x = xa + (xb - xa) * s;
    x[d] = f64::from(p);
    x
}

/// The grid line along `d` through `fixed` meeting the plane of the triangle with corner `x0`
/// and normal `n` (`n[d] ≠ 0`).
fn tri_line_point(x0: Vector3<f64>, n: Vector3<f64>, d: usize, fixed: [i32; 2]) -> Vector3<f64> {
    let (d1, d2) = ((d + 1) % 3, (d + 2) % 3);
    let (f0, f1) = (f64::from(fixed[0]), f64::from(fixed[1]));
    let mut x = Vector3::zeros();
    x[d1] = f0;
    x[d2] = f1;
    x[d] = x0[d] + (n[d1] * (x0[d1] - f0) + n[d2] * (x0[d2] - f1)) / n[d];
    x
}

/// Integers strictly between `a` and `b` (neither of which is an integer).
fn integers_between(a: f64, b: f64) -> std::ops::RangeInclusive<i32> {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    (lo.floor() as i32 + 1)..=(hi.floor() as i32)
}

/// A crossing of the surface with the x-parallel grid line `(y, z)`: `((y, z), x)`.
type LineCrossing = ([i32; 2], f64);

/// A polygon traced in a cell face, before vertex numbering.
type KeyPolygon = Vec<Key>;

/// The polygons of one listed cell: clipped surface pieces, then for each face slot the
/// component of each of that face's regions.
struct CellPieces {
    surface: Vec<KeyPolygon>,
    components: usize,
    surface_component: Vec<usize>,
    /// `slot_component[2 d + s][r]`: component of region `r` of the cell's face on axis `d`,
    /// lower (`s = 0`) or upper (`s = 1`).
    slot_component: [Vec<usize>; 6],
}

fn inconsistent(cell: [i32; 3], message: impl Into<String>) -> GeometryError {
    GeometryError::SliceInconsistent { cell, message: message.into() }
}

impl<'a> Slicer<'a> {
    /// Maps the surface to grid coordinates and checks genericity (see [`GRID_MARGIN`]);
    /// `None` if the shift is degenerate.
    fn new(surface: &'a TriangleMesh, origin: Point3<f64>, h: f64) -> Option<Self> {
        let local: Vec<Vector3<f64>> = surface.vertices.iter().map(|v| (v - origin) / h).collect();
        let normals: Vec<Vector3<f64>> = surface
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| local[i as usize]);
                (b - a).cross(&(c - a))
            })
            .collect();
        // Vertices off the grid planes.
        for t in &surface.triangles {
            for &v in t {
                if local[v as usize].iter().any(|&x| near_integer(x)) {
                    return None;
                }
            }
        }
        // Edge crossings off the grid lines, triangle crossings off the grid corners. Each
        // triangle is independent, so this runs in parallel; x-line crossings are collected.
        let per_triangle: Option<Vec<Vec<LineCrossing>>> = (0..surface.triangles.len())
            .into_par_iter()
            .map(|t| {
                let tri = surface.triangles[t];
                let xs = tri.map(|i| local[i as usize]);
                for e in 0..3 {
                    let (a, b) = (tri[e], tri[(e + 1) % 3]);
                    let (a, b) = (a.min(b), a.max(b));
                    let (xa, xb) = (local[a as usize], local[b as usize]);
                    for d in 0..3 {
                        for p in integers_between(xa[d], xb[d]) {
                            let x = edge_plane_point(xa, xb, d, p);
                            if near_integer(x[(d + 1) % 3]) || near_integer(x[(d + 2) % 3]) {
                                return None;
                            }
                        }
                    }
                }
                let n = normals[t];
                let mut crossings = Vec::new();
                for d in 0..3 {
                    if n[d] == 0.0 {
                        // Parallel to the lines: a line in its plane would make an edge cross a
                        // grid line, which the edge check rejects.
                        continue;
                    }
                    let (d1, d2) = ((d + 1) % 3, (d + 2) % 3);
                    let range = |k: usize| {
                        let lo = xs.iter().map(|x| x[k]).fold(f64::INFINITY, f64::min);
                        let hi = xs.iter().map(|x| x[k]).fold(f64::NEG_INFINITY, f64::max);
                        integers_between(lo, hi)
                    };
                    for f0 in range(d1) {
                        for f1 in range(d2) {
                            let q = [f64::from(f0), f64::from(f1)];
                            let orient = |i: usize| {
                                let (p, r) = (xs[i], xs[(i + 1) % 3]);
                                (r[d1] - p[d1]) * (q[1] - p[d2]) - (r[d2] - p[d2]) * (q[0] - p[d1])
                            };
                            let (o0, o1, o2) = (orient(0), orient(1), orient(2));
                            let inside = (o0 > 0.0 && o1 > 0.0 && o2 > 0.0) || (o0 < 0.0 && o1 < 0.0 && o2 < 0.0);
                            if !inside {
                                continue;
                            }
                            let x = tri_line_point(xs[0], n, d, [f0, f1]);
                            if near_integer(x[d]) || !x[d].is_finite() {
                                return None;
                            }
                            if d == 0 {
                                crossings.push(([f0, f1], x[0]));
                            }
                        }
                    }
                }
                Some(crossings)
            })
            .collect();
        let mut x_lines: HashMap<[i32; 2], Vec<f64>> = HashMap::new();
        for (line, x) in per_triangle?.into_iter().flatten() {
            x_lines.entry(line).or_default().push(x);
        }
        for xs in x_lines.values_mut() {
            xs.sort_by(f64::total_cmp);
        }
        Some(Self { surface, origin, h, local, normals, x_lines })
    }

    /// Whether grid corner `c` is inside: the parity of surface crossings on the x-line
    /// through it beyond it (the grid extends past the surface, so the ray leaves it).
    fn corner_inside(&self, c: [i32; 3]) -> bool {
        self.x_lines.get(&[c[1], c[2]]).is_some_and(|xs| {
            let beyond = xs.len() - xs.partition_point(|&x| x < f64::from(c[0]));
            beyond % 2 == 1
        })
    }

    /// Position of a key in grid coordinates.
    fn local_position(&self, key: Key) -> Vector3<f64> {
        match key {
            Key::Vertex(v) => self.local[v as usize],
            Key::EdgePlane { a, b, axis, plane } => {
                edge_plane_point(self.local[a as usize], self.local[b as usize], axis as usize, plane)
            }
            Key::TriLine { tri, axis, fixed } => {
                let x0 = self.local[self.surface.triangles[tri as usize][0] as usize];
                tri_line_point(x0, self.normals[tri as usize], axis as usize, fixed)
            }
            Key::Corner(c) => Vector3::from(c.map(f64::from)),
        }
    }

    /// World position of a key: surface vertices exactly, others mapped from grid
    /// coordinates (grid-plane coordinates then equal `origin + p·h` on every face).
    fn world_position(&self, key: Key) -> Point3<f64> {
        match key {
            Key::Vertex(v) => self.surface.vertices[v as usize],
            _ => {
                let x = self.local_position(key);
                Point3::from(std::array::from_fn(|d| self.origin[d] + x[d] * self.h))
            }
        }
    }

    /// Triangle `t` clipped to cell `cell` (Sutherland–Hodgman over the six planes), as keys
    /// in the triangle's orientation; `None` if nothing of positive area remains.
    fn clip_triangle(&self, t: usize, cell: [i32; 3]) -> Result<Option<KeyPolygon>, GeometryError> {
        let tri = self.surface.triangles[t];
        let masks = [0b101u8, 0b011, 0b110];
        let mut poly: Vec<ClipVertex> = (0..3)
            .map(|i| ClipVertex {
                key: Key::Vertex(tri[i]),
                x: self.local[tri[i] as usize],
                edges: masks[i],
                planes: [(0, 0); 2],
                num_planes: 0,
            })
            .collect();
        let mut next = Vec::with_capacity(9);
        for d in 0..3 {
            for (p, keep_above) in [(cell[d], true), (cell[d] + 1, false)] {
                let pf = f64::from(p);
                let inside = |v: &ClipVertex| if keep_above { v.x[d] > pf } else { v.x[d] < pf };
                next.clear();
                for i in 0..poly.len() {
                    let (cur, nxt) = (&poly[i], &poly[(i + 1) % poly.len()]);
                    let (cin, nin) = (inside(cur), inside(nxt));
                    if cin {
                        next.push(*cur);
                    }
                    if cin != nin {
                        next.push(self.split(t, cur, nxt, d, p).ok_or_else(|| {
                            inconsistent(cell, format!("clipping triangle {t}: edge without common support"))
                        })?);
                    }
                }
                std::mem::swap(&mut poly, &mut next);
                if poly.len() < 3 {
                    return Ok(None);
                }
            }
        }
        Ok(Some(poly.iter().map(|v| v.key).collect()))
    }

    /// The point where the clipped-polygon edge `p → q` of triangle `t` crosses plane
    /// `x[d] = plane`: on a triangle edge if both lie on it, else on the grid line where a
    /// grid plane both lie on meets the clipping plane.
    fn split(&self, t: usize, p: &ClipVertex, q: &ClipVertex, d: usize, plane: i32) -> Option<ClipVertex> {
        let common = p.edges & q.edges;
        if common != 0 {
            let e = common.trailing_zeros() as usize;
            let tri = self.surface.triangles[t];
            let (a, b) = (tri[e].min(tri[(e + 1) % 3]), tri[e].max(tri[(e + 1) % 3]));
            let key = Key::EdgePlane { a, b, axis: d as u8, plane };
            return Some(ClipVertex {
                key,
                x: self.local_position(key),
                edges: 1 << e,
                planes: [(d as u8, plane), (0, 0)],
                num_planes: 1,
            });
        }
        let pp = &p.planes[..p.num_planes as usize];
        let qp = &q.planes[..q.num_planes as usize];
        let &(d2, p2) = pp.iter().find(|s| qp.contains(s))?;
        let d2 = d2 as usize;
        if d2 == d {
            return None;
        }
        let axis = 3 - d - d2;
        let mut fixed = [0; 2];
        for (k, value) in [(d, plane), (d2, p2)] {
            fixed[if k == (axis + 1) % 3 { 0 } else { 1 }] = value;
        }
        let key = Key::TriLine { tri: t as u32, axis: axis as u8, fixed };
        Some(ClipVertex {
            key,
            x: self.local_position(key),
            edges: 0,
            planes: [(d2 as u8, p2), (d as u8, plane)],
            num_planes: 2,
        })
    }

    /// The regions inside the solid of the grid face on plane `x[d] = cell_b[d]` below cell
    /// `cell_b`, counter-clockwise about `+d`, given the directed boundary `segments` the
    /// surface draws on it (region on their left).
    fn face_regions(
        &self,
        d: usize,
        cell_b: [i32; 3],
        segments: &[(Key, Key)],
    ) -> Result<Vec<KeyPolygon>, GeometryError> {
        let (u, w) = ((d + 1) % 3, (d + 2) % 3);
        let (p, i, j) = (cell_b[d], cell_b[u], cell_b[w]);
        let corner = |su: i32, sw: i32| {
            let mut c = [0; 3];
            c[d] = p;
            c[u] = i + su;
            c[w] = j + sw;
            Key::Corner(c)
        };
        let corners = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
        let mut first_corner = [0; 3];
        first_corner[d] = p;
        first_corner[u] = i;
        first_corner[w] = j;
        if segments.is_empty() {
            return Ok(if self.corner_inside(first_corner) { vec![corners.to_vec()] } else { Vec::new() });
        }
        // Perimeter parameter in [0, 4) counter-clockwise from corner (i, j), for vertices
        // on the square's edges.
        let perimeter = |key: Key| -> Option<f64> {
            let Key::TriLine { .. } = key else { return None };
            let x = self.local_position(key);
            let (xu, xw) = (x[u] - f64::from(i), x[w] - f64::from(j));
            if key.on_plane(w, j) {
                Some(xu)
            } else if key.on_plane(u, i + 1) {
                Some(1.0 + xw)
            } else if key.on_plane(w, j + 1) {
                Some(3.0 - xu)
            } else if key.on_plane(u, i) {
                Some(4.0 - xw)
            } else {
                None
            }
        };
        let mut by_start: HashMap<Key, usize> = HashMap::with_capacity(segments.len());
        for (s, seg) in segments.iter().enumerate() {
            if by_start.insert(seg.0, s).is_some() {
                return Err(inconsistent(cell_b, format!("face on axis {d}: two segments leave one vertex")));
            }
        }
        let mut used = vec![false; segments.len()];
        // Chains from an entry point on the square's boundary to an exit point.
        let mut chains: Vec<Vec<Key>> = Vec::new();
        let mut events: Vec<(f64, usize, bool)> = Vec::new();
        for (s, seg) in segments.iter().enumerate() {
            let Some(entry) = perimeter(seg.0) else { continue };
            let mut chain = vec![seg.0];
            let mut cur = s;
            loop {
                if std::mem::replace(&mut used[cur], true) {
                    return Err(inconsistent(cell_b, format!("face on axis {d}: chain revisits a segment")));
                }
                let end = segments[cur].1;
                chain.push(end);
                if let Some(exit) = perimeter(end) {
                    events.push((entry, chains.len(), true));
                    events.push((exit, chains.len(), false));
                    break;
                }
                cur =
                    *by_start.get(&end).ok_or_else(|| inconsistent(cell_b, format!("face on axis {d}: open chain")))?;
            }
            chains.push(chain);
        }
        // Closed loops inside the square.
        let mut islands = Vec::new();
        let mut holes = Vec::new();
        for s in 0..segments.len() {
            if used[s] {
                continue;
            }
            let mut lp = Vec::new();
            let mut cur = s;
            while !std::mem::replace(&mut used[cur], true) {
                lp.push(segments[cur].0);
                cur = *by_start
                    .get(&segments[cur].1)
                    .ok_or_else(|| inconsistent(cell_b, format!("face on axis {d}: open loop")))?;
            }
            if cur != s {
                return Err(inconsistent(cell_b, format!("face on axis {d}: loop does not close")));
            }
            let pts: Vec<Vector3<f64>> = lp.iter().map(|&k| self.local_position(k)).collect();
            let area2: f64 = (0..pts.len())
                .map(|a| {
                    let (pa, pb) = (pts[a], pts[(a + 1) % pts.len()]);
                    pa[u] * pb[w] - pb[u] * pa[w]
                })
                .sum();
            if area2 > 0.0 {
                islands.push(lp);
            } else {
                holes.push(lp);
            }
        }
        let mut regions = Vec::new();
        if chains.is_empty() {
            if self.corner_inside(first_corner) {
                regions.push(corners.to_vec());
            }
        } else {
            events.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut event_of_exit = vec![0; chains.len()];
            for (e, ev) in events.iter().enumerate() {
                if !ev.2 {
                    event_of_exit[ev.1] = e;
                }
            }
            let mut done = vec![false; chains.len()];
            for first in 0..chains.len() {
                if done[first] {
                    continue;
                }
                let mut polygon = Vec::new();
                let mut c = first;
                while !std::mem::replace(&mut done[c], true) {
                    polygon.extend_from_slice(&chains[c]);
                    let e = event_of_exit[c];
                    let (exit_s, _, _) = events[e];
                    let (entry_s, next, is_entry) = events[(e + 1) % events.len()];
                    if !is_entry {
                        return Err(inconsistent(cell_b, format!("face on axis {d}: two exits in a row")));
                    }
                    // Corners passed counter-clockwise from the exit to the next entry.
                    let end = if entry_s > exit_s { entry_s } else { entry_s + 4.0 };
                    let mut k = exit_s.floor() + 1.0;
                    while k < end {
                        polygon.push(corners[(k as usize) % 4]);
                        k += 1.0;
                    }
                    c = next;
                }
                if c != first {
                    return Err(inconsistent(cell_b, format!("face on axis {d}: boundary walk does not close")));
                }
                regions.push(polygon);
            }
        }
        regions.extend(islands);
        if holes.is_empty() {
            return Ok(regions);
        }
        // A region with holes is not a simple polygon: bridge its holes into it and cut the
        // result into triangles (faces with the same two elements; no new vertices, so the
        // surface pieces need no change).
        let with_points = |poly: &[Key]| -> Vec<(Key, Pt)> {
            poly.iter()
                .map(|&k| {
                    let x = self.local_position(k);
                    (k, [x[u], x[w]])
                })
                .collect()
        };
        let regions: Vec<Vec<(Key, Pt)>> = regions.iter().map(|r| with_points(r)).collect();
        let mut region_holes: Vec<Vec<Vec<(Key, Pt)>>> = vec![Vec::new(); regions.len()];
        for hole in &holes {
            let hole = with_points(hole);
            let owner = (0..regions.len())
                .filter(|&r| point_in_polygon(hole[0].1, &regions[r]))
                .min_by(|&a, &b| twice_area(&regions[a]).total_cmp(&twice_area(&regions[b])))
                .ok_or_else(|| inconsistent(cell_b, format!("face on axis {d}: hole outside every region")))?;
            region_holes[owner].push(hole);
        }
        let mut out = Vec::new();
        for (region, hs) in regions.into_iter().zip(region_holes) {
            if hs.is_empty() {
                out.push(region.iter().map(|v| v.0).collect());
                continue;
            }
            let merged = bridge_holes(region, hs)
                .ok_or_else(|| inconsistent(cell_b, format!("face on axis {d}: no bridge to a hole")))?;
            out.extend(ear_clip(merged).ok_or_else(|| {
                inconsistent(cell_b, format!("face on axis {d}: region with holes not triangulated"))
            })?);
        }
        Ok(out)
    }

    /// Slices on the voxelized grid.
    fn slice(&self, grid: &crate::VoxelGrid) -> Result<HexSlicing, GeometryError> {
        // 1. Surface pieces of every listed cell.
        let surface_pieces: Vec<Vec<KeyPolygon>> = (0..grid.len())
            .into_par_iter()
            .map(|c| {
                let mut out = Vec::new();
                for &t in grid.triangles_of(c) {
                    if let Some(poly) = self.clip_triangle(t as usize, grid.cells[c])? {
                        out.push(poly);
                    }
                }
                Ok(out)
            })
            .collect::<Result<_, GeometryError>>()?;

        // 2. Regions of every grid face of a listed cell, computed once per face from the
        // cell below it (whose surface pieces' edges on the face, reversed, bound them).
        let mut faces: Vec<(usize, [i32; 3])> = Vec::with_capacity(4 * grid.len());
        for cell in &grid.cells {
            for d in 0..3 {
                let mut up = *cell;
                up[d] += 1;
                faces.push((d, *cell));
                faces.push((d, up));
            }
        }
        faces.sort_unstable();
        faces.dedup();
        let regions: Vec<Vec<KeyPolygon>> = faces
            .par_iter()
            .map(|&(d, cell_b)| {
                let mut cell_a = cell_b;
                cell_a[d] -= 1;
                let mut segments = Vec::new();
                if let Some(a) = grid.find(cell_a) {
                    let p = cell_b[d];
                    for poly in &surface_pieces[a] {
                        for k in 0..poly.len() {
                            let (s, e) = (poly[k], poly[(k + 1) % poly.len()]);
                            if s.on_plane(d, p) && e.on_plane(d, p) {
                                segments.push((e, s));
                            }
                        }
                    }
                }
                self.face_regions(d, cell_b, &segments)
            })
            .collect::<Result<_, GeometryError>>()?;
        let face_index = |d: usize, cell_b: [i32; 3]| faces.binary_search(&(d, cell_b)).ok();

        // 3. Connected components per cell: its polygons joined through shared edges.
        let pieces: Vec<CellPieces> = (0..grid.len())
            .into_par_iter()
            .map(|c| {
                let cell = grid.cells[c];
                let surface = surface_pieces[c].clone();
                let mut polygons: Vec<&[Key]> = surface.iter().map(Vec::as_slice).collect();
                let mut slot_ranges = [(0, 0); 6];
                for d in 0..3 {
                    for s in 0..2 {
                        let mut cell_b = cell;
                        cell_b[d] += s as i32;
                        let f = face_index(d, cell_b).ok_or_else(|| inconsistent(cell, "face not listed"))?;
                        let start = polygons.len();
                        polygons.extend(regions[f].iter().map(Vec::as_slice));
                        slot_ranges[2 * d + s] = (start, polygons.len());
                    }
                }
                let mut sets = UnionFind::new(polygons.len());
                let mut edge_owner: HashMap<(Key, Key), usize> = HashMap::new();
                for (pi, poly) in polygons.iter().enumerate() {
                    for k in 0..poly.len() {
                        let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
                        let edge = if a < b { (a, b) } else { (b, a) };
                        if let Some(&other) = edge_owner.get(&edge) {
                            sets.union(pi, other);
                        } else {
                            edge_owner.insert(edge, pi);
                        }
                    }
                }
                let mut label = vec![usize::MAX; polygons.len()];
                let mut components = 0;
                let mut component = vec![0; polygons.len()];
                for pi in 0..polygons.len() {
                    let r = sets.find(pi);
                    if label[r] == usize::MAX {
                        label[r] = components;
                        components += 1;
                    }
                    component[pi] = label[r];
                }
                let slot_component = std::array::from_fn(|s| component[slot_ranges[s].0..slot_ranges[s].1].to_vec());
                let surface_component = component[..surface.len()].to_vec();
                Ok(CellPieces { surface, components, surface_component, slot_component })
            })
            .collect::<Result<_, GeometryError>>()?;

        // 4. Element numbering in cell order, then faces with numbered vertices.
        let mut element_base = Vec::with_capacity(pieces.len());
        let mut element_cells = Vec::new();
        for (c, piece) in pieces.iter().enumerate() {
            element_base.push(element_cells.len());
            element_cells.extend(std::iter::repeat_n(grid.cells[c], piece.components));
        }
        let mut vertex_ids: HashMap<Key, u32> = HashMap::new();
        let mut vertices = Vec::new();
        let mut number = |polygon: &[Key]| -> Vec<u32> {
            polygon
                .iter()
                .map(|&k| {
                    *vertex_ids.entry(k).or_insert_with(|| {
                        vertices.push(self.world_position(k));
                        (vertices.len() - 1) as u32
                    })
                })
                .collect()
        };
        let mut mesh_faces = Vec::new();
        for (c, piece) in pieces.iter().enumerate() {
            for (poly, &comp) in piece.surface.iter().zip(&piece.surface_component) {
                mesh_faces.push(PolyFace {
                    polygon: number(poly),
                    inner: (element_base[c] + comp) as u32,
                    outer: None,
                });
            }
        }
        for (f, &(d, cell_b)) in faces.iter().enumerate() {
            if regions[f].is_empty() {
                continue;
            }
            let mut cell_a = cell_b;
            cell_a[d] -= 1;
            let (Some(a), Some(b)) = (grid.find(cell_a), grid.find(cell_b)) else {
                return Err(inconsistent(cell_b, format!("inside region on axis {d} next to an outside cell")));
            };
            for (r, poly) in regions[f].iter().enumerate() {
                let inner = element_base[a] + pieces[a].slot_component[2 * d + 1][r];
                let outer = element_base[b] + pieces[b].slot_component[2 * d][r];
                mesh_faces.push(PolyFace { polygon: number(poly), inner: inner as u32, outer: Some(outer as u32) });
            }
        }
        let num_elements = element_cells.len();
        Ok(HexSlicing {
            mesh: PolyhedralMesh { vertices, faces: mesh_faces, num_elements },
            element_cells,
            origin: self.origin,
            cell_size: self.h,
            merge: MergeReport::default(),
        })
    }
}

/// A point in the plane of a grid face, in the face's `(u, w)` grid coordinates.
type Pt = [f64; 2];

/// Twice the signed area of triangle `(o, a, b)`.
fn cross(o: Pt, a: Pt, b: Pt) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// Twice the signed area of a polygon.
fn twice_area(poly: &[(Key, Pt)]) -> f64 {
    (0..poly.len()).map(|k| cross([0.0, 0.0], poly[k].1, poly[(k + 1) % poly.len()].1)).sum()
}

/// Even–odd point-in-polygon test (a doubled bridge edge crosses the ray twice, so it also
/// works on bridged polygons).
fn point_in_polygon(q: Pt, poly: &[(Key, Pt)]) -> bool {
    let mut inside = false;
    for k in 0..poly.len() {
        let (a, b) = (poly[k].1, poly[(k + 1) % poly.len()].1);
        if (a[1] > q[1]) != (b[1] > q[1]) && q[0] < a[0] + (q[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]) {
            inside = !inside;
        }
    }
    inside
}

/// Whether the closed segments `ab` and `cd` meet.
fn segments_meet(a: Pt, b: Pt, c: Pt, d: Pt) -> bool {
    let (o1, o2, o3, o4) = (cross(a, b, c), cross(a, b, d), cross(c, d, a), cross(c, d, b));
    let within = |p: Pt, q: Pt, r: Pt| {
        r[0] >= p[0].min(q[0]) && r[0] <= p[0].max(q[0]) && r[1] >= p[1].min(q[1]) && r[1] <= p[1].max(q[1])
    };
    (o1 * o2 < 0.0 && o3 * o4 < 0.0)
        || (o1 == 0.0 && within(a, b, c))
        || (o2 == 0.0 && within(a, b, d))
        || (o3 == 0.0 && within(c, d, a))
        || (o4 == 0.0 && within(c, d, b))
}

/// Joins clockwise `holes` to the counter-clockwise `outer` polygon by bridges (doubled
/// edges between mutually visible vertices, shortest first), giving one weakly simple
/// polygon; `None` if some hole has no visible vertex.
fn bridge_holes(mut outer: Vec<(Key, Pt)>, mut holes: Vec<Vec<(Key, Pt)>>) -> Option<Vec<(Key, Pt)>> {
    while let Some(hole) = holes.pop() {
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (i, m) in hole.iter().enumerate() {
            for (j, v) in outer.iter().enumerate() {
                pairs.push(((m.1[0] - v.1[0]).powi(2) + (m.1[1] - v.1[1]).powi(2), i, j));
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let rings = |outer: &[(Key, Pt)]| {
            let mut all: Vec<Vec<(Key, Pt)>> = vec![outer.to_vec(), hole.clone()];
            all.extend(holes.iter().cloned());
            all
        };
        let all = rings(&outer);
        let visible = |m: (Key, Pt), v: (Key, Pt)| {
            let blocked = all.iter().any(|ring| {
                (0..ring.len()).any(|k| {
                    let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
                    let incident = [a.0, b.0].iter().any(|&x| x == m.0 || x == v.0);
                    !incident && segments_meet(m.1, v.1, a.1, b.1)
                })
            });
            let mid = [(m.1[0] + v.1[0]) / 2.0, (m.1[1] + v.1[1]) / 2.0];
            !blocked && point_in_polygon(mid, &outer) && all[1..].iter().all(|h| !point_in_polygon(mid, h))
        };
        let &(_, i, j) = pairs.iter().find(|&&(_, i, j)| visible(hole[i], outer[j]))?;
        let mut merged = Vec::with_capacity(outer.len() + hole.len() + 2);
        merged.extend_from_slice(&outer[..=j]);
        merged.extend((0..=hole.len()).map(|k| hole[(i + k) % hole.len()]));
        merged.extend_from_slice(&outer[j..]);
        outer = merged;
    }
    Some(outer)
}

/// Ear clipping of a (weakly) simple counter-clockwise polygon into triangles of positive
/// area; `None` if no ear is found.
fn ear_clip(mut poly: Vec<(Key, Pt)>) -> Option<Vec<KeyPolygon>> {
    // Strictly convex corners only: collinear vertices (along the square's edges, or crossings
    // of a flat wall's diagonal) must not become zero-area triangles, and rounding makes their
    // cross products ~1e-16, not 0. In grid units: far above rounding, far below real ears.
    const MIN_TWICE_AREA: f64 = GRID_MARGIN;
    let mut out = Vec::with_capacity(poly.len());
    while poly.len() > 3 {
        let n = poly.len();
        let ear = (0..n).find(|&i| {
            let (a, b, c) = (poly[(i + n - 1) % n], poly[i], poly[(i + 1) % n]);
            if cross(a.1, b.1, c.1) <= MIN_TWICE_AREA {
                return false;
            }
            !poly.iter().any(|p| {
                p.0 != a.0
                    && p.0 != b.0
                    && p.0 != c.0
                    && cross(a.1, b.1, p.1) >= 0.0
                    && cross(b.1, c.1, p.1) >= 0.0
                    && cross(c.1, a.1, p.1) >= 0.0
            })
        })?;
        out.push(vec![poly[(ear + n - 1) % n].0, poly[ear].0, poly[(ear + 1) % n].0]);
        poly.remove(ear);
    }
    if cross(poly[0].1, poly[1].1, poly[2].1) <= MIN_TWICE_AREA {
        return None;
    }
    out.push(poly.iter().map(|v| v.0).collect());
    Some(out)
}
