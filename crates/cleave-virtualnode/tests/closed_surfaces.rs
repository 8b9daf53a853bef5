//! Piece surfaces under oblique, curved and swept cuts: a torus carved at 15 mm cut by a blade
//! tilted 20° coming straight down and by oblique planes, the cuts of `scenes/torus_blades.ron`
//! (two blades, a wavy sheet, an oblique plane), and a block cut by an oblique plane and a wavy
//! soup that passes within 4e-7 m of a lattice plane. Welded by rest position at 1e-12 m, every
//! piece's surface has every edge in exactly two triangles and no sliver (no edge shorter than,
//! and no corner nearer its opposite edge than, 1e-5 of the lattice spacing), but for one cap
//! the repair cannot flip after the scene's wavy sheet (counted below).
//! With the old T-junction tolerance (1e-10 h) the carved torus alone has 14 slivers; without
//! the sliver repair the wavy soup leaves 4. Before the merged cut face kept the corner where a
//! cut crosses an edge between two source triangles, the oblique planes left 12 open edges;
//! before coverage was reconciled between the two cells on either side of a face, the torus
//! scene's cuts left 4 (a hole in a cut face on the sheet's flat part).

use cleave_core::{CutSurface, Cuttable, Material, Point3, Real, Vector3};
use cleave_geometry::{Blade, Keyframe, TriangleMesh};
use cleave_virtualnode::{VirtualNodeMesh, box_surface};
use nalgebra::UnitQuaternion;
use std::collections::HashMap;

/// (slivers, edges not in exactly two triangles) over all pieces.
fn defects(mesh: &VirtualNodeMesh, h: Real) -> (usize, usize) {
    let s = mesh.render_surface();
    let mut piece_of = vec![0usize; mesh.num_duplicates()];
    for (k, piece) in mesh.pieces().iter().enumerate() {
        for &d in &piece.elements {
            piece_of[d as usize] = k;
        }
    }
    let key = |p: &Point3<Real>| [p.x, p.y, p.z].map(|c| (c * 1e12).round() as i64);
    let mut slivers = 0;
    let mut edges: HashMap<(usize, [i64; 3], [i64; 3]), usize> = HashMap::new();
    for (t, tri) in s.triangles.iter().enumerate() {
        let p = tri.map(|i| s.positions[i as usize]);
        let lengths = [(p[1] - p[0]).norm(), (p[2] - p[1]).norm(), (p[0] - p[2]).norm()];
        let longest = lengths.iter().copied().fold(0.0, Real::max);
        let height = (p[1] - p[0]).cross(&(p[2] - p[0])).norm() / longest;
        if lengths.iter().any(|&l| l < 1e-5 * h) || height < 1e-5 * h {
            slivers += 1;
        }
        for e in 0..3 {
            let (a, b) = (key(&p[e]), key(&p[(e + 1) % 3]));
            let piece = piece_of[s.duplicates[t] as usize];
            *edges.entry(if a < b { (piece, a, b) } else { (piece, b, a) }).or_default() += 1;
        }
    }
    (slivers, edges.values().filter(|&&n| n != 2).count())
}

#[test]
fn a_torus_cut_by_a_tilted_blade_and_oblique_planes_has_closed_pieces_without_slivers() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/meshes/torus.obj")).unwrap();
    let torus = TriangleMesh::from_obj_str(&text).unwrap().transformed(|p| Point3::new(p.x, p.y, p.z + 0.045));
    let mut mesh = VirtualNodeMesh::carve(&torus, 0.015, Material::new(1e5, 0.3, 1000.0).unwrap()).unwrap();
    assert_eq!(defects(&mesh, 0.015), (0, 0), "carved");
    // The knife of scenes/torus_blades.ron, 36 steps of 1/60 s.
    let knife = vec![
        Point3::new(0.0, -0.2, 0.0),
        Point3::new(0.0, 0.2, 0.0),
        Point3::new(0.0, 0.2, 0.15),
        Point3::new(0.0, -0.2, 0.15),
    ];
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 20f64.to_radians());
    let blade = Blade::new(
        knife,
        vec![
            Keyframe { time: 0.0, translation: Vector3::new(0.01, 0.0, 0.12), rotation: tilt },
            Keyframe { time: 0.6, translation: Vector3::new(0.01, 0.0, -0.03), rotation: tilt },
        ],
    )
    .unwrap();
    for k in 0..36 {
        let (t0, t1) = (k as Real / 60.0, (k + 1) as Real / 60.0);
        let soup = if k == 0 { blade.swept(t0, t1) } else { blade.swept_after(t0, t1) };
        mesh.cut(&CutSurface::Triangles(soup)).unwrap();
    }
    assert_eq!(mesh.pieces().len(), 2);
    assert_eq!(defects(&mesh, 0.015), (0, 0), "after the tilted blade");
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.08, 0.08, 0.04), normal: Vector3::new(1.0, 1.0, 0.6) }).unwrap();
    mesh.cut(&CutSurface::Plane { point: Point3::new(-0.05, 0.02, 0.03), normal: Vector3::new(0.3, -1.0, 0.45) })
        .unwrap();
    assert!(mesh.pieces().len() >= 5, "{} pieces", mesh.pieces().len());
    assert_eq!(defects(&mesh, 0.015), (0, 0), "after two oblique planes");
}

#[test]
fn a_block_cut_by_an_oblique_plane_and_a_wavy_soup_has_closed_pieces_without_slivers() {
    let (lo, hi) = (Point3::new(0.0, 0.0, 0.0), Point3::new(0.3, 0.2, 0.2));
    let mut mesh =
        VirtualNodeMesh::carve(&box_surface(lo, hi), 0.05, Material::new(1e5, 0.3, 1000.0).unwrap()).unwrap();
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.13, 0.1, 0.1), normal: Vector3::new(1.0, 0.7, 0.4) }).unwrap();
    assert_eq!(defects(&mesh, 0.05), (0, 0), "after the oblique plane");
    // z = 0.1 + 0.02 sin(20 x) cos(15 y) on a 30 × 30 grid over [-0.05, 0.35] × [-0.05, 0.25]:
    // near x = 0 its triangles pass within 4e-7 m of the lattice plane z = 0.1.
    let n = 30;
    let at = |i: usize, j: usize| {
        let (x, y) = (-0.05 + 0.4 * i as Real / n as Real, -0.05 + 0.3 * j as Real / n as Real);
        Point3::new(x, y, 0.1 + 0.02 * (20.0 * x).sin() * (15.0 * y).cos())
    };
    let soup = (0..n)
        .flat_map(|i| {
            (0..n).flat_map(move |j| {
                [[at(i, j), at(i + 1, j), at(i + 1, j + 1)], [at(i, j), at(i + 1, j + 1), at(i, j + 1)]]
            })
        })
        .collect();
    mesh.cut(&CutSurface::Triangles(soup)).unwrap();
    assert_eq!(mesh.pieces().len(), 4);
    assert_eq!(defects(&mesh, 0.05), (0, 0), "after the wavy soup");
}

#[test]
fn the_torus_scenes_cuts_separate_every_quarter_and_leave_closed_pieces() {
    // The cuts of scenes/torus_blades.ron: the tilted blade and the turning blade (a helicoid)
    // leave four quarters; the wavy sheet z = 0.045 + 0.012 sin(2πx/0.2) cos(2πy/0.2) must
    // split each into a top and a bottom. Where the sheet's facets lie at z = 0.045 they nearly
    // coincide with strip side planes the helicoid left 3e-17 m above: the faces there were
    // left uncovered, and one quarter stayed whole (7 pieces). Where the sheet's flat part lies
    // inside a lattice tetrahedron, a face between two of its cells was covered on one side
    // only (a corner on a side plane rounded two ways): a hole of 4 open edges in a cut face.
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/meshes/torus.obj")).unwrap();
    let torus = TriangleMesh::from_obj_str(&text).unwrap().transformed(|p| Point3::new(p.x, p.y, p.z + 0.045));
    let mut mesh = VirtualNodeMesh::carve(&torus, 0.015, Material::new(5e5, 0.3, 1000.0).unwrap()).unwrap();
    let knife = |along_x: bool| -> Vec<Point3<Real>> {
        let corner = |s: Real, z: Real| if along_x { Point3::new(s, 0.0, z) } else { Point3::new(0.0, s, z) };
        vec![corner(-0.2, 0.0), corner(0.2, 0.0), corner(0.2, 0.15), corner(-0.2, 0.15)]
    };
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 20f64.to_radians());
    let tilted = Blade::new(
        knife(false),
        vec![
            Keyframe { time: 0.3, translation: Vector3::new(0.01, 0.0, 0.12), rotation: tilt },
            Keyframe { time: 0.9, translation: Vector3::new(0.01, 0.0, -0.03), rotation: tilt },
        ],
    )
    .unwrap();
    let turning = Blade::new(
        knife(true),
        vec![
            Keyframe { time: 1.1, translation: Vector3::new(0.0, 0.0, 0.12), rotation: UnitQuaternion::identity() },
            Keyframe {
                time: 1.7,
                translation: Vector3::new(0.0, 0.0, -0.03),
                rotation: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 35f64.to_radians()),
            },
        ],
    )
    .unwrap();
    // Steps of 1/60 s, as the scene runs them.
    for (blade, start, end) in [(&tilted, 0.3, 0.9), (&turning, 1.1, 1.7)] {
        let steps =
            ((start * 60.0) as usize..(end * 60.0) as usize).map(|k| (k as Real / 60.0, (k + 1) as Real / 60.0));
        for (k, (t0, t1)) in steps.enumerate() {
            let soup = if k == 0 { blade.swept(t0, t1) } else { blade.swept_after(t0, t1) };
            mesh.cut(&CutSurface::Triangles(soup)).unwrap();
        }
    }
    assert_eq!(mesh.pieces().len(), 4, "the blades leave four quarters");
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/meshes/wavy_sheet.obj")).unwrap();
    let sheet = TriangleMesh::from_obj_str(&text).unwrap();
    let soup: Vec<_> = (0..sheet.triangles.len()).filter_map(|t| sheet.triangle_points(t)).collect();
    mesh.cut(&CutSurface::Triangles(soup.clone())).unwrap();
    // Independently of the pieces: every duplicate's cells lie on one side of the sheet (its
    // piecewise-linear height under each cell's centre).
    let height = |x: Real, y: Real| -> Real {
        soup.iter()
            .find_map(|[a, b, c]| {
                let d = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
                let l1 = ((x - a.x) * (c.y - a.y) - (c.x - a.x) * (y - a.y)) / d;
                let l2 = ((b.x - a.x) * (y - a.y) - (x - a.x) * (b.y - a.y)) / d;
                (l1 >= -1e-12 && l2 >= -1e-12 && l1 + l2 <= 1.0 + 1e-12)
                    .then(|| a.z + l1 * (b.z - a.z) + l2 * (c.z - a.z))
            })
            .expect("the sheet spans the torus")
    };
    let straddling = (0..mesh.num_duplicates())
        .filter(|&d| {
            let cells = mesh.duplicate_cells(d);
            let above: Vec<bool> = cells
                .cells
                .iter()
                .map(|cell| {
                    let c = cells.cell_center(cell);
                    c.z > height(c.x, c.y)
                })
                .collect();
            above.iter().any(|&a| a) && above.iter().any(|&a| !a)
        })
        .count();
    assert_eq!(straddling, 0, "duplicates with material on both sides of the sheet");
    assert_eq!(mesh.pieces().len(), 8, "each quarter's top and bottom");
    // Closed. One sliver is left: a cap of the carved surface whose corner lies on its long edge
    // (2.6e-18 m off it, a short edge of 2.8e-5 h) and whose flip would join two vertices
    // already joined, so the repair leaves it (`SliverRepair::left`).
    let closed_but_one_cap = |mesh: &VirtualNodeMesh, stage: &str| {
        let (slivers, open) = defects(mesh, 0.015);
        assert_eq!(open, 0, "edges not in two triangles after {stage}");
        assert!(slivers <= 1, "{slivers} slivers after {stage}");
    };
    closed_but_one_cap(&mesh, "the wavy sheet");
    // The scene's last cut: an oblique plane across every piece.
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.08, 0.08, 0.04), normal: Vector3::new(1.0, 1.0, 0.6) }).unwrap();
    closed_but_one_cap(&mesh, "the oblique plane");
}
