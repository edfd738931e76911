//! The few transcendental functions the physics needs, from the `libm` crate rather than the
//! platform's C library, so that a recording made on one machine replays bit for bit on another
//! (the platform's `sin`, `cos`, `acos` may differ in the last bit between C libraries and versions;
//! `libm` is the same Rust code everywhere). Square roots need no such care: IEEE 754 rounds them
//! exactly on every machine.
//!
//! The rotations here reproduce nalgebra's `UnitQuaternion::from_scaled_axis` and `try_slerp`
//! operation for operation, with the trigonometry swapped.

use crate::Vec3;
use nalgebra::{Quaternion, Unit, UnitQuaternion};

/// sin x, the same bits on every machine.
#[inline]
pub fn sin(x: f64) -> f64 {
    libm::sin(x)
}

/// cos x, the same bits on every machine.
#[inline]
pub fn cos(x: f64) -> f64 {
    libm::cos(x)
}

/// acos x, the same bits on every machine.
#[inline]
pub fn acos(x: f64) -> f64 {
    libm::acos(x)
}

/// The rotation of angle |v| about v/|v| (identity for v = 0).
pub fn quaternion_from_scaled_axis(v: &Vec3) -> UnitQuaternion<f64> {
    let angle = v.norm();
    if angle == 0.0 || !angle.is_finite() {
        return if angle == 0.0 {
            UnitQuaternion::identity()
        } else {
            // Non-finite: keep it visible to the divergence guard rather than hiding it.
            UnitQuaternion::new_unchecked(Quaternion::new(f64::NAN, 0.0, 0.0, 0.0))
        };
    }
    let axis = v / angle;
    let half = 0.5 * angle;
    let s = sin(half);
    UnitQuaternion::new_unchecked(Quaternion::from_parts(cos(half), axis * s))
}

/// Spherical interpolation a fraction `t` of the way from `a` to `b` along the shorter arc; `None`
/// when the two are half a turn apart within `epsilon` (no arc is shorter).
pub fn try_slerp(
    a: &UnitQuaternion<f64>,
    b: &UnitQuaternion<f64>,
    t: f64,
    epsilon: f64,
) -> Option<UnitQuaternion<f64>> {
    let mut other = b.coords;
    if a.coords.dot(&other) < 0.0 {
        other = -other;
    }
    let cos_half = a.coords.dot(&other);
    if cos_half.abs() >= 1.0 {
        return Some(*a);
    }
    let half = acos(cos_half);
    let sin_half = sin(half);
    if sin_half.abs() < epsilon {
        return None;
    }
    let wa = sin((1.0 - t) * half) / sin_half;
    let wb = sin(t * half) / sin_half;
    let coords = a.coords * wa + other * wb;
    Some(UnitQuaternion::new_unchecked(Quaternion::from(
        Unit::new_unchecked(coords).into_inner(),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotations_agree_with_nalgebra_to_rounding() {
        for v in [
            Vec3::new(0.3, -1.2, 2.0),
            Vec3::new(1e-9, 0.0, 0.0),
            Vec3::new(0.0, 3.1, 0.0),
        ] {
            let ours = quaternion_from_scaled_axis(&v);
            let theirs = UnitQuaternion::from_scaled_axis(v);
            assert!(ours.angle_to(&theirs) < 1e-14, "{v:?}");
        }
        assert_eq!(
            quaternion_from_scaled_axis(&Vec3::zeros()),
            UnitQuaternion::identity()
        );
        let a = UnitQuaternion::from_scaled_axis(Vec3::new(0.1, 0.2, 0.3));
        let b = UnitQuaternion::from_scaled_axis(Vec3::new(-1.0, 0.5, 2.0));
        for t in [0.0, 0.25, 0.5, 1.0] {
            let ours = try_slerp(&a, &b, t, 1e-12).unwrap();
            let theirs = a.try_slerp(&b, t, 1e-12).unwrap();
            assert!(ours.angle_to(&theirs) < 1e-14, "t = {t}");
        }
        assert!(try_slerp(&a, &a, 0.5, 1e-12).is_some());
    }
}
