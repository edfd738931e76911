//! Real time: after warm-up, a step allocates nothing. A counting global allocator watches the heap
//! while the world steps scenes with every system of the core model switched on.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use palpa::scene::load_scene;
use palpa::world::World;

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::SeqCst) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::SeqCst) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The counter is global: the tests take turns.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

#[test]
fn a_step_allocates_nothing_after_warm_up() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    for scene in [
        "scenes/organ.toml",
        "scenes/inclined_plane.toml",
        "scenes/table_rest.toml",
        "scenes/probe_press.toml",
    ] {
        let scene = load_scene(&common::repo_root().join(scene)).unwrap();
        let mut world = World::from_scene(&scene);
        // Warm up past the probe's first contact (about 2.2 s into probe_press.toml).
        for _ in 0..2500 {
            world.step();
        }
        ALLOCATIONS.store(0, Ordering::SeqCst);
        COUNTING.store(true, Ordering::SeqCst);
        for _ in 0..3000 {
            world.step();
        }
        COUNTING.store(false, Ordering::SeqCst);
        let count = ALLOCATIONS.load(Ordering::SeqCst);
        // The counter itself works: building a world allocates.
        COUNTING.store(true, Ordering::SeqCst);
        let again = World::from_scene(&scene);
        COUNTING.store(false, Ordering::SeqCst);
        assert!(
            ALLOCATIONS.load(Ordering::SeqCst) > count,
            "the counting allocator counts"
        );
        assert_eq!(
            count, 0,
            "{}: {count} allocations in 3000 steps",
            scene.name
        );
        drop(again);
    }
}

#[test]
fn subdivision_and_coarsening_allocate_nothing_on_the_tick() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    // probe_refine.toml: the probe touches at about 1.5 s, refines while it presses and strokes,
    // lifts off at 7 s, and every inserted node is removed by about 7.5 s.
    let scene = load_scene(&common::repo_root().join("scenes/probe_refine.toml")).unwrap();
    let mut world = World::from_scene(&scene);
    for _ in 0..1000 {
        world.step();
    }
    ALLOCATIONS.store(0, Ordering::SeqCst);
    COUNTING.store(true, Ordering::SeqCst);
    let mut most = 0;
    for _ in 0..7000 {
        world.step();
        most = most.max(world.bodies[0].node_count());
    }
    COUNTING.store(false, Ordering::SeqCst);
    let count = ALLOCATIONS.load(Ordering::SeqCst);
    let r = world.refinements[0].as_ref().unwrap();
    assert!(most > 162, "the run refined");
    assert!(r.counters.coarsened > 0 && world.bodies[0].node_count() == 162);
    assert_eq!(
        count, 0,
        "{count} allocations while refining and coarsening"
    );
}
