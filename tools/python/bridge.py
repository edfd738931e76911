#!/usr/bin/env python3
"""Example device bridge for palpa, in Python, over iceoryx2 (PyPI package `iceoryx2`, see
requirements.txt).

It plays the part of a haptic device's bridge: it publishes tool poses on
"<prefix>/tool/<tool>/pose" and reads the force to render on "<prefix>/tool/<tool>/feedback",
with ctypes structures that mirror proto/palpa_ipc.h byte for byte. It sends a press motion (down
into the default scene's organ and back up), one pose at a time, waits for the answer to each, and
prints the force. Works against `palpa serve` in real-time or in --lockstep mode.

    python3 tools/python/bridge.py --prefix palpa --tool probe --seconds 3
"""

import argparse
import ctypes
import json
import math
import sys
import time

import iceoryx2 as iox2

from press import press_height  # beside this script


class ToolPoseV1(ctypes.Structure):
    """palpa_tool_pose_v1 (88 bytes)."""

    _fields_ = [
        ("seq", ctypes.c_uint64),
        ("device_time_ns", ctypes.c_uint64),
        ("position", ctypes.c_double * 3),
        ("orientation", ctypes.c_double * 4),
        ("jaw", ctypes.c_double),
        ("buttons", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name() -> str:
        return "palpa_tool_pose_v1"


class ToolFeedbackV1(ctypes.Structure):
    """palpa_tool_feedback_v1 (80 bytes)."""

    _fields_ = [
        ("seq", ctypes.c_uint64),
        ("device_time_ns", ctypes.c_uint64),
        ("tick", ctypes.c_uint64),
        ("force", ctypes.c_double * 3),
        ("torque", ctypes.c_double * 3),
        ("contacts", ctypes.c_uint32),
        ("flags", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name() -> str:
        return "palpa_tool_feedback_v1"


assert ctypes.sizeof(ToolPoseV1) == 88 and ctypes.sizeof(ToolFeedbackV1) == 80


def latest_value(node, name, payload):
    """The daemon's latest-value stream settings: history 1, buffer 1, safe overflow."""
    return (
        node.service_builder(iox2.ServiceName.new(name))
        .publish_subscribe(payload)
        .history_size(1)
        .subscriber_max_buffer_size(1)
        .enable_safe_overflow(True)
        .open_or_create()
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--prefix", default="palpa")
    parser.add_argument("--tool", default="probe")
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--top", type=float, default=0.0645, help="height of the surface pressed (m)")
    args = parser.parse_args()

    iox2.set_log_level(iox2.LogLevel.Error)
    node = iox2.NodeBuilder.new().create(iox2.ServiceType.Ipc)
    base = f"{args.prefix}/tool/{args.tool}"
    publisher = latest_value(node, f"{base}/pose", ToolPoseV1).publisher_builder().create()
    subscriber = latest_value(node, f"{base}/feedback", ToolFeedbackV1).subscriber_builder().create()

    # Wait for the daemon: its last feedback reaches us once both ends are connected.
    deadline = time.monotonic() + 30
    while subscriber.receive() is None:
        if time.monotonic() > deadline:
            sys.exit(f"no daemon answers on prefix {args.prefix!r}")
        time.sleep(0.001)

    steps = int(round(args.seconds * 1000))
    answered = 0
    max_force = 0.0
    last = None
    for seq in range(1, steps + 1):
        t = seq * 0.001
        pose = ToolPoseV1(
            seq=seq,
            device_time_ns=time.monotonic_ns(),
            position=(ctypes.c_double * 3)(0.0, 0.0, press_height(t, args.top)),
            orientation=(ctypes.c_double * 4)(1.0, 0.0, 0.0, 0.0),
        )
        publisher.send_copy(pose)
        wait_until = time.monotonic() + 10.0  # a watchdog, not a deadline: lockstep answers every pose
        got = None
        while got is None and time.monotonic() < wait_until:
            sample = subscriber.receive()
            while sample is not None:
                f = sample.payload().contents
                if f.seq == seq:
                    got = (f.tick, list(f.force), f.contacts, f.flags)
                sample = subscriber.receive()
            if got is None:
                time.sleep(0.00002)
        if got is None:
            continue
        answered += 1
        last = got
        force = math.sqrt(sum(x * x for x in got[1]))
        max_force = max(max_force, force)
        if seq % 250 == 0:
            print(f"t {t:5.2f} s  z {press_height(t, args.top):.4f} m  force {got[1][2]:+.4f} N  contacts {got[2]}")
    print(json.dumps({"sent": steps, "answered": answered, "max_force": max_force,
                      "final_force": last[1] if last else None, "final_contacts": last[2] if last else None}))


if __name__ == "__main__":
    main()
