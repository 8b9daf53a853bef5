//! Cutting the voxel mesh (mueller2004 §2.3): which cube faces a cut separates (the dual edges
//! it crosses, against counts made by hand), the shared cut contract on a box placed by a
//! lattice translation and a quarter turn, the conformance suite on a cut body, and a plane's
//! pieces against their cube counts.

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real, Vector3};
use cleave_testkit::compare::Problem;
use cleave_testkit::cut_conformance::{CutBody, CutSubject, Transfer, contract_cuts, cut_conformance};
use cleave_testkit::problems::{cantilever, crack};
use cleave_testkit::{assert_all_pass, conformance_suite};
use cleave_voxel::VoxelMesh;
use nalgebra::Isometry3;

fn material() -> Material {
    Material::new(3e5, 0.35, 1100.0).unwrap()
}

/// The box of `dims` cubes of edge `h` with minimum corner `origin`, moved by `motion` (which
/// must map the lattice to itself: lattice translations and quarter turns).
fn moved_box(origin: Point3<Real>, h: Real, dims: [usize; 3], motion: &Isometry3<Real>) -> VoxelMesh {
    let new_origin = motion * origin;
    let mut lo = [i32::MAX; 3];
    let mut cells = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let centre = origin + Vector3::new(i as Real + 0.5, j as Real + 0.5, k as Real + 0.5) * h;
                let moved = motion * centre - new_origin;
                let cell: [i32; 3] = std::array::from_fn(|a| (moved[a] / h).floor() as i32);
                for a in 0..3 {
                    lo[a] = lo[a].min(cell[a]);
                }
                cells.push(cell);
            }
        }
    }
    // Cells from 0 up, the origin moved to match.
    let cells: Vec<[i32; 3]> = cells.iter().map(|c| std::array::from_fn(|a| c[a] - lo[a])).collect();
    let shifted = new_origin + Vector3::new(lo[0] as Real, lo[1] as Real, lo[2] as Real) * h;
    VoxelMesh::new(material(), shifted, h, &cells).unwrap()
}

fn block() -> VoxelMesh {
    moved_box(Point3::new(0.03, -0.21, 0.11), 0.1, [8, 4, 4], &Isometry3::identity())
}

#[test]
fn the_crack_separates_the_faces_whose_dual_edges_it_crosses() {
    for n in [2usize, 4] {
        let grid = Problem::CutCantilever.grid(n);
        let mesh = VoxelMesh::from_box(cantilever::material(0.3), grid.origin, grid.h, grid.dims).unwrap();
        let faces = mesh.crossed_faces(&crack::cantilever(grid.h));
        // n cubes across the width, n/2 above z = 0.5, all with their +x face on x = 2.
        assert_eq!(faces.len(), n * n / 2, "n = {n}");
        assert!(faces.iter().all(|f| f.axis == 0 && f.cell[0] == 2 * n as i32 - 1 && f.cell[2] >= n as i32 / 2));
        // A crack 1e-6 h off the node plane crosses the same dual edges.
        let off = crack::half_plane(&Point3::origin(), &Point3::new(4.0, 1.0, 1.0), 2.0 + 1e-6 * grid.h, 0.5, grid.h);
        assert_eq!(mesh.crossed_faces(&off), faces, "n = {n}");
    }
    // n = 3: the front z = 0.5 runs through the centres of a row of faces, whose dual edges
    // touch the crack's edge: the closed crack takes them (2 of 3 rows, 3 faces each).
    let grid = Problem::CutCantilever.grid(3);
    let mesh = VoxelMesh::from_box(cantilever::material(0.3), grid.origin, grid.h, grid.dims).unwrap();
    assert_eq!(mesh.crossed_faces(&crack::cantilever(grid.h)).len(), 6);
}

#[test]
fn an_oblique_plane_splits_a_box_by_its_cube_centres() {
    let mut mesh = block();
    let point = Point3::new(0.4, 0.0, 0.0);
    let normal = Vector3::new(1.0, 0.3, 0.1);
    let nodes = mesh.num_nodes();
    let change = mesh.cut(&CutSurface::Plane { point, normal }).unwrap();
    assert_eq!(change.epoch, 1);
    let pieces = mesh.pieces();
    assert_eq!(pieces.len(), 2);
    // Each piece is the cubes whose centre lies on its side (counted here directly).
    let h = mesh.cell_size();
    let below = mesh
        .cells()
        .iter()
        .filter(|c| {
            let centre = mesh.origin() + Vector3::new(c[0] as Real + 0.5, c[1] as Real + 0.5, c[2] as Real + 0.5) * h;
            normal.dot(&(centre - point)) < 0.0
        })
        .count();
    let mut counts: Vec<usize> = pieces.iter().map(|p| p.elements.len()).collect();
    counts.sort_unstable();
    assert_eq!(counts, vec![below.min(128 - below), below.max(128 - below)]);
    let volume: Real = pieces.iter().map(|p| p.volume).sum();
    assert!((volume - 128.0 * h.powi(3)).abs() < 1e-12 * volume);
    println!("{nodes} nodes -> {}, pieces of {counts:?} cubes", mesh.num_nodes());
}

#[test]
fn cut_block_passes_the_conformance_suite() {
    let mut mesh = block();
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.4, 0.0, 0.0), normal: Vector3::new(1.0, 0.3, 0.1) }).unwrap();
    // A partial cut: a slanted triangle that ends inside the material.
    let tri = [Point3::new(0.6, -0.3, 0.2), Point3::new(0.7, 0.3, 0.35), Point3::new(0.65, -0.3, 0.6)];
    mesh.cut(&CutSurface::Triangles(vec![tri])).unwrap();
    assert_eq!(mesh.pieces().len(), 2);
    assert_all_pass(&conformance_suite(&mesh));
}

#[test]
fn cuts_keep_the_cut_contract() {
    let make = |motion: &Isometry3<Real>| -> Box<dyn CutBody> {
        Box::new(moved_box(Point3::new(0.03, -0.21, 0.11), 0.1, [8, 4, 4], motion))
    };
    let subject = CutSubject {
        make: &make,
        cuts: contract_cuts(0.31),
        // A lattice translation and a quarter turn about z: voxels are invariant under these only.
        placement: Isometry3::new(Vector3::new(0.3, -1.2, 2.5), Vector3::z() * std::f64::consts::FRAC_PI_2),
        transfer: Transfer::Exact,
    };
    assert_all_pass(&cut_conformance(&subject));
}
