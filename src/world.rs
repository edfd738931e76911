//! The world: owns the bodies and obstacles, and steps them as an explicit list of stages.
//!
//! Only what the scene needs runs: [`Systems`] is decided once from the scene (no obstacle contact
//! without obstacles, no rigid integration for fixed bodies...), and the step calls only those stages.
//! One step is, for every body in scene order:
//! forces → node integration (semi-implicit Euler, end positions kept apart) → obstacle contact and
//! friction on the node trajectories → commit positions → rigid component integration.

use crate::Vec3;
use crate::body::Body;
use crate::collision::obstacle::Obstacle;
use crate::contact::obstacle::resolve_nodes_against_obstacles;
use crate::dynamics::forces::accumulate_body_forces;
use crate::dynamics::integrate::{commit_positions, integrate_nodes_symplectic};
use crate::dynamics::stability::{StabilityMargin, symplectic_margin};
use crate::scene::{Scene, WorldParams};

/// Which systems the scene switches on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Systems {
    /// Non-zero gravity.
    pub gravity: bool,
    /// Some body has air viscosity.
    pub air_viscosity: bool,
    /// There are obstacles: node–obstacle contact runs.
    pub obstacle_contact: bool,
    /// Some obstacle has a non-zero friction coefficient.
    pub obstacle_friction: bool,
    /// Some body's rigid component is free to move.
    pub rigid_motion: bool,
}

impl Systems {
    /// Names of the systems that are on, in a fixed order (always-on parts of the model first).
    pub fn names(&self) -> Vec<&'static str> {
        let mut names = vec!["surface_springs", "links"];
        for (on, name) in [
            (self.rigid_motion, "rigid_components"),
            (self.gravity, "gravity"),
            (self.air_viscosity, "air_viscosity"),
            (self.obstacle_contact, "obstacle_contact"),
            (self.obstacle_friction, "obstacle_friction"),
        ] {
            if on {
                names.push(name);
            }
        }
        names
    }
}

/// Counters of the last step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepCounters {
    /// Node–obstacle contacts resolved.
    pub obstacle_contacts: usize,
}

/// Everything simulated, and the step.
#[derive(Clone, Debug)]
pub struct World {
    /// Gravity, time step, defaults.
    pub params: WorldParams,
    /// Deformable bodies, in scene order.
    pub bodies: Vec<Body>,
    /// Fixed obstacles, in scene order.
    pub obstacles: Vec<Obstacle>,
    /// Number of steps taken; simulated time is `tick × dt`.
    pub tick: u64,
    /// Counters of the last step.
    pub counters: StepCounters,
    systems: Systems,
}

impl World {
    /// An empty world.
    pub fn new(params: WorldParams) -> Self {
        let mut world = Self {
            params,
            bodies: Vec::new(),
            obstacles: Vec::new(),
            tick: 0,
            counters: StepCounters::default(),
            systems: Systems::default(),
        };
        world.assemble();
        world
    }

    /// Builds the world a scene describes.
    pub fn from_scene(scene: &Scene) -> Self {
        let mut world = Self::new(scene.world.clone());
        for spec in &scene.bodies {
            world.bodies.push(Body::new(
                &spec.name,
                &spec.mesh,
                &spec.params,
                &spec.placement,
            ));
        }
        world.obstacles = scene.obstacles.clone();
        world.assemble();
        world
    }

    /// Adds a body (and re-decides which systems run).
    pub fn add_body(&mut self, body: Body) {
        self.bodies.push(body);
        self.assemble();
    }

    /// Adds an obstacle (and re-decides which systems run).
    pub fn add_obstacle(&mut self, obstacle: Obstacle) {
        self.obstacles.push(obstacle);
        self.assemble();
    }

    /// Decides which systems run from what the world holds.
    fn assemble(&mut self) {
        self.systems = Systems {
            gravity: self.params.gravity != Vec3::zeros(),
            air_viscosity: self.bodies.iter().any(|b| b.params.air_viscosity > 0.0),
            obstacle_contact: !self.obstacles.is_empty() && !self.bodies.is_empty(),
            obstacle_friction: self
                .obstacles
                .iter()
                .any(|o| o.friction > 0.0 || o.static_friction > 0.0),
            rigid_motion: self.bodies.iter().any(|b| !b.rigid.fixed),
        };
    }

    /// The systems this world runs.
    pub fn systems(&self) -> Systems {
        self.systems
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.tick as f64 * self.params.dt
    }

    /// Advances the world by one time step. Allocates nothing.
    pub fn step(&mut self) {
        let dt = self.params.dt;
        let gravity = self.params.gravity;
        let mut counters = StepCounters::default();
        for body in &mut self.bodies {
            accumulate_body_forces(body, &gravity);
            integrate_nodes_symplectic(&mut body.surface, dt);
            if self.systems.obstacle_contact {
                counters.obstacle_contacts +=
                    resolve_nodes_against_obstacles(&mut body.surface, &self.obstacles, dt);
            }
            commit_positions(&mut body.surface);
            body.rigid.integrate(dt);
        }
        self.counters = counters;
        self.tick += 1;
    }

    /// Smallest signed distance of any node of `body` to any obstacle (m); `None` without obstacles.
    pub fn min_obstacle_gap(&self, body: &Body) -> Option<f64> {
        if self.obstacles.is_empty() {
            return None;
        }
        let mut gap = f64::INFINITY;
        for x in &body.surface.position_in_world {
            for o in &self.obstacles {
                gap = gap.min(o.shape.signed_distance(x));
            }
        }
        Some(gap)
    }

    /// Stability margin of each body under the paper's scheme at this world's step.
    pub fn stability_margins(&self) -> Vec<StabilityMargin> {
        self.bodies
            .iter()
            .map(|b| symplectic_margin(b, self.params.dt))
            .collect()
    }
}
