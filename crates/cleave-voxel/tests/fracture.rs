//! Stress fracture of the voxel mesh (mueller2004 §2.3): a notched bar pulled at both ends breaks
//! across its neck, where the stress is largest, and nowhere else; a fracture changes no node's
//! position or velocity (the gather carries them) and keeps mass; nothing breaks below the
//! strength.

use cleave_core::{Cuttable, Discretization, Fracturable, Material, Matrix3, Point3, Real, Vector3};
use cleave_integrator::solve_static;
use cleave_voxel::VoxelMesh;

/// A bar of 20 × 4 × 4 cubes of 0.05 m whose column x = 10 keeps only its lower half (z < 2).
fn notched_bar() -> VoxelMesh {
    let mut cells = Vec::new();
    for z in 0..4 {
        for y in 0..4 {
            for x in 0..20 {
                if !(x == 10 && z >= 2) {
                    cells.push([x, y, z]);
                }
            }
        }
    }
    VoxelMesh::new(Material::new(1e6, 0.3, 1000.0).unwrap(), Point3::origin(), 0.05, &cells).unwrap()
}

#[test]
fn a_notched_bar_pulled_apart_breaks_across_its_neck_and_nowhere_else() {
    let mut bar = notched_bar();
    // Ends held: x = 0 fixed, x = 1 pulled 1 mm along x; the static state of the current bar.
    let state = |bar: &VoxelMesh| -> Vec<Real> {
        let rest = bar.rest_dofs();
        let prescribed: Vec<(usize, Real)> = (0..bar.num_nodes())
            .flat_map(|n| {
                let x = rest[3 * n];
                let end = if x < 1e-9 {
                    Some(0.0)
                } else if x > 1.0 - 1e-9 {
                    Some(1e-3)
                } else {
                    None
                };
                end.into_iter().flat_map(move |u| (0..3).map(move |a| (3 * n + a, if a == 0 { u } else { 0.0 })))
            })
            .collect();
        let zero = vec![0.0; 3 * bar.num_nodes()];
        let solution = solve_static(bar, &zero, &prescribed).unwrap();
        rest.iter().zip(&solution.displacement).map(|(r, u)| r + u).collect()
    };
    let x = state(&bar);
    let rest = bar.rest_dofs().to_vec();
    let rotations = vec![Matrix3::identity(); bar.num_cubes()];
    // The stress the criterion reads (smoothed over each cube's neighbours), far from the neck
    // (columns 3 to 6) and the largest anywhere.
    let smoothed = bar.smoothed_stresses(&x, &rotations);
    let stress = |cube: usize| smoothed[cube].symmetric_eigen().eigenvalues.max();
    let far = (0..bar.num_cubes()).filter(|&c| (3..=6).contains(&bar.cells()[c][0])).map(stress).fold(0.0, Real::max);
    let peak = (0..bar.num_cubes()).map(stress).fold(0.0, Real::max);
    println!("far-field stress {far:.1} Pa, peak {peak:.1} Pa (E δ / L = {:.1} Pa)", 1e6 * 1e-3);
    assert!(peak > 1.15 * far, "the neck concentrates the stress");
    // Below the strength: nothing breaks.
    assert!(bar.fracture(&x, &rotations, 1.01 * peak).unwrap().is_none());
    // Between the far field and the peak: the crack starts at the neck and, solved again after
    // each fracture as a run would, grows across it until the bar is in two.
    let strength = 0.5 * (far + peak);
    // The same stretched bar turned about a skew axis and moved, with the frames the integrator
    // would extract: the corotated stress, and so the faces it breaks, are the same.
    let motion = nalgebra::Isometry3::new(Vector3::new(0.3, -1.2, 2.5), Vector3::new(0.4, -0.7, 0.9));
    let moved: Vec<Real> = x
        .chunks_exact(3)
        .flat_map(|p| {
            let q = motion * Point3::new(p[0], p[1], p[2]);
            [q.x, q.y, q.z]
        })
        .collect();
    let mut frames = vec![Matrix3::identity(); bar.num_cubes()];
    bar.write_rotations(&moved, &mut frames);
    let mut turned = notched_bar();
    turned.fracture(&moved, &frames, strength).unwrap().expect("the turned neck breaks");
    let change = bar.fracture(&x, &rotations, strength).unwrap().expect("the neck breaks");
    assert_eq!(turned.cut_faces(), bar.cut_faces(), "a rigid motion changes what breaks");
    // The gather carries every node's position: each new node is where its source was.
    let cleave_core::DofRemap::Gather(source) = &change.remap else { panic!("a gather") };
    let after = bar.rest_dofs();
    for (n, &s) in source.iter().enumerate() {
        for a in 0..3 {
            assert_eq!(after[3 * n + a], rest[3 * s as usize + a]);
        }
    }
    let mut rounds = 1;
    while bar.pieces().len() < 2 && rounds < 6 {
        let x = state(&bar);
        let rotations = vec![Matrix3::identity(); bar.num_cubes()];
        bar.fracture(&x, &rotations, strength).unwrap();
        rounds += 1;
    }
    let faces = bar.cut_faces();
    println!("{} faces separated in {rounds} rounds: {faces:?}", faces.len());
    assert_eq!(bar.pieces().len(), 2, "the neck breaks through");
    // Nowhere else: every separated face lies at the neck (its cube within a column of it).
    assert!(faces.iter().all(|f| (9..=10).contains(&f.cell[0])), "{faces:?}");
    let mass: Real = bar.pieces().iter().map(|p| p.mass).sum();
    assert!((mass - 1000.0 * 0.05f64.powi(3) * (320 - 8) as Real).abs() < 1e-12 * mass);
}

/// Cubes that touch at one corner or one edge share those nodes, so they move together: one
/// piece, and every node in exactly one piece (a rigid hand-off trusts this; the pieces were
/// once found through faces alone, and such a corner node lay in two of them).
#[test]
fn cubes_touching_at_a_corner_or_an_edge_are_one_piece() {
    let material = Material::new(1e6, 0.3, 1000.0).unwrap();
    for cells in [vec![[0, 0, 0], [1, 1, 1]], vec![[0, 0, 0], [1, 1, 0]], vec![[0, 0, 0], [2, 0, 0]]] {
        let body = VoxelMesh::new(material, Point3::origin(), 0.1, &cells).unwrap();
        let shared = cells[1].iter().zip(&cells[0]).all(|(a, b)| (a - b).abs() <= 1);
        let pieces = body.pieces();
        assert_eq!(pieces.len(), if shared { 1 } else { 2 }, "{cells:?}");
        let mut count = vec![0; body.num_nodes()];
        pieces.iter().flat_map(|p| &p.nodes).for_each(|&n| count[n as usize] += 1);
        assert!(count.iter().all(|&c| c == 1), "{cells:?}: {count:?}");
    }
}
