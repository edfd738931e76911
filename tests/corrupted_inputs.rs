//! Structured corruption of real inputs: 150 damaged copies each of a recorded session (flipped
//! bytes, cuts, length fields set huge, damaged messages), of the repository's scenes and of OBJ
//! meshes. Every reader must give a value or a clear error — in-process (any panic is caught and
//! named with its variant) and through the `palpa-replay` and `palpa check` binaries (an exit by
//! signal or panic fails; an error exit must say something on stderr). Variants are deterministic
//! (a fixed-seed generator).

mod common;

use common::Rng;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::process::Command;

use palpa::record::replay::{
    mesh_payload, read_recording, read_recording_file, summarise, verify, write_recording,
};
use palpa::scene::mesh::{MeshError, icosphere, parse_obj};
use palpa::scene::{SceneError, parse_scene};

const VARIANTS: usize = 150;

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("palpa-corrupt-{}-{name}", std::process::id()))
}

/// Runs `f`, turning a panic into a test failure that names the variant.
fn no_panic<T>(what: &str, f: impl FnOnce() -> T) -> T {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(v) => v,
        Err(e) => {
            let message = e
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            panic!("{what}: panicked: {message}");
        }
    }
}

/// A binary's run on damaged input ended normally: an exit code (no signal, no abort), not a
/// panic's 101, and an error exit says why (an error on stderr, or `palpa-replay --verify`'s
/// FAILED / DAMAGED verdict on stdout). Returns the exit code.
fn assert_clean_exit(what: &str, out: &std::process::Output) -> i32 {
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let code = out
        .status
        .code()
        .unwrap_or_else(|| panic!("{what}: killed by a signal ({:?}): {stderr}", out.status));
    assert_ne!(code, 101, "{what}: panicked: {stderr}");
    assert!(!stderr.contains("panicked"), "{what}: {stderr}");
    if code != 0 {
        assert!(
            stderr.contains("Error")
                || stdout.contains("verify: FAILED")
                || stdout.contains("verify: DAMAGED"),
            "{what}: exit {code} without a message: {stdout}{stderr}"
        );
    }
    code
}

/// `palpa-replay --verify`: the recording is complete, undamaged and replays bit for bit.
const VERIFY_OK: i32 = 0;
/// `palpa-replay --verify`: a difference, or the file cannot be read or replayed.
const VERIFY_FAILED: i32 = 1;
/// `palpa-replay --verify`: the file is damaged or cut short; what could be read replays.
const VERIFY_DAMAGED: i32 = 3;

fn palpa_replay(file: &Path, mode: &str) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_palpa-replay"))
        .args([file.to_str().unwrap(), mode])
        .output()
        .unwrap()
}

/// How the reader and in-process replay took a file: what `palpa-replay --verify` must exit with.
fn expected_verify_code(bytes: &[u8], work: &Path) -> i32 {
    let code = match read_recording(bytes) {
        Err(_) => VERIFY_FAILED,
        Ok(recording) => {
            let intact = recording.complete && recording.damage.is_none();
            match (verify(&recording, work, |_, _| {}), intact) {
                (Ok(_), true) => VERIFY_OK,
                (Ok(_), false) => VERIFY_DAMAGED,
                (Err(_), _) => VERIFY_FAILED,
            }
        }
    };
    let _ = std::fs::remove_dir_all(work);
    code
}

// ---------------------------------------------------------------------------------------------
// Recordings

/// Offsets of the top-level records of an MCAP file (after the magic).
fn record_offsets(bytes: &[u8]) -> Vec<(usize, u8)> {
    let mut out = Vec::new();
    let mut at = 8;
    while at + 9 <= bytes.len() {
        let opcode = bytes[at];
        let length = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        out.push((at, opcode));
        if opcode == 0x02 {
            break;
        }
        at += 9 + length;
    }
    out
}

fn huge(rng: &mut Rng, file_len: usize) -> u64 {
    [
        u64::MAX,
        5_000_470_302_814_682_325,
        1 << 40,
        u64::from(u32::MAX),
        2 * file_len as u64,
        rng.next(),
    ][rng.below(6)]
}

/// Variant `k` of the recording: a kind chosen by `k`, details by the generator.
fn corrupt_recording(bytes: &[u8], k: usize, rng: &mut Rng) -> (String, Vec<u8>) {
    let mut out = bytes.to_vec();
    let records = record_offsets(bytes);
    let n = out.len();
    match k % 6 {
        0 => {
            let at = rng.below(n);
            out[at] ^= 1 << rng.below(8);
            (format!("bit flip at {at}"), out)
        }
        1 => {
            let flips = 2 + rng.below(30);
            for _ in 0..flips {
                let at = rng.below(n);
                out[at] = rng.next() as u8;
            }
            (format!("{flips} random bytes"), out)
        }
        2 => {
            let at = rng.below(n);
            out.truncate(at);
            (format!("cut at {at}"), out)
        }
        3 => {
            let (at, opcode) = records[rng.below(records.len())];
            let value = huge(rng, n);
            out[at + 1..at + 9].copy_from_slice(&value.to_le_bytes());
            (
                format!("record 0x{opcode:02x} at {at}: length {value}"),
                out,
            )
        }
        4 => {
            // A chunk's sizes or compression-name length.
            let chunks: Vec<usize> = records
                .iter()
                .filter(|r| r.1 == 0x06)
                .map(|r| r.0)
                .collect();
            let at = chunks[rng.below(chunks.len())];
            let value = huge(rng, n);
            let body = at + 9;
            let name_len = u32::from_le_bytes(out[body + 28..body + 32].try_into().unwrap());
            let (field, offset, width) = match rng.below(3) {
                0 => ("uncompressed_size", body + 16, 8),
                1 => ("compression length", body + 28, 4),
                _ => ("compressed_size", body + 32 + name_len as usize, 8),
            };
            out[offset..offset + width].copy_from_slice(&value.to_le_bytes()[..width]);
            (format!("chunk at {at}: {field} {value}"), out)
        }
        _ => {
            // A string length inside a record (attachment name, channel topic, ...): huge u32
            // just after the fixed fields of a random record.
            let (at, opcode) = records[rng.below(records.len())];
            let field = at + 9 + [4, 16, 20][rng.below(3)];
            if field + 4 <= n {
                out[field..field + 4].copy_from_slice(&u32::MAX.to_le_bytes());
            }
            (
                format!("record 0x{opcode:02x} at {at}: u32 at {field} set huge"),
                out,
            )
        }
    }
}

fn record_session(path: &Path) {
    record_session_of(path, "1");
}

/// Records `seconds` of the probe scene (chunks close every second).
fn record_session_of(path: &Path, seconds: &str) {
    let out = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args([
            "run",
            concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/probe_press.toml"),
            "--duration",
            seconds,
            "--record",
            path.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn corrupted_recordings_give_clear_errors_in_process_and_from_palpa_replay() {
    let path = temp("session.mcap");
    record_session(&path);
    let bytes = std::fs::read(&path).unwrap();
    let whole = read_recording(&bytes).unwrap();
    assert!(whole.complete && whole.damage.is_none());
    // The intact file passes.
    let out = palpa_replay(&path, "--verify");
    assert_eq!(
        assert_clean_exit("palpa-replay --verify on the intact recording", &out),
        VERIFY_OK
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("verify: OK"));
    let mut rng = Rng(0x5eed_0001);
    let (mut ok, mut damaged, mut refused, mut verified, mut differs) = (0, 0, 0, 0, 0);
    let work = temp("work");
    for k in 0..VARIANTS {
        let (what, variant) = corrupt_recording(&bytes, k, &mut rng);
        let what = format!("recording variant {k} ({what})");
        no_panic(&what, || match read_recording(&variant) {
            Ok(recording) => {
                ok += 1;
                damaged += recording.damage.is_some() as usize;
                // Every variant differs from the recording: the reader must not take it as whole.
                assert!(
                    variant == bytes || !recording.complete || recording.damage.is_some(),
                    "{what}: read as a complete, undamaged recording"
                );
                let _ = summarise(&recording);
                let mut payload = Vec::new();
                for m in &recording.messages {
                    if m.topic.starts_with("/palpa/mesh/") {
                        let _ = mesh_payload(m, &mut payload);
                    }
                }
                match verify(&recording, &work, |_, _| {}) {
                    Ok(_) => verified += 1,
                    Err(e) => {
                        differs += 1;
                        assert!(!e.to_string().is_empty());
                    }
                }
                let _ = std::fs::remove_dir_all(&work);
            }
            Err(damage) => {
                refused += 1;
                assert!(damage.offset <= variant.len() as u64, "{what}: {damage}");
            }
        });
        // The binary, on every tenth variant.
        if k % 10 == 0 {
            let file = temp(&format!("variant-{k}.mcap"));
            std::fs::write(&file, &variant).unwrap();
            let out = palpa_replay(&file, "--summary");
            assert_clean_exit(&format!("palpa-replay --summary on {what}"), &out);
            // --verify: never 0 for a damaged file; 3 when what could be read replays, 1 when the
            // file cannot be read or replayed — as the reader and replay decided in-process.
            let out = palpa_replay(&file, "--verify");
            let code = assert_clean_exit(&format!("palpa-replay --verify on {what}"), &out);
            let expected = expected_verify_code(&variant, &work);
            assert_ne!(expected, VERIFY_OK, "{what}: taken as intact in-process");
            assert_eq!(
                code,
                expected,
                "palpa-replay --verify on {what}: {}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
            if code == VERIFY_DAMAGED {
                assert!(
                    String::from_utf8_lossy(&out.stdout).contains("is damaged"),
                    "{what}"
                );
            }
            std::fs::remove_file(file).ok();
        }
    }
    eprintln!(
        "{VARIANTS} damaged recordings: {ok} read ({damaged} up to damage; {verified} verified, \
         {differs} refused by verify), {refused} refused by the reader"
    );
    // The variants reach both paths: reading refused, and reading up to the damage (the chunk CRCs
    // catch flipped bytes, so what is read replays; damaged messages are the next test's).
    assert!(refused > 0 && damaged > 0 && verified > 0);
    // A cut file is still read up to its damage: the killed-daemon case.
    let cut = read_recording(&bytes[..bytes.len() * 2 / 3]).unwrap();
    assert!(!cut.complete && cut.damage.is_some());
    std::fs::remove_file(path).ok();
}

#[test]
fn verify_reports_a_recording_cut_short_after_its_scene_message_as_damaged() {
    let path = temp("cut.mcap");
    record_session_of(&path, "3");
    let bytes = std::fs::read(&path).unwrap();
    let whole = read_recording(&bytes).unwrap();
    assert!(whole.complete && whole.damage.is_none());
    let work = temp("work-cut");
    let all_ticks = verify(&whole, &work, |_, _| {}).unwrap().ticks;
    let _ = std::fs::remove_dir_all(&work);
    // Three cuts after the scene message: in the middle of the last chunk of ticks (damaged bytes
    // at the cut: what follows is lost), in the middle of the last chunk (the session's end event
    // alone: the writer closed the chunk of the last tick before it), and at the end of the last
    // chunk (the file just stops after a whole chunk, without the index records, summary and
    // footer that close it — a killed daemon's file). And, for comparison, a whole file with one
    // flipped byte in its summary section (an index).
    let records = record_offsets(&bytes);
    let chunks: Vec<usize> = records
        .iter()
        .filter(|r| r.1 == 0x06)
        .map(|r| r.0)
        .collect();
    let (footer, _) = *records.iter().rfind(|r| r.1 == 0x02).unwrap();
    let length_at =
        |chunk: usize| u64::from_le_bytes(bytes[chunk + 1..chunk + 9].try_into().unwrap()) as usize;
    let last_chunk = chunks[chunks.len() - 1];
    let ticks_chunk = chunks[chunks.len() - 2];
    let chunk_end = last_chunk + 9 + length_at(last_chunk);
    let mut flipped = bytes.clone();
    flipped[footer - 5] ^= 0x10;
    for (what, variant, all_read) in [
        (
            "cut inside its last chunk of ticks",
            bytes[..ticks_chunk + 9 + length_at(ticks_chunk) / 2].to_vec(),
            false,
        ),
        (
            "cut inside its last chunk",
            bytes[..last_chunk + 9 + length_at(last_chunk) / 2].to_vec(),
            true,
        ),
        (
            "cut after its last chunk",
            bytes[..chunk_end].to_vec(),
            true,
        ),
        ("a summary byte flipped", flipped, true),
    ] {
        let recording = read_recording(&variant).unwrap();
        assert!(!recording.complete, "{what}");
        let ticks = verify(&recording, &work, |_, _| {}).unwrap().ticks;
        let _ = std::fs::remove_dir_all(&work);
        if all_read {
            assert_eq!(ticks, all_ticks, "{what}");
        } else {
            assert!(
                0 < ticks && ticks < all_ticks,
                "{what}: {ticks} of {all_ticks} ticks"
            );
        }
        let file = temp("cut-short.mcap");
        std::fs::write(&file, &variant).unwrap();
        let out = palpa_replay(&file, "--verify");
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert_eq!(
            out.status.code(),
            Some(VERIFY_DAMAGED),
            "{what}: {stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(stdout.contains("damaged"), "{what}: {stdout}");
        assert!(!stdout.contains("verify: OK"), "{what}: {stdout}");
        // Where, and how much was verified.
        let place = match &recording.damage {
            Some(d) => format!("at byte {}", d.offset),
            None => format!("at byte {} without its footer", variant.len()),
        };
        assert!(stdout.contains(&place), "{what}: {stdout}");
        assert!(
            stdout.contains(&format!(
                "the {ticks} ticks read before the damage replay bit for bit"
            )),
            "{what}: {stdout}"
        );
        std::fs::remove_file(file).ok();
    }
    std::fs::remove_file(path).ok();
}

#[test]
fn recordings_with_damaged_messages_replay_or_fail_cleanly() {
    // Damage inside messages that the file's checksums cannot see: rewritten with valid framing.
    let path = temp("messages.mcap");
    record_session(&path);
    let original = read_recording_file(&path).unwrap();
    let mut rng = Rng(0x5eed_0002);
    let work = temp("work-messages");
    let mut refused = 0;
    for k in 0..30 {
        let mut recording = original.clone();
        let what = match k % 3 {
            0 => {
                let m = rng.below(recording.messages.len());
                let message = &mut recording.messages[m];
                for _ in 0..1 + rng.below(4) {
                    if !message.data.is_empty() {
                        let at = rng.below(message.data.len());
                        message.data[at] = rng.next() as u8;
                    }
                }
                format!("bytes of message {m} ({})", message.topic)
            }
            1 => {
                let m = rng.below(recording.messages.len());
                recording.messages[m].log_time = huge(&mut rng, 0);
                format!("log time of message {m}")
            }
            _ => {
                let m = rng.below(recording.attachments.len());
                let names = [
                    "/etc/palpa-test",
                    "../../../../x.obj",
                    "",
                    "a/../../..",
                    ".",
                ];
                recording.attachments[m].0 = names[rng.below(names.len())].to_string();
                format!("attachment name {:?}", recording.attachments[m].0)
            }
        };
        let file = temp(&format!("messages-{k}.mcap"));
        write_recording(&recording, &file).unwrap();
        let what = format!("message variant {k} ({what})");
        no_panic(&what, || {
            let read = read_recording_file(&file).unwrap();
            if let Err(e) = verify(&read, &work, |_, _| {}) {
                refused += 1;
                assert!(!e.to_string().is_empty());
            }
            let _ = std::fs::remove_dir_all(&work);
        });
        std::fs::remove_file(file).ok();
    }
    assert!(!Path::new("/etc/palpa-test").exists());
    assert!(refused > 0);
    std::fs::remove_file(path).ok();
}

// ---------------------------------------------------------------------------------------------
// Scenes

fn mangle_text(text: &str, rng: &mut Rng, tokens: &[&str]) -> (String, String) {
    let mut out = text.to_string();
    let lines: Vec<&str> = text.lines().collect();
    let boundary = |s: &str, mut at: usize| {
        while !s.is_char_boundary(at) {
            at -= 1;
        }
        at
    };
    match rng.below(6) {
        0 => {
            let mut bytes = out.into_bytes();
            let at = rng.below(bytes.len());
            bytes[at] ^= 1 << rng.below(8);
            (
                format!("bit flip at {at}"),
                String::from_utf8_lossy(&bytes).into_owned(),
            )
        }
        1 => {
            let at = boundary(&out, rng.below(out.len()));
            out.truncate(at);
            (format!("cut at {at}"), out)
        }
        2 => {
            // Replace a word (a number, a key, an index) with an extreme token.
            let at = boundary(&out, rng.below(out.len()));
            let end = out[at..]
                .find(|c: char| c.is_whitespace() || ",]}".contains(c))
                .map_or(out.len(), |k| at + k);
            let token = tokens[rng.below(tokens.len())];
            out.replace_range(at..end, token);
            (format!("word at {at} -> {token:?}"), out)
        }
        3 => {
            let l = rng.below(lines.len());
            let kept: Vec<&str> = lines
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != l)
                .map(|(_, s)| *s)
                .collect();
            (format!("line {} deleted", l + 1), kept.join("\n"))
        }
        4 => {
            let l = rng.below(lines.len());
            let mut copy: Vec<&str> = lines.clone();
            copy.insert(l, lines[l]);
            (format!("line {} doubled", l + 1), copy.join("\n"))
        }
        _ => {
            let at = boundary(&out, rng.below(out.len()));
            let token = tokens[rng.below(tokens.len())];
            out.insert_str(at, token);
            (format!("{token:?} inserted at {at}"), out)
        }
    }
}

#[test]
fn mangled_scenes_give_errors_with_line_and_column() {
    let root = common::repo_root();
    let mut scenes = Vec::new();
    for dir in ["scenes", "scenes/stress"] {
        let mut paths: Vec<PathBuf> = std::fs::read_dir(root.join(dir))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        paths.sort();
        for p in paths {
            scenes.push((std::fs::read_to_string(&p).unwrap(), p));
        }
    }
    // The binary reads mangled scenes from a folder with the meshes they refer to.
    let folder = temp("scenes");
    std::fs::create_dir_all(&folder).unwrap();
    for dir in ["scenes", "scenes/stress"] {
        for e in std::fs::read_dir(root.join(dir)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|e| e == "obj") {
                std::fs::copy(&p, folder.join(p.file_name().unwrap())).unwrap();
            }
        }
    }
    let tokens = [
        "1e308",
        "-1",
        "nan",
        "inf",
        "0",
        "7",
        "99999999999",
        "[]",
        "{}",
        "\"\"",
        "[",
        "=",
        "\u{e9}",
        "[[body]]",
        "subdivisions = 7",
        "\n",
        "#",
        "\"",
        "obj = \"/dev/zero\"",
        "obj = \"missing.obj\"",
        "mesh = { icosphere = { radius = 1, subdivisions = 7 } }",
    ];
    let mut rng = Rng(0x5eed_0003);
    let (mut ok, mut refused) = (0, 0);
    for k in 0..VARIANTS {
        let (text, path) = &scenes[k % scenes.len()];
        let (what, mangled) = mangle_text(text, &mut rng, &tokens);
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let what = format!("scene variant {k} ({name}: {what})");
        no_panic(&what, || {
            match parse_scene(&mangled, &name, path.parent().unwrap()) {
                Ok(_) => ok += 1,
                Err(SceneError::At {
                    line,
                    column,
                    message,
                    ..
                }) => {
                    refused += 1;
                    assert!(
                        line >= 1 && line <= mangled.lines().count() + 1 && column >= 1,
                        "{what}: {line}:{column}"
                    );
                    assert!(!message.is_empty());
                }
                Err(e) => panic!("{what}: not located: {e}"),
            }
        });
        if k % 10 == 0 {
            let file = folder.join(format!("variant-{k}.toml"));
            std::fs::write(&file, &mangled).unwrap();
            let out = Command::new(env!("CARGO_BIN_EXE_palpa"))
                .args(["check", file.to_str().unwrap()])
                .output()
                .unwrap();
            assert_clean_exit(&format!("palpa check on {what}"), &out);
        }
    }
    eprintln!("{VARIANTS} mangled scenes: {ok} valid, {refused} refused with a position");
    assert!(refused > VARIANTS / 3 && ok > 0);
    std::fs::remove_dir_all(folder).ok();
}

// ---------------------------------------------------------------------------------------------
// OBJ meshes

fn generated_obj() -> String {
    let mesh = icosphere(0.05, 2);
    let mut text = String::from("# generated\no organ\n");
    for p in &mesh.positions_in_body {
        text.push_str(&format!("v {} {} {}\n", p.x as f32, p.y as f32, p.z as f32));
    }
    text.push_str("vn 0 0 1\n");
    for t in &mesh.triangles {
        text.push_str(&format!(
            "f {}//1 {}//1 {}//1\n",
            t[0] + 1,
            t[1] + 1,
            t[2] + 1
        ));
    }
    text
}

fn mangled_objs_are_refused_cleanly(source: &str, label: &str, seed: u64) {
    let mut reference = parse_obj(source.as_bytes(), label).unwrap();
    reference.validate().unwrap();
    let tokens = [
        "0",
        "-1",
        "-100000",
        "4294967296",
        "99999999999999999999",
        "-9223372036854775808",
        "1/2/3/4",
        "1//",
        "/",
        "nan",
        "inf",
        "1e39",
        "-0",
        "x",
        "\u{e9}",
        "f",
        "v",
        "vt",
        "o",
        "\n",
        "1/-9",
        "1//-9",
        "f 1 2",
        "v 1 2",
    ];
    let mut rng = Rng(seed);
    let (mut ok, mut refused) = (0, 0);
    for k in 0..VARIANTS {
        let (what, mangled) = mangle_text(source, &mut rng, &tokens);
        let what = format!("{label} variant {k} ({what})");
        no_panic(&what, || match parse_obj(mangled.as_bytes(), label) {
            Ok(mut mesh) => match mesh.validate() {
                Ok(()) => ok += 1,
                Err(e) => {
                    refused += 1;
                    assert!(!e.to_string().is_empty());
                }
            },
            Err(MeshError::ObjSyntax { line, column, .. }) => {
                refused += 1;
                assert!(line >= 1 && line <= mangled.lines().count() + 1 && column >= 1);
            }
            Err(e) => {
                refused += 1;
                assert!(!e.to_string().is_empty(), "{what}");
            }
        });
    }
    eprintln!("{VARIANTS} mangled {label}: {ok} valid meshes, {refused} refused");
    assert!(refused > VARIANTS / 3);
}

#[test]
fn mangled_generated_obj_meshes_are_refused_cleanly() {
    mangled_objs_are_refused_cleanly(&generated_obj(), "generated.obj", 0x5eed_0004);
}

#[test]
fn mangled_shared_obj_meshes_are_refused_cleanly() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let dir = shared.join("data/meshes");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "obj"))
        .collect();
    paths.sort();
    assert!(!paths.is_empty(), "no OBJ meshes in {}", dir.display());
    for (k, path) in paths.iter().enumerate() {
        let text = std::fs::read_to_string(path).unwrap();
        let label = path.file_name().unwrap().to_string_lossy().to_string();
        mangled_objs_are_refused_cleanly(&text, &label, 0x5eed_0100 + k as u64);
    }
}
