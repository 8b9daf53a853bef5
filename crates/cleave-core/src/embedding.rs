//! Embedded points: each point is a sparse row of (node, weight) pairs, `p = Σ w_k x_k`. The one
//! way to render surfaces, pin material points, probe displacements and apply collision penalties.

use crate::{Point3, Real};

/// A point that cannot be embedded.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EmbedError {
    /// The point lies outside every element.
    #[error("point {index} at ({x}, {y}, {z}) lies outside the discretized solid")]
    Outside {
        /// index of the point in the query
        index: usize,
        /// its x coordinate
        x: Real,
        /// its y coordinate
        y: Real,
        /// its z coordinate
        z: Real,
    },
}

/// Sparse rows of interpolation weights, CSR layout.
#[derive(Clone, Debug, PartialEq)]
pub struct Embedding {
    offsets: Vec<u32>,
    nodes: Vec<u32>,
    weights: Vec<Real>,
}

/// The embedding with no rows (a derived default would lack the leading offset, and its first
/// pushed row would be lost).
impl Default for Embedding {
    fn default() -> Self {
        Self::new()
    }
}

impl Embedding {
    /// An embedding with no rows.
    pub fn new() -> Self {
        Self { offsets: vec![0], nodes: Vec::new(), weights: Vec::new() }
    }

    /// Appends a row.
    pub fn push_row(&mut self, nodes: &[u32], weights: &[Real]) {
        debug_assert_eq!(nodes.len(), weights.len());
        self.nodes.extend_from_slice(nodes);
        self.weights.extend_from_slice(weights);
        self.offsets.push(self.nodes.len() as u32);
    }

    /// Number of rows (embedded points).
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row `i`: its nodes and weights.
    #[inline]
    pub fn row(&self, i: usize) -> (&[u32], &[Real]) {
        let range = self.offsets[i] as usize..self.offsets[i + 1] as usize;
        (&self.nodes[range.clone()], &self.weights[range])
    }

    /// Node lists of all rows (for coupling patterns).
    pub fn node_groups(&self) -> impl Iterator<Item = &[u32]> {
        (0..self.len()).map(|i| self.row(i).0)
    }

    /// The embedded point `i` for the DOF vector `x`.
    #[inline]
    pub fn point(&self, x: &[Real], i: usize) -> Point3<Real> {
        let (nodes, weights) = self.row(i);
        let mut p = Point3::origin();
        for (&n, &w) in nodes.iter().zip(weights) {
            let k = 3 * n as usize;
            p.x += w * x[k];
            p.y += w * x[k + 1];
            p.z += w * x[k + 2];
        }
        p
    }

    /// Writes every embedded point for the DOF vector `x` into `out` (resized).
    pub fn evaluate(&self, x: &[Real], out: &mut Vec<Point3<Real>>) {
        out.clear();
        out.extend((0..self.len()).map(|i| self.point(x, i)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_default_embedding_keeps_its_first_row() {
        let mut e = Embedding::default();
        assert!(e.is_empty());
        e.push_row(&[3, 5], &[0.25, 0.75]);
        assert_eq!(e.len(), 1);
        assert_eq!(e.row(0), (&[3u32, 5][..], &[0.25, 0.75][..]));
    }
}
