//! Unit tests of detection and the penalty terms on plain embedding rows (every point its own
//! node or a few nodes' combination): bounds that find the same pairs bit for bit, the signed
//! distance of surface contact, forces as the energy's negative gradient, no net force or torque.
#![cfg(test)]

use crate::colliders::*;
use crate::rows::*;
use crate::set::*;
use cleave_core::{Embedding, Point3, Real, Vector3};
use cleave_geometry::closest_parameters_of_lines;

/// The colliders of a test, owned.
#[derive(Clone, Default)]
struct Constraints {
    contact_points: Option<Embedding>,
    planes: Vec<PlaneCollider>,
    meshes: Vec<MeshCollider>,
    surface_contact: Option<SurfaceContact>,
}

impl Constraints {
    fn colliders(&self) -> Colliders<'_> {
        Colliders {
            points: self.contact_points.as_ref(),
            planes: &self.planes,
            meshes: &self.meshes,
            surface: self.surface_contact.as_ref(),
        }
    }
}

/// Two triangles of two pieces (points 0–2 and 3–5, every point its own node) at `lower`
/// and `upper`; at rest the upper one floats 1 m higher, so nothing touches there.
fn two_triangles(
    lower: [[Real; 3]; 3],
    upper: [[Real; 3]; 3],
    planes: Vec<PlaneCollider>,
) -> (Constraints, Vec<Real>, Vec<Real>) {
    let mut points = Embedding::new();
    for i in 0..6u32 {
        points.push_row(&[i], &[1.0]);
    }
    let x: Vec<Real> = lower.iter().chain(&upper).flatten().copied().collect();
    let rest: Vec<Real> = x.iter().enumerate().map(|(i, &c)| if i >= 9 && i % 3 == 2 { c + 1.0 } else { c }).collect();
    let constraints = Constraints {
        contact_points: Some(points),
        planes,
        surface_contact: Some(SurfaceContact {
            triangles: vec![[0, 1, 2], [3, 4, 5]],
            on_cut: Vec::new(),
            piece: Vec::new(),
            stiffness: 1e4,
            damping: 0.0,
            friction: 0.0,
            thickness: 0.0,
            reach: 0.05,
            edge_contact: true,
        }),
        ..Default::default()
    };
    (constraints, x, rest)
}

/// The upper triangle sunk into the lower one (lower faces up, upper faces down: opposing),
/// with a tilted ground plane under a corner.
fn setup() -> (Constraints, Vec<Real>, Vec<Real>) {
    let ground = PlaneCollider {
        point: Point3::new(0.0, 0.0, 0.01),
        normal: Vector3::new(0.1, -0.2, 1.0).normalize(),
        stiffness: 3e3,
        damping: 0.0,
        friction: 0.0,
    };
    two_triangles(
        [[0.0, 0.0, 0.0], [1.0, 0.1, 0.02], [0.2, 1.0, -0.03]],
        [[0.3, 0.3, -0.004], [0.35, 0.5, -0.002], [0.55, 0.3, 0.05]],
        vec![ground],
    )
}

/// Two triangles whose edges cross 3.7 mm into each other (an edge along x whose triangle
/// faces up, one along y whose triangle faces down), slightly skewed so that nothing is
/// axis aligned, with no point near the other's face: an edge–edge contact.
fn crossing_edges() -> (Constraints, Vec<Real>, Vec<Real>) {
    two_triangles(
        [[0.5, 0.02, 0.01], [-0.5, -0.01, -0.01], [0.03, -0.5, -0.5]],
        [[0.1, -0.5, -0.002], [0.12, 0.5, -0.001], [0.6, 0.02, 0.5]],
        Vec::new(),
    )
}

#[test]
fn crossing_edges_make_an_edge_contact() {
    let (constraints, x, rest) = crossing_edges();
    let mut set = ContactSet::new(&constraints.colliders(), &rest);
    set.detect(&constraints.colliders(), &x, &vec![0.0; x.len()], 0.01, &Vector3::zeros());
    let stats = set.stats();
    // The crossing's depth along the common normal, computed here from the four points.
    let at = |k: usize| Point3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]);
    let (a, b) = ([at(0), at(1)], [at(3), at(4)]);
    let (s, t) = closest_parameters_of_lines(&a, &b).unwrap();
    let gap = ((a[0] + (a[1] - a[0]) * s) - (b[0] + (b[1] - b[0]) * t)).norm();
    println!("{stats:?}; the edges cross {gap:.3e} m deep");
    assert_eq!(stats.edges, 1, "{stats:?}");
    assert!((stats.max_penetration - gap).abs() < 1e-12 * gap.max(1.0), "{} vs {gap}", stats.max_penetration);
}

/// Two points 1 mm above a flat triangle of another piece, at rest: not active, but kept as
/// near pairs; a solution that moves them towards it joins them exactly when it carries them
/// more than half the reach (0.025 m) through, `d + h n·u⁺ < −reach/2`, each with the
/// implicit block `h² k n nᵀ` (1.0 along `n`). The same in a turned and moved copy of the
/// scene, where the normal is not an axis.
#[test]
fn pairs_the_solution_drives_together_join_the_step() {
    let turns = [
        (nalgebra::Rotation3::identity(), Vector3::zeros()),
        (nalgebra::Rotation3::new(Vector3::new(0.4, -0.9, 0.3)), Vector3::new(2.0, -1.0, 0.5)),
    ];
    for (turn, shift) in turns {
        let place = |p: [Real; 3]| (turn * Vector3::from(p) + shift).into();
        let (constraints, x, rest) = two_triangles(
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]].map(place),
            [[0.3, 0.3, 0.001], [0.35, 0.5, 0.001], [0.55, 0.3, 0.2]].map(place),
            Vec::new(),
        );
        let normal = turn * Vector3::z();
        let points = constraints.contact_points.clone().unwrap();
        let h = 0.01;
        for (speed, expected) in [(2.5, 0), (3.1, 2)] {
            let mut set = ContactSet::new(&constraints.colliders(), &rest);
            set.detect(&constraints.colliders(), &x, &vec![0.0; x.len()], h, &Vector3::zeros());
            assert_eq!(set.stats().surface, 0, "nothing closes at rest");
            let mut v = vec![0.0; x.len()];
            for k in [3, 4] {
                v[3 * k..3 * k + 3].copy_from_slice((-speed * normal).as_slice());
            }
            let added = set.activate_driven(&points, &v, h);
            println!("towards it at {speed} m/s: predicted gap {:.4} m, {added} pairs join", 0.001 - h * speed);
            assert_eq!(added, expected);
            for c in &set.contacts {
                assert_eq!(c.kind, ContactKind::Surface);
                assert!((c.normal - normal).norm() < 1e-12 && (c.depth - 0.001).abs() < 1e-12, "{c:?}");
                assert!((c.matrix - normal * normal.transpose() * (h * h * 1e4)).norm() < 1e-9);
            }
        }
    }
}

/// The upper triangle's two low points 8 cm above the lower one, farther than the reach
/// (5 cm), at 10 m/s (10 cm in the step of 0.01 s): moving towards it they are found and
/// active; moving away they are near pairs only (within the reach plus their step's motion),
/// and the same in the scene turned and moved. A search box along each point's path found
/// none when moving away in the scene as given and two in the turned one (a tilted
/// triangle's box reaches behind the point): it made contacts depend on the scene's
/// orientation, and was reverted.
#[test]
fn what_a_point_finds_does_not_depend_on_the_scene_orientation() {
    let turns = [
        (nalgebra::Rotation3::identity(), Vector3::zeros()),
        (nalgebra::Rotation3::new(Vector3::new(0.4, -0.9, 0.3)), Vector3::new(2.0, -1.0, 0.5)),
    ];
    for (turn, shift) in turns {
        let place = |p: [Real; 3]| (turn * Vector3::from(p) + shift).into();
        let (constraints, x, rest) = two_triangles(
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]].map(place),
            [[0.3, 0.3, 0.08], [0.35, 0.5, 0.08], [0.55, 0.3, 0.3]].map(place),
            Vec::new(),
        );
        let normal = turn * Vector3::z();
        let h = 0.01;
        for (speed, active, near) in [(10.0, 2, 0), (-10.0, 0, 2)] {
            let mut v = vec![0.0; x.len()];
            for k in 3..6 {
                v[3 * k..3 * k + 3].copy_from_slice((-speed * normal).as_slice());
            }
            let mut set = ContactSet::new(&constraints.colliders(), &rest);
            set.detect(&constraints.colliders(), &x, &v, h, &Vector3::zeros());
            let found_near = set.near.iter().flatten().count();
            println!("at {speed} m/s towards the lower triangle: {:?}, {found_near} near pairs", set.stats());
            assert_eq!(set.stats().surface, active, "{speed} m/s");
            assert_eq!(found_near, near, "{speed} m/s");
            for c in &set.contacts {
                assert!((c.normal - normal).norm() < 1e-12 && (c.depth - 0.08).abs() < 1e-12, "{c:?}");
            }
        }
    }
}

/// A set built for the next epoch takes the trees of the components it shares with the last
/// one, and its first detection refits them: the upper triangle, 1 m above at the last
/// detection, now sunk into the lower one, gives exactly the contacts a set with trees
/// built afresh gives (a kept tree that were not refit would still hold it 1 m up).
#[test]
fn kept_trees_are_refit_and_find_what_new_ones_find() {
    let (constraints, x, rest) = setup();
    let zero = vec![0.0; x.len()];
    let mut last = ContactSet::new(&constraints.colliders(), &rest);
    last.detect(&constraints.colliders(), &rest, &zero, 0.01, &Vector3::zeros());
    assert_eq!(last.stats().surface, 0, "nothing touches at rest");
    let mut kept = ContactSet::new(&constraints.colliders(), &rest);
    kept.reuse_trees(last);
    assert_eq!(kept.reused_trees.iter().flatten().count(), 2, "both pieces keep their trees");
    kept.detect(&constraints.colliders(), &x, &zero, 0.01, &Vector3::zeros());
    let mut fresh = ContactSet::new(&constraints.colliders(), &rest);
    fresh.detect(&constraints.colliders(), &x, &zero, 0.01, &Vector3::zeros());
    assert!(fresh.stats().surface > 0, "{:?}", fresh.stats());
    assert_eq!(kept.stats(), fresh.stats());
    assert_eq!(format!("{:?}", kept.contacts), format!("{:?}", fresh.contacts));
}

/// The box [0, size]² × [0, thick] (corner k at the bits of k) and its 12 triangles,
/// outward, counter-clockwise seen from outside.
fn slab(size: Real, thick: Real) -> (Vec<[Real; 3]>, Vec<[u32; 3]>) {
    let corners =
        (0..8).map(|k| [size * (k & 1) as Real, size * ((k >> 1) & 1) as Real, thick * (k >> 2) as Real]).collect();
    let triangles = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (corners, triangles)
}

/// The corners of a regular tetrahedron of half-size `half` turned by `turn` about `centre`
/// (points 8–11 after a slab's 8; [`TETRAHEDRON_TRIANGLES`] its outward faces).
fn tetrahedron(turn: nalgebra::Rotation3<Real>, centre: Vector3<Real>, half: Real) -> [Vector3<Real>; 4] {
    [[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]]
        .map(|c| turn * Vector3::from(c) * half + centre)
}
/// The outward faces of [`tetrahedron`]'s corners as points 8–11.
const TETRAHEDRON_TRIANGLES: [[u32; 3]; 4] = [[8, 9, 10], [8, 11, 9], [8, 10, 11], [9, 11, 10]];

/// The DOFs of a slab's corners followed by a tetrahedron's.
fn slab_then_tetrahedron_dofs(slab: &[[Real; 3]], corners: &[Vector3<Real>; 4]) -> Vec<Real> {
    slab.iter().flatten().copied().chain(corners.iter().flat_map(|c| [c.x, c.y, c.z])).collect()
}

/// A reproducible sequence of numbers in [0, 1) (a 64-bit linear congruential generator).
fn uniform(seed: u64) -> impl FnMut() -> Real {
    let mut state = seed;
    move || {
        state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as Real / (1u64 << 53) as Real
    }
}

/// Surface contact between a slab (points 0–7) and a tetrahedron (points 8–11) at `x`, each
/// point its own node, with `triangles` as the surface; the rest shape holds the tetrahedron
/// 10 m away, so nothing is behind anything at rest.
fn slab_and_tetrahedron(triangles: Vec<[u32; 3]>, x: &[Real]) -> (Constraints, Vec<Real>) {
    let mut points = Embedding::new();
    for i in 0..12u32 {
        points.push_row(&[i], &[1.0]);
    }
    let rest = x.iter().enumerate().map(|(i, &c)| if i >= 24 { c + 10.0 } else { c }).collect();
    let constraints = Constraints {
        contact_points: Some(points),
        surface_contact: Some(SurfaceContact {
            triangles,
            on_cut: Vec::new(),
            piece: Vec::new(),
            stiffness: 1e4,
            damping: 0.0,
            friction: 0.0,
            thickness: 0.0,
            reach: 0.01,
            edge_contact: false,
        }),
        ..Default::default()
    };
    (constraints, rest)
}

/// A pair's points, weights, normal and depth, the numbers as bits.
type PairBits = ([u32; 4], [u64; 4], Vector3<u64>, u64);

/// The contacts and near pairs of a set's last detection, each as its bits.
fn pairs_bit_for_bit(set: &ContactSet) -> (Vec<PairBits>, Vec<PairBits>) {
    let bits = |row: &Row, normal: &Vector3<Real>, depth: Real| -> PairBits {
        (row.points, row.weights.map(Real::to_bits), normal.map(Real::to_bits), depth.to_bits())
    };
    let contacts = set.contacts.iter().map(|c| bits(&c.row, &c.normal, c.depth)).collect();
    let near = set.near.iter().flatten().map(|p| bits(&p.row, &p.normal, p.gap.0)).collect();
    (contacts, near)
}

/// The pairs (contacts and near pairs) that detection finds at `x`, `v`, with the search
/// bounded by the pieces' rigid motions, by their mean velocities alone, and with every
/// other piece searched (no filter of the pairs of pieces), asserted equal bit for bit;
/// returns how many.
fn pairs_found_alike(constraints: &Constraints, rest: &[Real], x: &[Real], v: &[Real], h: Real) -> usize {
    let found = |ignore_turning: bool, search_every_piece: bool| {
        let mut set = ContactSet::new(&constraints.colliders(), rest);
        set.ignore_turning = ignore_turning;
        set.search_every_piece = search_every_piece;
        set.detect(&constraints.colliders(), x, v, h, &Vector3::zeros());
        pairs_bit_for_bit(&set)
    };
    let turning = found(false, false);
    assert_eq!(turning, found(true, false), "mean velocities: x = {x:?}, v = {v:?}");
    assert_eq!(turning, found(false, true), "every piece: x = {x:?}, v = {v:?}");
    turning.0.len() + turning.1.len()
}

/// One piece whose two halves meet along an unfinished cut (two coinciding faces of opposite
/// orientation, joined by a bridge triangle), turning fast as a whole (up to 45 rad/s, h|ω|
/// up to 0.45) while the halves fold into each other: its points' searches of its own cut faces find the same pairs with the
/// boxes bounded by its rigid motion as with those bounded by its mean velocity, in 3000
/// random states. Leaf boxes that left out the spread of a triangle's corners' velocities
/// (τ_t, which the search's reach holds) lost pairs here.
#[test]
fn own_cut_boxes_by_the_rigid_motion_find_what_boxes_by_the_mean_velocity_find() {
    let mut random = uniform(0x6a09_e667_f3bc_c909);
    let mut spin = || Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
    // A 4 × 4 grid of points per half (3 cm square), lower half 0–15, upper 16–31, and the
    // bridge's apex 32 beside the corner both halves share in the rest shape.
    let grid = |k: usize| Vector3::new(0.01 * (k % 4) as Real, 0.01 * (k / 4) as Real, 0.0);
    let mut triangles = Vec::new();
    for (half, up) in [(0u32, true), (16, false)] {
        for j in 0..3u32 {
            for i in 0..3u32 {
                let [a, b, c, d] = [i + 4 * j, i + 1 + 4 * j, i + 4 * (j + 1), i + 1 + 4 * (j + 1)].map(|k| k + half);
                if up {
                    triangles.extend([[a, b, d], [a, d, c]]);
                } else {
                    triangles.extend([[a, d, b], [a, c, d]]);
                }
            }
        }
    }
    triangles.push([15, 31, 32]);
    let on_cut = (0..triangles.len()).map(|t| t < 36).collect();
    let rest: Vec<Real> = (0..33)
        .flat_map(|k| {
            let p = if k == 32 { Vector3::new(0.04, 0.04, 0.0) } else { grid(k % 16) };
            [p.x, p.y, p.z]
        })
        .collect();
    let mut points = Embedding::new();
    for i in 0..33u32 {
        points.push_row(&[i], &[1.0]);
    }
    let constraints = Constraints {
        contact_points: Some(points),
        surface_contact: Some(SurfaceContact {
            triangles,
            on_cut,
            piece: Vec::new(),
            stiffness: 1e4,
            damping: 0.0,
            friction: 0.0,
            thickness: 0.0,
            reach: 0.002,
            edge_contact: false,
        }),
        ..Default::default()
    };
    let (mut pairs, h) = (0, 0.01);
    for _ in 0..3000 {
        // The upper half folded about the shared corner's edge by a small angle, the whole
        // placed at random; velocities: a turn of up to 45 rad/s of the whole, a
        // folding of up to 2 rad/s, and up to 5 cm/s per point.
        let fold = nalgebra::Rotation3::new(Vector3::new(1.0, -1.0, 0.0).normalize() * 0.2 * spin().x);
        // Half the states unturned (the cut faces across z, where a box's gap is the
        // distance itself, not a fraction of it).
        let turn = match spin().x > 0.0 {
            true => nalgebra::Rotation3::new(spin() * 6.0),
            false => nalgebra::Rotation3::identity(),
        };
        let shift = spin() * 0.1;
        let (w, omega, folding) = (spin() * 2.0, spin() * 90.0, spin() * 4.0);
        let corner = grid(15);
        let (mut x, mut v) = (Vec::new(), Vec::new());
        for k in 0..33 {
            let r = Vector3::new(rest[3 * k], rest[3 * k + 1], rest[3 * k + 2]);
            let (p, own) = if (16..32).contains(&k) {
                (corner + fold * (r - corner), folding.cross(&(r - corner)))
            } else {
                (r, Vector3::zeros())
            };
            let placed = turn * p + shift;
            let u = w + omega.cross(&placed) + turn * own + spin() * 0.1;
            x.extend_from_slice(placed.as_slice());
            v.extend_from_slice(u.as_slice());
        }
        pairs += pairs_found_alike(&constraints, &rest, &x, &v, h);
    }
    println!("{pairs} pairs found alike");
    assert!(pairs > 1000, "too few pairs ({pairs}) for the comparison to mean anything");
}

/// A tetrahedron and a slab creeping about in 400 steps of at most a twentieth of the reach,
/// turning and shaking, the tetrahedron hovering at the edge of the search (its lowest
/// corners about a reach above the slab, which moves up and down): the set kept from step to step (whose whole-surface
/// trees are refit only after a tenth of the reach of motion, their boxes loosened until
/// then) finds the same pairs, bit for bit, as a set built afresh at every state. Searching
/// the stale boxes without loosening them lost pairs here.
#[test]
fn trees_not_refit_yet_find_what_fresh_ones_find() {
    let (size, thick, reach) = (0.05, 0.004, 0.01);
    let (slab, slab_triangles) = slab(size, thick);
    let mut random = uniform(0xbb67_ae85_84ca_a73b);
    let mut spin = || Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
    let mut triangles = slab_triangles.clone();
    triangles.extend(TETRAHEDRON_TRIANGLES);
    let (mut centre, mut drift) = (Vector3::new(0.5 * size, 0.5 * size, thick + reach), Vector3::zeros());
    let mut turn = nalgebra::Rotation3::identity();
    let x_of = |centre: Vector3<Real>, turn: nalgebra::Rotation3<Real>, drift: Vector3<Real>| -> Vec<Real> {
        let corners = tetrahedron(turn, centre, 0.003);
        let slab = slab.iter().map(|p| Vector3::from(*p) + drift);
        slab.chain(corners).flat_map(|c| [c.x, c.y, c.z]).collect()
    };
    let (constraints, rest) = slab_and_tetrahedron(triangles, &x_of(centre, turn, drift));
    let mut kept = ContactSet::new(&constraints.colliders(), &rest);
    let (h, mut pairs, mut stale_steps) = (0.01, 0, 0);
    for _ in 0..400 {
        // Each step moves every point by at most 0.5 mm (a twentieth of the reach).
        centre += spin() * 0.0004;
        centre.z = centre.z.clamp(thick + reach, thick + reach + 0.0025);
        drift.z = (drift.z + 0.0004 * spin().z).clamp(-0.002, 0.002);
        turn = nalgebra::Rotation3::new(spin() * 0.05) * turn;
        let x = x_of(centre, turn, drift);
        let v: Vec<Real> = (0..x.len()).map(|_| 0.2 * (spin().x)).collect();
        kept.detect(&constraints.colliders(), &x, &v, h, &Vector3::zeros());
        let mut fresh = ContactSet::new(&constraints.colliders(), &rest);
        fresh.detect(&constraints.colliders(), &x, &v, h, &Vector3::zeros());
        assert_eq!(pairs_bit_for_bit(&kept), pairs_bit_for_bit(&fresh), "centre {centre:?}");
        pairs += kept.contacts.len() + kept.near.iter().flatten().count();
        stale_steps += usize::from(kept.staleness.iter().any(|&s| s > 0.0));
    }
    println!("{pairs} pairs alike, {stale_steps} of 400 steps searched trees not refit");
    assert!(pairs > 400 && stale_steps > 100, "{pairs} pairs, {stale_steps} steps with loosened trees");
}

/// Pieces that turn fast (up to a quarter radian per step) and deform a little: the search
/// bounded by each piece's fitted rigid motion finds exactly the pairs, contacts and near
/// pairs alike, that the search bounded by the mean velocities alone finds, in 3000 random
/// poses of a small tetrahedron at a 5 cm slab whose faces are cut faces (so its points also
/// search its own cut faces). A rigid bound that left out the turn of the searched piece
/// between the point and the triangle (|ω| d) lost pairs here.
#[test]
fn bounds_by_the_rigid_motion_find_what_bounds_by_the_mean_velocity_find() {
    let (size, thick) = (0.05, 0.004);
    let (slab, slab_triangles) = slab(size, thick);
    let mut random = uniform(0x2545_f491_4f6c_dd1d);
    let mut spin = || Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
    let (mut pairs, h) = (0, 0.01);
    for _ in 0..3000 {
        let turn = nalgebra::Rotation3::new(spin() * 6.0);
        let offset = spin();
        let centre =
            Vector3::new(size * (1.0 + 0.3 * offset.x), size * (0.5 + offset.y), thick * (0.5 + 3.0 * offset.z));
        let corners = tetrahedron(turn, centre, 0.004);
        let x = slab_then_tetrahedron_dofs(&slab, &corners);
        // Each piece: a mean velocity, a turn of up to 25 rad/s about its centre, and a
        // deformation of up to 5 cm/s per point.
        let mut v = vec![0.0; x.len()];
        for points in [0..8, 8..12] {
            let count = points.len() as Real;
            let centre =
                points.clone().map(|k| Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2])).sum::<Vector3<Real>>()
                    / count;
            let (w, omega) = (spin() * 2.0, spin() * 50.0);
            for k in points {
                let r = Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]) - centre;
                let u = w + omega.cross(&r) + spin() * 0.1;
                v[3 * k..3 * k + 3].copy_from_slice(u.as_slice());
            }
        }
        let mut triangles = slab_triangles.clone();
        triangles.extend(TETRAHEDRON_TRIANGLES);
        let (mut constraints, rest) = slab_and_tetrahedron(triangles, &x);
        if let Some(surface) = constraints.surface_contact.as_mut() {
            surface.on_cut = (0..16).map(|t| t < 12).collect();
        }
        pairs += pairs_found_alike(&constraints, &rest, &x, &v, h);
    }
    println!("{pairs} pairs found alike");
    assert!(pairs > 1000, "too few pairs ({pairs}) for the comparison to mean anything");
}

/// A small tetrahedron above a 5 cm slab, farther from it than the reach (1–4 cm against
/// 1 cm) but closing fast (up to 3 m/s, h = 0.01 s, turning), the slab moving too: the pairs
/// of pieces ruled in once per step (their root boxes against the loosest radius of any
/// point) keep every pair that searching every other piece from every point finds, in 3000
/// random states. A filter that left out the searching piece's own motion lost pairs here.
#[test]
fn the_pair_filter_keeps_every_pair_searching_every_piece_finds() {
    let (size, thick) = (0.05, 0.004);
    let (slab, slab_triangles) = slab(size, thick);
    let mut random = uniform(0x9e37_79b9_7f4a_7c15);
    let mut spin = || Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
    let (mut pairs, h) = (0, 0.01);
    for _ in 0..3000 {
        let turn = nalgebra::Rotation3::new(spin() * 6.0);
        let offset = spin();
        let centre =
            Vector3::new(size * (0.5 + 0.6 * offset.x), size * (0.5 + 0.6 * offset.y), thick + 0.025 + 0.06 * offset.z);
        let corners = tetrahedron(turn, centre, 0.004);
        let x = slab_then_tetrahedron_dofs(&slab, &corners);
        let mut v = vec![0.0; x.len()];
        let slab_velocity = spin() * 2.0;
        for k in 0..8 {
            v[3 * k..3 * k + 3].copy_from_slice(slab_velocity.as_slice());
        }
        let (closing, omega) = (Vector3::new(0.0, 0.0, -3.0 * (spin().z + 0.5)) + spin(), spin() * 20.0);
        for (k, corner) in corners.iter().enumerate() {
            let u = closing + omega.cross(&(corner - centre));
            v[24 + 3 * k..27 + 3 * k].copy_from_slice(u.as_slice());
        }
        let mut triangles = slab_triangles.clone();
        triangles.extend(TETRAHEDRON_TRIANGLES);
        let (constraints, rest) = slab_and_tetrahedron(triangles, &x);
        pairs += pairs_found_alike(&constraints, &rest, &x, &v, h);
    }
    println!("{pairs} pairs found alike");
    assert!(pairs > 500, "too few pairs ({pairs}) for the comparison to mean anything");
}

/// Surface points of a small tetrahedron tossed around the rim of a thin slab (4 mm, thinner
/// than twice the reach) in 3000 random poses: every point–triangle contact of a tetrahedron
/// point is exactly the slab's analytic signed distance where the point is inside the slab,
/// and there is none where it is outside. A facing filter that skipped the nearest face and
/// took a farther one gave points on or beside the rim depths of up to the slab's thickness
/// (docs/math/contact.md §5).
#[test]
fn surface_contact_depth_is_the_signed_distance_of_the_other_piece() {
    let (size, thick) = (1.0, 0.004);
    let (slab, slab_triangles) = slab(size, thick);
    let inside_depth = |p: &Point3<Real>| {
        let d = [p.x, size - p.x, p.y, size - p.y, p.z, thick - p.z];
        d.iter().all(|&d| d > 0.0).then(|| d.iter().copied().fold(Real::MAX, Real::min))
    };
    let mut random = uniform(0x9e37_79b9_7f4a_7c15);
    let (mut inside_points, mut checked) = (0, 0);
    for _ in 0..3000 {
        // A regular tetrahedron of edge ~6 mm, randomly turned, centred within 6 mm of the
        // slab's edge x = 1 at a random height around the slab.
        let axis = Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
        let turn = nalgebra::Rotation3::new(axis * 6.0);
        let centre = Vector3::new(size + 0.012 * (random() - 0.5), 0.5, thick * (3.0 * random() - 1.0));
        let corners = tetrahedron(turn, centre, 0.002);
        let x = slab_then_tetrahedron_dofs(&slab, &corners);
        let mut triangles = slab_triangles.clone();
        triangles.extend(TETRAHEDRON_TRIANGLES);
        let (constraints, rest) = slab_and_tetrahedron(triangles, &x);
        let mut set = ContactSet::new(&constraints.colliders(), &rest);
        set.detect(&constraints.colliders(), &x, &vec![0.0; x.len()], 0.01, &Vector3::zeros());
        for k in 8..12u32 {
            let p = Point3::from(corners[k as usize - 8]);
            let contact = set.contacts.iter().find(|c| c.kind == ContactKind::Surface && c.row.points[0] == k);
            match (inside_depth(&p), contact) {
                (Some(depth), Some(c)) => {
                    inside_points += 1;
                    assert!(
                        (c.depth + depth).abs() < 1e-12,
                        "point {p} is {depth} m inside, contact depth {}",
                        c.depth
                    );
                }
                (Some(depth), None) => panic!("point {p} is {depth} m inside the slab and has no contact"),
                (None, Some(c)) => {
                    assert!(c.depth >= -1e-12, "point {p} is outside the slab and has contact depth {}", c.depth)
                }
                (None, None) => {}
            }
            checked += 1;
        }
    }
    println!("{checked} points, {inside_points} inside the slab");
    assert!(inside_points > 300, "the poses must put many points inside the slab");
}

/// A point closing on a slab's rim from just beyond its top edge (0.05–0.3 mm past the
/// side, 0.5–3 mm above the top, falling at 1 m/s): its nearest feature is the edge, equally
/// near the top face (which it projects into within the sideways tolerance, and faces) and
/// the side face (which it does not face). It must meet the top face whatever the order of
/// the slab's triangles and of their corners, in a randomly turned and moved scene. Taking
/// whichever face the search met first gave no contact in some of these (a rounding-level
/// tie between the two faces).
#[test]
fn a_pair_at_an_edge_does_not_depend_on_the_order_of_the_triangles() {
    let (size, thick) = (1.0, 0.004);
    let (slab, slab_triangles) = slab(size, thick);
    let mut random = uniform(0x2545_f491_4f6c_dd1d);
    let mut met = 0;
    for trial in 0..200 {
        // A tetrahedron with its apex (point 8) down: the apex's vertex normal points down.
        let apex = Vector3::new(
            size + 1e-4 * (0.5 + 2.5 * random()),
            0.2 + 0.6 * random(),
            thick + 1e-3 * (0.5 + 2.5 * random()),
        );
        let top: Vec<Vector3<Real>> = (0..3)
            .map(|k| {
                let angle = 2.0 * std::f64::consts::PI * k as Real / 3.0 + random();
                apex + Vector3::new(0.002 * angle.cos(), 0.002 * angle.sin(), 0.003)
            })
            .collect();
        let axis = Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
        let turn = nalgebra::Rotation3::new(axis * 6.0);
        let shift = Vector3::new(random() - 0.5, random() - 0.5, random() - 0.5);
        let place = |c: Vector3<Real>| turn * c + shift;
        let x: Vec<Real> = slab
            .iter()
            .map(|&c| Vector3::from(c))
            .chain(std::iter::once(apex).chain(top))
            .flat_map(|c| place(c).data.0[0])
            .collect();
        let down = turn * -Vector3::z();
        let v: Vec<Real> = (0..x.len()).map(|i| if i >= 24 { down[i % 3] } else { 0.0 }).collect();
        // The three side faces seen from outside, counter-clockwise, and the top.
        let tetrahedron = [[8, 10, 9], [8, 11, 10], [8, 9, 11], [9, 10, 11]];
        for order in 0..4 {
            let mut triangles = slab_triangles.clone();
            if order & 1 == 1 {
                triangles.reverse();
            }
            if order & 2 == 2 {
                triangles.iter_mut().for_each(|t| t.rotate_left(1));
            }
            triangles.extend(tetrahedron);
            let (constraints, rest) = slab_and_tetrahedron(triangles, &x);
            let mut set = ContactSet::new(&constraints.colliders(), &rest);
            set.detect(&constraints.colliders(), &x, &v, 0.01, &Vector3::zeros());
            let contact = set.contacts.iter().find(|c| c.kind == ContactKind::Surface && c.row.points[0] == 8);
            let Some(contact) = contact else {
                panic!("trial {trial}, order {order}: the apex {apex:?} closing on the top face has no contact")
            };
            assert!(
                (contact.normal + down).norm() < 1e-12,
                "trial {trial}, order {order}: normal {:?}",
                contact.normal
            );
            assert!(
                (contact.depth - (apex.z - thick)).abs() < 1e-12,
                "trial {trial}, order {order}: gap {}",
                contact.depth
            );
            met += 1;
        }
    }
    assert_eq!(met, 800);
}

#[test]
fn contact_forces_are_the_negative_gradient_of_the_contact_energy() {
    for (constraints, x, rest) in [setup(), crossing_edges()] {
        forces_are_the_negative_gradient(constraints, x, rest);
    }
}

fn forces_are_the_negative_gradient(constraints: Constraints, x: Vec<Real>, rest: Vec<Real>) {
    let points = constraints.contact_points.as_ref().unwrap();
    let mut set = ContactSet::new(&constraints.colliders(), &rest);
    set.detect(&constraints.colliders(), &x, &vec![0.0; x.len()], 0.01, &Vector3::zeros());
    let kinds = set.stats();
    assert!((kinds.surface > 0 && kinds.planes > 0) || kinds.edges > 0, "{kinds:?}");
    let mut force = vec![0.0; x.len()];
    add_forces(points, &set.contacts, &mut force);
    let mut worst: Real = 0.0;
    let scale = force.iter().map(|f| f.abs()).fold(0.0, Real::max);
    for i in 0..x.len() {
        let eps = 1e-7;
        let (mut plus, mut minus) = (x.clone(), x.clone());
        plus[i] += eps;
        minus[i] -= eps;
        let derivative =
            (energy(points, &set.contacts, &plus).0 - energy(points, &set.contacts, &minus).0) / (2.0 * eps);
        worst = worst.max((derivative + force[i]).abs());
    }
    println!("{kinds:?}; largest |dE/dx + f| = {worst:.2e} of |f| up to {scale:.2e}");
    assert!(worst < 1e-6 * scale);
}

#[test]
fn surface_contact_forces_have_no_net_force_or_torque() {
    for (mut constraints, x, rest) in [setup(), crossing_edges()] {
        constraints.planes.clear();
        no_net_force_or_torque(constraints, x, rest);
    }
}

fn no_net_force_or_torque(constraints: Constraints, x: Vec<Real>, rest: Vec<Real>) {
    let points = constraints.contact_points.as_ref().unwrap().clone();
    let mut set = ContactSet::new(&constraints.colliders(), &rest);
    set.detect(&constraints.colliders(), &x, &vec![0.0; x.len()], 0.01, &Vector3::zeros());
    let stats = set.stats();
    assert!(stats.surface + stats.edges >= 1);
    let mut force = vec![0.0; x.len()];
    add_forces(&points, &set.contacts, &mut force);
    // The implicit part as well: the action of the contact matrix on any velocity.
    let v: Vec<Real> = (0..x.len()).map(|i| ((i * 7 % 5) as Real - 2.0) * 0.3).collect();
    let mut action = vec![0.0; x.len()];
    add_action(&points, &set.contacts, &v, &mut action);
    for (what, f) in [("force", &force), ("matrix action", &action)] {
        let (mut total, mut torque) = (Vector3::zeros(), Vector3::zeros());
        let mut size: Real = 0.0;
        for k in 0..6 {
            let fk = Vector3::new(f[3 * k], f[3 * k + 1], f[3 * k + 2]);
            total += fk;
            torque += Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]).cross(&fk);
            size = size.max(fk.norm());
        }
        println!(
            "{what}: net force {:.1e}, net torque {:.1e}, largest nodal force {size:.2e}",
            total.norm(),
            torque.norm()
        );
        assert!(size > 0.0 && total.norm() < 1e-12 * size && torque.norm() < 1e-12 * size, "{what}");
    }
}
