//! The watchable part of a recording: Foxglove's public `foxglove.SceneUpdate` at display rate, with
//! each organ as a triangle list (one entity per body), each tool as spheres along its capsules, and
//! each tool's feedback force as an arrow from its tip (5 cm per newton). All in the "world" frame, so
//! opening the file in Foxglove shows the session in a 3D panel.
//!
//! Built on the recorder thread from the records it already receives (mesh keyframes and deltas,
//! tool inputs and feedback): nothing is added to the tick.

use foxglove::Encode;
use foxglove::messages::{
    ArrowPrimitive, Color, Point3, Pose, Quaternion, SceneEntity, SceneUpdate, SpherePrimitive,
    Timestamp, TriangleListPrimitive, Vector3,
};

use crate::Vec3;
use crate::ipc::payload::{MESH_KEYFRAME, MeshHeaderV1};
use crate::tool::{CapsulePart, MAX_PARTS, ToolPose, ToolShape};

/// Topic of the visual channel.
pub const TOPIC_SCENE_UPDATE: &str = "/foxglove/scene";

/// Metres of arrow per newton of feedback.
const ARROW_METRES_PER_NEWTON: f64 = 0.05;

/// The schema of the visual channel (name, encoding, descriptor bytes).
pub fn scene_update_schema() -> (String, String, Vec<u8>) {
    let schema = SceneUpdate::get_schema().expect("foxglove.SceneUpdate has a schema");
    (schema.name, schema.encoding, schema.data.into_owned())
}

/// What the visual channel knows of the session.
pub struct VisualState {
    bodies: Vec<(Vec<[f32; 3]>, Vec<u32>)>,
    tools: Vec<(ToolShape, Option<ToolPose>, Vec3)>,
}

impl VisualState {
    /// Empty state for `bodies` bodies and the given tool shapes.
    pub fn new(bodies: usize, tools: Vec<ToolShape>) -> Self {
        Self {
            bodies: vec![(Vec::new(), Vec::new()); bodies],
            tools: tools
                .into_iter()
                .map(|s| (s, None, Vec3::zeros()))
                .collect(),
        }
    }

    /// Makes room for `bodies` bodies (a transection added some; runs on the writer thread).
    pub fn ensure_bodies(&mut self, bodies: usize) {
        if self.bodies.len() < bodies {
            self.bodies.resize(bodies, (Vec::new(), Vec::new()));
        }
    }

    /// A tool's pose as used.
    pub fn set_tool_pose(&mut self, tool: usize, pose: ToolPose) {
        if let Some(t) = self.tools.get_mut(tool) {
            t.1 = Some(pose);
        }
    }

    /// A tool's feedback force.
    pub fn set_tool_force(&mut self, tool: usize, force: Vec3) {
        if let Some(t) = self.tools.get_mut(tool) {
            t.2 = force;
        }
    }

    /// Applies a mesh message; returns true when it completes a display tick (its body is the last).
    pub fn apply_mesh(&mut self, header: &MeshHeaderV1, data: &[u8]) -> bool {
        let f32_at =
            |at: usize| f32::from_le_bytes(data[at..at + 4].try_into().expect("four bytes"));
        let u32_at =
            |at: usize| u32::from_le_bytes(data[at..at + 4].try_into().expect("four bytes"));
        let Some((positions, triangles)) = self.bodies.get_mut(header.body as usize) else {
            return false;
        };
        let n = header.vertex_count as usize;
        if header.kind == MESH_KEYFRAME {
            *positions = (0..n)
                .map(|i| [0, 1, 2].map(|k| f32_at(12 * i + 4 * k)))
                .collect();
            *triangles = (0..3 * header.triangle_count as usize)
                .map(|k| u32_at(12 * n + 4 * k))
                .collect();
        } else if positions.len() == n {
            for e in 0..header.changed_count as usize {
                let i = u32_at(16 * e) as usize;
                if i < n {
                    positions[i] = [0, 1, 2].map(|k| f32_at(16 * e + 4 + 4 * k));
                }
            }
        }
        header.body as usize + 1 == self.bodies.len()
    }

    /// The scene at `time_ns` of simulation time, encoded.
    pub fn scene_update(
        &self,
        time_ns: u64,
        body_names: &[String],
        tool_names: &[String],
    ) -> Vec<u8> {
        let timestamp = Some(Timestamp::new(
            (time_ns / 1_000_000_000) as u32,
            (time_ns % 1_000_000_000) as u32,
        ));
        let identity = || Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        };
        let origin = || {
            Some(Pose {
                position: Some(Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                }),
                orientation: Some(identity()),
            })
        };
        let mut entities = Vec::new();
        for (b, (positions, triangles)) in self.bodies.iter().enumerate() {
            if positions.is_empty() {
                continue;
            }
            entities.push(SceneEntity {
                timestamp,
                frame_id: "world".into(),
                id: format!("body/{}", body_names.get(b).map_or("?", |s| s.as_str())),
                triangles: vec![TriangleListPrimitive {
                    pose: origin(),
                    points: positions
                        .iter()
                        .map(|p| Point3 {
                            x: p[0] as f64,
                            y: p[1] as f64,
                            z: p[2] as f64,
                        })
                        .collect(),
                    color: Some(Color {
                        r: 0.85,
                        g: 0.35,
                        b: 0.35,
                        a: 1.0,
                    }),
                    colors: Vec::new(),
                    indices: triangles.clone(),
                }],
                ..SceneEntity::default()
            });
        }
        for (t, (shape, pose, force)) in self.tools.iter().enumerate() {
            let Some(pose) = pose else { continue };
            let mut parts = [CapsulePart::default(); MAX_PARTS];
            let jaw = 0.0;
            let count = shape.parts_in_tool(jaw, &mut parts);
            let mut spheres = Vec::new();
            for part in &parts[..count] {
                let placed = part.placed(pose);
                let length = (placed.b - placed.a).norm();
                let steps = ((length / placed.radius.max(1e-4)).ceil() as usize).clamp(1, 64);
                for k in 0..=steps {
                    let c = placed.a.lerp(&placed.b, k as f64 / steps as f64);
                    spheres.push(SpherePrimitive {
                        pose: Some(Pose {
                            position: Some(Vector3 {
                                x: c.x,
                                y: c.y,
                                z: c.z,
                            }),
                            orientation: Some(identity()),
                        }),
                        size: Some(Vector3 {
                            x: 2.0 * placed.radius,
                            y: 2.0 * placed.radius,
                            z: 2.0 * placed.radius,
                        }),
                        color: Some(Color {
                            r: 0.7,
                            g: 0.7,
                            b: 0.75,
                            a: 1.0,
                        }),
                    });
                }
            }
            let mut arrows = Vec::new();
            let magnitude = force.norm();
            if magnitude > 1e-9 {
                // Rotate +x onto the force direction.
                let direction = force / magnitude;
                let rotation = nalgebra::UnitQuaternion::rotation_between(&Vec3::x(), &direction)
                    .unwrap_or_else(|| {
                        nalgebra::UnitQuaternion::from_axis_angle(
                            &Vec3::z_axis(),
                            std::f64::consts::PI,
                        )
                    });
                let q = rotation.quaternion();
                let tip = pose.position_in_world;
                arrows.push(ArrowPrimitive {
                    pose: Some(Pose {
                        position: Some(Vector3 {
                            x: tip.x,
                            y: tip.y,
                            z: tip.z,
                        }),
                        orientation: Some(Quaternion {
                            x: q.i,
                            y: q.j,
                            z: q.k,
                            w: q.w,
                        }),
                    }),
                    shaft_length: magnitude * ARROW_METRES_PER_NEWTON,
                    shaft_diameter: 0.002,
                    head_length: 0.006,
                    head_diameter: 0.005,
                    color: Some(Color {
                        r: 0.2,
                        g: 0.8,
                        b: 0.2,
                        a: 1.0,
                    }),
                });
            }
            entities.push(SceneEntity {
                timestamp,
                frame_id: "world".into(),
                id: format!("tool/{}", tool_names.get(t).map_or("?", |s| s.as_str())),
                spheres,
                arrows,
                ..SceneEntity::default()
            });
        }
        let update = SceneUpdate {
            deletions: Vec::new(),
            entities,
        };
        let mut bytes = Vec::new();
        update.encode(&mut bytes).expect("a Vec grows as needed");
        bytes
    }
}
