//! Rigid tools driven by a pose each tick (MODEL.md §4): a sphere probe, a laparoscopic instrument
//! (capsule shaft ending in a rounded tip), a grasper (shaft and two jaws opened by a scalar input) and
//! a blade (a thin rounded segment).
//!
//! Every shape is a union of at most [`MAX_PARTS`] *capsule parts* (a segment with a radius; a sphere
//! is a capsule of length zero), so contact and continuous detection deal with one primitive. The tool
//! frame's origin is the tool's reference point (the tip: feedback torques are taken about it) and its
//! +z axis is the direction the instrument points to: a shaft runs from the tip back along −z.
//!
//! A tool's pose comes either from a script of keyframes (positions interpolated linearly,
//! orientations by slerp, jaw linearly; held before the first and after the last keyframe) or from
//! outside (`input = "ipc"`: the daemon sets it each tick with [`Tool::set_target`]).

use nalgebra::UnitQuaternion;

use crate::Vec3;

/// Largest number of capsule parts in a tool shape.
pub const MAX_PARTS: usize = 3;

/// The geometry of a tool, in its own frame.
#[derive(Clone, Debug, PartialEq)]
pub enum ToolShape {
    /// A ball of this radius centred on the tip.
    Sphere {
        /// m.
        radius: f64,
    },
    /// A laparoscopic instrument: a shaft of this radius from the tip back `length` metres along −z,
    /// rounded at both ends.
    Capsule {
        /// m.
        radius: f64,
        /// m.
        length: f64,
    },
    /// A grasper: two jaws hinged at the tip, each a rounded segment of `jaw_length` pointing along +z,
    /// its axis a radius to the side of the tool's (so that closed jaws meet along their inner faces),
    /// and rotated by ± half the opening about the tool's y axis, plus a shaft behind the hinge.
    Grasper {
        /// Length of each jaw (m).
        jaw_length: f64,
        /// Radius of the jaws and the shaft (m).
        radius: f64,
        /// Length of the shaft behind the hinge (m); 0 for none.
        shaft_length: f64,
    },
    /// A blade: a thin rounded segment from the tip along +z.
    Blade {
        /// m.
        length: f64,
        /// Full thickness (m).
        thickness: f64,
    },
}

/// When a grasper holds what is between its jaws (scene keys in its `grasper` table).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GraspSettings {
    /// The jaws grasp when both touch tissue and the opening is at most this (rad).
    pub grasp_below: f64,
    /// Grasped nodes are let go when the opening grows past this (rad); above `grasp_below`.
    pub release_above: f64,
    /// Free nodes within this distance of a jaw's surface are grasped too (m).
    pub reach: f64,
}

impl Default for GraspSettings {
    fn default() -> Self {
        Self {
            grasp_below: 0.05,
            release_above: 0.5,
            reach: 0.0,
        }
    }
}

/// A capsule: the points within `radius` of the segment from `a` to `b`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CapsulePart {
    /// Segment start.
    pub a: Vec3,
    /// Segment end.
    pub b: Vec3,
    /// m.
    pub radius: f64,
}

impl CapsulePart {
    /// Closest point of the segment to `p`.
    pub fn closest_on_segment(&self, p: &Vec3) -> Vec3 {
        let ab = self.b - self.a;
        let length_squared = ab.norm_squared();
        if length_squared <= f64::MIN_POSITIVE {
            return self.a;
        }
        let s = ((p - self.a).dot(&ab) / length_squared).clamp(0.0, 1.0);
        self.a + ab * s
    }

    /// Signed distance of `p` to the capsule surface (negative inside).
    pub fn signed_distance(&self, p: &Vec3) -> f64 {
        (p - self.closest_on_segment(p)).norm() - self.radius
    }

    /// The closest surface point to `p` and the outward normal there. A point exactly on the segment
    /// gets `fallback_normal`.
    pub fn project_to_surface(&self, p: &Vec3, fallback_normal: &Vec3) -> (Vec3, Vec3) {
        let axis_point = self.closest_on_segment(p);
        let offset = p - axis_point;
        let distance = offset.norm();
        let normal = if distance > 1e-15 {
            offset / distance
        } else {
            *fallback_normal
        };
        (axis_point + normal * self.radius, normal)
    }

    /// The same capsule placed by a pose.
    pub fn placed(&self, pose: &ToolPose) -> CapsulePart {
        CapsulePart {
            a: pose.position_in_world + pose.world_from_tool * self.a,
            b: pose.position_in_world + pose.world_from_tool * self.b,
            radius: self.radius,
        }
    }
}

impl ToolShape {
    /// The capsule parts in the tool frame for a jaw opening (rad); returns how many are used.
    pub fn parts_in_tool(&self, jaw: f64, parts: &mut [CapsulePart; MAX_PARTS]) -> usize {
        match *self {
            ToolShape::Sphere { radius } => {
                parts[0] = CapsulePart {
                    a: Vec3::zeros(),
                    b: Vec3::zeros(),
                    radius,
                };
                1
            }
            ToolShape::Capsule { radius, length } => {
                parts[0] = CapsulePart {
                    a: Vec3::zeros(),
                    b: Vec3::new(0.0, 0.0, -length),
                    radius,
                };
                1
            }
            ToolShape::Grasper {
                jaw_length,
                radius,
                shaft_length,
            } => {
                let half = 0.5 * jaw.max(0.0);
                let (s, c) = (crate::math::sin(half), crate::math::cos(half));
                for (k, sign) in [1.0, -1.0].into_iter().enumerate() {
                    // Each jaw's axis lies a radius off the tool's axis, so that closed jaws (opening
                    // 0) meet along their inner faces, as a real grasper's do; the jaw turns about
                    // the tool's y axis through the tip.
                    let direction = Vec3::new(sign * s, 0.0, c);
                    let offset = Vec3::new(sign * radius * c, 0.0, -radius * s);
                    parts[k] = CapsulePart {
                        a: offset,
                        b: offset + direction * jaw_length,
                        radius,
                    };
                }
                if shaft_length > 0.0 {
                    parts[2] = CapsulePart {
                        a: Vec3::zeros(),
                        b: Vec3::new(0.0, 0.0, -shaft_length),
                        radius,
                    };
                    3
                } else {
                    2
                }
            }
            ToolShape::Blade { length, thickness } => {
                parts[0] = CapsulePart {
                    a: Vec3::zeros(),
                    b: Vec3::new(0.0, 0.0, length),
                    radius: 0.5 * thickness,
                };
                1
            }
        }
    }
}

/// Where a tool is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolPose {
    /// The tip (m, world frame).
    pub position_in_world: Vec3,
    /// world_from_tool rotation.
    pub world_from_tool: UnitQuaternion<f64>,
}

impl Default for ToolPose {
    fn default() -> Self {
        Self {
            position_in_world: Vec3::zeros(),
            world_from_tool: UnitQuaternion::identity(),
        }
    }
}

impl ToolPose {
    /// A point given in the tool frame, in the world.
    pub fn to_world(&self, p_in_tool: &Vec3) -> Vec3 {
        self.position_in_world + self.world_from_tool * p_in_tool
    }

    /// A world point in the tool frame.
    pub fn to_tool(&self, p_in_world: &Vec3) -> Vec3 {
        self.world_from_tool
            .inverse_transform_vector(&(p_in_world - self.position_in_world))
    }
}

/// One keyframe of a scripted tool.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe {
    /// Time (s).
    pub t: f64,
    /// Pose at that time.
    pub pose: ToolPose,
    /// Jaw opening (rad).
    pub jaw: f64,
}

/// Where a tool's pose comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum ToolInput {
    /// Keyframes in increasing time.
    Script(Vec<Keyframe>),
    /// Set from outside each tick (the daemon's shared-memory input).
    Ipc,
}

impl ToolInput {
    /// The scripted pose and jaw at time `t`; `None` for external input.
    pub fn sample(&self, t: f64) -> Option<(ToolPose, f64)> {
        let ToolInput::Script(keys) = self else {
            return None;
        };
        let first = keys.first()?;
        let last = keys.last()?;
        if t <= first.t {
            return Some((first.pose, first.jaw));
        }
        if t >= last.t {
            return Some((last.pose, last.jaw));
        }
        // keys[k].t <= t < keys[k + 1].t
        let k = keys.partition_point(|key| key.t <= t) - 1;
        let (a, b) = (&keys[k], &keys[k + 1]);
        let s = (t - a.t) / (b.t - a.t);
        let pose = ToolPose {
            position_in_world: a.pose.position_in_world.lerp(&b.pose.position_in_world, s),
            world_from_tool: crate::math::try_slerp(
                &a.pose.world_from_tool,
                &b.pose.world_from_tool,
                s,
                1e-12,
            )
            .unwrap_or(a.pose.world_from_tool),
        };
        Some((pose, a.jaw + (b.jaw - a.jaw) * s))
    }
}

/// What a tool feels this tick: the force and torque the tissue exerts on it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Feedback {
    /// Force on the tool (N, world frame), after the `max_force` clamp.
    pub force_in_world: Vec3,
    /// Torque on the tool about its tip (N·m, world frame).
    pub torque_in_world: Vec3,
    /// Contacts with the tool at the end of the tick: nodes it holds, and triangles it presses
    /// between their nodes (`faces`).
    pub contacts: u32,
    /// The force was scaled down to `max_force`.
    pub clamped: bool,
    /// Σ of the normal force magnitudes of the contact nodes (N), before clamping.
    pub normal_force: f64,
    /// Σ of the tangential (friction) force magnitudes of the contact nodes (N), before clamping.
    pub friction_force: f64,
    /// Contact nodes sliding on the tool this tick.
    pub sliding: u32,
    /// Nodes a grasper holds in its jaws' frames this tick.
    pub grasped: u32,
    /// Of the contacts, triangles the tool pressed between their nodes this tick
    /// (`crate::contact::tool_faces`).
    pub faces: u32,
}

/// A rigid tool.
#[derive(Clone, Debug)]
pub struct Tool {
    /// Name from the scene.
    pub name: String,
    /// Geometry.
    pub shape: ToolShape,
    /// Pose source.
    pub input: ToolInput,
    /// Largest force magnitude sent to the device (N), if any.
    pub max_force: Option<f64>,
    /// Pose at the start of the tick being computed (after a step: the current pose).
    pub previous_pose: ToolPose,
    /// Pose at the end of the tick being computed (after a step: the current pose).
    pub pose: ToolPose,
    /// Jaw opening at the start of the tick (rad).
    pub previous_jaw: f64,
    /// Jaw opening at the end of the tick (rad).
    pub jaw: f64,
    /// Capsule parts in the world at the start of the tick.
    pub parts_start: [CapsulePart; MAX_PARTS],
    /// Capsule parts in the world at the end of the tick.
    pub parts_end: [CapsulePart; MAX_PARTS],
    /// Capsule parts in the tool frame at the end of the tick.
    pub parts_in_tool: [CapsulePart; MAX_PARTS],
    /// How many parts are used.
    pub part_count: usize,
    /// Feedback of the last tick.
    pub feedback: Feedback,
    /// Target set from outside for the next tick (IPC input).
    target: Option<(ToolPose, f64)>,
    /// False for an externally driven tool until its first pose arrives: until then it has no parts
    /// and touches nothing, and its first pose places it without sweeping from the origin.
    pub active: bool,
    /// How a grasper grasps (`None` for other shapes).
    pub grasp: Option<GraspSettings>,
    /// Whether the grasper holds what is between its jaws.
    pub grasping: bool,
}

impl Tool {
    /// A tool at its input's pose for time 0 (or the origin for IPC input until a pose arrives).
    pub fn new(name: &str, shape: ToolShape, input: ToolInput, max_force: Option<f64>) -> Self {
        let (pose, jaw) = input.sample(0.0).unwrap_or((ToolPose::default(), 0.0));
        let mut tool = Self {
            name: name.to_string(),
            shape,
            input,
            max_force,
            previous_pose: pose,
            pose,
            previous_jaw: jaw,
            jaw,
            parts_start: [CapsulePart::default(); MAX_PARTS],
            parts_end: [CapsulePart::default(); MAX_PARTS],
            parts_in_tool: [CapsulePart::default(); MAX_PARTS],
            part_count: 0,
            feedback: Feedback::default(),
            target: None,
            active: false,
            grasp: None,
            grasping: false,
        };
        if matches!(tool.shape, ToolShape::Grasper { .. }) {
            tool.grasp = Some(GraspSettings::default());
        }
        tool.active = matches!(tool.input, ToolInput::Script(_));
        tool.place();
        tool.parts_start = tool.parts_end;
        tool
    }

    /// Sets the pose and jaw the tool moves to during the next tick (external input).
    pub fn set_target(&mut self, pose: ToolPose, jaw: f64) {
        self.target = Some((pose, jaw));
    }

    /// Takes an externally driven tool out of the scene (its bridge went quiet): it touches nothing
    /// and releases what it held, until a new pose makes it appear again.
    pub fn deactivate(&mut self) {
        if matches!(self.input, ToolInput::Ipc) {
            self.active = false;
            self.target = None;
            self.place();
            self.parts_start = self.parts_end;
        }
    }

    /// Begins a tick ending at time `t_end`: the current pose becomes the start, the new pose comes
    /// from the script or the last external target (held when none arrived).
    pub fn begin_tick(&mut self, t_end: f64) {
        if !self.active && self.target.is_some() {
            // First external pose: the tool appears there, it does not sweep from the origin.
            let (pose, jaw) = self.target.expect("checked");
            self.pose = pose;
            self.jaw = jaw;
            self.active = true;
            self.place();
        }
        self.previous_pose = self.pose;
        self.previous_jaw = self.jaw;
        self.parts_start = self.parts_end;
        if let Some((pose, jaw)) = self.input.sample(t_end).or(self.target) {
            self.pose = pose;
            self.jaw = jaw;
        }
        self.place();
    }

    fn place(&mut self) {
        if !self.active {
            self.part_count = 0;
            return;
        }
        self.part_count = self.shape.parts_in_tool(self.jaw, &mut self.parts_in_tool);
        for k in 0..self.part_count {
            self.parts_end[k] = self.parts_in_tool[k].placed(&self.pose);
        }
    }

    /// Velocity of a point fixed in the tool frame over the tick (m/s), from its start and end.
    pub fn point_velocity(&self, p_in_tool: &Vec3, dt: f64) -> Vec3 {
        (self.pose.to_world(p_in_tool) - self.previous_pose.to_world(p_in_tool)) / dt
    }

    /// Signed distance of `p` to the tool at the end of the tick (negative inside) and the part.
    pub fn signed_distance(&self, p: &Vec3) -> (f64, usize) {
        let mut best = (f64::INFINITY, 0);
        for k in 0..self.part_count {
            let d = self.parts_end[k].signed_distance(p);
            if d < best.0 {
                best = (d, k);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn script_interpolates_and_holds() {
        let key = |t: f64, x: f64, jaw: f64| Keyframe {
            t,
            pose: ToolPose {
                position_in_world: Vec3::new(x, 0.0, 0.0),
                world_from_tool: UnitQuaternion::from_euler_angles(0.0, 0.0, x),
            },
            jaw,
        };
        let input = ToolInput::Script(vec![
            key(0.0, 0.0, 0.0),
            key(1.0, 1.0, 0.5),
            key(3.0, 0.0, 0.5),
        ]);
        let (p, jaw) = input.sample(0.5).unwrap();
        assert!((p.position_in_world.x - 0.5).abs() < 1e-15);
        assert!((p.world_from_tool.angle() - 0.5).abs() < 1e-12);
        assert!((jaw - 0.25).abs() < 1e-15);
        assert_eq!(input.sample(-1.0).unwrap().0.position_in_world.x, 0.0);
        assert_eq!(input.sample(2.0).unwrap().0.position_in_world.x, 0.5);
        assert_eq!(input.sample(9.0).unwrap().0.position_in_world.x, 0.0);
        assert!(ToolInput::Ipc.sample(0.0).is_none());
    }

    #[test]
    fn grasper_jaws_open_symmetrically() {
        let shape = ToolShape::Grasper {
            jaw_length: 0.02,
            radius: 0.002,
            shaft_length: 0.1,
        };
        let mut parts = [CapsulePart::default(); MAX_PARTS];
        assert_eq!(shape.parts_in_tool(0.6, &mut parts), 3);
        assert!((parts[0].b.x + parts[1].b.x).abs() < 1e-15);
        let opening = (parts[0].b - parts[0].a).angle(&(parts[1].b - parts[1].a));
        assert!((opening - 0.6).abs() < 1e-12);
        // Closed, the jaws lie side by side and meet along their inner faces (at x = 0).
        shape.parts_in_tool(0.0, &mut parts);
        assert!((parts[0].a.x - 0.002).abs() < 1e-15 && (parts[1].a.x + 0.002).abs() < 1e-15);
        assert!((parts[0].b.x - 0.002).abs() < 1e-15 && parts[0].b.z == 0.02);
    }
}
