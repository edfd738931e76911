//! Reading recordings back, and replaying them: rebuild the scene from the recording, feed the
//! recorded inputs tick by tick, and compare every feedback and mesh message bit for bit.
//!
//! Reading scans the file record by record (chunks decompressed in order), so a recording cut short
//! by a crash is read up to its last complete chunk, without a summary section.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use prost::Message;

use super::proto;
use super::recorder::{feedback_message, mesh_message};
use crate::Vec3;
use crate::daemon::feedback_payload;
use crate::daemon::sink::event;
use crate::display::MeshSchedule;
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
    /// The file ended properly (footer read); false for a file cut short.
    pub complete: bool,
}

/// Reads a recording from its bytes; a damaged tail ends the reading (the recording is then marked
/// incomplete), damage before the first message is an error.
pub fn read_recording(bytes: &[u8]) -> Result<Recording, String> {
    let options = mcap::read::Options::IgnoreEndMagic;
    let reader = mcap::read::ChunkFlattener::new_with_options(bytes, options.into())
        .map_err(|e| e.to_string())?;
    let mut topics: BTreeMap<u16, String> = BTreeMap::new();
    let mut recording = Recording::default();
    let mut scene = None;
    for record in reader {
        let record = match record {
            Ok(r) => r,
            Err(_) => break,
        };
        match record {
            mcap::records::Record::Channel(channel) => {
                topics.insert(channel.id, channel.topic.clone());
            }
            mcap::records::Record::Message { header, data } => {
                let topic = topics.get(&header.channel_id).cloned().unwrap_or_default();
                if topic == "/palpa/scene" && scene.is_none() {
                    scene = Some(proto::Scene::decode(&data[..]).map_err(|e| e.to_string())?);
                }
                recording.messages.push(RecordedMessage {
                    topic,
                    log_time: header.log_time,
                    data: data.into_owned(),
                });
            }
            mcap::records::Record::Attachment { header, data, .. } => {
                recording
                    .attachments
                    .push((header.name.clone(), data.into_owned()));
            }
            mcap::records::Record::Footer(_) => recording.complete = true,
            _ => {}
        }
    }
    recording.scene = scene.ok_or("the recording has no /palpa/scene message")?;
    Ok(recording)
}

/// Reads a recording file.
pub fn read_recording_file(path: &Path) -> Result<Recording, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    read_recording(&bytes).map_err(|e| format!("{}: {e}", path.display()))
}

/// Message counts per topic and session figures.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SessionSummary {
    /// Messages per topic.
    pub messages: BTreeMap<String, u64>,
    /// Last simulated tick recorded.
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
}

/// Summarises a recording.
pub fn summarise(recording: &Recording) -> SessionSummary {
    let mut s = SessionSummary {
        tools: recording.scene.tools.clone(),
        complete: recording.complete,
        ..SessionSummary::default()
    };
    for m in &recording.messages {
        *s.messages.entry(m.topic.clone()).or_default() += 1;
        s.ticks = s
            .ticks
            .max((m.log_time as f64 / (recording.scene.dt * 1e9)).round() as u64);
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
                _ => {}
            }
        }
    }
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

/// Unpacks the scene and its meshes into `dir` (the scene nested deep enough for every relative
/// mesh path to stay inside `dir`) and loads it.
fn rebuild_scene(recording: &Recording, dir: &Path) -> Result<crate::scene::Scene, String> {
    let depth = recording
        .attachments
        .iter()
        .map(|(name, _)| {
            Path::new(name)
                .components()
                .take_while(|c| matches!(c, std::path::Component::ParentDir))
                .count()
        })
        .max()
        .unwrap_or(0);
    let mut scene_dir = dir.to_path_buf();
    for k in 0..depth {
        scene_dir.push(format!("s{k}"));
    }
    std::fs::create_dir_all(&scene_dir).map_err(|e| e.to_string())?;
    for (name, data) in &recording.attachments {
        if name == "scene.toml" {
            continue;
        }
        let target: PathBuf = scene_dir.join(name);
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent).map_err(|e| e.to_string())?;
        }
        std::fs::write(&target, data).map_err(|e| e.to_string())?;
    }
    parse_scene(&recording.scene.source, &recording.scene.name, &scene_dir)
        .map_err(|e| e.to_string())
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

/// Replays a recording and compares every feedback and mesh message with the recorded one;
/// `progress(tick, last)` is called every 1000 ticks.
pub fn verify(
    recording: &Recording,
    work_dir: &Path,
    mut progress: impl FnMut(u64, u64),
) -> Result<VerifyReport, VerifyError> {
    let scene = rebuild_scene(recording, work_dir).map_err(VerifyError::Scene)?;
    let mut world = World::from_scene(&scene);
    let session = &recording.scene;
    let mut meshes = MeshSchedule::new(&world, session.display_rate_hz, session.keyframe_every_s);
    let serve_mode = session.mode == "serve";
    let tool_index: BTreeMap<String, usize> = world
        .tools
        .iter()
        .enumerate()
        .map(|(i, t)| (t.name.clone(), i))
        .collect();
    // Every tool is driven by the recorded poses; a scripted tool keeps its starting pose and state.
    let drive = |world: &mut World| {
        for tool in &mut world.tools {
            tool.input = ToolInput::Ipc;
        }
    };
    drive(&mut world);

    // Inputs and events by tick, outputs in order.
    let mut inputs: BTreeMap<u64, Vec<proto::ToolInput>> = BTreeMap::new();
    let mut events: BTreeMap<u64, Vec<proto::Event>> = BTreeMap::new();
    let mut outputs: Vec<&RecordedMessage> = Vec::new();
    for m in &recording.messages {
        if m.topic.ends_with("/input") {
            let i = proto::ToolInput::decode(&m.data[..])
                .map_err(|e| VerifyError::Scene(e.to_string()))?;
            inputs.entry(i.tick).or_default().push(i);
        } else if m.topic == "/palpa/events" {
            let e =
                proto::Event::decode(&m.data[..]).map_err(|e| VerifyError::Scene(e.to_string()))?;
            events.entry(e.tick).or_default().push(e);
        } else if m.topic.ends_with("/feedback") || m.topic.starts_with("/palpa/mesh/") {
            outputs.push(m);
        }
    }
    let tick_of = |m: &RecordedMessage| (m.log_time as f64 / (session.dt * 1e9)).round() as u64;
    let last = outputs.last().map_or(0, |m| tick_of(m));
    let tools = world.tools.len();
    let mut connected: Vec<bool> = world.tools.iter().map(|t| t.active).collect();
    let mut echo = vec![(0u64, 0u64); tools];
    let mut report = VerifyReport {
        digest: 0xcbf29ce484222325,
        ..VerifyReport::default()
    };
    let mut next = 0usize;
    // The keyframe at tick 0 (and whatever else was recorded before the first step).
    let check_outputs_at = |world: &World,
                            meshes: &mut MeshSchedule,
                            connected: &[bool],
                            rejected: &[bool],
                            echo: &[(u64, u64)],
                            next: &mut usize,
                            report: &mut VerifyReport|
     -> Result<(), VerifyError> {
        let tick = world.tick;
        let mut mesh_produced: Vec<(bool, Vec<u8>)> = Vec::new();
        let wants_keyframe = outputs[*next..]
            .iter()
            .take_while(|m| tick_of(m) == tick)
            .any(|m| m.topic == "/palpa/mesh/keyframe");
        if wants_keyframe {
            meshes.request_keyframe();
        }
        let _ = meshes.produce(world, |header, bytes| -> Result<(), ()> {
            mesh_produced.push(mesh_message(header, bytes));
            Ok(())
        });
        let mut mesh_cursor = 0;
        while *next < outputs.len() && tick_of(outputs[*next]) == tick {
            let m = outputs[*next];
            *next += 1;
            let replayed: Vec<u8> = if m.topic.ends_with("/feedback") {
                let name = m
                    .topic
                    .trim_start_matches("/palpa/tool/")
                    .trim_end_matches("/feedback");
                let Some(&t) = tool_index.get(name) else {
                    return Err(VerifyError::Differs(Difference {
                        tick,
                        channel: m.topic.clone(),
                        field: "tool".into(),
                        recorded: name.into(),
                        replayed: "(no such tool)".into(),
                    }));
                };
                let payload =
                    feedback_payload(&world.tools[t], tick, connected[t], rejected[t], echo[t]);
                report.feedback += 1;
                feedback_message(name, &payload).encode_to_vec()
            } else {
                report.meshes += 1;
                match mesh_produced.get(mesh_cursor) {
                    Some((_, bytes)) => {
                        mesh_cursor += 1;
                        bytes.clone()
                    }
                    None => Vec::new(),
                }
            };
            fnv(&mut report.digest, &replayed);
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
    };
    let no_rejections = vec![false; tools];
    check_outputs_at(
        &world,
        &mut meshes,
        &connected,
        &no_rejections,
        &echo,
        &mut next,
        &mut report,
    )?;
    while world.tick < last {
        let tick = world.tick;
        let mut rejected = vec![false; tools];
        if let Some(list) = events.get(&tick) {
            for e in list.iter().filter(|e| e.kind == event::RESET) {
                let _ = e;
                world = World::from_scene(&scene);
                drive(&mut world);
                meshes.reset(&world);
                connected = world.tools.iter().map(|t| t.active).collect();
            }
        }
        if let Some(list) = inputs.get(&tick) {
            for input in list {
                let Some(&t) = tool_index.get(input.tool.as_str()) else {
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
                world.tools[t].set_target(pose, input.jaw.max(0.0));
                connected[t] = true;
                echo[t] = if serve_mode {
                    (input.seq, input.device_time_ns)
                } else {
                    (0, 0)
                };
            }
        }
        if let Some(list) = events.get(&tick) {
            for e in list {
                let Some(&t) = tool_index.get(e.tool.as_str()) else {
                    continue;
                };
                match e.kind {
                    event::INPUT_REJECTED => rejected[t] = true,
                    event::DISCONNECT => {
                        world.tools[t].deactivate();
                        connected[t] = false;
                    }
                    _ => {}
                }
            }
        }
        if !serve_mode {
            for (t, tool) in world.tools.iter().enumerate() {
                connected[t] = tool.active || connected[t];
            }
        }
        world.step();
        if !serve_mode {
            for (t, tool) in world.tools.iter().enumerate() {
                connected[t] = tool.active;
            }
        }
        report.ticks += 1;
        check_outputs_at(
            &world,
            &mut meshes,
            &connected,
            &rejected,
            &echo,
            &mut next,
            &mut report,
        )?;
        if world.tick % 1000 == 0 {
            progress(world.tick, last);
        }
    }
    if next < outputs.len() {
        let m = outputs[next];
        return Err(VerifyError::Differs(Difference {
            tick: tick_of(m),
            channel: m.topic.clone(),
            field: "(message)".into(),
            recorded: "present".into(),
            replayed: "not produced".into(),
        }));
    }
    Ok(report)
}

/// Why a replay failed.
#[derive(Clone, Debug, PartialEq)]
pub enum VerifyError {
    /// The scene could not be rebuilt, or a message could not be decoded.
    Scene(String),
    /// Replay produced a different message.
    Differs(Difference),
}

impl std::fmt::Display for VerifyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            VerifyError::Scene(e) => write!(f, "cannot replay: {e}"),
            VerifyError::Differs(d) => write!(f, "{d}"),
        }
    }
}

/// Writes a recording (its scene, attachments and messages) to a new MCAP file — used to make
/// altered copies in tests and to repair truncated files.
pub fn write_recording(recording: &Recording, path: &Path) -> Result<(), String> {
    let file = std::fs::File::create(path).map_err(|e| e.to_string())?;
    let mut writer = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_threads(0)
        .profile("palpa")
        .create(std::io::BufWriter::new(file))
        .map_err(|e| e.to_string())?;
    let mut channels: BTreeMap<String, u16> = BTreeMap::new();
    for m in &recording.messages {
        if !channels.contains_key(&m.topic) {
            let message = message_type_of(&m.topic);
            let schema = writer
                .add_schema(
                    &format!("palpa.{message}"),
                    "protobuf",
                    super::DESCRIPTOR_SET,
                )
                .map_err(|e| e.to_string())?;
            let id = writer
                .add_channel(schema, &m.topic, "protobuf", &BTreeMap::new())
                .map_err(|e| e.to_string())?;
            channels.insert(m.topic.clone(), id);
        }
    }
    for (name, data) in &recording.attachments {
        writer
            .attach(&mcap::Attachment {
                log_time: 0,
                create_time: 0,
                name: name.clone(),
                media_type: "application/octet-stream".into(),
                data: std::borrow::Cow::Borrowed(data),
            })
            .map_err(|e| e.to_string())?;
    }
    for (k, m) in recording.messages.iter().enumerate() {
        writer
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: channels[&m.topic],
                    sequence: k as u32,
                    log_time: m.log_time,
                    publish_time: m.log_time,
                },
                &m.data,
            )
            .map_err(|e| e.to_string())?;
    }
    writer.finish().map_err(|e| e.to_string())?;
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
