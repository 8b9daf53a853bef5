//! DG on hexahedrally sliced meshes (kaufmann2008 §10): non-convex polyhedra at the surface. The
//! conformance suite, exact element volumes, and the MLS surface embedding reproducing affine
//! fields at the bunny's surface vertices.

use cleave_core::{Discretization, Material, Matrix3, Point3, Real, Vector3};
use cleave_dg::{DgMesh, DgOptions, Flux};
use cleave_geometry::{TriangleMesh, hex_slice};
use cleave_testkit::{assert_all_pass, conformance_suite};

fn bunny() -> TriangleMesh {
    let text = include_str!("../../../scenes/meshes/bunny.obj");
    TriangleMesh::from_obj_str(text).unwrap().transformed(|p| Point3::new(0.02 * p.x, -0.02 * p.z, 0.02 * p.y))
}

fn sliced_bunny(cell: Real, degree: usize) -> (DgMesh, TriangleMesh) {
    let surface = bunny();
    let slicing = hex_slice(&surface, cell).unwrap();
    let material = Material::new(2e5, 0.3, 1000.0).unwrap();
    (DgMesh::new(slicing.mesh, material, DgOptions::new(degree, Flux::InteriorPenalty), None).unwrap(), surface)
}

#[test]
fn sliced_bunny_passes_the_conformance_suite() {
    for degree in [1, 2] {
        let (dg, _) = sliced_bunny(0.06, degree);
        println!("{}: {} elements, η = {}", dg.name(), dg.num_elements(), dg.penalty());
        assert!(dg.num_elements() > 20);
        assert_all_pass(&conformance_suite(&dg));
    }
}

#[test]
fn element_masses_sum_to_the_enclosed_mass() {
    let (dg, surface) = sliced_bunny(0.022, 1);
    // ρ ∫ ψ_0 … the mass is the work of a unit gravity on the unit translation field.
    let mut load = vec![0.0; 3 * dg.num_nodes()];
    dg.add_gravity_load(&Vector3::new(1.0, 0.0, 0.0), &mut load);
    let mut unit_x = vec![0.0; load.len()];
    dg.add_translation(&Vector3::x(), &mut unit_x);
    let mass: Real = load.iter().zip(&unit_x).map(|(f, u)| f * u).sum();
    let expected = 1000.0 * surface.signed_volume();
    println!("{} elements: mass {mass} vs {expected}", dg.num_elements());
    assert!((mass - expected).abs() < 1e-10 * expected, "{mass} vs {expected}");
}

#[test]
fn mls_surface_rows_reproduce_affine_fields() {
    let (dg, surface) = sliced_bunny(0.022, 1);
    let rows = dg.embed_surface(&surface.vertices).unwrap();
    let a = Matrix3::new(1.1, 0.2, -0.3, 0.05, 0.9, 0.1, -0.2, 0.3, 1.2);
    let b = Vector3::new(0.1, -0.2, 0.3);
    let mut x: Vec<Real> = dg
        .rest_dofs()
        .chunks_exact(3)
        .flat_map(|p| {
            let q = a * Vector3::new(p[0], p[1], p[2]);
            [q.x, q.y, q.z]
        })
        .collect();
    dg.add_translation(&b, &mut x);
    let error = surface
        .vertices
        .iter()
        .enumerate()
        .map(|(i, p)| (rows.point(&x, i).coords - (a * p.coords + b)).norm())
        .fold(0.0, Real::max);
    let widest = rows.len();
    println!("{widest} rows, max error {error:.2e} m");
    assert!(error < 1e-12, "MLS rows miss an affine field by {error} m");
    // and the rows are smooth, not the discontinuous element field: every row mixes elements
    let nb = dg.basis_size() as u32;
    let multi = (0..rows.len()).filter(|&i| {
        let nodes = rows.row(i).0;
        nodes.iter().any(|&n| n / nb != nodes[0] / nb)
    });
    assert!(multi.count() > rows.len() / 2);
}

#[test]
fn the_closed_form_gravity_load_equals_the_quadrature_on_cut_non_convex_cells() {
    // `add_gravity_load` is closed form (∫ψ_i = L_00 δ_i0); `add_load` integrates the same
    // constant force density by the signed cone rule. Degrees 1 and 2, the sliced bunny's
    // non-convex cells, and after a plane and a triangle cut (non-convex children, merged
    // slivers).
    use cleave_core::{CutSurface, Cuttable};
    for degree in [1, 2] {
        let (mut dg, _) = sliced_bunny(0.04, degree);
        let g = Vector3::new(0.3, -1.2, -9.81);
        for stage in 0..3 {
            match stage {
                1 => {
                    dg.cut(&CutSurface::Plane {
                        point: Point3::new(0.0, 0.0, 0.05),
                        normal: Vector3::new(0.2, 0.1, 1.0),
                    })
                    .unwrap();
                }
                2 => {
                    let triangle =
                        [Point3::new(-0.2, -0.2, 0.1), Point3::new(0.2, -0.1, 0.12), Point3::new(0.0, 0.01, 0.08)];
                    dg.cut(&CutSurface::Triangles(vec![triangle])).unwrap();
                }
                _ => {}
            }
            let mut closed = vec![0.0; 3 * dg.num_nodes()];
            dg.add_gravity_load(&g, &mut closed);
            let mut quadrature = vec![0.0; closed.len()];
            let rho = dg.material().density;
            dg.add_load(&|_| g * rho, &mut quadrature);
            let scale = quadrature.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
            let worst = closed.iter().zip(&quadrature).map(|(a, b)| (a - b).abs()).fold(0.0, Real::max);
            assert!(worst < 1e-11 * scale, "degree {degree} stage {stage}: {worst:e} of {scale:e}");
        }
    }
}
