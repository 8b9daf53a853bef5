//! Voxel benches: the warped stiffness action (voxels per second and fraction of FP64 peak), one
//! implicit step of the bunny drop with each solver, and cantilever assembly + factorization.
//!
//! The build targets baseline x86-64 (SSE2); the cube's 24×24 product picks AVX2+FMA at run time
//! (`pulp`). FP64 peak per core: 16 flop/cycle with AVX2+FMA (two 256-bit FMA ports, 4 doubles
//! each, 2 flops per FMA), 32 with AVX-512. A cube costs 2·576 (the 24×24 product) + 2·2·8·9
//! (rotating 8 corners in and out) = 1440 flops; `results/voxel-bench.md` turns voxels/s into
//! fractions of the machine's peaks.

use cleave_benches::bunny_voxels;
use cleave_core::{Discretization, Matrix3, Point3, Real, Vector3};
use cleave_integrator::{Constraints, Integrator, PlaneCollider, Settings, Solver, solve_static};
use cleave_testkit::problems::cantilever;
use cleave_voxel::VoxelMesh;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

fn stiffness_action(c: &mut Criterion) {
    let mut group = c.benchmark_group("voxel_stiffness_action");
    for target in [10_000, 80_000] {
        let (mesh, _) = bunny_voxels(target);
        let n = 3 * mesh.num_nodes();
        let rotations: Vec<Matrix3<Real>> = (0..mesh.num_cubes())
            .map(|i| nalgebra::Rotation3::from_euler_angles(0.01 * i as Real, 0.2, -0.3).into_inner())
            .collect();
        let dx: Vec<Real> = (0..n).map(|i| ((i * 7919) % 1000) as Real * 1e-3).collect();
        let mut out = vec![0.0; n];
        group.throughput(Throughput::Elements(mesh.num_cubes() as u64));
        group.bench_with_input(BenchmarkId::from_parameter(mesh.num_cubes()), &mesh, |b, mesh| {
            b.iter(|| {
                out.fill(0.0);
                mesh.add_stiffness_action(&rotations, black_box(&dx), 1.0, &mut out);
                black_box(&out);
            })
        });
    }
    group.finish();
}

fn bunny_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("bunny_drop_step");
    group.sample_size(10);
    for target in [10_000, 80_000] {
        let (mesh, surface) = bunny_voxels(target);
        let contact = mesh.embed(&surface.vertices).expect("surface embeds");
        let solvers = [
            ("cg_matrix_free", Solver::ConjugateGradient { tolerance: 1e-6, max_iterations: 1000, assembled: false }),
            ("cg_assembled", Solver::ConjugateGradient { tolerance: 1e-6, max_iterations: 1000, assembled: true }),
            ("cholesky", Solver::Cholesky),
        ];
        for (name, solver) in solvers {
            if solver == Solver::Cholesky && target > 20_000 {
                // The AMD-ordered factor of the 80k-cube bunny (~290k DOFs) needs tens of GB here;
                // see docs/results/voxel-bench.md.
                continue;
            }
            let mut settings = Settings::new(1.0 / 60.0);
            settings.rayleigh_beta = 0.01;
            settings.solver = solver;
            let constraints = Constraints {
                contact_points: Some(contact.clone()),
                planes: vec![PlaneCollider {
                    point: Point3::origin(),
                    normal: Vector3::z(),
                    stiffness: 2e4,
                    damping: 20.0,
                    friction: 0.0,
                }],
                ..Default::default()
            };
            let mut integrator = Integrator::new(&mesh, settings, constraints).expect("integrator");
            // Start mid-fall with some deformation so CG has work like in the scene.
            for _ in 0..20 {
                integrator.step(&mesh).expect("step");
            }
            group.bench_function(BenchmarkId::new(name, mesh.num_cubes()), |b| {
                b.iter(|| black_box(integrator.step(&mesh).expect("step")))
            });
        }
    }
    group.finish();
}

fn cantilever_factorization(c: &mut Criterion) {
    let mut group = c.benchmark_group("cantilever_assemble_factorize");
    group.sample_size(10);
    for n in [8, 16] {
        let material = cantilever::material(0.3);
        let mesh = VoxelMesh::from_box(material, Point3::origin(), 1.0 / n as Real, [4 * n, n, n]).expect("beam");
        let mut load = vec![0.0; 3 * mesh.num_nodes()];
        let f = cantilever::force_density(&material);
        mesh.add_load(&|_| f, &mut load);
        let clamped = cantilever::clamped_dofs(&mesh);
        group.bench_function(BenchmarkId::from_parameter(n), |b| {
            b.iter(|| black_box(solve_static(&mesh, &load, &clamped).expect("solve")))
        });
    }
    group.finish();
}

criterion_group!(benches, stiffness_action, bunny_step, cantilever_factorization);
criterion_main!(benches);
