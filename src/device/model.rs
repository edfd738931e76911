//! A model of a desktop haptic device held by a hand: the handle is a mass with damping, driven by the
//! hand (a spring-damper pulling it toward where the person wants to go) and by the force the daemon
//! asks the motors to render (clamped to the device's maximum); it moves inside its workspace, and its
//! position is read through encoders of finite resolution. So forces change the motion as they would
//! for a person holding a real device.

use crate::Vec3;

/// The mechanical figures of a device.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeviceSpec {
    /// Name of the preset.
    pub name: &'static str,
    /// Effective mass of the handle (kg).
    pub handle_mass: f64,
    /// Viscous damping of the mechanism (N·s/m).
    pub damping: f64,
    /// Largest force the motors render (N).
    pub max_force: f64,
    /// Half of the workspace box along x, y, z (m).
    pub workspace_half: Vec3,
    /// Encoder resolution of the position (m).
    pub resolution: f64,
}

/// Presets for common devices (maximum forces from their data sheets).
pub const PRESETS: [DeviceSpec; 3] = [
    DeviceSpec {
        name: "touch",
        handle_mass: 0.045,
        damping: 0.6,
        max_force: 3.3,
        workspace_half: Vec3::new(0.08, 0.06, 0.035),
        resolution: 0.055e-3,
    },
    DeviceSpec {
        name: "falcon",
        handle_mass: 0.15,
        damping: 1.0,
        max_force: 8.0,
        workspace_half: Vec3::new(0.05, 0.05, 0.05),
        resolution: 0.06e-3,
    },
    DeviceSpec {
        name: "omega",
        handle_mass: 0.2,
        damping: 1.5,
        max_force: 12.0,
        workspace_half: Vec3::new(0.08, 0.08, 0.06),
        resolution: 0.01e-3,
    },
];

/// The hand: a spring-damper toward the intended position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hand {
    /// N/m.
    pub stiffness: f64,
    /// N·s/m.
    pub damping: f64,
}

impl Default for Hand {
    fn default() -> Self {
        Self {
            stiffness: 400.0,
            damping: 6.0,
        }
    }
}

/// The handle's state.
#[derive(Clone, Debug)]
pub struct Device {
    /// Figures.
    pub spec: DeviceSpec,
    /// Hand.
    pub hand: Hand,
    /// Centre of the workspace in the world (m).
    pub workspace_centre: Vec3,
    /// Handle position (m, world).
    pub position: Vec3,
    /// Handle velocity (m/s, world).
    pub velocity: Vec3,
    /// Force rendered at the last step (N), after the clamp.
    pub rendered: Vec3,
}

impl Device {
    /// A device at rest at `position`, its workspace centred there.
    pub fn new(spec: DeviceSpec, hand: Hand, position: Vec3) -> Self {
        Self {
            spec,
            hand,
            workspace_centre: position,
            position,
            velocity: Vec3::zeros(),
            rendered: Vec3::zeros(),
        }
    }

    /// One step of `dt`: the hand pulls toward `target` (moving at `target_velocity`), the motors
    /// render `feedback` (clamped), the handle moves and stops at the workspace walls.
    pub fn step(&mut self, target: &Vec3, target_velocity: &Vec3, feedback: &Vec3, dt: f64) {
        let magnitude = feedback.norm();
        self.rendered = if magnitude > self.spec.max_force && magnitude > 0.0 {
            feedback * (self.spec.max_force / magnitude)
        } else {
            *feedback
        };
        let hand = (target - self.position) * self.hand.stiffness
            + (target_velocity - self.velocity) * self.hand.damping;
        let force = hand + self.rendered - self.velocity * self.spec.damping;
        self.velocity += force * (dt / self.spec.handle_mass);
        self.position += self.velocity * dt;
        for k in 0..3 {
            let lo = self.workspace_centre[k] - self.spec.workspace_half[k];
            let hi = self.workspace_centre[k] + self.spec.workspace_half[k];
            if self.position[k] < lo || self.position[k] > hi {
                self.position[k] = self.position[k].clamp(lo, hi);
                self.velocity[k] = 0.0;
            }
        }
    }

    /// The position the encoders report: each coordinate rounded to the resolution.
    pub fn measured_position(&self) -> Vec3 {
        self.position
            .map(|x| (x / self.spec.resolution).round() * self.spec.resolution)
    }
}
