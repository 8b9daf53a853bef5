//! `Cuttable` for the voxel mesh (mueller2004 §2.3; docs/math/voxel-cutting.md): a cut separates
//! the cubes across every face whose dual edge (the segment between the two cubes' centres)
//! crosses the cut surface, decided with exact orientation predicates; the nodes of separated
//! faces are duplicated per group of cubes still joined around them (`DofRemap::Gather`, so
//! every material point keeps its motion). Pieces are the cubes joined through faces that are
//! not cut. The render surface of a body of whole cubes (a box) is the boundary of each piece's
//! cubes, outer and cut faces alike; a body carrying a surface mesh renders it separated along
//! triangle edges and capped (`surface.rs`).

use crate::mesh::{CubeFace, VoxelMesh};
use cleave_core::{
    CutSurface, Cuttable, Discretization, EmbeddedSurface, Piece, Point3, Real, TopologyChange, TopologyError, Vector3,
};
use cleave_geometry::UnionFind;
use cleave_geometry::predicates::side3;

/// The side of `p` for the plane through `point` with `normal`: `true` on the side the normal
/// points to or on the plane (a point on it takes the positive side, so a plane through cube
/// centres separates consistently).
fn plane_side(point: &Point3<Real>, normal: &Vector3<Real>, p: &Point3<Real>) -> bool {
    normal.dot(&(p - point)) >= 0.0
}

/// Whether the segment `p → q` crosses the closed triangle `t`: its ends on strictly different
/// sides of the triangle's plane (an end on the plane counts as below it, one consistent rule)
/// and the line through them passing through the triangle, edges and corners included (a dual
/// edge through the edge two triangles share crosses both; the set of faces is the same).
fn crosses(p: &Point3<Real>, q: &Point3<Real>, t: &[Point3<Real>; 3]) -> bool {
    if (side3(&t[0], &t[1], &t[2], p) > 0) == (side3(&t[0], &t[1], &t[2], q) > 0) {
        return false;
    }
    let around = [side3(p, q, &t[0], &t[1]), side3(p, q, &t[1], &t[2]), side3(p, q, &t[2], &t[0])];
    around.iter().all(|&s| s >= 0) || around.iter().all(|&s| s <= 0)
}

impl VoxelMesh {
    /// Centre of the cube at integer coordinates `cell`.
    fn centre(&self, cell: [i32; 3]) -> Point3<Real> {
        self.origin()
            + Vector3::new(cell[0] as Real + 0.5, cell[1] as Real + 0.5, cell[2] as Real + 0.5) * self.cell_size()
    }

    /// The interior faces not yet cut whose dual edge crosses `surface` (sorted). A degenerate
    /// triangle (three collinear corners) crosses nothing.
    pub fn crossed_faces(&self, surface: &CutSurface) -> Vec<CubeFace> {
        let mut faces = Vec::new();
        let consider = |cell: [i32; 3],
                        axis: usize,
                        faces: &mut Vec<CubeFace>,
                        test: &dyn Fn(&Point3<Real>, &Point3<Real>) -> bool| {
            let mut next = cell;
            next[axis] += 1;
            let face = CubeFace { cell, axis };
            if self.cube_at(cell).is_some()
                && self.cube_at(next).is_some()
                && self.cut_faces().binary_search(&face).is_err()
                && test(&self.centre(cell), &self.centre(next))
            {
                faces.push(face);
            }
        };
        match surface {
            CutSurface::Plane { point, normal } => {
                for &cell in self.cells() {
                    for axis in 0..3 {
                        consider(cell, axis, &mut faces, &|p, q| {
                            plane_side(point, normal, p) != plane_side(point, normal, q)
                        });
                    }
                }
            }
            CutSurface::Triangles(triangles) => {
                let h = self.cell_size();
                let origin = self.origin();
                for t in triangles {
                    // The cubes whose dual edges can reach the triangle: those whose centre lies
                    // within one cube of its box.
                    let lo: [i32; 3] = std::array::from_fn(|a| {
                        ((t.iter().map(|p| p[a]).fold(Real::INFINITY, Real::min) - origin[a]) / h - 1.5).floor() as i32
                    });
                    let hi: [i32; 3] = std::array::from_fn(|a| {
                        ((t.iter().map(|p| p[a]).fold(Real::NEG_INFINITY, Real::max) - origin[a]) / h + 0.5).ceil()
                            as i32
                    });
                    if (0..3).any(|a| hi[a] < lo[a]) || (0..3).any(|a| (hi[a] as i64 - lo[a] as i64) > 1 << 20) {
                        continue;
                    }
                    for z in lo[2]..=hi[2] {
                        for y in lo[1]..=hi[1] {
                            for x in lo[0]..=hi[0] {
                                for axis in 0..3 {
                                    consider([x, y, z], axis, &mut faces, &|p, q| crosses(p, q, t));
                                }
                            }
                        }
                    }
                }
            }
        }
        faces.sort_unstable();
        faces.dedup();
        faces
    }

    /// Cube index → piece index, and the number of pieces: cubes joined through faces that are
    /// not cut, numbered by their first cube.
    fn piece_of_cubes(&self) -> (Vec<u32>, usize) {
        let mut joined = UnionFind::new(self.num_cubes());
        for (cube, &cell) in self.cells().iter().enumerate() {
            for axis in 0..3 {
                let mut next = cell;
                next[axis] += 1;
                if let Some(other) = self.cube_at(next)
                    && self.cut_faces().binary_search(&CubeFace { cell, axis }).is_err()
                {
                    joined.union(cube, other);
                }
            }
        }
        let mut piece_of_root = vec![u32::MAX; self.num_cubes()];
        let mut pieces = 0u32;
        let piece_of = (0..self.num_cubes())
            .map(|cube| {
                let root = joined.find(cube);
                if piece_of_root[root] == u32::MAX {
                    piece_of_root[root] = pieces;
                    pieces += 1;
                }
                piece_of_root[root]
            })
            .collect();
        (piece_of, pieces as usize)
    }
}

impl Cuttable for VoxelMesh {
    fn cut(&mut self, surface: &CutSurface) -> Result<TopologyChange, TopologyError> {
        let faces = self.crossed_faces(surface);
        let (mesh, change) = self.separate_faces(&faces).map_err(|e| TopologyError::Invalid(e.to_string()))?;
        *self = mesh;
        Ok(change)
    }

    /// The surface the cubes carry, separated and capped (`surface.rs`), or for a body of whole
    /// cubes the boundary of each piece's cubes: every cube face without a neighbour or on a cut,
    /// two triangles over the cube's own nodes (so the two sides of a cut face are two pieces'
    /// surfaces), outward.
    fn surface(&self) -> Option<EmbeddedSurface> {
        let (piece_of, _) = self.piece_of_cubes();
        if let Some(input) = self.embedded_input() {
            return Some(self.separated_surface(input, &piece_of));
        }
        let mut surface = EmbeddedSurface::default();
        let mut vertex_of = std::collections::HashMap::new();
        let rest = self.rest_dofs();
        for (cube, &cell) in self.cells().iter().enumerate() {
            for axis in 0..3 {
                for side in [0usize, 1] {
                    let mut neighbour = cell;
                    neighbour[axis] += if side == 1 { 1 } else { -1 };
                    let between = if side == 1 { CubeFace { cell, axis } } else { CubeFace { cell: neighbour, axis } };
                    let cut = self.cut_faces().binary_search(&between).is_ok();
                    if self.cube_at(neighbour).is_some() && !cut {
                        continue;
                    }
                    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                    let corner = |a: usize, b: usize| (side << axis) | (a << u) | (b << v);
                    let quad = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                    let nodes = quad.map(|c| self.cube_nodes()[cube][c]);
                    let ids = nodes.map(|n| {
                        *vertex_of.entry(n).or_insert_with(|| {
                            let i = 3 * n as usize;
                            surface.rest_vertices.push(Point3::new(rest[i], rest[i + 1], rest[i + 2]));
                            surface.embedding.push_row(&[n], &[1.0]);
                            (surface.rest_vertices.len() - 1) as u32
                        })
                    });
                    // (u, v, axis) is right-handed: the cyclic order faces +axis; flipped on the
                    // minus side.
                    let pair = if side == 1 {
                        [[ids[0], ids[1], ids[2]], [ids[0], ids[2], ids[3]]]
                    } else {
                        [[ids[0], ids[2], ids[1]], [ids[0], ids[3], ids[2]]]
                    };
                    for t in pair {
                        surface.triangles.push(t);
                        surface.on_cut.push(cut);
                        surface.piece.push(piece_of[cube]);
                    }
                }
            }
        }
        Some(surface)
    }

    fn pieces(&self) -> Vec<Piece> {
        let (piece_of, count) = self.piece_of_cubes();
        let volume = self.cell_size().powi(3);
        let density = self.material().density;
        let mut pieces = vec![Piece::default(); count];
        for (cube, &p) in piece_of.iter().enumerate() {
            let piece = &mut pieces[p as usize];
            piece.elements.push(cube as u32);
            piece.nodes.extend_from_slice(&self.cube_nodes()[cube]);
            piece.volume += volume;
        }
        for piece in &mut pieces {
            piece.nodes.sort_unstable();
            piece.nodes.dedup();
            piece.mass = density * piece.volume;
        }
        pieces
    }
}
