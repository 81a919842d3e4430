//! Where the nodes sit along the rod: each section is cut into the same
//! number of equal elements, so a rod of sections of different lengths has
//! elements of different lengths (equal within a section) and every section
//! end is a node. A rod of equal sections has `n` equal elements `L / n`.

/// The nodes' arc lengths of a rod of `n` elements.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Arc length of node `i`, `i = 0..=n` [m].
    arcs: Vec<f64>,
    /// Length of element `i` (index `i - 1`) [m].
    elements: Vec<f64>,
}

impl Mesh {
    /// `n` equal elements over `length`.
    pub fn uniform(length: f64, n: usize) -> Mesh {
        let ds = length / n as f64;
        Mesh {
            arcs: (0..=n).map(|i| length * i as f64 / n as f64).collect(),
            elements: vec![ds; n],
        }
    }

    /// `n / k` equal elements in each of the `k` sections of the given
    /// lengths (`n` a multiple of `k`; empty lengths: one section of `length`).
    pub fn new(length: f64, section_lengths: &[f64], n: usize) -> Mesh {
        let k = section_lengths.len();
        if k <= 1 || section_lengths.iter().all(|l| *l == section_lengths[0]) {
            return Mesh::uniform(length, n);
        }
        debug_assert_eq!(n % k, 0);
        let per_section = n / k;
        let mut arcs = Vec::with_capacity(n + 1);
        let mut elements = Vec::with_capacity(n);
        let mut start = 0.0;
        arcs.push(0.0);
        for l in section_lengths {
            let h = l / per_section as f64;
            for j in 1..=per_section {
                arcs.push(start + l * j as f64 / per_section as f64);
                elements.push(h);
            }
            start += l;
        }
        Mesh { arcs, elements }
    }

    /// Number of elements.
    pub fn n(&self) -> usize {
        self.elements.len()
    }

    /// Arc lengths of the nodes `0..=n` [m].
    pub fn arcs(&self) -> &[f64] {
        &self.arcs
    }

    /// Element lengths, element `i` at index `i - 1` [m].
    pub fn element_lengths(&self) -> &[f64] {
        &self.elements
    }

    /// The node nearest to arc length `s`.
    pub fn nearest_node(&self, s: f64) -> usize {
        let after = self.arcs.partition_point(|a| *a < s).min(self.n());
        if after > 0 && s - self.arcs[after - 1] < self.arcs[after] - s {
            after - 1
        } else {
            after
        }
    }

    /// The node at arc length `s`, up to round-off (1e-9 of an element),
    /// or `None` when `s` falls between nodes.
    pub fn node_at(&self, s: f64) -> Option<usize> {
        let node = self.nearest_node(s);
        let h = self.elements[node.saturating_sub(1).min(self.n() - 1)];
        ((s - self.arcs[node]).abs() <= 1e-9 * h.max(s.abs())).then_some(node)
    }
}

/// The element counts whose mesh has a node at arc length `s` (up to
/// [`Mesh::node_at`]'s round-off): the multiples of the count returned, a
/// multiple of the `sections` (of the given lengths, or equal ones when
/// `section_lengths` is empty); None when no count up to `limit` has one.
pub fn counts_with_node(
    length: f64,
    section_lengths: &[f64],
    sections: usize,
    s: f64,
    limit: usize,
) -> Option<usize> {
    let unequal =
        section_lengths.len() > 1 && section_lengths.iter().any(|l| *l != section_lengths[0]);
    if !unequal {
        // One uniform mesh: node k sits at k L / n.
        let d = denominator(s / length, limit)?;
        return Some(lcm(sections, d));
    }
    // n / sections equal elements in each section: the fraction of its section.
    let mut start = 0.0;
    for l in section_lengths {
        if s <= start + l * (1.0 + 1e-12) {
            let d = denominator(((s - start) / l).clamp(0.0, 1.0), limit)?;
            return Some(sections * d);
        }
        start += l;
    }
    None
}

/// The smallest `d` in `1..=limit` for which `x d` is an integer up to
/// round-off (relative 1e-9, as [`Mesh::node_at`]).
fn denominator(x: f64, limit: usize) -> Option<usize> {
    (1..=limit).find(|d| {
        let y = x * *d as f64;
        (y - y.round()).abs() <= 1e-9 * y.abs().max(1.0)
    })
}

/// The least common multiple (`a`, `b` positive and small).
pub fn lcm(a: usize, b: usize) -> usize {
    let (mut x, mut y) = (a, b);
    while y != 0 {
        (x, y) = (y, x % y);
    }
    a / x * b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sections_of_different_lengths_get_equal_shares_of_the_elements() {
        let mesh = Mesh::new(1.0, &[0.2, 0.5, 0.3], 6);
        assert_eq!(mesh.element_lengths(), &[0.1, 0.1, 0.25, 0.25, 0.15, 0.15]);
        let expected = [0.0, 0.1, 0.2, 0.45, 0.7, 0.85, 1.0];
        for (a, b) in mesh.arcs().iter().zip(expected) {
            assert!((a - b).abs() < 1e-15, "{a} vs {b}");
        }
        assert_eq!(mesh.node_at(0.45), Some(3));
        assert_eq!(mesh.node_at(0.7), Some(4));
        assert_eq!(mesh.node_at(1.0), Some(6));
        assert_eq!(mesh.node_at(0.5), None);
        assert_eq!(mesh.nearest_node(0.5), 3);
        assert_eq!(mesh.nearest_node(0.6), 4);
    }

    #[test]
    fn the_counts_with_a_node_are_the_multiples_of_one() {
        // 0.35 L: n a multiple of 20; in 3 equal sections also of 3.
        assert_eq!(counts_with_node(1.0, &[], 1, 0.35, 1000), Some(20));
        assert_eq!(counts_with_node(1.0, &[], 3, 0.35, 1000), Some(60));
        assert_eq!(counts_with_node(2.0, &[], 1, 2.0, 1000), Some(1));
        // 0.45 is the end of the second of 0.2, 0.25, 0.55: any count.
        let lengths = [0.2, 0.25, 0.55];
        assert_eq!(counts_with_node(1.0, &lengths, 3, 0.45, 1000), Some(3));
        // 0.3 is a fifth into the second section: 5 elements a section.
        assert_eq!(counts_with_node(1.0, &lengths, 3, 0.25, 1000), Some(15));
        for n in [15, 30, 60] {
            assert!(Mesh::new(1.0, &lengths, n).node_at(0.25).is_some(), "{n}");
        }
        assert!(Mesh::new(1.0, &lengths, 12).node_at(0.25).is_none());
        assert_eq!(counts_with_node(1.0, &[], 1, 0.123456789, 1000), None);
    }

    #[test]
    fn equal_sections_are_the_uniform_mesh() {
        assert_eq!(Mesh::new(1.0, &[0.5, 0.5], 4), Mesh::uniform(1.0, 4));
        assert_eq!(Mesh::new(1.0, &[], 4), Mesh::uniform(1.0, 4));
    }
}
