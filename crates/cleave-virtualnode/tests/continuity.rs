//! A cut at a deformed state changes nothing physical: every material point keeps its position
//! (the `Gather` of node positions reproduces the embedded points), the elastic energy, the mass
//! and the momentum are unchanged, and the gathered rotations are the new frames' rotations.

use cleave_core::{
    CutSurface, Cuttable, Discretization, DofRemap, FrameRemap, Material, Matrix3, Point3, Real, Vector3,
};
use cleave_testkit::Lcg;
use cleave_virtualnode::VirtualNodeMesh;

fn converged_rotations(d: &dyn Discretization, x: &[Real], start: Vec<Matrix3<Real>>) -> Vec<Matrix3<Real>> {
    let mut r = start;
    for _ in 0..60 {
        d.write_rotations(x, &mut r);
    }
    r
}

#[test]
fn cuts_at_a_deformed_state_keep_positions_energy_mass_and_momentum() {
    let material = Material::new(2e5, 0.3, 900.0).unwrap();
    let mut mesh =
        VirtualNodeMesh::from_box(Point3::new(0.02, 0.01, -0.03), Point3::new(0.62, 0.33, 0.29), 0.08, material)
            .unwrap();
    let mut rng = Lcg::new(5);
    // A smooth large deformation plus per-node noise, and a velocity field.
    let deform = |p: &[Real], rng: &mut Lcg| {
        let q = Vector3::new(p[0] + 0.2 * (3.0 * p[1]).sin(), p[1] + 0.1 * p[0] * p[2], p[2] - 0.15 * p[0] * p[0]);
        [q.x + 0.003 * rng.next(), q.y + 0.003 * rng.next(), q.z + 0.003 * rng.next()]
    };
    let mut x: Vec<Real> = mesh.rest_dofs().chunks_exact(3).flat_map(|p| deform(p, &mut rng)).collect();
    let mut v: Vec<Real> = (0..x.len()).map(|_| rng.next()).collect();
    let cuts = [
        CutSurface::Plane { point: Point3::new(0.3, 0.0, 0.0), normal: Vector3::new(1.0, -0.4, 0.2) },
        CutSurface::Triangles(vec![
            [Point3::new(0.1, -0.1, 0.1), Point3::new(0.5, 0.2, 0.05), Point3::new(0.2, 0.4, 0.3)],
            [Point3::new(0.5, 0.2, 0.05), Point3::new(0.2, 0.4, 0.3), Point3::new(0.7, 0.5, 0.35)],
        ]),
        // Through lattice nodes: the lattice origin is lo − h and nodes lie every h/2.
        CutSurface::Plane { point: Point3::new(0.0, 0.01 - 0.08 + 0.04 * 5.0, 0.0), normal: Vector3::y() },
    ];
    for cut in &cuts {
        // Material points: the mesh's own quadrature points.
        let mut points = Vec::new();
        mesh.visit_field(&vec![0.0; x.len()], 2, &mut |s| points.push(s.position));
        let points: Vec<Point3<Real>> = points.into_iter().step_by(3).collect();
        let before = mesh.embed(&points).unwrap();
        let positions: Vec<Point3<Real>> = (0..points.len()).map(|i| before.point(&x, i)).collect();
        let velocities: Vec<Point3<Real>> = (0..points.len()).map(|i| before.point(&v, i)).collect();
        let r_old = converged_rotations(&mesh, &x, vec![Matrix3::identity(); mesh.num_frames()]);
        let energy = mesh.elastic_energy(&r_old, &x);
        let momentum = |mesh: &VirtualNodeMesh, v: &[Real]| -> Vector3<Real> {
            let m = mesh.mass().diagonal();
            (0..m.len() / 3)
                .map(|k| Vector3::new(m[3 * k] * v[3 * k], m[3 * k + 1] * v[3 * k + 1], m[3 * k + 2] * v[3 * k + 2]))
                .sum()
        };
        let (p_old, mass) = (momentum(&mesh, &v), mesh.mass().total());
        let (nodes_before, frames_before) = (mesh.num_nodes(), mesh.num_frames());

        let change = mesh.cut(cut).unwrap();
        let DofRemap::Gather(src) = &change.remap else { panic!("a cut is a gather") };
        assert_eq!(src.len(), mesh.num_nodes());
        x = change.remap.apply(&x);
        v = change.remap.apply(&v);
        let after = mesh.embed(&points).unwrap();
        let position_error = (0..points.len()).map(|i| (after.point(&x, i) - positions[i]).norm()).fold(0.0, Real::max);
        let velocity_error =
            (0..points.len()).map(|i| (after.point(&v, i) - velocities[i]).norm()).fold(0.0, Real::max);
        let FrameRemap::Gather(parents) = &change.frames else { panic!("frames are gathered") };
        let r_gathered = change.frames.apply(&r_old);
        assert_eq!(parents.len(), mesh.num_frames());
        let r_new = converged_rotations(&mesh, &x, r_gathered.clone());
        let frame_error = r_new.iter().zip(&r_gathered).map(|(a, b)| (a - b).amax()).fold(0.0, Real::max);
        let energy_after = mesh.elastic_energy(&r_new, &x);
        let p_new = momentum(&mesh, &v);
        println!(
            "{} → {} nodes, {} → {} frames, {} pieces: position error {position_error:.1e}, velocity error {velocity_error:.1e}, frame error {frame_error:.1e}, energy {energy:.6e} → {energy_after:.6e}, momentum error {:.1e}",
            nodes_before,
            mesh.num_nodes(),
            frames_before,
            mesh.num_frames(),
            mesh.pieces().len(),
            (p_new - p_old).norm() / p_old.norm()
        );
        assert!(mesh.num_nodes() > nodes_before && mesh.num_frames() > frames_before);
        assert!(position_error < 1e-13, "{position_error}");
        assert!(velocity_error < 1e-13, "{velocity_error}");
        assert!(frame_error < 1e-10, "{frame_error}");
        assert!((energy_after - energy).abs() < 1e-11 * energy, "{energy} → {energy_after}");
        assert!((p_new - p_old).norm() < 1e-12 * p_old.norm());
        assert!((mesh.mass().total() - mass).abs() < 1e-12 * mass);
    }
}
