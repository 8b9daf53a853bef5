//! `Integrator::apply_topology_change` on every solver path (Cholesky, assembled CG, matrix-free
//! CG, two-level CG), with pins and ground contact re-resolved on the new mesh: the same cubes
//! built again from a reversed cell list, mapped by a `Gather` of nodes and frames found by
//! lattice coordinates. `VoxelMesh` sorts its cubes and nodes, so this gather is the identity
//! permutation; the genuine renumbering is `crates/cleave-dg/tests/topology_change.rs`. What this
//! test adds: the two-level coarse space, the contact rows and the pins are rebuilt mid-run
//! without changing a bit of the trajectory, positions and velocities are kept, and rotations
//! are carried as warm starts rather than reset.

use cleave_core::{Discretization, DofRemap, FrameRemap, Material, Point3, Real, TopologyChange, Vector3};
use cleave_integrator::{Constraints, Integrator, PlaneCollider, Preconditioner, Settings, Solver};
use cleave_voxel::VoxelMesh;

fn cells() -> Vec<[i32; 3]> {
    let mut cells = Vec::new();
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..6 {
                cells.push([i, j, k]);
            }
        }
    }
    cells
}

fn mesh(reversed: bool) -> VoxelMesh {
    let mut cells = cells();
    if reversed {
        cells.reverse();
    }
    let material = Material::new(2e5, 0.3, 1000.0).unwrap().with_damping(0.0, 0.01).unwrap();
    VoxelMesh::new(material, Point3::new(0.0, 0.0, 0.05), 0.1, &cells).unwrap()
}

/// Clamped at x = 0 (re-resolved from the rest-space region on every mesh), resting with its
/// bottom close to a ground plane that its free end will hit.
fn constraints(mesh: &VoxelMesh, probes: &[Point3<Real>]) -> Constraints {
    let pinned_dofs = mesh
        .rest_dofs()
        .chunks_exact(3)
        .enumerate()
        .filter(|(_, p)| p[0].abs() < 1e-9)
        .flat_map(|(n, _)| [3 * n, 3 * n + 1, 3 * n + 2])
        .collect();
    let ground =
        PlaneCollider { point: Point3::origin(), normal: Vector3::z(), stiffness: 1e5, damping: 10.0, friction: 0.0 };
    Constraints {
        pinned_dofs,
        contact_points: Some(mesh.embed(probes).unwrap()),
        planes: vec![ground],
        ..Default::default()
    }
}

fn probes() -> Vec<Point3<Real>> {
    (0..=6).flat_map(|i| [Point3::new(0.1 * i as Real, 0.0, 0.05), Point3::new(0.1 * i as Real, 0.2, 0.25)]).collect()
}

/// The old node and the old cube of every new one, found by their lattice coordinates.
fn renumbering(old: &VoxelMesh, new: &VoxelMesh) -> TopologyChange {
    let nodes =
        new.node_coords().iter().map(|c| old.node_coords().iter().position(|o| o == c).unwrap() as u32).collect();
    let frames = new.cells().iter().map(|c| old.cells().iter().position(|o| o == c).unwrap() as u32).collect();
    TopologyChange {
        epoch: new.epoch(),
        remap: DofRemap::Gather(nodes),
        frames: FrameRemap::Gather(frames),
        pattern_changed: true,
    }
}

fn points(mesh: &VoxelMesh, x: &[Real]) -> Vec<Point3<Real>> {
    let embedding = mesh.embed(&probes()).unwrap();
    (0..embedding.len()).map(|i| embedding.point(x, i)).collect()
}

fn largest_difference(a: &[Point3<Real>], b: &[Point3<Real>]) -> Real {
    a.iter().zip(b).map(|(p, q)| (p - q).norm()).fold(0.0, Real::max)
}

#[test]
fn a_renumbering_mid_run_continues_the_same_trajectory_on_every_solver_path() {
    let paths: [(Solver, Preconditioner, Real); 4] = [
        (Solver::Cholesky, Preconditioner::BlockJacobi, 1e-10),
        (
            Solver::ConjugateGradient { tolerance: 1e-12, max_iterations: 2000, assembled: true },
            Preconditioner::BlockJacobi,
            1e-8,
        ),
        (
            Solver::ConjugateGradient { tolerance: 1e-12, max_iterations: 2000, assembled: false },
            Preconditioner::BlockJacobi,
            1e-8,
        ),
        (
            Solver::ConjugateGradient { tolerance: 1e-12, max_iterations: 2000, assembled: false },
            Preconditioner::TwoLevel,
            1e-8,
        ),
    ];
    let (a, b) = (mesh(false), mesh(true));
    let change = renumbering(&a, &b);
    let probes = probes();
    for (solver, preconditioner, tolerance) in paths {
        let mut settings = Settings::new(1.0 / 60.0);
        settings.solver = solver;
        settings.preconditioner = preconditioner;
        settings.rayleigh_beta = 0.01;
        let mut straight = Integrator::new(&a, settings.clone(), constraints(&a, &probes)).unwrap();
        let mut changed = Integrator::new(&a, settings, constraints(&a, &probes)).unwrap();
        for _ in 0..15 {
            straight.step(&a).unwrap();
            changed.step(&a).unwrap();
        }
        let before = points(&a, changed.positions());
        let velocities_before = points(&a, changed.velocities());
        let energy_before = changed.energies(&a).total_energy();
        // The integrator's rotations belong to the start of the last step; the rebuild refreshes
        // them at the current positions from their warm starts, as A would.
        let mut rotations_before = changed.rotations().to_vec();
        a.write_rotations(changed.positions(), &mut rotations_before);
        changed.apply_topology_change(&b, &change, constraints(&b, &probes)).unwrap();
        // The straight run takes an identity change at the same instant, so both refresh their
        // rotations once at the change; the only difference left is the renumbering.
        let identity = TopologyChange {
            epoch: a.epoch(),
            remap: DofRemap::Identity,
            frames: FrameRemap::Identity,
            pattern_changed: true,
        };
        straight.apply_topology_change(&a, &identity, constraints(&a, &probes)).unwrap();

        // Exact continuity: positions, velocities, energy; warm starts carried, not reset.
        assert_eq!(largest_difference(&before, &points(&b, changed.positions())), 0.0);
        assert_eq!(largest_difference(&velocities_before, &points(&b, changed.velocities())), 0.0);
        let energy_after = changed.energies(&b).total_energy();
        // The rebuild refines the warm-started rotations once more (polar iterations), which moves
        // the warped elastic energy by rounding-level amounts, never more.
        assert!((energy_after - energy_before).abs() <= 1e-8 * energy_before.abs(), "{energy_before} → {energy_after}");
        let FrameRemap::Gather(src) = &change.frames else { unreachable!() };
        let bent = rotations_before.iter().map(|r| (r - nalgebra::Matrix3::identity()).norm()).fold(0.0, Real::max);
        assert!(bent > 1e-3, "the beam must have rotated frames before the change: {bent}");
        for (k, &s) in src.iter().enumerate() {
            let drift = (changed.rotations()[k] - rotations_before[s as usize]).norm();
            assert!(drift < 1e-12, "{solver:?}: frame {k} restarted {drift} away from its old rotation");
        }

        let mut scale: Real = 0.0;
        let mut worst: Real = 0.0;
        for _ in 0..45 {
            straight.step(&a).unwrap();
            let report = changed.step(&b).unwrap();
            let (p, q) = (points(&a, straight.positions()), points(&b, changed.positions()));
            scale = scale.max(p.iter().zip(&probes).map(|(p, r)| (p - r).norm()).fold(0.0, Real::max));
            worst = worst.max(largest_difference(&p, &q));
            assert!(report.total_energy().is_finite());
        }
        println!("{solver:?} {preconditioner:?}: largest displacement {scale:.3e} m, difference {worst:.3e} m");
        assert!(scale > 0.01, "the beam must move: {scale}");
        assert!(worst <= tolerance * scale, "{solver:?} {preconditioner:?}: trajectories differ by {worst:e} m");
    }
}
