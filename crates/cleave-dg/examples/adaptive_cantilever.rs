//! Does adaptive refinement buy accuracy per DOF? The static cantilever of benchmarks.md §2
//! (4 × 1 × 1 m, clamped at x = 0, gravity, E = 1e6 Pa, ν = 0.3, linear) on DG IP degree 1:
//! uniform grids 4n × n × n against grids refined where the stress is high (kaufmann2008 §10's
//! criterion, docs/math/dg.md §14), each solved, refined and solved again until nothing passes
//! the threshold; the mean tip deflection against the reference the consistent methods agree on
//! (docs/results/compare.md: −3.93017 m ± 0.1 %, independent of this run).
//!
//! Run: `cargo run --release -p cleave-dg --example adaptive_cantilever` (results in
//! docs/results/dg-refinement.md).

use cleave_core::{Discretization, Matrix3, Point3, Real, Refinable};
use cleave_dg::{DgMesh, DgOptions, Flux, RefineSplit, Refinement};
use cleave_geometry::PolyhedralMesh;
use cleave_testkit::problems::cantilever;

/// The consistent methods' limit of the mean tip deflection [m] (docs/results/compare.md §2).
const REFERENCE: Real = -3.93017;

fn clamped_grid(n: usize) -> DgMesh {
    let mesh = PolyhedralMesh::grid(Point3::origin(), 1.0 / n as Real, [4 * n, n, n]);
    DgMesh::clamped(mesh, cantilever::material(0.3), DgOptions::new(1, Flux::InteriorPenalty), &|p| p.x < 1e-9)
        .expect("the grid builds")
}

/// The static solution's displacement and its mean tip deflection.
fn solve(dg: &DgMesh) -> (Vec<Real>, Real) {
    let material = *dg.material();
    let f = cantilever::force_density(&material);
    let mut load = dg.dirichlet_load().to_vec();
    dg.add_load(&|_| f, &mut load);
    let solution = cleave_integrator::solve_static(dg, &load, &[]).expect("the clamped beam solves");
    // 64 × 64 cells of 2 × 2 Gauss points on the face x = 4, nudged inside.
    let quadrature = cantilever::tip_face_quadrature(64);
    let points: Vec<Point3<Real>> = quadrature.iter().map(|(p, _)| Point3::new(p.x - 1e-9, p.y, p.z)).collect();
    let embedding = dg.embed(&points).expect("tip points lie in the beam");
    let tip = quadrature.iter().enumerate().map(|(i, (_, w))| w * embedding.point(&solution.displacement, i).z).sum();
    (solution.displacement, tip)
}

fn row(label: &str, dg: &DgMesh, tip: Real) {
    println!(
        "| {label} | {} | {} | {tip:.6} | {:.2e} |",
        dg.num_elements(),
        3 * dg.num_nodes(),
        ((tip - REFERENCE) / REFERENCE).abs()
    );
}

fn main() {
    println!("| run | elements | DOFs | tip_uz_avg [m] | error |");
    println!("|---|---|---|---|---|");
    for n in [2, 4, 8] {
        let dg = clamped_grid(n);
        let (_, tip) = solve(&dg);
        row(&format!("uniform n = {n}"), &dg, tip);
    }
    for (split, max_depth) in [(RefineSplit::Octants, 2), (RefineSplit::Halves, 4)] {
        for fraction in [0.5, 0.25] {
            let mut dg = clamped_grid(2);
            dg.set_refinement(Refinement { split, max_depth });
            let (mut u, mut tip) = solve(&dg);
            // The threshold: a fraction of the largest element stress of the first solve.
            let stress_of = |dg: &DgMesh, u: &[Real]| -> Vec<Real> {
                let x: Vec<Real> = dg.rest_dofs().iter().zip(u).map(|(r, u)| r + u).collect();
                (0..dg.num_elements())
                    .map(|e| {
                        let sigma = dg.element_stress(e, &x, &Matrix3::identity());
                        sigma.symmetric_eigenvalues().iter().fold(0.0, |m: Real, v| m.max(v.abs()))
                    })
                    .collect()
            };
            let threshold = fraction * stress_of(&dg, &u).iter().fold(0.0, |m: Real, &s| m.max(s));
            let label = |round: usize| format!("{split:?} (depth ≤ {max_depth}), τ = {fraction} σ_max, round {round}");
            row(&label(0), &dg, tip);
            for round in 1..=max_depth as usize {
                let x: Vec<Real> = dg.rest_dofs().iter().zip(&u).map(|(r, u)| r + u).collect();
                let rotations = vec![Matrix3::identity(); dg.num_frames()];
                if dg.refine(&x, &rotations, threshold).expect("refines").is_none() {
                    break;
                }
                (u, tip) = solve(&dg);
                row(&label(round), &dg, tip);
            }
        }
    }
}
