//! A corotated linear-tetrahedron body for contact's tests in a step, so that they need no
//! backend: boxes of six tetrahedra each (the cube split along its diagonal), whose nodes are the
//! contact points (identity embedding rows) and whose unshared tetrahedron faces are the surface
//! (two triangles per box face, oriented outwards, one piece per box).
#![allow(dead_code)]

use cleave_core::rotation::write_frame_rotations;
use cleave_core::{
    BlockSet, BlockSetBuilder, Discretization, EmbedError, Embedding, FieldSample, Mass, Material, Matrix3, Point3,
    Real, RotationStats, Vector3,
};
use nalgebra::DMatrix;
use std::collections::HashMap;

/// Boxes of corotated linear tetrahedra.
pub struct TetBoxes {
    rest: Vec<Real>,
    tets: Vec<[u32; 4]>,
    dm_inv: Vec<Matrix3<Real>>,
    mass: Mass,
    density: Real,
    blocks: BlockSet,
    /// Surface triangles over the nodes, outward, and the box each belongs to.
    pub triangles: Vec<[u32; 3]>,
    /// The box of each surface triangle.
    pub piece: Vec<u32>,
}

/// The six tetrahedra of a cube with corners numbered by bits (x = 1, y = 2, z = 4), all around
/// the diagonal 0–7: one per order in which a path from corner 0 to corner 7 takes the axes.
const CUBE_TETS: [[u32; 4]; 6] = [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]];

impl TetBoxes {
    /// One box per `(min corner, max corner)`, all of `material`.
    pub fn new(boxes: &[(Point3<Real>, Point3<Real>)], material: &Material) -> Self {
        let (lambda, mu) = material.lame();
        let mut rest = Vec::new();
        let mut tets = Vec::new();
        let mut box_of_tet = Vec::new();
        for (b, (lo, hi)) in boxes.iter().enumerate() {
            let first = (rest.len() / 3) as u32;
            for corner in 0..8 {
                for a in 0..3 {
                    rest.push(if corner >> a & 1 == 1 { hi[a] } else { lo[a] });
                }
            }
            for t in CUBE_TETS {
                tets.push(t.map(|c| first + c));
                box_of_tet.push(b as u32);
            }
        }
        let point = |n: u32| Point3::new(rest[3 * n as usize], rest[3 * n as usize + 1], rest[3 * n as usize + 2]);
        let mut masses = vec![0.0; rest.len()];
        let mut dm_inv = Vec::new();
        let mut builder = BlockSetBuilder::new().translation_invariant();
        for (frame, tet) in tets.iter_mut().enumerate() {
            let edges = |t: &[u32; 4]| {
                let p0 = point(t[0]);
                Matrix3::from_columns(&[point(t[1]) - p0, point(t[2]) - p0, point(t[3]) - p0])
            };
            if edges(tet).determinant() < 0.0 {
                tet.swap(2, 3);
            }
            let dm = edges(tet);
            let volume = dm.determinant() / 6.0;
            let inverse = dm.try_inverse().expect("a box of positive size");
            // Shape function gradients: rows of Dm⁻¹ for corners 1–3, minus their sum for corner 0.
            let mut gradients = [Vector3::zeros(); 4];
            for c in 1..4 {
                gradients[c] = inverse.row(c - 1).transpose();
            }
            gradients[0] = -(gradients[1] + gradients[2] + gradients[3]);
            // K_ab = V (λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a · g_b) I): linear isotropic elasticity.
            let mut k = DMatrix::zeros(12, 12);
            for (a, ga) in gradients.iter().enumerate() {
                for (b, gb) in gradients.iter().enumerate() {
                    let block = (ga * gb.transpose()) * lambda
                        + (gb * ga.transpose()) * mu
                        + Matrix3::identity() * (mu * ga.dot(gb));
                    for i in 0..3 {
                        for j in 0..3 {
                            k[(3 * a + i, 3 * b + j)] = volume * block[(i, j)];
                        }
                    }
                }
            }
            let id = builder.add_rest_matrix(k).expect("a symmetric stiffness");
            builder.push(tet, id, Some(frame as u32));
            dm_inv.push(inverse);
            for &n in tet.iter() {
                for a in 0..3 {
                    masses[3 * n as usize + a] += material.density * volume / 4.0;
                }
            }
        }
        let blocks = builder.finish(rest.len() / 3).expect("valid blocks");
        // Faces used by one tetrahedron only, oriented away from its fourth corner.
        let mut faces: HashMap<[u32; 3], (usize, [u32; 3])> = HashMap::new();
        for (t, tet) in tets.iter().enumerate() {
            for skip in 0..4 {
                let mut face: Vec<u32> = (0..4).filter(|&c| c != skip).map(|c| tet[c]).collect();
                let (a, b, c) = (point(face[0]), point(face[1]), point(face[2]));
                if (b - a).cross(&(c - a)).dot(&(point(tet[skip]) - a)) > 0.0 {
                    face.swap(1, 2);
                }
                let oriented = [face[0], face[1], face[2]];
                let mut key = oriented;
                key.sort_unstable();
                if faces.remove(&key).is_none() {
                    faces.insert(key, (t, oriented));
                }
            }
        }
        let mut surface: Vec<(usize, [u32; 3])> = faces.into_values().collect();
        surface.sort_unstable();
        let triangles = surface.iter().map(|s| s.1).collect();
        let piece = surface.iter().map(|s| box_of_tet[s.0]).collect();
        Self { rest, tets, dm_inv, mass: Mass::Lumped(masses), density: material.density, blocks, triangles, piece }
    }

    /// Every node as a contact point (an identity row).
    pub fn node_points(&self) -> Embedding {
        let mut points = Embedding::new();
        for n in 0..self.num_nodes() as u32 {
            points.push_row(&[n], &[1.0]);
        }
        points
    }

    /// The nodes of box `b`.
    pub fn box_nodes(&self, b: usize) -> std::ops::Range<usize> {
        8 * b..8 * b + 8
    }
}

impl Discretization for TetBoxes {
    fn name(&self) -> &str {
        "tet boxes"
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
        self.tets.len()
    }

    fn write_rotations(&self, x: &[Real], rotations: &mut [Matrix3<Real>]) -> RotationStats {
        write_frame_rotations(rotations, 8, |t| {
            let p = |c: usize| {
                let i = 3 * self.tets[t][c] as usize;
                Vector3::new(x[i], x[i + 1], x[i + 2])
            };
            Matrix3::from_columns(&[p(1) - p(0), p(2) - p(0), p(3) - p(0)]) * self.dm_inv[t]
        })
    }

    fn blocks(&self) -> &BlockSet {
        &self.blocks
    }

    /// Lumped: `∫ f N_k ≈ f(X_k) V_k`, with `V_k` the node's share of its tetrahedra's volume
    /// (its mass over the density).
    fn add_load(&self, force_density: &dyn Fn(&Point3<Real>) -> Vector3<Real>, out: &mut [Real]) {
        let m = self.mass.diagonal();
        for (k, p) in self.rest.chunks_exact(3).enumerate() {
            let f = force_density(&Point3::new(p[0], p[1], p[2]));
            for a in 0..3 {
                out[3 * k + a] += f[a] * m[3 * k + a] / self.density;
            }
        }
    }

    /// The barycentric row of the first tetrahedron that holds the point.
    fn embed(&self, points: &[Point3<Real>]) -> Result<Embedding, EmbedError> {
        let mut embedding = Embedding::new();
        for (index, q) in points.iter().enumerate() {
            let found = self.tets.iter().zip(&self.dm_inv).find_map(|(tet, inverse)| {
                let i = 3 * tet[0] as usize;
                let b = inverse * (q - Point3::new(self.rest[i], self.rest[i + 1], self.rest[i + 2]));
                let weights = [1.0 - b.sum(), b.x, b.y, b.z];
                weights.iter().all(|&w| w >= -1e-12).then_some((tet, weights))
            });
            let Some((tet, weights)) = found else {
                return Err(EmbedError::Outside { index, x: q.x, y: q.y, z: q.z });
            };
            embedding.push_row(tet, &weights);
        }
        Ok(embedding)
    }

    fn visit_field(&self, _displacement: &[Real], _min_degree: usize, _visit: &mut dyn FnMut(&FieldSample)) {}
}

/// Linear and angular momentum (about the origin) of the lumped masses.
pub fn momentum(body: &TetBoxes, x: &[Real], v: &[Real]) -> (Vector3<Real>, Vector3<Real>) {
    let m = body.mass().diagonal();
    let (mut p, mut l) = (Vector3::zeros(), Vector3::zeros());
    for k in 0..m.len() / 3 {
        let mv = Vector3::new(m[3 * k] * v[3 * k], m[3 * k + 1] * v[3 * k + 1], m[3 * k + 2] * v[3 * k + 2]);
        p += mv;
        l += Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]).cross(&mv);
    }
    (p, l)
}
