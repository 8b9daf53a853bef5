//! The render surface of a virtual node mesh: every cell face covered by the object surface or a
//! cut, triangulated, each vertex embedded (barycentric weights) in the duplicate that owns it.
//!
//! Faces keep the orientation of their cell (outward), so the two sides of a cut get their own,
//! opposite copies. Where a vertex of one face lies on an edge of another face of the same piece
//! (cells split by different planes meet along that edge), it is inserted into that edge, so
//! that welding the vertices of a piece by rest position leaves no T-junction: the surface of
//! every piece is then closed (every directed edge is matched by its reverse).

use crate::arrangement::Cover;
use crate::mesh::VirtualNodeMesh;
use cleave_core::{Embedding, Point3, Real, Vector3};
use std::collections::HashMap;

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

struct Polygon {
    duplicate: u32,
    kind: SurfaceKind,
    points: Vec<Point3<Real>>,
}

/// A uniform grid of points for "which vertices lie near this segment" queries.
struct PointGrid {
    cell: Real,
    buckets: HashMap<[i64; 3], Vec<Point3<Real>>>,
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
    /// T-junctions resolved within each piece, fanned into triangles from each face's vertex
    /// average.
    pub fn render_surface(&self) -> RenderSurface {
        let h = self.lattice().h;
        let tolerance = T_JUNCTION_TOLERANCE * h;
        // Covered faces, grouped by piece.
        let pieces = self.pieces();
        let mut polygons_of_piece: Vec<Vec<Polygon>> = Vec::with_capacity(pieces.len());
        for piece in &pieces {
            let mut polygons = Vec::new();
            for &d in &piece.duplicates {
                let cells = self.duplicate_cells(d as usize);
                for cell in &cells.cells {
                    for face in &cell.faces {
                        let kind = match face.cover {
                            Cover::Open => continue,
                            Cover::Surface => SurfaceKind::Original,
                            Cover::Cut => SurfaceKind::Cut,
                        };
                        polygons.push(Polygon {
                            duplicate: d,
                            kind,
                            points: face.verts.iter().map(|&v| cells.point(v)).collect(),
                        });
                    }
                }
            }
            polygons_of_piece.push(polygons);
        }
        let mut surface = RenderSurface { embedding: Embedding::new(), ..Default::default() };
        let mut found = Vec::new();
        let mut loop_: Vec<Point3<Real>> = Vec::new();
        for polygons in &polygons_of_piece {
            let mut grid = PointGrid { cell: 0.25 * h, buckets: HashMap::new() };
            for polygon in polygons {
                for p in &polygon.points {
                    let key = grid.key(p);
                    grid.buckets.entry(key).or_default().push(*p);
                }
            }
            for bucket in grid.buckets.values_mut() {
                bucket
                    .sort_by(|a, b| (a.x, a.y, a.z).partial_cmp(&(b.x, b.y, b.z)).unwrap_or(std::cmp::Ordering::Equal));
                bucket.dedup();
            }
            // Vertices are shared within one duplicate (same embedding) by exact position.
            let mut index: HashMap<(u32, [u64; 3]), u32> = HashMap::new();
            for polygon in polygons {
                let d = polygon.duplicate as usize;
                let shape = self.duplicate_shape(d);
                let nodes = self.duplicate_nodes_of(d);
                let mut vertex = |surface: &mut RenderSurface, p: Point3<Real>| -> u32 {
                    *index.entry((polygon.duplicate, [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])).or_insert_with(
                        || {
                            surface.positions.push(p);
                            surface.embedding.push_row(&nodes, &shape.barycentric(&p));
                            surface.positions.len() as u32 - 1
                        },
                    )
                };
                loop_.clear();
                let n = polygon.points.len();
                for i in 0..n {
                    let (a, b) = (polygon.points[i], polygon.points[(i + 1) % n]);
                    loop_.push(a);
                    grid.on_segment(&a, &b, tolerance, &mut found);
                    loop_.extend(found.iter().map(|f| f.1));
                }
                let centre =
                    Point3::from(loop_.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / loop_.len() as Real);
                let c = vertex(&mut surface, centre);
                let ids: Vec<u32> = loop_.iter().map(|p| vertex(&mut surface, *p)).collect();
                for i in 0..ids.len() {
                    let (a, b) = (ids[i], ids[(i + 1) % ids.len()]);
                    if a != b {
                        surface.triangles.push([c, a, b]);
                        surface.kinds.push(polygon.kind);
                        surface.duplicates.push(polygon.duplicate);
                    }
                }
            }
        }
        surface
    }
}
