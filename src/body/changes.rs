//! A record of where a body's topology changed: the springs a cut rewrote or added and the nodes
//! whose mass, links or springs changed, so that the force kernel and the solvers follow the change
//! where it happened instead of passing over the whole mesh.
//!
//! The record covers the changes from one topology version to another. A follower that was in step
//! with the body at a version the record starts from (or after) and finds the body at the version
//! the record ends with may use it; any other change (one its author did not record, a record that
//! ran out of room) leaves the follower to pass over the mesh, as it would without a record.

/// Springs and nodes changed between two topology versions of a body.
#[derive(Debug, Default)]
pub struct TopologyChanges {
    /// The body's topology version when the record began.
    from_version: u64,
    /// The version the recorded changes bring the body to.
    to_version: u64,
    /// Springs rewritten or added (indices, in increasing order once sealed).
    edges: crate::Room<u32>,
    /// Nodes whose mass, link, air damping or springs changed, and new nodes (in increasing order
    /// once sealed).
    nodes: crate::Room<u32>,
    /// The record ran out of room: it does not cover its versions.
    overflow: bool,
}

/// A clone keeps the room (the record's limits are its lists' capacities).
impl Clone for TopologyChanges {
    fn clone(&self) -> Self {
        let mut copy = Self::with_capacity(self.edges.capacity(), self.nodes.capacity());
        copy.edges.extend_from_slice(&self.edges);
        copy.nodes.extend_from_slice(&self.nodes);
        copy.from_version = self.from_version;
        copy.to_version = self.to_version;
        copy.overflow = self.overflow;
        copy
    }
}

impl TopologyChanges {
    /// A record with room for `edges` springs and `nodes` nodes per span of versions.
    pub fn with_capacity(edges: usize, nodes: usize) -> Self {
        Self {
            edges: crate::Room::with_capacity(edges),
            nodes: crate::Room::with_capacity(nodes),
            ..Self::default()
        }
    }

    /// Starts a record from the body's topology version `version` (forgets the previous one).
    pub fn begin(&mut self, version: u64) {
        self.from_version = version;
        self.to_version = version;
        self.edges.clear();
        self.nodes.clear();
        self.overflow = false;
    }

    /// Records spring `k` as rewritten or added.
    pub fn edge(&mut self, k: u32) {
        if self.edges.len() < self.edges.capacity() {
            self.edges.push(k);
        } else {
            self.overflow = true;
        }
    }

    /// Records node `v` as changed or new.
    pub fn node(&mut self, v: u32) {
        if self.nodes.len() < self.nodes.capacity() {
            self.nodes.push(v);
        } else {
            self.overflow = true;
        }
    }

    /// The record now brings the body to version `version`: puts the springs and nodes in
    /// increasing order, each once.
    pub fn seal(&mut self, version: u64) {
        self.to_version = version;
        self.edges.sort_unstable();
        self.edges.dedup();
        self.nodes.sort_unstable();
        self.nodes.dedup();
    }

    /// Gives up the record: whoever follows passes over the mesh.
    pub fn lose(&mut self) {
        self.overflow = true;
    }

    /// Whether the record holds every change from version `since` (the follower's) to
    /// `current` (the body's).
    pub fn covers(&self, since: u64, current: u64) -> bool {
        !self.overflow
            && self.from_version <= since
            && since <= current
            && self.to_version == current
    }

    /// The springs rewritten or added, in increasing order.
    pub fn edges(&self) -> &[u32] {
        &self.edges
    }

    /// The nodes changed or new, in increasing order.
    pub fn nodes(&self) -> &[u32] {
        &self.nodes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_covers_only_the_versions_it_saw() {
        let mut changes = TopologyChanges::with_capacity(4, 4);
        changes.begin(5);
        changes.edge(7);
        changes.edge(2);
        changes.edge(7);
        changes.node(3);
        changes.seal(6);
        assert_eq!(changes.edges(), &[2, 7]);
        assert!(changes.covers(5, 6));
        assert!(changes.covers(6, 6));
        // A follower from before the record, or a change after it that nobody recorded.
        assert!(!changes.covers(4, 6));
        assert!(!changes.covers(5, 7));
        // Out of room: no longer covers anything.
        for k in 0..5 {
            changes.edge(k);
        }
        assert!(!changes.covers(5, 6));
    }
}
