/*
 * palpa shared-memory IPC contract, version 1.
 *
 * Every payload below is plain data with C layout, exchanged over iceoryx2 services named under a
 * prefix (default "palpa"; `palpa serve --prefix NAME`). Units are SI; vectors are in the world frame
 * of the scene; quaternions are w, x, y, z. The iceoryx2 type name of each payload is given with it:
 * a bridge in another language must register the same name and the same size.
 *
 * Services (all created by the daemon at start; bridges and displays open them):
 *
 *   "<prefix>/tool/<tool>/pose"       publish-subscribe, bridge -> daemon, palpa_tool_pose_v1,
 *                                     history 1, subscriber buffer 1, safe overflow (newest wins)
 *   "<prefix>/tool/<tool>/feedback"   publish-subscribe, daemon -> bridge, palpa_tool_feedback_v1,
 *                                     history 1, subscriber buffer 1, safe overflow
 *   "<prefix>/display/mesh"           publish-subscribe, daemon -> displays, slice of uint8_t with a
 *                                     palpa_mesh_header_v1 user header; layout below
 *   "<prefix>/stats"                  publish-subscribe, daemon -> anyone, palpa_stats_v1, once a second
 *   "<prefix>/control"                request-response, anyone -> daemon,
 *                                     palpa_control_request_v1 -> palpa_control_response_v1
 *
 * Check this header against the Rust types: tests/ipc_layout.rs compiles a C program with offsetof.
 */
#ifndef PALPA_IPC_H
#define PALPA_IPC_H

#include <stdint.h>

/* service "<prefix>/tool/<tool name>/pose", iceoryx2 type name "palpa_tool_pose_v1" */
typedef struct {
    uint64_t seq;             /* strictly increasing per bridge run */
    uint64_t device_time_ns;  /* bridge's CLOCK_MONOTONIC at sampling */
    double   position[3];     /* m, world frame: the tool's tip */
    double   orientation[4];  /* unit quaternion w, x, y, z (world_from_tool) */
    double   jaw;             /* rad, grasper opening; 0 for tools without jaws */
    uint32_t buttons;         /* bit mask */
    uint32_t reserved;        /* 0 */
} palpa_tool_pose_v1;         /* 88 bytes */

/* Feedback flags. */
#define PALPA_FEEDBACK_STALE      1u  /* disconnected: no fresh pose within the timeout; force is 0 */
#define PALPA_FEEDBACK_CLAMPED    2u  /* force scaled down to the tool's max_force */
#define PALPA_FEEDBACK_DIVERGED   4u  /* the divergence guard restored a body (any body, not only one
                                         this tool touches) during the tick that computed this
                                         feedback, or the force/torque was not finite and is sent as
                                         0; set on that tick's feedback of every tool */
#define PALPA_FEEDBACK_REJECTED   8u  /* the newest pose was rejected; the last good one was used */

/* service "<prefix>/tool/<tool name>/feedback", iceoryx2 type name "palpa_tool_feedback_v1" */
typedef struct {
    uint64_t seq;             /* seq of the pose this answers (0 before any pose) */
    uint64_t device_time_ns;  /* echoed from that pose */
    uint64_t tick;            /* simulation tick that computed it */
    double   force[3];        /* N, world frame: the force to render on the device */
    double   torque[3];       /* N m, world frame, about the tool's reference point (tip) */
    uint32_t contacts;        /* nodes in contact */
    uint32_t flags;           /* PALPA_FEEDBACK_* bits */
} palpa_tool_feedback_v1;     /* 80 bytes */

/* Active-system bits of palpa_stats_v1.active_systems. */
#define PALPA_SYSTEM_GRAVITY            (1u << 0)
#define PALPA_SYSTEM_AIR_VISCOSITY      (1u << 1)
#define PALPA_SYSTEM_OBSTACLE_CONTACT   (1u << 2)
#define PALPA_SYSTEM_OBSTACLE_FRICTION  (1u << 3)
#define PALPA_SYSTEM_RIGID_COMPONENTS   (1u << 4)
#define PALPA_SYSTEM_TOOL_CONTACT       (1u << 5)
#define PALPA_SYSTEM_BODY_CONTACT       (1u << 6)

/* service "<prefix>/stats", iceoryx2 type name "palpa_stats_v1"; published once per second of
 * simulation (every 1000 ticks), figures over that window unless marked total. */
typedef struct {
    uint64_t tick;                  /* last tick of the window */
    uint64_t window_ticks;          /* ticks in the window */
    double   compute_min_us;        /* tick compute time (step + publish), microseconds */
    double   compute_mean_us;
    double   compute_max_us;
    double   compute_p99_us;
    double   lateness_mean_us;      /* wake-up lateness past the tick's deadline */
    double   lateness_max_us;
    uint64_t synchronicity_misses;  /* total: ticks whose compute exceeded the period */
    uint64_t rejected_inputs;       /* total: poses rejected by the input checks */
    uint64_t disconnects;           /* total: tools that went stale */
    uint32_t active_systems;        /* PALPA_SYSTEM_* bits */
    uint32_t tools_connected;       /* bit i: tool i (scene order) has a fresh pose */
    uint32_t paused;                /* 1 while paused */
    uint32_t dropped_records;       /* total: records the recorder dropped (0 when not recording) */
    double   stability_margin;      /* smallest over bodies: explicit-scheme omega*dt limit minus the
                                       worst node's omega*dt (negative: multirate/implicit needed) */
    uint64_t guard_events;          /* total: times the divergence guard restored a body */
    uint64_t ipc_errors;            /* total: iceoryx2 operations of the loop that failed (counted;
                                       the daemon goes on) */
} palpa_stats_v1;                   /* 128 bytes */

/* Control commands. */
#define PALPA_CONTROL_RESET     1u  /* rebuild the world from the scene, tick 0 */
#define PALPA_CONTROL_PAUSE     2u
#define PALPA_CONTROL_RESUME    3u
#define PALPA_CONTROL_KEYFRAME  4u  /* publish a mesh keyframe on the next display tick */

/* service "<prefix>/control", request type name "palpa_control_request_v1" */
typedef struct {
    uint32_t command;   /* PALPA_CONTROL_* */
    uint32_t reserved;  /* 0 */
    uint64_t argument;  /* 0 (reserved for commands with an argument) */
} palpa_control_request_v1;   /* 16 bytes */

/* response type name "palpa_control_response_v1" */
typedef struct {
    uint32_t command;   /* echoed */
    int32_t  status;    /* 0 done, -1 unknown command */
    uint64_t tick;      /* tick at which it was applied */
} palpa_control_response_v1;  /* 16 bytes */

/* Mesh stream: "<prefix>/display/mesh", user header type name "palpa_mesh_header_v1", payload a
 * slice of uint8_t of `payload_bytes` bytes laid out according to `kind`:
 *
 *   kind 0, keyframe: vertex_count x float[3] positions (m, world), then
 *                     triangle_count x uint32_t[3] vertex indices (counter-clockwise from outside)
 *   kind 1, delta:    changed_count x { uint32_t vertex; float position[3]; }  (16 bytes each)
 *
 * One message per body per display tick. A display that joins late waits for a keyframe (sent at
 * start, every few seconds, and on PALPA_CONTROL_KEYFRAME), then applies deltas whose base_tick
 * matches the tick of the state it holds. A body with adaptive subdivision changes its vertices and
 * triangles at contact: its next message is then a keyframe with the new counts (a delta never
 * changes vertex_count; a display sizes its buffers from each keyframe).
 */
typedef struct {
    uint32_t kind;            /* 0 keyframe, 1 delta */
    uint32_t body;            /* body index: scene order, then bodies a transection added in order of creation (each starts with a keyframe) */
    uint64_t tick;            /* tick of the state this message brings the display to */
    uint64_t base_tick;       /* delta: tick of the state it applies to; keyframe: = tick */
    uint32_t vertex_count;    /* vertices of the body at `tick` */
    uint32_t triangle_count;  /* keyframe: triangles that follow; delta: 0 */
    uint32_t changed_count;   /* delta: entries that follow; keyframe: 0 */
    uint32_t payload_bytes;   /* bytes of the slice that carry data */
} palpa_mesh_header_v1;       /* 40 bytes */

#endif /* PALPA_IPC_H */
