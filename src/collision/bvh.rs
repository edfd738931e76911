//! Broad phase between deformable surfaces: a bounding-volume hierarchy over a body's triangles,
//! built once from the rest shape (the topology is fixed between topology changes) and refitted every
//! tick to the boxes swept by the triangles over the tick. Two hierarchies are traversed together to
//! list the triangle pairs whose swept boxes overlap — the only pairs continuous detection must test,
//! so the cost grows as n log n plus the number of real near pairs, not n².
//!
//! Deterministic: the build splits at the median of centroids with ties broken by triangle index, and
//! traversal order is fixed. Refit and queries allocate nothing: the output list has a capacity set up
//! front, and a query that would exceed it says so instead of growing.

use crate::collision::tool::Aabb;
use crate::{Room, Vec3};

/// Triangles per leaf.
const LEAF_SIZE: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    aabb: Aabb,
    /// Leaf: first index into `order`; inner: index of the left child (the right one is `left + 1`
    /// is not assumed: see `right`).
    first_or_left: u32,
    /// Leaf: triangle count; inner: 0.
    count: u32,
    /// Inner: index of the right child.
    right: u32,
}

/// A hierarchy of swept triangle boxes for one body (its lists keep their room when copied: its
/// queries take their stack's room as their limit).
#[derive(Clone, Debug)]
pub struct TriangleBvh {
    nodes: Room<Node>,
    order: Room<u32>,
    /// Swept box of each triangle, by triangle index, from the last refit.
    triangle_boxes: Room<Aabb>,
    centroids: Room<Vec3>,
    stack: Room<(u32, u32)>,
    built_version: u64,
    /// The features each triangle owns (see [`TriangleBvh::owned`]), from the last rebuild.
    owned: Room<u8>,
    /// Scratch of the ownership pass: each side as (smaller node, larger node, 3 × triangle + side).
    side_keys: Room<(u32, u32, u32)>,
    /// Scratch of the ownership pass: whether a node was met yet.
    node_seen: Room<bool>,
    /// Scratch of the refit: each node's box over the tick (a node is shared by about six
    /// triangles: its box is taken once).
    node_boxes: Room<Aabb>,
    /// Each triangle's place in `order` (the leaves' order), from the last rebuild.
    rank: Room<u32>,
    /// What the boxes were last fitted to, as its user named it ([`TriangleBvh::set_fit_tag`]);
    /// 0 after every rebuild and refit until named.
    fit_tag: u64,
}

/// [`TriangleBvh::owned`] bit of the triangle's corner `k` (0, 1, 2).
pub const fn owns_vertex(k: usize) -> u8 {
    1 << k
}

/// [`TriangleBvh::owned`] bit of the triangle's side `k`, from corner `k` to corner `(k + 1) % 3`.
pub const fn owns_side(k: usize) -> u8 {
    8 << k
}

impl TriangleBvh {
    /// Builds the hierarchy for `triangles` at `positions`.
    pub fn build(triangles: &[[u32; 3]], positions: &[Vec3]) -> Self {
        let mut bvh = Self::with_capacity(triangles.len());
        bvh.rebuild(triangles, positions);
        bvh
    }

    /// An empty hierarchy with room for `triangles` triangles, so that [`TriangleBvh::rebuild`]
    /// allocates nothing for a mesh of up to that many.
    pub fn with_capacity(triangles: usize) -> Self {
        Self {
            nodes: Room::with_capacity(2 * triangles / LEAF_SIZE + 2),
            order: Room::with_capacity(triangles),
            triangle_boxes: Room::with_capacity(triangles),
            centroids: Room::with_capacity(triangles),
            stack: Room::with_capacity(256),
            built_version: 0,
            owned: Room::with_capacity(triangles),
            side_keys: Room::with_capacity(3 * triangles),
            node_seen: Room::with_capacity(3 * triangles + 3),
            node_boxes: Room::with_capacity(3 * triangles + 3),
            rank: Room::with_capacity(triangles),
            fit_tag: 0,
        }
    }

    /// Builds the hierarchy again for `triangles` at `positions` (after a topology change), in place:
    /// the same tree [`TriangleBvh::build`] gives, allocation-free within the capacity.
    pub fn rebuild(&mut self, triangles: &[[u32; 3]], positions: &[Vec3]) {
        self.fit_tag = 0;
        self.centroids.clear();
        self.centroids.extend(triangles.iter().map(|t| {
            (positions[t[0] as usize] + positions[t[1] as usize] + positions[t[2] as usize]) / 3.0
        }));
        self.order.clear();
        self.order.extend(0..triangles.len() as u32);
        self.nodes.clear();
        if !triangles.is_empty() {
            build_node(
                &mut self.nodes,
                &mut self.order,
                &self.centroids,
                0,
                triangles.len(),
            );
        }
        self.rank.clear();
        self.rank.resize(triangles.len(), 0);
        for (place, &t) in self.order.iter().enumerate() {
            self.rank[t as usize] = place as u32;
        }
        self.triangle_boxes.clear();
        self.triangle_boxes.resize(triangles.len(), Aabb::empty());
        self.refit(triangles, positions, positions, 0.0);
        self.assign_features(triangles);
    }

    /// Gives every node and every side of the mesh to one triangle (a node to the first triangle
    /// that has it, a side to the first of the one or two triangles that share it), so that a
    /// search over triangle pairs tests each vertex–face and edge–edge pair once. Exact for such a
    /// search: a node's (side's) swept box lies inside the box of every triangle that has it, so
    /// whenever it meets another triangle's box, so does its owner's.
    fn assign_features(&mut self, triangles: &[[u32; 3]]) {
        self.owned.clear();
        self.owned.resize(triangles.len(), 0);
        let nodes = triangles
            .iter()
            .flat_map(|t| t.iter())
            .max()
            .map_or(0, |&m| m as usize + 1);
        self.node_seen.clear();
        self.node_seen.resize(nodes, false);
        self.side_keys.clear();
        for (i, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let v = t[k] as usize;
                if !self.node_seen[v] {
                    self.node_seen[v] = true;
                    self.owned[i] |= owns_vertex(k);
                }
                let (a, b) = (t[k], t[(k + 1) % 3]);
                self.side_keys
                    .push((a.min(b), a.max(b), 3 * i as u32 + k as u32));
            }
        }
        self.side_keys.sort_unstable();
        let mut previous = None;
        for &(a, b, at) in &self.side_keys {
            if previous != Some((a, b)) {
                self.owned[at as usize / 3] |= owns_side(at as usize % 3);
                previous = Some((a, b));
            }
        }
    }

    /// The box of every triangle, from the last refit (`None` for an empty hierarchy).
    pub fn bounds(&self) -> Option<Aabb> {
        self.nodes.first().map(|node| node.aabb)
    }

    /// The features triangle `t` owns: bits [`owns_vertex`]`(k)` and [`owns_side`]`(k)`.
    pub fn owned(&self, t: usize) -> u8 {
        self.owned[t]
    }

    /// Whether the hierarchy was built for this topology (`version` is the body's topology version,
    /// `triangles` its triangle count).
    pub fn is_built_for(&self, version: u64, triangles: usize) -> bool {
        self.built_version == version && self.order.len() == triangles
    }

    /// Names what the boxes were just fitted to (any value but 0), so that a user who fits them to
    /// the same boxes again can tell it need not ([`TriangleBvh::fit_tag`]). Every rebuild and
    /// refit forgets the name.
    pub fn set_fit_tag(&mut self, tag: u64) {
        self.fit_tag = tag;
    }

    /// The name given to the boxes since the last rebuild or refit (0: none).
    pub fn fit_tag(&self) -> u64 {
        self.fit_tag
    }

    /// Records the topology version the hierarchy was built for.
    pub fn set_built_version(&mut self, version: u64) {
        self.built_version = version;
    }

    /// Refits every box to the triangles swept from `start` to `end` positions, grown by `margin`.
    /// Children come after their parent in the node array, so one backward pass suffices.
    pub fn refit(&mut self, triangles: &[[u32; 3]], start: &[Vec3], end: &[Vec3], margin: f64) {
        self.fit_tag = 0;
        // Each node's box once (the minima and maxima of the same six points as a triangle's own
        // include: the same boxes), unless the nodes outnumber the room reserved for them.
        let nodes = start.len().min(end.len());
        let per_node = nodes <= self.node_boxes.capacity();
        if per_node {
            self.node_boxes.clear();
            self.node_boxes.extend(
                start[..nodes]
                    .iter()
                    .zip(&end[..nodes])
                    .map(|(s, e)| Aabb::of_pair(s, e)),
            );
        }
        for k in (0..self.nodes.len()).rev() {
            let node = self.nodes[k];
            let mut aabb = Aabb::empty();
            if node.count > 0 {
                let first = node.first_or_left as usize;
                for &t in &self.order[first..first + node.count as usize] {
                    let corners = &triangles[t as usize];
                    let mut own = if per_node {
                        triangle_box(&self.node_boxes, corners)
                    } else {
                        let mut own = Aabb::empty();
                        for &v in corners {
                            own.include(&start[v as usize]);
                            own.include(&end[v as usize]);
                        }
                        own
                    };
                    own.inflate(margin);
                    self.triangle_boxes[t as usize] = own;
                    aabb.merge(&own);
                }
            } else {
                aabb = self.children_box(&node);
            }
            self.nodes[k].aabb = aabb;
        }
    }

    /// The box of an inner node's two children.
    fn children_box(&self, node: &Node) -> Aabb {
        let mut aabb = self.nodes[node.first_or_left as usize].aabb;
        aabb.merge(&self.nodes[node.right as usize].aabb);
        aabb
    }

    /// Appends to `found` every triangle whose box (from the last refit) overlaps `aabb`, in a fixed
    /// order. Returns false when `found` reached its capacity first (the list is then incomplete).
    pub fn query(&mut self, aabb: &Aabb, found: &mut Vec<u32>) -> bool {
        if self.nodes.is_empty() {
            return true;
        }
        let stack = &mut self.stack;
        stack.clear();
        stack.push((0, 0));
        while let Some((a, _)) = stack.pop() {
            let node = &self.nodes[a as usize];
            if !node.aabb.overlaps(aabb) {
                continue;
            }
            if node.count > 0 {
                let first = node.first_or_left as usize;
                for &t in &self.order[first..first + node.count as usize] {
                    if self.triangle_boxes[t as usize].overlaps(aabb) {
                        if found.len() == found.capacity() {
                            return false;
                        }
                        found.push(t);
                    }
                }
            } else {
                if stack.len() + 2 > stack.capacity() {
                    return false;
                }
                stack.push((node.right, 0));
                stack.push((node.first_or_left, 0));
            }
        }
        true
    }

    /// Appends to `pairs` every (triangle of self, triangle of other) whose boxes overlap, in a fixed
    /// order. Returns false when `pairs` reached its capacity first (the list is then incomplete).
    pub fn overlapping_pairs(&mut self, other: &TriangleBvh, pairs: &mut Vec<(u32, u32)>) -> bool {
        if self.nodes.is_empty() || other.nodes.is_empty() {
            return true;
        }
        let stack = &mut self.stack;
        stack.clear();
        stack.push((0, 0));
        while let Some((a, b)) = stack.pop() {
            let (na, nb) = (&self.nodes[a as usize], &other.nodes[b as usize]);
            if !na.aabb.overlaps(&nb.aabb) {
                continue;
            }
            match (na.count > 0, nb.count > 0) {
                (true, true) => {
                    let (fa, fb) = (na.first_or_left as usize, nb.first_or_left as usize);
                    for &ta in &self.order[fa..fa + na.count as usize] {
                        for &tb in &other.order[fb..fb + nb.count as usize] {
                            let (ba, bb) = (
                                &self.triangle_boxes[ta as usize],
                                &other.triangle_boxes[tb as usize],
                            );
                            if !ba.overlaps(bb) {
                                continue;
                            }
                            if pairs.len() == pairs.capacity() {
                                return false;
                            }
                            pairs.push((ta, tb));
                        }
                    }
                }
                _ => {
                    if !push_children(stack, (a, na), (b, nb)) {
                        return false;
                    }
                }
            }
        }
        true
    }
}

impl TriangleBvh {
    /// Triangle `t`'s place in the order of the leaves: a query ([`TriangleBvh::query`]) finds
    /// triangles in this order.
    pub fn rank(&self, t: u32) -> u32 {
        self.rank[t as usize]
    }

    /// Appends to `pairs` every pair of distinct triangles of this hierarchy whose boxes overlap
    /// and that `keep` keeps, each once as (smaller, larger), in a fixed order (one traversal of
    /// the hierarchy against itself, where a query per triangle would walk it from the root once
    /// per triangle). Returns false when `pairs` reached its capacity first (the list is then
    /// incomplete).
    pub fn self_overlapping_pairs(
        &mut self,
        mut keep: impl FnMut(u32, u32) -> bool,
        pairs: &mut Vec<(u32, u32)>,
    ) -> bool {
        if self.nodes.is_empty() {
            return true;
        }
        let stack = &mut self.stack;
        stack.clear();
        stack.push((0, 0));
        let mut offer = |ta: u32, tb: u32, pairs: &mut Vec<(u32, u32)>| {
            let pair = (ta.min(tb), ta.max(tb));
            if !keep(pair.0, pair.1) {
                return true;
            }
            if pairs.len() == pairs.capacity() {
                return false;
            }
            pairs.push(pair);
            true
        };
        while let Some((a, b)) = stack.pop() {
            let (na, nb) = (&self.nodes[a as usize], &self.nodes[b as usize]);
            if a != b && !na.aabb.overlaps(&nb.aabb) {
                continue;
            }
            match (na.count > 0, nb.count > 0) {
                (true, true) => {
                    let (fa, fb) = (na.first_or_left as usize, nb.first_or_left as usize);
                    let left = &self.order[fa..fa + na.count as usize];
                    let right = &self.order[fb..fb + nb.count as usize];
                    for (k, &ta) in left.iter().enumerate() {
                        // (Within one leaf, each pair once.)
                        let others = if a == b { &right[k + 1..] } else { right };
                        for &tb in others {
                            if self.triangle_boxes[ta as usize]
                                .overlaps(&self.triangle_boxes[tb as usize])
                                && !offer(ta, tb, pairs)
                            {
                                return false;
                            }
                        }
                    }
                }
                (false, false) if a == b => {
                    if stack.len() + 3 > stack.capacity() {
                        return false;
                    }
                    stack.push((na.first_or_left, na.right));
                    stack.push((na.right, na.right));
                    stack.push((na.first_or_left, na.first_or_left));
                }
                _ => {
                    if !push_children(stack, (a, na), (b, nb)) {
                        return false;
                    }
                }
            }
        }
        true
    }
}

/// Pushes onto `stack` the pairs of children of node pair (`a`, `b`) (nodes `na`, `nb`, not both
/// leaves; two distinct nodes, or nodes of two hierarchies): a leaf against the other's children,
/// or each child against each. False when the stack has no room.
fn push_children(
    stack: &mut Room<(u32, u32)>,
    (a, na): (u32, &Node),
    (b, nb): (u32, &Node),
) -> bool {
    let room = if na.count > 0 || nb.count > 0 { 2 } else { 4 };
    if stack.len() + room > stack.capacity() {
        return false;
    }
    if na.count > 0 {
        stack.push((a, nb.right));
        stack.push((a, nb.first_or_left));
    } else if nb.count > 0 {
        stack.push((na.right, b));
        stack.push((na.first_or_left, b));
    } else {
        stack.push((na.right, nb.right));
        stack.push((na.right, nb.first_or_left));
        stack.push((na.first_or_left, nb.right));
        stack.push((na.first_or_left, nb.first_or_left));
    }
    true
}

/// The box of a triangle with `corners`, from its nodes' boxes.
fn triangle_box(node_boxes: &[Aabb], corners: &[u32; 3]) -> Aabb {
    let mut own = Aabb::empty();
    for &v in corners {
        own.merge(&node_boxes[v as usize]);
    }
    own
}

/// Builds the subtree over `order[begin..end]` and returns its node index.
fn build_node(
    nodes: &mut Vec<Node>,
    order: &mut [u32],
    centroids: &[Vec3],
    begin: usize,
    end: usize,
) -> u32 {
    let index = nodes.len() as u32;
    nodes.push(Node {
        aabb: Aabb::empty(),
        first_or_left: begin as u32,
        count: (end - begin) as u32,
        right: 0,
    });
    if end - begin <= LEAF_SIZE {
        return index;
    }
    let mut bounds = Aabb::empty();
    for &t in &order[begin..end] {
        bounds.include(&centroids[t as usize]);
    }
    let extent = bounds.max - bounds.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    order[begin..end].sort_unstable_by(|&p, &q| {
        centroids[p as usize][axis]
            .total_cmp(&centroids[q as usize][axis])
            .then(p.cmp(&q))
    });
    let middle = begin + (end - begin) / 2;
    let left = build_node(nodes, order, centroids, begin, middle);
    let right = build_node(nodes, order, centroids, middle, end);
    nodes[index as usize] = Node {
        aabb: Aabb::empty(),
        first_or_left: left,
        count: 0,
        right,
    };
    index
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::mesh::icosphere;

    #[test]
    fn every_node_and_side_has_exactly_one_owner() {
        let mesh = icosphere(0.05, 2);
        // Also with a hole (a boundary: sides in one triangle only) and renumbered triangles.
        let mut open = mesh.triangles.clone();
        open.remove(7);
        open.reverse();
        for triangles in [mesh.triangles.clone(), open] {
            let bvh = TriangleBvh::build(&triangles, &mesh.positions_in_body);
            let mut vertex_owners = vec![0; mesh.positions_in_body.len()];
            let mut side_owners = std::collections::BTreeMap::new();
            for (i, t) in triangles.iter().enumerate() {
                for k in 0..3 {
                    if bvh.owned(i) & owns_vertex(k) != 0 {
                        vertex_owners[t[k] as usize] += 1;
                    }
                    let key = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                    let count = side_owners.entry(key).or_insert(0);
                    if bvh.owned(i) & owns_side(k) != 0 {
                        *count += 1;
                    }
                }
            }
            assert!(vertex_owners.iter().all(|&c| c == 1), "{vertex_owners:?}");
            assert!(side_owners.values().all(|&c| c == 1));
            // Taking a triangle out leaves its sides in its neighbours: 480 sides either way.
            assert_eq!(side_owners.len(), 480);
        }
    }

    #[test]
    fn a_refit_or_a_rebuild_forgets_what_the_boxes_were_fitted_to() {
        // The body-contact listing skips a refit where the tag still names the reference the
        // boxes were fitted to; self-contact refits the same hierarchy to other boxes.
        let sphere = icosphere(0.05, 1);
        let positions = &sphere.positions_in_body;
        let mut bvh = TriangleBvh::build(&sphere.triangles, positions);
        assert_eq!(bvh.fit_tag(), 0);
        bvh.set_fit_tag(7);
        assert_eq!(bvh.fit_tag(), 7);
        bvh.refit(&sphere.triangles, positions, positions, 1e-3);
        assert_eq!(bvh.fit_tag(), 0);
        bvh.set_fit_tag(8);
        bvh.rebuild(&sphere.triangles, positions);
        assert_eq!(bvh.fit_tag(), 0);
    }

    #[test]
    fn self_pairs_match_brute_force() {
        let sphere = icosphere(0.05, 2);
        let positions = &sphere.positions_in_body;
        let mut bvh = TriangleBvh::build(&sphere.triangles, positions);
        let moved: Vec<Vec3> = positions
            .iter()
            .enumerate()
            .map(|(k, p)| p * (1.0 + 0.02 * ((k * 7919 % 13) as f64 - 6.0) / 6.0))
            .collect();
        bvh.refit(&sphere.triangles, positions, &moved, 1e-3);
        let mut pairs = Vec::with_capacity(100_000);
        assert!(bvh.self_overlapping_pairs(|a, b| (a + b) % 3 != 0, &mut pairs));
        let mut expected = Vec::new();
        let boxes = &bvh.triangle_boxes;
        for a in 0..sphere.triangles.len() as u32 {
            for b in a + 1..sphere.triangles.len() as u32 {
                if boxes[a as usize].overlaps(&boxes[b as usize]) && (a + b) % 3 != 0 {
                    expected.push((a, b));
                }
            }
        }
        // In the order of a query per triangle: by the first, then the second's place in the
        // leaves.
        let mut queried = Vec::new();
        let mut found = Vec::with_capacity(1000);
        for ta in 0..sphere.triangles.len() as u32 {
            found.clear();
            let own = bvh.triangle_boxes[ta as usize];
            assert!(bvh.query(&own, &mut found));
            queried.extend(
                found
                    .iter()
                    .filter(|&&tb| tb > ta && (ta + tb) % 3 != 0)
                    .map(|&tb| (ta, tb)),
            );
        }
        let mut ranked = pairs.clone();
        ranked.sort_unstable_by_key(|&(ta, tb)| (ta, bvh.rank(tb)));
        assert_eq!(ranked, queried);
        let count = pairs.len();
        pairs.sort_unstable();
        pairs.dedup();
        assert_eq!(pairs.len(), count, "a pair listed twice");
        assert_eq!(pairs, expected);
        assert!(
            expected.len() > sphere.triangles.len(),
            "too few pairs to tell"
        );
        // A list with too little room says so.
        let mut short = Vec::with_capacity(10);
        assert!(!bvh.self_overlapping_pairs(|_, _| true, &mut short));
    }

    #[test]
    fn bvh_pairs_match_brute_force() {
        let a = icosphere(0.05, 2);
        let mut b = icosphere(0.05, 2);
        for p in &mut b.positions_in_body {
            *p += Vec3::new(0.09, 0.01, 0.0);
        }
        let mut bvh_a = TriangleBvh::build(&a.triangles, &a.positions_in_body);
        let bvh_b = TriangleBvh::build(&b.triangles, &b.positions_in_body);
        let mut pairs = Vec::with_capacity(100_000);
        assert!(bvh_a.overlapping_pairs(&bvh_b, &mut pairs));
        let tri_box = |m: &crate::scene::mesh::SurfaceMesh, t: usize| {
            let mut bx = Aabb::empty();
            for &v in &m.triangles[t] {
                bx.include(&m.positions_in_body[v as usize]);
            }
            bx
        };
        let mut brute = Vec::new();
        for ta in 0..a.triangles.len() {
            for tb in 0..b.triangles.len() {
                if tri_box(&a, ta).overlaps(&tri_box(&b, tb)) {
                    brute.push((ta as u32, tb as u32));
                }
            }
        }
        pairs.sort_unstable();
        assert!(!brute.is_empty());
        assert_eq!(pairs, brute);
        // A full output list says so.
        let mut small = Vec::with_capacity(3);
        assert!(!bvh_a.overlapping_pairs(&bvh_b, &mut small));
        // A box query finds exactly the triangles whose boxes meet the box.
        let mut query = Aabb::empty();
        query.include(&Vec3::new(0.03, -0.01, -0.02));
        query.include(&Vec3::new(0.05, 0.02, 0.01));
        let mut found = Vec::with_capacity(1000);
        assert!(bvh_a.query(&query, &mut found));
        found.sort_unstable();
        let expected: Vec<u32> = (0..a.triangles.len())
            .filter(|&t| tri_box(&a, t).overlaps(&query))
            .map(|t| t as u32)
            .collect();
        assert!(!expected.is_empty());
        assert_eq!(found, expected);
    }
}
