//! A topology-free discretization for the integrator's own tests: nodes joined by blocks whose
//! rest matrices the test chooses (no frames, so every rotation is the identity), with a lumped
//! mass. Small enough that every number it produces can be computed independently by hand or
//! with dense nalgebra.
#![allow(dead_code)]

use cleave_core::{
    BlockSet, BlockSetBuilder, Discretization, EmbedError, Embedding, FieldSample, Mass, Matrix3, Point3, Real,
    RotationStats, Vector3,
};
use nalgebra::DMatrix;

/// Nodes at rest positions, a lumped mass per node and unwarped blocks.
pub struct Springs {
    rest: Vec<Real>,
    mass: Mass,
    blocks: BlockSet,
}

impl Springs {
    /// `rest`: 3 entries per node; `masses`: one per node (the same on its three DOFs);
    /// `blocks`: node list and symmetric rest matrix (3·nodes square) of each block.
    pub fn new(rest: Vec<Real>, masses: &[Real], blocks: &[(Vec<u32>, DMatrix<Real>)]) -> Self {
        assert_eq!(rest.len(), 3 * masses.len());
        let mut builder = BlockSetBuilder::new();
        for (nodes, k) in blocks {
            let id = builder.add_rest_matrix(k.clone()).expect("symmetric rest matrix");
            builder.push(nodes, id, None);
        }
        let blocks = builder.finish(masses.len()).expect("valid blocks");
        let mass = Mass::Lumped(masses.iter().flat_map(|&m| [m; 3]).collect());
        Self { rest, mass, blocks }
    }
}

impl Discretization for Springs {
    fn name(&self) -> &str {
        "springs"
    }

    fn num_nodes(&self) -> usize {
        self.rest.len() / 3
    }

    fn rest_dofs(&self) -> &[Real] {
        &self.rest
    }

    fn epoch(&self) -> u64 {
        0
    }

    fn mass(&self) -> &Mass {
        &self.mass
    }

    fn num_frames(&self) -> usize {
        0
    }

    fn write_rotations(&self, _x: &[Real], _rotations: &mut [Matrix3<Real>]) -> RotationStats {
        RotationStats::default()
    }

    fn blocks(&self) -> &BlockSet {
        &self.blocks
    }

    /// The density at each node times a unit volume (unused by these tests' numbers).
    fn add_load(&self, force_density: &dyn Fn(&Point3<Real>) -> Vector3<Real>, out: &mut [Real]) {
        for (o, p) in out.chunks_exact_mut(3).zip(self.rest.chunks_exact(3)) {
            let f = force_density(&Point3::new(p[0], p[1], p[2]));
            for a in 0..3 {
                o[a] += f[a];
            }
        }
    }

    /// Each point follows the nearest node (weight 1).
    fn embed(&self, points: &[Point3<Real>]) -> Result<Embedding, EmbedError> {
        let mut embedding = Embedding::new();
        for p in points {
            let nearest = self
                .rest
                .chunks_exact(3)
                .map(|q| (Point3::new(q[0], q[1], q[2]) - p).norm())
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map_or(0, |(k, _)| k as u32);
            embedding.push_row(&[nearest], &[1.0]);
        }
        Ok(embedding)
    }

    fn visit_field(&self, _displacement: &[Real], _min_degree: usize, _visit: &mut dyn FnMut(&FieldSample)) {}
}

/// The 6×6 rest matrix of a spring between two nodes with axis stiffnesses `k`:
/// `[A −A; −A A]`, `A = diag(k)`. It annihilates translations.
pub fn spring(k: [Real; 3]) -> DMatrix<Real> {
    let mut m = DMatrix::zeros(6, 6);
    for a in 0..3 {
        m[(a, a)] = k[a];
        m[(a + 3, a + 3)] = k[a];
        m[(a, a + 3)] = -k[a];
        m[(a + 3, a)] = -k[a];
    }
    m
}

/// Deterministic numbers in [−1, 1].
pub struct Lcg(u64);

impl Lcg {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(1))
    }

    /// Next number in [−1, 1].
    pub fn next_value(&mut self) -> Real {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as Real / (1u64 << 53) as Real) * 2.0 - 1.0
    }
}
