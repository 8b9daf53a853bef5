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

/// The stiff cells of the crack 1e-6 h off the node plane, whose caps of 1e-19 of a tetrahedron
/// come apart as free specks: with row-sum lumping their far virtual nodes got 1e-6 of the cap's
/// mass under its whole stiffness (h² K_kk / m_k up to 9.5e17 against 2.9e11 uncut), and at
/// E = 1e12 Pa the run diverged at step 307 (ν = 0.3) or the factorization found the matrix not
/// positive definite at step 0 (ν = 0.4999). With specks lumped uniformly (`SPECK_VOLUME`) both
/// run their 600 steps within the energy criterion, the specks included.
#[test]
fn the_stiff_beam_cracked_next_to_a_node_plane_stays_stable() {
    let virtualnode = find("virtualnode").unwrap();
    let stiff_near: Vec<_> =
        cells().into_iter().filter(|c| c.case() == "cut-near-node-plane" && c.youngs_modulus == 1e12).collect();
    assert_eq!(stiff_near.len(), 2, "ν = 0.3 and 0.4999");
    for cell in stiff_near {
        let result = run_cell(virtualnode.as_ref(), "linear-tet", cell, 600);
        println!("ν = {}: {} (max energy factor {:.4})", cell.poisson_ratio, result.verdict, result.max_energy_factor);
        assert_eq!(result.verdict, Verdict::Pass, "ν = {}: {}", cell.poisson_ratio, result.verdict);
        assert_eq!(result.steps_done, 600);
    }
}

/// What the speck rule changes: on that cracked beam the 19 specks' nodes have `h² K_kk / m_k`
/// within a few times the uncut lattice's largest (a node of a uniformly lumped duplicate sees the
/// mass-to-stiffness ratio of a whole tetrahedron; measured 9.5e17 with row sums), no node of a
/// speck carries less than a tenth of the speck's mass per node (with row sums about 1e-6 of
/// it), and every piece keeps its mass `ρ V` exactly.
#[test]
fn the_nodes_of_a_speck_share_its_mass() {
    use cleave_core::{Cuttable, Discretization, Matrix3};
    use cleave_testkit::stability::CrackPlacement;
    use cleave_virtualnode::{SPECK_VOLUME, VirtualNodeMesh};
    let grid = beam_grid();
    let material = Material::new(1e12, 0.4999, DENSITY).unwrap();
    let h: Real = 1.0 / 60.0;
    let tet = grid.h.powi(3) / 12.0;
    let ratios = |placement: Option<CrackPlacement>| {
        let mut mesh = VirtualNodeMesh::from_box(grid.origin, grid.max_corner(), grid.h, material).unwrap();
        if let Some(placement) = placement {
            mesh.cut(&placement.surface(&grid)).unwrap();
        }
        let mut diag = vec![Matrix3::zeros(); mesh.num_nodes()];
        mesh.blocks().add_diagonal_blocks(&vec![Matrix3::identity(); mesh.num_frames()], 1.0, &mut diag);
        let mass = mesh.mass().diagonal();
        let pieces = mesh.pieces();
        for piece in &pieces {
            let m: Real = piece.nodes.iter().map(|&n| mass[3 * n as usize]).sum();
            assert!(
                (m / (DENSITY * piece.volume) - 1.0).abs() < 1e-9,
                "piece mass {m} vs ρV {}",
                DENSITY * piece.volume
            );
        }
        let specks: Vec<u32> =
            pieces.iter().filter(|p| p.volume < SPECK_VOLUME * tet).flat_map(|p| p.nodes.iter().copied()).collect();
        for speck in pieces.iter().filter(|p| p.volume < SPECK_VOLUME * tet) {
            let per_node = DENSITY * speck.volume / speck.nodes.len() as Real;
            let lightest = speck.nodes.iter().map(|&n| mass[3 * n as usize]).fold(Real::INFINITY, Real::min);
            assert!(lightest > 0.1 * per_node, "a speck's node has {lightest:e} kg of {per_node:e} per node");
        }
        let ratio = |k: usize| h * h * diag[k].norm() / mass[3 * k];
        let largest = (0..mesh.num_nodes()).map(ratio).fold(0.0, Real::max);
        let speck_largest = specks.iter().map(|&k| ratio(k as usize)).fold(0.0, Real::max);
        (largest, specks.len(), speck_largest)
    };
    let (uncut, none, _) = ratios(None);
    assert_eq!(none, 0, "the uncut beam has no speck");
    let (_, speck_nodes, speck_largest) = ratios(Some(CrackPlacement::NearNodePlane));
    println!("largest h² K_kk / m_k: uncut {uncut:.3e}, on the {speck_nodes} nodes of specks {speck_largest:.3e}");
    assert!(speck_nodes >= 19 * 4, "{speck_nodes} nodes in specks");
    assert!(speck_largest < 4.0 * uncut, "{speck_largest:.3e} against {uncut:.3e} uncut");
}
