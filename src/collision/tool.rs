//! Continuous detection between a moving point (a surface node on its straight trajectory over the
//! tick) and a moving tool capsule (segment ends moving on straight lines, radius fixed).
//!
//! Conservative advancement: the distance d(t) from the point to the capsule surface changes at most
//! as fast as the relative speed bound L = |Δp| + max(|Δa|, |Δb|) (any point of the segment moves at a
//! blend of its ends' speeds), so advancing t by d(t)/L can never step over the first contact. The
//! search stops at contact (d ≤ tolerance), past the end of the tick, or after a fixed number of
//! iterations — then it reports a contact at the time reached, so it never misses one.

use crate::Vec3;
use crate::tool::CapsulePart;

/// Iteration cap of the advancement; reaching it reports a (possibly false) contact.
const MAX_ITERATIONS: u32 = 128;

/// Blend of two placements of a capsule, `s` ∈ [0, 1].
pub fn lerp_capsule(start: &CapsulePart, end: &CapsulePart, s: f64) -> CapsulePart {
    CapsulePart {
        a: start.a.lerp(&end.a, s),
        b: start.b.lerp(&end.b, s),
        radius: start.radius,
    }
}

/// Earliest fraction of the tick t ∈ [0, 1] at which a point moving from `p0` to `p1` is within
/// `tolerance` of the surface of a capsule moving from `start` to `end` (or inside it); `None` when
/// it provably stays farther all tick.
pub fn time_of_impact_point_capsule(
    p0: &Vec3,
    p1: &Vec3,
    start: &CapsulePart,
    end: &CapsulePart,
    tolerance: f64,
) -> Option<f64> {
    let speed_bound = (p1 - p0).norm() + (end.a - start.a).norm().max((end.b - start.b).norm());
    let mut t = 0.0;
    for _ in 0..MAX_ITERATIONS {
        let p = p0.lerp(p1, t);
        let distance = lerp_capsule(start, end, t).signed_distance(&p);
        if distance <= tolerance {
            return Some(t);
        }
        if speed_bound <= 0.0 {
            return None;
        }
        t += distance / speed_bound;
        if t > 1.0 {
            return None;
        }
    }
    Some(t)
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box.
    pub fn empty() -> Self {
        Self {
            min: Vec3::repeat(f64::INFINITY),
            max: Vec3::repeat(f64::NEG_INFINITY),
        }
    }

    /// Grows to contain `p`.
    pub fn include(&mut self, p: &Vec3) {
        self.min = self.min.inf(p);
        self.max = self.max.sup(p);
    }

    /// Grows by `margin` on every side.
    pub fn inflate(&mut self, margin: f64) {
        self.min -= Vec3::repeat(margin);
        self.max += Vec3::repeat(margin);
    }

    /// True when the segment from `p` to `q` may meet the box (its own box overlaps).
    pub fn overlaps_segment(&self, p: &Vec3, q: &Vec3) -> bool {
        let lo = p.inf(q);
        let hi = p.sup(q);
        lo.x <= self.max.x
            && hi.x >= self.min.x
            && lo.y <= self.max.y
            && hi.y >= self.min.y
            && lo.z <= self.max.z
            && hi.z >= self.min.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere(c: Vec3, r: f64) -> CapsulePart {
        CapsulePart {
            a: c,
            b: c,
            radius: r,
        }
    }

    #[test]
    fn a_fast_sphere_passing_a_point_is_caught_at_the_first_touch() {
        // A 5 mm sphere moving 0.1 m in one tick past a point it grazes at 1 mm from its centre.
        let start = sphere(Vec3::new(-0.05, 0.001, 0.0), 0.005);
        let end = sphere(Vec3::new(0.05, 0.001, 0.0), 0.005);
        let p = Vec3::zeros();
        let t = time_of_impact_point_capsule(&p, &p, &start, &end, 1e-12).unwrap();
        // Touch when |x| = sqrt(0.005² − 0.001²).
        let x = (0.005f64.powi(2) - 0.001f64.powi(2)).sqrt();
        let expected = (0.05 - x) / 0.1;
        assert!(
            t <= expected + 1e-9 && t > expected - 1e-6,
            "t = {t}, expected {expected}"
        );
    }

    #[test]
    fn a_miss_is_a_miss_and_contact_at_start_is_zero() {
        let start = sphere(Vec3::new(-0.05, 0.01, 0.0), 0.005);
        let end = sphere(Vec3::new(0.05, 0.01, 0.0), 0.005);
        let p = Vec3::zeros();
        assert!(time_of_impact_point_capsule(&p, &p, &start, &end, 1e-12).is_none());
        let inside = Vec3::new(-0.05, 0.01, 0.0);
        assert_eq!(
            time_of_impact_point_capsule(&inside, &inside, &start, &end, 1e-12),
            Some(0.0)
        );
    }
}
