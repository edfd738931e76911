//! Adaptive subdivision's invariants: after any sequence of face and edge subdivisions and
//! coarsenings the total surface mass is the initial one (1e-12 relative), every node mass stays
//! positive, inserting a node moves neither the centre of mass nor the linear momentum (1e-12), and
//! coarsening everything restores the original mesh exactly.

mod common;

use common::surface_momentum as momentum;
use palpa::Vec3;
use palpa::body::{Body, BodyParams, Placement};
use palpa::scene::mesh::icosphere;
use palpa::topology::{
    InsertionLog, SpringRule, coarsen_last, mass_fractions, subdivide_edge, subdivide_face,
};
use proptest::prelude::*;

fn moving_body() -> Body {
    let mut mesh = icosphere(0.05, 2);
    mesh.validate().unwrap();
    let placement = Placement {
        velocity_in_world: Vec3::new(0.3, -0.1, 0.2),
        angular_velocity_in_world: Vec3::new(1.0, 2.0, -0.5),
        ..Placement::default()
    };
    let mut body = Body::new("b", &mesh, &BodyParams::default(), &placement);
    // Unequal masses, as after some refinement: perturb them while keeping the total.
    let n = body.node_count();
    for i in 0..n {
        let f = 1.0 + 0.5 * ((i * 7919) % 13) as f64 / 13.0;
        body.surface.mass[i] *= f;
    }
    let total: f64 = body.surface.mass.iter().sum();
    for i in 0..n {
        body.surface.mass[i] *= 0.2 / total;
        body.surface.inverse_mass[i] = 1.0 / body.surface.mass[i];
    }
    body
}

#[test]
fn the_paper_fractions_stay_in_0_1_and_keep_the_consistency_condition() {
    let (w, m) = ([0.2, 0.3, 0.5], [1.0, 3.0, 0.5]);
    let a = mass_fractions(w, m);
    let m_p: f64 = (0..3).map(|k| a[k] * m[k]).sum();
    let after = [0, 1, 2].map(|k| (1.0 - a[k]) * m[k]);
    // m_P = α m'_A + β m'_B + γ m'_C (the paper's consistency condition).
    let interpolated: f64 = (0..3).map(|k| w[k] * after[k]).sum();
    assert!((m_p - interpolated).abs() < 1e-15);
    assert!(a.iter().all(|x| (0.0..=1.0).contains(x)));
}

/// One operation of a random sequence.
#[derive(Clone, Debug)]
enum Op {
    Face { triangle: usize, w: [f64; 3] },
    Edge { edge: usize, t: f64 },
    Coarsen,
}

fn weight() -> impl Strategy<Value = f64> {
    prop_oneof![1e-9..1e-8f64, 1e-3..1.0f64, Just(0.5)]
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        3 => (0usize..1000, weight(), weight(), weight()).prop_map(|(triangle, a, b, c)| Op::Face { triangle, w: [a, b, c] }),
        2 => (0usize..1000, prop_oneof![1e-9..1e-8f64, 0.01..0.99f64]).prop_map(|(edge, t)| Op::Edge { edge, t }),
        1 => Just(Op::Coarsen),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn subdivision_conserves_mass_centre_and_momentum(ops in proptest::collection::vec(op(), 1..40)) {
        let mut body = moving_body();
        let mut log = InsertionLog::default();
        let original_mass: f64 = body.surface_mass();
        let original_triangles = body.surface.triangles.clone();
        let original_masses = body.surface.mass.clone();
        let original_edges = (body.edges.a.clone(), body.edges.b.clone(), body.edges.stiffness.clone());
        for op in ops {
            let com = body.surface_centre_of_mass();
            let p = momentum(&body);
            let inserted = match op {
                Op::Face { triangle, w } => {
                    let t = triangle % body.surface.triangles.len();
                    subdivide_face(&mut body, &mut log, t, w, SpringRule::Area, 0.0).ok()
                }
                Op::Edge { edge, t } => {
                    let k = edge % body.edges.len();
                    let (a, b) = (body.edges.a[k], body.edges.b[k]);
                    subdivide_edge(&mut body, &mut log, a, b, t, SpringRule::ConstantKl, 0.0).ok()
                }
                Op::Coarsen => { coarsen_last(&mut body, &mut log); None }
            };
            let total = body.surface_mass();
            prop_assert!(((total - original_mass) / original_mass).abs() < 1e-12, "mass {total} vs {original_mass}");
            prop_assert!(body.surface.mass.iter().all(|&m| m > 0.0 && m.is_finite()));
            if inserted.is_some() {
                let com_jump = (body.surface_centre_of_mass() - com).norm();
                let p_jump = (momentum(&body) - p).norm();
                prop_assert!(com_jump < 1e-12, "centre of mass jumped {com_jump}");
                prop_assert!(p_jump < 1e-12 * p.norm().max(1e-3), "momentum jumped {p_jump}");
            }
            // The mesh stays a closed, consistently oriented manifold with one spring per edge.
            // (Points within 1e-9 of an edge make slivers that validation would call degenerate, so
            // only the topology is checked here.)
            let mesh = palpa::scene::mesh::SurfaceMesh {
                positions_in_body: body.surface.homologue_in_body.clone(),
                triangles: body.surface.triangles.clone(),
            };
            prop_assert_eq!(mesh.edges().len(), body.edges.len());
            prop_assert_eq!(mesh.triangles.len() * 3, mesh.edges().len() * 2);
        }
        while coarsen_last(&mut body, &mut log).is_some() {}
        prop_assert_eq!(&body.surface.triangles, &original_triangles);
        prop_assert_eq!(&body.surface.mass, &original_masses);
        prop_assert_eq!(&(body.edges.a.clone(), body.edges.b.clone(), body.edges.stiffness.clone()), &original_edges);
    }
}

#[test]
fn a_face_split_adds_one_node_two_triangles_three_edges_and_coarsening_undoes_it() {
    let mut body = moving_body();
    let mut log = InsertionLog::default();
    let (n, t, e) = (
        body.node_count(),
        body.surface.triangles.len(),
        body.edges.len(),
    );
    let mass = body.surface_mass();
    let links: f64 = body.surface.link_stiffness.iter().sum();
    let p = subdivide_face(
        &mut body,
        &mut log,
        7,
        [0.2, 0.3, 0.5],
        SpringRule::Area,
        1e-4,
    )
    .unwrap();
    assert_eq!(p as usize, n);
    assert_eq!(
        (
            body.node_count(),
            body.surface.triangles.len(),
            body.edges.len()
        ),
        (n + 1, t + 2, e + 3)
    );
    assert!(body.surface.mass[n] > 0.0 && body.surface.mass[n] < mass / n as f64 * 2.0);
    // The area rule moves link stiffness to the new node without changing the total (the elastic
    // foundation per unit area is kept).
    let links_after: f64 = body.surface.link_stiffness.iter().sum();
    assert!(
        ((links_after - links) / links).abs() < 1e-12,
        "{links} → {links_after}"
    );
    let (ea, eb) = (body.edges.a[3], body.edges.b[3]);
    let q = subdivide_edge(&mut body, &mut log, ea, eb, 0.4, SpringRule::Angle, 1e-4).unwrap();
    assert_eq!(q as usize, n + 1);
    assert_eq!(
        (body.surface.triangles.len(), body.edges.len()),
        (t + 4, e + 6)
    );
    assert!((body.surface_mass() - mass).abs() < 1e-15);
    // Limits: a point too close to a corner is refused, and so is a point outside.
    assert!(
        subdivide_face(
            &mut body,
            &mut log,
            0,
            [1.0, 1e-9, 1e-9],
            SpringRule::Area,
            1e-3
        )
        .is_err()
    );
    assert!(
        subdivide_face(
            &mut body,
            &mut log,
            0,
            [1.2, -0.1, -0.1],
            SpringRule::Area,
            0.0
        )
        .is_err()
    );
    assert_eq!(coarsen_last(&mut body, &mut log), Some(q));
    assert_eq!(coarsen_last(&mut body, &mut log), Some(p));
    assert_eq!(coarsen_last(&mut body, &mut log), None);
    assert_eq!(
        (
            body.node_count(),
            body.surface.triangles.len(),
            body.edges.len()
        ),
        (n, t, e)
    );
}
