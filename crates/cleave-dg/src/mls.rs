//! MLS surface embedding (kaufmann2008 §8): discontinuous element fields are stitched at the mesh
//! vertices by averaging over incident elements, and a surface point is interpolated from nearby
//! vertices by moving least squares with Gaussian weights and a linear basis, so linear fields are
//! reproduced exactly. The weights are composed into one sparse `Embedding` row per point
//! (docs/math/dg.md §6).

use crate::DgMesh;
use cleave_core::{EmbedError, Embedding, Point3, Real, Vector3};
use nalgebra::{Matrix4, Vector4};
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Neighbouring vertices per point: enough for a well-posed linear fit on curved surfaces, few
/// enough that a contact row couples a handful of elements.
const NEIGHBOURS: usize = 12;

/// Embeds `points` by MLS over the stitched vertex field of `mesh`.
pub fn embed_mls(mesh: &DgMesh, points: &[Point3<Real>]) -> Result<Embedding, EmbedError> {
    let poly = mesh.polyhedral_mesh();
    let nb = mesh.basis_size();
    // Incident elements of every vertex.
    let mut incident: Vec<Vec<u32>> = vec![Vec::new(); poly.vertices.len()];
    for face in &poly.faces {
        for &v in &face.polygon {
            incident[v as usize].push(face.inner);
            if let Some(o) = face.outer {
                incident[v as usize].push(o);
            }
        }
    }
    for list in &mut incident {
        list.sort_unstable();
        list.dedup();
    }
    let used: Vec<u32> = (0..poly.vertices.len() as u32).filter(|&v| !incident[v as usize].is_empty()).collect();
    // Stitch rows: vertex v ↦ Σ_K Σ_i ψ^K_i(v) / n_v on node (K, i).
    let stitch: Vec<Vec<(u32, Real)>> = used
        .par_iter()
        .map(|&v| {
            let p = poly.vertices[v as usize];
            let elements = &incident[v as usize];
            let mut values = vec![0.0; nb];
            let mut gradients = vec![Vector3::zeros(); nb];
            let mut row = Vec::with_capacity(elements.len() * nb);
            for &e in elements {
                mesh.evaluate_basis(e as usize, &p, &mut values, &mut gradients);
                for (i, value) in values.iter().enumerate() {
                    row.push((e * nb as u32 + i as u32, value / elements.len() as Real));
                }
            }
            row
        })
        .collect();
    let rows: Vec<Result<Vec<(u32, Real)>, EmbedError>> = points
        .par_iter()
        .enumerate()
        .map(|(index, p)| {
            let outside = || EmbedError::Outside { index, x: p.x, y: p.y, z: p.z };
            let mut nearest: Vec<(Real, usize)> =
                used.iter().enumerate().map(|(k, &v)| ((poly.vertices[v as usize] - p).norm_squared(), k)).collect();
            let count = NEIGHBOURS.min(nearest.len());
            if count < 4 {
                return Err(outside());
            }
            nearest.select_nth_unstable_by(count - 1, |a, b| a.0.total_cmp(&b.0));
            nearest.truncate(count);
            // Support tied to the local sampling density: the distance to the farthest neighbour.
            let radius2 = nearest.iter().map(|n| n.0).fold(0.0, Real::max).max(Real::MIN_POSITIVE);
            let basis = |k: usize| {
                let d = poly.vertices[used[k] as usize] - p;
                Vector4::new(1.0, d.x, d.y, d.z)
            };
            let mut moment = Matrix4::zeros();
            let weights: Vec<Real> = nearest.iter().map(|n| (-n.0 / radius2).exp()).collect();
            for (n, w) in nearest.iter().zip(&weights) {
                let b = basis(n.1);
                moment += b * b.transpose() * *w;
            }
            let inverse = moment.try_inverse().ok_or_else(outside)?;
            // φ_v(p) = w_v e₀ᵀ M⁻¹ b(v) (basis centred at p, so b(p) = e₀).
            let first_row = inverse.row(0).transpose();
            let mut merged: BTreeMap<u32, Real> = BTreeMap::new();
            for (n, w) in nearest.iter().zip(&weights) {
                let phi = w * first_row.dot(&basis(n.1));
                for &(node, s) in &stitch[n.1] {
                    *merged.entry(node).or_insert(0.0) += phi * s;
                }
            }
            Ok(merged.into_iter().collect())
        })
        .collect();
    let mut embedding = Embedding::new();
    let (mut nodes, mut weights) = (Vec::new(), Vec::new());
    for row in rows {
        let row = row?;
        nodes.clear();
        weights.clear();
        for (n, w) in row {
            nodes.push(n);
            weights.push(w);
        }
        embedding.push_row(&nodes, &weights);
    }
    Ok(embedding)
}
