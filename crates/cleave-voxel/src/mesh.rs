//! The voxel cube mesh (mueller2004 §2.1–2.2): equal cubes in a hash map keyed by integer
//! coordinates, shared corner nodes, one 24×24 stiffness for the whole mesh, per-cube rotations,
//! lumped mass, trilinear embedding, and a matrix-free warped stiffness action. Cubes can be
//! separated across chosen faces ([`VoxelMesh::separate_faces`]): the nodes of a cut face are
//! duplicated, which is fracture along cube faces and the conforming cracked reference of
//! benchmarks.md §5.

use crate::stiffness::{corner_offset, corner_signs, cube_stiffness};
use cleave_core::quadrature::gauss_legendre;
use cleave_core::{
    BlockSet, BlockSetBuilder, CoarseSpace, Discretization, DofRemap, EmbedError, Embedding, FieldSample, FrameRemap,
    Mass, Material, Matrix3, Point3, Real, RotationStats, TopologyChange, Vector3,
};
use cleave_geometry::UnionFind;
use nalgebra::DMatrix;
use std::collections::{HashMap, HashSet};

/// Why a voxel mesh could not be built.
#[derive(Debug, thiserror::Error)]
pub enum VoxelError {
    /// Cell size not finite and positive.
    #[error("cube size must be finite and > 0, got {0}")]
    CellSize(Real),
    /// No cubes.
    #[error("the voxel mesh has no cubes")]
    Empty,
    /// The same cube listed twice.
    #[error("cube ({0}, {1}, {2}) is listed twice")]
    DuplicateCube(i32, i32, i32),
    /// Internal block bookkeeping failed (a bug).
    #[error(transparent)]
    Blocks(#[from] cleave_core::BlockSetError),
    /// A face to separate does not lie between two cubes of the mesh.
    #[error("face of cube ({0}, {1}, {2}) towards +{3} does not lie between two cubes of the mesh")]
    NotInteriorFace(i32, i32, i32, char),
}

/// The face between the cube at integer coordinates `cell` and its neighbour at `cell + e_axis`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CubeFace {
    /// The cube on the face's minus side.
    pub cell: [i32; 3],
    /// The face's normal axis (0 = x, 1 = y, 2 = z).
    pub axis: usize,
}

impl CubeFace {
    /// Lattice coordinates of the face's four corners.
    pub fn corners(&self) -> [[i32; 3]; 4] {
        let (u, v) = ((self.axis + 1) % 3, (self.axis + 2) % 3);
        std::array::from_fn(|k| {
            let mut c = self.cell;
            c[self.axis] += 1;
            c[u] += (k & 1) as i32;
            c[v] += (k >> 1) as i32;
            c
        })
    }
}

/// Iterations of the warm-started rotation extraction per step; the warm start makes 2–3 enough
/// for smooth motion, the cap bounds the cost of violent steps.
const ROTATION_ITERATIONS: usize = 8;

/// Edge of the coarse cubes of the two-level preconditioner, in cubes (measured in
/// `docs/results/voxel-bench.md`).
const DEFAULT_COARSENING: i32 = 2;

/// A mesh of equal cubes with shared corners.
#[derive(Clone, Debug)]
pub struct VoxelMesh {
    material: Material,
    origin: Point3<Real>,
    h: Real,
    /// Sorted z-major (`(z, y, x)`): `cube_at` is a binary search. A hash table, as the paper
    /// has, took 35 B a cube more (docs/results/voxel-bench.md, memory).
    cells: Vec<[i32; 3]>,
    node_coords: Vec<[i32; 3]>,
    rest: Vec<Real>,
    mass: Mass,
    stiffness: Box<[Real; 576]>,
    blocks: BlockSet,
    epoch: u64,
    coarsening: i32,
    /// Faces across which cubes do not share nodes (sorted).
    cut_faces: Vec<CubeFace>,
    /// The surface mesh the cubes carry, if any ([`VoxelMesh::carry_surface`]).
    input: Option<std::sync::Arc<crate::surface::EmbeddedInput>>,
}

impl VoxelMesh {
    /// The boundary faces (cube faces without a neighbour) as triangles over the nodes, two per
    /// face, outward oriented.
    pub fn boundary_triangles(&self) -> Vec<[u32; 3]> {
        // For each axis and side: the four corners of that face (bit `axis` fixed), in cyclic order.
        let mut triangles = Vec::new();
        for (cube, cell) in self.cells().iter().enumerate() {
            for axis in 0..3 {
                for side in [0, 1] {
                    let mut neighbour = *cell;
                    neighbour[axis] += if side == 1 { 1 } else { -1 };
                    if self.cube_at(neighbour).is_some() {
                        continue;
                    }
                    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                    let corner = |a: usize, b: usize| (side << axis) | (a << u) | (b << v);
                    let quad = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                    let nodes = quad.map(|c| self.cube_nodes()[cube][c]);
                    // (u, v, axis) is right-handed, so the cyclic order above faces +axis; flip it on
                    // the minus side.
                    if side == 1 {
                        triangles.push([nodes[0], nodes[1], nodes[2]]);
                        triangles.push([nodes[0], nodes[2], nodes[3]]);
                    } else {
                        triangles.push([nodes[0], nodes[2], nodes[1]]);
                        triangles.push([nodes[0], nodes[3], nodes[2]]);
                    }
                }
            }
        }
        triangles
    }

    /// Builds the mesh of the cubes `[origin + h·c, origin + h·(c+1)]` for `c ∈ cells`.
    pub fn new(material: Material, origin: Point3<Real>, h: Real, cells: &[[i32; 3]]) -> Result<Self, VoxelError> {
        Self::with_cut_faces(material, origin, h, cells, &[])
    }

    /// Builds the mesh of `cells` with the cubes on the two sides of every face in `cut` holding
    /// their own copies of that face's nodes (a zero-thickness crack along cube faces). Node
    /// copies are united across every face that is not cut; a node no cut face touches is one
    /// node for all its cubes, as in [`VoxelMesh::new`] (cubes that touch only along an edge or
    /// at a corner keep sharing it). So a cut face's corner is duplicated exactly when the cubes
    /// around it fall apart into several groups across uncut faces: a crack front (an edge
    /// where the cut ends inside the material) keeps one node.
    pub fn with_cut_faces(
        material: Material,
        origin: Point3<Real>,
        h: Real,
        cells: &[[i32; 3]],
        cut: &[CubeFace],
    ) -> Result<Self, VoxelError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(VoxelError::CellSize(h));
        }
        if cells.is_empty() {
            return Err(VoxelError::Empty);
        }
        // Sort cubes and nodes z-major so that cubes near in index share nodes near in index: the
        // parallel scatter's per-chunk DOF ranges then barely overlap.
        let mut cells = cells.to_vec();
        cells.sort_unstable_by_key(|c| (c[2], c[1], c[0]));
        if let Some(w) = cells.windows(2).find(|w| w[0] == w[1]) {
            return Err(VoxelError::DuplicateCube(w[0][0], w[0][1], w[0][2]));
        }
        let cell_index: HashMap<[i32; 3], u32> = cells.iter().enumerate().map(|(i, c)| (*c, i as u32)).collect();
        let mut cut_faces: Vec<CubeFace> = cut.to_vec();
        cut_faces.sort_unstable();
        cut_faces.dedup();
        for face in &cut_faces {
            let mut other = face.cell;
            other[face.axis.min(2)] += 1;
            if face.axis > 2 || !cell_index.contains_key(&face.cell) || !cell_index.contains_key(&other) {
                let c = face.cell;
                return Err(VoxelError::NotInteriorFace(c[0], c[1], c[2], ['x', 'y', 'z'][face.axis.min(2)]));
            }
        }
        let coords_of = |copy: usize| {
            let (cell, o) = (cells[copy / 8], corner_offset(copy % 8));
            [cell[0] + o[0], cell[1] + o[1], cell[2] + o[2]]
        };
        // Copy 8·cube + corner; united across uncut faces, and wholly at untouched nodes.
        let mut copies = UnionFind::new(8 * cells.len());
        let cut_set: HashSet<CubeFace> = cut_faces.iter().copied().collect();
        let touched: HashSet<[i32; 3]> = cut_faces.iter().flat_map(|f| f.corners()).collect();
        let mut first_copy: HashMap<[i32; 3], u32> = HashMap::with_capacity(cells.len() * 2);
        for copy in 0..8 * cells.len() {
            let coords = coords_of(copy);
            if !touched.contains(&coords) {
                let first = *first_copy.entry(coords).or_insert(copy as u32);
                copies.union(first as usize, copy);
            }
        }
        if !cut_faces.is_empty() {
            for (cube, cell) in cells.iter().enumerate() {
                for axis in 0..3 {
                    let mut next = *cell;
                    next[axis] += 1;
                    let Some(&neighbour) = cell_index.get(&next) else { continue };
                    if cut_set.contains(&CubeFace { cell: *cell, axis }) {
                        continue;
                    }
                    // Corner c of this cube with bit `axis` set is corner c − 2^axis of the next.
                    for c in (0..8).filter(|c| c & (1 << axis) != 0) {
                        copies.union(8 * cube + c, 8 * neighbour as usize + (c - (1 << axis)));
                    }
                }
            }
        }
        // One node per class, numbered z-major by lattice coordinates, then by first copy.
        let mut classes: Vec<([i32; 3], u32)> = (0..8 * cells.len() as u32)
            .filter(|&copy| copies.find(copy as usize) == copy as usize)
            .map(|copy| (coords_of(copy as usize), copy))
            .collect();
        classes.sort_unstable_by_key(|(c, copy)| (c[2], c[1], c[0], *copy));
        let mut class_node: HashMap<u32, u32> = HashMap::with_capacity(classes.len());
        for (node, (_, copy)) in classes.iter().enumerate() {
            class_node.insert(*copy, node as u32);
        }
        let node_coords: Vec<[i32; 3]> = classes.iter().map(|(c, _)| *c).collect();
        let cube_nodes: Vec<[u32; 8]> = (0..cells.len())
            .map(|cube| std::array::from_fn(|c| class_node[&(copies.find(8 * cube + c) as u32)]))
            .collect();
        let mut rest: Vec<Real> = Vec::with_capacity(3 * node_coords.len());
        rest.extend(node_coords.iter().flat_map(|c| (0..3).map(move |a| origin[a] + h * c[a] as Real)));
        let mut lumped = vec![0.0; 3 * node_coords.len()];
        let corner_mass = material.density * h * h * h / 8.0;
        for nodes in &cube_nodes {
            for &n in nodes {
                for a in 0..3 {
                    lumped[3 * n as usize + a] += corner_mass;
                }
            }
        }
        let stiffness = Box::new(cube_stiffness(&material, h));
        let mut builder = BlockSetBuilder::new().translation_invariant();
        let rest_id = builder.add_rest_matrix(DMatrix::from_row_slice(24, 24, &stiffness[..]))?;
        for (cube, nodes) in cube_nodes.iter().enumerate() {
            builder.push(nodes, rest_id, Some(cube as u32));
        }
        drop(cube_nodes);
        let blocks = builder.finish(node_coords.len())?;
        Ok(Self {
            material,
            origin,
            h,
            cells,
            node_coords,
            rest,
            mass: Mass::Lumped(lumped),
            stiffness,
            blocks,
            epoch: 0,
            coarsening: DEFAULT_COARSENING,
            cut_faces,
            input: None,
        })
    }

    /// The faces across which cubes do not share nodes, sorted.
    pub fn cut_faces(&self) -> &[CubeFace] {
        &self.cut_faces
    }

    /// Makes the cubes carry the closed surface `surface` (rest space, inside the cubes): its
    /// triangles split so no edge exceeds the cube edge, each assigned to the cube under its
    /// centroid. Cuts then separate it along triangle edges and cap what opens
    /// (`Cuttable::surface`, docs/math/voxel-cutting.md §4).
    pub fn carry_surface(&mut self, surface: &cleave_geometry::TriangleMesh) -> Result<usize, String> {
        let h = self.h;
        let input = crate::surface::EmbeddedInput::new(surface, self.origin, h, |p| {
            let local = (p - self.origin) / h;
            let base = [local.x.floor() as i32, local.y.floor() as i32, local.z.floor() as i32];
            (0..27).find_map(|k: i32| {
                let cell = [base[0] + k % 3 - 1, base[1] + (k / 3) % 3 - 1, base[2] + k / 9 - 1];
                let inside = (0..3).all(|a| (-1e-9..=1.0 + 1e-9).contains(&(local[a] - cell[a] as Real)));
                (inside && self.cube_at(cell).is_some()).then_some(cell)
            })
        })?;
        let triangles = input.num_triangles();
        self.input = Some(std::sync::Arc::new(input));
        Ok(triangles)
    }

    /// The surface the cubes carry, if any.
    pub(crate) fn embedded_input(&self) -> Option<&crate::surface::EmbeddedInput> {
        self.input.as_deref()
    }

    /// This mesh with the cubes also separated across `faces` (added to [`VoxelMesh::cut_faces`]),
    /// in the next epoch, and the change that carries state over: every new node is a copy of
    /// the old node at its place (`DofRemap::Gather`), cubes and their frames keep their
    /// indices. Positions and velocities mapped this way describe the same motion of every
    /// material point, so a separation between steps adds no energy.
    pub fn separate_faces(&self, faces: &[CubeFace]) -> Result<(VoxelMesh, TopologyChange), VoxelError> {
        let all: Vec<CubeFace> = self.cut_faces.iter().chain(faces).copied().collect();
        let mut mesh = Self::with_cut_faces(self.material, self.origin, self.h, &self.cells, &all)?;
        mesh.coarsening = self.coarsening;
        mesh.input.clone_from(&self.input);
        let source: Vec<u32> = {
            let mut source = vec![u32::MAX; mesh.num_nodes()];
            for (new, old) in mesh.cube_nodes().iter().zip(self.cube_nodes()) {
                for (&n, &o) in new.iter().zip(old) {
                    source[n as usize] = o;
                }
            }
            source
        };
        let same = mesh.cut_faces == self.cut_faces;
        mesh.epoch = if same { self.epoch } else { self.epoch + 1 };
        let change = TopologyChange {
            epoch: mesh.epoch,
            remap: if same { DofRemap::Identity } else { DofRemap::Gather(source) },
            frames: FrameRemap::Identity,
            pattern_changed: !same,
        };
        Ok((mesh, change))
    }

    /// A box of `dims` cubes of edge `h` with minimum corner `origin`.
    pub fn from_box(material: Material, origin: Point3<Real>, h: Real, dims: [usize; 3]) -> Result<Self, VoxelError> {
        let mut cells = Vec::with_capacity(dims.iter().product());
        for k in 0..dims[2] as i32 {
            for j in 0..dims[1] as i32 {
                for i in 0..dims[0] as i32 {
                    cells.push([i, j, k]);
                }
            }
        }
        Self::new(material, origin, h, &cells)
    }

    /// The material of every cube.
    pub fn material(&self) -> &Material {
        &self.material
    }

    /// Cube edge length.
    pub fn cell_size(&self) -> Real {
        self.h
    }

    /// Minimum corner of cube (0, 0, 0).
    pub fn origin(&self) -> Point3<Real> {
        self.origin
    }

    /// Integer coordinates of the cubes, z-major order (cube index = position here).
    pub fn cells(&self) -> &[[i32; 3]] {
        &self.cells
    }

    /// Number of cubes.
    pub fn num_cubes(&self) -> usize {
        self.cells.len()
    }

    /// Node indices of every cube, corner `c = bx + 2by + 4bz`.
    pub fn cube_nodes(&self) -> &[[u32; 8]] {
        // One copy: the block set's node lists, one block of 8 per cube in cube order.
        self.blocks.all_nodes().as_chunks::<8>().0
    }

    /// Integer lattice coordinates of every node.
    pub fn node_coords(&self) -> &[[i32; 3]] {
        &self.node_coords
    }

    /// The one rest stiffness (row-major 24×24) all cubes share.
    pub fn cube_stiffness(&self) -> &[Real; 576] {
        &self.stiffness
    }

    /// Index of the cube at integer coordinates, if present (a binary search of the sorted cells).
    pub fn cube_at(&self, cell: [i32; 3]) -> Option<usize> {
        self.cells.binary_search_by_key(&(cell[2], cell[1], cell[0]), |c| (c[2], c[1], c[0])).ok()
    }

    /// Deformation gradient at the center of `cube`: `F = Σ_c x_c s_cᵀ / (4h)`, which is `I` at
    /// rest (docs/math/voxel-stiffness.md §4).
    pub fn center_gradient(&self, cube: usize, x: &[Real]) -> Matrix3<Real> {
        let mut f = Matrix3::zeros();
        for (c, &n) in self.cube_nodes()[cube].iter().enumerate() {
            let s = corner_signs(c);
            let p = &x[3 * n as usize..3 * n as usize + 3];
            for a in 0..3 {
                for b in 0..3 {
                    f[(a, b)] += p[a] * s[b];
                }
            }
        }
        f / (4.0 * self.h)
    }

    /// Sets the edge of the coarse cubes of [`Discretization::coarse_space`] in cubes (≥ 2;
    /// smaller values are raised to 2).
    pub fn set_coarsening(&mut self, ratio: i32) {
        self.coarsening = ratio.max(2);
    }

    /// The coarse space of cubes of edge `ratio·h` (the parents `⌊c/ratio⌋` of the cubes) with
    /// trilinear interpolation of every fine node from a parent that contains it. Neighbouring
    /// parents share their face nodes and interpolate a node on a shared face from those alone,
    /// so the prolongation is continuous and reproduces every coarse trilinear field, rigid
    /// motions included. `ratio` below 2 is raised to 2.
    pub fn coarse_space_with_ratio(&self, ratio: i32) -> CoarseSpace {
        let ratio = ratio.max(2);
        let parent = |cell: &[i32; 3]| cell.map(|c| c.div_euclid(ratio));
        let mut coarse_nodes: Vec<[i32; 3]> = Vec::with_capacity(self.cells.len() / 2);
        for cell in &self.cells {
            let p = parent(cell);
            for c in 0..8 {
                let o = corner_offset(c);
                coarse_nodes.push([p[0] + o[0], p[1] + o[1], p[2] + o[2]]);
            }
        }
        coarse_nodes.sort_unstable_by_key(|c| (c[2], c[1], c[0]));
        coarse_nodes.dedup();
        let coarse_index: HashMap<[i32; 3], u32> =
            coarse_nodes.iter().enumerate().map(|(i, c)| (*c, i as u32)).collect();
        // One parent per fine node: the parent of any cube touching it.
        let mut node_parent: Vec<Option<[i32; 3]>> = vec![None; self.node_coords.len()];
        for (cell, nodes) in self.cells.iter().zip(self.cube_nodes()) {
            for &n in nodes {
                node_parent[n as usize].get_or_insert_with(|| parent(cell));
            }
        }
        let mut prolongation = Embedding::new();
        let (mut nodes, mut weights) = (Vec::with_capacity(8), Vec::with_capacity(8));
        for (coords, p) in self.node_coords.iter().zip(&node_parent) {
            let p = p.expect("every node belongs to a cube");
            // Local coordinate in the parent, in [0, 1] per axis.
            let t: [Real; 3] = std::array::from_fn(|a| (coords[a] - ratio * p[a]) as Real / ratio as Real);
            nodes.clear();
            weights.clear();
            for c in 0..8 {
                let o = corner_offset(c);
                let w: Real = (0..3).map(|a| if o[a] == 1 { t[a] } else { 1.0 - t[a] }).product();
                if w != 0.0 {
                    nodes.push(coarse_index[&[p[0] + o[0], p[1] + o[1], p[2] + o[2]]]);
                    weights.push(w);
                }
            }
            prolongation.push_row(&nodes, &weights);
        }
        CoarseSpace { num_nodes: coarse_nodes.len(), prolongation }
    }

    /// Trilinear shape values and reference gradients at local coordinates `t ∈ [0,1]³`.
    fn shape(&self, t: [Real; 3]) -> ([Real; 8], [[Real; 3]; 8]) {
        let mut values = [0.0; 8];
        let mut gradients = [[0.0; 3]; 8];
        for c in 0..8 {
            let o = corner_offset(c);
            let f: [Real; 3] = std::array::from_fn(|a| if o[a] == 1 { t[a] } else { 1.0 - t[a] });
            let d: [Real; 3] = std::array::from_fn(|a| if o[a] == 1 { 1.0 } else { -1.0 } / self.h);
            values[c] = f[0] * f[1] * f[2];
            gradients[c] = [d[0] * f[1] * f[2], f[0] * d[1] * f[2], f[0] * f[1] * d[2]];
        }
        (values, gradients)
    }

    fn gauss_points(min_degree: usize) -> (&'static [Real], &'static [Real]) {
        let n = (min_degree / 2 + 1).clamp(1, 6);
        gauss_legendre(n).expect("1..=6 point rules exist")
    }

    /// The fast warped kernel shared by the force and the stiffness action:
    /// `out_c += s · R K (Rᵀ v_c − offset_c)` where `offset` is the rest corners (force) or zero.
    fn warped_cube_product(
        &self,
        rotations: &[Matrix3<Real>],
        v: &[Real],
        subtract_rest: bool,
        scale: Real,
        out: &mut [Real],
    ) {
        let k = &*self.stiffness;
        // The 24 × 24 product in the widest vector instructions the processor has, chosen at
        // run time: the release build targets baseline x86-64 (SSE2), and AVX2 doubles the
        // action's speed on the voxel bunny (docs/results/voxel-bench.md, "Run-time SIMD").
        let arch = pulp::Arch::new();
        self.blocks.scatter_plan().scatter_add(out, |cube, buf, base| {
            let nodes = &self.cube_nodes()[cube];
            let r = &rotations[cube];
            let mut local = [0.0; 24];
            // For the force, positions are taken relative to the cube's first corner (in x and
            // in X): K annihilates a common translation, so the result is the same, but the
            // rounding no longer grows with the distance to the world origin.
            let first = 3 * nodes[0] as usize;
            let (o, o_rest) = if subtract_rest {
                ([v[first], v[first + 1], v[first + 2]], [self.rest[first], self.rest[first + 1], self.rest[first + 2]])
            } else {
                ([0.0; 3], [0.0; 3])
            };
            for (c, &n) in nodes.iter().enumerate() {
                let i = 3 * n as usize;
                let (p0, p1, p2) = (v[i] - o[0], v[i + 1] - o[1], v[i + 2] - o[2]);
                for a in 0..3 {
                    // (Rᵀ p)_a = Σ_b R_ba p_b
                    let mut value = r[(0, a)] * p0 + r[(1, a)] * p1 + r[(2, a)] * p2;
                    if subtract_rest {
                        value -= self.rest[i + a] - o_rest[a];
                    }
                    local[3 * c + a] = value;
                }
            }
            // y = K local as a sum of columns (K is symmetric, so column `col` is row `col`):
            // 24-wide axpys vectorize without reassociating a dot product's sum.
            let y = arch.dispatch(CubeProduct { k, local: &local });
            for (c, &n) in nodes.iter().enumerate() {
                let i = 3 * n as usize - base;
                let (q0, q1, q2) = (y[3 * c], y[3 * c + 1], y[3 * c + 2]);
                for a in 0..3 {
                    buf[i + a] += scale * (r[(a, 0)] * q0 + r[(a, 1)] * q1 + r[(a, 2)] * q2);
                }
            }
        });
    }
}

/// `K l` for the symmetric 24 × 24 cube matrix `K`, as a sum of its columns (column `col` is row
/// `col`): 24-wide multiply-adds that vectorize without reassociating a dot product's sum, so
/// every instruction set gives the same bits. Compiled once per instruction set `pulp` knows
/// and chosen at run time (`pulp::Arch::dispatch` inlines it into a function built for AVX2+FMA
/// where the processor has them).
struct CubeProduct<'a> {
    k: &'a [Real; 576],
    local: &'a [Real; 24],
}

impl pulp::WithSimd for CubeProduct<'_> {
    type Output = [Real; 24];

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> [Real; 24] {
        let mut y = [0.0; 24];
        for (col, &l) in self.local.iter().enumerate() {
            let k_col: &[Real; 24] = self.k[24 * col..24 * col + 24].try_into().expect("24 entries");
            for (y, &k) in y.iter_mut().zip(k_col) {
                *y += k * l;
            }
        }
        y
    }
}

impl Discretization for VoxelMesh {
    fn name(&self) -> &str {
        "voxel"
    }

    fn num_nodes(&self) -> usize {
        self.node_coords.len()
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
        self.cells.len()
    }

    fn write_rotations(&self, x: &[Real], rotations: &mut [Matrix3<Real>]) -> RotationStats {
        cleave_core::rotation::write_frame_rotations(rotations, ROTATION_ITERATIONS, |cube| {
            self.center_gradient(cube, x)
        })
    }

    fn blocks(&self) -> &BlockSet {
        &self.blocks
    }

    fn coarse_space(&self) -> Option<CoarseSpace> {
        Some(self.coarse_space_with_ratio(self.coarsening))
    }

    fn as_cuttable(&mut self) -> Option<&mut dyn cleave_core::Cuttable> {
        Some(self)
    }

    fn as_fracturable(&mut self) -> Option<&mut dyn cleave_core::Fracturable> {
        Some(self)
    }

    fn copy_for_cutting(&self) -> Option<Box<dyn Discretization>> {
        Some(Box::new(self.clone()))
    }

    fn add_internal_force(&self, rotations: &[Matrix3<Real>], x: &[Real], out: &mut [Real]) {
        self.warped_cube_product(rotations, x, true, -1.0, out);
    }

    fn add_stiffness_action(&self, rotations: &[Matrix3<Real>], dx: &[Real], scale: Real, out: &mut [Real]) {
        self.warped_cube_product(rotations, dx, false, scale, out);
    }

    fn add_load(&self, force_density: &dyn Fn(&Point3<Real>) -> Vector3<Real>, out: &mut [Real]) {
        // 3 points per axis: exact for trilinear × quadratic force densities.
        let (points, weights) = Self::gauss_points(4);
        let jacobian = (self.h / 2.0).powi(3);
        for (cube, cell) in self.cells.iter().enumerate() {
            let corner = self.origin + Vector3::new(cell[0] as Real, cell[1] as Real, cell[2] as Real) * self.h;
            for (qa, wa) in points.iter().zip(weights) {
                for (qb, wb) in points.iter().zip(weights) {
                    for (qc, wc) in points.iter().zip(weights) {
                        let t = [(qa + 1.0) / 2.0, (qb + 1.0) / 2.0, (qc + 1.0) / 2.0];
                        let p = corner + Vector3::new(t[0], t[1], t[2]) * self.h;
                        let f = force_density(&p) * (wa * wb * wc * jacobian);
                        let (values, _) = self.shape(t);
                        for (c, &n) in self.cube_nodes()[cube].iter().enumerate() {
                            for a in 0..3 {
                                out[3 * n as usize + a] += values[c] * f[a];
                            }
                        }
                    }
                }
            }
        }
    }

    fn embed(&self, points: &[Point3<Real>]) -> Result<Embedding, EmbedError> {
        let mut embedding = Embedding::new();
        let tolerance = 1e-9;
        for (index, p) in points.iter().enumerate() {
            let local = (p - self.origin) / self.h;
            let base = [local.x.floor() as i32, local.y.floor() as i32, local.z.floor() as i32];
            // A point on a cube face or corner may belong to a neighbour only: try the cube the
            // floor names first, then the neighbours whose closed cube still contains the point.
            let mut found = None;
            'search: for dz in [0, -1, 1] {
                for dy in [0, -1, 1] {
                    for dx in [0, -1, 1] {
                        let cell = [base[0] + dx, base[1] + dy, base[2] + dz];
                        if let Some(cube) = self.cube_at(cell) {
                            let t: [Real; 3] = std::array::from_fn(|a| local[a] - cell[a] as Real);
                            if t.iter().all(|&t| (-tolerance..=1.0 + tolerance).contains(&t)) {
                                found = Some((cube, t.map(|t| t.clamp(0.0, 1.0))));
                                break 'search;
                            }
                        }
                    }
                }
            }
            let Some((cube, t)) = found else {
                return Err(EmbedError::Outside { index, x: p.x, y: p.y, z: p.z });
            };
            let (weights, _) = self.shape(t);
            embedding.push_row(&self.cube_nodes()[cube], &weights);
        }
        Ok(embedding)
    }

    fn visit_field(&self, displacement: &[Real], min_degree: usize, visit: &mut dyn FnMut(&FieldSample)) {
        let (points, weights) = Self::gauss_points(min_degree);
        let jacobian = (self.h / 2.0).powi(3);
        for (cube, cell) in self.cells.iter().enumerate() {
            let corner = self.origin + Vector3::new(cell[0] as Real, cell[1] as Real, cell[2] as Real) * self.h;
            for (qa, wa) in points.iter().zip(weights) {
                for (qb, wb) in points.iter().zip(weights) {
                    for (qc, wc) in points.iter().zip(weights) {
                        let t = [(qa + 1.0) / 2.0, (qb + 1.0) / 2.0, (qc + 1.0) / 2.0];
                        let (values, gradients) = self.shape(t);
                        let mut u = Vector3::zeros();
                        let mut grad = Matrix3::zeros();
                        for (c, &n) in self.cube_nodes()[cube].iter().enumerate() {
                            let d = &displacement[3 * n as usize..3 * n as usize + 3];
                            for a in 0..3 {
                                u[a] += values[c] * d[a];
                                for b in 0..3 {
                                    grad[(a, b)] += d[a] * gradients[c][b];
                                }
                            }
                        }
                        visit(&FieldSample {
                            position: corner + Vector3::new(t[0], t[1], t[2]) * self.h,
                            weight: wa * wb * wc * jacobian,
                            displacement: u,
                            gradient: grad,
                        });
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod boundary_tests {
    use super::*;

    #[test]
    fn the_boundary_of_an_l_shaped_voxel_body_is_closed_outward_and_encloses_its_cubes() {
        let material = Material::new(1e5, 0.3, 1000.0).unwrap();
        let cells = [[0, 0, 0], [1, 0, 0], [0, 1, 0]];
        let mesh = VoxelMesh::new(material, Point3::new(0.3, -0.2, 1.0), 0.5, &cells).unwrap();
        let vertices: Vec<Point3<Real>> = mesh.rest_dofs().chunks(3).map(|p| Point3::new(p[0], p[1], p[2])).collect();
        let surface = cleave_geometry::TriangleMesh::new(vertices, mesh.boundary_triangles());
        // Three cubes expose 3·6 − 2·2 = 14 faces, two triangles each.
        assert_eq!(surface.triangles.len(), 28);
        surface.validate_closed().unwrap();
        assert!((surface.signed_volume() - 3.0 * 0.125).abs() < 1e-12, "{}", surface.signed_volume());
    }
}

#[cfg(test)]
mod simd_tests {
    use super::*;
    use pulp::WithSimd;

    #[test]
    fn the_dispatched_cube_product_gives_the_scalar_bits() {
        // Whatever instruction set the processor offers, the product adds the same columns in
        // the same order without fusing: bit for bit the baseline's result.
        let material = Material::new(2.7e5, 0.31, 1000.0).unwrap();
        let k = crate::stiffness::cube_stiffness(&material, 0.013);
        for seed in 0..20 {
            let local: [Real; 24] = std::array::from_fn(|i| ((i * 7919 + seed * 104_729) as Real * 0.618).sin() * 1e-3);
            let scalar = CubeProduct { k: &k, local: &local }.with_simd(pulp::Scalar::new());
            let dispatched = pulp::Arch::new().dispatch(CubeProduct { k: &k, local: &local });
            assert_eq!(scalar.map(Real::to_bits), dispatched.map(Real::to_bits));
            // And it is K l: row 3 by a plain dot product, within rounding.
            let row: Real = (0..24).map(|j| k[24 * 3 + j] * local[j]).sum();
            assert!((row - scalar[3]).abs() <= 1e-12 * k.iter().map(|v| v.abs()).fold(0.0, Real::max) * 1e-3 * 24.0);
        }
    }
}
