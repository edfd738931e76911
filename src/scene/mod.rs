//! Scene files: TOML, SI units, every key documented in the README.
//!
//! Text enters through [`load_scene`] (a path) or [`parse_scene`] (text plus the name and directory to
//! report and resolve against) and leaves as a validated [`Scene`]: meshes built, checked and placed in
//! their body frames, parameters resolved with their defaults. Anything wrong — TOML syntax, unknown
//! keys, wrong types, impossible values, bad meshes — is a [`SceneError`] naming the file, line and
//! column and what was expected.

pub mod mesh;
mod schema;

use std::ops::Range;
use std::path::{Path, PathBuf};

use nalgebra::{Quaternion, UnitQuaternion};
use toml::Spanned;

use crate::Vec3;
use crate::body::{BodyParams, Placement};
use crate::collision::obstacle::{Obstacle, ObstacleShape};
use crate::dynamics::Integrator;
use crate::dynamics::attachment::{AttachmentSpec, Tie, WORLD};
use crate::tool::{GraspSettings, Keyframe, ToolInput, ToolPose, ToolShape};
use mesh::SurfaceMesh;
use schema::*;

/// The scene a new user gets when they give none: an organ-like body dropped onto a table.
pub const DEFAULT_SCENE: &str = include_str!("../../scenes/organ.toml");

/// The laparoscopy scene (issue 15), compiled in so that `palpa demo --scene laparoscopy` runs
/// anywhere.
pub const LAPAROSCOPY_SCENE: &str = include_str!("../../scenes/laparoscopy.toml");

/// Scenes compiled in, by the name the commands accept in place of a file: `organ` (the default
/// scene) and `laparoscopy`.
pub const BUILT_IN_SCENES: [(&str, &str); 2] =
    [("organ", DEFAULT_SCENE), ("laparoscopy", LAPAROSCOPY_SCENE)];

/// The built-in scene of that name, parsed (`None` when there is none).
pub fn built_in_scene(name: &str) -> Option<Result<Scene, SceneError>> {
    BUILT_IN_SCENES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(n, text)| parse_scene(text, &format!("<{n} scene>"), Path::new(".")))
}

/// Most vertices the meshes of one scene may have together: far past what can be stepped in 1 ms,
/// and a bound on the memory a short scene file can ask for (a few lines of bodies with 7
/// subdivisions each would otherwise allocate without limit).
pub const MAX_SCENE_VERTICES: usize = 1 << 20;

/// Largest √(k/m)·Δt and (c/m)·Δt an attachment's ties may give a node they pull: their forces are
/// explicit, and the scheme is stable with a wide margin below this.
pub const ATTACHMENT_STEP_LIMIT: f64 = 0.5;

/// Parameters of the world.
#[derive(Clone, Debug, PartialEq)]
pub struct WorldParams {
    /// Gravity (m/s², world frame).
    pub gravity: Vec3,
    /// Time step (s).
    pub dt: f64,
    /// Default air viscosity per unit mass of the bodies (1/s).
    pub air_viscosity: f64,
    /// Default integrator of the bodies.
    pub integrator: Integrator,
    /// Let a second thread run half of the force passes of each body of
    /// [`crate::dynamics::kernel::SPLIT_NODES`] nodes or more (the result bits are the same either
    /// way; see [`crate::dynamics::helper`]).
    pub helper_thread: bool,
    /// Tools meet the triangles of a body between its nodes, not only its nodes
    /// ([`crate::contact::tool_faces`]; bodies that refine at contact answer with new nodes).
    pub face_contact: bool,
}

impl Default for WorldParams {
    fn default() -> Self {
        Self {
            gravity: Vec3::new(0.0, 0.0, -9.81),
            dt: 0.001,
            air_viscosity: 0.0,
            integrator: Integrator::default(),
            helper_thread: true,
            face_contact: true,
        }
    }
}

/// A body as the scene describes it, ready to be built.
#[derive(Clone, Debug)]
pub struct BodySpec {
    /// Unique name.
    pub name: String,
    /// Validated surface in the body frame, centred on the surface centre of mass.
    pub mesh: SurfaceMesh,
    /// Where it starts and how it moves.
    pub placement: Placement,
    /// Mechanical parameters.
    pub params: BodyParams,
    /// A short description of the mesh source, for summaries.
    pub mesh_source: String,
}

/// A tool as the scene describes it.
#[derive(Clone, Debug)]
pub struct ToolSpec {
    /// Unique name (letters, digits, `_`, `-`).
    pub name: String,
    /// Geometry.
    pub shape: ToolShape,
    /// Pose source.
    pub input: ToolInput,
    /// Device force limit (N).
    pub max_force: Option<f64>,
    /// How a grasper grasps (`None` for other shapes).
    pub grasp: Option<GraspSettings>,
}

/// A validated scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Name used in messages: the file path, or `<default scene>`.
    pub name: String,
    /// The TOML text as read.
    pub source: String,
    /// World parameters.
    pub world: WorldParams,
    /// Bodies, in file order.
    pub bodies: Vec<BodySpec>,
    /// Obstacles, in file order.
    pub obstacles: Vec<Obstacle>,
    /// Tools, in file order.
    pub tools: Vec<ToolSpec>,
    /// Attachments (ligaments), in file order, their ties resolved.
    pub attachments: Vec<AttachmentSpec>,
    /// Files the scene loaded (meshes), in load order: the path as written in the scene (relative to
    /// the scene file) and where it was found.
    pub asset_names: Vec<(String, PathBuf)>,
}

/// A scene that cannot be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: cannot read the scene file: {source}")]
    Io {
        /// The path as given.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Something at a place in the file is wrong.
    #[error("{path}:{line}:{column}: {message}")]
    At {
        /// The file (or `<default scene>`).
        path: String,
        /// 1-based line.
        line: usize,
        /// 1-based column (characters).
        column: usize,
        /// What is wrong and what was expected.
        message: String,
    },
}

/// Reads and validates a scene file; meshes are resolved relative to its directory.
pub fn load_scene(path: &Path) -> Result<Scene, SceneError> {
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: path.display().to_string(),
        source,
    })?;
    // Text that is not UTF-8 is named at its first bad byte, as any other error.
    let text = String::from_utf8(bytes).map_err(|e| {
        let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        // (The bytes before it are UTF-8.)
        let before = std::str::from_utf8(valid).unwrap_or_default();
        let line_start = before.rfind('\n').map_or(0, |k| k + 1);
        SceneError::At {
            path: path.display().to_string(),
            line: before.matches('\n').count() + 1,
            column: before[line_start..].chars().count() + 1,
            message: format!(
                "byte {} (0x{:02x}) is not UTF-8 text: a scene file is UTF-8 TOML",
                valid.len(),
                e.as_bytes()[valid.len()]
            ),
        }
    })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    parse_scene(&text, &path.display().to_string(), dir)
}

/// The embedded default scene.
pub fn default_scene() -> Scene {
    parse_scene(DEFAULT_SCENE, "<default scene>", Path::new("."))
        .expect("the embedded default scene is valid (tested)")
}

/// Validates scene text; `name` is used in messages, `dir` resolves relative mesh paths.
pub fn parse_scene(text: &str, name: &str, dir: &Path) -> Result<Scene, SceneError> {
    let ctx = Ctx { text, name };
    let file: SceneFile = toml::from_str(text).map_err(|e| toml_error(&ctx, &e))?;

    let world_defaults = WorldParams::default();
    let world = match &file.world {
        None => world_defaults,
        Some(w) => WorldParams {
            gravity: ctx.vector(w.gravity.as_ref(), world_defaults.gravity, "gravity")?,
            dt: ctx.number(w.dt.as_ref(), world_defaults.dt, "dt", Rule::Positive)?,
            air_viscosity: ctx.number(
                w.air_viscosity.as_ref(),
                world_defaults.air_viscosity,
                "air_viscosity",
                Rule::NonNegative,
            )?,
            integrator: ctx.integrator(w.integrator.as_ref(), world_defaults.integrator)?,
            helper_thread: w
                .helper_thread
                .as_ref()
                .map_or(world_defaults.helper_thread, |v| *v.get_ref()),
            face_contact: w
                .face_contact
                .as_ref()
                .map_or(world_defaults.face_contact, |v| *v.get_ref()),
        },
    };
    if world.dt > 0.1 {
        let span = file
            .world
            .as_ref()
            .and_then(|w| w.dt.as_ref())
            .map_or(0..0, |s| s.span());
        return Err(ctx.error(
            span,
            format!("`dt` must be at most 0.1 s, found {}", world.dt),
        ));
    }

    let mut assets = Vec::new();
    let mut bodies: Vec<BodySpec> = Vec::with_capacity(file.body.len());
    let mut vertices = 0;
    for (index, body) in file.body.iter().enumerate() {
        let spec = ctx.body(body, index, &world, dir, &mut assets, &mut vertices)?;
        ctx.unique(
            bodies.iter().map(|b| &b.name),
            &spec.name,
            body,
            &body.get_ref().name,
            "body",
        )?;
        bodies.push(spec);
    }
    let mut obstacles: Vec<Obstacle> = Vec::with_capacity(file.obstacle.len());
    for (index, obstacle) in file.obstacle.iter().enumerate() {
        let o = ctx.obstacle(obstacle, index)?;
        let given = &obstacle.get_ref().name;
        ctx.unique(
            obstacles.iter().map(|b| &b.name),
            &o.name,
            obstacle,
            given,
            "obstacle",
        )?;
        obstacles.push(o);
    }
    let mut tools: Vec<ToolSpec> = Vec::with_capacity(file.tool.len());
    for (index, tool) in file.tool.iter().enumerate() {
        let t = ctx.tool(tool, index)?;
        ctx.unique(
            tools.iter().map(|o| &o.name),
            &t.name,
            tool,
            &tool.get_ref().name,
            "tool",
        )?;
        tools.push(t);
    }
    let mut attachments: Vec<AttachmentSpec> = Vec::with_capacity(file.attachment.len());
    for (index, attachment) in file.attachment.iter().enumerate() {
        let a = ctx.attachment(attachment, index, &bodies, world.dt)?;
        ctx.unique(
            attachments.iter().map(|a| &a.name),
            &a.name,
            attachment,
            &attachment.get_ref().name,
            "attachment",
        )?;
        attachments.push(a);
    }
    Ok(Scene {
        name: name.to_string(),
        source: text.to_string(),
        world,
        bodies,
        obstacles,
        tools,
        attachments,
        asset_names: assets,
    })
}

/// Reads a motion script file: a TOML document with one key, `script = [{ t, position, orientation,
/// jaw }, ...]`, in the format of a scene tool's `script` (used by `palpa-device --script`).
pub fn parse_script(text: &str, name: &str) -> Result<Vec<Keyframe>, SceneError> {
    let ctx = Ctx { text, name };
    let file: ScriptFile = toml::from_str(text).map_err(|e| toml_error(&ctx, &e))?;
    ctx.script(&file.script)
}

/// A TOML syntax or shape error at its place; toml's bare `duplicate key` gets the key's name (the
/// text its span covers).
fn toml_error(ctx: &Ctx, e: &toml::de::Error) -> SceneError {
    let span = e.span().unwrap_or(0..0);
    let mut message = e.message().trim_end().to_string();
    if message == "duplicate key"
        && let Some(key) = ctx.text.get(span.clone()).map(str::trim)
        && !key.is_empty()
        && key.len() <= 80
    {
        message = format!("duplicate key `{key}` (a key may be given once in a table)");
    }
    ctx.error(span, message)
}

/// What a number must satisfy.
#[derive(Clone, Copy)]
enum Rule {
    Positive,
    NonNegative,
}

struct Ctx<'a> {
    text: &'a str,
    name: &'a str,
}

impl Ctx<'_> {
    fn error(&self, span: Range<usize>, message: String) -> SceneError {
        let mut offset = span.start.min(self.text.len());
        while !self.text.is_char_boundary(offset) {
            offset -= 1;
        }
        let before = &self.text[..offset];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = self.text[line_start..offset].chars().count() + 1;
        SceneError::At {
            path: self.name.to_string(),
            line,
            column,
            message,
        }
    }

    fn number(
        &self,
        value: Option<&Spanned<f64>>,
        default: f64,
        key: &str,
        rule: Rule,
    ) -> Result<f64, SceneError> {
        let Some(v) = value else { return Ok(default) };
        let x = *v.get_ref();
        let (ok, expected) = match rule {
            Rule::Positive => (x.is_finite() && x > 0.0, "a finite number > 0"),
            Rule::NonNegative => (x.is_finite() && x >= 0.0, "a finite number ≥ 0"),
        };
        if ok {
            Ok(x)
        } else {
            Err(self.error(v.span(), format!("`{key}` must be {expected}, found {x}")))
        }
    }

    fn vector(
        &self,
        value: Option<&Spanned<[f64; 3]>>,
        default: Vec3,
        key: &str,
    ) -> Result<Vec3, SceneError> {
        let Some(v) = value else { return Ok(default) };
        let a = *v.get_ref();
        if a.iter().all(|x| x.is_finite()) {
            Ok(Vec3::from(a))
        } else {
            Err(self.error(
                v.span(),
                format!("`{key}` must be three finite numbers, found {a:?}"),
            ))
        }
    }

    fn positive_vector(&self, v: &Spanned<[f64; 3]>, key: &str) -> Result<Vec3, SceneError> {
        let a = *v.get_ref();
        if a.iter().all(|x| x.is_finite() && *x > 0.0) {
            Ok(Vec3::from(a))
        } else {
            Err(self.error(
                v.span(),
                format!("`{key}` must be three finite numbers > 0, found {a:?}"),
            ))
        }
    }

    fn orientation(
        &self,
        value: Option<&Spanned<[f64; 4]>>,
        key: &str,
    ) -> Result<UnitQuaternion<f64>, SceneError> {
        let Some(v) = value else {
            return Ok(UnitQuaternion::identity());
        };
        let [w, x, y, z] = *v.get_ref();
        let q = Quaternion::new(w, x, y, z);
        let norm = q.norm();
        if !norm.is_finite() || (norm - 1.0).abs() > 1e-3 {
            return Err(self.error(
                v.span(),
                format!("`{key}` must be a unit quaternion [w, x, y, z] (norm 1 within 1e-3), found norm {norm}"),
            ));
        }
        Ok(UnitQuaternion::from_quaternion(q))
    }

    fn integrator(
        &self,
        value: Option<&Spanned<String>>,
        default: Integrator,
    ) -> Result<Integrator, SceneError> {
        let Some(v) = value else { return Ok(default) };
        Integrator::from_name(v.get_ref()).ok_or_else(|| {
            self.error(
                v.span(),
                format!(
                    "`integrator` must be \"symplectic\", \"multirate\" or \"implicit\", found {:?}",
                    v.get_ref()
                ),
            )
        })
    }

    /// An error at the name (or the whole table) when `name` is already among `taken`.
    fn unique<'n, T>(
        &self,
        mut taken: impl Iterator<Item = &'n String>,
        name: &str,
        table: &Spanned<T>,
        given: &Option<Spanned<String>>,
        kind: &str,
    ) -> Result<(), SceneError> {
        if taken.any(|n| n == name) {
            let span = given.as_ref().map_or(table.span(), |n| n.span());
            return Err(self.error(span, format!("duplicate {kind} name `{name}`")));
        }
        Ok(())
    }

    fn subdivision(
        &self,
        section: &Spanned<SubdivisionSection>,
    ) -> Result<Option<crate::topology::SubdivisionSettings>, SceneError> {
        let s = section.get_ref();
        if s.enabled == Some(false) {
            return Ok(None);
        }
        let d = crate::topology::SubdivisionSettings::default();
        let rule = match &s.rule {
            None => d.rule,
            Some(r) => crate::topology::SpringRule::from_name(r.get_ref()).ok_or_else(|| {
                self.error(
                    r.span(),
                    format!(
                        "`rule` must be \"angle\", \"constant_kl\" or \"area\", found {:?}",
                        r.get_ref()
                    ),
                )
            })?,
        };
        let max_depth = match &s.max_depth {
            None => d.max_depth,
            Some(v) if (1..=8).contains(v.get_ref()) => *v.get_ref(),
            Some(v) => {
                return Err(self.error(
                    v.span(),
                    format!("`max_depth` must be 1 to 8, found {}", v.get_ref()),
                ));
            }
        };
        Ok(Some(crate::topology::SubdivisionSettings {
            rule,
            max_depth,
            min_edge: self.number(s.min_edge.as_ref(), d.min_edge, "min_edge", Rule::Positive)?,
            coarsen_after_s: self.number(
                s.coarsen_after.as_ref(),
                d.coarsen_after_s,
                "coarsen_after",
                Rule::NonNegative,
            )?,
            tolerance: self.number(
                s.tolerance.as_ref(),
                d.tolerance,
                "tolerance",
                Rule::Positive,
            )?,
            zone_edge: match &s.zone_edge {
                None => d.zone_edge,
                Some(v) => Some(self.number(Some(v), 0.0, "zone_edge", Rule::Positive)?),
            },
        }))
    }

    fn plasticity(
        &self,
        section: &Spanned<PlasticitySection>,
    ) -> Result<Option<crate::dynamics::plasticity::PlasticitySettings>, SceneError> {
        let s = section.get_ref();
        if s.enabled == Some(false) {
            return Ok(None);
        }
        let d = crate::dynamics::plasticity::PlasticitySettings::default();
        Ok(Some(crate::dynamics::plasticity::PlasticitySettings {
            yield_stretch: self.number(
                s.yield_.as_ref(),
                d.yield_stretch,
                "yield",
                Rule::NonNegative,
            )?,
            creep: self.number(s.creep.as_ref(), d.creep, "creep", Rule::NonNegative)?,
            max: self.number(s.max.as_ref(), d.max, "max", Rule::NonNegative)?,
        }))
    }

    fn tearing(
        &self,
        section: &Spanned<TearingSection>,
    ) -> Result<Option<crate::topology::TearingSettings>, SceneError> {
        let s = section.get_ref();
        if s.enabled == Some(false) {
            return Ok(None);
        }
        let d = crate::topology::TearingSettings::default();
        let whole = |value: &Option<Spanned<u32>>,
                     default: usize,
                     name: &str,
                     range: std::ops::RangeInclusive<u32>|
         -> Result<usize, SceneError> {
            match value {
                None => Ok(default),
                Some(v) if range.contains(v.get_ref()) => Ok(*v.get_ref() as usize),
                Some(v) => Err(self.error(
                    v.span(),
                    format!(
                        "`{name}` must be {} to {}, found {}",
                        range.start(),
                        range.end(),
                        v.get_ref()
                    ),
                )),
            }
        };
        Ok(Some(crate::topology::TearingSettings {
            strain: self.number(s.strain.as_ref(), d.strain, "strain", Rule::Positive)?,
            ticks: whole(&s.ticks, d.ticks as usize, "ticks", 1..=100_000)? as u32,
            max_per_tick: whole(&s.max_per_tick, d.max_per_tick, "max_per_tick", 1..=64)?,
            max_nodes: whole(&s.max_nodes, d.max_nodes, "max_nodes", 16..=1 << 16)?,
            max_pieces: whole(&s.max_pieces, d.max_pieces, "max_pieces", 0..=64)?,
        }))
    }

    fn cutting(
        &self,
        section: &Spanned<CuttingSection>,
    ) -> Result<Option<crate::topology::CuttingSettings>, SceneError> {
        let s = section.get_ref();
        if s.enabled == Some(false) {
            return Ok(None);
        }
        let d = crate::topology::CuttingSettings::default();
        let min_angle = self.number(
            s.min_angle.as_ref(),
            d.min_angle_deg,
            "min_angle",
            Rule::Positive,
        )?;
        if min_angle > 30.0 {
            let span = s.min_angle.as_ref().map_or(section.span(), |v| v.span());
            return Err(self.error(
                span,
                format!("`min_angle` must be at most 30 (degrees), found {min_angle}"),
            ));
        }
        let prestress = self.number(
            s.prestress.as_ref(),
            d.prestress,
            "prestress",
            Rule::NonNegative,
        )?;
        if prestress >= 0.5 {
            let span = s.prestress.as_ref().map_or(section.span(), |v| v.span());
            return Err(self.error(
                span,
                format!("`prestress` must be below 0.5 (a fraction of the rest length), found {prestress}"),
            ));
        }
        let max_nodes = match &s.max_nodes {
            None => d.max_nodes,
            Some(v) if (16..=1 << 16).contains(v.get_ref()) => *v.get_ref() as usize,
            Some(v) => {
                return Err(self.error(
                    v.span(),
                    format!("`max_nodes` must be 16 to 65536, found {}", v.get_ref()),
                ));
            }
        };
        let max_pieces = match &s.max_pieces {
            None => d.max_pieces,
            Some(v) if *v.get_ref() <= 64 => *v.get_ref() as usize,
            Some(v) => {
                return Err(self.error(
                    v.span(),
                    format!("`max_pieces` must be 0 to 64, found {}", v.get_ref()),
                ));
            }
        };
        Ok(Some(crate::topology::CuttingSettings {
            max_pieces,
            resistance: self.number(
                s.resistance.as_ref(),
                d.resistance,
                "resistance",
                Rule::NonNegative,
            )?,
            min_angle_deg: min_angle,
            prestress,
            max_nodes,
            tolerance: self.number(
                s.tolerance.as_ref(),
                d.tolerance,
                "tolerance",
                Rule::Positive,
            )?,
        }))
    }

    /// A name from the file, or the default; names appear in traces and service names, so they are
    /// kept to letters, digits, `_`, `-` and `.`.
    fn name(&self, value: Option<&Spanned<String>>, default: String) -> Result<String, SceneError> {
        let Some(v) = value else { return Ok(default) };
        let name = v.get_ref();
        if name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
        {
            return Err(self.error(
                v.span(),
                format!("`name` must be non-empty and use only letters, digits, `_`, `-` and `.`, found {name:?}"),
            ));
        }
        Ok(name.clone())
    }

    fn tool(&self, tool: &Spanned<ToolSection>, index: usize) -> Result<ToolSpec, SceneError> {
        let t = tool.get_ref();
        let name = self.name(t.name.as_ref(), format!("tool{index}"))?;
        let Some(shape_section) = &t.shape else {
            return Err(self.error(tool.span(), format!("tool `{name}` needs a `shape`")));
        };
        let s = shape_section.get_ref();
        let given = [
            s.sphere.is_some(),
            s.capsule.is_some(),
            s.grasper.is_some(),
            s.blade.is_some(),
        ];
        if given.iter().filter(|g| **g).count() != 1 {
            return Err(self.error(
                shape_section.span(),
                "`shape` must have exactly one of `sphere = { radius }`, `capsule = { radius, length }`, \
                 `grasper = { jaw_length, radius, shaft_length }` or `blade = { length, thickness }`"
                    .to_string(),
            ));
        }
        let positive = |v: &Spanned<f64>, key: &str| self.number(Some(v), 0.0, key, Rule::Positive);
        let mut grasp = None;
        let shape = if let Some(sphere) = &s.sphere {
            ToolShape::Sphere {
                radius: positive(&sphere.get_ref().radius, "radius")?,
            }
        } else if let Some(capsule) = &s.capsule {
            let c = capsule.get_ref();
            ToolShape::Capsule {
                radius: positive(&c.radius, "radius")?,
                length: positive(&c.length, "length")?,
            }
        } else if let Some(grasper) = &s.grasper {
            let g = grasper.get_ref();
            let defaults = GraspSettings::default();
            let grasp_below = self.number(
                g.grasp_below.as_ref(),
                defaults.grasp_below,
                "grasp_below",
                Rule::NonNegative,
            )?;
            let release_above = self.number(
                g.release_above.as_ref(),
                defaults.release_above,
                "release_above",
                Rule::Positive,
            )?;
            if release_above <= grasp_below {
                let span = g
                    .release_above
                    .as_ref()
                    .or(g.grasp_below.as_ref())
                    .map_or(grasper.span(), |v| v.span());
                return Err(self.error(
                    span,
                    format!(
                        "`release_above` ({release_above} rad) must be larger than `grasp_below` \
                         ({grasp_below} rad): the jaws let go only after opening past where they \
                         grasped"
                    ),
                ));
            }
            grasp = Some(GraspSettings {
                grasp_below,
                release_above,
                reach: self.number(g.reach.as_ref(), defaults.reach, "reach", Rule::NonNegative)?,
            });
            ToolShape::Grasper {
                jaw_length: positive(&g.jaw_length, "jaw_length")?,
                radius: positive(&g.radius, "radius")?,
                shaft_length: self.number(
                    g.shaft_length.as_ref(),
                    0.0,
                    "shaft_length",
                    Rule::NonNegative,
                )?,
            }
        } else {
            let b = s.blade.as_ref().expect("one shape was given").get_ref();
            ToolShape::Blade {
                length: positive(&b.length, "length")?,
                thickness: positive(&b.thickness, "thickness")?,
            }
        };
        let input_kind = t.input.as_ref().map(|i| (i.get_ref().as_str(), i.span()));
        let input = match (input_kind, &t.script) {
            (Some(("ipc", span)), Some(_)) => {
                return Err(self.error(span, "`input = \"ipc\"` takes no `script`".to_string()));
            }
            (Some(("ipc", _)), None) => ToolInput::Ipc,
            (None | Some(("script", _)), Some(script)) => ToolInput::Script(self.script(script)?),
            (Some(("script", _)), None) | (None, None) => {
                return Err(self.error(
                    tool.span(),
                    format!("tool `{name}` needs `input = \"ipc\"` or a `script`"),
                ));
            }
            (Some((other, span)), _) => {
                return Err(self.error(
                    span,
                    format!("`input` must be \"script\" or \"ipc\", found {other:?}"),
                ));
            }
        };
        let max_force = match &t.max_force {
            None => None,
            Some(v) => Some(self.number(Some(v), 0.0, "max_force", Rule::Positive)?),
        };
        Ok(ToolSpec {
            name,
            shape,
            input,
            max_force,
            grasp,
        })
    }

    fn script(
        &self,
        script: &Spanned<Vec<Spanned<KeyframeSection>>>,
    ) -> Result<Vec<Keyframe>, SceneError> {
        let keys = script.get_ref();
        if keys.is_empty() {
            return Err(self.error(
                script.span(),
                "`script` needs at least one keyframe".to_string(),
            ));
        }
        let mut out: Vec<Keyframe> = Vec::with_capacity(keys.len());
        for key in keys {
            let k = key.get_ref();
            let t = *k.t.get_ref();
            if !t.is_finite() {
                return Err(self.error(k.t.span(), format!("`t` must be a finite time, found {t}")));
            }
            if let Some(previous) = out.last()
                && t <= previous.t
            {
                return Err(self.error(
                    k.t.span(),
                    format!("keyframe times must increase: {t} follows {}", previous.t),
                ));
            }
            let jaw = match &k.jaw {
                None => out.last().map_or(0.0, |p| p.jaw),
                Some(v) => self.number(Some(v), 0.0, "jaw", Rule::NonNegative)?,
            };
            out.push(Keyframe {
                t,
                pose: ToolPose {
                    position_in_world: self.vector(Some(&k.position), Vec3::zeros(), "position")?,
                    world_from_tool: self.orientation(k.orientation.as_ref(), "orientation")?,
                },
                jaw,
            });
        }
        Ok(out)
    }

    fn body(
        &self,
        body: &Spanned<BodySection>,
        index: usize,
        world: &WorldParams,
        dir: &Path,
        assets: &mut Vec<(String, PathBuf)>,
        vertices: &mut usize,
    ) -> Result<BodySpec, SceneError> {
        let b = body.get_ref();
        let name = b
            .name
            .as_ref()
            .map_or_else(|| format!("body{index}"), |n| n.get_ref().clone());
        let Some(mesh_section) = &b.mesh else {
            return Err(self.error(body.span(), format!("body `{name}` needs a `mesh`")));
        };
        let (mesh, mesh_source) = self.mesh(mesh_section, dir, assets, vertices)?;
        let d = BodyParams::default();
        let params = BodyParams {
            surface_mass: self.number(
                b.surface_mass.as_ref(),
                d.surface_mass,
                "surface_mass",
                Rule::Positive,
            )?,
            rigid_mass: self.number(
                b.rigid_mass.as_ref(),
                d.rigid_mass,
                "rigid_mass",
                Rule::Positive,
            )?,
            surface_stiffness: self.number(
                b.surface_stiffness.as_ref(),
                d.surface_stiffness,
                "surface_stiffness",
                Rule::Positive,
            )?,
            surface_damping: self.number(
                b.surface_damping.as_ref(),
                d.surface_damping,
                "surface_damping",
                Rule::NonNegative,
            )?,
            link_stiffness: self.number(
                b.link_stiffness.as_ref(),
                d.link_stiffness,
                "link_stiffness",
                Rule::Positive,
            )?,
            link_damping: self.number(
                b.link_damping.as_ref(),
                d.link_damping,
                "link_damping",
                Rule::NonNegative,
            )?,
            air_viscosity: self.number(
                b.air_viscosity.as_ref(),
                world.air_viscosity,
                "air_viscosity",
                Rule::NonNegative,
            )?,
            friction: self.number(
                b.friction.as_ref(),
                d.friction,
                "friction",
                Rule::NonNegative,
            )?,
            fixed: b.fixed.unwrap_or(d.fixed),
            self_contact: b
                .self_contact
                .as_ref()
                .map_or(d.self_contact, |v| *v.get_ref()),
            integrator: match &b.integrator {
                None => None,
                Some(v) => Some(self.integrator(Some(v), world.integrator)?),
            },
            subdivision: match &b.subdivision {
                None => None,
                Some(v) => self.subdivision(v)?,
            },
            cutting: match &b.cutting {
                None => None,
                Some(v) => self.cutting(v)?,
            },
            plasticity: match &b.plasticity {
                None => None,
                Some(v) => self.plasticity(v)?,
            },
            tearing: match &b.tearing {
                None => None,
                Some(v) => self.tearing(v)?,
            },
        };
        if let Some(v) = &b.self_contact
            && *v.get_ref()
            && (params.cutting.is_some() || params.tearing.is_some())
        {
            return Err(self.error(
                v.span(),
                "`self_contact` cannot be combined with `cutting` or `tearing` yet (the two \
                 sides of a cut start touching; see the README, Self-contact)"
                    .to_string(),
            ));
        }
        let placement = Placement {
            position_in_world: self.vector(b.position.as_ref(), Vec3::zeros(), "position")?,
            world_from_body: self.orientation(b.orientation.as_ref(), "orientation")?,
            velocity_in_world: self.vector(b.velocity.as_ref(), Vec3::zeros(), "velocity")?,
            angular_velocity_in_world: self.vector(
                b.angular_velocity.as_ref(),
                Vec3::zeros(),
                "angular_velocity",
            )?,
        };
        Ok(BodySpec {
            name,
            mesh,
            placement,
            params,
            mesh_source,
        })
    }

    fn mesh(
        &self,
        section: &Spanned<MeshSection>,
        dir: &Path,
        assets: &mut Vec<(String, PathBuf)>,
        vertices: &mut usize,
    ) -> Result<(SurfaceMesh, String), SceneError> {
        let m = section.get_ref();
        let given = [
            m.icosphere.is_some(),
            m.ellipsoid.is_some(),
            m.box_.is_some(),
            m.obj.is_some(),
            m.capsule.is_some(),
        ];
        if given.iter().filter(|g| **g).count() != 1 {
            return Err(self.error(
                section.span(),
                "`mesh` must have exactly one of `icosphere = { radius, subdivisions }`, \
                 `ellipsoid = { radii, subdivisions }`, `box = { size, subdivisions }`, `capsule = { radius, length, around }` or \
                 `obj = \"path.obj\"`"
                    .to_string(),
            ));
        }
        let scale = self.mesh_scale(m.scale.as_ref())?;
        // Primitives are counted before they are built, OBJ meshes (bounded by their file) after.
        let mut budget = |added: usize| -> Result<(), SceneError> {
            *vertices = vertices.saturating_add(added);
            if *vertices > MAX_SCENE_VERTICES {
                return Err(self.error(
                    section.span(),
                    format!(
                        "the scene's meshes would have {} vertices with this one ({added}), more than \
                         the {MAX_SCENE_VERTICES} a scene may have",
                        *vertices
                    ),
                ));
            }
            Ok(())
        };
        let icosphere_vertices = |s: u32| 10 * 4usize.pow(s) + 2;
        // (An OBJ file's vertices merged at their positions, named in its errors.)
        let mut merged_in_file = mesh::MergedVertices::default();
        let (mut mesh, source) = if let Some(ico) = &m.icosphere {
            let radius = self.number(Some(&ico.get_ref().radius), 0.0, "radius", Rule::Positive)?;
            let subdivisions = self.subdivisions(&ico.get_ref().subdivisions, 2, 7)?;
            budget(icosphere_vertices(subdivisions))?;
            (
                mesh::icosphere(radius, subdivisions),
                format!("icosphere r={radius:?} s={subdivisions}"),
            )
        } else if let Some(ell) = &m.ellipsoid {
            let radii = self.positive_vector(&ell.get_ref().radii, "radii")?;
            let subdivisions = self.subdivisions(&ell.get_ref().subdivisions, 2, 7)?;
            budget(icosphere_vertices(subdivisions))?;
            let mut mesh = mesh::icosphere(1.0, subdivisions);
            mesh.scale(radii);
            (
                mesh,
                format!("ellipsoid radii={:?} s={subdivisions}", radii.as_slice()),
            )
        } else if let Some(bx) = &m.box_ {
            self.box_mesh(bx.get_ref(), &mut budget)?
        } else if let Some(cap) = &m.capsule {
            self.capsule_mesh(cap, &mut budget)?
        } else {
            let obj = m.obj.as_ref().expect("one mesh kind was given");
            let path = dir.join(obj.get_ref());
            let (mesh, merged) =
                mesh::load_obj(&path).map_err(|e| self.error(obj.span(), format!("mesh: {e}")))?;
            budget(mesh.vertex_count())?;
            assets.push((obj.get_ref().clone(), path));
            merged_in_file = merged;
            (mesh, format!("obj {}", obj.get_ref()))
        };
        mesh.scale(scale);
        mesh.validate().map_err(|e| {
            let note = merged_in_file.note_for(&e);
            self.error(section.span(), format!("mesh ({source}): {e}{note}"))
        })?;
        mesh.recentre_on_surface_centre();
        mesh.reorder_for_locality();
        Ok((mesh, source))
    }

    /// A mesh's `scale`: one number or three, each finite and > 0 (1 when absent).
    fn mesh_scale(&self, scale: Option<&Spanned<ScaleValue>>) -> Result<Vec3, SceneError> {
        let Some(s) = scale else {
            return Ok(Vec3::repeat(1.0));
        };
        let v = match s.get_ref() {
            ScaleValue::Uniform(x) => Vec3::repeat(*x),
            ScaleValue::PerAxis(a) => Vec3::from(*a),
        };
        if !v.iter().all(|x| x.is_finite() && *x > 0.0) {
            // As written: one number, or the three.
            let found = match s.get_ref() {
                ScaleValue::Uniform(x) => format!("{x}"),
                ScaleValue::PerAxis([x, y, z]) => format!("[{x}, {y}, {z}]"),
            };
            return Err(self.error(
                s.span(),
                format!("`scale` must be a number > 0 or three numbers > 0, found {found}"),
            ));
        }
        Ok(v)
    }

    /// A sphere's or ellipsoid's `subdivisions`: at most `max` (`default` when absent).
    fn subdivisions(
        &self,
        s: &Option<Spanned<u32>>,
        default: u32,
        max: u32,
    ) -> Result<u32, SceneError> {
        match s {
            None => Ok(default),
            Some(v) if *v.get_ref() <= max => Ok(*v.get_ref()),
            Some(v) => Err(self.error(
                v.span(),
                format!(
                    "`subdivisions` must be at most {max}, found {}",
                    v.get_ref()
                ),
            )),
        }
    }

    /// `box = { size, subdivisions }`: its surface grid counted against `budget`, then built.
    fn box_mesh(
        &self,
        bx: &BoxMeshSection,
        budget: &mut dyn FnMut(usize) -> Result<(), SceneError>,
    ) -> Result<(SurfaceMesh, String), SceneError> {
        let size = self.positive_vector(&bx.size, "size")?;
        let subdivisions = match &bx.subdivisions {
            None => [0; 3],
            Some(v) => {
                let n = match v.get_ref() {
                    BoxSubdivisions::Uniform(n) => [*n; 3],
                    BoxSubdivisions::PerAxis(a) => *a,
                };
                if n.iter().any(|&k| k > 100) {
                    // (As written: one number, or three.)
                    let found = match v.get_ref() {
                        BoxSubdivisions::Uniform(n) => format!("{n}"),
                        BoxSubdivisions::PerAxis(a) => format!("{a:?}"),
                    };
                    return Err(self.error(
                        v.span(),
                        format!("`subdivisions` must be at most 100 (per axis), found {found}"),
                    ));
                }
                n
            }
        };
        // Grid points on the surface: all of them less the interior ones.
        let [a, b, c] = subdivisions.map(|k| k as usize);
        budget((a + 2) * (b + 2) * (c + 2) - a * b * c)?;
        Ok((
            mesh::box_mesh_per_axis(size, subdivisions),
            format!("box size={:?} s={subdivisions:?}", size.as_slice()),
        ))
    }

    /// `capsule = { radius, length, around }`: its rings (about one node spacing apart) bounded
    /// and counted against `budget` before it is built.
    fn capsule_mesh(
        &self,
        cap: &Spanned<CapsuleMeshSection>,
        budget: &mut dyn FnMut(usize) -> Result<(), SceneError>,
    ) -> Result<(SurfaceMesh, String), SceneError> {
        let c = cap.get_ref();
        let radius = self.number(Some(&c.radius), 0.0, "radius", Rule::Positive)?;
        let length = self.number(Some(&c.length), 0.0, "length", Rule::Positive)?;
        let around = match &c.around {
            None => 24,
            Some(v) if (6..=256).contains(v.get_ref()) => *v.get_ref(),
            Some(v) => {
                return Err(self.error(
                    v.span(),
                    format!("`around` must be 6 to 256, found {}", v.get_ref()),
                ));
            }
        };
        let spacing = std::f64::consts::TAU * radius / around as f64;
        let rings =
            (length / spacing).ceil() + (std::f64::consts::PI * radius / spacing).ceil() + 2.0;
        if rings.is_nan() || rings * around as f64 > MAX_SCENE_VERTICES as f64 {
            return Err(self.error(
                cap.span(),
                format!(
                    "the capsule would have about {} vertices, more than a scene may have",
                    rings * around as f64
                ),
            ));
        }
        budget((rings as usize) * around as usize)?;
        Ok((
            mesh::capsule(radius, length, around),
            format!("capsule r={radius:?} l={length:?} around={around}"),
        ))
    }

    /// An `[[attachment]]` table, its ties resolved on the bodies as placed.
    fn attachment(
        &self,
        table: &Spanned<AttachmentSection>,
        index: usize,
        bodies: &[BodySpec],
        dt: f64,
    ) -> Result<AttachmentSpec, SceneError> {
        let a = table.get_ref();
        let name = self.name(a.name.as_ref(), format!("attachment{index}"))?;
        let Some(body_value) = &a.body else {
            return Err(self.error(
                table.span(),
                format!("attachment `{name}` needs a `body` (the name of the body it ties)"),
            ));
        };
        let body = self.attachment_body(body_value, "body", &name, bodies)?;
        let Some(at_value) = &a.at else {
            return Err(self.error(
                table.span(),
                format!(
                    "attachment `{name}` needs `at`, the centre of the tied region (m, body frame)"
                ),
            ));
        };
        let at = self.vector(Some(at_value), Vec3::zeros(), "at")?;
        let radius = self.number(a.radius.as_ref(), 0.01, "radius", Rule::Positive)?;
        let stiffness = self.number(a.stiffness.as_ref(), 50.0, "stiffness", Rule::Positive)?;
        let damping = self.number(a.damping.as_ref(), 0.5, "damping", Rule::NonNegative)?;
        let to = self.attachment_to(a.to.as_ref(), body, &name, bodies)?;
        let spec = &bodies[body];
        let region = self.attachment_region(table, &name, spec, &at, radius)?;
        // The region's nodes' masses (the surface mass spread by area, as the body does).
        let mass = node_masses(spec);
        let region_mass: f64 = region.iter().map(|&i| mass[i as usize]).sum();
        let ties: Vec<Tie> = region
            .iter()
            .map(|&i| {
                let share = mass[i as usize] / region_mass;
                Tie {
                    node: i,
                    other_node: to.map_or(WORLD, |o| nearest_node(&bodies[o], &world_of(spec, i))),
                    stiffness: stiffness * share,
                    damping: damping * share,
                }
            })
            .collect();
        self.check_attachment_steps(
            table,
            &name,
            (stiffness, damping, region_mass),
            to.map(|o| (&bodies[o], &ties[..])),
            dt,
        )?;
        Ok(AttachmentSpec {
            name,
            body,
            to,
            ties,
        })
    }

    /// The body an attachment's `key` names; an error listing the scene's bodies when none has
    /// that name.
    fn attachment_body(
        &self,
        value: &Spanned<String>,
        key: &str,
        name: &str,
        bodies: &[BodySpec],
    ) -> Result<usize, SceneError> {
        bodies
            .iter()
            .position(|b| &b.name == value.get_ref())
            .ok_or_else(|| {
                let names = bodies
                    .iter()
                    .map(|b| format!("`{}`", b.name))
                    .collect::<Vec<_>>()
                    .join(", ");
                let expected = if bodies.is_empty() {
                    "the scene has no bodies".to_string()
                } else {
                    format!("expected one of {names}")
                };
                self.error(
                    value.span(),
                    format!(
                        "`{key}` of attachment `{name}` names no body: found {:?}, {expected}",
                        value.get_ref(),
                    ),
                )
            })
    }

    /// What an attachment ties its body to: another body, or the world (`to` absent or `"world"`).
    fn attachment_to(
        &self,
        value: Option<&Spanned<String>>,
        body: usize,
        name: &str,
        bodies: &[BodySpec],
    ) -> Result<Option<usize>, SceneError> {
        let Some(v) = value.filter(|v| v.get_ref() != "world") else {
            return Ok(None);
        };
        let o = self.attachment_body(v, "to", name, bodies)?;
        if o == body {
            return Err(self.error(
                v.span(),
                format!(
                    "attachment `{name}` ties body `{}` to itself",
                    bodies[o].name
                ),
            ));
        }
        Ok(Some(o))
    }

    /// The nodes of `spec` within `radius` of `at` (body frame), in index order; an error naming
    /// the nearest node's distance when there is none.
    fn attachment_region(
        &self,
        table: &Spanned<AttachmentSection>,
        name: &str,
        spec: &BodySpec,
        at: &Vec3,
        radius: f64,
    ) -> Result<Vec<u32>, SceneError> {
        let region: Vec<u32> = (0..spec.mesh.positions_in_body.len() as u32)
            .filter(|&i| (spec.mesh.positions_in_body[i as usize] - at).norm() <= radius)
            .collect();
        if region.is_empty() {
            let nearest = spec
                .mesh
                .positions_in_body
                .iter()
                .map(|p| (p - at).norm())
                .fold(f64::INFINITY, f64::min);
            return Err(self.error(
                table.span(),
                format!(
                    "attachment `{name}`: no node of body `{}` within `radius` = {radius} m of `at` (the nearest is {nearest:.4} m away)",
                    spec.name
                ),
            ));
        }
        Ok(region)
    }

    /// Explicit ties must be stable at `dt` on every node they pull: √(k/m) Δt and (c/m) Δt at
    /// most ATTACHMENT_STEP_LIMIT (on the region, k/m is the attachment's k/M; on the other body,
    /// each node's sum of the ties that pull it over its mass). The error points at the key to
    /// lower (the stiffness when both are past the limit).
    fn check_attachment_steps(
        &self,
        table: &Spanned<AttachmentSection>,
        name: &str,
        (stiffness, damping, region_mass): (f64, f64, f64),
        other: Option<(&BodySpec, &[Tie])>,
        dt: f64,
    ) -> Result<(), SceneError> {
        let a = table.get_ref();
        let mut worst = (stiffness / region_mass).sqrt() * dt;
        let mut worst_damping = damping / region_mass * dt;
        if let Some((other, ties)) = other {
            let other_mass = node_masses(other);
            let mut pull = vec![(0.0f64, 0.0f64); other_mass.len()];
            for t in ties {
                let p = &mut pull[t.other_node as usize];
                p.0 += t.stiffness;
                p.1 += t.damping;
            }
            for ((k, c), m) in pull.iter().zip(&other_mass) {
                worst = worst.max((k / m).sqrt() * dt);
                worst_damping = worst_damping.max(c / m * dt);
            }
        }
        let (stiff, damped) = (
            worst > ATTACHMENT_STEP_LIMIT,
            worst_damping > ATTACHMENT_STEP_LIMIT,
        );
        if !(stiff || damped) {
            return Ok(());
        }
        let (what, key) = match (stiff, damped) {
            (true, true) => ("too stiff and too damped", a.stiffness.as_ref()),
            (true, false) => ("too stiff", a.stiffness.as_ref()),
            _ => ("too damped", a.damping.as_ref()),
        };
        let span = key.map_or(table.span(), |s| s.span());
        Err(self.error(
            span,
            format!(
                "attachment `{name}` is {what} for dt = {dt} s on the nodes it ties: √(k/m)·dt = {worst:.3} and (c/m)·dt = {worst_damping:.3}, both must be at most {ATTACHMENT_STEP_LIMIT} (lower `stiffness` or `damping`, or widen `radius`)"
            ),
        ))
    }

    fn obstacle(
        &self,
        obstacle: &Spanned<ObstacleSection>,
        index: usize,
    ) -> Result<Obstacle, SceneError> {
        let o = obstacle.get_ref();
        let name = o
            .name
            .as_ref()
            .map_or_else(|| format!("obstacle{index}"), |n| n.get_ref().clone());
        let shape = match (&o.plane, &o.box_) {
            (Some(plane), None) => {
                let p = plane.get_ref();
                let point = self.vector(p.point.as_ref(), Vec3::zeros(), "point")?;
                let normal = self.vector(Some(&p.normal), Vec3::zeros(), "normal")?;
                let length = normal.norm();
                if length < 1e-12 {
                    return Err(self.error(
                        p.normal.span(),
                        "`normal` must be a non-zero vector".to_string(),
                    ));
                }
                ObstacleShape::Plane {
                    point_in_world: point,
                    normal_in_world: normal / length,
                }
            }
            (None, Some(bx)) => {
                let b = bx.get_ref();
                ObstacleShape::Box {
                    center_in_world: self.vector(b.center.as_ref(), Vec3::zeros(), "center")?,
                    half_extents: self.positive_vector(&b.size, "size")? * 0.5,
                    world_from_box: self.orientation(b.orientation.as_ref(), "orientation")?,
                }
            }
            _ => {
                return Err(self.error(
                    obstacle.span(),
                    format!(
                        "obstacle `{name}` must have exactly one of `plane = {{ point, normal }}` or \
                         `box = {{ center, size, orientation }}`"
                    ),
                ));
            }
        };
        let friction = self.number(o.friction.as_ref(), 0.5, "friction", Rule::NonNegative)?;
        let static_friction = self.number(
            o.static_friction.as_ref(),
            friction,
            "static_friction",
            Rule::NonNegative,
        )?;
        if static_friction < friction {
            let span = o
                .static_friction
                .as_ref()
                .map_or(obstacle.span(), |s| s.span());
            return Err(self.error(
                span,
                format!(
                    "`static_friction` ({static_friction}) must be at least `friction` ({friction})"
                ),
            ));
        }
        Ok(Obstacle {
            name,
            shape,
            friction,
            static_friction,
        })
    }
}

/// The node masses of a body spec: its surface mass spread by area, as the body does (evenly when
/// the mesh has no area).
fn node_masses(b: &BodySpec) -> Vec<f64> {
    let areas = b.mesh.vertex_areas();
    let total: f64 = areas.iter().sum();
    let n = areas.len() as f64;
    areas
        .iter()
        .map(|a| {
            if total > 0.0 {
                b.params.surface_mass * a / total
            } else {
                b.params.surface_mass / n
            }
        })
        .collect()
}

/// Node `i` of a body spec where the scene places it (world frame).
fn world_of(b: &BodySpec, i: u32) -> Vec3 {
    b.placement.position_in_world
        + b.placement.world_from_body * b.mesh.positions_in_body[i as usize]
}

/// The node of `other` nearest `x` (world frame; the first of equals).
fn nearest_node(other: &BodySpec, x: &Vec3) -> u32 {
    let mut best = (f64::INFINITY, 0u32);
    for j in 0..other.mesh.positions_in_body.len() as u32 {
        let d = (world_of(other, j) - x).norm_squared();
        if d < best.0 {
            best = (d, j);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_scene_is_valid() {
        let scene = default_scene();
        assert!(!scene.bodies.is_empty());
    }
}
