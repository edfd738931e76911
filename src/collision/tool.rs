//! Continuous detection between a moving point (a surface node on its straight trajectory over the
//! tick) and a moving tool capsule (segment ends moving on straight lines, radius fixed).
//!
//! Conservative advancement: the distance d(t) from the point to the capsule surface changes at most
//! as fast as the relative speed bound L = |Δp| + max(|Δa|, |Δb|) (any point of the segment moves at a
//! blend of its ends' speeds), so advancing t by d(t)/L can never step over the first contact. The
//! search stops at contact (d ≤ tolerance), past the end of the tick, or after a fixed number of
//! iterations — then it reports a contact at the time reached, so it never misses one.

use crate::Vec3;
use crate::tool::{CapsulePart, Tool};

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
    advance(speed_bound, tolerance, |t| {
        lerp_capsule(start, end, t).signed_distance(&p0.lerp(p1, t))
    })
}

/// Closest point of triangle (a, b, c) to `p` (by the Voronoi regions of its corners and edges).
pub fn closest_point_on_triangle(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Vec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denominator = va + vb + vc;
    if denominator.abs() <= f64::MIN_POSITIVE {
        // A degenerate triangle: fall back to the nearest corner.
        return [*a, *b, *c]
            .into_iter()
            .min_by(|x, y| (p - x).norm_squared().total_cmp(&(p - y).norm_squared()))
            .expect("three corners");
    }
    let v = vb / denominator;
    let w = vc / denominator;
    a + ab * v + ac * w
}

/// Distance between segments (p1, q1) and (p2, q2), degenerate segments included.
pub fn segment_segment_distance(p1: &Vec3, q1: &Vec3, p2: &Vec3, q2: &Vec3) -> f64 {
    let (s, t) = segment_segment_closest(p1, q1, p2, q2);
    ((p1 + (q1 - p1) * s) - (p2 + (q2 - p2) * t)).norm()
}

/// Parameters (s, t) ∈ [0, 1]² of the closest points `p1 + s (q1 − p1)` and `p2 + t (q2 − p2)` of
/// two segments.
pub fn segment_segment_closest(p1: &Vec3, q1: &Vec3, p2: &Vec3, q2: &Vec3) -> (f64, f64) {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    let tiny = f64::MIN_POSITIVE;
    if a <= tiny && e <= tiny {
        (0.0, 0.0)
    } else if a <= tiny {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= tiny {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denominator = a * e - b * b;
            let mut s = if denominator > 0.0 {
                ((b * f - c * e) / denominator).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    }
}

/// Distance between segment (p, q) and triangle (a, b, c); 0 when the segment crosses it.
pub fn segment_triangle_distance(p: &Vec3, q: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> f64 {
    let normal = (b - a).cross(&(c - a));
    let dp = (p - a).dot(&normal);
    let dq = (q - a).dot(&normal);
    if (dp <= 0.0 && dq >= 0.0) || (dp >= 0.0 && dq <= 0.0) {
        let denominator = dp - dq;
        let crossing = if denominator.abs() > f64::MIN_POSITIVE {
            p + (q - p) * (dp / denominator)
        } else {
            *p
        };
        let inside = (b - a).cross(&(crossing - a)).dot(&normal) >= 0.0
            && (c - b).cross(&(crossing - b)).dot(&normal) >= 0.0
            && (a - c).cross(&(crossing - c)).dot(&normal) >= 0.0;
        if inside {
            return 0.0;
        }
    }
    let mut best = (closest_point_on_triangle(p, a, b, c) - p).norm();
    best = best.min((closest_point_on_triangle(q, a, b, c) - q).norm());
    for (x, y) in [(a, b), (b, c), (c, a)] {
        best = best.min(segment_segment_distance(p, q, x, y));
    }
    best
}

/// Earliest fraction of the tick t ∈ [0, 1] at which a capsule moving from `start` to `end` comes
/// within `tolerance` of a triangle whose corners move from `triangle_start` to `triangle_end`;
/// `None` when it provably stays farther all tick. Conservative advancement, as for points.
pub fn time_of_impact_capsule_triangle(
    start: &CapsulePart,
    end: &CapsulePart,
    triangle_start: &[Vec3; 3],
    triangle_end: &[Vec3; 3],
    tolerance: f64,
) -> Option<f64> {
    let triangle_speed = (0..3)
        .map(|k| (triangle_end[k] - triangle_start[k]).norm())
        .fold(0.0, f64::max);
    let capsule_speed = (end.a - start.a).norm().max((end.b - start.b).norm());
    let speed_bound = triangle_speed + capsule_speed;
    advance(speed_bound, tolerance, |t| {
        let capsule = lerp_capsule(start, end, t);
        let [a, b, c] = [0, 1, 2].map(|k| triangle_start[k].lerp(&triangle_end[k], t));
        segment_triangle_distance(&capsule.a, &capsule.b, &a, &b, &c) - capsule.radius
    })
}

/// Conservative advancement of a distance function `distance(t)` on [0, 1] that changes at most by
/// `speed_bound` per unit t: the earliest t with distance ≤ `tolerance`, or `None`.
///
/// Two bounds keep it short. From the current t with distance d and the end distance d₁, the function
/// cannot dip below (d + d₁ − L (1 − t)) / 2 in between (it must come down and go back up at slope at
/// most L); when that is above the tolerance there is no contact. Otherwise t advances by d / L, which
/// cannot step over the first contact. The iteration cap reports a contact (conservative).
fn advance(speed_bound: f64, tolerance: f64, distance: impl Fn(f64) -> f64) -> Option<f64> {
    let end_distance = distance(1.0);
    let mut t = 0.0;
    for _ in 0..MAX_ITERATIONS {
        let d = distance(t);
        if d <= tolerance {
            return Some(t);
        }
        if speed_bound <= 0.0 || 0.5 * (d + end_distance - speed_bound * (1.0 - t)) > tolerance {
            return None;
        }
        t += d / speed_bound;
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

    /// Grows to contain `other`.
    pub fn merge(&mut self, other: &Aabb) {
        self.min = self.min.inf(&other.min);
        self.max = self.max.sup(&other.max);
    }

    /// The box of the points `p` and `q` (a point's sweep over a tick).
    pub fn of_pair(p: &Vec3, q: &Vec3) -> Self {
        Self {
            min: p.inf(q),
            max: p.sup(q),
        }
    }

    /// Grows by `margin` on every side.
    pub fn inflate(&mut self, margin: f64) {
        self.min -= Vec3::repeat(margin);
        self.max += Vec3::repeat(margin);
    }

    /// Which sides of the box the segment from `p` to `q` lies wholly beyond: bit 2k for below the
    /// box on axis k, bit 2k+1 for above. Points whose codes have a common bit have a bounding box
    /// that misses this one (the classic outcode test, exact like [`Aabb::overlaps_segment`]).
    pub fn outcode(&self, p: &Vec3, q: &Vec3) -> u8 {
        let mut code = 0;
        for k in 0..3 {
            if p[k] < self.min[k] && q[k] < self.min[k] {
                code |= 1 << (2 * k);
            }
            if p[k] > self.max[k] && q[k] > self.max[k] {
                code |= 2 << (2 * k);
            }
        }
        code
    }

    /// True when the two boxes overlap (touching counts). The six comparisons are all made and
    /// joined with a bitwise and, with no branch between them: a hierarchy query's answers are as
    /// likely one way as the other, and a mispredicted branch costs more than the comparisons.
    #[inline]
    pub fn overlaps(&self, other: &Aabb) -> bool {
        (self.min.x <= other.max.x)
            & (self.max.x >= other.min.x)
            & (self.min.y <= other.max.y)
            & (self.max.y >= other.min.y)
            & (self.min.z <= other.max.z)
            & (self.max.z >= other.min.z)
    }

    /// How far apart the two boxes lie along the axis that parts them most: positive when they do
    /// not meet, zero or less when they overlap, not a number when a coordinate is not.
    pub fn gap(&self, other: &Aabb) -> f64 {
        let mut gap = f64::NEG_INFINITY;
        for k in 0..3 {
            for d in [other.min[k] - self.max[k], self.min[k] - other.max[k]] {
                if d.is_nan() {
                    return f64::NAN;
                }
                gap = gap.max(d);
            }
        }
        gap
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

/// The box a tool's parts fill at the end of the tick, each part's axis grown by its radius times
/// `1 + grow` (`grow` = 0: the parts themselves; a speculative contact's margin otherwise).
pub fn tool_reach(tool: &Tool, grow: f64) -> Aabb {
    let mut reach = Aabb::empty();
    let mut margin: f64 = 0.0;
    for part in &tool.parts_end[..tool.part_count] {
        reach.include(&part.a);
        reach.include(&part.b);
        margin = margin.max(part.radius * (1.0 + grow));
    }
    reach.inflate(margin);
    reach
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
    fn a_small_probe_through_a_face_between_nodes_is_caught() {
        // A 1 mm sphere dropping 4 cm in one tick through the middle of a 10 cm triangle.
        let start = sphere(Vec3::new(0.02, 0.02, 0.02), 0.001);
        let end = sphere(Vec3::new(0.02, 0.02, -0.02), 0.001);
        let tri = [
            Vec3::zeros(),
            Vec3::new(0.1, 0.0, 0.0),
            Vec3::new(0.0, 0.1, 0.0),
        ];
        let t = time_of_impact_capsule_triangle(&start, &end, &tri, &tri, 1e-12).unwrap();
        assert!((t - 0.019 / 0.04).abs() < 1e-6, "t = {t}");
        // Beside the triangle it misses.
        let start = sphere(Vec3::new(0.2, 0.2, 0.02), 0.001);
        let end = sphere(Vec3::new(0.2, 0.2, -0.02), 0.001);
        assert!(time_of_impact_capsule_triangle(&start, &end, &tri, &tri, 1e-12).is_none());
    }

    #[test]
    fn segment_distances() {
        let tri = [
            Vec3::zeros(),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        // Crossing the interior.
        let d = segment_triangle_distance(
            &Vec3::new(0.2, 0.2, 1.0),
            &Vec3::new(0.2, 0.2, -1.0),
            &tri[0],
            &tri[1],
            &tri[2],
        );
        assert_eq!(d, 0.0);
        // Parallel above, closest to the interior.
        let d = segment_triangle_distance(
            &Vec3::new(0.1, 0.1, 0.5),
            &Vec3::new(0.3, 0.1, 0.5),
            &tri[0],
            &tri[1],
            &tri[2],
        );
        assert!((d - 0.5).abs() < 1e-15);
        // Skew segments: distance between x axis and the line y = 1 along z.
        let d = segment_segment_distance(
            &Vec3::new(-1.0, 0.0, 0.0),
            &Vec3::new(1.0, 0.0, 0.0),
            &Vec3::new(0.0, 1.0, -1.0),
            &Vec3::new(0.0, 1.0, 1.0),
        );
        assert!((d - 1.0).abs() < 1e-15);
        // Parallel segments.
        let d = segment_segment_distance(
            &Vec3::zeros(),
            &Vec3::new(1.0, 0.0, 0.0),
            &Vec3::new(0.5, 0.3, 0.0),
            &Vec3::new(2.0, 0.3, 0.0),
        );
        assert!((d - 0.3).abs() < 1e-15);
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
