//! Fuzz targets as property tests over arbitrary bytes (cargo-fuzz needs a nightly toolchain): the
//! recording reader, the scene parser, the OBJ loader, the pose checks of the IPC input, the
//! mesh-stream decoder, the little-endian payloads `palpa-zenoh` reads and the live view's handling
//! of upgrade requests each take any input and return a value or a clear error — never a panic, an
//! abort or an allocation the input cannot account for.
//!
//! Every target runs `PALPA_FUZZ_CASES` cases (default 4096: about a second each in release on two
//! cores); proptest's seed is fixed per target through its `rng_seed`, so a run is reproducible.

use std::path::Path;
use std::sync::OnceLock;

use palpa::daemon::input::{InputLimits, ToolInputState};
use palpa::display::{DisplayMesh, MeshEncoder, max_message_bytes};
use palpa::ipc::payload::{MESH_DELTA, MESH_KEYFRAME, MeshHeaderV1, ToolPoseV1};
use palpa::record::proto;
use palpa::record::reader::MAGIC;
use palpa::record::replay::{
    RecordedMessage, Recording, mesh_payload, read_recording, summarise, write_recording,
};
use palpa::scene::mesh::{icosphere, parse_obj};
use palpa::scene::{SceneError, parse_scene};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use prost::Message;

fn cases() -> u32 {
    std::env::var("PALPA_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(4096)
}

fn config(seed: u64) -> Config {
    Config {
        cases: cases(),
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..Config::default()
    }
}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

// ---------------------------------------------------------------------------------------------
// Recordings

/// A small valid recording (scene, inputs, feedback, a keyframe and deltas), zstd-chunked as the
/// recorder writes it, made once.
fn seed_recording() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| {
        let source = std::fs::read_to_string(repo().join("scenes/probe_press.toml")).unwrap();
        let scene = proto::Scene {
            name: "probe_press.toml".into(),
            source: source.clone(),
            dt: 0.001,
            tools: vec!["probe".into()],
            mode: "run".into(),
            display_rate_hz: 60.0,
            keyframe_every_s: 1.0,
            ..Default::default()
        };
        let mut messages = vec![RecordedMessage {
            topic: "/palpa/scene".into(),
            log_time: 0,
            data: scene.encode_to_vec(),
        }];
        for tick in 0..40u64 {
            let input = proto::ToolInput {
                tick,
                tool: "probe".into(),
                position: Some(proto::Vec3 {
                    x: 0.0,
                    y: 0.0,
                    z: 0.1 - tick as f64 * 1e-4,
                }),
                orientation: Some(proto::Quaternion {
                    w: 1.0,
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                }),
                seq: tick + 1,
                ..Default::default()
            };
            messages.push(RecordedMessage {
                topic: "/palpa/tool/probe/input".into(),
                log_time: tick * 1_000_000,
                data: input.encode_to_vec(),
            });
            let feedback = proto::Feedback {
                tick,
                tool: "probe".into(),
                contacts: (tick % 3) as u32,
                ..Default::default()
            };
            messages.push(RecordedMessage {
                topic: "/palpa/tool/probe/feedback".into(),
                log_time: tick * 1_000_000,
                data: feedback.encode_to_vec(),
            });
            let mesh = if tick == 0 {
                (
                    "/palpa/mesh/keyframe",
                    proto::MeshKeyframe {
                        tick,
                        body: 0,
                        positions: vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                        triangles: vec![0, 1, 2],
                    }
                    .encode_to_vec(),
                )
            } else {
                (
                    "/palpa/mesh/delta",
                    proto::MeshDelta {
                        tick,
                        body: 0,
                        base_tick: tick - 1,
                        vertex_count: 3,
                        vertices: vec![1],
                        positions: vec![1.0, tick as f32, 0.0],
                    }
                    .encode_to_vec(),
                )
            };
            messages.push(RecordedMessage {
                topic: mesh.0.into(),
                log_time: tick * 1_000_000,
                data: mesh.1,
            });
        }
        let recording = Recording {
            scene,
            attachments: vec![("scene.toml".into(), source.into_bytes())],
            messages,
            complete: true,
            damage: None,
        };
        let path = std::env::temp_dir().join(format!("palpa-fuzz-{}.mcap", std::process::id()));
        write_recording(&recording, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::remove_file(path).ok();
        bytes
    })
}

/// Reads a recording and uses everything a reader of it uses; `Ok` or a located error.
fn exercise_recording(bytes: &[u8]) {
    match read_recording(bytes) {
        Ok(recording) => {
            let summary = summarise(&recording);
            assert!(summary.messages.values().sum::<u64>() <= recording.messages.len() as u64);
            if let Some(damage) = &recording.damage {
                assert!(damage.offset <= bytes.len() as u64);
                assert!(!damage.to_string().is_empty());
            }
            let mut payload = Vec::new();
            for m in recording
                .messages
                .iter()
                .filter(|m| m.topic.starts_with("/palpa/mesh/"))
            {
                match mesh_payload(m, &mut payload) {
                    Ok(header) => {
                        // What the player publishes, a display can apply (or refuse) safely.
                        let mut display = DisplayMesh::default();
                        let _ = display.apply(&header, &payload);
                    }
                    Err(e) => assert!(!e.to_string().is_empty()),
                }
            }
        }
        Err(damage) => {
            assert!(damage.offset <= bytes.len() as u64, "{damage}");
            assert!(!damage.to_string().is_empty());
        }
    }
}

/// An edit of a valid recording: flipped bytes, a cut, a u64 field made huge.
#[derive(Clone, Debug)]
enum Edit {
    Flip { at: usize, mask: u8 },
    Cut { at: usize },
    Huge { at: usize, value: u64 },
}

fn apply(bytes: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    for edit in edits {
        match *edit {
            Edit::Flip { at, mask } => {
                let n = out.len();
                if n > 0 {
                    out[at % n] ^= mask.max(1);
                }
            }
            Edit::Cut { at } => {
                let n = out.len();
                out.truncate(at % (n + 1));
            }
            Edit::Huge { at, value } => {
                let n = out.len();
                if n >= 8 {
                    let at = at % (n - 7);
                    out[at..at + 8].copy_from_slice(&value.to_le_bytes());
                }
            }
        }
    }
    out
}

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    let huge = prop_oneof![
        Just(u64::MAX),
        Just(5_000_470_302_814_682_325u64),
        Just(1u64 << 32),
        Just(u64::from(u32::MAX)),
        any::<u64>(),
    ];
    let edit = prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(at, mask)| Edit::Flip { at, mask }),
        any::<usize>().prop_map(|at| Edit::Cut { at }),
        (any::<usize>(), huge).prop_map(|(at, value)| Edit::Huge { at, value }),
    ];
    prop::collection::vec(edit, 1..6)
}

/// Records with valid framing and arbitrary bodies: opcode, a length that may lie, bytes.
fn framed_records() -> impl Strategy<Value = Vec<u8>> {
    let record = (
        prop_oneof![1u8..=15, any::<u8>()],
        prop::collection::vec(any::<u8>(), 0..64),
        prop_oneof![Just(None), any::<u64>().prop_map(Some)],
    );
    prop::collection::vec(record, 0..12).prop_map(|records| {
        let mut out = MAGIC.to_vec();
        for (opcode, body, length) in records {
            out.push(opcode);
            out.extend_from_slice(&length.unwrap_or(body.len() as u64).to_le_bytes());
            out.extend_from_slice(&body);
        }
        out
    })
}

#[test]
fn fuzz_recording_reader() {
    let seed = seed_recording();
    // The untouched seed reads back whole.
    let whole = read_recording(seed).unwrap();
    assert!(whole.complete && whole.damage.is_none());
    assert_eq!(whole.messages.len(), 121);
    proptest!(config(1), |(edits in edits())| {
        exercise_recording(&apply(seed, &edits));
    });
    proptest!(config(2), |(bytes in framed_records())| {
        exercise_recording(&bytes);
    });
    proptest!(config(3), |(bytes in prop::collection::vec(any::<u8>(), 0..512))| {
        exercise_recording(&bytes);
    });
}

// ---------------------------------------------------------------------------------------------
// Scenes

fn scene_texts() -> &'static [(String, String)] {
    static TEXTS: OnceLock<Vec<(String, String)>> = OnceLock::new();
    TEXTS.get_or_init(|| {
        let mut texts = Vec::new();
        for dir in ["scenes", "scenes/stress"] {
            let mut entries: Vec<_> = std::fs::read_dir(repo().join(dir))
                .unwrap()
                .map(|e| e.unwrap().path())
                .filter(|p| p.extension().is_some_and(|e| e == "toml"))
                .collect();
            entries.sort();
            for path in entries {
                texts.push((dir.to_string(), std::fs::read_to_string(&path).unwrap()));
            }
        }
        texts
    })
}

/// Parses scene text; an error names a line and column inside the text.
fn exercise_scene(text: &str, dir: &str) {
    match parse_scene(text, "fuzz.toml", &repo().join(dir)) {
        Ok(scene) => assert!(scene.bodies.iter().all(|b| b.mesh.vertex_count() > 0)),
        Err(SceneError::At {
            path,
            line,
            column,
            message,
        }) => {
            assert_eq!(path, "fuzz.toml");
            assert!(line >= 1 && line <= text.lines().count() + 1, "line {line}");
            assert!(column >= 1);
            assert!(!message.is_empty());
        }
        Err(e) => panic!("a parse of text gave {e}"),
    }
}

#[test]
fn fuzz_scene_parser() {
    let texts = scene_texts();
    assert!(texts.len() >= 10);
    proptest!(config(4), |(bytes in prop::collection::vec(any::<u8>(), 0..256))| {
        exercise_scene(&String::from_utf8_lossy(&bytes), "scenes");
    });
    let tokens = prop_oneof![
        Just("1e308"),
        Just("-1"),
        Just("nan"),
        Just("inf"),
        Just("0"),
        Just("7"),
        Just("9999999999"),
        Just("[]"),
        Just("{}"),
        Just("\"\""),
        Just("["),
        Just("=]"),
        Just("\u{e9}"),
        Just("[[body]]"),
        Just("subdivisions = 8"),
        Just("\n"),
        Just("#"),
        Just("\""),
    ];
    proptest!(config(5), |(
        which in any::<usize>(),
        edits in prop::collection::vec((any::<usize>(), tokens, any::<bool>()), 1..4),
    )| {
        let (dir, text) = &texts[which % texts.len()];
        let mut text = text.clone();
        for (at, token, replace_word) in edits {
            let mut at = at % (text.len() + 1);
            while !text.is_char_boundary(at) {
                at -= 1;
            }
            if replace_word {
                // Replace the word (number, key, value) at `at`.
                let end = text[at..]
                    .find(|c: char| c.is_whitespace() || ",]}".contains(c))
                    .map_or(text.len(), |k| at + k);
                text.replace_range(at..end, token);
            } else {
                text.insert_str(at, token);
            }
        }
        exercise_scene(&text, dir);
    });
}

// ---------------------------------------------------------------------------------------------
// OBJ meshes

fn obj_text() -> &'static str {
    static TEXT: OnceLock<String> = OnceLock::new();
    TEXT.get_or_init(|| {
        let mesh = icosphere(0.05, 1);
        let mut text = String::from("# icosphere\no sphere\n");
        for p in &mesh.positions_in_body {
            text.push_str(&format!("v {} {} {}\n", p.x as f32, p.y as f32, p.z as f32));
        }
        text.push_str("vt 0 0\nvt 1 0\nvn 0 0 1\n");
        for (k, t) in mesh.triangles.iter().enumerate() {
            if k % 2 == 0 {
                text.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
            } else {
                text.push_str(&format!(
                    "f {}/1/1 {}/2/1 {}//1\n",
                    t[0] + 1,
                    t[1] + 1,
                    t[2] + 1
                ));
            }
        }
        text
    })
}

/// Loads OBJ bytes and validates the mesh; an error is typed and located.
fn exercise_obj(bytes: &[u8]) {
    match parse_obj(bytes, "fuzz.obj") {
        Ok(mut mesh) => {
            if mesh.validate().is_ok() {
                let n = mesh.vertex_count() as u32;
                assert!(mesh.triangles.iter().flatten().all(|&v| v < n));
                assert!(mesh.signed_volume() > 0.0);
            }
        }
        Err(palpa::scene::mesh::MeshError::ObjSyntax { line, column, .. }) => {
            assert!(line >= 1 && line <= bytes.split(|&b| b == b'\n').count() + 1);
            assert!(column >= 1);
        }
        Err(e) => assert!(!e.to_string().is_empty()),
    }
}

#[test]
fn fuzz_obj_loader() {
    let text = obj_text();
    let mut reference = parse_obj(text.as_bytes(), "seed.obj").unwrap();
    reference.validate().unwrap();
    proptest!(config(6), |(bytes in prop::collection::vec(any::<u8>(), 0..512))| {
        exercise_obj(&bytes);
    });
    let tokens = prop_oneof![
        Just("0"),
        Just("-1"),
        Just("-100000"),
        Just("4294967296"),
        Just("99999999999999999999"),
        Just("-9223372036854775808"),
        Just("1/2/3/4"),
        Just("1//"),
        Just("/"),
        Just("nan"),
        Just("inf"),
        Just("1e39"),
        Just("-0"),
        Just("x"),
        Just("\u{e9}"),
        Just("f"),
        Just("v"),
        Just("vt"),
        Just("vn"),
        Just("o"),
        Just("\n"),
        Just("1/-9"),
        Just("1//-9"),
    ];
    proptest!(config(7), |(edits in prop::collection::vec((any::<usize>(), tokens), 1..5))| {
        let mut text = text.to_string();
        for (at, token) in edits {
            // On a character's first byte: an earlier edit may have put a two-byte one there.
            let mut at = at % (text.len() + 1);
            while !text.is_char_boundary(at) {
                at -= 1;
            }
            let end = text[at..]
                .find(char::is_whitespace)
                .map_or(text.len(), |k| at + k);
            text.replace_range(at..end, token);
        }
        exercise_obj(text.as_bytes());
    });
}

// ---------------------------------------------------------------------------------------------
// IPC pose checks

fn pose_from(words: &[u64; 11]) -> ToolPoseV1 {
    let f = |k: usize| f64::from_bits(words[k]);
    ToolPoseV1 {
        seq: words[0],
        device_time_ns: words[1],
        position: [f(2), f(3), f(4)],
        orientation: [f(5), f(6), f(7), f(8)],
        jaw: f(9),
        buttons: words[10] as u32,
        reserved: (words[10] >> 32) as u32,
    }
}

fn float_bits() -> impl Strategy<Value = u64> {
    prop_oneof![
        any::<u64>(),
        Just(f64::NAN.to_bits()),
        Just(f64::INFINITY.to_bits()),
        Just(f64::MAX.to_bits()),
        Just(0u64),
        Just(1f64.to_bits()),
        (-1.0f64..1.0).prop_map(f64::to_bits),
    ]
}

#[test]
fn fuzz_ipc_pose_checks() {
    let pose_words = prop::array::uniform11(float_bits());
    proptest!(config(8), |(
        poses in prop::collection::vec((pose_words, 0u64..2000), 1..8),
        max_speed in prop_oneof![Just(10.0), Just(0.0), Just(f64::MAX), Just(1e-300)],
    )| {
        let limits = InputLimits { max_speed, ..InputLimits::default() };
        let mut state = ToolInputState::default();
        let mut tick = 0u64;
        for (words, step) in poses {
            tick = tick.saturating_add(step);
            let pose = pose_from(&words);
            if let Ok((accepted, jaw)) = state.offer(&pose, tick, 0.001, &limits) {
                // An accepted pose is one a tool can take: finite, unit orientation, jaw ≥ 0.
                prop_assert!(accepted.position_in_world.iter().all(|x| x.is_finite()));
                prop_assert!((accepted.world_from_tool.norm() - 1.0).abs() < 1e-9);
                prop_assert!(jaw.is_finite() && jaw >= 0.0);
            }
            state.update_staleness(tick, &limits);
        }
    });
}

// ---------------------------------------------------------------------------------------------
// Mesh stream

#[test]
fn fuzz_mesh_stream_decoder() {
    // A display holding a real keyframe, then any header and bytes.
    let mesh = icosphere(0.05, 1);
    let positions: Vec<palpa::Vec3> = mesh.positions_in_body.clone();
    let mut out = vec![0u8; max_message_bytes(positions.len(), mesh.triangles.len())];
    let mut encoder = MeshEncoder::new(0, positions.len());
    let keyframe = encoder.keyframe(7, &positions, &mesh.triangles, &mut out);
    let keyframe_bytes = out[..keyframe.payload_bytes as usize].to_vec();
    let header = (
        prop_oneof![Just(MESH_KEYFRAME), Just(MESH_DELTA), any::<u32>()],
        prop_oneof![Just(7u64), any::<u64>()],
        prop_oneof![Just(42u32), any::<u32>(), 0u32..100],
        prop_oneof![any::<u32>(), 0u32..100],
        prop_oneof![any::<u32>(), 0u32..40],
        prop_oneof![any::<u32>(), 0u32..2048],
    );
    proptest!(config(9), |(
        (kind, base_tick, vertex_count, triangle_count, changed_count, payload_bytes) in header,
        bytes in prop::collection::vec(any::<u8>(), 0..2048),
    )| {
        let mut display = DisplayMesh::default();
        display.apply(&keyframe, &keyframe_bytes).unwrap();
        let before = display.clone();
        let header = MeshHeaderV1 {
            kind,
            body: 0,
            tick: 8,
            base_tick,
            vertex_count,
            triangle_count,
            changed_count,
            payload_bytes,
        };
        match display.apply(&header, &bytes) {
            Ok(()) => {
                let n = display.positions.len() as u32;
                prop_assert!(display.triangles.iter().flatten().all(|&v| v < n));
                prop_assert!(display.positions.len() * 12 <= bytes.len().max(before.positions.len() * 12));
            }
            Err(e) => {
                prop_assert!(!e.to_string().is_empty());
                // A refused message changes nothing but, after a gap, readiness.
                prop_assert_eq!(&display.positions, &before.positions);
                prop_assert_eq!(&display.triangles, &before.triangles);
            }
        }
    });
}

// ---------------------------------------------------------------------------------------------
// Zenoh payloads (palpa-zenoh) and the live view's upgrade requests

#[test]
fn fuzz_wire_payloads() {
    use palpa::ipc::payload::{StatsV1, ToolFeedbackV1, WireV1};
    proptest!(config(10), |(bytes in prop::collection::vec(any::<u8>(), 0..160))| {
        // Any bytes: a payload only when the size is exactly the structure's, and then the same
        // bytes when written back (every bit pattern of every field is kept, NaNs included).
        let pose = ToolPoseV1::read_le(&bytes);
        prop_assert_eq!(pose.is_some(), bytes.len() == ToolPoseV1::BYTES);
        if let Some(pose) = pose {
            prop_assert_eq!(pose.to_le_vec(), bytes.clone());
        }
        let feedback = ToolFeedbackV1::read_le(&bytes);
        prop_assert_eq!(feedback.is_some(), bytes.len() == ToolFeedbackV1::BYTES);
        if let Some(feedback) = feedback {
            prop_assert_eq!(feedback.to_le_vec(), bytes.clone());
        }
        let stats = StatsV1::read_le(&bytes);
        prop_assert_eq!(stats.is_some(), bytes.len() == StatsV1::BYTES);
        if let Some(stats) = stats {
            prop_assert_eq!(stats.to_le_vec(), bytes.clone());
        }
        let header = MeshHeaderV1::read_le(&bytes);
        prop_assert_eq!(header.is_some(), bytes.len() == MeshHeaderV1::BYTES);
        if let Some(header) = header {
            prop_assert_eq!(header.to_le_vec(), bytes.clone());
        }
    });
    // Exactly-sized payloads of any bits, as a remote client may send them.
    proptest!(config(11), |(bytes in prop::collection::vec(any::<u8>(), 88))| {
        let pose = ToolPoseV1::read_le(&bytes).expect("88 bytes are a pose");
        prop_assert_eq!(pose.to_le_vec(), bytes);
    });
}

#[cfg(feature = "live")]
#[test]
fn fuzz_live_view_upgrade_requests() {
    use palpa::record::live::{rename_answer, rename_offer};
    let request = |protocols: &str| {
        format!(
            "GET / HTTP/1.1\r\nHost: h\r\nUpgrade: websocket\r\nSec-WebSocket-Protocol: {protocols}\r\n\r\n"
        )
        .into_bytes()
    };
    proptest!(config(12), |(
        bytes in prop::collection::vec(any::<u8>(), 0..600),
        offered in prop::sample::subsequence(
            vec!["foxglove.websocket.v1", "foxglove.sdk.v1", "foxglove.sdk.v1.1", "chat", "x"],
            0..=4,
        ),
        shuffle in any::<bool>(),
    )| {
        let mut offered = offered;
        if shuffle {
            offered.reverse();
        }
        let protocols = offered.join(", ");
        // Any bytes: an answer, never a panic; a head without the legacy offer alone is unchanged.
        let (head, legacy) = rename_offer(&bytes);
        if !legacy {
            prop_assert_eq!(&head, &bytes);
        }
        let _ = rename_answer(&bytes);
        let original = request(&protocols);
        let (head, legacy) = rename_offer(&original);
        let expect_legacy = offered.contains(&"foxglove.websocket.v1")
            && !offered.iter().any(|p| p.starts_with("foxglove.sdk."));
        prop_assert_eq!(legacy, expect_legacy);
        if legacy {
            let text = String::from_utf8(head).unwrap();
            prop_assert!(text.contains("\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n"));
            prop_assert!(text.ends_with("\r\n\r\n"));
        } else {
            prop_assert_eq!(head, original);
        }
    });
}
