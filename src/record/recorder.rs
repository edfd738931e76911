//! The recorder: a thread of its own writes one MCAP file per session, fed by the tick through bounded
//! lock-free queues. The tick never waits: it pushes plain records (mesh bytes travel in buffers
//! taken from a pool filled at start), and when a queue or the pool is full the record is dropped and
//! counted — reported in the statistics and written as an event, never silent.
//!
//! The file has the protobuf schemas of `proto/palpa.proto` embedded, zstd-compressed chunks closed at
//! least once per simulated second (and by size), so a daemon killed mid-session loses at most the
//! last second; the scene file and the meshes it loaded are attachments. Log times are simulation
//! time (tick × dt); wall-clock receive times are inside the messages.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;

use crossbeam_queue::ArrayQueue;
use prost::Message;

use super::DESCRIPTOR_SET;
use super::proto;
use crate::dynamics::guard::GuardCause;
use crate::ipc::payload::{MESH_KEYFRAME, MeshHeaderV1, StatsV1, ToolFeedbackV1, ToolPoseV1};
use crate::scene::Scene;
use crate::world::World;

/// Longest body name a [`Record::BodyAdded`] carries (bytes).
pub const MAX_BODY_NAME: usize = 96;

/// Records the tick hands to the recorder.
#[derive(Debug)]
pub enum Record {
    /// A pose used for a tool, applied before stepping from `tick`.
    Input {
        /// Tick it applies at.
        tick: u64,
        /// Tool index.
        tool: u16,
        /// The pose as received.
        pose: ToolPoseV1,
        /// CLOCK_MONOTONIC when the daemon read it (ns).
        receive_wall_time_ns: u64,
    },
    /// What a tool felt after a step.
    Feedback {
        /// Tool index.
        tool: u16,
        /// The feedback as published.
        feedback: ToolFeedbackV1,
    },
    /// A mesh message, its bytes in a pooled buffer (layout of `proto/palpa_ipc.h`).
    Mesh {
        /// Header.
        header: MeshHeaderV1,
        /// Bytes.
        data: Vec<u8>,
    },
    /// Loop statistics.
    Stats(StatsV1),
    /// The divergence guard restored a body during the step that ended at `tick`.
    Guard {
        /// Tick.
        tick: u64,
        /// Body index.
        body: u16,
        /// Why.
        cause: GuardCause,
    },
    /// A transection added body `body`, named by the first `len` bytes of `name` (UTF-8).
    BodyAdded {
        /// Tick at whose end it appeared.
        tick: u64,
        /// Its index.
        body: u16,
        /// Its name.
        name: [u8; MAX_BODY_NAME],
        /// Bytes of the name.
        len: u8,
    },
    /// Something that happened.
    Event {
        /// Tick.
        tick: u64,
        /// `proto::event::Kind` value.
        kind: i32,
        /// Tool index, or `u16::MAX`.
        tool: u16,
    },
}

/// Sizes of the recorder's queues and chunks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecorderSettings {
    /// Records the queue holds.
    pub queue_capacity: usize,
    /// Pooled mesh buffers.
    pub mesh_buffers: usize,
    /// Largest uncompressed chunk (bytes).
    pub chunk_bytes: u64,
    /// Ticks between forced chunk closes.
    pub flush_every_ticks: u64,
}

impl Default for RecorderSettings {
    fn default() -> Self {
        Self {
            queue_capacity: 1 << 16,
            mesh_buffers: 64,
            chunk_bytes: 4 << 20,
            flush_every_ticks: 1000,
        }
    }
}

/// What the recorder wrote.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecordingSummary {
    /// Messages written per topic.
    pub messages: BTreeMap<String, u64>,
    /// Records dropped because a queue or the pool was full.
    pub dropped: u64,
}

/// The tick's side of a bounded hand-over of records to a thread of its own (the recorder's writer,
/// the live view's publisher): a lock-free queue of records and a pool of mesh buffers filled at
/// start. Pushing never allocates, and never blocks unless waiting was asked for; a record that does
/// not fit is dropped and counted.
pub struct RecordQueue {
    pub(crate) queue: Arc<ArrayQueue<Record>>,
    pub(crate) pool: Arc<ArrayQueue<Vec<u8>>>,
    pub(crate) dropped: Arc<AtomicU64>,
}

impl RecordQueue {
    /// Room for `capacity` records and `mesh_buffers` mesh messages of up to `mesh_bytes` bytes.
    pub fn new(capacity: usize, mesh_buffers: usize, mesh_bytes: usize) -> Self {
        let pool = Arc::new(ArrayQueue::new(mesh_buffers.max(1)));
        for _ in 0..mesh_buffers.max(1) {
            let _ = pool.push(Vec::with_capacity(mesh_bytes));
        }
        Self {
            queue: Arc::new(ArrayQueue::new(capacity.max(1))),
            pool,
            dropped: Arc::new(AtomicU64::new(0)),
        }
    }

    /// The same queue, for the consuming thread.
    pub(crate) fn share(&self) -> Self {
        Self {
            queue: self.queue.clone(),
            pool: self.pool.clone(),
            dropped: self.dropped.clone(),
        }
    }

    /// Hands `record` over; with `wait` (while `wait` says the consumer still runs) waits for room
    /// instead of dropping. Returns false (and counts it) when it was dropped.
    pub fn push(&self, record: Record, wait: &dyn Fn() -> bool) -> bool {
        let mut record = record;
        loop {
            match self.queue.push(record) {
                Err(rejected) if wait() => {
                    record = rejected;
                    std::thread::yield_now();
                }
                Ok(()) => return true,
                Err(rejected) => {
                    if let Record::Mesh { data, .. } = rejected {
                        let _ = self.pool.push(data);
                    }
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                    return false;
                }
            }
        }
    }

    /// Copies a mesh message into a pooled buffer and hands it over (see [`RecordQueue::push`]);
    /// counts a drop when no buffer is free. Never allocates: buffers were sized for the largest
    /// message at start.
    pub fn push_mesh(&self, header: &MeshHeaderV1, bytes: &[u8], wait: &dyn Fn() -> bool) -> bool {
        let mut buffer = self.pool.pop();
        while buffer.is_none() && wait() {
            std::thread::yield_now();
            buffer = self.pool.pop();
        }
        let Some(mut data) = buffer else {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return false;
        };
        data.clear();
        data.extend_from_slice(bytes);
        self.push(
            Record::Mesh {
                header: *header,
                data,
            },
            wait,
        )
    }

    /// Records dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

/// The largest mesh message `world` can produce (its bodies, and the spare bodies a transection
/// may add), in bytes.
pub fn largest_mesh_message(world: &World) -> usize {
    let (spare_vertices, spare_triangles) = world.spare_mesh_capacity();
    world
        .bodies
        .iter()
        .map(|b| {
            let (vertices, triangles) = b.mesh_capacity();
            crate::display::max_message_bytes(vertices, triangles)
        })
        .chain(std::iter::once(crate::display::max_message_bytes(
            spare_vertices,
            spare_triangles,
        )))
        .max()
        .unwrap_or(0)
}

/// What can go wrong while recording a session.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The recording's file could not be created.
    #[error("cannot create {}: {reason}", path.display())]
    Create {
        /// The file asked for.
        path: std::path::PathBuf,
        /// Why (in the message).
        reason: std::io::Error,
    },
    /// A mesh file the scene loaded could not be read again to be attached.
    #[error("cannot read {}: {reason}", path.display())]
    ReadAsset {
        /// The mesh file.
        path: std::path::PathBuf,
        /// Why (in the message).
        reason: std::io::Error,
    },
    /// Writing the MCAP file failed (what was written before stays readable up to the last
    /// flushed chunk).
    #[error("recording: {0}")]
    Mcap(#[from] mcap::McapError),
    /// The writer thread could not be started.
    #[error("cannot start the recorder thread: {0}")]
    Thread(std::io::Error),
    /// The writer thread panicked.
    #[error("the recorder thread panicked")]
    Panicked,
}

/// The tick side of the recorder.
pub struct Recorder {
    records: RecordQueue,
    done: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<RecordingSummary, RecordError>>>,
    /// Wait for room instead of dropping (an offline run, where no deadline is at stake).
    wait_when_full: bool,
}

impl Recorder {
    /// Makes [`Recorder::push`] and [`Recorder::push_mesh`] wait for the writer when the queue or
    /// the pool is full, instead of dropping the record: for a run that is not real time (`palpa
    /// run`), which may step faster than the writer writes and must lose nothing.
    pub fn waiting_when_full(mut self) -> Self {
        self.wait_when_full = true;
        self
    }

    /// While waiting is on and the writer still runs: lets it work.
    fn can_wait(&self) -> bool {
        self.wait_when_full && self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Creates the file, writes the scene and its assets, and starts the writer thread.
    pub fn start(
        path: &Path,
        scene: &Scene,
        world: &World,
        session: &SessionInfo,
        settings: RecorderSettings,
    ) -> Result<Self, RecordError> {
        let file = File::create(path).map_err(|reason| RecordError::Create {
            path: path.to_path_buf(),
            reason,
        })?;
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_threads(0)
            .chunk_size(Some(settings.chunk_bytes))
            .profile("palpa")
            .library(concat!("palpa ", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::new(file))?;
        let mut channels = Channels::new(&mut writer, world)?;
        let scene_message = scene_record(scene, world, session);
        channels.write(
            &mut writer,
            "/palpa/scene",
            0,
            &scene_message.encode_to_vec(),
        )?;
        attach_assets(&mut writer, scene)?;
        writer.flush()?;

        let records = RecordQueue::new(
            settings.queue_capacity,
            settings.mesh_buffers,
            largest_mesh_message(world),
        );
        let done = Arc::new(AtomicBool::new(false));
        let thread_state = WriterThread {
            records: records.share(),
            done: done.clone(),
            out: McapOut { writer, channels },
            encoder: RecordEncoder::new(world),
            flush_every_ticks: settings.flush_every_ticks.max(1),
        };
        let thread = std::thread::Builder::new()
            .name("palpa-recorder".into())
            .spawn(move || thread_state.run())
            .map_err(RecordError::Thread)?;
        Ok(Self {
            records,
            done,
            thread: Some(thread),
            wait_when_full: false,
        })
    }

    /// Hands a record to the writer; never blocks (unless [`Recorder::waiting_when_full`]). Returns
    /// false (and counts it) when the queue was full.
    pub fn push(&self, record: Record) -> bool {
        self.records.push(record, &|| self.can_wait())
    }

    /// Copies a mesh message into a pooled buffer and hands it over; counts a drop when no buffer
    /// is free. Never allocates: buffers were sized for the largest message at start.
    pub fn push_mesh(&self, header: &MeshHeaderV1, bytes: &[u8]) -> bool {
        self.records.push_mesh(header, bytes, &|| self.can_wait())
    }

    /// Records dropped so far.
    pub fn dropped(&self) -> u64 {
        self.records.dropped()
    }

    /// Drains the queue, writes the summary and closes the file.
    pub fn finish(mut self) -> Result<RecordingSummary, RecordError> {
        self.close()
    }

    fn close(&mut self) -> Result<RecordingSummary, RecordError> {
        self.done.store(true, Ordering::Release);
        match self.thread.take() {
            Some(t) => t.join().map_err(|_| RecordError::Panicked)?,
            None => Ok(RecordingSummary::default()),
        }
    }
}

/// A recorder dropped without [`Recorder::finish`] (an error or a panic unwinding through the
/// session) still drains its queue and writes the summary and footer: every way out of a session
/// leaves a complete file. An error of the writer is printed, as nothing else can report it.
impl Drop for Recorder {
    fn drop(&mut self) {
        if self.thread.is_some()
            && let Err(e) = self.close()
        {
            eprintln!("palpa: {e}");
        }
    }
}

/// Topic → channel id, with the schemas registered.
struct Channels {
    ids: BTreeMap<String, u16>,
    counts: BTreeMap<String, u64>,
    sequence: u32,
}

const TOPIC_SCENE: &str = "/palpa/scene";
const TOPIC_KEYFRAME: &str = "/palpa/mesh/keyframe";
const TOPIC_DELTA: &str = "/palpa/mesh/delta";
/// Topic of the loop statistics.
pub const TOPIC_STATS: &str = "/palpa/stats";
/// Topic of the events.
pub const TOPIC_EVENTS: &str = "/palpa/events";

/// Topic of a tool's inputs.
pub fn input_topic(tool: &str) -> String {
    format!("/palpa/tool/{tool}/input")
}

/// Topic of a tool's feedback.
pub fn feedback_topic(tool: &str) -> String {
    format!("/palpa/tool/{tool}/feedback")
}

impl Channels {
    fn new<W: std::io::Write + std::io::Seek>(
        writer: &mut mcap::Writer<W>,
        world: &World,
    ) -> mcap::McapResult<Self> {
        let mut schema = BTreeMap::new();
        for name in [
            "Scene",
            "ToolInput",
            "Feedback",
            "MeshKeyframe",
            "MeshDelta",
            "Stats",
            "Event",
        ] {
            let id = writer.add_schema(&format!("palpa.{name}"), "protobuf", DESCRIPTOR_SET)?;
            schema.insert(name, id);
        }
        let mut topics: Vec<(String, &str)> = vec![
            (TOPIC_SCENE.into(), "Scene"),
            (TOPIC_KEYFRAME.into(), "MeshKeyframe"),
            (TOPIC_DELTA.into(), "MeshDelta"),
            (TOPIC_STATS.into(), "Stats"),
            (TOPIC_EVENTS.into(), "Event"),
        ];
        for tool in &world.tools {
            topics.push((input_topic(&tool.name), "ToolInput"));
            topics.push((feedback_topic(&tool.name), "Feedback"));
        }
        let mut ids = BTreeMap::new();
        for (topic, message) in topics {
            let id = writer.add_channel(schema[message], &topic, "protobuf", &BTreeMap::new())?;
            ids.insert(topic, id);
        }
        let (name, encoding, data) = super::visual::scene_update_schema();
        let visual_schema = writer.add_schema(&name, &encoding, &data)?;
        let id = writer.add_channel(
            visual_schema,
            super::visual::TOPIC_SCENE_UPDATE,
            "protobuf",
            &BTreeMap::new(),
        )?;
        ids.insert(super::visual::TOPIC_SCENE_UPDATE.to_string(), id);
        Ok(Self {
            ids,
            counts: BTreeMap::new(),
            sequence: 0,
        })
    }

    fn write<W: std::io::Write + std::io::Seek>(
        &mut self,
        writer: &mut mcap::Writer<W>,
        topic: &str,
        log_time: u64,
        data: &[u8],
    ) -> mcap::McapResult<()> {
        let channel_id = self.ids[topic];
        self.sequence = self.sequence.wrapping_add(1);
        writer.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id,
                sequence: self.sequence,
                log_time,
                publish_time: log_time,
            },
            data,
        )?;
        *self.counts.entry(topic.to_string()).or_default() += 1;
        Ok(())
    }
}

/// How a session ran (what replay needs to reproduce it).
#[derive(Clone, Debug, PartialEq)]
pub struct SessionInfo {
    /// "run" or "serve".
    pub mode: String,
    /// Mesh messages per second.
    pub display_rate_hz: f64,
    /// Seconds between periodic keyframes.
    pub keyframe_every_s: f64,
}

/// The scene message of a session.
pub fn scene_record(scene: &Scene, world: &World, session: &SessionInfo) -> proto::Scene {
    proto::Scene {
        mode: session.mode.clone(),
        display_rate_hz: session.display_rate_hz,
        keyframe_every_s: session.keyframe_every_s,
        name: scene.name.clone(),
        source: scene.source.clone(),
        dt: world.params.dt,
        bodies: world.bodies.iter().map(|b| b.name.clone()).collect(),
        tools: world.tools.iter().map(|t| t.name.clone()).collect(),
        systems: world
            .systems()
            .names()
            .into_iter()
            .map(String::from)
            .collect(),
        palpa_version: env!("CARGO_PKG_VERSION").into(),
        body_nodes: world.bodies.iter().map(|b| b.node_count() as u32).collect(),
        body_triangles: world
            .bodies
            .iter()
            .map(|b| b.surface.triangles.len() as u32)
            .collect(),
    }
}

/// Attaches the scene text and every mesh file it loaded, named by their path relative to the scene.
fn attach_assets<W: std::io::Write + std::io::Seek>(
    writer: &mut mcap::Writer<W>,
    scene: &Scene,
) -> Result<(), RecordError> {
    writer.attach(&mcap::Attachment {
        log_time: 0,
        create_time: 0,
        name: "scene.toml".into(),
        media_type: "application/toml".into(),
        data: std::borrow::Cow::Borrowed(scene.source.as_bytes()),
    })?;
    for (relative, path) in &scene.asset_names {
        let data = std::fs::read(path).map_err(|reason| RecordError::ReadAsset {
            path: path.clone(),
            reason,
        })?;
        writer.attach(&mcap::Attachment {
            log_time: 0,
            create_time: 0,
            name: relative.clone(),
            media_type: "model/obj".into(),
            data: std::borrow::Cow::Owned(data),
        })?;
    }
    Ok(())
}

fn vec3(v: [f64; 3]) -> Option<proto::Vec3> {
    Some(proto::Vec3 {
        x: v[0],
        y: v[1],
        z: v[2],
    })
}

/// The protobuf message of a feedback record (what replay re-encodes to compare).
pub fn feedback_message(tool: &str, feedback: &ToolFeedbackV1) -> proto::Feedback {
    proto::Feedback {
        tick: feedback.tick,
        tool: tool.into(),
        force: vec3(feedback.force),
        torque: vec3(feedback.torque),
        contacts: feedback.contacts,
        flags: feedback.flags,
        seq: feedback.seq,
    }
}

/// The protobuf message of a mesh record: a keyframe or a delta, from the IPC layout bytes.
pub fn mesh_message(header: &MeshHeaderV1, data: &[u8]) -> (bool, Vec<u8>) {
    let f32_at = |at: usize| f32::from_le_bytes(data[at..at + 4].try_into().expect("four bytes"));
    let u32_at = |at: usize| u32::from_le_bytes(data[at..at + 4].try_into().expect("four bytes"));
    if header.kind == MESH_KEYFRAME {
        let n = header.vertex_count as usize;
        let t = header.triangle_count as usize;
        let message = proto::MeshKeyframe {
            tick: header.tick,
            body: header.body,
            positions: (0..3 * n).map(|k| f32_at(4 * k)).collect(),
            triangles: (0..3 * t).map(|k| u32_at(12 * n + 4 * k)).collect(),
        };
        (true, message.encode_to_vec())
    } else {
        let c = header.changed_count as usize;
        let message = proto::MeshDelta {
            tick: header.tick,
            body: header.body,
            base_tick: header.base_tick,
            vertex_count: header.vertex_count,
            vertices: (0..c).map(|e| u32_at(16 * e)).collect(),
            positions: (0..c)
                .flat_map(|e| (0..3).map(move |k| (e, k)))
                .map(|(e, k)| f32_at(16 * e + 4 + 4 * k))
                .collect(),
        };
        (false, message.encode_to_vec())
    }
}

/// The protobuf message of a statistics record.
pub fn stats_message(s: &StatsV1, dropped: u64) -> proto::Stats {
    proto::Stats {
        tick: s.tick,
        window_ticks: s.window_ticks,
        compute_min_us: s.compute_min_us,
        compute_mean_us: s.compute_mean_us,
        compute_max_us: s.compute_max_us,
        compute_p99_us: s.compute_p99_us,
        lateness_mean_us: s.lateness_mean_us,
        lateness_max_us: s.lateness_max_us,
        synchronicity_misses: s.synchronicity_misses,
        rejected_inputs: s.rejected_inputs,
        disconnects: s.disconnects,
        active_systems: s.active_systems,
        tools_connected: s.tools_connected,
        paused: s.paused != 0,
        dropped_records: dropped,
        stability_margin: s.stability_margin,
        guard_events: s.guard_events,
        ipc_errors: s.ipc_errors,
    }
}

/// Where the messages a session's records make go: an MCAP file, or the live view's channels.
pub trait MessageOut {
    /// Whether messages of `topic` are wanted (those of a topic that is not are neither encoded nor
    /// written).
    fn wants(&self, topic: &str) -> bool;
    /// Writes one encoded message of `topic`, at `log_time` (ns of simulation time).
    fn write(&mut self, topic: &str, log_time: u64, data: &[u8]) -> Result<(), RecordError>;
}

/// The MCAP file of a recording.
struct McapOut {
    writer: mcap::Writer<BufWriter<File>>,
    channels: Channels,
}

impl MessageOut for McapOut {
    fn wants(&self, _topic: &str) -> bool {
        true
    }

    fn write(&mut self, topic: &str, log_time: u64, data: &[u8]) -> Result<(), RecordError> {
        Ok(self
            .channels
            .write(&mut self.writer, topic, log_time, data)?)
    }
}

/// Turns the records the tick hands over into the session's messages: the protobuf messages of
/// `proto/palpa.proto` and, at display rate, the `foxglove.SceneUpdate` of the scene. Shared by the
/// recorder and the live view, so a live viewer sees what a recording holds.
pub struct RecordEncoder {
    dt_ns: u64,
    tool_names: Vec<String>,
    body_names: Vec<String>,
    visual: super::visual::VisualState,
}

impl RecordEncoder {
    /// For a session of `world` (its tools and bodies at start).
    pub fn new(world: &World) -> Self {
        Self {
            dt_ns: (world.params.dt * 1e9).round() as u64,
            tool_names: world.tools.iter().map(|t| t.name.clone()).collect(),
            body_names: world.bodies.iter().map(|b| b.name.clone()).collect(),
            visual: super::visual::VisualState::new(
                world.bodies.len(),
                world.tools.iter().map(|t| t.shape.clone()).collect(),
            ),
        }
    }

    /// Nanoseconds of simulation time per tick.
    pub fn dt_ns(&self) -> u64 {
        self.dt_ns
    }

    fn tool_name(&self, tool: u16) -> String {
        self.tool_names
            .get(tool as usize)
            .cloned()
            .unwrap_or_default()
    }

    /// Writes the event that `count` records were dropped, at `tick`.
    pub fn write_dropped(
        &mut self,
        out: &mut dyn MessageOut,
        tick: u64,
        count: u64,
    ) -> Result<(), RecordError> {
        let event = proto::Event {
            tick,
            kind: proto::event::Kind::RecordDropped as i32,
            tool: String::new(),
            detail: format!("{count} records dropped (queue or mesh pool full)"),
            ..proto::Event::default()
        };
        self.write_event(out, &event).map(|_| ())
    }

    /// Writes an event on the events channel at its tick; returns the tick.
    fn write_event(
        &mut self,
        out: &mut dyn MessageOut,
        message: &proto::Event,
    ) -> Result<u64, RecordError> {
        if out.wants(TOPIC_EVENTS) {
            out.write(
                TOPIC_EVENTS,
                message.tick * self.dt_ns,
                &message.encode_to_vec(),
            )?;
        }
        Ok(message.tick)
    }

    /// Encodes one record into `out` (a mesh record's buffer goes back to `pool`); `dropped` is the
    /// drop count the statistics carry. Returns the record's tick.
    pub fn encode(
        &mut self,
        record: Record,
        pool: &ArrayQueue<Vec<u8>>,
        dropped: u64,
        out: &mut dyn MessageOut,
    ) -> Result<u64, RecordError> {
        let dt = self.dt_ns;
        match record {
            Record::Input {
                tick,
                tool,
                pose,
                receive_wall_time_ns,
            } => {
                let name = self.tool_name(tool);
                let [w, x, y, z] = pose.orientation;
                self.visual.set_tool_pose(
                    tool as usize,
                    crate::tool::ToolPose {
                        position_in_world: pose.position.into(),
                        world_from_tool: nalgebra::UnitQuaternion::from_quaternion(
                            nalgebra::Quaternion::new(w, x, y, z),
                        ),
                    },
                );
                let topic = input_topic(&name);
                if out.wants(&topic) {
                    let message = proto::ToolInput {
                        tick,
                        tool: name,
                        position: vec3(pose.position),
                        orientation: Some(proto::Quaternion { w, x, y, z }),
                        jaw: pose.jaw,
                        seq: pose.seq,
                        device_time_ns: pose.device_time_ns,
                        receive_wall_time_ns,
                        buttons: pose.buttons,
                    };
                    out.write(&topic, tick * dt, &message.encode_to_vec())?;
                }
                Ok(tick)
            }
            Record::Feedback { tool, feedback } => {
                let name = self.tool_name(tool);
                self.visual
                    .set_tool_force(tool as usize, feedback.force.into());
                let topic = feedback_topic(&name);
                if out.wants(&topic) {
                    let message = feedback_message(&name, &feedback);
                    out.write(&topic, feedback.tick * dt, &message.encode_to_vec())?;
                }
                Ok(feedback.tick)
            }
            Record::Mesh { header, data } => {
                let payload = &data[..header.payload_bytes as usize];
                let display_tick_done = self.visual.apply_mesh(&header, payload);
                let topic = if header.kind == MESH_KEYFRAME {
                    TOPIC_KEYFRAME
                } else {
                    TOPIC_DELTA
                };
                let written = if out.wants(topic) {
                    let (_, bytes) = mesh_message(&header, payload);
                    out.write(topic, header.tick * dt, &bytes)
                } else {
                    Ok(())
                };
                let _ = pool.push(data);
                written?;
                if display_tick_done && out.wants(super::visual::TOPIC_SCENE_UPDATE) {
                    let time = header.tick * dt;
                    let update = self
                        .visual
                        .scene_update(time, &self.body_names, &self.tool_names);
                    out.write(super::visual::TOPIC_SCENE_UPDATE, time, &update)?;
                }
                Ok(header.tick)
            }
            Record::Stats(stats) => {
                if out.wants(TOPIC_STATS) {
                    let message = stats_message(&stats, dropped);
                    out.write(TOPIC_STATS, stats.tick * dt, &message.encode_to_vec())?;
                }
                Ok(stats.tick)
            }
            Record::Guard { tick, body, cause } => {
                let name = self
                    .body_names
                    .get(body as usize)
                    .cloned()
                    .unwrap_or_default();
                let message = proto::Event {
                    tick,
                    kind: proto::event::Kind::DivergenceGuard as i32,
                    tool: String::new(),
                    detail: format!("body {name}: {cause:?}"),
                    body: body as u32,
                    body_name: name,
                };
                self.write_event(out, &message)
            }
            Record::BodyAdded {
                tick,
                body,
                name,
                len,
            } => {
                let name = String::from_utf8_lossy(&name[..len as usize]).into_owned();
                if body as usize >= self.body_names.len() {
                    self.body_names.resize(body as usize + 1, String::new());
                }
                self.body_names[body as usize] = name.clone();
                self.visual.ensure_bodies(body as usize + 1);
                let message = proto::Event {
                    tick,
                    kind: proto::event::Kind::BodyAdded as i32,
                    body: body as u32,
                    body_name: name,
                    ..proto::Event::default()
                };
                self.write_event(out, &message)
            }
            Record::Event { tick, kind, tool } => {
                let message = proto::Event {
                    tick,
                    kind,
                    tool: if tool == u16::MAX {
                        String::new()
                    } else {
                        self.tool_name(tool)
                    },
                    ..proto::Event::default()
                };
                self.write_event(out, &message)
            }
        }
    }
}

struct WriterThread {
    records: RecordQueue,
    done: Arc<AtomicBool>,
    out: McapOut,
    encoder: RecordEncoder,
    flush_every_ticks: u64,
}

impl WriterThread {
    fn run(mut self) -> Result<RecordingSummary, RecordError> {
        let mut last_flush_tick = 0u64;
        let mut reported_drops = 0u64;
        loop {
            let finishing = self.done.load(Ordering::Acquire);
            let mut wrote = false;
            while let Some(record) = self.records.queue.pop() {
                wrote = true;
                let tick = self.encoder.encode(
                    record,
                    &self.records.pool,
                    self.records.dropped(),
                    &mut self.out,
                )?;
                if tick >= last_flush_tick + self.flush_every_ticks {
                    // Close the chunk: what is on disk stays readable if the process dies now.
                    self.out.writer.flush()?;
                    last_flush_tick = tick;
                }
            }
            let dropped = self.records.dropped();
            if dropped > reported_drops {
                self.encoder.write_dropped(
                    &mut self.out,
                    last_flush_tick,
                    dropped - reported_drops,
                )?;
                reported_drops = dropped;
            }
            if finishing && self.records.queue.is_empty() {
                break;
            }
            if !wrote {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
        self.out.writer.finish()?;
        Ok(RecordingSummary {
            messages: self.out.channels.counts,
            dropped: self.records.dropped(),
        })
    }
}

/// Where a scene's asset should go when a recording is unpacked: `relative` joined to `dir`.
pub fn asset_path(dir: &Path, relative: &str) -> PathBuf {
    dir.join(relative)
}
