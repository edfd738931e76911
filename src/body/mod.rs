//! A deformable body of the paper (MODEL.md §1): a surface of point masses joined by damped edge
//! springs, a virtual rigid component, and one zero-rest-length damped link per surface node to its
//! homologue on the rigid component.
//!
//! State is laid out as structure of arrays ([`Surface`], [`Edges`]) indexed by node and edge number.
//! Every buffer the step writes is sized when the body is built, so stepping never allocates.

pub mod changes;
mod contact_state;
pub mod mesh;
mod rigid;
pub mod settings;

pub use contact_state::{JawHold, NO_TOOL, ToolContact};
pub use rigid::RigidComponent;

use crate::Vec3;
pub use changes::TopologyChanges;
use mesh::SurfaceMesh;
use nalgebra::UnitQuaternion;
use settings::{
    CuttingSettings, Integrator, POOL_NODES, PlasticitySettings, SubdivisionSettings,
    TearingSettings,
};

/// The mechanical parameters of a body, SI units (see the README's scene format).
#[derive(Clone, Debug, PartialEq)]
pub struct BodyParams {
    /// Total mass of the surface nodes (kg), spread over the nodes by area.
    pub surface_mass: f64,
    /// Mass of the virtual rigid component (kg).
    pub rigid_mass: f64,
    /// Stiffness of each edge spring (N/m).
    pub surface_stiffness: f64,
    /// Damping of each edge spring (N·s/m).
    pub surface_damping: f64,
    /// Stiffness of each node's link to its homologue (N/m).
    pub link_stiffness: f64,
    /// Damping of each node's link (N·s/m).
    pub link_damping: f64,
    /// Air viscosity per unit mass (1/s): a node of mass m feels −ν m v; the rigid component −ν M V
    /// and the torque −ν I ω.
    pub air_viscosity: f64,
    /// Coulomb coefficient between this body and tools.
    pub friction: f64,
    /// When true the rigid component is held where the scene puts it (an organ attached to the
    /// abdominal wall); the surface still deforms around it.
    pub fixed: bool,
    /// When true the body's surface may not pass through itself (its folds and pressed sheets
    /// are stopped by the collision net, see `contact::self_pairs`). Not with cutting or tearing
    /// (the scene refuses it; [`BodyParams::self_contact_on`] ignores it).
    pub self_contact: bool,
    /// This body's integrator, when it differs from the world's.
    pub integrator: Option<Integrator>,
    /// Adaptive subdivision at tool contact, when on.
    pub subdivision: Option<SubdivisionSettings>,
    /// Cutting by blades, when on.
    pub cutting: Option<CuttingSettings>,
    /// Plastic flow of the homologues, when on.
    pub plasticity: Option<PlasticitySettings>,
    /// Tearing of overstretched springs, when on.
    pub tearing: Option<TearingSettings>,
}

impl BodyParams {
    /// The settings of the cutter that changes this body's topology (cutting, tearing or both: the
    /// pools are the larger of the two), `None` when neither is on.
    pub fn topology_cutter(&self) -> Option<CuttingSettings> {
        match (self.cutting, self.tearing) {
            (Some(c), Some(t)) => Some(CuttingSettings {
                max_nodes: c.max_nodes.max(t.max_nodes),
                max_pieces: c.max_pieces.max(t.max_pieces),
                ..c
            }),
            (Some(c), None) => Some(c),
            (None, Some(t)) => Some(CuttingSettings {
                max_nodes: t.max_nodes,
                max_pieces: t.max_pieces,
                ..CuttingSettings::default()
            }),
            (None, None) => None,
        }
    }
}

impl BodyParams {
    /// Whether the body's self-contact is on: asked for, on a body that is neither cut nor torn
    /// (the two sides of a cut start touching, which self-contact would take for a collision
    /// every tick).
    pub fn self_contact_on(&self) -> bool {
        self.self_contact && self.cutting.is_none() && self.tearing.is_none()
    }
}

impl Default for BodyParams {
    fn default() -> Self {
        Self {
            surface_mass: 0.2,
            rigid_mass: 1.0,
            surface_stiffness: 50.0,
            surface_damping: 0.01,
            link_stiffness: 20.0,
            link_damping: 0.05,
            air_viscosity: 0.0,
            friction: 0.3,
            fixed: false,
            self_contact: false,
            integrator: None,
            subdivision: None,
            cutting: None,
            plasticity: None,
            tearing: None,
        }
    }
}

/// Most nodes, triangles and edges a body may reach: its own plus the room reserved for topology
/// changes (subdivision pool, cutting pool). Every per-node, per-triangle and per-edge buffer of the
/// body and of its solvers holds this much, so changes within the limits allocate nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Limits {
    /// Nodes.
    pub nodes: usize,
    /// Triangles.
    pub triangles: usize,
    /// Edge springs.
    pub edges: usize,
}

/// Surface nodes, structure of arrays. Index `i` is node `i` in every array.
#[derive(Clone, Debug)]
pub struct Surface {
    /// Node positions at the start of the current step (m, world frame).
    pub position_in_world: Vec<Vec3>,
    /// Node positions at the end of the step being computed (m, world frame); swapped with
    /// `position_in_world` when the step is done, so a step keeps both ends of every trajectory.
    pub next_position_in_world: Vec<Vec3>,
    /// Node velocities (m/s, world frame).
    pub velocity_in_world: Vec<Vec3>,
    /// Force accumulated on each node during the step (N, world frame).
    pub force_in_world: Vec<Vec3>,
    /// Node masses (kg).
    pub mass: Vec<f64>,
    /// Inverse node masses (1/kg).
    pub inverse_mass: Vec<f64>,
    /// Air viscosity coefficient of each node (N·s/m): ν mᵢ.
    pub air_damping: Vec<f64>,
    /// Homologue of each node on the rigid component (m, body frame).
    pub homologue_in_body: Vec<Vec3>,
    /// Homologue positions this step (m, world frame); scratch refreshed by the force stage.
    pub homologue_in_world: Vec<Vec3>,
    /// How far plastic flow has moved each homologue from its original place (m, body frame); zero
    /// unless the body has plasticity (`homologue_in_body` already includes it).
    pub plastic_offset_in_body: Vec<Vec3>,
    /// Link stiffness of each node (N/m).
    pub link_stiffness: Vec<f64>,
    /// Link damping of each node (N·s/m).
    pub link_damping: Vec<f64>,
    /// Triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Which tool holds each node, if any (the contact zone).
    pub tool_contact: Vec<ToolContact>,
    /// Diagonal of each node's stiffness: its link plus its edges (N/m). Kept up to date by
    /// [`Body::refresh_diagonals`] when the topology changes.
    pub stiffness_diagonal: Vec<f64>,
    /// Diagonal of each node's damping: its link, its edges and the air (N·s/m).
    pub damping_diagonal: Vec<f64>,
}

/// The state of a node being added to a surface (topology changes), SI units, world frame.
#[derive(Clone, Copy, Debug)]
pub struct NewNode {
    /// m.
    pub position_in_world: Vec3,
    /// m.
    pub next_position_in_world: Vec3,
    /// m/s.
    pub velocity_in_world: Vec3,
    /// kg.
    pub mass: f64,
    /// m, body frame.
    pub homologue_in_body: Vec3,
    /// m.
    pub homologue_in_world: Vec3,
    /// m, body frame: the plastic set already in `homologue_in_body`.
    pub plastic_offset_in_body: Vec3,
    /// N/m.
    pub link_stiffness: f64,
    /// N·s/m.
    pub link_damping: f64,
}

/// Edge springs, structure of arrays. Index `e` is edge `e` in every array.
#[derive(Clone, Debug, Default)]
pub struct Edges {
    /// First node of each edge.
    pub a: Vec<u32>,
    /// Second node of each edge.
    pub b: Vec<u32>,
    /// Rest length (m).
    pub rest_length: Vec<f64>,
    /// Stiffness (N/m).
    pub stiffness: Vec<f64>,
    /// Damping (N·s/m).
    pub damping: Vec<f64>,
}

impl Edges {
    /// Number of edges.
    pub fn len(&self) -> usize {
        self.a.len()
    }

    /// True when there are no edges.
    pub fn is_empty(&self) -> bool {
        self.a.is_empty()
    }

    /// Appends an edge spring: ends, rest length (m), stiffness (N/m), damping (N·s/m).
    pub fn push(&mut self, a: u32, b: u32, rest_length: f64, stiffness: f64, damping: f64) {
        self.a.push(a);
        self.b.push(b);
        self.rest_length.push(rest_length);
        self.stiffness.push(stiffness);
        self.damping.push(damping);
    }

    /// Removes the last edge spring.
    pub fn pop(&mut self) {
        self.a.pop();
        self.b.pop();
        self.rest_length.pop();
        self.stiffness.pop();
        self.damping.pop();
    }

    /// Reserves room for `additional` more edges in every array.
    pub fn reserve(&mut self, additional: usize) {
        self.a.reserve(additional);
        self.b.reserve(additional);
        self.rest_length.reserve(additional);
        self.stiffness.reserve(additional);
        self.damping.reserve(additional);
    }
}

impl Surface {
    /// Reserves room for `additional` more nodes in every per-node array.
    pub fn reserve_nodes(&mut self, additional: usize) {
        self.position_in_world.reserve(additional);
        self.next_position_in_world.reserve(additional);
        self.velocity_in_world.reserve(additional);
        self.force_in_world.reserve(additional);
        self.mass.reserve(additional);
        self.inverse_mass.reserve(additional);
        self.air_damping.reserve(additional);
        self.homologue_in_body.reserve(additional);
        self.homologue_in_world.reserve(additional);
        self.plastic_offset_in_body.reserve(additional);
        self.link_stiffness.reserve(additional);
        self.link_damping.reserve(additional);
        self.tool_contact.reserve(additional);
        self.stiffness_diagonal.reserve(additional);
        self.damping_diagonal.reserve(additional);
    }

    /// Appends a node to every per-node array: no force, not in contact, air damping ν m, diagonals
    /// to be refreshed by [`Body::refresh_diagonals`].
    pub fn push_node(&mut self, node: NewNode, air_viscosity: f64) {
        self.position_in_world.push(node.position_in_world);
        self.next_position_in_world
            .push(node.next_position_in_world);
        self.velocity_in_world.push(node.velocity_in_world);
        self.force_in_world.push(Vec3::zeros());
        self.mass.push(node.mass);
        self.inverse_mass.push(1.0 / node.mass);
        self.air_damping.push(air_viscosity * node.mass);
        self.homologue_in_body.push(node.homologue_in_body);
        self.homologue_in_world.push(node.homologue_in_world);
        self.plastic_offset_in_body
            .push(node.plastic_offset_in_body);
        self.link_stiffness.push(node.link_stiffness);
        self.link_damping.push(node.link_damping);
        self.tool_contact.push(ToolContact::default());
        self.stiffness_diagonal.push(0.0);
        self.damping_diagonal.push(0.0);
    }

    /// Removes the last node from every per-node array (its triangles and edges are the caller's).
    pub fn pop_node(&mut self) {
        self.position_in_world.pop();
        self.next_position_in_world.pop();
        self.velocity_in_world.pop();
        self.force_in_world.pop();
        self.mass.pop();
        self.inverse_mass.pop();
        self.air_damping.pop();
        self.homologue_in_body.pop();
        self.homologue_in_world.pop();
        self.plastic_offset_in_body.pop();
        self.link_stiffness.pop();
        self.link_damping.pop();
        self.tool_contact.pop();
        self.stiffness_diagonal.pop();
        self.damping_diagonal.pop();
    }
}

/// One deformable body.
#[derive(Clone, Debug)]
pub struct Body {
    /// Name from the scene.
    pub name: String,
    /// The surface component.
    pub surface: Surface,
    /// The edge springs.
    pub edges: Edges,
    /// The virtual rigid component.
    pub rigid: RigidComponent,
    /// Parameters the body was built from.
    pub params: BodyParams,
    /// Counts changes of the surface's topology (subdivisions and coarsenings), so that whoever
    /// mirrors the mesh knows when to send it whole again.
    pub topology_version: u64,
    /// Surface edges used by exactly one triangle (the lips of cuts, a mesh's own border).
    pub boundary_edges: u32,
    /// How far the mesh may grow (see [`Limits`]); set by [`Body::reserve_room`].
    pub limits: Limits,
}

/// Initial placement of a body in the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Where the body frame's origin (centre of mass of the surface) is (m, world frame).
    pub position_in_world: Vec3,
    /// world_from_body rotation.
    pub world_from_body: UnitQuaternion<f64>,
    /// Initial linear velocity (m/s, world frame), of both components.
    pub velocity_in_world: Vec3,
    /// Initial angular velocity (rad/s, world frame), of both components.
    pub angular_velocity_in_world: Vec3,
}

impl Default for Placement {
    fn default() -> Self {
        Self {
            position_in_world: Vec3::zeros(),
            world_from_body: UnitQuaternion::identity(),
            velocity_in_world: Vec3::zeros(),
            angular_velocity_in_world: Vec3::zeros(),
        }
    }
}

impl Body {
    /// Builds a body from a mesh already in its body frame (see [`SurfaceMesh::validate`] and
    /// [`SurfaceMesh::recentre_on_surface_centre`], which scenes apply; this constructor checks
    /// nothing so tests can build odd bodies such as a single node).
    ///
    /// Surface mass is spread by area (evenly when the mesh has no area); every edge gets the body's
    /// stiffness and damping and its current length as rest length; every node a link to a homologue
    /// at its own body-frame position. The rigid component's inertia is that of the solid the mesh
    /// encloses with the rigid mass spread uniformly (a point mass's isotropic fallback when the mesh
    /// encloses no volume).
    pub fn new(name: &str, mesh: &SurfaceMesh, params: &BodyParams, placement: &Placement) -> Self {
        let n = mesh.vertex_count();
        let areas = mesh.vertex_areas();
        let total_area: f64 = areas.iter().sum();
        let mass: Vec<f64> = if total_area > 0.0 {
            areas
                .iter()
                .map(|a| params.surface_mass * a / total_area)
                .collect()
        } else {
            vec![params.surface_mass / n as f64; n]
        };
        let inverse_mass = mass.iter().map(|m| 1.0 / m).collect();
        let air_damping = mass.iter().map(|m| params.air_viscosity * m).collect();

        let rotation = placement.world_from_body;
        let omega = placement.angular_velocity_in_world;
        let position_in_world: Vec<Vec3> = mesh
            .positions_in_body
            .iter()
            .map(|r| placement.position_in_world + rotation * r)
            .collect();
        let velocity_in_world = position_in_world
            .iter()
            .map(|x| placement.velocity_in_world + omega.cross(&(x - placement.position_in_world)))
            .collect();

        let mut edges = Edges::default();
        // A prestressed body's springs are shorter at rest than the mesh: the surface is in tension.
        let rest_scale = 1.0 - params.cutting.map_or(0.0, |c| c.prestress);
        for [a, b] in mesh.edges() {
            let rest = rest_scale
                * (mesh.positions_in_body[b as usize] - mesh.positions_in_body[a as usize]).norm();
            edges.push(a, b, rest, params.surface_stiffness, params.surface_damping);
        }

        let inertia_in_body = if mesh.triangles.is_empty() || mesh.signed_volume() <= 0.0 {
            nalgebra::Matrix3::identity() * params.rigid_mass
        } else {
            mesh.solid_inertia_about_origin(params.rigid_mass)
        };
        let rigid = RigidComponent::new(
            params.rigid_mass,
            inertia_in_body,
            placement,
            params.air_viscosity,
            params.fixed,
        );

        let surface = Surface {
            next_position_in_world: position_in_world.clone(),
            homologue_in_world: position_in_world.clone(),
            position_in_world,
            velocity_in_world,
            force_in_world: vec![Vec3::zeros(); n],
            mass,
            inverse_mass,
            air_damping,
            homologue_in_body: mesh.positions_in_body.clone(),
            plastic_offset_in_body: vec![Vec3::zeros(); n],
            link_stiffness: vec![params.link_stiffness; n],
            link_damping: vec![params.link_damping; n],
            triangles: mesh.triangles.clone(),
            tool_contact: vec![ToolContact::default(); n],
            stiffness_diagonal: Vec::new(),
            damping_diagonal: Vec::new(),
        };
        let mut body = Self {
            name: name.to_string(),
            surface,
            edges,
            rigid,
            params: params.clone(),
            topology_version: 0,
            boundary_edges: count_boundary_edges(&mesh.triangles),
            // No room reserved yet: the mesh may grow, allocating (tests, tools); a world reserves.
            limits: Limits {
                nodes: usize::MAX,
                triangles: usize::MAX,
                edges: usize::MAX,
            },
        };
        body.refresh_diagonals();
        body
    }

    /// Nodes of room the body's topology changes may use: the subdivision pool and the cutting pool.
    pub fn room_nodes(&self) -> usize {
        let subdivision = if self.params.subdivision.is_some() {
            POOL_NODES
        } else {
            0
        };
        subdivision + self.params.topology_cutter().map_or(0, |c| c.max_nodes)
    }

    /// Reserves the room of [`Body::room_nodes`] in every buffer (2 triangles and 3 edges per node)
    /// and sets [`Body::limits`] to it.
    pub fn reserve_room(&mut self) {
        self.reserve_room_of(self.room_nodes());
    }

    /// Reserves room for `room` more nodes (2 triangles and 3 edges per node) and sets the limits.
    pub fn reserve_room_of(&mut self, room: usize) {
        let n = self.node_count();
        let t = self.surface.triangles.len();
        let e = self.edges.len();
        let limits = Limits {
            nodes: n + room,
            triangles: t + 2 * room,
            edges: e + 3 * room,
        };
        self.surface.reserve_nodes(limits.nodes - n);
        self.surface.triangles.reserve(limits.triangles - t);
        self.edges.reserve(limits.edges - e);
        self.limits = limits;
    }

    /// Whether the mesh can take `nodes`, `triangles` and `edges` more within its limits.
    pub fn has_room(&self, nodes: usize, triangles: usize, edges: usize) -> bool {
        self.node_count() + nodes <= self.limits.nodes
            && self.surface.triangles.len() + triangles <= self.limits.triangles
            && self.edges.len() + edges <= self.limits.edges
    }

    /// Most nodes and triangles the body can have: its own, plus the subdivision and cutting pools.
    pub fn mesh_capacity(&self) -> (usize, usize) {
        let room = self.room_nodes();
        if self.limits.nodes == usize::MAX {
            (
                self.node_count() + room,
                self.surface.triangles.len() + 2 * room,
            )
        } else {
            (self.limits.nodes, self.limits.triangles)
        }
    }

    /// Lumped rest area of every node: a third of each triangle around it, from the homologues (m²).
    pub fn lumped_rest_areas(&self) -> Vec<f64> {
        let s = &self.surface;
        let mut areas = vec![0.0; s.homologue_in_body.len()];
        for t in &s.triangles {
            let [a, b, c] = t.map(|v| s.homologue_in_body[v as usize]);
            let area = 0.5 * (b - a).cross(&(c - a)).norm();
            for v in t {
                areas[*v as usize] += area / 3.0;
            }
        }
        areas
    }

    /// Gives every node a link of `stiffness` (N/m³) and `damping` (N·s/m³) per unit of its lumped
    /// rest area, so that the elastic foundation does not depend on the mesh. Call
    /// [`World::reassemble`](crate::world::World::reassemble) afterwards on a body already in a world.
    pub fn set_links_per_area(&mut self, stiffness: f64, damping: f64) {
        let areas = self.lumped_rest_areas();
        let s = &mut self.surface;
        for (i, a) in areas.iter().enumerate() {
            s.link_stiffness[i] = stiffness * a;
            s.link_damping[i] = damping * a;
        }
        self.refresh_diagonals();
    }

    /// Recomputes [`Surface::stiffness_diagonal`] and [`Surface::damping_diagonal`] (allocation-free
    /// within their capacity).
    pub fn refresh_diagonals(&mut self) {
        let s = &mut self.surface;
        s.stiffness_diagonal.clear();
        s.stiffness_diagonal.extend_from_slice(&s.link_stiffness);
        s.damping_diagonal.clear();
        s.damping_diagonal.extend(
            s.link_damping
                .iter()
                .zip(&s.air_damping)
                .map(|(c, g)| c + g),
        );
        let e = &self.edges;
        for k in 0..e.len() {
            for node in [e.a[k] as usize, e.b[k] as usize] {
                s.stiffness_diagonal[node] += e.stiffness[k];
                s.damping_diagonal[node] += e.damping[k];
            }
        }
    }

    /// Number of surface nodes.
    pub fn node_count(&self) -> usize {
        self.surface.position_in_world.len()
    }

    /// Total surface mass (kg).
    pub fn surface_mass(&self) -> f64 {
        self.surface.mass.iter().sum()
    }

    /// Surface mass plus rigid mass (kg).
    pub fn total_mass(&self) -> f64 {
        self.surface_mass() + self.rigid.mass
    }

    /// Centre of mass of the surface nodes (m, world frame).
    pub fn surface_centre_of_mass(&self) -> Vec3 {
        let s = &self.surface;
        let mut sum = Vec3::zeros();
        for (x, m) in s.position_in_world.iter().zip(&s.mass) {
            sum += x * *m;
        }
        sum / self.surface_mass()
    }

    /// Velocity of the surface centre of mass (m/s, world frame).
    pub fn surface_centre_of_mass_velocity(&self) -> Vec3 {
        let s = &self.surface;
        let mut sum = Vec3::zeros();
        for (v, m) in s.velocity_in_world.iter().zip(&s.mass) {
            sum += v * *m;
        }
        sum / self.surface_mass()
    }

    /// Kinetic energy of the surface nodes plus the rigid component (J).
    pub fn kinetic_energy(&self) -> f64 {
        let s = &self.surface;
        let nodes: f64 = s
            .velocity_in_world
            .iter()
            .zip(&s.mass)
            .map(|(v, m)| 0.5 * m * v.norm_squared())
            .sum();
        nodes + self.rigid.kinetic_energy()
    }

    /// True when every position and velocity of the body is finite.
    pub fn is_finite(&self) -> bool {
        let s = &self.surface;
        s.position_in_world
            .iter()
            .chain(&s.velocity_in_world)
            .all(|v| v.iter().all(|x| x.is_finite()))
            && self.rigid.is_finite()
    }
}

/// Surface edges used by exactly one triangle (a full count, for checks; the body keeps its own).
pub fn count_boundary_edges(triangles: &[[u32; 3]]) -> u32 {
    let mut keys: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    keys.sort_unstable();
    let mut count = 0;
    let mut k = 0;
    while k < keys.len() {
        let mut j = k + 1;
        while j < keys.len() && keys[j] == keys[k] {
            j += 1;
        }
        if j - k == 1 {
            count += 1;
        }
        k = j;
    }
    count
}
