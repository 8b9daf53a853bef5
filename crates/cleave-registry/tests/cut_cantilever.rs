//! The cut cantilever of benchmarks.md §5 through the registrations: the voxel crack's duplicated
//! DOFs against counts made by hand, and for every backend that cuts, the cracked beam against the uncut one (softer: more strain energy for the
//! same load, since ½fᵀu = max over v of fᵀv − ½vᵀKv and removing coupling lowers K; the crack
//! opens because gravity bends the top fibres into tension).

use cleave_core::{Point3, Real, Vector3};
use cleave_registry::registered;
use cleave_testkit::compare::{DirichletSpec, Problem, run_problem};
use cleave_testkit::problems::cantilever;

#[test]
fn every_cutting_backend_is_softer_cut_and_its_crack_opens() {
    let cutting: Vec<_> = registered()
        .into_iter()
        .flat_map(|b| b.variants().into_iter().map(move |v| (b.name().to_string(), v)))
        .filter(|(b, v)| cleave_registry::find(b).unwrap().cuts(v))
        .collect();
    // Every backend that can cut takes part (its capabilities are read off what it builds).
    for b in registered().iter().filter(|b| b.capabilities().cut) {
        assert!(cutting.iter().any(|(name, _)| name == b.name()), "{} cuts but runs no cut cantilever", b.name());
    }
    assert!(!cutting.is_empty());
    for (name, variant) in &cutting {
        let backend = cleave_registry::find(name).unwrap();
        let n = 2;
        let uncut = run_problem(backend.as_ref(), variant, Problem::Cantilever, n).unwrap();
        let cut = run_problem(backend.as_ref(), variant, Problem::CutCantilever, n).unwrap();
        let (e0, e1) = (uncut.strain_energy.unwrap(), cut.strain_energy.unwrap());
        assert!(e1 > 1.01 * e0, "{name}: cut energy {e1} vs uncut {e0}");
        assert!(cut.tip_uz_avg.unwrap() < uncut.tip_uz_avg.unwrap(), "{name}: the cut tip must sink further");
        let opening = cut.crack_opening.unwrap();
        assert!(opening > 0.0, "{name}: opening {opening}");
        if name == "voxel" {
            // By hand: the (n + 1) · n/2 nodes on x = 2 above the front are duplicated.
            assert_eq!(cut.dofs - uncut.dofs, 3 * (n + 1) * n / 2);
        }
        // The cut is applied to the uncut box of `build_box`: same lattice, same DOFs before.
        let grid = Problem::Cantilever.grid(n);
        let material = cantilever::material(0.3);
        let clamp = |p: &Point3<Real>| p.x.abs() < 1e-9;
        let dirichlet = DirichletSpec { region: &clamp, value: &|_| Vector3::zeros() };
        let built = backend.build_box(variant, &material, &grid, &dirichlet).unwrap();
        assert_eq!(3 * built.discretization.num_nodes(), uncut.dofs);
    }
}

#[test]
fn the_dynamic_cut_adds_no_energy_keeps_momentum_and_settles_on_the_static_cracked_beam() {
    for (name, variant) in [("voxel", "trilinear"), ("virtualnode", "linear-tet")] {
        let backend = cleave_registry::find(name).unwrap();
        let n = 2;
        let dynamic = run_problem(backend.as_ref(), variant, Problem::CutDynamic, n).unwrap();
        let statics = run_problem(backend.as_ref(), variant, Problem::CutCantilever, n).unwrap();
        let (before, after) = (dynamic.energy_before_cut.unwrap(), dynamic.energy_after_cut.unwrap());
        // Conservation across the cut: the state is carried exactly, so only rounding may differ.
        assert!(after - before <= 1e-12 * before.abs(), "{name}: {before} J -> {after} J");
        assert!(dynamic.energy_max_after_cut.unwrap() - before <= 1e-12 * before.abs(), "{name}: energy rose later");
        assert!(dynamic.momentum_change.unwrap() <= 1e-12 * dynamic.momentum_before_cut.unwrap(), "{name}");
        // Settled by 4 s on the static cracked deflection scaled by E_static / E_dynamic.
        let scaled = statics.tip_uz_avg.unwrap() * 1e-2;
        let settle = (dynamic.tip_uz_avg.unwrap() - scaled) / scaled;
        assert!(settle.abs() < 0.01, "{name}: {settle}");
    }
}
