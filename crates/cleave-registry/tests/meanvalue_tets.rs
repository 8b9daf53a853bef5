//! On a mesh of tetrahedra the mean value element is linear FEM (wicke2007 §3, mean-value.md
//! §6.6): every block of the virtual node backend's box (linear tetrahedra of the BCC lattice,
//! the boundary ones carved) equals the mean value stiffness of the same tetrahedron, scaled by
//! the carved fraction of its volume (1 for whole tetrahedra), to round-off.

use cleave_core::{Material, Point3, Real};
use cleave_meanvalue::{ConvexPolyhedron, ElementIntegrals};
use cleave_registry::find;
use cleave_testkit::compare::{BoxGrid, DirichletSpec};

#[test]
fn the_mean_value_stiffness_of_a_tetrahedron_is_the_virtual_node_backends() {
    let material = Material::new(1e6, 0.3, 1000.0).unwrap();
    let (lambda, mu) = material.lame();
    let grid = BoxGrid { origin: Point3::new(0.1, -0.2, 0.3), h: 0.25, dims: [4, 2, 2] };
    let backend = find("virtualnode").unwrap();
    let built = backend.build_box("linear-tet", &material, &grid, &DirichletSpec::none()).unwrap();
    let d = built.discretization.as_ref();
    let rest = d.rest_dofs();
    let point = |n: u32| Point3::new(rest[3 * n as usize], rest[3 * n as usize + 1], rest[3 * n as usize + 2]);
    let blocks = d.blocks();
    let (mut whole, mut worst): (usize, Real) = (0, 0.0);
    for b in 0..blocks.len() {
        let block = blocks.block(b);
        assert_eq!(block.nodes.len(), 4, "an uncut virtual node box has tetrahedral blocks");
        let points: [Point3<Real>; 4] = std::array::from_fn(|c| point(block.nodes[c]));
        let tet = ConvexPolyhedron::tetrahedron(points).unwrap();
        let reference = ElementIntegrals::new(&tet, 0).stiffness(lambda, mu);
        let fraction = block.rest.dot(&reference) / reference.norm_squared();
        let difference = (block.rest - &reference * fraction).amax() / block.rest.amax();
        worst = worst.max(difference);
        assert!(fraction > 0.0 && fraction <= 1.0 + 1e-12, "block {b}: volume fraction {fraction}");
        if (fraction - 1.0).abs() < 1e-12 {
            whole += 1;
        }
    }
    println!("{} blocks, {whole} whole tetrahedra, worst relative difference {worst:.2e}", blocks.len());
    assert!(whole > 0 && worst < 1e-12, "{worst:.2e}");
}
