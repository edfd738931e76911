use palpa::scene::load_scene;
use palpa::world::World;
fn main() {
    let scene = load_scene(std::path::Path::new("scenes/probe_press.toml")).unwrap();
    let mut w = World::from_scene(&scene);
    let (mut faces, mut nodes, mut pushes) = (0, 0, 0);
    for k in 0..6500 {
        w.step();
        faces += w.counters.tool_face_contacts;
        nodes += w.counters.tool_captures;
        pushes += w.counters.tool_push_outs;
        if w.counters.tool_face_contacts > 0 && faces < 20 {
            println!(
                "tick {k}: face contact, contacts {}",
                w.tools[0].feedback.contacts
            );
        }
    }
    println!("faces {faces} nodes {nodes} pushes {pushes}");
}
