use palpa::scene::load_scene;
use palpa::world::World;
fn main() {
    let scene = load_scene(std::path::Path::new("scenes/probe_press.toml")).unwrap();
    let mut w = World::from_scene(&scene);
    for _ in 0..5500 {
        w.step();
    }
    let tool = &w.tools[0];
    let b = &w.bodies[0];
    for i in 0..b.node_count() {
        let c = b.surface.tool_contact[i];
        if c.tool != u32::MAX {
            let x = b.surface.position_in_world[i];
            let n = (x - tool.pose.position_in_world).normalize();
            let f = b.surface.force_in_world[i];
            println!(
                "node {i} x {:?} n {:?} F {:?} F·n {:e} h {:?}",
                x.as_slice(),
                n.as_slice(),
                f.as_slice(),
                f.dot(&n),
                b.surface.homologue_in_world[i].as_slice()
            );
        }
    }
}
