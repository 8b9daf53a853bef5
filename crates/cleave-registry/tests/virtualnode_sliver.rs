//! The sliver case of the stability suite for virtual node tetrahedra: the beam cracked by a
//! plane 1e-5 h from a lattice node plane. Checked against independent numbers: the smallest
//! region is at most 1e-9 of a lattice tetrahedron's volume h³/12 (benchmarks.md §4's sliver),
//! the crack separates nothing (one piece) and keeps the box's volume, and the cell runs through
//! the harness on that mesh (not on the uncut box) to a verdict.

use cleave_core::{Material, Real};
use cleave_registry::{SLIVER_OFFSET, find, sliver_beam};
use cleave_testkit::compare::ExtremeCase;
use cleave_testkit::stability::{DENSITY, Verdict, beam_grid, cells, run_cell};

#[test]
fn the_cracked_beam_has_a_region_below_1e9_of_a_tet_and_stays_one_piece() {
    let grid = beam_grid();
    let material = Material::new(1e6, 0.3, DENSITY).unwrap();
    let mesh = sliver_beam(&material, &grid).unwrap();
    let tet = grid.h.powi(3) / 12.0;
    let volumes = mesh.duplicate_volumes();
    let smallest = volumes.iter().copied().fold(Real::INFINITY, Real::min);
    let below: Vec<Real> = volumes.iter().copied().filter(|&v| v <= 1e-9 * tet).collect();
    println!(
        "crack at {SLIVER_OFFSET:e} h: {} duplicates, smallest region {:.3e} of a tet, {} regions ≤ 1e-9 of a tet",
        volumes.len(),
        smallest / tet,
        below.len()
    );
    assert!(smallest > 0.0, "every region has positive volume");
    assert!(smallest <= 1e-9 * tet, "smallest region {:.3e} of a tet", smallest / tet);
    // A cap at a lattice node on the node plane: the corner of a tetrahedron cut off by a plane at
    // distance δ = 1e-5 h has volume ∝ δ³, so it is far below 1e-9 (measured 2.0e-15).
    assert!(smallest / tet < 1e-12, "smallest region {:.3e} of a tet", smallest / tet);
    let box_volume = (0..3).map(|a| grid.dims[a] as Real * grid.h).product::<Real>();
    assert!((mesh.volume() / box_volume - 1.0).abs() < 1e-12, "volume {} vs {box_volume}", mesh.volume());
    assert_eq!(mesh.pieces().len(), 1, "a crack through part of the height separates nothing");
}

#[test]
fn the_sliver_cell_runs_on_the_cracked_beam() {
    let virtualnode = find("virtualnode").unwrap();
    let grid = beam_grid();
    let material = Material::new(1e6, 0.3, DENSITY).unwrap();
    let clamp = |p: &cleave_core::Point3<Real>| p.x.abs() < 1e-9;
    let dirichlet =
        cleave_testkit::compare::DirichletSpec { region: &clamp, value: &|_| cleave_core::Vector3::zeros() };
    let uncut = virtualnode.build_box("linear-tet", &material, &grid, &dirichlet).unwrap();
    let built = virtualnode
        .build_extreme("linear-tet", ExtremeCase::Sliver, &material, &grid, &dirichlet)
        .unwrap()
        .expect("the sliver case builds its own (cracked) beam");
    // The crack duplicated the tetrahedra it crosses.
    assert!(built.elements > uncut.elements, "{} vs {} elements", built.elements, uncut.elements);
    let start = virtualnode.extreme_start("linear-tet", ExtremeCase::Sliver, &built, &grid).unwrap();
    assert_eq!(start, built.discretization.rest_dofs(), "the sliver beam starts at rest");

    let sliver = cells().into_iter().find(|c| c.case() == "sliver").unwrap();
    let result = run_cell(virtualnode.as_ref(), "linear-tet", sliver, 60);
    println!("sliver, 60 steps: {} (max energy factor {:.4})", result.verdict, result.max_energy_factor);
    assert!(!matches!(result.verdict, Verdict::NotApplicable(_) | Verdict::Error(_)), "{}", result.verdict);
    assert_eq!(result.verdict, Verdict::Pass, "{}", result.verdict);
    assert_eq!(result.steps_done, 60);
}
