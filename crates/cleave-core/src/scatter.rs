//! Parallel scatter-add without atomics: items (blocks, cubes) are split into contiguous chunks,
//! each chunk adds into a private buffer that covers only the DOF range the chunk touches, and the
//! buffers are summed into the output in parallel. With items sorted spatially the ranges barely
//! overlap, so the extra memory and the reduction cost are about one DOF vector.

use crate::Real;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::Mutex;

/// A per-epoch plan: item chunks, the DOF range each touches, and their reusable buffers.
#[derive(Debug)]
pub struct ScatterPlan {
    num_dofs: usize,
    chunks: Vec<Range<usize>>,
    dof_ranges: Vec<Range<usize>>,
    buffers: Mutex<Vec<Vec<Real>>>,
}

/// One zeroed buffer per DOF range.
fn zeroed_buffers(dof_ranges: &[Range<usize>]) -> Vec<Vec<Real>> {
    dof_ranges.iter().map(|r| vec![0.0; r.len()]).collect()
}

impl Clone for ScatterPlan {
    /// Fresh buffers of the same ranges, without taking the lock of this plan's (a scatter may
    /// hold it; every scatter zeroes its buffers before use).
    fn clone(&self) -> Self {
        Self {
            num_dofs: self.num_dofs,
            chunks: self.chunks.clone(),
            dof_ranges: self.dof_ranges.clone(),
            buffers: Mutex::new(zeroed_buffers(&self.dof_ranges)),
        }
    }
}

impl ScatterPlan {
    /// Plans a scatter over `num_items` items whose touched DOFs are given by `item_dof_range`
    /// (half-open, scalar DOF indices), into vectors of length `num_dofs`.
    pub fn new(num_items: usize, num_dofs: usize, item_dof_range: impl Fn(usize) -> Range<usize>) -> Self {
        // A few chunks per thread balance the load; every chunk costs one buffer range.
        let num_chunks = (rayon::current_num_threads() * 4).clamp(1, num_items.max(1));
        let chunk_len = num_items.div_ceil(num_chunks).max(1);
        let mut chunks = Vec::new();
        let mut dof_ranges = Vec::new();
        let mut start = 0;
        while start < num_items {
            let end = (start + chunk_len).min(num_items);
            let (mut lo, mut hi) = (usize::MAX, 0);
            for item in start..end {
                let r = item_dof_range(item);
                if r.start < r.end {
                    lo = lo.min(r.start);
                    hi = hi.max(r.end);
                }
            }
            if lo > hi {
                lo = 0;
                hi = 0;
            }
            chunks.push(start..end);
            dof_ranges.push(lo..hi);
            start = end;
        }
        let buffers = Mutex::new(zeroed_buffers(&dof_ranges));
        Self { num_dofs, chunks, dof_ranges, buffers }
    }

    /// Length of the DOF vectors this plan scatters into.
    pub fn num_dofs(&self) -> usize {
        self.num_dofs
    }

    /// Calls `per_item(item, buffer, base)` for every item, in parallel over chunks, where
    /// `buffer[dof - base]` is the private accumulator of DOF `dof`; then adds all buffers into
    /// `out`. Allocation-free after construction.
    pub fn scatter_add<F>(&self, out: &mut [Real], per_item: F)
    where
        F: Fn(usize, &mut [Real], usize) + Sync,
    {
        assert_eq!(out.len(), self.num_dofs, "scatter output has the wrong length");
        let mut buffers = self.buffers.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        buffers.par_iter_mut().zip(self.chunks.par_iter().zip(self.dof_ranges.par_iter())).for_each(
            |(buffer, (items, range))| {
                buffer.fill(0.0);
                for item in items.clone() {
                    per_item(item, buffer, range.start);
                }
            },
        );
        // Reduce: split `out` into pieces and let each piece gather from the buffers overlapping it.
        let piece = self.num_dofs.div_ceil(rayon::current_num_threads() * 4).max(1024);
        let buffers = &*buffers;
        let ranges = &self.dof_ranges;
        out.par_chunks_mut(piece).enumerate().for_each(|(p, out_piece)| {
            let lo = p * piece;
            let hi = lo + out_piece.len();
            for (buffer, range) in buffers.iter().zip(ranges) {
                let a = range.start.max(lo);
                let b = range.end.min(hi);
                if a < b {
                    let src = &buffer[a - range.start..b - range.start];
                    for (o, s) in out_piece[a - lo..b - lo].iter_mut().zip(src) {
                        *o += s;
                    }
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parallel_scatter_equals_serial_sum() {
        // items i add (i+1) to dofs i, i+1, i+2 (a banded pattern like sorted elements)
        let n_items = 10_000;
        let n_dofs = n_items + 2;
        let plan = ScatterPlan::new(n_items, n_dofs, |i| i..i + 3);
        let mut out = vec![1.0; n_dofs];
        plan.scatter_add(&mut out, |i, buf, base| {
            for d in i..i + 3 {
                buf[d - base] += (i + 1) as Real;
            }
        });
        let mut expected = vec![1.0; n_dofs];
        for i in 0..n_items {
            for d in i..i + 3 {
                expected[d] += (i + 1) as Real;
            }
        }
        assert_eq!(out, expected);
        // and a second call reuses the buffers without leftovers
        let mut again = vec![1.0; n_dofs];
        plan.scatter_add(&mut again, |i, buf, base| {
            for d in i..i + 3 {
                buf[d - base] += (i + 1) as Real;
            }
        });
        assert_eq!(again, expected);
    }
}
