//! The contact structures of one topology and their per-step scratch: each surface point's ring,
//! the surface's pieces, edges and feature edges, pseudonormals, and the trees kept from one
//! epoch to the next (docs/math/contact.md §2, §5).

use crate::colliders::Colliders;
use crate::motion::{PieceMotion, RefitScratch, to_parry};
use crate::narrow::NearPair;
use crate::rows::Contact;
use cleave_core::{Embedding, Point3, Real, Vector3};
use cleave_geometry::closest_point_on_triangle;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy};
use rayon::prelude::*;

/// Where on a surface a triangle's nearest point lies ([`ContactSet::feature`]).
pub(crate) enum Feature {
    Face,
    /// A surface edge (index into `ContactSet::edges`).
    Edge(u32),
    /// A surface point.
    Corner(u32),
}

/// Per-epoch contact structures and per-step scratch.
#[derive(Default)]
pub struct ContactSet {
    pub(crate) contacts: Vec<Contact>,
    pub(crate) positions: Vec<Point3<Real>>,
    pub(crate) velocities: Vec<Vector3<Real>>,
    pub(crate) vertex_normals: Vec<Vector3<Real>>,
    pub(crate) triangle_normals: Vec<Vector3<Real>>,
    /// This step's `(b − a) × (c − a)` of every surface triangle.
    pub(crate) triangle_area_normals: Vec<Vector3<Real>>,
    /// One-ring of every surface point (CSR), itself included: pairs excluded by adjacency.
    pub(crate) ring_offsets: Vec<usize>,
    pub(crate) ring: Vec<u32>,
    /// Triangles around every surface point (CSR): the corner pseudonormals.
    pub(crate) vertex_triangle_offsets: Vec<usize>,
    pub(crate) vertex_triangles: Vec<u32>,
    /// Rest position of every surface point, and the connected component of the surface it
    /// belongs to (triangles sharing vertices).
    pub(crate) rest: Vec<Point3<Real>>,
    pub(crate) component: Vec<u32>,
    /// Points per component.
    pub(crate) component_points: Vec<u32>,
    /// This step's largest difference of two corners' velocities in each triangle.
    pub(crate) triangle_spread: Vec<Real>,
    /// This step's motion of each component, what the search is bounded by.
    pub(crate) motion: PieceMotion,
    /// Per point its position when its piece's whole-surface tree was last refit, and per
    /// piece the largest move of a point since (its tree's boxes loosened by it hold the
    /// triangles); which trees this step refits, and the per-range scratch.
    pub(crate) refit_positions: Vec<Point3<Real>>,
    pub(crate) staleness: Vec<Real>,
    pub(crate) refit_now: Vec<bool>,
    pub(crate) staleness_ranges: Vec<Real>,
    /// Per piece this step, `reach + h(|w_b| + s_b + τ_b)` (rounded up): with `h|u|` added, at
    /// least any point's search radius for the piece.
    pub(crate) loose_reach: Vec<Real>,
    /// Per piece this step (CSR), the other pieces near enough that one of its points or
    /// feature edges may reach them: what each point and edge searches.
    pub(crate) piece_candidate_offsets: Vec<usize>,
    pub(crate) piece_candidates: Vec<u32>,
    /// Bound the search by the mean velocities alone (ω = 0 for every piece): the bounds before
    /// the rigid fit, which find the same pairs (a test compares the two).
    pub(crate) ignore_turning: bool,
    /// Search every other piece from every point and edge (no pair filter): what the filter
    /// keeps, it must find the same pairs with (a test compares the two).
    pub(crate) search_every_piece: bool,
    /// Per surface component: its triangles, and those on a cut (indices into the surface's
    /// triangles), with a bounding volume hierarchy over each list (built at the first step of
    /// an epoch, refit every step).
    pub(crate) component_triangles: Vec<Vec<u32>>,
    pub(crate) component_cut_triangles: Vec<Vec<u32>>,
    pub(crate) bvh_all: Vec<Bvh>,
    pub(crate) bvh_cut: Vec<Bvh>,
    /// Per surface component: its triangle count and a hash of its triangles' rest corners in
    /// list order. A component of the next epoch with the same fingerprint is the same surface
    /// (a piece the cut did not touch) and takes this epoch's tree instead of building one.
    pub(crate) component_fingerprint: Vec<(usize, u64)>,
    /// Trees taken from the previous epoch for the components that match one of its own
    /// ([`ContactSet::reuse_trees`]), until the first detection refits them.
    pub(crate) reused_trees: Vec<Option<Bvh>>,
    /// This step's root box of every `bvh_all` tree: a query misses a piece
    /// whose root it misses, without setting up a traversal (most pieces are far from most
    /// points).
    pub(crate) roots_all: Vec<Aabb>,
    pub(crate) refit: RefitScratch,
    pub(crate) per_point: Vec<Option<Contact>>,
    /// Per surface point, the pair it found this step but did not activate (not predicted to
    /// close): [`ContactSet::activate_driven`] activates it when the step's solution closes it.
    pub(crate) near: Vec<Option<NearPair>>,
    /// Surface edges (point pairs), the triangles on either side, and the *feature* edges among
    /// them (where the faces meet at more than [`FEATURE_DIHEDRAL_COS`] at rest, or fewer or
    /// more than two faces meet): edge–edge contact searches from feature edges only.
    pub(crate) edges: Vec<[u32; 2]>,
    pub(crate) edge_faces: Vec<[u32; 2]>,
    /// Per triangle, the edge from its vertex `k` to vertex `k + 1` (for the edge pseudonormals).
    pub(crate) triangle_edges: Vec<[u32; 3]>,
    pub(crate) feature_edges: Vec<u32>,
    /// Per surface component its feature edges (indices into `edges`), with a bounding volume
    /// hierarchy over each list (built at the first step of an epoch, refit every step).
    pub(crate) component_feature_edges: Vec<Vec<u32>>,
    pub(crate) bvh_edges: Vec<Bvh>,
    pub(crate) per_edge: Vec<Option<Contact>>,
    /// Normal force of the last step per (collider, point): planes, then meshes, then the
    /// surface; what friction is proportional to.
    pub(crate) lagged: Vec<Real>,
    /// What the set was built from ([`ContactSet::built_for`]).
    pub(crate) built_from: (usize, usize, u64),
}

impl std::fmt::Debug for ContactSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ContactSet").field("contacts", &self.contacts.len()).finish()
    }
}

/// Edges whose faces meet at an angle with cosine below this at rest (about 26°) are feature
/// edges, searched for edge–edge contact: where faces meet flatter, the vertex–triangle
/// contacts of the faces around them keep surfaces apart.
pub(crate) const FEATURE_DIHEDRAL_COS: Real = 0.9;

impl ContactSet {
    /// Per-epoch structures: the one-ring, rest position and surface component of every point.
    pub fn new(colliders: &Colliders<'_>, rest_dofs: &[Real]) -> Self {
        let mut set = ContactSet::default();
        if let (Some(points), Some(surface)) = (colliders.points, colliders.surface) {
            set.rest = (0..points.len()).map(|i| points.point(rest_dofs, i)).collect();
            let mut sets = cleave_geometry::UnionFind::new(points.len());
            for t in &surface.triangles {
                sets.union(t[0] as usize, t[1] as usize);
                sets.union(t[0] as usize, t[2] as usize);
            }
            // The parts of one piece's surface are one component: a sheet a crack left inside a
            // piece lies inside the rest of its surface, which is not a contact (`SurfaceContact::piece`).
            // (The integrator refuses a piece list of another length than the triangles'.)
            if surface.piece.len() == surface.triangles.len() {
                let pieces = surface.piece.iter().max().map_or(0, |&p| p as usize + 1);
                let mut first_of_piece = vec![u32::MAX; pieces];
                for (t, &piece) in surface.triangles.iter().zip(&surface.piece) {
                    let first = &mut first_of_piece[piece as usize];
                    if *first == u32::MAX {
                        *first = t[0];
                    }
                    sets.union(*first as usize, t[0] as usize);
                }
            }
            let roots: Vec<u32> = (0..points.len()).map(|i| sets.find(i) as u32).collect();
            let mut compact = vec![u32::MAX; points.len()];
            let mut count = 0;
            set.component = roots
                .iter()
                .map(|&r| {
                    if compact[r as usize] == u32::MAX {
                        compact[r as usize] = count;
                        count += 1;
                    }
                    compact[r as usize]
                })
                .collect();
            set.component_points = vec![0; count as usize];
            for &c in &set.component {
                set.component_points[c as usize] += 1;
            }
            set.component_triangles = vec![Vec::new(); count as usize];
            set.component_cut_triangles = vec![Vec::new(); count as usize];
            for (t, tri) in surface.triangles.iter().enumerate() {
                let c = set.component[tri[0] as usize] as usize;
                set.component_triangles[c].push(t as u32);
                if surface.on_cut.get(t).copied().unwrap_or(false) {
                    set.component_cut_triangles[c].push(t as u32);
                }
            }
            set.component_fingerprint = set
                .component_triangles
                .par_iter()
                .map(|list| {
                    let hash = list.iter().flat_map(|&t| surface.triangles[t as usize]).fold(0u64, |hash, k| {
                        set.rest[k as usize]
                            .iter()
                            .fold(hash, |h, x| (h.rotate_left(5) ^ x.to_bits()).wrapping_mul(0x517c_c1b7_2722_0a95))
                    });
                    (list.len(), hash)
                })
                .collect();
            let both: Vec<bool> = (0..set.component_cut_triangles.len())
                .into_par_iter()
                .map(|c| set.holds_both_faces_of_a_cut(c, &surface.triangles))
                .collect();
            for (list, both) in set.component_cut_triangles.iter_mut().zip(both) {
                if !both {
                    list.clear();
                }
            }
            let mut counts = vec![0usize; points.len() + 1];
            for t in &surface.triangles {
                for &k in t {
                    counts[k as usize + 1] += 1;
                }
            }
            for k in 0..points.len() {
                counts[k + 1] += counts[k];
            }
            let mut fill = counts.clone();
            set.vertex_triangles = vec![0; counts[points.len()]];
            for (u, t) in surface.triangles.iter().enumerate() {
                for &k in t {
                    set.vertex_triangles[fill[k as usize]] = u as u32;
                    fill[k as usize] += 1;
                }
            }
            set.vertex_triangle_offsets = counts;
            // The one-ring from the triangles around each point, in parallel over blocks of
            // points (one list per block, not per point), then concatenated.
            let (offsets, around) = (&set.vertex_triangle_offsets, &set.vertex_triangles);
            let blocks: Vec<(Vec<u32>, Vec<usize>)> = (0..points.len())
                .collect::<Vec<_>>()
                .par_chunks(1024)
                .map(|block| {
                    let (mut rings, mut lengths) = (Vec::new(), Vec::with_capacity(block.len()));
                    let mut ring: Vec<u32> = Vec::with_capacity(32);
                    for &i in block {
                        ring.clear();
                        ring.push(i as u32);
                        ring.extend(
                            around[offsets[i]..offsets[i + 1]].iter().flat_map(|&t| surface.triangles[t as usize]),
                        );
                        ring.sort_unstable();
                        ring.dedup();
                        rings.extend_from_slice(&ring);
                        lengths.push(ring.len());
                    }
                    (rings, lengths)
                })
                .collect();
            set.ring_offsets.push(0);
            for (rings, lengths) in blocks {
                set.ring.extend_from_slice(&rings);
                for length in lengths {
                    let last = *set.ring_offsets.last().unwrap_or(&0);
                    set.ring_offsets.push(last + length);
                }
            }
            set.find_edges(&surface.triangles);
        }
        set.built_from = Self::key(colliders, rest_dofs);
        set
    }

    /// Whether this set was built from the same contact points, surface and rest positions
    /// (by their sizes and a hash of all that [`new`](Self::new) reads): a set built ahead for
    /// another topology must not be used for this one.
    pub fn built_for(&self, colliders: &Colliders<'_>, rest_dofs: &[Real]) -> bool {
        self.built_from == Self::key(colliders, rest_dofs)
    }

    fn key(colliders: &Colliders<'_>, rest_dofs: &[Real]) -> (usize, usize, u64) {
        use std::hash::{Hash, Hasher};
        // Without surface contact a set holds no structures ([`new`](Self::new) builds them
        // for the surface only): any two are alike, and nothing is hashed.
        if colliders.surface.is_none() {
            return (0, 0, 0);
        }
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        rest_dofs.iter().for_each(|x| x.to_bits().hash(&mut hasher));
        if let Some(points) = colliders.points {
            for i in 0..points.len() {
                let (nodes, weights) = points.row(i);
                nodes.hash(&mut hasher);
                weights.iter().for_each(|w| w.to_bits().hash(&mut hasher));
            }
        }
        if let Some(surface) = colliders.surface {
            surface.triangles.hash(&mut hasher);
            surface.on_cut.hash(&mut hasher);
            surface.piece.hash(&mut hasher);
        }
        (
            colliders.points.map_or(0, Embedding::len),
            colliders.surface.map_or(0, |s| s.triangles.len()),
            hasher.finish(),
        )
    }

    /// Forgets what steps left in the set (contacts, near pairs, lagged normal forces), keeping
    /// the structures of its topology: a set handed to a new epoch starts as one just built.
    pub fn forget_steps(&mut self) {
        self.contacts.clear();
        self.near.clear();
        self.lagged.clear();
    }

    /// This step's active contacts (found by [`detect`](Self::detect), extended by
    /// [`activate_driven`](Self::activate_driven)).
    pub fn contacts(&self) -> &[Contact] {
        &self.contacts
    }

    /// The one-ring of surface point `point`, itself included.
    pub fn ring(&self, point: u32) -> &[u32] {
        &self.ring[self.ring_offsets[point as usize]..self.ring_offsets[point as usize + 1]]
    }

    /// Takes the triangle trees of `previous` (the last epoch's set) for the components whose
    /// fingerprint matches one of its own: a cut leaves most pieces as they were, and building
    /// their trees again cost most of a cut step's contact search. A matching tree is correct
    /// whatever the match (the first detection refits every box from the new surface; a tree
    /// over as many leaves is valid for any of them), and as good as a new one when the
    /// triangles are the same.
    pub fn reuse_trees(&mut self, previous: ContactSet) {
        if previous.bvh_all.len() != previous.component_fingerprint.len() {
            return;
        }
        let mut trees: std::collections::HashMap<(usize, u64), Bvh> =
            previous.component_fingerprint.into_iter().zip(previous.bvh_all).collect();
        self.reused_trees = self.component_fingerprint.iter().map(|key| trees.remove(key)).collect();
    }

    /// Whether component `c` holds both faces of some cut: two of its cut triangles coincide in
    /// the rest shape with opposite normals (an unfinished cut, or a flap still attached). Only
    /// then can a point of the component meet the component's own cut faces; a component
    /// whose cuts went through has the other face in another component, and searching its
    /// own cut faces only visits coplanar neighbours (55 % of all candidates on bunny_slice).
    pub(crate) fn holds_both_faces_of_a_cut(&self, c: usize, triangles: &[[u32; 3]]) -> bool {
        let list = &self.component_cut_triangles[c];
        if list.len() < 2 {
            return false;
        }
        let corners = |t: u32| triangles[t as usize].map(|k| self.rest[k as usize]);
        let size = |[a, b, c]: [Point3<Real>; 3]| (b - a).norm().max((c - a).norm()).max((c - b).norm());
        let leaves: Vec<Aabb> = list
            .iter()
            .map(|&t| {
                let [a, b, c] = corners(t);
                let margin = Vector3::repeat(1e-9 * size([a, b, c]));
                Aabb::new(to_parry(&(a.inf(&b).inf(&c) - margin)), to_parry(&(a.sup(&b).sup(&c) + margin)))
            })
            .collect();
        let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves);
        list.iter().any(|&t| {
            let [a, b, c] = corners(t);
            let normal = (b - a).cross(&(c - a));
            let centroid = Point3::from((a.coords + b.coords + c.coords) / 3.0);
            let tolerance = 1e-9 * size([a, b, c]);
            let query = Aabb::new(
                to_parry(&(centroid - Vector3::repeat(tolerance))),
                to_parry(&(centroid + Vector3::repeat(tolerance))),
            );
            bvh.intersect_aabb(&query).any(|leaf| {
                let u = list[leaf as usize];
                let other = corners(u);
                let other_normal = (other[1] - other[0]).cross(&(other[2] - other[0]));
                u != t
                    && normal.dot(&other_normal) < 0.0
                    && (closest_point_on_triangle(&centroid, &other).0 - centroid).norm() <= tolerance
            })
        })
    }

    /// The other pieces this step's points and feature edges of `piece` search.
    pub(crate) fn candidate_pieces(&self, piece: usize) -> impl Iterator<Item = usize> + '_ {
        let range = self.piece_candidate_offsets[piece]..self.piece_candidate_offsets[piece + 1];
        self.piece_candidates[range].iter().map(|&b| b as usize)
    }

    /// The surface's edges, their faces, each triangle's edges and the feature edges.
    pub(crate) fn find_edges(&mut self, triangles: &[[u32; 3]]) {
        // Every side of every triangle as (lower point, higher point, triangle, side), sorted:
        // the sides of one edge are consecutive.
        let mut sides: Vec<(u32, u32, u32, u8)> = triangles
            .par_iter()
            .enumerate()
            .flat_map_iter(|(t, tri)| {
                (0..3).map(move |k| (tri[k].min(tri[(k + 1) % 3]), tri[k].max(tri[(k + 1) % 3]), t as u32, k as u8))
            })
            .collect();
        sides.par_sort_unstable();
        let mut starts: Vec<usize> = (0..sides.len())
            .filter(|&i| i == 0 || (sides[i - 1].0, sides[i - 1].1) != (sides[i].0, sides[i].1))
            .collect();
        starts.push(sides.len());
        let rest_normal = |t: u32| {
            let [a, b, c] = triangles[t as usize].map(|k| self.rest[k as usize]);
            (b - a).cross(&(c - a)).try_normalize(0.0)
        };
        let feature: Vec<bool> = starts
            .par_windows(2)
            .map(|w| {
                let group = &sides[w[0]..w[1]];
                group.len() != 2
                    || match (rest_normal(group[0].2), rest_normal(group[1].2)) {
                        (Some(n0), Some(n1)) => n0.dot(&n1) < FEATURE_DIHEDRAL_COS,
                        _ => false,
                    }
            })
            .collect();
        self.triangle_edges = vec![[0; 3]; triangles.len()];
        for (w, feature) in starts.windows(2).zip(feature) {
            let group = &sides[w[0]..w[1]];
            let e = self.edges.len() as u32;
            for &(_, _, t, k) in group {
                self.triangle_edges[t as usize][k as usize] = e;
            }
            if feature {
                self.feature_edges.push(e);
            }
            self.edges.push([group[0].0, group[0].1]);
            self.edge_faces.push([group[0].2, group.get(1).map_or(group[0].2, |g| g.2)]);
        }
        self.component_feature_edges = vec![Vec::new(); self.component_points.len()];
        for &e in &self.feature_edges {
            self.component_feature_edges[self.component[self.edges[e as usize][0] as usize] as usize].push(e);
        }
    }

    /// Whether point `i` lies behind triangle `tri` (at barycentric `beta`) in the rest shape.
    /// Nothing overlaps at rest, so such a pair of one surface is not a contact but a point
    /// beside an obtuse convex edge seen from the face across it; the two faces of a cut
    /// coincide at rest (gap 0) and stay candidates.
    pub(crate) fn behind_at_rest(&self, i: usize, tri: &[u32; 3], beta: &[Real; 3]) -> bool {
        let [a, b, c] = tri.map(|k| self.rest[k as usize]);
        let normal = (b - a).cross(&(c - a));
        let scale = normal.norm();
        if scale == 0.0 {
            return false;
        }
        let on = Point3::from(a.coords * beta[0] + b.coords * beta[1] + c.coords * beta[2]);
        normal.dot(&(self.rest[i] - on)) / scale < -1e-9 * (b - a).norm().max((c - a).norm())
    }

    /// The angle-weighted pseudonormal (not normalized) of the feature of triangle `t` that
    /// holds its point at barycentrics `beta`: the triangle's normal inside it, the sum of the
    /// two faces' normals on an edge, the angle-weighted vertex normal at a corner. Its sign
    /// against `q − c`, with `c` the nearest surface point, tells whether `q` lies inside a
    /// closed surface (Bærentzen & Aanæs 2005).
    pub(crate) fn pseudonormal(&self, triangles: &[[u32; 3]], t: usize, beta: &[Real; 3]) -> Vector3<Real> {
        match self.feature(triangles, t, beta) {
            Feature::Face => self.triangle_normals[t],
            Feature::Edge(e) => {
                let [f0, f1] = self.edge_faces[e as usize];
                self.triangle_normals[f0 as usize] + self.triangle_normals[f1 as usize]
            }
            // Weighted by each triangle's angle at the corner (area weights are not exact here);
            // computed only for the rare point whose nearest feature is a corner.
            Feature::Corner(corner) => self.triangles_around(corner).iter().fold(Vector3::zeros(), |sum, &u| {
                let around = &triangles[u as usize];
                let k = (0..3).find(|&k| around[k] == corner).unwrap_or(0);
                let p = around.map(|i| self.positions[i as usize]);
                let (e1, e2) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                sum + self.triangle_normals[u as usize] * e1.cross(&e2).norm().atan2(e1.dot(&e2))
            }),
        }
    }

    /// The feature of triangle `t` that holds its point at barycentrics `beta`: the triangle
    /// itself (no zero weight), the surface edge opposite the one zero weight, or the corner
    /// of the largest weight (two zero weights).
    pub(crate) fn feature(&self, triangles: &[[u32; 3]], t: usize, beta: &[Real; 3]) -> Feature {
        match beta.iter().filter(|&&b| b == 0.0).count() {
            0 => Feature::Face,
            // On the edge from vertex k to k + 1, opposite the zero weight.
            1 => Feature::Edge(self.triangle_edges[t][(0..3).find(|&k| beta[(k + 2) % 3] == 0.0).unwrap_or(0)]),
            _ => Feature::Corner(triangles[t][(0..3).max_by(|&a, &b| beta[a].total_cmp(&beta[b])).unwrap_or(0)]),
        }
    }

    /// The triangles around surface point `corner`.
    pub(crate) fn triangles_around(&self, corner: u32) -> &[u32] {
        &self.vertex_triangles
            [self.vertex_triangle_offsets[corner as usize]..self.vertex_triangle_offsets[corner as usize + 1]]
    }

    /// The triangles at the feature of triangle `t` that holds its point at barycentrics
    /// `beta` ([`Self::feature`]), in index order: `t` inside it, the faces of an edge, every
    /// triangle around a corner.
    pub(crate) fn feature_triangles(&self, triangles: &[[u32; 3]], t: usize, beta: &[Real; 3], out: &mut Vec<u32>) {
        out.clear();
        match self.feature(triangles, t, beta) {
            Feature::Face => {}
            Feature::Edge(e) => out.extend(self.edge_faces[e as usize]),
            Feature::Corner(corner) => out.extend_from_slice(self.triangles_around(corner)),
        }
        // (At an edge of more than two faces `edge_faces` holds two of them: `t` is always one.)
        out.push(t as u32);
        out.sort_unstable();
        out.dedup();
    }

    pub(crate) fn excluded(&self, point: u32, triangle: &[u32; 3]) -> bool {
        let ring = &self.ring[self.ring_offsets[point as usize]..self.ring_offsets[point as usize + 1]];
        // The triangle contains the point or a neighbour of it: a neighbouring triangle's vertex.
        triangle.iter().any(|v| ring.binary_search(v).is_ok())
    }
}
