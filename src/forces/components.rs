//! Connected components of a graph on particles (bonds, fast couplings, held distances):
//! union–find with path halving, each set's root its smallest member. The distance split
//! finds molecules with it, the splitter the fast-force graph's components, the
//! equilibrium mollifier the molecules of its held distances.

/// Disjoint sets over `0..n`.
pub struct Components {
    parent: Vec<usize>,
}

impl Components {
    pub fn new(n: usize) -> Self {
        Components {
            parent: (0..n).collect(),
        }
    }

    /// The smallest member of `i`'s set.
    pub fn root(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    /// Join the sets of `a` and `b`.
    pub fn join(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.root(a), self.root(b));
        if ra != rb {
            self.parent[ra.max(rb)] = ra.min(rb);
        }
    }

    /// The sets of `members` (ascending), each in ascending order, ordered by their
    /// smallest member.
    pub fn groups(&mut self, members: impl Iterator<Item = usize>) -> Vec<Vec<usize>> {
        let mut slot = vec![usize::MAX; self.parent.len()];
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for i in members {
            let r = self.root(i);
            if slot[r] == usize::MAX {
                slot[r] = groups.len();
                groups.push(Vec::new());
            }
            groups[slot[r]].push(i);
        }
        groups
    }

    /// Each of `0..n`'s set as a number, 0, 1, … in the order of the sets' smallest members.
    pub fn labels(&mut self) -> Vec<u32> {
        let n = self.parent.len();
        let mut label = vec![0u32; n];
        for (k, group) in self.groups(0..n).into_iter().enumerate() {
            for i in group {
                label[i] = k as u32;
            }
        }
        label
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_are_numbered_by_their_smallest_member() {
        let mut c = Components::new(6);
        c.join(4, 1);
        c.join(5, 3);
        c.join(3, 4);
        assert_eq!(c.groups(0..6), vec![vec![0], vec![1, 3, 4, 5], vec![2]]);
        assert_eq!(c.labels(), vec![0, 1, 2, 1, 1, 1]);
        assert_eq!(c.groups([2, 5].into_iter()), vec![vec![2], vec![5]]);
    }
}
