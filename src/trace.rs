//! The CSV trace of a headless run: one row per traced tick per body, header first.
//!
//! Numbers are written in Rust's shortest round-trip form, so two identical runs give identical bytes.

use std::io::Write;

use crate::world::World;

/// The trace header.
pub const TRACE_HEADER: &str = "tick,time,body,com_x,com_y,com_z,rigid_x,rigid_y,rigid_z,qw,qx,qy,qz,vx,vy,vz,kinetic_energy,total_mass,nodes,triangles,min_obstacle_gap,max_penetration,integrator,substeps,worst_omega_dt,stability_margin,guard_events,boundary_edges,plastic_set";

/// Writes the header line.
pub fn write_trace_header(out: &mut impl Write) -> std::io::Result<()> {
    writeln!(out, "{TRACE_HEADER}")
}

/// The feedback trace header.
pub const FEEDBACK_HEADER: &str = "tick,time,tool,fx,fy,fz,tx,ty,tz,contacts,clamped,grasped";

/// Writes the feedback header line.
pub fn write_feedback_header(out: &mut impl Write) -> std::io::Result<()> {
    writeln!(out, "{FEEDBACK_HEADER}")
}

/// Writes one feedback row per tool for the world's current tick: the force (N) and torque about the
/// tip (N·m) the tissue exerts on the tool, world frame, after the `max_force` clamp.
pub fn write_feedback_rows(out: &mut impl Write, world: &World) -> std::io::Result<()> {
    for tool in &world.tools {
        let f = &tool.feedback;
        writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{},{},{}",
            world.tick,
            world.time(),
            tool.name,
            f.force_in_world.x,
            f.force_in_world.y,
            f.force_in_world.z,
            f.torque_in_world.x,
            f.torque_in_world.y,
            f.torque_in_world.z,
            f.contacts,
            f.clamped as u8,
            f.grasped
        )?;
    }
    Ok(())
}

/// Writes one row per body for the world's current tick. `min_obstacle_gap` is empty without obstacles.
pub fn write_trace_rows(out: &mut impl Write, world: &World) -> std::io::Result<()> {
    let margins = world.stability_margins();
    for (b, body) in world.bodies.iter().enumerate() {
        let com = body.surface_centre_of_mass();
        let margin = &margins[b];
        let v = body.surface_centre_of_mass_velocity();
        let r = &body.rigid;
        let q = r.world_from_body.quaternion();
        let gap = world
            .min_obstacle_gap(body)
            .map_or(String::new(), |g| g.to_string());
        writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            world.tick,
            world.time(),
            body.name,
            com.x,
            com.y,
            com.z,
            r.position_in_world.x,
            r.position_in_world.y,
            r.position_in_world.z,
            q.w,
            q.i,
            q.j,
            q.k,
            v.x,
            v.y,
            v.z,
            body.kinetic_energy(),
            body.total_mass(),
            body.node_count(),
            body.surface.triangles.len(),
            gap,
            world.max_penetration(body),
            world.integrator_of(b).name(),
            world.substeps_of(b).0,
            margin.omega_dt,
            margin.margin,
            world.guards[b].events,
            body.boundary_edges,
            crate::dynamics::plasticity::largest_set(body)
        )?;
    }
    Ok(())
}
