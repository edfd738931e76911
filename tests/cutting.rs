//! Cutting: incisions along a blade's sweep keep the mesh an oriented manifold of good triangles,
//! conserve mass and momentum, and follow the blade's path.

use palpa::Vec3;
use palpa::body::{Body, BodyParams, Placement};
use palpa::scene::mesh::{SurfaceMesh, icosphere};
use palpa::topology::cut::{Cutter, CuttingSettings, check_surface, smallest_angle_deg};

fn cutting_body(mesh: &SurfaceMesh) -> Body {
    let params = BodyParams {
        cutting: Some(CuttingSettings::default()),
        ..BodyParams::default()
    };
    let mut body = Body::new("organ", mesh, &params, &Placement::default());
    body.reserve_room();
    body
}

fn momentum(body: &Body) -> Vec3 {
    let s = &body.surface;
    s.velocity_in_world
        .iter()
        .zip(&s.mass)
        .fold(Vec3::zeros(), |acc, (v, m)| acc + v * *m)
}

#[test]
fn explore_straight_incision() {
    let mesh = icosphere(0.05, 3);
    let mut body = cutting_body(&mesh);
    let mut cutter = Cutter::new(&body, CuttingSettings::default(), 1);
    let mass0 = body.surface_mass();
    // A blade held vertically, its cutting segment from 1 cm below the top to 1 cm above it, drawn
    // along x across the top of the sphere: 9 cm in 900 steps of 0.1 mm.
    let seg = |x: f64| [Vec3::new(x, 0.0013, 0.04), Vec3::new(x, 0.0013, 0.06)];
    let steps = 900;
    for k in 0..steps {
        let x0 = -0.045 + 0.09 * k as f64 / steps as f64;
        let x1 = -0.045 + 0.09 * (k + 1) as f64 / steps as f64;
        let step = cutter.cut(&mut body, 0, seg(x0), seg(x1));
        if let Err(e) = check_surface(&body) {
            panic!("step {k}: {e} ({step:?})");
        }
    }
    println!(
        "nodes {} boundary {} counters {:?} smallest {} bound {} orig {}",
        body.node_count(),
        body.boundary_edges,
        cutter.counters,
        cutter.smallest_created_angle_deg,
        cutter.quality_bound_deg,
        smallest_angle_deg(&body)
    );
    println!("mass {} {}", mass0, body.surface_mass());
    println!("momentum {:?}", momentum(&body));
}
