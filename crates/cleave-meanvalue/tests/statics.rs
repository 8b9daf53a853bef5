//! The mean value mesh in static solves: the patch test (an affine displacement prescribed on
//! the boundary is reproduced inside to round-off) on cubes and on a box cut by oblique planes
//! into pentagon- and triangle-faced cells, a quadratic field with its analytic body force
//! converging at second order in L2 and first in H1 on both, tetrahedra equal to linear FEM's closed-form
//! stiffness, and a rigidly rotated state carrying no elastic force.

use cleave_core::{Discretization, Material, Matrix3, Point3, Real, Vector3};
use cleave_integrator::solve_static;
use cleave_meanvalue::{ConvexPolyhedron, ElementIntegrals, MeanValueMesh, quality};
use nalgebra::Rotation3;

fn material() -> Material {
    Material::new(1e6, 0.3, 1000.0).unwrap()
}

/// The box `[0,1]³` as `n³` cubes, each cut by the planes (normal, offset): a conforming
/// polyhedral mesh, since every cell meets a plane where its neighbours do. Nodes are welded by
/// position.
fn cut_box(n: usize, planes: &[(Vector3<Real>, Real)]) -> MeanValueMesh {
    let h = 1.0 / n as Real;
    let mut cells = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let lo = Point3::new(i as Real, j as Real, k as Real) * h;
                cells.push(ConvexPolyhedron::cuboid(lo, lo + Vector3::repeat(h)).unwrap());
            }
        }
    }
    for (normal, offset) in planes {
        let normal = normal.normalize();
        cells = cells
            .into_iter()
            .flat_map(|c| {
                let (a, b) = c.split(&normal, *offset, 1e-12);
                [a, b].into_iter().flatten()
            })
            .collect();
    }
    weld(cells).unwrap()
}

fn weld(cells: Vec<ConvexPolyhedron>) -> Result<MeanValueMesh, cleave_meanvalue::MeanValueError> {
    MeanValueMesh::from_cells(material(), cells)
}

fn on_boundary(p: &Point3<Real>) -> bool {
    (0..3).any(|a| p[a].abs() < 1e-12 || (p[a] - 1.0).abs() < 1e-12)
}

/// Solves with `exact` prescribed on the boundary nodes under `load`; the largest nodal error
/// against `exact`, relative to its largest value.
fn nodal_error(mesh: &MeanValueMesh, exact: &dyn Fn(&Point3<Real>) -> Vector3<Real>, load: &[Real]) -> Real {
    let rest = mesh.rest_dofs();
    let point = |k: usize| Point3::new(rest[3 * k], rest[3 * k + 1], rest[3 * k + 2]);
    let prescribed: Vec<(usize, Real)> = mesh
        .dirichlet_nodes(&on_boundary)
        .into_iter()
        .flat_map(|k| {
            let u = exact(&point(k as usize));
            (0..3).map(move |a| (3 * k as usize + a, u[a]))
        })
        .collect();
    let solution = solve_static(mesh, load, &prescribed).unwrap();
    let (mut error, mut scale): (Real, Real) = (0.0, 0.0);
    for k in 0..mesh.num_nodes() {
        let u = exact(&point(k));
        let d = &solution.displacement[3 * k..3 * k + 3];
        error = error.max((Vector3::new(d[0], d[1], d[2]) - u).norm());
        scale = scale.max(u.norm());
    }
    error / scale
}

#[test]
fn an_affine_field_passes_the_patch_test_on_cubes_and_on_cut_cells() {
    let a = Matrix3::new(0.01, 0.002, -0.003, 0.004, -0.02, 0.001, 0.0, 0.005, 0.015);
    let b = Vector3::new(0.1, -0.2, 0.05);
    let affine = |p: &Point3<Real>| a * p.coords + b;
    // Offsets chosen so no cut leaves a cell below 8.5e-6 of a cube's volume: slivers (the
    // offsets 0.61, 0.37, 0.13 leave one of 1.6e-11) amplify round-off in their gradients by
    // their aspect ratio, which is why the paper merges them (issue 36, cutting).
    let planes = [
        (Vector3::new(1.0, 0.7, 0.3), 0.58),
        (Vector3::new(-0.4, 1.0, 0.9), 0.41),
        (Vector3::new(0.2, -0.5, 1.0), 0.31),
    ];
    for (label, mesh) in [("cubes", cut_box(3, &[])), ("cut cells", cut_box(3, &planes))] {
        let zero = vec![0.0; 3 * mesh.num_nodes()];
        let error = nodal_error(&mesh, &affine, &zero);
        let faces: usize = (0..mesh.num_elements()).map(|e| mesh.element(e).0.faces().len()).sum();
        println!(
            "{label}: {} elements, {faces} faces, {} nodes: patch error {error:.2e}",
            mesh.num_elements(),
            mesh.num_nodes()
        );
        assert!(error < 1e-10, "{label}: {error:.2e}");
    }
}

#[test]
fn a_quadratic_field_converges_at_second_order_in_l2_and_first_in_h1() {
    // u = c (x², y², z²): ε = 2c diag(x, y, z), div σ = 2c (λ + 2μ) (1, 1, 1), f = −div σ. (At
    // the nodes of a uniform cube mesh the solution is exact: superconvergence, so the errors
    // are measured in L2 and H1 over the element rule.)
    let c = 0.01;
    let exact = |p: &Point3<Real>| Vector3::new(p.x * p.x, p.y * p.y, p.z * p.z) * c;
    let exact_gradient = |p: &Point3<Real>| Matrix3::from_diagonal(&Vector3::new(p.x, p.y, p.z)) * (2.0 * c);
    let (lambda, mu) = material().lame();
    let force = Vector3::repeat(-2.0 * c * (lambda + 2.0 * mu));
    let planes = [(Vector3::new(1.0, 0.7, 0.3), 0.58), (Vector3::new(-0.4, 1.0, 0.9), 0.41)];
    let build = |label: &str, n: usize| match label {
        "cubes" => cut_box(n, &[]),
        "cut cells" => cut_box(n, &planes),
        _ => MeanValueMesh::from_split_box(material(), Point3::origin(), 1.0 / n as Real, [n; 3]).unwrap(),
    };
    for label in ["cubes", "cut cells", "split box"] {
        let mut errors = Vec::new();
        for n in [2, 4, 8] {
            let mesh = build(label, n);
            let mut load = vec![0.0; 3 * mesh.num_nodes()];
            mesh.add_load(&|_| force, &mut load);
            let rest = mesh.rest_dofs();
            let prescribed: Vec<(usize, Real)> = mesh
                .dirichlet_nodes(&on_boundary)
                .into_iter()
                .flat_map(|k| {
                    let k = k as usize;
                    let u = exact(&Point3::new(rest[3 * k], rest[3 * k + 1], rest[3 * k + 2]));
                    (0..3).map(move |a| (3 * k + a, u[a]))
                })
                .collect();
            let solution = solve_static(&mesh, &load, &prescribed).unwrap();
            let [mut l2, mut l2_norm, mut h1, mut h1_norm] = [0.0; 4];
            mesh.visit_field(&solution.displacement, 2, &mut |s| {
                l2 += s.weight * (s.displacement - exact(&s.position)).norm_squared();
                l2_norm += s.weight * exact(&s.position).norm_squared();
                h1 += s.weight * (s.gradient - exact_gradient(&s.position)).norm_squared();
                h1_norm += s.weight * exact_gradient(&s.position).norm_squared();
            });
            errors.push(((l2 / l2_norm).sqrt(), (h1 / h1_norm).sqrt()));
        }
        let rate =
            |f: fn(&(Real, Real)) -> Real| errors.windows(2).map(|w| (f(&w[0]) / f(&w[1])).log2()).collect::<Vec<_>>();
        let (l2_rates, h1_rates) = (rate(|e| e.0), rate(|e| e.1));
        println!("{label}: errors {errors:?}, L2 rates {l2_rates:?}, H1 rates {h1_rates:?}");
        // The asymptotic (finest) rates against issue 36's bounds; the cut mesh is irregular at
        // n = 2 (measured: L2 1.83 → 1.93, H1 0.90 → 0.96; cubes 2.00 and 1.00 throughout).
        // The split box has every cell split at every n.
        assert!(l2_rates[1] >= 1.9, "{label}: L2 rates {l2_rates:?}");
        assert!(h1_rates[1] >= 0.9, "{label}: H1 rates {h1_rates:?}");
    }
}

#[test]
fn a_split_box_fills_the_box_with_valid_cells_at_every_size() {
    for n in [1, 2, 4, 8] {
        let h = 1.0 / n as Real;
        let mesh = MeanValueMesh::from_split_box(material(), Point3::new(0.3, -0.2, 0.1), h, [2 * n, n, n]).unwrap();
        let volume: Real = (0..mesh.num_elements()).map(|e| mesh.element(e).0.volume()).sum();
        let worst = (0..mesh.num_elements()).map(|e| quality(mesh.element(e).0)).fold(Real::INFINITY, Real::min);
        let split = mesh.num_elements() as Real / (2 * n * n * n) as Real;
        println!(
            "n = {n}: {} elements ({split:.2} per cube), {} nodes, worst quality {worst:.2e}",
            mesh.num_elements(),
            mesh.num_nodes()
        );
        // The cells tile the box: their volumes add up to its own (2 h n · h n · h n = 2), to the
        // round-off of thousands of polyhedron volumes and of vertices snapped to planes within
        // 1e-12 of a cell (measured 1.1e-12 at n = 8; a missing cell would be 1e-3 at least).
        assert!((volume - 2.0).abs() < 1e-11, "n = {n}: volume {volume}");
        // Nearly every cube is split at every size (the planes scale with the cells).
        assert!(split > 2.0, "n = {n}: {split} elements per cube");
        assert!(worst > 0.0);
    }
}

#[test]
fn a_tetrahedron_is_linear_fem() {
    let points = [
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.1, 0.0),
        Point3::new(0.2, 0.9, 0.1),
        Point3::new(0.1, 0.2, 1.1),
    ];
    let tet = ConvexPolyhedron::tetrahedron(points).unwrap();
    let (lambda, mu) = material().lame();
    let k = ElementIntegrals::new(&tet, 0).stiffness(lambda, mu);
    // Linear FEM: K = V Bᵀ D B with the barycentric gradients from a 4×4 solve and D in
    // Voigt order (xx, yy, zz, yz, xz, xy) with engineering shears.
    let a = nalgebra::Matrix4::from_fn(|r, c| if r < 3 { points[c][r] } else { 1.0 });
    let inverse = a.try_inverse().unwrap();
    let g = |i: usize| Vector3::new(inverse[(i, 0)], inverse[(i, 1)], inverse[(i, 2)]);
    let mut bmat = nalgebra::SMatrix::<Real, 6, 12>::zeros();
    for i in 0..4 {
        let gi = g(i);
        bmat[(0, 3 * i)] = gi.x;
        bmat[(1, 3 * i + 1)] = gi.y;
        bmat[(2, 3 * i + 2)] = gi.z;
        bmat[(3, 3 * i + 1)] = gi.z;
        bmat[(3, 3 * i + 2)] = gi.y;
        bmat[(4, 3 * i)] = gi.z;
        bmat[(4, 3 * i + 2)] = gi.x;
        bmat[(5, 3 * i)] = gi.y;
        bmat[(5, 3 * i + 1)] = gi.x;
    }
    let mut d = nalgebra::SMatrix::<Real, 6, 6>::zeros();
    for r in 0..3 {
        for c in 0..3 {
            d[(r, c)] = lambda + if r == c { 2.0 * mu } else { 0.0 };
        }
        d[(r + 3, r + 3)] = mu;
    }
    let volume = tet.volume();
    let reference = bmat.transpose() * d * bmat * volume;
    let difference = (k - reference).amax() / reference.amax();
    assert!(difference < 1e-13, "{difference:.2e}");
}

#[test]
fn a_rigid_rotation_carries_no_elastic_force_or_energy() {
    let planes = [(Vector3::new(1.0, 0.7, 0.3), 0.61), (Vector3::new(-0.4, 1.0, 0.9), 0.37)];
    let mesh = cut_box(2, &planes);
    let rotation =
        Rotation3::from_axis_angle(&Vector3::y_axis(), 1.1) * Rotation3::from_axis_angle(&Vector3::x_axis(), 0.4);
    let shift = Vector3::new(0.3, -1.0, 2.0);
    let x: Vec<Real> = mesh
        .rest_dofs()
        .chunks(3)
        .flat_map(|p| {
            let q = rotation * Vector3::new(p[0], p[1], p[2]) + shift;
            [q.x, q.y, q.z]
        })
        .collect();
    // The polar iteration is warm-started (a step's rotations start from the last step's): from
    // the identity a 1.2 rad turn takes a few calls, as a body turning over a few steps would.
    let mut rotations = vec![Matrix3::identity(); mesh.num_frames()];
    for _ in 0..4 {
        mesh.write_rotations(&x, &mut rotations);
    }
    for r in &rotations {
        assert!((r - rotation.matrix()).norm() < 1e-10, "{:.2e}", (r - rotation.matrix()).norm());
    }
    let mut force = vec![0.0; x.len()];
    mesh.add_internal_force(&rotations, &x, &mut force);
    let largest = force.iter().fold(0.0, |m: Real, f| m.max(f.abs()));
    let energy = mesh.elastic_energy(&rotations, &x);
    // Against the force of a 1 % stretch, a scale the test would notice.
    let stretched: Vec<Real> = mesh.rest_dofs().iter().map(|r| r * 1.01).collect();
    let identity = vec![Matrix3::identity(); mesh.num_frames()];
    let mut reference = vec![0.0; x.len()];
    mesh.add_internal_force(&identity, &stretched, &mut reference);
    let scale = reference.iter().fold(0.0, |m: Real, f| m.max(f.abs()));
    assert!(largest < 1e-10 * scale, "force {largest:.2e} against {scale:.2e}");
    assert!(energy.abs() < 1e-10 * mesh.elastic_energy(&identity, &stretched), "energy {energy:.2e}");
}

#[test]
fn a_hanging_node_is_refused_and_inserting_it_into_the_neighbour_is_accepted() {
    // Two unit cubes side by side; the left one halved by y = 0.5, which puts two nodes on the
    // shared face x = 1 that the right cube's square face lacks.
    let left = ConvexPolyhedron::cuboid(Point3::origin(), Point3::new(1.0, 1.0, 1.0)).unwrap();
    let (a, b) = left.split(&Vector3::y(), 0.5, 1e-12);
    let right = ConvexPolyhedron::cuboid(Point3::new(1.0, 0.0, 0.0), Point3::new(2.0, 1.0, 1.0)).unwrap();
    let error = weld(vec![a.clone().unwrap(), b.clone().unwrap(), right.clone()]).unwrap_err();
    assert!(error.to_string().contains("not conforming"), "{error}");
    // Split the right cube by the same plane: its face x = 1 now has the same two halves as the
    // left cube's, and the mesh conforms.
    let (c, d) = right.split(&Vector3::y(), 0.5, 1e-12);
    let mesh = weld(vec![a.unwrap(), b.unwrap(), c.unwrap(), d.unwrap()]).unwrap();
    assert_eq!(mesh.num_elements(), 4);
}

#[test]
fn the_internal_force_of_a_bent_body_turns_with_the_body() {
    // A bent, cut body (not the rest state): u = bending about y plus a twist. Rotating and
    // translating it rigidly must rotate every nodal force by the same rotation (the frames are
    // found again from the moved positions).
    let planes = [(Vector3::new(1.0, 0.7, 0.3), 0.58), (Vector3::new(-0.4, 1.0, 0.9), 0.41)];
    let mesh = cut_box(2, &planes);
    let bent: Vec<Real> = mesh
        .rest_dofs()
        .chunks(3)
        .flat_map(|p| {
            let (x, y, z) = (p[0], p[1], p[2]);
            [x - 0.1 * x * z, y + 0.05 * x * z, z + 0.08 * x * x + 0.03 * y * x]
        })
        .collect();
    let rotation =
        Rotation3::from_axis_angle(&Vector3::z_axis(), 0.7) * Rotation3::from_axis_angle(&Vector3::x_axis(), -1.2);
    let shift = Vector3::new(-2.0, 0.5, 3.0);
    let moved: Vec<Real> = bent
        .chunks(3)
        .flat_map(|p| {
            let q = rotation * Vector3::new(p[0], p[1], p[2]) + shift;
            [q.x, q.y, q.z]
        })
        .collect();
    let force_at = |x: &[Real]| {
        let mut rotations = vec![Matrix3::identity(); mesh.num_frames()];
        for _ in 0..6 {
            mesh.write_rotations(x, &mut rotations);
        }
        let mut f = vec![0.0; x.len()];
        mesh.add_internal_force(&rotations, x, &mut f);
        (f, mesh.elastic_energy(&rotations, x))
    };
    let (f, energy) = force_at(&bent);
    let (g, moved_energy) = force_at(&moved);
    let scale = f.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
    assert!(scale > 0.0 && energy > 0.0);
    let mut worst: Real = 0.0;
    for (a, b) in f.chunks(3).zip(g.chunks(3)) {
        let turned = rotation * Vector3::new(a[0], a[1], a[2]);
        worst = worst.max((turned - Vector3::new(b[0], b[1], b[2])).norm());
    }
    assert!(worst < 1e-9 * scale, "{worst:.2e} of {scale:.2e}");
    assert!((moved_energy - energy).abs() < 1e-9 * energy, "{moved_energy} vs {energy}");
}
