//! Adaptive refinement of a DG body (kaufmann2008 §10, "Dynamic adaptivity"; docs/math/dg.md §14): an element whose
//! largest absolute principal stress exceeds a threshold is split 1→8 (three planes through its
//! centroid normal to its own axes: a hexahedral cell into its eight octants) or 1→2 (the plane
//! through its centroid normal to that principal direction); its children carry its polynomial
//! exactly, and no neighbour needs a matching level (DG couples faces of any shape).

use super::cut::{MeshEdit, plane_through};
use super::{DgMesh, PLANARITY};
use cleave_core::{Matrix3, Point3, Real, Refinable, TopologyChange, TopologyError, Vector3};
use cleave_geometry::split_mesh_element;

/// How an element is split.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RefineSplit {
    /// 1→8: by the three planes through the centroid normal to the element's axes
    /// ([`DgMesh::element_axes`]).
    #[default]
    Octants,
    /// 1→2: by the plane through the centroid normal to the principal stress direction.
    Halves,
}

/// How [`Refinable::refine`] splits a DG body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Refinement {
    /// 1→8 or 1→2.
    pub split: RefineSplit,
    /// Elements made by this many refinements are not split again (the smallest cell is the
    /// original's 8^-depth, or 2^-depth, of its volume).
    pub max_depth: u32,
}

impl Default for Refinement {
    fn default() -> Self {
        Self { split: RefineSplit::Octants, max_depth: 3 }
    }
}

impl DgMesh {
    /// How `refine` splits.
    pub fn refinement(&self) -> Refinement {
        self.refinement
    }

    /// Sets how `refine` splits.
    pub fn set_refinement(&mut self, refinement: Refinement) {
        self.refinement = refinement;
    }

    /// Per element, how many refinements made it.
    pub fn refinement_depths(&self) -> &[u32] {
        &self.depth
    }

    /// Three orthonormal axes of element `e` from its faces: the normal of the largest area of
    /// parallel faces, the face normal most nearly orthogonal to it (made orthogonal), their
    /// cross product. A box's own axes, whatever its pose, so 1→8 splits a hexahedral cell into
    /// its octants; for a general polyhedron, planes that follow its faces.
    pub fn element_axes(&self, e: usize) -> [Vector3<Real>; 3] {
        // (unit normal up to sign, summed area) per direction of parallel faces.
        let mut directions: Vec<(Vector3<Real>, Real)> = Vec::new();
        for &(f, _) in &self.element_faces[e] {
            // Newell's area vector about the face's mean: exact to rounding, so that neighbours'
            // planes agree far inside the on-plane tolerance.
            let points: Vec<&Point3<Real>> =
                self.mesh.faces[f as usize].polygon.iter().map(|&v| &self.mesh.vertices[v as usize]).collect();
            let mean = points.iter().map(|p| p.coords).sum::<Vector3<Real>>() / points.len() as Real;
            let twice_area: Vector3<Real> = (0..points.len())
                .map(|k| (points[k].coords - mean).cross(&(points[(k + 1) % points.len()].coords - mean)))
                .sum();
            let area = twice_area.norm() / 2.0;
            if !(area > 0.0 && area.is_finite()) {
                continue;
            }
            let normal = twice_area.normalize();
            match directions.iter_mut().find(|(n, _)| n.dot(&normal).abs() > 1.0 - 1e-9) {
                Some((_, total)) => *total += area,
                None => directions.push((normal, area)),
            }
        }
        let first = directions.iter().max_by(|a, b| a.1.total_cmp(&b.1)).map_or(Vector3::x(), |d| d.0);
        let second = directions
            .iter()
            .map(|(n, area)| (n - first * first.dot(n), *area))
            .filter(|(n, _)| n.norm() > 1e-6)
            .max_by(|a, b| a.0.norm().total_cmp(&b.0.norm()).then(a.1.total_cmp(&b.1)))
            .map_or_else(|| first.cross(&if first.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() }), |d| d.0)
            .normalize();
        [first, second, first.cross(&second)]
    }

    /// Element `e`'s corotated stress at its centroid (the rest frame's Cauchy stress of the
    /// linear material, `σ = λ tr ε I + 2 μ ε` with `ε = sym(Rᵀ F) − I`, `F` the centroid
    /// gradient of its polynomial at positions `x`).
    pub fn element_stress(&self, e: usize, x: &[Real], rotation: &Matrix3<Real>) -> Matrix3<Real> {
        let f = self.centroid_gradient(e, x);
        let f = rotation.transpose() * f;
        let strain = (f + f.transpose()) * 0.5 - Matrix3::identity();
        let (lambda, mu) = self.material.lame();
        Matrix3::identity() * (lambda * strain.trace()) + strain * (2.0 * mu)
    }
}

impl Refinable for DgMesh {
    /// Splits every element below the depth limit whose largest absolute principal stress
    /// exceeds `threshold` (the most stressed first), all in one change.
    fn refine(
        &mut self,
        x: &[Real],
        rotations: &[Matrix3<Real>],
        threshold: Real,
    ) -> Result<Option<TopologyChange>, TopologyError> {
        if !(threshold.is_finite() && threshold > 0.0) {
            return Err(TopologyError::Invalid(format!(
                "a refinement threshold must be a finite stress > 0 Pa, got {threshold}"
            )));
        }
        let elements = self.mesh.num_elements;
        if x.len() != 3 * elements * self.exps.len() || rotations.len() != elements {
            return Err(TopologyError::Invalid(format!(
                "refining needs {} positions and {elements} rotations, got {} and {}",
                3 * elements * self.exps.len(),
                x.len(),
                rotations.len()
            )));
        }
        if self.has_dirichlet && !self.clamp_kept {
            return Err(TopologyError::Invalid(
                "a DG body with weak Dirichlet data other than a clamp (DgMesh::clamped) cannot be refined: the data is not kept for the rebuild"
                    .into(),
            ));
        }
        // (stress, element, rest-space principal direction), the most stressed first.
        let mut marked: Vec<(Real, usize, Vector3<Real>)> = (0..elements)
            .filter(|&e| self.depth[e] < self.refinement.max_depth)
            .filter_map(|e| {
                let eigen = self.element_stress(e, x, &rotations[e]).symmetric_eigen();
                let k = eigen.eigenvalues.iamax();
                let stress = eigen.eigenvalues[k].abs();
                (stress > threshold).then(|| (stress, e, eigen.eigenvectors.column(k).into_owned()))
            })
            .collect();
        if marked.is_empty() {
            return Ok(None);
        }
        marked.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let tolerance = self.on_plane_tolerance();
        let mut edit = MeshEdit::new(self);
        for &(_, element, direction) in &marked {
            let centroid = self.bases[element].frame.center;
            let axes = self.element_axes(element);
            let normals = match self.refinement.split {
                RefineSplit::Octants => axes.to_vec(),
                // A direction within rounding of one of the element's axes is that axis, so
                // that neighbours stretched alike split along one plane, not along two planes
                // a rounding apart (whose crossings would make faces of no width).
                RefineSplit::Halves => {
                    let nearest =
                        axes.iter().max_by(|a, b| a.dot(&direction).abs().total_cmp(&b.dot(&direction).abs()));
                    vec![nearest.filter(|a| a.dot(&direction).abs() > 1.0 - 1e-9).copied().unwrap_or(direction)]
                }
            };
            // An element whose split would leave a face bent beyond the mesh's planarity
            // tolerance (a plane passing a hair from a vertex a neighbour made), or that the mesh
            // step cannot split, stays whole (and may split at a later check).
            let before = edit.clone();
            let (mut split_any, mut unsplittable) = (false, false);
            for normal in normals {
                let plane = plane_through(&centroid, &normal);
                // Every current piece of `element` in turn (one, then two, then four).
                let pieces: Vec<usize> =
                    (0..edit.parent.len()).filter(|&c| edit.parent[c] as usize == element).collect();
                // Splitting a piece renumbers those after it by its extra children: go backwards.
                for &piece in pieces.iter().rev() {
                    match split_mesh_element(&edit.mesh, piece, &plane, tolerance) {
                        Ok(split) => {
                            split_any |= split.split_elements > 0;
                            edit.apply(split);
                        }
                        Err(_) => unsplittable = true,
                    }
                }
            }
            // A split the mesh step cannot make, or one leaving a bent face, leaves it whole.
            if !split_any || unsplittable || edit.mesh.validate(PLANARITY).is_err() {
                edit = before;
                continue;
            }
            for (c, &p) in edit.parent.iter().enumerate() {
                if p as usize == element {
                    edit.depth[c] = self.depth[element] + 1;
                }
            }
        }
        if !edit.changed {
            return Ok(None);
        }
        self.rebuild(edit, "a refinement").map(Some)
    }
}
