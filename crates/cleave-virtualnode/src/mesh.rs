//! The virtual node mesh (sifakis2007 §3–4): a BCC lattice carved by the object's surface,
//! one duplicate of a lattice tetrahedron per material region, node copies identified across
//! materially contiguous faces; corotated linear tetrahedra scaled by region volume; cutting by
//! triangle soups.

use crate::FastMap;
use crate::lattice::{BccLattice, LatticeTetCorners, number_nodes};
use crate::tet::{TetRule, TetShape};
use cleave_core::rotation::write_frame_rotations;
use cleave_core::{
    BlockSet, BlockSetBuilder, CutSurface, Cuttable, Discretization, DofRemap, EmbedError, Embedding, FieldSample,
    FrameRemap, Mass, Material, Matrix3, Piece, Point3, Real, RotationStats, TopologyChange, TopologyError, Vector3,
};
use cleave_geometry::arrangement::{Arrangement, Cover, OVERLAP_TOLERANCE, TET_FACES};
use cleave_geometry::predicates::{convex_overlap_area, largest_component, project};
use cleave_geometry::{InsideTester, TriangleMesh, UnionFind};
use nalgebra::{DMatrix, Point2};
use rayon::prelude::*;

/// Why a virtual node mesh could not be built.
#[derive(Debug, thiserror::Error)]
pub enum VirtualNodeError {
    /// Lattice spacing not finite and positive, or too small for the coordinates' precision.
    #[error("lattice spacing must be finite, > 0 and resolvable at the surface's coordinates, got {0}")]
    Spacing(Real),
    /// The surface is unusable for carving.
    #[error("surface: {0}")]
    Surface(#[from] cleave_geometry::GeometryError),
    /// The lattice over the surface's bounding box would be too large.
    #[error("a lattice of spacing {h} over the surface needs {cubes} cubes (limit {limit})")]
    TooLarge {
        /// the spacing asked for
        h: Real,
        /// cubes needed
        cubes: u64,
        /// the limit
        limit: u64,
    },
    /// Carving left no material.
    #[error("carving left no material (is the surface inside out or smaller than the lattice?)")]
    Empty,
    /// Internal block bookkeeping failed (a bug).
    #[error(transparent)]
    Blocks(#[from] cleave_core::BlockSetError),
}

/// Largest number of lattice cubes a mesh may have.
pub const MAX_LATTICE_CUBES: u64 = 20_000_000;

/// Iterations of the warm-started rotation extraction.
const ROTATION_ITERATIONS: usize = 8;

/// One lattice tetrahedron that holds material.
#[derive(Clone, Debug)]
struct LatticeTet {
    /// Lattice node index of each corner.
    nodes: [u32; 4],
    /// Rest shape.
    shape: TetShape,
    /// Id of its full rest stiffness in the library.
    rest_class: u32,
    /// Neighbour across face `i` (opposite corner `i`): tet and its face index.
    neighbors: [Option<(u32, u8)>; 4],
}

/// One duplicate of a lattice tetrahedron: a material region and its node copies.
#[derive(Clone, Debug)]
struct Duplicate {
    tet: u32,
    cells: Arrangement,
    volume: Real,
    nodes: [u32; 4],
    /// Derived from the cells once, when the duplicate is made.
    cache: DuplicateCache,
}

/// What a rebuild needs of a duplicate, computed once per duplicate.
#[derive(Clone, Debug)]
struct DuplicateCache {
    /// Open pieces of each tetrahedron face.
    faces: [FacePieces; 4],
    /// `∫_region N_k` for the four corners.
    shape_integrals: [Real; 4],
    /// Bounding box of the cells.
    bounds: (Point3<Real>, Point3<Real>),
    /// The rest stiffness scaled by the volume fraction, unless the region is the whole
    /// tetrahedron (which shares its lattice class's matrix).
    stiffness: Option<DMatrix<Real>>,
}

impl DuplicateCache {
    fn new(tet: &LatticeTet, cells: &Arrangement, volume: Real, material: &Material) -> Self {
        let faces = std::array::from_fn(|f| {
            if cells.face_is_whole(f) {
                return FacePieces::Whole;
            }
            let axis = face_axis(tet, f);
            FacePieces::Pieces(
                cells
                    .open_face_pieces(f)
                    .iter()
                    .map(|loop_| loop_.iter().map(|p| project(p, axis)).collect())
                    .collect(),
            )
        });
        let mut shape_integrals = [0.0; 4];
        for_each_cell_point(cells, &TetRule::of_degree(1), &mut |p, w| {
            let n = tet.shape.barycentric(&p);
            for c in 0..4 {
                shape_integrals[c] += w * n[c];
            }
        });
        let fraction = volume / tet.shape.volume;
        // A whole tetrahedron (its volume from the cells equals the determinant's up to
        // rounding) shares the lattice class's matrix.
        let stiffness = ((fraction - 1.0).abs() > 1e-12).then(|| tet.shape.stiffness(material, fraction));
        Self { faces, shape_integrals, bounds: cells.bounds(), stiffness }
    }
}

impl Duplicate {
    fn new(
        tet_index: u32,
        tet: &LatticeTet,
        cells: Arrangement,
        volume: Real,
        nodes: [u32; 4],
        material: &Material,
    ) -> Self {
        let cache = DuplicateCache::new(tet, &cells, volume, material);
        Self { tet: tet_index, cells, volume, nodes, cache }
    }
}

/// Calls `visit(point, weight)` for a rule on every cell, each convex cell fanned into
/// tetrahedra from its vertex average.
fn for_each_cell_point(cells: &Arrangement, rule: &TetRule, visit: &mut dyn FnMut(Point3<Real>, Real)) {
    for cell in &cells.cells {
        let apex = cells.cell_center(cell);
        for face in &cell.faces {
            let p0 = cells.point(face.verts[0]);
            for w in face.verts[1..].windows(2) {
                let (p1, p2) = (cells.point(w[0]), cells.point(w[1]));
                let (e1, e2, e3) = (p0 - apex, p1 - apex, p2 - apex);
                let volume = e1.dot(&e2.cross(&e3)) / 6.0;
                if volume == 0.0 {
                    continue;
                }
                for (q, wq) in rule.points.iter().zip(&rule.weights) {
                    visit(apex + e1 * q[0] + e2 * q[1] + e3 * q[2], wq * volume);
                }
            }
        }
    }
}

/// Statistics of the last topology change.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CutStats {
    /// Duplicates whose cells a triangle touched.
    pub touched: usize,
    /// Duplicates before and after.
    pub duplicates: (usize, usize),
    /// Nodes before and after.
    pub nodes: (usize, usize),
}

/// How the mass `ρ·V_region` of a duplicate is lumped to its four nodes. Both give the total
/// mass `ρ·Σ V_region` exactly.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MassLumping {
    /// `m_k = ρ ∫_region N_k`: the row sums of the consistent mass. Puts every region's mass at
    /// its own centre of mass and makes `M g` the exact gravity load. A virtual node far from a
    /// small region gets almost none while the region's stiffness reaches it undiminished (a cap
    /// of 1e-19 of a tetrahedron next to a node gave `h² K_kk / m_k` = 9.5e17 at E = 1e12,
    /// ν = 0.4999, beyond what a Cholesky factorization in `f64` resolves); pieces below
    /// [`SPECK_VOLUME`] are therefore lumped uniformly (docs/math/virtual-node.md §4).
    #[default]
    RowSum,
    /// `m_k = ρ V_region / 4` (sifakis2007's duplicates of the full tetrahedron, scaled): the
    /// mass-to-stiffness ratio of every duplicate equals that of the uncut tetrahedron.
    Uniform,
}

/// Pieces smaller than this fraction of a lattice tetrahedron's volume are *specks*: under
/// [`MassLumping::RowSum`] their duplicates are lumped uniformly (`ρ V / 4` per node), because
/// row sums give a speck's far virtual nodes a vanishing share of its mass under its whole
/// stiffness (docs/math/virtual-node.md §4, "Mass of specks"). A speck's mass, volume and
/// momentum are its own either way; only how its mass sits on its nodes changes.
pub const SPECK_VOLUME: Real = 1e-9;

/// A BCC lattice carved into an object and cut, simulated with corotated linear tetrahedra.
#[derive(Debug)]
pub struct VirtualNodeMesh {
    material: Material,
    lattice: BccLattice,
    lattice_nodes: Vec<[i32; 3]>,
    tets: Vec<LatticeTet>,
    cube_tets: FastMap<[i32; 3], Vec<u32>>,
    rest_library: Vec<DMatrix<Real>>,
    duplicates: Vec<Duplicate>,
    dups_of_tet: Vec<Vec<u32>>,
    node_lattice: Vec<u32>,
    rest: Vec<Real>,
    mass: Mass,
    blocks: BlockSet,
    epoch: u64,
    last_cut: CutStats,
    lumping: MassLumping,
    /// Contiguous duplicate pairs across lattice faces: `(a, face of a, b, face of b)`.
    links: Vec<Link>,
    /// The carved object's surface, kept for rendering triangles the cuts left whole.
    source: SourceSurface,
    /// What the last cut changed, for the render surface to redo only what it must.
    last_change: Option<ChangeRecord>,
    /// The last render surface's polygons and loops (see [`crate::surface`]).
    pub(crate) render_cache: std::sync::Mutex<crate::surface::RenderCache>,
}

/// A copy with its own render cache (what a cut prepared off the step's thread starts from).
impl Clone for VirtualNodeMesh {
    fn clone(&self) -> Self {
        let render_cache = self.render_cache.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone();
        Self {
            material: self.material,
            lattice: self.lattice.clone(),
            lattice_nodes: self.lattice_nodes.clone(),
            tets: self.tets.clone(),
            cube_tets: self.cube_tets.clone(),
            rest_library: self.rest_library.clone(),
            duplicates: self.duplicates.clone(),
            dups_of_tet: self.dups_of_tet.clone(),
            node_lattice: self.node_lattice.clone(),
            rest: self.rest.clone(),
            mass: self.mass.clone(),
            blocks: self.blocks.clone(),
            epoch: self.epoch,
            last_cut: self.last_cut,
            lumping: self.lumping,
            links: self.links.clone(),
            source: self.source.clone(),
            last_change: self.last_change.clone(),
            render_cache: std::sync::Mutex::new(render_cache),
        }
    }
}

/// What one topology change replaced: read by the render surface, which keeps the polygons
/// (and their loops) of everything the change cannot have reached.
#[derive(Clone, Debug)]
pub(crate) struct ChangeRecord {
    /// The epoch before the change.
    pub epoch_before: u64,
    /// New index of every old duplicate that was kept unchanged.
    pub new_of_old: Vec<Option<u32>>,
    /// Lattice tetrahedra with a replaced duplicate.
    pub changed_tet: Vec<bool>,
}

/// The object surface a mesh was carved from, outward oriented, with the lattice tetrahedra
/// (kept ones only) each triangle may meet: the render surface draws a triangle whole, without
/// clipping it to tetrahedra, while no cut has touched any of them.
#[derive(Clone, Debug, Default)]
pub(crate) struct SourceSurface {
    /// Non-degenerate triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[Point3<Real>; 3]>,
    /// Kept lattice tetrahedra whose bounding box meets each triangle's.
    pub tets_of_triangle: Vec<Vec<u32>>,
    /// The inverse: triangles per kept lattice tetrahedron.
    pub triangles_of_tet: Vec<Vec<u32>>,
    /// Per kept lattice tetrahedron, the source triangle of each object-surface face of its
    /// carved duplicates (cell and face order); valid while no cut has touched it.
    pub face_sources: Vec<Vec<u32>>,
}

/// Two duplicates contiguous across a lattice face: `(a, face of a, b, face of b)`.
type Link = (u32, u8, u32, u8);

/// What a rebuild after a cut may keep: the old links between duplicates the cut left alone.
struct LinkReuse {
    old_links: Vec<Link>,
    /// New index of every old duplicate that was kept unchanged.
    new_of_old: Vec<Option<u32>>,
    /// Lattice tetrahedra with a replaced duplicate.
    changed_tet: Vec<bool>,
}

/// Open pieces of one face of one duplicate, projected for overlap tests.
#[derive(Clone, Debug)]
enum FacePieces {
    Whole,
    Pieces(Vec<Vec<Point2<Real>>>),
}

impl VirtualNodeMesh {
    /// Carves `surface` (closed, outward oriented) out of a BCC lattice of cube edge `h`: the
    /// surface triangles are the first cut, and only regions inside the surface are kept.
    pub fn carve(surface: &TriangleMesh, h: Real, material: Material) -> Result<Self, VirtualNodeError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(VirtualNodeError::Spacing(h));
        }
        let tester = InsideTester::new(surface)?;
        let (lo, hi) = surface.aabb();
        let lattice = BccLattice::covering(lo, hi, h);
        let cubes = lattice.dims.iter().map(|&d| d as u64).product::<u64>();
        if cubes > MAX_LATTICE_CUBES {
            return Err(VirtualNodeError::TooLarge { h, cubes, limit: MAX_LATTICE_CUBES });
        }
        let all = lattice.tetrahedra();
        let mut cube_tets: FastMap<[i32; 3], Vec<u32>> = FastMap::default();
        for (t, corners) in all.iter().enumerate() {
            for cube in BccLattice::cubes_of_tet(corners) {
                cube_tets.entry(cube).or_default().push(t as u32);
            }
        }
        // Outward orientation is what the render surface needs; the inside test does not care.
        let inward = surface.signed_volume() < 0.0;
        let triangles: Vec<[Point3<Real>; 3]> = (0..surface.triangles.len())
            .filter_map(|t| surface.triangle_points(t))
            .map(|[a, b, c]| if inward { [a, c, b] } else { [a, b, c] })
            .collect();
        let mut tris_of_tet: Vec<Vec<u32>> = vec![Vec::new(); all.len()];
        for (i, tri) in triangles.iter().enumerate() {
            for t in candidate_tets(&lattice, &cube_tets, tri) {
                let corners = all[t as usize].map(|d| lattice.position(d));
                if boxes_overlap(bounds(&corners), bounds(tri)) {
                    tris_of_tet[t as usize].push(i as u32);
                }
            }
        }
        let carved: Vec<Vec<Region>> = all
            .par_iter()
            .zip(&tris_of_tet)
            .map(|(corners, tris)| {
                let points = corners.map(|d| lattice.position(d));
                let mut arrangement = Arrangement::tetrahedron(points);
                if tris.is_empty() {
                    let centre = Point3::from((0..4).fold(Vector3::zeros(), |s, i| s + points[i].coords) / 4.0);
                    return if tester.contains(&centre) {
                        let v = arrangement.volume();
                        vec![(arrangement, v)]
                    } else {
                        Vec::new()
                    };
                }
                for &t in tris {
                    arrangement.cut(&triangles[t as usize], Cover::Surface);
                }
                arrangement
                    .regions()
                    .into_iter()
                    .filter(|(cells, _)| {
                        let largest = cells
                            .iter()
                            .copied()
                            .max_by(|&a, &b| {
                                arrangement
                                    .cell_volume(&arrangement.cells[a])
                                    .total_cmp(&arrangement.cell_volume(&arrangement.cells[b]))
                            })
                            .expect("regions are not empty");
                        tester.contains(&arrangement.cell_center(&arrangement.cells[largest]))
                    })
                    .map(|(cells, volume)| (arrangement.restricted(&cells), volume))
                    .collect()
            })
            .collect();
        // Keep the tetrahedra with material, in lattice order (z-major by face).
        let kept: Vec<usize> = (0..all.len()).filter(|&t| !carved[t].is_empty()).collect();
        if kept.is_empty() {
            return Err(VirtualNodeError::Empty);
        }
        let kept_corners: Vec<LatticeTetCorners> = kept.iter().map(|&t| all[t]).collect();
        let (lattice_nodes, node_index) = number_nodes(&kept_corners);
        let mut rest_library = Vec::new();
        let mut classes: FastMap<[[i32; 3]; 3], u32> = FastMap::default();
        let mut tets = Vec::with_capacity(kept.len());
        let mut cube_tets: FastMap<[i32; 3], Vec<u32>> = FastMap::default();
        for (k, corners) in kept_corners.iter().enumerate() {
            let points = corners.map(|d| lattice.position(d));
            // Degenerate only when h/2 is below the rounding of the coordinates.
            let shape = TetShape::new(points).ok_or(VirtualNodeError::Spacing(h))?;
            let key: [[i32; 3]; 3] =
                std::array::from_fn(|i| std::array::from_fn(|a| corners[i + 1][a] - corners[0][a]));
            let rest_class = *classes.entry(key).or_insert_with(|| {
                rest_library.push(shape.stiffness(&material, 1.0));
                rest_library.len() as u32 - 1
            });
            for cube in BccLattice::cubes_of_tet(corners) {
                cube_tets.entry(cube).or_default().push(k as u32);
            }
            tets.push(LatticeTet { nodes: corners.map(|d| node_index[&d]), shape, rest_class, neighbors: [None; 4] });
        }
        // Face adjacency through sorted node triples.
        let mut faces: FastMap<[u32; 3], (u32, u8)> = FastMap::default();
        for t in 0..tets.len() {
            for (f, face) in TET_FACES.iter().enumerate() {
                let mut key = face.map(|c| tets[t].nodes[c]);
                key.sort_unstable();
                if let Some((other, of)) = faces.remove(&key) {
                    tets[t].neighbors[f] = Some((other, of));
                    tets[other as usize].neighbors[of as usize] = Some((t as u32, f as u8));
                } else {
                    faces.insert(key, (t as u32, f as u8));
                }
            }
        }
        let mut kept_index = vec![u32::MAX; all.len()];
        for (k, &t) in kept.iter().enumerate() {
            kept_index[t] = k as u32;
        }
        let mut source = SourceSurface {
            tets_of_triangle: vec![Vec::new(); triangles.len()],
            triangles_of_tet: vec![Vec::new(); kept.len()],
            triangles: Vec::new(),
            face_sources: Vec::new(),
        };
        for (t, tris) in tris_of_tet.iter().enumerate() {
            if kept_index[t] == u32::MAX {
                continue;
            }
            for &i in tris {
                source.tets_of_triangle[i as usize].push(kept_index[t]);
                source.triangles_of_tet[kept_index[t] as usize].push(i);
            }
        }
        source.triangles = triangles;
        let mut carved = carved;
        let mut made = Vec::new();
        for (k, &t) in kept.iter().enumerate() {
            for (cells, volume) in std::mem::take(&mut carved[t]) {
                made.push((k as u32, cells, volume));
            }
        }
        let duplicates: Vec<Duplicate> = made
            .into_par_iter()
            .map(|(k, cells, volume)| Duplicate::new(k, &tets[k as usize], cells, volume, [0; 4], &material))
            .collect();
        let mut mesh = Self {
            material,
            lattice,
            lattice_nodes,
            tets,
            cube_tets,
            rest_library,
            duplicates,
            dups_of_tet: Vec::new(),
            node_lattice: Vec::new(),
            rest: Vec::new(),
            mass: Mass::Lumped(Vec::new()),
            blocks: BlockSetBuilder::new().finish(0)?,
            epoch: 0,
            last_cut: CutStats::default(),
            lumping: MassLumping::default(),
            links: Vec::new(),
            source,
            last_change: None,
            render_cache: Default::default(),
        };
        mesh.rebuild_topology(None, None)?;
        mesh.source.face_sources = (0..mesh.tets.len()).into_par_iter().map(|t| mesh.carved_face_sources(t)).collect();
        Ok(mesh)
    }

    /// An axis-aligned box `[lo, hi]` carved out of a lattice of spacing `h`.
    pub fn from_box(lo: Point3<Real>, hi: Point3<Real>, h: Real, material: Material) -> Result<Self, VirtualNodeError> {
        Self::carve(&box_surface(lo, hi), h, material)
    }

    /// The material.
    pub fn material(&self) -> &Material {
        &self.material
    }

    /// The lattice.
    pub fn lattice(&self) -> &BccLattice {
        &self.lattice
    }

    /// Number of duplicates (elements, frames).
    pub fn num_duplicates(&self) -> usize {
        self.duplicates.len()
    }

    /// Number of lattice tetrahedra holding material.
    pub fn num_lattice_tets(&self) -> usize {
        self.tets.len()
    }

    /// Total material volume (sum of region volumes).
    pub fn volume(&self) -> Real {
        self.duplicates.iter().map(|d| d.volume).sum()
    }

    /// Region volume of every duplicate.
    pub fn duplicate_volumes(&self) -> Vec<Real> {
        self.duplicates.iter().map(|d| d.volume).collect()
    }

    /// Node indices of every duplicate (in its lattice tetrahedron's corner order).
    pub fn duplicate_nodes(&self) -> Vec<[u32; 4]> {
        self.duplicates.iter().map(|d| d.nodes).collect()
    }

    /// The four nodes of duplicate `d` (in its lattice tetrahedron's corner order).
    pub fn duplicate_nodes_of(&self, d: usize) -> [u32; 4] {
        self.duplicates[d].nodes
    }

    /// The convex cells of a duplicate's region.
    pub fn duplicate_cells(&self, d: usize) -> &Arrangement {
        &self.duplicates[d].cells
    }

    /// Rest shape of the lattice tetrahedron of duplicate `d`.
    pub fn duplicate_shape(&self, d: usize) -> &TetShape {
        &self.tets[self.duplicates[d].tet as usize].shape
    }

    /// Whether node copy `corner` of duplicate `d` is real (its region contains that corner).
    pub fn is_real_copy(&self, d: usize, corner: usize) -> bool {
        self.duplicates[d].cells.has_corner(corner)
    }

    /// The surface the mesh was carved from.
    pub(crate) fn source(&self) -> &SourceSurface {
        &self.source
    }

    /// Rest shape of lattice tetrahedron `t`.
    pub(crate) fn tet_shape(&self, t: usize) -> &TetShape {
        &self.tets[t].shape
    }

    /// Duplicates of lattice tetrahedron `t`.
    pub(crate) fn duplicates_of_tet(&self, t: usize) -> &[u32] {
        &self.dups_of_tet[t]
    }

    /// Lattice tetrahedron of duplicate `d`.
    pub(crate) fn last_change(&self) -> Option<&ChangeRecord> {
        self.last_change.as_ref()
    }

    /// Lattice node of each corner of lattice tetrahedron `t`.
    pub(crate) fn tet_lattice_nodes(&self, t: usize) -> [u32; 4] {
        self.tets[t].nodes
    }

    pub(crate) fn tet_of_duplicate(&self, d: usize) -> usize {
        self.duplicates[d].tet as usize
    }

    /// Statistics of the last cut.
    pub fn last_cut(&self) -> CutStats {
        self.last_cut
    }

    /// Connected pieces: components of duplicates linked by shared nodes.
    pub fn pieces(&self) -> Vec<Piece> {
        let n = self.node_lattice.len();
        let mut uf = UnionFind::new(n);
        for d in &self.duplicates {
            for c in 1..4 {
                uf.union(d.nodes[0] as usize, d.nodes[c] as usize);
            }
        }
        let mut index: FastMap<usize, usize> = FastMap::default();
        let mut pieces: Vec<Piece> = Vec::new();
        for (i, d) in self.duplicates.iter().enumerate() {
            let root = uf.find(d.nodes[0] as usize);
            let k = *index.entry(root).or_insert_with(|| {
                pieces.push(Piece::default());
                pieces.len() - 1
            });
            pieces[k].elements.push(i as u32);
            pieces[k].volume += d.volume;
        }
        for node in 0..n {
            if let Some(&k) = index.get(&uf.find(node)) {
                pieces[k].nodes.push(node as u32);
            }
        }
        for p in &mut pieces {
            p.mass = self.material.density * p.volume;
        }
        pieces
    }

    /// Identifies node copies across materially contiguous faces and rebuilds nodes, mass and
    /// blocks. With `old = (old nodes per duplicate, parent of each duplicate)`, copies are only
    /// identified when they came from the same old node, so the result refines the old nodes.
    fn rebuild_topology(
        &mut self,
        old: Option<(&[[u32; 4]], &[u32])>,
        reuse: Option<&LinkReuse>,
    ) -> Result<Vec<u32>, VirtualNodeError> {
        let mut dups_of_tet = vec![Vec::new(); self.tets.len()];
        for (i, d) in self.duplicates.iter().enumerate() {
            dups_of_tet[d.tet as usize].push(i as u32);
        }
        // Pairs of duplicates across each lattice face that are materially contiguous.
        let tets = &self.tets;
        let duplicates = &self.duplicates;
        let lattice_h = self.lattice.h;
        let mut links: Vec<Link> = (0..tets.len())
            .into_par_iter()
            .flat_map_iter(|t| {
                let mut out = Vec::new();
                let mut scratch = (Vec::new(), Vec::new());
                for f in 0..4 {
                    let Some((other, of)) = tets[t].neighbors[f] else { continue };
                    if (other as usize) < t {
                        continue;
                    }
                    // Faces between two tetrahedra the cut did not touch keep their links.
                    if reuse.is_some_and(|r| !r.changed_tet[t] && !r.changed_tet[other as usize]) {
                        continue;
                    }
                    let threshold = OVERLAP_TOLERANCE * 2.0 * lattice_h * lattice_h;
                    for &a in &dups_of_tet[t] {
                        for &b in &dups_of_tet[other as usize] {
                            let (pa, pb) = (
                                &duplicates[a as usize].cache.faces[f],
                                &duplicates[b as usize].cache.faces[of as usize],
                            );
                            if contiguous(pa, pb, threshold, &mut scratch) {
                                out.push((a, f as u8, b, of));
                            }
                        }
                    }
                }
                out
            })
            .collect();
        if let Some(r) = reuse {
            // Links of faces recomputed above are not kept (a changed tetrahedron may still hold
            // unchanged duplicates).
            links.extend(r.old_links.iter().filter_map(|&(a, f, b, of)| {
                let (a, b) = (r.new_of_old[a as usize]?, r.new_of_old[b as usize]?);
                let (ta, tb) = (duplicates[a as usize].tet as usize, duplicates[b as usize].tet as usize);
                (!r.changed_tet[ta] && !r.changed_tet[tb]).then_some((a, f, b, of))
            }));
        }
        let num_copies = 4 * self.duplicates.len();
        let mut uf = UnionFind::new(num_copies);
        for &(a, f, b, of) in &links {
            let (ta, tb) = (
                &self.tets[self.duplicates[a as usize].tet as usize],
                &self.tets[self.duplicates[b as usize].tet as usize],
            );
            for &ca in &TET_FACES[f as usize] {
                let node = ta.nodes[ca];
                let Some(cb) = TET_FACES[of as usize].iter().copied().find(|&c| tb.nodes[c] == node) else { continue };
                if let Some((old_nodes, parent)) = old {
                    let (pa, pb) = (parent[a as usize] as usize, parent[b as usize] as usize);
                    if old_nodes[pa][ca] != old_nodes[pb][cb] {
                        continue;
                    }
                }
                uf.union(4 * a as usize + ca, 4 * b as usize + cb);
            }
        }
        // Classes → nodes, ordered by lattice node, then by first copy.
        let roots: Vec<u32> = (0..num_copies).map(|c| uf.find(c) as u32).collect();
        let mut seen = vec![false; num_copies];
        let mut classes: Vec<(u32, usize, usize)> = Vec::new();
        for (copy, &root) in roots.iter().enumerate() {
            if !std::mem::replace(&mut seen[root as usize], true) {
                let lattice_node = self.tets[self.duplicates[copy / 4].tet as usize].nodes[copy % 4];
                classes.push((lattice_node, copy, root as usize));
            }
        }
        classes.sort_unstable();
        let mut node_of_root = vec![u32::MAX; num_copies];
        for (i, c) in classes.iter().enumerate() {
            node_of_root[c.2] = i as u32;
        }
        let mut gather = Vec::with_capacity(classes.len());
        for &(_, copy, _) in &classes {
            if let Some((old_nodes, parent)) = old {
                gather.push(old_nodes[parent[copy / 4] as usize][copy % 4]);
            }
        }
        for (i, d) in self.duplicates.iter_mut().enumerate() {
            for c in 0..4 {
                d.nodes[c] = node_of_root[roots[4 * i + c] as usize];
            }
        }
        self.node_lattice = classes.iter().map(|c| c.0).collect();
        self.rest = self
            .node_lattice
            .iter()
            .flat_map(|&n| {
                let p = self.lattice.position(self.lattice_nodes[n as usize]);
                [p.x, p.y, p.z]
            })
            .collect();
        self.mass = self.lumped_mass();
        let mut builder = BlockSetBuilder::new().translation_invariant();
        for k in &self.rest_library {
            builder.add_rest_matrix(k.clone())?;
        }
        for (i, d) in self.duplicates.iter().enumerate() {
            let tet = &self.tets[d.tet as usize];
            let id = match &d.cache.stiffness {
                None => tet.rest_class,
                Some(k) => builder.add_rest_matrix(k.clone())?,
            };
            builder.push(&d.nodes, id, Some(i as u32));
        }
        self.blocks = builder.finish(self.node_lattice.len())?;
        self.dups_of_tet = dups_of_tet;
        self.links = links;
        Ok(gather)
    }

    /// The lumped mass of the current duplicates under the chosen [`MassLumping`].
    fn lumped_mass(&self) -> Mass {
        let mut lumped = vec![0.0; self.rest.len()];
        let rho = self.material.density;
        match self.lumping {
            MassLumping::RowSum => {
                // m_k = ρ ∫_region N_k (exact: the centroid rule on every fan tetrahedron, N
                // being linear), except in specks, lumped uniformly (ρV/4 per node).
                let speck = self.speck_duplicates();
                for (d, &speck) in self.duplicates.iter().zip(&speck) {
                    for (c, &n) in d.nodes.iter().enumerate() {
                        let share = if speck { d.volume / 4.0 } else { d.cache.shape_integrals[c] };
                        for a in 0..3 {
                            lumped[3 * n as usize + a] += rho * share;
                        }
                    }
                }
            }
            MassLumping::Uniform => {
                for d in &self.duplicates {
                    for &n in &d.nodes {
                        for a in 0..3 {
                            lumped[3 * n as usize + a] += rho * d.volume / 4.0;
                        }
                    }
                }
            }
        }
        Mass::Lumped(lumped)
    }

    /// Per duplicate, whether it belongs to a piece smaller than [`SPECK_VOLUME`] of a lattice
    /// tetrahedron.
    fn speck_duplicates(&self) -> Vec<bool> {
        let mut speck = vec![false; self.duplicates.len()];
        let limit = SPECK_VOLUME * self.lattice.h.powi(3) / 12.0;
        // Every duplicate of a speck is smaller than the speck: without such a duplicate there
        // is none, and the pieces need not be found.
        if !self.duplicates.iter().any(|d| d.volume < limit) {
            return speck;
        }
        for piece in self.pieces().iter().filter(|p| p.volume < limit) {
            for &e in &piece.elements {
                speck[e as usize] = true;
            }
        }
        speck
    }

    /// Chooses how region mass is lumped to the four nodes of its duplicate (rebuilds the mass;
    /// no topology change).
    pub fn set_mass_lumping(&mut self, lumping: MassLumping) {
        self.lumping = lumping;
        self.mass = self.lumped_mass();
    }

    /// Duplicates whose region may contain `p` (within `tolerance`), best first, with the
    /// barycentric weights of their tetrahedron.
    fn locate(&self, p: &Point3<Real>) -> Option<(usize, [Real; 4])> {
        let h = self.lattice.h;
        let tolerance = 1e-6 * h;
        let lo = self.lattice.cube_of(&(p - Vector3::repeat(tolerance)));
        let hi = self.lattice.cube_of(&(p + Vector3::repeat(tolerance)));
        let mut best: Option<(Real, usize, [Real; 4])> = None;
        for i in lo[0]..=hi[0] {
            for j in lo[1]..=hi[1] {
                for k in lo[2]..=hi[2] {
                    let Some(list) = self.cube_tets.get(&[i, j, k]) else { continue };
                    for &t in list {
                        let shape = &self.tets[t as usize].shape;
                        let w = shape.barycentric(p);
                        if w.iter().any(|&w| w < -1e-6) {
                            continue;
                        }
                        for &d in &self.dups_of_tet[t as usize] {
                            let cells = &self.duplicates[d as usize].cells;
                            let distance = (0..cells.cells.len())
                                .map(|c| cells.outside_distance(c, p))
                                .fold(Real::INFINITY, Real::min);
                            if best.is_none_or(|b| distance < b.0) {
                                best = Some((distance, d as usize, w));
                            }
                        }
                    }
                }
            }
        }
        // Inside a cell up to rounding; points on region boundaries, and the rare point of a
        // sliver cell whose rounded faces are not convex, take the nearest cell within 1e-6 h.
        best.filter(|b| b.0 <= 1e-6 * h).map(|b| (b.1, b.2))
    }

    /// Deformation gradient of duplicate `d` at positions `x`.
    fn gradient(&self, d: usize, x: &[Real]) -> Matrix3<Real> {
        let dup = &self.duplicates[d];
        let shape = &self.tets[dup.tet as usize].shape;
        let p = |c: usize| {
            let i = 3 * dup.nodes[c] as usize;
            Vector3::new(x[i], x[i + 1], x[i + 2])
        };
        let x0 = p(0);
        Matrix3::from_columns(&[p(1) - x0, p(2) - x0, p(3) - x0]) * shape.dm_inv
    }

    /// Calls `visit(duplicate, point, weight)` for the points of a rule of `degree` on every cell
    /// (each convex cell fanned into tetrahedra from its vertex average).
    fn for_each_quadrature_point(&self, degree: usize, visit: &mut dyn FnMut(usize, Point3<Real>, Real)) {
        let rule = TetRule::of_degree(degree);
        for (d, dup) in self.duplicates.iter().enumerate() {
            for_each_cell_point(&dup.cells, &rule, &mut |p, w| visit(d, p, w));
        }
    }
}

impl Discretization for VirtualNodeMesh {
    fn name(&self) -> &str {
        "virtualnode"
    }

    fn num_nodes(&self) -> usize {
        self.node_lattice.len()
    }

    fn rest_dofs(&self) -> &[Real] {
        &self.rest
    }

    fn epoch(&self) -> u64 {
        self.epoch
    }

    fn mass(&self) -> &Mass {
        &self.mass
    }

    fn num_frames(&self) -> usize {
        self.duplicates.len()
    }

    fn write_rotations(&self, x: &[Real], rotations: &mut [Matrix3<Real>]) -> RotationStats {
        write_frame_rotations(rotations, ROTATION_ITERATIONS, |d| self.gradient(d, x))
    }

    fn blocks(&self) -> &BlockSet {
        &self.blocks
    }

    fn add_load(&self, force_density: &dyn Fn(&Point3<Real>) -> Vector3<Real>, out: &mut [Real]) {
        self.for_each_quadrature_point(3, &mut |d, p, w| {
            let dup = &self.duplicates[d];
            let n = self.tets[dup.tet as usize].shape.barycentric(&p);
            let f = force_density(&p) * w;
            for c in 0..4 {
                let i = 3 * dup.nodes[c] as usize;
                for a in 0..3 {
                    out[i + a] += n[c] * f[a];
                }
            }
        });
    }

    fn embed(&self, points: &[Point3<Real>]) -> Result<Embedding, EmbedError> {
        let mut embedding = Embedding::new();
        for (index, p) in points.iter().enumerate() {
            let Some((d, w)) = self.locate(p) else {
                return Err(EmbedError::Outside { index, x: p.x, y: p.y, z: p.z });
            };
            embedding.push_row(&self.duplicates[d].nodes, &w);
        }
        Ok(embedding)
    }

    fn visit_field(&self, displacement: &[Real], min_degree: usize, visit: &mut dyn FnMut(&FieldSample)) {
        self.for_each_quadrature_point(min_degree.max(1), &mut |d, p, w| {
            let dup = &self.duplicates[d];
            let shape = &self.tets[dup.tet as usize].shape;
            let n = shape.barycentric(&p);
            let mut u = Vector3::zeros();
            let mut gradient = Matrix3::zeros();
            for c in 0..4 {
                let i = 3 * dup.nodes[c] as usize;
                let uc = Vector3::new(displacement[i], displacement[i + 1], displacement[i + 2]);
                u += uc * n[c];
                gradient += uc * shape.gradients[c].transpose();
            }
            visit(&FieldSample { position: p, weight: w, displacement: u, gradient });
        });
    }

    fn as_cuttable(&mut self) -> Option<&mut dyn Cuttable> {
        Some(self)
    }

    /// Dirichlet nodes of a carved body (docs/math/virtual-node.md, "Dirichlet data"). BCC
    /// tetrahedra straddle the object's surface, so a duplicate at the boundary has node copies
    /// outside it (virtual nodes). Holding only the nodes that lie in `region` leaves those
    /// free, and the free nodes' shape functions do not vanish on the boundary: the data is then
    /// imposed only in part (measured: L2 rates 0.9 and 1.2 on the manufactured solutions, the
    /// cantilever 0.5 % soft). Here every node of every duplicate whose region has an
    /// object-surface face all of whose vertices lie in `region` is held, and so is every node
    /// lying in `region` itself. Every free node then belongs only to duplicates that do not
    /// touch the Dirichlet part, so its shape function vanishes there: linear tetrahedra
    /// converge at rate 2 in L2 again.
    fn dirichlet_nodes(&self, region: &dyn Fn(&Point3<Real>) -> bool) -> Vec<u32> {
        let rest = self.rest_dofs();
        let mut held: Vec<bool> = rest.chunks_exact(3).map(|p| region(&Point3::new(p[0], p[1], p[2]))).collect();
        for duplicate in &self.duplicates {
            let cells = &duplicate.cells;
            let touches = cells.cells.iter().flat_map(|c| &c.faces).any(|face| {
                face.cover == Cover::Surface
                    && face.verts.len() >= 3
                    && face.verts.iter().all(|&v| region(&cells.point(v)))
            });
            if touches {
                for &node in &duplicate.nodes {
                    held[node as usize] = true;
                }
            }
        }
        (0..held.len() as u32).filter(|&k| held[k as usize]).collect()
    }

    fn copy_for_cutting(&self) -> Option<Box<dyn Discretization>> {
        Some(Box::new(self.clone()))
    }
}

impl Cuttable for VirtualNodeMesh {
    fn cut(&mut self, surface: &CutSurface) -> Result<TopologyChange, TopologyError> {
        match surface {
            CutSurface::Plane { point, normal } => self.cut_plane(point, normal),
            CutSurface::Triangles(t) => self.cut_triangles(t),
        }
    }

    fn surface(&self) -> Option<cleave_core::EmbeddedSurface> {
        let surface = self.render_surface();
        let mut piece_of_duplicate = vec![0u32; self.num_duplicates()];
        for (k, piece) in VirtualNodeMesh::pieces(self).iter().enumerate() {
            for &d in &piece.elements {
                piece_of_duplicate[d as usize] = k as u32;
            }
        }
        Some(cleave_core::EmbeddedSurface {
            rest_vertices: surface.positions,
            piece: surface.duplicates.iter().map(|&d| piece_of_duplicate[d as usize]).collect(),
            on_cut: surface.kinds.iter().map(|k| *k == crate::surface::SurfaceKind::Cut).collect(),
            triangles: surface.triangles,
            embedding: surface.embedding,
        })
    }

    fn pieces(&self) -> Vec<Piece> {
        VirtualNodeMesh::pieces(self)
    }
}

/// A region of a cut duplicate: its cells and volume.
type Region = (Arrangement, Real);

/// What one cut does to the duplicates it touches.
enum CutOp<'a> {
    Triangles(&'a [[Point3<Real>; 3]]),
    Plane([Point3<Real>; 3]),
}

impl VirtualNodeMesh {
    /// Cuts by the whole plane through `point` with normal `normal` (exact side decisions against
    /// the plane through `point`, `point + h t₁`, `point + h t₂` for two tangents `t₁, t₂`;
    /// axis-aligned normals give exactly axis-aligned planes).
    pub fn cut_plane(&mut self, point: &Point3<Real>, normal: &Vector3<Real>) -> Result<TopologyChange, TopologyError> {
        let len = normal.norm();
        if !(len.is_finite() && len > 0.0 && point.iter().all(|x| x.is_finite())) {
            return Err(TopologyError::Invalid(format!("cut plane through {point:?} with normal {normal:?}")));
        }
        let n = normal / len;
        let h = self.lattice.h;
        let axis = (0..3).find(|&a| n[a].abs() == 1.0);
        let (t1, t2) = match axis {
            Some(a) => (Vector3::ith((a + 1) % 3, h), Vector3::ith((a + 2) % 3, h)),
            None => {
                let helper = if n.x.abs() <= n.y.abs() && n.x.abs() <= n.z.abs() {
                    Vector3::x()
                } else if n.y.abs() <= n.z.abs() {
                    Vector3::y()
                } else {
                    Vector3::z()
                };
                let t1 = n.cross(&helper).normalize();
                (t1 * h, n.cross(&t1) * h)
            }
        };
        let plane = [*point, point + t1, point + t2];
        let margin = 1e-9 * h;
        let selected: Vec<(u32, Vec<u32>)> = (0..self.duplicates.len() as u32)
            .filter(|&d| {
                let (lo, hi) = self.duplicates[d as usize].cache.bounds;
                let (mut below, mut above) = (false, false);
                for c in 0..8 {
                    let corner = Point3::new(
                        if c & 1 == 0 { lo.x } else { hi.x },
                        if c & 2 == 0 { lo.y } else { hi.y },
                        if c & 4 == 0 { lo.z } else { hi.z },
                    );
                    let s = n.dot(&(corner - point));
                    below |= s <= margin;
                    above |= s >= -margin;
                }
                below && above
            })
            .map(|d| (d, Vec::new()))
            .collect();
        self.apply_cut(selected, CutOp::Plane(plane))
    }

    /// Cuts by a triangle soup (rest coordinates): material is separated exactly where a
    /// triangle covers it. Exactly degenerate triangles cut nothing; non-finite ones are an error.
    pub fn cut_triangles(&mut self, triangles: &[[Point3<Real>; 3]]) -> Result<TopologyChange, TopologyError> {
        if let Some(i) = triangles.iter().position(|t| !t.iter().all(|p| p.iter().all(|x| x.is_finite()))) {
            return Err(TopologyError::Invalid(format!(
                "cut triangle {i} has a non-finite corner: {:?}",
                triangles[i]
            )));
        }
        let mut tris_of_dup: FastMap<u32, Vec<u32>> = FastMap::default();
        for (i, tri) in triangles.iter().enumerate() {
            let tb = bounds(tri);
            for t in candidate_tets(&self.lattice, &self.cube_tets, tri) {
                let corners = self.tets[t as usize].shape.corners;
                if !boxes_overlap(bounds(&corners), tb) {
                    continue;
                }
                for &d in &self.dups_of_tet[t as usize] {
                    if boxes_overlap(self.duplicates[d as usize].cache.bounds, tb) {
                        let list = tris_of_dup.entry(d).or_default();
                        if list.last() != Some(&(i as u32)) {
                            list.push(i as u32);
                        }
                    }
                }
            }
        }
        let mut touched: Vec<(u32, Vec<u32>)> = tris_of_dup.into_iter().collect();
        touched.sort_unstable_by_key(|t| t.0);
        self.apply_cut(touched, CutOp::Triangles(triangles))
    }

    fn apply_cut(&mut self, touched: Vec<(u32, Vec<u32>)>, op: CutOp<'_>) -> Result<TopologyChange, TopologyError> {
        let results: Vec<(u32, Option<Vec<Region>>)> = touched
            .par_iter()
            .map(|(d, tris)| {
                let mut cells = self.duplicates[*d as usize].cells.clone();
                let changed = match &op {
                    CutOp::Triangles(triangles) => {
                        let mut changed = false;
                        for &t in tris {
                            changed |= cells.cut(&triangles[t as usize], Cover::Cut);
                        }
                        changed
                    }
                    CutOp::Plane(plane) => cells.cut_plane(plane, Cover::Cut),
                };
                if !changed {
                    return (*d, None);
                }
                let regions = cells.regions();
                (*d, Some(regions.into_iter().map(|(c, v)| (cells.restricted(&c), v)).collect()))
            })
            .collect();
        let old_dups = self.duplicates.len();
        let old_nodes_count = self.node_lattice.len();
        if results.iter().all(|r| r.1.is_none()) {
            self.last_cut = CutStats {
                touched: touched.len(),
                duplicates: (old_dups, old_dups),
                nodes: (old_nodes_count, old_nodes_count),
            };
            return Ok(TopologyChange {
                epoch: self.epoch,
                remap: DofRemap::Identity,
                frames: FrameRemap::Identity,
                pattern_changed: false,
            });
        }
        let mut replaced: FastMap<u32, Vec<Region>> =
            results.into_iter().filter_map(|(d, r)| r.map(|r| (d, r))).collect();
        let old = std::mem::take(&mut self.duplicates);
        let old_nodes: Vec<[u32; 4]> = old.iter().map(|d| d.nodes).collect();
        let mut parent = Vec::with_capacity(old.len() + replaced.len());
        let mut reuse = LinkReuse {
            old_links: std::mem::take(&mut self.links),
            new_of_old: vec![None; old.len()],
            changed_tet: vec![false; self.tets.len()],
        };
        for (i, dup) in old.into_iter().enumerate() {
            match replaced.remove(&(i as u32)) {
                Some(children) => {
                    reuse.changed_tet[dup.tet as usize] = true;
                    for (cells, volume) in children {
                        parent.push(i as u32);
                        let tet = &self.tets[dup.tet as usize];
                        self.duplicates.push(Duplicate::new(dup.tet, tet, cells, volume, dup.nodes, &self.material));
                    }
                }
                None => {
                    reuse.new_of_old[i] = Some(self.duplicates.len() as u32);
                    parent.push(i as u32);
                    self.duplicates.push(dup);
                }
            }
        }
        let gather = self
            .rebuild_topology(Some((&old_nodes, &parent)), Some(&reuse))
            .map_err(|e| TopologyError::Invalid(format!("rebuilding after the cut failed: {e}")))?;
        self.last_change = Some(ChangeRecord {
            epoch_before: self.epoch,
            new_of_old: reuse.new_of_old,
            changed_tet: reuse.changed_tet,
        });
        self.epoch += 1;
        self.last_cut = CutStats {
            touched: touched.len(),
            duplicates: (old_dups, self.duplicates.len()),
            nodes: (old_nodes_count, self.node_lattice.len()),
        };
        Ok(TopologyChange {
            epoch: self.epoch,
            remap: DofRemap::Gather(gather),
            frames: FrameRemap::Gather(parent),
            pattern_changed: true,
        })
    }
}

/// Projection axis of face `f` of a lattice tetrahedron.
fn face_axis(tet: &LatticeTet, f: usize) -> usize {
    let [a, b, c] = TET_FACES[f].map(|i| tet.shape.corners[i]);
    largest_component(&(b - a).cross(&(c - a)))
}

fn contiguous(
    a: &FacePieces,
    b: &FacePieces,
    threshold: Real,
    scratch: &mut (Vec<Point2<Real>>, Vec<Point2<Real>>),
) -> bool {
    let any_area = |pieces: &[Vec<Point2<Real>>]| {
        pieces.iter().any(|p| cleave_geometry::predicates::polygon_area_2d(p).abs() > threshold)
    };
    match (a, b) {
        (FacePieces::Whole, FacePieces::Whole) => true,
        (FacePieces::Whole, FacePieces::Pieces(p)) | (FacePieces::Pieces(p), FacePieces::Whole) => any_area(p),
        (FacePieces::Pieces(pa), FacePieces::Pieces(pb)) => {
            pa.iter().any(|x| pb.iter().any(|y| convex_overlap_area(x, y, scratch) > threshold))
        }
    }
}

/// Lattice tetrahedra (indices into the cube map's numbering) in cubes the triangle's bounding
/// box touches, with one cube of margin.
fn candidate_tets(lattice: &BccLattice, cube_tets: &FastMap<[i32; 3], Vec<u32>>, tri: &[Point3<Real>; 3]) -> Vec<u32> {
    let (lo, hi) = bounds(tri);
    let (a, b) = (lattice.cube_of(&lo), lattice.cube_of(&hi));
    let clamp = |c: i32, axis: usize| c.clamp(-1, lattice.dims[axis]);
    let mut out = Vec::new();
    for i in clamp(a[0] - 1, 0)..=clamp(b[0] + 1, 0) {
        for j in clamp(a[1] - 1, 1)..=clamp(b[1] + 1, 1) {
            for k in clamp(a[2] - 1, 2)..=clamp(b[2] + 1, 2) {
                if let Some(list) = cube_tets.get(&[i, j, k]) {
                    out.extend_from_slice(list);
                }
            }
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

fn bounds(points: &[Point3<Real>]) -> (Point3<Real>, Point3<Real>) {
    let mut lo = Point3::from([Real::INFINITY; 3]);
    let mut hi = Point3::from([Real::NEG_INFINITY; 3]);
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}

/// Whether two boxes overlap, padded by `1e-9` of their size (constructed points on a plane may
/// be rounded to either side of it).
fn boxes_overlap(a: (Point3<Real>, Point3<Real>), b: (Point3<Real>, Point3<Real>)) -> bool {
    let pad = 1e-9 * ((a.1 - a.0).norm() + (b.1 - b.0).norm());
    (0..3).all(|k| a.0[k] <= b.1[k] + pad && b.0[k] <= a.1[k] + pad)
}

/// The closed, outward oriented surface of the box `[lo, hi]` (12 triangles):
/// [`TriangleMesh::cuboid`], kept under this name for virtual node's callers.
pub fn box_surface(lo: Point3<Real>, hi: Point3<Real>) -> TriangleMesh {
    TriangleMesh::cuboid(lo, hi)
}
