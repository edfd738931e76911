//! The virtual rigid component of a body (MODEL.md §1, §3): it never collides; it feels gravity, air
//! viscosity and the reactions of the links, and carries the homologues of the surface nodes.
//!
//! Rotation is integrated through the angular momentum `L = I ω` in the world frame (the paper's
//! "integrate I ω with the torque"), the angular velocity recovered with the world-frame inverse
//! inertia `R I⁻¹ Rᵀ`, and `ω Δt` composed into the orientation quaternion as an axis–angle rotation.
//! Storing `L` rather than `ω` makes a torque-free body conserve its angular momentum exactly.

use super::Placement;
use crate::Vec3;
use crate::math::quaternion_from_scaled_axis;
use nalgebra::{Matrix3, UnitQuaternion};

/// Rigid component state and constants.
#[derive(Clone, Debug)]
pub struct RigidComponent {
    /// Mass M (kg).
    pub mass: f64,
    /// Inertia tensor in the body frame (kg·m²).
    pub inertia_in_body: Matrix3<f64>,
    /// Its inverse, computed once.
    pub inverse_inertia_in_body: Matrix3<f64>,
    /// Position X of the body frame's origin (m, world frame).
    pub position_in_world: Vec3,
    /// Orientation q (world_from_body).
    pub world_from_body: UnitQuaternion<f64>,
    /// Linear velocity V (m/s, world frame).
    pub velocity_in_world: Vec3,
    /// Angular momentum L = I ω (kg·m²/s, world frame).
    pub angular_momentum_in_world: Vec3,
    /// Air viscosity per unit mass ν (1/s).
    pub air_viscosity: f64,
    /// Held in place (never integrated).
    pub fixed: bool,
    /// Force accumulated during the step (N, world frame).
    pub force_in_world: Vec3,
    /// Torque about X accumulated during the step (N·m, world frame).
    pub torque_in_world: Vec3,
}

impl RigidComponent {
    /// A rigid component at the given placement.
    pub fn new(
        mass: f64,
        inertia_in_body: Matrix3<f64>,
        placement: &Placement,
        air_viscosity: f64,
        fixed: bool,
    ) -> Self {
        let inverse_inertia_in_body = inertia_in_body
            .try_inverse()
            .unwrap_or_else(|| Matrix3::identity() / mass);
        let mut rigid = Self {
            mass,
            inertia_in_body,
            inverse_inertia_in_body,
            position_in_world: placement.position_in_world,
            world_from_body: placement.world_from_body,
            velocity_in_world: placement.velocity_in_world,
            angular_momentum_in_world: Vec3::zeros(),
            air_viscosity,
            fixed,
            force_in_world: Vec3::zeros(),
            torque_in_world: Vec3::zeros(),
        };
        rigid.angular_momentum_in_world =
            rigid.inertia_in_world() * placement.angular_velocity_in_world;
        if fixed {
            rigid.velocity_in_world = Vec3::zeros();
            rigid.angular_momentum_in_world = Vec3::zeros();
        }
        rigid
    }

    /// Inertia tensor in the world frame, `R I Rᵀ`.
    pub fn inertia_in_world(&self) -> Matrix3<f64> {
        let r = self.world_from_body.to_rotation_matrix();
        r.matrix() * self.inertia_in_body * r.matrix().transpose()
    }

    /// Angular velocity ω = R I⁻¹ Rᵀ L (rad/s, world frame).
    pub fn angular_velocity_in_world(&self) -> Vec3 {
        let r = self.world_from_body.to_rotation_matrix();
        r * (self.inverse_inertia_in_body * (r.inverse() * self.angular_momentum_in_world))
    }

    /// Translational plus rotational kinetic energy (J).
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.mass * self.velocity_in_world.norm_squared()
            + 0.5
                * self
                    .angular_velocity_in_world()
                    .dot(&self.angular_momentum_in_world)
    }

    /// True when the state is finite.
    pub fn is_finite(&self) -> bool {
        self.position_in_world
            .iter()
            .chain(self.velocity_in_world.iter())
            .chain(self.angular_momentum_in_world.iter())
            .all(|x| x.is_finite())
            && self.world_from_body.coords.iter().all(|x| x.is_finite())
    }

    /// Starts a step: gravity and air viscosity, the volume forces (links add their reactions after).
    pub fn reset_forces(&mut self, gravity: &Vec3) {
        self.force_in_world =
            gravity * self.mass - self.velocity_in_world * (self.air_viscosity * self.mass);
        // −Γ_ω ω with Γ_ω = ν I (world): the torque is −ν L.
        self.torque_in_world = -self.angular_momentum_in_world * self.air_viscosity;
    }

    /// Semi-implicit Euler: velocity then position with the new velocity; angular momentum then
    /// orientation with the new angular velocity.
    pub fn integrate(&mut self, dt: f64) {
        if self.fixed {
            return;
        }
        self.velocity_in_world += self.force_in_world * (dt / self.mass);
        self.position_in_world += self.velocity_in_world * dt;
        self.angular_momentum_in_world += self.torque_in_world * dt;
        // ω for the rotation over the step is read at the half-step orientation (predicted with the
        // start-of-step ω): the same composition as the paper, with an energy drift of O(Δt²)
        // instead of O(Δt) on an asymmetric body.
        let start = self.world_from_body;
        let omega_start = self.angular_velocity_in_world();
        self.world_from_body = quaternion_from_scaled_axis(&(omega_start * (0.5 * dt))) * start;
        let omega = self.angular_velocity_in_world();
        let rotation = quaternion_from_scaled_axis(&(omega * dt));
        self.world_from_body = UnitQuaternion::new_normalize((rotation * start).into_inner());
    }
}
