//! The render surface: every piece's surface is closed by its own vertex indices (no welding
//! by position), encloses the piece's volume, and its original part has the object's area.

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real, Vector3};
use cleave_geometry::{Blade, Keyframe};
use cleave_virtualnode::{SurfaceKind, VirtualNodeMesh};
use nalgebra::UnitQuaternion;
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
        for &d in &p.elements {
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

/// The box's surface with every face split into a grid of `n × n` squares, two triangles each.
fn fine_box(lo: Point3<Real>, hi: Point3<Real>, n: usize) -> cleave_geometry::TriangleMesh {
    let coarse = cleave_virtualnode::box_surface(lo, hi);
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    // Each coarse face is two triangles (a, b, c) and (a, c, d) over one quad: rebuild the quad.
    for pair in coarse.triangles.chunks_exact(2) {
        let [a, b, c] = pair[0].map(|v| coarse.vertices[v as usize]);
        let d = coarse.vertices[pair[1][2] as usize];
        let at = |i: usize, j: usize| {
            let (u, v) = (i as Real / n as Real, j as Real / n as Real);
            a + (b - a) * u + (d - a) * v + (c - b - (d - a)) * (u * v)
        };
        let base = vertices.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                vertices.push(at(i, j));
            }
        }
        let id = |i: usize, j: usize| base + (j * (n + 1) + i) as u32;
        for j in 0..n {
            for i in 0..n {
                triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
    }
    // Faces share their edges' points: weld them (rounded to 1e-12 m).
    let mut index: HashMap<[i64; 3], u32> = HashMap::new();
    let mut welded = Vec::new();
    let map: Vec<u32> = vertices
        .iter()
        .map(|p| {
            let key = [p.x, p.y, p.z].map(|c| (c * 1e12).round() as i64);
            *index.entry(key).or_insert_with(|| {
                welded.push(*p);
                welded.len() as u32 - 1
            })
        })
        .collect();
    let triangles = triangles.into_iter().map(|t| t.map(|v| map[v as usize])).collect();
    cleave_geometry::TriangleMesh::new(welded, triangles)
}

#[test]
fn triangles_no_cut_touched_are_drawn_whole() {
    // A box whose faces are triangles smaller than the lattice: carved and uncut, its surface
    // is exactly its own triangles, not their pieces clipped to each lattice tetrahedron. (The
    // two-triangle faces of `box_surface` are longer than the lattice and always clipped.)
    let (lo, hi) = (Point3::new(0.013, -0.37, 0.2), Point3::new(0.733, 0.05, 0.62));
    let source = fine_box(lo, hi, 12);
    let material = Material::new(1e5, 0.3, 1000.0).unwrap();
    let mut mesh = VirtualNodeMesh::carve(&source, 0.09, material).unwrap();
    let s = mesh.render_surface();
    assert!(source.validate_closed().is_ok());
    assert_eq!(s.triangles.len(), source.triangles.len());
    // A cut through one corner clips only the triangles whose tetrahedra it touches. The far
    // faces (x = hi.x, y = hi.y) stay whole: points where clipped neighbours meet their edges
    // are inserted there (no T-junction), but no vertex lies inside them apart from the grid's
    // own (a clipped face would have one per tetrahedron face crossed).
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.1, -0.3, 0.0), normal: Vector3::new(1.0, 1.0, 0.0) }).unwrap();
    let s = mesh.render_surface();
    let interior_vertices = |axis: usize, value: Real| {
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
    let grid_interior = 11 * 11;
    let (far_x, far_y, cut_side) = (interior_vertices(0, hi.x), interior_vertices(1, hi.y), interior_vertices(2, hi.z));
    println!(
        "after the corner cut: {} triangles; interior vertices: x = hi face {far_x}, y = hi face {far_y} (grid {grid_interior}), z = hi face {cut_side}",
        s.triangles.len()
    );
    assert!(far_x == grid_interior && far_y == grid_interior);
    assert!(cut_side > grid_interior + 10, "the face the cut crosses is clipped");
}

#[test]
fn the_render_surface_after_a_cut_is_the_one_built_from_scratch() {
    // A blade slides down through a carved box in strips (the render after each strip keeps
    // what the strip cannot have reached), then a plane splits a piece (nothing is kept) and a
    // tilted blade cuts part way. Every render equals the one made from nothing, bit for bit.
    let (lo, hi) = (Point3::new(0.013, -0.37, 0.2), Point3::new(0.733, 0.05, 0.62));
    let material = Material::new(1e5, 0.3, 1000.0).unwrap();
    let mut mesh = VirtualNodeMesh::carve(&fine_box(lo, hi, 12), 0.09, material).unwrap();
    let same = |mesh: &VirtualNodeMesh| {
        let (a, b) = (mesh.render_surface(), mesh.render_surface_from_scratch());
        assert_eq!(a.positions, b.positions);
        assert_eq!(a.triangles, b.triangles);
        assert_eq!(a.kinds, b.kinds);
        assert_eq!(a.duplicates, b.duplicates);
        assert_eq!(a.embedding.len(), b.embedding.len());
        for row in 0..a.embedding.len() {
            assert_eq!(a.embedding.row(row), b.embedding.row(row));
        }
        a.triangles.len()
    };
    same(&mesh);
    let blade = |x: Real, tilt: Real| {
        let polygon = vec![
            Point3::new(x, -0.5, 0.0),
            Point3::new(x, 0.2, 0.0),
            Point3::new(x + tilt, 0.2, 0.1),
            Point3::new(x + tilt, -0.5, 0.1),
        ];
        let keys = vec![
            Keyframe { time: 0.0, translation: Vector3::new(0.0, 0.0, 0.7), rotation: UnitQuaternion::identity() },
            Keyframe { time: 1.0, translation: Vector3::new(0.0, 0.0, 0.1), rotation: UnitQuaternion::identity() },
        ];
        Blade::new(polygon, keys).unwrap()
    };
    let straight = blade(0.31, 0.0);
    let mut reused = 0;
    for k in 0..12 {
        let (t0, t1) = (k as Real / 12.0, (k + 1) as Real / 12.0);
        let soup = if k == 0 { straight.swept(t0, t1) } else { straight.swept_after(t0, t1) };
        mesh.cut(&CutSurface::Triangles(soup)).unwrap();
        let triangles = same(&mesh);
        reused += mesh.render_polygons_reused();
        println!("strip {k}: {triangles} triangles, {} polygons kept", mesh.render_polygons_reused());
    }
    assert!(reused > 0, "the strips must leave polygons to keep");
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.0, 0.0, 0.41), normal: Vector3::new(0.1, 0.0, 1.0) }).unwrap();
    same(&mesh);
    let tilted = blade(0.55, 0.04);
    for k in 0..5 {
        let (t0, t1) = (k as Real / 12.0, (k + 1) as Real / 12.0);
        let soup = if k == 0 { tilted.swept(t0, t1) } else { tilted.swept_after(t0, t1) };
        mesh.cut(&CutSurface::Triangles(soup)).unwrap();
        same(&mesh);
    }
}
