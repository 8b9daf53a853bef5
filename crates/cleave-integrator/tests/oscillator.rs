//! The step against the damped oscillator `m ü = −k u − c u̇ + m g`, one per axis of a node tied
//! to a pinned node by a spring block: the trajectory equals the exact recurrence of backward
//! Euler (docs/math/corotated-integrator.md, "The step"), the reported energy falls by exactly
//! what backward Euler dissipates, and the trajectory converges to the continuous solution at
//! order 1 as h → 0.

mod common;

use cleave_core::{Discretization, Real, Vector3};
use cleave_integrator::{Constraints, Integrator, Settings, Solver};
use common::{Springs, spring};

const MASS: Real = 2.0;
const STIFFNESS: [Real; 3] = [50.0, 200.0, 80.0];
const ALPHA: Real = 0.1;
const BETA: Real = 0.002;
const GRAVITY: [Real; 3] = [0.0, 1.5, -9.81];
const U0: [Real; 3] = [0.1, -0.05, 0.02];
const V0: [Real; 3] = [0.0, 0.3, -0.2];

/// Node 0 (pinned, mass 5) at (0.3, −0.2, 1.0), node 1 (mass `MASS`) at (1.3, 0.4, 1.1), one
/// spring block between them.
fn oscillator() -> Springs {
    let rest = vec![0.3, -0.2, 1.0, 1.3, 0.4, 1.1];
    Springs::new(rest, &[5.0, MASS], &[(vec![0, 1], spring(STIFFNESS))])
}

/// Rayleigh damping `c = α m + β k` of axis `a`.
fn damping(a: usize) -> Real {
    ALPHA * MASS + BETA * STIFFNESS[a]
}

fn integrator(springs: &Springs, h: Real, solver: Solver) -> Integrator {
    let mut settings = Settings::new(h);
    settings.gravity = Vector3::from(GRAVITY);
    settings.rayleigh_alpha = ALPHA;
    settings.rayleigh_beta = BETA;
    settings.solver = solver;
    let constraints = Constraints { pinned_dofs: vec![0, 1, 2], ..Default::default() };
    let mut integrator = Integrator::new(springs, settings, constraints).unwrap();
    let mut x = springs.rest_dofs().to_vec();
    let mut v = vec![0.0; 6];
    x[3..].iter_mut().zip(U0).for_each(|(x, u)| *x += u);
    v[3..].copy_from_slice(&V0);
    integrator.set_state(springs, x, v);
    integrator
}

const SOLVERS: [Solver; 3] = [
    Solver::Cholesky,
    Solver::ConjugateGradient { tolerance: 1e-14, max_iterations: 50, assembled: false },
    Solver::ConjugateGradient { tolerance: 1e-14, max_iterations: 50, assembled: true },
];

#[test]
fn steps_follow_the_exact_backward_euler_recurrence() {
    // (m + h c + h² k) v⁺ = m v + h (−k u + m g),  u⁺ = u + h v⁺, per axis, from the step's
    // equation with M = m, K_R = k (no frames), D = α m + β k.
    let springs = oscillator();
    let h = 0.01;
    for solver in SOLVERS {
        let mut integrator = integrator(&springs, h, solver);
        let (mut u, mut v) = (U0, V0);
        let mut worst: Real = 0.0;
        for step in 0..300 {
            integrator.step(&springs).unwrap();
            for a in 0..3 {
                let k = STIFFNESS[a];
                v[a] = (MASS * v[a] + h * (-k * u[a] + MASS * GRAVITY[a])) / (MASS + h * damping(a) + h * h * k);
                u[a] += h * v[a];
            }
            let x = integrator.positions();
            let velocity = integrator.velocities();
            for a in 0..3 {
                let du = (x[3 + a] - springs.rest_dofs()[3 + a] - u[a]).abs();
                let dv = (velocity[3 + a] - v[a]).abs();
                worst = worst.max(du / 0.1).max(dv / 1.0);
                assert!(du < 1e-12 * 0.1 && dv < 1e-12, "{solver:?} step {step} axis {a}: Δu {du:e}, Δv {dv:e}");
                // The pinned node never moves.
                assert_eq!(x[a], springs.rest_dofs()[a]);
                assert_eq!(velocity[a], 0.0);
            }
        }
        println!("{solver:?}: largest deviation from the recurrence {worst:.2e} (relative to 0.1 m, 1 m/s)");
    }
}

#[test]
fn reported_energy_falls_by_exactly_what_backward_euler_dissipates() {
    // Multiplying m (v⁺ − v) = −h k u⁺ − h c v⁺ + h m g by v⁺ gives, per axis,
    // E⁺ − E = −h c v⁺² − ½ m (v⁺ − v)² − ½ k (u⁺ − u)²  with  E = ½ m v² + ½ k u² − m g·x
    // (the report's kinetic + elastic + gravitational energy), an identity of the scheme.
    let springs = oscillator();
    let h = 1.0 / 60.0;
    let mut integrator = integrator(&springs, h, Solver::Cholesky);
    let mut before = integrator.energies(&springs).total_energy();
    let mut x_old = integrator.positions().to_vec();
    let mut v_old = integrator.velocities().to_vec();
    for step in 0..200 {
        let report = integrator.step(&springs).unwrap();
        let (x, v) = (integrator.positions(), integrator.velocities());
        let dissipated: Real = (0..3)
            .map(|a| {
                let (vp, dv, du) = (v[3 + a], v[3 + a] - v_old[3 + a], x[3 + a] - x_old[3 + a]);
                h * damping(a) * vp * vp + 0.5 * MASS * dv * dv + 0.5 * STIFFNESS[a] * du * du
            })
            .sum();
        let after = report.total_energy();
        let scale = report.kinetic_energy + report.elastic_energy + dissipated;
        assert!(
            (after - before + dissipated).abs() < 1e-11 * scale.max(1e-3),
            "step {step}: ΔE = {:e}, dissipated {dissipated:e}",
            after - before
        );
        assert!(dissipated > 0.0);
        before = after;
        x_old = x.to_vec();
        v_old = v.to_vec();
    }
}

/// The continuous solution of axis `a` at time `t`: displacement `u(t)` (equilibrium `m g / k`
/// plus the underdamped decay) and velocity `u̇(t)`.
fn continuous(a: usize, t: Real) -> (Real, Real) {
    let (m, k, c) = (MASS, STIFFNESS[a], damping(a));
    let equilibrium = m * GRAVITY[a] / k;
    let omega = (k / m).sqrt();
    let sigma = c / (2.0 * m);
    let omega_d = (omega * omega - sigma * sigma).sqrt();
    let w0 = U0[a] - equilibrium;
    let b = (V0[a] + sigma * w0) / omega_d;
    let (decay, cos, sin) = ((-sigma * t).exp(), (omega_d * t).cos(), (omega_d * t).sin());
    let u = equilibrium + decay * (w0 * cos + b * sin);
    let v = decay * ((b * omega_d - sigma * w0) * cos - (sigma * b + w0 * omega_d) * sin);
    (u, v)
}

/// Energy about the equilibrium, `½ m v² + ½ k (u − m g / k)²`, of axis `a`.
fn oscillation_energy(a: usize, u: Real, v: Real) -> Real {
    let w = u - MASS * GRAVITY[a] / STIFFNESS[a];
    0.5 * MASS * v * v + 0.5 * STIFFNESS[a] * w * w
}

#[test]
fn trajectory_converges_to_the_continuous_solution_at_order_one() {
    // Largest |u_n − u(t_n)| over t ∈ [0, T = 1 s] and the three axes, for h = 1/100 … 1/1600:
    // backward Euler is first order, so halving h halves the error. Its leading error is
    // numerical damping: per unit time the amplification 1/(1 − hλ) = exp(hλ + h²λ²/2 + …)
    // adds −h ω²/2 to the decay rate, so the discrete oscillation decays below the continuous
    // envelope and its energy at T is the continuous one times exp(−h ω² T) per axis.
    let springs = oscillator();
    let t_end = 1.0;
    let mut rows = Vec::new();
    for steps in [100, 200, 400, 800, 1600] {
        let h = t_end / steps as Real;
        let mut integrator = integrator(&springs, h, Solver::Cholesky);
        let mut worst: Real = 0.0;
        for n in 1..=steps {
            integrator.step(&springs).unwrap();
            let t = n as Real * h;
            for a in 0..3 {
                let u = integrator.positions()[3 + a] - springs.rest_dofs()[3 + a];
                worst = worst.max((u - continuous(a, t).0).abs());
            }
        }
        let (x, v) = (integrator.positions(), integrator.velocities());
        let discrete: Real =
            (0..3).map(|a| oscillation_energy(a, x[3 + a] - springs.rest_dofs()[3 + a], v[3 + a])).sum();
        let exact: Real = (0..3).map(|a| oscillation_energy(a, continuous(a, t_end).0, continuous(a, t_end).1)).sum();
        let predicted: Real = (0..3)
            .map(|a| {
                let (u, v) = continuous(a, t_end);
                oscillation_energy(a, u, v) * (1.0 - (-h * STIFFNESS[a] / MASS * t_end).exp())
            })
            .sum();
        rows.push((h, worst, discrete, exact, predicted));
    }
    for (h, worst, discrete, exact, predicted) in &rows {
        println!(
            "h = {h:.6}: max |u − u(t)| {worst:.4e} m, energy at T {discrete:.6e} J vs continuous {exact:.6e} J \
             (lost {:.4e}, predicted {predicted:.4e})",
            exact - discrete
        );
    }
    let rates: Vec<Real> = rows.windows(2).map(|w| (w[0].1 / w[1].1).log2()).collect();
    println!("rates {rates:?}");
    for w in rows.windows(2) {
        assert!(w[1].1 < w[0].1, "the error must shrink with h: {rows:?}");
    }
    let last = *rates.last().unwrap();
    assert!((last - 1.0).abs() < 0.05, "rate {last} at the finest pair, expected 1: {rows:?}");
    for &(h, _, discrete, exact, predicted) in &rows {
        // Below the continuous energy, by the numerical damping's share.
        assert!(discrete < exact, "h = {h}: {discrete} vs {exact}");
        let ratio = (exact - discrete) / predicted;
        assert!((ratio - 1.0).abs() < 0.01, "h = {h}: energy lost {:e}, predicted {predicted:e}", exact - discrete);
    }
}
