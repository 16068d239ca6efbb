#!/usr/bin/env python3
"""Reads the MAVLink frames a flight recording kept (`/deckwatch/link`, read with the `mcap`
package) and decodes each with pymavlink (neither written at deckwatch). Prints JSON: per
direction the message types pymavlink decoded and their counts, frames it could not decode, and
frames whose recorded name is not what pymavlink decoded; the vehicle samples' count.

Usage: link_traffic.py FILE.mcap
"""
import json
import os
import sys

os.environ.setdefault("MAVLINK20", "1")
from mcap.reader import NonSeekingReader, make_reader
from pymavlink.dialects.v20 import common as mavlink2


def main(path):
    out = {"out": {}, "in": {}, "undecoded": 0, "misnamed": [], "vehicle_samples": 0, "cut": None}
    with open(path, "rb") as f:
        try:
            messages = list(make_reader(f).iter_messages(topics=["/deckwatch/link", "/deckwatch/vehicle"]))
        except Exception as e:  # noqa: BLE001 - a file whose end is cut: read what is there
            # A recorder stopped before it wrote its summary (a loaded machine) leaves a file
            # `deckwatch recover` completes; its messages are read in order up to the cut.
            out["cut"] = repr(e)
            f.seek(0)
            messages = []
            try:
                for m in NonSeekingReader(f).iter_messages():
                    if m[1].topic in ("/deckwatch/link", "/deckwatch/vehicle"):
                        messages.append(m)
            except Exception:  # noqa: BLE001 - the cut itself
                pass
        for schema, channel, message in messages:
            if channel.topic == "/deckwatch/vehicle":
                out["vehicle_samples"] += 1
                continue
            m = json.loads(message.data)
            parser = mavlink2.MAVLink(None)
            parser.robust_parsing = True
            try:
                decoded = parser.parse_buffer(bytes.fromhex(m["frame"])) or []
            except Exception:
                decoded = []
            if len(decoded) != 1:
                out["undecoded"] += 1
                continue
            kind = decoded[0].get_type()
            side = out["out"] if m["outgoing"] else out["in"]
            side[kind] = side.get(kind, 0) + 1
            if kind != m["name"] or decoded[0].get_msgId() != m["msg_id"]:
                out["misnamed"].append([m["name"], kind])
    print(json.dumps(out, sort_keys=True))


if __name__ == "__main__":
    main(sys.argv[1])
