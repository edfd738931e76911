//! Reading recordings back, and replaying them: rebuild the scene from the recording, feed the
//! recorded inputs tick by tick, and compare every feedback and mesh message bit for bit.
//!
//! Reading scans the file record by record (chunks decompressed in order), so a recording cut short
//! by a crash is read up to its last complete chunk, without a summary section.

use std::collections::BTreeMap;
use std::convert::Infallible;
use std::path::{Path, PathBuf};

use prost::Message;

use super::proto;
use super::reader::{Damage, Item, Problem, read_records};
use super::recorder::{RecordError, feedback_message, mesh_message};
use crate::Vec3;
use crate::daemon::feedback_payload;
use crate::daemon::sink::event;
use crate::display::MeshSchedule;
use crate::ipc::payload::{MESH_DELTA, MESH_KEYFRAME, MeshHeaderV1};
use crate::scene::parse_scene;
use crate::tool::{ToolInput, ToolPose};
use crate::world::World;

/// One recorded message.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordedMessage {
    /// Topic.
    pub topic: String,
    /// Log time (ns of simulation time).
    pub log_time: u64,
    /// Protobuf bytes.
    pub data: Vec<u8>,
}

/// A recording read back.
#[derive(Clone, Debug, Default)]
pub struct Recording {
    /// The session's scene message.
    pub scene: proto::Scene,
    /// Attachments: name and bytes.
    pub attachments: Vec<(String, Vec<u8>)>,
    /// Every message, in file order.
    pub messages: Vec<RecordedMessage>,
    /// The file ended properly (footer read, the data and summary CRCs and the end magic checked);
    /// false for a file cut short or damaged.
    pub complete: bool,
    /// Where and why reading stopped, when it found damaged bytes: before the footer (what follows
    /// is lost), or at the data end record or footer (every message was read, but the data
    /// section's CRC, the summary section and footer, or the end magic are damaged). A file that
    /// simply ends after a whole record has none (and is not complete).
    pub damage: Option<Damage>,
}

/// A recording file that cannot be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RecordingError {
    /// The file cannot be read at all.
    #[error("cannot read {path}: {reason}")]
    Io {
        /// The path as given.
        path: String,
        /// The operating system's reason.
        reason: String,
    },
    /// The bytes are not a readable recording (nothing usable before the damage).
    #[error("{path}: {damage}")]
    Damaged {
        /// The path as given.
        path: String,
        /// Where and what.
        damage: Damage,
    },
}

/// Reads a recording from its bytes. Damage after the scene message ends the reading: what came
/// before is kept, the recording is marked incomplete and [`Recording::damage`] says where and why.
/// Damage before the scene message is an error.
pub fn read_recording(bytes: &[u8]) -> Result<Recording, Damage> {
    let mut topics: BTreeMap<u16, String> = BTreeMap::new();
    let mut recording = Recording::default();
    let mut scene = None;
    let result = read_records(bytes, |item| {
        match item {
            Item::Channel { id, topic } => {
                topics.insert(id, topic.to_string());
            }
            Item::Message {
                channel_id,
                log_time,
                data,
            } => {
                let topic = topics
                    .get(&channel_id)
                    .ok_or(Problem::UnknownChannel {
                        channel: channel_id,
                    })?
                    .clone();
                if topic == "/palpa/scene" && scene.is_none() {
                    scene = Some(proto::Scene::decode(data).map_err(|e| Problem::Scene {
                        reason: e.to_string(),
                    })?);
                }
                recording.messages.push(RecordedMessage {
                    topic,
                    log_time,
                    data: data.to_vec(),
                });
            }
            Item::Attachment { name, data } => {
                recording
                    .attachments
                    .push((name.to_string(), data.to_vec()));
            }
            Item::Footer => recording.complete = true,
        }
        Ok(())
    });
    match (result, scene) {
        (Ok(()), Some(scene)) => recording.scene = scene,
        (Err(damage), Some(scene)) => {
            recording.scene = scene;
            recording.complete = false;
            recording.damage = Some(damage);
        }
        (Err(damage), None) => return Err(damage),
        (Ok(()), None) => {
            return Err(Damage {
                offset: bytes.len() as u64,
                problem: Problem::NoScene,
            });
        }
    }
    Ok(recording)
}

/// Reads a recording file (a regular file: a device or a pipe is refused rather than read
/// without end).
pub fn read_recording_file(path: &Path) -> Result<Recording, RecordingError> {
    let io = |e: std::io::Error| RecordingError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    };
    let metadata = std::fs::metadata(path).map_err(io)?;
    if !metadata.is_file() {
        return Err(RecordingError::Io {
            path: path.display().to_string(),
            reason: "not a regular file".into(),
        });
    }
    let bytes = std::fs::read(path).map_err(io)?;
    read_recording(&bytes).map_err(|damage| RecordingError::Damaged {
        path: path.display().to_string(),
        damage,
    })
}

/// Message counts per topic and session figures.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SessionSummary {
    /// Messages per topic.
    pub messages: BTreeMap<String, u64>,
    /// Ticks simulated: the last recorded tick, or the session's end where it says so (a
    /// session with resets: the sum over its epochs, each ending at its reset's tick).
    pub ticks: u64,
    /// Simulated duration (s).
    pub duration_s: f64,
    /// Tool names.
    pub tools: Vec<String>,
    /// Largest contact count of any tool.
    pub max_contacts: u32,
    /// Largest feedback force magnitude (N).
    pub max_force: f64,
    /// Synchronicity misses (events).
    pub misses: u64,
    /// Rejected inputs (events).
    pub rejects: u64,
    /// The file ended properly.
    pub complete: bool,
    /// Where and why reading stopped early, if it stopped at damaged bytes.
    pub damage: Option<Damage>,
}

/// The tick of a log time (saturating: a damaged time or step gives a large tick, never a panic).
fn tick_at(log_time: u64, dt: f64) -> u64 {
    (log_time as f64 / (dt * 1e9)).round() as u64
}

/// Summarises a recording.
pub fn summarise(recording: &Recording) -> SessionSummary {
    let mut s = SessionSummary {
        tools: recording.scene.tools.clone(),
        complete: recording.complete,
        damage: recording.damage.clone(),
        ..SessionSummary::default()
    };
    // Ticks of the epochs before the last reset, and the last tick of the current one.
    let (mut before, mut epoch_last) = (0u64, 0u64);
    for m in &recording.messages {
        *s.messages.entry(m.topic.clone()).or_default() += 1;
        epoch_last = epoch_last.max(tick_at(m.log_time, recording.scene.dt));
        if m.topic.ends_with("/feedback")
            && let Ok(f) = proto::Feedback::decode(&m.data[..])
        {
            s.max_contacts = s.max_contacts.max(f.contacts);
            if let Some(force) = f.force {
                s.max_force = s.max_force.max(Vec3::new(force.x, force.y, force.z).norm());
            }
        }
        if m.topic == "/palpa/events"
            && let Ok(e) = proto::Event::decode(&m.data[..])
        {
            match e.kind {
                event::SYNCHRONICITY_MISS => s.misses += 1,
                event::INPUT_REJECTED => s.rejects += 1,
                event::RESET => {
                    before = before.saturating_add(epoch_last);
                    epoch_last = 0;
                }
                _ => {}
            }
        }
    }
    s.ticks = before.saturating_add(epoch_last);
    s.duration_s = s.ticks as f64 * recording.scene.dt;
    s
}

/// Where replay first differs from the recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Difference {
    /// Tick of the message.
    pub tick: u64,
    /// Topic.
    pub channel: String,
    /// First differing field.
    pub field: String,
    /// Recorded value (debug text).
    pub recorded: String,
    /// Replayed value (debug text).
    pub replayed: String,
}

impl std::fmt::Display for Difference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "tick {}: {} field `{}` differs: recorded {}, replayed {}",
            self.tick, self.channel, self.field, self.recorded, self.replayed
        )
    }
}

/// What a successful replay checked.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VerifyReport {
    /// Ticks replayed.
    pub ticks: u64,
    /// Feedback messages compared.
    pub feedback: u64,
    /// Mesh messages compared.
    pub meshes: u64,
    /// FNV-1a digest of every replayed message, in order.
    pub digest: u64,
}

/// Deepest `..` an attachment may climb (a scene's meshes a few folders up).
const MAX_ATTACHMENT_DEPTH: usize = 16;

/// How far above its scene an attachment name climbs (`../../m.obj`: 2, `a/../../m.obj`: 1), or
/// `None` for a name that cannot be unpacked safely (absolute, empty, or too deep).
fn attachment_depth(name: &str) -> Option<usize> {
    let mut level: isize = 0;
    let mut lowest: isize = 0;
    let mut parts = 0;
    for component in Path::new(name).components() {
        match component {
            std::path::Component::Normal(_) => {
                level += 1;
                parts += 1;
            }
            std::path::Component::ParentDir => level -= 1,
            std::path::Component::CurDir => {}
            std::path::Component::RootDir | std::path::Component::Prefix(_) => return None,
        }
        lowest = lowest.min(level);
    }
    let depth = lowest.unsigned_abs();
    (parts > 0 && level > lowest && depth <= MAX_ATTACHMENT_DEPTH).then_some(depth)
}

/// Unpacks the scene and its meshes into `dir` (the scene nested deep enough for every relative
/// mesh path to stay inside `dir`) and loads it. Attachment names are checked first: a recording
/// cannot write outside `dir`.
fn rebuild_scene(recording: &Recording, dir: &Path) -> Result<crate::scene::Scene, VerifyError> {
    let mut depth = 0;
    for (name, _) in &recording.attachments {
        match attachment_depth(name) {
            Some(d) => depth = depth.max(d),
            None => return Err(VerifyError::AttachmentName { name: name.clone() }),
        }
    }
    let mut scene_dir = dir.to_path_buf();
    for k in 0..depth {
        scene_dir.push(format!("s{k}"));
    }
    let unpack = |name: &str, e: std::io::Error| VerifyError::Unpack {
        name: name.to_string(),
        dir: dir.display().to_string(),
        reason: e.to_string(),
    };
    std::fs::create_dir_all(&scene_dir).map_err(|e| unpack("(scene folder)", e))?;
    for (name, data) in &recording.attachments {
        if name == "scene.toml" {
            continue;
        }
        let target: PathBuf = scene_dir.join(name);
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent).map_err(|e| unpack(name, e))?;
        }
        std::fs::write(&target, data).map_err(|e| unpack(name, e))?;
    }
    parse_scene(&recording.scene.source, &recording.scene.name, &scene_dir)
        .map_err(|e| VerifyError::Scene(e.to_string()))
}

fn fnv(digest: &mut u64, bytes: &[u8]) {
    for &b in bytes {
        *digest ^= b as u64;
        *digest = digest.wrapping_mul(0x100000001b3);
    }
}

/// Names the first field where two encodings of the same message type differ.
fn first_difference<M: Message + Default + std::fmt::Debug>(
    recorded: &[u8],
    replayed: &[u8],
) -> (String, String, String) {
    let a = M::decode(recorded)
        .map(|m| format!("{m:?}"))
        .unwrap_or_else(|e| format!("undecodable ({e})"));
    let b = M::decode(replayed)
        .map(|m| format!("{m:?}"))
        .unwrap_or_else(|e| format!("undecodable ({e})"));
    // Debug output lists fields in order: the first differing `name: value` names the field.
    let split = |s: &str| -> Vec<String> { s.split(", ").map(str::to_string).collect() };
    for (x, y) in split(&a).iter().zip(split(&b).iter()) {
        if x != y {
            let field = x
                .split(':')
                .next()
                .unwrap_or("?")
                .trim_start_matches(|c: char| !c.is_alphanumeric())
                .to_string();
            let field = field.rsplit(' ').next().unwrap_or(&field).to_string();
            return (field, x.clone(), y.clone());
        }
    }
    ("(encoding)".into(), a, b)
}

/// How long this machine took to replay each tick's step (wall clock: a diagnostic beside the
/// compared bits, never part of them), with the ticks the recording marks as synchronicity misses
/// apart. A tick the daemon missed that replays well within the period was not the scene's work:
/// the daemon's thread was held off its core (the machine's other work, or stolen time on a
/// virtual machine) or waited on IPC.
#[derive(Clone, Debug)]
pub struct StepTimes {
    /// Ticks per 1 µs bin of replayed step time; the last bin holds the longer ones.
    histogram: Vec<u32>,
    ticks: u64,
    sum_us: f64,
    /// Longest replayed step (µs).
    pub max_us: f64,
    /// The session's period (µs).
    pub period_us: f64,
    /// The replayed step time of each tick the recording marks as a synchronicity miss, in the
    /// order replayed (µs).
    pub at_misses_us: Vec<f64>,
}

/// Bins of [`StepTimes`]'s histogram (1 µs each).
const STEP_TIME_BINS: usize = 20_000;

impl StepTimes {
    fn new(period_us: f64) -> Self {
        Self {
            histogram: vec![0; STEP_TIME_BINS],
            ticks: 0,
            sum_us: 0.0,
            max_us: 0.0,
            period_us,
            at_misses_us: Vec::new(),
        }
    }

    fn record(&mut self, us: f64) {
        self.histogram[(us.max(0.0) as usize).min(STEP_TIME_BINS - 1)] += 1;
        self.ticks += 1;
        self.sum_us += us;
        self.max_us = self.max_us.max(us);
    }

    /// Steps timed.
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// Mean replayed step time (µs); 0 when none was timed.
    pub fn mean_us(&self) -> f64 {
        self.sum_us / self.ticks.max(1) as f64
    }

    /// The `q` quantile (0 < q ≤ 1) of the replayed step times at 1 µs resolution: the upper edge
    /// of the bin it falls in, at most the longest step (µs); 0 when none was timed.
    pub fn quantile_us(&self, q: f64) -> f64 {
        crate::daemon::stats::histogram_quantile_us(&self.histogram, self.ticks, q, self.max_us)
    }
}

/// Replays a recording and compares every feedback and mesh message with the recorded one;
/// `progress(tick, last)` is called every 1000 ticks.
pub fn verify(
    recording: &Recording,
    work_dir: &Path,
    progress: impl FnMut(u64, u64),
) -> Result<VerifyReport, VerifyError> {
    verify_timed(recording, work_dir, progress).map(|(report, _)| report)
}

/// [`verify`], also timing each replayed step on this machine ([`StepTimes`]).
pub fn verify_timed(
    recording: &Recording,
    work_dir: &Path,
    mut progress: impl FnMut(u64, u64),
) -> Result<(VerifyReport, StepTimes), VerifyError> {
    let mut replay = Replay::new(recording, work_dir)?;
    // The keyframe at tick 0 (and whatever else was recorded before the first step).
    replay.check_outputs()?;
    while replay.at() < replay.last {
        if replay.report.ticks >= replay.covered {
            return Err(VerifyError::Session(format!(
                "{} ticks replayed and the outputs account for at most {}: damaged log times or resets",
                replay.report.ticks, replay.covered
            )));
        }
        replay.step();
        replay.check_outputs()?;
        if replay.report.ticks % 1000 == 0 {
            progress(replay.report.ticks, replay.total);
        }
    }
    if let Some(&(_, m)) = replay.outputs.get(replay.next) {
        return Err(VerifyError::Differs(Difference {
            tick: tick_at(m.log_time, replay.session.dt),
            channel: m.topic.clone(),
            field: "(message)".into(),
            recorded: "present".into(),
            replayed: "not produced".into(),
        }));
    }
    Ok((replay.report, replay.times))
}

/// A replay under way: the recorded scene's world, driven by the recorded inputs and events, and
/// the recorded outputs it is compared with, in order.
struct Replay<'r> {
    session: &'r proto::Scene,
    scene: crate::scene::Scene,
    world: World,
    meshes: MeshSchedule,
    /// A `palpa serve` session (its feedback echoes the inputs' sequence numbers and device
    /// times), not a `palpa run` one.
    serve_mode: bool,
    tool_index: BTreeMap<String, usize>,
    /// Inputs and events by epoch and tick, outputs (with their epoch) in order. A reset starts
    /// an epoch: the world's tick starts again from 0, so a tick names a moment only with the
    /// number of resets before it (counted in file order, the order the daemon did things in).
    inputs: BTreeMap<(u64, u64), Vec<proto::ToolInput>>,
    events: BTreeMap<(u64, u64), Vec<proto::Event>>,
    outputs: Vec<(u64, &'r RecordedMessage)>,
    /// The epoch being replayed.
    epoch: u64,
    /// Epoch and tick where the session ended (its end event, else its last output), the ticks
    /// that makes over every epoch, and the most ticks the outputs can account for.
    last: (u64, u64),
    total: u64,
    covered: u64,
    /// Per tool: connected, its input rejected this tick, the sequence number and device time its
    /// feedback echoes.
    connected: Vec<bool>,
    rejected: Vec<bool>,
    echo: Vec<(u64, u64)>,
    /// The next output to compare.
    next: usize,
    report: VerifyReport,
    times: StepTimes,
}

impl<'r> Replay<'r> {
    /// The recorded session's scene rebuilt in `work_dir`, its world at the start, and the
    /// recording's messages sorted into inputs, events and outputs (each input checked).
    fn new(recording: &'r Recording, work_dir: &Path) -> Result<Self, VerifyError> {
        let session = &recording.scene;
        check_session(session)?;
        let scene = rebuild_scene(recording, work_dir)?;
        if scene.world.dt.to_bits() != session.dt.to_bits() {
            return Err(VerifyError::Session(format!(
                "the scene steps at dt = {} s but the session was recorded at {} s",
                scene.world.dt, session.dt
            )));
        }
        let mut world = World::from_scene(&scene);
        let meshes = MeshSchedule::new(&world, session.display_rate_hz, session.keyframe_every_s);
        let tool_index: BTreeMap<String, usize> = world
            .tools
            .iter()
            .enumerate()
            .map(|(i, t)| (t.name.clone(), i))
            .collect();
        drive_by_recorded_poses(&mut world);
        let mut inputs: BTreeMap<(u64, u64), Vec<proto::ToolInput>> = BTreeMap::new();
        let mut events: BTreeMap<(u64, u64), Vec<proto::Event>> = BTreeMap::new();
        let mut outputs: Vec<(u64, &RecordedMessage)> = Vec::new();
        let mut epoch = 0u64;
        let mut ended = None;
        // Ticks of the epochs before the current one.
        let mut before = 0u64;
        for m in &recording.messages {
            if m.topic.ends_with("/input") {
                let i: proto::ToolInput = decode_message(m)?;
                check_input(&i).map_err(|reason| MessageError::new(m, reason))?;
                inputs.entry((epoch, i.tick)).or_default().push(i);
            } else if m.topic == "/palpa/events" {
                let e: proto::Event = decode_message(m)?;
                let (kind, tick) = (e.kind, e.tick);
                events.entry((epoch, tick)).or_default().push(e);
                if kind == event::RESET {
                    epoch += 1;
                    before = before.saturating_add(tick);
                } else if kind == event::SESSION_END {
                    ended = Some((epoch, tick));
                }
            } else if m.topic.ends_with("/feedback") || m.topic.starts_with("/palpa/mesh/") {
                outputs.push((epoch, m));
            }
        }
        let last_output = outputs
            .last()
            .map_or((0, 0), |&(e, m)| (e, tick_at(m.log_time, session.dt)));
        let last = ended.map_or(last_output, |end| end.max(last_output));
        // Every body sends a mesh message every `display_every` ticks and every tool a feedback
        // message every tick, so the outputs of a session of `total` ticks are at least
        // `total / display_every` (less one per epoch, and the ticks after the last display tick):
        // a tick beyond that is a damaged log time, which would otherwise be replayed for ages.
        let display_every = meshes.display_every();
        let covered = (outputs.len() as u64 + epoch + 2).saturating_mul(display_every);
        let total = if last.0 == epoch {
            before.saturating_add(last.1)
        } else {
            before
        };
        if total > covered {
            return Err(VerifyError::Session(format!(
                "the session ends at tick {} (after {} resets), but {} output messages at one per \
                 {display_every} ticks cover at most {covered} ticks: a damaged log time",
                last.1,
                last.0,
                outputs.len()
            )));
        }
        let tools = world.tools.len();
        Ok(Self {
            session,
            scene,
            connected: world.tools.iter().map(|t| t.active).collect(),
            rejected: vec![false; tools],
            echo: vec![(0u64, 0u64); tools],
            world,
            meshes,
            serve_mode: session.mode == "serve",
            tool_index,
            inputs,
            events,
            outputs,
            epoch: 0,
            last,
            total,
            covered,
            next: 0,
            report: VerifyReport {
                digest: 0xcbf29ce484222325,
                ..VerifyReport::default()
            },
            times: StepTimes::new(session.dt * 1e6),
        })
    }

    /// The epoch and tick of the world being replayed.
    fn at(&self) -> (u64, u64) {
        (self.epoch, self.world.tick)
    }

    /// The epoch and tick of a recorded output.
    fn output_at(&self, &(epoch, m): &(u64, &RecordedMessage)) -> (u64, u64) {
        (epoch, tick_at(m.log_time, self.session.dt))
    }

    /// One tick: the recorded reset, inputs and events of the world's tick applied, then a step.
    fn step(&mut self) {
        self.rejected.fill(false);
        // A reset starts the next epoch: the world's tick starts again from 0, and this step takes
        // the new epoch's inputs and events of tick 0 (the daemon answers its control requests
        // before it reads the poses). Resets answered together follow each other at tick 0.
        while self
            .events
            .get(&self.at())
            .is_some_and(|list| list.iter().any(|e| e.kind == event::RESET))
        {
            self.epoch += 1;
            self.world = World::from_scene(&self.scene);
            drive_by_recorded_poses(&mut self.world);
            self.meshes.reset(&self.world);
            self.connected = self.world.tools.iter().map(|t| t.active).collect();
        }
        let at = self.at();
        self.take_inputs(at);
        self.take_events(at);
        if !self.serve_mode {
            for (t, tool) in self.world.tools.iter().enumerate() {
                self.connected[t] = tool.active || self.connected[t];
            }
        }
        let started = std::time::Instant::now();
        self.world.step();
        let us = started.elapsed().as_secs_f64() * 1e6;
        self.times.record(us);
        // The daemon marks a miss with the tick the step led to.
        if self
            .events
            .get(&self.at())
            .is_some_and(|list| list.iter().any(|e| e.kind == event::SYNCHRONICITY_MISS))
        {
            self.times.at_misses_us.push(us);
        }
        if !self.serve_mode {
            for (t, tool) in self.world.tools.iter().enumerate() {
                self.connected[t] = tool.active;
            }
        }
        self.report.ticks += 1;
    }

    /// The recorded poses of `at` (epoch and tick) set as the tools' targets.
    fn take_inputs(&mut self, at: (u64, u64)) {
        let Some(list) = self.inputs.get(&at) else {
            return;
        };
        for input in list {
            let Some(&t) = self.tool_index.get(input.tool.as_str()) else {
                continue;
            };
            let p = input.position.unwrap_or_default();
            let q = input.orientation.unwrap_or_default();
            let pose = ToolPose {
                position_in_world: Vec3::new(p.x, p.y, p.z),
                world_from_tool: nalgebra::UnitQuaternion::from_quaternion(
                    nalgebra::Quaternion::new(q.w, q.x, q.y, q.z),
                ),
            };
            self.world.tools[t].set_target(pose, input.jaw.max(0.0));
            self.connected[t] = true;
            self.echo[t] = if self.serve_mode {
                (input.seq, input.device_time_ns)
            } else {
                (0, 0)
            };
        }
    }

    /// The recorded rejections and disconnections of `at` (epoch and tick).
    fn take_events(&mut self, at: (u64, u64)) {
        let Some(list) = self.events.get(&at) else {
            return;
        };
        for e in list {
            let Some(&t) = self.tool_index.get(e.tool.as_str()) else {
                continue;
            };
            match e.kind {
                event::INPUT_REJECTED => self.rejected[t] = true,
                event::DISCONNECT => {
                    self.world.tools[t].deactivate();
                    self.connected[t] = false;
                }
                _ => {}
            }
        }
    }

    /// The outputs recorded at the world's tick, each compared with the one the replay produces
    /// (and added to the digest); the first that differs is the error.
    fn check_outputs(&mut self) -> Result<(), VerifyError> {
        let tick = self.world.tick;
        let mesh_produced = self.produce_meshes();
        let mut mesh_cursor = 0;
        while self.next < self.outputs.len()
            && self.output_at(&self.outputs[self.next]) == self.at()
        {
            let (_, m) = self.outputs[self.next];
            self.next += 1;
            let replayed: Vec<u8> = if m.topic.ends_with("/feedback") {
                self.report.feedback += 1;
                self.feedback_for(m)?
            } else {
                self.report.meshes += 1;
                match mesh_produced.get(mesh_cursor) {
                    Some((_, bytes)) => {
                        mesh_cursor += 1;
                        bytes.clone()
                    }
                    None => Vec::new(),
                }
            };
            fnv(&mut self.report.digest, &replayed);
            if replayed != m.data {
                let (field, recorded, replayed) = if m.topic.ends_with("/feedback") {
                    first_difference::<proto::Feedback>(&m.data, &replayed)
                } else if m.topic.ends_with("keyframe") {
                    first_difference::<proto::MeshKeyframe>(&m.data, &replayed)
                } else {
                    first_difference::<proto::MeshDelta>(&m.data, &replayed)
                };
                return Err(VerifyError::Differs(Difference {
                    tick,
                    channel: m.topic.clone(),
                    field,
                    recorded,
                    replayed,
                }));
            }
        }
        Ok(())
    }

    /// The mesh messages of the world's tick, as the daemon would send them. A keyframe request
    /// (a display connecting) gives every body a keyframe; a body whose topology changed, or a
    /// body a transection made, gets one of its own. Only the first is replayed as a request:
    /// when every body has a recorded keyframe at this tick.
    fn produce_meshes(&mut self) -> Vec<(bool, Vec<u8>)> {
        let mut keyframed = 0u64;
        let mut keyframes = 0usize;
        for &(_, m) in self.outputs[self.next..]
            .iter()
            .take_while(|o| self.output_at(o) == self.at())
            .filter(|(_, m)| m.topic == "/palpa/mesh/keyframe")
        {
            let body = proto::MeshKeyframe::decode(m.data.as_slice()).map_or(u32::MAX, |k| k.body);
            if body < 64 && keyframed & (1 << body) == 0 {
                keyframed |= 1 << body;
                keyframes += 1;
            }
        }
        if keyframes > 0 && keyframes >= self.world.bodies.len().min(64) {
            self.meshes.request_keyframe();
        }
        let mut produced = Vec::new();
        let Ok(()) = self
            .meshes
            .produce(&self.world, |header, bytes| -> Result<(), Infallible> {
                produced.push(mesh_message(header, bytes));
                Ok(())
            });
        produced
    }

    /// The feedback message the replay sends for the recorded feedback message `m`.
    fn feedback_for(&self, m: &RecordedMessage) -> Result<Vec<u8>, VerifyError> {
        let name = m
            .topic
            .trim_start_matches("/palpa/tool/")
            .trim_end_matches("/feedback");
        let Some(&t) = self.tool_index.get(name) else {
            return Err(VerifyError::Differs(Difference {
                tick: self.world.tick,
                channel: m.topic.clone(),
                field: "tool".into(),
                recorded: name.into(),
                replayed: "(no such tool)".into(),
            }));
        };
        let world = &self.world;
        let mut payload = feedback_payload(
            &world.tools[t],
            world.tick,
            self.connected[t],
            self.rejected[t],
            self.echo[t],
        );
        // As the daemon sends it: flag 4 on every tool's feedback of a tick where the divergence
        // guard restored a body.
        if crate::daemon::guard_acted(world) {
            payload.flags |= crate::ipc::payload::FEEDBACK_DIVERGED;
        }
        Ok(feedback_message(name, &payload).encode_to_vec())
    }
}

/// Every tool driven by the recorded poses; a scripted tool keeps its starting pose and state.
fn drive_by_recorded_poses(world: &mut World) {
    for tool in &mut world.tools {
        tool.input = ToolInput::Ipc;
    }
}

/// Why a replay failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum VerifyError {
    /// The scene could not be rebuilt from the recording.
    #[error("cannot replay: the recorded scene does not load: {0}")]
    Scene(String),
    /// An attachment's name would unpack outside the work folder.
    #[error(
        "cannot replay: attachment name {name:?} is not a relative path within {MAX_ATTACHMENT_DEPTH} folders of the scene"
    )]
    AttachmentName {
        /// The name as recorded.
        name: String,
    },
    /// An attachment could not be written to the work folder.
    #[error("cannot replay: cannot unpack attachment {name:?} into {dir}: {reason}")]
    Unpack {
        /// The attachment.
        name: String,
        /// The work folder.
        dir: String,
        /// The operating system's reason.
        reason: String,
    },
    /// A recorded message cannot be decoded or is not a value the daemon sends.
    #[error("cannot replay: {0}")]
    Message(#[from] MessageError),
    /// The session's parameters or log times cannot be those of a real session.
    #[error("cannot replay: {0}")]
    Session(String),
    /// Replay produced a different message.
    #[error("{0}")]
    Differs(Difference),
}

/// A recorded message that cannot be used.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{topic} message at log time {log_time} ns: {reason}")]
pub struct MessageError {
    /// Its topic.
    pub topic: String,
    /// Its log time (ns).
    pub log_time: u64,
    /// What is wrong.
    pub reason: String,
}

impl MessageError {
    fn new(m: &RecordedMessage, reason: String) -> Self {
        Self {
            topic: m.topic.clone(),
            log_time: m.log_time,
            reason,
        }
    }
}

/// Decodes a recorded message as `M`.
fn decode_message<M: Message + Default>(m: &RecordedMessage) -> Result<M, MessageError> {
    M::decode(&m.data[..]).map_err(|e| {
        MessageError::new(
            m,
            format!(
                "cannot be decoded as palpa.{}: {e}",
                message_type_of(&m.topic)
            ),
        )
    })
}

/// The session parameters replay depends on are those a session can have.
fn check_session(session: &proto::Scene) -> Result<(), VerifyError> {
    let positive = |x: f64| x.is_finite() && x > 0.0;
    let problem = if !positive(session.dt) {
        Some(format!("dt = {} s", session.dt))
    } else if !positive(session.display_rate_hz) {
        Some(format!("display rate = {} Hz", session.display_rate_hz))
    } else if !positive(session.keyframe_every_s) || session.keyframe_every_s / session.dt > 1e15 {
        Some(format!("keyframes every {} s", session.keyframe_every_s))
    } else {
        None
    };
    match problem {
        Some(p) => Err(VerifyError::Session(format!(
            "the recorded session has {p}, which no session can have: a damaged scene message"
        ))),
        None => Ok(()),
    }
}

/// A recorded input is a pose the daemon could have accepted: finite numbers and a unit
/// quaternion (within a loose 10⁻² — the daemon's own tolerance is tighter).
fn check_input(input: &proto::ToolInput) -> Result<(), String> {
    let p = input.position.unwrap_or_default();
    let q = input.orientation.unwrap_or_default();
    let numbers = [p.x, p.y, p.z, q.w, q.x, q.y, q.z, input.jaw];
    let norm = (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
    if numbers.iter().all(|x| x.is_finite()) && (norm - 1.0).abs() <= 1e-2 {
        Ok(())
    } else {
        Err(format!(
            "input of tool {:?} at tick {} is not a pose the daemon accepts (position {:?}, \
             quaternion norm {norm}, jaw {}): damaged message",
            input.tool,
            input.tick,
            [p.x, p.y, p.z],
            input.jaw
        ))
    }
}

/// Writes a recording (its scene, attachments and messages) to a new MCAP file — used to make
/// altered copies in tests and to repair truncated files.
pub fn write_recording(recording: &Recording, path: &Path) -> Result<(), RecordError> {
    let file = std::fs::File::create(path).map_err(|reason| RecordError::Create {
        path: path.to_path_buf(),
        reason,
    })?;
    let mut writer = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_threads(0)
        .profile("palpa")
        .create(std::io::BufWriter::new(file))?;
    let mut channels: BTreeMap<String, u16> = BTreeMap::new();
    for m in &recording.messages {
        if !channels.contains_key(&m.topic) {
            let message = message_type_of(&m.topic);
            let schema = writer.add_schema(
                &format!("palpa.{message}"),
                "protobuf",
                super::DESCRIPTOR_SET,
            )?;
            let id = writer.add_channel(schema, &m.topic, "protobuf", &BTreeMap::new())?;
            channels.insert(m.topic.clone(), id);
        }
    }
    for (name, data) in &recording.attachments {
        writer.attach(&mcap::Attachment {
            log_time: 0,
            create_time: 0,
            name: name.clone(),
            media_type: "application/octet-stream".into(),
            data: std::borrow::Cow::Borrowed(data),
        })?;
    }
    for (k, m) in recording.messages.iter().enumerate() {
        writer.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channels[&m.topic],
                sequence: k as u32,
                log_time: m.log_time,
                publish_time: m.log_time,
            },
            &m.data,
        )?;
    }
    writer.finish()?;
    Ok(())
}

/// The protobuf message type of a palpa topic.
pub fn message_type_of(topic: &str) -> &'static str {
    match topic {
        "/palpa/scene" => "Scene",
        "/palpa/mesh/keyframe" => "MeshKeyframe",
        "/palpa/mesh/delta" => "MeshDelta",
        "/palpa/stats" => "Stats",
        "/palpa/events" => "Event",
        t if t.ends_with("/input") => "ToolInput",
        _ => "Feedback",
    }
}

/// The IPC form (header and payload bytes, in the layout of `proto/palpa_ipc.h`) of a recorded mesh
/// message, checked so that a display can apply it: whole vertices, triangle corners and changed
/// vertices within the vertex count. `payload` is cleared and filled.
pub fn mesh_payload(
    m: &RecordedMessage,
    payload: &mut Vec<u8>,
) -> Result<MeshHeaderV1, MessageError> {
    payload.clear();
    let bad = |reason: String| MessageError::new(m, reason);
    let count = |n: usize, what: &str| {
        u32::try_from(n).map_err(|_| bad(format!("{n} {what} do not fit the IPC header")))
    };
    if m.topic == "/palpa/mesh/keyframe" {
        let k: proto::MeshKeyframe = decode_message(m)?;
        if k.positions.len() % 3 != 0 || k.triangles.len() % 3 != 0 {
            return Err(bad(format!(
                "{} coordinates and {} triangle corners: not whole vertices and triangles",
                k.positions.len(),
                k.triangles.len()
            )));
        }
        let vertices = count(k.positions.len() / 3, "vertices")?;
        if let Some(v) = k.triangles.iter().find(|&&v| v >= vertices) {
            return Err(bad(format!(
                "a triangle refers to vertex {v} of {vertices}"
            )));
        }
        for x in &k.positions {
            payload.extend_from_slice(&x.to_le_bytes());
        }
        for x in &k.triangles {
            payload.extend_from_slice(&x.to_le_bytes());
        }
        Ok(MeshHeaderV1 {
            kind: MESH_KEYFRAME,
            body: k.body,
            tick: k.tick,
            base_tick: k.tick,
            vertex_count: vertices,
            triangle_count: count(k.triangles.len() / 3, "triangles")?,
            changed_count: 0,
            payload_bytes: count(payload.len(), "payload bytes")?,
        })
    } else if m.topic == "/palpa/mesh/delta" {
        let d: proto::MeshDelta = decode_message(m)?;
        if d.positions.len() != 3 * d.vertices.len() {
            return Err(bad(format!(
                "{} changed vertices but {} coordinates",
                d.vertices.len(),
                d.positions.len()
            )));
        }
        if let Some(v) = d.vertices.iter().find(|&&v| v >= d.vertex_count) {
            return Err(bad(format!(
                "a changed vertex {v} of {} vertices",
                d.vertex_count
            )));
        }
        for (v, p) in d.vertices.iter().zip(d.positions.chunks_exact(3)) {
            payload.extend_from_slice(&v.to_le_bytes());
            for x in p {
                payload.extend_from_slice(&x.to_le_bytes());
            }
        }
        Ok(MeshHeaderV1 {
            kind: MESH_DELTA,
            body: d.body,
            tick: d.tick,
            base_tick: d.base_tick,
            vertex_count: d.vertex_count,
            triangle_count: 0,
            changed_count: count(d.vertices.len(), "changed vertices")?,
            payload_bytes: count(payload.len(), "payload bytes")?,
        })
    } else {
        Err(bad("not a mesh message".into()))
    }
}
