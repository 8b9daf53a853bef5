//! Blades through carved blocks: a tilted blade coming down separates the block along the
//! plane its edge sweeps, a turning blade along the ruled surface its edge sweeps (cut area
//! against quadrature of the analytic helicoid), and a blade sliding in its own plane leaves the
//! pieces the plane through its path leaves.

use cleave_core::{CutSurface, Cuttable, Material, Point3, Real, Vector3};
use cleave_geometry::{Blade, Keyframe};
use cleave_virtualnode::{SurfaceKind, VirtualNodeMesh, box_surface};
use nalgebra::UnitQuaternion;

fn block(lo: Point3<Real>, hi: Point3<Real>, h: Real) -> VirtualNodeMesh {
    VirtualNodeMesh::carve(&box_surface(lo, hi), h, Material::new(1e5, 0.3, 1000.0).unwrap()).unwrap()
}

/// Cuts `mesh` with what `blade` covers over `steps` equal steps of [0, 1], as a scene does.
fn sweep(mesh: &mut VirtualNodeMesh, blade: &Blade, steps: usize) {
    for k in 0..steps {
        let (t0, t1) = (k as Real / steps as Real, (k + 1) as Real / steps as Real);
        let soup = if k == 0 { blade.swept(t0, t1) } else { blade.swept_after(t0, t1) };
        mesh.cut(&CutSurface::Triangles(soup)).unwrap();
    }
}

/// Rest-space cut triangles of the render surface.
fn cut_triangles(mesh: &VirtualNodeMesh) -> Vec<[Point3<Real>; 3]> {
    let surface = mesh.render_surface();
    surface
        .triangles
        .iter()
        .zip(&surface.kinds)
        .filter(|(_, k)| **k == SurfaceKind::Cut)
        .map(|(t, _)| t.map(|i| surface.positions[i as usize]))
        .collect()
}

fn area(t: &[Point3<Real>; 3]) -> Real {
    0.5 * (t[1] - t[0]).cross(&(t[2] - t[0])).norm()
}

/// A knife 0.8 wide and 0.2 tall in its frame's plane x = 0, cutting edge along y at z = 0.
fn knife() -> Vec<Point3<Real>> {
    vec![
        Point3::new(0.0, -0.4, 0.0),
        Point3::new(0.0, 0.4, 0.0),
        Point3::new(0.0, 0.4, 0.2),
        Point3::new(0.0, -0.4, 0.2),
    ]
}

fn path(from: Vector3<Real>, to: Vector3<Real>, turn: (UnitQuaternion<Real>, UnitQuaternion<Real>)) -> Vec<Keyframe> {
    vec![
        Keyframe { time: 0.0, translation: from, rotation: turn.0 },
        Keyframe { time: 1.0, translation: to, rotation: turn.1 },
    ]
}

#[test]
fn a_tilted_blade_coming_down_leaves_two_pieces_split_by_the_plane_its_edge_sweeps() {
    // Block [0, 0.3] × [0, 0.2] × [0, 0.2], cells 0.05; the knife tilted 20° about its edge,
    // edge at x = 0.137 (off the lattice), pushed from above the block to below it in 12 steps.
    // Cutting its face at every pose would leave a slice per step; its edge sweeps x = 0.137.
    let (lo, hi) = (Point3::new(0.0, 0.0, 0.0), Point3::new(0.3, 0.2, 0.2));
    let mut mesh = block(lo, hi, 0.05);
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 20f64.to_radians());
    let blade = Blade::new(knife(), path(Vector3::new(0.137, 0.1, 0.35), Vector3::new(0.137, 0.1, -0.1), (tilt, tilt)))
        .unwrap();
    sweep(&mut mesh, &blade, 12);
    let pieces = mesh.pieces();
    assert_eq!(pieces.len(), 2, "volumes {:?}", pieces.iter().map(|p| p.volume).collect::<Vec<_>>());
    let mut volumes: Vec<Real> = pieces.iter().map(|p| p.volume).collect();
    volumes.sort_by(Real::total_cmp);
    for (v, exact) in volumes.iter().zip([0.137 * 0.04, 0.163 * 0.04]) {
        assert!((v - exact).abs() < 1e-12 * exact, "piece volume {v} against {exact}");
    }
    let cut = cut_triangles(&mesh);
    let cut_area: Real = cut.iter().map(area).sum();
    assert!((cut_area - 2.0 * 0.04).abs() < 1e-12, "both sheets of the cut: {cut_area}");
    for p in cut.iter().flatten() {
        assert!((p.x - 0.137).abs() < 1e-12, "cut vertex {p} off the swept plane x = 0.137");
    }
}

#[test]
fn a_turning_blade_cuts_the_helicoid_its_edge_sweeps() {
    // Block [-0.15, 0.15]² × [0, 0.1], cells 0.04; the knife's edge (0.8 long, through the
    // turning axis z) turns from -35° to 35° about z while it descends from z = 0.15 to -0.05:
    // inside the block it sweeps the helicoid (s cos φ, s sin φ, z(φ)), φ ∈ [-17.5°, 17.5°],
    // c = 0.2 / θ, limited to the square. The cut separates two pieces; each sheet of the cut
    // has that helicoid's area, here from quadrature: per φ the ruling crosses the square for
    // |s| ≤ w / cos φ, and ∫₀^L √(s² + c²) ds = (L √(L² + c²) + c² asinh(L / c)) / 2.
    let (w, drop, theta) = (0.15, 0.2, 70f64.to_radians());
    let mut mesh = block(Point3::new(-w, -w, 0.0), Point3::new(w, w, 0.1), 0.04);
    let turn = |deg: Real| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), deg.to_radians());
    // The knife's plane x = 0 turned by -90° + φ: its edge along (cos φ, sin φ).
    let along_x = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -90f64.to_radians());
    let blade = Blade::new(
        knife(),
        path(
            Vector3::new(0.0, 0.0, 0.15),
            Vector3::new(0.0, 0.0, 0.15 - drop),
            (turn(-35.0) * along_x, turn(35.0) * along_x),
        ),
    )
    .unwrap();
    sweep(&mut mesh, &blade, 20);
    assert_eq!(mesh.pieces().len(), 2);
    let c = drop / theta;
    let strip = |length: Real| length * (length * length + c * c).sqrt() + c * c * (length / c).asinh();
    let (a, b, n) = (-17.5f64.to_radians(), 17.5f64.to_radians(), 400);
    let simpson: Real = (0..=n)
        .map(|k| {
            let phi = a + (b - a) * k as Real / n as Real;
            let weight = if k == 0 || k == n {
                1.0
            } else if k % 2 == 1 {
                4.0
            } else {
                2.0
            };
            weight * strip(w / phi.cos())
        })
        .sum::<Real>()
        * (b - a)
        / (3.0 * n as Real);
    let sheet: Real = cut_triangles(&mesh).iter().map(area).sum::<Real>() / 2.0;
    let relative = (sheet - simpson).abs() / simpson;
    assert!(relative < 0.01, "cut sheet {sheet} against the helicoid's {simpson}: {relative:e}");
}

#[test]
fn a_blade_sliding_in_its_own_plane_leaves_the_pieces_of_that_plane() {
    // The knife upright in the plane x = 0.137, pushed down through the block in 9 steps: the
    // strips its lower edge sweeps add up to the section, so the pieces are those of the plane
    // x = 0.137, volume for volume.
    let (lo, hi) = (Point3::new(0.0, 0.0, 0.0), Point3::new(0.3, 0.2, 0.2));
    let mut swept = block(lo, hi, 0.05);
    let upright = UnitQuaternion::identity();
    let blade =
        Blade::new(knife(), path(Vector3::new(0.137, 0.1, 0.3), Vector3::new(0.137, 0.1, -0.05), (upright, upright)))
            .unwrap();
    sweep(&mut swept, &blade, 9);
    let mut planar = block(lo, hi, 0.05);
    planar.cut(&CutSurface::Plane { point: Point3::new(0.137, 0.0, 0.0), normal: Vector3::x() }).unwrap();
    let volumes = |mesh: &VirtualNodeMesh| {
        let mut v: Vec<Real> = mesh.pieces().iter().map(|p| p.volume).collect();
        v.sort_by(Real::total_cmp);
        v
    };
    let (a, b) = (volumes(&swept), volumes(&planar));
    assert_eq!(a.len(), 2);
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() < 1e-12 * y, "{a:?} against {b:?}");
    }
}
