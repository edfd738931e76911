#!/usr/bin/env python3
"""An independent reader of palpa recordings: decodes every message of every channel of an MCAP file
with the protobuf schemas embedded in it (the `mcap` and `mcap-protobuf-support` packages, not
palpa's code) and prints, as JSON, the message count per topic and a few decoded figures, with the
bodies of the session: those of the scene, then those transections added (`BODY_ADDED` events), in
body-index order, and the tick of the session's end (its `SESSION_END` event; null without one).

    python3 tools/python/read_recording.py session.mcap
"""

import json
import sys
from collections import Counter

from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: read_recording.py FILE.mcap")
    counts = Counter()
    max_force = 0.0
    last_tick = 0
    scene_name = None
    bodies = []
    scene_bodies = 0
    session_end_tick = None
    with open(sys.argv[1], "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            counts[channel.topic] += 1
            if schema.name == "palpa.Scene":
                scene_name = decoded.name
                bodies = list(decoded.bodies)
                scene_bodies = len(bodies)
            if schema.name == "palpa.Event":
                kind = decoded.DESCRIPTOR.fields_by_name["kind"].enum_type.values_by_number.get(decoded.kind)
                kind = kind.name if kind is not None else decoded.kind
                if kind == "BODY_ADDED":
                    while len(bodies) <= decoded.body:
                        bodies.append("body%d" % len(bodies))
                    bodies[decoded.body] = decoded.body_name
                elif kind == "RESET":
                    del bodies[scene_bodies:]
                elif kind == "SESSION_END":
                    session_end_tick = decoded.tick
            if schema.name == "palpa.Feedback":
                f_ = decoded.force
                max_force = max(max_force, (f_.x ** 2 + f_.y ** 2 + f_.z ** 2) ** 0.5)
                last_tick = max(last_tick, decoded.tick)
            if schema.name == "palpa.MeshKeyframe":
                assert len(decoded.positions) % 3 == 0 and len(decoded.triangles) % 3 == 0
    print(json.dumps({"scene": scene_name, "messages": dict(sorted(counts.items())),
                      "max_force": max_force, "last_feedback_tick": last_tick,
                      "session_end_tick": session_end_tick,
                      "bodies": bodies}))


if __name__ == "__main__":
    main()
