//! Convergence of the voxel backend under refinement (benchmarks.md §1 and §2), release mode:
//! manufactured solutions with measured L2/H1 rates, and the static cantilever converging
//! monotonically to the limit the consistent methods agree on (DG IP p = 2 as the independent one).

use cleave_core::{Discretization, Material, Point3, Real};
use cleave_integrator::solve_static;
use cleave_testkit::problems::{
    Manufactured, cantilever, field_errors, nodal_dirichlet, on_unit_cube_boundary, refinement_rates,
};
use cleave_voxel::VoxelMesh;

fn manufactured_errors(case: Manufactured, n: usize) -> (Real, Real) {
    let material = Material::new(1e6, 0.3, 1000.0).unwrap();
    let mesh = VoxelMesh::from_box(material, Point3::origin(), 1.0 / n as Real, [n, n, n]).unwrap();
    let mut load = vec![0.0; 3 * mesh.num_nodes()];
    mesh.add_load(&|p| case.body_force(&material, p), &mut load);
    // Strong Dirichlet data: the exact displacement at the boundary nodes.
    let prescribed = nodal_dirichlet(&mesh, on_unit_cube_boundary, |p| case.displacement(p));
    let solution = solve_static(&mesh, &load, &prescribed).unwrap();
    let errors = field_errors(&mesh, &solution.displacement, 6, &|p| (case.displacement(p), case.gradient(p)));
    (errors.l2_relative, errors.h1_relative)
}

#[test]
fn manufactured_solutions_converge_at_rates_two_and_one() {
    for case in [Manufactured::Sin111, Manufactured::Cos123] {
        let sizes = [4, 8, 16];
        let errors: Vec<(Real, Real)> = sizes.iter().map(|&n| manufactured_errors(case, n)).collect();
        for (l2, h1_rate) in refinement_rates(&format!("{case:?}"), &sizes, &errors) {
            assert!(l2 >= 1.9, "{case:?}: L2 rate {l2} < 1.9");
            assert!(h1_rate >= 0.9, "{case:?}: H1 rate {h1_rate} < 0.9");
        }
        // and the errors are small in absolute terms at n = 16 (a wrong load would stall them)
        assert!(errors[2].0 < 0.02 && errors[2].1 < 0.15, "{case:?}: {:?}", errors[2]);
    }
}

/// Tip deflection (average of u_z over the face x = 4) of the 4n × n × n voxel cantilever.
fn cantilever_tip(n: usize) -> (Real, Real) {
    let material = cantilever::material(0.3);
    let mesh = VoxelMesh::from_box(material, Point3::origin(), 1.0 / n as Real, [4 * n, n, n]).unwrap();
    let mut load = vec![0.0; 3 * mesh.num_nodes()];
    let f = cantilever::force_density(&material);
    mesh.add_load(&|_| f, &mut load);
    let solution = solve_static(&mesh, &load, &cantilever::clamped_dofs(&mesh)).unwrap();
    let quadrature = cantilever::tip_face_quadrature(n);
    let points: Vec<Point3<Real>> = quadrature.iter().map(|(p, _)| *p).collect();
    let embedding = mesh.embed(&points).unwrap();
    let tip: Real =
        quadrature.iter().enumerate().map(|(i, (_, w))| w * embedding.point(&solution.displacement, i).z).sum();
    (tip, solution.strain_energy)
}

/// Limits of the cantilever's mean tip deflection [m] and strain energy ½ fᵀu [J] that
/// independent consistent methods agree on: DG IP p = 2 at n = 4, 8 (tips −3.912736, −3.924035;
/// energies 3.178240e4, 3.189335e4) extrapolates to −3.93076 m and 3.19594e4 J, agreeing with
/// the voxel n = 16, 32 extrapolation (−3.92998 m, 3.19496e4 J) to 0.03 %
/// (docs/results/compare.md). Euler–Bernoulli's 3.767 m omits shear and the clamp; BZ p = 2
/// extrapolates to −4.1336 m, 5 % away.
const CONSISTENT_TIP: Real = -3.930;
const CONSISTENT_ENERGY: Real = 3.1955e4;

/// Richardson extrapolation of levels n and 2n converging like h^(2λ), λ = 0.711 the
/// clamped-edge singularity exponent at ν = 0.3 (benchmarks.md §2).
fn extrapolate(coarse: Real, fine: Real) -> Real {
    cleave_testkit::compare::richardson(coarse, fine, 2.0, 2.0 * cleave_testkit::compare::CANTILEVER_LAMBDA)
}

#[test]
fn static_cantilever_converges_monotonically_to_the_consistent_limit() {
    // Measured when written (tip [m], strain energy [J]); the solves are deterministic, so a
    // change beyond 1e-6 relative is a change of the discretization or the solver.
    let measured = [
        (1, -2.574888067, 2.114059206e4),
        (2, -3.392970915, 2.747358358e4),
        (4, -3.757361098, 3.046178326e4),
        (8, -3.876367996, 3.147409002e4),
        (16, -3.912373903, 3.179026098e4),
    ];
    let results: Vec<(Real, Real)> = measured.iter().map(|&(n, _, _)| cantilever_tip(n)).collect();
    for ((n, tip_measured, energy_measured), (tip, energy)) in measured.iter().zip(&results) {
        println!("n = {n:2}: tip_uz_avg = {tip:.9e} m, strain energy = {energy:.9e} J");
        assert!((tip / tip_measured - 1.0).abs() < 1e-6, "n = {n}: tip {tip:.9} vs measured {tip_measured:.9}");
        assert!((energy / energy_measured - 1.0).abs() < 1e-6, "n = {n}: energy {energy} vs {energy_measured}");
    }
    // Deflection and energy grow with refinement (trilinear cubes are too stiff in bending) and
    // the increments shrink: monotone convergence from above in stiffness.
    for w in results.windows(2) {
        assert!(w[1].0 < w[0].0 && w[1].1 > w[0].1, "deflection and energy must grow: {results:?}");
    }
    for w in results.windows(3) {
        assert!((w[2].0 - w[1].0).abs() < (w[1].0 - w[0].0).abs(), "increments must shrink: {results:?}");
    }
    // The limit from n = 8, 16 (measured −3.93381 m, +0.10 %; 3.19785e4 J, +0.07 %) lies within
    // 1 % of what the consistent methods agree on; BZ's limit would be 5 % away.
    let [.., (tip_8, energy_8), (tip_16, energy_16)] = results.as_slice() else { unreachable!() };
    let (tip, energy) = (extrapolate(*tip_8, *tip_16), extrapolate(*energy_8, *energy_16));
    println!("Richardson limits: tip {tip:.6} m, energy {energy:.6e} J");
    assert!((tip / CONSISTENT_TIP - 1.0).abs() < 0.01, "tip limit {tip} vs {CONSISTENT_TIP}");
    assert!((energy / CONSISTENT_ENERGY - 1.0).abs() < 0.01, "energy limit {energy} vs {CONSISTENT_ENERGY}");
}
