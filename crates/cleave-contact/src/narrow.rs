//! The narrow phase: each step's contacts of the surface points against planes, static meshes and
//! the body's own surface (vertex–triangle between and within pieces, edge–edge between feature
//! edges), the pairs the solution drives together, and the lagged normal forces friction reads
//! (docs/math/contact.md §2–§5).

use crate::colliders::{Colliders, MeshCollider, SurfaceContact};
use crate::motion::*;
use crate::rows::*;
use crate::set::*;
use cleave_core::{Embedding, Point3, Real, Vector3};
use cleave_geometry::{closest_parameters_of_lines, closest_point_on_triangle};
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::math::Vector as ParryVector;
use parry3d_f64::partitioning::Bvh;
use rayon::prelude::*;

/// A surface pair within the reach that the start-of-step velocities did not predict to close:
/// what [`make_contact`] needs to activate it later.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NearPair {
    pub(crate) row: Row,
    pub(crate) which: (ContactKind, u32, Real),
    pub(crate) normal: Vector3<Real>,
    pub(crate) gap: (Real, Real, Real),
    pub(crate) params: (Real, Real, Real),
    /// Penetration the solution may predict before the pair joins: half the reach, so that
    /// pairs closing by a little do not cost a second solve (the next step's prediction sees
    /// them).
    pub(crate) slack: Real,
}

/// The contact normal of point `q` against the triangle point `c` closest to it (at
/// `distance`), the triangle having unit normal `n`: `n` when `q` projects into the triangle
/// or lies within `lateral` of it sideways (a vertex on a vertex of a coinciding face, where
/// the deformed faces around it leave gaps between their projections), none when farther
/// beyond its edges (it is the neighbouring triangle's; where no triangle's, an edge meets an
/// edge, which vertex–triangle contact does not see: docs/math/contact.md §5). The force pair
/// then acts on one line up to that sideways offset, which bounds its torque.
pub(crate) fn contact_normal(
    q: &Point3<Real>,
    c: &Point3<Real>,
    n: &Vector3<Real>,
    distance: Real,
    lateral: Real,
) -> Option<Vector3<Real>> {
    let offset = q - c;
    (distance == 0.0 || (offset - n * n.dot(&offset)).norm() <= lateral.max(1e-9 * distance)).then_some(*n)
}

/// A point's pair with one triangle: gap along `normal`, distance to the triangle, and the
/// barycentrics of the triangle point it meets.
pub(crate) struct Candidate {
    gap: Real,
    distance: Real,
    triangle: usize,
    beta: [Real; 3],
    normal: Vector3<Real>,
}

/// Sideways tolerance of [`contact_normal`], as a fraction of the reach.
pub(crate) const LATERAL_FRACTION: Real = 0.05;

impl ContactSet {
    /// Finds this step's contacts at `x` with velocities `v`.
    pub fn detect(&mut self, colliders: &Colliders<'_>, x: &[Real], v: &[Real], h: Real, gravity: &Vector3<Real>) {
        self.contacts.clear();
        let Some(points) = colliders.points else { return };
        let n = points.len();
        self.positions.resize(n, Point3::origin());
        self.velocities.resize(n, Vector3::zeros());
        self.positions.par_iter_mut().zip(self.velocities.par_iter_mut()).enumerate().for_each(|(i, (p, u))| {
            *p = points.point(x, i);
            *u = points.point(v, i).coords;
        });
        let collider_count = colliders.planes.len() + colliders.meshes.len() + 1;
        if self.lagged.len() != collider_count * n + self.feature_edges.len() {
            self.lagged = vec![0.0; collider_count * n + self.feature_edges.len()];
        }
        // One slot per point, reused by every collider: no allocation after the first step.
        let mut per_point = std::mem::take(&mut self.per_point);
        per_point.resize(n, None);
        let (positions, velocities, lagged) = (&self.positions, &self.velocities, &self.lagged);
        // Planes in one sequential pass per plane: a dot product per point, and the few points
        // at the plane become contacts (a parallel pass through a slot per point cost more in
        // writing and scanning the slots than the test itself).
        for (k, plane) in colliders.planes.iter().enumerate() {
            let params = (plane.stiffness, plane.damping, plane.friction);
            let g = plane.normal.dot(gravity);
            let offset = -plane.normal.dot(&plane.point.coords);
            for (i, (q, u)) in positions.iter().zip(velocities).enumerate() {
                let d = plane.normal.dot(&q.coords) + offset;
                let slot = k * n + i;
                let which = (ContactKind::Plane, slot as u32, lagged[slot]);
                if let Some(contact) =
                    make_contact(Row::point(i as u32), which, plane.normal, (d, offset, 0.0), u, g, h, params)
                {
                    self.contacts.push(contact);
                }
            }
        }
        for (k, mesh) in colliders.meshes.iter().enumerate() {
            let k = colliders.planes.len() + k;
            per_point.par_iter_mut().enumerate().for_each(|(i, slot_of_point)| {
                *slot_of_point = (|| {
                    let (q, u) = (&positions[i], &velocities[i]);
                    let radius = mesh.reach + h * u.norm();
                    let (c, normal) = mesh.closest(q, radius)?;
                    let d = normal.dot(&(q - c));
                    // Deeper than `reach` behind a triangle is the far side of a thin wall.
                    if d < -mesh.reach {
                        return None;
                    }
                    let params = (mesh.stiffness, mesh.damping, mesh.friction);
                    let slot = k * n + i;
                    let which = (ContactKind::Mesh, slot as u32, lagged[slot]);
                    make_contact(
                        Row::point(i as u32),
                        which,
                        normal,
                        (d, -normal.dot(&c.coords), 0.0),
                        u,
                        normal.dot(gravity),
                        h,
                        params,
                    )
                })();
            });
            self.contacts.extend(per_point.iter().flatten().copied());
        }
        self.per_point = per_point;
        if let Some(surface) = colliders.surface {
            self.detect_surface(surface, h, gravity, (collider_count - 1) * n);
            if surface.edge_contact {
                self.detect_edges(surface, h, collider_count * n);
            }
        }
    }

    fn detect_surface(&mut self, surface: &SurfaceContact, h: Real, gravity: &Vector3<Real>, first_slot: usize) {
        let (positions, velocities) = (&self.positions, &self.velocities);
        let triangles = &surface.triangles;
        // Deformed vertex normals (area weighted): a contact needs opposing surfaces, so points
        // of one smooth surface never push on its own nearby triangles.
        self.vertex_normals.clear();
        self.vertex_normals.resize(positions.len(), Vector3::zeros());
        // Each triangle's area normal once (the vertex normals sum them), then its unit normal.
        self.triangle_area_normals.resize(triangles.len(), Vector3::zeros());
        self.triangle_normals.resize(triangles.len(), Vector3::zeros());
        // And the largest difference of its corners' velocities, which bounds how much faster any
        // corner moves than any point of the triangle.
        self.triangle_spread.resize(triangles.len(), 0.0);
        self.triangle_area_normals
            .par_iter_mut()
            .zip(self.triangle_normals.par_iter_mut())
            .zip(self.triangle_spread.par_iter_mut())
            .zip(triangles)
            .for_each(|(((area_normal, normal), spread), triangle)| {
                let [a, b, c] = triangle.map(|i| positions[i as usize]);
                *area_normal = (b - a).cross(&(c - a));
                *normal = area_normal.try_normalize(0.0).unwrap_or_else(Vector3::zeros);
                let [va, vb, vc] = triangle.map(|i| velocities[i as usize]);
                *spread = (va - vb).norm().max((vb - vc).norm()).max((vc - va).norm());
            });
        let (offsets, around, area_normals) =
            (&self.vertex_triangle_offsets, &self.vertex_triangles, &self.triangle_area_normals);
        self.vertex_normals.par_iter_mut().enumerate().for_each(|(i, normal)| {
            *normal =
                around[offsets[i]..offsets[i + 1]].iter().fold(Vector3::zeros(), |s, &t| s + area_normals[t as usize]);
        });
        // Motion is bounded relative to the mean velocity `w_b` of the piece searched:
        // |u_q − u_t| ≤ |u_q − w_b| + |u_t − w_b|, the second in the leaf boxes, the first in
        // the query. So a piece moving as a whole (falling, sliding) does not inflate its boxes
        // by its motion, and a point is searched with only its speed relative to each piece;
        // tighter still relative to its rigid motion (`RigidMotion`).
        self.motion.measure(
            if self.ignore_turning { 0.0 } else { h },
            (positions, velocities),
            (&self.component, &self.component_points),
            (triangles, &self.triangle_spread),
        );
        let motion = &self.motion;
        let component = &self.component;
        // A leaf box of a piece's whole surface is the triangle's own (the nearest-triangle
        // search below bounds its radius by the motion); a leaf box of its cut faces holds the
        // reach, the triangle's motion relative to the piece and the spread of its corners'
        // velocities (the own-cut query is a box).
        let num_whole = self.component_triangles.len();
        let triangle_spread = &self.triangle_spread;
        let leaf = |triangle: u32, tree: usize| -> Aabb {
            let t = &triangles[triangle as usize];
            let mut lo = positions[t[0] as usize];
            let mut hi = lo;
            for &i in t {
                lo = lo.inf(&positions[i as usize]);
                hi = hi.sup(&positions[i as usize]);
            }
            if tree < num_whole {
                return Aabb::new(to_parry(&lo), to_parry(&hi));
            }
            // With the piece's rigid motion `f(x) = w + ω × (x − c)` and a point q of the same
            // piece at distance d from the point p of the triangle it meets, |u − v_p| ≤ |ω| d
            // + |u − f(q)| + max_k |v_k − f(x_k)|, so `consider`'s reach
            // reach + h(|u − v_p| + max_k |v_k − v_p|) is at least d only if
            // d (1 − h|ω|) ≤ reach + h(|u − f(q)| + max_k |v_k − f(x_k)| + τ_t): the leaf box
            // holds all of it but the query's |u − f(q)| (`own_query`), each over 1 − h|ω|.
            let rigid = &motion.rigid[component[t[0] as usize] as usize];
            let deviation = t.iter().map(|&i| motion.point_deviation[i as usize]).fold(0.0, Real::max);
            let margin = Vector3::repeat(
                (surface.reach + h * (deviation + triangle_spread[triangle as usize])) / rigid.shrink(h)
                    * (1.0 + 1e-12),
            );
            Aabb::new(to_parry(&(lo - margin)), to_parry(&(hi + margin)))
        };
        let lists = self.component_triangles.iter().chain(&self.component_cut_triangles);
        if self.bvh_all.is_empty() {
            // Built at the first step of an epoch, one tree per task; a tree taken from the
            // last epoch is refit instead.
            let mut reused = std::mem::take(&mut self.reused_trees);
            reused.resize_with(self.component_triangles.len(), || None);
            let mut all: Vec<Bvh> = reused
                .into_par_iter()
                .map(Some)
                .chain(self.component_cut_triangles.par_iter().map(|_| None))
                .zip(self.component_triangles.par_iter().chain(self.component_cut_triangles.par_iter()))
                .enumerate()
                .map(|(tree, (reused, list))| {
                    let leaves = list.iter().map(|&t| leaf(t, tree));
                    match reused.flatten() {
                        Some(mut bvh) => {
                            refit_in_place(&mut bvh, leaves);
                            bvh
                        }
                        None => build_tree(leaves),
                    }
                })
                .collect();
            self.bvh_cut = all.split_off(self.component_triangles.len());
            self.bvh_all = all;
            self.refit_positions.clear();
            self.refit_positions.extend_from_slice(positions);
            self.staleness.clear();
            self.staleness.resize(num_whole, 0.0);
        } else {
            // A piece's whole-surface tree is refit only once a point moved more than
            // STALE_REACH reaches since its last refit: until then each of its boxes, loosened
            // by `staleness` (the largest such move), holds the triangles it was fit to, and
            // the searches loosen them so (a piece at rest is refit every few dozen steps).
            let refit_positions = &self.refit_positions;
            fold_ranges(&mut self.staleness_ranges, num_whole, positions.len(), 0.0, |row, range| {
                for i in range {
                    let c = component[i] as usize;
                    row[c] = row[c].max((positions[i] - refit_positions[i]).norm());
                }
            });
            combine_rows(&self.staleness_ranges, num_whole, &mut self.staleness, 0.0, |stale, &moved| {
                *stale = stale.max(moved)
            });
            let limit = STALE_REACH * surface.reach;
            self.refit_now.clear();
            self.refit_now.extend(self.staleness.iter().map(|&s| s > limit || s.is_nan()));
            self.refit_now.resize(num_whole + self.bvh_cut.len(), true);
            let refit_now = &self.refit_now;
            // Trees side by side, one task each (a piece's tree is refit sequentially in place:
            // on bunny_slice's 22 trees 1.45 against 2.7 ms/step for each tree in turn spread
            // over the pool); a tree too large to be one task uses parry's parallel update.
            let lists_par = self.component_triangles.par_iter().chain(self.component_cut_triangles.par_iter());
            self.bvh_all.par_iter_mut().chain(self.bvh_cut.par_iter_mut()).zip(lists_par).enumerate().for_each(
                |(tree, (bvh, list))| {
                    if list.len() < PARALLEL_REFIT_LEAVES && refit_now[tree] {
                        refit_in_place(bvh, list.iter().map(|&t| leaf(t, tree)));
                    }
                },
            );
            for (tree, (bvh, list)) in self.bvh_all.iter_mut().chain(self.bvh_cut.iter_mut()).zip(lists).enumerate() {
                if list.len() >= PARALLEL_REFIT_LEAVES && refit_now[tree] {
                    self.refit.refit(bvh, list.len(), |k| leaf(list[k], tree));
                }
            }
            for (stale, &refit) in self.staleness.iter_mut().zip(refit_now) {
                if refit {
                    *stale = 0.0;
                }
            }
            self.refit_positions.par_iter_mut().zip(positions).zip(component).for_each(|((last, p), &c)| {
                if refit_now[c as usize] {
                    *last = *p;
                }
            });
        }
        self.roots_all.clear();
        self.roots_all
            .extend(self.bvh_all.iter().zip(&self.staleness).map(|(bvh, &stale)| bvh.root_aabb().loosened(stale)));
        // Per piece the search radius (below) less the point's own speed term, bounded from
        // above: reach + h(|w_b| + s_b + τ_b).
        self.loose_reach.clear();
        self.loose_reach.extend((0..self.bvh_all.len()).map(|b| {
            (surface.reach
                + h * (self.motion.velocity[b].norm() + self.motion.spread[b] + self.motion.triangle_spread[b]))
                * (1.0 + 1e-9)
        }));
        // Every point of piece a lies in a's root box and moves at most |w_a| + s_a, so a
        // piece b farther from that box than loose_reach[b] + h(|w_a| + s_a) is beyond every
        // point's loose bound below, and beyond every edge query of `detect_edges` (which is
        // within reach + h(|w_a| + s_a + |w_b| + s_b), smaller). Tested once per pair of
        // pieces instead of once per point and piece (22 pieces on bunny_slice).
        self.piece_candidate_offsets.clear();
        self.piece_candidates.clear();
        self.piece_candidate_offsets.push(0);
        for (a, root_a) in self.roots_all.iter().enumerate() {
            let own_speed = h * (self.motion.velocity[a].norm() + self.motion.spread[a]) * (1.0 + 1e-6);
            for (b, root_b) in self.roots_all.iter().enumerate() {
                let bound = self.loose_reach[b] + own_speed + 1e-12 * surface.reach;
                if b != a && (self.search_every_piece || squared_distance_between_boxes(root_a, root_b) < bound * bound)
                {
                    self.piece_candidates.push(b as u32);
                }
            }
            self.piece_candidate_offsets.push(self.piece_candidates.len());
        }

        let mut per_point = std::mem::take(&mut self.per_point);
        let mut near = std::mem::take(&mut self.near);
        // Every slot is written below (an empty one by its tag alone): clearing both lists
        // first wrote 5 MB a step on bunny_slice.
        near.resize(self.positions.len(), None);
        per_point.resize(positions.len(), None);
        let this = &*self;
        let params = (surface.stiffness, surface.damping, surface.friction);
        let lateral = LATERAL_FRACTION * surface.reach;
        per_point.par_iter_mut().zip(near.par_iter_mut()).enumerate().for_each_init(
            Vec::new,
            |at_feature: &mut Vec<u32>, (i, (slot, near))| {
                let q = positions[i];
                let u = velocities[i];
                let vertex_normal = this.vertex_normals[i];
                *slot = None;
                *near = None;
                if vertex_normal == Vector3::zeros() {
                    return;
                }
                let own = this.component[i] as usize;
                // The point's own part of its own piece's cut-face leaf boxes (see `leaf`).
                let own_query = || {
                    let rigid = &this.motion.rigid[own];
                    let deviation = u - this.motion.velocity[own] - rigid.angular.cross(&(q - rigid.center));
                    let motion = Vector3::repeat(h * deviation.norm() / rigid.shrink(h) * (1.0 + 1e-12));
                    Aabb::new(to_parry(&(q - motion)), to_parry(&(q + motion)))
                };
                // Whether a pair is within reach: farther than the reach is no contact yet; deeper
                // than it behind the surface is beyond what the search sees (the boxes hold the
                // reach).
                let within_reach = |candidate: &Candidate| {
                    let tri = triangles[candidate.triangle];
                    let other_velocity = tri
                        .iter()
                        .zip(&candidate.beta)
                        .fold(Vector3::zeros(), |s, (&k, &b)| s + velocities[k as usize] * b);
                    let reach = surface.reach
                        + h * ((u - other_velocity).norm()
                            + tri
                                .iter()
                                .map(|&k| (velocities[k as usize] - other_velocity).norm())
                                .fold(0.0, Real::max));
                    candidate.distance <= reach && candidate.gap >= -surface.reach
                };
                // Per searched surface its pair for this point, within reach; the smallest gap wins.
                let mut best: Option<Candidate> = None;
                let mut keep = |candidate: Candidate| {
                    if best.as_ref().is_none_or(|b| candidate.gap < b.gap) {
                        best = Some(candidate);
                    }
                };
                // The point's own piece only through its cut faces (the two faces of an unfinished
                // cut, a flap): its own smooth surface around the point is never visited. A pair
                // needs opposing faces, no adjacency and to be within reach, and the closest such
                // triangle is taken (so neither what the box search visits beyond the reach nor the
                // order it visits in changes which).
                {
                    let query = own_query();
                    let list = &this.component_cut_triangles[own];
                    let mut nearest: Option<Candidate> = None;
                    for t in this.bvh_cut[own].intersect_aabb(&query).map(|leaf| list[leaf as usize]) {
                        let tri = &triangles[t as usize];
                        if vertex_normal.dot(&this.triangle_normals[t as usize]) >= 0.0 || this.excluded(i as u32, tri)
                        {
                            continue;
                        }
                        let corners = tri.map(|k| positions[k as usize]);
                        let (c, beta) = closest_point_on_triangle(&q, &corners);
                        let distance = (q - c).norm();
                        if contact_normal(&q, &c, &this.triangle_normals[t as usize], distance, lateral).is_none()
                            || this.behind_at_rest(i, tri, &beta)
                        {
                            continue;
                        }
                        let normal = this.triangle_normals[t as usize];
                        let candidate =
                            Candidate { gap: normal.dot(&(q - c)), distance, triangle: t as usize, beta, normal };
                        // Equally near (a point on a vertex or edge of the coinciding face): the
                        // lowest-numbered triangle, whatever order the tree visits them in.
                        let nearer = |b: &Candidate| {
                            distance < b.distance || (distance == b.distance && candidate.triangle < b.triangle)
                        };
                        if nearest.as_ref().is_none_or(nearer) && within_reach(&candidate) {
                            nearest = Some(candidate);
                        }
                    }
                    if let Some(candidate) = nearest {
                        keep(candidate);
                    }
                }
                // Every other piece by its signed distance: the nearest triangle of its closed
                // surface, inside or outside by the pseudonormal of the nearest feature (face, edge
                // or vertex); inside, the normal along q − c. Taking a farther triangle because a nearer one
                // faces the wrong way, as a facing filter does, made points on or beside another
                // piece's rim "penetrate" a face beyond the rim by up to the reach (most of the
                // deep contacts after a cut through touching pieces: docs/math/contact.md §5).
                // Another piece's nearest triangle counts within reach.
                let mut consider = |candidate: Candidate| {
                    if within_reach(&candidate) {
                        keep(candidate);
                    }
                };
                let q_parry = to_parry(&q);
                let speed = h * u.norm();
                for b in this.candidate_pieces(own) {
                    // Most pieces are far from most points: a bound on the radius below that
                    // needs no square root (|u − w_b| ≤ |u| + |w_b|) rules them out first.
                    let root = &this.roots_all[b];
                    let loose = this.loose_reach[b] + speed * (1.0 + 1e-9);
                    if squared_distance_to_box(q_parry, root.mins, root.maxs) >= loose * loose {
                        continue;
                    }
                    // The nearest triangle within the largest reach any triangle of the piece can
                    // have (`consider` below), by branch and bound on the triangles' own boxes:
                    // what is found depends on the triangles only, not on boxes, so not on how the
                    // scene is turned. Per triangle the reach is the surface's plus the step's
                    // approach, h(|u − v_t| + max_k |v_k − v_t|) with v_t the velocity of its point
                    // (a convex combination of its corners'), which is at most
                    // h(|u − w_b| + s_b + τ_b) with w_b the piece's mean velocity, s_b its points'
                    // largest speed relative to it and τ_b the largest difference of two corners'
                    // velocities in one of its triangles (a rotating piece: its points' speeds
                    // relative to w_b grow with its size, τ_b only with its triangles'). The
                    // factor keeps rounding from putting a triangle `consider` takes outside.
                    let radius = (surface.reach
                        + h * ((u - this.motion.velocity[b]).norm()
                            + this.motion.spread[b]
                            + this.motion.triangle_spread[b]))
                        * (1.0 + 1e-12);
                    if squared_distance_to_box(q_parry, root.mins, root.maxs) >= radius * radius {
                        continue;
                    }
                    // A piece that turns moves its points relative to its mean velocity by up to
                    // its angular speed times its size, but a triangle near q relative to q by
                    // little more than what the piece's rigid motion does at q: with v = w + ω ×
                    // (x − c) + δ, |u − v_t| ≤ |u − w − ω × (q − c)| + |ω| d + δ_b at distance d,
                    // so d ≤ reach_t needs d (1 − h|ω|) ≤ reach + h(|u − w − ω × (q − c)| + δ_b
                    // + τ_b).
                    let rigid = &this.motion.rigid[b];
                    let relative = u - this.motion.velocity[b] - rigid.angular.cross(&(q - rigid.center));
                    let rigid_radius = (surface.reach
                        + h * (relative.norm() + rigid.deviation + this.motion.triangle_spread[b]))
                        / rigid.shrink(h)
                        * (1.0 + 1e-12);
                    let radius = radius.min(rigid_radius);
                    let list = &this.component_triangles[b];
                    // A box of a tree not refit since its piece moved by up to `stale` holds its
                    // triangles once loosened by that on every side.
                    let stale = ParryVector::splat(this.staleness[b]);
                    let nearest = this.bvh_all[b].find_best(
                        radius * radius,
                        |node, _| squared_distance_to_box(q_parry, node.mins() - stale, node.maxs() + stale),
                        |leaf, _| {
                            let t = list[leaf as usize] as usize;
                            let corners = triangles[t].map(|k| positions[k as usize]);
                            let (c, beta) = closest_point_on_triangle(&q, &corners);
                            Some(((q - c).norm_squared(), (t, c, beta)))
                        },
                    );
                    let Some((_, (distance_squared, (t, c, beta)))) = nearest else { continue };
                    let distance = distance_squared.sqrt();
                    // Every triangle at the nearest feature is nearest (a corner's, an edge's faces):
                    // the pair is decided over all of them, so it does not depend on which one the
                    // search met first (its order, or rounding between the faces of an edge).
                    this.feature_triangles(triangles, t, &beta, at_feature);
                    // The pair is held by the feature's first triangle, whichever the search found.
                    let (t, c, beta, distance) = match at_feature[0] as usize {
                        first if first != t => {
                            let (c, beta) =
                                closest_point_on_triangle(&q, &triangles[first].map(|k| positions[k as usize]));
                            (first, c, beta, (q - c).norm())
                        }
                        _ => (t, c, beta, distance),
                    };
                    let offset = q - c;
                    // The feature's triangles with their own closest points (the same point up to
                    // rounding), in index order.
                    let on_triangle = |o: u32| {
                        if o as usize == t {
                            return (c, beta);
                        }
                        closest_point_on_triangle(&q, &triangles[o as usize].map(|k| positions[k as usize]))
                    };
                    // Inside by the pseudonormal, and behind every face at the nearest feature: where
                    // an edge or corner of a piece is not manifold (two regions of one piece meeting
                    // there), its pseudonormal can say inside for a point beside it, and a point
                    // inside near a reflex edge or corner, the only inside points whose nearest
                    // feature is not a face, is behind every face there.
                    let behind = at_feature.iter().all(|&o| this.triangle_normals[o as usize].dot(&offset) < 0.0);
                    if distance > 1e-9 * surface.reach
                        && behind
                        && offset.dot(&this.pseudonormal(triangles, t, &beta)) < 0.0
                    {
                        // Inside: pushed out along the shortest way, whatever feature is nearest.
                        let normal = -offset / distance;
                        consider(Candidate { gap: -distance, distance, triangle: t, beta, normal });
                    } else {
                        // Outside or touching: only a face it projects into and that faces it, the
                        // smallest gap among the feature's faces. An edge or corner nearest from
                        // outside is no contact yet (its direction q − c says little about where the
                        // point will meet the surface: a point 2 cm beside an edge, closing along x,
                        // would get a sideways push), and no farther triangle stands in for it.
                        let mut facing: Option<Candidate> = None;
                        for &o in at_feature.iter() {
                            let normal = this.triangle_normals[o as usize];
                            let (c, beta) = on_triangle(o);
                            let gap = normal.dot(&(q - c));
                            if vertex_normal.dot(&normal) < 0.0
                                && contact_normal(&q, &c, &normal, distance, lateral).is_some()
                                && facing.as_ref().is_none_or(|f| gap < f.gap)
                            {
                                facing = Some(Candidate { gap, distance, triangle: o as usize, beta, normal });
                            }
                        }
                        if let Some(candidate) = facing {
                            consider(candidate);
                        }
                    }
                }
                let Some(Candidate { gap, triangle, beta, normal, .. }) = best else { return };
                let tri = triangles[triangle];
                let other_velocity =
                    tri.iter().zip(&beta).fold(Vector3::zeros(), |s, (&k, &b)| s + velocities[k as usize] * b);
                let relative = u - other_velocity;
                let d = gap - surface.thickness;
                let which = (ContactKind::Surface, (first_slot + i) as u32, this.lagged[first_slot + i]);
                // Touching counts (faces a cut has just separated coincide, and nothing else would
                // hold the upper one up in the step after the cut), up to rounding of the gap.
                let gap = (d, -surface.thickness, 1e-9 * surface.reach);
                let row = Row::vertex_triangle(i as u32, tri, beta);
                // Gravity enters the prediction where the triangle's side is at rest (slower than a
                // step of free fall, g h): a piece lying on another falls onto it as onto the
                // ground. Where both sides move, they may be falling together, and it does not.
                let resting = other_velocity.norm() < h * gravity.norm();
                let gravity_along = if resting { normal.dot(gravity) } else { 0.0 };
                *slot = make_contact(row, which, normal, gap, &relative, gravity_along, h, params);
                if slot.is_none() {
                    *near = Some(NearPair { row, which, normal, gap, params, slack: 0.5 * surface.reach });
                }
            },
        );
        self.contacts.extend(per_point.iter().flatten().copied());
        self.near = near;
        self.per_point = per_point;
    }

    /// Edge–edge contacts: each feature edge against the feature edges of the other pieces, where
    /// the closest points of the two lines lie inside both edges and the two pieces' faces at the
    /// edges oppose along the common normal `e_a × e_b` (docs/math/contact.md §2). The closest
    /// active pair per feature edge; a pair is taken from its lower-numbered edge.
    fn detect_edges(&mut self, surface: &SurfaceContact, h: Real, first_slot: usize) {
        let (positions, velocities) = (&self.positions, &self.velocities);
        // Leaf box of a feature edge: its ends, the reach, and their motion relative to their
        // piece's mean velocity in one step (as the cut triangles' boxes, `detect_surface`).
        let (component, component_velocity) = (&self.component, &self.motion.velocity);
        let leaf = |g: u32| -> Aabb {
            let [p, q] = self.edges[g as usize];
            let w = component_velocity[component[p as usize] as usize];
            let speed = (velocities[p as usize] - w).norm().max((velocities[q as usize] - w).norm());
            let margin = Vector3::repeat(surface.reach + h * speed);
            let (p, q) = (positions[p as usize], positions[q as usize]);
            Aabb::new(to_parry(&(p.inf(&q) - margin)), to_parry(&(p.sup(&q) + margin)))
        };
        if self.bvh_edges.is_empty() {
            self.bvh_edges =
                self.component_feature_edges.par_iter().map(|list| build_tree(list.iter().map(|&g| leaf(g)))).collect();
        } else {
            self.bvh_edges
                .par_iter_mut()
                .zip(self.component_feature_edges.par_iter())
                .for_each(|(bvh, list)| refit_in_place(bvh, list.iter().map(|&g| leaf(g))));
        }
        // Every slot is written below.
        let mut per_edge = std::mem::take(&mut self.per_edge);
        per_edge.resize(self.feature_edges.len(), None);
        let this = &*self;
        let params = (surface.stiffness, surface.damping, surface.friction);
        // Outward normal of the faces at an edge (their sum, deformed).
        let edge_normal = |e: usize| {
            let [f0, f1] = this.edge_faces[e];
            this.triangle_normals[f0 as usize] + this.triangle_normals[f1 as usize]
        };
        per_edge.par_iter_mut().enumerate().for_each(|(k, slot)| {
            let e = this.feature_edges[k] as usize;
            let a = this.edges[e];
            let ends = a.map(|i| positions[i as usize]);
            let speeds = a.map(|i| velocities[i as usize]);
            let own = this.component[a[0] as usize] as usize;
            let outward_a = edge_normal(e);
            // The closest active pair.
            let mut best: Option<(Real, Contact)> = None;
            let which = (ContactKind::Edge, (first_slot + k) as u32, this.lagged[first_slot + k]);
            for b in this.candidate_pieces(own) {
                // A pair is taken from its lower-numbered edge, and a piece's list is in
                // increasing order: a piece whose edges all come before this one has none.
                let (bvh, list) = (&this.bvh_edges[b], &this.component_feature_edges[b]);
                if list.last().is_none_or(|&last| (last as usize) < e) {
                    continue;
                }
                let w = this.motion.velocity[b];
                let motion = Vector3::repeat(h * (speeds[0] - w).norm().max((speeds[1] - w).norm()));
                let query =
                    Aabb::new(to_parry(&(ends[0].inf(&ends[1]) - motion)), to_parry(&(ends[0].sup(&ends[1]) + motion)));
                // (The root box is the piece's triangles' own; the leaves of its edge tree lie
                // within it loosened by the reach and the piece's spread of speeds.)
                if !this.roots_all[b].loosened(surface.reach + h * this.motion.spread[b]).intersects(&query) {
                    continue;
                }
                for g in bvh.intersect_aabb(&query).map(|leaf| list[leaf as usize] as usize) {
                    if g < e {
                        continue;
                    }
                    let other = this.edges[g].map(|i| positions[i as usize]);
                    let Some((s, t)) = closest_parameters_of_lines(&ends, &other) else { continue };
                    // Within the reach of an end the pair is that end's: the vertex–triangle
                    // contacts of the faces around it see it, and the two edges' common normal
                    // turns arbitrarily as they come to share a corner.
                    let (length_a, length_b) = ((ends[1] - ends[0]).norm(), (other[1] - other[0]).norm());
                    let (margin_s, margin_t) = (surface.reach / length_a, surface.reach / length_b);
                    if !(margin_s..=1.0 - margin_s).contains(&s) || !(margin_t..=1.0 - margin_t).contains(&t) {
                        continue;
                    }
                    // The common normal, towards this edge's side of the other piece.
                    let Some(mut normal) = (ends[1] - ends[0]).cross(&(other[1] - other[0])).try_normalize(0.0) else {
                        continue;
                    };
                    let outward_b = edge_normal(g);
                    if normal.dot(&outward_b) < 0.0 {
                        normal = -normal;
                    }
                    if normal.dot(&outward_a) >= 0.0 || normal.dot(&outward_b) <= 0.0 {
                        continue;
                    }
                    let p = ends[0] + (ends[1] - ends[0]) * s;
                    let q = other[0] + (other[1] - other[0]) * t;
                    let d = normal.dot(&(p - q)) - surface.thickness;
                    let row = Row::edge_edge(a, s, this.edges[g], t);
                    let relative = row.entries().fold(Vector3::zeros(), |sum, (i, w)| sum + velocities[i as usize] * w);
                    // Farther than the reach (with this step's approach) is no contact yet;
                    // deeper than the reach is the far side of a thin part.
                    if d > surface.reach + h * relative.norm() || d < -surface.reach {
                        continue;
                    }
                    let distance = (p - q).norm();
                    if best.as_ref().is_some_and(|best| distance >= best.0) {
                        continue;
                    }
                    let gap = (d, -surface.thickness, 1e-9 * surface.reach);
                    if let Some(contact) = make_contact(row, which, normal, gap, &relative, 0.0, h, params) {
                        best = Some((distance, contact));
                    }
                }
            }
            *slot = best.map(|(_, contact)| contact);
        });
        self.contacts.extend(per_edge.iter().flatten().copied());
        self.per_edge = per_edge;
    }

    /// Stores the normal force every active contact carried in the step just solved (new
    /// velocities `v`): `max(0, −k (min(d, 0) + h n·u⁺) − c n·u⁺)` with `u⁺` the row's
    /// velocity; friction of the next step is proportional to it.
    pub fn store_normal_forces(&mut self, points: &Embedding, v: &[Real], h: Real) {
        self.lagged.iter_mut().for_each(|l| *l = 0.0);
        for c in &self.contacts {
            let approach = c.normal.dot(&row_value(points, c, v));
            let force = -c.stiffness * (c.depth.min(0.0) + h * approach) - c.damping * approach;
            self.lagged[c.slot as usize] = force.max(0.0);
        }
    }

    /// Activates the near pairs of this step's detection that velocities `v` (the step's
    /// solution) drive more than their slack into each other, `d + h n·u⁺ < −slack` (half the
    /// reach), and returns how many: the
    /// caller solves again with them. Their gap is not negative, so they add no force, only
    /// the implicit term that stops the approach (docs/math/contact.md §3).
    pub fn activate_driven(&mut self, points: &Embedding, v: &[Real], h: Real) -> usize {
        let mut added = 0;
        for slot in self.near.iter_mut() {
            let Some(pair) = slot else { continue };
            let u = pair
                .row
                .entries()
                .fold(Vector3::zeros(), |sum, (point, w)| sum + points.point(v, point as usize).coords * w);
            if pair.gap.0 + h * pair.normal.dot(&u) < -pair.slack
                && let Some(contact) =
                    make_contact(pair.row, pair.which, pair.normal, pair.gap, &u, 0.0, h, pair.params)
            {
                self.contacts.push(contact);
                added += 1;
                *slot = None;
            }
        }
        added
    }

    /// Visits the couple of every pair between two sides of the body's surface in the step just
    /// solved (velocities `v`, not yet applied to `x`), with a node of each side: a penalty pair
    /// acts on two points that the penetration (or, for a pair the prediction activated, the
    /// approach) holds apart along the normal, so its tangential (friction) part is a couple
    /// `r × f` with `r = p − c` the row's value at `x`, which changes the angular momentum by
    /// `h r × f` where the continuum's touching surfaces have none. `visit(a, b, h r × f)`;
    /// docs/math/contact.md §5.
    pub fn visit_pair_couples(
        &self,
        points: &Embedding,
        x: &[Real],
        v: &[Real],
        h: Real,
        mut visit: impl FnMut(u32, u32, Vector3<Real>),
    ) {
        for c in self.contacts.iter().filter(|c| c.row.len > 1) {
            let force = c.force - c.matrix * row_value(points, c, v) / h;
            let couple = row_value(points, c, x).cross(&force) * h;
            let side = |entry: usize| points.row(c.row.points[entry] as usize).0.first().copied();
            if let (Some(a), Some(b)) = (side(0), side(c.row.len as usize - 1)) {
                visit(a, b, couple);
            }
        }
    }

    /// Counts per kind and the deepest penetration.
    pub fn stats(&self) -> ContactStats {
        let mut stats = ContactStats::default();
        for c in &self.contacts {
            match c.kind {
                ContactKind::Plane => stats.planes += 1,
                ContactKind::Mesh => stats.meshes += 1,
                ContactKind::Surface => stats.surface += 1,
                ContactKind::Edge => stats.edges += 1,
            }
            stats.max_penetration = stats.max_penetration.max(-c.depth);
        }
        stats
    }
}

impl MeshCollider {
    /// The closest point of the mesh to `q` within `radius` and the unit normal of its
    /// triangle (pointing to the allowed side).
    pub(crate) fn closest(&self, q: &Point3<Real>, radius: Real) -> Option<(Point3<Real>, Vector3<Real>)> {
        let r = Vector3::repeat(radius);
        let query = Aabb::new(to_parry(&(q - r)), to_parry(&(q + r)));
        let mut best: Option<(Real, Point3<Real>, usize)> = None;
        for t in self.bvh.intersect_aabb(&query) {
            let corners = self.triangles[t as usize].map(|k| self.vertices[k as usize]);
            let (c, _) = closest_point_on_triangle(q, &corners);
            let distance = (q - c).norm();
            if contact_normal(q, &c, &self.normals[t as usize], distance, LATERAL_FRACTION * self.reach).is_none() {
                continue;
            }
            if distance <= radius && best.is_none_or(|b| distance < b.0) {
                best = Some((distance, c, t as usize));
            }
        }
        best.and_then(|(distance, c, t)| {
            Some((c, contact_normal(q, &c, &self.normals[t], distance, LATERAL_FRACTION * self.reach)?))
        })
    }
}
