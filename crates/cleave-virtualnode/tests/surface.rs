//! The render surface: every piece's surface is closed by its own vertex indices (no welding
//! by position), encloses the piece's volume, and its original part has the object's area.

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real, Vector3};
use cleave_virtualnode::{SurfaceKind, VirtualNodeMesh};
use std::collections::HashMap;

struct PieceReport {
    /// Directed edges whose reverse occurs a different number of times (boundary edges).
    unbalanced: usize,
    /// Undirected edges not on exactly two triangles.
    non_manifold: usize,
    /// Of those, edges on four triangles, cut triangles among them (the two coinciding sheets
    /// of a cut that ends inside the material, also where they meet the outer surface).
    crack: usize,
    volume_error: Real,
}

fn check_pieces(mesh: &VirtualNodeMesh) -> Vec<PieceReport> {
    let surface = mesh.render_surface();
    let pieces = mesh.pieces();
    let mut piece_of_dup = vec![0; mesh.num_duplicates()];
    for (k, p) in pieces.iter().enumerate() {
        for &d in &p.duplicates {
            piece_of_dup[d as usize] = k;
        }
    }
    // Edges are matched by the surface's own vertex indices, with no welding by position: that
    // is what a reader of the deformed surface sees, where two vertices at one rest position
    // move apart unless they are one material point.
    let welded: Vec<usize> = (0..surface.positions.len()).collect();
    let mut reports = Vec::new();
    for (k, piece) in pieces.iter().enumerate() {
        let mut directed: HashMap<(usize, usize), i64> = HashMap::new();
        let mut on_cut: HashMap<(usize, usize), bool> = HashMap::new();
        let mut volume = 0.0;
        for (t, tri) in surface.triangles.iter().enumerate() {
            if piece_of_dup[surface.duplicates[t] as usize] != k {
                continue;
            }
            let v = tri.map(|i| welded[i as usize]);
            for e in 0..3 {
                let (a, b) = (v[e], v[(e + 1) % 3]);
                if a != b {
                    *directed.entry((a, b)).or_default() += 1;
                    *on_cut.entry((a.min(b), a.max(b))).or_default() |= surface.kinds[t] == SurfaceKind::Cut;
                }
            }
            let p = tri.map(|i| surface.positions[i as usize].coords);
            volume += p[0].dot(&p[1].cross(&p[2])) / 6.0;
        }
        let unbalanced =
            directed.iter().filter(|(e, n)| directed.get(&(e.1, e.0)).copied().unwrap_or(0) != **n).count();
        let count = |e: &(usize, usize)| {
            directed.get(e).copied().unwrap_or(0) + directed.get(&(e.1, e.0)).copied().unwrap_or(0)
        };
        let undirected: Vec<(usize, usize)> = on_cut.keys().copied().collect();
        let non_manifold = undirected.iter().filter(|e| count(e) != 2).count();
        let crack = undirected.iter().filter(|e| count(e) == 4 && on_cut[e]).count();
        reports.push(PieceReport {
            unbalanced,
            non_manifold,
            crack,
            volume_error: (volume - piece.volume).abs() / piece.volume,
        });
    }
    reports
}

fn block() -> VirtualNodeMesh {
    let material = Material::new(1e5, 0.3, 1000.0).unwrap();
    VirtualNodeMesh::from_box(Point3::new(0.013, -0.37, 0.2), Point3::new(0.731, 0.05, 0.66), 0.09, material).unwrap()
}

#[test]
fn carved_and_cut_pieces_have_closed_surfaces_enclosing_their_volume() {
    let mut mesh = block();
    let surface = mesh.render_surface();
    let area = |kind: SurfaceKind, s: &cleave_virtualnode::RenderSurface| -> Real {
        s.triangles
            .iter()
            .zip(&s.kinds)
            .filter(|(_, k)| **k == kind)
            .map(|(t, _)| {
                let p = t.map(|i| s.positions[i as usize]);
                0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm()
            })
            .sum()
    };
    let (x, y, z) = (0.718, 0.42, 0.46);
    let box_area = 2.0 * (x * y + y * z + z * x);
    let original = area(SurfaceKind::Original, &surface);
    println!("carved: {} triangles, original area {original:.15} vs {box_area:.15}", surface.triangles.len());
    assert!((original - box_area).abs() < 1e-12 * box_area);
    // Embedding rows reproduce the rest positions.
    let rest = mesh.rest_dofs();
    let worst = (0..surface.positions.len())
        .map(|i| (surface.embedding.point(rest, i) - surface.positions[i]).norm())
        .fold(0.0, Real::max);
    assert!(worst < 1e-14, "{worst}");

    let cuts = [
        (
            "slanted plane",
            CutSurface::Plane { point: Point3::new(0.3, 0.0, 0.0), normal: Vector3::new(1.0, 0.2, -0.1) },
            true,
        ),
        // Exactly through lattice nodes (origin lo − h, nodes every h/2).
        (
            "plane through nodes",
            CutSurface::Plane { point: Point3::new(0.0, 0.0, 0.2 - 0.09 + 0.045 * 7.0), normal: Vector3::z() },
            true,
        ),
        (
            "partial soup",
            CutSurface::Triangles(vec![
                [Point3::new(0.5, -0.5, 0.1), Point3::new(0.6, 0.2, 0.3), Point3::new(0.55, -0.5, 0.5)],
                [Point3::new(0.6, 0.2, 0.3), Point3::new(0.55, -0.5, 0.5), Point3::new(0.62, 0.1, 0.55)],
            ]),
            false,
        ),
    ];
    for (name, cut, separating) in &cuts {
        mesh.cut(cut).unwrap();
        let reports = check_pieces(&mesh);
        let unbalanced: usize = reports.iter().map(|r| r.unbalanced).sum();
        let non_manifold: usize = reports.iter().map(|r| r.non_manifold).sum();
        let crack: usize = reports.iter().map(|r| r.crack).sum();
        let volume_error = reports.iter().map(|r| r.volume_error).fold(0.0, Real::max);
        println!(
            "{name}: {} pieces, {unbalanced} unbalanced edges, {non_manifold} edges not on exactly two triangles ({crack} of them on the two sheets of an unfinished cut), worst enclosed-volume error {volume_error:.2e}",
            reports.len()
        );
        assert_eq!(unbalanced, 0, "{name}");
        if *separating {
            assert_eq!(non_manifold, 0, "{name}");
        } else {
            assert!(crack > 0, "{name}: the cut must end inside the material");
            assert_eq!(non_manifold, crack, "{name}: only the two sheets of the unfinished cut may share edges");
        }
        assert!(volume_error < 1e-11, "{name}: {volume_error}");
    }
    let s = mesh.render_surface();
    let cut_area = area(SurfaceKind::Cut, &s);
    println!("cut area (both sides) {cut_area:.6}");
}

#[test]
fn cut_area_of_an_axis_plane_is_twice_the_cross_section() {
    let mut mesh = block();
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.0, 0.0, 0.2 - 0.09 + 0.045 * 7.0), normal: Vector3::z() })
        .unwrap();
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.4, 0.0, 0.0), normal: Vector3::x() }).unwrap();
    let s = mesh.render_surface();
    let mut area = [0.0; 2];
    for (t, kind) in s.triangles.iter().zip(&s.kinds) {
        let p = t.map(|i| s.positions[i as usize]);
        area[(*kind == SurfaceKind::Cut) as usize] += 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
    }
    let (x, y, z) = (0.718, 0.42, 0.46);
    let cut = 2.0 * (x * y + y * z);
    println!("original {:.15} vs {:.15}, cut {:.15} vs {cut:.15}", area[0], 2.0 * (x * y + y * z + z * x), area[1]);
    assert_eq!(mesh.pieces().len(), 4);
    assert!((area[1] - cut).abs() < 1e-12 * cut);
    assert!((area[0] - 2.0 * (x * y + y * z + z * x)).abs() < 1e-12);
}

#[test]
fn triangles_no_cut_touched_are_drawn_whole() {
    // The carved box's surface is its 12 triangles as they are (box_surface has 12), not their
    // pieces clipped to each lattice tetrahedron.
    let mut mesh = block();
    let s = mesh.render_surface();
    assert_eq!(s.triangles.len(), 12);
    // A cut through one corner clips only the triangles whose tetrahedra it touches. The far
    // faces (x = 0.731, y = 0.05) stay whole: points where the clipped neighbours' pieces meet
    // their edges are inserted there (no T-junction), but no vertex lies inside them apart from
    // the centre each fanned triangle gets (a clipped face would have one per tet face crossed).
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.1, -0.3, 0.0), normal: Vector3::new(1.0, 1.0, 0.0) }).unwrap();
    let s = mesh.render_surface();
    let interior_vertices = |axis: usize, value: Real| {
        let (lo, hi) = ([0.013, -0.37, 0.2], [0.731, 0.05, 0.66]);
        let mut inside: Vec<u32> = s
            .triangles
            .iter()
            .filter(|t| t.iter().all(|&v| (s.positions[v as usize][axis] - value).abs() < 1e-12))
            .flatten()
            .copied()
            .filter(|&v| {
                let p = s.positions[v as usize];
                (0..3).filter(|&a| a != axis).all(|a| p[a] > lo[a] + 1e-9 && p[a] < hi[a] - 1e-9)
            })
            .collect();
        inside.sort_unstable();
        inside.dedup();
        inside.len()
    };
    let (far_x, far_y, cut_side) =
        (interior_vertices(0, 0.731), interior_vertices(1, 0.05), interior_vertices(2, 0.66));
    println!(
        "after the corner cut: {} triangles; interior vertices: x = 0.731 face {far_x}, y = 0.05 face {far_y}, z = 0.66 face {cut_side}",
        s.triangles.len()
    );
    assert!(far_x <= 2 && far_y <= 2);
    assert!(cut_side > 10, "the face the cut crosses is clipped");
}
