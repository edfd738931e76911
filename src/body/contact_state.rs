//! The per-node contact state with the tools, kept by the body (written by the contact stages).

use crate::Vec3;

/// No tool: the node is free.
pub const NO_TOOL: u32 = u32::MAX;

/// The contact state of one surface node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolContact {
    /// Tool index, or [`NO_TOOL`].
    pub tool: u32,
    /// Capsule part of that tool.
    pub part: u32,
    /// Where the node sits on the tool (m, tool frame; for a grasped node, where it sat when grasped).
    pub point_in_tool: Vec3,
    /// Set while a grasper holds the node in the frame of one of its jaws.
    pub grasp: Option<JawHold>,
}

/// A node held in a jaw's frame: the jaw (+1 for part 0, −1 for part 1, 0 between them) and the
/// half opening when it was grasped (rad).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JawHold {
    /// +1 for jaw 0, −1 for jaw 1, 0 for the frame between them.
    pub side: f64,
    /// Half the jaw opening when the node was grasped (rad).
    pub half_opening: f64,
}

impl JawHold {
    /// A hold on part `part` of a grasper (0 or 1: its jaws) whose half opening is `half_opening`.
    pub fn on_part(part: usize, half_opening: f64) -> Self {
        Self {
            side: if part == 0 { 1.0 } else { -1.0 },
            half_opening,
        }
    }

    /// Where a node grasped at `point_in_tool` is, in the tool frame, for the half opening `half`
    /// now: its jaw turned about the tool's y axis since the grasp.
    pub fn point_now(&self, point_in_tool: &Vec3, half: f64) -> Vec3 {
        let angle = self.side * (half - self.half_opening);
        let (s, c) = (crate::math::sin(angle), crate::math::cos(angle));
        let p = point_in_tool;
        Vec3::new(c * p.x + s * p.z, p.y, -s * p.x + c * p.z)
    }
}
