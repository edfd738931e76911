//! A second thread for the force passes of large bodies.
//!
//! A body of [`crate::dynamics::kernel::SPLIT_NODES`] nodes or more runs its edge pass and its node
//! pass as units that write disjoint memory (their own accumulators or nodes, their own per-lane
//! sums), combined in a fixed order when all are done: the result bits depend on the units, never
//! on which thread ran one. The tick's thread posts the pass to the helper ([`Helper::for_each`]),
//! and both take the next unit left until none is; a helper that has not started by then (it
//! sleeps, or the machine gave its core to another process) takes none, its post taken back
//! ([`Helper::join`]). A tick waits for the helper only while the helper runs a unit — for as long
//! as that takes, also when the helper's core is taken from it midway (on a busy machine of two
//! cores, the tail of the tick's times). No allocation, lock or system call on the tick but the
//! wake-up of a sleeping helper (`unpark`).
//!
//! The helper keeps looking for work for [`SPIN`] after its last part, then sleeps until the next
//! post; the tick's thread waits on an atomic (spinning, then yielding), never on a lock.

use std::cell::UnsafeCell;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// How long the helper looks for the next part after its last one (or after being woken) before
/// it sleeps: long enough to catch a tick's second pass, short enough to leave the core to others
/// between ticks.
pub const SPIN: Duration = Duration::from_micros(200);

const IDLE: u32 = 0;
const POSTED: u32 = 1;
const TAKEN: u32 = 2;
const DONE: u32 = 3;
const QUIT: u32 = 4;

/// A posted part: a closure on the posting thread's stack, whose lifetime [`Helper::join`] erases
/// and keeps (it returns only when the helper is done with it or never took it).
type Job = *mut (dyn FnMut() + Send + 'static);

struct Shared {
    state: AtomicU32,
    /// Written by the posting thread only while `state` is `IDLE` (before its release store of
    /// `POSTED`); read by the helper only after its acquire exchange `POSTED` → `TAKEN`.
    job: UnsafeCell<Option<Job>>,
    panicked: AtomicBool,
    taken: AtomicU64,
}

// SAFETY: `job` is handed over through `state` as its comment says: never read and written at once.
// The closure it points to is `Send`.
unsafe impl Sync for Shared {}
// SAFETY: as above.
unsafe impl Send for Shared {}

/// One helper thread (see the module's documentation).
pub struct Helper {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
    posted: AtomicU64,
    /// A `join` is under way (another thread's `join` meanwhile runs both parts itself).
    busy: AtomicBool,
}

impl std::fmt::Debug for Helper {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Helper")
            .field("running", &self.thread.is_some())
            .field("posted", &self.posted())
            .field("taken", &self.taken())
            .finish()
    }
}

impl Helper {
    /// Starts the helper thread (a helper whose thread could not start runs every part on the
    /// posting thread).
    pub fn spawn() -> Self {
        let shared = Arc::new(Shared {
            state: AtomicU32::new(IDLE),
            job: UnsafeCell::new(None),
            panicked: AtomicBool::new(false),
            taken: AtomicU64::new(0),
        });
        let theirs = Arc::clone(&shared);
        let thread = thread::Builder::new()
            .name("palpa-helper".into())
            .spawn(move || work(&theirs))
            .ok();
        Self {
            shared,
            thread,
            posted: AtomicU64::new(0),
            busy: AtomicBool::new(false),
        }
    }

    /// True when the helper thread runs.
    pub fn is_running(&self) -> bool {
        self.thread.is_some()
    }

    /// Parts posted since the start.
    pub fn posted(&self) -> u64 {
        self.posted.load(Ordering::Relaxed)
    }

    /// Parts the helper thread ran (the others ran on the posting thread).
    pub fn taken(&self) -> u64 {
        self.shared.taken.load(Ordering::Relaxed)
    }

    /// Runs `a` on this thread and `b` on the helper when it takes it before `a` is done, here
    /// after `a` otherwise; returns when both are done.
    ///
    /// # Panics
    /// When `a` or `b` panics (after the helper is done with `b`).
    pub fn join<A: FnOnce(), B: FnOnce() + Send>(&self, a: A, b: B) {
        let Some(thread) = self
            .thread
            .as_ref()
            .filter(|_| !self.busy.swap(true, Ordering::Acquire))
        else {
            a();
            b();
            return;
        };
        // Released after the post is settled (declared before the guard, dropped after it).
        let _busy = Release(&self.busy);
        let mut b = Some(b);
        let mut run_b = move || {
            if let Some(b) = b.take() {
                b();
            }
        };
        {
            let job: *mut (dyn FnMut() + Send + '_) = &mut run_b;
            // SAFETY: only the lifetime is erased; the guard below keeps this frame (and the
            // closure) alive until the helper is done with it or has given up taking it.
            let job: Job = unsafe { std::mem::transmute(job) };
            // SAFETY: the state is IDLE: the helper does not read `job` (see `Shared`).
            unsafe { *self.shared.job.get() = Some(job) };
        }
        self.posted.fetch_add(1, Ordering::Relaxed);
        self.shared.state.store(POSTED, Ordering::Release);
        thread.thread().unpark();
        let guard = Reclaim {
            shared: &self.shared,
        };
        a();
        let ran_here = guard.finish();
        if ran_here {
            run_b();
        }
        if self.shared.panicked.swap(false, Ordering::AcqRel) {
            panic!("a force pass's part panicked on the helper thread");
        }
    }
}

/// A world's helper, started at the first pass that offers it a part (warm-up: a thread and its
/// stack are allocated then); a clone starts its own.
#[derive(Debug, Default)]
pub struct LazyHelper {
    helper: Option<Helper>,
}

impl Clone for LazyHelper {
    fn clone(&self) -> Self {
        Self { helper: None }
    }
}

impl LazyHelper {
    /// The helper, started now if it was not.
    pub fn get(&mut self) -> &Helper {
        self.helper.get_or_insert_with(Helper::spawn)
    }

    /// Ends the helper's thread, if started (the next [`LazyHelper::get`] starts another).
    pub fn stop(&mut self) {
        self.helper = None;
    }

    /// Parts posted to the helper and parts it ran, since it started (zeros if it did not).
    pub fn counts(&self) -> (u64, u64) {
        self.helper
            .as_ref()
            .map_or((0, 0), |h| (h.posted(), h.taken()))
    }
}

impl Helper {
    /// Runs `work(0) .. work(units − 1)`, each once, on this thread and the helper: each takes
    /// the next unit left until none is (a helper that has not started when this thread runs out
    /// takes none).
    pub fn for_each(&self, units: usize, work: &(dyn Fn(usize) + Sync)) {
        let next = std::sync::atomic::AtomicUsize::new(0);
        let take = || {
            loop {
                let unit = next.fetch_add(1, Ordering::Relaxed);
                if unit >= units {
                    return;
                }
                work(unit);
            }
        };
        self.join(take, take);
    }
}

/// Clears a `join`'s busy flag when it ends, also by a panic.
struct Release<'a>(&'a AtomicBool);

impl Drop for Release<'_> {
    fn drop(&mut self) {
        self.0.store(false, Ordering::Release);
    }
}

/// Takes the posted part back or waits until the helper is done with it — also when the first part
/// panics, so that the helper never runs a closure whose frame is gone.
struct Reclaim<'a> {
    shared: &'a Shared,
}

impl Reclaim<'_> {
    /// True when the part was taken back (to be run here).
    fn finish(self) -> bool {
        let ran_here = settle(self.shared);
        std::mem::forget(self);
        ran_here
    }
}

impl Drop for Reclaim<'_> {
    fn drop(&mut self) {
        settle(self.shared);
    }
}

/// Back to IDLE: the posted part taken back (true), or waited for until the helper ran it.
fn settle(shared: &Shared) -> bool {
    let ran_here =
        match shared
            .state
            .compare_exchange(POSTED, IDLE, Ordering::AcqRel, Ordering::Acquire)
        {
            Ok(_) => true,
            Err(_) => {
                let mut spins = 0u32;
                while shared.state.load(Ordering::Acquire) != DONE {
                    if spins < 1 << 14 {
                        spins += 1;
                        std::hint::spin_loop();
                    } else {
                        thread::yield_now();
                    }
                }
                shared.state.store(IDLE, Ordering::Release);
                false
            }
        };
    // SAFETY: IDLE again: the helper does not read `job`.
    unsafe { *shared.job.get() = None };
    ran_here
}

impl Drop for Helper {
    fn drop(&mut self) {
        // No part is posted (`join` returns with the state IDLE and takes `&self`).
        self.shared.state.store(QUIT, Ordering::Release);
        if let Some(thread) = self.thread.take() {
            thread.thread().unpark();
            let _ = thread.join();
        }
    }
}

/// The helper thread: takes posted parts, spins for [`SPIN`] after each one, sleeps otherwise.
fn work(shared: &Shared) {
    leave_the_ticks_core();
    let mut since = Instant::now();
    let mut idle_spins = 0u32;
    loop {
        match shared.state.load(Ordering::Acquire) {
            POSTED => {
                if shared
                    .state
                    .compare_exchange(POSTED, TAKEN, Ordering::AcqRel, Ordering::Acquire)
                    .is_ok()
                {
                    // SAFETY: taken (POSTED → TAKEN): the poster wrote `job` before posting and
                    // waits for DONE before it reads, writes or drops anything the job refers to.
                    let job = unsafe { *shared.job.get() };
                    if let Some(job) = job {
                        // SAFETY: as above: the closure lives until DONE.
                        let ok = catch_unwind(AssertUnwindSafe(|| unsafe { (*job)() })).is_ok();
                        if !ok {
                            shared.panicked.store(true, Ordering::Release);
                        }
                    }
                    shared.taken.fetch_add(1, Ordering::Relaxed);
                    shared.state.store(DONE, Ordering::Release);
                    since = Instant::now();
                    idle_spins = 0;
                }
            }
            QUIT => return,
            _ => {
                idle_spins += 1;
                std::hint::spin_loop();
                // The clock read only now and then.
                if idle_spins % 64 == 0 && since.elapsed() >= SPIN {
                    thread::park();
                    since = Instant::now();
                    idle_spins = 0;
                }
            }
        }
    }
}

/// A helper started by a real-time tick thread (`palpa serve --rt`, with the `ipc` feature:
/// SCHED_FIFO, pinned to one core) inherits both: it takes the normal scheduler back, and, when it was pinned to one core,
/// every other core, so that it never holds the tick thread's core while it spins or sleeps.
#[cfg(all(target_os = "linux", feature = "ipc"))]
fn leave_the_ticks_core() {
    // SAFETY: plain system calls on the calling thread, with sets sized as the calls ask.
    unsafe {
        let normal = libc::sched_param { sched_priority: 0 };
        libc::sched_setscheduler(0, libc::SCHED_OTHER, &normal);
        let size = std::mem::size_of::<libc::cpu_set_t>();
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, size, &mut set) != 0 || libc::CPU_COUNT(&set) != 1 {
            return;
        }
        let cores = libc::sysconf(libc::_SC_NPROCESSORS_ONLN).max(1) as usize;
        let mut others: libc::cpu_set_t = std::mem::zeroed();
        for core in 0..cores.min(libc::CPU_SETSIZE as usize) {
            if !libc::CPU_ISSET(core, &set) {
                libc::CPU_SET(core, &mut others);
            }
        }
        if libc::CPU_COUNT(&others) > 0 {
            libc::sched_setaffinity(0, size, &others);
        }
    }
}

#[cfg(not(all(target_os = "linux", feature = "ipc")))]
fn leave_the_ticks_core() {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_parts_run_once_whoever_takes_them() {
        let helper = Helper::spawn();
        assert!(helper.is_running());
        for round in 0..2_000u64 {
            let (mut a, mut b) = (0u64, 0u64);
            helper.join(|| a += round + 1, || b += 2 * round + 1);
            assert_eq!((a, b), (round + 1, 2 * round + 1));
            // Sometimes the helper sleeps: it must wake for the next post.
            if round % 500 == 0 {
                thread::sleep(SPIN * 3);
            }
        }
        assert_eq!(helper.posted(), 2_000);
        assert!(helper.taken() <= 2_000);
    }

    #[cfg(all(target_os = "linux", feature = "ipc"))]
    #[test]
    fn a_helper_started_by_a_pinned_thread_runs_on_the_other_cores() {
        // SAFETY (all blocks): plain system calls on the calling thread, with sets sized as they ask.
        let cores = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) }.max(1) as usize;
        let size = std::mem::size_of::<libc::cpu_set_t>();
        let pinned_to = cores - 1;
        let (taken, helper_cores) = thread::spawn(move || {
            unsafe {
                let mut set: libc::cpu_set_t = std::mem::zeroed();
                libc::CPU_SET(pinned_to, &mut set);
                assert_eq!(libc::sched_setaffinity(0, size, &set), 0);
            }
            let helper = Helper::spawn();
            let mut seen = Vec::new();
            helper.join(
                // Gives the helper up to 5 s to take the part.
                || {
                    let start = Instant::now();
                    while helper.taken() == 0 && start.elapsed() < Duration::from_secs(5) {
                        thread::sleep(Duration::from_millis(1));
                    }
                },
                || {
                    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
                    unsafe { libc::sched_getaffinity(0, size, &mut set) };
                    seen = (0..cores)
                        .filter(|&c| unsafe { libc::CPU_ISSET(c, &set) })
                        .collect();
                },
            );
            (helper.taken(), seen)
        })
        .join()
        .expect("the pinned thread");
        assert_eq!(taken, 1, "the helper did not take the part within 5 s");
        if cores == 1 {
            assert_eq!(helper_cores, vec![0], "one core: the helper keeps it");
        } else {
            let others: Vec<usize> = (0..cores).filter(|&c| c != pinned_to).collect();
            assert_eq!(helper_cores, others, "the helper kept the pinned core");
        }
    }

    #[test]
    fn joins_from_several_threads_at_once_each_run_both_parts() {
        let helper = Helper::spawn();
        thread::scope(|scope| {
            for t in 0..4u64 {
                let helper = &helper;
                scope.spawn(move || {
                    for round in 0..500u64 {
                        let (mut a, mut b) = (0u64, 0u64);
                        let busy = || {
                            for k in 0..2_000u64 {
                                std::hint::black_box(k);
                            }
                        };
                        helper.join(
                            || {
                                a = t + round;
                                busy();
                            },
                            || {
                                b = t * round + 1;
                                busy();
                            },
                        );
                        assert_eq!((a, b), (t + round, t * round + 1));
                    }
                });
            }
        });
        assert!(helper.taken() <= helper.posted());
    }

    #[test]
    fn for_each_runs_every_unit_once() {
        let helper = Helper::spawn();
        for units in [0, 1, 2, 3, 7] {
            let runs: Vec<std::sync::atomic::AtomicU32> =
                (0..units).map(|_| AtomicU32::new(0)).collect();
            helper.for_each(units, &|u| {
                runs[u].fetch_add(1, Ordering::Relaxed);
            });
            assert!(
                runs.iter().all(|r| r.load(Ordering::Relaxed) == 1),
                "{units}"
            );
        }
    }

    #[test]
    fn a_panic_in_the_helper_part_reaches_the_caller() {
        let helper = Helper::spawn();
        let result = catch_unwind(AssertUnwindSafe(|| {
            helper.join(
                || thread::sleep(Duration::from_millis(5)),
                || panic!("part b"),
            );
        }));
        // Either the helper ran it (its panic reported after the wait) or it ran here.
        assert!(result.is_err());
        // The helper survives and takes parts again.
        let mut b = 0;
        helper.join(|| {}, || b = 7);
        assert_eq!(b, 7);
    }
}
