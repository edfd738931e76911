//! Surface meshes: the primitives a scene can ask for (icosphere, ellipsoid, subdivided box), OBJ
//! files, and the checks every mesh must pass before it becomes a body (closed, oriented 2-manifold
//! without degenerate triangles).
//!
//! Data enters as a primitive description or an OBJ path and leaves as a [`SurfaceMesh`] whose
//! triangles are wound counter-clockwise seen from outside, with no unreferenced vertices, centred so
//! that the area-weighted centre of the surface (the centre of mass of the surface nodes, since masses
//! are spread by area) is at the origin of the body frame.

use std::collections::BTreeMap;
use std::path::Path;

use crate::Vec3;

pub use crate::body::mesh::SurfaceMesh;

/// Why a mesh cannot be used as a body surface.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// The mesh has no triangles.
    #[error("the mesh has no triangles")]
    Empty,
    /// A coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFinite {
        /// Offending vertex.
        vertex: u32,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {vertex}, but the mesh has {count} vertices")]
    IndexOutOfRange {
        /// Offending triangle.
        triangle: usize,
        /// The index it uses.
        vertex: u32,
        /// Number of vertices.
        count: usize,
    },
    /// A triangle has (almost) no area: repeated or collinear corners.
    #[error(
        "triangle {triangle} (vertices {a}, {b}, {c}, 0-based) is degenerate: area {area:.3e} m² for a longest edge of {longest:.3e} m"
    )]
    Degenerate {
        /// Offending triangle.
        triangle: usize,
        /// Its corners.
        a: u32,
        /// Its corners.
        b: u32,
        /// Its corners.
        c: u32,
        /// Its area.
        area: f64,
        /// Its longest edge.
        longest: f64,
    },
    /// An edge is not shared by exactly two triangles: the surface has a hole or a fin.
    #[error(
        "the mesh is not a closed manifold: the edge between vertices {a} and {b} (0-based) is used by {count} triangle(s), expected 2"
    )]
    NotClosed {
        /// Edge end.
        a: u32,
        /// Edge end.
        b: u32,
        /// How many triangles use it.
        count: usize,
    },
    /// Two triangles traverse an edge in the same direction: the orientation is inconsistent.
    #[error(
        "the mesh is not consistently oriented: the edge from vertex {a} to {b} (0-based) is used in the same direction by two triangles"
    )]
    Inconsistent {
        /// Edge start.
        a: u32,
        /// Edge end.
        b: u32,
    },
    /// The triangles around a vertex do not form a single fan (two surfaces touching at a point).
    #[error(
        "the mesh is not a manifold at vertex {vertex} (0-based): its triangles form more than one fan"
    )]
    NonManifoldVertex {
        /// Offending vertex.
        vertex: u32,
    },
    /// The mesh encloses no volume.
    #[error("the mesh encloses no volume (signed volume {volume:e} m³)")]
    NoVolume {
        /// The signed volume found.
        volume: f64,
    },
    /// The coordinates are too large for the checks' arithmetic (volume or extent overflow).
    #[error("the mesh is too large: its extent ({extent:e} m) or volume overflows")]
    TooLarge {
        /// The bounding-box diagonal.
        extent: f64,
    },
    /// A line of the OBJ file is wrong.
    #[error("{path}:{line}:{column}: {message}")]
    ObjSyntax {
        /// File path as given.
        path: String,
        /// 1-based line.
        line: usize,
        /// 1-based column (characters).
        column: usize,
        /// What is wrong and what was expected.
        message: String,
    },
    /// The OBJ file could not be read.
    #[error("cannot read OBJ file {path}: {reason}")]
    Obj {
        /// File path as given.
        path: String,
        /// What went wrong.
        reason: String,
    },
}

impl MeshError {
    /// The vertices the error names.
    pub fn vertices(&self) -> Vec<u32> {
        match *self {
            MeshError::NonFinite { vertex } | MeshError::NonManifoldVertex { vertex } => {
                vec![vertex]
            }
            MeshError::IndexOutOfRange { vertex, .. } => vec![vertex],
            MeshError::Degenerate { a, b, c, .. } => vec![a, b, c],
            MeshError::NotClosed { a, b, .. } | MeshError::Inconsistent { a, b } => vec![a, b],
            _ => Vec::new(),
        }
    }

    /// The same error with its vertex numbers mapped through `before` (a vertex's number before a
    /// renumbering, by its number after).
    fn renumbered(self, before: &[u32]) -> MeshError {
        let was = |v: u32| before.get(v as usize).copied().unwrap_or(v);
        match self {
            MeshError::Degenerate {
                triangle,
                a,
                b,
                c,
                area,
                longest,
            } => MeshError::Degenerate {
                triangle,
                a: was(a),
                b: was(b),
                c: was(c),
                area,
                longest,
            },
            MeshError::NotClosed { a, b, count } => {
                let (a, b) = (was(a), was(b));
                MeshError::NotClosed {
                    a: a.min(b),
                    b: a.max(b),
                    count,
                }
            }
            MeshError::Inconsistent { a, b } => MeshError::Inconsistent {
                a: was(a),
                b: was(b),
            },
            MeshError::NonManifoldVertex { vertex } => MeshError::NonManifoldVertex {
                vertex: was(vertex),
            },
            other => other,
        }
    }
}

impl SurfaceMesh {
    /// Checks that the mesh is a closed, consistently oriented 2-manifold without degenerate triangles,
    /// drops unreferenced vertices, and flips the winding if the mesh was wound inside out.
    pub fn validate(&mut self) -> Result<(), MeshError> {
        if self.triangles.is_empty() {
            return Err(MeshError::Empty);
        }
        let n = self.positions_in_body.len();
        for (v, p) in self.positions_in_body.iter().enumerate() {
            if !p.iter().all(|x| x.is_finite()) {
                return Err(MeshError::NonFinite { vertex: v as u32 });
            }
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            for &v in tri {
                if v as usize >= n {
                    return Err(MeshError::IndexOutOfRange {
                        triangle: t,
                        vertex: v,
                        count: n,
                    });
                }
            }
        }
        // The checks name vertices by their number in the mesh as given (an OBJ file's, 0-based),
        // not after the unreferenced ones are dropped.
        let kept = self.drop_unreferenced_vertices();
        let as_given = |e: MeshError| match &kept {
            Some(kept) => e.renumbered(kept),
            None => e,
        };
        self.check_degenerate().map_err(as_given)?;
        self.check_manifold().map_err(as_given)?;
        let volume = self.signed_volume();
        let extent = self.bounding_diagonal();
        if !volume.is_finite() || !extent.is_finite() || !self.area().is_finite() {
            return Err(MeshError::TooLarge { extent });
        }
        if volume.abs() <= 1e-12 * extent.powi(3) {
            return Err(MeshError::NoVolume { volume });
        }
        if volume < 0.0 {
            for tri in &mut self.triangles {
                tri.swap(1, 2);
            }
        }
        Ok(())
    }

    fn bounding_diagonal(&self) -> f64 {
        let mut lo = Vec3::repeat(f64::INFINITY);
        let mut hi = Vec3::repeat(f64::NEG_INFINITY);
        for p in &self.positions_in_body {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (hi - lo).norm()
    }

    /// Drops the vertices no triangle uses; when there were any, returns each kept vertex's number
    /// before.
    fn drop_unreferenced_vertices(&mut self) -> Option<Vec<u32>> {
        let n = self.positions_in_body.len();
        let mut used = vec![false; n];
        for tri in &self.triangles {
            for &v in tri {
                used[v as usize] = true;
            }
        }
        if used.iter().all(|&u| u) {
            return None;
        }
        let mut remap = vec![u32::MAX; n];
        let mut kept = Vec::with_capacity(n);
        let mut before = Vec::with_capacity(n);
        for (v, &u) in used.iter().enumerate() {
            if u {
                remap[v] = kept.len() as u32;
                kept.push(self.positions_in_body[v]);
                before.push(v as u32);
            }
        }
        self.positions_in_body = kept;
        for tri in &mut self.triangles {
            *tri = tri.map(|v| remap[v as usize]);
        }
        Some(before)
    }

    fn check_degenerate(&self) -> Result<(), MeshError> {
        for (t, &[a, b, c]) in self.triangles.iter().enumerate() {
            let [pa, pb, pc] = [a, b, c].map(|i| self.positions_in_body[i as usize]);
            let longest = (pb - pa).norm().max((pc - pb).norm()).max((pa - pc).norm());
            let area = 0.5 * (pb - pa).cross(&(pc - pa)).norm();
            // Repeated corners, or an area so small against the longest edge that the triangle is a
            // segment to within rounding (an aspect ratio of 1:1000 is still accepted).
            if a == b || b == c || c == a || longest == 0.0 || area <= 1e-10 * longest * longest {
                return Err(MeshError::Degenerate {
                    triangle: t,
                    a,
                    b,
                    c,
                    area,
                    longest,
                });
            }
        }
        Ok(())
    }

    fn check_manifold(&self) -> Result<(), MeshError> {
        // Directed edges, sorted, so both the closed-surface and the orientation checks are merges.
        let mut directed: Vec<[u32; 2]> = self
            .triangles
            .iter()
            .flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]])
            .collect();
        directed.sort_unstable();
        for w in directed.windows(2) {
            if w[0] == w[1] {
                // Three or more triangles on one edge also show up as a repeated direction, but say
                // "not closed" for them: that is the real problem.
                let count = self.edge_use_count(w[0][0], w[0][1]);
                if count != 2 {
                    let [a, b] = w[0];
                    return Err(MeshError::NotClosed {
                        a: a.min(b),
                        b: a.max(b),
                        count,
                    });
                }
                return Err(MeshError::Inconsistent {
                    a: w[0][0],
                    b: w[0][1],
                });
            }
        }
        for &[a, b] in &directed {
            if directed.binary_search(&[b, a]).is_err() {
                let count = self.edge_use_count(a, b);
                return Err(MeshError::NotClosed {
                    a: a.min(b),
                    b: a.max(b),
                    count,
                });
            }
        }
        // Every edge has exactly two triangles in opposite directions. A vertex is manifold when its
        // triangles form one fan: following "next corner" links from any of them visits them all.
        let n = self.positions_in_body.len();
        let mut start = vec![0usize; n + 1];
        for tri in &self.triangles {
            for &v in tri {
                start[v as usize + 1] += 1;
            }
        }
        for v in 0..n {
            start[v + 1] += start[v];
        }
        // For each vertex, the (next, after-next) corner pairs of its triangles.
        let mut fill = start.clone();
        let mut fan = vec![[0u32; 2]; start[n]];
        for &[a, b, c] in &self.triangles {
            for (v, x, y) in [(a, b, c), (b, c, a), (c, a, b)] {
                fan[fill[v as usize]] = [x, y];
                fill[v as usize] += 1;
            }
        }
        for v in 0..n {
            let pairs = &mut fan[start[v]..start[v + 1]];
            pairs.sort_unstable();
            let first = pairs[0][0];
            let mut at = first;
            let mut steps = 0;
            loop {
                let Ok(k) = pairs.binary_search_by(|p| p[0].cmp(&at)) else {
                    return Err(MeshError::NonManifoldVertex { vertex: v as u32 });
                };
                at = pairs[k][1];
                steps += 1;
                if at == first || steps > pairs.len() {
                    break;
                }
            }
            if steps != pairs.len() {
                return Err(MeshError::NonManifoldVertex { vertex: v as u32 });
            }
        }
        Ok(())
    }

    fn edge_use_count(&self, a: u32, b: u32) -> usize {
        self.triangles
            .iter()
            .filter(|tri| {
                (0..3).any(|k| {
                    let (x, y) = (tri[k], tri[(k + 1) % 3]);
                    (x == a && y == b) || (x == b && y == a)
                })
            })
            .count()
    }

    /// Renumbers the vertices along a Z-order (Morton) curve of their positions, so that vertices
    /// close in space are close in memory and the edge loop of the step stays in cache. Deterministic:
    /// ties keep the original order. Triangles are renumbered accordingly and sorted.
    pub fn reorder_for_locality(&mut self) {
        let n = self.positions_in_body.len();
        if n < 2 {
            return;
        }
        let mut lo = Vec3::repeat(f64::INFINITY);
        let mut hi = Vec3::repeat(f64::NEG_INFINITY);
        for p in &self.positions_in_body {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let extent = (hi - lo).max().max(f64::MIN_POSITIVE);
        let quantise = |x: f64, l: f64| (((x - l) / extent) * 1023.0).clamp(0.0, 1023.0) as u32;
        let spread = |mut v: u32| {
            // Spread 10 bits so that two zero bits separate each.
            v &= 0x3ff;
            v = (v | (v << 16)) & 0x0300_00ff;
            v = (v | (v << 8)) & 0x0300_f00f;
            v = (v | (v << 4)) & 0x030c_30c3;
            (v | (v << 2)) & 0x0924_9249
        };
        let mut order: Vec<(u32, u32)> = self
            .positions_in_body
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let code = spread(quantise(p.x, lo.x))
                    | (spread(quantise(p.y, lo.y)) << 1)
                    | (spread(quantise(p.z, lo.z)) << 2);
                (code, i as u32)
            })
            .collect();
        order.sort_unstable();
        let mut new_index = vec![0u32; n];
        for (new, &(_, old)) in order.iter().enumerate() {
            new_index[old as usize] = new as u32;
        }
        self.positions_in_body = order
            .iter()
            .map(|&(_, old)| self.positions_in_body[old as usize])
            .collect();
        for tri in &mut self.triangles {
            let t = tri.map(|v| new_index[v as usize]);
            // Rotate so the smallest index comes first (same winding).
            let k = (0..3).min_by_key(|&k| t[k]).expect("three corners");
            *tri = [t[k], t[(k + 1) % 3], t[(k + 2) % 3]];
        }
        self.triangles.sort_unstable();
    }

    /// Moves the mesh so that the area-weighted centre of its vertices is at the origin, and returns
    /// the offset that was subtracted.
    pub fn recentre_on_surface_centre(&mut self) -> Vec3 {
        let areas = self.vertex_areas();
        let total: f64 = areas.iter().sum();
        let mut centre = Vec3::zeros();
        for (p, a) in self.positions_in_body.iter().zip(&areas) {
            centre += p * *a;
        }
        centre /= total;
        for p in &mut self.positions_in_body {
            *p -= centre;
        }
        centre
    }
}

/// An icosphere of the given radius: an icosahedron whose faces are split in four `subdivisions` times,
/// every vertex pushed onto the sphere. 12, 42, 162, 642, 2562, 10242, 40962 vertices for 0..=6.
pub fn icosphere(radius: f64, subdivisions: u32) -> SurfaceMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3::from(*p).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        // Ordered map: vertex numbering must not depend on hashing.
        let mut midpoints: BTreeMap<(u32, u32), u32> = BTreeMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *midpoints.entry(key).or_insert_with(|| {
                let p = ((positions[a as usize] + positions[b as usize]) * 0.5).normalize();
                positions.push(p);
                (positions.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(triangles.len() * 4);
        for &[a, b, c] in &triangles {
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    for p in &mut positions {
        *p *= radius;
    }
    let mut mesh = SurfaceMesh {
        positions_in_body: positions,
        triangles,
    };
    orient_outward(&mut mesh);
    mesh
}

/// A capsule along x (a tube with rounded ends, such as a bowel loop or a Fallopian tube): a cylinder
/// of `radius` and `length` between two hemispheres, `around` nodes on every ring (at least 6), rings
/// about as far apart as the nodes on a ring. Every other ring is turned by half a step, so that the
/// triangles are close to equilateral.
pub fn capsule(radius: f64, length: f64, around: u32) -> SurfaceMesh {
    let around = around.max(6) as usize;
    let spacing = std::f64::consts::TAU * radius / around as f64;
    let quarter = ((std::f64::consts::FRAC_PI_2 * radius / spacing).round() as usize).max(1);
    let segments = ((length / spacing).round() as usize).max(1);
    // Rings as (x, ring radius), from the −x pole to the +x one.
    let mut rings: Vec<(f64, f64)> = Vec::new();
    for q in 1..=quarter {
        let theta = std::f64::consts::FRAC_PI_2 * q as f64 / quarter as f64;
        rings.push((-0.5 * length - radius * theta.cos(), radius * theta.sin()));
    }
    for k in 1..=segments {
        rings.push((-0.5 * length + length * k as f64 / segments as f64, radius));
    }
    for q in (1..quarter).rev() {
        let theta = std::f64::consts::FRAC_PI_2 * q as f64 / quarter as f64;
        rings.push((0.5 * length + radius * theta.cos(), radius * theta.sin()));
    }
    let mut positions = vec![Vec3::new(-0.5 * length - radius, 0.0, 0.0)];
    for (i, &(x, r)) in rings.iter().enumerate() {
        let turn = if i % 2 == 1 { 0.5 } else { 0.0 };
        for j in 0..around {
            let phi = std::f64::consts::TAU * (j as f64 + turn) / around as f64;
            positions.push(Vec3::new(x, r * phi.cos(), r * phi.sin()));
        }
    }
    positions.push(Vec3::new(0.5 * length + radius, 0.0, 0.0));
    let last = (positions.len() - 1) as u32;
    let ring = |i: usize, j: usize| (1 + i * around + j % around) as u32;
    let mut triangles = Vec::new();
    for j in 0..around {
        triangles.push([0, ring(0, j + 1), ring(0, j)]);
        triangles.push([last, ring(rings.len() - 1, j), ring(rings.len() - 1, j + 1)]);
    }
    for i in 0..rings.len() - 1 {
        for j in 0..around {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j + 1),
                ring(i + 1, j),
            );
            let length_of = |p: u32, q: u32| (positions[p as usize] - positions[q as usize]).norm();
            if length_of(a, c) <= length_of(b, d) {
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            } else {
                triangles.push([a, b, d]);
                triangles.push([b, c, d]);
            }
        }
    }
    // Each triangle faces away from the axis.
    for t in &mut triangles {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        let centre = (a + b + c) / 3.0;
        let on_axis = Vec3::new(centre.x.clamp(-0.5 * length, 0.5 * length), 0.0, 0.0);
        if (b - a).cross(&(c - a)).dot(&(centre - on_axis)) < 0.0 {
            t.swap(1, 2);
        }
    }
    SurfaceMesh {
        positions_in_body: positions,
        triangles,
    }
}

/// An axis-aligned box of the given full size, centred on the origin, each face split into
/// `(subdivisions + 1)²` quads of two triangles (diagonals alternating from quad to quad).
pub fn box_mesh(size: Vec3, subdivisions: u32) -> SurfaceMesh {
    box_mesh_per_axis(size, [subdivisions; 3])
}

/// A box whose edges along axis k are split into `subdivisions[k] + 1` segments (a thin plate can be
/// fine across and one segment thick).
pub fn box_mesh_per_axis(size: Vec3, subdivisions: [u32; 3]) -> SurfaceMesh {
    let s = subdivisions.map(|n| n as i64 + 1);
    let mut index: BTreeMap<[i64; 3], u32> = BTreeMap::new();
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let mut vertex = |g: [i64; 3], positions: &mut Vec<Vec3>| -> u32 {
        *index.entry(g).or_insert_with(|| {
            let p = Vec3::new(
                (g[0] as f64 / s[0] as f64 - 0.5) * size.x,
                (g[1] as f64 / s[1] as f64 - 0.5) * size.y,
                (g[2] as f64 / s[2] as f64 - 0.5) * size.z,
            );
            positions.push(p);
            (positions.len() - 1) as u32
        })
    };
    for axis in 0..3 {
        let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0, s[axis]] {
            let mut normal = [0.0; 3];
            normal[axis] = if side == 0 { -1.0 } else { 1.0 };
            let normal = Vec3::from(normal);
            for i in 0..s[u] {
                for j in 0..s[w] {
                    let corner = |di: i64, dj: i64| {
                        let mut g = [0i64; 3];
                        g[axis] = side;
                        g[u] = i + di;
                        g[w] = j + dj;
                        g
                    };
                    let q = [
                        vertex(corner(0, 0), &mut positions),
                        vertex(corner(1, 0), &mut positions),
                        vertex(corner(1, 1), &mut positions),
                        vertex(corner(0, 1), &mut positions),
                    ];
                    // Diagonals alternate like a chessboard's squares: one diagonal everywhere
                    // makes the membrane stiffer in shear along it, and a box dropped flat slid
                    // along that diagonal as it collapsed.
                    let split = if (i + j) % 2 == 0 {
                        [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
                    } else {
                        [[q[1], q[2], q[3]], [q[1], q[3], q[0]]]
                    };
                    for mut tri in split {
                        let [a, b, c] = tri.map(|k| positions[k as usize]);
                        if (b - a).cross(&(c - a)).dot(&normal) < 0.0 {
                            tri.swap(1, 2);
                        }
                        triangles.push(tri);
                    }
                }
            }
        }
    }
    SurfaceMesh {
        positions_in_body: positions,
        triangles,
    }
}

/// Reads the surface an OBJ file describes, all its objects and groups as one mesh (see
/// [`parse_obj`]), with the vertices merged into others at their position (for errors).
pub fn load_obj(path: &Path) -> Result<(SurfaceMesh, MergedVertices), MeshError> {
    let obj_error = |reason: String| MeshError::Obj {
        path: path.display().to_string(),
        reason,
    };
    // A device or a pipe named as a mesh would be read without end.
    let metadata = std::fs::metadata(path).map_err(|e| obj_error(e.to_string()))?;
    if !metadata.is_file() {
        return Err(obj_error("not a regular file".into()));
    }
    let bytes = std::fs::read(path).map_err(|e| obj_error(e.to_string()))?;
    parse_obj_merged(&bytes, &path.display().to_string())
}

/// The file's vertices that [`parse_obj`] merged into another at exactly the same position: for
/// each vertex kept (the first at its position in the file), the others, in file order; all
/// 0-based, as numbered in the file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MergedVertices(BTreeMap<u32, Vec<u32>>);

impl MergedVertices {
    /// How many of the file's vertices were merged into another.
    pub fn count(&self) -> usize {
        self.0.values().map(Vec::len).sum()
    }

    /// For an error that names vertices, the file's vertices each named one also stands for, so
    /// that the numbers can be found in the file's faces (empty when none of them was merged).
    pub fn note_for(&self, error: &MeshError) -> String {
        let mut note = String::new();
        let mut named = Vec::new();
        for vertex in error.vertices() {
            // (A degenerate triangle may name one vertex twice: noted once.)
            if named.contains(&vertex) {
                continue;
            }
            named.push(vertex);
            if let Some(others) = self.0.get(&vertex) {
                let others: Vec<String> = others.iter().map(u32::to_string).collect();
                note += &format!(
                    "{} {vertex} also stands for the file's {}",
                    if note.is_empty() {
                        "; vertex"
                    } else {
                        ", vertex"
                    },
                    others.join(", ")
                );
            }
        }
        if !note.is_empty() {
            note += " (vertices at one position are merged into the first)";
        }
        note
    }
}

/// Reads OBJ text from bytes; `name` is used in messages. The text is checked line by line first
/// (UTF-8, numbers where numbers belong, every face index within the vertices, texture coordinates
/// and normals the file defines), so that an error names its line and column and the reading
/// ([`read_checked_obj`]) only ever sees indices it can resolve; then vertices at the same
/// position are merged ([`weld_coincident_vertices`]).
pub fn parse_obj(bytes: &[u8], name: &str) -> Result<SurfaceMesh, MeshError> {
    parse_obj_merged(bytes, name).map(|(mesh, _)| mesh)
}

/// [`parse_obj`], with the vertices it merged.
pub fn parse_obj_merged(
    bytes: &[u8],
    name: &str,
) -> Result<(SurfaceMesh, MergedVertices), MeshError> {
    let syntax = |line: usize, column: usize, message: String| MeshError::ObjSyntax {
        path: name.to_string(),
        line,
        column,
        message,
    };
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let before = &bytes[..e.valid_up_to()];
        let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
        let column = before.len()
            - before
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |i| i + 1)
            + 1;
        syntax(line, column, "not UTF-8 text".into())
    })?;
    check_obj_text(text).map_err(|(line, column, message)| syntax(line, column, message))?;
    let mesh = read_checked_obj(text);
    if mesh.triangles.is_empty() {
        return Err(MeshError::Obj {
            path: name.to_string(),
            reason: "no faces found".into(),
        });
    }
    Ok(weld_coincident_vertices(mesh))
}

/// The vertices and faces of OBJ text that [`check_obj_text`] accepted: every `v` in file order
/// (read as 32-bit numbers, then widened), every `f` fanned into triangles from its first corner
/// (`a b c d` → `a b c`, `a c d`), its vertex indices resolved against the whole file (positive
/// from the first `v`, negative back from the last `v` before the face). Objects, groups,
/// materials, smoothing groups, lines and points do not split or add to the surface: a closed
/// surface written as several groups sharing vertices is one mesh, as the file means it.
fn read_checked_obj(text: &str) -> SurfaceMesh {
    let mut mesh = SurfaceMesh {
        positions_in_body: Vec::new(),
        triangles: Vec::new(),
    };
    let mut corners: Vec<u32> = Vec::new();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                // Checked: three numbers follow.
                let mut xyz = words.map(|w| w.parse::<f32>().map_or(f64::NAN, f64::from));
                let mut next = || xyz.next().unwrap_or(f64::NAN);
                let (x, y, z) = (next(), next(), next());
                mesh.positions_in_body.push(Vec3::new(x, y, z));
            }
            Some("f") => {
                let so_far = mesh.positions_in_body.len() as i64;
                corners.clear();
                corners.extend(words.filter_map(|word| {
                    // Checked: a nonzero vertex index within the file's vertices.
                    let index: i64 = word.split('/').next()?.parse().ok()?;
                    let zero_based = if index > 0 { index - 1 } else { so_far + index };
                    u32::try_from(zero_based).ok()
                }));
                for k in 1..corners.len().saturating_sub(1) {
                    mesh.triangles
                        .push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            _ => {}
        }
    }
    mesh
}

/// Merges vertices at exactly the same position into the first of them in the file (and says
/// which were merged into which), so that a
/// surface written as separate triangles (a triangle soup, as a mesh converted from STL is) is read
/// as the closed surface it describes. In a valid closed 2-manifold no two vertices share a
/// position, so a mesh that is valid as written is unchanged; a vertex left unreferenced by the
/// merge is dropped later with the others.
fn weld_coincident_vertices(mut mesh: SurfaceMesh) -> (SurfaceMesh, MergedVertices) {
    let key = |p: &Vec3| [p.x, p.y, p.z].map(|c| if c == 0.0 { 0 } else { c.to_bits() });
    let mut order: Vec<u32> = (0..mesh.positions_in_body.len() as u32).collect();
    // Ties keep the file's order, so each position's first vertex comes first.
    order.sort_by_key(|&v| key(&mesh.positions_in_body[v as usize]));
    let mut first_of = (0..mesh.positions_in_body.len() as u32).collect::<Vec<u32>>();
    let mut merged = MergedVertices::default();
    for pair in order.windows(2) {
        let [a, b] = [pair[0], pair[1]];
        if key(&mesh.positions_in_body[a as usize]) == key(&mesh.positions_in_body[b as usize]) {
            first_of[b as usize] = first_of[a as usize];
            merged.0.entry(first_of[a as usize]).or_default().push(b);
        }
    }
    if merged.count() > 0 {
        for tri in &mut mesh.triangles {
            *tri = tri.map(|v| first_of[v as usize]);
        }
    }
    (mesh, merged)
}

/// The line-by-line check of OBJ text: `(line, column, what is wrong)` of the first problem.
fn check_obj_text(text: &str) -> Result<(), (usize, usize, String)> {
    // Positive face indices may refer forward (to vertices later in the file); negative ones count
    // back from the last vertex read.
    let count = |keyword: &str| {
        text.lines()
            .filter(|l| l.split_whitespace().next() == Some(keyword))
            .count()
    };
    let totals = [count("v"), count("vt"), count("vn")];
    let mut so_far = [0usize; 3];
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let column = |word: &str| {
            let offset = word.as_ptr() as usize - line.as_ptr() as usize;
            line[..offset].chars().count() + 1
        };
        let at = |word: &str, message: String| (number + 1, column(word), message);
        let numbers = |needed: usize, what: &str, words: &mut std::str::SplitWhitespace<'_>| {
            for k in 0..needed {
                match words.next() {
                    None => {
                        return Err(at(
                            keyword,
                            format!("`{keyword}` needs {needed} numbers ({what}), found {k}"),
                        ));
                    }
                    Some(word) if word.parse::<f32>().is_err() => {
                        return Err(at(
                            word,
                            format!("expected a number ({what}), found {word:?}"),
                        ));
                    }
                    Some(_) => {}
                }
            }
            Ok(())
        };
        match keyword {
            "v" => {
                numbers(3, "x y z", &mut words)?;
                let rest: Vec<&str> = words.collect();
                match rest.len() {
                    0 => {}
                    1 if rest[0].parse::<f32>().is_ok_and(|w| w != 0.0) => {}
                    3 if rest.iter().all(|w| w.parse::<f32>().is_ok()) => {}
                    _ => {
                        return Err(at(
                            rest[0],
                            "after x y z, `v` takes a weight w ≠ 0 or a colour r g b".into(),
                        ));
                    }
                }
                so_far[0] += 1;
            }
            "vt" => {
                numbers(2, "u v", &mut words)?;
                so_far[1] += 1;
            }
            "vn" => {
                numbers(3, "x y z", &mut words)?;
                so_far[2] += 1;
            }
            "f" | "l" => {
                let mut corners = 0;
                for word in words {
                    corners += 1;
                    let parts: Vec<&str> = word.split('/').collect();
                    if parts.len() > 3 {
                        return Err(at(
                            word,
                            format!("expected a corner v, v/vt, v//vn or v/vt/vn, found {word:?}"),
                        ));
                    }
                    for (k, part) in parts.iter().enumerate() {
                        if part.is_empty() && k > 0 {
                            continue;
                        }
                        let what = ["vertex", "texture coordinate", "normal"][k];
                        let index: i64 = part.parse().map_err(|_| {
                            at(word, format!("expected a {what} index, found {part:?}"))
                        })?;
                        let valid = if index > 0 {
                            index as u64 <= totals[k] as u64
                        } else {
                            index != 0 && index.unsigned_abs() <= so_far[k] as u64
                        };
                        if !valid {
                            return Err(at(
                                word,
                                format!(
                                    "{what} index {index} out of range: the file defines {} ({} so far)",
                                    totals[k], so_far[k]
                                ),
                            ));
                        }
                    }
                }
                if keyword == "f" && corners < 3 {
                    return Err(at(
                        keyword,
                        format!("a face needs at least 3 corners, found {corners}"),
                    ));
                }
            }
            _ => {}
        }
    }
    Ok(())
}

fn orient_outward(mesh: &mut SurfaceMesh) {
    if mesh.signed_volume() < 0.0 {
        for tri in &mut mesh.triangles {
            tri.swap(1, 2);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icosphere_counts_follow_the_subdivision_series() {
        for (s, n) in [(0, 12), (1, 42), (2, 162), (3, 642), (4, 2562)] {
            let mut m = icosphere(0.1, s);
            assert_eq!(m.vertex_count(), n);
            m.validate().unwrap();
            assert!(m.signed_volume() > 0.0);
        }
    }

    #[test]
    fn capsule_is_a_closed_outward_tube_of_the_right_volume() {
        let (r, l) = (0.02, 0.12);
        let mut m = capsule(r, l, 24);
        m.validate().unwrap();
        let exact = std::f64::consts::PI * r * r * l + 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        let v = m.signed_volume();
        assert!(v > 0.95 * exact && v < exact, "volume {v} against {exact}");
    }

    #[test]
    fn box_counts_and_volume() {
        let mut m = box_mesh(Vec3::new(1.0, 2.0, 3.0), 0);
        assert_eq!(m.vertex_count(), 8);
        assert_eq!(m.triangles.len(), 12);
        m.validate().unwrap();
        assert!((m.signed_volume() - 6.0).abs() < 1e-12);
        let mut m = box_mesh(Vec3::new(1.0, 1.0, 1.0), 2);
        // 6 faces of 3x3 quads: 6*9*2 triangles; vertices on a 4x4x4 grid's boundary.
        assert_eq!(m.triangles.len(), 108);
        assert_eq!(m.vertex_count(), 4 * 4 * 4 - 2 * 2 * 2);
        m.validate().unwrap();
    }

    #[test]
    fn locality_reordering_keeps_the_surface() {
        let mut m = icosphere(0.1, 3);
        let (area, volume) = (m.area(), m.signed_volume());
        m.reorder_for_locality();
        m.validate().unwrap();
        assert!((m.area() - area).abs() < 1e-15);
        assert!((m.signed_volume() - volume).abs() < 1e-15);
        // Neighbours in memory are neighbours in space: edges span short index ranges on average.
        let edges = m.edges();
        let mean_span: f64 =
            edges.iter().map(|[a, b]| (b - a) as f64).sum::<f64>() / edges.len() as f64;
        assert!(
            mean_span < m.vertex_count() as f64 / 8.0,
            "mean index span {mean_span}"
        );
    }

    #[test]
    fn box_inertia_matches_the_closed_form() {
        let (x, y, z) = (1.0, 2.0, 3.0);
        let m = box_mesh(Vec3::new(x, y, z), 1);
        let inertia = m.solid_inertia_about_origin(12.0);
        assert!((inertia[(0, 0)] - (y * y + z * z)).abs() < 1e-12);
        assert!((inertia[(1, 1)] - (x * x + z * z)).abs() < 1e-12);
        assert!((inertia[(2, 2)] - (x * x + y * y)).abs() < 1e-12);
        assert!(inertia[(0, 1)].abs() < 1e-12);
    }
}
