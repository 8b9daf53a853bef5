//! Tests of the exact polyhedral moments (`docs/math/polyhedral-integration.md`) and of
//! `PolyhedralMesh::validate`: every moment against an independent number (simplex closed
//! form, products of 1D integrals, collapsed Gauss rules, box splittings, Monte Carlo).

mod common;

use std::collections::HashMap;

use cleave_geometry::{
    Frame, GeometryError, MAX_MOMENT_DEGREE, PolyFace, PolyhedralMesh, element_moments, element_moments_from_faces,
    element_volume_centroid, face_area_normal_centroid, face_moments, monomial_exponents, monomial_index,
    shift_moments, try_element_moments, try_face_moments,
};
use common::Rng;
use nalgebra::{Matrix3, Point3, Rotation3, Vector3};

// ---------------------------------------------------------------------------------------------
// Independent reference machinery.

/// Disjoint axis-aligned boxes `(lo, hi)` whose union is a solid.
type Boxes = Vec<([f64; 3], [f64; 3])>;

/// A polynomial in three variables `(u, v, w)`: exponents → coefficient.
type Poly = HashMap<[u32; 3], f64>;

/// `Π_k (c_k0 + c_k1 u + c_k2 v + c_k3 w)^{α_k}` expanded.
fn affine_power(alpha: [u32; 3], affine: &[[f64; 4]; 3]) -> Poly {
    let mut p: Poly = HashMap::from([([0, 0, 0], 1.0)]);
    for k in 0..3 {
        for _ in 0..alpha[k] {
            let mut next: Poly = HashMap::new();
            for (e, c) in &p {
                *next.entry(*e).or_default() += c * affine[k][0];
                for j in 0..3 {
                    let mut f = *e;
                    f[j] += 1;
                    *next.entry(f).or_default() += c * affine[k][j + 1];
                }
            }
            p = next;
        }
    }
    p
}

fn factorial(n: u32) -> f64 {
    (1..=n).map(f64::from).product()
}

/// `∫_{unit simplex} u^a v^b w^c = a! b! c! / (a+b+c+3)!`.
fn simplex_integral(p: &Poly) -> f64 {
    p.iter()
        .map(|(e, c)| c * factorial(e[0]) * factorial(e[1]) * factorial(e[2]) / factorial(e[0] + e[1] + e[2] + 3))
        .sum()
}

/// `∫_{[lo,hi]} p` as a product of 1D integrals per term.
fn box_integral(p: &Poly, lo: [f64; 3], hi: [f64; 3]) -> f64 {
    p.iter()
        .map(|(e, c)| {
            c * (0..3)
                .map(|k| {
                    let n = e[k] as i32 + 1;
                    (hi[k].powi(n) - lo[k].powi(n)) / f64::from(n)
                })
                .product::<f64>()
        })
        .sum()
}

/// The affine map `y ↦ ξ = (R y + t − c)/s` as rows `[const, ∂/∂y0, ∂/∂y1, ∂/∂y2]`.
fn frame_affine(rotation: &Matrix3<f64>, translation: Vector3<f64>, frame: &Frame) -> [[f64; 4]; 3] {
    let shift = (translation - frame.center.coords) / frame.scale;
    std::array::from_fn(|k| {
        [shift[k], rotation[(k, 0)] / frame.scale, rotation[(k, 1)] / frame.scale, rotation[(k, 2)] / frame.scale]
    })
}

/// Exact `∫ ξ^α dV` over the union of disjoint boxes (given in `y`) mapped by `x = R y + t`.
/// Each box is expanded about its own corner (`y = lo + z`), so the binomial expansion does
/// not cancel the way an expansion about a distant origin would.
fn boxes_moment(
    boxes: &[([f64; 3], [f64; 3])],
    rotation: &Matrix3<f64>,
    t: Vector3<f64>,
    frame: &Frame,
    alpha: [u32; 3],
) -> f64 {
    boxes
        .iter()
        .map(|(lo, hi)| {
            let corner = rotation * Vector3::from(*lo) + t;
            let p = affine_power(alpha, &frame_affine(rotation, corner, frame));
            box_integral(&p, [0.0; 3], std::array::from_fn(|k| hi[k] - lo[k]))
        })
        .sum()
}

/// Gauss–Legendre nodes and weights on [0, 1] (Newton on P_n).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            let w = 2.0 / ((1.0 - x * x) * dp * dp);
            (0.5 * (x + 1.0), 0.5 * w)
        })
        .collect()
}

/// `∫ ξ^α dA` over a planar polygon by a signed fan of triangles from vertex 0, each integrated
/// by the collapsed (Duffy) 8×8 Gauss rule, exact to degree 15 in each direction.
fn fan_quadrature(points: &[Point3<f64>], normal: &Vector3<f64>, frame: &Frame, alpha: [u32; 3]) -> f64 {
    let gl = gauss_legendre(8);
    let f = |x: Point3<f64>| {
        let xi = (x - frame.center) / frame.scale;
        xi.x.powi(alpha[0] as i32) * xi.y.powi(alpha[1] as i32) * xi.z.powi(alpha[2] as i32)
    };
    let a = points[0];
    let mut total = 0.0;
    for i in 1..points.len() - 1 {
        let (b, c) = (points[i], points[i + 1]);
        let jac = (b - a).cross(&(c - b)).dot(normal); // signed twice-area
        for &(s, ws) in &gl {
            for &(t, wt) in &gl {
                total += ws * wt * jac * s * f(a + s * ((b - a) + t * (c - b)));
            }
        }
    }
    total
}

/// `sup |ξ^α|` over points with per-axis bounds `m`: the natural size of a moment.
fn bound(alpha: [u32; 3], m: [f64; 3]) -> f64 {
    (0..3).map(|k| m[k].powi(alpha[k] as i32)).product()
}

fn axis_max(points: &[Point3<f64>], frame: &Frame) -> [f64; 3] {
    let mut m = [0.0f64; 3];
    for p in points {
        let xi = (p - frame.center) / frame.scale;
        for k in 0..3 {
            m[k] = m[k].max(xi[k].abs());
        }
    }
    m
}

/// Builds a one-element mesh from polygons given by coordinates (vertices deduplicated).
#[derive(Default)]
struct Builder {
    mesh: PolyhedralMesh,
}

impl Builder {
    fn vertex(&mut self, p: Point3<f64>) -> u32 {
        if let Some(i) = self.mesh.vertices.iter().position(|q| *q == p) {
            return i as u32;
        }
        self.mesh.vertices.push(p);
        (self.mesh.vertices.len() - 1) as u32
    }

    fn face(&mut self, points: &[Point3<f64>]) {
        let polygon = points.iter().map(|p| self.vertex(*p)).collect();
        self.mesh.faces.push(PolyFace { polygon, inner: 0, outer: None });
        self.mesh.num_elements = 1;
    }
}

fn tet_mesh(p: [Point3<f64>; 4]) -> PolyhedralMesh {
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    PolyhedralMesh {
        vertices: p.to_vec(),
        faces: faces.iter().map(|f| PolyFace { polygon: f.to_vec(), inner: 0, outer: None }).collect(),
        num_elements: 1,
    }
}

const DEGREE: usize = 4;

// ---------------------------------------------------------------------------------------------
// Monomial order.

#[test]
fn monomial_order_and_index() {
    let e = monomial_exponents(2);
    assert_eq!(
        e,
        vec![
            [0, 0, 0],
            [1, 0, 0],
            [0, 1, 0],
            [0, 0, 1],
            [2, 0, 0],
            [1, 1, 0],
            [1, 0, 1],
            [0, 2, 0],
            [0, 1, 1],
            [0, 0, 2]
        ]
    );
    for d in 0..=10usize {
        let e = monomial_exponents(d);
        assert_eq!(e.len(), (d + 1) * (d + 2) * (d + 3) / 6);
        for (i, a) in e.iter().enumerate() {
            assert_eq!(monomial_index(*a), i, "{a:?}");
        }
    }
    // Absurd exponents do not overflow or panic.
    assert!(monomial_index([u32::MAX; 3]) > 0);
}

// ---------------------------------------------------------------------------------------------
// Tetrahedra.

#[test]
fn tetrahedra_match_the_simplex_closed_form() {
    let mut rng = Rng(0x7e7);
    let mut worst = 0.0f64;
    let mut worst_high = 0.0f64;
    let mut worst_strict = [0.0f64; 2];
    let degree = 6;
    for trial in 0..20 {
        let lo = Point3::new(-1.0, -1.0, -1.0);
        let hi = Point3::new(2.0, 1.5, 3.0);
        let mut p: [Point3<f64>; 4] = std::array::from_fn(|_| rng.point(&lo, &hi));
        let jac = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
        if jac.determinant() < 0.0 {
            p.swap(1, 2);
        }
        let jac = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
        let det = jac.determinant();
        let mesh = tet_mesh(p);
        assert!(mesh.validate(1e-12).is_ok(), "trial {trial}");
        // A frame off the tetrahedron's centre, scale of its size (trials alternate far-ish).
        let centroid = Point3::from((p[0].coords + p[1].coords + p[2].coords + p[3].coords) / 4.0);
        let offset = if trial % 2 == 0 { 0.3 } else { 2.0 };
        let frame = Frame { center: centroid + offset * Vector3::new(0.7, -0.4, 0.5), scale: 1.37 };
        let mut got = Vec::new();
        element_moments(&mesh, 0, &frame, degree, &mut got);
        let m = axis_max(&p, &frame);
        for (i, &alpha) in monomial_exponents(degree).iter().enumerate() {
            let q0 = (p[0] - frame.center) / frame.scale;
            let cols = jac / frame.scale;
            let affine: [[f64; 4]; 3] = std::array::from_fn(|k| [q0[k], cols[(k, 0)], cols[(k, 1)], cols[(k, 2)]]);
            let exact = det * simplex_integral(&affine_power(alpha, &affine));
            let size = det / 6.0 * bound(alpha, m);
            let err = (got[i] - exact).abs() / size.max(exact.abs());
            let low = alpha.iter().sum::<u32>() <= DEGREE as u32;
            if low {
                worst = worst.max(err);
            } else {
                worst_high = worst_high.max(err);
            }
            if exact.abs() > 0.01 * size {
                let w = &mut worst_strict[usize::from(!low)];
                *w = w.max((got[i] - exact).abs() / exact.abs());
            }
            assert!(err < 1e-12, "trial {trial} α {alpha:?}: got {} exact {exact} err {err:e}", got[i]);
        }
    }
    assert!(worst_strict[0] < 1e-12, "relative error {:e} of a non-negligible moment of degree ≤ 4", worst_strict[0]);
    println!(
        "tetrahedra: max error relative to V·sup|ξ^α|: {worst:.2e} (degree ≤ 4), {worst_high:.2e} (degree 5–6); \
         relative to the moment itself where it is ≥ 1% of that: {:.2e}, {:.2e}",
        worst_strict[0], worst_strict[1]
    );
}

// ---------------------------------------------------------------------------------------------
// Boxes and the grid.

fn check_box(mesh: &PolyhedralMesh, element: usize, lo: [f64; 3], hi: [f64; 3], frame: &Frame) -> f64 {
    let mut got = Vec::new();
    element_moments(mesh, element, frame, DEGREE, &mut got);
    let corners: Vec<Point3<f64>> = (0..8)
        .map(|c| Point3::new([lo[0], hi[0]][c & 1], [lo[1], hi[1]][(c >> 1) & 1], [lo[2], hi[2]][c >> 2]))
        .collect();
    let m = axis_max(&corners, frame);
    let volume = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
    let mut worst = 0.0f64;
    for (i, &alpha) in monomial_exponents(DEGREE).iter().enumerate() {
        let exact = boxes_moment(&[(lo, hi)], &Matrix3::identity(), Vector3::zeros(), frame, alpha);
        let err = (got[i] - exact).abs() / (volume * bound(alpha, m)).max(exact.abs());
        assert!(err < 1e-12, "element {element} α {alpha:?}: got {} exact {exact} err {err:e}", got[i]);
        worst = worst.max(err);
    }
    worst
}

#[test]
fn boxes_match_products_of_1d_integrals() {
    let origin = Point3::new(0.3, -1.2, 2.0);
    let h = 0.7;
    let one = PolyhedralMesh::grid(origin, h, [1, 1, 1]);
    let lo = [0.3, -1.2, 2.0];
    let hi = [1.0, -0.5, 2.7];
    let centred = Frame { center: Point3::new(0.65, -0.85, 2.35), scale: 0.35 };
    let off = Frame { center: Point3::new(0.1, 0.2, -0.3), scale: 1.7 };
    let e1 = check_box(&one, 0, lo, hi, &centred);
    let e2 = check_box(&one, 0, lo, hi, &off);
    // Element (1, 2, 0) of a 2×3×1 grid.
    let grid = PolyhedralMesh::grid(origin, h, [2, 3, 1]);
    let (i, j) = (1.0, 2.0);
    let lo = [0.3 + i * h, -1.2 + j * h, 2.0];
    let hi = [lo[0] + h, lo[1] + h, 2.7];
    let e3 = check_box(&grid, 1 + 2 * 2, lo, hi, &Frame { center: Point3::new(1.0, 0.3, 2.2), scale: 0.5 });
    println!("boxes: max error {e1:.2e} (centred frame), {e2:.2e} (offset frame), {e3:.2e} (2×3×1 grid element)");
}

#[test]
fn grid_elements_are_boxes_and_sum_to_the_box() {
    let origin = Point3::new(-0.7, 0.3, 1.1);
    let h = 0.25;
    let dims = [3, 2, 4];
    let grid = PolyhedralMesh::grid(origin, h, dims);
    let element_faces = grid.element_faces();
    let global = Frame { center: origin + 0.5 * h * Vector3::new(3.0, 2.0, 4.0), scale: 0.7 };
    let mut total = 0.0;
    let mut worst = 0.0f64;
    let (mut scanned, mut listed) = (Vec::new(), Vec::new());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let e = i + dims[0] * (j + dims[1] * k);
                let lo = [origin.x + i as f64 * h, origin.y + j as f64 * h, origin.z + k as f64 * h];
                let hi = [lo[0] + h, lo[1] + h, lo[2] + h];
                let own =
                    Frame { center: Point3::new(lo[0] + h / 2.0, lo[1] + h / 2.0, lo[2] + h / 2.0), scale: h / 2.0 };
                worst = worst.max(check_box(&grid, e, lo, hi, &own)).max(check_box(&grid, e, lo, hi, &global));
                element_moments(&grid, e, &global, DEGREE, &mut scanned);
                element_moments_from_faces(&grid, &element_faces[e], &global, DEGREE, &mut listed);
                assert_eq!(scanned, listed, "element {e}");
                total += listed[0];
            }
        }
    }
    let exact = 24.0 * h * h * h;
    println!("grid: volume sum error {:.2e}, max element moment error {worst:.2e}", (total - exact).abs() / exact);
    assert!((total - exact).abs() < 1e-13 * exact);
    let stats = grid.validate(1e-12).unwrap();
    assert_eq!(
        (stats.elements, stats.faces, stats.boundary_faces),
        (24, 4 * 2 * 4 + 3 * 3 * 4 + 3 * 2 * 5, 2 * (6 + 12 + 8))
    );
    assert!((stats.volume - exact).abs() < 1e-13 * exact);
}

/// The conditioning argument of the math doc §3: with the frame at distance `R` from an element
/// of size `h` (scale `h`), the error relative to `V·sup|ξ^α|` grows like `ε·R/h`, not like
/// `(R/h)^q`. Measured on a rotated box (so no face is axis-aligned) against the box formula.
#[test]
fn error_grows_linearly_with_frame_distance() {
    let rotation = *Rotation3::from_euler_angles(0.4, 0.9, -0.3).matrix();
    let t = Vector3::new(0.3, 0.1, -0.2);
    let (lo, hi) = ([0.0; 3], [1.0, 0.8, 1.2]);
    let mut b = Builder::default();
    let p = |c: usize| {
        Point3::from(
            rotation * Vector3::new([lo[0], hi[0]][c & 1], [lo[1], hi[1]][(c >> 1) & 1], [lo[2], hi[2]][c >> 2]) + t,
        )
    };
    for quad in [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]] {
        b.face(&quad.map(p));
    }
    let mesh = b.mesh;
    mesh.validate(1e-12).unwrap();
    let centre = Point3::from(rotation * Vector3::new(0.5, 0.4, 0.6) + t);
    let mut got = Vec::new();
    for distance in [0.0f64, 10.0, 100.0, 1000.0] {
        let frame = Frame { center: centre + distance * Vector3::new(0.6, -0.48, 0.64), scale: 1.0 };
        element_moments(&mesh, 0, &frame, DEGREE, &mut got);
        let m = axis_max(&mesh.vertices, &frame);
        let mut worst = 0.0f64;
        for (i, &alpha) in monomial_exponents(DEGREE).iter().enumerate() {
            let exact = boxes_moment(&[(lo, hi)], &rotation, t, &frame, alpha);
            worst = worst.max((got[i] - exact).abs() / (0.96 * bound(alpha, m)));
        }
        println!("frame at distance {distance:6} h: max error relative to V·sup|ξ^α| {worst:.2e}");
        assert!(worst < 1e-14 * distance.max(1.0), "distance {distance}: {worst:e}");
    }
}

// ---------------------------------------------------------------------------------------------
// Faces.

#[test]
fn face_moments_match_fan_quadrature() {
    let mut rng = Rng(0xface);
    let origin = Point3::new(0.4, -0.3, 1.2);
    let rotation = Rotation3::from_euler_angles(0.3, -1.1, 0.7);
    let (eu, ev, normal) = (rotation * Vector3::x(), rotation * Vector3::y(), rotation * Vector3::z());
    let planar = |uv: &[(f64, f64)]| uv.iter().map(|&(u, v)| origin + u * eu + v * ev).collect::<Vec<_>>();
    let shapes: Vec<(&str, Vec<Point3<f64>>)> = vec![
        ("random triangle", {
            let lo = Point3::new(-1.0, -1.0, -1.0);
            let hi = Point3::new(1.0, 1.0, 1.0);
            (0..3).map(|_| rng.point(&lo, &hi)).collect()
        }),
        ("convex quad", planar(&[(0.0, 0.0), (1.3, 0.1), (1.1, 0.9), (-0.2, 0.7)])),
        // Non-convex, and vertex 0 sits at a reflex corner: the signed fan overlaps itself.
        ("non-convex arrow", planar(&[(0.5, 0.4), (0.0, 1.0), (0.0, 0.0), (1.5, 0.5), (0.0, 1.5), (0.2, 1.1)])),
    ];
    for (name, points) in shapes {
        let n = if name == "random triangle" {
            (points[1] - points[0]).cross(&(points[2] - points[0])).normalize()
        } else {
            normal
        };
        let mesh = PolyhedralMesh {
            vertices: points.clone(),
            faces: vec![PolyFace { polygon: (0..points.len() as u32).collect(), inner: 0, outer: None }],
            num_elements: 1,
        };
        let frame = Frame { center: Point3::new(0.1, 0.25, 0.9), scale: 0.8 };
        let mut got = Vec::new();
        face_moments(&mesh, 0, &frame, DEGREE, &mut got);
        let area = fan_quadrature(&points, &n, &frame, [0, 0, 0]);
        assert!(area > 0.0, "{name}: polygon must be counter-clockwise around its normal");
        let m = axis_max(&points, &frame);
        let mut worst = 0.0f64;
        for (i, &alpha) in monomial_exponents(DEGREE).iter().enumerate() {
            let exact = fan_quadrature(&points, &n, &frame, alpha);
            let err = (got[i] - exact).abs() / (area * bound(alpha, m)).max(exact.abs());
            assert!(err < 1e-12, "{name} α {alpha:?}: got {} exact {exact} err {err:e}", got[i]);
            worst = worst.max(err);
        }
        let (a, normal_out, _) = face_area_normal_centroid(&mesh, 0);
        assert!((a - area).abs() < 1e-13 * area && (normal_out - n).norm() < 1e-13, "{name}");
        println!("face {name}: area {area:.6}, max error {worst:.2e}");
    }
}

// ---------------------------------------------------------------------------------------------
// Non-convex polyhedra.

/// L polygon in (u, v), counter-clockwise.
const L: [(f64, f64); 6] = [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)];

/// The prism `L × [0, height]` scaled by `size` and moved to `origin`, with its boxes.
fn l_prism(origin: Point3<f64>, size: f64, height: f64) -> (PolyhedralMesh, Boxes) {
    let p = |u: f64, v: f64, w: f64| origin + Vector3::new(size * u, size * v, w);
    let mut b = Builder::default();
    let bottom: Vec<_> = L.iter().rev().map(|&(u, v)| p(u, v, 0.0)).collect();
    let top: Vec<_> = L.iter().map(|&(u, v)| p(u, v, height)).collect();
    b.face(&bottom);
    b.face(&top);
    for i in 0..L.len() {
        let (a, c) = (L[i], L[(i + 1) % L.len()]);
        b.face(&[p(a.0, a.1, 0.0), p(c.0, c.1, 0.0), p(c.0, c.1, height), p(a.0, a.1, height)]);
    }
    let o = [origin.x, origin.y, origin.z];
    let boxes = vec![
        (o, [o[0] + 2.0 * size, o[1] + size, o[2] + height]),
        ([o[0], o[1] + size, o[2]], [o[0] + size, o[1] + 2.0 * size, o[2] + height]),
    ];
    (b.mesh, boxes)
}

/// The cube `[0, 1]³` without the corner block `[a, 1]`, scaled by `size`, rotated and moved:
/// nine faces, three of them non-convex L polygons; also returns its boxes in `y`.
fn notched_cube(a: [f64; 3], size: f64, rotation: &Matrix3<f64>, t: Vector3<f64>) -> (PolyhedralMesh, Boxes) {
    let [ax, ay, az] = a;
    let p = |x: f64, y: f64, z: f64| Point3::from(rotation * (size * Vector3::new(x, y, z)) + t);
    let faces: Vec<Vec<[f64; 3]>> = vec![
        vec![[0., 0., 0.], [0., 0., 1.], [0., 1., 1.], [0., 1., 0.]],
        vec![[0., 0., 0.], [1., 0., 0.], [1., 0., 1.], [0., 0., 1.]],
        vec![[0., 0., 0.], [0., 1., 0.], [1., 1., 0.], [1., 0., 0.]],
        vec![[1., 0., 0.], [1., 1., 0.], [1., 1., az], [1., ay, az], [1., ay, 1.], [1., 0., 1.]],
        vec![[0., 1., 0.], [0., 1., 1.], [ax, 1., 1.], [ax, 1., az], [1., 1., az], [1., 1., 0.]],
        vec![[0., 0., 1.], [1., 0., 1.], [1., ay, 1.], [ax, ay, 1.], [ax, 1., 1.], [0., 1., 1.]],
        vec![[ax, ay, az], [ax, 1., az], [ax, 1., 1.], [ax, ay, 1.]],
        vec![[ax, ay, az], [ax, ay, 1.], [1., ay, 1.], [1., ay, az]],
        vec![[ax, ay, az], [1., ay, az], [1., 1., az], [ax, 1., az]],
    ];
    let mut b = Builder::default();
    for f in &faces {
        let pts: Vec<_> = f.iter().map(|c| p(c[0], c[1], c[2])).collect();
        b.face(&pts);
    }
    let s = size;
    let boxes = vec![
        ([0.0, 0.0, 0.0], [ax * s, s, s]),
        ([ax * s, 0.0, 0.0], [s, ay * s, s]),
        ([ax * s, ay * s, 0.0], [s, s, az * s]),
    ];
    (b.mesh, boxes)
}

fn check_against_boxes(
    name: &str,
    mesh: &PolyhedralMesh,
    boxes: &[([f64; 3], [f64; 3])],
    rotation: &Matrix3<f64>,
    t: Vector3<f64>,
    frame: &Frame,
) -> Vec<f64> {
    let stats = mesh.validate(1e-12).unwrap_or_else(|e| panic!("{name}: {e}"));
    let mut got = Vec::new();
    element_moments(mesh, 0, frame, DEGREE, &mut got);
    let volume: f64 = boxes.iter().map(|(lo, hi)| (0..3).map(|k| hi[k] - lo[k]).product::<f64>()).sum();
    assert!((stats.volume - volume).abs() < 1e-13 * volume);
    let m = axis_max(&mesh.vertices, frame);
    let mut worst = 0.0f64;
    for (i, &alpha) in monomial_exponents(DEGREE).iter().enumerate() {
        let exact = boxes_moment(boxes, rotation, t, frame, alpha);
        let err = (got[i] - exact).abs() / (volume * bound(alpha, m)).max(exact.abs());
        assert!(err < 1e-12, "{name} α {alpha:?}: got {} exact {exact} err {err:e}", got[i]);
        worst = worst.max(err);
    }
    println!("{name}: max error against the box splitting {worst:.2e}");
    got
}

#[test]
fn non_convex_polyhedra_match_their_box_splitting() {
    let (prism, boxes) = l_prism(Point3::new(0.2, -0.5, 1.0), 0.6, 0.45);
    let frame = Frame { center: Point3::new(0.7, 0.1, 1.3), scale: 0.6 };
    check_against_boxes("L-prism", &prism, &boxes, &Matrix3::identity(), Vector3::zeros(), &frame);

    let t = Vector3::new(0.2, -0.4, 0.7);
    let (cube, boxes) = notched_cube([0.45, 0.6, 0.35], 1.3, &Matrix3::identity(), t);
    let frame = Frame { center: Point3::new(0.8, 0.1, 1.2), scale: 0.9 };
    let got = check_against_boxes("notched cube", &cube, &boxes, &Matrix3::identity(), t, &frame);

    // Volume and centroid from the boxes.
    let (volume, centroid) = element_volume_centroid(&cube, 0);
    let (mut v, mut c) = (0.0, Vector3::zeros());
    for (lo, hi) in &boxes {
        let vb = (0..3).map(|k| hi[k] - lo[k]).product::<f64>();
        v += vb;
        c += vb * Vector3::from_fn(|k, _| 0.5 * (lo[k] + hi[k]));
    }
    let exact_centroid = c / v + t;
    assert!((volume - v).abs() < 1e-14 * v && (volume - got[0]).abs() < 1e-14 * v);
    assert!((centroid.coords - exact_centroid).norm() < 1e-14, "{centroid} vs {exact_centroid}");

    let rotation =
        *Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(Vector3::new(1.0, 2.0, -0.5)), 0.9).matrix();
    let (rotated, boxes) = notched_cube([0.45, 0.6, 0.35], 1.3, &rotation, t);
    let frame = Frame { center: Point3::new(0.5, 0.3, 1.1), scale: 0.9 };
    check_against_boxes("rotated notched cube", &rotated, &boxes, &rotation, t, &frame);
}

/// Monte Carlo estimate of every moment over `inside ∩ [lo, hi]`: (mean, standard error).
fn monte_carlo(
    lo: Point3<f64>,
    hi: Point3<f64>,
    inside: impl Fn(&Point3<f64>) -> bool,
    frame: &Frame,
    samples: usize,
    seed: u64,
) -> Vec<(f64, f64)> {
    let exps = monomial_exponents(DEGREE);
    let mut rng = Rng(seed);
    let (mut sum, mut sum2) = (vec![0.0; exps.len()], vec![0.0; exps.len()]);
    let mut values = vec![0.0; exps.len()];
    for _ in 0..samples {
        let x = rng.point(&lo, &hi);
        if !inside(&x) {
            continue;
        }
        let xi = (x - frame.center) / frame.scale;
        for (v, e) in values.iter_mut().zip(&exps) {
            *v = xi.x.powi(e[0] as i32) * xi.y.powi(e[1] as i32) * xi.z.powi(e[2] as i32);
        }
        for i in 0..exps.len() {
            sum[i] += values[i];
            sum2[i] += values[i] * values[i];
        }
    }
    let box_volume = (hi - lo).product();
    let n = samples as f64;
    (0..exps.len())
        .map(|i| {
            let mean = sum[i] / n;
            let var = sum2[i] / n - mean * mean;
            (box_volume * mean, box_volume * (var / n).sqrt())
        })
        .collect()
}

#[test]
fn non_convex_polyhedra_match_monte_carlo() {
    const SAMPLES: usize = 4_000_000;
    let origin = Point3::new(0.2, -0.5, 1.0);
    let (size, height) = (0.6, 0.45);
    let (prism, _) = l_prism(origin, size, height);
    let frame = Frame { center: Point3::new(0.7, 0.1, 1.3), scale: 0.6 };
    let inside_l = |x: &Point3<f64>| {
        let (u, v) = ((x.x - origin.x) / size, (x.y - origin.y) / size);
        (u < 1.0 || v < 1.0) && x.z >= origin.z && x.z <= origin.z + height
    };
    let hi = origin + Vector3::new(2.0 * size, 2.0 * size, height);

    let t = Vector3::new(0.2, -0.4, 0.7);
    let (a, s) = ([0.45, 0.6, 0.35], 1.3);
    let (cube, _) = notched_cube(a, s, &Matrix3::identity(), t);
    let cube_frame = Frame { center: Point3::new(0.8, 0.1, 1.2), scale: 0.9 };
    let inside_notched = |x: &Point3<f64>| {
        let y = (x.coords - t) / s;
        !(y.x > a[0] && y.y > a[1] && y.z > a[2])
    };
    let cases = [
        ("L-prism", &prism, &frame, origin, hi, &inside_l as &dyn Fn(&Point3<f64>) -> bool),
        ("notched cube", &cube, &cube_frame, Point3::from(t), Point3::from(t + Vector3::repeat(s)), &inside_notched),
    ];
    for (name, mesh, frame, lo, hi, inside) in cases {
        let mut got = Vec::new();
        element_moments(mesh, 0, frame, DEGREE, &mut got);
        let mc = monte_carlo(lo, hi, inside, frame, SAMPLES, 0x5eed);
        let mut worst = 0.0f64;
        for (i, &(mean, se)) in mc.iter().enumerate() {
            let z = (got[i] - mean).abs() / se;
            assert!(z < 5.0, "{name} monomial {i}: exact {} MC {mean} ± {se}", got[i]);
            worst = worst.max(z);
        }
        println!("{name}: Monte Carlo ({SAMPLES} samples) max deviation {worst:.2} standard errors");
    }
}

// ---------------------------------------------------------------------------------------------
// Orientation of faces, validation errors, robustness.

#[test]
fn grid_face_normals_point_from_inner_to_outer() {
    let grid = PolyhedralMesh::grid(Point3::new(1.0, 2.0, 3.0), 0.5, [2, 2, 2]);
    for (f, face) in grid.faces.iter().enumerate() {
        let (area, normal, centroid) = face_area_normal_centroid(&grid, f);
        assert!((area - 0.25).abs() < 1e-15, "face {f}");
        let (_, inner) = element_volume_centroid(&grid, face.inner as usize);
        let away = centroid - inner;
        assert!((normal.dot(&away) - 0.25).abs() < 1e-14, "face {f}: normal {normal} not out of inner");
        assert!((normal.norm() - 1.0).abs() < 1e-15 && normal.iter().filter(|c| c.abs() > 0.5).count() == 1);
    }
}

fn one_cell() -> PolyhedralMesh {
    PolyhedralMesh::grid(Point3::new(0.0, 0.0, 0.0), 2.0, [1, 1, 1])
}

#[test]
fn validate_names_the_offender() {
    let tol = 1e-9;
    assert_eq!(PolyhedralMesh::default().validate(tol), Err(GeometryError::NoElements));
    assert_eq!(one_cell().validate(-1.0), Err(GeometryError::InvalidTolerance { tolerance: -1.0 }));

    let mut m = one_cell();
    m.vertices[3].y = f64::NAN;
    assert!(matches!(m.validate(tol), Err(GeometryError::NonFiniteVertex { vertex: 3, .. })));

    let mut m = one_cell();
    m.faces[4].polygon[2] = 99;
    assert_eq!(m.validate(tol), Err(GeometryError::FaceVertexOutOfRange { face: 4, index: 99, vertex_count: 8 }));

    let mut m = one_cell();
    m.faces[2].outer = Some(7);
    assert_eq!(m.validate(tol), Err(GeometryError::FaceElementOutOfRange { face: 2, element: 7, num_elements: 1 }));
    let mut m = one_cell();
    m.faces[5].inner = 1;
    assert_eq!(m.validate(tol), Err(GeometryError::FaceElementOutOfRange { face: 5, element: 1, num_elements: 1 }));
    let mut m = one_cell();
    m.faces[5].outer = Some(0);
    assert_eq!(m.validate(tol), Err(GeometryError::SelfAdjacentFace { face: 5, element: 0 }));

    let mut m = one_cell();
    m.faces[1].polygon = vec![0, 1, 0];
    assert!(matches!(m.validate(tol), Err(GeometryError::DegenerateFace { face: 1, distinct_vertices: 2, .. })));
    let mut m = one_cell();
    m.vertices.push(Point3::new(4.0, 0.0, 0.0)); // vertex 8, collinear with 0 = (0,0,0) and 1 = (2,0,0)
    m.faces[3].polygon = vec![0, 1, 8];
    let err = m.validate(tol).unwrap_err();
    assert!(matches!(err, GeometryError::DegenerateFace { face: 3, distinct_vertices: 3, area: 0.0, .. }), "{err}");
    let mut m = one_cell();
    let repeated = m.faces[3].polygon[1];
    m.faces[3].polygon.push(repeated);
    let err = m.validate(tol).unwrap_err();
    assert!(matches!(err, GeometryError::DegenerateFace { face: 3, distinct_vertices: 4, .. }), "{err}");

    // Lift one corner of the face z = 2 (face 5: vertices 4, 5, 7, 6 of the 1-cell grid) by
    // δ = 0.1·h: relative deviation δ'/(2√2 (2 + δ'²)) with δ' = δ/h (quadrilateral Newell
    // plane through the vertex mean, diameter the long diagonal).
    let mut m = one_cell();
    let top = m.faces[5].polygon.clone();
    assert!(top.iter().all(|&v| m.vertices[v as usize].z == 2.0));
    let lifted = top[2] as usize; // opposite to top[0]
    m.vertices[lifted].z += 0.2;
    let d = 0.1f64;
    let expected = d / (2.0 * 2f64.sqrt() * (2.0 + d * d));
    // The lifted vertex also lies on two side faces, but moving it along z keeps it in their
    // planes: only the top face is warped.
    match m.validate(1e-3) {
        Err(GeometryError::NonPlanarFace { face, vertex, deviation, tolerance }) => {
            assert_eq!((face, tolerance), (5, 1e-3));
            assert!(top.contains(&vertex));
            assert!((deviation - expected).abs() < 1e-12, "deviation {deviation} vs {expected}");
            println!("non-planar face: deviation {deviation:.6e} (expected {expected:.6e})");
        }
        other => panic!("expected NonPlanarFace, got {other:?}"),
    }
    assert!(m.validate(0.02).is_ok());

    // Removing face 5 opens the element; the reported edge is the reverse of one of face 5's.
    let mut m = one_cell();
    let removed = m.faces.remove(5).polygon;
    match m.validate(tol) {
        Err(GeometryError::OpenElementBoundary { element: 0, a, b, .. }) => {
            let k = removed.len();
            assert!((0..k).any(|i| (removed[i], removed[(i + 1) % k]) == (b, a)), "edge ({a}, {b})");
        }
        other => panic!("expected OpenElementBoundary, got {other:?}"),
    }

    // Flipping face 2 makes it traverse its edges in the same direction as its neighbours.
    let mut m = one_cell();
    m.faces[2].polygon.reverse();
    match m.validate(tol) {
        Err(GeometryError::InconsistentElementOrientation { element: 0, faces, .. }) => {
            assert!(faces.0 == 2 || faces.1 == 2, "{faces:?}");
        }
        other => panic!("expected InconsistentElementOrientation, got {other:?}"),
    }

    // Flipping all faces: closed, consistent, inward: volume −h³.
    let mut m = one_cell();
    for f in &mut m.faces {
        f.polygon.reverse();
    }
    match m.validate(tol) {
        Err(GeometryError::NonPositiveVolume { element: 0, volume }) => assert!((volume + 8.0).abs() < 1e-13),
        other => panic!("expected NonPositiveVolume, got {other:?}"),
    }

    // In a 2-element grid, swapping inner and outer of the interface flips it for both.
    let mut m = PolyhedralMesh::grid(Point3::origin(), 1.0, [2, 1, 1]);
    let interface = m.faces.iter().position(|f| f.outer.is_some()).unwrap();
    let f = &mut m.faces[interface];
    (f.inner, f.outer) = (f.outer.unwrap(), Some(f.inner));
    assert!(matches!(m.validate(tol), Err(GeometryError::InconsistentElementOrientation { element: 0, .. })));

    // Messages name the offender.
    let msg = GeometryError::NonPlanarFace { face: 7, vertex: 3, deviation: 0.5, tolerance: 1e-6 }.to_string();
    assert!(msg.contains("face 7") && msg.contains("vertex 3"), "{msg}");
    let msg = GeometryError::OpenElementBoundary { element: 4, a: 1, b: 2, face: 9 }.to_string();
    assert!(msg.contains("element 4") && msg.contains("(1, 2)") && msg.contains("face 9"), "{msg}");
}

#[test]
fn bad_queries_return_errors_or_nan_without_panicking() {
    let grid = one_cell();
    let frame = Frame { center: Point3::origin(), scale: 1.0 };
    let mut out = Vec::new();
    assert_eq!(
        try_element_moments(&grid, 3, &frame, 2, &mut out),
        Err(GeometryError::ElementOutOfRange { element: 3, num_elements: 1 })
    );
    element_moments(&grid, 3, &frame, 2, &mut out);
    assert!(out.len() == 10 && out.iter().all(|x| x.is_nan()));
    assert_eq!(
        try_face_moments(&grid, 6, &frame, 1, &mut out),
        Err(GeometryError::FaceOutOfRange { face: 6, num_faces: 6 })
    );
    let bad = Frame { center: Point3::origin(), scale: 0.0 };
    assert!(matches!(try_face_moments(&grid, 0, &bad, 1, &mut out), Err(GeometryError::InvalidFrame { .. })));
    let deg = MAX_MOMENT_DEGREE + 1;
    assert_eq!(
        try_element_moments(&grid, 0, &frame, deg, &mut out),
        Err(GeometryError::MomentDegreeTooHigh { degree: deg, limit: MAX_MOMENT_DEGREE })
    );
    element_moments(&grid, 0, &frame, usize::MAX, &mut out);
    assert!(out.is_empty());
    let (v, c) = element_volume_centroid(&grid, 5);
    assert!(v.is_nan() && c.x.is_nan());

    // Random garbage: nothing panics.
    let mut rng = Rng(0xbad);
    let pick = |rng: &mut Rng, n: u64| (rng.next_u64() % n) as u32;
    for _ in 0..3000 {
        let nv = pick(&mut rng, 7) as usize;
        let vertices = (0..nv)
            .map(|_| {
                let mut p = Point3::new(rng.unit(), rng.unit(), rng.unit());
                match pick(&mut rng, 10) {
                    0 => p.x = f64::NAN,
                    1 => p.y = f64::INFINITY,
                    2 => p = Point3::origin(),
                    _ => {}
                }
                p
            })
            .collect();
        let faces = (0..pick(&mut rng, 7))
            .map(|_| PolyFace {
                polygon: (0..pick(&mut rng, 6)).map(|_| pick(&mut rng, 9)).collect(),
                inner: pick(&mut rng, 4),
                outer: if pick(&mut rng, 2) == 0 { None } else { Some(pick(&mut rng, 4)) },
            })
            .collect();
        let mesh = PolyhedralMesh { vertices, faces, num_elements: pick(&mut rng, 4) as usize };
        let tol = [0.0, 1e-6, -1.0, f64::NAN, f64::INFINITY][pick(&mut rng, 5) as usize];
        let _ = mesh.validate(tol);
        let degree = pick(&mut rng, 4) as usize;
        for e in 0..5 {
            element_moments(&mesh, e, &frame, degree, &mut out);
            let _ = element_volume_centroid(&mesh, e);
        }
        for f in 0..8 {
            face_moments(&mesh, f, &frame, degree, &mut out);
            let _ = face_area_normal_centroid(&mesh, f);
        }
    }
}

/// Moments moved to another frame by `shift_moments` (the binomial map, no integration) equal
/// the moments integrated afresh in that frame, for a rotated non-convex element and each of
/// its faces, to a child's frame (half the scale, off centre) and back to a frame twice as
/// large; a wrong sign of the offset or power of the ratio misses by O(1).
#[test]
fn shifted_moments_equal_moments_integrated_in_the_new_frame() {
    let rotation = Rotation3::from_euler_angles(0.3, -0.7, 1.1).into_inner();
    let (mesh, _) = notched_cube([0.35, 0.5, 0.4], 0.8, &rotation, Vector3::new(0.2, -0.4, 0.9));
    let degree = 5;
    let parent = cleave_geometry::element_frame(&mesh, 0);
    let child =
        Frame { center: parent.center + Vector3::new(0.3, -0.2, 0.1) * parent.scale, scale: 0.5 * parent.scale };
    let wide = Frame { center: parent.center - Vector3::new(0.1, 0.4, -0.2) * parent.scale, scale: 2.0 * parent.scale };
    let (mut from, mut fresh, mut shifted) = (Vec::new(), Vec::new(), Vec::new());
    let compare = |fresh: &[f64], shifted: &[f64], what: &str| {
        let size = fresh.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let worst = fresh.iter().zip(shifted).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(worst <= 1e-12 * size, "{what}: {worst:e} of {size:e}");
    };
    for to in [child, wide] {
        element_moments(&mesh, 0, &parent, degree, &mut from);
        element_moments(&mesh, 0, &to, degree, &mut fresh);
        shift_moments(&from, &parent, &to, degree, &mut shifted).unwrap();
        compare(&fresh, &shifted, "element");
        for f in 0..mesh.faces.len() {
            face_moments(&mesh, f, &parent, degree, &mut from);
            face_moments(&mesh, f, &to, degree, &mut fresh);
            shift_moments(&from, &parent, &to, degree, &mut shifted).unwrap();
            compare(&fresh, &shifted, &format!("face {f}"));
        }
    }
    // Bad input is an error, not a panic.
    let bad = Frame { center: parent.center, scale: 0.0 };
    assert!(shift_moments(&from, &parent, &bad, degree, &mut shifted).is_err());
    assert!(shift_moments(&from[1..], &parent, &child, degree, &mut shifted).is_err());
    assert!(shift_moments(&from, &parent, &child, MAX_MOMENT_DEGREE + 1, &mut shifted).is_err());
}
