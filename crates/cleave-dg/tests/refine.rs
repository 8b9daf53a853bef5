//! Stress-driven refinement of a DG body (`Refinable for DgMesh`, docs/math/dg.md §14), on a
//! 0.3 × 0.2 × 0.2 box of 0.1 m cubes turned and moved, in a stretched and turned state (no
//! special pose): a uniform stretch `s` along `e` has the analytic largest principal stress
//! `(λ + 2μ) s`, so a threshold just below it refines every element and one just above none;
//! 1→8 makes each cube eight cubes of an eighth of its volume, 1→2 two halves across `e`; only
//! the stretched elements refine when the others rest (neighbours two levels apart); the field
//! at random points, the volume and the mass are kept to 1e-12; the body stays one piece.

use cleave_core::{Cuttable, Discretization, Material, Matrix3, Point3, Real, Refinable, Vector3};
use cleave_dg::{DgMesh, DgOptions, Flux, RefineSplit, Refinement};
use cleave_geometry::PolyhedralMesh;
use nalgebra::{Rotation3, Unit};

fn turn() -> Rotation3<Real> {
    Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.4, -0.3, 0.85)), 0.7)
}

const SHIFT: Vector3<Real> = Vector3::new(0.5, -1.0, 2.0);
const YOUNG: Real = 1e5;
const POISSON: Real = 0.3;

fn body(degree: usize, flux: Flux, split: RefineSplit, max_depth: u32) -> DgMesh {
    let grid = PolyhedralMesh::grid(Point3::origin(), 0.1, [3, 2, 2]);
    let mesh = PolyhedralMesh { vertices: grid.vertices.iter().map(|p| turn() * p + SHIFT).collect(), ..grid };
    let mut dg =
        DgMesh::new(mesh, Material::new(YOUNG, POISSON, 1000.0).unwrap(), DgOptions::new(degree, flux), None).unwrap();
    dg.set_refinement(Refinement { split, max_depth });
    dg
}

/// `λ + 2μ`: the stress of a uniaxial strain per unit strain.
fn p_modulus() -> Real {
    YOUNG * (1.0 - POISSON) / ((1.0 + POISSON) * (1.0 - 2.0 * POISSON))
}

/// The box's local x axis in the world.
fn stretch_axis() -> Vector3<Real> {
    turn() * Vector3::new(1.0, 0.0, 0.0)
}

/// DOFs of `x ↦ Q (I + s e eᵀ) x + t` on the elements `stretched` picks (by centroid, the
/// others at rest moved the same rigid way): a uniform stretch `s` along `e`, turned by `Q`.
fn stretched_state(dg: &DgMesh, s: Real, stretched: &dyn Fn(&Point3<Real>) -> bool) -> Vec<Real> {
    let q = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(-0.2, 0.9, 0.3)), 0.5).into_inner();
    let e = stretch_axis();
    let nb = dg.basis_size();
    let mut x = dg.rest_dofs().to_vec();
    let centroids = element_centroids(dg);
    for (element, (centroid, _)) in centroids.iter().enumerate() {
        let a = if stretched(centroid) { q * (Matrix3::identity() + s * e * e.transpose()) } else { q };
        for i in 0..nb {
            let node = element * nb + i;
            let d = a * Vector3::new(x[3 * node], x[3 * node + 1], x[3 * node + 2]);
            x[3 * node..3 * node + 3].copy_from_slice(d.as_slice());
        }
    }
    dg.add_translation(&Vector3::new(0.3, 0.1, -0.2), &mut x);
    x
}

/// Each element's centroid and volume, by its quadrature rule (exact for degree 1).
fn element_centroids(dg: &DgMesh) -> Vec<(Point3<Real>, Real)> {
    let mut sums = vec![(Vector3::zeros(), 0.0); dg.num_frames()];
    let zero = vec![0.0; dg.rest_dofs().len()];
    dg.visit_field(&zero, 1, &mut |sample| {
        // Which element: the one holding the point.
        let e = dg.locate(&sample.position).expect("a quadrature point lies in the body");
        sums[e].0 += sample.position.coords * sample.weight;
        sums[e].1 += sample.weight;
    });
    sums.iter().map(|(sum, volume)| (Point3::from(sum / *volume), *volume)).collect()
}

fn field(dg: &DgMesh, x: &[Real], p: &Point3<Real>) -> Vector3<Real> {
    let e = dg.locate(p).expect("inside");
    let nb = dg.basis_size();
    let (mut values, mut gradients) = (vec![0.0; nb], vec![Vector3::zeros(); nb]);
    dg.evaluate_basis(e, p, &mut values, &mut gradients);
    (0..nb)
        .map(|i| Vector3::new(x[3 * (e * nb + i)], x[3 * (e * nb + i) + 1], x[3 * (e * nb + i) + 2]) * values[i])
        .sum()
}

fn rotations(dg: &DgMesh, x: &[Real]) -> Vec<Matrix3<Real>> {
    let mut r = vec![Matrix3::identity(); dg.num_frames()];
    dg.write_rotations(x, &mut r);
    r
}

fn samples(seed: u64) -> Vec<Point3<Real>> {
    let mut random = cleave_testkit::Lcg::new(seed);
    (0..300)
        .map(|_| {
            let local = Point3::new(0.3 * random.next().abs(), 0.2 * random.next().abs(), 0.2 * random.next().abs());
            turn() * local + SHIFT
        })
        .collect()
}

#[test]
fn a_uniform_stretch_refines_every_element_above_its_analytic_stress_and_none_below() {
    let s = 0.02;
    let stress = p_modulus() * s;
    for (split, children) in [(RefineSplit::Octants, 8), (RefineSplit::Halves, 2)] {
        for (degree, flux) in [(1, Flux::InteriorPenalty), (2, Flux::BabuskaZlamal)] {
            let mut dg = body(degree, flux, split, 1);
            let x = stretched_state(&dg, s, &|_| true);
            let r = rotations(&dg, &x);
            // 0.1 % above the analytic stress: nothing; 0.1 % below: all twelve cubes.
            assert!(dg.refine(&x, &r, 1.001 * stress).unwrap().is_none(), "{split:?} degree {degree}");
            let change = dg.refine(&x, &r, 0.999 * stress).unwrap().expect("every element refines");
            assert_eq!(dg.num_frames(), 12 * children, "{split:?} degree {degree}");
            let centroids = element_centroids(&dg);
            for (c, (centroid, volume)) in centroids.iter().enumerate() {
                // Each child an equal share of its 1e-3 m³ cube.
                assert!((volume - 1e-3 / children as Real).abs() < 1e-14, "{split:?}: child {c} of {volume} m³");
                let local = turn().inverse() * (centroid - SHIFT);
                // Octants: centroids at odd multiples of 0.025 on every axis; halves: on the
                // stretch axis only (the plane is normal to it), the others at 0.05 + 0.1 k.
                let on_grid = |v: Real, step: Real| ((v / step).round() - v / step).abs() < 1e-9;
                let fine = |v: Real| on_grid(v - 0.025, 0.05);
                let coarse = |v: Real| on_grid(v - 0.05, 0.1);
                let ok = match split {
                    RefineSplit::Octants => fine(local.x) && fine(local.y) && fine(local.z),
                    RefineSplit::Halves => fine(local.x) && coarse(local.y) && coarse(local.z),
                };
                assert!(ok, "{split:?} degree {degree}: child {c} centred at {local} (box frame)");
            }
            let after = change.remap.apply(&x);
            let r = rotations(&dg, &after);
            // Depth 1 reached: no further refinement.
            assert!(dg.refine(&after, &r, 0.5 * stress).unwrap().is_none());
            assert!(dg.refinement_depths().iter().all(|&d| d == 1));
            // The stress of the refined field is the same uniform stretch.
            for (e, rotation) in r.iter().enumerate() {
                let sigma = dg.element_stress(e, &after, rotation);
                let largest = sigma.symmetric_eigenvalues().iter().fold(0.0, |m: Real, v| m.max(v.abs()));
                assert!((largest - stress).abs() < 1e-9 * stress, "{largest} vs {stress}");
            }
        }
    }
}

#[test]
fn refining_part_of_a_body_twice_keeps_the_field_volume_and_mass() {
    let s = 0.02;
    let stress = p_modulus() * s;
    for (split, children) in [(RefineSplit::Octants, 8u32), (RefineSplit::Halves, 2)] {
        for (degree, flux) in [(1, Flux::InteriorPenalty), (2, Flux::InteriorPenalty), (2, Flux::BabuskaZlamal)] {
            let mut dg = body(degree, flux, split, 2);
            // The cubes of the first column (box-frame x < 0.1) stretched, the rest at rest.
            let left = |p: &Point3<Real>| (turn().inverse() * (p - SHIFT)).x < 0.1;
            let mut random = cleave_testkit::Lcg::new(11);
            let mut x = stretched_state(&dg, s, &left);
            // A small random part on top: no special field (below the threshold's reach).
            for v in &mut x {
                *v += 1e-9 * random.next();
            }
            let points = samples(3);
            let before: Vec<Vector3<Real>> = points.iter().map(|p| field(&dg, &x, p)).collect();
            let volume: Real = dg.pieces().iter().map(|p| p.volume).sum();
            let mut elements = 12;
            for round in 0..2 {
                let r = rotations(&dg, &x);
                let change = dg.refine(&x, &r, 0.9 * stress).unwrap().expect("the stretched column refines");
                // Four cubes, then their children: 4 → 4 c → 4 c² elements in the column.
                let marked = 4 * children.pow(round);
                elements += marked * (children - 1);
                assert_eq!(dg.num_frames(), elements as usize, "{split:?} degree {degree} round {round}");
                x = change.remap.apply(&x);
                let scale = before.iter().map(|u| u.norm()).fold(0.0, Real::max);
                for (p, old) in points.iter().zip(&before) {
                    let new = field(&dg, &x, p);
                    assert!((new - old).norm() < 1e-12 * scale, "{split:?} degree {degree}: {new} vs {old} at {p}");
                }
                let pieces = dg.pieces();
                assert_eq!(pieces.len(), 1, "refinement separates nothing");
                assert!((pieces[0].volume - volume).abs() < 1e-12 * volume);
                assert!((pieces[0].mass - 1000.0 * volume).abs() < 1e-12 * pieces[0].mass);
                assert!(dg.surface().is_none(), "a refined, uncut body keeps its MLS surface");
            }
            let r = rotations(&dg, &x);
            assert!(dg.refine(&x, &r, 0.9 * stress).unwrap().is_none(), "depth 2 is the limit");
        }
    }
}

#[test]
fn bad_thresholds_and_states_are_refused() {
    let mut dg = body(1, Flux::InteriorPenalty, RefineSplit::Octants, 1);
    let x = dg.rest_dofs().to_vec();
    let r = rotations(&dg, &x);
    for threshold in [0.0, -1.0, Real::NAN, Real::INFINITY] {
        let error = dg.refine(&x, &r, threshold).unwrap_err().to_string();
        assert!(error.contains("threshold"), "{error}");
    }
    let error = dg.refine(&x[..6], &r, 1.0).unwrap_err().to_string();
    assert!(error.contains("positions"), "{error}");
    assert!(dg.refine(&x, &r, 1.0).unwrap().is_none(), "the rest state has no stress");
}
