//! Contact on cut bodies, on virtual node meshes driven by the integrator (docs/math/contact.md):
//! a cut block's halves rest on each other, the energy right after a cut counts the new surface,
//! the faces of an unfinished cut do not pass through each other, crossed bars meet edge on
//! edge, contact structures built ahead are used only for their own surface, a crack ending
//! inside the material is no contact at rest, and the piecewise preconditioner solves what the
//! direct solver solves. Contact's tests that need no cut (friction on a slope, mesh and plane
//! colliders, momentum of thrown bodies) use plain embedding rows in
//! `crates/cleave-contact/tests/step.rs`.

use cleave_core::{CutSurface, Cuttable, Discretization, Material, Point3, Real, Vector3};
use cleave_integrator::{
    Constraints, ContactSet, Integrator, PlaneCollider, Preconditioner, Settings, Solver, StepReport, SurfaceContact,
};
use cleave_virtualnode::VirtualNodeMesh;

const H: Real = 1.0 / 60.0;

fn settings(gravity: Vector3<Real>) -> Settings {
    let mut s = Settings::new(H);
    s.solver = Solver::Cholesky;
    s.gravity = gravity;
    s.rayleigh_beta = 0.01;
    s
}

fn ground(stiffness: Real, friction: Real) -> PlaneCollider {
    PlaneCollider { point: Point3::origin(), normal: Vector3::z(), stiffness, damping: 0.0, friction }
}

/// Contact points and surface contact from the mesh's own render surface.
fn contact_constraints(
    mesh: &mut VirtualNodeMesh,
    planes: Vec<PlaneCollider>,
    surface: Option<(Real, Real)>,
) -> Constraints {
    let s = mesh.as_cuttable().unwrap().surface().unwrap();
    let surface_contact = surface.map(|(stiffness, friction)| SurfaceContact {
        triangles: s.triangles.clone(),
        on_cut: s.on_cut.clone(),
        piece: s.piece.clone(),
        stiffness,
        damping: 0.0,
        friction,
        thickness: 0.0,
        reach: 0.005,
        edge_contact: true,
    });
    Constraints { contact_points: Some(s.embedding), planes, surface_contact, ..Default::default() }
}

#[test]
fn halves_of_a_cut_block_rest_on_each_other() {
    let material = Material::new(1e6, 0.3, 1000.0).unwrap();
    let h = 0.05;
    let mut mesh = VirtualNodeMesh::from_box(Point3::origin(), Point3::new(0.2, 0.2, 0.2), h, material).unwrap();
    // Cut horizontally in two halves, then let the upper one settle on the lower one.
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.0, 0.0, 0.1), normal: Vector3::z() }).unwrap();
    assert_eq!(mesh.pieces().len(), 2);
    let constraints = contact_constraints(&mut mesh, vec![ground(1e5, 0.5)], Some((1e5, 0.5)));
    let points = constraints.contact_points.clone().unwrap();
    let upper: Vec<usize> = (0..points.len()).filter(|&i| points.point(mesh.rest_dofs(), i).z > 0.1 - 1e-9).collect();
    let mut integrator = Integrator::new(&mesh, settings(Vector3::new(0.0, 0.0, -9.81)), constraints).unwrap();
    let mut reports: Vec<StepReport> = Vec::new();
    for _ in 0..150 {
        reports.push(integrator.step(&mesh).unwrap());
    }
    let x = integrator.positions();
    let lowest_upper = upper.iter().map(|&i| points.point(x, i).z).fold(Real::INFINITY, Real::min);
    let deepest = reports[60..].iter().map(|r| r.contacts.max_penetration).fold(0.0, Real::max);
    let surface_contacts = reports.last().unwrap().contacts.surface;
    let (e_settled, e_end) = (reports[90].total_energy(), reports[149].total_energy());
    println!(
        "upper half's lowest point {lowest_upper:.6} m (cut at 0.1, lower half sags under it), deepest penetration after 1 s {deepest:.2e} m (1 % of h = {:.1e}), {surface_contacts} surface contacts, energy {e_settled:.6e} J at 1.5 s -> {e_end:.6e} J at 2.5 s",
        0.01 * h
    );
    // Without contact between the halves the upper one falls 0.1 m onto the ground.
    assert!(lowest_upper > 0.099, "the upper half must rest on the lower: {lowest_upper}");
    assert!(surface_contacts > 0);
    assert!(deepest < 0.01 * h, "penetration {deepest} above 1 % of the element size");
    assert!(e_end <= e_settled + 1e-9 * e_settled.abs().max(1.0), "energy grows at rest: {e_settled} -> {e_end}");
}

/// The energy of the state right after a cut, asked for before any step: the ground contacts
/// are found then for the new surface (a topology change no longer finds them up front), so
/// the penalty energy is exactly Σ ½ k min(d, 0)² over the new surface points, computed here
/// from their positions, and the other energies are those before the cut (the remap is exact).
#[test]
fn energy_right_after_a_cut_counts_the_new_surface_on_the_ground() {
    let material = Material::new(1e5, 0.3, 1000.0).unwrap();
    let mut mesh = VirtualNodeMesh::from_box(Point3::origin(), Point3::new(0.1, 0.1, 0.1), 0.05, material).unwrap();
    let stiffness = 2e4;
    let constraints = contact_constraints(&mut mesh, vec![ground(stiffness, 0.5)], None);
    let mut integrator = Integrator::new(&mesh, settings(Vector3::new(0.0, 0.0, -9.81)), constraints).unwrap();
    for _ in 0..30 {
        integrator.step(&mesh).unwrap();
    }
    let before = integrator.energies(&mesh);
    let change = mesh.cut(&CutSurface::Plane { point: Point3::new(0.0512, 0.0, 0.0), normal: Vector3::x() }).unwrap();
    let constraints = contact_constraints(&mut mesh, vec![ground(stiffness, 0.5)], None);
    let points = constraints.contact_points.clone().unwrap();
    integrator.apply_topology_change(&mesh, &change, constraints).unwrap();
    let after = integrator.energies(&mesh);
    let x = integrator.positions();
    let expected: Real = (0..points.len()).map(|i| 0.5 * stiffness * points.point(x, i).z.min(0.0).powi(2)).sum();
    println!(
        "penalty energy {:.6e} J before the cut, {:.6e} J after it ({:.6e} J summed over the new surface's points)",
        before.penalty_energy, after.penalty_energy, expected
    );
    assert!(expected > 0.0, "the block must sit in the ground's penalty layer");
    assert!((after.penalty_energy - expected).abs() < 1e-12 * expected, "{} vs {expected}", after.penalty_energy);
    let rest_of = |e: &cleave_integrator::StepReport| e.kinetic_energy + e.elastic_energy + e.gravitational_energy;
    assert!((rest_of(&after) - rest_of(&before)).abs() < 1e-12 * rest_of(&before).abs().max(1e-6));
}

const SLIT: Real = 0.1537;

#[test]
fn faces_of_an_unfinished_cut_do_not_pass_through_each_other() {
    let material = Material::new(2e5, 0.3, 1000.0).unwrap();
    let build = || {
        let mut mesh = VirtualNodeMesh::from_box(Point3::origin(), Point3::new(0.3, 0.1, 0.2), 0.05, material).unwrap();
        // A slit in the plane x = 0.1537 (between lattice node planes, so every node lies on
        // one side) from the top down to half the height.
        let (a, b, c, d) = (
            Point3::new(SLIT, -0.1, 0.1),
            Point3::new(SLIT, 0.2, 0.1),
            Point3::new(SLIT, 0.2, 0.3),
            Point3::new(SLIT, -0.1, 0.3),
        );
        mesh.cut(&CutSurface::Triangles(vec![[a, b, c], [a, c, d]])).unwrap();
        assert_eq!(mesh.pieces().len(), 1, "the slit leaves one piece");
        mesh
    };
    // The two flaps above the slit's end are pushed into each other: every copy of a node moves
    // with the side its duplicates' material lies on (a virtual node beyond the slit belongs to
    // the other side's material), faster higher up.
    let squeeze = |mesh: &VirtualNodeMesh| -> Vec<Real> {
        let mut side = vec![0.0; mesh.num_nodes()];
        for (d, nodes) in mesh.duplicate_nodes().iter().enumerate() {
            let cells = mesh.duplicate_cells(d);
            let centre = cells.cells.iter().map(|c| cells.cell_center(c).x).sum::<Real>() / cells.cells.len() as Real;
            for &n in nodes {
                side[n as usize] = if centre < SLIT { 1.0 } else { -1.0 };
            }
        }
        mesh.rest_dofs()
            .chunks_exact(3)
            .zip(&side)
            .flat_map(|(p, toward)| [toward * 1.5 * ((p[2] - 0.1) / 0.1).max(0.0), 0.0, 0.0])
            .collect()
    };
    let mut crossing = Vec::new();
    for with_contact in [true, false] {
        let mut mesh = build();
        let constraints = contact_constraints(&mut mesh, Vec::new(), with_contact.then_some((1e5, 0.0)));
        let s = mesh.as_cuttable().unwrap().surface().unwrap();
        let mut integrator = Integrator::new(&mesh, settings(Vector3::zeros()), constraints).unwrap();
        let v = squeeze(&mesh);
        integrator.set_state(&mesh, mesh.rest_dofs().to_vec(), v);
        let mut worst: Real = 0.0;
        for _ in 0..20 {
            integrator.step(&mesh).unwrap();
            // How far the left face (outward +x) has crossed the right face (outward −x):
            // the largest overlap of their x ranges near the slit's top edge.
            let x = integrator.positions();
            let face_x = |sign: Real| -> Vec<Real> {
                s.triangles
                    .iter()
                    .zip(&s.on_cut)
                    .filter(|(t, cut)| {
                        **cut && {
                            let [a, b, c] = t.map(|i| s.rest_vertices[i as usize]);
                            (b - a).cross(&(c - a)).x * sign > 0.0 && a.z > 0.15
                        }
                    })
                    .flat_map(|(t, _)| t.map(|i| s.embedding.point(x, i as usize).x))
                    .collect()
            };
            let left = face_x(1.0).into_iter().fold(Real::NEG_INFINITY, Real::max);
            let right = face_x(-1.0).into_iter().fold(Real::INFINITY, Real::min);
            worst = worst.max(left - right);
        }
        crossing.push(worst);
    }
    println!("overlap of the slit's faces: {:.2e} m with contact, {:.2e} m without", crossing[0], crossing[1]);
    assert!(crossing[1] > 0.01, "the squeeze must push the faces through each other without contact");
    assert!(crossing[0] < 1e-3, "with contact the faces may not cross: {}", crossing[0]);
}

/// Two square bars crossed at right angles, each turned 45° about its axis so that an edge of
/// the upper one falls on an edge of the lower one, midway between the surface points along
/// both edges: no point of either meets a face of the other until the edges have sunk a
/// quarter of the lattice spacing (12.5 mm) into each other, so only edge–edge contact stops
/// them at the crossing. Returns the least separation of the two edges at the crossing over
/// the run (negative: the edges passed into each other) [m], measured on the lines through
/// the surface points on either side of the crossing.
fn crossed_bars(edges: bool) -> Real {
    let material = Material::new(1e6, 0.3, 1000.0).unwrap();
    let h = 0.05;
    let mut mesh = VirtualNodeMesh::from_box(Point3::origin(), Point3::new(0.6, 0.1, 0.2), h, material).unwrap();
    mesh.cut(&CutSurface::Plane { point: Point3::new(0.0, 0.0, 0.1), normal: Vector3::z() }).unwrap();
    let pieces = mesh.pieces();
    assert_eq!(pieces.len(), 2);
    let rest = mesh.rest_dofs().to_vec();
    let is_lower = |p: &cleave_core::Piece| {
        p.nodes.iter().map(|&n| rest[3 * n as usize + 2]).sum::<Real>() / (p.nodes.len() as Real) < 0.1
    };
    let lower = if is_lower(&pieces[0]) { 0 } else { 1 };
    let turn = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_4);
    let across = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2) * turn;
    // Half the diagonal of the 0.1 m square section: where the edges touch.
    let ridge = 0.05 * std::f64::consts::SQRT_2;
    let (mut x, mut v) = (rest.clone(), vec![0.0; rest.len()]);
    for (piece, (rotation, centre, offset)) in [
        (lower, (turn, Point3::new(0.3, 0.05, 0.05), Vector3::zeros())),
        // Offset by half the lattice spacing along both axes, 5 mm above contact, falling at
        // 0.1 m/s (1.7 mm per step).
        (1 - lower, (across, Point3::new(0.3, 0.05, 0.15), Vector3::new(0.025, 0.025, 2.0 * ridge + 0.005))),
    ] {
        for &n in &pieces[piece].nodes {
            let n = 3 * n as usize;
            let p = rotation * (Point3::new(rest[n], rest[n + 1], rest[n + 2]) - centre) + offset;
            x[n..n + 3].copy_from_slice(p.as_slice());
            if piece != lower {
                v[n + 2] = -0.1;
            }
        }
    }
    let mut constraints = contact_constraints(&mut mesh, Vec::new(), Some((1e6, 0.0)));
    let points = constraints.contact_points.clone().unwrap();
    // The lower bar's top edge is its rest edge y = z = 0.1, crossed between x = 0.30 and 0.35;
    // the upper bar's bottom edge is its rest edge y = 0, z = 0.1, crossed between x = 0.25
    // and 0.30.
    // Both pieces have points there (the faces of the cut coincide at rest): the piece's own.
    let point_at = |piece: usize, rest_position: Point3<Real>| {
        let (i, distance) = (0..points.len())
            .filter(|&i| pieces[piece].nodes.contains(&points.row(i).0[0]))
            .map(|i| (i, (points.point(&rest, i) - rest_position).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        assert!(distance < 1e-9, "no surface point at {rest_position}");
        i
    };
    let lower_edge = [point_at(lower, Point3::new(0.3, 0.1, 0.1)), point_at(lower, Point3::new(0.35, 0.1, 0.1))];
    let upper = 1 - lower;
    let upper_edge = [point_at(upper, Point3::new(0.25, 0.0, 0.1)), point_at(upper, Point3::new(0.3, 0.0, 0.1))];
    if !edges {
        constraints.surface_contact.as_mut().unwrap().edge_contact = false;
    }
    let mut integrator = Integrator::new(&mesh, settings(Vector3::zeros()), constraints).unwrap();
    integrator.set_state(&mesh, x, v);
    let mut least = Real::INFINITY;
    let mut edge_contacts = 0;
    for _ in 0..30 {
        let report = integrator.step(&mesh).unwrap();
        edge_contacts = edge_contacts.max(report.contacts.edges);
        let at = |i: usize| points.point(integrator.positions(), i);
        let (a, b) = (lower_edge.map(at), upper_edge.map(at));
        let (s, t) = cleave_geometry::closest_parameters_of_lines(&a, &b).unwrap();
        let normal = (a[1] - a[0]).cross(&(b[1] - b[0])).normalize();
        let gap = normal.dot(&((b[0] + (b[1] - b[0]) * t) - (a[0] + (a[1] - a[0]) * s)));
        // Oriented from the lower edge up to the upper one.
        least = least.min(gap * normal.z.signum());
    }
    println!("edge contact {edges}: up to {edge_contacts} edge contacts, least separation of the edges {least:.2e} m");
    assert_eq!(edge_contacts > 0, edges);
    least
}

#[test]
fn crossed_bars_meet_edge_on_edge() {
    let with = crossed_bars(true);
    let without = crossed_bars(false);
    // Vertex–triangle contact alone lets the edges sink into each other until points meet
    // faces; edge–edge contact holds them within 1 % of the element size.
    assert!(without < -0.005, "without edge contact the edges should pass into each other: {without}");
    assert!(with > -0.01 * 0.05, "with edge contact they meet at the edges: {with} m");
}

/// Contact structures built ahead for the new surface (`ContactSet::new`) give the run that
/// building them at the change gives, bit for bit; ones built for another surface (the one
/// before the cut) are not used, and the run is the same too.
#[test]
fn contact_structures_built_ahead_are_used_only_for_their_own_surface() {
    let material = Material::new(1e5, 0.3, 1000.0).unwrap();
    let run = |prepare: Option<bool>| {
        let mut mesh = VirtualNodeMesh::from_box(Point3::origin(), Point3::new(0.1, 0.1, 0.1), 0.05, material).unwrap();
        let constraints = contact_constraints(&mut mesh, vec![ground(2e4, 0.5)], Some((2e4, 0.5)));
        let before_cut = constraints.clone();
        let rest_before = mesh.rest_dofs().to_vec();
        let mut integrator = Integrator::new(&mesh, settings(Vector3::new(0.0, 0.0, -9.81)), constraints).unwrap();
        for _ in 0..10 {
            integrator.step(&mesh).unwrap();
        }
        let change =
            mesh.cut(&CutSurface::Plane { point: Point3::new(0.0, 0.0, 0.0512), normal: Vector3::z() }).unwrap();
        let constraints = contact_constraints(&mut mesh, vec![ground(2e4, 0.5)], Some((2e4, 0.5)));
        let prepared = prepare.map(|own| match own {
            true => ContactSet::new(&constraints.colliders(), mesh.rest_dofs()),
            false => ContactSet::new(&before_cut.colliders(), &rest_before),
        });
        let expected = prepare == Some(true);
        let used = integrator.apply_topology_change_with(&mesh, &change, constraints, prepared).unwrap();
        assert_eq!(used, expected, "prepared {prepare:?}: used {used}");
        for _ in 0..20 {
            integrator.step(&mesh).unwrap();
        }
        integrator.positions().iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    };
    let built_at_the_change = run(None);
    assert!(run(Some(true)) == built_at_the_change, "the structures built ahead change the run");
    assert!(run(Some(false)) == built_at_the_change, "structures of another surface change the run");
}

#[test]
fn a_crack_ending_inside_the_material_is_no_contact_at_rest() {
    // One triangle wholly inside a block, 2.5-3.2 mm below its top: the crack it opens ends in
    // the material on every side, so the piece's surface is its outer box plus a closed
    // two-sided sheet inside it, not joined to the box. Taken as a body of its own, the sheet
    // penetrates its own piece at rest by its depth, within the reach (5 mm).
    let material = Material::new(5e5, 0.3, 1000.0).unwrap();
    let mut mesh = VirtualNodeMesh::from_box(Point3::origin(), Point3::new(0.2, 0.2, 0.1), 0.05, material).unwrap();
    let crack =
        [Point3::new(0.052, 0.061, 0.0975), Point3::new(0.143, 0.072, 0.0968), Point3::new(0.097, 0.151, 0.0972)];
    mesh.cut(&CutSurface::Triangles(vec![crack])).unwrap();
    assert_eq!(mesh.pieces().len(), 1);
    let constraints = contact_constraints(&mut mesh, Vec::new(), Some((1e5, 0.5)));
    let s = mesh.as_cuttable().unwrap().surface().unwrap();
    let sheet = s.on_cut.iter().filter(|&&cut| cut).count();
    let mut integrator = Integrator::new(&mesh, settings(Vector3::zeros()), constraints).unwrap();
    let report = integrator.step(&mesh).unwrap();
    println!(
        "{sheet} sheet triangles; at rest: deepest pair {:.2e} m, penalty energy {:.2e} J, {} surface pairs",
        report.contacts.max_penetration, report.penalty_energy, report.contacts.surface
    );
    assert!(sheet >= 2, "the crack must open a sheet");
    assert!(report.contacts.max_penetration <= 1e-12, "deepest pair {:.3e} m at rest", report.contacts.max_penetration);
    assert!(report.penalty_energy <= 1e-12, "penalty energy {:.3e} J at rest", report.penalty_energy);
    let moved = integrator.positions().iter().zip(mesh.rest_dofs()).map(|(x, r)| (x - r).abs()).fold(0.0, Real::max);
    assert!(moved <= 1e-12, "a body at rest without loads moved {moved:.3e} m");
}

/// Positions after `steps` steps of a block cut by three oblique planes into pieces that fall
/// on the ground and on each other, with `solver` and `preconditioner`, and the iterations of
/// every step.
fn cut_block_settling(solver: Solver, preconditioner: Preconditioner, steps: usize) -> (Vec<Real>, Vec<usize>) {
    let material = Material::new(2e5, 0.3, 1000.0).unwrap();
    let mut mesh = VirtualNodeMesh::from_box(Point3::origin(), Point3::new(0.2, 0.2, 0.12), 0.03, material).unwrap();
    for (point, normal) in [
        (Point3::new(0.1, 0.1, 0.06), Vector3::new(1.0, 0.2, 0.1)),
        (Point3::new(0.1, 0.1, 0.06), Vector3::new(-0.15, 1.0, 0.05)),
        (Point3::new(0.1, 0.1, 0.05), Vector3::new(0.1, -0.1, 1.0)),
    ] {
        mesh.cut(&CutSurface::Plane { point, normal: normal.normalize() }).unwrap();
    }
    assert_eq!(mesh.pieces().len(), 8, "three planes through the middle leave eight pieces");
    let constraints = contact_constraints(&mut mesh, vec![ground(2e4, 0.5)], Some((2e4, 0.5)));
    let mut s = settings(Vector3::new(0.0, 0.0, -9.81));
    s.solver = solver;
    s.preconditioner = preconditioner;
    let mut integrator = Integrator::new(&mesh, s, constraints).unwrap();
    let iterations = (0..steps).map(|_| integrator.step(&mesh).unwrap().iterations).collect();
    (integrator.positions().to_vec(), iterations)
}

#[test]
fn the_piecewise_preconditioner_solves_the_steps_the_direct_solver_solves() {
    // The direct solver is independent of the preconditioner: CG converged tightly with it must
    // follow the same trajectory of eight pieces settling in contact (measured 5e-13 m). The
    // coarse space and the per-piece factors must also pay for themselves: measured 127 CG
    // iterations a step against block-Jacobi's 266 at this tolerance (172 without the coarse
    // space). Pieces glued by stiff cut-face contacts are what keeps it from fewer
    // (docs/math/corotated-integrator.md, "Piecewise preconditioner").
    let steps = 40;
    let (direct, _) = cut_block_settling(Solver::Cholesky, Preconditioner::Auto, steps);
    let cg = |preconditioner| {
        let solver = Solver::ConjugateGradient { tolerance: 1e-10, max_iterations: 5000, assembled: false };
        cut_block_settling(solver, preconditioner, steps)
    };
    let (pieces, pieces_iterations) = cg(Preconditioner::Pieces);
    let (_, jacobi_iterations) = cg(Preconditioner::BlockJacobi);
    let apart = direct.iter().zip(&pieces).map(|(a, b)| (a - b).abs()).fold(0.0, Real::max);
    let mean = |i: &[usize]| i.iter().sum::<usize>() as Real / i.len() as Real;
    let (with_pieces, with_jacobi) = (mean(&pieces_iterations), mean(&jacobi_iterations));
    println!(
        "largest position difference to the direct solver {apart:.2e} m; CG iterations a step: {with_pieces:.1} piecewise, {with_jacobi:.1} block-Jacobi"
    );
    assert!(apart < 1e-7, "the piecewise CG left the direct solver's trajectory by {apart} m");
    assert!(
        with_pieces < 0.6 * with_jacobi,
        "the piecewise preconditioner must take fewer than 60 % of block-Jacobi's iterations: {with_pieces} vs {with_jacobi}"
    );
}
