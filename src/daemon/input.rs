//! Input hygiene for poses arriving from device bridges: every pose is checked before it may move a
//! tool, and a tool whose bridge went quiet is marked disconnected.
//!
//! A pose is rejected (and counted) when a number is not finite, the quaternion is not unit within
//! tolerance, its sequence number does not increase, or it jumps farther from the last good pose than
//! the speed limit allows in the time between them — measured on the daemon's receive clock (its
//! ticks between the two accepted poses), never on the bridge's `device_time_ns`; the tool then
//! keeps its last good pose. A tool
//! with no accepted pose for `stale_after_ticks` is disconnected: its history is forgotten, so a
//! restarted bridge (whose sequence starts again) or one that connects late is picked up with its
//! first good pose, wherever that is.

use nalgebra::{Quaternion, UnitQuaternion};

use crate::Vec3;
use crate::ipc::payload::ToolPoseV1;
use crate::tool::ToolPose;

/// Limits of the input checks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InputLimits {
    /// Fastest believable tool motion (m/s).
    pub max_speed: f64,
    /// Allowed deviation of the quaternion's norm from 1.
    pub quaternion_tolerance: f64,
    /// Ticks without an accepted pose after which a tool is disconnected.
    pub stale_after_ticks: u64,
}

impl Default for InputLimits {
    fn default() -> Self {
        Self {
            max_speed: 10.0,
            quaternion_tolerance: 1e-3,
            stale_after_ticks: 100,
        }
    }
}

/// Why a pose was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rejection {
    /// A NaN or infinite number.
    NonFinite,
    /// The quaternion's norm is not 1 within tolerance (a zero quaternion included).
    NotUnitQuaternion,
    /// The sequence number did not increase.
    SequenceBackwards,
    /// Farther from the last good pose than the speed limit allows.
    TooFast,
    /// A coordinate beyond [`MAX_COORDINATE`]: no device's.
    OutOfReach,
}

/// The largest coordinate a pose may have (m). A first pose (or the first after the tool went
/// stale) is taken wherever it is, with no last pose to bound its jump: one at 1e300 m was taken,
/// and the speed check then refused every real pose until the tool went stale again (found by an
/// integrator's bridge, 2026-12-07).
pub const MAX_COORDINATE: f64 = 1000.0;

/// The input state of one externally driven tool.
#[derive(Clone, Debug, Default)]
pub struct ToolInputState {
    last_good: Option<ToolPoseV1>,
    last_good_tick: u64,
    /// Whether the tool has a fresh pose.
    pub connected: bool,
    /// Poses rejected so far.
    pub rejected: u64,
    /// Times the tool went stale.
    pub disconnects: u64,
    /// A pose offered since the last step was rejected (cleared when a step's feedback is sent:
    /// a rejection while the daemon is paused flags the first step after it, as a replay of the
    /// recording does).
    pub rejected_this_tick: bool,
}

impl ToolInputState {
    /// Checks a pose received at `tick` of the daemon's clock (`dt` its period); on acceptance it
    /// becomes the last good pose and is returned as a tool pose and jaw.
    pub fn offer(
        &mut self,
        pose: &ToolPoseV1,
        tick: u64,
        dt: f64,
        limits: &InputLimits,
    ) -> Result<(ToolPose, f64), Rejection> {
        let result = self.check(pose, tick, dt, limits);
        self.rejected_this_tick |= result.is_err();
        match result {
            Ok(accepted) => {
                self.last_good = Some(*pose);
                self.last_good_tick = tick;
                self.connected = true;
                Ok(accepted)
            }
            Err(reason) => {
                self.rejected += 1;
                Err(reason)
            }
        }
    }

    fn check(
        &self,
        pose: &ToolPoseV1,
        tick: u64,
        dt: f64,
        limits: &InputLimits,
    ) -> Result<(ToolPose, f64), Rejection> {
        let numbers = pose
            .position
            .iter()
            .chain(&pose.orientation)
            .chain([&pose.jaw]);
        if numbers.into_iter().any(|x| !x.is_finite()) {
            return Err(Rejection::NonFinite);
        }
        if pose.position.iter().any(|x| x.abs() > MAX_COORDINATE) {
            return Err(Rejection::OutOfReach);
        }
        let [w, x, y, z] = pose.orientation;
        let q = Quaternion::new(w, x, y, z);
        if (q.norm() - 1.0).abs() > limits.quaternion_tolerance {
            return Err(Rejection::NotUnitQuaternion);
        }
        let position = Vec3::from(pose.position);
        if let Some(last) = &self.last_good
            && self.connected
        {
            if pose.seq <= last.seq {
                return Err(Rejection::SequenceBackwards);
            }
            // The daemon's own clock, never the bridge's `device_time_ns`: a bridge cannot widen
            // its own limit by jumping its time stamps.
            let elapsed = tick.saturating_sub(self.last_good_tick).max(1) as f64 * dt;
            if (position - Vec3::from(last.position)).norm() > limits.max_speed * elapsed {
                return Err(Rejection::TooFast);
            }
        }
        let tool_pose = ToolPose {
            position_in_world: position,
            world_from_tool: UnitQuaternion::from_quaternion(q),
        };
        Ok((tool_pose, pose.jaw.max(0.0)))
    }

    /// Advances the staleness clock to `tick`; returns true when the tool just went stale.
    pub fn update_staleness(&mut self, tick: u64, limits: &InputLimits) -> bool {
        if self.connected && tick.saturating_sub(self.last_good_tick) > limits.stale_after_ticks {
            self.connected = false;
            self.disconnects += 1;
            return true;
        }
        false
    }

    /// The last accepted pose (its `seq` and `device_time_ns` are echoed in feedback).
    pub fn last_good(&self) -> Option<&ToolPoseV1> {
        self.last_good.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(seq: u64, x: f64) -> ToolPoseV1 {
        ToolPoseV1 {
            seq,
            device_time_ns: seq * 1_000_000,
            position: [x, 0.0, 0.0],
            orientation: [1.0, 0.0, 0.0, 0.0],
            ..ToolPoseV1::default()
        }
    }

    #[test]
    fn bad_poses_are_rejected_and_the_next_good_one_is_used() {
        let limits = InputLimits::default();
        let mut state = ToolInputState::default();
        assert!(state.offer(&pose(1, 0.0), 1, 0.001, &limits).is_ok());
        let mut nan = pose(2, 0.0);
        nan.position[1] = f64::NAN;
        assert_eq!(
            state.offer(&nan, 2, 0.001, &limits),
            Err(Rejection::NonFinite)
        );
        let mut zero_q = pose(3, 0.0);
        zero_q.orientation = [0.0; 4];
        assert_eq!(
            state.offer(&zero_q, 3, 0.001, &limits),
            Err(Rejection::NotUnitQuaternion)
        );
        assert_eq!(
            state.offer(&pose(4, 1.0), 4, 0.001, &limits),
            Err(Rejection::TooFast)
        );
        assert_eq!(
            state.offer(&pose(1, 0.0), 5, 0.001, &limits),
            Err(Rejection::SequenceBackwards)
        );
        assert_eq!(state.rejected, 4);
        let (good, _) = state.offer(&pose(6, 0.001), 6, 0.001, &limits).unwrap();
        assert_eq!(good.position_in_world.x, 0.001);
        // Far out of any device's reach, first pose or not.
        assert_eq!(
            state.offer(&pose(7, 1e300), 7, 0.001, &limits),
            Err(Rejection::OutOfReach)
        );
        let mut fresh = ToolInputState::default();
        assert_eq!(
            fresh.offer(&pose(1, -1001.0), 1, 0.001, &limits),
            Err(Rejection::OutOfReach)
        );
        assert!(fresh.offer(&pose(2, -999.0), 2, 0.001, &limits).is_ok());
    }

    #[test]
    fn the_speed_limit_runs_on_the_daemon_clock_not_the_bridge_time_stamps() {
        let limits = InputLimits::default();
        let mut state = ToolInputState::default();
        state.offer(&pose(1, 0.0), 10, 0.001, &limits).unwrap();
        // One tick later, 1 m away, claiming an hour passed on the device: rejected.
        let mut jump = pose(2, 1.0);
        jump.device_time_ns = 3_600_000_000_000;
        assert_eq!(
            state.offer(&jump, 11, 0.001, &limits),
            Err(Rejection::TooFast)
        );
        // 5 mm one tick after the last good pose is within 10 m/s, whatever the device time says.
        let mut near = pose(3, 0.005);
        near.device_time_ns = 0;
        assert!(state.offer(&near, 11, 0.001, &limits).is_ok());
        // 0.9 m after 100 ticks of the daemon (0.1 s) is 9 m/s: accepted.
        let mut far = pose(4, 0.905);
        far.device_time_ns = 1;
        assert!(state.offer(&far, 111, 0.001, &limits).is_ok());
    }

    #[test]
    fn a_quiet_bridge_goes_stale_and_a_restarted_one_is_picked_up() {
        let limits = InputLimits::default();
        let mut state = ToolInputState::default();
        state.offer(&pose(50, 0.0), 1, 0.001, &limits).unwrap();
        assert!(!state.update_staleness(100, &limits));
        assert!(state.update_staleness(102, &limits));
        assert!(!state.connected);
        // The restarted bridge counts from 1 again and may be anywhere.
        assert!(state.offer(&pose(1, 0.3), 150, 0.001, &limits).is_ok());
        assert!(state.connected);
        assert_eq!(state.disconnects, 1);
    }
}
