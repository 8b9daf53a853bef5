//! DG benches (kaufmann2008): one corotated implicit step of the dynamic beam (benchmarks.md §3)
//! with sparse Cholesky and with block-Jacobi CG, for both degrees and two refinements, so the
//! paper's observation that Cholesky scales better than CG can be checked here; and the build
//! (integration + η search) of the Table 1 grid.

use cleave_core::{Discretization, Material, Point3, Real, Vector3};
use cleave_dg::{DgMesh, DgOptions, Flux, WeakDirichlet};
use cleave_geometry::PolyhedralMesh;
use cleave_integrator::{Constraints, Integrator, Settings, Solver};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn beam(n: usize, degree: usize) -> DgMesh {
    let material = Material::new(1e8, 0.3, 1000.0).unwrap().with_damping(0.0, 0.01).unwrap();
    let mesh = PolyhedralMesh::grid(Point3::origin(), 1.0 / n as Real, [4 * n, n, n]);
    let clamp = |p: &Point3<Real>| p.x < 1e-9;
    let zero = |_: &Point3<Real>| Vector3::zeros();
    let dirichlet = WeakDirichlet { on_boundary: &clamp, data: &zero };
    DgMesh::new(mesh, material, DgOptions::new(degree, Flux::InteriorPenalty), Some(&dirichlet)).expect("beam builds")
}

fn beam_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("dg_beam_step");
    group.sample_size(10);
    for degree in [1, 2] {
        for n in [2, 4] {
            let dg = beam(n, degree);
            let solvers = [
                ("cholesky", Solver::Cholesky),
                (
                    "cg_assembled",
                    Solver::ConjugateGradient { tolerance: 1e-6, max_iterations: 20_000, assembled: true },
                ),
            ];
            for (name, solver) in solvers {
                let mut settings = Settings::new(1.0 / 60.0);
                settings.rayleigh_beta = 0.01;
                settings.solver = solver;
                let mut integrator = Integrator::new(&dg, settings, Constraints::default()).expect("integrator");
                // Start mid-swing, as in the benchmark.
                for _ in 0..10 {
                    integrator.step(&dg).expect("step");
                }
                let id = BenchmarkId::new(format!("{name}/p{degree}"), format!("n{n}_{}dofs", 3 * dg.num_nodes()));
                group.bench_function(id, |b| b.iter(|| black_box(integrator.step(&dg).expect("step"))));
            }
        }
    }
    group.finish();
}

fn table1_build(c: &mut Criterion) {
    let mut group = c.benchmark_group("dg_table1_build");
    group.sample_size(10);
    for (label, flux, degree) in
        [("bz-1", Flux::BabuskaZlamal, 1), ("ip-1", Flux::InteriorPenalty, 1), ("ip-2", Flux::InteriorPenalty, 2)]
    {
        let material = Material::new(1e6, 0.3, 1000.0).unwrap();
        group.bench_function(label, |b| {
            b.iter(|| {
                let mesh = PolyhedralMesh::grid(Point3::origin(), 0.1, [10, 10, 10]);
                let clamp = |p: &Point3<Real>| p.x < 1e-9;
                let zero = |_: &Point3<Real>| Vector3::zeros();
                let dirichlet = WeakDirichlet { on_boundary: &clamp, data: &zero };
                black_box(DgMesh::new(mesh, material, DgOptions::new(degree, flux), Some(&dirichlet)).expect("builds"))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, beam_step, table1_build);
criterion_main!(benches);
