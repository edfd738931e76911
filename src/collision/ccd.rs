//! Continuous collision detection (CCD), narrow phase: does a moving vertex hit a moving triangle, or
//! a moving edge hit a moving edge, during a step, and when first?
//!
//! Data in: the 8 positions of one query, at the start (t = 0) and at the end (t = 1) of the step,
//! the motion being linear in t in between, and [`CcdSettings`]. Data out: `None` when the two
//! primitives provably never touch during the step, otherwise a [`CcdHit`] whose `time_of_impact`
//! is a lower bound of the earliest contact time. Nothing is allocated on the heap, nothing is kept
//! between queries, and the same input always gives the same output.
//!
//! Method: inclusion-based root finding, after Wang, Ferguson, Schneider, Jiang, Attene and Panozzo,
//! "A Large Scale Benchmark and an Inclusion-Based Algorithm for Continuous Collision Detection",
//! ACM TOG 40(5), 2021. A contact is a zero of a function F(t, u, v) ∈ ℝ³ on the box [0, 1]³, where
//! u and v place the contact point on the face (barycentric) or on each edge. F is affine in each of
//! t, u and v separately, so over any sub-box each coordinate of F lies between the least and the
//! greatest of its 8 corner values. A box is thrown away when, for some coordinate, all 8 computed
//! corner values are farther from 0 than a rigorous bound of their rounding error; otherwise it is
//! split in two, and the pending box that starts earliest in time is examined next, until one box has
//! F within the tolerance of 0 over all of it (a hit at its start time) or none is left (no contact).
//! Additions to the paper's scheme cut the boxes examined several-fold on degenerate queries:
//! * the same exclusion test on five combinations r·F of the coordinates chosen per box from the
//!   Jacobian of F (`ContactFunction::rejected_along_jacobian_rows` below), two of which still
//!   work when the motion stays in one plane;
//! * a *witness*: at the start time of a box that is not thrown away, the (u, v) where |F| is least
//!   is found in floating point and F is checked there with the rigorous bound; within a quarter of
//!   the tolerance, the box is a hit at its start time, with no need to split u and v down to the
//!   tolerance (`ContactFunction::witness_at`). A near miss that rounding can still resolve is not
//!   taken for a witness;
//! * time intervals with float ends, cut where a coordinate that provably has no zero on the box's
//!   start face can first reach zero (F is affine in t at each (u, v) corner), instead of halved
//!   level after level towards that front;
//! * cut just before a root that Newton's method finds in the box (on the domain's sides when
//!   F keeps to a plane), so that a crossing at an angle is settled in a few boxes instead of
//!   being closed in on one bit at a time (`ContactFunction::newton_time_cut`);
//! * and, where the primitives move in a coordinate plane (F exactly 0 on an axis), a box inside
//!   the (u, v) domain that starts after 0 is thrown away: there the earliest contact is at the
//!   start or on a side of the domain (see `ContactFunction::evaluate`).
//!
//! Why no contact is ever missed: the u and v intervals are dyadic (k / 2^level) and the time
//! intervals' ends are floats, so the corners are exact floats and two parts of a box share their
//! cut, covering their parent exactly; the only roundings are in the corner values,
//! and they are bounded from above (`ContactFunction::new` below derives the bound); so a box is
//! thrown away only when the exact F has no zero in it. Running out of work (`max_boxes`, 64 by
//! default, or the fixed queue filling up) never gives `None`: it reports a hit at the earliest time
//! not yet resolved, with `exhausted` set. The search is compiled a second time for AVX2, taken when
//! the machine has it, with the same IEEE operations (the same answers to the bit).
//!
//! ```
//! use palpa::Vec3;
//! use palpa::collision::ccd::{CcdSettings, vertex_face_time_of_impact};
//!
//! // A point falling from 1 m above a fixed triangle to 1 m below it: contact at t = 1/2.
//! let (a, b, c) = (Vec3::zeros(), Vec3::x(), Vec3::y());
//! let (p0, p1) = (Vec3::new(0.25, 0.25, 1.0), Vec3::new(0.25, 0.25, -1.0));
//! let settings = CcdSettings::default();
//! let hit = vertex_face_time_of_impact(&p0, &a, &b, &c, &p1, &a, &b, &c, &settings)
//!     .expect("they touch");
//! assert!(hit.time_of_impact <= 0.5 && hit.time_of_impact > 0.5 - 1e-5);
//!
//! // 1 mm beside the triangle's edge: provably no contact.
//! let (p0, p1) = (Vec3::new(-0.001, 0.5, 1.0), Vec3::new(-0.001, 0.5, -1.0));
//! assert_eq!(vertex_face_time_of_impact(&p0, &a, &b, &c, &p1, &a, &b, &c, &settings), None);
//! ```

use crate::Vec3;
use std::mem::MaybeUninit;

/// Settings of the inclusion-based root finder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CcdSettings {
    /// Target precision in the units of the coordinates (m): a box of the (t, u, v) domain is
    /// reported as a contact once every coordinate of the contact function over it provably lies
    /// within ±`tolerance`; a false positive then means the primitives come within √3 × `tolerance`
    /// of each other. It is raised when needed to 16 times the rounding error bound of the query
    /// (which grows with the magnitude of the coordinates), so that a box can always be accepted.
    /// Smaller gives a tighter time of impact and costs more boxes per contact.
    pub tolerance: f64,
    /// The most boxes one query examines. Past it the query stops and reports a hit with
    /// `exhausted = true` at the earliest time not yet resolved, which bounds the running time.
    pub max_boxes: u32,
}

impl Default for CcdSettings {
    /// 1 µm and [`DEFAULT_MAX_BOXES`] boxes (see there for the time it bounds). On the public
    /// benchmark's hand-made queries (coordinates of order 1) the false positives are separations
    /// below what f64 resolves. Every one of its queries is settled within 59 boxes (its 320
    /// contacts take 10.7 on average; up to 115, and 6 exhausted at the budget, before the Newton
    /// cuts); an exhausted query is reported at the earliest time not yet resolved — an earlier,
    /// still conservative, time of impact.
    fn default() -> Self {
        Self {
            tolerance: 1e-6,
            max_boxes: DEFAULT_MAX_BOXES,
        }
    }
}

/// Default of [`CcdSettings::max_boxes`]: a bound on the time of one query. A box past the first
/// [`LATE_TESTS_AFTER`] costs about 140 ns (edges) to 210 ns (a vertex and a face, with the
/// triangle's part across its hypotenuse) on the development machine: a query that spends the
/// budget takes 9 to 13 µs (18 to 30 µs at the 128 boxes before 2026-12-08). Every query of the
/// public benchmark's shared set settles within 59 boxes (6.2 µs at most), so the budget changes
/// none of its answers or times of impact; 1 200 made degenerate on purpose (edges sliding
/// parallel, vertices sliding in, beside or just above the triangle's plane) settle within 28
/// (3.5 µs); edges moving in a coordinate plane spend it in about 1 case in 430 to 3 000 (1 in 2 000
/// to 3 000 at 128), each then a hit at the earliest time not yet resolved (conservative; the world
/// counts them, `BodyContactCounters::budget_spent`). The simulation's own queries spend it in a
/// body folding onto itself (`scenes/self_fold.toml`, 3 s): 4 of 5 781 collisions. (Halved from
/// 128 on 2026-12-08, it was 244 of 5 729 at first: ordinary crossings of millimetre edges moving
/// a millimetre took 65 to 99 boxes, answered a median 3.4e-4 of a tick early; the cut before a
/// Newton root as far as the witness reaches, [`ContactFunction::cut_before`], settles them in 19
/// to 34.) A stack crushed by a probe still comes apart when it lifts (`tests/body_contact.rs`).
pub const DEFAULT_MAX_BOXES: u32 = 64;

/// Outcome of one query that may be a contact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CcdHit {
    /// A lower bound of the earliest contact time, in [0, 1] (0 = start of the step).
    pub time_of_impact: f64,
    /// How many boxes of the (t, u, v) domain were examined.
    pub boxes: u32,
    /// True when the query stopped before settling (the box budget, a full queue, or input that
    /// is not finite or too large): the contact is then only "not excluded", and
    /// `time_of_impact` is the earliest time still unresolved.
    pub exhausted: bool,
}

/// Point p moving linearly from p0 (t=0) to p1 (t=1) against triangle (a,b,c) moving linearly a0->a1 etc.
/// Returns Some(hit) when they may touch at some t in [0,1]; time_of_impact is a conservative lower bound
/// of the earliest contact time; None only when they provably never touch.
///
/// The triangle is closed (its edges and corners count) and may be degenerate.
#[allow(clippy::too_many_arguments)] // the 8 positions of a query, in the benchmark's order
pub fn vertex_face_time_of_impact(
    p0: &Vec3,
    a0: &Vec3,
    b0: &Vec3,
    c0: &Vec3,
    p1: &Vec3,
    a1: &Vec3,
    b1: &Vec3,
    c1: &Vec3,
    settings: &CcdSettings,
) -> Option<CcdHit> {
    if !all_finite(&[p0, a0, b0, c0, p1, a1, b1, c1]) {
        return Some(unresolved());
    }
    // The moving point stays in the box of its two positions; every point of the moving triangle
    // is a convex combination of its six positions. Disjoint boxes mean no contact.
    if boxes_disjoint(&[p0, p1], &[a0, b0, c0, a1, b1, c1]) {
        return None;
    }
    // F = p − (a + u (b − a) + v (c − a)) = (p − a) + u (a − b) + v (a − c), u, v ≥ 0, u + v ≤ 1.
    ContactFunction::new(
        [p0 - a0, p1 - a1],
        [a0 - b0, a1 - b1],
        [a0 - c0, a1 - c1],
        true,
        settings.tolerance,
    )
    .map_or(Some(unresolved()), |f| f.earliest_root(settings.max_boxes))
}

/// Edge (a,b) against edge (c,d), each end moving linearly from t=0 to t=1.
///
/// Returns `Some(hit)` when the edges may touch at some t in [0, 1], with `time_of_impact` a
/// conservative lower bound of the earliest contact time; `None` only when they provably never
/// touch. The edges are closed segments (their ends count) and may be parallel or of zero length.
#[allow(clippy::too_many_arguments)] // the 8 positions of a query, in the benchmark's order
pub fn edge_edge_time_of_impact(
    a0: &Vec3,
    b0: &Vec3,
    c0: &Vec3,
    d0: &Vec3,
    a1: &Vec3,
    b1: &Vec3,
    c1: &Vec3,
    d1: &Vec3,
    settings: &CcdSettings,
) -> Option<CcdHit> {
    if !all_finite(&[a0, b0, c0, d0, a1, b1, c1, d1]) {
        return Some(unresolved());
    }
    if boxes_disjoint(&[a0, b0, a1, b1], &[c0, d0, c1, d1]) {
        return None;
    }
    // F = (a + u (b − a)) − (c + v (d − c)) = (a − c) + u (b − a) + v (c − d), u, v ∈ [0, 1].
    ContactFunction::new(
        [a0 - c0, a1 - c1],
        [b0 - a0, b1 - a1],
        [c0 - d0, c1 - d1],
        false,
        settings.tolerance,
    )
    .map_or(Some(unresolved()), |f| f.earliest_root(settings.max_boxes))
}

/// The answer when nothing can be proved (input not finite, or too large to evaluate safely).
fn unresolved() -> CcdHit {
    CcdHit {
        time_of_impact: 0.0,
        boxes: 0,
        exhausted: true,
    }
}

fn all_finite(points: &[&Vec3]) -> bool {
    points.iter().all(|p| p.iter().all(|x| x.is_finite()))
}

/// True when the axis-aligned bounding boxes of the two point sets are disjoint. Only comparisons,
/// so no rounding: a strict gap on one axis proves that their convex hulls never meet.
fn boxes_disjoint(first: &[&Vec3], second: &[&Vec3]) -> bool {
    (0..3).any(|k| {
        let (lo1, hi1) = extent(first, k);
        let (lo2, hi2) = extent(second, k);
        hi1 < lo2 || hi2 < lo1
    })
}

fn extent(points: &[&Vec3], k: usize) -> (f64, f64) {
    points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p[k]), hi.max(p[k]))
        })
}

/// Deepest bisection level of one parameter: interval ends k / 2^level stay exact in f64, and so
/// does 1 − t. In practice the tolerance or `max_boxes` ends the search long before.
const MAX_LEVEL: u32 = 52;

/// Room for pending boxes. The search is best-first in time, so the boxes waiting are those that
/// start later than the one being split. Most queries need a handful, so the search starts with a
/// small queue (cheap to set up on the stack) and moves to the large one only when that fills up;
/// none of the benchmark's hand-made degenerate queries fills the large one. A full large queue
/// ends the query as an exhausted hit, like the box budget.
const SMALL_QUEUE: usize = 32;
/// See [`SMALL_QUEUE`]. 1024 boxes of 56 bytes, on the stack.
const LARGE_QUEUE: usize = 1024;

/// The effective tolerance is at least this many rounding error bounds, so that a box can always be
/// accepted however large the coordinates are (otherwise the search could only end by exhaustion).
const TOLERANCE_FLOOR_IN_ERRORS: f64 = 16.0;

/// A witness (a point where F is checked to be within the tolerance, see
/// [`ContactFunction::witness_at`]) must be within this fraction of the tolerance: a quarter, so
/// that a witness found at the start of a box still leaves room for the time the box spans.
const WITNESS_SCALE: f64 = 0.25;

/// Above this sum of magnitudes the corner values could overflow: such a query is not searched.
const LARGEST_MAGNITUDE: f64 = 1e300;

/// The Jacobian-row test multiplies three magnitudes (r·F is cubic in them): above this it is
/// skipped, as it could overflow. Below it, at most 96 S³ < 1e303.
const LARGEST_MAGNITUDE_FOR_ROWS: f64 = 1e100;

/// One dyadic interval [k / 2^level, (k + 1) / 2^level] of [0, 1], its ends kept as floats (exact:
/// k < 2^52) so that a box's examination does not rebuild them from bits; its level is read off the
/// exponent of its width, 2^−level exactly.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Dyadic {
    lo: f64,
    hi: f64,
}

impl Dyadic {
    const WHOLE: Dyadic = Dyadic { lo: 0.0, hi: 1.0 };

    fn level(self) -> u32 {
        let width = self.hi - self.lo;
        1023 - ((width.to_bits() >> 52) as u32 & 0x7ff)
    }

    /// Both ends, exactly.
    fn bounds(self) -> (f64, f64) {
        (self.lo, self.hi)
    }

    /// (2k + 1) / 2^(level + 1), exactly: the width is a power of two, its half too, and the sum
    /// has at most 53 significant bits below level 53.
    fn middle(self) -> f64 {
        self.lo + 0.5 * (self.hi - self.lo)
    }

    fn lower_half(self) -> Dyadic {
        Dyadic {
            lo: self.lo,
            hi: self.middle(),
        }
    }

    fn upper_half(self) -> Dyadic {
        Dyadic {
            lo: self.middle(),
            hi: self.hi,
        }
    }
}

/// A box of the parameter domain. The time interval has float ends (it is cut in halves, or where
/// a coordinate of F can first reach 0, see [`ContactFunction::evaluate`]); the two parts of a cut
/// share the cut float, so they cover their parent exactly. u and v are dyadic.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ParamBox {
    /// [start, end] of the time interval, 0 ≤ start < end ≤ 1.
    t: (f64, f64),
    /// How many cuts made the time interval (its depth in the search).
    t_cuts: u32,
    u: Dyadic,
    v: Dyadic,
    /// Cuts of all three parameters that made the box (t_cuts plus the levels of u and v), kept
    /// so that [`priority`], which the queue computes often, needs no level from a width.
    depth: u32,
}

impl ParamBox {
    const WHOLE: ParamBox = ParamBox {
        t: (0.0, 1.0),
        t_cuts: 0,
        u: Dyadic::WHOLE,
        v: Dyadic::WHOLE,
        depth: 0,
    };

    /// The two parts of the box cut along parameter `param` (0 = t, at `t_cut`; 1 = u; 2 = v).
    #[inline(always)]
    fn cut(&self, param: usize, t_cut: f64) -> [ParamBox; 2] {
        let (mut lower, mut upper) = (*self, *self);
        match param {
            0 => {
                lower.t = (self.t.0, t_cut);
                upper.t = (t_cut, self.t.1);
                lower.t_cuts += 1;
                upper.t_cuts += 1;
            }
            1 => {
                lower.u = self.u.lower_half();
                upper.u = self.u.upper_half();
            }
            _ => {
                lower.v = self.v.lower_half();
                upper.v = self.v.upper_half();
            }
        }
        lower.depth += 1;
        upper.depth += 1;
        [lower, upper]
    }
}

/// Most cuts of one time interval: far more than the tolerance needs (halving 1 down to 1e-15
/// takes 50), a bound on the search's depth.
const MAX_TIME_CUTS: u32 = 120;

/// A cut at the front of a coordinate that would leave less than this fraction of the time
/// interval before it is not made (the front is then as good as at the start, and such cuts could
/// crawl forward one float at a time); the box is split as any other.
const MIN_FRONT_FRACTION: f64 = 1.0 / 1024.0;

/// The middle of a time interval when it lies strictly inside it (a float between its ends).
#[inline(always)]
fn time_middle(t: (f64, f64)) -> Option<f64> {
    let middle = t.0 + 0.5 * (t.1 - t.0);
    (t.0 < middle && middle < t.1).then_some(middle)
}

/// Order of examination: earlier start in time first; among equal starts, the more split box first
/// (it is closer to being settled, and finishing it keeps the queue short). Integer keys, so the
/// order is exact and the same on every machine: the bits of a non-negative float order as it does.
#[inline(always)]
fn priority(b: &ParamBox) -> u128 {
    let start = u128::from(b.t.0.to_bits());
    debug_assert_eq!(b.depth, b.t_cuts + b.u.level() + b.v.level());
    (start << 32) | u128::from(u32::MAX - b.depth)
}

/// A binary min-heap of boxes by [`priority`] in a fixed array: no allocation, and no
/// initialisation either (the large queue is 56 KiB, which writing out would cost microseconds
/// on every query that needs it): only the slots below `len` are ever read, and each was written.
struct Queue<const N: usize> {
    items: [MaybeUninit<ParamBox>; N],
    len: usize,
}

impl<const N: usize> Queue<N> {
    fn new() -> Self {
        Queue {
            items: [const { MaybeUninit::uninit() }; N],
            len: 0,
        }
    }

    /// Item `i` (below `len`).
    #[inline(always)]
    fn get(&self, i: usize) -> ParamBox {
        assert!(i < self.len, "a queue slot past its length");
        // SAFETY: every slot below `len` holds an item: `push` writes slot `len` before `len`
        // counts it, and the sifts only copy items between slots below `len`.
        unsafe { self.items[i].assume_init() }
    }

    #[inline(always)]
    fn set(&mut self, i: usize, item: ParamBox) {
        self.items[i] = MaybeUninit::new(item);
    }

    /// The items waiting, in heap order.
    fn pending(&self) -> impl Iterator<Item = ParamBox> + '_ {
        (0..self.len).map(|i| self.get(i))
    }

    /// The caller checks that there is room.
    #[inline(always)]
    fn push(&mut self, b: ParamBox) {
        let key = priority(&b);
        let mut i = self.len;
        self.len += 1;
        while i > 0 {
            let parent = (i - 1) / 2;
            let above = self.get(parent);
            if priority(&above) <= key {
                break;
            }
            self.set(i, above);
            i = parent;
        }
        self.set(i, b);
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<ParamBox> {
        if self.len == 0 {
            return None;
        }
        let top = self.get(0);
        let last = self.get(self.len - 1);
        let last_key = priority(&last);
        self.len -= 1;
        let mut i = 0;
        loop {
            let mut child = 2 * i + 1;
            if child >= self.len {
                break;
            }
            if child + 1 < self.len && priority(&self.get(child + 1)) < priority(&self.get(child)) {
                child += 1;
            }
            let below = self.get(child);
            if priority(&below) >= last_key {
                break;
            }
            self.set(i, below);
            i = child;
        }
        self.set(i, last);
        Some(top)
    }
}

/// Time intervals whose witness was looked for in vain, the last few. The witness of a box depends
/// only on its time interval (its (u, v) is sought over the whole domain), which the boxes split
/// along u and v share: the search asks again for the same one, often many times in a row. A pure
/// function remembered, so the answers and their bits are those of the search without it.
#[derive(Default)]
struct WitnessMemo {
    failed: [(u64, u64); WITNESS_MEMO],
    next: usize,
}

/// A Newton point counts as a root (see [`ContactFunction::newton_time_cut`]) when every coordinate
/// of F there is within this fraction of the tolerance: a near miss closer than the tolerance is
/// not taken for one (its cuts would only crowd the search around it).
const NEWTON_RESIDUAL: f64 = 1e-2;
/// Newton steps from the box's centre (the root of an isolated crossing is found to rounding in a
/// few once the box holds it).
const NEWTON_STEPS: usize = 4;

/// The Newton cuts, the start and end normals of the Jacobian-row test and the triangle's part
/// across its hypotenuse are tried only on a box examined after this many in the query. A query of
/// the simulation's collision net takes 2 to 3 boxes and keeps the answers, to the bit, of the
/// search without them (any change of the boxes' order moves the time of impact reported within
/// the tolerance, and with it a whole simulation's bits); the slow queries, degenerate or near
/// misses, spend most of their boxes past it, where these tests settle them.
const LATE_TESTS_AFTER: u32 = 16;

/// What Newton's method found in a box (see [`ContactFunction::newton_time_cut`]).
enum NewtonRoot {
    /// A root well inside the box's time: cut just before it.
    Cut(f64),
    /// A root at the box's start time, at this (u, v), and the time just before it (at or before
    /// the start when the root is within a witness's reach of it).
    AtStart(f64, f64, f64),
}

/// Failed witness searches remembered (the boxes pending at a time interval are few).
const WITNESS_MEMO: usize = 4;

impl WitnessMemo {
    /// Bits, not values: the interval is the same only if its ends are the same floats (and
    /// (0, 0), the empty slot, is no interval).
    fn key(t: (f64, f64)) -> (u64, u64) {
        (t.0.to_bits(), t.1.to_bits())
    }

    #[inline(always)]
    fn holds(&self, t: (f64, f64)) -> bool {
        let key = Self::key(t);
        self.failed.contains(&key)
    }

    #[inline(always)]
    fn insert(&mut self, t: (f64, f64)) {
        self.failed[self.next] = Self::key(t);
        self.next = (self.next + 1) % WITNESS_MEMO;
    }
}

/// What a search has done so far: boxes examined, failed witnesses.
#[derive(Default)]
struct SearchState {
    boxes: u32,
    failed_witnesses: WitnessMemo,
}

/// What to do with a box after evaluating F at its corners.
#[derive(Debug)]
enum Verdict {
    /// F provably has no zero in the box.
    Reject,
    /// F is within the tolerance of 0 over the whole box (or the box cannot be split): a hit.
    Accept,
    /// Split along this parameter (0 = t, 1 = u, 2 = v); a time split at the given time.
    Split(usize, f64),
}

/// F(t, u, v) = D(t) + u E(t) + v G(t) with X(t) = (1 − t) X₀ + t X₁, coordinate by coordinate; the
/// differences D, E, G of the query positions at t = 0 and t = 1 are computed once per query.
struct ContactFunction {
    /// [time][axis].
    d: [[f64; 3]; 2],
    e: [[f64; 3]; 2],
    g: [[f64; 3]; 2],
    /// Upper bound of |computed − exact| of any corner value of F, per axis.
    error: [f64; 3],
    /// The same for the Jacobian-row test: 0 on an axis where D, E and G are all 0 (F is exactly
    /// 0 there, with no rounding), which keeps `f64::MIN_POSITIVE` out of its products: times a
    /// row's component below 1 it gives a subnormal number, which x86 processors compute in
    /// microcode at a hundred times the cost (primitives moving in a coordinate plane, common in
    /// the benchmark's hand-made queries, spent half their time there).
    row_error: [f64; 3],
    tolerance: f64,
    /// Vertex–face: only u + v ≤ 1 is on the triangle.
    triangle: bool,
    /// Whether the magnitudes allow the Jacobian-row test without overflow.
    use_rows: bool,
    /// Whether F is exactly 0 on some axis (the eight points share that coordinate: primitives
    /// moving in a coordinate plane), where the earliest contact lies on a side of the domain or at
    /// the start (see [`ContactFunction::evaluate`]).
    planar: bool,
}

impl ContactFunction {
    /// Takes the differences, already rounded, and derives the rounding error bound.
    ///
    /// Error analysis (standard model fl(x ∘ y) = (x ∘ y)(1 + δ), |δ| ≤ ε = 2⁻⁵³, γₙ = nε / (1 − nε)):
    /// * each difference is one rounding away from the exact one, so for D: |D − D*| ≤ γ₁ |D|. F is
    ///   linear in D, E, G with weights (1 − t), (1 − t) u, (1 − t) v, t, t u, t v (u, v ≤ 1), so
    ///   the rounded differences move F by at most γ₁ S, with S = max over the two times of
    ///   |D| + |E| + |G|;
    /// * a corner value is evaluated as (D(t) + u·E(t)) + v·G(t), with X(t) = (1 − t)·X₀ + t·X₁;
    ///   every term goes through at most 6 roundings (1 − t, the product by it, the sum with t·X₁,
    ///   the product by u, then two sums), so the evaluation error is at most γ₆ times
    ///   (1 − t)(|D₀| + u|E₀| + v|G₀|) + t(|D₁| + u|E₁| + v|G₁|) ≤ γ₆ S.
    ///
    /// γ₁ + γ₆ < 7.001 ε, so 8 ε S (computed with a few more roundings, still > 7.001 ε S) bounds
    /// the total, with more than 10 % to spare. Products can underflow, adding at most 2⁻¹⁰⁷⁵ each:
    /// `f64::MIN_POSITIVE` covers them. The bound is the same for every box of the query.
    ///
    /// Returns `None` when the magnitudes are too large to evaluate without overflow.
    fn new(
        d: [Vec3; 2],
        e: [Vec3; 2],
        g: [Vec3; 2],
        triangle: bool,
        tolerance: f64,
    ) -> Option<Self> {
        let mut f = ContactFunction {
            d: [d[0].into(), d[1].into()],
            e: [e[0].into(), e[1].into()],
            g: [g[0].into(), g[1].into()],
            error: [0.0; 3],
            row_error: [0.0; 3],
            tolerance: 0.0,
            triangle,
            use_rows: true,
            planar: false,
        };
        let epsilon = f64::EPSILON / 2.0;
        let mut largest_error: f64 = 0.0;
        for k in 0..3 {
            let magnitude = |i: usize| f.d[i][k].abs() + f.e[i][k].abs() + f.g[i][k].abs();
            let s = magnitude(0).max(magnitude(1));
            // False for NaN and infinity too (differences of finite inputs can overflow).
            let evaluable = s < LARGEST_MAGNITUDE;
            if !evaluable {
                return None;
            }
            f.use_rows &= s < LARGEST_MAGNITUDE_FOR_ROWS;
            f.error[k] = 8.0 * epsilon * s + f64::MIN_POSITIVE;
            f.row_error[k] = if s > 0.0 { f.error[k] } else { 0.0 };
            // (A difference of two finite floats is 0 only when they are equal: exact.)
            f.planar |= s == 0.0;
            largest_error = largest_error.max(f.error[k]);
        }
        // A NaN or negative setting falls back to the floor (max ignores NaN).
        f.tolerance = tolerance.max(TOLERANCE_FLOOR_IN_ERRORS * largest_error);
        Some(f)
    }

    /// Best-first search of [0, 1]³: the pending box that starts earliest in time is examined next,
    /// so the first box accepted starts no later than the earliest contact (which lies in that box
    /// or in a pending one, and those start no earlier). A depth-first search would instead trace a
    /// whole curve of contacts backwards in time down to the tolerance (edges crossing in a common
    /// plane), one accepted box after another.
    fn earliest_root(&self, max_boxes: u32) -> Option<CcdHit> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the machine has AVX2, checked just above.
            return unsafe { self.earliest_root_avx2(max_boxes) };
        }
        self.earliest_root_here(max_boxes)
    }

    /// [`ContactFunction::earliest_root`] compiled for AVX2: the same IEEE operations in the same
    /// order (no fused multiply–add: only `avx` and `avx2` are enabled, and Rust never contracts a
    /// product and a sum on its own), so the same answer to the bit, in fewer instructions.
    ///
    /// # Safety
    /// The machine must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2")]
    unsafe fn earliest_root_avx2(&self, max_boxes: u32) -> Option<CcdHit> {
        self.earliest_root_here(max_boxes)
    }

    #[inline(always)]
    fn earliest_root_here(&self, max_boxes: u32) -> Option<CcdHit> {
        let mut queue = Queue::<SMALL_QUEUE>::new();
        queue.push(ParamBox::WHOLE);
        let mut state = SearchState::default();
        match self.search(&mut queue, &mut state, max_boxes) {
            Ok(result) => result,
            Err(halves) => self.search_on(&queue, halves, state, max_boxes),
        }
    }

    /// The rest of a search whose small queue is full, in a large queue.
    #[cold]
    #[inline(never)]
    fn search_on(
        &self,
        small: &Queue<SMALL_QUEUE>,
        halves: [ParamBox; 2],
        mut state: SearchState,
        max_boxes: u32,
    ) -> Option<CcdHit> {
        let mut queue = Queue::<LARGE_QUEUE>::new();
        for b in small.pending().chain(halves) {
            queue.push(b);
        }
        match self.search(&mut queue, &mut state, max_boxes) {
            Ok(result) => result,
            // The box just split started earliest among the pending ones, and its lower half
            // starts where it did: a conservative stop.
            Err([lower, _]) => Some(CcdHit {
                time_of_impact: lower.t.0,
                boxes: state.boxes,
                exhausted: true,
            }),
        }
    }

    /// Examines boxes until the queue is empty (`Ok(None)`), a box is accepted or the budget is
    /// spent (`Ok(Some(hit))`), or the two halves of a split box do not fit (`Err(halves)`).
    #[inline(always)]
    fn search<const N: usize>(
        &self,
        queue: &mut Queue<N>,
        state: &mut SearchState,
        max_boxes: u32,
    ) -> Result<Option<CcdHit>, [ParamBox; 2]> {
        let boxes = &mut state.boxes;
        while let Some(current) = queue.pop() {
            let t_lo = current.t.0;
            if *boxes >= max_boxes {
                // `current` starts earliest among the unresolved boxes: a conservative stop.
                return Ok(Some(CcdHit {
                    time_of_impact: t_lo,
                    boxes: *boxes,
                    exhausted: true,
                }));
            }
            *boxes += 1;
            let verdict = self.evaluate(&current, &mut state.failed_witnesses, *boxes);
            match verdict {
                Verdict::Reject => {}
                Verdict::Accept => {
                    return Ok(Some(CcdHit {
                        time_of_impact: t_lo,
                        boxes: *boxes,
                        exhausted: false,
                    }));
                }
                Verdict::Split(param, t_cut) => {
                    let [lower, upper] = current.cut(param, t_cut);
                    if queue.len + 2 > N {
                        return Err([lower, upper]);
                    }
                    queue.push(lower);
                    queue.push(upper);
                }
            }
        }
        Ok(None)
    }

    /// Corner values of F over the box, exclusion tests, acceptance, choice of the split.
    #[inline(always)]
    fn evaluate(&self, b: &ParamBox, failed_witnesses: &mut WitnessMemo, boxes: u32) -> Verdict {
        let (t_lo, mut t_hi) = b.t;
        // Examined at its start time alone (see the coordinate planes below): not split in time.
        let mut at_start_only = false;
        let (mut u_lo, mut u_hi) = b.u.bounds();
        let (mut v_lo, mut v_hi) = b.v.bounds();
        // Rounding is monotone and 1 is a float, so a computed sum above 1 means an exact one
        // above 1: the whole box is beyond the triangle's hypotenuse.
        if self.triangle && u_lo + v_lo > 1.0 {
            return Verdict::Reject;
        }
        // Primitives moving in a coordinate plane (F exactly 0 on an axis, the inputs exact): at a
        // time t > 0 where they touch at (u, v) inside the domain, they touched earlier at a side of
        // it (u or v at 0 or 1, or u + v = 1 for a triangle) or at the start. For fixed t, F is
        // affine in (u, v), so its zeros in the domain form a convex set: a point, a segment of a
        // line across the domain (whose ends are on its sides) or the whole domain. At the first
        // time of contact t* > 0 a zero inside the domain alone is a point where the 2 × 2 part of
        // the Jacobian in (u, v) is regular, and the zero then moves continuously with t: it
        // existed, inside, just before t*. So a box that starts after 0 and lies inside the
        // domain holds no earliest contact: it is rejected whole. (Edges moving and turning in one
        // plane had the boxes on either side of their contacts' curve cut in time one by one,
        // all over the (u, v) square: 128 boxes, the budget, in 1 to 2 % of random cases.)
        if self.planar {
            // (Exact: dyadic parameters of at most 52 bits.)
            let hypotenuse = self.triangle && u_hi + v_hi >= 1.0;
            let sides = [
                u_lo == 0.0,
                v_lo == 0.0,
                !self.triangle && u_hi == 1.0,
                !self.triangle && v_hi == 1.0,
            ];
            let on = sides.iter().filter(|&&side| side).count();
            if on == 0 && !hypotenuse {
                if t_lo > 0.0 {
                    return Verdict::Reject;
                }
                // A box inside the domain that starts at 0 holds an earliest contact only at the
                // start: it is examined on its face t = 0 alone, and not split in time. (Edges in a
                // plane that touch after the start had the start of the tick split in u and v
                // across the domain before the earliest-first order left it: of 3 000 translating,
                // 8 spent the budget of 64 boxes, 1 since; of 3 000 turning, 13, 7 since.)
                t_hi = t_lo;
                at_start_only = true;
            }
            // On one side of the square (or of the triangle, along u = 0 or v = 0) only: the
            // rest of the box holds no earliest contact, so the box is examined on that face
            // alone — tighter bounds, and no split across the side. (Edges moving in a
            // coordinate plane had their boxes along the side split in all three parameters:
            // up to 128 boxes, the budget.)
            if t_lo > 0.0 && on == 1 && !hypotenuse {
                match sides.iter().position(|&side| side) {
                    Some(0) => u_hi = 0.0,
                    Some(1) => v_hi = 0.0,
                    Some(2) => u_lo = 1.0,
                    _ => v_lo = 1.0,
                }
            }
        }
        // The two ends of the time interval side by side (the compiler pairs them in SIMD lanes).
        let t = [t_lo, t_hi];
        // Exact for dyadic t, but the error bound does not rely on it.
        let s = [1.0 - t_lo, 1.0 - t_hi];
        let mut lo = [0.0f64; 3];
        let mut hi = [0.0f64; 3];
        // corners[axis][time end][(u, v) corner], and E(t), G(t) (= ∂F/∂u, ∂F/∂v) at both ends.
        let mut corners = [[[0.0f64; 4]; 2]; 3];
        let mut e = [[0.0f64; 2]; 3];
        let mut g = [[0.0f64; 2]; 3];
        for k in 0..3 {
            // Exactly the evaluation order of the error analysis in `new`.
            let d = lerp(s, t, self.d[0][k], self.d[1][k]);
            e[k] = lerp(s, t, self.e[0][k], self.e[1][k]);
            g[k] = lerp(s, t, self.g[0][k], self.g[1][k]);
            for i in 0..2 {
                let at_u_lo = d[i] + u_lo * e[k][i];
                let at_u_hi = d[i] + u_hi * e[k][i];
                let (gv_lo, gv_hi) = (v_lo * g[k][i], v_hi * g[k][i]);
                corners[k][i] = [
                    at_u_lo + gv_lo,
                    at_u_lo + gv_hi,
                    at_u_hi + gv_lo,
                    at_u_hi + gv_hi,
                ];
            }
            let (min, max) = min_max(&corners[k]);
            // The exact F of this axis lies in [min − error, max + error] over the box.
            if min > self.error[k] || max < -self.error[k] {
                return Verdict::Reject;
            }
            lo[k] = min;
            hi[k] = max;
        }
        // The tests a long search needs (see `LATE_TESTS_AFTER`).
        let late = boxes > LATE_TESTS_AFTER;
        if self.use_rows && self.rejected_along_jacobian_rows(&corners, &e, &g, &lo, &hi, late) {
            return Verdict::Reject;
        }
        if late
            && self.triangle
            && u_hi + v_hi > 1.0
            && self.rejected_on_triangle_part(s, t, (u_lo, u_hi), (v_lo, v_hi), &e, &g)
        {
            return Verdict::Reject;
        }
        let within_tolerance = (0..3).all(|k| {
            lo[k] - self.error[k] >= -self.tolerance && hi[k] + self.error[k] <= self.tolerance
        });
        if within_tolerance {
            return Verdict::Accept;
        }
        // A witness: the point of the start face t = t_lo where |F| is least, found in floating
        // point and checked with the rigorous bound. If F is within the tolerance there, the box
        // is a hit at t_lo, as if it had been split down to a box around that point.
        let start_face = start_face_bounds(&corners);
        if self.start_face_within_tolerance(&start_face) && !failed_witnesses.holds(b.t) {
            if self.witness_at(t_lo, t_hi) {
                return Verdict::Accept;
            }
            // (A box examined at its start alone asked with no time after it: not remembered
            // for the boxes of its time interval that ask with the whole interval.)
            if !at_start_only {
                failed_witnesses.insert(b.t);
            }
        }
        // Split the parameter along which F changes most over the box: "widest" measured in the
        // units of F, so a parameter that F hardly depends on is not split in vain.
        let mut change = [0.0f64; 3];
        for k in 0..3 {
            for (start, end) in corners[k][0].iter().zip(&corners[k][1]) {
                change[0] = change[0].max((end - start).abs());
            }
            change[1] = change[1].max(e[k][0].abs()).max(e[k][1].abs());
            change[2] = change[2].max(g[k][0].abs()).max(g[k][1].abs());
        }
        change[1] *= u_hi - u_lo;
        change[2] *= v_hi - v_lo;
        // But when F provably has no zero on the box's start face (t = t_lo), any contact in it is
        // later than t_lo: cut the time interval where the excluding coordinate can first reach 0
        // (F is affine in t at each (u, v) corner, so that time is where the first corner's line
        // crosses the bound); the earlier part is then thrown away when examined. Otherwise boxes
        // whose only contacts are at their end time (parallel edges landing flat on each other)
        // are split along u and v all along the contact set, by the thousand, before the
        // earliest-first order reaches that time; and halving time instead chases, one level at a
        // time, a front that only the coarseness of u and v put there. Not below the tolerance,
        // where time no longer matters for acceptance and the split would only chase rounding.
        let middle = if b.t_cuts < MAX_TIME_CUTS && !at_start_only {
            time_middle(b.t)
        } else {
            None
        };
        if let Some(middle) = middle
            && change[0] > self.tolerance * WITNESS_SCALE
            && let Some(fraction) = self.start_face_front(&corners, &start_face)
            && fraction >= MIN_FRONT_FRACTION
        {
            let cut = t_lo + fraction * (t_hi - t_lo);
            let cut = if t_lo < cut && cut < t_hi {
                cut
            } else {
                middle
            };
            return Verdict::Split(0, cut);
        }
        // A root of F in the box that Newton's method finds (with a residual far below the
        // tolerance): time is cut just before it, so that the later part starts within a witness
        // of it and the earlier part holds no root. Halving would close in on an isolated root one
        // bit of each parameter at a time (a hundred boxes and more for edges crossing at an
        // angle, where the witness at a box's start only counts within a quarter of the
        // tolerance); like the fronts' cuts above, the cut only guides the search.
        if middle.is_some() && late {
            match self.newton_time_cut(b) {
                Some(NewtonRoot::Cut(cut)) => return Verdict::Split(0, cut),
                // A root at the box's start time, where the least-squares witness missed it (F
                // least along a whole line of (u, v), parallel edges, and that line's own least
                // point a near miss rounding tells apart): the witness at the root's (u, v).
                Some(NewtonRoot::AtStart(u, v, cut)) => {
                    if self.witness_at_point(t_lo, t_hi, u, v) {
                        return Verdict::Accept;
                    }
                    // The root lies later than a witness at the start reaches: cut just before
                    // it all the same, however thin the part before (edges in one plane, an end
                    // of one meeting the other a few tenths of a micrometre after a front cut: a
                    // hundred boxes and more halving time down to it, the budget spent).
                    if cut > t_lo {
                        return Verdict::Split(0, cut);
                    }
                }
                None => {}
            }
        }
        let mut best: Option<usize> = None;
        let splittable = [
            middle.is_some(),
            b.u.level() < MAX_LEVEL,
            b.v.level() < MAX_LEVEL,
        ];
        for param in 0..3 {
            if !splittable[param] {
                continue;
            }
            // Strictly greater: on ties the earlier parameter (t first) wins.
            if best.is_none_or(|chosen| change[param] > change[chosen]) {
                best = Some(param);
            }
        }
        match best {
            Some(param) => Verdict::Split(param, middle.unwrap_or(t_lo)),
            // Too small to split and not excluded: it counts as a hit.
            None => Verdict::Accept,
        }
    }

    /// A time just before a root of F in the box, found by [`NEWTON_STEPS`] Newton steps from the
    /// box's centre (on the sides of the domain when F keeps to a plane,
    /// [`ContactFunction::newton_side_cut`]): the root's time less what F moves by an eighth of
    /// the tolerance at the root, so that the witness at the later part's start finds it. `None`
    /// when the steps do not end on a root (residual above [`NEWTON_RESIDUAL`] of the tolerance)
    /// inside the box, or the cut would leave less than [`MIN_FRONT_FRACTION`] of the interval
    /// before it. Floating point only: any cut is sound, the examination of the parts decides.
    #[inline(always)]
    fn newton_time_cut(&self, b: &ParamBox) -> Option<NewtonRoot> {
        let (t_lo, t_hi) = b.t;
        let (u_lo, u_hi) = b.u.bounds();
        let (v_lo, v_hi) = b.v.bounds();
        let mut t = t_lo + 0.5 * (t_hi - t_lo);
        let mut u = u_lo + 0.5 * (u_hi - u_lo);
        let mut v = v_lo + 0.5 * (v_hi - v_lo);
        let mut rate = 0.0;
        let (mut fu_norm, mut fv_norm) = (0.0, 0.0);
        let mut residual = f64::INFINITY;
        for _ in 0..NEWTON_STEPS {
            let s = 1.0 - t;
            let mut f = [0.0f64; 3];
            let mut ft = [0.0f64; 3];
            let mut fu = [0.0f64; 3];
            let mut fv = [0.0f64; 3];
            for k in 0..3 {
                let d = s * self.d[0][k] + t * self.d[1][k];
                fu[k] = s * self.e[0][k] + t * self.e[1][k];
                fv[k] = s * self.g[0][k] + t * self.g[1][k];
                f[k] = (d + u * fu[k]) + v * fv[k];
                ft[k] = (self.d[1][k] - self.d[0][k])
                    + u * (self.e[1][k] - self.e[0][k])
                    + v * (self.g[1][k] - self.g[0][k]);
            }
            residual = f[0].abs().max(f[1].abs()).max(f[2].abs());
            let across = cross(&fu, &fv);
            let det = dot(&ft, &across);
            rate = dot(&ft, &ft).sqrt();
            (fu_norm, fv_norm) = (dot(&fu, &fu).sqrt(), dot(&fv, &fv).sqrt());
            let scale = rate * fu_norm * fv_norm;
            // The same measure with the rows scaled instead of the columns (Newton's step does not
            // change with either): a coordinate of F that is tiny all over (primitives a rounding
            // error out of a common plane) still has its own zero to find.
            let row = |k: usize| (ft[k] * ft[k] + fu[k] * fu[k] + fv[k] * fv[k]).sqrt();
            let row_scale = row(0) * row(1) * row(2);
            // (Not a number fails too.)
            let regular = det.abs() > 1e-9 * scale || det.abs() > 1e-9 * row_scale;
            if !regular {
                // F keeps to a plane (primitives moving in one plane): its zeros are curves,
                // whose earliest point lies on a side of the domain.
                return self.newton_side_cut(b);
            }
            t -= dot(&f, &across) / det;
            u -= dot(&ft, &cross(&f, &fv)) / det;
            v -= dot(&ft, &cross(&fu, &f)) / det;
        }
        // A root, not a near miss: F at the last Newton point within a small part of the
        // tolerance (in floating point: only a guide), and in the box.
        let root = residual <= NEWTON_RESIDUAL * self.tolerance;
        if !root {
            return None;
        }
        // u and v may lie outside by what moves F by a witness's share of the tolerance.
        let slack = |x: f64| {
            if x > 0.0 {
                WITNESS_SCALE * self.tolerance / x
            } else {
                0.0
            }
        };
        let (su, sv) = (slack(fu_norm), slack(fv_norm));
        let inside = t >= t_lo
            && t <= t_hi
            && u >= u_lo - su
            && u <= u_hi + su
            && v >= v_lo - sv
            && v <= v_hi + sv;
        if !inside {
            return None;
        }
        self.cut_before(b, (t, rate), u, v)
    }

    /// The cut before a root at time `root`, where F changes at `rate` with time: as far before it
    /// as a witness's neighbourhood reaches in time (what moves F by an eighth of the tolerance at
    /// the larger of `rate` and [`ContactFunction::time_rate`]), so that the witness at the later
    /// part's start has the root within it, if that leaves at least [`MIN_FRONT_FRACTION`] of the
    /// box's time before it; otherwise the root's (u, v) for a witness at the box's start, with
    /// the cut for when that witness fails. (Up to 2026-12-07, outside coordinate planes, the cut
    /// was by the rate at the root alone, which may be a fraction of the bound the witness uses
    /// where an edge turns: the witness at the cut then failed, and the search went on halving
    /// (u, v) and time down to the root — ordinary crossings of millimetre edges in a body
    /// folding onto itself took 65 to 99 boxes, 19 to 34 since. Edges in one plane, the end of one
    /// turning onto the other, spent the budget the same way before it was mended there first.)
    #[inline(always)]
    fn cut_before(
        &self,
        b: &ParamBox,
        (root, rate): (f64, f64),
        u: f64,
        v: f64,
    ) -> Option<NewtonRoot> {
        let (t_lo, t_hi) = b.t;
        let cut = root - WITNESS_SCALE * self.tolerance / (2.0 * rate.max(self.time_rate()));
        let least = t_lo + MIN_FRONT_FRACTION * (t_hi - t_lo);
        if cut >= t_hi {
            None
        } else if cut > least {
            Some(NewtonRoot::Cut(cut))
        } else {
            Some(NewtonRoot::AtStart(u, v, cut))
        }
    }

    /// [`ContactFunction::newton_time_cut`] on the sides of the domain the box lies on (u or v at 0
    /// or 1, or u + v = 1 for a triangle): the earliest root found there by Gauss–Newton steps on
    /// (t, position along the side).
    #[inline(always)]
    fn newton_side_cut(&self, b: &ParamBox) -> Option<NewtonRoot> {
        let (t_lo, t_hi) = b.t;
        let (u_lo, u_hi) = b.u.bounds();
        let (v_lo, v_hi) = b.v.bounds();
        // (u0, du, v0, dv, s_lo, s_hi): u = u0 + s du, v = v0 + s dv over s in [s_lo, s_hi].
        let mut sides = [[0.0f64; 6]; 5];
        let mut count = 0;
        let mut side = |x: [f64; 6]| {
            sides[count] = x;
            count += 1;
        };
        if u_lo == 0.0 {
            side([0.0, 0.0, 0.0, 1.0, v_lo, v_hi]);
        }
        if v_lo == 0.0 {
            side([0.0, 1.0, 0.0, 0.0, u_lo, u_hi]);
        }
        if self.triangle {
            if u_lo + v_lo <= 1.0 && u_hi + v_hi >= 1.0 {
                side([
                    0.0,
                    1.0,
                    1.0,
                    -1.0,
                    u_lo.max(1.0 - v_hi),
                    u_hi.min(1.0 - v_lo),
                ]);
            }
        } else {
            if u_hi == 1.0 {
                side([1.0, 0.0, 0.0, 1.0, v_lo, v_hi]);
            }
            if v_hi == 1.0 {
                side([0.0, 1.0, 1.0, 0.0, u_lo, u_hi]);
            }
        }
        let mut earliest: Option<(f64, f64, f64, f64)> = None;
        for &[u0, du, v0, dv, s_lo, s_hi] in &sides[..count] {
            let mut t = t_lo + 0.5 * (t_hi - t_lo);
            let mut p = s_lo + 0.5 * (s_hi - s_lo);
            let mut residual = f64::INFINITY;
            let mut rate = 0.0;
            let mut solved = true;
            for _ in 0..NEWTON_STEPS {
                let (u, v) = (u0 + p * du, v0 + p * dv);
                let s = 1.0 - t;
                let mut f = [0.0f64; 3];
                let mut ft = [0.0f64; 3];
                let mut fs = [0.0f64; 3];
                for k in 0..3 {
                    let d = s * self.d[0][k] + t * self.d[1][k];
                    let e = s * self.e[0][k] + t * self.e[1][k];
                    let g = s * self.g[0][k] + t * self.g[1][k];
                    f[k] = (d + u * e) + v * g;
                    fs[k] = du * e + dv * g;
                    ft[k] = (self.d[1][k] - self.d[0][k])
                        + u * (self.e[1][k] - self.e[0][k])
                        + v * (self.g[1][k] - self.g[0][k]);
                }
                residual = f[0].abs().max(f[1].abs()).max(f[2].abs());
                let (a, c, m) = (dot(&ft, &ft), dot(&fs, &fs), dot(&ft, &fs));
                let det = a * c - m * m;
                rate = a.sqrt();
                let regular = det > 1e-12 * a * c;
                if !regular {
                    solved = false;
                    break;
                }
                let (rt, rs) = (dot(&ft, &f), dot(&fs, &f));
                t -= (c * rt - m * rs) / det;
                p -= (a * rs - m * rt) / det;
            }
            let root = solved
                && residual <= NEWTON_RESIDUAL * self.tolerance
                && t >= t_lo
                && t <= t_hi
                && p >= s_lo
                && p <= s_hi;
            if root && earliest.is_none_or(|(e, ..)| t < e) {
                earliest = Some((t, rate, u0 + p * du, v0 + p * dv));
            }
        }
        let (t, rate, u, v) = earliest?;
        self.cut_before(b, (t, rate), u, v)
    }

    /// Whether F provably comes within the tolerance of 0 at some (u, v) of the domain at time t
    /// (t in [0, 1]). The (u, v) where |F| is least is found in floating point (any point of the
    /// domain would be sound: only the final check counts), moved onto a grid of 2⁻⁴⁰ inside the
    /// domain so that u + v ≤ 1 holds exactly, and F is evaluated there in the order of the error
    /// analysis in [`ContactFunction::new`], whose bound covers any t, u, v in [0, 1].
    #[inline(always)]
    fn witness_at(&self, t: f64, t_end: f64) -> bool {
        let (d, e, g) = self.at_time(t);
        let (u, v) = nearest_parameters(&d, &e, &g, self.triangle);
        self.witness_check(t, t_end, u, v, &d, &e, &g)
    }

    /// [`ContactFunction::witness_at`] at a given (u, v) (a root Newton's method found).
    #[inline(always)]
    fn witness_at_point(&self, t: f64, t_end: f64, u: f64, v: f64) -> bool {
        let (d, e, g) = self.at_time(t);
        self.witness_check(t, t_end, u, v, &d, &e, &g)
    }

    /// D, E and G at time t, each interpolated between its values at the tick's start and end.
    #[inline(always)]
    fn at_time(&self, t: f64) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let s = 1.0 - t;
        let mut d = [0.0f64; 3];
        let mut e = [0.0f64; 3];
        let mut g = [0.0f64; 3];
        for k in 0..3 {
            d[k] = s * self.d[0][k] + t * self.d[1][k];
            e[k] = s * self.e[0][k] + t * self.e[1][k];
            g[k] = s * self.g[0][k] + t * self.g[1][k];
        }
        (d, e, g)
    }

    /// The witness's check at the candidate (u, v), D, E and G being evaluated at t.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn witness_check(
        &self,
        t: f64,
        t_end: f64,
        u: f64,
        v: f64,
        d: &[f64; 3],
        e: &[f64; 3],
        g: &[f64; 3],
    ) -> bool {
        // Not a number (a degenerate Newton point) clamps to nothing useful: no witness.
        if !(u.is_finite() && v.is_finite()) {
            return false;
        }
        // Onto the grid (exact: the products by powers of two are exact, floor is exact), so that
        // 1 − u is exact and v ≤ 1 − u means u + v ≤ 1 exactly.
        const GRID: f64 = 1_099_511_627_776.0; // 2^40
        let u = ((u * GRID).floor() / GRID).clamp(0.0, 1.0);
        let mut v = ((v * GRID).floor() / GRID).clamp(0.0, 1.0);
        if self.triangle {
            v = v.min(1.0 - u);
        }
        let tolerance = self.tolerance * WITNESS_SCALE;
        let close = (0..3).all(|k| {
            let f = (d[k] + u * e[k]) + v * g[k];
            f.abs() + self.error[k] <= tolerance
        });
        // A near miss closer than the tolerance that rounding can still tell apart (an axis whose
        // values are all tiny, hence exactly computed) is not taken for a contact: the witness
        // counts only if F provably keeps no sign on any axis over its neighbourhood, the box that
        // F needs to change by the tolerance from it (later in time, both ways in u and v).
        close && !self.excluded_near(t, t_end, u, v, e, g, tolerance)
    }

    /// A bound of how fast any coordinate of F changes with time anywhere on the domain: a
    /// witness's neighbourhood reaches as far in time as this rate needs to change F by the
    /// witness's tolerance ([`ContactFunction::excluded_near`]).
    #[inline(always)]
    fn time_rate(&self) -> f64 {
        (0..3).fold(0.0f64, |most, k| {
            most.max(
                (self.d[1][k] - self.d[0][k]).abs()
                    + (self.e[1][k] - self.e[0][k]).abs()
                    + (self.g[1][k] - self.g[0][k]).abs(),
            )
        })
    }

    /// Whether some coordinate of F provably has no zero on the neighbourhood of (t, u, v) described
    /// in [`ContactFunction::witness_at`].
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn excluded_near(
        &self,
        t: f64,
        t_end: f64,
        u: f64,
        v: f64,
        e: &[f64; 3],
        g: &[f64; 3],
        tolerance: f64,
    ) -> bool {
        let mut rate = [self.time_rate(), 0.0, 0.0];
        for k in 0..3 {
            rate[1] = rate[1].max(e[k].abs());
            rate[2] = rate[2].max(g[k].abs());
        }
        let reach = |r: f64| if r > 0.0 { tolerance / r } else { 1.0 };
        let t_hi = t_end.min(t + reach(rate[0]));
        let (u_lo, u_hi) = ((u - reach(rate[1])).max(0.0), (u + reach(rate[1])).min(1.0));
        let (v_lo, v_hi) = ((v - reach(rate[2])).max(0.0), (v + reach(rate[2])).min(1.0));
        let (ts, ss) = ([t, t_hi], [1.0 - t, 1.0 - t_hi]);
        (0..3).any(|k| {
            let d = lerp(ss, ts, self.d[0][k], self.d[1][k]);
            let e = lerp(ss, ts, self.e[0][k], self.e[1][k]);
            let g = lerp(ss, ts, self.g[0][k], self.g[1][k]);
            let mut min = f64::INFINITY;
            let mut max = f64::NEG_INFINITY;
            for i in 0..2 {
                for uu in [u_lo, u_hi] {
                    for vv in [v_lo, v_hi] {
                        let x = (d[i] + uu * e[i]) + vv * g[i];
                        min = min.min(x);
                        max = max.max(x);
                    }
                }
            }
            min > self.error[k] || max < -self.error[k]
        })
    }

    /// Whether every coordinate of F may come within the tolerance of 0 on the face t = t_lo of the
    /// box (a witness there is worth looking for).
    #[inline(always)]
    fn start_face_within_tolerance(&self, start_face: &[(f64, f64); 3]) -> bool {
        (0..3).all(|k| {
            let (min, max) = start_face[k];
            min - self.error[k] <= self.tolerance && max + self.error[k] >= -self.tolerance
        })
    }

    /// When some coordinate of F provably has no zero on the face t = t_lo of the box, the
    /// fraction of the time interval before which it provably has none (up to rounding: the cut
    /// only guides the search, the examination of each part decides), the latest over such
    /// coordinates; `None` when no coordinate excludes the start face.
    #[inline(always)]
    fn start_face_front(
        &self,
        corners: &[[[f64; 4]; 2]; 3],
        start_face: &[(f64, f64); 3],
    ) -> Option<f64> {
        let mut front: Option<f64> = None;
        for ((axis, error), &(min, max)) in corners.iter().zip(self.error).zip(start_face) {
            // Twice the error bound: at the cut the coordinate is still about one bound clear of
            // it, so the earlier part is thrown away when examined; a start face less than that
            // clear is left to the other splits.
            let bound = 2.0 * error;
            // Signed so that the start face is above the bound.
            let sign = if min > bound {
                1.0
            } else if max < -bound {
                -1.0
            } else {
                continue;
            };
            let mut first = 1.0f64;
            for (start, end) in axis[0].iter().zip(&axis[1]) {
                let (start, end) = (sign * start, sign * end);
                if end <= bound {
                    first = first.min((start - bound) / (start - end));
                }
            }
            front = Some(front.map_or(first, |f| f.max(first)));
        }
        front
    }

    /// A second, sharper exclusion test, for boxes the coordinate test keeps: the same test on r·F
    /// for five directions r: the rows of the adjugate of F's Jacobian J at the box, so that
    /// r·F ≈ det J × (offset from the root in t, in u, in v), and the two directions in the plane
    /// of ∂F/∂u and ∂F/∂v square to each of them (r·F free of u, or of v, when F stays in that
    /// plane: the adjugate's rows then all lie along its normal, where F has no component, and
    /// reject nothing — primitives moving in one plane). Any fixed r is sound: r·F is affine
    /// in each parameter too, so over the box it lies between its 8 corner values, and it vanishes
    /// wherever F does. Near a grazing contact or nearly parallel edges J is ill-conditioned, and the
    /// coordinate test alone keeps thousands of boxes around the root that these rows throw away.
    ///
    /// Error bound: each computed corner F̂ is within `error` of the exact F per axis, so
    /// |r·F̂ − r·F| ≤ Σ|r_k| error_k; the dot product adds at most γ₃ Σ|r_k||F̂_k| (each term goes
    /// through one product and at most two sums), and |F̂_k| ≤ m_k = max(|lo_k|, |hi_k|). The bound
    /// used, Σ|r_k|(error_k + 4ε m_k) + `f64::MIN_POSITIVE` (underflow of the three products), stays
    /// above that after its own few roundings, since `error` already has more than 10 % to spare.
    /// On an axis where D, E and G are all 0, F̂_k = F_k = 0 exactly: `row_error` drops its term.
    #[allow(clippy::needless_range_loop)] // the same corner of three arrays
    #[inline(always)]
    fn rejected_along_jacobian_rows(
        &self,
        corners: &[[[f64; 4]; 2]; 3],
        e: &[[f64; 2]; 3],
        g: &[[f64; 2]; 3],
        lo: &[f64; 3],
        hi: &[f64; 3],
        late: bool,
    ) -> bool {
        let mut dt = [0.0f64; 3];
        let mut du = [0.0f64; 3];
        let mut dv = [0.0f64; 3];
        for k in 0..3 {
            // Columns of J, up to positive factors (which do not change the signs tested).
            dt[k] = (0..4).map(|j| corners[k][1][j] - corners[k][0][j]).sum();
            du[k] = e[k][0] + e[k][1];
            dv[k] = g[k][0] + g[k][1];
        }
        let epsilon = f64::EPSILON / 2.0;
        let magnitude = [
            lo[0].abs().max(hi[0].abs()),
            lo[1].abs().max(hi[1].abs()),
            lo[2].abs().max(hi[2].abs()),
        ];
        // Scaled by a power of two (exact) so that its products stay as large as the others'.
        let normal = scaled_to_unit_exponent(cross(&du, &dv));
        // The normal at the box's end time: across E and G there, so that at t = t_hi the
        // combination is the same at every (u, v). A box that ends just before a root (the earlier
        // part of a cut before it) is then rejected whole, however wide in u and v: over such a
        // box the combination is (t − t_hi)·(a bracket that keeps its sign) plus its value at the
        // root's side, where the mean normal leaves a tilt of the zero set that only splitting u
        // and v down to the cut's distance from the root removes.
        // The same at the start time: a near miss whose root lies before the box (primitives
        // moving apart from one) is rejected whole. Both only on a search past
        // [`LATE_TESTS_AFTER`] boxes, see there.
        let directions = [
            normal,
            cross(&dv, &dt),
            cross(&dt, &du),
            cross(&du, &normal),
            cross(&dv, &normal),
        ];
        let weight: [f64; 3] =
            std::array::from_fn(|k| self.row_error[k] + 4.0 * epsilon * magnitude[k]);
        // All five bounds first, side by side (each summed in the same order as one at a time).
        let bounds = directions.map(|r| row_bound(&r, &weight));
        for (r, bound) in directions.iter().zip(bounds) {
            if corners_apart(r, bound, corners) {
                return true;
            }
        }
        if !late {
            return false;
        }
        [1, 0].into_iter().any(|i| {
            let e_at = [e[0][i], e[1][i], e[2][i]];
            let g_at = [g[0][i], g[1][i], g[2][i]];
            let r = scaled_to_unit_exponent(cross(&e_at, &g_at));
            corners_apart(&r, row_bound(&r, &weight), corners)
        })
    }
}

/// The rounding bound of the combination `r` of F's coordinates, each coordinate's error weighed
/// by `weight` (with the error floor of an axis on which F is exactly 0).
#[inline(always)]
fn row_bound(r: &[f64; 3], weight: &[f64; 3]) -> f64 {
    ((f64::MIN_POSITIVE + r[0].abs() * weight[0]) + r[1].abs() * weight[1]) + r[2].abs() * weight[2]
}

/// Whether the combination `r` of F's coordinates at a box's eight corners (`corners[k][i][j]`:
/// coordinate k at time end i, corner j) lies wholly beyond `bound` on one side of 0.
#[inline(always)]
fn corners_apart(r: &[f64; 3], bound: f64, corners: &[[[f64; 4]; 2]; 3]) -> bool {
    let mut x = [[0.0f64; 4]; 2];
    // Indexed loops: measurably faster here than the zipped iterators clippy suggests.
    #[allow(clippy::needless_range_loop)]
    for i in 0..2 {
        for j in 0..4 {
            x[i][j] = (r[0] * corners[0][i][j] + r[1] * corners[1][i][j]) + r[2] * corners[2][i][j];
        }
    }
    let (min, max) = min_max(&x);
    min > bound || max < -bound
}

impl ContactFunction {
    /// For a triangle, a box across its hypotenuse (u + v = 1) examined on its part on the
    /// triangle only: the box clipped to u + v ≤ 1, a polygon of up to five vertices whose
    /// coordinates are exact floats (u and v are dyadic, sums of two of them and 1 − v are exact).
    /// F is affine in (u, v) at each time and affine in t at each (u, v), so over the polygon
    /// times the box's time interval each coordinate of F, and any fixed combination of them,
    /// lies between its least and greatest value at the polygon's vertices at the interval's two
    /// ends (rounding bounded as in [`ContactFunction::new`], which holds at any (t, u, v) of the
    /// domain). Besides the coordinates, the combination across the time and along-the-hypotenuse
    /// columns of the Jacobian, which measures u + v: a vertex passing just beyond a triangle's
    /// edge otherwise has its near miss closed in on by boxes along the edge's diagonal in (u, v),
    /// split down to the miss's distance (a hundred boxes for a miss of 1 mm on a metre-sized
    /// triangle, the benchmark's cube-internal-edges).
    #[inline(never)]
    fn rejected_on_triangle_part(
        &self,
        s: [f64; 2],
        t: [f64; 2],
        (u_lo, u_hi): (f64, f64),
        (v_lo, v_hi): (f64, f64),
        e: &[[f64; 2]; 3],
        g: &[[f64; 2]; 3],
    ) -> bool {
        let on_triangle = |(u, v): (f64, f64)| u + v <= 1.0;
        let corners = [(u_lo, v_lo), (u_hi, v_lo), (u_hi, v_hi), (u_lo, v_hi)];
        let mut polygon = [(0.0f64, 0.0f64); 5];
        let mut n = 0;
        // Sutherland–Hodgman against u + v ≤ 1, corners in order round the box: the even sides
        // keep v, the odd ones keep u.
        for i in 0..4 {
            let (p, q) = (corners[i], corners[(i + 1) % 4]);
            if on_triangle(p) {
                polygon[n] = p;
                n += 1;
            }
            if on_triangle(p) != on_triangle(q) {
                polygon[n] = if i % 2 == 0 {
                    (1.0 - p.1, p.1)
                } else {
                    (p.0, 1.0 - p.0)
                };
                n += 1;
            }
        }
        let polygon = &polygon[..n];
        // values[axis][time end][vertex]
        let mut values = [[[0.0f64; 5]; 2]; 3];
        let mut magnitude = [0.0f64; 3];
        for k in 0..3 {
            // Exactly the evaluation order of the error analysis in `new`.
            let d = lerp(s, t, self.d[0][k], self.d[1][k]);
            let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..2 {
                for (j, &(u, v)) in polygon.iter().enumerate() {
                    let x = (d[i] + u * e[k][i]) + v * g[k][i];
                    values[k][i][j] = x;
                    min = min.min(x);
                    max = max.max(x);
                }
            }
            if min > self.error[k] || max < -self.error[k] {
                return true;
            }
            magnitude[k] = min.abs().max(max.abs());
        }
        if !self.use_rows {
            return false;
        }
        let mut dt = [0.0f64; 3];
        let mut du = [0.0f64; 3];
        let mut dv = [0.0f64; 3];
        for k in 0..3 {
            dt[k] = (0..n).map(|j| values[k][1][j] - values[k][0][j]).sum();
            du[k] = e[k][0] + e[k][1];
            dv[k] = g[k][0] + g[k][1];
        }
        let along = [du[0] - dv[0], du[1] - dv[1], du[2] - dv[2]];
        let normal = scaled_to_unit_exponent(cross(&du, &dv));
        // The last two: in the triangle's plane, across the hypotenuse (the combination that
        // measures u + v) and across the time column (one that hardly changes with time), for
        // motion that keeps to the plane, where the first, third and fourth are along the normal,
        // on which F is 0. A vertex sliding in the triangle's plane into it across the hypotenuse
        // had the boxes before its crossing closed in on along the hypotenuse, each level of
        // (u, v) halving their distance to the crossing (the budget of 128 boxes spent, 20 to
        // 28 µs a query), and the boxes at the hypotenuse's ends cut in time one after another
        // (72 boxes); now 20 to 30 boxes.
        let directions = [
            scaled_to_unit_exponent(cross(&dt, &along)),
            normal,
            cross(&dv, &dt),
            cross(&dt, &du),
            scaled_to_unit_exponent(cross(&along, &normal)),
            scaled_to_unit_exponent(cross(&dt, &normal)),
        ];
        let epsilon = f64::EPSILON / 2.0;
        let weight: [f64; 3] =
            std::array::from_fn(|k| self.row_error[k] + 4.0 * epsilon * magnitude[k]);
        directions.iter().any(|r| {
            let bound = row_bound(r, &weight);
            let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
            for ((x0, x1), x2) in values[0].iter().zip(&values[1]).zip(&values[2]) {
                for ((a, b), c) in x0.iter().zip(x1).zip(x2).take(n) {
                    let x = (r[0] * a + r[1] * b) + r[2] * c;
                    min = min.min(x);
                    max = max.max(x);
                }
            }
            min > bound || max < -bound
        })
    }
}

/// (1 − t)·x₀ + t·x₁ at both ends of a time interval, given s = 1 − t.
#[inline(always)]
fn lerp(s: [f64; 2], t: [f64; 2], x0: f64, x1: f64) -> [f64; 2] {
    [s[0] * x0 + t[0] * x1, s[1] * x0 + t[1] * x1]
}

/// The least and the greatest of 8 values, by plain comparisons in a fixed tree (no NaN can occur:
/// finite inputs, magnitudes bounded; the tree pairs lanes so that it compiles to vector min/max).
#[inline(always)]
fn min_max(x: &[[f64; 4]; 2]) -> (f64, f64) {
    let less = |a: f64, b: f64| if a < b { a } else { b };
    let more = |a: f64, b: f64| if a > b { a } else { b };
    let lo: [f64; 4] = std::array::from_fn(|j| less(x[0][j], x[1][j]));
    let hi: [f64; 4] = std::array::from_fn(|j| more(x[0][j], x[1][j]));
    let lo = [less(lo[0], lo[2]), less(lo[1], lo[3])];
    let hi = [more(hi[0], hi[2]), more(hi[1], hi[3])];
    (less(lo[0], lo[1]), more(hi[0], hi[1]))
}

/// Per axis, the least and the greatest corner value of F on a box's start face (t = t_lo).
#[inline(always)]
fn start_face_bounds(corners: &[[[f64; 4]; 2]; 3]) -> [(f64, f64); 3] {
    corners.map(|axis| {
        let face = &axis[0];
        (
            face[0].min(face[1]).min(face[2]).min(face[3]),
            face[0].max(face[1]).max(face[2]).max(face[3]),
        )
    })
}

#[inline(always)]
fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The (u, v) of the domain (the triangle u, v ≥ 0, u + v ≤ 1, or the square [0, 1]²) where
/// |d + u e + v g| is least, in floating point: the unconstrained least-squares point if it lies
/// inside, otherwise the best of the least points of the domain's sides. Only a candidate: NaN or
/// a poor point makes a check fail, never a wrong answer.
#[inline(always)]
fn nearest_parameters(d: &[f64; 3], e: &[f64; 3], g: &[f64; 3], triangle: bool) -> (f64, f64) {
    let (ee, eg, gg) = (dot(e, e), dot(e, g), dot(g, g));
    let (ed, gd) = (dot(e, d), dot(g, d));
    let det = ee * gg - eg * eg;
    if det > 1e-12 * ee * gg && det > 0.0 {
        let u = (eg * gd - gg * ed) / det;
        let v = (eg * ed - ee * gd) / det;
        let inside = u >= 0.0
            && v >= 0.0
            && if triangle {
                u + v <= 1.0
            } else {
                u <= 1.0 && v <= 1.0
            };
        if inside {
            return (u, v);
        }
    }
    // Sides as start + s·direction, s in [0, 1], in (u, v).
    const TRIANGLE: [[f64; 4]; 3] = [
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [1.0, 0.0, -1.0, 1.0],
    ];
    const SQUARE: [[f64; 4]; 4] = [
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0, 1.0],
        [0.0, 1.0, 1.0, 0.0],
    ];
    let sides: &[[f64; 4]] = if triangle { &TRIANGLE } else { &SQUARE };
    let mut best = (f64::INFINITY, 0.0, 0.0);
    for &[u0, v0, du, dv] in sides {
        let mut start = [0.0f64; 3];
        let mut along = [0.0f64; 3];
        for k in 0..3 {
            start[k] = d[k] + u0 * e[k] + v0 * g[k];
            along[k] = du * e[k] + dv * g[k];
        }
        let length = dot(&along, &along);
        let s = if length > 0.0 {
            (-dot(&start, &along) / length).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let mut gap = 0.0;
        for k in 0..3 {
            let x = start[k] + s * along[k];
            gap += x * x;
        }
        if gap < best.0 {
            best = (gap, u0 + s * du, v0 + s * dv);
        }
    }
    (best.1, best.2)
}

/// `v` times the power of two that brings its largest component into [1, 2) (exact unless tiny
/// components underflow, which changes the direction a little: any direction is sound).
#[inline(always)]
fn scaled_to_unit_exponent(v: [f64; 3]) -> [f64; 3] {
    let largest = v[0].abs().max(v[1].abs()).max(v[2].abs());
    if !(largest.is_normal()) {
        return v;
    }
    let exponent = ((largest.to_bits() >> 52) & 0x7ff) as i64 - 1023;
    // 2^−exponent, split in two factors so that neither overflows nor is subnormal.
    let half = exponent / 2;
    let f1 = f64::from_bits(((1023 - half) as u64) << 52);
    let f2 = f64::from_bits(((1023 - (exponent - half)) as u64) << 52);
    [v[0] * f1 * f2, v[1] * f1 * f2, v[2] * f1 * f2]
}

#[inline(always)]
fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vec3 {
        Vec3::new(x, y, z)
    }

    fn vf(p: [Vec3; 2], a: [Vec3; 2], b: [Vec3; 2], c: [Vec3; 2]) -> Option<CcdHit> {
        let s = CcdSettings::default();
        vertex_face_time_of_impact(&p[0], &a[0], &b[0], &c[0], &p[1], &a[1], &b[1], &c[1], &s)
    }

    fn ee(a: [Vec3; 2], b: [Vec3; 2], c: [Vec3; 2], d: [Vec3; 2]) -> Option<CcdHit> {
        let s = CcdSettings::default();
        edge_edge_time_of_impact(&a[0], &b[0], &c[0], &d[0], &a[1], &b[1], &c[1], &d[1], &s)
    }

    fn fixed(p: Vec3) -> [Vec3; 2] {
        [p, p]
    }

    /// The unit right triangle in the plane z = 0, not moving.
    fn unit_triangle() -> ([Vec3; 2], [Vec3; 2], [Vec3; 2]) {
        (
            fixed(v(0.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
            fixed(v(0.0, 1.0, 0.0)),
        )
    }

    /// A hit whose time of impact is a lower bound of `t` and within `slack` of it.
    fn assert_hit_near(hit: Option<CcdHit>, t: f64, slack: f64) {
        let hit = hit.expect("a real contact must be reported");
        assert!(!hit.exhausted, "{hit:?}");
        assert!(
            hit.time_of_impact <= t,
            "{hit:?} is later than the contact at {t}"
        );
        assert!(hit.time_of_impact >= t - slack, "{hit:?} is far below {t}");
    }

    #[test]
    fn vertex_through_the_face_interior() {
        let (a, b, c) = unit_triangle();
        let hit = vf([v(0.25, 0.25, 1.0), v(0.25, 0.25, -1.0)], a, b, c);
        assert_hit_near(hit, 0.5, 1e-5);
    }

    #[test]
    fn clear_miss_is_rejected_cheaply() {
        let (a, b, c) = unit_triangle();
        // Beside the triangle, crossing its plane (the bounding boxes overlap in z only).
        assert_eq!(vf([v(2.0, 2.0, 1.0), v(2.0, 2.0, -1.0)], a, b, c), None);
        // Across the hypotenuse's extension, where u + v > 1: the bounding boxes overlap.
        let hit = vf([v(0.6, 0.6, 1.0), v(0.6, 0.6, -1.0)], a, b, c);
        assert_eq!(hit, None);
        // Parallel edges half a unit apart, then one end of cd rising.
        let hit = ee(
            fixed(v(0.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
            fixed(v(0.0, 0.5, 0.0)),
            [v(1.0, 0.5, 0.0), v(1.0, 0.5, 1.0)],
        );
        assert_eq!(hit, None);
    }

    #[test]
    fn vertex_through_a_corner_and_an_edge_of_the_face() {
        let (a, b, c) = unit_triangle();
        // Exactly through corner a, corner b, the middle of edge ab and of the hypotenuse bc.
        for (x, y) in [(0.0, 0.0), (1.0, 0.0), (0.5, 0.0), (0.5, 0.5), (0.0, 1.0)] {
            let hit = vf([v(x, y, 1.0), v(x, y, -1.0)], a, b, c);
            assert_hit_near(hit, 0.5, 1e-5);
        }
    }

    #[test]
    fn contact_at_the_start_gives_time_zero() {
        let (a, b, c) = unit_triangle();
        // On the face at t = 0, leaving it.
        let hit = vf([v(0.2, 0.2, 0.0), v(0.2, 0.2, 1.0)], a, b, c).expect("touching at t = 0");
        assert_eq!(hit.time_of_impact, 0.0);
        // Crossing edges at t = 0, moving apart.
        let hit = ee(
            [v(-1.0, 0.0, 0.0), v(-1.0, 0.0, -1.0)],
            [v(1.0, 0.0, 0.0), v(1.0, 0.0, -1.0)],
            fixed(v(0.0, -1.0, 0.0)),
            fixed(v(0.0, 1.0, 0.0)),
        )
        .expect("crossing at t = 0");
        assert_eq!(hit.time_of_impact, 0.0);
    }

    #[test]
    fn contact_exactly_at_the_end_of_the_step() {
        let (a, b, c) = unit_triangle();
        let hit = vf([v(0.2, 0.3, 1.0), v(0.2, 0.3, 0.0)], a, b, c);
        assert_hit_near(hit, 1.0, 1e-5);
        let hit = ee(
            [v(0.5, -1.0, 1.0), v(0.5, -1.0, 0.0)],
            [v(0.5, 1.0, 1.0), v(0.5, 1.0, 0.0)],
            fixed(v(0.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
        );
        assert_hit_near(hit, 1.0, 1e-5);
    }

    #[test]
    fn no_motion() {
        let (a, b, c) = unit_triangle();
        // Resting on the face: touching all the time, first at t = 0.
        let hit = vf(fixed(v(0.3, 0.3, 0.0)), a, b, c).expect("resting contact");
        assert_eq!(hit.time_of_impact, 0.0);
        // Hovering above it, never touching.
        assert_eq!(vf(fixed(v(0.3, 0.3, 0.1)), a, b, c), None);
        // Static crossing edges and static skew edges.
        let hit = ee(
            fixed(v(-1.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
            fixed(v(0.0, -1.0, 0.0)),
            fixed(v(0.0, 1.0, 0.0)),
        );
        assert_eq!(hit.map(|h| h.time_of_impact), Some(0.0));
        let hit = ee(
            fixed(v(-1.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
            fixed(v(0.0, -1.0, 0.01)),
            fixed(v(0.0, 1.0, 0.01)),
        );
        assert_eq!(hit, None);
    }

    #[test]
    fn parallel_edges_touching() {
        // Edge cd, parallel to ab and overlapping it along x, falls onto it at t = 1/2 and goes on.
        let hit = ee(
            fixed(v(0.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
            [v(0.5, 1.0, 0.0), v(0.5, -1.0, 0.0)],
            [v(1.5, 1.0, 0.0), v(1.5, -1.0, 0.0)],
        );
        assert_hit_near(hit, 0.5, 1e-5);
        // Collinear and overlapping all along: contact from the start.
        let hit = ee(
            fixed(v(0.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
            [v(0.5, 0.0, 0.0), v(2.5, 0.0, 0.0)],
            [v(1.5, 0.0, 0.0), v(3.5, 0.0, 0.0)],
        );
        assert_eq!(hit.map(|h| h.time_of_impact), Some(0.0));
        // Collinear, end to end only at t = 1/4: cd slides along the line and just meets b.
        let hit = ee(
            fixed(v(0.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
            [v(2.0, 0.0, 0.0), v(-2.0, 0.0, 0.0)],
            [v(3.0, 0.0, 0.0), v(-1.0, 0.0, 0.0)],
        );
        assert_hit_near(hit, 0.25, 1e-5);
        // Parallel, a hair apart, never touching.
        let hit = ee(
            fixed(v(0.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
            [v(0.5, 1.0, 1e-3), v(0.5, -1.0, 1e-3)],
            [v(1.5, 1.0, 1e-3), v(1.5, -1.0, 1e-3)],
        );
        assert_eq!(hit, None);
    }

    #[test]
    fn coplanar_sliding() {
        let (a, b, c) = unit_triangle();
        // In the plane of the face, entering it across edge ca (x = 0) at t = 1/3.
        let hit = vf([v(-1.0, 0.25, 0.0), v(2.0, 0.25, 0.0)], a, b, c);
        assert_hit_near(hit, 1.0 / 3.0, 1e-5);
        // In the plane, passing beside the face.
        assert_eq!(vf([v(-1.0, 1.5, 0.0), v(2.0, 1.5, 0.0)], a, b, c), None);
        // An edge sliding in the plane z = 0 towards another one, meeting it end-on at t = 1/2.
        let hit = ee(
            [v(-3.0, 0.5, 0.0), v(1.0, 0.5, 0.0)],
            [v(-2.0, 0.5, 0.0), v(2.0, 0.5, 0.0)],
            fixed(v(0.0, 0.0, 0.0)),
            fixed(v(0.0, 1.0, 0.0)),
        );
        assert_hit_near(hit, 0.5, 1e-5);
    }

    /// A vertex sliding in the triangle's plane into it across its hypotenuse: the earliest contact
    /// is where its path crosses u + v = 1, which the combination across the hypotenuse in the
    /// plane finds in a few dozen boxes (without it the search spent the budget of 128 boxes
    /// closing in along the hypotenuse, exhausted, its time of impact 3e-4 early).
    #[test]
    fn a_vertex_sliding_in_the_plane_across_the_hypotenuse_is_settled_in_a_few_dozen_boxes() {
        let (a, b, c) = unit_triangle();
        // (x, y) from (0.4878, 0.8531) to (-0.1848, 1.0198), z = 0: x + y falls from 1.34 to 0.83, crossing 1 at t* while x > 0.
        let (p0, p1) = (v(0.4878, 0.8531, 0.0), v(-0.1848, 1.0198, 0.0));
        let t_star = (p0.x + p0.y - 1.0) / ((p0.x + p0.y) - (p1.x + p1.y));
        let hit = vf([p0, p1], a, b, c);
        assert_hit_near(hit, t_star, 1e-6);
        assert!(
            hit.is_some_and(|h| !h.exhausted && h.boxes <= 40),
            "{hit:?}"
        );
        // Beside the hypotenuse's end (x + y reaches 1 where x is already below 0): no contact.
        let (p0, p1) = (v(0.3, 0.9, 0.0), v(-0.3, 1.2, 0.0));
        assert_eq!(vf([p0, p1], a, b, c), None);
    }

    /// Two edges lying along one line at the start, a micrometre apart across it, the second
    /// sliding and turning away: the contact just after the start, where Newton's root lies a few
    /// tenths of a micrometre after the box's start, beyond its witness's reach. The cut just
    /// before it settles the query in 22 boxes (57 when the search went on halving time down to
    /// it).
    #[test]
    fn a_root_just_after_a_boxs_start_is_cut_before_when_its_witness_fails() {
        let at = |x: i64, y: i64, z: i64| {
            let scale = (-40f64).exp2();
            v(x as f64 * scale, y as f64 * scale, z as f64 * scale)
        };
        let a = fixed(Vec3::zeros());
        let b = fixed(at(8096459183, 977519870006, -503304252622));
        let c = [
            at(2428839259, 293255984013, -150991232679),
            at(2994426733, 674525964087, -156760934296),
        ];
        let d = [
            at(10525528554, 1270776285099, -654296470259),
            at(11091116029, 1652046265173, -660066171877),
        ];
        let hit = ee(a, b, c, d).expect("the edges touch");
        assert!(!hit.exhausted, "{hit:?}");
        assert!(
            (1.1655e-6..=1.16551e-6).contains(&hit.time_of_impact),
            "{hit:?}"
        );
        assert!(hit.boxes <= 32, "{hit:?}");
    }

    /// Two millimetre edges of a body folding onto itself (`scenes/self_fold.toml`, recorded from
    /// its collision net), crossing at an angle with their ends moving up to 1.2 mm in the tick:
    /// Newton's root lies within a witness's reach of the box's start by the rate at the root, not
    /// by the bound the witness uses. The cut as far before the root as the witness reaches
    /// settles it in 29 boxes; cut by the rate at the root alone, the search halved u, v and time
    /// down to it, 77 boxes (past the budget of 64).
    #[test]
    fn a_crossing_of_edges_in_a_fold_is_settled_by_the_cut_before_its_root() {
        let a = [
            v(
                -0.013751237982412559,
                0.013506669415953645,
                0.0005107201890253262,
            ),
            v(
                -0.013774176156717582,
                0.013531083685164076,
                0.0004781842189144616,
            ),
        ];
        let b = [
            v(
                -0.011437679631904023,
                0.015996505377867846,
                0.0007532350075357823,
            ),
            v(
                -0.011599272084383007,
                0.016162595095376205,
                0.00042156511887202707,
            ),
        ];
        let c = [
            v(
                -0.012616596468963523,
                0.015486662725319598,
                0.0009676000099448752,
            ),
            v(
                -0.013489820516473027,
                0.014941903849019542,
                0.00027192781511511417,
            ),
        ];
        let d = [
            v(
                -0.011438207911460224,
                0.01584074881920941,
                0.0007416571297294048,
            ),
            v(
                -0.011403618496693834,
                0.015705491126503456,
                0.0004617083463867208,
            ),
        ];
        let hit = ee(a, b, c, d).expect("the edges cross");
        assert!(!hit.exhausted, "{hit:?}");
        assert!(hit.boxes <= 40, "{hit:?}");
        // The same time as the search without a budget finds (0.75173, within the tolerance).
        assert!((0.7516..=0.7519).contains(&hit.time_of_impact), "{hit:?}");
    }

    /// Edge a translating with velocity `w` crosses the fixed edge b at `t_star`, at `u_star` along
    /// a and `v_star` along b: `(a0, b0, a1, b1)`, the edge b being `(c, d)`.
    fn crossing(
        (c, d): (Vec3, Vec3),
        (u_star, v_star, t_star): (f64, f64, f64),
        along: Vec3,
        w: Vec3,
    ) -> [Vec3; 4] {
        let x = c + (d - c) * v_star;
        let a0 = x - along * u_star - w * t_star;
        [a0, a0 + along, a0 + w, a0 + along + w]
    }

    #[test]
    fn a_newton_step_cuts_time_just_before_a_crossing() {
        // Skew edges crossing inside both (t* = 0.618…, u* = 0.61, v* = 0.37): every coordinate
        // of F mixes t, u and v, so no coordinate's front finds the time alone.
        let t_star = (5f64.sqrt() - 1.0) / 2.0;
        let (c, d) = (v(0.1, -0.7, 0.05), v(0.3, 0.9, -0.1));
        let [a0, b0, a1, b1] = crossing(
            (c, d),
            (0.61, 0.37, t_star),
            v(1.1, -0.3, 0.2),
            v(0.1, 0.05, -1.5),
        );
        let hit = ee([a0, a1], [b0, b1], fixed(c), fixed(d));
        assert_hit_near(hit, t_star, 1e-6);
        // (128 boxes, the budget, without the Newton cut; the cuts start after LATE_TESTS_AFTER.)
        assert!(
            hit.is_some_and(|h| h.boxes <= LATE_TESTS_AFTER + 8),
            "{hit:?}"
        );
        // In one (tilted) plane: an end of edge a sweeping across edge b, whose earliest contact
        // is on a side of the domain (u = 0) where F keeps to the plane.
        let plane = |x: f64, y: f64| v(x, y, 0.3 * x - 0.2 * y);
        let (c, d) = (plane(0.2, -0.8), plane(0.35, 0.9));
        let along = plane(-0.9, 0.4) - plane(0.0, 0.0);
        let w = plane(0.8, 0.3) - plane(0.0, 0.0);
        let [a0, b0, a1, b1] = crossing((c, d), (0.0, 0.43, t_star), along, w);
        let hit = ee([a0, a1], [b0, b1], fixed(c), fixed(d));
        assert_hit_near(hit, t_star, 1e-6);
        assert!(
            hit.is_some_and(|h| h.boxes <= LATE_TESTS_AFTER + 8),
            "{hit:?}"
        );
    }

    #[test]
    fn degenerate_primitives() {
        // A triangle collapsed to a segment, hit in its middle at t = 1/2.
        let hit = vf(
            [v(0.5, 0.0, 1.0), v(0.5, 0.0, -1.0)],
            fixed(v(0.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
            fixed(v(1.0, 0.0, 0.0)),
        );
        assert_hit_near(hit, 0.5, 1e-5);
        // Two zero-length edges (points) meeting at t = 1/2.
        let hit = ee(
            [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)],
            [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)],
            [v(1.0, 0.0, 0.0), v(0.0, 0.0, 0.0)],
            [v(1.0, 0.0, 0.0), v(0.0, 0.0, 0.0)],
        );
        assert_hit_near(hit, 0.5, 1e-5);
    }

    #[test]
    fn far_from_the_origin_still_exact() {
        // The interior crossing translated by 2^20 m: the inputs stay exact, the answer must too.
        let o = v(1_048_576.0, -1_048_576.0, 1_048_576.0);
        let hit = vf(
            [v(0.25, 0.25, 1.0) + o, v(0.25, 0.25, -1.0) + o],
            fixed(v(0.0, 0.0, 0.0) + o),
            fixed(v(1.0, 0.0, 0.0) + o),
            fixed(v(0.0, 1.0, 0.0) + o),
        );
        assert_hit_near(hit, 0.5, 1e-5);
    }

    /// A vertex crossing the plane of a fixed triangle 0.1 mm beyond its hypotenuse is rejected
    /// within half the default budget once the late tests start, on the triangle's part of the domain (it took close to 128
    /// boxes for the benchmark's cube-internal-edges, a miss of 1 mm: boxes along the diagonal of
    /// (u, v)); the same crossing 0.1 mm inside is found, and one on the hypotenuse itself.
    #[test]
    fn a_near_miss_beyond_the_hypotenuse_is_rejected_soon() {
        let (a, b, c) = unit_triangle();
        let one = CcdSettings {
            tolerance: 1e-6,
            max_boxes: 64,
        };
        let across = |x: f64, y: f64| [v(x, y, 1.0), v(x, y, -1.0)];
        let beyond = 0.5 + 1e-4 / std::f64::consts::SQRT_2;
        let p = across(beyond, beyond);
        let hit = vertex_face_time_of_impact(
            &p[0], &a[0], &b[0], &c[0], &p[1], &a[1], &b[1], &c[1], &one,
        );
        assert_eq!(hit, None);
        let inside = 0.5 - 1e-4 / std::f64::consts::SQRT_2;
        assert_hit_near(vf(across(inside, inside), a, b, c), 0.5, 1e-5);
        assert_hit_near(vf(across(0.25, 0.75), a, b, c), 0.5, 1e-5);
    }

    #[test]
    fn budget_exhaustion_reports_a_conservative_hit() {
        let (a, b, c) = unit_triangle();
        let settings = CcdSettings {
            tolerance: 1e-6,
            max_boxes: 1,
        };
        // Crosses the plane of the face just past the hypotenuse of a triangle whose corner c
        // swings (F is not affine: the triangle part's combination does not settle it in one box).
        let c = [c[0], c[1] + v(0.5, 0.0, 0.0)];
        let p = [v(0.6, 0.6, 1.0), v(0.6, 0.6, -1.0)];
        let hit = vertex_face_time_of_impact(
            &p[0], &a[0], &b[0], &c[0], &p[1], &a[1], &b[1], &c[1], &settings,
        )
        .expect("an unfinished query is a hit");
        assert!(hit.exhausted);
        assert_eq!(hit.boxes, 1);
        assert_eq!(hit.time_of_impact, 0.0);
        // With the default budget the same query is settled: no contact.
        assert_eq!(vf(p, a, b, c), None);
    }

    #[test]
    fn non_finite_input_is_never_excluded() {
        let (a, b, c) = unit_triangle();
        let hit = vf([v(f64::NAN, 0.0, 1.0), v(0.0, 0.0, -1.0)], a, b, c);
        assert_eq!(hit.map(|h| h.exhausted), Some(true));
    }

    #[test]
    fn dyadic_halves_are_exact_down_to_the_deepest_level() {
        // Every path of halvings, checked against k / 2^level from integers.
        for path in [0u64, u64::MAX, 0x5555_5555_5555_5555, 0x0123_4567_89ab_cdef] {
            let mut d = Dyadic::WHOLE;
            let mut k = 0u64;
            for level in 1..=MAX_LEVEL {
                let upper = (path >> (level % 64)) & 1 == 1;
                d = if upper {
                    d.upper_half()
                } else {
                    d.lower_half()
                };
                k = 2 * k + u64::from(upper);
                let scale = (2.0f64).powi(-(level as i32));
                assert_eq!(d.level(), level);
                assert_eq!(d.bounds(), ((k as f64) * scale, ((k + 1) as f64) * scale));
            }
        }
        // A key-free queue item: the box is all it stores.
        assert_eq!(std::mem::size_of::<ParamBox>(), 56);
    }

    #[test]
    fn same_input_same_output() {
        let (a, b, c) = unit_triangle();
        let p = [v(0.1, 0.7, 0.3), v(0.2, 0.1, -0.4)];
        assert_eq!(vf(p, a, b, c), vf(p, a, b, c));
    }

    /// A small deterministic generator (no dependency, same sequence on every run).
    struct Lcg(u64);

    impl Lcg {
        /// An integer in [−8, 8] divided by 8: products and sums of a few of these stay exact.
        fn coordinate(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 33) % 17) as f64 / 8.0 - 1.0
        }

        fn point(&mut self) -> Vec3 {
            v(self.coordinate(), self.coordinate(), self.coordinate())
        }

        /// One of 0, 1/4, 1/2, 3/4, 1.
        fn fraction(&mut self) -> f64 {
            (self.coordinate() * 8.0 + 8.0).rem_euclid(5.0) / 4.0
        }

        /// One of 0, 1/4, 1/2, 1: dividing by it (when not 0) is exact.
        fn power_of_two_or_zero(&mut self) -> f64 {
            [0.0, 0.25, 0.5, 1.0][(self.coordinate() * 8.0 + 8.0) as usize % 4]
        }
    }

    /// The AVX2 build of the search and the plain one give the same answers, to the bit, on
    /// random queries near contact (mixed magnitudes, so that the error bounds and the witness
    /// are exercised) — what makes the dispatch invisible.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx2_search_gives_the_same_bits_as_the_plain_one() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = Lcg(777);
        let mut hits = 0;
        for i in 0..3000 {
            let scale = [1.0, 1e-3, 37.5][i % 3];
            let mut point = || rng.point() * scale + v(1e-9, -2e-9, 3e-9) * (i % 7) as f64;
            let (d0, d1, e0, e1, g0, g1) = (point(), point(), point(), point(), point(), point());
            let f = ContactFunction::new([d0, d1], [e0, e1], [g0, g1], i % 2 == 0, 1e-6 * scale)
                .expect("small magnitudes");
            let plain = f.earliest_root_here(DEFAULT_MAX_BOXES);
            // SAFETY: AVX2 checked above.
            let fast = unsafe { f.earliest_root_avx2(DEFAULT_MAX_BOXES) };
            assert_eq!(
                plain.map(|h| (h.time_of_impact.to_bits(), h.boxes, h.exhausted)),
                fast.map(|h| (h.time_of_impact.to_bits(), h.boxes, h.exhausted)),
                "query {i}"
            );
            hits += usize::from(plain.is_some());
        }
        // Both kinds of answer were compared.
        assert!(hits > 100 && hits < 2900, "{hits} hits");
    }

    #[test]
    fn constructed_exact_contacts_are_always_found() {
        // Each case places the contact exactly (all arithmetic on small dyadic numbers is exact) at
        // a known time t*, so the answer must be a hit no later than t*.
        let mut rng = Lcg(12345);
        for _ in 0..2000 {
            let t_star = rng.power_of_two_or_zero();
            let (u, w) = (rng.fraction(), rng.fraction());
            let at = |x0: Vec3, x1: Vec3| x0 + (x1 - x0) * t_star;

            // Vertex–face: barycentric (u, w) scaled into the triangle.
            let (a0, a1, b0, b1, c0, c1) = (
                rng.point(),
                rng.point(),
                rng.point(),
                rng.point(),
                rng.point(),
                rng.point(),
            );
            let (bu, bw) = if u + w <= 1.0 {
                (u, w)
            } else {
                (1.0 - u, 1.0 - w)
            };
            let (a, b, c) = (at(a0, a1), at(b0, b1), at(c0, c1));
            let q = a + (b - a) * bu + (c - a) * bw;
            // p moves through q at t*: choose p0, then p1 = p0 + (q − p0) / t* (exact for these t*).
            let (p0, p1) = if t_star == 0.0 {
                (q, rng.point())
            } else {
                let p0 = rng.point();
                (p0, p0 + (q - p0) / t_star)
            };
            assert_eq!(at(p0, p1), q, "construction must be exact");
            let hit = vf([p0, p1], [a0, a1], [b0, b1], [c0, c1]);
            let hit = hit.unwrap_or_else(|| panic!("missed vertex-face contact at {t_star}"));
            assert!(hit.time_of_impact <= t_star);

            // Edge–edge: the point at u on ab meets the point at w on cd.
            let w = rng.power_of_two_or_zero();
            let (a0, a1, b0, b1, c0, c1) = (
                rng.point(),
                rng.point(),
                rng.point(),
                rng.point(),
                rng.point(),
                rng.point(),
            );
            let (a, b, c) = (at(a0, a1), at(b0, b1), at(c0, c1));
            let q = a + (b - a) * u;
            // d(t*) = c(t*) + (q − c(t*)) / w when w > 0; with w = 0 the contact is at c itself.
            let (c0, c1) = if w == 0.0 {
                (c0 + (q - c), c1 + (q - c))
            } else {
                (c0, c1)
            };
            let c = at(c0, c1);
            let d = if w == 0.0 {
                rng.point()
            } else {
                c + (q - c) / w
            };
            let d0 = rng.point();
            let d1 = if t_star == 0.0 {
                rng.point()
            } else {
                d0 + (d - d0) / t_star
            };
            let d0 = if t_star == 0.0 { d } else { d0 };
            assert_eq!(at(d0, d1), d, "construction must be exact");
            assert_eq!(c + (d - c) * w, q, "construction must be exact");
            let hit = ee([a0, a1], [b0, b1], [c0, c1], [d0, d1]);
            let hit = hit.unwrap_or_else(|| panic!("missed edge-edge contact at {t_star}"));
            assert!(hit.time_of_impact <= t_star);
        }
    }
}
