//! Fixed obstacles (MODEL.md §4, §8): infinite planes at any orientation and oriented boxes.
//!
//! Queries take world-frame points. A contact is described by the plane it must be resolved against:
//! an outward unit normal and a point on the surface, so planes and box faces are handled alike.

use crate::Vec3;
use nalgebra::UnitQuaternion;

/// The geometry of a fixed obstacle.
#[derive(Clone, Debug, PartialEq)]
pub enum ObstacleShape {
    /// Half-space below a plane; the normal points out of the obstacle (into free space).
    Plane {
        /// A point on the plane (m, world frame).
        point_in_world: Vec3,
        /// Unit outward normal (world frame).
        normal_in_world: Vec3,
    },
    /// A solid oriented box.
    Box {
        /// Centre (m, world frame).
        center_in_world: Vec3,
        /// Half of the size along each box axis (m).
        half_extents: Vec3,
        /// world_from_box rotation.
        world_from_box: UnitQuaternion<f64>,
    },
}

/// A fixed obstacle with its friction coefficients.
#[derive(Clone, Debug, PartialEq)]
pub struct Obstacle {
    /// Name from the scene.
    pub name: String,
    /// Geometry.
    pub shape: ObstacleShape,
    /// Kinetic Coulomb coefficient against tissue.
    pub friction: f64,
    /// Static Coulomb coefficient against tissue (≥ the kinetic one in physical scenes).
    pub static_friction: f64,
}

/// The plane a penetrating point is pushed back to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactPlane {
    /// Unit outward normal (world frame).
    pub normal_in_world: Vec3,
    /// A point on the obstacle surface (m, world frame).
    pub point_in_world: Vec3,
}

impl ContactPlane {
    /// Signed distance of `p` to the plane, negative below it.
    pub fn signed_distance(&self, p: &Vec3) -> f64 {
        (p - self.point_in_world).dot(&self.normal_in_world)
    }
}

impl ObstacleShape {
    /// The plane itself when the shape is a plane (the contact stages' fast path).
    pub fn as_plane(&self) -> Option<ContactPlane> {
        match self {
            ObstacleShape::Plane {
                point_in_world,
                normal_in_world,
            } => Some(ContactPlane {
                normal_in_world: *normal_in_world,
                point_in_world: *point_in_world,
            }),
            _ => None,
        }
    }

    /// Signed distance of `p` to the obstacle surface: negative inside.
    pub fn signed_distance(&self, p: &Vec3) -> f64 {
        match self {
            ObstacleShape::Plane {
                point_in_world,
                normal_in_world,
            } => (p - point_in_world).dot(normal_in_world),
            ObstacleShape::Box {
                center_in_world,
                half_extents,
                world_from_box,
            } => {
                let local = world_from_box.inverse_transform_vector(&(p - center_in_world));
                let q = local.abs() - half_extents;
                let outside = q.sup(&Vec3::zeros()).norm();
                let inside = q.x.max(q.y).max(q.z).min(0.0);
                outside + inside
            }
        }
    }

    /// The plane of the obstacle's surface that `p` lies within `margin` of (outside) or behind:
    /// the plane itself, or for a box the face nearest to `p` when `p` is within the box grown by
    /// `margin` (the plane a node resting on the obstacle is held by). `None` farther out.
    pub fn plane_within(&self, p: &Vec3, margin: f64) -> Option<ContactPlane> {
        match self {
            ObstacleShape::Plane { .. } => self
                .as_plane()
                .filter(|plane| plane.signed_distance(p) <= margin),
            ObstacleShape::Box {
                center_in_world,
                half_extents,
                world_from_box,
            } => {
                let local = world_from_box.inverse_transform_vector(&(p - center_in_world));
                let q = local.abs() - half_extents;
                if q.x > margin || q.y > margin || q.z > margin {
                    return None;
                }
                Some(box_face(
                    center_in_world,
                    half_extents,
                    world_from_box,
                    nearest_face(&local, half_extents),
                ))
            }
        }
    }

    /// If a point moving from `start` to `end` ends inside the obstacle, the plane to push it back to:
    /// for a box, the face the segment entered through (the nearest face when it started inside).
    pub fn contact_plane(&self, start: &Vec3, end: &Vec3) -> Option<ContactPlane> {
        match self {
            ObstacleShape::Plane { .. } => self
                .as_plane()
                .filter(|plane| plane.signed_distance(end) < 0.0),
            ObstacleShape::Box {
                center_in_world,
                half_extents,
                world_from_box,
            } => {
                let end_local = world_from_box.inverse_transform_vector(&(end - center_in_world));
                let q = end_local.abs() - half_extents;
                if q.x >= 0.0 || q.y >= 0.0 || q.z >= 0.0 {
                    return None;
                }
                let start_local =
                    world_from_box.inverse_transform_vector(&(start - center_in_world));
                let face = entry_face(&start_local, &end_local, half_extents)
                    .unwrap_or_else(|| nearest_face(&end_local, half_extents));
                Some(box_face(
                    center_in_world,
                    half_extents,
                    world_from_box,
                    face,
                ))
            }
        }
    }
}

/// The plane of face (`axis`, `sign`) of a box, in the world frame.
fn box_face(
    center_in_world: &Vec3,
    half_extents: &Vec3,
    world_from_box: &UnitQuaternion<f64>,
    (axis, sign): (usize, f64),
) -> ContactPlane {
    let mut normal_local = Vec3::zeros();
    normal_local[axis] = sign;
    let mut point_local = Vec3::zeros();
    point_local[axis] = sign * half_extents[axis];
    ContactPlane {
        normal_in_world: world_from_box * normal_local,
        point_in_world: center_in_world + world_from_box * point_local,
    }
}

/// The face (axis, sign) a segment from outside the box enters through, by the slab method; `None`
/// when the start is inside.
fn entry_face(start: &Vec3, end: &Vec3, half: &Vec3) -> Option<(usize, f64)> {
    let q = start.abs() - half;
    if q.x < 0.0 && q.y < 0.0 && q.z < 0.0 {
        return None;
    }
    let d = end - start;
    let mut t_enter = f64::NEG_INFINITY;
    let mut face = None;
    for axis in 0..3 {
        if d[axis] == 0.0 {
            continue;
        }
        // The slab's near side, given the direction of motion.
        let sign = if d[axis] > 0.0 { -1.0 } else { 1.0 };
        let t = (sign * half[axis] - start[axis]) / d[axis];
        if t > t_enter {
            t_enter = t;
            face = Some((axis, sign));
        }
    }
    face
}

/// The face nearest to a point inside the box.
fn nearest_face(p: &Vec3, half: &Vec3) -> (usize, f64) {
    let mut best = (0, 1.0);
    let mut best_depth = f64::INFINITY;
    for axis in 0..3 {
        let depth = half[axis] - p[axis].abs();
        if depth < best_depth {
            best_depth = depth;
            best = (axis, if p[axis] >= 0.0 { 1.0 } else { -1.0 });
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> ObstacleShape {
        ObstacleShape::Box {
            center_in_world: Vec3::zeros(),
            half_extents: Vec3::new(1.0, 1.0, 1.0),
            world_from_box: UnitQuaternion::identity(),
        }
    }

    #[test]
    fn box_signed_distance_inside_and_outside() {
        let b = unit_box();
        assert_eq!(b.signed_distance(&Vec3::new(0.0, 0.0, 0.5)), -0.5);
        assert_eq!(b.signed_distance(&Vec3::new(0.0, 0.0, 3.0)), 2.0);
        assert!((b.signed_distance(&Vec3::new(2.0, 2.0, 0.0)) - 2f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn the_plane_within_a_margin_is_the_nearest_face() {
        let b = unit_box();
        // Within the margin above the top face, and just inside it near the +x face.
        let top = b.plane_within(&Vec3::new(0.2, 0.1, 1.0005), 1e-3).unwrap();
        assert_eq!(top.normal_in_world, Vec3::z());
        assert_eq!(top.point_in_world, Vec3::new(0.0, 0.0, 1.0));
        let side = b.plane_within(&Vec3::new(0.99, 0.2, -0.5), 1e-3).unwrap();
        assert_eq!(side.normal_in_world, Vec3::x());
        assert!(b.plane_within(&Vec3::new(0.0, 0.0, 1.002), 1e-3).is_none());
        let floor = ObstacleShape::Plane {
            point_in_world: Vec3::zeros(),
            normal_in_world: Vec3::z(),
        };
        assert!(
            floor
                .plane_within(&Vec3::new(5.0, 0.0, 0.0009), 1e-3)
                .is_some()
        );
        assert!(
            floor
                .plane_within(&Vec3::new(5.0, 0.0, -0.3), 1e-3)
                .is_some()
        );
        assert!(
            floor
                .plane_within(&Vec3::new(5.0, 0.0, 0.0011), 1e-3)
                .is_none()
        );
    }

    #[test]
    fn box_contact_uses_the_face_a_fast_point_entered_through() {
        let b = unit_box();
        // Enters through +z but ends nearer the +x face.
        let plane = b
            .contact_plane(&Vec3::new(0.9, 0.0, 1.5), &Vec3::new(0.95, 0.0, 0.0))
            .unwrap();
        assert_eq!(plane.normal_in_world, Vec3::z());
        assert!(
            b.contact_plane(&Vec3::zeros(), &Vec3::new(0.0, 0.0, 2.0))
                .is_none()
        );
    }
}
