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
    CutSurface, Cuttable, Discretization, EmbeddedSurface, Fracturable, Matrix3, Piece, Point3, Real, TopologyChange,
    TopologyError, Vector3,
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

    /// Cube index → component of the cubes joined through faces that are not cut (what
    /// `without_crumbs` compares a separation's outcome with).
    fn piece_of_cubes_through_faces(&self) -> Vec<u32> {
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
        (0..self.num_cubes()).map(|cube| joined.find(cube) as u32).collect()
    }

    /// Cube index → piece index, and the number of pieces: cubes joined through shared nodes
    /// (what moves them together), numbered by their first cube. Cubes joined through a face
    /// that is not cut share its nodes; so do cubes that touch at one edge or corner only
    /// (the voxelization leaves such contacts joined, and a piece is what they move as).
    pub(crate) fn piece_of_cubes(&self) -> (Vec<u32>, usize) {
        let mut joined = UnionFind::new(self.num_cubes());
        let mut first_cube = vec![u32::MAX; self.num_nodes()];
        for (cube, nodes) in self.cube_nodes().iter().enumerate() {
            for &n in nodes {
                match first_cube[n as usize] {
                    u32::MAX => first_cube[n as usize] = cube as u32,
                    first => {
                        joined.union(first as usize, cube);
                    }
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

/// Cubes from the fracturing cube, per axis, that the fracture plane separates (mueller2004
/// §2.3's "local neighborhood"): a 5 × 5 × 5 block, so a crack is at least two cubes long each
/// way and further cracks grow from its ends as the stress concentrates there.
pub const FRACTURE_REACH: i32 = 2;

impl VoxelMesh {
    /// The corotated small-strain stress of `cube` at positions `x` with its frame `rotation`, in
    /// the frame's axes: `σ = λ tr(ε) I + 2μ ε`, `ε = sym(Rᵀ F) − I`, with `F` the deformation
    /// gradient at the cube's centre (docs/math/voxel-cutting.md §5).
    pub fn cube_stress(&self, cube: usize, x: &[Real], rotation: &Matrix3<Real>) -> Matrix3<Real> {
        let f = rotation.transpose() * self.center_gradient(cube, x);
        let strain = (f + f.transpose()) * 0.5 - Matrix3::identity();
        let (lambda, mu) = self.material().lame();
        Matrix3::identity() * (lambda * strain.trace()) + strain * (2.0 * mu)
    }

    /// The largest principal stress of `cube` ([`VoxelMesh::cube_stress`]) and its direction in
    /// the world.
    pub fn principal_stress(&self, cube: usize, x: &[Real], rotation: &Matrix3<Real>) -> (Real, Vector3<Real>) {
        let eigen = self.cube_stress(cube, x, rotation).symmetric_eigen();
        let k = eigen.eigenvalues.imax();
        (eigen.eigenvalues[k], rotation * eigen.eigenvectors.column(k).into_owned())
    }

    /// The stress the fracture criterion reads: each cube's stress (in its frame, which is the
    /// rest-space orientation) averaged with the cubes around it that still share a node with
    /// it (its 3 × 3 × 3 block, a crack's other side left out). One cube's stress jumps where a
    /// contact point pushes on it; the average is the stress of the material around it, so a
    /// single cube is not torn off by a point load (docs/math/voxel-cutting.md §5).
    pub fn smoothed_stresses(&self, x: &[Real], rotations: &[Matrix3<Real>]) -> Vec<Matrix3<Real>> {
        let stresses: Vec<Matrix3<Real>> =
            (0..self.num_cubes()).map(|c| self.cube_stress(c, x, &rotations[c])).collect();
        (0..self.num_cubes())
            .map(|cube| {
                let cell = self.cells()[cube];
                let nodes = &self.cube_nodes()[cube];
                let (mut sum, mut count) = (Matrix3::zeros(), 0.0);
                for k in 0..27 {
                    let other = [cell[0] + k % 3 - 1, cell[1] + (k / 3) % 3 - 1, cell[2] + k / 9 - 1];
                    if let Some(o) = self.cube_at(other)
                        && self.cube_nodes()[o].iter().any(|n| nodes.contains(n))
                    {
                        sum += stresses[o];
                        count += 1.0;
                    }
                }
                sum / count
            })
            .collect()
    }

    /// The faces mueller2004 §2.3 separates for `cube`: the cubes within [`FRACTURE_REACH`] of
    /// it labelled by the side of the plane through its centre across `direction` (a rest-space
    /// direction), every face between two labels that is not cut yet.
    pub fn fracture_faces(&self, cube: usize, direction: &Vector3<Real>) -> Vec<CubeFace> {
        let centre = self.centre(self.cells()[cube]);
        let side = |cell: [i32; 3]| direction.dot(&(self.centre(cell) - centre)) >= 0.0;
        let c = self.cells()[cube];
        let mut faces = Vec::new();
        for dz in -FRACTURE_REACH..=FRACTURE_REACH {
            for dy in -FRACTURE_REACH..=FRACTURE_REACH {
                for dx in -FRACTURE_REACH..FRACTURE_REACH + 1 {
                    let cell = [c[0] + dx, c[1] + dy, c[2] + dz];
                    if self.cube_at(cell).is_none() {
                        continue;
                    }
                    for axis in 0..3 {
                        let mut next = cell;
                        next[axis] += 1;
                        let inside = (next[axis] - c[axis]).abs() <= FRACTURE_REACH;
                        let face = CubeFace { cell, axis };
                        if inside
                            && self.cube_at(next).is_some()
                            && side(cell) != side(next)
                            && self.cut_faces().binary_search(&face).is_err()
                        {
                            faces.push(face);
                        }
                    }
                }
            }
        }
        faces
    }
}

impl Fracturable for VoxelMesh {
    /// Every cube whose largest principal stress (smoothed over the cubes around it,
    /// [`VoxelMesh::smoothed_stresses`]) exceeds `threshold` fractures by mueller2004 §2.3's rule ([`VoxelMesh::fracture_faces`]), the most stressed first; a cube inside the
    /// neighbourhood of one that already fractured in this call waits for the next (its stress
    /// changes once the crack opens). `None` if nothing broke.
    fn fracture(
        &mut self,
        x: &[Real],
        rotations: &[Matrix3<Real>],
        threshold: Real,
    ) -> Result<Option<TopologyChange>, TopologyError> {
        if x.len() != 3 * self.num_nodes() || rotations.len() != self.num_cubes() {
            return Err(TopologyError::Invalid(format!(
                "fracture needs {} positions and {} rotations, got {} and {}",
                3 * self.num_nodes(),
                self.num_cubes(),
                x.len(),
                rotations.len()
            )));
        }
        // Stresses in each cube's frame: their directions are rest-space directions, where the
        // faces are labelled.
        let mut stressed: Vec<(Real, usize, Vector3<Real>)> = self
            .smoothed_stresses(x, rotations)
            .into_iter()
            .enumerate()
            .filter_map(|(cube, stress)| {
                let eigen = stress.symmetric_eigen();
                let k = eigen.eigenvalues.imax();
                (eigen.eigenvalues[k] > threshold)
                    .then(|| (eigen.eigenvalues[k], cube, eigen.eigenvectors.column(k).into_owned()))
            })
            .collect();
        if stressed.is_empty() {
            return Ok(None);
        }
        stressed.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut faces = Vec::new();
        let mut fractured: Vec<[i32; 3]> = Vec::new();
        for (_, cube, direction) in stressed {
            let cell = self.cells()[cube];
            if fractured.iter().any(|f| (0..3).all(|a| (f[a] - cell[a]).abs() <= FRACTURE_REACH)) {
                continue;
            }
            fractured.push(cell);
            faces.extend(self.fracture_faces(cube, &direction));
        }
        faces.sort_unstable();
        faces.dedup();
        let faces = self.without_crumbs(faces);
        if faces.is_empty() {
            return Ok(None);
        }
        let (mesh, change) = self.separate_faces(&faces).map_err(|e| TopologyError::Invalid(e.to_string()))?;
        *self = mesh;
        Ok(Some(change))
    }
}

/// The fewest cubes a fracture may break off as a fragment: a plane's staircase through a thin
/// part of the body isolates single surface cubes, which the paper's rule would shed as crumbs
/// (docs/math/voxel-cutting.md §5).
pub const MIN_FRAGMENT_CUBES: usize = 8;

impl VoxelMesh {
    /// `faces` less those whose separation would leave a piece of fewer than
    /// [`MIN_FRAGMENT_CUBES`] cubes that was not that small before: the new faces touching such
    /// a piece are kept joined, until no such piece is left.
    fn without_crumbs(&self, mut faces: Vec<CubeFace>) -> Vec<CubeFace> {
        // Joined through faces, as the loop below judges the pieces after.
        let before = self.piece_of_cubes_through_faces();
        let mut size_before = vec![0usize; self.num_cubes()];
        for &p in &before {
            size_before[p as usize] += 1;
        }
        loop {
            let mut joined = UnionFind::new(self.num_cubes());
            for (cube, &cell) in self.cells().iter().enumerate() {
                for axis in 0..3 {
                    let mut next = cell;
                    next[axis] += 1;
                    let face = CubeFace { cell, axis };
                    if let Some(other) = self.cube_at(next)
                        && self.cut_faces().binary_search(&face).is_err()
                        && faces.binary_search(&face).is_err()
                    {
                        joined.union(cube, other);
                    }
                }
            }
            let root: Vec<usize> = (0..self.num_cubes()).map(|cube| joined.find(cube)).collect();
            let mut size = vec![0usize; self.num_cubes()];
            for &r in &root {
                size[r] += 1;
            }
            let crumb = |cube: usize| {
                let n = size[root[cube]];
                n < MIN_FRAGMENT_CUBES && n < size_before[before[cube] as usize]
            };
            let kept: Vec<CubeFace> = faces
                .iter()
                .copied()
                .filter(|f| {
                    let mut next = f.cell;
                    next[f.axis] += 1;
                    let (a, b) = (self.cube_at(f.cell), self.cube_at(next));
                    !(a.is_some_and(crumb) || b.is_some_and(crumb))
                })
                .collect();
            if kept.len() == faces.len() {
                return faces;
            }
            faces = kept;
        }
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
            return Some(self.separated_surface(input, &piece_of).0);
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
