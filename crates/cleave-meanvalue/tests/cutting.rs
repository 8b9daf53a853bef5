//! Cutting the mean value mesh (wicke2007 §5): the shared cut contract on a box of cuboids moved
//! off the axes, the conformance suite on a cut body, and the counts of the paper's Fig. 9 block.

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real, Vector3};
use cleave_meanvalue::{ConvexPolyhedron, MeanValueMesh, QUALITY_FLOOR, quality};
use cleave_testkit::cut_conformance::{CutBody, CutSubject, Transfer, contract_cuts, cut_conformance};
use cleave_testkit::{assert_all_pass, conformance_suite};
use nalgebra::Isometry3;

fn material() -> Material {
    Material::new(3e5, 0.35, 1100.0).unwrap()
}

/// The box of `dims` cuboids of edge `h` at `origin`, moved by `motion`.
fn moved_box(origin: Point3<Real>, h: Real, dims: [usize; 3], motion: &Isometry3<Real>) -> MeanValueMesh {
    let mesh = MeanValueMesh::from_box(material(), origin, h, dims).unwrap();
    let rest: Vec<Point3<Real>> =
        mesh.rest_dofs().chunks_exact(3).map(|p| motion * Point3::new(p[0], p[1], p[2])).collect();
    let elements = (0..mesh.num_elements())
        .map(|e| {
            let (shape, nodes) = mesh.element(e);
            let vertices = shape.vertices().iter().map(|p| motion * p).collect();
            (ConvexPolyhedron::new(vertices, shape.faces().to_vec()).unwrap(), nodes.to_vec())
        })
        .collect();
    MeanValueMesh::new(material(), rest, elements, cleave_meanvalue::DEFAULT_REFINEMENT).unwrap()
}

fn block() -> MeanValueMesh {
    moved_box(Point3::new(0.03, -0.21, 0.11), 0.1, [8, 4, 4], &Isometry3::identity())
}

#[test]
fn an_oblique_plane_cuts_a_box_in_two() {
    let mut mesh = block();
    let volume: Real = mesh.pieces().iter().map(|p| p.volume).sum();
    let (nodes, elements) = (mesh.num_nodes(), mesh.num_elements());
    let change = mesh
        .cut(&CutSurface::Plane { point: Point3::new(0.4, 0.0, 0.0), normal: Vector3::new(1.0, 0.3, 0.1) })
        .unwrap();
    let pieces = mesh.pieces();
    println!(
        "{nodes} nodes, {elements} elements -> {} nodes, {} elements, {} pieces",
        mesh.num_nodes(),
        mesh.num_elements(),
        pieces.len()
    );
    assert_eq!(pieces.len(), 2);
    assert_eq!(change.epoch, 1);
    let after: Real = pieces.iter().map(|p| p.volume).sum();
    assert!(((after - volume) / volume).abs() < 1e-12, "{volume} -> {after}");
    // The piece below the plane x + 0.3 y + 0.1 z = 0.4: its volume by the plane's section of
    // the box, measured with an independent cell sum.
    let n = Vector3::new(1.0, 0.3, 0.1);
    let below = |p: &Point3<Real>| n.dot(&(p - Point3::new(0.4, 0.0, 0.0))) < 0.0;
    let samples = 80;
    let (lo, hi) = (Point3::new(0.03, -0.21, 0.11), Point3::new(0.83, 0.19, 0.51));
    let mut inside = 0usize;
    for i in 0..samples {
        for j in 0..samples {
            for k in 0..samples {
                let f = |a: usize| (a as Real + 0.5) / samples as Real;
                let p =
                    Point3::new(lo.x + (hi.x - lo.x) * f(i), lo.y + (hi.y - lo.y) * f(j), lo.z + (hi.z - lo.z) * f(k));
                inside += usize::from(below(&p));
            }
        }
    }
    let expected = volume * inside as Real / (samples * samples * samples) as Real;
    let smaller = pieces.iter().map(|p| p.volume).fold(Real::MAX, Real::min);
    assert!((smaller - expected).abs() < 3e-3 * volume, "{smaller} against {expected}");
}

#[test]
fn cut_block_passes_the_conformance_suite() {
    let mut mesh = block();
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.4, 0.0, 0.0), normal: Vector3::new(1.0, 0.3, 0.1) }).unwrap();
    let tri = [Point3::new(0.6, -0.3, 0.2), Point3::new(0.7, 0.3, 0.35), Point3::new(0.65, -0.3, 0.6)];
    mesh.cut(&CutSurface::Triangles(vec![tri])).unwrap();
    assert_eq!(mesh.pieces().len(), 2);
    println!("{} elements, {} nodes", mesh.num_elements(), mesh.num_nodes());
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
        placement: Isometry3::new(Vector3::new(0.37, -1.21, 2.53), Vector3::new(0.3, -0.5, 0.8)),
        // Measured: 1.3e-3 and 1.3e-4 (the interpolation error of the bent field, O(κh²)).
        transfer: Transfer::Interpolated { bent_motion: 5e-3, bent_energy: 1e-3 },
    };
    let checks = cut_conformance(&subject);
    for c in &checks {
        println!("{}: {:.3e} (tolerance {:.1e})", c.name, c.error, c.tolerance);
    }
    assert_all_pass(&checks);
}

/// What a sequence of random cuts left: cuts refused, slivers merged, left below the floor,
/// degenerate sections kept whole, and the worst element quality seen.
struct SequenceReport {
    cuts: usize,
    refused: usize,
    merged: usize,
    below: usize,
    degenerate: usize,
    worst: Real,
}

/// Six rounds of six random cuts on a fresh 4 × 3 × 3 box of 0.1 m cubes (soups of three
/// triangles in even rounds, planes in odd ones); with `near_node_planes`, every third cut is
/// instead a plane 1e-9 to 1e-3 of a cell off a node plane and tilted 1e-4 from it. Checks after
/// every cut that nothing panicked and the volume is kept to 1e-12.
fn random_sequences(seed: u64, near_node_planes: bool) -> SequenceReport {
    let mut random = cleave_testkit::Lcg::new(seed);
    let mut report = SequenceReport { cuts: 0, refused: 0, merged: 0, below: 0, degenerate: 0, worst: Real::MAX };
    for round in 0..6 {
        let mut mesh = moved_box(Point3::new(0.0, 0.0, 0.0), 0.1, [4, 3, 3], &Isometry3::identity());
        let volume: Real = mesh.pieces().iter().map(|p| p.volume).sum();
        for _ in 0..6 {
            let centre =
                Point3::new(0.2, 0.15, 0.15) + Vector3::new(random.next(), random.next(), random.next()) * 0.15;
            let soup: Vec<[Point3<Real>; 3]> = (0..3)
                .map(|_| {
                    let mut p = || centre + Vector3::new(random.next(), random.next(), random.next()) * 0.25;
                    [p(), p(), p()]
                })
                .collect();
            let surface = if near_node_planes && report.cuts % 3 == 2 {
                let axis = report.cuts % 9 / 3;
                let mut point = centre;
                point[axis] =
                    0.1 * (1.0 + (2.0 * random.next()).floor()) + 0.1 * 10f64.powf(-6.0 + 3.0 * random.next());
                let mut normal = Vector3::new(random.next(), random.next(), random.next()) * 1e-4;
                normal[axis] = 1.0;
                CutSurface::Plane { point, normal }
            } else if round % 2 == 0 {
                CutSurface::Triangles(soup)
            } else {
                CutSurface::Plane { point: centre, normal: Vector3::new(random.next(), random.next(), random.next()) }
            };
            report.cuts += 1;
            match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| mesh.cut(&surface))) {
                Err(_) => panic!("a cut panicked"),
                Ok(Err(e)) => {
                    report.refused += 1;
                    println!("refused: {e}");
                }
                Ok(Ok(_)) => {
                    report.merged += mesh.last_cut().merged;
                    report.below += mesh.last_cut().below_floor;
                    report.degenerate += mesh.last_cut().degenerate;
                }
            }
            let after: Real = mesh.pieces().iter().map(|p| p.volume).sum();
            assert!(((after - volume) / volume).abs() < 1e-12);
            for e in 0..mesh.num_elements() {
                report.worst = report.worst.min(quality(mesh.element(e).0));
            }
        }
        println!(
            "round {round}: {} elements, {} nodes, {} pieces",
            mesh.num_elements(),
            mesh.num_nodes(),
            mesh.pieces().len()
        );
    }
    println!(
        "{} of {} cuts refused; {} slivers merged, {} left below {QUALITY_FLOOR}, {} degenerate sections kept whole; worst element quality {:.3e}",
        report.refused, report.cuts, report.merged, report.below, report.degenerate, report.worst
    );
    report
}

#[test]
fn random_cut_sequences_never_panic_and_keep_every_element_above_the_floor() {
    // Measured (seed 3): none refused, no sliver to merge, worst quality 4.0e-2.
    let report = random_sequences(3, false);
    assert_eq!(report.refused, 0);
    assert!(report.worst >= QUALITY_FLOOR, "worst element quality {}", report.worst);
}

/// Planes a hair off node planes leave slabs and wedges. A slab next to a sound neighbour
/// merges into it; a wedge where a tilted plane crosses a node plane inside a cell sits on part
/// of its neighbours' face and rises from nothing, so no union with neighbours on its side is
/// convex (mean-value.md §9, "Slivers"): those stay, counted in `CutReport::below_floor`.
#[test]
fn cuts_next_to_node_planes_merge_their_slabs_and_report_what_stays() {
    let report = random_sequences(3, true);
    assert_eq!(report.refused, 0);
    assert!(report.merged > 0, "the near-node planes leave slivers to merge");
    // Measured: 83 merged, 51 left (worst 1.1e-5, a wedge). The report must count every element
    // left below the floor: the worst seen is below it exactly when some were reported.
    assert_eq!(report.below > 0, report.worst < QUALITY_FLOOR);
}

/// wicke2007's Fig. 9 block (3 × 3 × 3 cubes of 0.1 m), as `scenes/block_slice_meanvalue.ron`
/// starts: the paper reports 64 nodes and 27 elements before its first cut; the corner plane
/// x + y + z = 0.45 takes off the tetrahedron of legs 0.15 m, whose volume is known exactly.
#[test]
fn the_fig9_block_loses_its_corner_tetrahedron_exactly() {
    let mut mesh = moved_box(Point3::new(-0.15, -0.15, 0.0), 0.1, [3, 3, 3], &Isometry3::identity());
    assert_eq!((mesh.num_nodes(), mesh.num_elements()), (64, 27));
    let n = Vector3::new(1.0, 1.0, 1.0);
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.15, 0.15, 0.15), normal: n }).unwrap();
    let pieces = mesh.pieces();
    println!(
        "after the corner cut: {} nodes, {} elements, {} pieces",
        mesh.num_nodes(),
        mesh.num_elements(),
        pieces.len()
    );
    assert_eq!(pieces.len(), 2);
    let corner = pieces.iter().map(|p| p.volume).fold(Real::MAX, Real::min);
    let exact = 0.15f64.powi(3) / 6.0;
    assert!(((corner - exact) / exact).abs() < 1e-12, "{corner} vs {exact}");
    // Every element valid and none below the quality floor.
    for e in 0..mesh.num_elements() {
        assert!(quality(mesh.element(e).0) >= QUALITY_FLOOR, "element {e}");
    }
}

/// A blade's progress: thin strips, each a step of its edge coming down through a block,
/// tilted; after every step the body passes the conformance suite (rigid motions free of force,
/// forces the gradient of the energy, affine fields embedded exactly).
#[test]
fn a_blade_cutting_step_by_step_leaves_a_sound_body() {
    let mut mesh = moved_box(Point3::new(-0.15, -0.15, 0.0), 0.1, [3, 3, 3], &Isometry3::identity());
    let edge = |z: Real| [Point3::new(-0.2, -0.02 + 0.375 * z, z), Point3::new(0.2, -0.02 + 0.375 * z, z)];
    let steps = 12;
    for k in 0..steps {
        let (z0, z1) = (0.32 - 0.02 * k as Real, 0.32 - 0.02 * (k + 1) as Real);
        let ([a, b], [c, d]) = (edge(z0), edge(z1));
        mesh.cut(&CutSurface::Triangles(vec![[a, b, d], [a, d, c]])).unwrap();
    }
    println!("{} nodes, {} elements, {} pieces", mesh.num_nodes(), mesh.num_elements(), mesh.pieces().len());
    assert_eq!(mesh.pieces().len(), 1, "the blade stops 0.08 m above the ground");
    assert_all_pass(&conformance_suite(&mesh));
}

/// A block clamped at its base settles under gravity; then a blade's strips cut it one per
/// step, each strip's front line inside the cells (straight nodes on the cut cells' edges). The
/// remap carries the settled state, so no cut may change the total energy by more than the
/// interpolation of a smooth field does (measured: 2e-6 relative at most). With the face limit
/// taking the first collinear edge instead of the one holding the point, a front node copied its
/// neighbour's value and each cut added up to 50 % (caught by the block_slice scene's energy).
#[test]
fn a_blade_cutting_a_settled_block_adds_no_energy() {
    use cleave_integrator::{Constraints, Integrator, Settings};
    let pins = |d: &dyn Discretization| -> Vec<usize> {
        let r = d.rest_dofs();
        (0..r.len() / 3).filter(|&k| r[3 * k + 2].abs() < 1e-9).flat_map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect()
    };
    let material = Material::new(2e5, 0.3, 1000.0).unwrap();
    let mut mesh = MeanValueMesh::from_box(material, Point3::new(-0.15, -0.15, 0.0), 0.1, [3, 3, 3]).unwrap();
    let mut settings = Settings::new(1.0 / 60.0);
    settings.rayleigh_beta = 0.01;
    settings.gravity = Vector3::new(0.0, 0.0, -9.81);
    let mut integrator =
        Integrator::new(&mesh, settings, Constraints { pinned_dofs: pins(&mesh), ..Default::default() }).unwrap();
    for _ in 0..40 {
        integrator.step(&mesh).unwrap();
    }
    let mut worst: Real = 0.0;
    for k in 0..12 {
        let (z0, z1) = (0.32 - 0.02 * k as Real, 0.32 - 0.02 * (k + 1) as Real);
        let [a, b, c, d] = [(-0.2, z0), (0.2, z0), (-0.2, z1), (0.2, z1)].map(|(x, z)| Point3::new(x, -0.02, z));
        let before = integrator.energies(&mesh).total_energy();
        let change = mesh.cut(&CutSurface::Triangles(vec![[a, b, d], [a, d, c]])).unwrap();
        let constraints = Constraints { pinned_dofs: pins(&mesh), ..Default::default() };
        integrator.apply_topology_change(&mesh, &change, constraints).unwrap();
        let after = integrator.energies(&mesh).total_energy();
        worst = worst.max(((after - before) / before).abs());
        integrator.step(&mesh).unwrap();
    }
    println!("largest relative energy change across a cut: {worst:.2e}");
    assert!(worst < 1e-5, "{worst}");
}
