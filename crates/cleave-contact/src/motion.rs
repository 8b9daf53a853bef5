//! The broad phase's bounds: each piece's fitted rigid motion and how far its points stray from
//! it in a step, the per-piece bounding volume hierarchies and their refits (docs/math/contact.md
//! §2, "Motion bounds").

use cleave_core::{Matrix3, Point3, Real, Vector3};
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector as ParryVector;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, BvhLeafUpdateStatus, BvhWorkspace};
use rayon::prelude::*;

/// A rigid velocity field fit to a piece's points, `w + ω × (x − center)` with `w` its mean
/// velocity, and the largest deviation of a point's velocity from it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RigidMotion {
    pub(crate) center: Point3<Real>,
    pub(crate) angular: Vector3<Real>,
    pub(crate) deviation: Real,
}

/// The motion of every piece in a step, each measured over its points in parallel ranges whose
/// partial results are combined in range order (the same numbers whatever the threads do).
#[derive(Debug, Default)]
pub(crate) struct PieceMotion {
    /// Mean velocity of each piece's points.
    pub(crate) velocity: Vec<Vector3<Real>>,
    /// Largest speed of a piece's point relative to its mean velocity.
    pub(crate) spread: Vec<Real>,
    /// Largest difference of two corners' velocities in one of a piece's triangles (τ_b).
    pub(crate) triangle_spread: Vec<Real>,
    /// Rigid motion fit to each piece's points.
    pub(crate) rigid: Vec<RigidMotion>,
    /// Per point, how far its velocity deviates from its piece's rigid motion.
    pub(crate) point_deviation: Vec<Real>,
    /// Per range and piece partial results, and their totals per piece (no allocation after
    /// the first step).
    pub(crate) sums: Vec<(Vector3<Real>, Vector3<Real>)>,
    pub(crate) moments: Vec<(Real, Matrix3<Real>, Vector3<Real>)>,
    pub(crate) maxima: Vec<Real>,
    pub(crate) sum_totals: Vec<(Vector3<Real>, Vector3<Real>)>,
    pub(crate) moment_totals: Vec<(Real, Matrix3<Real>, Vector3<Real>)>,
}

/// Ranges the per-piece measures split their points (or triangles) into.
pub(crate) const MOTION_RANGES: usize = 16;

/// Runs `fold(row, range)` for [`MOTION_RANGES`] consecutive ranges of `0..items` in parallel,
/// each into its own `pieces`-long row of `scratch` (set to `zero` first).
pub(crate) fn fold_ranges<A: Copy + Send>(
    scratch: &mut Vec<A>,
    pieces: usize,
    items: usize,
    zero: A,
    fold: impl Fn(&mut [A], std::ops::Range<usize>) + Sync,
) {
    let length = items.div_ceil(MOTION_RANGES).max(1);
    scratch.clear();
    scratch.resize(MOTION_RANGES * pieces.max(1), zero);
    scratch.par_chunks_mut(pieces.max(1)).enumerate().for_each(|(k, row)| {
        fold(row, (k * length).min(items)..((k + 1) * length).min(items));
    });
}

/// Combines the rows [`fold_ranges`] left in `scratch` into `out`, one entry per piece set to
/// `zero` first, in range order.
pub(crate) fn combine_rows<A, B: Clone>(
    scratch: &[A],
    pieces: usize,
    out: &mut Vec<B>,
    zero: B,
    combine: impl Fn(&mut B, &A),
) {
    out.clear();
    out.resize(pieces, zero);
    for row in scratch.chunks(pieces.max(1)) {
        for (total, part) in out.iter_mut().zip(row) {
            combine(total, part);
        }
    }
}

impl PieceMotion {
    /// Measures the pieces' motions: mean velocities, spreads about them, the least-squares
    /// angular velocity of each about its mean position (`J ω = Σ r × (v − w)`,
    /// `J = Σ |r|² I − r rᵀ`; none where `J` is singular or the piece turns more than half a
    /// radian in a step `h`, or for `h = 0`), each point's deviation from its piece's rigid
    /// motion and each piece's largest, and the largest triangle spread. Any `ω` gives valid
    /// bounds with its own deviations; the fit makes them small.
    pub(crate) fn measure(
        &mut self,
        h: Real,
        (positions, velocities): (&[Point3<Real>], &[Vector3<Real>]),
        (component, points): (&[u32], &[u32]),
        (triangles, triangle_spread): (&[[u32; 3]], &[Real]),
    ) {
        let pieces = points.len();
        let n = positions.len();
        // Mean positions and velocities.
        let zero = (Vector3::zeros(), Vector3::zeros());
        fold_ranges(&mut self.sums, pieces, n, zero, |row, range| {
            for i in range {
                let sum = &mut row[component[i] as usize];
                sum.0 += positions[i].coords;
                sum.1 += velocities[i];
            }
        });
        combine_rows(&self.sums, pieces, &mut self.sum_totals, zero, |total, part| {
            total.0 += part.0;
            total.1 += part.1;
        });
        self.rigid.clear();
        self.velocity.clear();
        for (total, &count) in self.sum_totals.iter().zip(points) {
            let count = count.max(1) as Real;
            let center = Point3::from(total.0 / count);
            self.rigid.push(RigidMotion { center, angular: Vector3::zeros(), deviation: 0.0 });
            self.velocity.push(total.1 / count);
        }
        // Spreads about the mean velocities, and the fit's moments.
        let (mean, rigid) = (&self.velocity, &self.rigid);
        let zero = (0.0, Matrix3::zeros(), Vector3::zeros());
        fold_ranges(&mut self.moments, pieces, n, zero, |row, range| {
            for i in range {
                let c = component[i] as usize;
                let (r, relative) = (positions[i] - rigid[c].center, velocities[i] - mean[c]);
                let moment = &mut row[c];
                moment.0 = moment.0.max(relative.norm());
                moment.1 += Matrix3::identity() * r.norm_squared() - r * r.transpose();
                moment.2 += r.cross(&relative);
            }
        });
        combine_rows(&self.moments, pieces, &mut self.moment_totals, zero, |total, part| {
            total.0 = total.0.max(part.0);
            total.1 += part.1;
            total.2 += part.2;
        });
        self.spread.clear();
        self.spread.extend(self.moment_totals.iter().map(|total| total.0));
        for (rigid, (_, j, l)) in self.rigid.iter_mut().zip(&self.moment_totals) {
            rigid.angular = j
                .try_inverse()
                .map(|inverse| inverse * l)
                .filter(|w| h > 0.0 && w.iter().all(|x| x.is_finite()) && h * w.norm() <= 0.5)
                .unwrap_or_else(Vector3::zeros);
        }
        // Each point's deviation from its piece's rigid motion (in the ranges of `fold_ranges`,
        // written per point as well), and each piece's largest.
        self.point_deviation.resize(n, 0.0);
        let (mean, rigid) = (&self.velocity, &self.rigid);
        let length = n.div_ceil(MOTION_RANGES).max(1);
        self.maxima.clear();
        self.maxima.resize(MOTION_RANGES * pieces.max(1), 0.0);
        self.point_deviation
            .par_chunks_mut(length)
            .zip(self.maxima.par_chunks_mut(pieces.max(1)))
            .enumerate()
            .for_each(|(k, (deviations, row))| {
                for (offset, deviation) in deviations.iter_mut().enumerate() {
                    let i = k * length + offset;
                    let c = component[i] as usize;
                    let field = mean[c] + rigid[c].angular.cross(&(positions[i] - rigid[c].center));
                    *deviation = (velocities[i] - field).norm();
                    row[c] = row[c].max(*deviation);
                }
            });
        for row in self.maxima.chunks(pieces.max(1)) {
            for (rigid, &deviation) in self.rigid.iter_mut().zip(row) {
                rigid.deviation = rigid.deviation.max(deviation);
            }
        }
        // The largest triangle spread of each piece.
        fold_ranges(&mut self.maxima, pieces, triangles.len(), 0.0, |row, range| {
            for t in range {
                let c = component[triangles[t][0] as usize] as usize;
                row[c] = row[c].max(triangle_spread[t]);
            }
        });
        combine_rows(&self.maxima, pieces, &mut self.triangle_spread, 0.0, |total, &part| *total = total.max(part));
    }
}

impl RigidMotion {
    /// `1 − h|ω|`, at least a half ([`PieceMotion::measure`] keeps no faster turn).
    pub(crate) fn shrink(&self, h: Real) -> Real {
        1.0 - h * self.angular.norm()
    }
}

/// A tree over `leaves` (leaf `k` is the `k`-th box).
pub(crate) fn build_tree(leaves: impl Iterator<Item = Aabb>) -> Bvh {
    let leaves: Vec<Aabb> = leaves.collect();
    Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves)
}

/// Sets every leaf's box of `bvh` (leaf `k` the `k`-th of `leaves`, as many as it has) and
/// refits the inner boxes, in place on one thread.
pub(crate) fn refit_in_place(bvh: &mut Bvh, leaves: impl Iterator<Item = Aabb>) {
    for (k, aabb) in leaves.enumerate() {
        bvh.insert_or_update_partially(aabb, k as u32, 0.0);
    }
    bvh.refit_without_opt();
}

/// Squared distance between two boxes (zero where they overlap).
pub(crate) fn squared_distance_between_boxes(a: &Aabb, b: &Aabb) -> Real {
    (b.mins - a.maxs).max(a.mins - b.maxs).max(ParryVector::ZERO).length_squared()
}

/// Squared distance from `q` to the box from `lo` to `hi` (zero inside it).
pub(crate) fn squared_distance_to_box(q: ParryVector, lo: ParryVector, hi: ParryVector) -> Real {
    (lo - q).max(q - hi).max(ParryVector::ZERO).length_squared()
}

pub(crate) fn to_parry(p: &Point3<Real>) -> ParryVector {
    ParryVector::new(p.x, p.y, p.z)
}

/// How far, in reaches, a piece's points may move before its whole-surface tree is refit.
pub(crate) const STALE_REACH: Real = 0.1;

/// Trees with fewer leaves are refit one per task, side by side; larger ones with parry's
/// parallel batch update and refit (a single large piece would otherwise refit on one core).
pub(crate) const PARALLEL_REFIT_LEAVES: usize = 16384;

/// Scratch of the per-step hierarchy refits, reused across steps.
#[derive(Default)]
pub(crate) struct RefitScratch {
    pub(crate) updates: Vec<(Aabb, u32, Real)>,
    pub(crate) statuses: Vec<BvhLeafUpdateStatus>,
    pub(crate) workspace: BvhWorkspace,
}

impl RefitScratch {
    /// Moves leaf `k` of `bvh` to `leaf(k)` for every one of its `count` leaves and refits it:
    /// the boxes computed, written and merged upwards on the rayon pool.
    pub(crate) fn refit(&mut self, bvh: &mut Bvh, count: usize, leaf: impl Fn(usize) -> Aabb + Sync) {
        (0..count).into_par_iter().map(|k| (leaf(k), k as u32, 0.0)).collect_into_vec(&mut self.updates);
        bvh.insert_or_update_batch_partially_parallel(&self.updates, &mut self.statuses);
        bvh.refit_parallel(&mut self.workspace);
    }
}
