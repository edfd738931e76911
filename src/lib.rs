//! # palpa — the deformable-organ model of a haptic-loop server
//!
//! A body (an organ) is a triangle surface of point masses joined by damped edge springs, tied node by
//! node through zero-rest-length damped links to a *virtual rigid component* that never collides and
//! gives the body its rigid motion and its rest shape (Meseure & Chaillou 1997; see
//! `../shared/design/MODEL.md`). The world steps every body with the paper's semi-implicit Euler at
//! Δt = 1 ms, with contact and Coulomb friction against fixed obstacles.
//!
//! Map of the modules, in the order data flows through a step:
//! - [`scene`]: TOML scene files, meshes (primitives, OBJ), validation with file:line:column errors.
//! - [`body`]: the surface (structure of arrays), edge springs, links, rigid component.
//! - [`dynamics`]: forces, integration, stability analysis.
//! - [`tool`]: rigid tools (probe, instrument, grasper, blade) and their scripted or external poses.
//! - [`collision`]: obstacle geometry, continuous detection against tools.
//! - [`contact`]: node–obstacle and node–tool contact with Coulomb friction; force feedback.
//! - [`world`]: the [`World`](world::World) and its step as a list of stages.
//! - [`topology`]: adaptive subdivision with the paper's mass rule, and coarsening.
//! - [`math`]: the transcendental functions of the physics from `libm` (the same bits on every machine).
//! - [`trace`]: the CSV trace of a run.
//! - [`daemon`]: input hygiene and loop statistics of the 1 kHz daemon.
//! - [`device`]: the simulated haptic device (model and loop).
//! - [`display`]: mesh keyframes and deltas for renderers, and the client that rebuilds them.
//! - [`ipc`]: the shared-memory payloads (`proto/palpa_ipc.h`) and, with the `ipc` feature, services.
//! - `report` (feature `cli`): the plots, progress bar and figures the bench and report tools share.
//!
//! ```
//! use palpa::{World, scene::default_scene};
//!
//! // The embedded default scene: a soft organ dropped onto a table.
//! let mut world = World::from_scene(&default_scene());
//! for _ in 0..100 {
//!     world.step(); // 1 ms each, no allocation
//! }
//! let organ = &world.bodies[0];
//! assert!(organ.is_finite());
//! assert!(world.min_obstacle_gap(organ).unwrap() >= 0.0); // never below the table
//! ```
#![warn(missing_docs)]

pub mod body;
pub mod collision;
pub mod contact;
pub mod daemon;
pub mod device;
pub mod display;
pub mod dynamics;
pub mod ipc;
pub mod math;
#[cfg(feature = "record")]
pub mod record;
#[cfg(feature = "cli")]
pub mod report;
pub mod scene;
pub mod tool;
pub mod topology;
pub mod trace;
pub mod world;

/// A 3-vector of f64 (SI units; the frame is in the name of whatever holds it).
pub type Vec3 = nalgebra::Vector3<f64>;

pub use body::{Body, BodyParams, Placement};
pub use scene::{Scene, SceneError, load_scene, parse_scene};
pub use world::World;

/// A list whose room is part of its meaning: the tick's code reads a full list (its length at its
/// capacity) as its limit, so a copy must keep the room, which a `Vec`'s derived `Clone` does not.
/// Derefs to the `Vec`.
#[derive(Debug, Default, PartialEq)]
pub struct Room<T>(Vec<T>);

impl<'a, T> IntoIterator for &'a Room<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

impl<'a, T> IntoIterator for &'a mut Room<T> {
    type Item = &'a mut T;
    type IntoIter = std::slice::IterMut<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter_mut()
    }
}

impl<T> Room<T> {
    /// An empty list with room for `capacity` items.
    pub fn with_capacity(capacity: usize) -> Self {
        Self(Vec::with_capacity(capacity))
    }
}

impl<T: Clone> Clone for Room<T> {
    /// A copy with the same room reserved (a world cloned with bare copies would drop what its
    /// lists no longer hold).
    fn clone(&self) -> Self {
        let mut copy = Vec::with_capacity(self.0.capacity());
        copy.extend_from_slice(&self.0);
        Self(copy)
    }
}

impl<T> std::ops::Deref for Room<T> {
    type Target = Vec<T>;
    fn deref(&self) -> &Vec<T> {
        &self.0
    }
}

impl<T> std::ops::DerefMut for Room<T> {
    fn deref_mut(&mut self) -> &mut Vec<T> {
        &mut self.0
    }
}
