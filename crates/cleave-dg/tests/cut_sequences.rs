//! Random cut sequences on DG bodies (docs/math/dg.md §13): a turned and moved grid of cubes and
//! the hexahedrally sliced bunny (non-convex cells), each cut by eight random planes and
//! triangles (random points and normals inside the body's box, triangles ending inside it); after
//! every cut no panic and no refusal, every element at least `SLIVER` (0.05) of the volume of the
//! element it came from (slivers merged) unless it is a piece by itself, volume kept to 1e-12,
//! and every piece's render surface closed (each edge walked as often each way, the piece's
//! volume enclosed to 1e-12).

use cleave_core::{CutSurface, Cuttable, Discretization, FrameRemap, Material, Point3, Real, Vector3};
use cleave_dg::{DgMesh, DgOptions, Flux};
use cleave_geometry::{PolyhedralMesh, TriangleMesh, hex_slice};
use cleave_testkit::Lcg;
use nalgebra::{Rotation3, Unit};
use std::collections::HashMap;

/// The merge threshold of `cleave-dg` (a fraction of the parent's volume).
const SLIVER: Real = 0.05;

fn grid() -> DgMesh {
    let turn = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.4, -0.3, 0.85)), 0.7);
    let grid = PolyhedralMesh::grid(Point3::origin(), 0.1, [4, 3, 3]);
    let mesh = PolyhedralMesh {
        vertices: grid.vertices.iter().map(|p| turn * p + Vector3::new(0.5, -1.0, 2.0)).collect(),
        ..grid
    };
    DgMesh::new(mesh, Material::new(1e5, 0.3, 1000.0).unwrap(), DgOptions::new(1, Flux::InteriorPenalty), None).unwrap()
}

fn sliced_bunny() -> DgMesh {
    let text = include_str!("../../../scenes/meshes/bunny.obj");
    let surface =
        TriangleMesh::from_obj_str(text).unwrap().transformed(|p| Point3::new(0.02 * p.x, -0.02 * p.z, 0.02 * p.y));
    let slicing = hex_slice(&surface, 0.05).unwrap();
    DgMesh::new(slicing.mesh, Material::new(2e5, 0.3, 1000.0).unwrap(), DgOptions::new(1, Flux::InteriorPenalty), None)
        .unwrap()
}

fn bounds(dg: &DgMesh) -> (Point3<Real>, Point3<Real>) {
    let vertices = &dg.polyhedral_mesh().vertices;
    vertices.iter().fold((vertices[0], vertices[0]), |(lo, hi), p| (lo.inf(p), hi.sup(p)))
}

fn random_surface(random: &mut Lcg, lo: &Point3<Real>, hi: &Point3<Real>, k: usize) -> CutSurface {
    let mut inside =
        || Point3::from(lo.coords + (hi - lo).component_mul(&Vector3::from_fn(|_, _| 0.5 + 0.45 * random.next())));
    if k.is_multiple_of(2) {
        let point = inside();
        let normal = Vector3::new(random.next(), random.next(), random.next());
        CutSurface::Plane { point, normal: if normal.norm() < 1e-3 { Vector3::x() } else { normal } }
    } else {
        // A triangle reaching past the box on one side and ending inside it.
        let (a, b) = (inside(), inside());
        let far = a + (a - b) * 3.0 + (hi - lo) * 0.5;
        CutSurface::Triangles(vec![[a, b, far]])
    }
}

fn check_surfaces_closed(dg: &DgMesh, context: &str) {
    let pieces = dg.pieces();
    // Rounding of the divergence sum grows with the body, not with a small piece.
    let body: Real = pieces.iter().map(|p| p.volume).sum();
    let Some(surface) = dg.surface() else { return };
    for (index, piece) in pieces.iter().enumerate() {
        // Closed and oriented: every edge walked as often one way as the other. An edge where a
        // crack whose front ends at its two vertices meets the boundary is walked twice each
        // way (the crack's mouth: two boundary faces and two crack faces; docs/math/dg.md §13.5).
        let mut walked: HashMap<(u32, u32), i32> = HashMap::new();
        let mut enclosed = 0.0;
        for (_, tri) in surface.triangles.iter().enumerate().filter(|(t, _)| surface.piece[*t] as usize == index) {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                *walked.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
            let p = tri.map(|v| surface.rest_vertices[v as usize].coords);
            enclosed += p[0].dot(&p[1].cross(&p[2])) / 6.0;
        }
        let open = walked.iter().filter(|e| *e.1 != 0).count();
        assert!(open == 0, "{context}: piece {index} is not closed: {open} edges walked more one way");
        assert!(
            (enclosed - piece.volume).abs() < 1e-12 * body,
            "{context}: piece {index} encloses {enclosed}, holds {}",
            piece.volume
        );
    }
}

fn run_sequences(make: fn() -> DgMesh, seeds: std::ops::Range<u64>, label: &str) {
    let (mut merged, mut cuts) = (0, 0);
    for seed in seeds {
        let mut dg = make();
        let mut random = Lcg::new(seed);
        let (lo, hi) = bounds(&dg);
        let volume: Real = dg.pieces().iter().map(|p| p.volume).sum();
        for k in 0..8 {
            let context = format!("{label} seed {seed} cut {k}");
            let before: Vec<Real> = (0..dg.num_frames()).map(|e| dg.element_volume(e)).collect();
            let pieces_before = dg.pieces().len();
            let surface = random_surface(&mut random, &lo, &hi, k);
            let change = dg.cut(&surface).unwrap_or_else(|e| panic!("{context}: {e}"));
            cuts += 1;
            merged += dg.last_cut_slivers().0;
            let parents: Vec<u32> = match &change.frames {
                FrameRemap::Gather(parents) => parents.clone(),
                _ => (0..dg.num_frames() as u32).collect(),
            };
            let pieces = dg.pieces();
            // Merging joins no pieces a cut made: a cut never lowers the count.
            assert!(pieces.len() >= pieces_before, "{context}: {} pieces after {pieces_before}", pieces.len());
            let alone: Vec<bool> = {
                let mut alone = vec![false; dg.num_frames()];
                for piece in pieces.iter().filter(|p| p.elements.len() == 1) {
                    alone[piece.elements[0] as usize] = true;
                }
                alone
            };
            for e in 0..dg.num_frames() {
                let (v, parent) = (dg.element_volume(e), before[parents[e] as usize]);
                assert!(
                    alone[e] || v >= SLIVER * parent,
                    "{context}: element {e} holds {v:.3e} of its parent's {parent:.3e}; slivers {:?}",
                    dg.last_cut_slivers()
                );
            }
            let now: Real = pieces.iter().map(|p| p.volume).sum();
            assert!((now - volume).abs() < 1e-12 * volume, "{context}: volume {now} vs {volume}");
            check_surfaces_closed(&dg, &context);
        }
    }
    println!("{label}: {cuts} cuts, {merged} slivers merged");
    assert!(merged > 0, "{label}: random cuts made no sliver: the check above is untested");
}

#[test]
fn random_cuts_of_a_turned_grid_leave_no_sliver_and_closed_pieces() {
    run_sequences(grid, 0..6, "grid");
}

#[test]
fn random_cuts_of_the_sliced_bunny_leave_no_sliver_and_closed_pieces() {
    run_sequences(sliced_bunny, 0..3, "bunny");
}
