//! Bodies whose surfaces cross where they start: a scene mistake the contact between bodies cannot
//! mend (it keeps surfaces from passing through each other, so two that start crossed stay
//! entangled, and the contacts and collisions along the crossing cost every tick). Looked for once,
//! when a scene is loaded, to warn about it (`palpa check`, `run`, `serve`, `demo`).

use crate::Vec3;
use crate::body::Body;
use crate::collision::bvh::TriangleBvh;
use crate::collision::tool::Aabb;

/// Two bodies whose surfaces cross.
#[derive(Clone, Debug, PartialEq)]
pub struct Crossing {
    /// The two bodies (indices, the smaller first).
    pub bodies: (usize, usize),
    /// Pairs of their triangles that cross (one triangle's side through the other's inside).
    pub triangle_pairs: usize,
    /// Where the first crossing found is (m, world frame): a side of one triangle through the
    /// other.
    pub at_in_world: Vec3,
}

/// The pairs of bodies whose surfaces cross at their current positions (bodies of the same
/// `group`, the pieces of one cut body, are not compared), in order of the bodies. Touching is not
/// crossing: a side must pass strictly through the inside of a triangle of the other body.
/// Allocates (a hierarchy per body compared): for the start of a session, not for the tick.
pub fn crossing_surfaces(bodies: &[Body], group: &[usize]) -> Vec<Crossing> {
    let bounds: Vec<Aabb> = bodies.iter().map(bounds_of).collect();
    let mut crossings = Vec::new();
    let mut found = Vec::new();
    for j in 1..bodies.len() {
        let mut hierarchy: Option<TriangleBvh> = None;
        for i in 0..j {
            if group.get(i).is_some_and(|g| group.get(j) == Some(g))
                || !bounds[i].overlaps(&bounds[j])
            {
                continue;
            }
            let (a, b) = (&bodies[i].surface, &bodies[j].surface);
            // Built at the positions: its boxes are the triangles' (no sweep, no margin).
            let bvh = hierarchy
                .get_or_insert_with(|| TriangleBvh::build(&b.triangles, &b.position_in_world));
            let mut pairs = 0;
            let mut first = None;
            for t in &a.triangles {
                let first_triangle = t.map(|v| a.position_in_world[v as usize]);
                let mut aabb = Aabb::empty();
                for p in &first_triangle {
                    aabb.include(p);
                }
                if !aabb.overlaps(&bounds[j]) {
                    continue;
                }
                found.clear();
                found.reserve(b.triangles.len());
                bvh.query(&aabb, &mut found);
                for &u in &found {
                    let second = b.triangles[u as usize].map(|v| b.position_in_world[v as usize]);
                    if let Some(at) = triangles_cross(&first_triangle, &second) {
                        pairs += 1;
                        first.get_or_insert(at);
                    }
                }
            }
            if let Some(at_in_world) = first {
                crossings.push(Crossing {
                    bodies: (i, j),
                    triangle_pairs: pairs,
                    at_in_world,
                });
            }
        }
    }
    crossings.sort_by_key(|c| c.bodies);
    crossings
}

fn bounds_of(body: &Body) -> Aabb {
    let mut aabb = Aabb::empty();
    for p in &body.surface.position_in_world {
        aabb.include(p);
    }
    aabb
}

/// Six times the signed volume of the tetrahedron (a, b, c, d).
fn orientation(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> f64 {
    (b - a).cross(&(c - a)).dot(&(d - a))
}

/// Where segment (p, q) passes strictly through the inside of triangle `t` (its ends strictly on
/// either side of the triangle's plane, the line strictly inside its three sides), if it does.
fn side_through(p: &Vec3, q: &Vec3, t: &[Vec3; 3]) -> Option<Vec3> {
    let (dp, dq) = (
        orientation(&t[0], &t[1], &t[2], p),
        orientation(&t[0], &t[1], &t[2], q),
    );
    if !(dp > 0.0 && dq < 0.0 || dp < 0.0 && dq > 0.0) {
        return None;
    }
    let around = [
        orientation(p, q, &t[0], &t[1]),
        orientation(p, q, &t[1], &t[2]),
        orientation(p, q, &t[2], &t[0]),
    ];
    let inside = around.iter().all(|&x| x > 0.0) || around.iter().all(|&x| x < 0.0);
    inside.then(|| p + (q - p) * (dp / (dp - dq)))
}

/// Where two triangles cross (a side of one strictly through the other's inside), if they do.
fn triangles_cross(first: &[Vec3; 3], second: &[Vec3; 3]) -> Option<Vec3> {
    for (triangle, other) in [(first, second), (second, first)] {
        for k in 0..3 {
            if let Some(at) = side_through(&triangle[k], &triangle[(k + 1) % 3], other) {
                return Some(at);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangle(z: f64, shift: f64) -> [Vec3; 3] {
        [
            Vec3::new(shift, 0.0, z),
            Vec3::new(shift + 1.0, 0.0, z),
            Vec3::new(shift, 1.0, z),
        ]
    }

    #[test]
    fn a_triangle_through_another_crosses_and_touching_ones_do_not() {
        let flat = triangle(0.0, 0.0);
        // Standing through the flat one's inside.
        let through = [
            Vec3::new(0.2, 0.2, -0.5),
            Vec3::new(0.3, 0.2, 0.5),
            Vec3::new(0.2, 0.3, 0.5),
        ];
        let at = triangles_cross(&flat, &through).expect("crosses");
        assert!(at.z.abs() < 1e-12 && at.x > 0.2 && at.x < 0.3, "{at:?}");
        assert!(triangles_cross(&through, &flat).is_some());
        // Resting on it (a corner on its plane), parallel above it, beside it.
        let resting = [
            Vec3::new(0.2, 0.2, 0.0),
            Vec3::new(0.3, 0.2, 0.5),
            Vec3::new(0.2, 0.3, 0.5),
        ];
        assert_eq!(triangles_cross(&flat, &resting), None);
        assert_eq!(triangles_cross(&flat, &triangle(1e-9, 0.0)), None);
        assert_eq!(triangles_cross(&flat, &triangle(0.0, 2.0)), None);
        // Standing through it but outside its sides.
        let beside = through.map(|p| p + Vec3::new(1.0, 1.0, 0.0));
        assert_eq!(triangles_cross(&flat, &beside), None);
    }
}
