//! The Rust payload types match `proto/palpa_ipc.h`: a C program built from the header prints the
//! size, alignment and every field offset of each type, and they must equal Rust's.

use std::mem::{align_of, offset_of, size_of};
use std::process::Command;

use palpa::ipc::payload::*;

macro_rules! rust_layout {
    ($out:ident, $c:literal, $t:ty, [$($field:ident),*]) => {
        $out.push(format!("{} size {}", $c, size_of::<$t>()));
        $out.push(format!("{} align {}", $c, align_of::<$t>()));
        $( $out.push(format!("{} {} {}", $c, stringify!($field), offset_of!($t, $field))); )*
    };
}

const TYPES: &[(&str, &[&str])] = &[
    (
        "palpa_tool_pose_v1",
        &[
            "seq",
            "device_time_ns",
            "position",
            "orientation",
            "jaw",
            "buttons",
            "reserved",
        ],
    ),
    (
        "palpa_tool_feedback_v1",
        &[
            "seq",
            "device_time_ns",
            "tick",
            "force",
            "torque",
            "contacts",
            "flags",
        ],
    ),
    (
        "palpa_stats_v1",
        &[
            "tick",
            "window_ticks",
            "compute_min_us",
            "compute_mean_us",
            "compute_max_us",
            "compute_p99_us",
            "lateness_mean_us",
            "lateness_max_us",
            "synchronicity_misses",
            "rejected_inputs",
            "disconnects",
            "active_systems",
            "tools_connected",
            "paused",
            "dropped_records",
            "stability_margin",
            "guard_events",
            "ipc_errors",
        ],
    ),
    (
        "palpa_control_request_v1",
        &["command", "reserved", "argument"],
    ),
    ("palpa_control_response_v1", &["command", "status", "tick"]),
    (
        "palpa_mesh_header_v1",
        &[
            "kind",
            "body",
            "tick",
            "base_tick",
            "vertex_count",
            "triangle_count",
            "changed_count",
            "payload_bytes",
        ],
    ),
];

#[test]
fn rust_payloads_match_the_c_header() {
    let root = env!("CARGO_MANIFEST_DIR");
    let dir = std::env::temp_dir().join(format!("palpa-ipc-layout-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut program = String::from(
        "#include <stdio.h>\n#include <stddef.h>\n#include \"palpa_ipc.h\"\nint main(void) {\n",
    );
    for (name, fields) in TYPES {
        program += &format!("  printf(\"{name} size %zu\\n\", sizeof({name}));\n");
        program += &format!("  printf(\"{name} align %zu\\n\", _Alignof({name}));\n");
        for f in *fields {
            program += &format!("  printf(\"{name} {f} %zu\\n\", offsetof({name}, {f}));\n");
        }
    }
    program += "  return 0;\n}\n";
    std::fs::write(dir.join("layout.c"), program).unwrap();
    let compiler = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let status = Command::new(&compiler)
        .args(["-std=c11", "-Wall", "-Werror", "-I"])
        .arg(format!("{root}/proto"))
        .arg(dir.join("layout.c"))
        .arg("-o")
        .arg(dir.join("layout"))
        .status()
        .unwrap_or_else(|e| panic!("cannot run the C compiler `{compiler}`: {e}"));
    assert!(status.success(), "the C header does not compile");
    let out = Command::new(dir.join("layout")).output().unwrap();
    let c_lines: Vec<String> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect();
    std::fs::remove_dir_all(&dir).unwrap();

    let mut rust = Vec::new();
    rust_layout!(
        rust,
        "palpa_tool_pose_v1",
        ToolPoseV1,
        [
            seq,
            device_time_ns,
            position,
            orientation,
            jaw,
            buttons,
            reserved
        ]
    );
    rust_layout!(
        rust,
        "palpa_tool_feedback_v1",
        ToolFeedbackV1,
        [seq, device_time_ns, tick, force, torque, contacts, flags]
    );
    rust_layout!(
        rust,
        "palpa_stats_v1",
        StatsV1,
        [
            tick,
            window_ticks,
            compute_min_us,
            compute_mean_us,
            compute_max_us,
            compute_p99_us,
            lateness_mean_us,
            lateness_max_us,
            synchronicity_misses,
            rejected_inputs,
            disconnects,
            active_systems,
            tools_connected,
            paused,
            dropped_records,
            stability_margin,
            guard_events,
            ipc_errors
        ]
    );
    rust_layout!(
        rust,
        "palpa_control_request_v1",
        ControlRequestV1,
        [command, reserved, argument]
    );
    rust_layout!(
        rust,
        "palpa_control_response_v1",
        ControlResponseV1,
        [command, status, tick]
    );
    rust_layout!(
        rust,
        "palpa_mesh_header_v1",
        MeshHeaderV1,
        [
            kind,
            body,
            tick,
            base_tick,
            vertex_count,
            triangle_count,
            changed_count,
            payload_bytes
        ]
    );
    assert_eq!(c_lines.len(), rust.len());
    for (c, r) in c_lines.iter().zip(&rust) {
        assert_eq!(c, r, "C and Rust layouts differ");
    }
    // The sizes the contract states.
    assert_eq!(size_of::<ToolPoseV1>(), 88);
    assert_eq!(size_of::<ToolFeedbackV1>(), 80);
    assert_eq!(size_of::<StatsV1>(), 128);
    assert_eq!(size_of::<MeshHeaderV1>(), 40);
    assert_eq!(TOOL_POSE_TYPE_NAME, "palpa_tool_pose_v1");
    assert_eq!(TOOL_FEEDBACK_TYPE_NAME, "palpa_tool_feedback_v1");
}
