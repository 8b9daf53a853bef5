//! Sliver merging (kaufmann2008 §10): elements of a [`PolyhedralMesh`] below a volume threshold
//! are merged into the face-adjacent neighbour they share the most face area with. See
//! `docs/math/hex-slicing.md` §6.

use std::cmp::{Ordering, Reverse};
use std::collections::{BTreeMap, BinaryHeap};

use crate::moments::{Frame, try_element_moments_from_faces};
use crate::{GeometryError, PolyhedralMesh};

/// What [`merge_small_elements`] did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MergeReport {
    /// The volume threshold: elements with a smaller volume were merged.
    pub threshold: f64,
    /// Number of elements of the input mesh.
    pub elements_before: usize,
    /// Number of elements of the output mesh.
    pub elements_after: usize,
    /// Number of merges performed (`elements_before − elements_after`).
    pub merges: usize,
    /// Smallest element volume of the input mesh (`+∞` without elements).
    pub min_volume_before: f64,
    /// Smallest element volume of the output mesh (`+∞` without elements).
    pub min_volume_after: f64,
    /// Elements below the threshold that were kept because they have no face-adjacent
    /// neighbour (isolated pieces of the solid).
    pub isolated_small: usize,
    /// `element_map[e]`: the output element that input element `e` is now part of.
    pub element_map: Vec<u32>,
    /// `survivors[k]`: the input element that output element `k` grew from (the one the
    /// others were merged into, directly or through a chain; `element_map[survivors[k]] == k`).
    pub survivors: Vec<u32>,
}

/// A small element waiting to be merged, ordered by volume, then index (so the order is
/// deterministic when volumes tie).
#[derive(Debug, Clone, Copy)]
struct Candidate {
    volume: f64,
    element: u32,
}

impl PartialEq for Candidate {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Candidate {}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> Ordering {
        self.volume.total_cmp(&other.volume).then(self.element.cmp(&other.element))
    }
}

/// Merges every element whose volume is below `min_volume` into a face-adjacent neighbour
/// (kaufmann2008 §10, "sliver merging"), in place.
///
/// Small elements are taken in ascending order of their *current* volume (ties: lower index
/// first). Each merges into the neighbour with which it shares the largest total face area,
/// summed over all faces between the two (ties: lower index), whatever that neighbour's size —
/// a sliver whose neighbours are all small still joins the one it is best attached to, and the
/// result is re-queued while it stays below the threshold. An element without neighbours is
/// an isolated piece of the solid: it is kept and counted in
/// [`MergeReport::isolated_small`].
///
/// Merging `A` into `B` deletes the faces between `A` and `B` and gives `A`'s other faces `B`
/// as their `inner` or `outer` element. A face's normal points out of `inner`, so it still
/// points out of the merged element and no polygon is reversed; the merged boundary stays
/// closed and outward because each edge of a deleted face was matched, in `A` and in `B`, by
/// faces that remain. The merged element may be non-convex and may have several faces to the
/// same neighbour. Surviving elements keep their relative order and are numbered densely;
/// vertices are kept (some may no longer be used by any face).
///
/// Volumes come from the exact moments of the input elements and are summed on merging, so the
/// total volume is unchanged. The input should pass [`PolyhedralMesh::validate`].
///
/// Errors: [`GeometryError::InvalidMergeThreshold`] for a negative, infinite or NaN
/// `min_volume`; [`GeometryError::FaceElementOutOfRange`] and
/// [`GeometryError::FaceVertexOutOfRange`] for bad indices (the mesh is then unchanged).
pub fn merge_small_elements(mesh: &mut PolyhedralMesh, min_volume: f64) -> Result<MergeReport, GeometryError> {
    if !(min_volume.is_finite() && min_volume >= 0.0) {
        return Err(GeometryError::InvalidMergeThreshold { threshold: min_volume });
    }
    let n = mesh.num_elements;
    for (face, f) in mesh.faces.iter().enumerate() {
        if let Some(element) = [Some(f.inner), f.outer].into_iter().flatten().find(|&e| e as usize >= n) {
            return Err(GeometryError::FaceElementOutOfRange { face, element, num_elements: n });
        }
        if let Some(&index) = f.polygon.iter().find(|&&v| v as usize >= mesh.vertices.len()) {
            return Err(GeometryError::FaceVertexOutOfRange { face, index, vertex_count: mesh.vertices.len() });
        }
    }

    let mut volume = element_volumes(mesh)?;
    let min_volume_before = volume.iter().copied().fold(f64::INFINITY, f64::min);

    // Shared face area per neighbour; BTreeMap so that ties and sums are deterministic.
    let mut shared: Vec<BTreeMap<u32, f64>> = vec![BTreeMap::new(); n];
    for f in &mesh.faces {
        if let Some(outer) = f.outer.filter(|&o| o != f.inner) {
            let area = mesh.polygon_area(&f.polygon);
            *shared[f.inner as usize].entry(outer).or_default() += area;
            *shared[outer as usize].entry(f.inner).or_default() += area;
        }
    }

    // merged_into[e] == e for survivors; otherwise the element e was merged into (a forest
    // whose roots are the survivors).
    let mut merged_into: Vec<u32> = (0..n as u32).collect();
    let mut isolated = vec![false; n];
    let mut queue: BinaryHeap<Reverse<Candidate>> = (0..n)
        .filter(|&e| volume[e] < min_volume)
        .map(|e| Reverse(Candidate { volume: volume[e], element: e as u32 }))
        .collect();
    let mut merges = 0;
    while let Some(Reverse(Candidate { volume: v, element: a })) = queue.pop() {
        let ai = a as usize;
        // Stale entries: merged away, already found isolated, or grown since queued.
        if merged_into[ai] != a || isolated[ai] || v.total_cmp(&volume[ai]) != Ordering::Equal {
            continue;
        }
        let Some(b) = best_neighbour(&shared[ai]) else {
            isolated[ai] = true;
            continue;
        };
        let bi = b as usize;
        merged_into[ai] = b;
        volume[bi] += volume[ai];
        merges += 1;
        let neighbours = std::mem::take(&mut shared[ai]);
        for (&c, &area) in &neighbours {
            let ci = c as usize;
            shared[ci].remove(&a);
            if c != b {
                *shared[bi].entry(c).or_default() += area;
                *shared[ci].entry(b).or_default() += area;
            }
        }
        shared[bi].remove(&a);
        if volume[bi] < min_volume {
            queue.push(Reverse(Candidate { volume: volume[bi], element: b }));
        }
    }

    // Dense numbering of the survivors in their original order, then every element's root.
    let survivors: Vec<u32> = (0..n as u32).filter(|&e| merged_into[e as usize] == e).collect();
    let mut new_index = vec![u32::MAX; n];
    for (k, &e) in survivors.iter().enumerate() {
        new_index[e as usize] = k as u32;
    }
    let element_map: Vec<u32> = (0..n)
        .map(|e| {
            let mut r = e;
            while merged_into[r] != r as u32 {
                r = merged_into[r] as usize;
            }
            new_index[r]
        })
        .collect();
    mesh.faces.retain_mut(|f| {
        f.inner = element_map[f.inner as usize];
        f.outer = f.outer.map(|o| element_map[o as usize]);
        f.outer != Some(f.inner)
    });
    mesh.num_elements = survivors.len();
    let min_volume_after = survivors.iter().map(|&e| volume[e as usize]).fold(f64::INFINITY, f64::min);
    Ok(MergeReport {
        threshold: min_volume,
        elements_before: n,
        elements_after: survivors.len(),
        merges,
        min_volume_before,
        min_volume_after,
        isolated_small: isolated.iter().filter(|&&i| i).count(),
        element_map,
        survivors,
    })
}

/// The neighbour with the largest shared area (lowest index among equals).
fn best_neighbour(shared: &BTreeMap<u32, f64>) -> Option<u32> {
    // BTreeMap iterates in ascending index; `max_by` keeps the last of equal maxima, so
    // iterate in reverse to keep the lowest index.
    shared.iter().rev().max_by(|x, y| x.1.total_cmp(y.1)).map(|(&e, _)| e)
}

/// Volume of every element by the divergence theorem (exact moments of degree 0).
fn element_volumes(mesh: &PolyhedralMesh) -> Result<Vec<f64>, GeometryError> {
    let mut moments = Vec::with_capacity(1);
    mesh.element_faces()
        .iter()
        .map(|faces| {
            if faces.is_empty() {
                return Ok(0.0);
            }
            let frame =
                Frame::bounding(faces.iter().flat_map(|f| f.polygon.iter()).map(|&v| mesh.vertices[v as usize]));
            try_element_moments_from_faces(mesh, faces, &frame, 0, &mut moments)?;
            Ok(moments[0])
        })
        .collect()
}
