//! Union–find (disjoint sets) with path halving, the root of a set being its smallest member so
//! that results do not depend on the order of the unions. Parents are stored as `u32` (the voxel
//! mesh keeps one set per cube corner, eight per cube: half the memory of `usize`).

/// Disjoint sets over `0..n`, `n ≤ u32::MAX`.
#[derive(Clone, Debug)]
pub struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    /// `n` singleton sets. Panics beyond `u32::MAX` sets (callers size their inputs first: no
    /// mesh here comes near it).
    pub fn new(n: usize) -> Self {
        let n = u32::try_from(n).expect("at most u32::MAX sets");
        Self { parent: (0..n).collect() }
    }

    /// The smallest member of `i`'s set.
    pub fn find(&mut self, i: usize) -> usize {
        let mut i = u32::try_from(i).expect("an index of the sets");
        while self.parent[i as usize] != i {
            self.parent[i as usize] = self.parent[self.parent[i as usize] as usize];
            i = self.parent[i as usize];
        }
        i as usize
    }

    /// Joins the sets of `a` and `b`; whether they were apart.
    pub fn union(&mut self, a: usize, b: usize) -> bool {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra.max(rb)] = ra.min(rb) as u32;
        }
        ra != rb
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_join_and_report_their_smallest_member() {
        let mut sets = UnionFind::new(6);
        assert!(sets.union(4, 2));
        assert!(sets.union(5, 4));
        assert!(!sets.union(2, 5));
        assert!(sets.union(1, 3));
        assert_eq!((0..6).map(|i| sets.find(i)).collect::<Vec<_>>(), vec![0, 1, 2, 1, 2, 2]);
    }
}
