//! Sums whose bits do not depend on the thread count: a parallel `sum()` adds its terms in an
//! order set by rayon's work stealing, so the same state could report energies differing in the
//! last digit from run to run. Here the terms are cut into a fixed number of contiguous ranges,
//! each summed in order on some thread, and the partial sums are added in range order.

use crate::Real;
use rayon::prelude::*;

/// Contiguous ranges a [`deterministic_sum`] cuts its terms into (a few per core of any machine
/// this runs on; the partial sums live on the stack).
pub const SUM_RANGES: usize = 64;

/// `Σ_{i < len} term(i)`, in parallel, with the same bits on any number of threads.
pub fn deterministic_sum(len: usize, term: impl Fn(usize) -> Real + Sync) -> Real {
    let mut partial = [0.0; SUM_RANGES];
    partial.par_iter_mut().enumerate().for_each(|(k, p)| {
        *p = (k * len / SUM_RANGES..(k + 1) * len / SUM_RANGES).map(&term).sum();
    });
    partial.iter().sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sum_has_the_same_bits_on_one_and_on_two_threads_and_is_the_sum() {
        // Terms of mixed magnitude, whose float sum depends on the order of addition.
        let term = |i: usize| (i as Real * 0.7548776662).sin() * 10f64.powi((i % 17) as i32 - 8);
        let len = 100_003;
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| deterministic_sum(len, term))
        };
        let (one, two) = (on(1), on(2));
        assert_eq!(one.to_bits(), two.to_bits());
        let sequential: Real = (0..len).map(term).sum();
        assert!((one - sequential).abs() <= 1e-12 * (0..len).map(|i| term(i).abs()).sum::<Real>());
        assert_eq!(deterministic_sum(0, term), 0.0);
        assert_eq!(deterministic_sum(3, |i| i as Real), 3.0);
    }
}
