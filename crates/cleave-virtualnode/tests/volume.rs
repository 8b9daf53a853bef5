//! Volume and mass after carving and cutting, against the analytic volume of the box; one
//! tetrahedron cut into more than a thousand regions; the paper's block cut into sticks.

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real, Vector3};
use cleave_geometry::arrangement::{Arrangement, Cover};
use cleave_virtualnode::VirtualNodeMesh;

fn material() -> Material {
    Material::new(1e5, 0.3, 1234.0).unwrap()
}

#[test]
fn carved_box_and_its_cuts_keep_the_analytic_volume_and_mass() {
    let (lo, hi) = (Point3::new(0.013, -0.37, 0.2), Point3::new(0.731, 0.05, 0.66));
    let exact = (hi - lo).product();
    let mut mesh = VirtualNodeMesh::from_box(lo, hi, 0.07, material()).unwrap();
    let check = |mesh: &VirtualNodeMesh, what: &str| {
        let v = mesh.volume();
        let m = mesh.mass().total();
        println!(
            "{what}: volume {v:.17} (exact {exact:.17}), rel {:.2e}; mass rel {:.2e}; {} duplicates, {} nodes, {} pieces",
            (v - exact).abs() / exact,
            (m - 1234.0 * exact).abs() / (1234.0 * exact),
            mesh.num_duplicates(),
            mesh.num_nodes(),
            mesh.pieces().len()
        );
        assert!((v - exact).abs() < 1e-12 * exact, "{what}: volume {v} vs {exact}");
        assert!((m - 1234.0 * exact).abs() < 1e-12 * 1234.0 * exact, "{what}: mass {m}");
        let pieces: Real = mesh.pieces().iter().map(|p| p.volume).sum();
        assert!((pieces - v).abs() < 1e-12 * exact);
    };
    check(&mesh, "carved");
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.3, 0.0, 0.0), normal: Vector3::new(1.0, 0.2, -0.1) }).unwrap();
    check(&mesh, "plane");
    assert_eq!(mesh.pieces().len(), 2);
    // A plane exactly through lattice nodes: the lattice origin is lo − h, nodes every h/2.
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.0, -0.37 + 0.07 * 2.0, 0.0), normal: Vector3::y() }).unwrap();
    check(&mesh, "axis plane");
    let soup = vec![
        [Point3::new(0.1, -0.5, 0.3), Point3::new(0.6, 0.2, 0.4), Point3::new(0.2, 0.2, 0.8)],
        [Point3::new(0.6, 0.2, 0.4), Point3::new(0.2, 0.2, 0.8), Point3::new(0.7, -0.4, 0.9)],
    ];
    mesh.cut(&CutSurface::Triangles(soup)).unwrap();
    check(&mesh, "soup");
}

#[test]
fn one_tetrahedron_cut_by_a_grid_of_planes_into_more_than_a_thousand_regions() {
    let corners = [
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
        Point3::new(0.0, 0.0, 1.0),
    ];
    let mut a = Arrangement::tetrahedron(corners);
    let n = 21;
    for axis in 0..3 {
        for i in 1..n {
            // A slightly tilted plane near x_axis = i/n, as one big triangle covering the tet.
            let c = i as Real / n as Real + 0.001 * (axis as Real + 1.0);
            let point = |u: Real, v: Real| {
                let mut p = Point3::origin();
                p[axis] = c + 0.002 * u;
                p[(axis + 1) % 3] = u;
                p[(axis + 2) % 3] = v;
                p
            };
            assert!(a.cut(&[point(-1.0, -1.0), point(4.0, -1.0), point(-1.0, 4.0)], Cover::Cut));
        }
    }
    let regions = a.regions();
    let total: Real = regions.iter().map(|r| r.1).sum();
    println!("{} regions, {} cells, volume {total:.17}", regions.len(), a.cells.len());
    assert!(regions.len() > 1000);
    assert!(regions.iter().all(|r| r.1 > 0.0));
    assert!((total - 1.0 / 6.0).abs() < 1e-12 / 6.0, "{total}");
}

fn sticks(h: Real, planes: &[Real], expect: usize) {
    let (lo, hi) = (Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 1.0, 0.5));
    let mut mesh = VirtualNodeMesh::from_box(lo, hi, h, material()).unwrap();
    let tets = mesh.num_lattice_tets();
    let before = mesh.num_duplicates();
    let start = std::time::Instant::now();
    for &c in planes {
        mesh.cut(&CutSurface::Plane { point: Point3::new(c, 0.0, 0.0), normal: Vector3::x() }).unwrap();
        mesh.cut(&CutSurface::Plane { point: Point3::new(0.0, c, 0.0), normal: Vector3::y() }).unwrap();
    }
    let pieces = mesh.pieces();
    println!(
        "h = {h}: {tets} lattice tets, {before} → {} duplicates, {} nodes, {} pieces (expected {expect}) in {:.0} ms",
        mesh.num_duplicates(),
        mesh.num_nodes(),
        pieces.len(),
        start.elapsed().as_secs_f64() * 1e3
    );
    assert_eq!(pieces.len(), expect);
    let stick = 0.5 / (expect as Real);
    for p in &pieces {
        assert!((p.volume - stick).abs() < 1e-9 * stick, "stick volume {} vs {stick}", p.volume);
    }
    assert!((mesh.volume() - 0.5).abs() < 1e-12 * 0.5);
}

#[test]
fn block_cut_into_sticks_by_32_planes_as_in_the_paper() {
    // sifakis2007 Fig. 4: 16 + 16 planes cut a block into 17 × 17 = 289 sticks.
    let planes: Vec<Real> = (1..17).map(|i| i as Real / 17.0).collect();
    sticks(0.25, &planes, 289);
}

#[test]
fn sticks_with_planes_through_lattice_nodes() {
    // h = 1/8: the lattice origin is −1/8 and nodes lie every 1/16, exactly representable, so
    // every plane x = k/16 passes exactly through lattice nodes, edges and faces.
    let planes: Vec<Real> = (1..16).map(|i| i as Real / 16.0).collect();
    sticks(0.125, &planes, 256);
}

#[test]
fn a_plane_and_a_soup_of_two_triangles_covering_it_cut_alike() {
    let (lo, hi) = (Point3::new(0.013, -0.37, 0.2), Point3::new(0.731, 0.05, 0.66));
    let mut by_plane = VirtualNodeMesh::from_box(lo, hi, 0.07, material()).unwrap();
    let mut by_soup = VirtualNodeMesh::from_box(lo, hi, 0.07, material()).unwrap();
    // The plane 2x + y − z = 0.1, and a square on it far larger than the box.
    let n = Vector3::new(2.0, 1.0, -1.0);
    let point = Point3::new(0.05, 0.0, 0.0);
    by_plane.cut(&CutSurface::Plane { point, normal: n }).unwrap();
    let on_plane = |y: Real, z: Real| Point3::new((0.1 - y + z) / 2.0, y, z);
    let q = [on_plane(-5.0, -5.0), on_plane(5.0, -5.0), on_plane(5.0, 5.0), on_plane(-5.0, 5.0)];
    by_soup.cut(&CutSurface::Triangles(vec![[q[0], q[1], q[2]], [q[0], q[2], q[3]]])).unwrap();
    let volumes = |m: &VirtualNodeMesh| {
        let mut v: Vec<Real> = m.pieces().iter().map(|p| p.volume).collect();
        v.sort_by(Real::total_cmp);
        v
    };
    let (a, b) = (volumes(&by_plane), volumes(&by_soup));
    println!("plane: {a:?}; soup: {b:?}");
    assert_eq!(a.len(), 2);
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() < 1e-12, "{x} vs {y}");
    }
}
