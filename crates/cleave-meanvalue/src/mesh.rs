//! A mesh of convex polyhedral mean value elements behind `Discretization`: shared nodes, one
//! corotated frame per element (the rotation of `F = Σ_i x_i ⊗ ∮ λ_i n dA / V`, the element's
//! mean deformation gradient, exact for affine motions), the element stiffness in the shared
//! block format (elements of the same shape share one rest matrix), lumped mass `ρ ∫ λ_i`, and
//! embedding by the element's coordinates. Box meshes of cuboids for the comparison problems.

use crate::coordinates::{Workspace, mean_value_coordinates};
use crate::element::{ElementIntegrals, quadrature};
use crate::polyhedron::{ConvexPolyhedron, PolyhedronError, Real};
use cleave_core::rotation::write_frame_rotations;
use cleave_core::{
    BlockSet, BlockSetBuilder, BlockSetError, Discretization, EmbedError, Embedding, FieldSample, Mass, Material,
    Matrix3, Point3, RotationStats, Vector3,
};
use nalgebra::DMatrix;
use std::collections::HashMap;
use thiserror::Error;

/// Fan refinements of the element rule (mean-value.md §5): 0 = one 4-point rule per fan
/// tetrahedron; the gradient correction keeps the patch test exact at any level.
pub const DEFAULT_REFINEMENT: u32 = 0;

/// Normals of the three plane families of [`MeanValueMesh::from_split_box`] (oblique to every
/// axis and to each other).
pub const SPLIT_NORMALS: [[Real; 3]; 3] = [[1.0, 0.7, 0.3], [-0.4, 1.0, 0.9], [0.2, -0.5, 1.0]];

/// Where the first plane of each family lies, in spacings from the box's lowest offset (spread
/// so no two families' planes meet on the cells' lattice at once).
const SPLIT_PHASES: [Real; 3] = [0.382, 0.236, 0.708];

/// Distance between the planes of a family of [`MeanValueMesh::from_split_box`], in cell edges.
pub const SPLIT_SPACING: Real = 1.5;

/// Polar iterations per rotation extraction (warm-started).
const ROTATION_ITERATIONS: usize = 8;

/// What can go wrong building a mean value mesh.
#[derive(Debug, Error)]
pub enum MeanValueError {
    /// An element is not a valid convex polyhedron.
    #[error("element {element}: {source}")]
    Element {
        /// The element.
        element: usize,
        /// Why.
        source: PolyhedronError,
    },
    /// An element names a node that does not exist.
    #[error("element {element} names node {node}, but there are {nodes} nodes")]
    NodeOutOfRange {
        /// The element.
        element: usize,
        /// The node.
        node: u32,
        /// Nodes of the mesh.
        nodes: usize,
    },
    /// The block set rejected the stiffness.
    #[error("element stiffness: {0}")]
    Blocks(#[from] BlockSetError),
    /// Elements do not meet face to face: a face no other element shares (as a node set) has
    /// another element right behind it, as where one element has a node on a shared face that
    /// its neighbour lacks (a hanging node).
    #[error("element {element} is not conforming: its face {face} is not another element's, yet one lies behind it")]
    NotConforming {
        /// The element.
        element: usize,
        /// Its face (local index).
        face: usize,
    },
    /// The surface to mesh is not a closed, outward surface, or meshing it failed.
    #[error("meshing the surface: {0}")]
    Surface(String),
    /// A box needs at least one cell per axis and a positive size.
    #[error("a box needs positive cell counts and size, got {dims:?} cells of {h} m")]
    BadBox {
        /// Cells per axis.
        dims: [usize; 3],
        /// Cell size.
        h: Real,
    },
}

/// What a cut's sliver merging did (`MeanValueMesh::last_cut`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CutReport {
    /// Elements below the quality floor merged into a neighbour.
    pub merged: usize,
    /// Elements left below the floor (no convex union with a neighbour).
    pub below_floor: usize,
    /// Elements a cut's plane crossed whose section was degenerate, kept whole (`cut.rs`).
    pub degenerate: usize,
}

/// One element: its polyhedron, its nodes, and what the steps need of its integrals.
#[derive(Clone, Debug)]
pub(crate) struct Element {
    pub(crate) shape: ConvexPolyhedron,
    pub(crate) nodes: Vec<u32>,
    /// `∮ λ_i n dA` per local node.
    boundary_gradients: Vec<Vector3<Real>>,
    /// The gradient correction per local node (`ElementIntegrals`), for field evaluation.
    shifts: Vec<Vector3<Real>>,
    pub(crate) volume: Real,
    /// Per face: lies on a cut (separated from the element across it, or a crack's face).
    pub(crate) cut: Vec<bool>,
}

/// A mean value mesh.
#[derive(Clone, Debug)]
pub struct MeanValueMesh {
    pub(crate) material: Material,
    pub(crate) rest: Vec<Real>,
    pub(crate) elements: Vec<Element>,
    mass: Mass,
    blocks: BlockSet,
    pub(crate) refinement: u32,
    pub(crate) epoch: u64,
    /// What the last cut's sliver merging did.
    pub(crate) last_cut: CutReport,
    /// The integrals of each shape (up to translation) and its rest matrix's id in `blocks`.
    library: HashMap<ShapeKey, SharedIntegrals>,
    /// The length unit of the shape keys.
    quantum: Real,
    /// Element bounding boxes and a uniform grid over them, for `embed`.
    locator: Locator,
}

#[derive(Clone, Debug)]
struct Locator {
    cell: Real,
    boxes: Vec<(Point3<Real>, Point3<Real>)>,
    grid: HashMap<[i64; 3], Vec<u32>>,
}

impl Locator {
    fn new(elements: &[Element]) -> Self {
        let boxes: Vec<(Point3<Real>, Point3<Real>)> = elements
            .iter()
            .map(|e| {
                let v = e.shape.vertices();
                let lo = v.iter().fold(v[0], |m, p| m.inf(p));
                let hi = v.iter().fold(v[0], |m, p| m.sup(p));
                (lo, hi)
            })
            .collect();
        let cell = elements.iter().map(|e| e.shape.diameter()).sum::<Real>() / elements.len().max(1) as Real;
        let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        let key = |p: &Point3<Real>| [0, 1, 2].map(|a| (p[a] / cell).floor() as i64);
        for (e, (lo, hi)) in boxes.iter().enumerate() {
            let (a, b) = (key(lo), key(hi));
            for i in a[0]..=b[0] {
                for j in a[1]..=b[1] {
                    for k in a[2]..=b[2] {
                        grid.entry([i, j, k]).or_default().push(e as u32);
                    }
                }
            }
        }
        Self { cell, boxes, grid }
    }

    /// Elements whose box holds `p` (within `slack`).
    fn candidates<'a>(&'a self, p: &'a Point3<Real>, slack: Real) -> impl Iterator<Item = usize> + 'a {
        let key = [0, 1, 2].map(|a| (p[a] / self.cell).floor() as i64);
        self.grid.get(&key).into_iter().flatten().map(|&e| e as usize).filter(move |&e| {
            let (lo, hi) = &self.boxes[e];
            (0..3).all(|a| p[a] >= lo[a] - slack && p[a] <= hi[a] + slack)
        })
    }
}

/// Elements equal up to translation (`shape_key`).
type ShapeKey = (Vec<i64>, Vec<Vec<usize>>);

/// What elements of one shape share: the rest matrix's id, `∮ λ_i n dA`, the gradient
/// corrections and `∫ λ_i`.
type SharedIntegrals = (u32, Vec<Vector3<Real>>, Vec<Vector3<Real>>, Vec<Real>);

/// A key for elements equal up to translation: vertex positions relative to the first vertex in
/// units of `quantum` (one length for the whole mesh, so that scaled copies, which need other
/// stiffnesses, get other keys), with the face lists.
fn shape_key(shape: &ConvexPolyhedron, quantum: Real) -> ShapeKey {
    let v = shape.vertices();
    let coords = v.iter().flat_map(|p| (0..3).map(move |a| ((p[a] - v[0][a]) / quantum).round() as i64)).collect();
    (coords, shape.faces().to_vec())
}

/// Every face that no other element shares (as a node set) must be on the body's boundary: a
/// point just outside it, 1e-6 of the element's diameter along the face normal, must lie in no
/// other element. Where a hanging node makes two sides of a shared face unequal, neither side
/// is shared and each has the other's element behind it.
fn validate_conforming(elements: &[Element], locator: &Locator) -> Result<(), MeanValueError> {
    let global = |e: &Element, face: &[usize]| {
        let mut key: Vec<u32> = face.iter().map(|&i| e.nodes[i]).collect();
        key.sort_unstable();
        key
    };
    let mut faces: HashMap<Vec<u32>, usize> = HashMap::new();
    for element in elements {
        for face in element.shape.faces() {
            *faces.entry(global(element, face)).or_insert(0) += 1;
        }
    }
    for (e, element) in elements.iter().enumerate() {
        let shape = &element.shape;
        for (f, face) in shape.faces().iter().enumerate() {
            if faces[&global(element, face)] != 1 || element.cut[f] {
                continue;
            }
            let centroid = face.iter().map(|&i| shape.vertices()[i].coords).sum::<Vector3<Real>>() / face.len() as Real;
            let outside = Point3::from(centroid + shape.normals()[f] * (1e-6 * shape.diameter()));
            let behind = locator.candidates(&outside, 0.0).filter(|&other| other != e).any(|other| {
                let s = &elements[other].shape;
                (0..s.faces().len()).all(|g| s.depth(g, &outside) > 1e-9 * s.diameter())
            });
            if behind {
                return Err(MeanValueError::NotConforming { element: e, face: f });
            }
        }
    }
    Ok(())
}

impl MeanValueMesh {
    /// Builds the mesh of `elements` (each a polyhedron over local vertices and the global node
    /// of each local vertex) on the nodes `rest` (positions). Every element is valid by
    /// construction (`ConvexPolyhedron::new`); the mesh must also be conforming (a node on a
    /// neighbour's face or edge inserted into that face), or `NotConforming` names an element.
    pub fn new(
        material: Material,
        rest: Vec<Point3<Real>>,
        elements: Vec<(ConvexPolyhedron, Vec<u32>)>,
        refinement: u32,
    ) -> Result<Self, MeanValueError> {
        let elements = elements
            .into_iter()
            .map(|(shape, nodes)| {
                let cut = vec![false; shape.faces().len()];
                (shape, nodes, cut)
            })
            .collect();
        Self::with_cut_faces(material, rest, elements, refinement, None)
    }

    /// [`MeanValueMesh::new`] with the faces that lie on a cut flagged per element (they are
    /// boundary, whatever lies behind them).
    pub(crate) fn with_cut_faces(
        material: Material,
        rest: Vec<Point3<Real>>,
        elements: Vec<(ConvexPolyhedron, Vec<u32>, Vec<bool>)>,
        refinement: u32,
        previous: Option<&MeanValueMesh>,
    ) -> Result<Self, MeanValueError> {
        let nodes = rest.len();
        let (lambda, mu) = material.lame();
        let mut builder = BlockSetBuilder::new().translation_invariant();
        let mut library: HashMap<ShapeKey, SharedIntegrals> = HashMap::new();
        let mut built = Vec::with_capacity(elements.len());
        // 2⁻⁴⁰ of the largest element: translated copies share a key, round-off aside (kept
        // across cuts, so unchanged elements find their shapes again).
        let quantum = previous.map_or_else(
            || elements.iter().map(|(shape, ..)| shape.diameter()).fold(0.0, Real::max) / (1u64 << 40) as Real,
            |p| p.quantum,
        );
        let mut lumped = vec![0.0; 3 * nodes];
        for (e, (shape, element_nodes, cut)) in elements.into_iter().enumerate() {
            if let Some(&node) = element_nodes.iter().find(|&&n| n as usize >= nodes) {
                return Err(MeanValueError::NodeOutOfRange { element: e, node, nodes });
            }
            if element_nodes.len() != shape.vertices().len() {
                return Err(MeanValueError::Element {
                    element: e,
                    source: PolyhedronError::BadFace {
                        face: 0,
                        indices: element_nodes.iter().map(|&n| n as usize).collect(),
                        vertices: shape.vertices().len(),
                    },
                });
            }
            let key = shape_key(&shape, quantum);
            let (rest_id, boundary_gradients, shifts, shape_integrals) = match library.get(&key) {
                Some(entry) => entry.clone(),
                None => {
                    // A shape the mesh before this cut had keeps its integrals (only the elements
                    // a cut made are integrated).
                    let (stiffness, boundary_gradients, shifts, shape_integrals) =
                        match previous.and_then(|p| p.library.get(&key).map(|entry| (p, entry))) {
                            Some((p, (id, bg, sh, si))) => {
                                (p.blocks.rest_matrices()[*id as usize].clone(), bg.clone(), sh.clone(), si.clone())
                            }
                            None => {
                                let integrals = ElementIntegrals::new(&shape, refinement);
                                let stiffness: DMatrix<Real> = integrals.stiffness(lambda, mu);
                                let shifts = integrals.shifts();
                                (stiffness, integrals.boundary_gradients, shifts, integrals.shape_integrals)
                            }
                        };
                    let id = builder.add_rest_matrix(stiffness)?;
                    let entry = (id, boundary_gradients, shifts, shape_integrals);
                    library.insert(key, entry.clone());
                    entry
                }
            };
            for (i, &n) in element_nodes.iter().enumerate() {
                for a in 0..3 {
                    lumped[3 * n as usize + a] += material.density * shape_integrals[i];
                }
            }
            builder.push(&element_nodes, rest_id, Some(e as u32));
            let volume = shape.volume();
            built.push(Element { shape, nodes: element_nodes, boundary_gradients, shifts, volume, cut });
        }
        let locator = Locator::new(&built);
        validate_conforming(&built, &locator)?;
        let blocks = builder.finish(nodes)?;
        Ok(Self {
            material,
            rest: rest.iter().flat_map(|p| [p.x, p.y, p.z]).collect(),
            elements: built,
            mass: Mass::Lumped(lumped),
            blocks,
            refinement,
            epoch: 0,
            last_cut: CutReport::default(),
            locator,
            library,
            quantum,
        })
    }

    /// The box `origin + h·[0, dims]` as `dims` cuboid cells (mean value elements on cubes: not
    /// trilinear, mean-value.md §6.8).
    pub fn from_box(
        material: Material,
        origin: Point3<Real>,
        h: Real,
        dims: [usize; 3],
    ) -> Result<Self, MeanValueError> {
        if dims.contains(&0) || !(h.is_finite() && h > 0.0) {
            return Err(MeanValueError::BadBox { dims, h });
        }
        let [nx, ny, nz] = dims.map(|d| d + 1);
        let node = |i: usize, j: usize, k: usize| (i + nx * (j + ny * k)) as u32;
        let rest: Vec<Point3<Real>> = (0..nz)
            .flat_map(|k| (0..ny).flat_map(move |j| (0..nx).map(move |i| (i, j, k))))
            .map(|(i, j, k)| origin + Vector3::new(i as Real, j as Real, k as Real) * h)
            .collect();
        let mut elements = Vec::with_capacity(dims.iter().product());
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let lo = rest[node(i, j, k) as usize];
                    let hi = rest[node(i + 1, j + 1, k + 1) as usize];
                    let shape = ConvexPolyhedron::cuboid(lo, hi)
                        .map_err(|source| MeanValueError::Element { element: elements.len(), source })?;
                    // `cuboid`'s corner c has bit 0 = x, bit 1 = y, bit 2 = z.
                    let nodes = (0..8).map(|c| node(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1))).collect();
                    elements.push((shape, nodes));
                }
            }
        }
        Self::new(material, rest, elements, DEFAULT_REFINEMENT)
    }

    /// The mesh of `cells`, their vertices welded into nodes where they coincide (to 1e-9 of
    /// the largest cell's diameter). The cells must meet face to face after welding (a vertex on
    /// a neighbour's face or edge must be a vertex of that face), or `NotConforming` names one.
    pub fn from_cells(material: Material, cells: Vec<ConvexPolyhedron>) -> Result<Self, MeanValueError> {
        let size = cells.iter().map(ConvexPolyhedron::diameter).fold(0.0, Real::max);
        let tolerance = 1e-9 * size.max(Real::MIN_POSITIVE);
        // Points are bucketed by a grid of the tolerance; a point is searched for in its bucket
        // and the 26 around it, so two copies of one vertex straddling a bucket edge still weld.
        let bucket = |p: &Point3<Real>| [p.x, p.y, p.z].map(|c| (c / tolerance).floor() as i64);
        let mut rest: Vec<Point3<Real>> = Vec::new();
        let mut buckets: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        let mut elements = Vec::with_capacity(cells.len());
        for cell in cells {
            let mut ids = Vec::with_capacity(cell.vertices().len());
            for p in cell.vertices() {
                let b = bucket(p);
                let found = (0..27).find_map(|k: i64| {
                    let key = [b[0] + k % 3 - 1, b[1] + (k / 3) % 3 - 1, b[2] + k / 9 - 1];
                    buckets.get(&key)?.iter().copied().find(|&n| (rest[n as usize] - p).norm() <= tolerance)
                });
                ids.push(found.unwrap_or_else(|| {
                    rest.push(*p);
                    let n = (rest.len() - 1) as u32;
                    buckets.entry(b).or_default().push(n);
                    n
                }));
            }
            elements.push((cell, ids));
        }
        Self::new(material, rest, elements, DEFAULT_REFINEMENT)
    }

    /// The box `origin + h·[0, dims]` as cuboid cells split by three families of parallel
    /// oblique planes, [`SPLIT_SPACING`] cell edges apart along their normals
    /// ([`SPLIT_NORMALS`], mean-value.md §11): nearly every cell is cut into convex polyhedra
    /// with triangle to heptagon faces, and since the planes scale with the cells the meshes
    /// look alike at every `h`, which is what a convergence study on polyhedral meshes needs.
    /// Conforming by construction: a plane that crosses a shared face or edge splits it alike
    /// in every cell that holds it.
    pub fn from_split_box(
        material: Material,
        origin: Point3<Real>,
        h: Real,
        dims: [usize; 3],
    ) -> Result<Self, MeanValueError> {
        if dims.contains(&0) || !(h.is_finite() && h > 0.0) {
            return Err(MeanValueError::BadBox { dims, h });
        }
        let extent = Vector3::new(dims[0] as Real, dims[1] as Real, dims[2] as Real) * h;
        let mut cells = Vec::with_capacity(4 * dims.iter().product::<usize>());
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let lo = origin + Vector3::new(i as Real, j as Real, k as Real) * h;
                    let cell = ConvexPolyhedron::cuboid(lo, lo + Vector3::repeat(h))
                        .map_err(|source| MeanValueError::Element { element: cells.len(), source })?;
                    cells.push(cell);
                }
            }
        }
        for (normal, phase) in SPLIT_NORMALS.iter().zip(SPLIT_PHASES) {
            let n = Vector3::from(*normal).normalize();
            // The offsets the box spans along n, from its lowest corner.
            let low = origin.coords.dot(&n) + (0..3).map(|a| (extent[a] * n[a]).min(0.0)).sum::<Real>();
            let span: Real = (0..3).map(|a| (extent[a] * n[a]).abs()).sum();
            let spacing = SPLIT_SPACING * h;
            let mut offset = low + phase * spacing;
            while offset < low + span {
                cells = cells
                    .into_iter()
                    .flat_map(|c| {
                        let (below, above) = c.split(&n, offset, 1e-12);
                        [below, above].into_iter().flatten()
                    })
                    .collect();
                offset += spacing;
            }
        }
        Self::from_cells(material, cells)
    }

    /// What the last cut's sliver merging did.
    pub fn last_cut(&self) -> CutReport {
        self.last_cut
    }

    /// Number of elements.
    pub fn num_elements(&self) -> usize {
        self.elements.len()
    }

    /// The material.
    pub fn material(&self) -> &Material {
        &self.material
    }

    /// Element `e`'s polyhedron and nodes.
    pub fn element(&self, e: usize) -> (&ConvexPolyhedron, &[u32]) {
        (&self.elements[e].shape, &self.elements[e].nodes)
    }

    /// The boundary as triangles over the nodes, outward oriented: every element face no other
    /// element shares (the same nodes), fanned from its first node.
    pub fn boundary_triangles(&self) -> Vec<[u32; 3]> {
        let mut count: HashMap<Vec<u32>, usize> = HashMap::new();
        let global = |e: &Element, face: &[usize]| face.iter().map(|&i| e.nodes[i]).collect::<Vec<u32>>();
        for element in &self.elements {
            for face in element.shape.faces() {
                let mut key = global(element, face);
                key.sort_unstable();
                *count.entry(key).or_insert(0) += 1;
            }
        }
        let mut triangles = Vec::new();
        for element in &self.elements {
            for face in element.shape.faces() {
                let nodes = global(element, face);
                let mut key = nodes.clone();
                key.sort_unstable();
                if count[&key] == 1 {
                    triangles.extend((1..nodes.len() - 1).map(|j| [nodes[0], nodes[j], nodes[j + 1]]));
                }
            }
        }
        triangles
    }

    /// The characteristic element size: the edge of a cube of the mean element volume (the cell
    /// edge on a box of cubes, as the voxel backend reports).
    pub fn element_size(&self) -> Real {
        let volume = self.elements.iter().map(|e| e.volume).sum::<Real>() / self.elements.len().max(1) as Real;
        volume.cbrt()
    }

    /// The mean deformation gradient of element `e` at positions `x`.
    fn gradient(&self, e: usize, x: &[Real]) -> Matrix3<Real> {
        let element = &self.elements[e];
        let mut f = Matrix3::zeros();
        for (&n, g) in element.nodes.iter().zip(&element.boundary_gradients) {
            let i = 3 * n as usize;
            f += Vector3::new(x[i], x[i + 1], x[i + 2]) * g.transpose();
        }
        f / element.volume
    }

    /// The element containing `p` and the coordinates there.
    fn locate(&self, p: &Point3<Real>, work: &mut Workspace) -> Option<(usize, Vec<Real>)> {
        let mut best: Option<(usize, Real)> = None;
        for e in self.locator.candidates(p, 1e-9 * self.locator.cell) {
            let shape = &self.elements[e].shape;
            let depth = (0..shape.faces().len()).map(|f| shape.depth(f, p)).fold(Real::MAX, Real::min);
            if best.is_none_or(|(_, d)| depth > d) {
                best = Some((e, depth));
            }
        }
        let (e, depth) = best?;
        if depth < -1e-9 * self.elements[e].shape.diameter() {
            return None;
        }
        let mut values = vec![0.0; self.elements[e].nodes.len()];
        mean_value_coordinates(&self.elements[e].shape, p, &mut values, None, work);
        Some((e, values))
    }
}

impl Discretization for MeanValueMesh {
    fn name(&self) -> &str {
        "meanvalue"
    }

    fn as_cuttable(&mut self) -> Option<&mut dyn cleave_core::Cuttable> {
        Some(self)
    }

    fn copy_for_cutting(&self) -> Option<Box<dyn Discretization>> {
        Some(Box::new(self.clone()))
    }

    fn num_nodes(&self) -> usize {
        self.rest.len() / 3
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
        self.elements.len()
    }

    fn write_rotations(&self, x: &[Real], rotations: &mut [Matrix3<Real>]) -> RotationStats {
        write_frame_rotations(rotations, ROTATION_ITERATIONS, |e| self.gradient(e, x))
    }

    fn blocks(&self) -> &BlockSet {
        &self.blocks
    }

    fn add_load(&self, force_density: &dyn Fn(&Point3<Real>) -> Vector3<Real>, out: &mut [Real]) {
        let mut work = Workspace::default();
        let mut values = Vec::new();
        for element in &self.elements {
            values.resize(element.nodes.len(), 0.0);
            let (points, weights) = quadrature(&element.shape, self.refinement);
            for (p, w) in points.iter().zip(&weights) {
                mean_value_coordinates(&element.shape, p, &mut values, None, &mut work);
                let f = force_density(p) * *w;
                for (&n, l) in element.nodes.iter().zip(&values) {
                    for a in 0..3 {
                        out[3 * n as usize + a] += l * f[a];
                    }
                }
            }
        }
    }

    fn embed(&self, points: &[Point3<Real>]) -> Result<Embedding, EmbedError> {
        let mut embedding = Embedding::new();
        let mut work = Workspace::default();
        for (index, p) in points.iter().enumerate() {
            let Some((e, values)) = self.locate(p, &mut work) else {
                return Err(EmbedError::Outside { index, x: p.x, y: p.y, z: p.z });
            };
            embedding.push_row(&self.elements[e].nodes, &values);
        }
        Ok(embedding)
    }

    fn visit_field(&self, displacement: &[Real], min_degree: usize, visit: &mut dyn FnMut(&FieldSample)) {
        let mut work = Workspace::default();
        // A finer fan for higher-degree error norms (each refinement ≈ one degree).
        let refinement = self.refinement.max(min_degree.saturating_sub(2) as u32).min(2);
        let (mut values, mut gradients) = (Vec::new(), Vec::new());
        for element in &self.elements {
            let k = element.nodes.len();
            values.resize(k, 0.0);
            gradients.resize(k, Vector3::zeros());
            let (points, weights) = quadrature(&element.shape, refinement);
            for (p, &w) in points.iter().zip(&weights) {
                mean_value_coordinates(&element.shape, p, &mut values, Some(&mut gradients), &mut work);
                let mut u = Vector3::zeros();
                let mut gradient = Matrix3::zeros();
                for (i, &n) in element.nodes.iter().enumerate() {
                    let j = 3 * n as usize;
                    let ui = Vector3::new(displacement[j], displacement[j + 1], displacement[j + 2]);
                    u += ui * values[i];
                    gradient += ui * (gradients[i] + element.shifts[i]).transpose();
                }
                visit(&FieldSample { position: *p, weight: w, displacement: u, gradient });
            }
        }
    }
}
