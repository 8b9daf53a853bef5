//! The cut contract every [`Cuttable`] backend must pass (docs/cutting.md of the design notes,
//! issue 34): run by each backend's tests in a few lines with its own body and cuts.
//!
//! - **Material points keep their motion**: positions and velocities of material points, away
//!   from the cut, are the same before and after it (1e-12 of the body's size): the remap
//!   carries `x` and `v` exactly.
//! - **Volume and mass**: the pieces' total volume and mass are unchanged (1e-12 relative).
//! - **Closed surfaces**: every piece's render surface, welded by position within the piece, uses
//!   every edge as often in one direction as in the other (closed and consistently oriented; a
//!   crack that ends inside the material leaves two coincident sheets whose edges are used twice
//!   each way) and has no zero-area triangle.
//! - **Energy**: the elastic energy of a bent state does not rise across a cut.
//! - **Degenerate soups never panic**: collinear triangles, triangles through nodes and along
//!   element edges, soups coplanar with element faces, a cut repeated, random soups and a NaN
//!   vertex are cut or refused with an error, never a panic.
//! - **Placement**: the same cuts on the body moved rigidly (by a motion the backend's
//!   discretization is invariant under) give pieces of the same volumes and masses.
//! - **Determinism**: two runs give the same bytes (rest DOFs, surfaces, pieces, remaps).

use crate::{Check, Lcg, affine_dofs, bent_state};
use cleave_core::{CutSurface, Cuttable, Discretization, DofRemap, EmbeddedSurface, Point3, Real, Vector3};
use nalgebra::{Isometry3, Matrix3, Rotation3};
use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};

/// A body that can be cut: what the suite needs of a backend.
pub trait CutBody: Discretization + Cuttable {}
impl<T: Discretization + Cuttable> CutBody for T {}

/// What a backend gives the suite.
pub struct CutSubject<'a> {
    /// Makes the backend's body placed by a rigid motion of its reference placement.
    pub make: &'a dyn Fn(&Isometry3<Real>) -> Box<dyn CutBody>,
    /// Cuts in the reference placement, made one after the other (planes, soups, partial cuts).
    pub cuts: Vec<CutSurface>,
    /// A rigid motion the discretization is invariant under (any, for a backend that follows
    /// the surface exactly; a lattice translation and a quarter turn for voxels).
    pub placement: Isometry3<Real>,
    /// How the backend carries the field across a cut.
    pub transfer: Transfer,
}

/// A curved cut soup for the contract's sequences: a strip of 24 triangles standing on the
/// curve x = 0.55 + 0.08 sin(3y), y ∈ [−0.3, 0.42], z from 0 to 0.7 (leaning 0.02 in x), for
/// bodies around [0, 0.8] × [−0.2, 0.2] × [0.1, 0.5].
pub fn curved_strip() -> Vec<[Point3<Real>; 3]> {
    (0..12)
        .flat_map(|k| {
            let y = |k: usize| -0.3 + 0.06 * k as Real;
            let x = |k: usize| 0.55 + 0.08 * (3.0 * y(k)).sin();
            let (p0, p1) = (Point3::new(x(k), y(k), 0.0), Point3::new(x(k + 1), y(k + 1), 0.0));
            let (q0, q1) = (p0 + Vector3::new(0.02, 0.0, 0.7), p1 + Vector3::new(0.02, 0.0, 0.7));
            [[p0, p1, q1], [p0, q1, q0]]
        })
        .collect()
}

/// The contract's cut sequence for bodies around [0, 0.8] × [−0.2, 0.2] × [0.1, 0.5]: an
/// oblique plane, a triangle ending inside the body, the curved strip, and the horizontal plane
/// at height `z` (chosen per backend off its lattice's node planes, or on them on purpose).
pub fn contract_cuts(z: Real) -> Vec<CutSurface> {
    vec![
        CutSurface::Plane { point: Point3::new(0.3, 0.0, 0.0), normal: Vector3::new(1.0, 0.3, 0.1) },
        CutSurface::Triangles(vec![[
            Point3::new(0.42, -0.3, 0.2),
            Point3::new(0.5, 0.3, 0.35),
            Point3::new(0.46, -0.3, 0.6),
        ]]),
        CutSurface::Triangles(curved_strip()),
        CutSurface::Plane { point: Point3::new(0.0, 0.0, z), normal: Vector3::z() },
    ]
}

/// How a backend carries the displacement field across a cut.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Transfer {
    /// The new space holds the old field: every material point keeps its position and velocity
    /// (duplicated nodes, restricted polynomials).
    Exact,
    /// The field is held exactly as with `Exact`, but the energy also depends on terms of the
    /// elements that a cut changes: DG's interior penalty, which small children need raised on
    /// the jumps already there (the bent state's per-element projection has jumps), and a
    /// degree-2 field's corotation, taken per element at its centroid. The bent state's elastic
    /// energy may rise by `energy_rise` (relative), the bound the backend states.
    ExactField {
        /// Largest relative rise of the bent state's elastic energy.
        energy_rise: Real,
    },
    /// New nodes take the old field's value and the new elements interpolate them with their own
    /// shape functions (wicke2007's splitting: mean value functions on the parts are not the
    /// parent's restricted). Affine states are still carried exactly (linear precision), which is
    /// checked to 1e-12; a bent state's material points may move by `bent_motion` of the body's
    /// size and its elastic energy rise by `bent_energy` (relative), the bounds the backend
    /// states and the suite checks.
    Interpolated {
        /// Largest motion of a material point of the bent state, relative to the body's size.
        bent_motion: Real,
        /// Largest relative rise of the bent state's elastic energy.
        bent_energy: Real,
    },
}

/// Every check of the contract (each a [`Check`] with what it measured).
pub fn cut_conformance(subject: &CutSubject<'_>) -> Vec<Check> {
    let mut checks = sequence_checks(subject);
    checks.push(degenerate_soups_never_panic(subject));
    checks.push(placement_gives_the_same_pieces(subject));
    checks.push(two_runs_give_the_same_bytes(subject));
    checks.push(pieces_partition_the_body(subject));
    checks
}

/// The body's size: the diagonal of its material points' bounding box (not of its rest DOFs,
/// which for a modal basis such as DG's are coefficients, not positions).
fn size(body: &dyn CutBody) -> Real {
    let (mut lo, mut hi) = (Vector3::repeat(Real::MAX), Vector3::repeat(Real::MIN));
    for p in material_points(body) {
        lo = lo.inf(&p.coords);
        hi = hi.sup(&p.coords);
    }
    (hi - lo).norm().max(Real::MIN_POSITIVE)
}

/// Distance from `p` to a cut surface.
fn distance_to_cut(p: &Point3<Real>, surface: &CutSurface) -> Real {
    match surface {
        CutSurface::Plane { point, normal } => ((p - point).dot(normal) / normal.norm()).abs(),
        CutSurface::Triangles(triangles) => triangles
            .iter()
            .filter(|t| t.iter().all(|v| v.coords.iter().all(|c| c.is_finite())))
            .map(|t| (p - cleave_geometry::closest_point_on_triangle(p, t).0).norm())
            .fold(Real::INFINITY, Real::min),
    }
}

/// Material points of `body`: its quadrature points in rest space.
fn material_points(body: &dyn CutBody) -> Vec<Point3<Real>> {
    let zero = vec![0.0; body.rest_dofs().len()];
    let mut points = Vec::new();
    body.visit_field(&zero, 1, &mut |s| points.push(s.position));
    points
}

fn totals(body: &mut dyn CutBody) -> (Real, Real) {
    let pieces = body.pieces();
    (pieces.iter().map(|p| p.volume).sum(), pieces.iter().map(|p| p.mass).sum())
}

fn energy(body: &dyn CutBody, x: &[Real]) -> Real {
    let mut rotations = vec![cleave_core::Matrix3::identity(); body.num_frames()];
    body.write_rotations(x, &mut rotations);
    body.elastic_energy(&rotations, x)
}

/// Edges of a piece's welded surface not used as often in each direction, plus zero-area
/// triangles, over all pieces.
pub fn open_surface_defects(surface: &EmbeddedSurface, weld: Real) -> usize {
    let key = |p: &Point3<Real>| p.coords.map(|c| (c / weld).round() as i64);
    let mut ids: HashMap<(u32, [i64; 3]), u32> = HashMap::new();
    let mut directed: HashMap<(u32, u32, u32), i32> = HashMap::new();
    let mut defects = 0;
    for (t, tri) in surface.triangles.iter().enumerate() {
        let piece = surface.piece.get(t).copied().unwrap_or(u32::MAX);
        let corners = tri.map(|v| surface.rest_vertices[v as usize]);
        if (corners[1] - corners[0]).cross(&(corners[2] - corners[0])).norm() <= weld * weld {
            defects += 1;
            continue;
        }
        let mut welded = [0u32; 3];
        for (w, c) in welded.iter_mut().zip(&corners) {
            let k = key(c);
            let len = ids.len() as u32;
            *w = *ids.entry((piece, [k[0], k[1], k[2]])).or_insert(len);
        }
        for e in 0..3 {
            let (a, b) = (welded[e], welded[(e + 1) % 3]);
            *directed.entry((piece, a, b)).or_insert(0) += 1;
        }
    }
    for (&(piece, a, b), &count) in &directed {
        if a < b || !directed.contains_key(&(piece, b, a)) {
            let back = directed.get(&(piece, b, a)).copied().unwrap_or(0);
            if count != back {
                defects += 1;
            }
        }
    }
    defects
}

/// The affine state `x = A X + b` (a rotation times a stretch) and an affine velocity.
fn affine_state(body: &dyn CutBody) -> (Vec<Real>, Vec<Real>) {
    let turn = Rotation3::from_euler_angles(0.4, -0.3, 0.9).into_inner();
    let stretch = Matrix3::new(1.1, 0.05, 0.0, 0.05, 0.95, 0.02, 0.0, 0.02, 1.03);
    let x = affine_dofs(body, &(turn * stretch), &Vector3::new(0.3, -0.2, 0.1));
    let v = affine_dofs(
        body,
        &Matrix3::new(0.2, -1.0, 0.3, 1.0, 0.1, -0.4, -0.3, 0.4, -0.1),
        &Vector3::new(1.0, 2.0, -0.5),
    );
    (x, v)
}

/// What a cut sequence measured.
struct Measured {
    motion: Real,
    conserved: Real,
    energy_rise: Real,
    /// Largest relative change of the energy, either way.
    energy_change: Real,
    defects: usize,
}

/// Material points, volume and mass, energy and closed surfaces over the subject's cuts.
fn sequence_checks(subject: &CutSubject<'_>) -> Vec<Check> {
    let bent = |body: &dyn CutBody| (bent_state(body), Lcg::new(7).vector(body.rest_dofs().len()));
    match subject.transfer {
        Transfer::Exact | Transfer::ExactField { .. } => {
            let m = run_sequence(subject, &bent);
            let energy_rise = match subject.transfer {
                Transfer::ExactField { energy_rise } => energy_rise,
                _ => 1e-12,
            };
            vec![
                Check { name: "cut: material points keep x and v", error: m.motion, tolerance: 1e-12 },
                Check { name: "cut: volume and mass conserved", error: m.conserved, tolerance: 1e-12 },
                Check {
                    name: "cut: elastic energy does not rise",
                    error: m.energy_rise.max(0.0),
                    tolerance: energy_rise,
                },
                Check { name: "cut: every piece's surface closed", error: m.defects as Real, tolerance: 0.0 },
            ]
        }
        Transfer::Interpolated { bent_motion, bent_energy } => {
            let m = run_sequence(subject, &affine_state);
            // A smooth velocity too (the bent state's displacement): interpolation cannot carry
            // a random nodal field, and is not asked to.
            let smooth = |body: &dyn CutBody| {
                let x = bent_state(body);
                let v = x.iter().zip(body.rest_dofs()).map(|(x, r)| x - r).collect();
                (x, v)
            };
            let b = run_sequence(subject, &smooth);
            vec![
                Check { name: "cut: material points keep an affine x and v", error: m.motion, tolerance: 1e-12 },
                Check { name: "cut: volume and mass conserved", error: m.conserved, tolerance: 1e-12 },
                Check { name: "cut: affine state's elastic energy kept", error: m.energy_change, tolerance: 1e-12 },
                Check { name: "cut: every piece's surface closed", error: m.defects as Real, tolerance: 0.0 },
                Check {
                    name: "cut: bent state's material points move little",
                    error: b.motion,
                    tolerance: bent_motion,
                },
                Check {
                    name: "cut: bent state's energy rises little",
                    error: b.energy_rise.max(0.0),
                    tolerance: bent_energy,
                },
            ]
        }
    }
}

/// Runs the subject's cuts from the state `start` makes.
/// Makes the start state `(x, v)` of a cut sequence for a body.
type StartState<'a> = &'a dyn Fn(&dyn CutBody) -> (Vec<Real>, Vec<Real>);

fn run_sequence(subject: &CutSubject<'_>, start: StartState<'_>) -> Measured {
    let mut body = (subject.make)(&Isometry3::identity());
    let scale = size(body.as_ref());
    let (mut x, mut v) = start(body.as_ref());
    let (mut motion, mut conserved, mut energy_rise, mut energy_change, mut defects) =
        (0.0, 0.0, Real::NEG_INFINITY, 0.0, 0usize);
    for cut in &subject.cuts {
        let points: Vec<Point3<Real>> =
            material_points(body.as_ref()).into_iter().filter(|p| distance_to_cut(p, cut) > 1e-9 * scale).collect();
        let before = body.embed(&points);
        let (volume, mass) = totals(body.as_mut());
        let energy_before = energy(body.as_ref(), &x);
        let change = match body.cut(cut) {
            Ok(change) => change,
            Err(_) => {
                motion = Real::INFINITY;
                continue;
            }
        };
        let (x_new, v_new) = (change.remap.apply(&x), change.remap.apply(&v));
        let after = body.embed(&points);
        match (before, after) {
            (Ok(before), Ok(after)) => {
                for i in 0..points.len() {
                    motion = Real::max(motion, (before.point(&x, i) - after.point(&x_new, i)).norm() / scale);
                    motion = Real::max(motion, (before.point(&v, i) - after.point(&v_new, i)).norm() / scale);
                }
            }
            _ => motion = Real::INFINITY,
        }
        let (volume_after, mass_after) = totals(body.as_mut());
        conserved = Real::max(conserved, ((volume_after - volume) / volume).abs());
        conserved = Real::max(conserved, ((mass_after - mass) / mass).abs());
        let energy_after = energy(body.as_ref(), &x_new);
        let change = (energy_after - energy_before) / energy_before.abs().max(Real::MIN_POSITIVE);
        energy_rise = Real::max(energy_rise, change);
        energy_change = Real::max(energy_change, change.abs());
        defects += body.surface().map_or(usize::MAX, |s| open_surface_defects(&s, 1e-12 * scale));
        (x, v) = (x_new, v_new);
    }
    Measured { motion, conserved, energy_rise, energy_change, defects }
}

/// Degenerate and random soups on a fresh body, each cut after the ones before: none panics
/// and every cut that succeeds conserves volume.
fn degenerate_soups_never_panic(subject: &CutSubject<'_>) -> Check {
    let mut body = (subject.make)(&Isometry3::identity());
    let rest = body.rest_dofs().to_vec();
    let node = |k: usize| Point3::new(rest[3 * k], rest[3 * k + 1], rest[3 * k + 2]);
    let nodes = rest.len() / 3;
    let (a, b, c) = (node(nodes / 3), node(nodes / 2), node(2 * nodes / 3));
    let mid = Point3::from((a.coords + b.coords) / 2.0);
    let mut random = Lcg::new(11);
    let scale = size(body.as_ref());
    let centre = Point3::from(
        rest.chunks_exact(3).map(|p| Vector3::new(p[0], p[1], p[2])).sum::<Vector3<Real>>() / nodes as Real,
    );
    let mut soup = |n: usize| -> CutSurface {
        let mut point = || centre + Vector3::new(random.next(), random.next(), random.next()) * 0.4 * scale;
        CutSurface::Triangles((0..n).map(|_| [point(), point(), point()]).collect())
    };
    let soups = vec![
        // Collinear (zero area), through three nodes, along an element edge's line.
        CutSurface::Triangles(vec![[a, b, Point3::from((a.coords + b.coords) / 2.0)]]),
        CutSurface::Triangles(vec![[a, b, c]]),
        CutSurface::Triangles(vec![[a, mid, c]]),
        // The plane through three nodes (coplanar with whatever faces hold them), twice.
        CutSurface::Plane { point: a, normal: (b - a).cross(&(c - a)) },
        CutSurface::Plane { point: a, normal: (b - a).cross(&(c - a)) },
        // Random soups, then a repeat of the first one.
        soup(12),
        soup(12),
        CutSurface::Triangles(vec![[a, b, c]]),
        // A NaN vertex and a zero normal must be refused, not panic.
        CutSurface::Triangles(vec![[a, b, Point3::new(Real::NAN, 0.0, 0.0)]]),
        CutSurface::Plane { point: a, normal: Vector3::zeros() },
    ];
    let (mut panics, mut drift) = (0usize, 0.0);
    for cut in &soups {
        let (volume, _) = totals(body.as_mut());
        match catch_unwind(AssertUnwindSafe(|| body.cut(cut))) {
            Err(_) => panics += 1,
            Ok(Ok(_)) => drift = Real::max(drift, ((totals(body.as_mut()).0 - volume) / volume).abs()),
            Ok(Err(_)) => {}
        }
    }
    // The number of panics, or (none) the largest relative volume drift of a cut that succeeded.
    let error = if panics > 0 { panics as Real } else { drift };
    Check { name: "cut: degenerate soups never panic", error, tolerance: 1e-12 }
}

/// `surface` moved by `motion`.
fn moved(surface: &CutSurface, motion: &Isometry3<Real>) -> CutSurface {
    match surface {
        CutSurface::Plane { point, normal } => {
            CutSurface::Plane { point: motion * point, normal: motion.rotation * normal }
        }
        CutSurface::Triangles(t) => CutSurface::Triangles(t.iter().map(|t| t.map(|p| motion * p)).collect()),
    }
}

/// The subject's cuts on the reference body and on the moved body give pieces of the same
/// volumes and masses (sorted; 1e-9 relative to the total).
fn placement_gives_the_same_pieces(subject: &CutSubject<'_>) -> Check {
    let run = |motion: &Isometry3<Real>| -> Option<Vec<(Real, Real)>> {
        let mut body = (subject.make)(motion);
        for cut in &subject.cuts {
            body.cut(&moved(cut, motion)).ok()?;
        }
        let mut pieces: Vec<(Real, Real)> = body.pieces().iter().map(|p| (p.volume, p.mass)).collect();
        pieces.sort_by(|a, b| a.0.total_cmp(&b.0));
        Some(pieces)
    };
    let error = match (run(&Isometry3::identity()), run(&subject.placement)) {
        (Some(a), Some(b)) if a.len() == b.len() => {
            let total: Real = a.iter().map(|p| p.0).sum();
            let mass: Real = a.iter().map(|p| p.1).sum();
            a.iter()
                .zip(&b)
                .map(|(a, b)| ((a.0 - b.0) / total).abs().max(((a.1 - b.1) / mass).abs()))
                .fold(0.0, Real::max)
        }
        _ => Real::INFINITY,
    };
    Check { name: "cut: a moved body gives the same pieces", error, tolerance: 1e-9 }
}

/// The bytes of a run: rest DOFs, surface, pieces and remaps, as bit patterns.
fn run_bytes(subject: &CutSubject<'_>) -> Vec<u64> {
    let mut body = (subject.make)(&Isometry3::identity());
    let mut bytes = Vec::new();
    for cut in &subject.cuts {
        match body.cut(cut) {
            Ok(change) => {
                bytes.push(change.epoch);
                match &change.remap {
                    DofRemap::Identity => bytes.push(0),
                    DofRemap::Gather(src) => bytes.extend(src.iter().map(|&s| u64::from(s))),
                    DofRemap::Linear(rows) => {
                        for i in 0..rows.len() {
                            let (n, w) = rows.row(i);
                            bytes.extend(n.iter().map(|&n| u64::from(n)));
                            bytes.extend(w.iter().map(|w| w.to_bits()));
                        }
                    }
                }
            }
            Err(_) => bytes.push(u64::MAX),
        }
    }
    bytes.extend(body.rest_dofs().iter().map(|x| x.to_bits()));
    if let Some(surface) = body.surface() {
        bytes.extend(
            surface.rest_vertices.iter().flat_map(|p| p.coords.iter().map(|c| c.to_bits()).collect::<Vec<_>>()),
        );
        bytes.extend(surface.triangles.iter().flat_map(|t| t.map(u64::from)));
        bytes.extend(surface.piece.iter().map(|&p| u64::from(p)));
    }
    for p in body.pieces() {
        bytes.extend(p.elements.iter().chain(&p.nodes).map(|&k| u64::from(k)));
        bytes.extend([p.volume.to_bits(), p.mass.to_bits()]);
    }
    bytes
}

/// After the subject's cuts, every node and every element lies in exactly one piece: what
/// moves together is one piece (a node in two pieces would join them; a rigid hand-off or a
/// renderer that trusts the pieces would tear the body there). Error: the nodes and elements
/// counted in no piece or in more than one.
fn pieces_partition_the_body(subject: &CutSubject<'_>) -> Check {
    let mut body = (subject.make)(&Isometry3::identity());
    for cut in &subject.cuts {
        let _ = body.cut(cut);
    }
    let pieces = body.pieces();
    let mut node_count = vec![0u32; body.num_nodes()];
    let mut element_count = vec![0u32; body.num_frames()];
    for p in &pieces {
        p.nodes.iter().for_each(|&n| node_count[n as usize] += 1);
        p.elements.iter().for_each(|&e| element_count[e as usize] += 1);
    }
    let wrong = node_count.iter().chain(&element_count).filter(|&&c| c != 1).count();
    Check { name: "cut: pieces partition nodes and elements", error: wrong as Real, tolerance: 0.0 }
}

fn two_runs_give_the_same_bytes(subject: &CutSubject<'_>) -> Check {
    let (first, second) = (run_bytes(subject), run_bytes(subject));
    let differing = if first.len() == second.len() {
        first.iter().zip(&second).filter(|(a, b)| a != b).count()
    } else {
        first.len().max(second.len())
    };
    Check { name: "cut: two runs give the same bytes", error: differing as Real, tolerance: 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn open_surface_defects_finds_holes_flips_and_slivers() {
        let tetrahedron = |triangles: Vec<[u32; 3]>| EmbeddedSurface {
            rest_vertices: vec![
                Point3::origin(),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
                Point3::new(0.0, 0.0, 1.0),
            ],
            piece: vec![0; triangles.len()],
            on_cut: vec![false; triangles.len()],
            triangles,
            embedding: Default::default(),
        };
        let closed = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        assert_eq!(open_surface_defects(&tetrahedron(closed.clone()), 1e-12), 0);
        // One triangle missing: its three edges are used one way only.
        assert_eq!(open_surface_defects(&tetrahedron(closed[..3].to_vec()), 1e-12), 3);
        // One triangle flipped: its three edges are used twice one way.
        let mut flipped = closed.clone();
        flipped[2] = [1, 3, 2];
        assert_eq!(open_surface_defects(&tetrahedron(flipped), 1e-12), 3);
        // Two coincident sheets of opposite orientation (a crack inside a piece) are closed.
        let mut sheets = closed.clone();
        sheets.extend([[0, 1, 2], [0, 2, 1]]);
        assert_eq!(open_surface_defects(&tetrahedron(sheets), 1e-12), 0);
        // A zero-area triangle is a defect.
        let mut sliver = tetrahedron(closed);
        sliver.rest_vertices.push(Point3::new(0.5, 0.0, 0.0));
        sliver.triangles.push([0, 4, 1]);
        sliver.piece.push(0);
        assert!(open_surface_defects(&sliver, 1e-12) >= 1);
    }
}
