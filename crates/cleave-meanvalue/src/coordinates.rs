//! 3D mean value coordinates on a convex polyhedron with polygonal faces, and their analytic
//! gradients: docs/math/mean-value.md, §2 (the polygon variant, eq. 5: each face's mean value
//! vector decomposed by the 2D mean value coordinates of the point where it meets the face
//! plane) and §3 (gradients, extended to that variant in §3.1). Points on or within
//! [`BOUNDARY_TOLERANCE`] of a face take the face's limit, the 2D coordinates of the polygon; no
//! evaluation divides by a vanishing distance.

use crate::polyhedron::{ConvexPolyhedron, Real};
use nalgebra::{Matrix3, Point3, Vector3};

/// Distance to a face plane, in units of the element's diameter, under which a point takes the
/// face's limit (measured error of the limit ≤ 6× this, mean-value.md §4).
pub const BOUNDARY_TOLERANCE: Real = 1e-12;

/// How far inside a gradient asked for on the boundary is evaluated instead, in diameters
/// (gradients are bounded but direction-dependent there; mean-value.md §4).
pub const GRADIENT_INSET: Real = 1e-9;

/// Distance under which a point counts as on a face (or a projected point as on a polygon edge):
/// [`BOUNDARY_TOLERANCE`] diameters, or four times the element's planarity defect when its cut
/// points' round-off is larger (a point that close to two faces' planes would otherwise meet a
/// face polygon's edge in the interior formula, where the 2D half-angle tangent is 0/0).
fn boundary_tolerance(element: &ConvexPolyhedron) -> Real {
    (BOUNDARY_TOLERANCE * element.diameter()).max(4.0 * element.planarity_defect())
}

/// The cross-product matrix `[a]×`.
fn cross_matrix(a: &Vector3<Real>) -> Matrix3<Real> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// Reusable buffers of one evaluation (an element's nodes and faces vary in size).
#[derive(Clone, Debug, Default)]
pub struct Workspace {
    weights: Vec<Real>,
    weight_gradients: Vec<Vector3<Real>>,
    face_mu: Vec<Real>,
    face_mu_gradients: Vec<Vector3<Real>>,
    t: Vec<Real>,
    t_gradients: Vec<Vector3<Real>>,
    /// One face's vertices, in order.
    polygon: Vec<Point3<Real>>,
    /// The values of the inset evaluation that gives a boundary point's gradients.
    inset_values: Vec<Real>,
}

/// 2D mean value coordinates (Floater 2003) of `y` in the convex polygon `points` (counter-
/// clockwise about `n`), in `mu`; with `gradients`, also `∇_y μ_j` (in the plane). `y` must lie
/// strictly inside. The half-angle tangents are `t_j = 2A_j / (s_j s_{j+1} + e_j·e_{j+1})`, which
/// loses nothing for small angles and only grows (like 1/distance) when `y` nears an edge.
fn polygon_coordinates(
    points: &[Point3<Real>],
    n: &Vector3<Real>,
    y: &Point3<Real>,
    mu: &mut Vec<Real>,
    gradients: Option<&mut Vec<Vector3<Real>>>,
    t: &mut Vec<Real>,
    t_gradients: &mut Vec<Vector3<Real>>,
) {
    let m = points.len();
    mu.clear();
    t.clear();
    t_gradients.clear();
    let e = |j: usize| points[j % m] - y;
    let want_gradients = gradients.is_some();
    for j in 0..m {
        let (a, b) = (e(j), e(j + 1));
        let (sa, sb) = (a.norm(), b.norm());
        let area2 = n.dot(&a.cross(&b));
        let denominator = sa * sb + a.dot(&b);
        let tj = area2 / denominator;
        t.push(tj);
        if want_gradients {
            // ∇(2A) = (e_j − e_{j+1}) × n, ∇s = −e/s, ∇(e_j·e_{j+1}) = −(e_j + e_{j+1}).
            let grad_area2 = (a - b).cross(n);
            let grad_denominator = -a * (sb / sa) - b * (sa / sb) - (a + b);
            t_gradients.push((grad_area2 - grad_denominator * tj) / denominator);
        }
    }
    let mut total = 0.0;
    for j in 0..m {
        let s = e(j).norm();
        let omega = (t[(j + m - 1) % m] + t[j]) / s;
        mu.push(omega);
        total += omega;
    }
    if let Some(gradients) = gradients {
        gradients.clear();
        let mut sum = Vector3::zeros();
        for j in 0..m {
            let a = e(j);
            let s = a.norm();
            // ω_j = (t_{j−1} + t_j)/s_j: ∇ω_j = (∇t_{j−1} + ∇t_j)/s_j + ω_j e_j / s_j².
            let g = (t_gradients[(j + m - 1) % m] + t_gradients[j]) / s + a * (mu[j] / (s * s));
            gradients.push(g);
            sum += g;
        }
        for j in 0..m {
            let g = (gradients[j] - sum * (mu[j] / total)) / total;
            gradients[j] = g;
        }
    }
    mu.iter_mut().for_each(|w| *w /= total);
}

/// The limit on the boundary: `x` projected onto face `f`, then the 2D coordinates of the
/// polygon, where a point within the tolerance of a polygon edge takes linear interpolation
/// along that edge (and a vertex its delta).
fn face_limit(element: &ConvexPolyhedron, f: usize, x: &Point3<Real>, values: &mut [Real], work: &mut Workspace) {
    let face = &element.faces()[f];
    let n = element.normals()[f];
    let vertices = element.vertices();
    let p = x + n * element.depth(f, x);
    values.iter_mut().for_each(|v| *v = 0.0);
    let tolerance = boundary_tolerance(element);
    let m = face.len();
    // On an edge's line: of the edges whose line holds the point (several, where straight
    // vertices make collinear edges), the one whose segment holds it, or comes nearest to.
    let mut on_edge: Option<(Real, usize, Real)> = None;
    for k in 0..m {
        let (a, b) = (vertices[face[k]], vertices[face[(k + 1) % m]]);
        let edge = b - a;
        let inward = n.cross(&edge).normalize();
        if inward.dot(&(p - a)) <= tolerance {
            let length = edge.norm();
            let along = (p - a).dot(&edge) / length;
            let beyond = (-along).max(along - length).max(0.0);
            if on_edge.is_none_or(|(best, ..)| beyond < best) {
                on_edge = Some((beyond, k, along));
            }
        }
    }
    if let Some((_, k, along)) = on_edge {
        let length = (vertices[face[(k + 1) % m]] - vertices[face[k]]).norm();
        // At a node (within the tolerance): exactly its delta, the Lagrange property.
        let s = if along <= tolerance {
            0.0
        } else if along >= length - tolerance {
            1.0
        } else {
            along / length
        };
        values[face[k]] += 1.0 - s;
        values[face[(k + 1) % m]] += s;
        return;
    }
    work.polygon.clear();
    work.polygon.extend(face.iter().map(|&v| vertices[v]));
    polygon_coordinates(&work.polygon, &n, &p, &mut work.face_mu, None, &mut work.t, &mut work.t_gradients);
    for (k, &v) in face.iter().enumerate() {
        values[v] += work.face_mu[k];
    }
}

/// Mean value coordinates `λ` of `x` in `element` (one per vertex, in `values`), and with
/// `gradients` their gradients `∇λ_i`. A point within [`BOUNDARY_TOLERANCE`] of a face plane, or
/// outside the element, takes the limit on the face it is farthest outside of (its projection's
/// 2D coordinates) for the values, and the gradient [`GRADIENT_INSET`] inside.
pub fn mean_value_coordinates(
    element: &ConvexPolyhedron,
    x: &Point3<Real>,
    values: &mut [Real],
    gradients: Option<&mut [Vector3<Real>]>,
    work: &mut Workspace,
) {
    let diameter = element.diameter();
    let tolerance = boundary_tolerance(element);
    let nearest = (0..element.faces().len())
        .map(|f| (f, element.depth(f, x)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("an element has faces");
    if nearest.1 <= tolerance {
        // Of the faces whose plane holds the point (coplanar faces where a neighbour's split
        // face was split alike), the one whose polygon holds its projection.
        let face = (0..element.faces().len())
            .filter(|&f| element.depth(f, x) <= tolerance.max(nearest.1))
            .map(|f| (f, outside_polygon(element, f, x)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(nearest.0, |(f, _)| f);
        face_limit(element, face, x, values, work);
        if let Some(gradients) = gradients {
            let centre = element.vertex_average();
            let inside = x + (centre - x).normalize() * (GRADIENT_INSET * diameter);
            let mut scratch = std::mem::take(&mut work.inset_values);
            scratch.resize(values.len(), 0.0);
            interior(element, &inside, &mut scratch, Some(gradients), work);
            work.inset_values = scratch;
        }
        return;
    }
    interior(element, x, values, gradients, work);
}

/// How far the projection of `x` onto face `f`'s plane lies outside its polygon (negative
/// inside): the largest outward distance from an edge's line.
fn outside_polygon(element: &ConvexPolyhedron, f: usize, x: &Point3<Real>) -> Real {
    let (face, n, vertices) = (&element.faces()[f], element.normals()[f], element.vertices());
    (0..face.len())
        .map(|k| {
            let (a, b) = (vertices[face[k]], vertices[face[(k + 1) % face.len()]]);
            let outward = (b - a).cross(&n);
            let length = outward.norm();
            if length > 0.0 { outward.dot(&(x - a)) / length } else { Real::MIN }
        })
        .fold(Real::MIN, Real::max)
}

/// (1)–(5) and (6)–(12) of mean-value.md for a point strictly inside every face plane.
fn interior(
    element: &ConvexPolyhedron,
    x: &Point3<Real>,
    values: &mut [Real],
    gradients: Option<&mut [Vector3<Real>]>,
    work: &mut Workspace,
) {
    let vertices = element.vertices();
    let k = vertices.len();
    let want_gradients = gradients.is_some();
    work.weights.clear();
    work.weights.resize(k, 0.0);
    work.weight_gradients.clear();
    work.weight_gradients.resize(k, Vector3::zeros());
    for (f, face) in element.faces().iter().enumerate() {
        let n = element.normals()[f];
        let h = element.depth(f, x);
        // The face's mean value vector m = ½ Σ θ ν over its edges, and its Jacobian.
        let mut mv = Vector3::zeros();
        let mut jm = Matrix3::zeros();
        let m = face.len();
        for e in 0..m {
            let (p, q) = (face[e], face[(e + 1) % m]);
            let dp = vertices[p] - x;
            let dq = vertices[q] - x;
            let (rp, rq) = (dp.norm(), dq.norm());
            let (up, uq) = (dp / rp, dq / rq);
            let edge = vertices[q] - vertices[p];
            let qv = dp.cross(&edge);
            let qn = qv.norm();
            let nu = qv / qn;
            let theta = up.cross(&uq).norm().atan2(up.dot(&uq));
            mv += nu * (0.5 * theta);
            if want_gradients {
                let grad_theta = nu.cross(&up) / rp + uq.cross(&nu) / rq;
                let jnu = (Matrix3::identity() - nu * nu.transpose()) * cross_matrix(&edge) / qn;
                jm += (nu * grad_theta.transpose() + jnu * theta) * 0.5;
            }
        }
        let nm = n.dot(&mv);
        let scale = nm / h;
        let c = h / nm;
        let y = x + mv * c;
        work.polygon.clear();
        work.polygon.extend(face.iter().map(|&v| vertices[v]));
        polygon_coordinates(
            &work.polygon,
            &n,
            &y,
            &mut work.face_mu,
            want_gradients.then_some(&mut work.face_mu_gradients),
            &mut work.t,
            &mut work.t_gradients,
        );
        for (j, &v) in face.iter().enumerate() {
            work.weights[v] += work.face_mu[j] * scale;
        }
        if want_gradients {
            // s = (n·m)/h: ∇s = J_mᵀ n / h + (n·m) n / h².
            let jmt_n = jm.transpose() * n;
            let grad_scale = jmt_n / h + n * (nm / (h * h));
            // y = x + c m, c = h/(n·m): ∇c = −n/(n·m) − h J_mᵀ n/(n·m)², J_y = I + m ∇cᵀ + c J_m.
            let grad_c = -n / nm - jmt_n * (h / (nm * nm));
            let jy = Matrix3::identity() + mv * grad_c.transpose() + jm * c;
            let jyt = jy.transpose();
            for (j, &v) in face.iter().enumerate() {
                work.weight_gradients[v] += jyt * work.face_mu_gradients[j] * scale + grad_scale * work.face_mu[j];
            }
        }
    }
    let total: Real = work.weights.iter().sum();
    for (value, w) in values.iter_mut().zip(&work.weights) {
        *value = w / total;
    }
    if let Some(gradients) = gradients {
        let sum: Vector3<Real> = work.weight_gradients.iter().sum();
        for ((g, wg), value) in gradients.iter_mut().zip(&work.weight_gradients).zip(values.iter()) {
            *g = (wg - sum * *value) / total;
        }
    }
}
