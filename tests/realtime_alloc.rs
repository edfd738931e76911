//! Real time: after warm-up, a step allocates nothing, nor does what the tick hands to a recording
//! and a live view. A counting global allocator watches the heap while the world steps scenes with
//! every system of the core model switched on.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use palpa::scene::load_scene;
use palpa::world::World;

struct Counting;

// Counting is per thread: the step runs on the test's thread, while the test harness allocates on
// its own (reporting another test's result) at any time.
thread_local! {
    static COUNTING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

fn counting() -> bool {
    COUNTING.with(|c| c.get())
}

fn set_counting(on: bool) {
    COUNTING.with(|c| c.set(on));
}

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if counting() {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if counting() {
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
        "scenes/plastic.toml",
    ] {
        let scene = load_scene(&common::repo_root().join(scene)).unwrap();
        let mut world = World::from_scene(&scene);
        // Warm up past the probe's first contact (about 2.2 s into probe_press.toml).
        for _ in 0..2500 {
            world.step();
        }
        ALLOCATIONS.store(0, Ordering::SeqCst);
        set_counting(true);
        for _ in 0..3000 {
            world.step();
        }
        set_counting(false);
        let count = ALLOCATIONS.load(Ordering::SeqCst);
        // The counter itself works: building a world allocates.
        set_counting(true);
        let again = World::from_scene(&scene);
        set_counting(false);
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
fn the_laparoscopy_scene_allocates_nothing_on_the_tick() {
    // Seven bodies in contact, fourteen ligaments, a probe palpating and a grasper taking, lifting
    // and letting go of a tube (the demo's devices as scripts).
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let scene = common::laparoscopy_with_demo_tools(6.0);
    let mut world = World::from_scene(&scene);
    for _ in 0..500 {
        world.step();
    }
    ALLOCATIONS.store(0, Ordering::SeqCst);
    set_counting(true);
    let mut grasped = 0;
    for _ in 500..6000 {
        world.step();
        grasped = grasped.max(world.tools[1].feedback.grasped);
    }
    set_counting(false);
    let count = ALLOCATIONS.load(Ordering::SeqCst);
    assert!(grasped > 0, "the grasper took nothing");
    assert_eq!(count, 0, "{count} allocations in 5 500 steps");
}

#[test]
fn a_large_body_sharing_its_passes_with_the_helper_thread_allocates_nothing_on_the_tick() {
    // 10 242 nodes (above `SPLIT_NODES`): the step's thread hands half of each force pass to the
    // world's helper thread (started, with its stack, at the first step), pressed by a probe.
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let scene = common::scene(
        r#"
        [world]
        integrator = "symplectic"
        [[body]]
        name = "organ"
        mesh = { icosphere = { radius = 0.05, subdivisions = 5 } }
        position = [0.0, 0.0, 0.05]
        surface_mass = 3.19
        fixed = true
        [[obstacle]]
        name = "table"
        plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }
        [[tool]]
        name = "probe"
        shape = { sphere = { radius = 0.008 } }
        input = "script"
        script = [ { t = 0.0, position = [0.0, 0.0, 0.11] }, { t = 0.3, position = [0.0, 0.0, 0.095] } ]
        "#,
    );
    let mut world = World::from_scene(&scene);
    assert!(world.bodies[0].node_count() >= palpa::dynamics::kernel::SPLIT_NODES);
    for _ in 0..100 {
        world.step();
    }
    let posted_before = world.helper_counts().0;
    ALLOCATIONS.store(0, Ordering::SeqCst);
    set_counting(true);
    let mut contacts = 0;
    for _ in 100..400 {
        world.step();
        contacts = contacts.max(world.tools[0].feedback.contacts);
    }
    set_counting(false);
    let count = ALLOCATIONS.load(Ordering::SeqCst);
    let posted = world.helper_counts().0 - posted_before;
    assert_eq!(posted, 600, "two halves a step offered to the helper");
    assert!(contacts > 0, "the probe touched nothing");
    assert_eq!(count, 0, "{count} allocations in 300 steps");
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
    set_counting(true);
    let mut most = 0;
    for _ in 0..7000 {
        world.step();
        most = most.max(world.bodies[0].node_count());
    }
    set_counting(false);
    let count = ALLOCATIONS.load(Ordering::SeqCst);
    let r = world.refinements[0].as_ref().unwrap();
    assert!(most > 162, "the run refined");
    assert!(r.counters.coarsened > 0 && world.bodies[0].node_count() == 162);
    assert_eq!(
        count, 0,
        "{count} allocations while refining and coarsening"
    );
}

#[test]
fn stiff_rigid_coupling_allocates_nothing_on_the_tick() {
    // The coupled implicit solve (contacts pinned and re-solved), multirate with the rigid component
    // sub-stepped, multirate with the rigid component stepped implicitly: from the drop to rest.
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    for (file, integrator) in [
        ("stiff_links.toml", "implicit"),
        ("stiff_links.toml", "multirate"),
        ("mass_ratio.toml", "multirate"),
    ] {
        let scene =
            common::scene_file_with_integrator(&format!("scenes/stress/{file}"), integrator);
        let mut world = World::from_scene(&scene);
        for _ in 0..10 {
            world.step();
        }
        ALLOCATIONS.store(0, Ordering::SeqCst);
        set_counting(true);
        // Through the landing (about 0.11 s) and the bounces.
        let mut contacts = 0;
        for _ in 0..600 {
            world.step();
            contacts += world.counters.obstacle_contacts;
        }
        set_counting(false);
        let count = ALLOCATIONS.load(Ordering::SeqCst);
        assert!(contacts > 0, "{file}: it landed on the table");
        assert_eq!(
            count, 0,
            "{file} / {integrator}: {count} allocations in 600 steps"
        );
    }
}

#[test]
fn cutting_and_transection_allocate_nothing_on_the_tick() {
    // incision.toml: the blade cuts from about 0.3 s to 1.5 s, the probe then refines the body on a
    // lip; transection.toml: the tube is cut through at tick 1138 and its halves become two bodies
    // (the second from the spares reserved up front).
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    for (file, ticks) in [
        ("scenes/incision.toml", 4000),
        ("scenes/transection.toml", 2000),
    ] {
        let scene = load_scene(&common::repo_root().join(file)).unwrap();
        let mut world = World::from_scene(&scene);
        for _ in 0..10 {
            world.step();
        }
        ALLOCATIONS.store(0, Ordering::SeqCst);
        set_counting(true);
        let (mut cuts, mut transections) = (0, 0);
        for _ in 0..ticks {
            world.step();
            cuts += world.counters.cuts;
            transections += world.counters.transections;
        }
        set_counting(false);
        let count = ALLOCATIONS.load(Ordering::SeqCst);
        assert!(cuts >= 5, "{file}: the blade cut ({cuts} cutting ticks)");
        if file.contains("transection") {
            assert_eq!(transections, 1, "{file}: the tube was cut through");
            assert_eq!(world.bodies.len(), 2);
        }
        assert_eq!(count, 0, "{file}: {count} allocations in {ticks} steps");
    }
}

/// What the daemon's tick hands to a recording and to a live view (feedback, inputs, mesh messages,
/// statistics, events) allocates nothing on the tick's thread: records go into bounded queues, mesh
/// bytes into buffers from pools filled at start. The recorder's and the live view's own threads
/// allocate as they encode, off the tick.
#[cfg(feature = "live")]
#[test]
fn recording_and_the_live_view_allocate_nothing_on_the_tick() {
    use palpa::daemon::sink::{RecordSink, event};
    use palpa::display::MeshSchedule;
    use palpa::ipc::payload::{StatsV1, ToolPoseV1};
    use palpa::record::live::{LiveSettings, LiveView};
    use palpa::record::recorder::{Recorder, RecorderSettings, SessionInfo};
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let scene = load_scene(&common::repo_root().join("scenes/probe_press.toml")).unwrap();
    let mut world = World::from_scene(&scene);
    let path = std::env::temp_dir().join(format!("palpa_alloc_{}.mcap", std::process::id()));
    let session = SessionInfo {
        mode: "serve".into(),
        display_rate_hz: 60.0,
        keyframe_every_s: 2.0,
    };
    // This loop steps far faster than real time: the recorder waits for its writer rather than
    // drop (as `palpa run` records), the live view drops what does not fit (as the daemon's does).
    let recorder = Recorder::start(&path, &scene, &world, &session, RecorderSettings::default())
        .unwrap()
        .waiting_when_full();
    let live = LiveView::start(
        "127.0.0.1:0".parse().unwrap(),
        &world,
        LiveSettings::default(),
    )
    .unwrap();
    let sink = RecordSink::to(recorder).with_live(live);
    let mut meshes = MeshSchedule::new(&world, 60.0, 2.0);
    let mut known = world.bodies.len();
    let pose = ToolPoseV1 {
        orientation: [1.0, 0.0, 0.0, 0.0],
        ..ToolPoseV1::default()
    };
    let tick = |world: &mut World, meshes: &mut MeshSchedule, known: &mut usize| {
        sink.input(world.tick, 0, &pose, 0);
        world.step();
        sink.bodies_added(world, known);
        for tool in 0..world.tools.len() {
            let feedback = palpa::daemon::feedback_of(world, tool, true, false, (0, 0));
            sink.feedback(tool, &feedback);
        }
        let _ = meshes.produce(world, |header, bytes| -> Result<(), ()> {
            sink.mesh(header, bytes);
            Ok(())
        });
        if world.tick % 1000 == 0 {
            sink.stats(&StatsV1 {
                tick: world.tick,
                ..StatsV1::default()
            });
            sink.event(world.tick, event::SYNCHRONICITY_MISS, None);
        }
    };
    for _ in 0..2500 {
        tick(&mut world, &mut meshes, &mut known);
    }
    ALLOCATIONS.store(0, Ordering::SeqCst);
    set_counting(true);
    for _ in 0..3000 {
        tick(&mut world, &mut meshes, &mut known);
    }
    set_counting(false);
    let count = ALLOCATIONS.load(Ordering::SeqCst);
    let (recorded, live) = sink.finish_all();
    let recorded = recorded.unwrap().unwrap();
    let live = live.unwrap();
    let _ = std::fs::remove_file(&path);
    assert_eq!(count, 0, "{count} allocations in 3000 ticks");
    // The recording got the whole stream (one SceneUpdate per display tick: every 17 ticks and the
    // keyframe ticks 1, 2001, 4001 of 5 500), the live view what it could take.
    assert_eq!(recorded.dropped, 0);
    let display_ticks = (1..=5500u64)
        .filter(|t| t % 17 == 0 || (t - 1) % 2000 == 0)
        .count() as u64;
    assert_eq!(recorded.messages["/foxglove/scene"], display_ticks);
    let shown = live.messages.get("/foxglove/scene").copied().unwrap_or(0);
    assert!(shown > 0 && shown <= display_ticks, "{live:?}");
}

#[test]
fn self_contact_allocates_nothing_on_the_tick() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    // A default ball dropped from 0.5 m onto the table with self-contact: it lands at about
    // 0.32 s, its top meets its bottom, its far pairs are listed again many times; then
    // probe_refine.toml with self-contact on its organ, whose topology the probe's subdivision
    // changes (the near pairs listed again).
    let ball = common::dropped_ball(true);
    let mut refine = load_scene(&common::repo_root().join("scenes/probe_refine.toml")).unwrap();
    refine.bodies[0].params.self_contact = true;
    for (name, scene, ticks) in [("ball", ball, 800), ("probe_refine", refine, 7000)] {
        let mut world = World::from_scene(&scene);
        for _ in 0..10 {
            world.step();
        }
        ALLOCATIONS.store(0, Ordering::SeqCst);
        set_counting(true);
        let mut collisions = 0u64;
        for _ in 0..ticks {
            world.step();
            collisions += u64::from(world.counters.bodies.collisions);
        }
        set_counting(false);
        let count = ALLOCATIONS.load(Ordering::SeqCst);
        println!(
            "{name}: {collisions} net collisions, topology version {}, {count} allocations",
            world.bodies[0].topology_version
        );
        assert_eq!(count, 0, "{name}: {count} allocations with self-contact");
    }
}

#[test]
fn faces_pressed_between_the_nodes_allocate_nothing_on_the_tick() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    // A 1.5 mm probe pressed between the nodes of the default organ and stroked 2 cm: the
    // triangles carry the contact (`palpa::contact::tool_faces`).
    let scene = common::scene(
        r#"
[[body]]
name = "organ"
mesh = { ellipsoid = { radii = [0.08, 0.05, 0.04], subdivisions = 3 } }
position = [0.0, 0.0, 0.041]
surface_mass = 0.3
rigid_mass = 1.2
surface_stiffness = 40.0
link_stiffness = 15.0
friction = 0.3

[[obstacle]]
name = "table"
plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }

[[tool]]
name = "probe"
shape = { sphere = { radius = 0.0015 } }
script = [
  { t = 0.0, position = [0.0013, 0.0021, 0.10] },
  { t = 0.8, position = [0.0013, 0.0021, 0.0835] },
  { t = 1.5, position = [0.0013, 0.0021, 0.055] },
  { t = 2.5, position = [0.0213, 0.0021, 0.055] },
]
"#,
    );
    let mut world = World::from_scene(&scene);
    for _ in 0..10 {
        world.step();
    }
    ALLOCATIONS.store(0, Ordering::SeqCst);
    set_counting(true);
    let mut faces = 0u64;
    for _ in 10..2500 {
        world.step();
        faces += u64::from(world.counters.tool_face_contacts);
    }
    set_counting(false);
    let count = ALLOCATIONS.load(Ordering::SeqCst);
    assert!(faces > 1000, "the faces carried the contact: {faces}");
    assert_eq!(count, 0, "{count} allocations in 2 490 steps");
}
