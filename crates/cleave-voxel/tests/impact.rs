//! The static analysis of an impact on a free body (`solve_inertia_relief`, mueller2004 §2.4;
//! docs/math/rigid-fragments.md §5) on a voxel bar, against the bar's analytic stress: a force
//! pushing one end of a free bar accelerates it, and the D'Alembert force of that acceleration,
//! spread over the bar's mass, leaves the axial stress falling linearly from the loaded end to
//! zero at the free one, `σ(x) = −(F / A)(1 − x / L)`.

use cleave_core::{Discretization, Material, Point3, Real, Vector3};
use cleave_integrator::{StepErrorKind, solve_inertia_relief};
use cleave_voxel::VoxelMesh;

const LENGTH: Real = 1.0;
const WIDTH: Real = 0.1;
const CUBE: Real = 0.05;
const YOUNG: Real = 1e6;

/// A free bar of 20 × 2 × 2 cubes along x.
fn bar() -> VoxelMesh {
    let cells: Vec<[i32; 3]> = (0..2).flat_map(|z| (0..2).flat_map(move |y| (0..20).map(move |x| [x, y, z]))).collect();
    VoxelMesh::new(Material::new(YOUNG, 0.3, 1000.0).unwrap(), Point3::origin(), CUBE, &cells).unwrap()
}

/// The load of a uniform pressure on the end x = 0 totalling `force` (each node of the 2 × 2
/// square's grid its share of area: corners ¼, edges ½, the centre 1, in units of a cube
/// face's quarter).
fn end_load(bar: &VoxelMesh, force: Vector3<Real>) -> Vec<Real> {
    let rest = bar.rest_dofs();
    let mut load = vec![0.0; rest.len()];
    let share = |c: Real| if c.abs() < 1e-9 || (c - WIDTH).abs() < 1e-9 { 0.5 } else { 1.0 };
    let mut total = 0.0;
    for n in 0..bar.num_nodes() {
        if rest[3 * n].abs() < 1e-9 {
            let w = share(rest[3 * n + 1]) * share(rest[3 * n + 2]);
            total += w;
            for a in 0..3 {
                load[3 * n + a] = w * force[a];
            }
        }
    }
    load.iter_mut().for_each(|f| *f /= total);
    load
}

/// The mean axial strain between the cross-sections at `x0` and `x1`.
fn axial_strain(bar: &VoxelMesh, u: &[Real], x0: Real, x1: Real) -> Real {
    let rest = bar.rest_dofs();
    let mean = |x: Real| {
        let nodes: Vec<usize> = (0..bar.num_nodes()).filter(|&n| (rest[3 * n] - x).abs() < 1e-9).collect();
        nodes.iter().map(|&n| u[3 * n]).sum::<Real>() / nodes.len() as Real
    };
    (mean(x1) - mean(x0)) / (x1 - x0)
}

#[test]
fn a_push_on_one_end_of_a_free_bar_leaves_the_stress_falling_linearly_to_the_other() {
    let bar = bar();
    let force = 50.0;
    let load = end_load(&bar, Vector3::new(force, 0.0, 0.0));
    let everything: Vec<u32> = (0..bar.num_nodes() as u32).collect();
    let solution = solve_inertia_relief(&bar, &load, &[everything]).unwrap();
    let u = &solution.displacement;
    // Uniaxial: ε(x) = σ(x) / E; the mean over the two cubes about x = L/4, L/2, 3L/4 (exact
    // for a linear stress).
    for (x, expected_fraction) in [(0.25, 0.75), (0.5, 0.5), (0.75, 0.25)] {
        let expected = -force / (WIDTH * WIDTH * YOUNG) * expected_fraction;
        let strain = axial_strain(&bar, u, x - CUBE, x + CUBE);
        println!("x = {x}: strain {strain:.4e}, analytic {expected:.4e}");
        assert!((strain - expected).abs() < 1e-3 * expected.abs(), "x = {x}: {strain} vs {expected}");
    }
    // The support takes nothing: the strain energy is that of the analytic field,
    // ∫ σ² A / (2E) dx = F² L / (6 E A).
    let analytic = force * force * LENGTH / (6.0 * YOUNG * WIDTH * WIDTH);
    println!("strain energy {:.4e}, analytic {analytic:.4e}", solution.strain_energy);
    assert!((solution.strain_energy - analytic).abs() < 2e-3 * analytic);
}

/// Two bars in one mesh, a gap of one cube between them; a tilted push on the first's end.
/// The second, listed as no body, is held at rest; the first's strain does not depend on
/// which of its nodes hold it (the D'Alembert load is in equilibrium, so a support's reactions
/// vanish): the same load, relieved here by hand, solved with another 3-2-1 support (three
/// corners) has the same strain energy.
#[test]
fn a_body_left_out_is_held_and_the_support_takes_no_load() {
    let cells: Vec<[i32; 3]> =
        (0..2).flat_map(|z| (0..2).flat_map(move |y| (0..21).filter(|&x| x != 10).map(move |x| [x, y, z]))).collect();
    let bars = VoxelMesh::new(Material::new(YOUNG, 0.3, 1000.0).unwrap(), Point3::origin(), CUBE, &cells).unwrap();
    let push = Vector3::new(30.0, -12.0, 7.0);
    let load = end_load(&bars, push);
    let rest = bars.rest_dofs().to_vec();
    let (first, second): (Vec<u32>, Vec<u32>) =
        (0..bars.num_nodes() as u32).partition(|&n| rest[3 * n as usize] < 0.52);
    let relieved = solve_inertia_relief(&bars, &load, std::slice::from_ref(&first)).unwrap();
    assert!(second.iter().all(|&n| (0..3).all(|a| relieved.displacement[3 * n as usize + a] == 0.0)));
    assert!(relieved.strain_energy > 0.0);

    // By hand: f_i − m_i (a + α × r_i), then corners (0,0,0) in x, y, z; (0.5,0,0) in y, z;
    // (0,0.1,0) in z (the turn about the bar's axis moves it along z).
    let mass = bars.mass().diagonal().to_vec();
    let at = |v: &[Real], n: u32| Vector3::new(v[3 * n as usize], v[3 * n as usize + 1], v[3 * n as usize + 2]);
    let total: Real = first.iter().map(|&n| mass[3 * n as usize]).sum();
    let centre = first.iter().map(|&n| mass[3 * n as usize] * at(&rest, n)).sum::<Vector3<Real>>() / total;
    let (mut force, mut moment, mut inertia) = (Vector3::zeros(), Vector3::zeros(), nalgebra::Matrix3::zeros());
    for &n in &first {
        let r = at(&rest, n) - centre;
        force += at(&load, n);
        moment += r.cross(&at(&load, n));
        inertia += mass[3 * n as usize] * (nalgebra::Matrix3::identity() * r.norm_squared() - r * r.transpose());
    }
    let (a, alpha) = (force / total, inertia.try_inverse().unwrap() * moment);
    let mut by_hand = load.clone();
    for &n in &first {
        let inertial = mass[3 * n as usize] * (a + alpha.cross(&(at(&rest, n) - centre)));
        (0..3).for_each(|k| by_hand[3 * n as usize + k] -= inertial[k]);
    }
    let node_at = |p: Vector3<Real>| (0..bars.num_nodes()).find(|&n| (at(&rest, n as u32) - p).norm() < 1e-9).unwrap();
    let (c0, c1, c2) =
        (node_at(Vector3::zeros()), node_at(Vector3::new(0.5, 0.0, 0.0)), node_at(Vector3::new(0.0, WIDTH, 0.0)));
    let mut prescribed = vec![(3 * c0, 0.0), (3 * c0 + 1, 0.0), (3 * c0 + 2, 0.0)];
    prescribed.extend([(3 * c1 + 1, 0.0), (3 * c1 + 2, 0.0), (3 * c2 + 2, 0.0)]);
    prescribed.extend(second.iter().flat_map(|&n| (0..3).map(move |k| (3 * n as usize + k, 0.0))));
    let corners = cleave_integrator::solve_static(&bars, &by_hand, &prescribed).unwrap();
    println!("strain energy: support chosen {:.9e}, corners {:.9e}", relieved.strain_energy, corners.strain_energy);
    assert!((relieved.strain_energy - corners.strain_energy).abs() < 1e-9 * corners.strain_energy);

    // Bodies must be disjoint.
    assert!(matches!(
        solve_inertia_relief(&bars, &load, &[first.clone(), first.clone()]),
        Err(StepErrorKind::OverlappingBodies { .. })
    ));
    // A body with its nodes on one line has no inertia to balance a load with.
    let line: Vec<u32> =
        first.iter().copied().filter(|&n| rest[3 * n as usize + 1] == 0.0 && rest[3 * n as usize + 2] == 0.0).collect();
    assert!(matches!(solve_inertia_relief(&bars, &load, &[line]), Err(StepErrorKind::SingularBody { body: 0, .. })));
}
