//! Where a body's triangles and springs are in its rest frame: a grid of cells over the homologues'
//! box, each cell listing the triangles and springs whose rest boxes meet it. The cutter asks it for
//! what lies near a point or a box instead of passing over the whole mesh, so that a cut step costs in
//! proportion to what the blade touches.
//!
//! Rest places move only where the mesh changes (a split node lies on its edge between the ends' rest
//! places, a copy sits on its origin's), so the grid is built once and then told of every triangle
//! and spring the cutter creates or rewrites: the item is listed again, in the cells of its new box,
//! from a pool reserved up front (an old listing stays, and a query checks what it finds). Any other
//! change of the mesh (subdivision, coarsening, a transection's renumbering) is seen by the body's
//! topology version and the grid is built again before its next use. Build and updates allocate
//! nothing within the room reserved when the index was made; an index that would need more says so,
//! and the cutter then passes over the mesh as before.

use crate::Vec3;
use crate::body::Body;
use crate::collision::tool::Aabb;

const NONE: u32 = u32::MAX;
/// Most cells a grid may have, per item it can hold.
const CELLS_PER_ITEM: usize = 2;
/// Listings reserved per item (a box meets about two cells along each axis).
const LISTINGS_PER_ITEM: usize = 8;

/// One grid: cells of one size over a box, each listing items (triangles or springs) by index.
#[derive(Clone, Debug)]
struct CellGrid {
    origin: Vec3,
    inverse_cell: f64,
    dims: [usize; 3],
    /// Listings made when the grid was built: cell `c` holds `items[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    items: Vec<u32>,
    /// Listings added since: a chain per cell through `extra` (item, next).
    head: crate::Room<u32>,
    extra: Vec<(u32, u32)>,
    /// Room for listings (built and added): a grid that would need more is out of date.
    room: usize,
}

impl CellGrid {
    fn with_capacity(items: usize) -> Self {
        let cells = CELLS_PER_ITEM * items.max(1);
        let room = LISTINGS_PER_ITEM * items.max(1);
        Self {
            origin: Vec3::zeros(),
            inverse_cell: 1.0,
            dims: [1; 3],
            start: Vec::with_capacity(cells + 1),
            items: Vec::with_capacity(room),
            head: crate::Room::with_capacity(cells),
            extra: Vec::with_capacity(room),
            room,
        }
    }

    /// Lays the cells over `bounds` with cells of about `cell` (grown when there would be more
    /// cells than the grid has room for).
    fn lay(&mut self, bounds: &Aabb, cell: f64) {
        let extent = bounds.max - bounds.min;
        let limit = self.head.capacity().max(1);
        let mut size = cell.max(1e-9 * extent.norm()).max(f64::MIN_POSITIVE);
        loop {
            let dims = [0, 1, 2].map(|k| (extent[k] / size) as usize + 1);
            if dims.iter().product::<usize>() <= limit || !size.is_finite() {
                self.dims = dims.map(|d| d.clamp(1, limit));
                break;
            }
            size *= 1.5;
        }
        self.origin = bounds.min;
        self.inverse_cell = 1.0 / size;
    }

    fn cell_of(&self, p: &Vec3) -> [usize; 3] {
        [0, 1, 2].map(|k| {
            let c = (p[k] - self.origin[k]) * self.inverse_cell;
            // Outside the box (or not a number): the nearest cell along that axis.
            if c >= 0.0 {
                (c as usize).min(self.dims[k] - 1)
            } else {
                0
            }
        })
    }

    /// The cells a box meets, as index ranges per axis.
    fn range(&self, b: &Aabb) -> [std::ops::RangeInclusive<usize>; 3] {
        let (lo, hi) = (self.cell_of(&b.min), self.cell_of(&b.max));
        [lo[0]..=hi[0], lo[1]..=hi[1], lo[2]..=hi[2]]
    }

    /// Calls `f` with every cell the box meets, in a fixed order.
    fn for_cells(&self, b: &Aabb, mut f: impl FnMut(usize)) {
        let [rx, ry, rz] = self.range(b);
        for z in rz {
            for y in ry.clone() {
                for x in rx.clone() {
                    f((z * self.dims[1] + y) * self.dims[0] + x);
                }
            }
        }
    }

    /// Lists items `0..count` by their boxes. False (and an empty grid) when the listings would not
    /// fit in the room reserved.
    fn build(&mut self, count: usize, boxes: impl Fn(usize) -> Aabb) -> bool {
        let cells = self.dims.iter().product::<usize>();
        self.start.clear();
        self.start.resize(cells + 1, 0);
        self.head.clear();
        self.head.resize(cells, NONE);
        self.extra.clear();
        self.items.clear();
        // Count the listings of each cell (in start[c + 1]), then their places.
        let mut total = 0usize;
        let mut counts = std::mem::take(&mut self.start);
        for i in 0..count {
            self.for_cells(&boxes(i), |c| {
                counts[c + 1] += 1;
                total += 1;
            });
        }
        self.start = counts;
        if total > self.room {
            self.start.iter_mut().for_each(|s| *s = 0);
            return false;
        }
        for c in 0..cells {
            self.start[c + 1] += self.start[c];
        }
        self.items.resize(total, NONE);
        // Fill each cell from its start, items in index order; `head` serves as the fill count.
        let mut filled = std::mem::take(&mut self.head);
        filled.iter_mut().for_each(|f| *f = 0);
        let mut items = std::mem::take(&mut self.items);
        for i in 0..count {
            self.for_cells(&boxes(i), |c| {
                items[self.start[c] as usize + filled[c] as usize] = i as u32;
                filled[c] += 1;
            });
        }
        self.items = items;
        filled.iter_mut().for_each(|f| *f = NONE);
        self.head = filled;
        true
    }

    /// Lists `item` in the cells its box meets. False when the room is used up.
    fn add(&mut self, item: u32, b: &Aabb) -> bool {
        let [rx, ry, rz] = self.range(b);
        let cells =
            (rx.end() + 1 - rx.start()) * (ry.end() + 1 - ry.start()) * (rz.end() + 1 - rz.start());
        if self.items.len() + self.extra.len() + cells > self.room {
            return false;
        }
        let (mut extra, mut head) = (
            std::mem::take(&mut self.extra),
            std::mem::take(&mut self.head),
        );
        self.for_cells(b, |c| {
            extra.push((item, head[c]));
            head[c] = (extra.len() - 1) as u32;
        });
        (self.extra, self.head) = (extra, head);
        true
    }

    /// Calls `f` with every item listed in a cell the box meets (an item may come more than once).
    fn query(&self, b: &Aabb, mut f: impl FnMut(u32)) {
        self.for_cells(b, |c| {
            for &item in &self.items[self.start[c] as usize..self.start[c + 1] as usize] {
                f(item);
            }
            let mut e = self.head[c];
            while e != NONE {
                let (item, next) = self.extra[e as usize];
                f(item);
                e = next;
            }
        });
    }
}

/// The rest-frame index of one body's triangles and springs, for its cutter.
#[derive(Clone, Debug)]
pub struct RestIndex {
    triangles: CellGrid,
    edges: CellGrid,
    /// The body's topology version the grids describe (with the cutter's own changes told).
    version: u64,
    /// The grids describe the body (built, and every change since told).
    valid: bool,
    /// Largest distance of a homologue from the body frame's origin (m), at the last build.
    radius: f64,
    /// Times the grids were built.
    pub builds: u64,
    stamp: u32,
    triangle_stamp: Vec<u32>,
    edge_stamp: Vec<u32>,
    /// What the last query found, in index order.
    pub found: crate::Room<u32>,
}

fn rest_box(h: &[Vec3], corners: &[u32]) -> Aabb {
    let mut b = Aabb::empty();
    for &v in corners {
        b.include(&h[v as usize]);
    }
    b
}

impl RestIndex {
    /// An index with room for `triangles` triangles and `edges` springs (the body's limits).
    pub fn with_capacity(triangles: usize, edges: usize) -> Self {
        Self {
            triangles: CellGrid::with_capacity(triangles),
            edges: CellGrid::with_capacity(edges),
            version: u64::MAX,
            valid: false,
            radius: 0.0,
            builds: 0,
            stamp: 0,
            triangle_stamp: vec![0; triangles],
            edge_stamp: vec![0; edges],
            found: crate::Room::with_capacity(triangles.max(edges)),
        }
    }

    /// Whether the grids describe `body` as it is now.
    pub fn is_valid_for(&self, body: &Body) -> bool {
        self.valid && self.version == body.topology_version
    }

    /// Makes the grids describe `body` (built again if the body changed otherwise than told).
    /// Returns whether they do (false: the body outgrew the room; the caller passes over the mesh).
    pub fn sync(&mut self, body: &Body, cell: f64) -> bool {
        if self.is_valid_for(body) {
            return true;
        }
        self.valid = false;
        let s = &body.surface;
        let h = &s.homologue_in_body;
        if s.triangles.len() > self.triangle_stamp.len() || body.edges.len() > self.edge_stamp.len()
        {
            return false;
        }
        let mut bounds = Aabb::empty();
        let mut radius2 = 0.0f64;
        for p in h {
            bounds.include(p);
            radius2 = radius2.max(p.norm_squared());
        }
        if !radius2.is_finite() || h.is_empty() {
            return false;
        }
        self.builds += 1;
        self.radius = radius2.sqrt();
        self.triangles.lay(&bounds, cell);
        self.edges.lay(&bounds, cell);
        let triangles = &s.triangles;
        let e = &body.edges;
        self.valid = self
            .triangles
            .build(triangles.len(), |t| rest_box(h, &triangles[t]))
            && self
                .edges
                .build(e.len(), |k| rest_box(h, &[e.a[k], e.b[k]]));
        self.version = body.topology_version;
        self.valid
    }

    /// Largest distance of a homologue from the body frame's origin at the last build (m): no node
    /// made since lies farther (split nodes lie between their edge's ends, copies on their origin).
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// Tells the index that triangle `t` of `body` is new or was rewritten.
    pub fn triangle_changed(&mut self, body: &Body, t: u32) {
        if self.valid {
            let b = rest_box(
                &body.surface.homologue_in_body,
                &body.surface.triangles[t as usize],
            );
            self.valid = self.triangles.add(t, &b);
        }
    }

    /// Tells the index that spring `k` of `body` is new or was rewritten.
    pub fn edge_changed(&mut self, body: &Body, k: u32) {
        if self.valid {
            let e = &body.edges;
            let b = rest_box(
                &body.surface.homologue_in_body,
                &[e.a[k as usize], e.b[k as usize]],
            );
            self.valid = self.edges.add(k, &b);
        }
    }

    /// The index now describes `body` at its current version (after the cutter told it every
    /// change it made). Without a valid index, nothing.
    pub fn caught_up(&mut self, body: &Body) {
        if self.valid {
            self.version = body.topology_version;
        }
    }

    /// Forgets the grids (the body was renumbered).
    pub fn invalidate(&mut self) {
        self.valid = false;
    }

    fn next_stamp(&mut self) -> u32 {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.triangle_stamp.iter_mut().for_each(|s| *s = 0);
            self.edge_stamp.iter_mut().for_each(|s| *s = 0);
            self.stamp = 1;
        }
        self.stamp
    }

    /// Starts a collection into `found` (see [`RestIndex::collect_triangles`],
    /// [`RestIndex::collect_edges`], [`RestIndex::finish`]).
    pub fn begin(&mut self) -> u32 {
        self.found.clear();
        self.next_stamp()
    }

    /// Adds to `found` the triangles listed near `b` (in rest coordinates) that `keep` accepts, each
    /// once in this collection. Only triangles that exist are offered.
    pub fn collect_triangles(
        &mut self,
        body: &Body,
        b: &Aabb,
        stamp: u32,
        mut keep: impl FnMut(u32, &[u32; 3]) -> bool,
    ) {
        let triangles = &body.surface.triangles;
        let (grid, marks, found) = (&self.triangles, &mut self.triangle_stamp, &mut self.found);
        grid.query(b, |t| {
            let i = t as usize;
            if i < triangles.len() && marks[i] != stamp {
                marks[i] = stamp;
                if keep(t, &triangles[i]) && found.len() < found.capacity() {
                    found.push(t);
                }
            }
        });
    }

    /// Adds to `found` the springs listed near `b` (in rest coordinates) that `keep` accepts (given
    /// the index and both ends), each once in this collection.
    pub fn collect_edges(
        &mut self,
        body: &Body,
        b: &Aabb,
        stamp: u32,
        mut keep: impl FnMut(u32, u32, u32) -> bool,
    ) {
        let e = &body.edges;
        let (grid, marks, found) = (&self.edges, &mut self.edge_stamp, &mut self.found);
        grid.query(b, |k| {
            let i = k as usize;
            if i < e.len() && marks[i] != stamp {
                marks[i] = stamp;
                if keep(k, e.a[i], e.b[i]) && found.len() < found.capacity() {
                    found.push(k);
                }
            }
        });
    }

    /// Puts `found` in index order (the order a pass over the mesh meets them).
    pub fn finish(&mut self) {
        self.found.sort_unstable();
    }

    /// The springs with an end at node `v`, in index order, into `found`; false (nothing found)
    /// when the index does not describe `body` as it is.
    pub fn incident_edges(&mut self, body: &Body, v: u32) -> bool {
        if !self.is_valid_for(body) || v as usize >= body.node_count() {
            return false;
        }
        let mark = self.begin();
        let at = Self::point(&body.surface.homologue_in_body[v as usize]);
        self.collect_edges(body, &at, mark, |_, a, b| a == v || b == v);
        self.finish();
        true
    }

    /// The box of a point.
    pub fn point(p: &Vec3) -> Aabb {
        Aabb { min: *p, max: *p }
    }

    /// The spring between `a` and `b` with the least index, if any (a pass over the springs finds
    /// that one first).
    pub fn find_edge(&mut self, body: &Body, a: u32, b: u32) -> Option<usize> {
        let mark = self.begin();
        let at = Self::point(&body.surface.homologue_in_body[a as usize]);
        self.collect_edges(body, &at, mark, |_, p, q| {
            (p == a && q == b) || (p == b && q == a)
        });
        self.found.iter().min().map(|&k| k as usize)
    }

    /// The triangle with least index that `keep` accepts among those with a corner at `v`.
    pub fn first_triangle_at(
        &mut self,
        body: &Body,
        v: u32,
        mut keep: impl FnMut(&[u32; 3]) -> bool,
    ) -> Option<usize> {
        let mark = self.begin();
        let at = Self::point(&body.surface.homologue_in_body[v as usize]);
        self.collect_triangles(body, &at, mark, |_, t| t.contains(&v) && keep(t));
        self.found.iter().min().map(|&t| t as usize)
    }
}
