"""A headless Foxglove WebSocket viewer of palpa's live view (`palpa serve --live`).

Connects offering one subprotocol, reads the server's advertisements, subscribes to channels and
decodes every message received with the schema the server advertised for its channel (a protobuf
FileDescriptorSet, loaded into a fresh descriptor pool: nothing of palpa's or Foxglove's is compiled
in). Prints one JSON summary line.

    python live_view_client.py ws://127.0.0.1:8765 --seconds 3
    python live_view_client.py ws://127.0.0.1:8765 --protocol foxglove.websocket.v1
    python live_view_client.py ws://127.0.0.1:8765 --stall 5   # subscribe, then stop reading

Needs `websockets` and `protobuf` (tools/python/requirements.txt).
"""

import argparse
import base64
import json
import struct
import sys
import time

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from websockets.sync.client import connect

MESSAGE_DATA = 0x01  # server binary opcode: subscription id (u32), log time (u64), payload


def message_class(schema_name: str, schema_b64: str):
    """The message class named `schema_name` in the advertised FileDescriptorSet."""
    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(schema_b64))
    pool = descriptor_pool.DescriptorPool()
    pending = list(files.file)
    # Add files in dependency order (a file can only be added after those it imports).
    while pending:
        added = False
        for f in list(pending):
            try:
                pool.Add(f)
            except TypeError:
                continue
            pending.remove(f)
            added = True
        if not added:
            for f in pending:
                pool.Add(f)  # raises with the reason
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("url")
    parser.add_argument("--protocol", default="foxglove.sdk.v1")
    parser.add_argument("--seconds", type=float, default=3.0, help="how long to read")
    parser.add_argument(
        "--topics",
        default="/foxglove/scene,/palpa/stats,/palpa/events,/palpa/tool/*/feedback",
        help="comma-separated topics to subscribe to (a * matches one path element)",
    )
    parser.add_argument("--stall", type=float, default=0.0, help="subscribe, then read nothing for S s")
    args = parser.parse_args()

    def wanted(topic: str) -> bool:
        for pattern in args.topics.split(","):
            a, b = pattern.split("/"), topic.split("/")
            if len(a) == len(b) and all(x == "*" or x == y for x, y in zip(a, b)):
                return True
        return False

    summary = {"protocol": None, "channels": {}, "messages": {}, "decode_errors": 0,
               "scene_updates": 0, "body_entities": 0, "triangles": 0, "tool_entities": 0,
               "feedback_forces": [], "server": None}
    deadline = time.monotonic() + 10.0
    while True:
        try:
            ws = connect(args.url, subprotocols=[args.protocol], open_timeout=5,
                         max_size=None, compression=None)
            break
        except (OSError, TimeoutError):
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)
    with ws:
        summary["protocol"] = ws.subprotocol
        classes = {}
        subscriptions = {}
        next_id = 1
        end = time.monotonic() + args.seconds
        stalled = False
        while time.monotonic() < end:
            try:
                frame = ws.recv(timeout=max(0.01, end - time.monotonic()))
            except TimeoutError:
                break
            if isinstance(frame, str):
                message = json.loads(frame)
                if message.get("op") == "serverInfo":
                    summary["server"] = message.get("name")
                elif message.get("op") == "advertise":
                    new = []
                    for channel in message["channels"]:
                        topic = channel["topic"]
                        summary["channels"][topic] = channel["schemaName"]
                        if not wanted(topic) or channel["encoding"] != "protobuf":
                            continue
                        classes[next_id] = (topic, message_class(channel["schemaName"], channel["schema"]))
                        new.append({"id": next_id, "channelId": channel["id"]})
                        subscriptions[next_id] = channel["id"]
                        next_id += 1
                    if new:
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))
                        if args.stall > 0 and not stalled:
                            # A viewer that stops reading: its socket fills, the server must cope.
                            stalled = True
                            time.sleep(args.stall)
                            return 0
                continue
            if not frame or frame[0] != MESSAGE_DATA or len(frame) < 13:
                continue
            subscription, _log_time = struct.unpack_from("<IQ", frame, 1)
            if subscription not in classes:
                continue
            topic, cls = classes[subscription]
            try:
                decoded = cls.FromString(bytes(frame[13:]))
            except Exception:  # noqa: BLE001 - counted and reported
                summary["decode_errors"] += 1
                continue
            summary["messages"][topic] = summary["messages"].get(topic, 0) + 1
            if topic == "/foxglove/scene":
                summary["scene_updates"] += 1
                for entity in decoded.entities:
                    if entity.id.startswith("body/"):
                        summary["body_entities"] += 1
                        summary["triangles"] = max(
                            summary["triangles"], sum(len(t.indices) // 3 for t in entity.triangles))
                    elif entity.id.startswith("tool/"):
                        summary["tool_entities"] += 1
            elif topic.endswith("/feedback"):
                f = decoded.force
                summary["feedback_forces"].append((f.x * f.x + f.y * f.y + f.z * f.z) ** 0.5)
    forces = summary.pop("feedback_forces")
    summary["feedback_max_force"] = max(forces, default=0.0)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
