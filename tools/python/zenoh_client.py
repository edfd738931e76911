#!/usr/bin/env python3
"""Remote client of palpa over Zenoh (PyPI `eclipse-zenoh`, see requirements.txt), through the
`palpa-zenoh` bridge.

Two parts a remote host plays:

* `press` — a device on another host: publishes `palpa_tool_pose_v1` on
  `palpa/<prefix>/tool/<tool>/pose` (a press down into the default scene's organ and back up, one pose
  at a time), waits for the `palpa_tool_feedback_v1` answering each on `.../feedback`, and prints the
  force.
* `display` — a display on another host: reads `palpa/<prefix>/display/mesh` (a `palpa_mesh_header_v1`
  then its payload) and keeps each body's vertices and triangles up to date from keyframes and deltas.

Payloads are the v1 structures of proto/palpa_ipc.h, little-endian (`struct` formats below).

    palpa serve --prefix palpa &
    palpa-zenoh --prefix palpa --listen tcp/0.0.0.0:7447 &
    python3 tools/python/zenoh_client.py press --connect tcp/127.0.0.1:7447
    python3 tools/python/zenoh_client.py display --connect tcp/127.0.0.1:7447 --seconds 3
"""

import argparse
import json
import math
import struct
import sys
import time

import zenoh

from press import press_height  # beside this script

POSE = struct.Struct("<QQ3d4ddII")  # palpa_tool_pose_v1, 88 bytes
FEEDBACK = struct.Struct("<QQQ3d3dII")  # palpa_tool_feedback_v1, 80 bytes
MESH_HEADER = struct.Struct("<IIQQIIII")  # palpa_mesh_header_v1, 40 bytes
assert POSE.size == 88 and FEEDBACK.size == 80 and MESH_HEADER.size == 40


def open_session(connect):
    config = zenoh.Config()
    config.insert_json5("mode", '"client"')
    config.insert_json5("connect/endpoints", json.dumps(connect))
    config.insert_json5("scouting/multicast/enabled", "false")
    # The bridge may still be starting: retry for a while.
    deadline = time.monotonic() + 20
    while True:
        try:
            return zenoh.open(config)
        except zenoh.ZError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


def press(session, args):
    base = f"palpa/{args.prefix}/tool/{args.tool}"
    latest = {"feedback": None}

    def on_feedback(sample):
        latest["feedback"] = FEEDBACK.unpack(bytes(sample.payload.to_bytes()))

    subscriber = session.declare_subscriber(f"{base}/feedback", on_feedback)
    publisher = session.declare_publisher(f"{base}/pose")

    def send(seq, z):
        publisher.put(POSE.pack(seq, time.monotonic_ns(), 0.0, 0.0, z, 1.0, 0.0, 0.0, 0.0, 0.0, 0, 0))

    # Wait for the bridge and the daemon: a first pose, re-sent until it is answered.
    deadline = time.monotonic() + 20
    while True:
        send(1, press_height(0.0, args.top))
        time.sleep(0.02)
        f = latest["feedback"]
        if f is not None and f[0] == 1:
            break
        if time.monotonic() > deadline:
            sys.exit(f"no answer on {base}/feedback: is palpa-zenoh bridging prefix {args.prefix!r}?")

    steps = int(round(args.seconds * 1000))
    answered, max_force, last, round_trips = 1, 0.0, None, []
    for seq in range(2, steps + 1):
        t = seq * 0.001
        sent = time.monotonic()
        send(seq, press_height(t, args.top))
        wait_until = sent + 5.0  # a watchdog: a lockstep daemon answers every pose
        while time.monotonic() < wait_until:
            f = latest["feedback"]
            if f is not None and f[0] >= seq:
                break
            time.sleep(0.00002)
        f = latest["feedback"]
        if f is None or f[0] != seq:
            continue
        round_trips.append((time.monotonic() - sent) * 1e6)
        answered += 1
        force = f[3:6]
        contacts = f[9]
        last = (list(force), contacts, f[10])
        max_force = max(max_force, math.sqrt(sum(x * x for x in force)))
        if seq % 250 == 0:
            print(f"t {t:5.2f} s  z {press_height(t, args.top):.4f} m  force {force[2]:+.4f} N  contacts {contacts}")
    subscriber.undeclare()
    round_trips.sort()
    p = lambda q: round_trips[min(len(round_trips) - 1, int(q * len(round_trips)))] if round_trips else None
    print(json.dumps({"sent": steps, "answered": answered, "max_force": max_force,
                      "final_force": last[0] if last else None,
                      "final_contacts": last[1] if last else None,
                      "round_trip_p50_us": p(0.5), "round_trip_p99_us": p(0.99)}))


def display(session, args):
    bodies = {}  # body -> (tick, positions [[x, y, z]], triangles [(a, b, c)])
    counts = {"keyframes": 0, "deltas": 0, "deltas_skipped": 0, "bad": 0}

    def on_mesh(sample):
        data = bytes(sample.payload.to_bytes())
        if len(data) < MESH_HEADER.size:
            counts["bad"] += 1
            return
        kind, body, tick, base_tick, n, t, changed, payload_bytes = MESH_HEADER.unpack_from(data)
        payload = data[MESH_HEADER.size:MESH_HEADER.size + payload_bytes]
        if kind == 0 and len(payload) == 12 * n + 12 * t:
            positions = [list(struct.unpack_from("<3f", payload, 12 * i)) for i in range(n)]
            triangles = [struct.unpack_from("<3I", payload, 12 * n + 12 * k) for k in range(t)]
            bodies[body] = (tick, positions, triangles)
            counts["keyframes"] += 1
        elif kind == 1 and len(payload) == 16 * changed:
            state = bodies.get(body)
            if state is None or state[0] != base_tick or len(state[1]) != n:
                counts["deltas_skipped"] += 1  # wait for a keyframe
                return
            for e in range(changed):
                vertex, x, y, z = struct.unpack_from("<I3f", payload, 16 * e)
                state[1][vertex] = [x, y, z]
            bodies[body] = (tick, state[1], state[2])
            counts["deltas"] += 1
        else:
            counts["bad"] += 1

    subscriber = session.declare_subscriber(f"palpa/{args.prefix}/display/mesh", on_mesh)
    time.sleep(args.seconds)
    subscriber.undeclare()
    summary = dict(counts)
    summary["bodies"] = {
        str(b): {"tick": s[0], "vertices": len(s[1]), "triangles": len(s[2]),
                 "lowest_z": min(p[2] for p in s[1]) if s[1] else None}
        for b, s in sorted(bodies.items())
    }
    print(json.dumps(summary))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("part", choices=["press", "display"])
    parser.add_argument("--connect", action="append", default=[], help="the bridge's endpoint (repeatable)")
    parser.add_argument("--prefix", default="palpa")
    parser.add_argument("--tool", default="probe")
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--top", type=float, default=0.0645, help="height of the surface pressed (m)")
    args = parser.parse_args()
    if not args.connect:
        args.connect = ["tcp/127.0.0.1:7447"]
    session = open_session(args.connect)
    try:
        press(session, args) if args.part == "press" else display(session, args)
    finally:
        session.close()


if __name__ == "__main__":
    main()
