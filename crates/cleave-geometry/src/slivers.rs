//! Sliver repair of a closed triangle surface: vertices and edges shorter than a tolerance
//! merged, T-junctions within it split, and caps (a corner within the tolerance of its opposite
//! edge) removed by flipping that edge, so the surface has no triangle of (near) zero area and
//! is closed
//! (docs/math/virtual-node.md, §1 item 7, "Slivers of the render surface").
//!
//! A surface cut by planes and soups meets lattice planes, source triangles and other cuts at
//! arbitrary distances: points computed twice in floating point land 1e-9 apart, and a cut
//! passing 1e-7 from a lattice plane leaves a polygon that thin. Drawn as they are, such
//! triangles have no usable normal (contact's pseudonormals) and collapse or fold when a reader
//! rounds positions (an f32 recording). Each repair moves the surface by at most the tolerance.

use crate::UnionFind;
use nalgebra::Point3;
/// A hash map with a fixed fast hasher: keys are vertex indices and grid cells, and the result
/// must not depend on a random seed.
type HashMap<K, V> = std::collections::HashMap<K, V, foldhash::fast::FixedState>;

/// What [`repair_slivers`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SliverRepair {
    /// Vertices merged into another across an edge shorter than the tolerance.
    pub collapsed: usize,
    /// Triangles dropped (collapsed, or a pair that cancelled).
    pub dropped: usize,
    /// Edges flipped to remove a cap.
    pub flipped: usize,
    /// Triangles split where an open edge had vertices within the tolerance of it (a
    /// T-junction the surface's maker missed).
    pub split: usize,
    /// Slivers left (a flip that would make the surface non-manifold is not made).
    pub left: usize,
}

/// Whether triangle `t` is a sliver at `tolerance`: an edge shorter than it, or a corner nearer
/// than it to the line of its opposite edge. Returns the corner opposite the longest edge
/// (0, 1 or 2) for a cap, `None` otherwise or when the triangle is fine.
fn sliver(positions: &[Point3<f64>], t: &[u32; 3], tolerance: f64) -> Option<Option<usize>> {
    let p = t.map(|i| positions[i as usize]);
    let edges = [(p[2] - p[1]).norm(), (p[0] - p[2]).norm(), (p[1] - p[0]).norm()];
    let shortest = edges.iter().copied().fold(f64::INFINITY, f64::min);
    if shortest < tolerance {
        return Some(None);
    }
    let (corner, longest) =
        edges.iter().copied().enumerate().fold((0, 0.0), |m, (k, e)| if e > m.1 { (k, e) } else { m });
    let double_area = (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
    (double_area < tolerance * longest).then_some(Some(corner))
}

/// Repairs the slivers of a closed, consistently oriented triangle surface in place (see the
/// module doc): first every two vertices nearer than `tolerance` are merged into the
/// lower-numbered one, every open edge with vertices of other open edges within
/// `junction_tolerance` of it is split at them (a T-junction the maker missed; the surface is
/// not moved, only joined where its maker's two computations of one curve disagree), every
/// edge shorter than `tolerance` is collapsed (triangles left with a repeated corner are
/// dropped, and so are pairs of triangles on the same corners with opposite orientations,
/// which cancel), then every cap (corner `a`
/// nearer than `tolerance` to the line of its opposite edge `bc`) is removed by flipping `bc`
/// with the triangle `cbd` across it: `abc`, `cbd` become `abd`, `adc`, which take the tag of
/// `cbd` (the cap had no area of its own). Vertices collapsed away are no longer used; the
/// caller compacts. `tags` holds one value per triangle and follows the triangles.
///
/// `same_point(u, v, joined)` says whether two vertices may be merged (the same material
/// point: not the two sides of a crack at one position); `joined` says whether an edge of a
/// triangle joins them (else they are only near). Short edges between vertices it refuses
/// are left, and counted in [`SliverRepair::left`]. Deterministic: the result depends only on
/// the input's order.
pub fn repair_slivers<T: Copy>(
    positions: &[Point3<f64>],
    triangles: &mut Vec<[u32; 3]>,
    tags: &mut Vec<T>,
    tolerance: f64,
    junction_tolerance: f64,
    same_point: impl Fn(u32, u32, bool) -> bool,
) -> SliverRepair {
    let mut report = SliverRepair::default();
    // Vertices nearer than the tolerance merged (also where no edge joins them: a point
    // computed twice whose copies each close their own triangles leaves a crack as wide as
    // their distance), then short edges collapsed.
    let mut sets = UnionFind::new(positions.len());
    // Per grid cell (of the tolerance's size) the last vertex put in it; `next` chains each
    // vertex to the one put in its cell before it.
    let mut grid: HashMap<[i64; 3], u32> = HashMap::default();
    let mut next = vec![u32::MAX; positions.len()];
    let cell = |p: &Point3<f64>| p.coords.map(|c| (c / tolerance).floor() as i64);
    let mut used = vec![false; positions.len()];
    for t in triangles.iter() {
        for &v in t {
            used[v as usize] = true;
        }
    }
    for (v, p) in positions.iter().enumerate().filter(|(v, _)| used[*v]) {
        let key = cell(p);
        for i in -1..=1 {
            for j in -1..=1 {
                for k in -1..=1 {
                    let mut slot = grid.get(&[key.x + i, key.y + j, key.z + k]).copied();
                    while let Some(u) = slot.filter(|&u| u != u32::MAX) {
                        if (positions[u as usize] - p).norm() < tolerance
                            && same_point(u, v as u32, false)
                            && sets.union(u as usize, v)
                        {
                            report.collapsed += 1;
                        }
                        slot = Some(next[u as usize]);
                    }
                }
            }
        }
        next[v] = grid.insert([key.x, key.y, key.z], v as u32).unwrap_or(u32::MAX);
    }
    report.split = split_t_junctions(positions, triangles, tags, junction_tolerance, &mut sets);
    if report.collapsed == 0
        && report.split == 0
        && !triangles.iter().any(|t| sliver(positions, t, tolerance).is_some())
    {
        return report;
    }
    for t in triangles.iter() {
        for k in 0..3 {
            let (u, v) = (t[k], t[(k + 1) % 3]);
            if (positions[u as usize] - positions[v as usize]).norm() < tolerance
                && same_point(u, v, true)
                && sets.union(u as usize, v as usize)
            {
                report.collapsed += 1;
            }
        }
    }
    let before = triangles.len();
    let mut kept = Vec::with_capacity(before);
    let mut kept_tags = Vec::with_capacity(before);
    for (t, tag) in triangles.iter().zip(tags.iter()) {
        let t = t.map(|v| sets.find(v as usize) as u32);
        if t[0] != t[1] && t[1] != t[2] && t[2] != t[0] {
            kept.push(t);
            kept_tags.push(*tag);
        }
    }
    // Pairs on the same corners with opposite orientations cancel (a fold the collapse made).
    let mut by_corners: HashMap<[u32; 3], Vec<usize>> = HashMap::default();
    for (i, t) in kept.iter().enumerate() {
        let mut key = *t;
        key.sort_unstable();
        by_corners.entry(key).or_default().push(i);
    }
    let mut drop = vec![false; kept.len()];
    let mut groups: Vec<&Vec<usize>> = by_corners.values().filter(|g| g.len() > 1).collect();
    groups.sort_unstable();
    for group in groups {
        let parity = |t: &[u32; 3]| {
            let m = (0..3).min_by_key(|&k| t[k]).expect("three corners");
            t[(m + 1) % 3] < t[(m + 2) % 3]
        };
        let (mut up, mut down): (Vec<usize>, Vec<usize>) = group.iter().partition(|&&i| parity(&kept[i]));
        while let (Some(a), Some(b)) = (up.pop(), down.pop()) {
            drop[a] = true;
            drop[b] = true;
        }
    }
    *triangles = kept.iter().zip(&drop).filter(|(_, d)| !**d).map(|(t, _)| *t).collect();
    *tags = kept_tags.iter().zip(&drop).filter(|(_, d)| !**d).map(|(t, _)| *t).collect();
    report.dropped = before - triangles.len();
    // Caps flipped away, in triangle order, until none can be.
    let mut directed: HashMap<(u32, u32), usize> =
        HashMap::with_capacity_and_hasher(3 * triangles.len(), Default::default());
    for (i, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            directed.insert((t[k], t[(k + 1) % 3]), i);
        }
    }
    for _pass in 0..4 {
        let mut flipped = 0;
        for i in 0..triangles.len() {
            let Some(Some(corner)) = sliver(positions, &triangles[i], tolerance) else { continue };
            let t = triangles[i];
            let (a, b, c) = (t[corner], t[(corner + 1) % 3], t[(corner + 2) % 3]);
            let Some(&j) = directed.get(&(c, b)) else { continue };
            let n = triangles[j];
            let d = n[(0..3).find(|&k| n[k] != b && n[k] != c).expect("a triangle has a third corner")];
            if d == a || directed.contains_key(&(a, d)) || directed.contains_key(&(d, a)) {
                continue;
            }
            for k in 0..3 {
                directed.remove(&(t[k], t[(k + 1) % 3]));
                directed.remove(&(n[k], n[(k + 1) % 3]));
            }
            triangles[i] = [a, b, d];
            triangles[j] = [a, d, c];
            tags[i] = tags[j];
            for (index, t) in [(i, triangles[i]), (j, triangles[j])] {
                for k in 0..3 {
                    directed.insert((t[k], t[(k + 1) % 3]), index);
                }
            }
            flipped += 1;
        }
        report.flipped += flipped;
        if flipped == 0 {
            break;
        }
    }
    report.left = triangles.iter().filter(|t| sliver(positions, t, tolerance).is_some()).count();
    report
}

/// Splits every triangle whose edge `uv` is open (its reverse `vu` is used by no triangle) and
/// has corners of other open edges within `tolerance` of it, strictly between `u` and `v`: the
/// triangle `uvx` becomes the fan `u w₁ x`, `w₁ w₂ x`, …, `w_k v x`. Vertices are compared
/// through `sets` (the merges made so far). Returns how many triangles were split.
fn split_t_junctions<T: Copy>(
    positions: &[Point3<f64>],
    triangles: &mut Vec<[u32; 3]>,
    tags: &mut Vec<T>,
    tolerance: f64,
    sets: &mut UnionFind,
) -> usize {
    let root = |sets: &mut UnionFind, v: u32| sets.find(v as usize) as u32;
    let mut directed: HashMap<(u32, u32), usize> = HashMap::default();
    for t in triangles.iter() {
        let t = t.map(|v| root(sets, v));
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    let open: Vec<(u32, u32)> = {
        let mut open: Vec<(u32, u32)> =
            directed.keys().copied().filter(|&(u, v)| u != v && !directed.contains_key(&(v, u))).collect();
        open.sort_unstable();
        open
    };
    if open.is_empty() {
        return 0;
    }
    let mut candidates: Vec<u32> = open.iter().flat_map(|&(u, v)| [u, v]).collect();
    candidates.sort_unstable();
    candidates.dedup();
    let mut split = 0;
    let count = triangles.len();
    for i in 0..count {
        let t = triangles[i].map(|v| root(sets, v));
        for k in 0..3 {
            let (u, v, x) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            if open.binary_search(&(u, v)).is_err() {
                continue;
            }
            let (a, b) = (positions[u as usize], positions[v as usize]);
            let d = b - a;
            let length = d.norm();
            let mut between: Vec<(f64, u32)> = candidates
                .iter()
                .filter(|&&w| w != u && w != v && w != x)
                .filter_map(|&w| {
                    let s = (positions[w as usize] - a).dot(&d) / (length * length);
                    let off = (positions[w as usize] - (a + d * s)).norm();
                    (s * length > tolerance && (1.0 - s) * length > tolerance && off <= tolerance).then_some((s, w))
                })
                .collect();
            if between.is_empty() {
                continue;
            }
            between.sort_by(|p, q| p.0.total_cmp(&q.0));
            let mut chain = vec![u];
            chain.extend(between.iter().map(|&(_, w)| w));
            chain.push(v);
            triangles[i] = [chain[0], chain[1], x];
            for w in chain[1..].windows(2) {
                triangles.push([w[0], w[1], x]);
                tags.push(tags[i]);
            }
            split += 1;
            break;
        }
    }
    split
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Edges of `triangles` not matched by their reverse exactly once.
    fn open_edges(triangles: &[[u32; 3]]) -> usize {
        let mut directed: HashMap<(u32, u32), i32> = HashMap::default();
        for t in triangles {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        directed.iter().filter(|((u, v), n)| **n != 1 || directed.get(&(*v, *u)) != Some(&1)).count()
    }

    fn volume(positions: &[Point3<f64>], triangles: &[[u32; 3]]) -> f64 {
        triangles
            .iter()
            .map(|t| {
                let p = t.map(|i| positions[i as usize].coords);
                p[0].dot(&p[1].cross(&p[2])) / 6.0
            })
            .sum()
    }

    /// A unit tetrahedron 0–1–2–3 whose bottom (z = 0) is split at vertex 4, which lies 1e-9
    /// inside the edge 0–1: the bottom is 0–2–4, 4–2–1 and the cap 0–4–1, and the side y = 0
    /// is one triangle 0–1–3 that does not know vertex 4.
    fn tetrahedron_with_a_cap() -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        let positions = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
            Point3::new(0.5, 1e-9, 0.0),
        ];
        let triangles = vec![[0, 2, 4], [4, 2, 1], [0, 1, 3], [0, 4, 1], [0, 3, 2], [1, 2, 3]];
        (positions, triangles)
    }

    #[test]
    fn a_cap_is_flipped_away_and_the_surface_stays_closed_with_its_volume() {
        let (positions, mut triangles) = tetrahedron_with_a_cap();
        assert_eq!(open_edges(&triangles), 0);
        assert!(sliver(&positions, &triangles[3], 1e-6).is_some());
        let mut tags: Vec<usize> = (0..triangles.len()).collect();
        let report = repair_slivers(&positions, &mut triangles, &mut tags, 1e-6, 1e-6, |_, _, _| true);
        // The cap 0–4–1 and the side 0–1–3 became 4–1–3 and 4–3–0, both of the side's tag.
        assert_eq!(report, SliverRepair { collapsed: 0, dropped: 0, flipped: 1, split: 0, left: 0 });
        assert_eq!(open_edges(&triangles), 0);
        assert_eq!((triangles[3], tags[3]), ([4, 1, 3], 2));
        assert_eq!((triangles[2], tags[2]), ([4, 3, 0], 2));
        // The flip moved the side by the cap's height: the volume by at most 1e-9 of it.
        assert!((volume(&positions, &triangles) - 1.0 / 6.0).abs() < 1e-9);
    }

    #[test]
    fn a_t_junction_within_the_tolerance_is_split_and_the_surface_closes() {
        // The tetrahedron whose side y = 0 knows vertex 4 (0–4–3, 4–1–3) while the bottom is
        // one triangle 0–2–1 that does not: vertex 4 lies 1e-9 off the bottom's edge 1–0.
        let (positions, _) = tetrahedron_with_a_cap();
        let mut triangles = vec![[0, 2, 1], [0, 4, 3], [4, 1, 3], [0, 3, 2], [1, 2, 3]];
        assert_eq!(open_edges(&triangles), 3);
        let mut tags: Vec<usize> = (0..triangles.len()).collect();
        let report = repair_slivers(&positions, &mut triangles, &mut tags, 1e-6, 1e-6, |_, _, _| true);
        assert_eq!(report.split, 1, "{report:?}");
        assert_eq!(open_edges(&triangles), 0, "{triangles:?}");
        assert_eq!((triangles.len(), tags[5]), (6, 0));
        assert!((volume(&positions, &triangles) - 1.0 / 6.0).abs() < 1e-9);
    }

    #[test]
    fn a_short_edge_is_collapsed_unless_its_ends_are_two_material_points() {
        // The tetrahedron with corner 3 doubled 1e-10 away as vertex 5: the faces x = 0 and the
        // slanted one use 5, the side y = 0 uses 3, and two slivers 0–3–5, 1–5–3 close the seam.
        let mut positions = tetrahedron_with_a_cap().0;
        positions.push(Point3::new(0.0, 1e-10, 1.0));
        let mut triangles = vec![[0, 2, 1], [0, 1, 3], [0, 5, 2], [1, 2, 5], [0, 3, 5], [1, 5, 3]];
        assert_eq!(open_edges(&triangles), 0);
        let mut tags = vec![0u8; triangles.len()];
        let refused =
            repair_slivers(&positions, &mut triangles.clone(), &mut tags.clone(), 1e-6, 1e-6, |_, _, _| false);
        assert_eq!((refused.collapsed, refused.left), (0, 2), "{refused:?}");
        let report = repair_slivers(&positions, &mut triangles, &mut tags, 1e-6, 1e-6, |_, _, _| true);
        assert_eq!((report.collapsed, report.dropped, report.left), (1, 2, 0), "{report:?}");
        assert_eq!(triangles.len(), 4);
        assert_eq!(open_edges(&triangles), 0);
        assert!((volume(&positions, &triangles) - 1.0 / 6.0).abs() < 1e-9);
    }
}
