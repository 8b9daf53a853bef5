//! Mean value coordinates on random convex polyhedra of 4 to 40 nodes (a cube or a tetrahedron
//! cut by random planes): partition of unity, linear precision and non-negativity inside, the
//! Lagrange property at the nodes and the linear approach to it, linear interpolation on edges,
//! the face limit on faces and the linear approach to it, analytic gradients against central differences and against their identities,
//! barycentric coordinates on tetrahedra, the cube's symmetry. Each reference is independent of
//! the formulas under test (the point itself, finite differences, a 4×4 solve, a delta).

use cleave_meanvalue::{ConvexPolyhedron, Workspace, mean_value_coordinates};
use nalgebra::{Matrix3, Matrix4, Point3, Vector3, Vector4};

/// xorshift64*: a fixed, dependency-free stream of numbers in [0, 1).
struct Random(u64);

impl Random {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn unit(&mut self) -> Vector3<f64> {
        loop {
            let v = Vector3::new(self.next(), self.next(), self.next()) * 2.0 - Vector3::repeat(1.0);
            if v.norm() > 0.1 && v.norm() < 1.0 {
                return v.normalize();
            }
        }
    }
}

/// A cube or a tetrahedron cut by random planes near its middle until it has at least `nodes`
/// vertices (or cuts stop adding any); the part that keeps the starting centroid is kept.
fn random_polyhedron(random: &mut Random, nodes: usize) -> ConvexPolyhedron {
    let mut element = if random.next() < 0.5 {
        ConvexPolyhedron::cuboid(Point3::origin(), Point3::new(1.0, 0.8 + 0.4 * random.next(), 1.2))
    } else {
        ConvexPolyhedron::tetrahedron([
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.2, 0.1, 0.0),
            Point3::new(0.3, 1.0, 0.1),
            Point3::new(0.4, 0.3, 1.1),
        ])
    }
    .unwrap();
    for _ in 0..200 {
        if element.vertices().len() >= nodes {
            break;
        }
        let centre = element.vertex_average();
        let n = random.unit();
        let offset = n.dot(&centre.coords) + 0.25 * element.diameter() * (0.3 + 0.7 * random.next());
        let (below, _) = element.split(&n, offset, 1e-6);
        if let Some(part) = below.filter(|p| p.vertices().len() <= 40 && p.volume() > 0.02 * element.volume()) {
            element = part;
        }
    }
    element
}

/// A random point inside: a convex combination of the vertices with random weights, pulled
/// towards the vertex average so it stays away from the boundary.
fn interior_point(random: &mut Random, element: &ConvexPolyhedron) -> Point3<f64> {
    let weights: Vec<f64> = element.vertices().iter().map(|_| random.next().powi(3)).collect();
    let total: f64 = weights.iter().sum();
    let p: Vector3<f64> = element.vertices().iter().zip(&weights).map(|(v, w)| v.coords * (w / total)).sum();
    Point3::from(p * 0.9 + element.vertex_average().coords * 0.1)
}

/// The largest distance of a face's vertex from the plane through its first vertex along the
/// face's normal.
fn planarity_defect(element: &ConvexPolyhedron) -> f64 {
    let v = element.vertices();
    element
        .faces()
        .iter()
        .zip(element.normals())
        .flat_map(|(face, n)| face.iter().map(move |&j| n.dot(&(v[j] - v[face[0]])).abs()))
        .fold(0.0, f64::max)
}

fn coordinates(element: &ConvexPolyhedron, x: &Point3<f64>) -> (Vec<f64>, Vec<Vector3<f64>>) {
    let k = element.vertices().len();
    let (mut values, mut gradients) = (vec![0.0; k], vec![Vector3::zeros(); k]);
    mean_value_coordinates(element, x, &mut values, Some(&mut gradients), &mut Workspace::default());
    (values, gradients)
}

#[test]
fn partition_of_unity_linear_precision_and_positivity_inside_random_polyhedra() {
    let mut random = Random(0x9E37_79B9_7F4A_7C15);
    let mut sizes = Vec::new();
    for case in 0..60 {
        let element = random_polyhedron(&mut random, 4 + case % 37);
        sizes.push(element.vertices().len());
        let diameter = element.diameter();
        for _ in 0..20 {
            let x = interior_point(&mut random, &element);
            let (lambda, gradients) = coordinates(&element, &x);
            let sum: f64 = lambda.iter().sum();
            assert!((sum - 1.0).abs() < 1e-13, "case {case}: Σλ = {sum}");
            let reproduced: Vector3<f64> = element.vertices().iter().zip(&lambda).map(|(v, l)| v.coords * *l).sum();
            let error = (reproduced - x.coords).norm() / diameter;
            // Round-off in the cut points leaves faces planar only to some 1e-13 of the
            // diameter; the reproduced point can be off by about that much.
            let tolerance = 1e-13 + 10.0 * planarity_defect(&element) / diameter;
            assert!(error < tolerance, "case {case}: linear precision {error:.2e} (tolerance {tolerance:.2e})");
            assert!(lambda.iter().all(|&l| l > 0.0), "case {case}: {lambda:?}");
            // The gradients' own identities: Σ∇λ = 0 and Σ v ∇λᵀ = I, to round-off in the size
            // of the terms summed (large where a face or edge is small).
            let sum_gradients: Vector3<f64> = gradients.iter().sum();
            let magnitude: f64 = gradients.iter().map(|g| g.norm()).sum();
            assert!(sum_gradients.norm() < 1e-13 * magnitude, "case {case}: Σ∇λ = {sum_gradients}");
            let c = element.vertex_average();
            let jacobian: Matrix3<f64> =
                element.vertices().iter().zip(&gradients).map(|(v, g)| (v - c) * g.transpose()).sum();
            let terms: f64 = element.vertices().iter().zip(&gradients).map(|(v, g)| (v - c).norm() * g.norm()).sum();
            let deviation = (jacobian - Matrix3::identity()).norm();
            let allowed = (1e-13 + 100.0 * planarity_defect(&element) / diameter) * terms.max(1.0);
            assert!(deviation < allowed, "case {case}: ‖Σ v∇λᵀ − I‖ = {deviation:.2e}, terms {terms:.2e}");
        }
    }
    sizes.sort_unstable();
    assert!(sizes[0] == 4 && *sizes.last().unwrap() >= 30, "node counts {sizes:?}");
}

#[test]
fn gradients_match_central_differences() {
    let mut random = Random(0xD1B5_4A32_D192_ED03);
    let mut worst: f64 = 0.0;
    for case in 0..40 {
        let element = random_polyhedron(&mut random, 4 + case % 30);
        let step = 1e-5 * element.diameter();
        for _ in 0..5 {
            let x = interior_point(&mut random, &element);
            let (_, gradients) = coordinates(&element, &x);
            let scale = gradients.iter().map(|g| g.norm()).fold(0.0, f64::max);
            for axis in 0..3 {
                let mut e = Vector3::zeros();
                e[axis] = step;
                let (plus, _) = coordinates(&element, &(x + e));
                let (minus, _) = coordinates(&element, &(x - e));
                for i in 0..gradients.len() {
                    let difference = (plus[i] - minus[i]) / (2.0 * step);
                    worst = worst.max((difference - gradients[i][axis]).abs() / scale);
                }
            }
        }
    }
    println!("worst gradient error against central differences, relative to max |∇λ|: {worst:.2e}");
    assert!(worst < 1e-6, "{worst:.2e}");
}

#[test]
fn nodes_edges_and_faces_take_their_limits_without_nan() {
    let mut random = Random(0x1234_5678_9ABC_DEF1);
    for case in 0..30 {
        let element = random_polyhedron(&mut random, 6 + case % 30);
        let diameter = element.diameter();
        let centre = element.vertex_average();
        let vertices = element.vertices();
        // At a node: the delta. Near it (1e-7 diam inside): within a few 1e-7.
        for (i, v) in vertices.iter().enumerate() {
            let (at, gradients) = coordinates(&element, v);
            for (j, l) in at.iter().enumerate() {
                assert!((l - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12, "case {case}: node {i}, λ_{j} = {l}");
            }
            assert!(gradients.iter().all(|g| g.iter().all(|c| c.is_finite())));
            // Approached linearly, |1 − λ_i| ≈ C dist/diam (C ≤ 2 on a cube, mean-value.md §4;
            // larger at the sharp corners random cuts make): a hundred times closer, a hundred
            // times smaller.
            let gap = |distance: f64| {
                let near = v + (centre - v).normalize() * (distance * diameter);
                1.0 - coordinates(&element, &near).0[i]
            };
            let (far, close) = (gap(1e-6), gap(1e-8));
            assert!(far < 1e-3 && close.abs() <= 0.02 * far + 1e-13, "case {case}: node {i}: {far:.2e}, {close:.2e}");
        }
        for (f, face) in element.faces().iter().enumerate() {
            let m = face.len();
            // On an edge: linear interpolation between its end nodes.
            let (a, b) = (face[0], face[1]);
            let s = 0.3 + 0.4 * random.next();
            let p = vertices[a] + (vertices[b] - vertices[a]) * s;
            let (values, _) = coordinates(&element, &p);
            let expected = |j: usize| {
                if j == a {
                    1.0 - s
                } else if j == b {
                    s
                } else {
                    0.0
                }
            };
            for (j, l) in values.iter().enumerate() {
                assert!((l - expected(j)).abs() < 1e-9, "case {case}: face {f} edge, λ_{j} = {l}");
            }
            // Inside a face: only the face's nodes, reproducing the point; the interior formula
            // 1e-8 diam inside agrees to about that distance.
            let weights: Vec<f64> = (0..m).map(|_| 0.2 + random.next()).collect();
            let total: f64 = weights.iter().sum();
            let q: Vector3<f64> = face.iter().zip(&weights).map(|(&v, w)| vertices[v].coords * (w / total)).sum();
            let q = Point3::from(q);
            let (on, _) = coordinates(&element, &q);
            let reproduced: Vector3<f64> = vertices.iter().zip(&on).map(|(v, l)| v.coords * *l).sum();
            let allowed = 1e-12 * diameter + 2.0 * planarity_defect(&element);
            assert!((reproduced - q.coords).norm() < allowed, "case {case}: face {f}");
            assert!(on.iter().enumerate().all(|(j, l)| face.contains(&j) || *l == 0.0));
            // The interior formula tends to the limit linearly (C dist/diam; C ≈ 2.4 on a cube,
            // mean-value.md §4): a hundred times closer, a hundred times smaller.
            let gap = |distance: f64| {
                let inside = q - element.normals()[f] * (distance * diameter);
                let (near, _) = coordinates(&element, &inside);
                on.iter().zip(&near).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
            };
            let (far, close) = (gap(1e-7), gap(1e-9));
            assert!(far < 1e-3 && close <= 0.02 * far + 1e-12, "case {case}: face {f}: {far:.2e}, {close:.2e}");
        }
    }
}

#[test]
fn a_tetrahedron_has_its_barycentric_coordinates_and_gradients() {
    let points = [
        Point3::new(0.1, -0.2, 0.0),
        Point3::new(1.3, 0.1, 0.2),
        Point3::new(0.2, 0.9, -0.1),
        Point3::new(0.5, 0.4, 1.4),
    ];
    let element = ConvexPolyhedron::tetrahedron(points).unwrap();
    // [v; 1] λ = [x; 1]: λ = A⁻¹ [x; 1], ∇λ_i = rows of A⁻¹'s first three columns.
    let a = Matrix4::from_fn(|r, c| if r < 3 { points[c][r] } else { 1.0 });
    let inverse = a.try_inverse().unwrap();
    let mut random = Random(7);
    for _ in 0..50 {
        let x = interior_point(&mut random, &element);
        let (lambda, gradients) = coordinates(&element, &x);
        let expected = inverse * Vector4::new(x.x, x.y, x.z, 1.0);
        for i in 0..4 {
            assert!((lambda[i] - expected[i]).abs() < 1e-14, "λ_{i}");
            let g = Vector3::new(inverse[(i, 0)], inverse[(i, 1)], inverse[(i, 2)]);
            assert!((gradients[i] - g).norm() < 1e-12 * g.norm(), "∇λ_{i}: {} vs {g}", gradients[i]);
        }
    }
}

#[test]
fn the_cube_is_symmetric_but_not_trilinear() {
    let cube = ConvexPolyhedron::cuboid(Point3::origin(), Point3::new(1.0, 1.0, 1.0)).unwrap();
    let (centre, _) = coordinates(&cube, &Point3::new(0.5, 0.5, 0.5));
    assert!(centre.iter().all(|l| (l - 0.125).abs() < 1e-15), "{centre:?}");
    // Mirror x ↔ 1 − x maps corner c to c ^ 1.
    let x = Point3::new(0.2, 0.35, 0.7);
    let (a, _) = coordinates(&cube, &x);
    let (b, _) = coordinates(&cube, &Point3::new(0.8, 0.35, 0.7));
    for c in 0..8 {
        assert!((a[c] - b[c ^ 1]).abs() < 1e-14);
    }
    // Trilinear weights reproduce linear functions too, but the coordinates differ from them.
    let trilinear: Vec<f64> = (0..8)
        .map(|c| {
            let f = |bit: usize, t: f64| if c & bit == 0 { 1.0 - t } else { t };
            f(1, x.x) * f(2, x.y) * f(4, x.z)
        })
        .collect();
    let difference = a.iter().zip(&trilinear).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max);
    assert!(difference > 1e-3, "mean value coordinates are not trilinear: {difference:.2e}");
}

/// A cube with two straight nodes inserted on one edge (a neighbour's nodes, as cutting leaves
/// them): every point along that edge, on each of its three collinear segments, is the linear
/// interpolation of that segment's ends, so the coordinates sum to one and reproduce the point.
/// (Taking the first edge whose line holds the point gave the end of another segment.)
#[test]
fn points_on_an_edge_with_straight_nodes_interpolate_their_own_segment() {
    let p = |x: f64, y: f64, z: f64| Point3::new(x, y, z);
    // The cube [0,1]³ with nodes 8 and 9 at z = 0.3 and 0.7 on the edge x = 0, y = 0.
    let mut vertices: Vec<Point3<f64>> =
        (0..8).map(|c| p((c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64)).collect();
    vertices.push(p(0.0, 0.0, 0.3));
    vertices.push(p(0.0, 0.0, 0.7));
    let faces = vec![
        vec![0, 2, 3, 1],
        vec![4, 5, 7, 6],
        vec![0, 1, 5, 4, 9, 8],
        vec![2, 6, 7, 3],
        vec![0, 8, 9, 4, 6, 2],
        vec![1, 3, 7, 5],
    ];
    let cube = ConvexPolyhedron::new(vertices.clone(), faces).unwrap();
    let mut lambda = vec![0.0; 10];
    let mut work = Workspace::default();
    for z in [0.05, 0.2, 0.3, 0.45, 0.6, 0.85, 0.95] {
        let x = p(0.0, 0.0, z);
        mean_value_coordinates(&cube, &x, &mut lambda, None, &mut work);
        let sum: f64 = lambda.iter().sum();
        let point: Vector3<f64> = lambda.iter().zip(&vertices).map(|(l, v)| v.coords * *l).sum();
        assert!((sum - 1.0).abs() < 1e-14, "z = {z}: Σλ = {sum}");
        assert!((point - x.coords).norm() < 1e-14, "z = {z}: {point:?}");
        // Only the segment's two ends carry weight.
        assert_eq!(lambda.iter().filter(|l| l.abs() > 1e-14).count(), if z == 0.3 { 1 } else { 2 }, "z = {z}");
    }
}
