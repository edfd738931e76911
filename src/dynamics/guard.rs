//! The divergence guard: after every step, a body whose state is not finite, moves faster than tissue
//! can, is torn further from its rigid component than any deformation explains, or holds more energy
//! than it started with plus the work the tools did on it, is restored to its rigid component's shape
//! — every node snapped to its homologue, its velocity to the rigid motion (the rigid component itself
//! The rigid component is checked too (finite, no faster than tissue can move, its turning included)
//! and every restore puts it back to its last good state with the nodes on it, so a rigid component
//! that runs away cannot drag the restored shape along (issue 12). After a restore the energy is
//! measured: if the restored motion still holds more than the budget, the body is stopped (rigid
//! component and nodes at rest), so a restore never adds energy. The event is counted with its cause
//! and the step goes on: a NaN never leaves the step.

use crate::Vec3;
use crate::body::{Body, RigidComponent};
use crate::collision::blocks::{BLOCK, NodeBlock};
use crate::collision::tool::Aabb;

/// Why the guard acted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GuardCause {
    /// A position or velocity became NaN or infinite.
    NonFinite,
    /// A node moved faster than [`MAX_SPEED`].
    Speed,
    /// A node went further from its homologue than the body's size times [`MAX_STRETCH`].
    Stretch,
    /// The energy grew past what gravity and the tools can explain.
    Energy,
}

/// Fastest a node may move (m/s): far beyond any surgical gesture or fall in a training rig.
pub const MAX_SPEED: f64 = 100.0;
/// Largest node–homologue distance, in body sizes.
pub const MAX_STRETCH: f64 = 5.0;
/// Smallest body size the stretch check assumes (m): a body of a few nodes (or one) has no extent
/// of its own to measure stretch against.
pub const MIN_SIZE: f64 = 0.1;
/// Energy slack allowed above the budget: this fraction of the budget plus [`ENERGY_SLACK_J`].
pub const ENERGY_SLACK: f64 = 0.5;
/// Absolute energy slack (J).
pub const ENERGY_SLACK_J: f64 = 0.05;

/// Events in a row from which the guard snaps a body onto its rest shape even when it would keep
/// the start positions ([`Guard::keep_start`]): 50 ms of a body that fails every step.
pub const SNAP_AFTER: u32 = 50;

/// Per-body guard state.
#[derive(Clone, Debug)]
pub struct Guard {
    /// Times the guard acted.
    pub events: u64,
    /// Cause of the last event.
    pub last_cause: Option<GuardCause>,
    /// The guard acted during the last step.
    pub acted: bool,
    /// Check the energy of the end of every step (set for a body stepped explicitly past its
    /// stability limit, which can gain energy within a tick); otherwise the caller checks the energy
    /// the force stage measured at the start of the step, one step behind.
    pub energy_at_end: bool,
    /// Restore the nodes to where they started the step instead of onto the rigid component's
    /// shape, unless the energy was what the guard found wrong (set by the world for a step that
    /// did not change the body's topology when other bodies may touch it: the rest shape of an
    /// organ pressed flat by another lies inside that one, and snapping onto it left the two
    /// crossed for good). Not from the [`SNAP_AFTER`]-th event in a row: the start state went on
    /// failing (the rest shape then, crossed or not).
    pub keep_start: bool,
    /// The budget was taken from the state the first step started from.
    started: bool,
    size: f64,
    budget: f64,
    gravity: Vec3,
    last_good_rigid: RigidComponent,
    /// Events in a row (0 after a step it let pass).
    in_a_row: u32,
    /// The pass over the nodes taken by [`Guard::measure`] since the last check, if any.
    measured: Option<Measure>,
}

/// What one pass over a body's nodes found: the largest squared speed and node–homologue distance,
/// whether any value is not finite, and (when asked) the box of the nodes' positions.
#[derive(Clone, Copy, Debug)]
pub struct Measure {
    speed2: f64,
    stretch2: f64,
    bad: bool,
    bounds: Option<Aabb>,
}

/// The box of `positions` (none of them NaN). Four nodes at a time, each of their twelve
/// coordinates with a least and greatest value of its own, folded by axis at the end: plain
/// comparisons on whole vectors, and the same box in any order.
fn position_bounds(positions: &[Vec3]) -> Aabb {
    let mut lo = [f64::INFINITY; 12];
    let mut hi = [f64::NEG_INFINITY; 12];
    let mut blocks = positions.chunks_exact(4);
    for block in &mut blocks {
        let mut c = [0.0; 12];
        for (l, p) in block.iter().enumerate() {
            c[3 * l] = p.x;
            c[3 * l + 1] = p.y;
            c[3 * l + 2] = p.z;
        }
        for j in 0..12 {
            lo[j] = if c[j] < lo[j] { c[j] } else { lo[j] };
            hi[j] = if c[j] > hi[j] { c[j] } else { hi[j] };
        }
    }
    let mut aabb = Aabb::empty();
    for p in blocks.remainder() {
        aabb.include(p);
    }
    for l in 0..4 {
        aabb.min = aabb
            .min
            .inf(&Vec3::new(lo[3 * l], lo[3 * l + 1], lo[3 * l + 2]));
        aabb.max = aabb
            .max
            .sup(&Vec3::new(hi[3 * l], hi[3 * l + 1], hi[3 * l + 2]));
    }
    aabb
}

impl Measure {
    /// One pass over the nodes of `body`; with `bounds`, the box of their positions as well.
    fn of(body: &Body, bounds: bool) -> Self {
        if bounds {
            Self::pass::<true>(body)
        } else {
            Self::pass::<false>(body)
        }
    }

    fn pass<const BOUNDS: bool>(body: &Body) -> Self {
        let s = &body.surface;
        let (speed2, stretch2, bad) = maxima(
            &s.velocity_in_world,
            &s.position_in_world,
            &s.homologue_in_world,
        );
        // A box only for finite positions (a NaN compares false and would shrink it).
        let bounds = (BOUNDS && !bad && !s.position_in_world.is_empty())
            .then(|| position_bounds(&s.position_in_world));
        Self {
            speed2,
            stretch2,
            bad,
            bounds,
        }
    }
}

/// The largest squared speed `|v|²` and stretch `|x − h|²` of the nodes with velocities `v`,
/// positions `x` and homologues `h` (as many as the shortest has), and whether any node's
/// `|v|² + |x − h|²` is not finite (NaN or infinite). No early exit. Plain comparisons, not
/// `f64::max` (whose NaN rule keeps a loop scalar), and an or of flags, not a sum: the same answer
/// in any order, so four nodes at a time with AVX where the machine has it (the same squares,
/// summed in the same order, and the same comparisons), else one at a time.
pub fn maxima(v: &[Vec3], x: &[Vec3], h: &[Vec3]) -> (f64, f64, bool) {
    let n = v.len().min(x.len()).min(h.len());
    let (v, x, h) = (&v[..n], &x[..n], &h[..n]);
    #[cfg(target_arch = "x86_64")]
    if crate::dynamics::kernel::simd_available() {
        // SAFETY: the machine has AVX; the three slices have the same length.
        return unsafe { avx_maxima(v, x, h) };
    }
    scalar_maxima(v, x, h, (0.0, 0.0, false))
}

/// [`maxima`] from what the node pass learnt of each block of nodes: the maxima and flag of each
/// block it saw whole, and the nodes of the blocks a stage touched after it rescanned (the same
/// comparisons, in another order: the same answer).
pub fn maxima_by_blocks(
    blocks: &[NodeBlock],
    v: &[Vec3],
    x: &[Vec3],
    h: &[Vec3],
) -> (f64, f64, bool) {
    let n = v.len().min(x.len()).min(h.len());
    let mut found = (0.0, 0.0, false);
    for (k, b) in blocks.iter().enumerate() {
        if b.touched {
            let nodes = (k * BLOCK).min(n)..((k + 1) * BLOCK).min(n);
            found = scalar_maxima(&v[nodes.clone()], &x[nodes.clone()], &h[nodes], found);
        } else {
            found.0 = if b.speed2 > found.0 {
                b.speed2
            } else {
                found.0
            };
            found.1 = if b.stretch2 > found.1 {
                b.stretch2
            } else {
                found.1
            };
            found.2 |= b.bad;
        }
    }
    found
}

/// [`maxima`] one node at a time, from `start` (the maxima and flag so far).
fn scalar_maxima(v: &[Vec3], x: &[Vec3], h: &[Vec3], start: (f64, f64, bool)) -> (f64, f64, bool) {
    let (mut speed2, mut stretch2, mut bad) = start;
    for ((v, x), h) in v.iter().zip(x).zip(h) {
        let v2 = v.norm_squared();
        let s2 = (x - h).norm_squared();
        speed2 = if v2 > speed2 { v2 } else { speed2 };
        stretch2 = if s2 > stretch2 { s2 } else { stretch2 };
        bad |= !(v2 + s2).is_finite();
    }
    (speed2, stretch2, bad)
}

/// [`maxima`] four nodes at a time (`max(a, b)` is `a > b ? a : b` in every lane, the scalar
/// comparison), then the lanes folded and the last nodes one at a time.
///
/// # Safety
/// The machine must have AVX; `v`, `x` and `h` have the same length.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn avx_maxima(v: &[Vec3], x: &[Vec3], h: &[Vec3]) -> (f64, f64, bool) {
    use crate::dynamics::kernel::avx::{dot3, lanes, load3, sub3};
    use std::arch::x86_64::*;
    let n = v.len();
    let full = n - n % 4;
    let zero = _mm256_setzero_pd();
    let (mut speed2, mut stretch2, mut bad) = (zero, zero, zero);
    let magnitude = _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX));
    let infinity = _mm256_set1_pd(f64::INFINITY);
    let mut i = 0;
    while i < full {
        // SAFETY: i + 4 <= n, the length of every slice.
        let (vv, xx, hh) = unsafe {
            (
                load3(v.as_ptr().add(i) as *const f64),
                load3(x.as_ptr().add(i) as *const f64),
                load3(h.as_ptr().add(i) as *const f64),
            )
        };
        let d = sub3(xx, hh);
        let v2 = dot3(vv, vv);
        let s2 = dot3(d, d);
        speed2 = _mm256_max_pd(v2, speed2);
        stretch2 = _mm256_max_pd(s2, stretch2);
        // Not finite: |sum| not below infinity (a NaN compares unordered: true).
        let sum = _mm256_and_pd(_mm256_add_pd(v2, s2), magnitude);
        bad = _mm256_or_pd(bad, _mm256_cmp_pd::<_CMP_NLT_UQ>(sum, infinity));
        i += 4;
    }
    let fold = |lanes: [f64; 4]| {
        lanes
            .into_iter()
            .fold(0.0, |best, l| if l > best { l } else { best })
    };
    let start = (
        fold(lanes(speed2)),
        fold(lanes(stretch2)),
        _mm256_movemask_pd(bad) != 0,
    );
    scalar_maxima(&v[full..], &x[full..], &h[full..], start)
}

/// Total mechanical energy of a body: kinetic, elastic (edges and links) and gravitational (J).
pub fn body_energy(body: &Body, gravity: &Vec3) -> f64 {
    let s = &body.surface;
    let r = &body.rigid;
    let mut energy = body.kinetic_energy() - gravity.dot(&r.position_in_world) * r.mass;
    let world_from_body = r.world_from_body.to_rotation_matrix();
    for i in 0..s.mass.len() {
        let h = r.position_in_world + world_from_body * s.homologue_in_body[i];
        energy += 0.5 * s.link_stiffness[i] * (h - s.position_in_world[i]).norm_squared();
        energy -= gravity.dot(&s.position_in_world[i]) * s.mass[i];
    }
    let e = &body.edges;
    for k in 0..e.len() {
        let length =
            (s.position_in_world[e.b[k] as usize] - s.position_in_world[e.a[k] as usize]).norm();
        let stretch = length - e.rest_length[k];
        energy += 0.5 * e.stiffness[k] * stretch * stretch;
    }
    energy
}

impl Guard {
    /// A guard for `body` as it starts.
    pub fn new(body: &Body, gravity: &Vec3) -> Self {
        let mut lo = Vec3::repeat(f64::INFINITY);
        let mut hi = Vec3::repeat(f64::NEG_INFINITY);
        for p in &body.surface.homologue_in_body {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        Self {
            events: 0,
            last_cause: None,
            acted: false,
            energy_at_end: false,
            keep_start: false,
            started: false,
            size: (hi - lo).norm().max(MIN_SIZE),
            budget: body_energy(body, gravity),
            gravity: *gravity,
            last_good_rigid: body.rigid.clone(),
            in_a_row: 0,
            measured: None,
        }
    }

    /// Takes the guard's pass over the nodes of `body` now, for the next [`Guard::check`], and with
    /// `bounds` the box of the node positions (see [`Guard::node_bounds`]). The check then reads
    /// this pass instead of making its own: the world measures after the positions are committed
    /// and before the cut stage, which reads the box, and the changes in between (cuts, coarsening)
    /// only add nodes on segments between nodes, or copies of nodes, or remove nodes, so neither
    /// the speeds, the stretches nor the box grow (nor can a value stop being finite).
    pub fn measure(&mut self, body: &Body, bounds: bool) {
        self.measured = Some(Measure::of(body, bounds));
    }

    /// Takes the largest squared speed and stretch of the nodes and whether any value is not
    /// finite, found in the state the next [`Guard::check`] looks at ([`maxima_by_blocks`]), as its
    /// pass over the nodes.
    pub fn take_maxima(&mut self, (speed2, stretch2, bad): (f64, f64, bool)) {
        self.measured = Some(Measure {
            speed2,
            stretch2,
            bad,
            bounds: None,
        });
    }

    /// The box of the node positions the last [`Guard::measure`] found (exact: every node inside,
    /// the extreme ones on its faces), if it was asked for and every value was finite.
    pub fn node_bounds(&self) -> Option<Aabb> {
        self.measured.and_then(|m| m.bounds)
    }

    /// The largest distance of a node from its homologue's world place (`homologue_in_world`, as
    /// the force stage placed it this tick) that the last [`Guard::measure`] found (m), if every
    /// value was finite.
    pub fn node_reach(&self) -> Option<f64> {
        self.measured.filter(|m| !m.bad).map(|m| m.stretch2.sqrt())
    }

    /// Starts watching `body` again after its mesh and rigid component were rebuilt (a transection):
    /// size, energy budget and last good rigid state from the body now; events kept.
    pub fn rebase(&mut self, body: &Body) {
        let fresh = Self::new(body, &self.gravity);
        self.size = fresh.size;
        self.budget = fresh.budget;
        self.last_good_rigid = fresh.last_good_rigid;
        self.measured = None;
    }

    /// Adds work done on the body by tools or anything outside the model (J).
    pub fn add_work(&mut self, work: f64) {
        if work.is_finite() {
            self.budget += work;
        }
    }

    /// The energy of the state the first step starts from (J): the budget is at least that (the state
    /// may have been set after the guard was made).
    pub fn start(&mut self, energy: f64) {
        if !self.started {
            self.started = true;
            self.raise_budget_to(energy);
        }
    }

    /// Raises the energy budget to at least `energy` (J): after a change the guard must accept, such
    /// as a topology change.
    pub fn raise_budget_to(&mut self, energy: f64) {
        if energy.is_finite() {
            self.budget = self.budget.max(energy);
        }
    }

    /// Checks the body after a step and restores it if needed. `energy` is its energy now (only
    /// computed by the caller when energy checks are on; `None` skips them).
    pub fn check(&mut self, body: &mut Body, energy: Option<f64>) -> Option<GuardCause> {
        self.acted = false;
        let cause = self.diagnose(body, energy);
        match cause {
            None => {
                self.last_good_rigid = body.rigid.clone();
                self.in_a_row = 0;
                None
            }
            Some(cause) => {
                // Kept start positions the step failed from again are a way out only if something
                // changes: the same state, stepped again, failed again, every tick (two stacked
                // organs crushed by a probe with no force limit: the guard acted on both at every
                // tick for good, the tick at 100 ms). From the second event in a row the body is
                // also stopped where it started; from the [`SNAP_AFTER`]-th it is snapped onto its
                // rest shape (as without `keep_start`, whose events in a row are not stopped). (Snapping at the second: 140–164 nodes of the two organs crossed at
                // two press depths, 11–20 keeping the start positions.)
                self.in_a_row = self.in_a_row.saturating_add(1);
                // Where the step started, unless that state is the one over the energy budget
                // (the energy checked is the one the force stage measured at the start of the step).
                let keep_start =
                    self.keep_start && self.in_a_row < SNAP_AFTER && cause != GuardCause::Energy;
                self.restore(body, keep_start, keep_start && self.in_a_row >= 2);
                self.events += 1;
                self.last_cause = Some(cause);
                self.acted = true;
                Some(cause)
            }
        }
    }

    /// Events in a row up to this step (0 when the last step passed).
    pub fn events_in_a_row(&self) -> u32 {
        self.in_a_row
    }

    fn diagnose(&mut self, body: &Body, energy: Option<f64>) -> Option<GuardCause> {
        // The pass the world took before the cut stage, or one now.
        let Measure {
            speed2,
            stretch2,
            bad,
            ..
        } = self
            .measured
            .take()
            .unwrap_or_else(|| Measure::of(body, false));
        if bad || !body.rigid.is_finite() {
            return Some(GuardCause::NonFinite);
        }
        // The rigid component: its centre, and the rim of its turning (|ω| times the body's size).
        let r = &body.rigid;
        let turning = r.angular_velocity_in_world().norm() * self.size;
        if speed2 > MAX_SPEED * MAX_SPEED
            || r.velocity_in_world.norm_squared() > MAX_SPEED * MAX_SPEED
            || turning > MAX_SPEED
        {
            return Some(GuardCause::Speed);
        }
        // The homologues are where the step's node pass put them, on the rigid component as it
        // started the step (the last good state); the nodes are where the step ended. What the
        // rigid component moved over the step is motion, not stretch: its centre's displacement
        // and its turning's at the body's size. (Without it a body falling faster than five sizes
        // a step, 5 m/s at a 0.1 s step, was restored every step from then on, frozen in the air.)
        // (Measured only past the plain bound: nothing to add on the tick of a body within it.)
        let max_stretch = MAX_STRETCH * self.size;
        if stretch2 > max_stretch * max_stretch {
            let moved = (r.position_in_world - self.last_good_rigid.position_in_world).norm()
                + r.world_from_body
                    .angle_to(&self.last_good_rigid.world_from_body)
                    * self.size;
            if stretch2 > (max_stretch + moved) * (max_stretch + moved) {
                return Some(GuardCause::Stretch);
            }
        }
        if let Some(e) = energy
            && e > self.budget + ENERGY_SLACK * self.budget.abs() + ENERGY_SLACK_J
        {
            return Some(GuardCause::Energy);
        }
        None
    }

    /// The last good rigid component, the nodes on it (or, with `keep_start`, where the step
    /// started) moving with it; stopped when `stop`, or if that motion holds more energy than the
    /// budget allows.
    fn restore(&mut self, body: &mut Body, keep_start: bool, stop: bool) {
        // Forces are a step's scratch: keep the current ones, restore the state.
        let (force, torque) = (body.rigid.force_in_world, body.rigid.torque_in_world);
        body.rigid.clone_from(&self.last_good_rigid);
        body.rigid.force_in_world = force;
        body.rigid.torque_in_world = torque;
        self.snap_nodes(body, keep_start);
        let allowed = self.budget + ENERGY_SLACK * self.budget.abs() + ENERGY_SLACK_J;
        let energy = body_energy(body, &self.gravity);
        if stop || !energy.is_finite() || energy > allowed {
            body.rigid.velocity_in_world = Vec3::zeros();
            body.rigid.angular_momentum_in_world = Vec3::zeros();
            self.snap_nodes(body, keep_start);
        }
    }

    fn snap_nodes(&self, body: &mut Body, keep_start: bool) {
        let r = &body.rigid;
        let world_from_body = r.world_from_body.to_rotation_matrix();
        let omega = r.angular_velocity_in_world();
        let s = &mut body.surface;
        for i in 0..s.mass.len() {
            let arm = world_from_body * s.homologue_in_body[i];
            let h = r.position_in_world + arm;
            // (After the commit, `next_position_in_world` holds where the step started.)
            let x = if keep_start {
                s.next_position_in_world[i]
            } else {
                h
            };
            s.position_in_world[i] = x;
            s.next_position_in_world[i] = x;
            s.homologue_in_world[i] = h;
            s.velocity_in_world[i] = r.velocity_in_world + omega.cross(&arm);
            s.force_in_world[i] = Vec3::zeros();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::{BodyParams, Placement};
    use crate::scene::mesh::icosphere;

    /// The AVX pass gives the scalar pass's answer to the bit, on nodes with every kind of value
    /// (NaN and infinities among them, one kind at a time and all together), for every length
    /// around a block of four.
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn the_avx_maxima_are_the_scalar_ones() {
        if !crate::dynamics::kernel::simd_available() {
            eprintln!("no AVX on this machine: nothing to compare");
            return;
        }
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let specials = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e200, -0.0];
        let mut compared = 0;
        for trial in 0..400 {
            let n = trial % 23;
            let mut value = |k: u64| {
                let r = next();
                if trial % 4 != 0 && r % 61 == k {
                    specials[(r / 61) as usize % specials.len()]
                } else {
                    (r >> 11) as f64 / (1u64 << 53) as f64 * 20.0 - 10.0
                }
            };
            let mut vectors = |k: u64| -> Vec<Vec3> {
                (0..n)
                    .map(|_| Vec3::new(value(k), value(k), value(k)))
                    .collect()
            };
            let (v, x, h) = (vectors(0), vectors(1), vectors(2));
            let simd = unsafe { avx_maxima(&v, &x, &h) };
            let scalar = scalar_maxima(&v, &x, &h, (0.0, 0.0, false));
            assert_eq!(simd.0.to_bits(), scalar.0.to_bits(), "speed², {n} nodes");
            assert_eq!(simd.1.to_bits(), scalar.1.to_bits(), "stretch², {n} nodes");
            assert_eq!(simd.2, scalar.2, "not finite, {n} nodes");
            compared += (scalar.2 as usize) + 1;
        }
        // Both kinds of answer were met: finite bodies and bodies with a bad value.
        assert!(compared > 400 && compared < 800, "{compared}");
    }

    fn body() -> Body {
        Body::new(
            "organ",
            &icosphere(0.05, 2),
            &BodyParams::default(),
            &Placement::default(),
        )
    }

    /// With `keep_start`, an event restores the nodes to where the step started, from the second
    /// in a row with the body stopped there (no velocity), and the [`SNAP_AFTER`]-th in a row snaps
    /// them onto the rest shape (the kept state kept failing; moving with the last good rigid
    /// component, as any snap); after a good step the next event
    /// keeps them again, with their velocities.
    #[test]
    fn events_in_a_row_stop_the_body_then_snap_it_onto_the_rest_shape() {
        let gravity = Vec3::new(0.0, 0.0, -9.81);
        let rest = body();
        let mut guard = Guard::new(&rest, &gravity);
        guard.keep_start = true;
        // A deformed start (what the commit leaves in `next_position_in_world`), moving.
        let mut state = rest.clone();
        for x in state.surface.next_position_in_world.iter_mut() {
            x.z *= 0.96;
        }
        state.rigid.velocity_in_world = Vec3::new(0.01, 0.0, 0.0);
        assert_eq!(guard.check(&mut state, None), None);
        let start = state.surface.next_position_in_world.clone();
        let on_rest_shape = |b: &Body| {
            b.surface
                .position_in_world
                .iter()
                .zip(&b.surface.homologue_in_world)
                .all(|(x, h)| x == h)
        };
        let still = |b: &Body| {
            b.surface
                .velocity_in_world
                .iter()
                .all(|v| *v == Vec3::zeros())
        };
        let glitch = |b: &mut Body| b.surface.velocity_in_world[3].x = 500.0;
        let mut steps = vec![(true, true, false)];
        steps.extend((2..SNAP_AFTER).map(|_| (true, true, true)));
        steps.push((true, false, false));
        steps.push((false, false, false));
        steps.push((true, true, false));
        for (step, &(glitched, kept, stopped)) in steps.iter().enumerate() {
            state.surface.next_position_in_world.clone_from(&start);
            if glitched {
                glitch(&mut state);
                assert_eq!(guard.check(&mut state, None), Some(GuardCause::Speed));
                assert_eq!(
                    state.surface.position_in_world == start,
                    kept,
                    "step {step}"
                );
                assert_eq!(on_rest_shape(&state), !kept, "step {step}");
                assert_eq!(still(&state), stopped, "step {step}");
            } else {
                state.surface.position_in_world.clone_from(&start);
                state.rigid.velocity_in_world = Vec3::new(0.01, 0.0, 0.0);
                state
                    .surface
                    .velocity_in_world
                    .fill(Vec3::new(0.01, 0.0, 0.0));
                assert_eq!(guard.check(&mut state, None), None, "step {step}");
            }
        }
        assert!(guard.keep_start);
    }

    #[test]
    fn a_state_that_is_not_finite_anywhere_is_caught() {
        let gravity = Vec3::new(0.0, 0.0, -9.81);
        let rest = body();
        let mut guard = Guard::new(&rest, &gravity);
        let mut good = rest.clone();
        assert_eq!(guard.check(&mut good, None), None);
        // A NaN or an infinity in one velocity or one position, at the first, a middle or the last
        // node: the or of the nodes' flags must see it wherever it is.
        let n = rest.node_count();
        for node in [0, n / 2, n - 1] {
            for value in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                for in_velocity in [true, false] {
                    let mut bad = rest.clone();
                    let s = &mut bad.surface;
                    if in_velocity {
                        s.velocity_in_world[node].y = value;
                    } else {
                        s.position_in_world[node].z = value;
                    }
                    let mut guard = Guard::new(&rest, &gravity);
                    assert_eq!(
                        guard.check(&mut bad, None),
                        Some(GuardCause::NonFinite),
                        "node {node}, {value}, velocity {in_velocity}"
                    );
                    // Restored to the last good state: finite again.
                    assert!(
                        bad.surface
                            .position_in_world
                            .iter()
                            .all(|x| x.iter().all(|c| c.is_finite()))
                    );
                }
            }
        }
    }
}
