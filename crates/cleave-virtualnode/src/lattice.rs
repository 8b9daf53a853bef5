//! The body-centred cubic (BCC) tetrahedral lattice: cube corners and cube centres as nodes, and
//! one tetrahedron per (pair of face-adjacent cube centres, edge of their shared face) — 12 per
//! cube, all congruent, positively oriented.
//!
//! Nodes are addressed by *doubled* integer coordinates: corner `(i, j, k)` of cube grid is
//! `(2i, 2j, 2k)`, the centre of cube `(i, j, k)` is `(2i+1, 2j+1, 2k+1)`; position
//! `origin + h/2 · doubled`.

use nalgebra::{Point3, Vector3};
use std::collections::HashMap;

/// A BCC lattice over a box of cubes.
#[derive(Clone, Debug)]
pub struct BccLattice {
    /// Position of doubled coordinate `(0, 0, 0)`.
    pub origin: Point3<f64>,
    /// Cube edge.
    pub h: f64,
    /// Number of cubes per axis.
    pub dims: [i32; 3],
}

/// One lattice tetrahedron: doubled coordinates of its corners, positively oriented.
pub type LatticeTetCorners = [[i32; 3]; 4];

impl BccLattice {
    /// The lattice of cubes of edge `h` covering `[lo, hi]` with one cube of margin on each side.
    pub fn covering(lo: Point3<f64>, hi: Point3<f64>, h: f64) -> Self {
        let origin = lo - Vector3::repeat(h);
        let dims = std::array::from_fn(|a| (((hi[a] - lo[a]) / h).ceil() as i32).max(1) + 2);
        Self { origin, h, dims }
    }

    /// Position of a node given by doubled coordinates.
    #[inline]
    pub fn position(&self, d: [i32; 3]) -> Point3<f64> {
        self.origin + Vector3::new(d[0] as f64, d[1] as f64, d[2] as f64) * (0.5 * self.h)
    }

    /// The cube containing `p` (may be outside the lattice's range).
    pub fn cube_of(&self, p: &Point3<f64>) -> [i32; 3] {
        std::array::from_fn(|a| ((p[a] - self.origin[a]) / self.h).floor() as i32)
    }

    /// Every tetrahedron of the lattice, z-major by the face between its two cube centres.
    pub fn tetrahedra(&self) -> Vec<LatticeTetCorners> {
        let mut tets = Vec::new();
        let [nx, ny, nz] = self.dims;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let cube = [i, j, k];
                    for axis in 0..3 {
                        if cube[axis] + 1 >= self.dims[axis] {
                            continue;
                        }
                        let c1 = cube.map(|c| 2 * c + 1);
                        let mut c2 = c1;
                        c2[axis] += 2;
                        // The shared face: doubled coordinate 2(cube+1) along `axis`, spanning the
                        // other two axes around the centres.
                        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
                        let corner = |db: i32, dc: i32| {
                            let mut p = c1;
                            p[axis] += 1;
                            p[b] += db;
                            p[c] += dc;
                            p
                        };
                        let square = [corner(-1, -1), corner(1, -1), corner(1, 1), corner(-1, 1)];
                        for e in 0..4 {
                            let (e1, e2) = (square[e], square[(e + 1) % 4]);
                            let mut t = [c1, c2, e1, e2];
                            if orientation(&t) < 0 {
                                t.swap(2, 3);
                            }
                            tets.push(t);
                        }
                    }
                }
            }
        }
        tets
    }

    /// The (up to two) cubes a tetrahedron lies in: those of its two cube centres.
    pub fn cubes_of_tet(t: &LatticeTetCorners) -> impl Iterator<Item = [i32; 3]> + '_ {
        t.iter().filter(|d| d.iter().all(|c| c.rem_euclid(2) == 1)).map(|d| d.map(|c| (c - 1) / 2))
    }
}

/// Six times the signed volume in doubled units.
pub fn orientation(t: &LatticeTetCorners) -> i64 {
    let d = |i: usize| -> [i64; 3] { std::array::from_fn(|a| (t[i][a] - t[0][a]) as i64) };
    let (a, b, c) = (d(1), d(2), d(3));
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// Index of every distinct node of the given tetrahedra, z-major.
pub fn number_nodes(tets: &[LatticeTetCorners]) -> (Vec<[i32; 3]>, HashMap<[i32; 3], u32>) {
    let mut nodes: Vec<[i32; 3]> = tets.iter().flat_map(|t| t.iter().copied()).collect();
    nodes.sort_unstable_by_key(|c| (c[2], c[1], c[0]));
    nodes.dedup();
    let index = nodes.iter().enumerate().map(|(i, c)| (*c, i as u32)).collect();
    (nodes, index)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn twelve_congruent_positive_tets_per_cube_fill_the_interior() {
        let lattice = BccLattice { origin: Point3::new(0.5, -1.0, 2.0), h: 0.3, dims: [3, 3, 3] };
        let tets = lattice.tetrahedra();
        // Faces between adjacent cubes: 3 · 2 · 3 · 3 = 54, four tets each.
        assert_eq!(tets.len(), 54 * 4);
        for t in &tets {
            // Volume of every BCC tet: h³/12, i.e. (2³/12)·6 = 4 in doubled units of 6·volume.
            assert_eq!(orientation(t), 4);
        }
        // The central cube is covered exactly: its 6 faces each have 4 tets that put half their
        // volume inside it → 24 · h³/24 = h³.
        let centre = [3, 3, 3];
        let inside = tets.iter().filter(|t| t.contains(&centre)).count();
        assert_eq!(inside, 24);
    }
}
