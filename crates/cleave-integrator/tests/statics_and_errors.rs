//! `solve_static` against a dense Cholesky of the same small SPD matrix assembled by hand (with
//! and without prescribed DOFs), and bad input (wrong load length, DOFs or nodes out of range)
//! coming back as distinct `StepErrorKind`s that name the offending value, never as panics.

mod common;

use cleave_core::{Embedding, Point3, Real};
use cleave_integrator::{
    Constraints, Integrator, PenaltyPins, PlaneCollider, Settings, StepErrorKind, SurfaceContact, solve_static,
};
use common::{Lcg, Springs, spring};
use nalgebra::{DMatrix, DVector};

/// Node list and rest matrix of each block.
type Blocks = Vec<(Vec<u32>, DMatrix<Real>)>;

/// Five nodes, four random SPD blocks (two pairs, a triple, a pair closing a loop).
fn network() -> (Springs, Blocks) {
    let mut rng = Lcg::new(7);
    let groups: [&[u32]; 4] = [&[0, 1], &[1, 2, 3], &[3, 4], &[4, 0]];
    let blocks: Blocks = groups
        .iter()
        .map(|nodes| {
            let n = 3 * nodes.len();
            let b = DMatrix::from_fn(n, n, |_, _| rng.next_value());
            let k = b.transpose() * &b + DMatrix::identity(n, n) * 0.5;
            (nodes.to_vec(), (&k + k.transpose()) * 0.5 * 1e3)
        })
        .collect();
    let rest: Vec<Real> = (0..15).map(|i| 0.1 * i as Real).collect();
    (Springs::new(rest, &[1.0; 5], &blocks), blocks)
}

/// `K` assembled densely from the blocks, independently of the library's pattern and kernels.
fn dense(blocks: &[(Vec<u32>, DMatrix<Real>)], dofs: usize) -> DMatrix<Real> {
    let mut k = DMatrix::zeros(dofs, dofs);
    for (nodes, kb) in blocks {
        for (i, &ni) in nodes.iter().enumerate() {
            for (j, &nj) in nodes.iter().enumerate() {
                for a in 0..3 {
                    for b in 0..3 {
                        k[(3 * ni as usize + a, 3 * nj as usize + b)] += kb[(3 * i + a, 3 * j + b)];
                    }
                }
            }
        }
    }
    k
}

#[test]
fn static_solve_equals_a_dense_cholesky_with_prescribed_dofs() {
    let (springs, blocks) = network();
    let k = dense(&blocks, 15);
    let mut rng = Lcg::new(11);
    let load: Vec<Real> = (0..15).map(|_| 10.0 * rng.next_value()).collect();
    for prescribed in [vec![], vec![(0, 0.01), (1, -0.02), (5, 0.0), (10, 0.03), (14, -0.015)]] {
        let solution = solve_static(&springs, &load, &prescribed).unwrap();
        // Partition: K_ff u_f = f_f − K_fp g_p, u_p = g_p.
        let fixed: Vec<usize> = prescribed.iter().map(|&(d, _)| d).collect();
        let free: Vec<usize> = (0..15).filter(|d| !fixed.contains(d)).collect();
        let mut u = DVector::zeros(15);
        for &(d, value) in &prescribed {
            u[d] = value;
        }
        let k_ff = DMatrix::from_fn(free.len(), free.len(), |i, j| k[(free[i], free[j])]);
        let rhs = DVector::from_fn(free.len(), |i, _| {
            load[free[i]] - fixed.iter().map(|&p| k[(free[i], p)] * u[p]).sum::<Real>()
        });
        let u_f = k_ff.cholesky().expect("SPD").solve(&rhs);
        for (i, &d) in free.iter().enumerate() {
            u[d] = u_f[i];
        }
        let scale = u.amax();
        let worst = (0..15).map(|d| (solution.displacement[d] - u[d]).abs()).fold(0.0, Real::max);
        println!("{} prescribed: max |u − u_dense| = {worst:.2e} (max |u| {scale:.3e})", prescribed.len());
        assert!(worst < 1e-12 * scale, "{} prescribed: {worst:e} vs {scale:e}", prescribed.len());
        for &(d, value) in &prescribed {
            assert_eq!(solution.displacement[d], value, "prescribed DOF {d}");
        }
        let energy = 0.5 * u.dot(&(&k * &u));
        assert!((solution.strain_energy - energy).abs() < 1e-12 * energy, "{} vs {energy}", solution.strain_energy);
    }
}

#[test]
fn static_solve_refuses_bad_input_with_named_values() {
    let (springs, _) = network();
    let error = solve_static(&springs, &[0.0; 14], &[]).unwrap_err();
    assert_eq!(error, StepErrorKind::LoadLength { what: "load", len: 14, dofs: 15 });
    assert_eq!(error.to_string(), "load has length 14 but the system has 15 DOFs");
    let error = solve_static(&springs, &[0.0; 15], &[(3, 0.0), (99, 0.1)]).unwrap_err();
    assert_eq!(error, StepErrorKind::DofOutOfRange { what: "prescribed", dof: 99, dofs: 15 });
    assert!(error.to_string().contains("99"), "{error}");
}

fn two_nodes() -> Springs {
    Springs::new(vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0], &[1.0, 1.0], &[(vec![0, 1], spring([10.0; 3]))])
}

#[test]
fn integrator_refuses_bad_constraints_with_named_values() {
    let springs = two_nodes();
    let settings = Settings::new(0.01);
    let build = |constraints: Constraints| Integrator::new(&springs, settings.clone(), constraints).err();

    let error = build(Constraints { pinned_dofs: vec![2, 6], ..Default::default() }).unwrap();
    assert_eq!(error.step, 0);
    assert_eq!(error.kind, StepErrorKind::DofOutOfRange { what: "pinned", dof: 6, dofs: 6 });
    assert_eq!(error.to_string(), "step 0: pinned DOF 6 is out of range (0..6)");

    let error = build(Constraints { extra_load: vec![1.0; 7], ..Default::default() }).unwrap();
    assert_eq!(error.kind, StepErrorKind::LoadLength { what: "extra load", len: 7, dofs: 6 });

    let mut outside = Embedding::new();
    outside.push_row(&[0], &[1.0]);
    outside.push_row(&[1, 2], &[0.5, 0.5]);
    let plane = PlaneCollider {
        point: Point3::origin(),
        normal: nalgebra::Vector3::z(),
        stiffness: 1e3,
        damping: 0.0,
        friction: 0.0,
    };
    let error = build(Constraints { contact_points: Some(outside.clone()), planes: vec![plane], ..Default::default() })
        .unwrap();
    assert_eq!(error.kind, StepErrorKind::NodeOutOfRange { what: "contact point", row: 1, node: 2, nodes: 2 });
    assert!(error.to_string().contains("node 2"), "{error}");

    let pins = PenaltyPins { points: outside, targets: vec![Point3::origin(); 2], stiffness: 1e3 };
    let error = build(Constraints { penalty_pins: Some(pins), ..Default::default() }).unwrap();
    assert_eq!(error.kind, StepErrorKind::NodeOutOfRange { what: "penalty pin", row: 1, node: 2, nodes: 2 });

    let mut inside = Embedding::new();
    inside.push_row(&[1], &[1.0]);
    let pins = PenaltyPins { points: inside, targets: vec![Point3::origin(); 3], stiffness: 1e3 };
    let error = build(Constraints { penalty_pins: Some(pins), ..Default::default() }).unwrap();
    assert_eq!(error.kind, StepErrorKind::PinTargets { targets: 3, points: 1 });

    // Surface contact naming a piece for some triangles only.
    let mut points = Embedding::new();
    for node in [0, 1, 0] {
        points.push_row(&[node], &[1.0]);
    }
    let surface = SurfaceContact {
        triangles: vec![[0, 1, 2]],
        on_cut: Vec::new(),
        piece: vec![0, 0],
        stiffness: 1e3,
        damping: 0.0,
        friction: 0.0,
        thickness: 0.0,
        reach: 0.01,
        edge_contact: false,
    };
    let error =
        build(Constraints { contact_points: Some(points), surface_contact: Some(surface), ..Default::default() })
            .unwrap();
    assert_eq!(error.kind, StepErrorKind::SurfacePieces { pieces: 2, triangles: 1 });

    // The kinds are distinct from the solver's catch-all.
    assert!(!matches!(error.kind, StepErrorKind::Solver(_)));
}
