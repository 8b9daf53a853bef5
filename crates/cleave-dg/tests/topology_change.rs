//! `Integrator::apply_topology_change` with a genuine renumbering: the same DG beam with its
//! elements labelled in reverse order (a `Gather` of every basis coefficient and of every frame),
//! applied mid-run, must keep every DOF's value, carry the rotations, rebuild the weak clamp's
//! load on the new numbering, and continue the trajectory of the unchanged mesh on the direct
//! and both CG paths.

use cleave_core::{Discretization, DofRemap, FrameRemap, Material, Point3, Real, TopologyChange, Vector3};
use cleave_dg::{DgMesh, DgOptions, Flux, WeakDirichlet};
use cleave_geometry::PolyhedralMesh;
use cleave_integrator::{Constraints, Integrator, Settings, Solver};

fn beam(reversed: bool) -> DgMesh {
    let mut mesh = PolyhedralMesh::grid(Point3::new(0.0, 0.0, 0.0), 0.25, [6, 2, 2]);
    if reversed {
        let last = mesh.num_elements as u32 - 1;
        for face in &mut mesh.faces {
            face.inner = last - face.inner;
            face.outer = face.outer.map(|o| last - o);
        }
    }
    let material = Material::new(1e6, 0.3, 1000.0).unwrap().with_damping(0.0, 0.01).unwrap();
    let zero = |_: &Point3<Real>| Vector3::zeros();
    let clamp = WeakDirichlet { on_boundary: &|c| c.x.abs() < 1e-9, data: &zero };
    DgMesh::new(mesh, material, DgOptions::new(1, Flux::InteriorPenalty), Some(&clamp)).unwrap()
}

fn constraints(d: &DgMesh) -> Constraints {
    Constraints { extra_load: d.dirichlet_load().to_vec(), ..Default::default() }
}

fn probe_points(d: &DgMesh, x: &[Real]) -> Vec<Point3<Real>> {
    let probes: Vec<Point3<Real>> = (0..6)
        .flat_map(|i| [Point3::new(0.25 * i as Real + 0.1, 0.1, 0.1), Point3::new(0.25 * i as Real + 0.2, 0.4, 0.3)])
        .collect();
    let embedding = d.embed(&probes).unwrap();
    (0..embedding.len()).map(|i| embedding.point(x, i)).collect()
}

#[test]
fn reversed_element_labels_mid_run_continue_the_same_trajectory() {
    let (a, b) = (beam(false), beam(true));
    assert_eq!(a.penalty(), b.penalty());
    let nb = a.num_nodes() / a.num_elements();
    let last = a.num_elements() - 1;
    let nodes: Vec<u32> = (0..b.num_nodes()).map(|k| ((last - k / nb) * nb + k % nb) as u32).collect();
    let frames: Vec<u32> = (0..b.num_elements()).map(|e| (last - e) as u32).collect();
    let change = TopologyChange {
        epoch: b.epoch(),
        remap: DofRemap::Gather(nodes),
        frames: FrameRemap::Gather(frames.clone()),
        pattern_changed: true,
    };
    let identity = TopologyChange {
        epoch: a.epoch(),
        remap: DofRemap::Identity,
        frames: FrameRemap::Identity,
        pattern_changed: true,
    };
    for solver in [
        Solver::Cholesky,
        Solver::ConjugateGradient { tolerance: 1e-13, max_iterations: 5000, assembled: true },
        Solver::ConjugateGradient { tolerance: 1e-13, max_iterations: 5000, assembled: false },
    ] {
        let mut settings = Settings::new(1.0 / 60.0);
        settings.solver = solver;
        settings.rayleigh_beta = 0.01;
        let mut straight = Integrator::new(&a, settings.clone(), constraints(&a)).unwrap();
        let mut changed = Integrator::new(&a, settings, constraints(&a)).unwrap();
        for _ in 0..20 {
            straight.step(&a).unwrap();
            changed.step(&a).unwrap();
        }
        let before = probe_points(&a, changed.positions());
        let mut rotations = changed.rotations().to_vec();
        a.write_rotations(changed.positions(), &mut rotations);
        changed.apply_topology_change(&b, &change, constraints(&b)).unwrap();
        straight.apply_topology_change(&a, &identity, constraints(&a)).unwrap();
        let after = probe_points(&b, changed.positions());
        assert!(before.iter().zip(&after).all(|(p, q)| p == q), "a renumbering moved a material point");
        let bent = rotations.iter().map(|r| (r - nalgebra::Matrix3::identity()).norm()).fold(0.0, Real::max);
        assert!(bent > 1e-3, "frames must be rotated before the change: {bent}");
        for (k, &s) in frames.iter().enumerate() {
            assert!((changed.rotations()[k] - rotations[s as usize]).norm() < 1e-12, "frame {k} was not carried");
        }
        let (mut worst, mut scale): (Real, Real) = (0.0, 0.0);
        for _ in 0..40 {
            straight.step(&a).unwrap();
            changed.step(&b).unwrap();
            let (p, q) = (probe_points(&a, straight.positions()), probe_points(&b, changed.positions()));
            let rest = probe_points(&a, a.rest_dofs());
            scale = scale.max(p.iter().zip(&rest).map(|(p, r)| (p - r).norm()).fold(0.0, Real::max));
            worst = worst.max(p.iter().zip(&q).map(|(p, q)| (p - q).norm()).fold(0.0, Real::max));
        }
        println!("{solver:?}: largest displacement {scale:.3e} m, difference {worst:.3e} m");
        assert!(scale > 0.01, "the beam must bend: {scale}");
        assert!(worst < 1e-9 * scale, "{solver:?}: the renumbered run drifts by {worst:e} m");
    }
}
