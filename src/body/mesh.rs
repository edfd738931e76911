//! The triangle surface a body is built from, in its body frame, and its geometry (areas, edges,
//! enclosed volume and inertia). Reading and checking meshes is the scene's (`crate::scene::mesh`).

use crate::Vec3;

/// A triangle surface in the body frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceMesh {
    /// Vertex positions, in the body frame (m).
    pub positions_in_body: Vec<Vec3>,
    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl SurfaceMesh {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions_in_body.len()
    }

    /// Area of triangle `t`.
    pub fn triangle_area(&self, t: usize) -> f64 {
        let [a, b, c] = self.triangles[t].map(|i| self.positions_in_body[i as usize]);
        0.5 * (b - a).cross(&(c - a)).norm()
    }

    /// Per-vertex area share: a third of the area of every incident triangle.
    pub fn vertex_areas(&self) -> Vec<f64> {
        let mut areas = vec![0.0; self.positions_in_body.len()];
        for t in 0..self.triangles.len() {
            let third = self.triangle_area(t) / 3.0;
            for &v in &self.triangles[t] {
                areas[v as usize] += third;
            }
        }
        areas
    }

    /// The node counts of the mesh's separate surfaces (its connected pieces), in the order of
    /// their first vertex: one entry for a single closed surface.
    pub fn shells(&self) -> Vec<usize> {
        let n = self.positions_in_body.len();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn root(parent: &mut [u32], mut v: u32) -> u32 {
            while parent[v as usize] != v {
                let up = parent[parent[v as usize] as usize];
                parent[v as usize] = up;
                v = up;
            }
            v
        }
        for tri in &self.triangles {
            let r = tri.map(|v| root(&mut parent, v));
            let low = r.into_iter().min().unwrap_or(0);
            for x in r {
                parent[x as usize] = low;
            }
        }
        // Roots are each piece's lowest vertex, so a piece's entry appears at its first vertex.
        let mut count = vec![0usize; n];
        for v in 0..n as u32 {
            count[root(&mut parent, v) as usize] += 1;
        }
        count.into_iter().filter(|&c| c > 0).collect()
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| self.triangle_area(t))
            .sum()
    }

    /// Signed enclosed volume (positive when triangles are wound counter-clockwise seen from outside).
    pub fn signed_volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|i| self.positions_in_body[i as usize]);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Unique undirected edges, each as (smaller index, larger index), sorted.
    pub fn edges(&self) -> Vec<[u32; 2]> {
        let mut edges: Vec<[u32; 2]> = self
            .triangles
            .iter()
            .flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]])
            .map(|[a, b]| [a.min(b), a.max(b)])
            .collect();
        edges.sort_unstable();
        edges.dedup();
        edges
    }

    /// Multiplies every coordinate by `scale` (per axis).
    pub fn scale(&mut self, scale: Vec3) {
        for p in &mut self.positions_in_body {
            p.component_mul_assign(&scale);
        }
    }

    /// Inertia tensor about the body-frame origin of the solid the mesh encloses, with uniform density
    /// and the given total mass (divergence theorem over tetrahedra from the origin).
    pub fn solid_inertia_about_origin(&self, mass: f64) -> nalgebra::Matrix3<f64> {
        let mut second_moment = nalgebra::Matrix3::zeros();
        let mut volume = 0.0;
        for tri in &self.triangles {
            let [a, b, c] = tri.map(|i| self.positions_in_body[i as usize]);
            let det = a.dot(&b.cross(&c));
            volume += det / 6.0;
            let s = a + b + c;
            second_moment +=
                (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose())
                    * (det / 120.0);
        }
        let density = mass / volume;
        let c = second_moment * density;
        nalgebra::Matrix3::identity() * c.trace() - c
    }
}
