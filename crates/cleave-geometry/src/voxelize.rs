//! Voxelization of a closed surface into the cells a hexahedral simulation mesh uses
//! (Müller et al. 2004, §2.1): cells that intersect the surface or lie inside it.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::overlap::triangle_aabb_overlap;
use crate::{GeometryError, TriangleMesh};

/// Largest number of cells of the (unpadded) grid [`voxelize`] accepts.
pub const MAX_GRID_CELLS: u64 = 200_000_000;

/// Cells are treated as closed cubes inflated by this fraction of the cell size, so a
/// surface touching a shared cell face (up to rounding) is listed in both neighbours.
pub const CELL_TOLERANCE: f64 = 1e-9;

/// The cells of a regular grid that intersect or lie inside a closed surface, with the
/// triangles intersecting each cell (compressed sparse rows).
///
/// Cell `[i, j, k]` is the cube from `origin + cell_size * (i, j, k)` to
/// `origin + cell_size * (i + 1, j + 1, k + 1)`. Cells are sorted by `(k, j, i)` (z-major).
/// The triangles of cell `c` are
/// `cell_triangles[cell_triangles_offsets[c] as usize..cell_triangles_offsets[c + 1] as usize]`
/// in increasing order; the list is empty exactly for cells completely inside the surface.
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelGrid {
    /// Minimum corner of cell `[0, 0, 0]`.
    pub origin: Point3<f64>,
    /// Edge length of a cell.
    pub cell_size: f64,
    /// Number of grid cells along x, y and z; every cell index satisfies
    /// `0 <= cell[d] < dims[d]`.
    pub dims: [i32; 3],
    /// Integer coordinates of the listed cells, sorted by `(k, j, i)`.
    pub cells: Vec<[i32; 3]>,
    /// CSR offsets into `cell_triangles`, `cells.len() + 1` entries starting at 0.
    pub cell_triangles_offsets: Vec<u32>,
    /// Triangle indices intersecting each cell, concatenated.
    pub cell_triangles: Vec<u32>,
}

impl VoxelGrid {
    /// Number of listed cells.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether no cell is listed.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// Triangles intersecting listed cell `c` (empty for inside cells and out-of-range `c`).
    pub fn triangles_of(&self, c: usize) -> &[u32] {
        match (self.cell_triangles_offsets.get(c), self.cell_triangles_offsets.get(c + 1)) {
            (Some(&a), Some(&b)) => self.cell_triangles.get(a as usize..b as usize).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// Whether listed cell `c` intersects the surface (as opposed to lying inside).
    pub fn is_surface(&self, c: usize) -> bool {
        !self.triangles_of(c).is_empty()
    }

    /// Minimum corner of the cube of cell `[i, j, k]`.
    pub fn cell_min(&self, cell: [i32; 3]) -> Point3<f64> {
        self.origin + Vector3::from(cell.map(f64::from)) * self.cell_size
    }

    /// Center of the cube of cell `[i, j, k]`.
    pub fn cell_center(&self, cell: [i32; 3]) -> Point3<f64> {
        self.origin + Vector3::from(cell.map(|x| f64::from(x) + 0.5)) * self.cell_size
    }

    /// Position of cell `[i, j, k]` in `cells`, if listed.
    pub fn find(&self, cell: [i32; 3]) -> Option<usize> {
        let key = |c: &[i32; 3]| (c[2], c[1], c[0]);
        self.cells.binary_search_by(|c| key(c).cmp(&key(&cell))).ok()
    }

    /// Integer coordinates of the grid cell containing `p` (which may be outside the grid or
    /// not listed), or `None` for non-finite `p` or coordinates beyond `i32`.
    pub fn cell_of(&self, p: &Point3<f64>) -> Option<[i32; 3]> {
        let q = (p - self.origin) / self.cell_size;
        let mut out = [0; 3];
        for d in 0..3 {
            let f = q[d].floor();
            if !(f >= f64::from(i32::MIN) && f <= f64::from(i32::MAX)) {
                return None;
            }
            out[d] = f as i32;
        }
        Some(out)
    }
}

/// Voxelizes a closed surface (Müller et al. 2004, §2.1).
///
/// The grid has `origin = mesh.aabb().0 - cell_size / 2` in every coordinate and
/// `floor(extent / cell_size + 1/2) + 1` cells per axis, just enough to cover the bounding
/// box (of all vertices, used or not). The minimum faces of the bounding box thus pass
/// through cell centers, not cell faces; elsewhere a vertex may lie on a cell face by
/// coincidence, which the tolerance below covers. A cell is listed if its closed cube (inflated by [`CELL_TOLERANCE`]` *
/// cell_size`) intersects a triangle, or if it lies completely inside the surface. Inside
/// cells are found without point queries: the non-intersected cells of the grid padded by
/// one layer are flood-filled (6-connected) from a corner, and non-intersected cells not
/// reached are inside. For a surface that is not closed the fill leaks, and only the
/// intersected cells are listed.
///
/// Validating the mesh is the caller's job ([`TriangleMesh::validate_closed`]), but no input
/// makes this panic. Errors: [`GeometryError::InvalidCellSize`] for a non-positive or
/// non-finite `cell_size`, [`GeometryError::GridTooLarge`] beyond [`MAX_GRID_CELLS`] cells (the
/// flood fill additionally uses one byte per cell of the padded grid, at most 9 times the
/// cell count for a grid one cell thick), [`GeometryError::NoTriangles`],
/// [`GeometryError::NonFiniteVertex`] and [`GeometryError::IndexOutOfRange`].
pub fn voxelize(mesh: &TriangleMesh, cell_size: f64) -> Result<VoxelGrid, GeometryError> {
    let h = cell_size;
    if !(h.is_finite() && h > 0.0) {
        return Err(GeometryError::InvalidCellSize { cell_size });
    }
    if mesh.triangles.is_empty() {
        return Err(GeometryError::NoTriangles);
    }
    if let Some((vertex, p)) = mesh.vertices.iter().enumerate().find(|(_, p)| !p.iter().all(|x| x.is_finite())) {
        return Err(GeometryError::NonFiniteVertex { vertex, position: [p.x, p.y, p.z] });
    }
    let vertex_count = mesh.vertices.len();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&index) = tri.iter().find(|&&i| i as usize >= vertex_count) {
            return Err(GeometryError::IndexOutOfRange { triangle: t, vertices: *tri, index, vertex_count });
        }
    }

    let (lo, hi) = mesh.aabb();
    let origin = lo - Vector3::repeat(h / 2.0);
    let dims_f: [f64; 3] = std::array::from_fn(|d| ((hi[d] - lo[d]) / h + 0.5).floor() + 1.0);
    voxelize_on_grid(mesh, origin, h, dims_f)
}

/// [`voxelize`] on a caller-chosen grid: `dims_f` cells (whole numbers, possibly huge) of edge
/// `h` from `origin`. The mesh must already have passed the input checks of [`voxelize`]; the
/// grid must cover the mesh's bounding box (cells outside it are simply not listed).
pub(crate) fn voxelize_on_grid(
    mesh: &TriangleMesh,
    origin: Point3<f64>,
    h: f64,
    dims_f: [f64; 3],
) -> Result<VoxelGrid, GeometryError> {
    let cells_f: f64 = dims_f.iter().product();
    if cells_f.is_nan() || cells_f > MAX_GRID_CELLS as f64 {
        return Err(GeometryError::GridTooLarge { dims: dims_f, cells: cells_f, limit: MAX_GRID_CELLS });
    }
    // Each dimension is now at most MAX_GRID_CELLS, so these casts are exact.
    let dims = dims_f.map(|n| n as usize);
    let [nx, ny, nz] = dims;

    // Vertices relative to the grid origin.
    let local: Vec<Vector3<f64>> = mesh.vertices.iter().map(|v| v - origin).collect();
    let tol = CELL_TOLERANCE * h;

    // (cell key, triangle) for every intersecting pair; key = (k * ny + j) * nx + i.
    let mut pairs: Vec<(u64, u32)> = (0..mesh.triangles.len())
        .into_par_iter()
        .fold(Vec::new, |mut acc, t| {
            let tri = mesh.triangles[t].map(|i| local[i as usize]);
            for_each_overlapping_cell(&tri, h, tol, dims, |[i, j, k]| {
                acc.push((((k * ny + j) * nx + i) as u64, t as u32));
            });
            acc
        })
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });
    pairs.par_sort_unstable();
    if u32::try_from(pairs.len()).is_err() {
        return Err(GeometryError::GridTooLarge { dims: dims_f, cells: cells_f, limit: MAX_GRID_CELLS });
    }

    // Padded grid: 0 = unknown, 1 = intersected, 2 = outside.
    let [px, py, pz] = dims.map(|n| n + 2);
    let padded = |i: usize, j: usize, k: usize| (k * py + j) * px + i;
    let mut state = vec![0u8; px * py * pz];
    for &(key, _) in &pairs {
        let key = key as usize;
        let (i, j, k) = (key % nx, (key / nx) % ny, key / (nx * ny));
        state[padded(i + 1, j + 1, k + 1)] = 1;
    }
    flood_outside(&mut state, [px, py, pz]);

    let mut cells = Vec::new();
    let mut offsets = vec![0u32];
    let mut cell_triangles = Vec::with_capacity(pairs.len());
    let mut next = 0;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if state[padded(i + 1, j + 1, k + 1)] == 2 {
                    continue;
                }
                let key = ((k * ny + j) * nx + i) as u64;
                while next < pairs.len() && pairs[next].0 == key {
                    cell_triangles.push(pairs[next].1);
                    next += 1;
                }
                cells.push([i as i32, j as i32, k as i32]);
                offsets.push(cell_triangles.len() as u32);
            }
        }
    }

    Ok(VoxelGrid {
        origin,
        cell_size: h,
        dims: dims.map(|n| n as i32),
        cells,
        cell_triangles_offsets: offsets,
        cell_triangles,
    })
}

/// Calls `f` with every cell `[i, j, k]` of a grid with `dims` cells whose cube, inflated
/// by `tol`, intersects the triangle `tri` (coordinates relative to the grid origin).
fn for_each_overlapping_cell(
    tri: &[Vector3<f64>; 3],
    h: f64,
    tol: f64,
    dims: [usize; 3],
    mut f: impl FnMut([usize; 3]),
) {
    // Cell index range [first, last] covering the interval [a, b] on an axis of `n` cells.
    let range = |a: f64, b: f64, n: usize| -> Option<(usize, usize)> {
        let first = ((a - tol) / h).floor().max(0.0);
        let last = ((b + tol) / h).floor().min(n as f64 - 1.0);
        // NaN fails both comparisons and yields None.
        (first <= last).then_some((first as usize, last as usize))
    };
    let mut ranges = [(0, 0); 3];
    for d in 0..3 {
        let a = tri[0][d].min(tri[1][d]).min(tri[2][d]);
        let b = tri[0][d].max(tri[1][d]).max(tri[2][d]);
        match range(a, b, dims[d]) {
            Some(r) => ranges[d] = r,
            None => return,
        }
    }
    let points = tri.map(Point3::from);
    let test = |cell: [usize; 3]| {
        let lo = Point3::from(cell.map(|x| x as f64 * h - tol));
        let hi = Point3::from(cell.map(|x| (x + 1) as f64 * h + tol));
        triangle_aabb_overlap(&points, &lo, &hi)
    };

    // Walk columns along the axis `c` where the triangle's normal is largest, restricting
    // each column to the cells the triangle's plane passes through.
    let normal = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
    let c = normal.iamax();
    let (u, w) = ((c + 1) % 3, (c + 2) % 3);
    let plane_ok = normal[c].abs() > 0.0 && normal.iter().all(|x| x.is_finite());
    let offset = normal.dot(&tri[0]);
    for iu in ranges[u].0..=ranges[u].1 {
        for iw in ranges[w].0..=ranges[w].1 {
            let (mut c_first, mut c_last) = ranges[c];
            if plane_ok {
                // Height of the plane over the four corners of the column's cross-section.
                let mut lo = f64::INFINITY;
                let mut hi = f64::NEG_INFINITY;
                for xu in [iu as f64 * h - tol, (iu + 1) as f64 * h + tol] {
                    for xw in [iw as f64 * h - tol, (iw + 1) as f64 * h + tol] {
                        let xc = (offset - normal[u] * xu - normal[w] * xw) / normal[c];
                        lo = lo.min(xc);
                        hi = hi.max(xc);
                    }
                }
                // Generous slack: the exact test below decides.
                let slack = 1e-6 * h;
                match range(lo - slack, hi + slack, dims[c]) {
                    Some((a, b)) => {
                        c_first = c_first.max(a);
                        c_last = c_last.min(b);
                    }
                    None => continue,
                }
            }
            for ic in c_first..=c_last {
                let mut cell = [0; 3];
                cell[u] = iu;
                cell[w] = iw;
                cell[c] = ic;
                if test(cell) {
                    f(cell);
                }
            }
        }
    }
}

/// Marks with 2 every cell 6-connected to cell 0 through cells in state 0.
fn flood_outside(state: &mut [u8], [px, py, pz]: [usize; 3]) {
    let mut stack = vec![0usize];
    state[0] = 2;
    let layer = px * py;
    while let Some(idx) = stack.pop() {
        let (i, j, k) = (idx % px, (idx / px) % py, idx / layer);
        let mut visit = |n: usize| {
            if state[n] == 0 {
                state[n] = 2;
                stack.push(n);
            }
        };
        if i > 0 {
            visit(idx - 1);
        }
        if i + 1 < px {
            visit(idx + 1);
        }
        if j > 0 {
            visit(idx - px);
        }
        if j + 1 < py {
            visit(idx + px);
        }
        if k > 0 {
            visit(idx - layer);
        }
        if k + 1 < pz {
            visit(idx + layer);
        }
    }
}
