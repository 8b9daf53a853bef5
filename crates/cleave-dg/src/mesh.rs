//! `DgMesh`: the discontinuous Galerkin discretization of kaufmann2008 on a polyhedral mesh — exact
//! element and face integrals, BZ or IP fluxes, weak Dirichlet data, penalty doubling until the
//! stiffness is positive definite, corotated face blocks. Formulas: docs/math/dg.md.

use crate::basis::{ElementBasis, add, basis_size, exponents, index, shifted_monomial};
use crate::quadrature::{polygon_rule, polyhedron_rule};
use cleave_core::{
    AssemblyPattern, BlockRanks, BlockSet, BlockSetBuilder, BlockSetError, CholeskyError, Discretization, EmbedError,
    Embedding, FieldSample, Mass, Material, Matrix3, Point3, Real, RotationStats, SparseCholesky, Vector3,
};
use cleave_geometry::{
    ElementFace, Frame, GeometryError, PolyhedralMesh, element_moments_from_faces, face_area_normal_centroid,
    face_moments,
};
use nalgebra::DMatrix;
use rayon::prelude::*;

mod cut;
mod refine;

/// How far a face's vertex may lie off its plane, in face diameters (`PolyhedralMesh::validate`).
const PLANARITY: Real = 1e-8;

pub use refine::{RefineSplit, Refinement};

/// The numerical flux on interior faces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flux {
    /// Babuška–Zlámal: penalty only. Stable for any η > 0, not consistent (docs/math/dg.md §4).
    BabuskaZlamal,
    /// Symmetric interior penalty: consistency, symmetry and penalty terms.
    InteriorPenalty,
}

/// Construction options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DgOptions {
    /// Polynomial degree of the basis: 1 (4 functions per element) or 2 (10).
    pub degree: usize,
    /// Interior-face flux.
    pub flux: Flux,
    /// Initial global penalty η (dimensionless; the face penalty is `η E area (1/vol⁻ + 1/vol⁺)`).
    pub penalty: Real,
    /// How often η may be doubled while the stiffness is not positive definite.
    pub max_doublings: u32,
    /// Factor applied to the first positive definite η (1: the paper's rule). The doubling stops
    /// just above the coercivity threshold, where the error is smallest; corotated dynamics of
    /// nearly incompressible IP models needs head room there, because warping the element and
    /// face terms by different rotations breaks the balance that makes `K` definite at rest
    /// (docs/math/dg.md §9 and docs/results/stability.md). `K(η)` is definite for every η above
    /// the first definite one, so no further check is needed.
    pub penalty_margin: Real,
    /// A cut's child below this fraction of the volume of the element it came from is merged
    /// into a neighbour (docs/math/dg.md §13.6); 0 turns merging off. Merging moves the
    /// sliver's material points by the jump between its polynomial and the neighbour's; without
    /// it every point keeps its motion exactly, but thin children condition the bases poorly.
    pub sliver_fraction: Real,
}

impl DgOptions {
    /// Degree and flux with the default penalty start: IP starts low (η = 1) and doubles until
    /// positive definite, since accuracy is best just above the coercivity threshold (measured in
    /// docs/math/dg.md §5); BZ, stable for any η, uses η = 10, the low end of the paper's range.
    pub fn new(degree: usize, flux: Flux) -> Self {
        let penalty = match flux {
            Flux::InteriorPenalty => 1.0,
            Flux::BabuskaZlamal => 10.0,
        };
        Self { degree, flux, penalty, max_doublings: 24, penalty_margin: 1.0, sliver_fraction: 0.05 }
    }
}

impl Default for DgOptions {
    fn default() -> Self {
        Self::new(1, Flux::InteriorPenalty)
    }
}

/// Weakly imposed Dirichlet data: boundary faces whose centroid satisfies `on_boundary` get
/// `u⁻ := g` (kaufmann2008 §5).
pub struct WeakDirichlet<'a> {
    /// Selects Dirichlet faces by their centroid (rest position).
    pub on_boundary: &'a (dyn Fn(&Point3<Real>) -> bool + Sync),
    /// The prescribed displacement `g` at a rest position.
    pub data: &'a (dyn Fn(&Point3<Real>) -> Vector3<Real> + Sync),
}

/// Why a DG mesh could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DgError {
    /// The polyhedral mesh is invalid.
    #[error("invalid polyhedral mesh: {0}")]
    Mesh(#[from] GeometryError),
    /// Unsupported degree.
    #[error("polynomial degree {0} is not supported (use 1 or 2)")]
    Degree(usize),
    /// Non-positive or non-finite penalty.
    #[error("penalty η = {0} must be positive and finite")]
    Penalty(Real),
    /// A penalty margin below 1 or not finite.
    #[error("penalty margin {0} must be a finite number ≥ 1")]
    PenaltyMargin(Real),
    /// A sliver fraction outside [0, 1).
    #[error("sliver fraction {0} must be a number in [0, 1)")]
    SliverFraction(Real),
    /// An element whose Gram matrix is singular.
    #[error("element {element} is degenerate (volume {volume:e} m³): its basis cannot be orthonormalized")]
    DegenerateElement {
        /// element index
        element: usize,
        /// its volume
        volume: Real,
    },
    /// The penalty doubling did not reach a positive definite stiffness.
    #[error("the stiffness is not positive definite even with η = {penalty} after {doublings} doublings")]
    NotPositiveDefinite {
        /// the last η tried
        penalty: Real,
        /// doublings done
        doublings: u32,
    },
    /// A block the backend built is malformed (a bug, reported instead of panicking).
    #[error("internal block error: {0}")]
    Blocks(#[from] BlockSetError),
    /// The sparse Cholesky of the definiteness check could not be set up (out of memory).
    #[error("definiteness check: {0}")]
    Solver(String),
}

/// The penalty doubling's test of positive definiteness of `K`, or for free bodies of `K + s I`
/// with `s` a 1e-8 fraction of the largest diagonal entry, which lifts the six rigid modes but not
/// a negative eigenvalue of an insufficient penalty, whose size is that of the stiffness itself
/// (docs/math/dg.md §5). Built at the first η and kept for the next: η changes values, never
/// the pattern, so the pattern, ranks, diagonal positions and symbolic factorization are reused.
struct DefinitenessCheck {
    pattern: AssemblyPattern,
    ranks: BlockRanks,
    values: Vec<Real>,
    identity: Vec<Matrix3<Real>>,
    /// Positions of the diagonal entries when `K` needs the shift (free bodies), else empty.
    shifted_diagonal: Vec<usize>,
    cholesky: SparseCholesky,
}

impl DefinitenessCheck {
    fn new(blocks: &BlockSet, num_nodes: usize, num_frames: usize, free_body: bool) -> Result<Self, DgError> {
        let pattern = AssemblyPattern::from_groups(num_nodes, blocks.node_groups());
        let ranks = BlockRanks::new(blocks, &pattern);
        let shifted_diagonal = if free_body {
            (0..pattern.dim())
                .map(|d| {
                    let node = (d / 3) as u32;
                    let rank = pattern.rank(node, node).expect("diagonal is in the pattern");
                    pattern.position(rank, node, d % 3, d % 3)
                })
                .collect()
        } else {
            Vec::new()
        };
        let cholesky = SparseCholesky::new(&pattern).map_err(|e| DgError::Solver(e.to_string()))?;
        let values = pattern.new_values();
        Ok(Self { pattern, ranks, values, identity: vec![Matrix3::identity(); num_frames], shifted_diagonal, cholesky })
    }

    /// Whether the stiffness of `blocks` (same pattern as at construction) is positive definite.
    fn holds(&mut self, blocks: &BlockSet) -> Result<bool, DgError> {
        self.values.fill(0.0);
        blocks.add_to_matrix(&self.identity, 1.0, &self.pattern, &self.ranks, &mut self.values);
        let largest = self.shifted_diagonal.iter().map(|&p| self.values[p]).fold(0.0, Real::max);
        for &p in &self.shifted_diagonal {
            self.values[p] += 1e-8 * largest;
        }
        match self.cholesky.factorize(&self.values) {
            Ok(()) => Ok(true),
            Err(CholeskyError::NotPositiveDefinite { .. }) => Ok(false),
            Err(e) => Err(DgError::Solver(e.to_string())),
        }
    }
}

/// `visit(element, point, weight, ψ(point), ∇ψ(point))` of [`DgMesh::for_each_quadrature_point`].
type QuadratureVisitor<'a> = dyn FnMut(usize, &Point3<Real>, Real, &[Real], &[Vector3<Real>]) + 'a;

/// Face matrices before the penalty is chosen.
struct FaceTerms {
    /// Nodes of the block (K⁻'s basis then K⁺'s, or K's alone on a Dirichlet face).
    nodes: Vec<u32>,
    /// Symmetric consistency parts warped by an element's frame: (matrix, frame element).
    warped: Vec<(DMatrix<Real>, u32)>,
    /// On a Dirichlet face, the consistency part as an anchored block: (`H` with `K = H + Hᵀ`,
    /// frame element), docs/math/dg.md §6.
    anchored: Option<(DMatrix<Real>, u32)>,
    /// Penalty matrix for η = 1 (unwarped).
    unit_penalty: DMatrix<Real>,
    /// The weight `η_f` it was built with.
    weight: Real,
}

/// The DG discretization of one elastic body.
#[derive(Clone)]
pub struct DgMesh {
    name: String,
    material: Material,
    options: DgOptions,
    mesh: PolyhedralMesh,
    exps: Vec<[u32; 3]>,
    bases: Vec<ElementBasis>,
    rest: Vec<Real>,
    mass: Mass,
    blocks: BlockSet,
    penalty: Real,
    doublings: u32,
    dirichlet_load: Vec<Real>,
    /// Per element and basis function: `g_i` with `F = Σ_i d_i ⊗ g_i` the gradient at the centroid.
    rotation_gradients: Vec<Vector3<Real>>,
    has_dirichlet: bool,
    /// Per element: (face index, reversed) of its outward faces.
    element_faces: Vec<Vec<(u32, bool)>>,
    /// Seconds spent choosing η (assemblies and Cholesky attempts), part of `new`.
    penalty_search_seconds: Real,
    /// Topology changes so far (`Cuttable::cut`).
    epoch: u64,
    /// Per face of `mesh`: whether it lies on a cut (rendered as a cut face).
    cut_faces: Vec<bool>,
    /// Per face: its penalty weight `η_f` per unit η (docs/math/dg.md §4), kept by the pieces
    /// of a face a cut splits (§13) so that a cut leaves every jump's energy as it was.
    face_weights: Vec<Real>,
    /// Per element: how many refinements made it (§14; a cut's children keep their parent's).
    depth: Vec<u32>,
    /// How `Refinable::refine` splits.
    refinement: Refinement,
    /// Per face: whether it carries weak Dirichlet data.
    dirichlet_faces: Vec<bool>,
    /// The last cut's sliver merging: (merged, left below the threshold without a neighbour).
    last_slivers: (usize, usize),
    /// Whether the Dirichlet data is a clamp (`u = 0`, [`DgMesh::clamped`]) that cuts and
    /// refinements keep; other data cannot be rebuilt.
    clamp_kept: bool,
}

impl std::fmt::Debug for DgMesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DgMesh")
            .field("name", &self.name)
            .field("elements", &self.mesh.num_elements)
            .field("penalty", &self.penalty)
            .finish()
    }
}

fn lame_tensor(material: &Material, n: &Vector3<Real>) -> [[[Real; 3]; 3]; 3] {
    // T[a][b][d] with (σ(e_b ⊗ ∇φ) n)_a = Σ_d T[a][b][d] ∂_d φ (docs/math/dg.md §3).
    let (lambda, mu) = material.lame();
    let mut t = [[[0.0; 3]; 3]; 3];
    for a in 0..3 {
        for b in 0..3 {
            for d in 0..3 {
                let delta = |i: usize, j: usize| if i == j { 1.0 } else { 0.0 };
                t[a][b][d] = lambda * n[a] * delta(b, d) + mu * (delta(a, b) * n[d] + n[b] * delta(a, d));
            }
        }
    }
    t
}

impl DgMesh {
    /// Builds the discretization: bases, element stiffness, face terms, weak Dirichlet data, and
    /// the penalty doubling (docs/math/dg.md §5).
    pub fn new(
        mesh: PolyhedralMesh,
        material: Material,
        options: DgOptions,
        dirichlet: Option<&WeakDirichlet<'_>>,
    ) -> Result<Self, DgError> {
        Self::with_face_weights(mesh, material, options, dirichlet, None, None)
    }

    /// [`DgMesh::new`] clamped (weak Dirichlet data `u = 0`) on the boundary faces whose centroid
    /// satisfies `on_boundary`: the clamp is kept by cuts and refinements (the pieces of a
    /// clamped face stay clamped), which data given as a function cannot be.
    pub fn clamped(
        mesh: PolyhedralMesh,
        material: Material,
        options: DgOptions,
        on_boundary: &(dyn Fn(&Point3<Real>) -> bool + Sync),
    ) -> Result<Self, DgError> {
        let zero = |_: &Point3<Real>| Vector3::zeros();
        let dirichlet = WeakDirichlet { on_boundary, data: &zero };
        let mut dg = Self::with_face_weights(mesh, material, options, Some(&dirichlet), None, None)?;
        dg.clamp_kept = true;
        Ok(dg)
    }

    /// [`DgMesh::new`] with some interior faces' penalty weights given (`inherited[f]`; the
    /// others are computed from the geometry): a cut's pieces of an old face keep the old face's
    /// weight, with BZ; with IP, no less than the geometric one (`face_terms`).
    pub(crate) fn with_face_weights(
        mesh: PolyhedralMesh,
        material: Material,
        options: DgOptions,
        dirichlet: Option<&WeakDirichlet<'_>>,
        inherited: Option<&[Option<Real>]>,
        clamped_faces: Option<&[bool]>,
    ) -> Result<Self, DgError> {
        if clamped_faces.is_some_and(|c| c.len() != mesh.faces.len()) {
            return Err(DgError::Solver("internal: one clamp flag per face expected".into()));
        }
        if !(1..=2).contains(&options.degree) {
            return Err(DgError::Degree(options.degree));
        }
        if !(options.penalty > 0.0 && options.penalty.is_finite()) {
            return Err(DgError::Penalty(options.penalty));
        }
        if !(options.penalty_margin >= 1.0 && options.penalty_margin.is_finite()) {
            return Err(DgError::PenaltyMargin(options.penalty_margin));
        }
        if !(0.0..1.0).contains(&options.sliver_fraction) {
            return Err(DgError::SliverFraction(options.sliver_fraction));
        }
        mesh.validate(PLANARITY)?;
        let degree = options.degree;
        let exps = exponents(degree);
        let nb = exps.len();
        debug_assert_eq!(nb, basis_size(degree));
        let outward_faces = mesh.element_faces();
        let element_faces: Vec<Vec<(u32, bool)>> =
            outward_faces.iter().map(|list| list.iter().map(|f| (f.face as u32, f.reversed)).collect()).collect();

        // Bases from exact moments (divergence theorem), in parallel over elements.
        let bases: Vec<Result<ElementBasis, DgError>> = (0..mesh.num_elements)
            .into_par_iter()
            .map(|e| {
                // Volume and centroid from degree-1 moments in a frame at the first vertex.
                let anchor = outward_faces[e]
                    .first()
                    .and_then(|f| f.polygon.first())
                    .map_or(Point3::origin(), |&v| mesh.vertices[v as usize]);
                let rough = Frame { center: anchor, scale: 1.0 };
                let mut first = Vec::new();
                element_moments_from_faces(&mesh, &outward_faces[e], &rough, 1, &mut first);
                let volume = first[0];
                let centroid = anchor + Vector3::new(first[1], first[2], first[3]) / volume;
                let scale = element_faces[e]
                    .iter()
                    .flat_map(|&(f, _)| mesh.faces[f as usize].polygon.iter())
                    .map(|&v| (mesh.vertices[v as usize] - centroid).norm())
                    .fold(0.0, Real::max);
                let frame = Frame { center: centroid, scale };
                let mut moments = Vec::new();
                element_moments_from_faces(&mesh, &outward_faces[e], &frame, 2 * degree, &mut moments);
                ElementBasis::new(frame, degree, &moments).ok_or(DgError::DegenerateElement { element: e, volume })
            })
            .collect();
        let bases: Vec<ElementBasis> = bases.into_iter().collect::<Result<_, _>>()?;

        let num_nodes = mesh.num_elements * nb;
        let mut rest = vec![0.0; 3 * num_nodes];
        let mut rotation_gradients = vec![Vector3::zeros(); num_nodes];
        for (e, basis) in bases.iter().enumerate() {
            // Identity field in monomials: c_0 = centroid, c_{x,y,z} = s e_{x,y,z}; d = Lᵀ c with
            // L = A⁻¹ (docs/math/dg.md §2).
            let l = basis.a.clone().try_inverse().expect("A = L⁻¹ is invertible");
            let mut c = vec![Vector3::zeros(); nb];
            c[0] = basis.frame.center.coords;
            for a in 0..3 {
                let mut e_a = Vector3::zeros();
                e_a[a] = basis.frame.scale;
                c[index(unit(a))] = e_a;
            }
            for i in 0..nb {
                let mut d = Vector3::zeros();
                for (alpha, c_alpha) in c.iter().enumerate() {
                    d += c_alpha * l[(alpha, i)];
                }
                rest[3 * (e * nb + i)..3 * (e * nb + i) + 3].copy_from_slice(d.as_slice());
                // F e_a = c_{1+a} / s = Σ_i d_i A_{i,1+a} / s.
                rotation_gradients[e * nb + i] =
                    Vector3::from_fn(|a, _| basis.a[(i, index(unit(a)))] / basis.frame.scale);
            }
        }

        // Consistent mass of an orthonormal basis: ρ I.
        let mass = Mass::Lumped(vec![material.density; 3 * num_nodes]);

        let element_stiffness: Vec<DMatrix<Real>> = (0..mesh.num_elements)
            .into_par_iter()
            .map(|e| element_stiffness(&mesh, &outward_faces[e], &bases[e], &exps, &material))
            .collect();

        // Dirichlet faces: the kept clamp's, or the boundary faces `on_boundary` selects.
        let dirichlet_faces: Vec<bool> = match clamped_faces {
            Some(kept) => mesh.faces.iter().enumerate().map(|(f, face)| face.outer.is_none() && kept[f]).collect(),
            None => (0..mesh.faces.len())
                .into_par_iter()
                .map(|f| {
                    mesh.faces[f].outer.is_none()
                        && dirichlet.is_some_and(|d| (d.on_boundary)(&face_area_normal_centroid(&mesh, f).2))
                })
                .collect(),
        };
        let face_terms: Vec<Option<FaceTerms>> = (0..mesh.faces.len())
            .into_par_iter()
            .map(|f| {
                let weight = inherited.and_then(|w| w.get(f).copied().flatten());
                face_terms(&mesh, f, &bases, &exps, &material, options.flux, dirichlet_faces[f], weight)
            })
            .collect();
        let face_weights = face_terms.iter().map(|t| t.as_ref().map_or(0.0, |t| t.weight)).collect();

        let has_dirichlet = dirichlet_faces.iter().any(|&d| d);

        let name = format!(
            "dg-{}-{}",
            match options.flux {
                Flux::BabuskaZlamal => "bz",
                Flux::InteriorPenalty => "ip",
            },
            degree
        );
        let mut this = Self {
            name,
            material,
            options,
            mesh,
            exps,
            bases,
            rest,
            mass,
            blocks: BlockSetBuilder::new().finish(num_nodes)?,
            penalty: options.penalty,
            doublings: 0,
            dirichlet_load: Vec::new(),
            rotation_gradients,
            has_dirichlet,
            element_faces,
            penalty_search_seconds: 0.0,
            epoch: 0,
            cut_faces: Vec::new(),
            face_weights,
            depth: Vec::new(),
            refinement: Refinement::default(),
            dirichlet_faces,
            clamp_kept: clamped_faces.is_some(),
            last_slivers: (0, 0),
        };
        this.depth = vec![0; this.mesh.num_elements];
        this.cut_faces = vec![false; this.mesh.faces.len()];
        let search = std::time::Instant::now();
        let mut check: Option<DefinitenessCheck> = None;
        // A piece without a Dirichlet face moves freely (a cut may free one from the clamp).
        let (piece_of, pieces) = this.piece_of_elements();
        let mut held = vec![false; pieces];
        for (face, _) in this.mesh.faces.iter().zip(&this.dirichlet_faces).filter(|(_, d)| **d) {
            held[piece_of[face.inner as usize]] = true;
        }
        let some_piece_free = held.iter().any(|h| !h);
        // The penalty doubling; the Dirichlet load depends on η, so it is built with the final η.
        loop {
            this.blocks = build_blocks(num_nodes, &element_stiffness, &face_terms, this.penalty)?;
            // BZ is a sum of positive semidefinite terms, positive definite for any η > 0 once
            // rigid modes are fixed: nothing to search (docs/math/dg.md §5).
            if options.flux == Flux::BabuskaZlamal {
                break;
            }
            let check = match &mut check {
                Some(check) => check,
                None => {
                    check.insert(DefinitenessCheck::new(&this.blocks, num_nodes, this.num_frames(), some_piece_free)?)
                }
            };
            if check.holds(&this.blocks)? {
                break;
            }
            if this.doublings >= options.max_doublings {
                return Err(DgError::NotPositiveDefinite { penalty: this.penalty, doublings: this.doublings });
            }
            this.penalty *= 2.0;
            this.doublings += 1;
        }
        if options.penalty_margin > 1.0 {
            this.penalty *= options.penalty_margin;
            this.blocks = build_blocks(num_nodes, &element_stiffness, &face_terms, this.penalty)?;
        }
        this.penalty_search_seconds = search.elapsed().as_secs_f64();
        let mut dirichlet_load = vec![0.0; 3 * num_nodes];
        // A kept clamp has data 0: no load.
        if let Some(dirichlet) = dirichlet.filter(|_| clamped_faces.is_none()) {
            let scaled = WeakDirichletScaled { inner: dirichlet, penalty: this.penalty };
            add_dirichlet_load(
                &this.mesh,
                &this.bases,
                &this.exps,
                &this.material,
                this.options.flux,
                &scaled,
                &mut dirichlet_load,
            );
        }
        this.dirichlet_load = dirichlet_load;
        Ok(this)
    }

    /// What the last cut's sliver merging did: elements merged into a neighbour, and elements
    /// left below the threshold (a piece of their own: no neighbour to merge into).
    pub fn last_cut_slivers(&self) -> (usize, usize) {
        self.last_slivers
    }

    /// The global penalty η the doubling reached.
    pub fn penalty(&self) -> Real {
        self.penalty
    }

    /// Seconds the penalty doubling took (assembly and Cholesky attempts), part of `new`.
    pub fn penalty_search_seconds(&self) -> Real {
        self.penalty_search_seconds
    }

    /// How many times η was doubled.
    pub fn penalty_doublings(&self) -> u32 {
        self.doublings
    }

    /// The load of the weak Dirichlet data (add it to the external force).
    pub fn dirichlet_load(&self) -> &[Real] {
        &self.dirichlet_load
    }

    /// The polyhedral mesh.
    pub fn polyhedral_mesh(&self) -> &PolyhedralMesh {
        &self.mesh
    }

    /// Number of elements.
    pub fn num_elements(&self) -> usize {
        self.mesh.num_elements
    }

    /// Element `e`'s volume (exact, from its moments).
    pub fn element_volume(&self, e: usize) -> Real {
        self.bases[e].volume
    }

    /// Basis functions per element.
    pub fn basis_size(&self) -> usize {
        self.exps.len()
    }

    /// The material.
    pub fn material(&self) -> &Material {
        &self.material
    }

    /// The options (with the initial penalty).
    pub fn options(&self) -> &DgOptions {
        &self.options
    }

    /// Values and gradients of element `e`'s basis at `p` (buffers of `basis_size()`).
    pub fn evaluate_basis(&self, e: usize, p: &Point3<Real>, values: &mut [Real], gradients: &mut [Vector3<Real>]) {
        self.bases[e].evaluate(&self.exps, p, values, gradients);
    }

    /// `F = Σ_i d_i ⊗ g_i`: element `e`'s deformation gradient at its centroid for positions `x`
    /// (its rotation frame, and the stress `Refinable` reads).
    fn centroid_gradient(&self, e: usize, x: &[Real]) -> Matrix3<Real> {
        let nb = self.exps.len();
        let mut f = Matrix3::zeros();
        for i in 0..nb {
            let node = e * nb + i;
            f +=
                Vector3::new(x[3 * node], x[3 * node + 1], x[3 * node + 2]) * self.rotation_gradients[node].transpose();
        }
        f
    }

    /// Element `e`'s outward faces as point loops.
    fn element_polygons(&self, e: usize) -> Vec<Vec<Point3<Real>>> {
        self.element_faces[e]
            .iter()
            .map(|&(f, reversed)| {
                let mut pts: Vec<Point3<Real>> =
                    self.mesh.faces[f as usize].polygon.iter().map(|&v| self.mesh.vertices[v as usize]).collect();
                if reversed {
                    pts.reverse();
                }
                pts
            })
            .collect()
    }

    /// Calls `visit(element, point, weight, ψ(point), ∇ψ(point))` at every point of the signed
    /// cone rule of every element (degree 7; docs/math/dg.md §3), for loads and error norms.
    fn for_each_quadrature_point(&self, visit: &mut QuadratureVisitor<'_>) {
        let nb = self.exps.len();
        let mut values = vec![0.0; nb];
        let mut gradients = vec![Vector3::zeros(); nb];
        for (e, basis) in self.bases.iter().enumerate() {
            polyhedron_rule(self.element_polygons(e).into_iter(), &basis.frame.center, &mut |p, w| {
                basis.evaluate(&self.exps, &p, &mut values, &mut gradients);
                visit(e, &p, w, &values, &gradients);
            });
        }
    }

    /// The element containing `p` (rest space), by the generalized winding number of each nearby
    /// element's faces: 1 inside, ½ on a face, ¼ on an edge, so a point on the boundary of the
    /// solid still finds the element it touches (the best one above ⅛). A point inside no element
    /// but within an element's bounding ball (a cone-rule sample of a non-convex element, a point
    /// rounding put just outside) takes the element whose centre is nearest relative to its size:
    /// its polynomial is the natural extension there. `None` beyond every bounding ball.
    pub fn locate(&self, p: &Point3<Real>) -> Option<usize> {
        let mut best: Option<(Real, usize)> = None;
        let mut nearest: Option<(Real, usize)> = None;
        for (e, basis) in self.bases.iter().enumerate() {
            let relative = (basis.frame.center - p).norm() / basis.frame.scale;
            if relative > 1.0 + 1e-9 {
                continue;
            }
            let w = cleave_geometry::polygon_winding_number(self.element_polygons(e).iter().map(Vec::as_slice), p);
            if w > 0.99 {
                return Some(e);
            }
            if w > 0.1 && best.is_none_or(|(b, _)| w > b) {
                best = Some((w, e));
            }
            if nearest.is_none_or(|(r, _)| relative < r) {
                nearest = Some((relative, e));
            }
        }
        best.or(nearest).map(|(_, e)| e)
    }
}

fn unit(a: usize) -> [u32; 3] {
    let mut e = [0; 3];
    e[a] = 1;
    e
}

/// Element stiffness `K_K[(i,a),(j,b)] = ∫ λ ∂_aψ_i ∂_bψ_j + μ (δ_ab ∇ψ_i·∇ψ_j + ∂_bψ_i ∂_aψ_j)`.
fn element_stiffness(
    mesh: &PolyhedralMesh,
    faces: &[ElementFace<'_>],
    basis: &ElementBasis,
    exps: &[[u32; 3]],
    material: &Material,
) -> DMatrix<Real> {
    let nb = exps.len();
    let degree = exps.iter().map(|x| x[0] + x[1] + x[2]).max().unwrap_or(0) as usize;
    let mut moments = Vec::new();
    if degree >= 1 {
        element_moments_from_faces(mesh, faces, &basis.frame, 2 * degree - 2, &mut moments);
    }
    let s2 = basis.frame.scale * basis.frame.scale;
    // S_cd[α][β] = ∫ ∂_c m_α ∂_d m_β (physical derivatives).
    let mut s = vec![DMatrix::<Real>::zeros(nb, nb); 9];
    for (al, ea) in exps.iter().enumerate() {
        for (be, eb) in exps.iter().enumerate() {
            for c in 0..3 {
                for d in 0..3 {
                    if ea[c] == 0 || eb[d] == 0 {
                        continue;
                    }
                    let mut sum = add(*ea, *eb);
                    sum[c] -= 1;
                    sum[d] -= 1;
                    s[3 * c + d][(al, be)] = (ea[c] * eb[d]) as Real / s2 * moments[index(sum)];
                }
            }
        }
    }
    // Into the orthonormal basis: A S Aᵀ.
    let g: Vec<DMatrix<Real>> = s.iter().map(|m| &basis.a * m * basis.a.transpose()).collect();
    let (lambda, mu) = material.lame();
    let mut k = DMatrix::zeros(3 * nb, 3 * nb);
    for i in 0..nb {
        for j in 0..nb {
            let dot = g[0][(i, j)] + g[4][(i, j)] + g[8][(i, j)];
            for a in 0..3 {
                for b in 0..3 {
                    let mut v = lambda * g[3 * a + b][(i, j)] + mu * g[3 * b + a][(i, j)];
                    if a == b {
                        v += mu * dot;
                    }
                    k[(3 * i + a, 3 * j + b)] = v;
                }
            }
        }
    }
    symmetrize(&mut k);
    k
}

fn symmetrize(k: &mut DMatrix<Real>) {
    let t = k.transpose();
    *k += t;
    *k *= 0.5;
}

/// Face integrals in the frame of `common`: `P[s][t] = ∫ ψ^s ψ^tᵀ` and `Q_d[s][t] = ∫ ψ^s ∂_dψ^tᵀ`
/// for the given sides (docs/math/dg.md §3).
struct FaceIntegrals {
    p: Vec<Vec<DMatrix<Real>>>,
    q: Vec<Vec<[DMatrix<Real>; 3]>>,
}

fn face_integrals(mesh: &PolyhedralMesh, f: usize, sides: &[&ElementBasis], exps: &[[u32; 3]]) -> FaceIntegrals {
    let nb = exps.len();
    let degree = exps.iter().map(|x| x[0] + x[1] + x[2]).max().unwrap_or(0) as usize;
    let common = sides[0].frame;
    let mut mom = Vec::new();
    face_moments(mesh, f, &common, 2 * degree, &mut mom);
    // B^s = A^s E^s: ψ^s_i = Σ_γ B^s_{iγ} ξ^γ in the common frame.
    let b: Vec<DMatrix<Real>> = sides
        .iter()
        .map(|side| {
            let o = (common.center - side.frame.center) / side.frame.scale;
            let r = common.scale / side.frame.scale;
            let mut e = DMatrix::zeros(nb, nb);
            let mut row = vec![0.0; nb];
            for (beta, eb) in exps.iter().enumerate() {
                shifted_monomial(*eb, &o, r, degree, &mut row);
                for g in 0..nb {
                    e[(beta, g)] = row[g];
                }
            }
            &side.a * e
        })
        .collect();
    let m0 = DMatrix::from_fn(nb, nb, |g, d| mom[index(add(exps[g], exps[d]))]);
    let md: [DMatrix<Real>; 3] = std::array::from_fn(|axis| {
        DMatrix::from_fn(nb, nb, |g, d| {
            if exps[d][axis] == 0 {
                return 0.0;
            }
            let mut e = add(exps[g], exps[d]);
            e[axis] -= 1;
            exps[d][axis] as Real / common.scale * mom[index(e)]
        })
    });
    let mut p = Vec::new();
    let mut q = Vec::new();
    for bs in &b {
        let mut prow = Vec::new();
        let mut qrow = Vec::new();
        for bt in &b {
            prow.push(bs * &m0 * bt.transpose());
            qrow.push(std::array::from_fn(|axis| bs * &md[axis] * bt.transpose()));
        }
        p.push(prow);
        q.push(qrow);
    }
    FaceIntegrals { p, q }
}

/// The terms of face `f`, `None` for free boundary faces. An interior face has the sides
/// `(K⁻, K⁺)` with `sgn = (1, −1)` and the average's weight ½; a Dirichlet face has the one side
/// `K` with `sgn = 1` and weight 1 (`σ⁻ := σ⁺`, docs/math/dg.md §4). An interior face's penalty
/// weight is `weight` when given (a piece of a face a cut split keeps the face's, §13).
#[allow(clippy::too_many_arguments)]
fn face_terms(
    mesh: &PolyhedralMesh,
    f: usize,
    bases: &[ElementBasis],
    exps: &[[u32; 3]],
    material: &Material,
    flux: Flux,
    is_dirichlet: bool,
    weight: Option<Real>,
) -> Option<FaceTerms> {
    let nb = exps.len() as u32;
    let face = &mesh.faces[f];
    let (area, normal, _) = face_area_normal_centroid(mesh, f);
    let (elements, signs, average, eta_f): (Vec<usize>, &[Real], Real, Real) = match face.outer {
        Some(outer) => {
            let (em, ep) = (face.inner as usize, outer as usize);
            let geometric = material.youngs_modulus * area * (1.0 / bases[em].volume + 1.0 / bases[ep].volume);
            // BZ is stable for any weight: a piece keeps its face's, and a cut keeps every jump's
            // energy. IP's consistency terms grow on a small child: its weight may not fall
            // below the geometric one (docs/math/dg.md §13).
            let eta_f = match (weight, flux) {
                (Some(w), Flux::BabuskaZlamal) => w,
                (Some(w), Flux::InteriorPenalty) => w.max(geometric),
                (None, _) => geometric,
            };
            (vec![em, ep], &[1.0, -1.0], 0.5, eta_f)
        }
        None => {
            if !is_dirichlet {
                return None;
            }
            let e = face.inner as usize;
            // The weight of an interior face between two such elements (docs/math/dg.md §4); a
            // piece of a clamped face keeps the face's, as an interior face's piece does.
            let geometric = 2.0 * material.youngs_modulus * area / bases[e].volume;
            let eta_f = match (weight, flux) {
                (Some(w), Flux::BabuskaZlamal) => w,
                (Some(w), Flux::InteriorPenalty) => w.max(geometric),
                (None, _) => geometric,
            };
            (vec![e], &[1.0], 1.0, eta_f)
        }
    };
    let sides: Vec<&ElementBasis> = elements.iter().map(|&e| &bases[e]).collect();
    let integrals = face_integrals(mesh, f, &sides, exps);
    let unit_penalty = penalty_matrix(&integrals, signs, eta_f);
    let mut warped = Vec::new();
    let mut anchored = None;
    if flux == Flux::InteriorPenalty {
        let t = lame_tensor(material, &normal);
        if let [frame] = elements[..] {
            // The jump against world-anchored data must not be corotated with the element
            // (docs/math/dg.md §6): an anchored block.
            anchored = Some((consistency_half(&integrals, &t, signs, average, 0), frame as u32));
        } else {
            for (trial, &frame) in elements.iter().enumerate() {
                let half = consistency_half(&integrals, &t, signs, average, trial);
                warped.push((&half + half.transpose(), frame as u32));
            }
        }
    }
    let nodes = elements.iter().flat_map(|&e| (0..nb).map(move |i| e as u32 * nb + i)).collect();
    Some(FaceTerms { nodes, warped, anchored, unit_penalty, weight: eta_f })
}

/// `η_f ∫ ⟦u⟧ : ⟦v⟧`: `[(s,i,a),(t,j,a)] = η_f sgn_s sgn_t P^{st}_{ij}`.
fn penalty_matrix(integrals: &FaceIntegrals, signs: &[Real], eta_f: Real) -> DMatrix<Real> {
    let nb = integrals.p[0][0].nrows();
    let n = signs.len() * nb;
    let mut k = DMatrix::zeros(3 * n, 3 * n);
    for (s, sign_s) in signs.iter().enumerate() {
        for (t, sign_t) in signs.iter().enumerate() {
            for i in 0..nb {
                for j in 0..nb {
                    let v = eta_f * sign_s * sign_t * integrals.p[s][t][(i, j)];
                    for a in 0..3 {
                        k[(3 * (s * nb + i) + a, 3 * (t * nb + j) + a)] = v;
                    }
                }
            }
        }
    }
    symmetrize(&mut k);
    k
}

/// The part of `K_f1` that uses the strain of side `trial`:
/// `K1[(s,i,a),(trial,j,b)] = −w sgn_s Σ_d T_abd Q^{s,trial}_{ij,d}` (rows: the jump of the test
/// function, columns: the strain of the trial function); its part of `K_f1 + K_f2` is `K1 + K1ᵀ`.
fn consistency_half(
    integrals: &FaceIntegrals,
    t: &[[[Real; 3]; 3]; 3],
    signs: &[Real],
    average: Real,
    trial: usize,
) -> DMatrix<Real> {
    let nb = integrals.p[0][0].nrows();
    let n = signs.len() * nb;
    let mut k = DMatrix::zeros(3 * n, 3 * n);
    for (s, sign_s) in signs.iter().enumerate() {
        for i in 0..nb {
            for j in 0..nb {
                for a in 0..3 {
                    for b in 0..3 {
                        let v: Real = (0..3).map(|d| t[a][b][d] * integrals.q[s][trial][d][(i, j)]).sum();
                        k[(3 * (s * nb + i) + a, 3 * (trial * nb + j) + b)] -= average * sign_s * v;
                    }
                }
            }
        }
    }
    k
}

fn build_blocks(
    num_nodes: usize,
    element_stiffness: &[DMatrix<Real>],
    faces: &[Option<FaceTerms>],
    penalty: Real,
) -> Result<BlockSet, BlockSetError> {
    let mut builder = BlockSetBuilder::new();
    let nb = element_stiffness.first().map_or(0, |k| k.nrows() / 3);
    for (e, k) in element_stiffness.iter().enumerate() {
        let id = builder.add_rest_matrix(k.clone())?;
        let nodes: Vec<u32> = (0..nb as u32).map(|i| e as u32 * nb as u32 + i).collect();
        builder.push(&nodes, id, Some(e as u32));
    }
    for terms in faces.iter().flatten() {
        for (k, frame) in &terms.warped {
            let id = builder.add_rest_matrix(k.clone())?;
            builder.push(&terms.nodes, id, Some(*frame));
        }
        if let Some((h, frame)) = &terms.anchored {
            builder.push_anchored(&terms.nodes, h.clone(), *frame)?;
        }
        let id = builder.add_rest_matrix(&terms.unit_penalty * penalty)?;
        builder.push(&terms.nodes, id, None);
    }
    builder.finish(num_nodes)
}

struct WeakDirichletScaled<'a, 'b> {
    inner: &'a WeakDirichlet<'b>,
    penalty: Real,
}

/// `F_(i,a) += ∫_F η_f g_a ψ_i − g · σ(ψ_i e_a) n` over Dirichlet faces (IP; BZ keeps only the
/// penalty part), with a degree-7 rule on the fan triangles.
fn add_dirichlet_load(
    mesh: &PolyhedralMesh,
    bases: &[ElementBasis],
    exps: &[[u32; 3]],
    material: &Material,
    flux: Flux,
    dirichlet: &WeakDirichletScaled<'_, '_>,
    out: &mut [Real],
) {
    let nb = exps.len();
    let mut values = vec![0.0; nb];
    let mut gradients = vec![Vector3::zeros(); nb];
    for (f, face) in mesh.faces.iter().enumerate() {
        if face.outer.is_some() {
            continue;
        }
        let (area, normal, centroid) = face_area_normal_centroid(mesh, f);
        if !(dirichlet.inner.on_boundary)(&centroid) {
            continue;
        }
        let e = face.inner as usize;
        let eta_f = 2.0 * dirichlet.penalty * material.youngs_modulus * area / bases[e].volume;
        let t = lame_tensor(material, &normal);
        let points: Vec<Point3<Real>> = face.polygon.iter().map(|&v| mesh.vertices[v as usize]).collect();
        polygon_rule(&points, &normal, &mut |p, w| {
            let g = (dirichlet.inner.data)(&p);
            bases[e].evaluate(exps, &p, &mut values, &mut gradients);
            for i in 0..nb {
                for a in 0..3 {
                    let mut v = eta_f * g[a] * values[i];
                    if flux == Flux::InteriorPenalty {
                        // g · σ(ψ_i e_a) n = Σ_b g_b Σ_d T[b][a][d] ∂_dψ_i
                        for b in 0..3 {
                            for d in 0..3 {
                                v -= g[b] * t[b][a][d] * gradients[i][d];
                            }
                        }
                    }
                    out[3 * (e * nb + i) + a] += w * v;
                }
            }
        });
    }
}

impl Discretization for DgMesh {
    fn name(&self) -> &str {
        &self.name
    }

    fn as_cuttable(&mut self) -> Option<&mut dyn cleave_core::Cuttable> {
        Some(self)
    }

    fn as_refinable(&mut self) -> Option<&mut dyn cleave_core::Refinable> {
        Some(self)
    }

    fn copy_for_cutting(&self) -> Option<Box<dyn Discretization>> {
        Some(Box::new(self.clone()))
    }

    fn num_nodes(&self) -> usize {
        self.mesh.num_elements * self.exps.len()
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
        self.mesh.num_elements
    }

    fn write_rotations(&self, x: &[Real], rotations: &mut [Matrix3<Real>]) -> RotationStats {
        cleave_core::rotation::write_frame_rotations(rotations, 20, |e| self.centroid_gradient(e, x))
    }

    fn blocks(&self) -> &BlockSet {
        &self.blocks
    }

    fn add_load(&self, force_density: &dyn Fn(&Point3<Real>) -> Vector3<Real>, out: &mut [Real]) {
        let nb = self.exps.len();
        self.for_each_quadrature_point(&mut |e, p, w, values, _| {
            let f = force_density(p);
            for i in 0..nb {
                for a in 0..3 {
                    out[3 * (e * nb + i) + a] += w * values[i] * f[a];
                }
            }
        });
    }

    fn add_translation(&self, t: &Vector3<Real>, x: &mut [Real]) {
        // The constant 1 is m_0 = Σ_i L_{0i} ψ_i and L is lower triangular, so only ψ_0 carries it.
        let nb = self.exps.len();
        for (e, basis) in self.bases.iter().enumerate() {
            let l00 = 1.0 / basis.a[(0, 0)];
            for a in 0..3 {
                x[3 * e * nb + a] += l00 * t[a];
            }
        }
    }

    fn add_gravity_load(&self, gravity: &Vector3<Real>, out: &mut [Real]) {
        // A constant density is exact in closed form: 1 = L_00 ψ_0 (L lower triangular), so
        // ∫_E ψ_i = L_00 ∫_E ψ_i ψ_0 = L_00 δ_i0 by orthonormality (docs/math/dg.md §2), with
        // L_00 = 1 / A_00. The quadrature of `add_load` took most of a cut's rebuild.
        let nb = self.exps.len();
        let rho = self.material.density;
        for (e, basis) in self.bases.iter().enumerate() {
            let l00 = 1.0 / basis.a[(0, 0)];
            for a in 0..3 {
                out[3 * e * nb + a] += rho * l00 * gravity[a];
            }
        }
    }

    fn embed(&self, points: &[Point3<Real>]) -> Result<Embedding, EmbedError> {
        let nb = self.exps.len();
        let mut embedding = Embedding::new();
        let mut values = vec![0.0; nb];
        let mut gradients = vec![Vector3::zeros(); nb];
        let mut nodes = vec![0u32; nb];
        for (index, p) in points.iter().enumerate() {
            let e = self.locate(p).ok_or(EmbedError::Outside { index, x: p.x, y: p.y, z: p.z })?;
            self.bases[e].evaluate(&self.exps, p, &mut values, &mut gradients);
            for (i, n) in nodes.iter_mut().enumerate() {
                *n = (e * nb + i) as u32;
            }
            embedding.push_row(&nodes, &values);
        }
        Ok(embedding)
    }

    fn embed_surface(&self, points: &[Point3<Real>]) -> Result<Embedding, EmbedError> {
        crate::mls::embed_mls(self, points)
    }

    fn visit_field(&self, displacement: &[Real], _min_degree: usize, visit: &mut dyn FnMut(&FieldSample)) {
        let nb = self.exps.len();
        self.for_each_quadrature_point(&mut |e, p, w, values, gradients| {
            let mut u = Vector3::zeros();
            let mut grad = Matrix3::zeros();
            for i in 0..nb {
                let node = e * nb + i;
                let d = Vector3::new(displacement[3 * node], displacement[3 * node + 1], displacement[3 * node + 2]);
                u += d * values[i];
                grad += d * gradients[i].transpose();
            }
            visit(&FieldSample { position: *p, weight: w, displacement: u, gradient: grad });
        });
    }
}
