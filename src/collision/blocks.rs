//! What the force stage's node pass learns about each block of consecutive nodes while it streams
//! through them: the box of their trajectories over the step (start and end positions), and the
//! divergence guard's largest squared speed and stretch with a flag for values that are not
//! finite. The contact stages then skip the blocks their queries miss (the tool broad phase, the
//! obstacles, the push-out), and the guard reads the blocks instead of every node, rescanning only
//! the blocks whose nodes a stage moved after the node pass.
//!
//! Every stage that moves a node after the node pass includes it ([`NodeBlocks::include`]: its
//! trajectory joins the box, and its block is marked for the guard's rescan) or drops the blocks
//! ([`NodeBlocks::drop_all`], [`NodeBlocks::drop_maxima`]); the world does so.

use crate::Vec3;
use crate::body::Surface;
use crate::collision::tool::Aabb;

/// Nodes a block covers: consecutive nodes, close in space when the mesh is ordered for locality
/// (as every mesh a scene loads is).
pub const BLOCK: usize = 64;

/// One block of [`BLOCK`] consecutive nodes (the last may be shorter).
#[derive(Clone, Copy, Debug)]
pub struct NodeBlock {
    /// Holds every node's start and end position of the step (`position_in_world`,
    /// `next_position_in_world`); a coordinate that is not a number is left out.
    pub bounds: Aabb,
    /// Largest `|v|²` of the node pass's velocities (m²/s²).
    pub speed2: f64,
    /// Largest `|x_end − h|²` of the node pass's end positions and homologues (m²).
    pub stretch2: f64,
    /// Some node's `|v|² + |x_end − h|²` was not finite (NaN or infinite), or some position
    /// included since is not a number.
    pub bad: bool,
    /// A stage moved a node of the block after the node pass: its maxima are stale (the guard
    /// rescans its nodes).
    pub touched: bool,
}

impl NodeBlock {
    /// A block the node pass has not seen yet.
    pub const EMPTY: Self = Self {
        bounds: Aabb {
            min: Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
            max: Vec3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
        },
        speed2: 0.0,
        stretch2: 0.0,
        bad: false,
        touched: false,
    };
}

/// The blocks of one body, from the last node pass that integrated every node.
#[derive(Clone, Debug, Default)]
pub struct NodeBlocks {
    blocks: Vec<NodeBlock>,
    /// The boxes hold every node's trajectory.
    bounds_valid: bool,
    /// The maxima (with the touched blocks rescanned) are the guard's.
    maxima_valid: bool,
}

impl NodeBlocks {
    /// Room for the blocks of `nodes` nodes.
    pub fn with_capacity(nodes: usize) -> Self {
        Self {
            blocks: Vec::with_capacity(nodes.div_ceil(BLOCK)),
            bounds_valid: false,
            maxima_valid: false,
        }
    }

    /// Empty blocks for `nodes` nodes, to be filled by a node pass; valid from now on.
    pub fn start(&mut self, nodes: usize) -> &mut [NodeBlock] {
        self.blocks.clear();
        self.blocks.resize(nodes.div_ceil(BLOCK), NodeBlock::EMPTY);
        self.bounds_valid = true;
        self.maxima_valid = true;
        &mut self.blocks
    }

    /// The blocks, when their boxes hold every trajectory of a body of `nodes` nodes.
    pub fn bounds(&self, nodes: usize) -> Option<&[NodeBlock]> {
        (self.bounds_valid && self.blocks.len() == nodes.div_ceil(BLOCK)).then_some(&self.blocks)
    }

    /// The blocks, when their maxima, with the touched blocks rescanned, are those of every node
    /// of a body of `nodes` nodes as they are now.
    pub fn maxima(&self, nodes: usize) -> Option<&[NodeBlock]> {
        (self.maxima_valid && self.blocks.len() == nodes.div_ceil(BLOCK)).then_some(&self.blocks)
    }

    /// Node `i` of `surface` moved after the node pass: its trajectory joins its block's box and
    /// the block is rescanned by the guard.
    #[inline]
    pub fn include(&mut self, surface: &Surface, i: usize) {
        match self.blocks.get_mut(i / BLOCK) {
            Some(b) => {
                let (x, next) = (
                    &surface.position_in_world[i],
                    &surface.next_position_in_world[i],
                );
                b.bounds.include(x);
                b.bounds.include(next);
                b.bad |= x.iter().chain(next.iter()).any(|c| c.is_nan());
                b.touched = true;
            }
            None => self.drop_all(),
        }
    }

    /// [`NodeBlocks::include`] each of `nodes`, while the boxes are valid (nothing to keep true
    /// otherwise).
    pub fn include_all(&mut self, surface: &Surface, nodes: &[u32]) {
        if self.bounds_valid {
            for &i in nodes {
                self.include(surface, i as usize);
            }
        }
    }

    /// Nodes were moved, added or removed without being included: no more use for this step.
    pub fn drop_all(&mut self) {
        self.bounds_valid = false;
        self.maxima_valid = false;
    }

    /// The nodes may change before the guard looks at them (another body's contact, a cut).
    pub fn drop_maxima(&mut self) {
        self.maxima_valid = false;
    }
}
