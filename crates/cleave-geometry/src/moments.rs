//! Exact monomial moments of polyhedral elements and polygon faces by the divergence theorem
//! (homogeneous reduction volume → faces → edges; derivation in `docs/math/polyhedral-integration.md`).

use nalgebra::{Point3, Vector3};

use crate::{ElementFace, GeometryError, PolyhedralMesh};

/// Highest total degree the moment functions accept. Far beyond what monomial bases can use
/// (their conditioning degrades long before), it only bounds the work and memory of one call.
pub const MAX_MOMENT_DEGREE: usize = 32;

/// Affine frame ξ = (x − center) / scale used to keep monomials well conditioned.
///
/// Choose `center` inside the element (centroid or bounding-box centre) and `scale` of the
/// order of its size: see `docs/math/polyhedral-integration.md` §3.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The point mapped to ξ = 0.
    pub center: Point3<f64>,
    /// The length mapped to 1; must be positive and finite.
    pub scale: f64,
}

impl Frame {
    /// The frame centred at the bounding-box centre of `points` with scale half the box
    /// diagonal (`scale = 1` when there are no points or they coincide).
    pub fn bounding(points: impl IntoIterator<Item = Point3<f64>>) -> Self {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for p in points {
            lo = lo.inf(&p.coords);
            hi = hi.sup(&p.coords);
        }
        if !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z) {
            return Self { center: Point3::origin(), scale: 1.0 };
        }
        let half = 0.5 * (hi - lo).norm();
        let scale = if half > 0.0 && half.is_finite() { half } else { 1.0 };
        Self { center: Point3::from(0.5 * (lo + hi)), scale }
    }

    fn validate(&self) -> Result<(), GeometryError> {
        let c = self.center;
        if c.iter().all(|x| x.is_finite()) && self.scale.is_finite() && self.scale > 0.0 {
            Ok(())
        } else {
            Err(GeometryError::InvalidFrame { center: [c.x, c.y, c.z], scale: self.scale })
        }
    }

    fn local(&self, p: &Point3<f64>) -> Vector3<f64> {
        (p - self.center) / self.scale
    }
}

/// Number of monomials of total degree ≤ `max_degree` in three variables,
/// `(d+1)(d+2)(d+3)/6` (saturating at `usize::MAX`).
pub fn num_monomials(max_degree: usize) -> usize {
    let d = max_degree as u128;
    let n = (d + 1) * (d + 2) * (d + 3) / 6;
    usize::try_from(n).unwrap_or(usize::MAX)
}

/// Exponents (a, b, c) of all monomials ξ^a η^b ζ^c of total degree ≤ max_degree, graded order:
/// degree 0, then degree 1 as x, y, z, then degree 2 as xx, xy, xz, yy, yz, zz, ... (within a degree,
/// lexicographically descending in a, then b). Length (d+1)(d+2)(d+3)/6.
pub fn monomial_exponents(max_degree: usize) -> Vec<[u32; 3]> {
    let mut out = Vec::with_capacity(num_monomials(max_degree));
    for n in 0..=max_degree as u32 {
        for a in (0..=n).rev() {
            for b in (0..=n - a).rev() {
                out.push([a, b, n - a - b]);
            }
        }
    }
    out
}

/// Position of (a,b,c) in that order: `n(n+1)(n+2)/6 + r(r+1)/2 + c` with `n = a+b+c`,
/// `r = b+c` (`docs/math/polyhedral-integration.md` (2)); saturates at `usize::MAX` for
/// exponents whose index does not fit.
pub fn monomial_index(e: [u32; 3]) -> usize {
    let [a, b, c] = e.map(u128::from);
    let n = a + b + c;
    let r = b + c;
    let index = n * (n + 1) * (n + 2) / 6 + r * (r + 1) / 2 + c;
    usize::try_from(index).unwrap_or(usize::MAX)
}

/// The moments of one region (an element's or a face's, any measure) in frame `to`, from its
/// moments in frame `from`, every monomial of total degree ≤ `max_degree`, into `out`. With
/// `ξ_to = o + r ξ_from`, `o = (c_from − c_to)/s_to`, `r = s_from/s_to`, each monomial expands
/// per axis by the binomial theorem (`docs/math/polyhedral-integration.md` §6):
/// `M_to[β] = Σ_{k ≤ β} Π_a C(β_a, k_a) o_a^(β_a − k_a) r^(k_a) M_from[k]`. No integration: a
/// child element or face reuses what its parent stored. Errors for an invalid frame, a degree
/// above [`MAX_MOMENT_DEGREE`] or a moment count that is not the degree's.
pub fn shift_moments(
    moments: &[f64],
    from: &Frame,
    to: &Frame,
    max_degree: usize,
    out: &mut Vec<f64>,
) -> Result<(), GeometryError> {
    check_degree(max_degree)?;
    from.validate()?;
    to.validate()?;
    let count = num_monomials(max_degree);
    if moments.len() != count {
        return Err(GeometryError::MomentCount { degree: max_degree, expected: count, got: moments.len() });
    }
    let o = (from.center - to.center) / to.scale;
    let r = from.scale / to.scale;
    // Per axis, the coefficient of ξ_from^k in (o + r ξ_from)^n: C(n, k) o^(n−k) r^k.
    let d = max_degree;
    let mut axis = vec![0.0; 3 * (d + 1) * (d + 1)];
    for a in 0..3 {
        for n in 0..=d {
            let mut binomial = 1.0;
            for k in 0..=n {
                axis[(a * (d + 1) + n) * (d + 1) + k] = binomial * o[a].powi((n - k) as i32) * r.powi(k as i32);
                binomial = binomial * (n - k) as f64 / (k + 1) as f64;
            }
        }
    }
    let exponents = monomial_exponents(max_degree);
    out.clear();
    out.resize(count, 0.0);
    for (i, beta) in exponents.iter().enumerate() {
        let coefficient = |a: usize, k: u32| axis[(a * (d + 1) + beta[a] as usize) * (d + 1) + k as usize];
        let mut sum = 0.0;
        for kx in 0..=beta[0] {
            for ky in 0..=beta[1] {
                for kz in 0..=beta[2] {
                    let c = coefficient(0, kx) * coefficient(1, ky) * coefficient(2, kz);
                    sum += c * moments[monomial_index([kx, ky, kz])];
                }
            }
        }
        out[i] = sum;
    }
    Ok(())
}

/// Index arithmetic shared by the recursions: for monomial `i`, its degree and the index of
/// `α − e_k` for the coordinates `k` with `α_k > 0`.
struct MonomialTable {
    exponents: Vec<[u32; 3]>,
    degree: Vec<u32>,
    /// `lower[i][k]` = index of `α_i − e_k`, or `usize::MAX` when `α_k = 0`.
    lower: Vec<[usize; 3]>,
}

impl MonomialTable {
    fn new(max_degree: usize) -> Self {
        let exponents = monomial_exponents(max_degree);
        let degree = exponents.iter().map(|e| e[0] + e[1] + e[2]).collect();
        let lower = exponents
            .iter()
            .map(|e| {
                std::array::from_fn(|k| {
                    if e[k] == 0 {
                        usize::MAX
                    } else {
                        let mut l = *e;
                        l[k] -= 1;
                        monomial_index(l)
                    }
                })
            })
            .collect();
        Self { exponents, degree, lower }
    }

    fn len(&self) -> usize {
        self.exponents.len()
    }

    /// `out[i] = p^α_i`.
    fn powers(&self, p: &Vector3<f64>, out: &mut [f64]) {
        out[0] = 1.0;
        for i in 1..self.len() {
            let k = (0..3).find(|&k| self.lower[i][k] != usize::MAX).expect("every non-constant monomial has a factor");
            out[i] = out[self.lower[i][k]] * p[k];
        }
    }

    /// `Σ_k α_k x_k · values[α − e_k]`: the moment of `x·∇ξ^α` given the lower moments.
    fn directional(&self, i: usize, x: &Vector3<f64>, values: &[f64]) -> f64 {
        let mut sum = 0.0;
        for k in 0..3 {
            let l = self.lower[i][k];
            if l != usize::MAX {
                sum += f64::from(self.exponents[i][k]) * x[k] * values[l];
            }
        }
        sum
    }
}

/// One face integrated in ξ-space: its moments (area measure), unit normal of the stored
/// orientation and plane offset `b = n·x` (eqs. (4)–(6) of the math doc).
struct LocalFace {
    normal: Vector3<f64>,
    offset: f64,
}

/// Scratch buffers of one moment computation.
struct Workspace {
    table: MonomialTable,
    points: Vec<Vector3<f64>>,
    end_powers: Vec<f64>,
    edge: Vec<f64>,
    edge_sum: Vec<f64>,
    face: Vec<f64>,
}

impl Workspace {
    fn new(max_degree: usize) -> Self {
        let table = MonomialTable::new(max_degree);
        let n = table.len();
        Self {
            table,
            points: Vec::new(),
            end_powers: vec![0.0; n],
            edge: vec![0.0; n],
            edge_sum: vec![0.0; n],
            face: vec![0.0; n],
        }
    }

    /// Integrates the polygon `self.points` (ξ-space, counter-clockwise around its Newell
    /// normal) into `self.face`; returns its normal and offset, or `None` for a zero-area face
    /// (then `self.face` is zero).
    fn integrate_polygon(&mut self) -> Option<LocalFace> {
        self.face.fill(0.0);
        let k = self.points.len();
        if k < 3 {
            return None;
        }
        let q0 = self.points[0];
        let mut newell = Vector3::zeros();
        for i in 1..k - 1 {
            newell += (self.points[i] - q0).cross(&(self.points[i + 1] - q0));
        }
        let norm = newell.norm();
        if norm == 0.0 {
            return None;
        }
        let n = newell / norm;
        // Project onto the plane through the vertex mean (math doc §2, "Planarity").
        let mean = self.points.iter().fold(Vector3::zeros(), |s, p| s + (p - q0)) / k as f64 + q0;
        for p in &mut self.points {
            *p -= ((*p - mean).dot(&n)) * n;
        }
        let x0 = self.points[0];
        let t = &self.table;
        self.edge_sum.fill(0.0);
        // Edges (p_i → p_{i+1}) for i = 1..k−2: the two edges at p_0 have h_e = 0.
        for i in 1..k - 1 {
            let a = self.points[i];
            let b = self.points[i + 1];
            let weight = (b - a).cross(&n).dot(&(a - x0));
            t.powers(&b, &mut self.end_powers);
            // Eq. (6): Ê[α] = (b^α + Σ_k α_k a_k Ê[α − e_k]) / (1 + q).
            for j in 0..t.len() {
                let value = (self.end_powers[j] + t.directional(j, &a, &self.edge)) / f64::from(1 + t.degree[j]);
                self.edge[j] = value;
                self.edge_sum[j] += weight * value;
            }
        }
        // Eq. (5): F[α] = (Σ_e h_e|e| Ê_e[α] + Σ_k α_k x0_k F[α − e_k]) / (2 + q).
        for j in 0..t.len() {
            self.face[j] = (self.edge_sum[j] + t.directional(j, &x0, &self.face)) / f64::from(2 + t.degree[j]);
        }
        Some(LocalFace { normal: n, offset: n.dot(&x0) })
    }

    /// Loads face `face`'s vertices into ξ-space; errors name a missing face or vertex.
    fn load_face(&mut self, mesh: &PolyhedralMesh, face: usize, frame: &Frame) -> Result<(), GeometryError> {
        let f = mesh.faces.get(face).ok_or(GeometryError::FaceOutOfRange { face, num_faces: mesh.faces.len() })?;
        self.points.clear();
        for &v in &f.polygon {
            let p = mesh.vertices.get(v as usize).ok_or(GeometryError::FaceVertexOutOfRange {
                face,
                index: v,
                vertex_count: mesh.vertices.len(),
            })?;
            self.points.push(frame.local(p));
        }
        Ok(())
    }
}

fn check_degree(max_degree: usize) -> Result<(), GeometryError> {
    if max_degree > MAX_MOMENT_DEGREE {
        Err(GeometryError::MomentDegreeTooHigh { degree: max_degree, limit: MAX_MOMENT_DEGREE })
    } else {
        Ok(())
    }
}

/// On failure of the infallible wrappers: NaN of the right length, or empty when the degree
/// itself is out of range.
fn poison(out: &mut Vec<f64>, max_degree: usize) {
    out.clear();
    if max_degree <= MAX_MOMENT_DEGREE {
        out.resize(num_monomials(max_degree), f64::NAN);
    }
}

/// Like [`face_moments`], returning an error for a face index out of range, a polygon vertex
/// index out of range, an invalid frame or `max_degree > MAX_MOMENT_DEGREE`.
pub fn try_face_moments(
    mesh: &PolyhedralMesh,
    face: usize,
    frame: &Frame,
    max_degree: usize,
    out: &mut Vec<f64>,
) -> Result<(), GeometryError> {
    check_degree(max_degree)?;
    frame.validate()?;
    let mut ws = Workspace::new(max_degree);
    ws.load_face(mesh, face, frame)?;
    ws.integrate_polygon();
    let s2 = frame.scale * frame.scale;
    out.clear();
    out.extend(ws.face.iter().map(|m| s2 * m));
    Ok(())
}

/// out[i] = ∫_F ξ^{α_i} dA(x) over face `face` (physical area measure; out[0] = area).
///
/// The polygon may be non-convex; a slightly warped one is integrated as its projection onto
/// its Newell plane. Never panics: when [`try_face_moments`] would fail, `out` is filled with
/// NaN (left empty if `max_degree > MAX_MOMENT_DEGREE`).
pub fn face_moments(mesh: &PolyhedralMesh, face: usize, frame: &Frame, max_degree: usize, out: &mut Vec<f64>) {
    if try_face_moments(mesh, face, frame, max_degree, out).is_err() {
        poison(out, max_degree);
    }
}

/// Like [`element_moments_from_faces`] with the element's faces found by a scan over all faces
/// of the mesh, returning an error for an element index out of range, a vertex index out of
/// range, an invalid frame or `max_degree > MAX_MOMENT_DEGREE`.
pub fn try_element_moments(
    mesh: &PolyhedralMesh,
    element: usize,
    frame: &Frame,
    max_degree: usize,
    out: &mut Vec<f64>,
) -> Result<(), GeometryError> {
    if element >= mesh.num_elements {
        return Err(GeometryError::ElementOutOfRange { element, num_elements: mesh.num_elements });
    }
    let faces = mesh.faces_of(element);
    try_element_moments_from_faces(mesh, &faces, frame, max_degree, out)
}

/// Like [`element_moments_from_faces`], returning an error for a face or vertex index out of
/// range, an invalid frame or `max_degree > MAX_MOMENT_DEGREE`.
pub fn try_element_moments_from_faces(
    mesh: &PolyhedralMesh,
    faces: &[ElementFace<'_>],
    frame: &Frame,
    max_degree: usize,
    out: &mut Vec<f64>,
) -> Result<(), GeometryError> {
    check_degree(max_degree)?;
    frame.validate()?;
    let mut ws = Workspace::new(max_degree);
    let n = ws.table.len();
    out.clear();
    out.resize(n, 0.0);
    for f in faces {
        ws.load_face(mesh, f.face, frame)?;
        let Some(local) = ws.integrate_polygon() else { continue };
        // Eq. (4): the outward normal of a reversed face is −n, so its offset is −b.
        let offset = if f.reversed { -local.offset } else { local.offset };
        for (o, m) in out.iter_mut().zip(&ws.face) {
            *o += offset * m;
        }
    }
    let s3 = frame.scale * frame.scale * frame.scale;
    for (o, q) in out.iter_mut().zip(&ws.table.degree) {
        *o *= s3 / f64::from(3 + q);
    }
    Ok(())
}

/// out[i] = ∫_E ξ^{α_i} dV(x) over element `element` of the mesh (physical volume measure: out[0] is
/// the element's volume in m³), for all monomials of degree ≤ max_degree in `frame`. `out` is resized.
///
/// The element may be non-convex; its boundary (the faces with `inner == element`, and those
/// with `outer == Some(element)` reversed) must be closed and outward oriented, as checked by
/// [`PolyhedralMesh::validate`]. Finding the faces scans the whole mesh; loops over all elements
/// should use [`element_moments_from_faces`] with [`PolyhedralMesh::element_faces`]. Never
/// panics: when [`try_element_moments`] would fail, `out` is filled with NaN (left empty if
/// `max_degree > MAX_MOMENT_DEGREE`).
pub fn element_moments(mesh: &PolyhedralMesh, element: usize, frame: &Frame, max_degree: usize, out: &mut Vec<f64>) {
    if try_element_moments(mesh, element, frame, max_degree, out).is_err() {
        poison(out, max_degree);
    }
}

/// [`element_moments`] for the element bounded by `faces` (outward for it, e.g. one entry of
/// [`PolyhedralMesh::element_faces`]). Never panics; NaN output as for [`element_moments`].
pub fn element_moments_from_faces(
    mesh: &PolyhedralMesh,
    faces: &[ElementFace<'_>],
    frame: &Frame,
    max_degree: usize,
    out: &mut Vec<f64>,
) {
    if try_element_moments_from_faces(mesh, faces, frame, max_degree, out).is_err() {
        poison(out, max_degree);
    }
}

/// The vertices of an element's faces (with repetitions), skipping out-of-range indices.
fn element_points<'a>(mesh: &'a PolyhedralMesh, element: usize) -> impl Iterator<Item = Point3<f64>> + 'a {
    let e = element as u64;
    mesh.faces
        .iter()
        .filter(move |f| u64::from(f.inner) == e || f.outer.map(u64::from) == Some(e))
        .flat_map(|f| f.polygon.iter())
        .filter_map(|&v| mesh.vertices.get(v as usize).copied())
}

/// The frame used by [`element_volume_centroid`]: bounding-box centre and half-diagonal of the
/// element's vertices.
pub fn element_frame(mesh: &PolyhedralMesh, element: usize) -> Frame {
    Frame::bounding(element_points(mesh, element))
}

/// Volume and centroid of an element (from the degree-1 moments).
///
/// NaN for an element index or vertex index out of range, and a NaN centroid for zero volume.
pub fn element_volume_centroid(mesh: &PolyhedralMesh, element: usize) -> (f64, Point3<f64>) {
    let frame = element_frame(mesh, element);
    let mut m = Vec::with_capacity(4);
    element_moments(mesh, element, &frame, 1, &mut m);
    let volume = m[0];
    let centroid = frame.center + frame.scale * Vector3::new(m[1], m[2], m[3]) / volume;
    (volume, centroid)
}

/// Area, unit normal (pointing out of `inner`) and centroid of a face (Newell normal).
///
/// A face of zero area has a zero normal and a NaN centroid; an index out of range gives NaN.
pub fn face_area_normal_centroid(mesh: &PolyhedralMesh, face: usize) -> (f64, Vector3<f64>, Point3<f64>) {
    let nan = (f64::NAN, Vector3::repeat(f64::NAN), Point3::from(Vector3::repeat(f64::NAN)));
    let Some(f) = mesh.faces.get(face) else { return nan };
    let frame = Frame::bounding(f.polygon.iter().filter_map(|&v| mesh.vertices.get(v as usize).copied()));
    let mut ws = Workspace::new(1);
    if ws.load_face(mesh, face, &frame).is_err() {
        return nan;
    }
    let normal = ws.integrate_polygon().map_or(Vector3::zeros(), |l| l.normal);
    let s = frame.scale;
    let area = s * s * ws.face[0];
    let centroid = frame.center + s * Vector3::new(ws.face[1], ws.face[2], ws.face[3]) / ws.face[0];
    (area, normal, centroid)
}
