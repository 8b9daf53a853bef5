//! How contacts enter the assembled system: the node groups its pattern still lacks for this
//! step's contact rows, and their blocks `(w wᵀ) ⊗ P` added to its values. Each contact is a row
//! `w` over nodes with a 3×3 `P` (`cleave_contact::Contact`, docs/math/contact.md §1); forces,
//! action, diagonal and energy are `cleave_contact`'s.

use cleave_contact::{Contact, ContactSet, for_each_entry};
use cleave_core::{AssemblyPattern, Embedding, Real};
use rayon::prelude::*;

/// [`add_matrix`]'s scratch, kept across steps: per contact its merged (node, weight) entries,
/// one entry per node (offsets and entries, CSR). Behind a lock because the matrix is filled
/// where only shared borrows reach.
#[derive(Debug, Default)]
pub(crate) struct MatrixScratch(std::sync::Mutex<MergedEntries>);

/// Offsets and `(node, weight)` entries (CSR).
type MergedEntries = (Vec<usize>, Vec<(u32, Real)>);

/// The node groups of this step's contact rows whose couplings the pattern lacks (a point and
/// a triangle, or two edges, of the body's surface that were never in contact before in this
/// epoch). Each group is the nodes of the row's points *and of the points around them*, so
/// that a point sliding on to a neighbouring triangle needs no new pattern.
pub(crate) fn missing_couplings(points: &Embedding, set: &ContactSet, pattern: &AssemblyPattern) -> Vec<Vec<u32>> {
    // Checked in parallel over the contacts, each row's nodes once (the corners of a triangle
    // mostly share a duplicate's nodes); the groups in contact order.
    set.contacts()
        .par_iter()
        .filter(|c| c.row.len > 1)
        .map_init(
            || Vec::with_capacity(16),
            |nodes: &mut Vec<u32>, c| {
                nodes.clear();
                for_each_entry(points, c, |n, _| nodes.push(n));
                nodes.sort_unstable();
                nodes.dedup();
                if !nodes.iter().any(|&j| nodes.iter().any(|&i| pattern.rank(i, j).is_none())) {
                    return None;
                }
                let mut group = Vec::new();
                for (v, _) in c.row.entries() {
                    for &around in set.ring(v) {
                        group.extend_from_slice(points.row(around as usize).0);
                    }
                }
                group.sort_unstable();
                group.dedup();
                Some(group)
            },
        )
        .flatten()
        .collect()
}

/// Adds `(w wᵀ) ⊗ P` of every contact to the assembled matrix, whose pattern holds every
/// contact row's couplings (see [`missing_couplings`]). In parallel over [`COLUMN_RANGES`]
/// ranges of column nodes ([`AssemblyPattern::for_column_ranges`]): each task writes the blocks
/// of every contact whose column node is its own.
pub(crate) fn add_matrix(
    points: &Embedding,
    contacts: &[Contact],
    scratch: &MatrixScratch,
    pattern: &AssemblyPattern,
    values: &mut [Real],
) {
    let nodes = pattern.num_nodes();
    if contacts.is_empty() || nodes == 0 {
        return;
    }
    let bounds: [u32; COLUMN_RANGES + 1] = std::array::from_fn(|k| (k * nodes / COLUMN_RANGES) as u32);
    let col_ptr = pattern.col_ptr();
    // Every contact's entries once, for all column ranges: one entry per node, weights summed
    // (the corners of a triangle mostly lie in one duplicate, so 16 entries are often 4 to 8
    // nodes; `w wᵀ` is the same matrix).
    let mut scratch = scratch.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let (offsets, all) = &mut *scratch;
    offsets.clear();
    all.clear();
    offsets.push(0);
    for c in contacts {
        let start = all.len();
        for_each_entry(points, c, |n, w| all.push((n, w)));
        let entries = &mut all[start..];
        entries.sort_unstable_by_key(|e| e.0);
        let mut kept = 0;
        for k in 0..entries.len() {
            if k > 0 && entries[k].0 == entries[kept].0 {
                entries[kept].1 += entries[k].1;
            } else {
                if k > 0 {
                    kept += 1;
                }
                entries[kept] = entries[k];
            }
        }
        all.truncate(start + kept + 1);
        offsets.push(all.len());
    }
    let (offsets, all) = (&*offsets, &*all);
    pattern.for_column_ranges(&bounds, values, &|columns, values, base| {
        for (c, range) in contacts.iter().zip(offsets.windows(2)) {
            let entries = &all[range[0]..range[1]];
            // The entries are sorted by node: those of this range's columns are consecutive,
            // and for each column its rows' ranks increase, found in one walk along its list.
            let first = entries.partition_point(|e| e.0 < columns.start);
            let last = first + entries[first..].partition_point(|e| e.0 < columns.end);
            for &(j, wj) in &entries[first..last] {
                let neighbours = pattern.neighbours(j);
                let mut rank = 0;
                for &(i, wi) in entries {
                    rank += neighbours[rank..].partition_point(|&k| k < i);
                    assert!(neighbours.get(rank) == Some(&i), "the pattern holds every contact row's couplings");
                    for col in 0..3 {
                        let at = col_ptr[3 * j as usize + col] + 3 * rank - base;
                        for row in 0..3 {
                            values[at + row] += wi * wj * c.matrix[(row, col)];
                        }
                    }
                }
            }
        }
    });
}

/// Column ranges the contact blocks are assembled over (a few per core of a small machine).
const COLUMN_RANGES: usize = 8;
