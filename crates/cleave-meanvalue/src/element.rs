//! One mean value element's integrals: quadrature points over the element fanned from its vertex
//! average into tetrahedra (each split into eight `refinement` times, a 4-point degree-2 rule on
//! each), the shape functions and their gradients there, the gradient correction that makes
//! `Σ_q w_q ∇λ_i(q)` equal the boundary integral `∮ λ_i n dA` (so linear fields are reproduced
//! exactly: the patch test), the 3k × 3k stiffness and the integrals of the shape functions.
//! docs/math/mean-value.md §5.

use crate::coordinates::{Workspace, mean_value_coordinates};
use crate::polyhedron::{ConvexPolyhedron, Real};
use nalgebra::{DMatrix, Matrix3, Point3, Vector3};

/// The 4-point degree-2 rule on a tetrahedron: barycentric `(a, b, b, b)` and permutations.
const TET_A: Real = 0.585_410_196_624_968_5;
const TET_B: Real = 0.138_196_601_125_010_5;

/// The 7-point degree-5 rule on a triangle (Dunavant): barycentric points and weights (sum 1).
const TRIANGLE_RULE: [([Real; 3], Real); 7] = [
    ([1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0], 0.225),
    ([0.059_715_871_789_769_8, 0.470_142_064_105_115_1, 0.470_142_064_105_115_1], 0.132_394_152_788_506_2),
    ([0.470_142_064_105_115_1, 0.059_715_871_789_769_8, 0.470_142_064_105_115_1], 0.132_394_152_788_506_2),
    ([0.470_142_064_105_115_1, 0.470_142_064_105_115_1, 0.059_715_871_789_769_8], 0.132_394_152_788_506_2),
    ([0.797_426_985_353_087_3, 0.101_286_507_323_456_3, 0.101_286_507_323_456_3], 0.125_939_180_544_827_2),
    ([0.101_286_507_323_456_3, 0.797_426_985_353_087_3, 0.101_286_507_323_456_3], 0.125_939_180_544_827_2),
    ([0.101_286_507_323_456_3, 0.101_286_507_323_456_3, 0.797_426_985_353_087_3], 0.125_939_180_544_827_2),
];

/// An element's quadrature with its shape functions, ready for assembly.
#[derive(Clone, Debug)]
pub struct ElementIntegrals {
    /// Quadrature points.
    pub points: Vec<Point3<Real>>,
    /// Their weights (sum: the volume).
    pub weights: Vec<Real>,
    /// `λ_i` at each point, `values[q * k + i]`.
    pub values: Vec<Real>,
    /// Corrected `∇λ_i` at each point, `gradients[q * k + i]`.
    pub gradients: Vec<Vector3<Real>>,
    /// `∮ λ_i n dA` by the face rule: the exact `∫ ∇λ_i dV` of a consistent element.
    pub boundary_gradients: Vec<Vector3<Real>>,
    /// `∫ λ_i dV` (lumped mass / density).
    pub shape_integrals: Vec<Real>,
    /// The volume.
    pub volume: Real,
    /// `|Σ_q w ∇λ_i − ∮ λ_i n dA|` before the correction, largest over `i`, over `V^{2/3}`: the
    /// raw rule's patch-test residual (mean-value.md §5).
    pub patch_residual: Real,
    shifts: Vec<Vector3<Real>>,
}

/// Every tetrahedron `(c, p_0, p_j, p_{j+1})` of the fan of `element` from `c`.
fn fan_tetrahedra(element: &ConvexPolyhedron, c: Point3<Real>) -> Vec<[Point3<Real>; 4]> {
    let v = element.vertices();
    let mut tets = Vec::new();
    for face in element.faces() {
        for j in 1..face.len() - 1 {
            tets.push([c, v[face[0]], v[face[j]], v[face[j + 1]]]);
        }
    }
    tets
}

/// The eight children of a tetrahedron (midpoint subdivision: four corners, four of the inner
/// octahedron cut along one diagonal).
fn subdivide(t: &[Point3<Real>; 4]) -> [[Point3<Real>; 4]; 8] {
    let m = |a: usize, b: usize| Point3::from((t[a].coords + t[b].coords) * 0.5);
    let (m01, m02, m03, m12, m13, m23) = (m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3));
    [
        [t[0], m01, m02, m03],
        [m01, t[1], m12, m13],
        [m02, m12, t[2], m23],
        [m03, m13, m23, t[3]],
        [m01, m02, m03, m13],
        [m01, m02, m12, m13],
        [m02, m03, m13, m23],
        [m02, m12, m13, m23],
    ]
}

fn tet_volume(t: &[Point3<Real>; 4]) -> Real {
    ((t[1] - t[0]).cross(&(t[2] - t[0])).dot(&(t[3] - t[0])) / 6.0).abs()
}

/// The element rule: the fan from the vertex average, each tetrahedron split into eight
/// `refinement` times, four points on each (points strictly inside, never on a face).
pub fn quadrature(element: &ConvexPolyhedron, refinement: u32) -> (Vec<Point3<Real>>, Vec<Real>) {
    let mut tets = fan_tetrahedra(element, element.vertex_average());
    for _ in 0..refinement {
        tets = tets.iter().flat_map(subdivide).collect();
    }
    let (mut points, mut weights) = (Vec::with_capacity(4 * tets.len()), Vec::with_capacity(4 * tets.len()));
    for t in &tets {
        let w = tet_volume(t) / 4.0;
        for corner in 0..4 {
            let mut p = t[corner].coords * TET_A;
            for other in (0..4).filter(|&o| o != corner) {
                p += t[other].coords * TET_B;
            }
            points.push(Point3::from(p));
            weights.push(w);
        }
    }
    (points, weights)
}

impl ElementIntegrals {
    /// Integrates `element` with the fan rule refined `refinement` times.
    pub fn new(element: &ConvexPolyhedron, refinement: u32) -> Self {
        let k = element.vertices().len();
        let mut work = Workspace::default();
        let (points, weights) = quadrature(element, refinement);
        let n = points.len();
        let mut values = vec![0.0; n * k];
        let mut gradients = vec![Vector3::zeros(); n * k];
        for (q, p) in points.iter().enumerate() {
            mean_value_coordinates(
                element,
                p,
                &mut values[q * k..(q + 1) * k],
                Some(&mut gradients[q * k..(q + 1) * k]),
                &mut work,
            );
        }
        let volume: Real = weights.iter().sum();
        // ∮ λ_i n dA, each face fanned into triangles with a degree-5 rule (the trace is the
        // face polygon's 2D mean value coordinates, the same from both sides of a shared face).
        let mut boundary_gradients = vec![Vector3::zeros(); k];
        let mut trace = vec![0.0; k];
        let v = element.vertices();
        for (f, face) in element.faces().iter().enumerate() {
            let normal = element.normals()[f];
            let centre = Point3::from(face.iter().map(|&i| v[i].coords).sum::<Vector3<Real>>() / face.len() as Real);
            for j in 0..face.len() {
                let (a, b) = (v[face[j]], v[face[(j + 1) % face.len()]]);
                let area = 0.5 * (a - centre).cross(&(b - centre)).dot(&normal);
                if area <= 0.0 {
                    continue;
                }
                for (bary, w) in TRIANGLE_RULE {
                    let p = Point3::from(centre.coords * bary[0] + a.coords * bary[1] + b.coords * bary[2]);
                    mean_value_coordinates(element, &p, &mut trace, None, &mut work);
                    for i in 0..k {
                        boundary_gradients[i] += normal * (trace[i] * w * area);
                    }
                }
            }
        }
        // The correction: a constant per shape function, so that the rule integrates ∇λ_i to
        // the boundary integral (Talischi et al. 2015's gradient correction for polyhedra).
        let mut patch_residual: Real = 0.0;
        let mut shifts = Vec::with_capacity(k);
        for i in 0..k {
            let raw: Vector3<Real> = (0..n).map(|q| gradients[q * k + i] * weights[q]).sum();
            let shift = (boundary_gradients[i] - raw) / volume;
            patch_residual = patch_residual.max((boundary_gradients[i] - raw).norm());
            for q in 0..n {
                gradients[q * k + i] += shift;
            }
            shifts.push(shift);
        }
        let shape_integrals = (0..k).map(|i| (0..n).map(|q| values[q * k + i] * weights[q]).sum()).collect();
        Self {
            points,
            weights,
            values,
            gradients,
            boundary_gradients,
            shape_integrals,
            volume,
            patch_residual: patch_residual / volume.powf(2.0 / 3.0),
            shifts,
        }
    }

    /// The gradient correction added to every `∇λ_i` (a constant per node).
    pub fn shifts(&self) -> Vec<Vector3<Real>> {
        self.shifts.clone()
    }

    /// Number of shape functions (element nodes).
    pub fn nodes(&self) -> usize {
        self.shape_integrals.len()
    }

    /// The isotropic linear elastic stiffness `K_ij = Σ_q w [λ ∇λ_i ∇λ_jᵀ + μ (∇λ_i·∇λ_j) I +
    /// μ ∇λ_j ∇λ_iᵀ]` (Lamé `lambda`, `mu`), 3k × 3k, node-major.
    pub fn stiffness(&self, lambda: Real, mu: Real) -> DMatrix<Real> {
        let k = self.nodes();
        let mut stiffness = DMatrix::zeros(3 * k, 3 * k);
        for (q, &w) in self.weights.iter().enumerate() {
            let g = &self.gradients[q * k..(q + 1) * k];
            for i in 0..k {
                for j in 0..k {
                    let block: Matrix3<Real> = (g[i] * g[j].transpose() * lambda
                        + Matrix3::identity() * (mu * g[i].dot(&g[j]))
                        + g[j] * g[i].transpose() * mu)
                        * w;
                    let mut view = stiffness.fixed_view_mut::<3, 3>(3 * i, 3 * j);
                    view += block;
                }
            }
        }
        // Symmetric up to round-off; make it exactly so (the block set checks).
        let transpose = stiffness.transpose();
        (stiffness + transpose) * 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_face_rule_gives_each_face_its_area_vector_and_the_correction_is_small() {
        let cube = ConvexPolyhedron::cuboid(Point3::origin(), Point3::new(1.0, 2.0, 0.5)).unwrap();
        let integrals = ElementIntegrals::new(&cube, 1);
        assert!((integrals.volume - 1.0).abs() < 1e-14);
        // Σ_i ∮ λ_i n dA = ∮ n dA = 0, and Σ_i v_i ⊗ ∮ λ_i n = ∮ x ⊗ n dA = V I (exact for the
        // 2D coordinates' linear precision on each face).
        let sum: Vector3<Real> = integrals.boundary_gradients.iter().sum();
        assert!(sum.norm() < 1e-14);
        let moment: Matrix3<Real> =
            cube.vertices().iter().zip(&integrals.boundary_gradients).map(|(v, g)| v.coords * g.transpose()).sum();
        assert!((moment - Matrix3::identity()).norm() < 1e-13, "{moment}");
        // Σ ∫λ_i = V.
        let total: Real = integrals.shape_integrals.iter().sum();
        assert!((total - 1.0).abs() < 1e-13);
        assert!(integrals.patch_residual < 1e-2, "raw patch residual {}", integrals.patch_residual);
    }
}
